"""Batch rendering of sweeps on Dask (its clients and ordering: :mod:`sonar_embree.survey.cluster`).

:func:`run` expands a sweep (:mod:`sonar_embree.runs.sweep`) into jobs, splits each
job's trajectory into tasks of ``pings_per_task`` pings (``simulate`` with
``ping_offset``: the pieces join into the same bits as one call), runs them on a
Dask cluster (a ``LocalCluster`` it starts and stops, or the caller's client /
scheduler address) and writes each finished job into ``OUT/<job id>/``:

- ``record.zarr`` (xarray/Zarr), ``record.xtf``, ``waterfall.png``, ``labels.png``
  (kind per sample: water black, seafloor grey, object yellow, shadow blue),
  ``coco.json``, ``record.npz``, as the sweep's ``outputs`` ask;
- ``job.json``: the job's scene, trajectory, seed and varied settings.

``OUT/sweep.json`` describes the whole sweep and ``OUT/coco.json`` (with "coco")
merges every job's boxes. Each job is written in a temporary folder and renamed
when complete, so a killed batch leaves only whole jobs; ``resume=True`` skips
them and redoes the rest. Outputs depend only on the sweep, never on the number of
workers. Each worker keeps the last scene it built, so the tasks of one job build
its scene once per worker.
"""
from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import os
import tempfile

from ..errors import ConfigError
from ..record import registry
from ..record.coco import merge, write_json
from ..io.files import LOCK_NAME, folder_lock
from ..io.owner import MANIFEST, OutputFolder
from ..record import Record
from .sweep import Job, SceneSpec, Sweep, load_sweep
from ..errors import SonarEmbreeError
from ..propagation.prepared import RunCache
from ..simulate import simulate
from ..survey.cluster import as_completed, client_for, threads_of

log = logging.getLogger(__name__)

_SCENE_CACHE: dict = {}


def _scene(spec: SceneSpec, seed: int):
    """(scene, its RunCache) of a worker: one scene at a time (memory stays bounded), its BVH and tables shared by
    the tasks that render it."""
    key = (spec.source, spec.index, int(seed))
    if key not in _SCENE_CACHE:
        _SCENE_CACHE.clear()
        _SCENE_CACHE[key] = (spec.build(seed), RunCache(scenes=1))
    return _SCENE_CACHE[key]


def render_part(spec: SceneSpec, job: Job, start: int, stop: int) -> Record:
    """Simulate pings ``start … stop − 1`` of a job (a Dask task)."""
    scene, cache = _scene(spec, job.seed)
    return simulate(scene, job.trajectory[start:stop], job.sonar, job.pulse, fan=job.fan, chain=job.chain,
                    labels=job.labels, keep_complex=job.keep_complex, ping_offset=start, start_time=job.start_time,
                    cache=cache, environment=job.environment)


def _write_outputs(rec: Record, job: Job, sweep: Sweep, folder: str) -> None:
    """Every output the sweep asks for, of one job's record, into ``folder``."""
    info = job.describe(sweep)
    rec = dataclasses.replace(rec, attrs={**rec.attrs, "job": info["id"], "scene": info["scene"],
                                          "trajectory": info["trajectory"], "sweep": sweep.name,
                                          **{f"vary.{k}": v for k, v in info["vary"].items()}})
    registry.write_each(rec, folder, sweep.outputs,
                        registry.WriteOptions(dict(sweep.png), tuple(sweep.categories), job.index))
    write_json(info, os.path.join(folder, "job.json"))


def _write_job(rec: Record, job: Job, sweep: Sweep, out: OutputFolder) -> None:
    """The job's folder, written whole (a temporary folder listed in the manifest, renamed into place)."""
    def write(tmp):
        os.mkdir(tmp)
        _write_outputs(rec, job, sweep, tmp)

    out.write_set([(job.id, write)])


def preflight(sweep: Sweep) -> None:
    """Render one ping of each scene's first job and write all its outputs to a scratch folder.

    Runs before anything is written to the output folder, so a sweep whose outputs
    cannot be made (a COCO category, a label, a format) stops in seconds with one line
    instead of after the jobs have rendered.
    """
    seen = set()
    try:
        for job in sweep.jobs:
            if job.scene_index in seen:
                continue
            seen.add(job.scene_index)
            rec = render_part(sweep.scenes[job.scene_index], job, 0, 1)
            with tempfile.TemporaryDirectory(prefix="sonar-embree-check-") as tmp:
                _write_outputs(rec, job, sweep, tmp)
    except SonarEmbreeError as exc:
        raise type(exc)(f"{sweep.source}: job {job.id} (one ping checked before the batch): {exc}") from None
    finally:
        _SCENE_CACHE.clear()


