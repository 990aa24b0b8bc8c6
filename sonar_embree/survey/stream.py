"""Streaming a long line to disk in blocks of pings, with bounded memory and resume (docs/physics.md §17).

Each block of pings is simulated as :func:`~sonar_embree.simulate` would simulate those pings alone
(``ping_offset`` = its first ping: the same bits as an in-memory run of them), written into its region of a
Zarr store laid out for the whole line (the CF dataset of :meth:`Record.to_xarray`, one Zarr chunk per block)
and appended to an XTF file, and only then counted as done in the store's ``stream.json``. A killed run
started again with the same inputs continues at the first block not done (its partial writes are
overwritten; the XTF is cut back to the blocks done) and ends with the same bytes as a run never stopped;
different inputs (the output paths included) are refused, and so are a store or XTF shorter than the progress
says. Nothing the stream did not write is touched: a non-empty folder without its ``stream.json`` and an
existing XTF file it did not start are refused unless ``overwrite=True``. Each block's files are fsynced before
the progress (written atomically, fsynced) counts it. The whole-line attributes (rays per ping, …) are the
first block's.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import shutil
import time
import warnings

import numpy as np

from ..errors import ConfigError
from ..io.files import LOCK_NAME, check_replaceable, folder_lock, fsync_path, os_error_line, write_json_durable
from ..validation import check_bool, iso_utc
from ..config import Sonar
from ..record import Record
from ..record.dataset import is_own_store
from ..propagation.prepared import RunCache
from ..scene import TiledDEM
from ..simulate import progress_bar as pings_bar, simulate, tile_reach_m, time_estimate_s
from .cluster import client_for, in_order, lazy_zeros, threads_of

log = logging.getLogger(__name__)

#: Name of the progress file inside the Zarr store.
PROGRESS = "stream.json"


def _fingerprint(scene, trajectory, sonar, pulse, kwargs) -> str:
    """A digest of everything that decides the output's bytes."""
    h = hashlib.sha256()
    if isinstance(scene, TiledDEM):                                 # its file and tiling
        h.update(scene.fingerprint().encode())
    for obj in () if isinstance(scene, TiledDEM) else scene.objects:
        h.update(obj.label.encode())
        h.update(np.ascontiguousarray(obj.vertices).tobytes())
        h.update(np.ascontiguousarray(obj.faces).tobytes())
        h.update(repr(obj.material).encode())
    for name in ("positions_m", "heading_deg", "pitch_deg", "roll_deg", "times_s", "velocity_m_s", "ship_positions_m",
                 "fix_times_s"):
        a = getattr(trajectory, name)
        h.update(b"none" if a is None else np.ascontiguousarray(a).tobytes())
    h.update(repr((trajectory.crs, trajectory.start_time, sonar, pulse, sorted(kwargs.items()))).encode())
    return h.hexdigest()


def _progress(path: str) -> dict | None:
    try:
        with open(os.path.join(path, PROGRESS)) as fh:
            progress = json.load(fh)
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: unreadable stream progress ({exc})") from None
    if not isinstance(progress, dict) or not {"fingerprint", "pings_done", "n_pings"} <= set(progress):
        raise ConfigError(f"{path}: {PROGRESS} is not a stream's progress; choose another folder")
    return progress


def _save_progress(path: str, progress: dict) -> None:
    """Progress written atomically and fsynced (a power cut leaves the old or the new count, never a torn one)."""
    write_json_durable(progress, os.path.join(path, PROGRESS))


def _foreign(path: str) -> list:
    """Names in the folder ``path`` other than the stream's own bookkeeping (its lock, its progress's temporary)."""
    own = (LOCK_NAME, PROGRESS + ".tmp")
    return sorted(n for n in os.listdir(path) if n not in own)


