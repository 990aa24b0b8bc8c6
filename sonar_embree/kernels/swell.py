"""Front-end kernels, a swell: the bounced rays of the image fan and their one- and two-bounce paths.

The rays are cast by :mod:`sonar_embree.propagation.swell` (against the surface mesh, then through the scene); these
kernels do the per-ray arithmetic between and after the casts (docs/physics.md §13).
"""
from __future__ import annotations

import math

import numpy as np

from ._numba import njit, prange
from .multipath import _CHUNK, _azimuth, _rotation


@njit(cache=True, nogil=True, parallel=True)
def swell_launch(up_start, up, dirs, t1, prim_s, pos, surface_normals, eps, u_out, p_out, ur_out, org_out, dir_out):
    """The upward rays that reached the surface: launch direction, surface point and mirrored direction.

    Ray i = up[k] left the sonar of its row's ping along u (float32 ``dirs``, made float64) and hit the
    surface facet ``prim_s[i]`` (normal n_P) at t1: P = S + t1·u, u_r = u − 2(u·n_P)·n_P, and the
    bounced ray for the scene cast starts eps along u_r (float32).

    Parameters
    ----------
    up_start : (rows + 1,) int64
        Offsets of each row's entries in ``up`` (row = 2·ping + side).
    up : (m,) int64
        Image-fan ray of each entry.
    dirs : (n, 3) float32; t1 : (n,) float32; prim_s : (n,) int32
        Upward directions, surface distances (m) and surface triangles of the image fan's rays.
    pos : (pings, 3) float64
        Sonar positions, local frame, m.
    surface_normals : (f, 3) float64
        Face normals of the surface mesh.
    eps : float
        Offset of the bounced ray's origin along u_r, m.
    u_out, p_out, ur_out : (m, 3) float64; org_out, dir_out : (m, 3) float32
        Written.
    """
    for row in prange(up_start.shape[0] - 1):
        b = row // 2
        for k in range(up_start[row], up_start[row + 1]):
            i = up[k]
            q = prim_s[i]
            ux, uy, uz = np.float64(dirs[i, 0]), np.float64(dirs[i, 1]), np.float64(dirs[i, 2])
            nx, ny, nz = surface_normals[q, 0], surface_normals[q, 1], surface_normals[q, 2]
            un = 2.0 * (ux * nx + uy * ny + uz * nz)
            rx, ry, rz = ux - un * nx, uy - un * ny, uz - un * nz
            t = np.float64(t1[i])
            px, py, pz = pos[b, 0] + t * ux, pos[b, 1] + t * uy, pos[b, 2] + t * uz
            u_out[k, 0], u_out[k, 1], u_out[k, 2] = ux, uy, uz
            p_out[k, 0], p_out[k, 1], p_out[k, 2] = px, py, pz
            ur_out[k, 0], ur_out[k, 1], ur_out[k, 2] = rx, ry, rz
            org_out[k, 0], org_out[k, 1], org_out[k, 2] = px + eps * rx, py + eps * ry, pz + eps * rz
            dir_out[k, 0], dir_out[k, 1], dir_out[k, 2] = rx, ry, rz


@njit(cache=True, nogil=True)
def _footprint(m, side, cpsi, cb, sb, nx, ny, nz, ur, n_x, cos_i, big_r):
    """dX/dβ of a bounced ray, (3,) m/rad: ∂u/∂β = rot·(0, −side·cos ψ·sin β, cos ψ·cos β) mirrored in the facet
    (normal n), then carried to the plane of X (normal n_x) over the unfolded range R."""
    f1, f2 = -side * cpsi * sb, cpsi * cb
    fx, fy, fz = m[1] * f1 + m[2] * f2, m[4] * f1 + m[5] * f2, m[7] * f1 + m[8] * f2
    fn = 2.0 * (fx * nx + fy * ny + fz * nz)
    fx, fy, fz = fx - fn * nx, fy - fn * ny, fz - fn * nz
    k = (n_x[0] * fx + n_x[1] * fy + n_x[2] * fz) / max(cos_i, 1e-12)
    return big_r * (fx + ur[0] * k), big_r * (fy + ur[1] * k), big_r * (fz + ur[2] * k)