def _merged_coco(sweep: Sweep, out: OutputFolder) -> None:
    parts = []
    for job in sweep.jobs:
        with open(os.path.join(out.path, job.id, "coco.json"), encoding="utf-8") as fh:
            d = json.load(fh)
        for im in d["images"]:
            im["file_name"] = f"{job.id}/{im['file_name']}"
        parts.append(d)
    merged = merge(parts)
    for k, a in enumerate(merged["annotations"]):
        a["id"] = k + 1
    out.write_set([("coco.json", lambda p: write_json(merged, p))])


def _manifest_json(sweep: Sweep) -> dict:
    return json.loads(json.dumps(sweep.manifest(), sort_keys=True, default=str))


def _check_folder(sweep: Sweep, out_dir: str, resume: bool) -> None:
    """Refuse an output folder that holds something else, before any work (nothing is written here)."""
    path = os.path.join(out_dir, "sweep.json")
    if os.path.exists(path):
        if not resume:
            raise ConfigError(f"{out_dir}: already holds a batch (sweep.json); use --resume to continue it, "
                              "or choose an empty folder")
        try:
            with open(path, encoding="utf-8") as fh:
                old = json.load(fh)
        except (OSError, ValueError) as exc:
            raise ConfigError(f"{path}: unreadable ({exc}); choose another folder") from None
        new = _manifest_json(sweep)
        if old != new:
            what = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
            raise ConfigError(f"{out_dir}: holds a different sweep than {sweep.source} (changed: "
                              f"{', '.join(what)}); choose another folder")
    elif os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise ConfigError(f"{out_dir}: exists and is not a folder")
    OutputFolder.check(out_dir, _names(sweep), resume=resume, inputs=[sweep.source], command="batch")


def _names(sweep: Sweep) -> list:
    """What a batch writes into its folder: the sweep, the merged COCO and a folder per job."""
    return ["sweep.json", "coco.json", *(j.id for j in sweep.jobs)]


def _prepare(sweep: Sweep, out_dir: str, resume: bool) -> tuple:
    """Claim the folder (its manifest first: what a killed run was writing goes), write ``sweep.json`` unless
    resuming; return (the folder, jobs to run, fresh)."""
    out = OutputFolder.claim(out_dir, _names(sweep), resume=resume, inputs=[sweep.source], command="batch")
    fresh = not os.path.exists(os.path.join(out_dir, "sweep.json"))
    if fresh:
        out.write_set([("sweep.json", lambda p: write_json(_manifest_json(sweep), p))])
    return out, [j for j in sweep.jobs if not os.path.isdir(os.path.join(out_dir, j.id))], fresh


