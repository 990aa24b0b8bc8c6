"""Interferometric side-scan: the angle of arrival from two receivers' phase difference (docs/physics.md §18b).

Two receivers a baseline b apart in the across-track plane hear an echo from the unit direction û with path
lengths differing by −b·û (the receiver the baseline points towards is nearer by b·û), so their complex baseband
signals (phase −2π·L/λ) differ in phase by

    Δφ = arg(z_b·z̄_0) = (2π/λ)·b·û = (2π/λ)·|b|·cos(θ + β),

θ the depression of û below the side's horizontal (outward) axis and β the baseline's elevation above it
(a vertical pair: β = 90°, Δφ = −(2π/λ)·|b|·sin θ). Δφ is known modulo 2π: it is unwrapped about the phase of a
reference depression (the transducer's tilt), which leaves an unambiguous sector of |Δ(cos(θ + β))| < λ/(2|b|)
around it. The cross product z_b·z̄_0 is averaged over a small window of samples and pings first (the standard
estimator; its phase noise falls as the coherence γ and the number of looks rise). Sources: Lurton, *An
Introduction to Underwater Acoustics*, 2nd ed., Springer, 2010, §8.3; G. Jin and D. Tang, "Uncertainties of
differential phase estimation associated with interferometric sonars", IEEE J. Oceanic Eng. 21(1), 53–63, 1996
(the phase-difference estimator and its variance).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import uniform_filter

from ..errors import ConfigError


def cross_spectrum(z0: np.ndarray, zb: np.ndarray, window=(1, 5)):
    """The window-averaged cross product of two receivers and their coherence.

    Parameters
    ----------
    z0, zb : (pings, samples) complex
        The reference receiver's and the baselined receiver's complex baseband.
    window : (int, int)
        Pings and samples averaged (a centred box; odd sizes keep the estimate centred).

    Returns
    -------
    cross : (pings, samples) complex
        ⟨z_b·z̄_0⟩ over the window; its angle is Δφ (rad).
    coherence : (pings, samples) float
        |⟨z_b·z̄_0⟩| / √(⟨|z_0|²⟩·⟨|z_b|²⟩) in [0, 1] (NaN where both are silent).
    """
    z0, zb = np.asarray(z0), np.asarray(zb)
    if z0.shape != zb.shape or z0.ndim != 2:
        raise ConfigError(f"cross_spectrum: two (pings, samples) arrays of one shape needed, got {z0.shape} and "
                          f"{zb.shape}")
    w = tuple(int(v) for v in window)
    if len(w) != 2 or min(w) < 1:
        raise ConfigError(f"cross_spectrum: window must be two sizes >= 1 (pings, samples), got {window!r}")
    x = zb * np.conj(z0)
    cross = uniform_filter(x.real, w, mode="nearest") + 1j * uniform_filter(x.imag, w, mode="nearest")
    p0 = uniform_filter(np.abs(z0) ** 2, w, mode="nearest")
    pb = uniform_filter(np.abs(zb) ** 2, w, mode="nearest")
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.abs(cross) / np.sqrt(p0 * pb)
    return cross, coherence


def baseline_geometry(offset0, offset_b):
    """(|b| in m, β in rad) of the baseline from receiver offset ``offset0`` to ``offset_b``, each (forward,
    outward, up) m in the side's frame (:class:`~sonar_embree.ReceiverArray`); a baseline with a component along
    track is refused (the method measures the angle in the across-track plane)."""
    b = np.asarray(offset_b, dtype=float) - np.asarray(offset0, dtype=float)
    length = float(np.hypot(b[1], b[2]))
    if length == 0.0 or abs(b[0]) > 1e-9 * max(length, 1.0):
        raise ConfigError(f"interferometry: the baseline {tuple(b)} m must lie across track (forward component 0, "
                          "outward or up not both 0)")
    return length, math.atan2(b[2], b[1])


def depression_angle(dphi, baseline_m: float, elevation_rad: float, wavelength_m: float, reference_rad: float):
    """θ (rad, below the side's horizontal) of phase differences ``dphi`` (rad, any shape).

    Δφ is unwrapped about the phase of the ``reference_rad`` depression, then θ = arccos(Δφ·λ/(2π|b|)) − β
    (the branch with θ + β in [0, π]); NaN where the unwrapped phase is beyond the baseline's reach.
    """
    k = 2.0 * math.pi * baseline_m / wavelength_m
    ref = k * math.cos(reference_rad + elevation_rad)
    unwrapped = ref + np.angle(np.exp(1j * (np.asarray(dphi) - ref)))
    c = unwrapped / k
    with np.errstate(invalid="ignore"):
        return np.where(np.abs(c) <= 1.0, np.arccos(np.clip(c, -1.0, 1.0)) - elevation_rad, np.nan)


__all__ = ["baseline_geometry", "cross_spectrum", "depression_angle"]
