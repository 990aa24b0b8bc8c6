"""Back-end kernels, expected intensity: footprint splatting and table interpolation (docs/physics.md §3, §5)."""
from __future__ import annotations

import math

from ._numba import njit, prange


@njit(cache=True, nogil=True)
def splat_table(channel, delay_samples, amplitude, table, table_start, table_rate, out):
    """Add a tabulated waveform, scaled and delayed, for every contribution.

    ``out[ch, n] += a · h(n − x)`` for every sample n where the waveform h is defined,
    with h read from ``table`` by linear interpolation (exact fractional delay up to
    the table resolution; nothing is rounded to the sample grid).

    Parameters
    ----------
    channel : (n,) int
        Row of ``out`` for each contribution; others are skipped.
    delay_samples : (n,) float64
        Delay x of each contribution in samples; NaN and ±inf are skipped. Parts of
        the waveform outside the record are dropped (nothing wraps around).
    amplitude : (n,) float64 or complex128
        Scale a of each contribution.
    table : (m,) float64 or complex128
        h(u) at u = table_start + i / table_rate (samples), i = 0 … m − 1; zero outside.
    table_start : float
        u of the first table entry, in samples (0 for a causal pulse, −half-width
        for a centred interpolation kernel).
    table_rate : float
        Table entries per sample.
    out : (n_channels, n_samples) complex128 or float64
        Accumulator, added to in place.
    """
    n_ch = out.shape[0]
    for i in range(delay_samples.shape[0]):
        ch = channel[i]
        if ch < 0 or ch >= n_ch:
            continue
        _splat_one(out, ch, delay_samples[i], amplitude[i], table, table_start, table_rate)


@njit(cache=True, nogil=True, inline='always')
def _splat_one(out, ch, x, a, table, table_start, table_rate):
    """out[ch, k] += a·h(k − x) for every k the tabulated waveform h covers (see :func:`splat_table`).

    Takes the whole accumulator and a row index: a row view per call would touch the array's shared
    reference count, which the threads contend for (kernels/_numba.py).
    """
    if not (abs(x) < math.inf):
        return
    n = out.shape[1]
    m = table.shape[0]
    span = (m - 1) / table_rate
    lo = x + table_start
    first = int(math.ceil(lo))
    last = int(math.floor(lo + span))
    if first < 0:
        first = 0
    if last > n - 1:
        last = n - 1
    for k in range(first, last + 1):
        u = (k - lo) * table_rate
        j = int(u)
        if j >= m - 1:
            if j == m - 1:
                out[ch, k] += a * table[m - 1]
            continue
        f = u - j
        out[ch, k] += a * (table[j] * (1.0 - f) + table[j + 1] * f)


@njit(cache=True, nogil=True)
def _hat_integral(x):
    """∫_{−∞}^{x} max(0, 1 − |u|) du."""
    if x <= -1.0:
        return 0.0
    if x < 0.0:
        return 0.5 * (x + 1.0) * (x + 1.0)
    if x < 1.0:
        return 1.0 - 0.5 * (1.0 - x) * (1.0 - x)
    return 1.0


@njit(cache=True, nogil=True)
def _splat_box(row, x, width, w, n):
    """Add weight w spread uniformly over [x − width/2, x + width/2] (samples), linearly interpolated."""
    if not (w != 0.0) or not (abs(x) < math.inf):
        return
    if width < 1e-6:
        if x < 0.0 or x > n - 1:
            return
        j = int(x)
        f = x - j
        row[j] += w * (1.0 - f)
        if j + 1 < n:
            row[j + 1] += w * f
        return
    scale = w / width
    lo = max(x - 0.5 * width, 0.0)  # the part outside the record is dropped, as for a point echo
    hi = min(x + 0.5 * width, n - 1.0)
    if not (hi > lo):
        return
    first = int(math.floor(lo))
    last = min(int(math.floor(hi)) + 1, n - 1)
    for k in range(first, last + 1):
        row[k] += scale * (_hat_integral(hi - k) - _hat_integral(lo - k))


@njit(cache=True, nogil=True, parallel=True)
def splat_rows(ray_start, delay_s, width_s, weights, rate_hz, out):
    """Footprint splatting of every row of a block: each ray's weight spread over its delay interval.

    ``out[r, k] += w/W · ∫_{x−W/2}^{x+W/2} Λ(u − k) du`` (Λ the linear-interpolation
    hat), which conserves Σw for intervals inside the record, falls back to linear
    splatting for W → 0, and drops (never wraps) what lies outside the record.
    Rows are independent, so the result does not depend on the thread count.

    Parameters
    ----------
    ray_start : (rows + 1,) int64
        Rays of row r are ``ray_start[r] … ray_start[r + 1] − 1``.
    delay_s, width_s : (n,) float64
        Centre and width of each ray's delay interval, s (in samples with ``rate_hz`` = 1).
    weights : (n,) float64
        Echo of each ray (zero: skipped).
    rate_hz : float
        Sample rate: the delays are scaled to samples here, in the loop, rather than by two array products before
        it (the same bits).
    out : (rows, n_samples) float64
        Accumulator, added to in place.
    """
    n = out.shape[1]
    for r in prange(ray_start.shape[0] - 1):
        for i in range(ray_start[r], ray_start[r + 1]):
            _splat_box(out[r], delay_s[i] * rate_hz, width_s[i] * rate_hz, weights[i], n)
