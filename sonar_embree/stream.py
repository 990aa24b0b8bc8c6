"""Streaming a long line to disk in blocks of pings, with bounded memory and resume (docs/physics.md §17).

Each block of pings is simulated as :func:`~sonar_embree.simulate` would simulate those pings alone
(``ping_offset`` = its first ping: the same bits as an in-memory run of them), written into its region of a
Zarr store laid out for the whole line (the CF dataset of :meth:`Record.to_xarray`, one Zarr chunk per block)
and appended to an XTF file, and only then counted as done in the store's ``stream.json``. A killed run
started again with the same inputs continues at the first block not done (its partial writes are
overwritten; the XTF is cut back to the blocks done) and ends with the same bytes as a run never stopped;
different inputs are refused. The whole-line attributes (rays per ping, …) are the first block's.
"""
from __future__ import annotations

import hashlib
import json
import os

import numpy as np

from .errors import ConfigError

#: Name of the progress file inside the Zarr store.
PROGRESS = "stream.json"


def _fingerprint(scene, trajectory, sonar, pulse, kwargs) -> str:
    """A digest of everything that decides the output's bytes."""
    h = hashlib.sha256()
    if hasattr(scene, "fingerprint"):                               # a TiledDEM: its file and tiling
        h.update(scene.fingerprint().encode())
    for obj in getattr(scene, "objects", ()):
        h.update(obj.label.encode())
        h.update(np.ascontiguousarray(obj.vertices).tobytes())
        h.update(np.ascontiguousarray(obj.faces).tobytes())
        h.update(repr(obj.material).encode())
    for name in ("positions_m", "heading_deg", "pitch_deg", "roll_deg", "times_s", "velocity_m_s"):
        a = getattr(trajectory, name)
        h.update(b"none" if a is None else np.ascontiguousarray(a).tobytes())
    h.update(repr((trajectory.crs, trajectory.start_time, sonar, pulse, sorted(kwargs.items()))).encode())
    return h.hexdigest()


def _progress(path: str) -> dict | None:
    try:
        with open(os.path.join(path, PROGRESS)) as fh:
            return json.load(fh)
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: unreadable stream progress ({exc})") from None


def _save_progress(path: str, progress: dict) -> None:
    tmp = os.path.join(path, PROGRESS + ".tmp")
    with open(tmp, "w") as fh:
        json.dump(progress, fh, sort_keys=True)
    os.replace(tmp, os.path.join(path, PROGRESS))


def _template(ds, n_pings: int, block: int):
    """The whole line's dataset with lazy (dask) ping-long variables shaped like the block's ``ds``."""
    import dask.array as da
    import xarray as xr

    def whole(var):
        if "ping" not in var.dims:
            return var
        shape = tuple(n_pings if d == "ping" else ds.sizes[d] for d in var.dims)
        chunks = tuple(block if d == "ping" else ds.sizes[d] for d in var.dims)
        return xr.Variable(var.dims, da.zeros(shape, dtype=var.dtype, chunks=chunks), var.attrs)

    return xr.Dataset({k: whole(v) for k, v in ds.data_vars.items()},
                      coords={k: whole(v.variable) for k, v in ds.coords.items()}, attrs=ds.attrs)


def _start(path, first, n_pings, block, fingerprint, xtf_path, xtf_scale):
    """Create the store (metadata, sample coordinates) and the XTF header from the first block's record."""
    from .io.dataset import to_xarray
    from .io.xtf import xtf_bytes

    ds = to_xarray(first)
    encoding = {name: {"chunks": tuple(block if d == "ping" else ds.sizes[d] for d in var.dims)}
                for name, var in ds.data_vars.items()}
    _template(ds, n_pings, block).to_zarr(path, mode="w", zarr_format=2, consolidated=True, encoding=encoding,
                                          compute=False)
    progress = {"fingerprint": fingerprint, "pings_done": 0, "n_pings": n_pings, "block_pings": block,
                "xtf": None}
    if xtf_path is not None:
        scale = _scale_of(first, xtf_scale)                          # fixed by the first block for the line
        header, _ = xtf_bytes(first, scale=scale)
        with open(xtf_path, "wb") as fh:
            fh.write(header)
        progress["xtf"] = {"header_bytes": len(header), "scale": scale}
    _save_progress(path, progress)
    return progress


def _scale_of(record, scale) -> float:
    from .io.xtf import sample_scale

    return 1.0 if record.samples is not None else sample_scale(record, scale)


