"""Sea-surface multipath by the image method, for a flat surface (docs/physics.md §13).

With S the sonar, S' its mirror image in the surface z = z_s and X a scattering
point, the four paths are S→X→S (2r, the direct echoes), S→X→S' and S'→X→S
(r + r', equal by reciprocity: one echo of twice the weight), and S'→X→S' (2r').
Every leg is checked for visibility in the real, unmirrored scene, carries the
membrane's Γ of its direction as the real transducer sees it, 1/r spreading and
absorption, and each bounce multiplies the intensity by |R_s|² (Rayleigh roughness,
:class:`~sonar_embree.environment.SeaSurface`). The scattering at X is bistatic
(σ(θi, θs, φ) of the object's law).

- S'→X→S': the side-scan fan cast from S' with the mirrored attitude (its rays that
  go down from S' are the real fan's upward rays after the bounce), so the fan's
  ray budget, footprints and laws apply unchanged.
- S→X→S': from every direct echo, the leg X → S' through the surface point P,
  its weight w = Γ²(u1)·Γ²(u2)·σ(θi, θs, φ)·e^(−α'(r + r'))·|R_s|²·dΩ/(r'²·cos θi) and
  its travel-time extent from the footprint's motion along the ray cell.
"""
from __future__ import annotations

import numpy as np

from . import kernels
from .echoes import Echoes, row_of, row_starts
from .fan import BlockEchoes, cast_block

#: Visibility rays start this far along their leg (m), off the surface they leave.
LEG_EPSILON_M = 1e-3


def mirror(pos: np.ndarray, z_s: float) -> np.ndarray:
    """Positions (n, 3) mirrored in the plane z = z_s (same frame as ``pos``)."""
    out = np.array(pos, dtype=np.float64)
    out[:, 2] = 2.0 * z_s - out[:, 2]
    return out


def mirror_pose(rot: np.ndarray, pos_local: np.ndarray, z_s_local: float):
    """The image transducer: attitude with world z negated (an improper rotation) and position 2z_s − z."""
    rot_i = rot.copy()
    rot_i[:, 2, :] *= -1.0
    return rot_i, mirror(pos_local, z_s_local)


def _below_top(caster, z: float) -> bool:
    """Whether a leg starting at height z (local) can be blocked at all: the scene reaches above it."""
    return float(caster.compiled.bounds_local[1, 2]) > z + LEG_EPSILON_M * 1e-3


