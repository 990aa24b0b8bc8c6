"""Signal processing between synthesis and the record (docs/physics.md §5).

Pulse shaping by convolution, matched filtering, detection of the carrier signal,
low-pass FIR filters, perfect TVG, receiver noise and the band-limited interpolation
kernel used for carrier synthesis. Arrays in, arrays out; the time axis is last.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import firwin, kaiserord, lfilter, oaconvolve
from scipy.special import i0

#: Kernels up to this many taps are applied directly (exact zeros stay zero); longer ones by FFT.
DIRECT_MAX_TAPS = 64


def convolve_time(x, kernel, lead: int = 0):
    """Convolution of every row of ``x`` with ``kernel``, truncated to the record.

    Parameters
    ----------
    x : (..., n_samples) float or complex
        Impulse trains (one row per ping and channel).
    kernel : (n_k,) float or complex
        Sampled waveform; ``kernel[lead]`` belongs to delay 0.
    lead : int
        Taps of the kernel before delay 0 (0: causal).

    Returns
    -------
    (..., n_samples)
        ``y[..., n] = Σ_k kernel[k] · x[..., n + lead − k]``.
    """
    n = x.shape[-1]
    if x.size == 0:
        return x.copy()
    kernel = np.asarray(kernel)
    if lead == 0 and kernel.shape[0] <= DIRECT_MAX_TAPS:
        return lfilter(kernel, [1.0], x, axis=-1)
    y = oaconvolve(x, np.reshape(kernel, (1,) * (x.ndim - 1) + (-1,)), mode="full", axes=-1)
    return np.ascontiguousarray(y[..., lead:lead + n])


def absorption_np_per_m(absorption_db_per_m: float) -> float:
    """Two-way intensity absorption coefficient in Np/m: 10^(−2αR/10) = exp(−this·R)."""
    return 2.0 * absorption_db_per_m * np.log(10.0) / 10.0


def matched_filter(x, replica):
    """Pulse compression: correlate every row with the replica, unit gain at the peak.

    y[n] = Σ_m x[n + m]·r*[m] / Σ_m |r[m]|², so an echo A·p̃(t − n₀/fs) gives
    y[n₀] ≈ A: the compressed peak sits at the echo's arrival time 2R/c.

    Parameters
    ----------
    x : (..., n_samples) complex
        Complex baseband record.
    replica : (m,) complex
        The pulse's complex envelope sampled at the record rate.

    Returns
    -------
    (..., n_samples) complex
    """
    r = np.asarray(replica)
    h = np.conj(r[::-1]) / np.sum(np.abs(r) ** 2)
    return convolve_time(x, h, lead=r.shape[0] - 1)


def lowpass_taps(cutoff_hz: float, rate_hz: float, transition_hz: float, attenuation_db: float = 80.0):
    """Linear-phase Kaiser-window low-pass FIR (odd length, centred) for ``rate_hz``."""
    nyq = 0.5 * rate_hz
    width = min(transition_hz, 2.0 * cutoff_hz, 2.0 * (nyq - cutoff_hz)) / nyq
    n, beta = kaiserord(attenuation_db, width)
    n += 1 - n % 2
    return firwin(n, cutoff_hz, window=("kaiser", beta), fs=rate_hz)


def lowpass(x, cutoff_hz: float, rate_hz: float, transition_hz: float | None = None):
    """Zero-phase (centred, linear-phase) low-pass FIR along the last axis; unit DC gain.

    ``transition_hz`` defaults to half the cut-off (bounded by the band edges).
    """
    taps = lowpass_taps(cutoff_hz, rate_hz, 0.5 * cutoff_hz if transition_hz is None else transition_hz)
    return convolve_time(x, taps, lead=taps.shape[0] // 2)


def analytic_baseband(x, carrier_hz: float, rate_hz: float, step: int = 1):
    """Coherent demodulation: analytic signal of the real carrier signal, mixed down by f0.

    x_a = x + j·H{x} (FFT Hilbert transform, zero-padded to twice the length so
    nothing wraps), then x̃(t) = x_a(t)·e^(−j2πf0 t). For x = Re{r̃·e^(j2πf0 t)}
    this returns r̃ (docs/physics.md §5), at every ``step``-th sample (only those are mixed).
    """
    n = x.shape[-1]
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    spec = np.fft.fft(x, nfft, axis=-1)
    h = np.zeros(nfft)
    h[0] = 1.0
    h[1:nfft // 2] = 2.0
    h[nfft // 2] = 1.0
    xa = np.fft.ifft(spec * h, axis=-1)[..., :n:step]
    t = np.arange(0, n, step) / rate_hz
    return xa * np.exp(-2j * np.pi * ((carrier_hz * t) % 1.0))


def square_law(x, carrier_hz: float, rate_hz: float, cutoff_hz: float | None = None):
    """Incoherent detection: 2·x² low-passed below the 2f0 term.

    For x = Re{r̃·e^(j2πf0 t)}, 2x² = |r̃|² + Re{r̃²·e^(j4πf0 t)}; the low-pass FIR
    (cut-off ``cutoff_hz``, default f0, transition f0/2) keeps |r̃|², the coherent
    intensity, so a steady tone gives the same level in both detections (the factor 2
    undoes the −3.01 dB of plain square-law detection).
    """
    cutoff = carrier_hz if cutoff_hz is None else cutoff_hz
    return lowpass(2.0 * x * x, cutoff, rate_hz, transition_hz=0.5 * carrier_hz)


def tvg_gain(time_s, sound_speed_m_s: float, alpha_db_per_m: float):
    """Perfect time-varying gain R⁴·10^(2αR/10) with R = c·t/2 (intensity factor)."""
    r = 0.5 * sound_speed_m_s * np.asarray(time_s, dtype=np.float64)
    return r ** 4 * 10.0 ** (2.0 * alpha_db_per_m * r / 10.0)


def complex_noise(rng, shape, variance: float):
    """Circular complex white Gaussian noise with E|n|² = ``variance``."""
    s = math.sqrt(0.5 * variance)
    return rng.normal(0.0, s, shape) + 1j * rng.normal(0.0, s, shape)


def band_taps(bandwidth_hz: float | None, rate_hz: float):
    """Complex-baseband taps of a receiver's band-pass of width ``bandwidth_hz`` centred on the carrier: a
    linear-phase Kaiser low-pass with cut-off B/2 and transition B/4 at the record rate, unit gain in the band, so
    its noise bandwidth rate·Σh² is B within 1 % (docs/physics.md §14). None (no filter) without a bandwidth or
    when B is no narrower than the record's band ``rate_hz``."""
    if bandwidth_hz is None or bandwidth_hz >= rate_hz:
        return None
    return lowpass_taps(0.5 * bandwidth_hz, rate_hz, 0.25 * bandwidth_hz)