@njit(cache=True, nogil=True, parallel=True)
def swell_paths(fan, bounce, poses, face_normals, weighting, bistatic, out, layout):
    """The one- and two-bounce paths of every bounced ray, without the beam's gains, σ (but Lambert's, see ``mu_obj``),
    maps or the direct leg's visibility.

    A ray reached the scene at X = P + (eps + t2)·u_r (triangle ``prim``, normal n): unfolded range
    R = t1 + eps + t2 (the facet is a mirror: a straight ray from S's image), r = |X − S|, u_d = (X − S)/r,
    cos θi = −n·u_r, cos θs = −n·u_d, sin θg = |u·n_P| at the surface, |R_s|² = exp(−4(k·h_w)² sin²θg):

        S→P→X→P→S:  w2 = |R_s|⁴·e^(−α'R)·ds·dβ / max(R, R_min)²       (× σ(θi)/cos θi by the law)
                    t = 2R/c,  Δt = 2·min(|u_r·dX/dβ|, cap)·dβ/c
        S→P→X→S and S→X→P→S (one echo):
                    w1 = |R_s|²·e^(−α'(R + r)/2)·ds·dβ / (max(r, R_min)²·cos θi)
                    (× σ(θi, θs, φ) afterwards), t = (R + r)/c,  Δt = min(|(u_r + u_d)·dX/dβ|, 2·cap)·dβ/c

    The beam's gains (w2 × Γ²(u)·Γ_rx²(u), w1 × Γ²(u)·Γ_rx²(u_d) + Γ²(u_d)·Γ_rx²(u), u the launch direction from its
    fan cell) are multiplied in after this kernel (:func:`~sonar_embree.kernels.rays.weigh_pairs`, from u_d =
    −``out.leg``). w2 = 0 unless cos θi > 1e-9, w1 = 0 unless cos θs > 1e-9 too; rays not ``seen`` (S→P blocked),
    missing the scene or with R beyond ``max_range_m`` get w1 = w2 = 0, t = inf. As in
    :func:`~sonar_embree.kernels.multipath.mixed_legs`, the rays go in chunks, stage by stage.

    Parameters
    ----------
    fan : :data:`~sonar_embree.kernels.args.Fan`
        The image fan's azimuth sines and spacing, each elevation cell's cos β, sin β and width (rad), and the rows'
        elevation cells ``el_start`` (rows + 1,) (azimuth-major rays over a row's cells).
    bounce : :data:`~sonar_embree.kernels.args.Bounce`
        The bounced rays (:func:`swell_launch`'s u, p, ur; the scene cast's prim and t2, ``seen``), the surface
        mesh's normals and the origin offset eps (m).
    poses : :data:`~sonar_embree.kernels.args.Poses`
        Body-to-world rotations, sonar positions (local frame, m) and δ = 2·v_fwd/c of each ping.
    face_normals : (f, 3) float64
        The scene's normals.
    weighting : :data:`~sonar_embree.kernels.args.Weighting`
        Two-way absorption (Np/m), near-field bound R_min (m), the longest unfolded range R (m), the |dR/dβ| cap
        (m/rad) and 2/c (s/m).
    bistatic : :data:`~sonar_embree.kernels.args.Bistatic`
        k·h_w; Lambert's μ per object ``mu_obj`` when every object has Lambert's law and there are no maps or
        texture (then the one-bounce σ = μ·cos θi·cos θs is applied here, as
        :func:`sonar_embree.propagation.multipath.apply_bistatic` would: the weight × (μ·cos θi)·cos θs; empty: σ is
        left to the caller), ``face_object`` (f,) int32 and ``want_phi`` (write φ: an arccos per ray); ``z_s`` and
        ``want_legs`` not read.
    out : :data:`~sonar_embree.kernels.args.SwellOut`
        Written; ``leg`` = −u_d and ``r`` are the direct leg X → S for the visibility check.
    layout : (n, 5) float64 or (0, 5)
        Each launch ray's own s, cos β, sin β, dβ and ds (rays aimed at objects via the swell,
        :mod:`sonar_embree.propagation.swell`); no rows (``NO_LAYOUT``): the fan's grid.
    """
    up_start = bounce.up_start
    for row in prange(up_start.shape[0] - 1):
        sc = np.empty((_SW_ROWS, _CHUNK))   # per ray: which paths are lit and the terms of its weights
        carry = (-1, 0.0)                   # the launch azimuth and its cos ψ
        for c0 in range(up_start[row], up_start[row + 1], _CHUNK):
            c1 = min(c0 + _CHUNK, up_start[row + 1])
            carry = _swell_chunk(row, c0, c1, carry, fan, bounce, poses, face_normals, weighting, bistatic, out,
                                 layout, sc)


#: Rows of a chunk's scratch ``sc`` (:func:`swell_paths`): which paths are lit (0 none, 1 two bounces, 2 both), R,
#: e^(−α'R/2)·|R_s|², the launch cell's cos ψ, cos β, sin β, dβ, ds and dX/dβ (3).
_SW_LIT, _SW_R, _SW_HALF, _SW_CPSI, _SW_CB, _SW_SB, _SW_DB, _SW_DS, _SW_DX = 0, 1, 2, 3, 4, 5, 6, 7, 8
_SW_ROWS = 11


