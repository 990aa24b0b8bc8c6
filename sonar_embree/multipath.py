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

from . import beam
from .echoes import Echoes
from .fan import BlockEchoes, cast_block

#: Visibility rays start this far along their leg (m), off the surface they leave.
LEG_EPSILON_M = 1e-3


def mirror_pose(rot: np.ndarray, pos_local: np.ndarray, z_s_local: float):
    """The image transducer: attitude with world z negated (an improper rotation) and position 2z_s − z."""
    rot_i = rot.copy()
    rot_i[:, 2, :] *= -1.0
    pos_i = pos_local.copy()
    pos_i[:, 2] = 2.0 * z_s_local - pos_i[:, 2]
    return rot_i, pos_i


def ray_rows(ray_start: np.ndarray) -> np.ndarray:
    """Row index (channels·ping + channel) of every ray."""
    return np.repeat(np.arange(ray_start.shape[0] - 1), np.diff(ray_start))


def membrane_gain(sonar, rot_b: np.ndarray, side: np.ndarray, u_world: np.ndarray) -> np.ndarray:
    """Γ of the channel's membrane (side −1 port, +1 starboard) for world directions u (n, 3)."""
    e = np.einsum("nji,nj->ni", rot_b, u_world)  # body = rotᵀ·world: (forward, starboard, down)
    c, s = np.cos(sonar.tilt_rad), np.sin(sonar.tilt_rad)
    height = e[:, 2] * c - side * e[:, 1] * s     # cos ψ · sin(β − δ)
    bore = side * e[:, 1] * c + e[:, 2] * s       # cos ψ · cos(β − δ)
    return beam.directivity(e[:, 0], height, bore, sonar.wavenumber_rad_m, sonar.length_m, sonar.height_m)


