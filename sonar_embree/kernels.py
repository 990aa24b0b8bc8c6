"""Numba kernels: array in, array out, into buffers the caller allocated.

The only module that imports numba. Kernels read no globals, allocate nothing,
draw no random numbers and skip (never wrap) indices outside the buffer. Each has
a naive NumPy twin in ``tests/naive.py``. Compiled code is cached on disk.
"""
from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def lambert_intensity(range_m, cos_inc, gamma, d_omega, mu, two_way_np_per_m, min_range_m, out):
    """Expected echo intensity of each ray on a Lambertian surface (PHYSICS.md §3).

    w = Γ⁴ · μ · cos θi · exp(−2α'R) · dΩ / R², with R bounded below by ``min_range_m``.

    Parameters
    ----------
    range_m : (n,) float64
        Slant range of the hit, m.
    cos_inc : (n,) float64
        cos θi; rays with cos θi ≤ 0 get 0.
    gamma : (n,) float64
        One-way directivity Γ of the ray's direction.
    d_omega : (n,) float64
        Solid angle of the ray, sr.
    mu : (n,) float64
        Linear Lambert coefficient of the surface hit.
    two_way_np_per_m : float
        Two-way absorption in Np/m (2α·ln10/10 for α in dB/m); 0 for none.
    min_range_m : float
        Lower bound on R (near-field guard).
    out : (n,) float64
        Written with the intensities (unit source: on-axis intensity 1 at 1 m).
    """
    for i in range(range_m.shape[0]):
        c = cos_inc[i]
        r = range_m[i]
        if not (c > 0.0) or not (r < math.inf):
            out[i] = 0.0
            continue
        if r < min_range_m:
            r = min_range_m
        g2 = gamma[i] * gamma[i]
        out[i] = g2 * g2 * mu[i] * c * math.exp(-two_way_np_per_m * range_m[i]) * d_omega[i] / (r * r)


@njit(cache=True, nogil=True)
def splat_linear(channel, delay_samples, weights, out):
    """Add each weight at a fractional sample position with linear interpolation weights.

    ``out[ch, j] += w·(1 − f)`` and ``out[ch, j + 1] += w·f`` with j = ⌊x⌋, f = x − j.
    Works for real or complex ``weights``/``out`` (coherent summation).

    Parameters
    ----------
    channel : (n,) int
        Row of ``out`` for each contribution (0 port, 1 starboard); others are skipped.
    delay_samples : (n,) float64
        Delay in samples from the first sample; NaN, negative or > n_samples − 1
        is skipped (nothing wraps around).
    weights : (n,) float64 or complex128
        Contribution of each ray.
    out : (n_channels, n_samples) float64 or complex128
        Accumulator, added to in place.
    """
    n_ch = out.shape[0]
    n = out.shape[1]
    for i in range(delay_samples.shape[0]):
        x = delay_samples[i]
        ch = channel[i]
        if not (x >= 0.0) or x > n - 1 or ch < 0 or ch >= n_ch:
            continue
        j = int(x)
        f = x - j
        w = weights[i]
        out[ch, j] += w * (1.0 - f)
        if j + 1 < n:
            out[ch, j + 1] += w * f
