"""Front-end kernels, sea-surface multipath: the one- and two-bounce paths of a block (docs/physics.md §13)."""
from __future__ import annotations

import math

import numpy as np

from ._numba import njit, prange

#: Rays per pass of :func:`mixed_legs` (and the swell's paths): their sinc arguments are gathered, then evaluated in one
#: vectorised loop. 1024 rather than 256: a chunk's call passes ~40 arrays (reference counts), −7 % per kernel.
_CHUNK = 1024


@njit(cache=True, nogil=True)
def _rotation(rot, b):
    """The 3×3 body-to-world rotation of ping b as a 9-tuple (row-major): scalars, no array view per echo."""
    return (rot[b, 0, 0], rot[b, 0, 1], rot[b, 0, 2], rot[b, 1, 0], rot[b, 1, 1], rot[b, 1, 2],
            rot[b, 2, 0], rot[b, 2, 1], rot[b, 2, 2])


@njit(cache=True, nogil=True)
def _footprint_slope(m, side, u, v, n, r):
    """|d(r + r')/dβ| of a ray cell: dX/dβ = r·(f − u·(n·f)/(n·u)), f = ∂u/∂β in world axes (m a 9-tuple)."""
    e1 = m[1] * u[0] + m[4] * u[1] + m[7] * u[2]
    e2 = m[2] * u[0] + m[5] * u[1] + m[8] * u[2]
    f = (m[1] * (-side * e2) + m[2] * (side * e1), m[4] * (-side * e2) + m[5] * (side * e1),
         m[7] * (-side * e2) + m[8] * (side * e1))
    k = (n[0] * f[0] + n[1] * f[1] + n[2] * f[2]) / (n[0] * u[0] + n[1] * u[1] + n[2] * u[2])
    out = 0.0
    for q in range(3):
        out += (u[q] - v[q]) * (f[q] - u[q] * k)
    return abs(out * r)


@njit(cache=True, nogil=True)
def _azimuth(n, u, v):
    """Angle between −u and v, both projected on the plane of normal n (0 when either is along n)."""
    nu = -(n[0] * u[0] + n[1] * u[1] + n[2] * u[2])
    nv = n[0] * v[0] + n[1] * v[1] + n[2] * v[2]
    bb, tt, bt = 0.0, 0.0, 0.0
    for q in range(3):
        bq = -u[q] - nu * n[q]
        tq = v[q] - nv * n[q]
        bb += bq * bq
        tt += tq * tq
        bt += bq * tq
    if bb <= 1e-24 or tt <= 1e-24:
        return 0.0
    return math.acos(min(max(bt / math.sqrt(bb * tt), -1.0), 1.0))


