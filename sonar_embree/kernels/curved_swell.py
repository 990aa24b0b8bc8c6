"""Front-end kernels, a swell over a sound-speed profile: the bounced rays' legs in closed form (docs/physics.md §13c).

A ray of Snell's invariant ξ climbs from the sonar at depth d_S to the **band** depth d_b (the swell's lowest
trough) along the profile's closed forms (:mod:`sonar_embree.kernels.eigenrays`: x/ξ, ∂x/∂ξ, T, L per linear
piece), runs straight through the band (c = c(d_b): across a band of a few decimetres c changes by centimetres per
second), meets a facet of the swell's mesh, is mirrored there, runs straight back down to d_b and then follows its
new invariant ξ' down through the scene (marched by :mod:`sonar_embree.kernels.refraction`). The same chain, in
closed form down to a given depth, gives the bounced ray tube: a launch direction moved by δ in s and in β, mirrored
in the same facet's plane, lands δ·∂X/∂s and δ·∂X/∂β away at the hit's depth; the tube's cross-section per unit of
ds·dβ is A = |∂X/∂s × ∂X/∂β|·|sin θ_X| (R² for straight rays: the straight swell's mirror image). The direct leg
X → S back to the sonar is the profile's unturned eigenray between the two depths (:func:`direct_eigenrays`).
"""
from __future__ import annotations

import math

from ._numba import njit, prange
from .eigenrays import _leg, _leg_x, _speed, newton_xi

#: Columns of :func:`swell_up_legs`' output: the band point Q (3, local m), the direction there (3, world), the one-way
#: time (s) and path length (m) from the sonar to Q.
U_Q, U_DIR, U_TIME, U_PATH = 0, 3, 6, 7
UP_WIDTH = 8
#: Columns of :func:`direct_eigenrays`' output: ξ (s/m; NaN: no unturned ray), one-way time (s), path (m), tube area
#: per steradian at the far end (m²), sin θ at the source and at the far end, c at the far end (m/s).
D_XI, D_TIME, D_PATH, D_SPREAD, D_SIN_SRC, D_SIN_DST, D_C_DST = range(7)
DIRECT_WIDTH = 7
#: Step (rad, and in s) of the finite differences of the bounced ray tube.
TUBE_STEP = 1e-5


@njit(cache=True, nogil=True)
def _band_leg(z, c, xi, d_src, d_band):
    """(x (m), T (s), L (m)) of the ray of invariant ξ between depths d_band ≤ d_src, NaN where it turns."""
    a, b = _leg(z, c, xi, d_src), _leg(z, c, xi, d_band)
    return xi * (a[0] - b[0]), a[2] - b[2], a[3] - b[3]


@njit(cache=True, nogil=True)
def _climb(z, c, d_src, d_band, u):
    """The ray leaving depth d_src along world direction u (upward) at the band: (horizontal unit h (2), x (m),
    T (s), L (m), cos θ and sin θ at the band); x NaN where it turns before the band."""
    hz = math.sqrt(u[0] * u[0] + u[1] * u[1])
    hx, hy = (u[0] / hz, u[1] / hz) if hz > 0.0 else (1.0, 0.0)
    xi = hz / _speed(z, c, d_src)
    x, t, length = _band_leg(z, c, xi, d_src, d_band)
    cb = xi * _speed(z, c, d_band)
    return hx, hy, x, t, length, cb, math.sqrt(max(1.0 - cb * cb, 0.0))


@njit(cache=True, nogil=True, parallel=True)
def swell_up_legs(launch, ping, pos, z, c, z0, d_band, out):
    """Every upward launch ray from its ping's sonar up to the band (see the module docstring).

    Parameters
    ----------
    launch : (n, 3) float64
        World unit launch directions (z up; only rays with z > 0 are read).
    ping : (n,) int64
        Each ray's ping.
    pos : (pings, 3) float64
        Sonar positions, local frame, m.
    z, c : (m,) float64
        The profile's knots from depth 0 (m) and speeds (m/s).
    z0 : float
        Local z of depth 0, m.
    d_band : float
        The band's depth, m (≤ every sonar's depth).
    out : (n, UP_WIDTH) float64
        Written, the columns ``U_*``; NaN time where the ray turns before the band or points down.
    """
    for i in prange(launch.shape[0]):
        b = ping[i]
        u = (launch[i, 0], launch[i, 1], launch[i, 2])
        out[i, U_TIME] = math.nan
        if not u[2] > 0.0:
            continue
        hx, hy, x, t, length, cb, sb = _climb(z, c, z0 - pos[b, 2], d_band, u)
        if not x == x:
            continue
        out[i, 0], out[i, 1], out[i, 2] = pos[b, 0] + hx * x, pos[b, 1] + hy * x, z0 - d_band
        out[i, 3], out[i, 4], out[i, 5] = hx * cb, hy * cb, sb
        out[i, U_TIME], out[i, U_PATH] = t, length


@njit(cache=True, nogil=True, inline='always')
def _mirror(u, n):
    """u mirrored in the plane of unit normal n."""
    un = 2.0 * (u[0] * n[0] + u[1] * n[1] + u[2] * n[2])
    return u[0] - un * n[0], u[1] - un * n[1], u[2] - un * n[2]


