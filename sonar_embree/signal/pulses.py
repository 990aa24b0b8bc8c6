"""Transmit waveforms and their envelopes (docs/physics.md §5)."""
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


def phase_offset_rad(pulse, carrier_hz: float, t_s):
    """Phase of the pulse relative to the carrier, θ(t) − 2π·f0·t, in rad (float64).

    θ(t) = 2π ∫₀ᵗ f(s) ds with f the instantaneous frequency:

    - CW: f = f0, offset 0;
    - linear FM: f = f_s + κt, κ = B/τ, f_s = f_c − B/2;
    - exponential chirp: f = f_s·κ^t. With ln κ = ln(f_e/f_s)/τ the phase is
      2π f_s·expm1(t·ln κ)/ln κ (2π f_s t when ln κ = 0); κ itself is never formed,
      so κ → 1, huge sweeps and very short pulses stay exact (docs/physics.md §5).

    Parameters
    ----------
    pulse : Pulse
    carrier_hz : float
        f0, the sonar's frequency (the baseband reference), Hz.
    t_s : (n,) float
        Time from the start of the pulse, s.
    """
    t = np.asarray(t_s, dtype=np.float64)
    if pulse.kind == "cw":
        return np.zeros_like(t)
    if pulse.kind == "lfm":
        fc = carrier_hz if pulse.center_hz is None else pulse.center_hz
        f_s = fc - 0.5 * pulse.bandwidth_hz
        kappa = pulse.bandwidth_hz / pulse.duration_s
        return 2.0 * np.pi * ((f_s - carrier_hz) * t + 0.5 * kappa * t * t)
    ln_k = math.log(pulse.f_stop_hz / pulse.f_start_hz) / pulse.duration_s
    if ln_k == 0.0:
        integral = t
    else:
        integral = np.expm1(t * ln_k) / ln_k
    return 2.0 * np.pi * (pulse.f_start_hz * integral - carrier_hz * t)


def instantaneous_frequency_hz(pulse, carrier_hz: float, t_s):
    """Instantaneous frequency f(t) of the pulse in Hz (docs/physics.md §5)."""
    t = np.asarray(t_s, dtype=np.float64)
    if pulse.kind == "cw":
        return np.full_like(t, float(carrier_hz))
    if pulse.kind == "lfm":
        fc = carrier_hz if pulse.center_hz is None else pulse.center_hz
        return fc - 0.5 * pulse.bandwidth_hz + pulse.bandwidth_hz / pulse.duration_s * t
    ln_k = math.log(pulse.f_stop_hz / pulse.f_start_hz) / pulse.duration_s
    return pulse.f_start_hz * np.exp(t * ln_k)


def complex_envelope(pulse, carrier_hz: float, t_s):
    """Complex baseband envelope p̃(t) = a(t)·e^(j(θ(t) − 2πf0 t)), 0 outside [0, τ).

    The transmitted signal is x(t) = Re{p̃(t)·e^(j2πf0 t)} = a(t)·cos θ(t); the
    untapered pulse has |p̃|² = 1 (docs/physics.md §3).
    """
    t = np.asarray(t_s, dtype=np.float64)
    a = envelope(pulse, t)
    return a * np.exp(1j * phase_offset_rad(pulse, carrier_hz, t))


def table_rate(pulse, carrier_hz: float, sample_rate_hz: float, minimum: int = 64) -> int:
    """Table entries per sample so that p̃ turns by ≤ 0.02 rad per entry (≥ ``minimum``)."""
    f_lo, f_hi = pulse.frequency_span_hz(carrier_hz)
    f_off = max(abs(f_lo - carrier_hz), abs(f_hi - carrier_hz))
    need = 2.0 * math.pi * f_off / (0.02 * sample_rate_hz)
    return int(max(minimum, math.ceil(need)))