@njit(cache=True, nogil=True, parallel=True)
def mixed_legs(ray_start, fan, hits, poses, face_normals, weighting, bistatic, out, layout):
    """The S→X→S' and S'→X→S paths of every direct echo of a side-scan block, without the beam's gains, σ (but
    Lambert's, see ``bistatic``), maps or visibility.

    S' is the sonar mirrored in the surface z = ``z_s``, v the unit vector X → S'
    (r' = |S' − X|), P = X + leg1·v the surface point and u2 the unit vector S → P
    (leg2 = |P − S|). Per echo:

        w = |R_s|²·e^(−α'(r + r'))·ds·dβ / (max(r', R_min)²·cos θi),
        |R_s|² = exp(−4·(k·h_w)²·sin²θg)  (sin θg = v_z at the surface),
        t = (r + r')/c,  Δt = min(|d(r + r')/dβ|, 2·cap)·dβ/c,

    cos θi = −n·u1 and cos θs = n·v with n facing the sonar, φ the angle between −u1
    and v in the plane of n (the bistatic azimuth; 0 for backscatter; computed only when ``want_phi``, for a
    law that depends on it, else left unwritten: an arccos per echo). The beam's gains Γ²(u1)·Γ_rx²(u2) +
    Γ²(u2)·Γ_rx²(u1) are multiplied in after this kernel (:func:`~sonar_embree.kernels.rays.weigh_pairs`, from
    u2). Rays without a direct echo (r = inf) get w = 0, t = inf. The rays go in chunks of :data:`_CHUNK`, stage by
    stage.

    Parameters
    ----------
    ray_start : (rows + 1,) int64
        The block's rows (row = 2·ping + side, port 0) of rays; a row's rays are azimuth-major over its elevation
        cells, as :func:`fan_rays` casts them.
    fan : :data:`~sonar_embree.kernels.args.Fan`
        The fan's azimuth spacing ``ds``, each elevation cell's width dβ (rad), and the rows' elevation cells
        ``el_start`` (rows + 1,) (its ``s``, cos β and sin β not read).
    hits : :data:`~sonar_embree.kernels.args.Hits`
        Direct slant ranges (n,) (m, inf: none), hit points (n, 3) (local frame, m) and triangles (n,) int32 of the
        block's rays.
    poses : :data:`~sonar_embree.kernels.args.Poses`
        Body-to-world rotations, sonar positions (local frame) and δ = 2·v_fwd/c of each ping (0: stop-and-hop).
    face_normals : (f, 3) float64
        Scene normals.
    weighting : :data:`~sonar_embree.kernels.args.Weighting`
        Two-way absorption (Np/m), near-field bound (m), the range window (not read), |dR/dβ| cap (m/rad) and 2/c
        (s/m).
    bistatic : :data:`~sonar_embree.kernels.args.Bistatic`
        The surface height ``z_s`` (local, m) and k·h_w (0: a mirror); Lambert's μ per object ``mu_obj`` when
        every object has Lambert's law and there are no maps or texture (then σ = μ·cos θi·cos θs is applied
        here: the weight × (μ·cos θi)·cos θs, as ``multipath.apply_bistatic`` would; empty: σ is left to the
        caller) and ``face_object`` (f,); ``want_phi``: whether to write ``out.phi``; ``want_legs``: whether to
        write ``out.leg1``, ``out.leg2`` (for the visibility legs; ``out.v`` and ``out.u2`` are always written: the
        stages of a chunk and the beam after the kernel read them).
    out : :data:`~sonar_embree.kernels.args.MixedOut`
        Written: time, extent, weight, cos θi, cos θs, φ (n,), v (n, 3), leg1 (n,), u2 (n, 3), leg2 (n,).
    layout : (n, 5) or (0, 5) float64
        Each ray's own s, cos β, sin β, dβ and ds (rays aimed at objects, :mod:`sonar_embree.propagation.aim`); then
        ``fan`` is not read (but for ``fan.el_start``'s length). No rows (``NO_LAYOUT``): the fan's layout.
    """
    el_start = fan.el_start
    for row in prange(ray_start.shape[0] - 1):
        sc = np.empty((_SC_ROWS, _CHUNK))   # per echo: Lambert's σ, its cell, r'
        carry = ((el_start[row + 1] - el_start[row] - 1 if layout.shape[0] == 0 else 0), -1)
        for c0 in range(ray_start[row], ray_start[row + 1], _CHUNK):
            c1 = min(c0 + _CHUNK, ray_start[row + 1])
            carry = _mixed_chunk(row, c0, c1, carry, fan, hits, poses, face_normals, weighting, bistatic, out, layout,
                                 sc)


#: Rows of a chunk's scratch ``sc`` (:func:`mixed_legs`): Lambert's σ (or 1), the ray's cell dβ and ds, and
#: r' = |S' − X|.
_SC_SIGMA, _SC_DB, _SC_DS, _SC_R2 = 0, 1, 2, 3
_SC_ROWS = 4


@njit(cache=True, nogil=True)  # one call per chunk of _CHUNK rays: its arrays' reference counts amortised
def _mixed_chunk(row, c0, c1, carry, fan, hits, poses, face_normals, weighting, bistatic, out, layout, sc):
    """Rays c0 … c1 − 1 of a row of :func:`mixed_legs`, in stages over the chunk. ``j``, ``az`` (the ray's elevation
    cell and azimuth on the fan's grid, counted) carry from chunk to chunk (``carry``) and are returned. The other
    arguments are :func:`mixed_legs`'."""
    b, side = row // 2, 1.0 if row % 2 == 1 else -1.0
    m = _rotation(poses.rot, b)
    carry = _launch_stage(row, c0, c1, carry, fan, layout, sc)
    _mirror_stage(c0, c1, b, hits, poses, bistatic, face_normals, out, sc)
    _sigma_stage(c0, c1, hits, out, bistatic, sc)
    _mixed_weight_stage(c0, c1, hits, out, weighting, bistatic, sc)
    _mixed_extent_stage(c0, c1, b, side, m, hits, poses, face_normals, out, weighting, sc)
    if bistatic.want_phi:
        _mixed_phi_stage(c0, c1, b, hits, poses, face_normals, out)
    if bistatic.want_legs:
        _mixed_leg_stage(c0, c1, b, hits, poses, bistatic, out, sc)
    return carry