@njit(cache=True, nogil=True)
def _to_plane(q, u, p, n):
    """Distance along u from q to the plane through p of normal n (inf when u runs along it)."""
    un = u[0] * n[0] + u[1] * n[1] + u[2] * n[2]
    if un == 0.0:
        return math.inf
    return ((p[0] - q[0]) * n[0] + (p[1] - q[1]) * n[1] + (p[2] - q[2]) * n[2]) / un


@njit(cache=True, nogil=True, parallel=True)
def swell_bounce(up, facet, dist, normals, z_band, out_p, out_dir, out_org, out_len):
    """Mirror every band ray that met the swell in its facet and run it straight back down to the band.

    Parameters
    ----------
    up : (n, UP_WIDTH) float64
        :func:`swell_up_legs`' output.
    facet : (n,) int32; dist : (n,) float32
        The facet each ray met from its band point (−1: none) and the distance to it, m.
    normals : (f, 3) float64
        The swell mesh's normals.
    z_band : float
        Local z of the band, m.
    out_p : (n, 3) float64
        Written: the surface point P (local, m).
    out_dir, out_org : (n, 3) float64
        Written: the mirrored direction u' and the point Q' where it reaches the band again.
    out_len : (n,) float64
        Written: the straight path through the band, |QP| + |PQ'| (m); NaN where the ray met no facet or its mirror
        does not point down.
    """
    for i in prange(up.shape[0]):
        out_len[i] = math.nan
        f = facet[i]
        if f < 0 or not up[i, U_TIME] == up[i, U_TIME]:
            continue
        t = float(dist[i])
        p = (up[i, 0] + t * up[i, 3], up[i, 1] + t * up[i, 4], up[i, 2] + t * up[i, 5])
        ur = _mirror((up[i, 3], up[i, 4], up[i, 5]), (normals[f, 0], normals[f, 1], normals[f, 2]))
        if not ur[2] < 0.0:
            continue
        down = (z_band - p[2]) / ur[2]
        out_p[i, 0], out_p[i, 1], out_p[i, 2] = p
        out_dir[i, 0], out_dir[i, 1], out_dir[i, 2] = ur
        out_org[i, 0], out_org[i, 1], out_org[i, 2] = p[0] + down * ur[0], p[1] + down * ur[1], z_band
        out_len[i] = t + down


@njit(cache=True, nogil=True)
def _landing(z, c, sonar, d_band, u, p, n, d_x):
    """Where the chain from ``sonar`` along world direction u (up to the band, straight to the plane through p of
    normal n, mirrored, straight down to the band, down the profile) reaches depth d_x: its horizontal position (2,
    local m); NaN where a leg turns."""
    z0 = sonar[3]
    hx, hy, x, _, _, cb, sb = _climb(z, c, z0 - sonar[2], d_band, u)
    q = (sonar[0] + hx * x, sonar[1] + hy * x, z0 - d_band)
    ub = (hx * cb, hy * cb, sb)
    t = _to_plane(q, ub, p, n)
    pp = (q[0] + t * ub[0], q[1] + t * ub[1], q[2] + t * ub[2])
    ur = _mirror(ub, n)
    down = (q[2] - pp[2]) / ur[2]
    hz = math.sqrt(ur[0] * ur[0] + ur[1] * ur[1])
    gx, gy = (ur[0] / hz, ur[1] / hz) if hz > 0.0 else (1.0, 0.0)
    xi = hz / _speed(z, c, d_band)
    a, b = _leg_x(z, c, xi, d_x), _leg_x(z, c, xi, d_band)
    x2 = xi * (a[0] - b[0])
    return pp[0] + down * ur[0] + gx * x2, pp[1] + down * ur[1] + gy * x2


@njit(cache=True, nogil=True, inline='always')
def _body_dir(rot, b, side, s, beta):
    """World direction of body azimuth sine s and depression β on a side (fan_rays' convention)."""
    cpsi = math.sqrt(1.0 - s * s)
    e1, e2 = side * cpsi * math.cos(beta), cpsi * math.sin(beta)
    return (rot[b, 0, 0] * s + rot[b, 0, 1] * e1 + rot[b, 0, 2] * e2,
            rot[b, 1, 0] * s + rot[b, 1, 1] * e1 + rot[b, 1, 2] * e2,
            rot[b, 2, 0] * s + rot[b, 2, 1] * e1 + rot[b, 2, 2] * e2)


