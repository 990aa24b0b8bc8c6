"""Survey planning: parallel side-scan lines over a polygon (docs/physics.md §15).

Each line images a swath of ± the range; adjacent lines are spaced so that their swaths overlap by at least
the requested share: n = ⌈W / (2R(1 − overlap))⌉ lines spread evenly over the polygon's width W across the
line direction, the outer ones half a spacing in from its edges. Every line is clipped to the polygon (a
concave polygon can cut one line into several) and run in and out by the range beyond it, so that its swath
reaches the polygon's corners; turns between lines are not surveyed, so each line is its own trajectory
(:func:`line_trajectories`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .errors import ConfigError


@dataclass(frozen=True)
class SurveyLine:
    """One straight survey line, world metres (x east, y north): from ``start_m`` to ``end_m`` (each (2,))."""

    start_m: tuple
    end_m: tuple

    @property
    def length_m(self) -> float:
        return float(math.dist(self.start_m, self.end_m))


def _polygon(polygon_m) -> np.ndarray:
    p = np.asarray(polygon_m, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3 or not np.all(np.isfinite(p)):
        raise ConfigError(f"plan_lines: the polygon must be at least 3 finite (x, y) vertices, got shape {p.shape}")
    if np.allclose(p[0], p[-1]):
        p = p[:-1]
    area = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    if abs(area) < 1e-9:
        raise ConfigError("plan_lines: the polygon has no area")
    return p


def _long_axis_deg(p: np.ndarray) -> float:
    """The direction (degrees from +x) along which the polygon is narrowest across: fewest, longest lines."""
    best = min(range(180), key=lambda a: np.ptp(p @ [-math.sin(math.radians(a)), math.cos(math.radians(a))]))
    return float(best)


def plan_lines(polygon_m, range_m: float, overlap: float = 0.2, direction_deg: float | None = None,
               run_in_m: float | None = None):
    """Parallel survey lines covering a polygon, alternating in direction (a lawnmower without its turns).

    Parameters
    ----------
    polygon_m : (k, 2) float
        The survey area's vertices, world metres.
    range_m : float
        The sonar's range (each line covers ± range_m across track).
    overlap : float
        The least share of a swath shared with the next line's, in [0, 0.9].
    direction_deg : float, optional
        Line direction, degrees counterclockwise from +x (east); default the one with the fewest lines.
    run_in_m : float, optional
        How far each line runs on before and after the polygon, m (default ``range_m``); pieces of one line that
        then overlap are joined.

    Returns
    -------
    list of SurveyLine
    """
    p = _polygon(polygon_m)
    if not (isinstance(range_m, (int, float)) and 0 < range_m < 1e5):
        raise ConfigError(f"plan_lines: range_m must be a positive range in m, got {range_m!r}")
    if not (isinstance(overlap, (int, float)) and 0 <= overlap <= 0.9):
        raise ConfigError(f"plan_lines: overlap must lie in [0, 0.9], got {overlap!r}")
    a = math.radians(_long_axis_deg(p) if direction_deg is None else float(direction_deg))
    along, across = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    v = p @ across
    width = float(np.ptp(v))
    n = max(1, math.ceil(width / (2.0 * range_m * (1.0 - overlap)) - 1e-9))
    offsets = v.min() + (np.arange(n) + 0.5) * width / n
    run_in = float(range_m if run_in_m is None else run_in_m)
    lines = []
    for k, off in enumerate(offsets):
        for s0, s1 in _joined([(a - run_in, b + run_in) for a, b in _chords(p, along, across, off)]):
            if k % 2:
                s0, s1 = s1, s0
            lines.append(SurveyLine(tuple(s0 * along + off * across), tuple(s1 * along + off * across)))
    return lines


def _joined(chords):
    """Overlapping (start, end) intervals, sorted by start, joined."""
    out = []
    for a, b in chords:
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def _chords(p: np.ndarray, along, across, off: float):
    """The (start, end) along-coordinates where the line ``across · x = off`` lies inside the polygon."""
    u, v = p @ along, p @ across
    u1, v1 = np.roll(u, -1), np.roll(v, -1)
    cross = (v - off) * (v1 - off) < 0
    cross |= (v == off) & (v1 > off) | (v1 == off) & (v > off)          # vertices on the line: count once
    t = (off - v[cross]) / (v1[cross] - v[cross])
    s = np.sort(u[cross] + t * (u1[cross] - u[cross]))
    return [(s[i], s[i + 1]) for i in range(0, len(s) - 1, 2) if s[i + 1] - s[i] > 1e-9]


def line_trajectories(lines, z_m: float, speed_m_s: float, ping_rate_hz: float, crs=None, start_time=None):
    """One :class:`~sonar_embree.Trajectory` per survey line at height ``z_m``, ``speed_m_s`` and a ping every
    1/``ping_rate_hz`` s (the last ping at or before the line's end; lines shorter than one ping's advance are
    left out); line k starts when line k − 1 ended (the turns take no time: they are not surveyed)."""
    from .trajectory import Trajectory

    if not (speed_m_s > 0 and ping_rate_hz > 0):
        raise ConfigError(f"line_trajectories: speed_m_s and ping_rate_hz must be > 0, got {speed_m_s}, {ping_rate_hz}")
    out, t0 = [], 0.0
    for line in lines:
        n = int(math.floor(line.length_m * ping_rate_hz / speed_m_s + 1e-9)) + 1
        if n < 2:                                                   # shorter than one ping's advance
            continue
        end = np.asarray(line.start_m) + (n - 1) * speed_m_s / ping_rate_hz * (
            np.subtract(line.end_m, line.start_m) / max(line.length_m, 1e-12))
        traj = Trajectory.line((*line.start_m, z_m), (*end, z_m), n, speed_m_s=speed_m_s)
        out.append(dataclasses.replace(traj, times_s=traj.times_s + t0, crs=crs, start_time=start_time))
        t0 += traj.times_s[-1] + 1.0 / ping_rate_hz
    return out