@njit(cache=True, nogil=True)  # one call per chunk of _CHUNK rays: its arrays' reference counts amortised
def _swell_chunk(row, c0, c1, carry, fan, bounce, poses, face_normals, weighting, bistatic, out, layout, sc):
    """Bounced rays c0 … c1 − 1 of a row of :func:`swell_paths`, in stages over the chunk; w1 and w2 are written
    without the beam's gains. The launch azimuth and its cos ψ carry from chunk to chunk (``carry``)."""
    b, side = row // 2, 1.0 if row % 2 == 1 else -1.0
    m = _rotation(poses.rot, b)
    _swell_init_stage(c0, c1, bounce, out, sc)
    _swell_hit_stage(c0, c1, bounce, face_normals, weighting, out, sc)
    carry = _swell_cell_stage(row, c0, c1, carry, fan, bounce, layout, sc)
    _swell_surface_stage(c0, c1, side, m, bounce, face_normals, weighting, bistatic, out, sc)
    _swell_leg_stage(c0, c1, b, poses, bounce, face_normals, out, sc)
    _swell_time_stage(c0, c1, bounce, weighting, out, sc)
    _swell_one_weight_stage(c0, c1, bounce, bistatic, weighting, out, sc)
    if bistatic.want_phi:
        _swell_phi_stage(c0, c1, bounce, face_normals, out, sc)
    return carry


@njit(cache=True, nogil=True)
def _swell_init_stage(c0, c1, bounce, out, sc):
    """A ray that returns nothing: unlit, w 0, t inf, cos θi = cos θs = 1, φ = r = 0, X at its surface
    point."""
    p = bounce.p
    for k in range(c0, c1):
        c = k - c0
        for q in range(_SW_LIT + 1):
            sc[q, c] = 0.0
        out.w1[k], out.w2[k], out.time1[k], out.time2[k] = 0.0, 0.0, math.inf, math.inf
        out.ext1[k], out.ext2[k] = 0.0, 0.0
        out.cos_i[k], out.cos_s[k], out.phi[k], out.r[k] = 1.0, 1.0, 0.0, 0.0
        out.x[k, 0], out.x[k, 1], out.x[k, 2] = p[k, 0], p[k, 1], p[k, 2]


@njit(cache=True, nogil=True)
def _swell_hit_stage(c0, c1, bounce, face_normals, weighting, out, sc):
    """X = P + (eps + t2)·u_r and cos θi = −n·u_r of each ray that reached the scene seen and within the window;
    lit (two bounces) where cos θi > 1e-9, R = t1 + eps + t2 kept."""
    up, t1, t2, prim, seen, p, ur = bounce.up, bounce.t1, bounce.t2, bounce.prim, bounce.seen, bounce.p, bounce.ur
    eps, x_out = bounce.eps, out.x
    for k in range(c0, c1):
        big_r = np.float64(t1[up[k]]) + eps + np.float64(t2[k])
        if prim[k] < 0 or not seen[k] > 0.0 or big_r > weighting.max_range_m:
            continue
        d = eps + np.float64(t2[k])
        x_out[k, 0], x_out[k, 1], x_out[k, 2] = p[k, 0] + d * ur[k, 0], p[k, 1] + d * ur[k, 1], p[k, 2] + d * ur[k, 2]
        q = prim[k]
        cos_i = -(face_normals[q, 0] * ur[k, 0] + face_normals[q, 1] * ur[k, 1] + face_normals[q, 2] * ur[k, 2])
        if cos_i > 1e-9:
            out.cos_i[k] = cos_i
            sc[_SW_LIT, k - c0], sc[_SW_R, k - c0] = 1.0, big_r


@njit(cache=True, nogil=True)
def _swell_cell_stage(row, c0, c1, carry, fan, bounce, layout, sc):
    """Each lit ray's launch cell (cos ψ, cos β, sin β, dβ, ds into ``sc``): from the fan grid (the mirror maps the
    image ray onto u), the azimuth carried on; or from each ray's own cell (``layout``, the rays aimed at objects)."""
    if layout.shape[0] > 0:
        up = bounce.up
        for k in range(c0, c1):
            if sc[_SW_LIT, k - c0] != 0.0:
                i = up[k]
                _put_swell_cell(sc, k - c0, (math.sqrt(1.0 - layout[i, 0] * layout[i, 0]), layout[i, 1], layout[i, 2],
                                             layout[i, 3], layout[i, 4]))
        return carry
    return _swell_grid_stage(row, c0, c1, carry, fan, bounce, sc)