def envelope_table(pulse, carrier_hz: float, sample_rate_hz: float, rate: int | None = None):
    """p̃ tabulated for :func:`sonar_embree.kernels.splat_table` (start 0).

    Returns
    -------
    table : (m,) complex128
        p̃(i / (rate·fs)), i = 0 … ceil(τ·fs·rate); the last entry is 0 (pulse end).
    rate : int
        Entries per sample.
    """
    rate = table_rate(pulse, carrier_hz, sample_rate_hz) if rate is None else int(rate)
    m = int(math.ceil(pulse.duration_s * sample_rate_hz * rate)) + 1
    t = np.arange(m) / (rate * sample_rate_hz)
    return complex_envelope(pulse, carrier_hz, t), rate


def replica(pulse, carrier_hz: float, sample_rate_hz: float):
    """The pulse's complex envelope sampled at the record rate, p̃(m/fs), m = 0 … (matched filter)."""
    m = int(math.ceil(pulse.duration_s * sample_rate_hz))
    t = np.arange(m) / sample_rate_hz
    r = complex_envelope(pulse, carrier_hz, t)
    nz = np.nonzero(r)[0]
    return r[: nz[-1] + 1] if nz.size else r[:1]


def passband_analytic(pulse, carrier_hz: float, rate_hz: float):
    """Analytic transmitted signal p̃(t)·e^(j2πf0 t) sampled at ``rate_hz`` (carrier synthesis)."""
    m = int(math.ceil(pulse.duration_s * rate_hz)) + 1
    t = np.arange(m) / rate_hz
    return complex_envelope(pulse, carrier_hz, t) * np.exp(2j * np.pi * ((carrier_hz * t) % 1.0))


def expected_kernel(pulse, carrier_hz: float, sample_rate_hz: float, matched_filter: bool,
                    oversample: int = 64):
    """Sample-cell averages of the detected intensity of a unit echo, for speckle-free mode.

    Without matched filtering this is :func:`intensity_kernel` (|p|², causal).
    With it, |q(t)|² of the matched-filter output q(t) = Σ_m p̃(t + m/fs)·p̃*(m/fs) / Σ|p̃|²
    (the record-rate correlator of :func:`sonar_embree.signal.processing.matched_filter` applied
    to a continuous unit echo at t = 0; q(0) = 1), which extends one pulse length before
    and after the echo time; see :func:`compressed_grid`.

    Returns
    -------
    kernel : (n_k,) float64
    lead : int
        Samples of the kernel before the echo time (0 without matched filter).
    """
    if not matched_filter:
        return intensity_kernel(pulse, sample_rate_hz, oversample), 0
    fs = float(sample_rate_hz)
    lead = int(math.ceil(pulse.duration_s * fs)) + 1
    q = compressed_grid(pulse, carrier_hz, fs, lead, oversample)  # (oversample, 2·lead + 1)
    return (np.abs(q) ** 2).mean(axis=0), lead


def compressed_grid(pulse, carrier_hz: float, sample_rate_hz: float, lead: int, oversample: int):
    """The matched-filter output q(t) of :func:`expected_kernel` on its sub-sample grid, by FFT.

    The grid t = (i − lead + f_k)/fs, i = 0 … 2·lead, f_k = (k + ½)/oversample − ½, is
    one correlation with the replica per sub-sample phase f_k: q[k, i] =
    Σ_m p̃((i − lead + m + f_k)/fs)·p̃*(m/fs) / Σ|p̃|². FFT correlation makes the set-up
    O(oversample·N log N) in the pulse's N = τ·fs samples, instead of O(oversample·N²).

    Returns
    -------
    (oversample, 2·lead + 1) complex128
    """
    from scipy.signal import fftconvolve

    fs = float(sample_rate_hz)
    rep = replica(pulse, carrier_hz, fs)
    m = rep.shape[0]
    f = (np.arange(oversample) + 0.5) / oversample - 0.5
    n = np.arange(2 * lead + m) - lead
    a = complex_envelope(pulse, carrier_hz, ((n[None, :] + f[:, None]) / fs).ravel()).reshape(oversample, -1)
    q = fftconvolve(a, np.conj(rep[::-1])[None, :], mode="valid", axes=1)
    return q / np.sum(np.abs(rep) ** 2)
