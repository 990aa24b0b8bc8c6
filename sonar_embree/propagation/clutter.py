"""Discrete clutter's scatterers and their echoes (docs/physics.md §10c).

Each object with a :class:`~sonar_embree.laws.clutter.Clutter` gets a Poisson number of points per triangle
(density × area), uniform on the triangle (barycentric √u₁ sampling), each with its cross-section σ_k and a
frozen phase φ_k, drawn once per run (or once per scene and seed with a RunCache) from a stream keyed by (seed,
object): the same points in every block, worker and run. A ping hears each point in its beam (the main lobe and
three side lobes along track, :data:`AZIMUTH_NULLS`) that it sees (one occlusion ray each, from the front of its face
unless the object is two-sided) as a point target,

    w_k = σ_k·Γ⁴(u_k)·e^(−2α'R_k)/R_k⁴,   t_k = 2R_k/c,   a_k = √w_k·e^(j2π(φ_k − 2R_k/λ)),

Γ the side's one-way membrane pattern (docs/physics.md §2); direct, straight paths only (a sea surface or a
sound-speed profile leaves clutter on its direct path, with a warning), the sonar at its ping position.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .. import checks
from ..errors import ConfigError
from ..validation import warn_once
from .echoes import Echoes

#: The most scatterers one scene may hold, all objects together: drawing them takes about 240 bytes each at the peak
#: (positions, normals, strengths, phases, the faces' corners they are drawn from, the k-d tree), 2.4 GB here.
MAX_SCATTERERS = 10_000_000
#: Peak bytes per scatterer while a field is drawn (measured order of magnitude; the message's estimate).
BYTES_PER_SCATTERER = 240
#: Scatterers sit this far above their face, m, so that their own face never occludes them.
LIFT_M = 1e-4
#: Along-track span heard, in first-null direction cosines λ/lx: the main lobe and three side lobes each way
#: (Γ⁴ below −41 dB of the axis beyond).
AZIMUTH_NULLS = 4


@dataclass(frozen=True, eq=False)
class ClutterField:
    """The frozen scatterers of a compiled scene: positions (n, 3) in its local frame (m), σ (n,) m², phase (n,)
    cycles, the face normal (n, 3) and whether it scatters from behind (n,), with a k-d tree of the positions."""

    points: np.ndarray
    sigma: np.ndarray
    phase: np.ndarray
    normal: np.ndarray
    two_sided: np.ndarray
    tree: cKDTree


@dataclass(frozen=True, eq=False)
class PointEchoes:
    """The clutter echoes of a block: :class:`Echoes` (zero extent; ``point_m`` each scatterer, local frame), each
    one's phase ``cycles`` (φ_k − 2R/λ, in cycles) and, with a receiver array, each element's amplitude factor
    ``element_gain`` (n, elements) Γ(u_k)/Γ(u) (:func:`element_gains`; None: 1)."""

    echoes: Echoes
    cycles: np.ndarray
    element_gain: np.ndarray | None = None


def clutter_field(compiled, seed: int) -> ClutterField | None:
    """The scene's scatterers for ``seed`` (None without clutter), drawn once per run
    (:class:`~sonar_embree.propagation.prepared.PreparedRun`)."""
    if not compiled.clutter:
        return None
    return _draw(compiled, int(seed))


def _draw(compiled, seed: int) -> ClutterField:
    tri = compiled.vertices[compiled.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    parts, total = [], 0.0
    for o, c in enumerate(compiled.clutter):
        if c is None:
            continue
        faces = np.flatnonzero(compiled.face_object == o)
        expected = c.density_per_m2 * float(area[faces].sum())
        total += expected
        if total > MAX_SCATTERERS:
            raise ConfigError(f"Clutter on {compiled.labels[o]!r}: {total:.3g} scatterers in the scene "
                              f"(density_per_m2 = {c.density_per_m2:g} over {area[faces].sum():.4g} m²; about "
                              f"{total * BYTES_PER_SCATTERER / 1e9:.3g} GB) exceed {MAX_SCATTERERS:g}; lower the "
                              "density or the object's area")
        rng = np.random.default_rng([seed, 0xC1077E2, o])
        f = np.repeat(faces, rng.poisson(c.density_per_m2 * area[faces]))
        s, r2 = np.sqrt(rng.random(f.size)), rng.random(f.size)
        t = tri[f]
        p = ((1.0 - s)[:, None] * t[:, 0] + (s * (1.0 - r2))[:, None] * t[:, 1] + (s * r2)[:, None] * t[:, 2]
             + LIFT_M * compiled.face_normals[f])
        parts.append((p, c.draw(rng, f.size), rng.random(f.size), compiled.face_normals[f],
                      np.full(f.size, compiled.two_sided[o])))
    p, sig, ph, nrm, two = (np.concatenate(x) for x in zip(*parts))
    return ClutterField(p, sig, ph, nrm, two, cKDTree(p))


def check_clutter(compiled, sonar) -> None:
    """Refuse clutter for a sonar type other than the side-scan; warn that it keeps to direct, straight paths."""
    if not compiled.clutter:
        return
    checks.check_side_scan_only(sonar, "Clutter")
    env = sonar.environment
    if env.surface is not None or env.sound_speed is not None:
        warn_once("Clutter: its scatterers are heard on the direct, straight path only (no sea-surface bounces, "
                  "no refraction)")


def side_gamma(sonar, u_body: np.ndarray, side: float) -> np.ndarray:
    """Γ of the port (``side`` −1) or starboard (+1) beam (:attr:`~sonar_embree.config.Sonar.transducer`) for
    body-frame unit directions (n, 3)."""
    d = sonar.tilt_rad
    e_side = np.array([0.0, side, 0.0])
    bore = math.cos(d) * e_side + np.array([0.0, 0.0, math.sin(d)])
    e2 = -math.sin(d) * e_side + np.array([0.0, 0.0, math.cos(d)])
    return sonar.transducer.one_way(u_body[:, 0], u_body @ e2, u_body @ bore)


def clutter_echoes(field: ClutterField, sonar, caster, rot, pos_local, max_range_m: float,
                   two_way_np_per_m: float) -> PointEchoes:
    """The scatterers each ping of a block hears, port then starboard per ping (rows as :class:`Echoes`).

    Parameters
    ----------
    rot : (pings, 3, 3) float64
        Body-to-world rotations.
    pos_local : (pings, 3) float64
        Sonar positions in the scene's local frame, m.
    max_range_m : float
        The range searched, m.
    two_way_np_per_m : float
        2α' of the two-way absorption, Np/m.
    """
    rows, times, weights, cycles, points = [], [], [], [], []
    lam, c = sonar.wavelength_m, sonar.sound_speed_m_s
    for b in range(rot.shape[0]):
        idx = np.asarray(field.tree.query_ball_point(pos_local[b], max_range_m), dtype=np.int64)
        d = field.points[idx] - pos_local[b]
        r = np.linalg.norm(d, axis=1)
        near = np.abs(d @ rot[b][:, 0]) <= AZIMUTH_NULLS * lam / sonar.length_m * r
        idx, d, r = idx[near], d[near], r[near]
        u = d / np.maximum(r, 1e-12)[:, None]
        front = field.two_sided[idx] | (np.einsum("ij,ij->i", field.normal[idx], u) < 0.0)
        g = np.stack([side_gamma(sonar, u @ rot[b], s) for s in (-1.0, 1.0)])
        seen = front & (r > 0) & np.any(g != 0.0, axis=0)
        seen[seen] = ~caster.occluded(np.repeat(pos_local[b][None].astype(np.float32), seen.sum(), axis=0),
                                      np.ascontiguousarray(u[seen], dtype=np.float32),
                                      (r[seen] - 2.0 * LIFT_M).astype(np.float32))
        for ch in (0, 1):
            k = np.flatnonzero(seen & (g[ch] != 0.0))
            rows.append(np.full(k.size, 2 * b + ch))
            times.append(2.0 * r[k] / c)
            weights.append(field.sigma[idx[k]] * g[ch, k] ** 4 * np.exp(-two_way_np_per_m * r[k]) / r[k] ** 4)
            cycles.append((field.phase[idx[k]] - 2.0 * r[k] / lam) % 1.0)
            points.append(field.points[idx[k]])
    row = np.concatenate(rows)
    start = np.concatenate(([0], np.cumsum(np.bincount(row, minlength=2 * rot.shape[0])))).astype(np.int64)
    n = row.size
    e = Echoes(2, start, np.concatenate(times), np.zeros(n), np.concatenate(weights),
               np.concatenate(points).reshape(-1, 3), np.zeros(0, dtype=np.int32))
    return PointEchoes(e, np.concatenate(cycles))


def element_gains(points: PointEchoes, sonar, rot, pos_local, rx_local) -> PointEchoes:
    """``points`` with each element's amplitude factor Γ(u_k)/Γ(u): the element hears the scatterer with the side's
    pattern along its own direction u_k (body frame, from its place at the ping's time ``rx_local`` (pings,
    2·elements, 3), local m) instead of the transmitter's u (1 where Γ(u) is 0). Both the along-track and the
    elevation pattern (docs/physics.md §18a)."""
    e = points.echoes
    n_el = rx_local.shape[1] // 2
    row = np.repeat(np.arange(e.ray_start.shape[0] - 1), np.diff(e.ray_start))
    ping, ch = row // 2, row % 2
    side = np.where(ch == 0, -1.0, 1.0)
    body = lambda d: np.einsum("nij,ni->nj", rot[ping], d / np.linalg.norm(d, axis=-1, keepdims=True))
    g_tx = _gamma(sonar, body(e.point_m - pos_local[ping]), side)
    gain = np.ones((row.size, n_el))
    for k in range(n_el):
        g_k = _gamma(sonar, body(e.point_m - rx_local[ping, ch * n_el + k]), side)
        gain[:, k] = np.where(g_tx != 0.0, g_k / np.where(g_tx != 0.0, g_tx, 1.0), 1.0)
    return dataclasses.replace(points, element_gain=gain)


def _gamma(sonar, u_body, side) -> np.ndarray:
    """:func:`side_gamma` of directions (n, 3) each on its own side (n,) (−1 port, +1 starboard)."""
    out = np.zeros(u_body.shape[0])
    for s in (-1.0, 1.0):
        m = side == s
        if m.any():
            out[m] = side_gamma(sonar, u_body[m], s)
    return out


__all__ = ["AZIMUTH_NULLS", "ClutterField", "PointEchoes", "check_clutter", "clutter_echoes", "clutter_field",
           "element_gains", "side_gamma"]