def _claim(path: str, overwrite: bool) -> None:
    """Make ``path`` a folder this stream may write: new, empty, a stream's own store, or (``overwrite``) a Zarr
    store this package wrote. Refuses, before any work, a folder the project did not create, whatever
    ``overwrite`` says."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise ConfigError(f"{path}: exists and is not a folder (a streamed line is a Zarr folder); choose another "
                          "path")
    if os.path.isdir(path):
        names = _foreign(path)
        if names and PROGRESS not in names and not (overwrite and is_own_store(path)):
            raise ConfigError(f"{path}: not empty and not a streamed line (found {names[0]!r}); choose a new or "
                              "empty folder" + ("" if overwrite else ", or pass overwrite=True to replace a Zarr "
                                                "store of sonar_embree"))
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as exc:
        raise os_error_line(exc, path) from None


def _check_xtf_free(xtf_path, old: dict | None, overwrite: bool) -> None:
    """Refuse to start an XTF over a non-empty file that this store's stream did not write (unless ``overwrite``)."""
    if xtf_path is None or not os.path.exists(xtf_path):
        return
    if os.path.isdir(xtf_path):
        raise ConfigError(f"{xtf_path}: is a folder, not an XTF file")
    ours = old is not None and old.get("xtf_path") == xtf_path
    if os.path.getsize(xtf_path) > 0 and not ours and not overwrite:
        raise ConfigError(f"{xtf_path}: exists and was not written by this stream; choose another name or pass "
                          "overwrite=True")
    if not ours:
        check_replaceable(xtf_path, ".xtf")                          # overwrite replaces an XTF, never another file


def _check_outputs(path: str, progress: dict, xtf_path) -> None:
    """Before a resume touches them: the store holds the whole line, and the XTF holds at least every ping
    counted as done and starts with the header this stream wrote."""
    import xarray as xr

    try:
        n = xr.open_zarr(path).sizes.get("ping")
    except Exception as exc:                                       # zarr/xarray raise many types
        raise ConfigError(f"{path}: the Zarr store of this streamed line is unreadable ({type(exc).__name__}); "
                          "pass resume=False to start over") from None
    if n != progress["n_pings"]:
        raise ConfigError(f"{path}: the store holds {n} pings, its progress says {progress['n_pings']}; pass "
                          "resume=False to start over")
    x = progress.get("xtf")
    if x is None:
        return
    if not os.path.isfile(xtf_path):
        raise ConfigError(f"{xtf_path}: the XTF of this streamed line is missing; pass resume=False to start over")
    need = x["header_bytes"] + progress["pings_done"] * x.get("ping_bytes", 0)
    size = os.path.getsize(xtf_path)
    if size < need:
        raise ConfigError(f"{xtf_path}: holds {size} bytes, fewer than the {need} of the {progress['pings_done']} "
                          "pings done; it was cut or changed: pass resume=False to start over")
    with open(xtf_path, "rb") as fh:
        if hashlib.sha256(fh.read(x["header_bytes"])).hexdigest() != x["header_sha256"]:
            raise ConfigError(f"{xtf_path}: its header is not the one this stream wrote; pass resume=False to "
                              "start over")


def _resumed(path: str, key: str, xtf_path, resume: bool, overwrite: bool) -> dict | None:
    """The progress to continue from, or None to start over (the folder emptied of the old store, the XTF
    checked free)."""
    old = _progress(path)
    if old is not None and resume and old.get("pings_done", 0) > 0 and not (overwrite and old["fingerprint"] != key):
        if old["fingerprint"] != key:
            was = old.get("xtf_path")
            why = f" (its XTF was {was}, now {xtf_path})" if was != xtf_path else ""
            raise ConfigError(f"{path}: holds a streamed line of other inputs{why}; remove it or pass resume=False")
        _check_outputs(path, old, xtf_path)
        return old
    _check_xtf_free(xtf_path, old, overwrite)
    for name in _foreign(path):                                      # ours (or overwrite): the old store goes
        p = os.path.join(path, name)
        shutil.rmtree(p) if os.path.isdir(p) and not os.path.islink(p) else os.unlink(p)
    return None


def _template(ds, n_pings: int, block: int):
    """The whole line's dataset with lazy (dask) ping-long variables shaped like the block's ``ds``."""
    import xarray as xr

    def whole(var):
        if "ping" not in var.dims:
            return var
        shape = tuple(n_pings if d == "ping" else ds.sizes[d] for d in var.dims)
        chunks = tuple(block if d == "ping" else ds.sizes[d] for d in var.dims)
        return xr.Variable(var.dims, lazy_zeros(shape, var.dtype, chunks), var.attrs)

    return xr.Dataset({k: whole(v) for k, v in ds.data_vars.items()},
                      coords={k: whole(v.variable) for k, v in ds.coords.items()}, attrs=ds.attrs)


def _one_clock(simulate_kwargs: dict, trajectory, progress: dict | None = None) -> dict:
    """``simulate_kwargs`` with one ``start_time`` for every block: the caller's, else the trajectory's, else the one
    a resumed line started with, else now. Left to each block, "now" moved on between blocks, and the XTF's ping
    times jumped by the render time at every block."""
    if simulate_kwargs.get("start_time") is not None or trajectory.start_time is not None:
        return simulate_kwargs
    start = (progress or {}).get("start_time")
    return {**simulate_kwargs, "start_time": start if start is not None else iso_utc(None)}