def occluded(caster, origins: np.ndarray, dirs: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """True where something lies on the segment origin + t·dir, LEG_EPSILON_M < t < dist (local frame)."""
    if origins.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    org = origins + LEG_EPSILON_M * dirs
    prim, tfar = caster.cast_raw(np.ascontiguousarray(org, dtype=np.float32),
                                 np.ascontiguousarray(dirs, dtype=np.float32), float(dist.max()))
    return (prim >= 0) & (tfar.astype(np.float64) < dist - 2.0 * LEG_EPSILON_M)


def image_echoes(front, caster, rot, pos_local, z_s_local, max_range_m, clock) -> tuple[Echoes, BlockEchoes]:
    """S'→X→S': the fan cast from the image transducer, each echo × |R_s|⁴ and its real upward leg checked."""
    s, surf = front.sonar, front.sonar.environment.surface
    rot_i, pos_i = mirror_pose(rot, pos_local, z_s_local)
    blk = cast_block(caster, front.plan, rot_i, pos_i, front.two_way_np_per_m, max_range_m,
                     2.0 / s.sound_speed_m_s, want_points=True, timings=clock, frequency_hz=s.frequency_hz)
    w = blk.weight.copy()
    hit = np.flatnonzero(w > 0)
    ping = ray_rows(blk.ray_start)[hit] // 2
    d = blk.point_m[hit] - pos_i[ping]
    r = np.linalg.norm(d, axis=1)
    d /= r[:, None]
    w[hit] *= surf.reflection_intensity(np.abs(d[:, 2]), s.wavenumber_rad_m) ** 2
    t_p = (pos_i[ping, 2] - z_s_local) / np.abs(d[:, 2])           # image → surface = sonar → surface
    up = d * np.array([1.0, 1.0, -1.0])
    w[hit[occluded(caster, pos_local[ping], up, t_p)]] = 0.0
    return Echoes(2, blk.ray_start, blk.time_s, blk.extent_s, w, blk.point_m, np.zeros(0, np.int32)), blk


def ray_cells(blk: BlockEchoes, n_az: int):
    """Row and elevation cell width dβ (rad) of every ray of a side-scan block."""
    n_el = np.diff(blk.el_start)
    row = ray_rows(blk.ray_start)
    j = (np.arange(row.shape[0]) - blk.ray_start[row]) % n_el[row]
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


def _scattered_azimuth(n, u_in, v_out):
    """φ between the backscatter direction −u_in and v_out, both projected on the plane of normal n."""
    b = -u_in - np.sum(-u_in * n, axis=1)[:, None] * n
    t = v_out - np.sum(v_out * n, axis=1)[:, None] * n
    nb, nt = np.linalg.norm(b, axis=1), np.linalg.norm(t, axis=1)
    ok = (nb > 1e-12) & (nt > 1e-12)
    cos_phi = np.where(ok, np.sum(b * t, axis=1) / np.where(ok, nb * nt, 1.0), 1.0)
    return np.arccos(np.clip(cos_phi, -1.0, 1.0))


def mixed_echoes(front, caster, blk, rot, pos_local, z_s_local) -> Echoes:
    """S→X→S' and S'→X→S (one echo, twice the weight) from every valid direct echo of ``blk``."""
    s, plan, c = front.sonar, front.plan, caster.compiled
    keep = np.flatnonzero(np.isfinite(blk.range_m))
    row, dbeta = ray_cells(blk, plan.s.shape[0])
    row, dbeta = row[keep], dbeta[keep]
    ping, side = row // 2, np.where(row % 2 == 1, 1.0, -1.0)
    x, prim, r = blk.point_m[keep], blk.prim[keep], blk.range_m[keep]
    u1 = (x - pos_local[ping]) / r[:, None]
    img = pos_local[ping] * [1.0, 1.0, -1.0] + [0.0, 0.0, 2.0 * z_s_local]
    v = img - x
    r2 = np.linalg.norm(v, axis=1)
    v /= r2[:, None]                                           # X → S' (through P)
    lam = (z_s_local - x[:, 2]) / (img[:, 2] - x[:, 2])
    p = x + (lam * r2)[:, None] * v
    to_p = p - pos_local[ping]
    d_sp = np.linalg.norm(to_p, axis=1)
    u2 = to_p / d_sp[:, None]
    n = c.face_normals[prim] * -np.sign(np.sum(c.face_normals[prim] * u1, axis=1))[:, None]
    cos_i, cos_s = -np.sum(n * u1, axis=1), np.sum(n * v, axis=1)
    g1, g2 = membrane_gain(s, rot[ping], side, u1), membrane_gain(s, rot[ping], side, u2)
    sigma = bistatic_sigma(c, s.frequency_hz, prim, cos_i, cos_s, _scattered_azimuth(n, u1, v))
    rb2 = np.maximum(r2, plan.min_range_m)
    w = (2.0 * g1 ** 2 * g2 ** 2 * sigma * np.exp(-0.5 * front.two_way_np_per_m * (r + r2)) * plan.ds * dbeta
         / (rb2 ** 2 * cos_i) * s.environment.surface.reflection_intensity(np.abs(v[:, 2]), s.wavenumber_rad_m))
    for detail in (c.maps, c.textures):
        if detail is not None:
            detail.apply(c, prim, x, w)
    blocked = occluded(caster, x, v, lam * r2) | occluded(caster, pos_local[ping], u2, d_sp)
    w[blocked] = 0.0
    ext = _mixed_extent(front, rot[ping], side, u1, v, n, r, dbeta)
    return _scattered(blk, keep, (r + r2) / s.sound_speed_m_s, ext, w, x)


def _mixed_extent(front, rot_b, side, u1, v, n, r, dbeta):
    """Travel-time extent |d(r + r')/dβ|·dβ/c of each ray cell's footprint (capped like the direct one)."""
    e = np.einsum("nji,nj->ni", rot_b, u1)
    f_w = np.einsum("nij,nj->ni", rot_b, np.stack([np.zeros_like(r), -side * e[:, 2], side * e[:, 1]], axis=1))
    dx = r[:, None] * (f_w - u1 * (np.sum(n * f_w, axis=1) / np.sum(n * u1, axis=1))[:, None])
    slope = np.minimum(np.abs(np.sum((u1 - v) * dx, axis=1)), 2.0 * front.plan.slope_cap_m_rad)
    return slope * dbeta / front.sonar.sound_speed_m_s


def _scattered(blk, keep, time_s, ext, w, x) -> Echoes:
    """Echoes aligned with the rows of ``blk``, holding only the rays ``keep``."""
    counts = np.bincount(ray_rows(blk.ray_start)[keep], minlength=blk.ray_start.shape[0] - 1)
    start = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    return Echoes(2, start, time_s, ext, w, x, np.zeros(0, np.int32))


def merge(parts) -> Echoes:
    """Echoes of several paths, row by row (each row: the parts' echoes in order); object ids if all have them."""
    rows = parts[0].ray_start.shape[0] - 1
    row = np.concatenate([ray_rows(e.ray_start) for e in parts])
    src = np.concatenate([np.full(e.weight.shape[0], k) for k, e in enumerate(parts)])
    order = np.lexsort((src, row))
    start = np.concatenate(([0], np.cumsum(np.bincount(row, minlength=rows)))).astype(np.int64)

    def cat(name):
        return np.concatenate([getattr(e, name) for e in parts])[order]

    pts = cat("point_m") if all(e.point_m.shape[0] == e.weight.shape[0] for e in parts) else np.zeros((0, 3))
    ids = cat("object_id") if all(e.object_id.shape[0] == e.weight.shape[0] for e in parts) else np.zeros(0, np.int32)
    return Echoes(parts[0].n_channels, start, cat("travel_time_s"), cat("extent_s"), cat("weight"), pts, ids)
