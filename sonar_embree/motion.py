"""Attitude and heave jitter of the vehicle: first-order Gauss–Markov processes (docs/physics.md §16).

Each of yaw, pitch, roll and heave is a stationary Gaussian process of zero mean, standard deviation σ and
autocorrelation exp(−|Δt|/T) (the Ornstein–Uhlenbeck process; Gelb, *Applied Optimal Estimation*, MIT Press,
1974, §3.8, the usual model of a vehicle's attitude and heave disturbances), sampled exactly at the ping
times t_k, however irregular:

    x_0 = σ·ε_0,   x_k = ρ_k·x_(k−1) + σ·√(1 − ρ_k²)·ε_k,   ρ_k = exp(−(t_k − t_(k−1))/T),

with ε standard normal draws from a generator seeded by (seed, component): the same seed gives the same
series, bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .validation import check_number

#: Components and their stream tags (one generator per component: adding one leaves the others unchanged).
COMPONENTS = {"yaw_deg": 1, "pitch_deg": 2, "roll_deg": 3, "heave_m": 4}


@dataclass(frozen=True)
class Motion:
    """RMS attitude and heave jitter with one correlation time.

    Parameters
    ----------
    yaw_rms_deg, pitch_rms_deg, roll_rms_deg : float
        Standard deviations of the heading, pitch and roll jitter, degrees (pitch and roll below 30°).
    heave_rms_m : float
        Standard deviation of the vertical jitter, m.
    correlation_s : float
        Correlation time T of every component, s.
    """

    yaw_rms_deg: float = 0.0
    pitch_rms_deg: float = 0.0
    roll_rms_deg: float = 0.0
    heave_rms_m: float = 0.0
    correlation_s: float = 1.0

    def __post_init__(self):
        check_number("Motion", "yaw_rms_deg", self.yaw_rms_deg, lo=0.0, hi=90.0)
        for name in ("pitch_rms_deg", "roll_rms_deg"):
            check_number("Motion", name, getattr(self, name), lo=0.0, hi=30.0)
        check_number("Motion", "heave_rms_m", self.heave_rms_m, lo=0.0, hi=100.0)
        check_number("Motion", "correlation_s", self.correlation_s, positive=True, hi=1e6)

    def rms(self, component: str) -> float:
        """σ of ``component`` (a key of :data:`COMPONENTS`)."""
        return {"yaw_deg": self.yaw_rms_deg, "pitch_deg": self.pitch_rms_deg, "roll_deg": self.roll_rms_deg,
                "heave_m": self.heave_rms_m}[component]


def gauss_markov(times_s: np.ndarray, rms: float, correlation_s: float, rng: np.random.Generator) -> np.ndarray:
    """One stationary first-order Gauss–Markov series at ``times_s`` (n,), standard deviation ``rms``."""
    t = np.asarray(times_s, dtype=float)
    eps = rng.standard_normal(t.shape[0])
    rho = np.exp(-np.diff(t) / correlation_s)
    out = np.empty(t.shape[0])
    if t.shape[0]:
        out[0] = rms * eps[0]
    for k in range(1, t.shape[0]):  # a recursion; n is the ping count, at most a few million
        out[k] = rho[k - 1] * out[k - 1] + rms * np.sqrt(1.0 - rho[k - 1] ** 2) * eps[k]
    return out


def jitter(motion: Motion, times_s: np.ndarray, seed: int = 0) -> dict:
    """Every component's series at ``times_s`` (dict of (n,) arrays; zeros where its RMS is 0)."""
    out = {}
    for name, tag in COMPONENTS.items():
        sigma = motion.rms(name)
        if sigma == 0.0:
            out[name] = np.zeros(len(times_s))
            continue
        out[name] = gauss_markov(times_s, sigma, motion.correlation_s,
                                 np.random.default_rng([int(seed), 0x6D07, tag]))
    return out
