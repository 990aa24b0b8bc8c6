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

from ..errors import ConfigError
from ..validation import check_number

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


# ---------------------------------------------------------------------------------------------- navigation
def track_heading_deg(positions_m: np.ndarray, times_s: np.ndarray) -> np.ndarray:
    """Heading of the track over ground at each fix, degrees clockwise from north, in [0, 360).

    The direction of the horizontal velocity d(x, y)/dt by second-order differences (central inside, one-sided
    second-order at the ends; non-uniform times allowed): on a circle sampled at equal times the central
    difference is the tangent exactly. Fixes where the vehicle does not move take the nearest moving fix's
    heading; a track that never moves has none (ConfigError).

    Parameters
    ----------
    positions_m : (n, 3) float
        World positions, x east and y north, m.
    times_s : (n,) float
        Strictly increasing times, s.
    """
    if positions_m.shape[0] < 2:
        raise ConfigError("heading from the track needs at least two fixes; give heading_deg")
    v = np.gradient(positions_m[:, :2], times_s, axis=0, edge_order=2 if positions_m.shape[0] > 2 else 1)
    moving = np.hypot(v[:, 0], v[:, 1]) > 1e-6
    if not moving.any():
        raise ConfigError("heading from the track: the positions never move; give heading_deg")
    idx = np.flatnonzero(moving)
    nearest = idx[np.clip(np.searchsorted(idx, np.arange(v.shape[0])), 0, idx.size - 1)]
    v = v[nearest]
    return np.degrees(np.arctan2(v[:, 0], v[:, 1])) % 360.0


def interpolate_poses(times_s, positions_m, heading_deg, pitch_deg, roll_deg, velocity_m_s, at_s):
    """Poses at the times ``at_s`` (within [times_s[0], times_s[-1]]) from poses at ``times_s``.

    Positions by a shape-preserving piecewise cubic (PCHIP: no overshoot between fixes, a smooth track through
    them; Fritsch & Carlson, SIAM J. Numer. Anal. 17, 1980); heading along the shorter turn between fixes,
    pitch, roll and the velocity linearly. At the fixes' own times every pose is the fix's (to round-off).

    Returns
    -------
    (positions (m, 3), heading (m,), pitch (m,), roll (m,), velocity (m, 3) or None)
    """
    from scipy.interpolate import PchipInterpolator

    pos = PchipInterpolator(times_s, positions_m, axis=0)(at_s) if times_s.size > 1 else positions_m.copy()
    unwrapped = np.unwrap(heading_deg, period=360.0)

    def lin(y):
        return np.interp(at_s, times_s, y)

    vel = None if velocity_m_s is None else np.stack([lin(velocity_m_s[:, k]) for k in range(3)], axis=1)
    return pos, lin(unwrapped) % 360.0, lin(pitch_deg), lin(roll_deg), vel


def layback_positions(positions_m: np.ndarray, layback_m: float):
    """Positions and headings of a towed sensor ``layback_m`` behind each fix along the track already run.

    The sensor follows the ship's path: at a fix whose arc length along the horizontal track is S, it is at arc
    length S − L on the polyline through the fixes (before the first fix: back along the first leg), with that
    leg's direction as its heading. Heights are kept (the trajectory's z is the sensor's).

    Returns
    -------
    (positions (n, 3), heading (n,) degrees clockwise from north)
    """
    xy = positions_m[:, :2]
    leg = np.diff(xy, axis=0)
    length = np.hypot(leg[:, 0], leg[:, 1])
    keep = length > 1e-9
    if not keep.any():
        raise ConfigError("layback: the track never moves, so 'behind' has no direction")
    pts = np.concatenate([xy[:1], xy[1:][keep]])
    leg, length = leg[keep], length[keep]
    arc = np.concatenate([[0.0], np.cumsum(length)])
    s_fix = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    s = s_fix - np.asarray(layback_m, dtype=np.float64)
    i = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, leg.shape[0] - 1)
    unit = leg / length[:, None]
    out = positions_m.copy()
    out[:, :2] = pts[i] + (s - arc[i])[:, None] * unit[i]
    return out, np.degrees(np.arctan2(unit[i, 0], unit[i, 1])) % 360.0