def occluded(caster, origins: np.ndarray, dirs: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """True where something lies on the upward segment origin + t·dir, LEG_EPSILON_M < t < dist (local frame).

    Only the part of a leg below the top of the scene can be blocked: legs are cut there, and those left
    shorter than 2·LEG_EPSILON_M (a flat floor's, a sonar above everything) are not cast at all.
    """
    top = float(caster.compiled.bounds_local[1, 2])
    if origins.shape[0] == 0 or not _below_top(caster, origins[:, 2].min()):  # every leg starts on top
        return np.zeros(origins.shape[0], dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.where(dirs[:, 2] > 0, (top - origins[:, 2]) / dirs[:, 2], np.inf)
    length = np.minimum(dist - LEG_EPSILON_M, reach + LEG_EPSILON_M) - LEG_EPSILON_M
    out = np.zeros(origins.shape[0], dtype=bool)
    cast = np.flatnonzero(length > 0)
    if cast.size:
        org = origins[cast] + LEG_EPSILON_M * dirs[cast]
        out[cast] = caster.occluded(np.ascontiguousarray(org, dtype=np.float32),
                                    np.ascontiguousarray(dirs[cast], dtype=np.float32),
                                    np.ascontiguousarray(length[cast], dtype=np.float32))
    return out


def image_echoes(front, caster, rot, pos_local, z_s_local, max_range_m, clock) -> tuple[Echoes, BlockEchoes]:
    """S'→X→S': the fan cast from the image transducer, each echo × |R_s|⁴ and its real upward leg checked."""
    s, surf = front.sonar, front.sonar.environment.surface
    rot_i, pos_i = mirror_pose(rot, pos_local, z_s_local)
    blk = cast_block(caster, front.plan, rot_i, pos_i, front.two_way_np_per_m, max_range_m,
                     2.0 / s.sound_speed_m_s, want_points=True, timings=clock, frequency_hz=s.frequency_hz)
    w = blk.weight.copy()
    hit = np.flatnonzero(w > 0)
    ping = row_of(blk.ray_start)[hit] // 2
    d = blk.point_m[hit] - pos_i[ping]
    r = np.linalg.norm(d, axis=1)
    d /= r[:, None]
    w[hit] *= surf.reflection_intensity(np.abs(d[:, 2]), s.wavenumber_rad_m) ** 2
    t_p = (pos_i[ping, 2] - z_s_local) / np.abs(d[:, 2])           # image → surface = sonar → surface
    up = d * np.array([1.0, 1.0, -1.0])
    w[hit[occluded(caster, pos_local[ping], up, t_p)]] = 0.0
    return Echoes(2, blk.ray_start, blk.time_s, blk.extent_s, w, blk.point_m, np.zeros(0, np.int32)), blk


def ray_cells(blk: BlockEchoes, rays: np.ndarray):
    """Row and elevation cell width dβ (rad) of the rays ``rays`` of a side-scan block."""
    n_el = np.diff(blk.el_start)
    row = np.searchsorted(blk.ray_start, rays, side="right") - 1
    j = (rays - blk.ray_start[row]) % n_el[row]
    return row, blk.dbeta[blk.el_start[row] + j]


def bistatic_sigma(compiled, frequency_hz, prim, cos_i, cos_s, phi):
    """σ(θi, θs, φ) of each echo's object law (maps and texture are applied separately)."""
    out = np.zeros(prim.shape[0])
    obj = compiled.face_object[prim]
    for o in np.unique(obj):
        law = compiled.laws[o]
        law = law.at_frequency(frequency_hz) if hasattr(law, "at_frequency") else law
        k = obj == o
        out[k] = law.sigma(cos_i[k], cos_s[k], phi[k])
    return out


def mixed_echoes(front, caster, blk, rot, pos_local, z_s_local) -> Echoes:
    """S→X→S' and S'→X→S (one echo, twice the weight) from every valid direct echo of ``blk``."""
    s, plan, c = front.sonar, front.plan, caster.compiled
    keep = np.flatnonzero(np.isfinite(blk.range_m))
    row, dbeta = ray_cells(blk, keep)
    x, prim = blk.point_m[keep], blk.prim[keep]
    n = keep.shape[0]
    t, ext, w, cos_i, cos_s, phi, leg1, leg2 = (np.empty(n) for _ in range(8))
    v, u2 = np.empty((n, 3)), np.empty((n, 3))
    kernels.mixed_legs(x, blk.range_m[keep], row // 2, np.where(row % 2 == 1, 1.0, -1.0), dbeta, prim,
                       np.ascontiguousarray(rot, dtype=np.float64), pos_local, z_s_local, c.face_normals,
                       plan.beam, plan.ds, plan.min_range_m, front.two_way_np_per_m, plan.slope_cap_m_rad,
                       s.sound_speed_m_s, s.wavenumber_rad_m * s.environment.surface.wave_height_m, t, ext, w,
                       cos_i, cos_s, phi, v, leg1, u2, leg2)
    w *= bistatic_sigma(c, s.frequency_hz, prim, cos_i, cos_s, phi)
    for detail in (c.maps, c.textures):
        if detail is not None:
            detail.apply(c, prim, x, w)
    lit = np.flatnonzero(w > 0)                                 # only lit echoes need their legs checked
    blocked = np.zeros(lit.shape[0], dtype=bool)
    if n and _below_top(caster, x[:, 2].min()):                 # a flat floor's legs start on top: skip the gathers
        blocked |= occluded(caster, x[lit], v[lit], leg1[lit])
    if n and _below_top(caster, pos_local[:, 2].min()):
        blocked |= occluded(caster, pos_local[row[lit] // 2], u2[lit], leg2[lit])
    w[lit[blocked]] = 0.0
    return _scattered(blk, keep, t, ext, w, x)


def _scattered(blk, keep, time_s, ext, w, x) -> Echoes:
    """Echoes aligned with the rows of ``blk``, holding only the rays ``keep``."""
    start = row_starts(row_of(blk.ray_start)[keep], blk.ray_start.shape[0] - 1)
    return Echoes(2, start, time_s, ext, w, x, np.zeros(0, np.int32))


def merge(parts, points: bool) -> Echoes:
    """Echoes of the paths ``parts`` (direct, one bounce, two bounces), row by row, each tagged with its path.

    The hit points are kept when ``points`` (speckle, maps), the object ids when every part has them.
    """
    row = np.concatenate([row_of(e.ray_start) for e in parts])
    order = np.argsort(row, kind="stable")                      # stable: within a row, the parts in order
    start = row_starts(row, parts[0].ray_start.shape[0] - 1)

    def cat(name):
        return np.concatenate([getattr(e, name) for e in parts])[order]

    pts = cat("point_m") if points else np.zeros((0, 3))
    ids = cat("object_id") if all(e.object_id.shape[0] == e.weight.shape[0] for e in parts) else np.zeros(0, np.int32)
    path = np.concatenate([np.full(e.weight.shape[0], k, dtype=np.int8) for k, e in enumerate(parts)])[order]
    return Echoes(parts[0].n_channels, start, cat("travel_time_s"), cat("extent_s"), cat("weight"), pts, ids, path)