@njit(cache=True, nogil=True)
def _launch_stage(row, c0, c1, carry, fan, layout, sc):
    """Each ray's cell dβ, ds (into ``sc``), the carry moved on: the fan's grid, the elevation cell counted on and the
    azimuth moved on after the row's last cell, or each ray's own cell (``layout``)."""
    if layout.shape[0] > 0:
        for i in range(c0, c1):
            sc[_SC_DB, i - c0], sc[_SC_DS, i - c0] = layout[i, 3], layout[i, 4]
        return carry
    j, az = carry
    ds, dbeta, el_start = fan.ds, fan.dbeta, fan.el_start
    n_el = el_start[row + 1] - el_start[row]
    for i in range(c0, c1):
        if j == n_el - 1:
            j, az = 0, az + 1
        else:
            j += 1
        sc[_SC_DB, i - c0], sc[_SC_DS, i - c0] = dbeta[el_start[row] + j], ds
    return j, az


@njit(cache=True, nogil=True, inline='always')
def _facing(face_normals, p, u):
    """Triangle p's normal turned to face the ray u (its incidence side)."""
    flip = -1.0 if face_normals[p, 0] * u[0] + face_normals[p, 1] * u[1] + face_normals[p, 2] * u[2] > 0.0 else 1.0
    return flip * face_normals[p, 0], flip * face_normals[p, 1], flip * face_normals[p, 2]


@njit(cache=True, nogil=True, inline='always')
def _direct_dir(r, x, pos, i, b):
    """u = (X − S)/r of echo i (ranges r, points x): the direct ray's unit direction."""
    ir = 1.0 / r[i]
    return (x[i, 0] - pos[b, 0]) * ir, (x[i, 1] - pos[b, 1]) * ir, (x[i, 2] - pos[b, 2]) * ir


@njit(cache=True, nogil=True)
def _mirror_stage(c0, c1, b, hits, poses, bistatic, face_normals, out, sc):
    """Each echo's leg to the image sonar S' (v = X → S', r' into ``sc``), its mirror u2 = S → P and cos θi, cos θs
    (facing the sonar)."""
    r, x, prim, pos, z_s = hits.range, hits.point, hits.prim, poses.pos, bistatic.z_s
    for i in range(c0, c1):
        if not math.isfinite(r[i]):
            continue
        u = _direct_dir(r, x, pos, i, b)
        vx, vy, vz = pos[b, 0] - x[i, 0], pos[b, 1] - x[i, 1], 2.0 * z_s - pos[b, 2] - x[i, 2]
        r2 = math.sqrt(vx * vx + vy * vy + vz * vz)
        ir2 = 1.0 / r2
        v = (vx * ir2, vy * ir2, vz * ir2)          # X → S'; S → P is its mirror (−v_x, −v_y, v_z)
        n = _facing(face_normals, prim[i], u)
        out.cos_i[i], out.cos_s[i] = -(n[0] * u[0] + n[1] * u[1] + n[2] * u[2]), n[0] * v[0] + n[1] * v[1] + n[2] * v[2]
        out.v[i, 0], out.v[i, 1], out.v[i, 2] = v
        out.u2[i, 0], out.u2[i, 1], out.u2[i, 2] = -v[0], -v[1], v[2]
        sc[_SC_R2, i - c0] = r2