@njit(cache=True, nogil=True)
def _swell_grid_stage(row, c0, c1, carry, fan, bounce, sc):
    """The launch cells on the fan's grid: the azimuth of each ray, divided only when it moves on; the fan's arrays
    taken once per chunk."""
    a_now, cpsi = carry
    s_az, ds, cos_beta, sin_beta, dbeta, el_start = fan
    up, ray_start = bounce.up, bounce.ray_start
    n_el = el_start[row + 1] - el_start[row]
    for k in range(c0, c1):
        if sc[_SW_LIT, k - c0] == 0.0:
            continue
        ray = up[k] - ray_start[row]
        a = a_now if 0 <= ray - a_now * n_el < n_el else ray // n_el      # the azimuth, divided when it moves on
        cell = el_start[row] + ray - a * n_el
        if a != a_now:
            a_now, cpsi = a, math.sqrt(1.0 - s_az[a] * s_az[a])
        _put_swell_cell(sc, k - c0, (cpsi, cos_beta[cell], sin_beta[cell], dbeta[cell], ds))
    return a_now, cpsi


@njit(cache=True, nogil=True, inline='always')
def _put_swell_cell(sc, c, cell):
    """Ray c's launch cell (cos ψ, cos β, sin β, dβ, ds) into ``sc``."""
    sc[_SW_CPSI, c], sc[_SW_CB, c], sc[_SW_SB, c], sc[_SW_DB, c], sc[_SW_DS, c] = cell


@njit(cache=True, nogil=True)
def _swell_surface_stage(c0, c1, side, m, bounce, face_normals, weighting, bistatic, out, sc):
    """Per lit ray, from its facet: e^(−α'R/2)·|R_s|² (|R_s|² = exp(−4(k·h_w)² sin²θg)) and dX/dβ
    (:func:`_footprint`) into ``sc``."""
    up, u, prim_s, prim, ur = bounce.up, bounce.u, bounce.prim_s, bounce.prim, bounce.ur
    normals = bounce.surface_normals
    two_way_np_per_m, wave_kh = weighting.two_way_np_per_m, bistatic.wave_kh
    for k in range(c0, c1):
        c = k - c0
        if sc[_SW_LIT, c] == 0.0:
            continue
        qs, q = prim_s[up[k]], prim[k]
        nx, ny, nz = normals[qs, 0], normals[qs, 1], normals[qs, 2]
        sg = u[k, 0] * nx + u[k, 1] * ny + u[k, 2] * nz
        sc[_SW_HALF, c] = math.exp(-0.5 * two_way_np_per_m * sc[_SW_R, c] - 4.0 * wave_kh * wave_kh * sg * sg)
        dx = _footprint(m, side, sc[_SW_CPSI, c], sc[_SW_CB, c], sc[_SW_SB, c], nx, ny, nz,
                        (ur[k, 0], ur[k, 1], ur[k, 2]), (face_normals[q, 0], face_normals[q, 1], face_normals[q, 2]),
                        out.cos_i[k], sc[_SW_R, c])
        sc[_SW_DX, c], sc[_SW_DX + 1, c], sc[_SW_DX + 2, c] = dx


@njit(cache=True, nogil=True)
def _swell_leg_stage(c0, c1, b, poses, bounce, face_normals, out, sc):
    """The direct leg X → S of each lit ray: −u_d, r = |X − S| and cos θs = −n·u_d (the one bounce lit where it
    exceeds 1e-9)."""
    pos, prim, x = poses.pos, bounce.prim, out.x
    for k in range(c0, c1):
        c = k - c0
        if sc[_SW_LIT, c] == 0.0:
            continue
        vx, vy, vz = x[k, 0] - pos[b, 0], x[k, 1] - pos[b, 1], x[k, 2] - pos[b, 2]
        r = math.sqrt(vx * vx + vy * vy + vz * vz)
        ir = 1.0 / r
        ud = (vx * ir, vy * ir, vz * ir)
        q = prim[k]
        cos_s = -(face_normals[q, 0] * ud[0] + face_normals[q, 1] * ud[1] + face_normals[q, 2] * ud[2])
        out.leg[k, 0], out.leg[k, 1], out.leg[k, 2], out.r[k], out.cos_s[k] = -ud[0], -ud[1], -ud[2], r, cos_s
        if cos_s > 1e-9:
            sc[_SW_LIT, c] = 2.0


