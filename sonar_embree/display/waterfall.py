"""Waterfall images of a :class:`~sonar_embree.record.Record` (the one display module).

Rows are pings (first ping at the top); the port channel is mirrored on the left so
that range grows outwards from the centre line, starboard is on the right.
"""
from __future__ import annotations

import numpy as np

from ..errors import ConfigError


def to_ground_range(intensity, slant_range_m, altitude_m, n_columns=None, ground_m=None):
    """Resample (n_pings, n_samples) slant-range data onto a common ground-range grid.

    Ground range x = √(R² − h²) with the per-ping altitude h. Samples nearer than the
    altitude, pings without altitude (NaN) and grid points beyond the record are 0.
    ``ground_m``: the grid to use (default: 0 to the farthest ground range of the lowest altitude).

    Returns
    -------
    ground_m : (n_columns,) float
        Ground range of each column, m.
    image : (n_pings, n_columns) float
    """
    r = np.asarray(slant_range_m)
    h = np.asarray(altitude_m, dtype=np.float64)
    ground = ground_grid(r, h, n_columns) if ground_m is None else np.asarray(ground_m)
    n_cols = ground.shape[0]
    out = np.zeros((intensity.shape[0], n_cols))
    for i in range(intensity.shape[0]):
        if not np.isfinite(h[i]):
            continue
        rr = np.sqrt(ground ** 2 + h[i] ** 2)
        out[i] = np.interp(rr, r, intensity[i], left=0.0, right=0.0)
    return ground, out


def ground_grid(slant_range_m, altitude_m, n_columns=None) -> np.ndarray:
    """The ground-range grid of :func:`to_ground_range`: ``n_columns`` (default one per sample) from 0 to the
    farthest ground range at the lowest altitude, m."""
    r, h = np.asarray(slant_range_m), np.asarray(altitude_m, dtype=np.float64)
    hmin = np.nanmin(h) if np.any(np.isfinite(h)) else 0.0
    return np.linspace(0.0, np.sqrt(max(r[-1] ** 2 - hmin ** 2, 0.0)), n_columns or r.shape[0])