@njit(cache=True, nogil=True)
def _sigma_stage(c0, c1, hits, out, bistatic, sc):
    """Lambert's σ = μ·cos θi·cos θs into ``sc`` (1 when σ is left to the caller, 0 without a direct echo)."""
    r, prim, mu_obj, face_object = hits.range, hits.prim, bistatic.mu_obj, bistatic.face_object
    for i in range(c0, c1):
        k = i - c0
        if not math.isfinite(r[i]):
            sc[_SC_SIGMA, k] = 0.0
            continue
        sc[_SC_SIGMA, k] = (mu_obj[face_object[prim[i]]] * max(out.cos_i[i], 0.0) * max(out.cos_s[i], 0.0)
                            if mu_obj.shape[0] > 0 else 1.0)


@njit(cache=True, nogil=True)
def _mixed_weight_stage(c0, c1, hits, out, weighting, bistatic, sc):
    """w without the gains (× Lambert's σ) and t = (r + r')/c (0 and inf without a direct echo)."""
    r, weight_out, time_out, v, cos_i = hits.range, out.weight, out.time, out.v, out.cos_i
    two_way_np_per_m, min_range_m, inv_c = weighting.two_way_np_per_m, weighting.min_range_m, 0.5 * weighting.time_per_m
    wave_kh = bistatic.wave_kh
    for i in range(c0, c1):
        k = i - c0
        if not math.isfinite(r[i]):
            weight_out[i], time_out[i] = 0.0, math.inf
            continue
        r2 = sc[_SC_R2, k]
        rb2 = max(r2, min_range_m)
        w = (math.exp(-0.5 * two_way_np_per_m * (r[i] + r2) - 4.0 * wave_kh * wave_kh * v[i, 2] * v[i, 2])
             * sc[_SC_DS, k] * sc[_SC_DB, k] / (rb2 * rb2 * cos_i[i]))
        weight_out[i], time_out[i] = w * sc[_SC_SIGMA, k], (r[i] + r2) * inv_c


@njit(cache=True, nogil=True)
def _mixed_extent_stage(c0, c1, b, side, m, hits, poses, face_normals, out, weighting, sc):
    """Δt = min(|d(r + r')/dβ|, 2·cap)·dβ/c (0 without a direct echo)."""
    r, x, prim, pos, v = hits.range, hits.point, hits.prim, poses.pos, out.v
    cap, inv_c = 2.0 * weighting.slope_cap_m_rad, 0.5 * weighting.time_per_m
    for i in range(c0, c1):
        if not math.isfinite(r[i]):
            out.extent[i] = 0.0
            continue
        u = _direct_dir(r, x, pos, i, b)
        n = _facing(face_normals, prim[i], u)
        vi = (v[i, 0], v[i, 1], v[i, 2])
        out.extent[i] = min(_footprint_slope(m, side, u, vi, n, r[i]), cap) * sc[_SC_DB, i - c0] * inv_c


@njit(cache=True, nogil=True)
def _mixed_phi_stage(c0, c1, b, hits, poses, face_normals, out):
    """φ, the bistatic azimuth between −u1 and v in the plane of n (an arccos per echo)."""
    r, x, prim, pos, v = hits.range, hits.point, hits.prim, poses.pos, out.v
    for i in range(c0, c1):
        if math.isfinite(r[i]):
            u = _direct_dir(r, x, pos, i, b)
            out.phi[i] = _azimuth(_facing(face_normals, prim[i], u), u, (v[i, 0], v[i, 1], v[i, 2]))


@njit(cache=True, nogil=True)
def _mixed_leg_stage(c0, c1, b, hits, poses, bistatic, out, sc):
    """The legs' lengths for the visibility check: X → P and S → P (= P → S')."""
    r, x, pos, z_s = hits.range, hits.point, poses.pos, bistatic.z_s
    for i in range(c0, c1):
        if not math.isfinite(r[i]):
            continue
        q = sc[_SC_R2, i - c0] / (2.0 * z_s - pos[b, 2] - x[i, 2])
        out.leg1[i], out.leg2[i] = (z_s - x[i, 2]) * q, (z_s - pos[b, 2]) * q   # X → P and S → P (= P → S')