@njit(cache=True, nogil=True)
def _swell_time_stage(c0, c1, bounce, weighting, out, sc):
    """Per lit ray: the two-bounce path S→P→X→P→S (w2 without the gains, t = 2R/c, Δt = 2·min(|u_r·dX/dβ|, cap)·dβ/c)
    and the one bounce's t = (R + r)/c and Δt = min(|(u_r + u_d)·dX/dβ|, 2·cap)·dβ/c."""
    ur, leg, inv_c, min_range_m = bounce.ur, out.leg, 0.5 * weighting.time_per_m, weighting.min_range_m
    cap = weighting.slope_cap_m_rad
    for k in range(c0, c1):
        c = k - c0
        if sc[_SW_LIT, c] == 0.0:
            continue
        big_r, half, db = sc[_SW_R, c], sc[_SW_HALF, c], sc[_SW_DB, c]
        dx0, dx1, dx2 = sc[_SW_DX, c], sc[_SW_DX + 1, c], sc[_SW_DX + 2, c]
        rb = max(big_r, min_range_m)
        out.w2[k] = half * half * sc[_SW_DS, c] * db / (rb * rb)
        slope = min(abs(ur[k, 0] * dx0 + ur[k, 1] * dx1 + ur[k, 2] * dx2), cap)
        out.time2[k], out.ext2[k] = 2.0 * big_r * inv_c, 2.0 * slope * db * inv_c
        out.time1[k] = (big_r + out.r[k]) * inv_c
        slope = abs((ur[k, 0] - leg[k, 0]) * dx0 + (ur[k, 1] - leg[k, 1]) * dx1 + (ur[k, 2] - leg[k, 2]) * dx2)
        out.ext1[k] = min(slope, 2.0 * cap) * db * inv_c


@njit(cache=True, nogil=True)
def _swell_one_weight_stage(c0, c1, bounce, bistatic, weighting, out, sc):
    """The one-bounce w1 without the gains (× Lambert's σ when it is applied here)."""
    prim, mu_obj, face_object = bounce.prim, bistatic.mu_obj, bistatic.face_object
    two_way_np_per_m, min_range_m = weighting.two_way_np_per_m, weighting.min_range_m
    for k in range(c0, c1):
        c = k - c0
        if sc[_SW_LIT, c] != 2.0:
            continue
        cos_i, cos_s, r = out.cos_i[k], out.cos_s[k], out.r[k]
        sigma = mu_obj[face_object[prim[k]]] * max(cos_i, 0.0) * max(cos_s, 0.0) if mu_obj.shape[0] > 0 else 1.0
        rb = max(r, min_range_m)
        out.w1[k] = sc[_SW_HALF, c] * math.exp(-0.5 * two_way_np_per_m * r) * sc[_SW_DS, c] * sc[_SW_DB, c] / (
            rb * rb * cos_i) * sigma


@njit(cache=True, nogil=True)
def _swell_phi_stage(c0, c1, bounce, face_normals, out, sc):
    """φ, the bistatic azimuth between −u_r and −u_d in the plane of n, where the one bounce is lit."""
    prim, ur, leg = bounce.prim, bounce.ur, out.leg
    for k in range(c0, c1):
        if sc[_SW_LIT, k - c0] == 2.0:
            q = prim[k]
            out.phi[k] = _azimuth((face_normals[q, 0], face_normals[q, 1], face_normals[q, 2]),
                                  (ur[k, 0], ur[k, 1], ur[k, 2]), (leg[k, 0], leg[k, 1], leg[k, 2]))


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _strip_hit(a_o, d_a, oz, dz, a0, a_step, z, t_lo, t_hi):
    """(t, ia) of the first crossing of the ray z = oz + t·dz, a = a_o + t·d_a (t_lo ≤ t ≤ t_hi) with the profile
    through (a0 + i·a_step, z[i]), linear between nodes; (inf, −1) without one. Strips are visited in the ray's
    order, so the first crossing found is the nearest."""
    na = z.shape[0]
    a_s = a_o + t_lo * d_a
    ia = min(max(int(math.floor((a_s - a0) / a_step)), 0), na - 2)
    step = 1 if d_a > 0.0 else -1
    while 0 <= ia <= na - 2:
        a_i = a0 + ia * a_step
        t0, t1 = t_lo, t_hi
        if d_a != 0.0:
            ta, tb = (a_i - a_o) / d_a, (a_i + a_step - a_o) / d_a
            t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
        if t0 > t_hi:
            break
        if t0 <= t1:
            slope = (z[ia + 1] - z[ia]) / a_step
            f1 = dz - d_a * slope
            if f1 != 0.0:
                t = -(oz - z[ia] - (a_o - a_i) * slope) / f1
                if t0 <= t <= t1:
                    return t, ia
        if d_a == 0.0:
            break
        ia += step
    return math.inf, -1