def block_mean(x, block: int):
    """Mean over consecutive blocks of ``block`` columns (the last block may be shorter)."""
    if block <= 1:
        return x
    n = x.shape[1]
    pad = (-n) % block
    xp = np.pad(x, ((0, 0), (0, pad)))
    counts = np.full(xp.shape[1] // block, float(block))
    counts[-1] = block - pad
    return xp.reshape(x.shape[0], -1, block).sum(axis=2) / counts


def waterfall_block(n_samples: int, max_columns: int | None) -> int:
    """Samples averaged into one waterfall column so that a side has at most ``max_columns`` (None: 1)."""
    if max_columns is None:
        return 1
    if max_columns < 1:
        raise ConfigError(f"waterfall max_columns must be >= 1, got {max_columns!r}")
    return int(np.ceil(n_samples / max_columns))


#: The display defaults of every waterfall (API, render, batch, demo): display TVG on, 35 dB shown,
#: white at the 99.99th percentile (the highlights) but at least FLOOR_HEADROOM_DB above the median
#: (the floor), so that a scene without highlights is grey, not clipped white.
DISPLAY_DEFAULTS = {"scale": "db", "dynamic_range_db": 35.0, "gamma": 0.5, "ground_range": False, "tvg": True,
                    "reference_percentile": 99.99, "floor_headroom_db": 12.0, "max_columns": 1024}


def check_display(scale: str = "db", dynamic_range_db: float = 35.0, gamma: float = 0.5,
                  reference_percentile: float = 99.99, max_columns: int | None = 1024,
                  floor_headroom_db: float = 12.0) -> None:
    """Raise a one-line :class:`ConfigError` for display settings :func:`waterfall_image` cannot use.

    Config readers call it before any work, so a bad ``[output]`` or ``[png]``
    value stops a run before it starts rather than after the simulation.
    """
    if scale not in ("db", "gamma"):
        raise ConfigError(f"waterfall scale must be 'db' or 'gamma', got {scale!r}")
    for name, value in (("dynamic_range_db", dynamic_range_db), ("gamma", gamma)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < float("inf"):
            raise ConfigError(f"waterfall {name} must be a number > 0, got {value!r}")
    if (isinstance(reference_percentile, bool) or not isinstance(reference_percentile, (int, float))
            or not 0 < reference_percentile <= 100):
        raise ConfigError(f"waterfall reference_percentile must be in (0, 100], got {reference_percentile!r}")
    if (isinstance(floor_headroom_db, bool) or not isinstance(floor_headroom_db, (int, float))
            or not 0 <= floor_headroom_db < float("inf")):
        raise ConfigError(f"waterfall floor_headroom_db must be a number >= 0, got {floor_headroom_db!r}")
    if max_columns is not None and (isinstance(max_columns, bool) or not isinstance(max_columns, int)
                                    or max_columns < 1):
        raise ConfigError(f"waterfall max_columns must be an integer >= 1, got {max_columns!r}")


def waterfall_image(record, scale: str = "db", dynamic_range_db: float = 35.0, gamma: float = 0.5,
                    ground_range: bool = False, tvg: bool = True, reference_percentile: float = 99.99,
                    max_columns: int | None = 1024, floor_headroom_db: float = 12.0, aspect: bool = False,
                    max_rows: int | None = None):
    """An 8-bit grey waterfall of both channels.

    Parameters
    ----------
    record : Record
        In memory, or opened lazily from a Zarr store (:meth:`Record.load`): the pings are read a block at a time.
    scale : {"db", "gamma"}
        "db": 10·log10 intensity over ``dynamic_range_db`` below the reference
        level; "gamma": (I / reference)^gamma.
    dynamic_range_db : float
        Displayed range for ``scale="db"``, dB.
    gamma : float
        Exponent for ``scale="gamma"``.
    ground_range : bool
        Resample to ground range using the per-ping altitude.
    tvg : bool
        Display-only range compensation by R⁴·10^(2αR/10), for viewing far range
        (skipped when the record has TVG already, ``attrs["tvg"]``). A record with a device's codes
        (``record.samples``, a :class:`~sonar_embree.Receiver`) is drawn from its codes (squared, so that dB are
        20·log10 of the code), as a viewer of its XTF draws it, without display TVG: its own gain law is in them.
    reference_percentile : float
        Percentile of the positive intensities that maps to white ...
    floor_headroom_db : float
        ... unless the median positive intensity (the floor) lies closer to it than
        this: then white is this many dB above the median, so that a scene without
        highlights is shown grey rather than clipped.
    max_columns : int or None
        Most columns per side; longer records are averaged (in intensity) over
        blocks of whole samples. None keeps one column per sample.
    aspect : bool
        Rows at the ground's aspect: a row stands for as much distance along track as a column across (the
        column's range step): pings closer than that are averaged (in intensity) in groups, pings farther apart
        are repeated. False: one row per ping.
    max_rows : int or None
        Most rows: more pings are averaged in groups (with ``aspect``, the groups grow and the aspect is kept as
        near as that allows). None: no limit.

    Returns
    -------
    (rows, 2·n_columns) uint8
        rows = n_pings without ``aspect`` or ``max_rows``.
    """
    check_display(scale, dynamic_range_db, gamma, reference_percentile, max_columns)
    if max_rows is not None and (isinstance(max_rows, bool) or not isinstance(max_rows, int) or max_rows < 1):
        raise ConfigError(f"waterfall max_rows must be an integer >= 1, got {max_rows!r}")
    group, repeat = _row_groups(record, max_columns, ground_range, aspect, max_rows)
    both, n = _reduced(record, tvg, ground_range, max_columns, group)
    pos = both[both > 0]
    ref = 1.0
    if pos.size:
        ref = max(np.percentile(pos, reference_percentile), np.median(pos) * 10.0 ** (floor_headroom_db / 10.0))
    if scale == "db":
        with np.errstate(divide="ignore"):
            db = 10.0 * np.log10(np.maximum(both, 0.0) / ref)
        v = np.clip(1.0 + db / dynamic_range_db, 0.0, 1.0)
    else:
        v = np.clip(np.maximum(both, 0.0) / ref, 0.0, 1.0) ** gamma
    img = np.repeat(np.round(255.0 * v).astype(np.uint8), repeat, axis=0)
    if tuple(record.channels) != ("port", "starboard"):
        return img  # other sonar types: the channels side by side, near range on the left
    return np.concatenate([img[:, :n][:, ::-1], img[:, n:]], axis=1)


#: Pings read at a time by :func:`waterfall_image` (a lazily opened record holds them in memory one block at a time).
PING_BLOCK = 1024


def _row_groups(record, max_columns, ground_range: bool, aspect: bool, max_rows):
    """(pings averaged per row, times each row is repeated) for :func:`waterfall_image`."""
    n_p = record.n_pings
    group, repeat = 1, 1
    if aspect and n_p > 1:
        xy = np.asarray(record.trajectory.positions_m)[:, :2]
        along = float(np.median(np.hypot(*np.diff(xy, axis=0).T)))
        r = record.slant_range_m
        if ground_range:
            r = ground_grid(r, record.altitude_m)
        width = (r[-1] - r[0]) / max(r.shape[0] - 1, 1) * waterfall_block(r.shape[0], max_columns)
        if along > 0.0:
            k = width / along
            group, repeat = (max(1, int(round(k))), 1) if k >= 1.0 else (1, max(1, int(round(1.0 / k))))
    if max_rows is not None and -(-n_p // group) * repeat > max_rows:
        repeat = max(1, max_rows // -(-n_p // group))               # fewer repeats first
        if -(-n_p // group) * repeat > max_rows:                    # still too many: average more pings a row
            group = -(-n_p // max_rows)
    return group, repeat


def _reduced(record, tvg: bool, ground_range: bool, max_columns, group: int):
    """The display's linear image, block of pings by block: display TVG, ground range, columns averaged over
    whole samples and rows over ``group`` pings; (rows, 2·n_columns) float64 and n_columns per side."""
    r = record.slant_range_m
    gain = None
    codes = record.samples is not None         # a device's codes carry its own gain law
    if tvg and not codes and not record.attrs.get("tvg", False):
        with np.errstate(divide="ignore"):  # in decades, then rescaled: no overflow for any absorption
            decades = 4.0 * np.log10(r) + 2.0 * record.acquisition.alpha_db_per_m * r / 10.0
        gain = 10.0 ** (decades - decades[np.isfinite(decades)].max(initial=0.0))
    altitude = np.asarray(record.altitude_m, dtype=np.float64)
    ground = ground_grid(r, altitude) if ground_range else None
    step = max(group, PING_BLOCK // group * group)
    rows = []
    for a in range(0, record.n_pings, step):
        b = min(a + step, record.n_pings)
        sides = ([np.asarray(record.samples[a:b, k], dtype=np.float64) ** 2 for k in range(len(record.channels))]
                 if codes else [np.asarray(record.channel(ch)[a:b], dtype=np.float64) for ch in record.channels])
        if gain is not None:
            sides = [s * gain for s in sides]
        if ground_range:
            sides = [to_ground_range(s, r, altitude[a:b], ground_m=ground)[1] for s in sides]
        sides = [block_mean(s, waterfall_block(s.shape[1], max_columns)) for s in sides]
        rows.append(_row_mean(np.concatenate(sides, axis=1), group))
    return np.concatenate(rows), sides[0].shape[1]


def _row_mean(x, group: int):
    """Mean over consecutive groups of ``group`` rows (the last may be shorter)."""
    return x if group <= 1 else block_mean(x.T, group).T
