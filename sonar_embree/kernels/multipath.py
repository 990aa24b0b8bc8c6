"""Front-end kernels, sea-surface multipath: the one-bounce legs of every direct echo (docs/physics.md §13)."""
from __future__ import annotations

import math

from ._numba import njit, prange
from .rays import _sinc


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/refraction.py
def _gain(rot, side, ux, uy, uz, beam, c, s):
    """Γ of the channel's membrane (side −1 port, +1 starboard) for the world direction u; rot body → world,
    c and s the cosine and sine of the tilt."""
    e0 = rot[0, 0] * ux + rot[1, 0] * uy + rot[2, 0] * uz     # body = rotᵀ·u: forward, starboard, down
    e1 = rot[0, 1] * ux + rot[1, 1] * uy + rot[2, 1] * uz
    e2 = rot[0, 2] * ux + rot[1, 2] * uy + rot[2, 2] * uz
    if side * e1 * c + e2 * s <= 0.0:                         # cos ψ · cos(β − δ): behind the baffle
        return 0.0
    return _sinc(beam[0] * e0) * _sinc(beam[1] * (e2 * c - side * e1 * s))


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/refraction.py
def _footprint_slope(rot, side, u, v, n, r):
    """|d(r + r')/dβ| of a ray cell: dX/dβ = r·(f − u·(n·f)/(n·u)), f = ∂u/∂β in world axes."""
    e1 = rot[0, 1] * u[0] + rot[1, 1] * u[1] + rot[2, 1] * u[2]
    e2 = rot[0, 2] * u[0] + rot[1, 2] * u[1] + rot[2, 2] * u[2]
    nf, nu = 0.0, 0.0
    fx = rot[0, 1] * (-side * e2) + rot[0, 2] * (side * e1)
    fy = rot[1, 1] * (-side * e2) + rot[1, 2] * (side * e1)
    fz = rot[2, 1] * (-side * e2) + rot[2, 2] * (side * e1)
    f = (fx, fy, fz)
    for q in range(3):
        nf += n[q] * f[q]
        nu += n[q] * u[q]
    out = 0.0
    for q in range(3):
        out += (u[q] - v[q]) * r * (f[q] - u[q] * nf / nu)
    return abs(out)


@njit(cache=True, nogil=True, parallel=True)
def mixed_legs(x, r, ping, side, dbeta, prim, rot, pos, z_s, face_normals, beam, ds, min_range_m, two_way_np_per_m,
               slope_cap_m_rad, sound_speed_m_s, wave_kh, time_out, extent_out, weight_out, cos_i_out, cos_s_out,
               phi_out, v_out, leg1_out, u2_out, leg2_out):
    """The S→X→S' and S'→X→S paths of every direct echo, without σ, maps or visibility.

    S' is the sonar mirrored in the surface z = ``z_s``, v the unit vector X → S'
    (r' = |S' − X|), P = X + leg1·v the surface point and u2 the unit vector S → P
    (leg2 = |P − S|). Per echo:

        w = 2·Γ²(u1)·Γ²(u2)·|R_s|²·e^(−α'(r + r'))·ds·dβ / (max(r', R_min)²·cos θi),
        |R_s|² = exp(−4·(k·h_w)²·sin²θg)  (sin θg = v_z at the surface),
        t = (r + r')/c,  Δt = min(|d(r + r')/dβ|, 2·cap)·dβ/c,

    cos θi = −n·u1 and cos θs = n·v with n facing the sonar, φ the angle between −u1
    and v in the plane of n (the bistatic azimuth; 0 for backscatter).

    Parameters
    ----------
    x : (n, 3) float64; r : (n,) float64
        Direct echoes' hit points (local frame, m) and slant ranges (m).
    ping, side : (n,) int64, float64
        Ping in the block and channel side (−1 port, +1 starboard) of each echo.
    dbeta : (n,) float64; prim : (n,) int32
        Elevation cell width (rad) and triangle of each echo.
    rot : (pings, 3, 3) float64; pos : (pings, 3) float64
        Body-to-world rotations and sonar positions (local frame).
    z_s : float
        Surface height in the local frame, m.
    face_normals : (f, 3) float64; beam : (4,) float64
        Scene normals; k·lx/2, k·ly/2, tilt (rad), 0.
    ds, min_range_m, two_way_np_per_m, slope_cap_m_rad, sound_speed_m_s : float
        Azimuth spacing, near-field bound, two-way absorption (Np/m), |dR/dβ| cap (m/rad), c (m/s).
    wave_kh : float
        k·h_w of the surface (0: a mirror).
    time_out, extent_out, weight_out, cos_i_out, cos_s_out, phi_out : (n,) float64
    v_out, u2_out : (n, 3) float64; leg1_out, leg2_out : (n,) float64
        Written.
    """
    ct, st = math.cos(beam[2]), math.sin(beam[2])
    for i in prange(x.shape[0]):
        b = ping[i]
        sx, sy, sz = pos[b, 0], pos[b, 1], pos[b, 2]
        u = ((x[i, 0] - sx) / r[i], (x[i, 1] - sy) / r[i], (x[i, 2] - sz) / r[i])
        vx, vy, vz = sx - x[i, 0], sy - x[i, 1], 2.0 * z_s - sz - x[i, 2]
        r2 = math.sqrt(vx * vx + vy * vy + vz * vz)
        v = (vx / r2, vy / r2, vz / r2)
        leg1 = r2 * (z_s - x[i, 2]) / (2.0 * z_s - sz - x[i, 2])
        px, py, pz = x[i, 0] + leg1 * v[0] - sx, x[i, 1] + leg1 * v[1] - sy, x[i, 2] + leg1 * v[2] - sz
        leg2 = math.sqrt(px * px + py * py + pz * pz)
        nrm = face_normals[prim[i]]
        flip = -1.0 if nrm[0] * u[0] + nrm[1] * u[1] + nrm[2] * u[2] > 0.0 else 1.0
        n = (flip * nrm[0], flip * nrm[1], flip * nrm[2])
        cos_i = -(n[0] * u[0] + n[1] * u[1] + n[2] * u[2])
        cos_s = n[0] * v[0] + n[1] * v[1] + n[2] * v[2]
        g1 = _gain(rot[b], side[i], u[0], u[1], u[2], beam, ct, st)
        g2 = _gain(rot[b], side[i], px / leg2, py / leg2, pz / leg2, beam, ct, st)
        rb2 = max(r2, min_range_m)
        att = math.exp(-0.5 * two_way_np_per_m * (r[i] + r2) - 4.0 * wave_kh * wave_kh * v[2] * v[2])
        weight_out[i] = 2.0 * g1 * g1 * g2 * g2 * att * ds * dbeta[i] / (rb2 * rb2 * cos_i)
        time_out[i] = (r[i] + r2) / sound_speed_m_s
        slope = min(_footprint_slope(rot[b], side[i], u, v, n, r[i]), 2.0 * slope_cap_m_rad)
        extent_out[i] = slope * dbeta[i] / sound_speed_m_s
        cos_i_out[i], cos_s_out[i] = cos_i, cos_s
        phi_out[i] = _azimuth(n, u, v)
        for q in range(3):
            v_out[i, q] = v[q]
        u2_out[i, 0], u2_out[i, 1], u2_out[i, 2] = px / leg2, py / leg2, pz / leg2
        leg1_out[i], leg2_out[i] = leg1, leg2


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