def _start(path, first, n_pings, block, fingerprint, xtf_path, xtf_opts):
    """Create the store (metadata, sample coordinates) and the XTF header from the first block's record.

    The progress file (the marker that makes the folder this stream's) is written before anything else."""
    from ..record.dataset import to_xarray
    from ..io.xtf import xtf_bytes

    progress = {"fingerprint": fingerprint, "pings_done": 0, "n_pings": n_pings, "block_pings": block,
                "xtf": None, "xtf_path": xtf_path, "start_time": first.attrs.get("start_time")}
    _save_progress(path, progress)
    ds = to_xarray(first)
    encoding = {name: {"chunks": tuple(block if d == "ping" else ds.sizes[d] for d in var.dims)}
                for name, var in ds.data_vars.items()}
    with _own_files_quiet():
        _template(ds, n_pings, block).to_zarr(path, mode="a", zarr_format=2, consolidated=True, encoding=encoding,
                                              compute=False)
    if xtf_path is not None:
        scale = _scale_of(first, xtf_opts[0])                        # fixed by the first block for the line
        header, _ = xtf_bytes(first, scale=scale, file_name=os.path.basename(xtf_path), samples_per_channel=xtf_opts[1])
        try:
            with open(xtf_path, "wb") as fh:
                fh.write(header)
        except OSError as exc:
            raise os_error_line(exc, xtf_path) from None
        progress["xtf"] = {"header_bytes": len(header), "scale": scale, "samples": xtf_opts[1],
                           "header_sha256": hashlib.sha256(header).hexdigest()}
    _save_progress(path, progress)
    return progress