@njit(cache=True, nogil=True, parallel=True)
def two_bounce(ray_start, x, pos_image, z_s, wave_kh, weight, up_out, leg_out):
    """S'→X→S' echoes of the fan cast from the image transducer S' (rows 2·ping + side, as the direct fan's).

    Per lit echo (weight > 0), with d = (X − S')/|X − S'| and sin θg = |d_z| at the surface:
    ``weight`` ×= |R_s|⁴ = exp(−8·(k·h_w)²·sin²θg) (two bounces), and the real upward leg from
    S to the surface point, u = (d_x, d_y, −d_z) over length (z_S' − z_s)/sin θg, is written for
    the visibility check (length 0 for unlit echoes).

    Parameters
    ----------
    ray_start : (rows + 1,) int64
    x : (n, 3) float64
        Hit points of the image fan, local frame, m.
    pos_image : (pings, 3) float64
        Image transducer positions S', local frame, m.
    z_s, wave_kh : float
        Surface height (local, m) and k·h_w.
    weight : (n,) float64
        The image fan's weights, multiplied in place.
    up_out : (n, 3) float64; leg_out : (n,) float64
        Written.
    """
    for row in prange(ray_start.shape[0] - 1):
        b = row // 2
        for i in range(ray_start[row], ray_start[row + 1]):
            if not weight[i] > 0.0:
                leg_out[i] = 0.0
                continue
            dx, dy, dz = x[i, 0] - pos_image[b, 0], x[i, 1] - pos_image[b, 1], x[i, 2] - pos_image[b, 2]
            rr = math.sqrt(dx * dx + dy * dy + dz * dz)
            sg = abs(dz) / rr
            weight[i] *= math.exp(-8.0 * wave_kh * wave_kh * sg * sg)
            up_out[i, 0], up_out[i, 1], up_out[i, 2] = dx / rr, dy / rr, -dz / rr
            leg_out[i] = (pos_image[b, 2] - z_s) / sg


@njit(cache=True, nogil=True, parallel=True)
def count_lit(starts, weights, counts):
    """counts[r] = echoes of weight > 0 in row r over every part (``starts``, ``weights``: tuples, one per part)."""
    for r in prange(counts.shape[0]):
        c = 0
        for p in range(len(starts)):
            w = weights[p]
            for i in range(starts[p][r], starts[p][r + 1]):
                if w[i] > 0.0:
                    c += 1
        counts[r] = c


@njit(cache=True, nogil=True, parallel=True)
def merge_lit(starts, times, extents, weights, points, ids, out_start, time_out, extent_out, weight_out, point_out,
              id_out, path_out):
    """The lit echoes of every part (path) row by row: within a row, part 0's, then part 1's, … in their order.

    Parameters
    ----------
    starts : tuple of (rows + 1,) int64
        Each part's row offsets.
    times, extents, weights : tuple of (n_p,) float64; points : tuple of (n_p, 3) float64; ids : tuple of (n_p,) int32
        Each part's echoes (points and ids are copied when ``point_out`` / ``id_out`` are not empty).
    out_start : (rows + 1,) int64
        Offsets of the merged rows (from :func:`count_lit`).
    time_out, extent_out, weight_out : (m,) float64; point_out : (m, 3) or (0, 3) float64
    id_out : (m,) or (0,) int32; path_out : (m,) int8
        Written; ``path_out`` holds the part index.
    """
    for r in prange(out_start.shape[0] - 1):
        k = out_start[r]
        for p in range(len(starts)):
            w = weights[p]
            for i in range(starts[p][r], starts[p][r + 1]):
                if not w[i] > 0.0:
                    continue
                time_out[k], extent_out[k], weight_out[k], path_out[k] = times[p][i], extents[p][i], w[i], p
                if point_out.shape[0] > 0:
                    point_out[k, 0], point_out[k, 1], point_out[k, 2] = (points[p][i, 0], points[p][i, 1],
                                                                         points[p][i, 2])
                if id_out.shape[0] > 0:
                    id_out[k] = ids[p][i]
                k += 1


@njit(cache=True, nogil=True, inline='always')
def _slab(lo, hi, o, inv, t0, t1):
    """One axis of the slab test: [t0, t1] narrowed to where o + t·d lies in [lo, hi] (inv = 1/d; d = 0: inv = inf,
    the whole line or nothing)."""
    if inv == math.inf or inv == -math.inf:
        return (t0, t1) if lo <= o <= hi else (1.0, -1.0)
    ta, tb = (lo - o) * inv, (hi - o) * inv
    return max(t0, min(ta, tb)), min(t1, max(ta, tb))


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _box_span(box_lo, box_hi, k, ox, oy, oz, ix, iy, iz, t0, t1):
    """(entry, exit) of the segment o + t·d, t0 ≤ t ≤ t1, in box k (slab test, i = 1/d per axis); exit < entry
    when it misses."""
    t0, t1 = _slab(box_lo[k, 0], box_hi[k, 0], ox, ix, t0, t1)
    t0, t1 = _slab(box_lo[k, 1], box_hi[k, 1], oy, iy, t0, t1)
    return _slab(box_lo[k, 2], box_hi[k, 2], oz, iz, t0, t1)