def run(sweep, out_dir, client=None, *, scheduler: str | None = None, workers: int | None = None,
        resume: bool = False, progress: bool = False, dashboard: str | None = None,
        max_in_flight: int | None = None) -> list:
    """Render every job of a sweep into ``out_dir``.

    Parameters
    ----------
    sweep : Sweep or str or PathLike
        A loaded sweep or its TOML file (:func:`sonar_embree.runs.sweep.load_sweep`).
    out_dir : str or PathLike
        Output folder: new or empty, or (with ``resume``) one this sweep wrote before.
    client : distributed.Client, optional
        Run on this client's cluster.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``). Workers need the
        package and the sweep's mesh files at the same paths; results come back to
        this process, which writes every file.
    workers : int, optional
        Worker processes of the ``LocalCluster`` started when neither ``client`` nor
        ``scheduler`` is given (default: the CPU count, at most 8), one Numba thread each.
    resume : bool
        Continue a batch in ``out_dir``: finished jobs are kept, the rest run. Refused
        when any input (settings, trajectories, mesh and CSV file contents) changed.
    progress : bool
        A progress bar over jobs (tqdm, on stderr).
    dashboard : str, optional
        Address of the local cluster's Dask dashboard (``":8787"``); default: none,
        and no HTTP port is bound on a public interface.
    max_in_flight : int, optional
        Most tasks submitted and not yet collected (default: 4 per worker thread,
        at least 8). Later tasks are submitted as earlier ones finish, so a sweep of
        any number of jobs runs in bounded memory on the scheduler and here.

    Returns
    -------
    list of str
        The ids of the jobs run now (finished jobs skipped by ``resume`` excluded).
    """
    sweep = sweep if isinstance(sweep, Sweep) else load_sweep(sweep)
    out_dir = os.path.abspath(os.fspath(out_dir))
    for name, value in (("workers", workers), ("max_in_flight", max_in_flight)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
            raise ConfigError(f"batch: {name} must be an integer >= 1, got {value!r}")
    if client is not None and scheduler is not None:
        raise ConfigError("batch: give either a client or a scheduler address, not both")
    _check_folder(sweep, out_dir, resume)
    preflight(sweep)
    created = not os.path.exists(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    with folder_lock(out_dir):                            # a second run of this folder is refused, not interleaved
        _check_folder(sweep, out_dir, resume)             # again, now that no other run can change it
        todo = _run_locked(sweep, out_dir, resume, created, client, scheduler, workers, dashboard,
                           max_in_flight, progress)
    return [j.id for j in todo]


def _run_locked(sweep, out_dir, resume, created, client, scheduler, workers, dashboard, max_in_flight,
                progress) -> list:
    out, todo, fresh = _prepare(sweep, out_dir, resume)
    try:
        if todo:
            _run_on_cluster(sweep, todo, out, client, scheduler, workers, dashboard, max_in_flight, progress)
        if "coco" in sweep.outputs:
            _merged_coco(sweep, out)
    except BaseException:
        if fresh and not any(os.path.isdir(os.path.join(out_dir, j.id)) for j in sweep.jobs):
            _remove_started(out_dir, created)  # nothing finished: leave no batch to refuse a re-run
        raise
    return todo


def _remove_started(out_dir: str, created: bool) -> None:
    for name in ("sweep.json", "coco.json", LOCK_NAME, MANIFEST):
        with contextlib.suppress(FileNotFoundError):
            os.unlink(os.path.join(out_dir, name))
    if created:
        with contextlib.suppress(OSError):
            os.rmdir(out_dir)


def _run_on_cluster(sweep, todo, out, client, scheduler, workers, dashboard, max_in_flight, progress):
    with client_for(client, scheduler, workers, dashboard) as c:
        if max_in_flight is None:
            max_in_flight = max(8, 4 * threads_of(c))
        _run_jobs(c, sweep, todo, out, progress, max_in_flight)


def _tasks(sweep: Sweep, todo: list):
    """(job, start, stop) of every task, job by job: a job's pieces are submitted together."""
    for job in todo:
        n = len(job.trajectory)
        for a in range(0, n, sweep.pings_per_task):
            yield job, a, min(a + sweep.pings_per_task, n)


def _run_jobs(client, sweep: Sweep, todo: list, out: OutputFolder, progress: bool, max_in_flight: int,
              stats: dict | None = None) -> None:
    """Submit tasks with back-pressure (at most ``max_in_flight`` uncollected) and write jobs as they finish."""
    tag = sweep.manifest_digest()[:10]
    tasks = _tasks(sweep, todo)
    parts: dict = {}              # job id -> {start: Record}
    expected = {j.id: -(-len(j.trajectory) // sweep.pings_per_task) for j in todo}
    pending = as_completed([])
    owner: dict = {}              # future key -> (job, first ping)
    in_flight, peak = 0, 0

    def submit_more():
        nonlocal in_flight, peak
        while in_flight < max_in_flight:
            task = next(tasks, None)
            if task is None:
                return
            job, a, b = task
            fut = client.submit(render_part, sweep.scenes[job.scene_index], job, a, b, pure=False,
                                priority=-job.index, key=f"sonar-embree-{tag}-{job.id}-{a}")
            owner[fut.key] = (job, a)
            pending.add(fut)
            in_flight += 1
            peak = max(peak, in_flight)

    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=len(todo), desc="jobs", unit="job")
    try:
        submit_more()
        for fut in pending:
            in_flight -= 1
            job, a = owner.pop(fut.key)
            got = parts.setdefault(job.id, {})
            got[a] = fut.result()  # raises the task's own exception
            fut.release()
            if len(got) == expected[job.id]:
                rec = Record.concatenate(got[a] for a in sorted(got))
                del parts[job.id]
                _write_job(rec, job, sweep, out)
                if bar is not None:
                    bar.update(1)
            submit_more()
    except BaseException:
        client.cancel(list(pending.futures))
        raise
    finally:
        if bar is not None:
            bar.close()
        if stats is not None:
            stats["peak_in_flight"] = peak