@njit(cache=True, nogil=True, parallel=True)
def swell_surface_hits(org, dirs, shift, k, a0, a_step, z, b0, b_step, n_b, t_max, prim_out, t_out):
    """First hit of every ray on the swell's strip mesh (:meth:`SeaSurface.mesh`), in closed form: the mesh is the
    profile z(a) across the crests (nodes a0 + i·a_step, heights z, linear between), extruded along them over
    b0 … b0 + (n_b − 1)·b_step. Same triangles as the mesh: quad (ia, ib) is faces q and n_q + q,
    q = ib·(na − 1) + ia, n_q = (na − 1)(n_b − 1), the second where the fraction along the crest exceeds the one
    across.

    Parameters
    ----------
    org, dirs : (n, 3) float32
        Ray origins (local frame, m) and unit directions.
    shift : (3,) float64
        World position of the local origin (the grid is in world coordinates), m.
    k : (2,) float64
        Unit vector across the crests (world x, y); along them is its left turn (−k_y, k_x).
    a0, a_step : float; z : (na,) float64
        The profile's first node and spacing across the crests (m) and its heights (world z, m).
    b0, b_step : float; n_b : int
        The nodes along the crests, m.
    t_max : float
        Farthest hit, m.
    prim_out : (n,) int32; t_out : (n,) float32
        Written: the facet hit (−1: none) and the distance to it (m; inf for none).
    """
    z_lo, z_hi = z.min(), z.max()
    b_hi = b0 + (n_b - 1) * b_step
    na = z.shape[0]
    n_q = (na - 1) * (n_b - 1)
    for i in prange(org.shape[0]):
        ox, oy, oz = org[i, 0] + shift[0], org[i, 1] + shift[1], org[i, 2] + shift[2]
        dx, dy, dz = np.float64(dirs[i, 0]), np.float64(dirs[i, 1]), np.float64(dirs[i, 2])
        a_o, d_a = ox * k[0] + oy * k[1], dx * k[0] + dy * k[1]
        b_o, d_b = ox * -k[1] + oy * k[0], dx * -k[1] + dy * k[0]        # along the crests: c = (−k_y, k_x)
        t_lo, t_hi = 0.0, t_max
        for lo, hi, o, d in ((z_lo, z_hi, oz, dz), (b0, b_hi, b_o, d_b)):   # the band of heights and the strips' ends
            if d == 0.0:
                if o < lo or o > hi:
                    t_lo = math.inf
                continue
            ta, tb = (lo - o) / d, (hi - o) / d
            t_lo, t_hi = max(t_lo, min(ta, tb)), min(t_hi, max(ta, tb))
        t, ia = (math.inf, -1) if t_lo > t_hi else _strip_hit(a_o, d_a, oz, dz, a0, a_step, z, t_lo, t_hi)
        if ia < 0:
            prim_out[i], t_out[i] = -1, np.float32(math.inf)
            continue
        fa = (a_o + t * d_a - (a0 + ia * a_step)) / a_step
        ib = min(max(int(math.floor((b_o + t * d_b - b0) / b_step)), 0), n_b - 2)
        fb = (b_o + t * d_b - (b0 + ib * b_step)) / b_step
        q = ib * (na - 1) + ia
        prim_out[i] = q if fa >= fb else n_q + q
        t_out[i] = np.float32(t)



#: Columns of a glint's lattice (:func:`swell_glints`): the strip, first s', s' step, first β', β' step (rad), rays in
#: s', rays in β' — in the crest frame of the swell (along the crests, across them, up), where every direction through
#: one strip has its β' within the strip's wedge seen from the sonar.
G_STRIP, G_S0, G_HS, G_B0, G_HB, G_NS, G_NB = range(7)
GLINT_WIDTH = 7