@njit(cache=True, nogil=True)
def _inverse(d):
    """1/d, ±inf for d = ±0."""
    return 1.0 / d if d != 0.0 else math.copysign(math.inf, d)


def visibility_legs(ray_start, legs, boxes, face_object, face_normals, out):
    """The legs of a block's lit echoes that can be blocked, as float32 rays for an occlusion query.

    Leg i starts at the sonar of its row's ping (``from_sonar``) or at its hit point x[i] and runs
    along dirs[i] for dist[i]. Only boxes it crosses hold anything that can block it: it is cast from
    where it enters the first of them (eps along it at least) to where it leaves the last (eps short of
    its end at most); a leg that crosses none, or has no length left, is not cast, nor is an echo of
    weight 0. The box of the echo's own object (its triangle ``prim``, when given) is passed over when that
    object is a height field (``box_obj`` ≥ 0) that cannot block the leg (docs/physics.md §13):
    with ``free_own`` (the one-bounce legs of a direct echo), when the direct ray reached x[i] from above
    (n·(x − S) < 0): the legs then run above the clear direct ray in its vertical plane; and for a leg
    from x[i] that rises more steeply than the field's steepest face (``box_slope``, tan): the field lies
    below it everywhere. Legs keep their order (rows counted, then filled).

    Parameters
    ----------
    ray_start : (rows + 1,) int64
        The block's rows (row = 2·ping + side).
    legs : :data:`~sonar_embree.kernels.args.Legs`
        Hit points x (n, 3) and sonar positions (pings, 3) (local frame, m); ``from_sonar``; each echo's leg: unit
        direction (n, 3) and length (n,) (m); the echoes' weights (n,); their triangles (n,) or (0,) int32 (empty:
        no box is passed over); ``free_own``; ``eps``, the offset from each end of a leg (m).
    boxes : :data:`~sonar_embree.kernels.args.Boxes`
        Boxes that hold the whole scene, lo and hi (k, 3) (local frame, m, already widened for rounding); the
        height-field object a box holds (k,) int32 (−1 for any other box) and its steepest slope (k,) (tan).
    face_object : (f,) int32; face_normals : (f, 3) float64
        The triangles' objects and normals.
    out : :data:`~sonar_embree.kernels.args.LegOut`
        Written: the part of each leg to cast, start and end (n,) (m along it; 0, 0: none), and, the first k
        rows, the legs' indices (n,) int64, origins and directions (n, 3) float32 and lengths (n,) float32.

    Returns
    -------
    k : int
        Legs to cast.
    """
    n = legs.weight.shape[0]
    own, rise, org = np.empty(n, np.int32), np.empty(n), np.empty((n, 3))
    counts = np.zeros(ray_start.shape[0], dtype=np.int64)
    _leg_spans(ray_start, legs, boxes, face_object, face_normals, own, rise, org, out.start, out.end, counts)
    np.cumsum(counts, out=counts)
    _leg_rays(ray_start, legs, out, counts)
    return int(counts[-1])


@njit(cache=True, nogil=True, parallel=True)
def _leg_spans(ray_start, legs, boxes, face_object, face_normals, own, rise, org, start_out, end_out, counts):
    """Each lit echo's leg span to cast (start_out, end_out; 0, 0: none) and the legs of row r in counts[r + 1]
    (see :func:`visibility_legs`), row by row: :func:`_row_owners`, then :func:`_row_spans`."""
    for row in prange(ray_start.shape[0] - 1):
        _row_owners(row, ray_start, legs, face_object, face_normals, own, rise, org)
        counts[row + 1] = _row_spans(row, ray_start, legs, boxes, own, rise, org, start_out, end_out)


