"""Waterfall images of a :class:`~sonar_embree.record.Record` (the one display module).

Rows are pings (first ping at the top); the port channel is mirrored on the left so
that range grows outwards from the centre line, starboard is on the right.
"""
from __future__ import annotations

import numpy as np

from .errors import ConfigError


def to_ground_range(intensity, slant_range_m, altitude_m, n_columns=None):
    """Resample (n_pings, n_samples) slant-range data onto a common ground-range grid.

    Ground range x = √(R² − h²) with the per-ping altitude h. Samples nearer than the
    altitude, pings without altitude (NaN) and grid points beyond the record are 0.

    Returns
    -------
    ground_m : (n_columns,) float
        Ground range of each column, m.
    image : (n_pings, n_columns) float
    """
    r = np.asarray(slant_range_m)
    n_cols = n_columns or r.shape[0]
    h = np.asarray(altitude_m, dtype=np.float64)
    hmin = np.nanmin(h) if np.any(np.isfinite(h)) else 0.0
    xmax = np.sqrt(max(r[-1] ** 2 - hmin ** 2, 0.0))
    ground = np.linspace(0.0, xmax, n_cols)
    out = np.zeros((intensity.shape[0], n_cols))
    for i in range(intensity.shape[0]):
        if not np.isfinite(h[i]):
            continue
        rr = np.sqrt(ground ** 2 + h[i] ** 2)
        out[i] = np.interp(rr, r, intensity[i], left=0.0, right=0.0)
    return ground, out


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
                    max_columns: int | None = 1024, floor_headroom_db: float = 12.0):
    """An 8-bit grey waterfall of both channels.

    Parameters
    ----------
    record : Record
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
        (skipped when the record has TVG already, ``attrs["tvg"]``).
    reference_percentile : float
        Percentile of the positive intensities that maps to white ...
    floor_headroom_db : float
        ... unless the median positive intensity (the floor) lies closer to it than
        this: then white is this many dB above the median, so that a scene without
        highlights is shown grey rather than clipped.
    max_columns : int or None
        Most columns per side; longer records are averaged (in intensity) over
        blocks of whole samples. None keeps one column per sample.

    Returns
    -------
    (n_pings, 2·n_columns) uint8
    """
    check_display(scale, dynamic_range_db, gamma, reference_percentile, max_columns)
    r = record.slant_range_m
    sides = [np.asarray(record.channel(ch), dtype=np.float64) for ch in record.channels]
    if tvg and not record.attrs.get("tvg", False):
        with np.errstate(divide="ignore"):  # in decades, then rescaled: no overflow for any absorption
            decades = 4.0 * np.log10(r) + 2.0 * record.sonar.alpha_db_per_m * r / 10.0
        gain = 10.0 ** (decades - decades[np.isfinite(decades)].max(initial=0.0))
        sides = [s * gain for s in sides]
    if ground_range:
        sides = [to_ground_range(s, r, record.altitude_m)[1] for s in sides]
    sides = [block_mean(s, waterfall_block(s.shape[1], max_columns)) for s in sides]
    both = np.concatenate(sides, axis=1)
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
    img = np.round(255.0 * v).astype(np.uint8)
    n = sides[0].shape[1]
    if tuple(record.channels) != ("port", "starboard"):
        return img  # other sonar types: the channels side by side, near range on the left
    return np.concatenate([img[:, :n][:, ::-1], img[:, n:]], axis=1)