@njit(cache=True, nogil=True)  # pings × objects × strips in a window, a few flops each: serial
def swell_glints(centre, radius, pos, k, a0, a_step, z, max_slope, reach_m, n_across, steps, max_rays, table, n_out):
    """The strips through which each object can be seen from each ping by one reflection (its glints), and the
    lattice of rays for each.

    The swell is long-crested: strip ia (between the profile's nodes a0 + ia·a_step and the next, heights ``z``)
    is a plane containing lines along the crests, so from the sonar S every direction that meets it lies in a
    wedge of angles β' about the crest axis. Directions are u = s'·c + √(1 − s'²)·(cos β'·k + sin β'·ẑ)
    (c along the crests, k across them; dΩ = ds'·dβ' exactly). A reflection in the strip maps the object's
    bounding sphere (C, ρ) onto its image (C', ρ); the rays towards the image lie in the cone of half-angle
    asin(ρ/|SC'|) about it. A glint is a strip whose wedge meets that cone (S and C both below the strip's
    plane): its lattice tiles the cone's (s', β') box clipped to the wedge, so that its rays reach the strip
    between its edges exactly, with cells at most 2γ/n across, no wider than ``steps`` and, in β', fine
    enough for one ray per range step over the object's depth (as :func:`~.aim.aim_lattices`). Only strips within
    W = (z_max − min(z_S, z_C))·tan(2·atan(max_slope)) + ρ outside [min(a_S, a_C), max(a_S, a_C)] can mirror
    C to S (a facet of slope ≤ max_slope turns a ray by at most twice its angle).

    Parameters
    ----------
    centre : (k, 3) float64; radius : (k,) float64
        Bounding spheres, world frame (the strips' frame), m.
    pos : (pings, 3) float64
        Sonar positions, world frame, m.
    k : (2,) float64
        Unit vector across the crests (world x, y).
    a0, a_step : float; z : (na,) float64
        The profile's first node and spacing across the crests (m) and its heights (world z, m).
    max_slope : float
        The largest |dz/da| of the swell.
    reach_m : float
        The farthest unfolded path |SC'| − ρ searched, m.
    n_across : float; steps : (3,) float64; max_rays : float
        Rays across a cone each way; the largest s' step, the largest β' step (rad) and the wanted range step (m);
        the most rays of one lattice.
    table : (pings, k, g, GLINT_WIDTH) float64
        Written: the glints of each (ping, object), the first ``n_out`` of them.
    n_out : (pings, k) int32
        Written: the number of glints; −1 where there are more than g, or one needs more than ``max_rays`` rays or
        holds the sonar (the object is then left to the fan in that ping).
    """
    na = z.shape[0]
    spread = math.tan(2.0 * math.atan(max_slope))
    z_max = z.max()
    for b in range(pos.shape[0]):
        a_s, z_s = pos[b, 0] * k[0] + pos[b, 1] * k[1], pos[b, 2]
        for j in range(centre.shape[0]):
            n_out[b, j] = 0
            a_c, z_c = centre[j, 0] * k[0] + centre[j, 1] * k[1], centre[j, 2]
            w = (z_max - min(z_s, z_c)) * spread + radius[j]
            lo = int(math.floor((min(a_s, a_c) - w - a0) / a_step))
            hi = int(math.ceil((max(a_s, a_c) + w - a0) / a_step))
            for ia in range(max(lo, 0), min(hi, na - 2) + 1):
                n = n_out[b, j]
                row = table[b, j, min(n, table.shape[2] - 1)]
                got = _glint(pos[b], centre[j], radius[j], k, a0 + ia * a_step, a_step, z[ia], z[ia + 1], reach_m,
                             n_across, steps, max_rays, row)
                if got == 0:
                    continue
                if got < 0 or n == table.shape[2]:
                    n_out[b, j] = -1
                    break
                row[G_STRIP] = ia
                n_out[b, j] = n + 1


@njit(cache=True, nogil=True)
def _glint(s3, c3, rho, k, a_i, a_step, z_i, z_j, reach_m, n_across, steps, max_rays, out):
    """The lattice of strip (a_i, z_i)–(a_i + a_step, z_j) for the sphere (C, ρ) seen from S (:func:`swell_glints`)
    in ``out``: 1 a lattice, 0 none, −1 one too big to aim at (or the sonar inside the image's sphere)."""
    dz = z_j - z_i
    ln = math.sqrt(a_step * a_step + dz * dz)
    n0, n1, n2 = -dz / ln * k[0], -dz / ln * k[1], a_step / ln          # the strip plane's upward normal
    p0, p1 = a_i * k[0], a_i * k[1]
    d_s = n0 * (s3[0] - p0) + n1 * (s3[1] - p1) + n2 * (s3[2] - z_i)
    d_c = n0 * (c3[0] - p0) + n1 * (c3[1] - p1) + n2 * (c3[2] - z_i)
    if d_s >= 0.0 or d_c >= 0.0:                                  # S and C below the strip's plane, else no mirror
        return 0
    v0, v1, v2 = c3[0] - 2.0 * d_c * n0 - s3[0], c3[1] - 2.0 * d_c * n1 - s3[1], c3[2] - 2.0 * d_c * n2 - s3[2]
    d = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if d - rho > reach_m:
        return 0
    if d <= rho * (1.0 + 1e-9):
        return -1
    vc, vk = -k[1] * v0 + k[0] * v1, k[0] * v0 + k[1] * v1          # along and across the crests
    gam = math.asin(rho / d)
    sc = vc / d
    cpsi = math.sqrt(max(1.0 - sc * sc, 0.0))
    if math.sin(gam) >= 0.999 * cpsi:
        return -1
    bc, db = math.atan2(v2, vk), math.asin(math.sin(gam) / cpsi)
    a_s = k[0] * s3[0] + k[1] * s3[1]
    e0, e1 = math.atan2(z_i - s3[2], a_i - a_s), math.atan2(z_j - s3[2], a_i + a_step - a_s)   # the wedge
    b_lo, b_hi = max(bc - db, min(e0, e1)), min(bc + db, max(e0, e1))
    if not b_hi > b_lo:
        return 0
    s_lo, s_hi = max(sc - gam, -1.0), min(sc + gam, 1.0)
    h = 2.0 * gam / n_across
    hs, hb = min(h, steps[0]), min(h, steps[1], 2.0 * gam * steps[2] / (2.0 * rho))
    ns, nb = math.ceil((s_hi - s_lo) / hs - 1e-9), math.ceil((b_hi - b_lo) / hb - 1e-9)
    if ns * nb > max_rays:
        return -1
    out[G_S0], out[G_HS], out[G_NS] = s_lo, (s_hi - s_lo) / ns, ns
    out[G_B0], out[G_HB], out[G_NB] = b_lo, (b_hi - b_lo) / nb, nb
    return 1