@njit(cache=True, nogil=True, parallel=True)
def swell_tubes(cells, row, rot, sonar, z, c, facets, hits, out):
    """The bounced ray tube at each hit, from the chain's closed forms (see the module docstring).

    Parameters
    ----------
    cells : (n, 2) float64
        Each ray's body azimuth sine s and depression β (rad).
    row : (n,) int64
        Each ray's row (2·ping + side, port 0).
    rot : (pings, 3, 3) float64
        Body-to-world rotations.
    sonar : (pings, 4) float64
        Sonar positions (local, m) and the local z of depth 0 (m).
    z, c : (m,) float64
        The profile's knots from depth 0 (m) and speeds (m/s).
    facets : (n, 7) float64
        Each ray's surface point P (3, local m), its facet's normal (3) and the band's depth (m).
    hits : (n, 7) float64
        Each ray's hit point X (3, local m), its arrival direction (3, world) and the hit's depth (m); rays with a
        NaN depth are skipped.
    out : (n, 4) float64
        Written: A = |∂X/∂s × ∂X/∂β|·|sin θ_X| (m² per unit of s·β) and ∂X/∂β (3, m/rad) in the hit's horizontal
        plane; NaN where the chain turns or the ray is skipped.
    """
    for i in prange(cells.shape[0]):
        out[i, 0] = math.nan
        d_x = hits[i, 6]
        if not d_x == d_x:
            continue
        b, side = row[i] // 2, 1.0 if row[i] % 2 == 1 else -1.0
        s, beta = cells[i, 0], cells[i, 1]
        p, n = (facets[i, 0], facets[i, 1], facets[i, 2]), (facets[i, 3], facets[i, 4], facets[i, 5])
        d_band = facets[i, 6]
        so = (sonar[b, 0], sonar[b, 1], sonar[b, 2], sonar[b, 3])
        h = TUBE_STEP
        sp = _landing(z, c, so, d_band, _body_dir(rot, b, side, s + h, beta), p, n, d_x)
        sm = _landing(z, c, so, d_band, _body_dir(rot, b, side, s - h, beta), p, n, d_x)
        bp = _landing(z, c, so, d_band, _body_dir(rot, b, side, s, beta + h), p, n, d_x)
        bm = _landing(z, c, so, d_band, _body_dir(rot, b, side, s, beta - h), p, n, d_x)
        ds = ((sp[0] - sm[0]) / (2.0 * h), (sp[1] - sm[1]) / (2.0 * h))
        db = ((bp[0] - bm[0]) / (2.0 * h), (bp[1] - bm[1]) / (2.0 * h))
        out[i, 0] = abs(ds[0] * db[1] - ds[1] * db[0]) * abs(hits[i, 5])
        out[i, 1], out[i, 2], out[i, 3] = db[0], db[1], 0.0


@njit(cache=True, nogil=True)
def _c_between(z, c, d_lo, d_hi):
    """The fastest c between two depths."""
    out = max(_speed(z, c, d_lo), _speed(z, c, d_hi))
    for j in range(z.shape[0]):
        if d_lo < z[j] < d_hi:
            out = max(out, c[j])
    return out


@njit(cache=True, nogil=True)
def _direct_xi(z, c, d_lo, d_hi, x):
    """ξ of the unturned ray between depths d_lo < d_hi covering x (m), or NaN (:func:`newton_xi`)."""
    start = x / math.sqrt(x * x + (d_hi - d_lo) ** 2) / _speed(z, c, d_lo)
    return newton_xi(z, c, (d_hi, d_lo, -1.0), x, start, (1.0 - 1e-12) / _c_between(z, c, d_lo, d_hi))


@njit(cache=True, nogil=True, parallel=True)
def direct_eigenrays(z, c, d_src, d_dst, x, out):
    """The unturned ray of the profile from depth ``d_src`` to depth ``d_dst`` over the horizontal distance ``x``
    (all (n,), m): the direct leg of a bounced path (the straight ray when c is constant).

    Its tube area per steradian at the far end is A = (x/ξ)·(∂x/∂ξ)·sin θ_S·sin θ_D / c_S² (R² for straight rays),
    docs/physics.md §12b.

    Parameters
    ----------
    z, c : (m,) float64
        The profile's knots (depths from 0, m) and speeds there (m/s).
    d_src, d_dst, x : (n,) float64
        Source depth, far-end depth and horizontal distance, m (d_src ≠ d_dst; equal depths have no unturned ray
        but the horizontal one, left out).
    out : (n, DIRECT_WIDTH) float64
        Written: the columns ``D_*``; NaN ξ where no unturned ray joins the two.
    """
    for i in prange(x.shape[0]):
        for k in range(DIRECT_WIDTH):
            out[i, k] = math.nan
        d_lo, d_hi = min(d_src[i], d_dst[i]), max(d_src[i], d_dst[i])
        if not d_hi > d_lo:
            continue
        xi = _direct_xi(z, c, d_lo, d_hi, x[i])
        if not xi == xi:
            continue
        a, b = _leg(z, c, xi, d_hi), _leg(z, c, xi, d_lo)
        c_src, c_dst = _speed(z, c, d_src[i]), _speed(z, c, d_dst[i])
        s_src, s_dst = math.sqrt(1.0 - (xi * c_src) ** 2), math.sqrt(1.0 - (xi * c_dst) ** 2)
        out[i, D_XI], out[i, D_TIME], out[i, D_PATH] = xi, a[2] - b[2], a[3] - b[3]
        out[i, D_SPREAD] = (a[0] - b[0]) * (a[1] - b[1]) * s_src * s_dst / (c_src * c_src)
        out[i, D_SIN_SRC], out[i, D_SIN_DST], out[i, D_C_DST] = s_src, s_dst, c_dst
