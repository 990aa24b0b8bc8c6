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
import logging
import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..trajectory import Trajectory

log = logging.getLogger(__name__)

#: Most lines a plan may hold (a 1e7 m square at 1 m range would be six million; refused with its size).
MAX_LINES = 10_000
#: Most pings the trajectories of a plan may hold together (each ping's pose is some 100 bytes).
MAX_PINGS = 20_000_000


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
    crossing = _crossing_edges(p)
    if crossing is not None:
        i, j = crossing
        raise ConfigError(f"plan_lines: the polygon's edges {i} and {j} cross (it is self-intersecting); give its "
                          "vertices in order around its boundary")
    area = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    if abs(area) < 1e-9:
        raise ConfigError("plan_lines: the polygon has no area (its vertices lie on one line)")
    return p


def _crossing_edges(p: np.ndarray):
    """The first pair (i, j) of non-adjacent edges (edge i from vertex i to i + 1) that properly cross, or None."""
    a, b = p, np.roll(p, -1, axis=0)
    n = len(p)

    def orient(o, q, r):
        return np.sign((q[..., 0] - o[..., 0]) * (r[..., 1] - o[..., 1]) - (q[..., 1] - o[..., 1]) * (r[..., 0] - o[..., 0]))

    for i in range(n):
        j = np.arange(i + 2, n if i > 0 else n - 1)                  # not adjacent to edge i
        if j.size == 0:
            continue
        d1, d2 = orient(a[i], b[i], a[j]), orient(a[i], b[i], b[j])
        d3, d4 = orient(a[j], b[j], a[i]), orient(a[j], b[j], b[i])
        hit = (d1 * d2 < 0) & (d3 * d4 < 0)
        if hit.any():
            return i, int(j[np.argmax(hit)])
    return None


def _finite(where: str, name: str, value, lo: float, hi: float, lo_open: bool = False) -> float:
    """``value`` as a float within [lo, hi] (lo excluded when ``lo_open``), or a one-line error."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float, np.number)) and math.isfinite(value)
    if not ok or not (lo < value if lo_open else lo <= value) or value > hi:
        low = f"> {lo:g}" if lo_open else f">= {lo:g}"
        raise ConfigError(f"{where}: {name} must be a finite number {low} and <= {hi:g}, got {value!r}")
    return float(value)


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
    range_m = _finite("plan_lines", "range_m", range_m, 0.0, 1e5, lo_open=True)
    if isinstance(overlap, bool) or not (isinstance(overlap, (int, float)) and 0 <= overlap <= 0.9):
        raise ConfigError(f"plan_lines: overlap must lie in [0, 0.9], got {overlap!r}")
    run_in = range_m if run_in_m is None else _finite("plan_lines", "run_in_m", run_in_m, 0.0, 10.0 * range_m)
    if direction_deg is not None:
        direction_deg = _finite("plan_lines", "direction_deg", direction_deg, -360.0, 360.0)
    a = math.radians(_long_axis_deg(p) if direction_deg is None else direction_deg)
    along, across = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    v = p @ across
    width = float(np.ptp(v))
    n = max(1, math.ceil(width / (2.0 * range_m * (1.0 - overlap)) - 1e-9))
    if n > MAX_LINES:
        km = n * float(np.ptp(p @ along)) / 1e3
        raise ConfigError(f"plan_lines: {width:.6g} m across at range_m = {range_m:g} m needs {n} lines (some "
                          f"{km:.3g} km of track), beyond {MAX_LINES}; survey smaller polygons or a longer range")
    offsets = v.min() + (np.arange(n) + 0.5) * width / n
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
    speed_m_s = _finite("line_trajectories", "speed_m_s", speed_m_s, 0.0, 50.0, lo_open=True)
    ping_rate_hz = _finite("line_trajectories", "ping_rate_hz", ping_rate_hz, 0.0, 1000.0, lo_open=True)
    z_m = _finite("line_trajectories", "z_m", z_m, -12_000.0, 1e4)
    size = survey_size(lines, speed_m_s, ping_rate_hz)
    if size["pings"] > MAX_PINGS:
        raise ConfigError(f"line_trajectories: {size['lines']} lines of {size['km']:.4g} km at {speed_m_s:g} m/s and "
                          f"{ping_rate_hz:g} Hz make {size['pings']} pings ({size['hours']:.4g} h of survey), beyond "
                          f"{MAX_PINGS}; plan fewer lines or a lower ping rate")
    log.info("survey plan: %d lines, %.4g km, %d pings, %.3g h at %g m/s", size["lines"], size["km"], size["pings"],
             size["hours"], speed_m_s)
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


def survey_size(lines, speed_m_s: float, ping_rate_hz: float) -> dict:
    """What a plan costs before it is built: ``lines``, ``km`` of track, ``pings`` (as
    :func:`line_trajectories` makes them) and ``hours`` of survey (the turns excluded)."""
    lengths = np.array([ln.length_m for ln in lines], dtype=np.float64)
    pings = np.floor(lengths * ping_rate_hz / speed_m_s + 1e-9) + 1
    pings = pings[pings >= 2]
    return {"lines": int(pings.size), "km": float(lengths.sum() / 1e3), "pings": int(pings.sum()),
            "hours": float(lengths.sum() / speed_m_s / 3600.0)}