@njit(cache=True, nogil=True, parallel=True)
def glint_rays(glints, ping, start, k, rot, pos, span, sides, rx_shift, dirs, origins, layout, row_out):
    """The rays of every glint's lattice (:func:`swell_glints`), glint g's at ``start[g]`` … ``start[g + 1]`` − 1:
    float32 world directions and origins, the layout of each in its fan row's body frame (s, cos β, sin β of the
    direction; dβ', ds' of its cell: the cell's solid angle is ds'·dβ') and its row 2·ping + side (side by the
    direction's starboard component), −1 where the row has no rays or the direction lies outside the fan's span
    (``span`` = s_lo, s_hi, β_lo, β_hi, with s reaching δ further on its side as for :func:`~.aim.aim_lattices`).

    Parameters
    ----------
    glints : (e, GLINT_WIDTH) float64; ping : (e,) int64
        The lattices and the ping of each.
    start : (e + 1,) int64
    k : (2,) float64
        Unit vector across the crests (world x, y); c = (−k_y, k_x, 0) runs along them.
    rot : (pings, 3, 3) float64; pos : (pings, 3) float64
    span : (4,) float64; sides : (2,) bool; rx_shift : (pings,) float64
    dirs, origins : (n, 3) float32; layout : (n, 5) float64; row_out : (n,) int64
        Written.
    """
    for g in prange(glints.shape[0]):
        b = ping[g]
        nb = int(glints[g, G_NB])
        for j in range(start[g + 1] - start[g]):
            i = start[g] + j
            sp = glints[g, G_S0] + (j // nb + 0.5) * glints[g, G_HS]
            bp = glints[g, G_B0] + (j % nb + 0.5) * glints[g, G_HB]
            cp = math.sqrt(1.0 - sp * sp)
            ck, cz = cp * math.cos(bp), cp * math.sin(bp)
            w0, w1, w2 = -k[1] * sp + k[0] * ck, k[0] * sp + k[1] * ck, cz
            for q in range(3):
                origins[i, q] = pos[b, q]
            dirs[i, 0], dirs[i, 1], dirs[i, 2] = w0, w1, w2
            f = rot[b, 0, 0] * w0 + rot[b, 1, 0] * w1 + rot[b, 2, 0] * w2          # body frame: forward,
            st = rot[b, 0, 1] * w0 + rot[b, 1, 1] * w1 + rot[b, 2, 1] * w2         # starboard, down
            dn = rot[b, 0, 2] * w0 + rot[b, 1, 2] * w1 + rot[b, 2, 2] * w2
            side = 1 if st >= 0.0 else 0
            be = math.atan2(dn, abs(st))
            ch = math.sqrt(max(1.0 - f * f, 1e-300))
            layout[i, 0], layout[i, 1], layout[i, 2] = f, abs(st) / ch, dn / ch
            layout[i, 3], layout[i, 4] = glints[g, G_HB], glints[g, G_HS]
            d = rx_shift[b]
            inside = span[0] + min(d, 0.0) <= f <= span[1] + max(d, 0.0) and span[2] <= be <= span[3]
            row_out[i] = 2 * b + side if sides[side] and inside else -1
