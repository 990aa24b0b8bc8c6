"""Batch rendering of sweeps on Dask (the only module that imports dask/distributed).

:func:`run` expands a sweep (:mod:`sonar_embree.sweep`) into jobs, splits each
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

import dataclasses
import json
import logging
import os
import shutil
import tempfile

import numpy as np

from .errors import ConfigError
from .io.coco import coco_dict, merge, write_json
from .record import Record
from .sweep import Job, SceneSpec, Sweep, load_sweep

log = logging.getLogger(__name__)

LABEL_COLOURS = np.array([[0, 0, 0], [110, 110, 110], [255, 210, 0], [30, 90, 255]], dtype=np.uint8)
_SCENE_CACHE: dict = {}


def _scene(spec: SceneSpec, seed: int):
    key = (spec.source, spec.index, int(seed))
    if key not in _SCENE_CACHE:
        _SCENE_CACHE.clear()  # one scene per worker at a time: memory stays bounded
        _SCENE_CACHE[key] = spec.build(seed)
    return _SCENE_CACHE[key]


def render_part(spec: SceneSpec, job: Job, start: int, stop: int) -> Record:
    """Simulate pings ``start … stop − 1`` of a job (a Dask task)."""
    from .simulate import simulate

    return simulate(_scene(spec, job.seed), job.trajectory[start:stop], job.sonar, job.pulse, fan=job.fan,
                    chain=job.chain, labels=job.labels, keep_complex=job.keep_complex, ping_offset=start)


def _write_job(rec: Record, job: Job, sweep: Sweep, out_dir: str) -> None:
    info = job.describe(sweep)
    rec = dataclasses.replace(rec, attrs={**rec.attrs, "job": info["id"], "scene": info["scene"],
                                          "trajectory": info["trajectory"], "sweep": sweep.name,
                                          **{f"vary.{k}": v for k, v in info["vary"].items()}})
    tmp = tempfile.mkdtemp(dir=out_dir, prefix=".tmp-")
    try:
        png = dict(sweep.png)
        cols = png.pop("max_columns", 1024)
        if "zarr" in sweep.outputs:
            rec.to_zarr(os.path.join(tmp, "record.zarr"))
        if "xtf" in sweep.outputs:
            rec.to_xtf(os.path.join(tmp, "record.xtf"))
        if "png" in sweep.outputs:
            rec.save_png(os.path.join(tmp, "waterfall.png"), max_columns=cols, **png)
        if "labels" in sweep.outputs:
            import imageio.v3 as iio

            img = LABEL_COLOURS[rec.labels.waterfall("kind", cols)]
            iio.imwrite(os.path.join(tmp, "labels.png"), img, extension=".png")
        if "coco" in sweep.outputs:
            write_json(coco_dict(rec, "waterfall.png", categories=sweep.categories, image_id=job.index,
                                 max_columns=cols), os.path.join(tmp, "coco.json"))
        if "npz" in sweep.outputs:
            rec.save(os.path.join(tmp, "record.npz"))
        write_json(info, os.path.join(tmp, "job.json"))
        os.replace(tmp, os.path.join(out_dir, job.id))  # the job appears whole or not at all
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _merged_coco(sweep: Sweep, out_dir: str) -> None:
    parts = []
    for job in sweep.jobs:
        with open(os.path.join(out_dir, job.id, "coco.json"), encoding="utf-8") as fh:
            d = json.load(fh)
        for im in d["images"]:
            im["file_name"] = f"{job.id}/{im['file_name']}"
        parts.append(d)
    merged = merge(parts)
    for k, a in enumerate(merged["annotations"]):
        a["id"] = k + 1
    write_json(merged, os.path.join(out_dir, "coco.json"))


def _prepare(sweep: Sweep, out_dir: str, resume: bool) -> list:
    os.makedirs(out_dir, exist_ok=True)
    manifest = sweep.manifest()
    path = os.path.join(out_dir, "sweep.json")
    if os.path.exists(path):
        with open(path, encoding="utf-8") as fh:
            old = json.load(fh)
        if not resume:
            raise ConfigError(f"{out_dir}: already holds a batch (sweep.json); use --resume to continue it, "
                              "or choose an empty folder")
        if old != json.loads(json.dumps(manifest, sort_keys=True, default=str)):
            raise ConfigError(f"{out_dir}: holds a different sweep than {sweep.source}; choose another folder")
    else:
        stray = [n for n in os.listdir(out_dir) if not n.startswith(".tmp-")]
        if stray:
            raise ConfigError(f"{out_dir}: not empty and not a batch folder (found {stray[0]!r})")
        write_json(json.loads(json.dumps(manifest, default=str)), path)
    for name in os.listdir(out_dir):  # what a killed run was writing
        if name.startswith(".tmp-"):
            shutil.rmtree(os.path.join(out_dir, name), ignore_errors=True)
    return [j for j in sweep.jobs if not os.path.isdir(os.path.join(out_dir, j.id))]


def run(sweep, out_dir, client=None, *, scheduler: str | None = None, workers: int | None = None,
        resume: bool = False, progress: bool = False) -> list:
    """Render every job of a sweep into ``out_dir``.

    Parameters
    ----------
    sweep : Sweep or str or PathLike
        A loaded sweep or its TOML file (:func:`sonar_embree.sweep.load_sweep`).
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
        ``scheduler`` is given (default: the CPU count, at most 8).
    resume : bool
        Continue a batch in ``out_dir``: finished jobs are kept, the rest run.
    progress : bool
        A progress bar over jobs (tqdm, on stderr).

    Returns
    -------
    list of str
        The ids of the jobs run now (finished jobs skipped by ``resume`` excluded).
    """
    sweep = sweep if isinstance(sweep, Sweep) else load_sweep(sweep)
    out_dir = os.path.abspath(os.fspath(out_dir))
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"batch: workers must be an integer >= 1, got {workers!r}")
    if client is not None and scheduler is not None:
        raise ConfigError("batch: give either a client or a scheduler address, not both")
    todo = _prepare(sweep, out_dir, resume)
    if todo:
        from distributed import Client, LocalCluster

        cluster = None
        own = client is None
        if own and scheduler is not None:
            try:
                client = Client(scheduler, timeout="20s")
            except OSError as exc:
                raise ConfigError(f"batch: cannot reach the Dask scheduler at {scheduler!r} ({exc})") from None
        elif own:
            n = workers or max(1, min(os.cpu_count() or 1, 8))
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                   silence_logs=logging.ERROR)
            client = Client(cluster)
        try:
            _run_jobs(client, sweep, todo, out_dir, progress)
        finally:
            if own:
                client.close()
                if cluster is not None:
                    cluster.close()
    if "coco" in sweep.outputs:
        _merged_coco(sweep, out_dir)
    return [j.id for j in todo]


def _run_jobs(client, sweep: Sweep, todo: list, out_dir: str, progress: bool) -> None:
    from distributed import as_completed

    tag = sweep.manifest()["settings"][:10]
    parts, owner = {}, {}
    for job in todo:
        spec = sweep.scenes[job.scene_index]
        n = len(job.trajectory)
        futs = [client.submit(render_part, spec, job, a, min(a + sweep.pings_per_task, n), pure=False,
                              priority=-job.index, key=f"sonar-embree-{tag}-{job.id}-{a}")
                for a in range(0, n, sweep.pings_per_task)]
        parts[job.id] = futs
        for f in futs:
            owner[f.key] = job
    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=len(todo), desc="jobs", unit="job")
    left = {j.id: len(parts[j.id]) for j in todo}
    try:
        for fut in as_completed([f for fs in parts.values() for f in fs]):
            job = owner[fut.key]
            if fut.status == "error":
                fut.result()  # raises the task's own exception
            left[job.id] -= 1
            if left[job.id]:
                continue
            rec = Record.concatenate(f.result() for f in parts[job.id])
            _write_job(rec, job, sweep, out_dir)
            del parts[job.id]
            if bar is not None:
                bar.update(1)
    except BaseException:
        for fs in parts.values():
            client.cancel(fs)
        raise
    finally:
        if bar is not None:
            bar.close()