def _write_block(path, rec, a: int, progress: dict, xtf_path) -> None:
    """The block's pings into their Zarr region and onto the XTF; then counted as done."""
    from .io.dataset import to_xarray
    from .io.xtf import xtf_bytes

    ds = to_xarray(rec)
    ds = ds.drop_vars([n for n, v in ds.variables.items() if "ping" not in v.dims])
    ds.attrs = {}
    ds.to_zarr(path, region={"ping": slice(a, a + rec.n_pings)}, zarr_format=2)
    if xtf_path is not None:
        _, packets = xtf_bytes(rec, scale=progress["xtf"]["scale"], first_ping=a)
        with open(xtf_path, "r+b") as fh:
            fh.truncate(progress["xtf"]["header_bytes"] + a * (len(packets) // rec.n_pings))
            fh.seek(0, os.SEEK_END)
            fh.write(packets)
    progress["pings_done"] = a + rec.n_pings
    _save_progress(path, progress)


def render_line(scene, trajectory, path, sonar=None, pulse=None, *, block_pings: int = 512, xtf_path=None,
                xtf_scale="auto", resume: bool = True, progress_bar: bool = False, **simulate_kwargs) -> str:
    """Simulate ``trajectory`` block by block into a Zarr store at ``path`` (and an XTF file), memory bounded by
    one block.

    Parameters
    ----------
    scene, trajectory, sonar, pulse
        As for :func:`~sonar_embree.simulate` (a :class:`~sonar_embree.TiledDEM`: each block gets the tiles within
        reach of its pings, so memory follows the swath); every other keyword of it (speckle, labels, seed, …) goes through
        ``simulate_kwargs`` (not ``ping_offset``, set per block, nor ``keep_complex``).
    path : str or PathLike
        The Zarr store (``xarray.open_zarr`` opens it, lazily).
    block_pings : int
        Pings per block: one Zarr chunk each, and what is redone after a kill.
    xtf_path : str or PathLike, optional
        Also write an XTF file as the blocks come (float samples × a factor fixed by the first block for
        ``xtf_scale="auto"``, see :func:`sonar_embree.io.xtf.sample_scale`).
    resume : bool
        Continue a store left by a killed run with the same inputs (default); False starts over.

    Returns
    -------
    str
        ``path``.
    """
    from .simulate import progress_bar as pings_bar, simulate

    path = os.fspath(path)
    if not isinstance(block_pings, (int, np.integer)) or isinstance(block_pings, bool) or block_pings < 1:
        raise ConfigError(f"render_line: block_pings must be an integer >= 1, got {block_pings!r}")
    for key in ("ping_offset", "keep_complex"):
        if key in simulate_kwargs:
            raise ConfigError(f"render_line: {key} is not a streaming option")
    n = len(trajectory)
    key = _fingerprint(scene, trajectory, sonar, pulse, simulate_kwargs | {"block_pings": int(block_pings),
                                                                            "xtf": xtf_path is not None})
    progress = _progress(path) if resume and os.path.isdir(path) else None
    if progress is not None and progress.get("fingerprint") != key:
        raise ConfigError(f"{path}: holds a streamed line of other inputs; remove it or pass resume=False")
    if progress is not None and xtf_path is not None and not os.path.exists(xtf_path):
        progress = None                                              # the XTF is gone: start over
    bar = pings_bar(progress_bar, n, 0 if progress is None else progress["pings_done"])
    a = 0 if progress is None else progress["pings_done"]
    while a < n:
        b = min(a + int(block_pings), n)
        rec = simulate(_block_scene(scene, trajectory[a:b], sonar), trajectory[a:b], sonar, pulse, ping_offset=a,
                       **simulate_kwargs)
        if progress is None:
            progress = _start(path, rec, n, int(block_pings), key, xtf_path, xtf_scale)
        _write_block(path, rec, a, progress, xtf_path)
        if bar is not None:
            bar.update(b - a)
        a = b
    if bar is not None:
        bar.close()
    return path


def _block_scene(scene, block, sonar):
    """The scene of a block: a :class:`~sonar_embree.TiledDEM`'s tiles within reach of its pings (kept while
    the next blocks need the same tiles), else the scene itself."""
    from .scene import TiledDEM
    from .simulate import tile_reach_m

    if not isinstance(scene, TiledDEM):
        return scene
    from .config import Sonar

    return scene.scene_around(block.positions_m, tile_reach_m(sonar or Sonar()))
