"""Transmit waveforms and their envelopes (PHYSICS.md §5)."""
from __future__ import annotations

import math

import numpy as np

# 4-term Blackman–Harris coefficients (Harris 1978, −92 dB side lobes).
_BH4 = (0.35875, 0.48829, 0.14128, 0.01168)


def blackman_harris(u):
    """Full 4-term Blackman–Harris window on u ∈ [0, 1] (0 at the ends, 1 at u = ½)."""
    a0, a1, a2, a3 = _BH4
    x = 2.0 * np.pi * np.asarray(u, dtype=np.float64)
    return a0 - a1 * np.cos(x) + a2 * np.cos(2 * x) - a3 * np.cos(3 * x)


def flat_top_blackman_harris(x, taper: float):
    """Flat-top Blackman–Harris envelope on the normalised pulse time x = t/τ.

    Flat (1) in the middle; each flank is half of a 4-term Blackman–Harris window
    covering ``taper/2`` of the pulse; 0 outside [0, 1). ``taper = 0`` is a
    rectangle, ``taper = 1`` a full Blackman–Harris window. Never negative (unlike
    scipy's ``flattop``).

    Parameters
    ----------
    x : (n,) float
        Time over pulse length.
    taper : float
        Flank fraction in [0, 1].

    Returns
    -------
    (n,) float
        Envelope amplitude in [0, 1].
    """
    x = np.asarray(x, dtype=np.float64)
    w = np.where((x >= 0.0) & (x < 1.0), 1.0, 0.0)
    if taper > 0.0:
        half = 0.5 * taper
        rise = (x >= 0.0) & (x < half)
        fall = (x > 1.0 - half) & (x < 1.0)
        w = np.where(rise, blackman_harris(x / taper), w)
        w = np.where(fall, blackman_harris((x - (1.0 - taper)) / taper), w)
    return w


def envelope(pulse, t_s):
    """Real amplitude envelope a(t) of ``pulse`` at times ``t_s`` (s) from its start."""
    return flat_top_blackman_harris(np.asarray(t_s, dtype=np.float64) / pulse.duration_s, pulse.taper)


def intensity_kernel(pulse, sample_rate_hz: float, oversample: int = 64):
    """Sample-cell averages of the pulse intensity |p(t)|², for FFT convolution.

    h[k] = fs·∫ |p(t)|² dt over the cell [(k − ½)/fs, (k + ½)/fs], so Σh = fs·∫|p|²dt
    (energy kept) and the centroid is unbiased for any τ·fs, integer or not.

    Returns
    -------
    (n_k,) float
        Kernel, k = 0 … ceil(τ·fs).
    """
    fs = float(sample_rate_hz)
    n_k = int(math.ceil(pulse.duration_s * fs)) + 1
    sub = (np.arange(n_k * oversample) + 0.5) / oversample - 0.5  # in samples
    a = envelope(pulse, sub / fs)
    return (a * a).reshape(n_k, oversample).mean(axis=1)