@contextlib.contextmanager
def _own_files_quiet():
    """Zarr warns about every file in a store it does not know; the stream's own two are expected there."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Object at (stream\.json|\.sonar-embree\.lock) is not recognized")
        yield


def _scale_of(record, scale) -> float:
    from ..io.xtf import sample_scale

    return 1.0 if record.samples is not None else sample_scale(record, scale)


def _fsync_block(path: str, ds, k: int) -> None:
    """fsync block ``k``'s chunk of every ping-long variable of ``ds`` (Zarr format 2 keys: the block's index on the ping
    axis, 0 on the others, which are one chunk each), then their folders and the store's: O(variables) per block,
    not a walk of the whole store. A chunk Zarr left unwritten (all fill value) has no file and nothing to flush."""
    for name, var in ds.variables.items():
        folder = os.path.join(path, name)
        chunk = os.path.join(folder, ".".join(str(k) if d == "ping" else "0" for d in var.dims))
        if os.path.exists(chunk):
            fsync_path(chunk)
        if os.path.isdir(folder):
            fsync_path(folder)
    fsync_path(path)


def _write_block(path, rec, a: int, progress: dict, xtf_path, line) -> None:
    """The block's pings (from ping ``a`` of the trajectory ``line``) into their Zarr region and onto the XTF,
    flushed to disk; then counted as done."""
    from ..record.dataset import to_xarray
    from ..io.xtf import xtf_bytes

    ds = to_xarray(rec)
    ds = ds.drop_vars([n for n, v in ds.variables.items() if "ping" not in v.dims])
    ds.attrs = {}
    with _own_files_quiet():
        ds.to_zarr(path, region={"ping": slice(a, a + rec.n_pings)}, zarr_format=2)
    if xtf_path is not None:
        _, packets = xtf_bytes(rec, scale=progress["xtf"]["scale"], first_ping=a,
                               samples_per_channel=progress["xtf"].get("samples"), line=line)
        per_ping = progress["xtf"].setdefault("ping_bytes", len(packets) // rec.n_pings)
        try:
            with open(xtf_path, "r+b") as fh:
                fh.truncate(progress["xtf"]["header_bytes"] + a * per_ping)
                fh.seek(0, os.SEEK_END)
                fh.write(packets)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:                                      # a full disk: name the file that did not fit
            raise os_error_line(exc, xtf_path) from None
    _fsync_block(path, ds, a // progress["block_pings"])
    progress["pings_done"] = a + rec.n_pings
    _save_progress(path, progress)


def _checked_block(block_pings, what: str) -> None:
    if not isinstance(block_pings, (int, np.integer)) or isinstance(block_pings, bool) or block_pings < 1:
        raise ConfigError(f"{what}: block_pings must be an integer >= 1, got {block_pings!r}")


def _checked_args(block_pings, flags: dict, simulate_kwargs: dict) -> None:
    _checked_block(block_pings, "render_line")
    for name, value in flags.items():
        check_bool("render_line", name, value)
    for key in ("ping_offset", "keep_complex"):
        if key in simulate_kwargs:
            raise ConfigError(f"render_line: {key} is not a streaming option")


def render_line(scene, trajectory, path, sonar=None, pulse=None, *, block_pings: int = 512, xtf_path=None,
                xtf_scale="auto", resume: bool = True, overwrite: bool = False, progress_bar: bool = False,
                png_path=None, xtf_samples: int | None = None, workers: int | None = None,
                scheduler: str | None = None, client=None, cache: RunCache | None = None, **simulate_kwargs) -> str:
    """Simulate ``trajectory`` block by block into a Zarr store at ``path`` (and an XTF file), memory bounded by
    one block.

    Parameters
    ----------
    scene, trajectory, sonar, pulse
        As for :func:`~sonar_embree.simulate` (a :class:`~sonar_embree.TiledDEM`: each block gets the tiles within
        reach of its pings, so memory follows the swath); every other keyword of it (speckle, labels, seed, …) goes through
        ``simulate_kwargs`` (not ``ping_offset``, set per block, nor ``keep_complex``).
    path : str or PathLike
        The Zarr store, a folder: new, empty, or one this function wrote (``xarray.open_zarr`` opens it, lazily).
        A folder holding anything else is refused unless ``overwrite``.
    block_pings : int
        Pings per block: one Zarr chunk each, and what is redone after a kill (at most the line's length).
    xtf_path : str or PathLike, optional
        Also write an XTF file as the blocks come: a sonar with a :class:`~sonar_embree.Receiver` writes its integer
        codes (uint8/uint16, as the device stores them); otherwise float samples × a factor fixed by the first
        block for ``xtf_scale="auto"`` (:func:`sonar_embree.io.xtf.sample_scale`). An existing non-empty file that
        this stream did not write is refused unless ``overwrite``.
    resume : bool
        Continue a store left by a killed run with the same inputs, the same ``xtf_path`` included (default);
        False starts over. A resume first checks the store and that the XTF holds every ping counted as done.
    overwrite : bool
        Replace a Zarr store of this package, or an XTF file, that this stream did not write (any other file or
        folder is refused all the same).
    xtf_samples : int, optional
        Samples per side written to the XTF, decimated as a device does (:func:`sonar_embree.io.xtf.decimate`);
        default every sample.
    png_path : str or PathLike, optional
        Also draw the finished line's waterfall PNG from the store (:meth:`Record.load`, a block of pings at a
        time) at the ground's aspect, at most :data:`PNG_MAX_ROWS` rows (atomic; a file that is not a PNG is
        refused).
    workers : int, optional
        Render the blocks on this many worker processes of a Dask ``LocalCluster`` (one Numba thread each; 1: in
        this process, on its threads). Default: on :func:`~sonar_embree.survey.cluster.default_workers` processes
        for a line of at least :data:`AUTO_MIN_PINGS` pings and :data:`AUTO_MIN_BLOCKS` blocks left on a machine of
        at least :data:`AUTO_MIN_CPUS` CPUs, else in this process. The blocks and their bits are the same either
        way; the store and the XTF are written here, in ping order.
    scheduler : str, optional
        Render the blocks on a running Dask scheduler (``tcp://host:8786``); workers need the package and, for a
        :class:`~sonar_embree.TiledDEM`, its tiles at the same paths.
    client : distributed.Client, optional
        Render the blocks on this client's cluster.
    cache : RunCache, optional
        What the blocks rendered in this process share (the scene's BVH, tables): default a new one for the line;
        hand the same to several lines over one scene (a survey does). Workers keep their own.

    Returns
    -------
    str
        ``path``.
    """
    _checked_cluster(workers, scheduler, client)
    if cache is not None and not isinstance(cache, RunCache):
        raise ConfigError(f"render_line: cache must be a sonar_embree.RunCache, got {cache!r}")
    path = os.path.abspath(os.fspath(path))
    xtf_path = None if xtf_path is None else os.path.abspath(os.fspath(xtf_path))
    _checked_args(block_pings, {"resume": resume, "overwrite": overwrite, "progress_bar": progress_bar},
                  simulate_kwargs)
    n = len(trajectory)
    block = int(min(block_pings, max(n, 1)))
    key = _fingerprint(scene, trajectory, sonar, pulse, simulate_kwargs | {"block_pings": block, "xtf": xtf_path,
                                                                           "xtf_samples": xtf_samples})
    _claim(path, overwrite)
    with folder_lock(path):
        progress = _resumed(path, key, xtf_path, resume, overwrite)
        simulate_kwargs = _one_clock(simulate_kwargs, trajectory, progress)
        try:
            args = (scene, trajectory, path, sonar, pulse, block, key, xtf_path, (xtf_scale, xtf_samples), progress,
                    progress_bar, simulate_kwargs)
            if _on_cluster(n, block, progress, workers, scheduler, client):
                _run_blocks_on_cluster(*args, (workers, scheduler, client))
            else:
                _run_blocks(*args, cache=cache)
        except OSError as exc:
            raise os_error_line(exc, exc.filename or path) from None
    if png_path is not None:
        Record.load(path).save_png(png_path, aspect=True, max_rows=PNG_MAX_ROWS)
    return path


#: The most rows of a streamed line's waterfall PNG (:func:`render_line`): longer lines average more pings a row.
PNG_MAX_ROWS = 8192


#: A line is rendered on worker processes by default from this many pings and blocks left, on a machine of this many
#: CPUs (render_line ``workers``). One process's threads saturate at 4–5× a single thread (issue 37's measurement
#: on 16 cores: 3.7× on 8). On 2 CPUs two workers, once running, beat two threads (310–343 against 248–258
#: pings/s speckle-free), but their start (cluster, scene, a BVH each) costs seconds, so a 3072-ping line is still
#: faster on threads (scripts/bench_scale.py, docs/benchmarks.md): below 8 CPUs threads stay the default.
AUTO_MIN_PINGS, AUTO_MIN_BLOCKS, AUTO_MIN_CPUS = 4096, 4, 8


def _checked_cluster(workers, scheduler, client, what: str = "render_line") -> None:
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer))
                                or workers < 1):
        raise ConfigError(f"{what}: workers must be an integer >= 1, got {workers!r}")
    if sum(x is not None for x in (workers, scheduler, client)) > 1:
        raise ConfigError(f"{what}: give one of workers, scheduler and client")


def _on_cluster(n: int, block: int, progress, workers, scheduler, client) -> bool:
    """Whether the blocks go to Dask workers (see render_line's ``workers``)."""
    if scheduler is not None or client is not None:
        return True
    if workers is not None:
        return workers > 1
    left = n - (0 if progress is None else progress["pings_done"])
    return (os.cpu_count() or 1) >= AUTO_MIN_CPUS and left >= AUTO_MIN_PINGS and -(-left // block) >= AUTO_MIN_BLOCKS


def render_block(scene, trajectory, sonar, pulse, first: int, simulate_kwargs: dict,
                 cache: RunCache | None = None) -> Record:
    """One block of a line (pings ``first`` … of the whole line): what a worker runs; the blocks of a line share
    ``cache`` (the scene's BVH is built once per process)."""
    return simulate(_block_scene(scene, trajectory, sonar), trajectory, sonar, pulse, ping_offset=first,
                    cache=cache, **simulate_kwargs)


def render_record(scene, trajectory, sonar=None, pulse=None, *, block_pings: int = 512, workers: int | None = None,
                  scheduler: str | None = None, client=None, **simulate_kwargs) -> Record:
    """What :func:`~sonar_embree.simulate` returns, rendered block by block on Dask worker processes.

    The one-shot counterpart of :func:`render_line` (``sonar-embree render --workers``): blocks of
    ``block_pings`` pings are simulated with their ``ping_offset`` on the workers and joined in ping order
    (:meth:`Record.concatenate`), so the data, labels and altitudes have the bits of one ``simulate`` call; only
    ``attrs["rays_per_ping"]``, a mean over blocks, may differ in its last digits. The whole record is held here.

    Parameters
    ----------
    scene, trajectory, sonar, pulse
        As :func:`~sonar_embree.simulate`.
    block_pings : int
        Pings per task.
    workers, scheduler, client
        One of: a LocalCluster of ``workers`` single-threaded processes (default: the CPU count, at most 8), a
        running scheduler's address, or a ``distributed.Client``.
    **simulate_kwargs
        As :func:`~sonar_embree.simulate` (not ``ping_offset``; ``progress`` shows a bar over the pings here).
    """
    _checked_cluster(workers, scheduler, client, "render_record")
    _checked_block(block_pings, "render_record")
    if "ping_offset" in simulate_kwargs:
        raise ConfigError("render_record: ping_offset is set per block here; render a piece with simulate()")
    bar = pings_bar(bool(simulate_kwargs.pop("progress", False)), len(trajectory))
    simulate_kwargs = _one_clock(simulate_kwargs, trajectory)
    n, block, parts = len(trajectory), int(block_pings), []
    try:
        with client_for(client, scheduler, workers, what="render_record") as c:
            shared, cache = c.scatter(scene, broadcast=True), c.scatter(RunCache(), broadcast=True)
            calls = ((a, (shared, trajectory[a:min(a + block, n)], sonar, pulse, a, simulate_kwargs, cache))
                     for a in range(0, n, block))
            for rec in in_order(c, render_block, calls, 2 * threads_of(c) + 1, "sonar-embree-render"):
                parts.append(rec)
                if bar is not None:
                    bar.update(rec.n_pings)
    finally:
        if bar is not None:
            bar.close()
    return Record.concatenate(parts)


def _run_blocks_on_cluster(scene, trajectory, path, sonar, pulse, block, key, xtf_path, xtf_opts, progress, bar,
                           simulate_kwargs, cluster) -> None:
    """The blocks on Dask workers (:mod:`sonar_embree.survey.cluster`), written here in ping order as they come."""
    n = len(trajectory)
    starts = range(0 if progress is None else progress["pings_done"], n, block)
    workers, scheduler, client = cluster
    with client_for(client, scheduler, workers, what="render_line") as c:
        shared, cache = c.scatter(scene, broadcast=True), c.scatter(RunCache(), broadcast=True)
        calls = ((a, (shared, trajectory[a:min(a + block, n)], sonar, pulse, a, simulate_kwargs, cache))
                 for a in starts)
        records = in_order(c, render_block, calls, 2 * threads_of(c) + 1, f"sonar-embree-line-{key[:10]}")
        _write_blocks(zip(starts, records), path, trajectory, block, key, xtf_path, xtf_opts, progress, bar)


def _run_blocks(scene, trajectory, path, sonar, pulse, block, key, xtf_path, xtf_opts, progress, bar,
                simulate_kwargs, cache: RunCache | None = None) -> None:
    """The blocks in this process, one after the other, sharing ``cache`` (default a new one)."""
    n = len(trajectory)
    starts = range(0 if progress is None else progress["pings_done"], n, block)
    cache = RunCache() if cache is None else cache
    records = (render_block(scene, trajectory[a:min(a + block, n)], sonar, pulse, a, simulate_kwargs, cache)
               for a in starts)
    _write_blocks(zip(starts, records), path, trajectory, block, key, xtf_path, xtf_opts, progress, bar)


def _write_blocks(blocks, path, line, block, key, xtf_path, xtf_opts, progress, bar) -> None:
    """Write each (first ping, record) of ``blocks`` of the trajectory ``line`` in turn (the store started with the
    first), counting them."""
    n = len(line)
    first = 0 if progress is None else progress["pings_done"]
    bar = pings_bar(bar, n, first)
    t_prev = time.perf_counter()
    for a, rec in blocks:
        b = a + rec.n_pings
        if progress is None:
            progress = _start(path, rec, n, block, key, xtf_path, xtf_opts)
        _write_block(path, rec, a, progress, xtf_path, line)
        if bar is not None:
            bar.update(b - a)
        now = time.perf_counter()
        if a == first + block and b < n:           # the second block sets the pace (the first's has the set-up)
            log.info("render_line: about %.0f s for the %d pings left (%.1f ms per ping in the second block, "
                     "written)", time_estimate_s(0.0, b, n, (now - t_prev) / (b - a)), n - b,
                     1e3 * (now - t_prev) / (b - a))
        t_prev = now
    if bar is not None:
        bar.close()


def _block_scene(scene, block, sonar):
    """The scene of a block: a :class:`~sonar_embree.TiledDEM`'s tiles within reach of its pings (kept while
    the next blocks need the same tiles), else the scene itself."""
    if not isinstance(scene, TiledDEM):
        return scene

    return scene.scene_around(block.positions_m, tile_reach_m(sonar or Sonar()))
