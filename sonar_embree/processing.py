"""Signal processing after synthesis: pulse shaping by FFT convolution (PHYSICS.md §5)."""
from __future__ import annotations

import numpy as np
from scipy.signal import lfilter, oaconvolve

#: Kernels up to this many taps are applied directly (exact zeros stay zero); longer ones by FFT.
DIRECT_MAX_TAPS = 64


def convolve_time(x, kernel):
    """Causal convolution of every row of ``x`` with ``kernel``, truncated to the record.

    Parameters
    ----------
    x : (..., n_samples) float or complex
        Impulse trains (one row per ping and channel).
    kernel : (n_k,) float or complex
        Sampled pulse (starting at delay 0).

    Returns
    -------
    (..., n_samples)
        ``y[..., n] = Σ_k kernel[k] · x[..., n − k]``.
    """
    n = x.shape[-1]
    if x.size == 0:
        return x.copy()
    kernel = np.asarray(kernel)
    if kernel.shape[0] <= DIRECT_MAX_TAPS:
        return lfilter(kernel, [1.0], x, axis=-1)
    y = oaconvolve(x, np.reshape(kernel, (1,) * (x.ndim - 1) + (-1,)), mode="full", axes=-1)
    return np.ascontiguousarray(y[..., :n])


def absorption_np_per_m(absorption_db_per_m: float) -> float:
    """Two-way intensity absorption coefficient in Np/m: 10^(−2αR/10) = exp(−this·R)."""
    return 2.0 * absorption_db_per_m * np.log(10.0) / 10.0