@njit(cache=True, nogil=True)
def _row_owners(row, ray_start, legs, face_object, face_normals, own, rise, org):
    """Per echo of the row: its leg's origin (``org``), the object of its triangle (``own``, −1: none given) and how
    its own height field may be passed over (``rise``: +inf where the direct ray reached it from above with
    ``free_own``, tan of the leg's elevation from its hit point, or −inf; NaN: an unlit echo, no leg)."""
    x, pos, from_sonar, dirs, weight = legs.point, legs.pos, legs.from_sonar, legs.dir, legs.weight
    prim, free_own = legs.prim, legs.free_own
    b = row // 2
    for i in range(ray_start[row], ray_start[row + 1]):
        if not weight[i] > 0.0:
            rise[i] = math.nan
            continue
        for q in range(3):
            org[i, q] = pos[b, q] if from_sonar else x[i, q]
        o, above, r = -1, False, -math.inf
        if prim.shape[0] > 0:
            p = prim[i]
            o = face_object[p]
            above = free_own and face_normals[p, 0] * (x[i, 0] - pos[b, 0]) + face_normals[p, 1] * (
                x[i, 1] - pos[b, 1]) + face_normals[p, 2] * (x[i, 2] - pos[b, 2]) < 0.0
            if not (from_sonar or above):
                h = math.sqrt(dirs[i, 0] * dirs[i, 0] + dirs[i, 1] * dirs[i, 1])
                r = dirs[i, 2] / h if h > 0.0 else math.copysign(math.inf, dirs[i, 2])
        own[i], rise[i] = o, math.inf if above else r


@njit(cache=True, nogil=True)
def _row_spans(row, ray_start, legs, boxes, own, rise, org, start_out, end_out):
    """Per lit echo of the row: its leg's span over the boxes it crosses, ``eps`` from each end, the boxes of its own
    height field passed over where :func:`_row_owners` allows; the number of legs with a span."""
    dirs, dist, eps = legs.dir, legs.length, legs.eps
    box_lo, box_hi, box_obj, box_slope = boxes
    count = 0
    for i in range(ray_start[row], ray_start[row + 1]):
        start_out[i], end_out[i] = 0.0, 0.0
        if not rise[i] == rise[i]:
            continue
        ox, oy, oz = org[i, 0], org[i, 1], org[i, 2]
        ix, iy, iz = _inverse(dirs[i, 0]), _inverse(dirs[i, 1]), _inverse(dirs[i, 2])
        start, end = math.inf, -math.inf
        for q in range(box_lo.shape[0]):
            if box_obj[q] < 0 or box_obj[q] != own[i] or not rise[i] > box_slope[q]:
                t0, t1 = _box_span(box_lo, box_hi, q, ox, oy, oz, ix, iy, iz, eps, dist[i] - eps)
                if t0 <= t1:
                    start, end = min(start, t0), max(end, t1)
        end = min(dist[i] - eps, end + eps)
        if end - start > 0.0:
            start_out[i], end_out[i] = start, end
            count += 1
    return count


@njit(cache=True, nogil=True, parallel=True)
def _leg_rays(ray_start, legs, out, counts):
    """The legs with a span as float32 rays, in order: row r's from counts[r] (see :func:`visibility_legs`)."""
    x, pos, from_sonar, dirs = legs.point, legs.pos, legs.from_sonar, legs.dir
    start_out, end_out, idx_out, org_out, dir_out, len_out = out
    for row in prange(ray_start.shape[0] - 1):
        b, k = row // 2, counts[row]
        for i in range(ray_start[row], ray_start[row + 1]):
            t0, t1 = start_out[i], end_out[i]
            if not t1 - t0 > 0.0:
                continue
            ox, oy, oz = (pos[b, 0], pos[b, 1], pos[b, 2]) if from_sonar else (x[i, 0], x[i, 1], x[i, 2])
            dx, dy, dz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
            idx_out[k] = i
            org_out[k, 0], org_out[k, 1], org_out[k, 2] = ox + t0 * dx, oy + t0 * dy, oz + t0 * dz
            dir_out[k, 0], dir_out[k, 1], dir_out[k, 2] = dx, dy, dz
            len_out[k] = t1 - t0
            k += 1