def band_noise(rng, shape, variance: float, taps):
    """Circular complex Gaussian noise of density ``variance``/rate through the band-pass ``taps`` (None: white,
    E|n|² = ``variance``): white noise a filter length longer, convolved in full ("valid"), so every sample has
    the same statistics, E|n|² = variance·Σh² and neighbours correlated as the filter's autocorrelation."""
    if taps is None:
        return complex_noise(rng, shape, variance)
    m = taps.shape[0]
    w = complex_noise(rng, tuple(shape[:-1]) + (shape[-1] + m - 1,), variance)
    return oaconvolve(w, np.reshape(taps, (1,) * (len(shape) - 1) + (-1,)), mode="valid", axes=-1)


def sinc_interpolator(half_width: int = 8, rate: int = 512, beta: float = 8.0):
    """Kaiser-windowed sinc h(u) = sinc(u)·w(u/half_width) tabulated for band-limited splatting.

    Splatting an impulse with it (:func:`sonar_embree.kernels.splat_table`, start
    −half_width) gives the impulse delayed by any fraction of a sample, band-limited
    to below the Nyquist frequency: flat (≤ 1e-4) up to a quarter of the rate.

    Returns
    -------
    table : (2·half_width·rate + 1,) float64
    start : float
        −half_width (samples).
    rate : int
        Entries per sample.
    """
    u = np.arange(-half_width * rate, half_width * rate + 1) / rate
    w = i0(beta * np.sqrt(np.clip(1.0 - (u / half_width) ** 2, 0.0, None))) / i0(beta)
    return np.sinc(u) * w, -float(half_width), rate
