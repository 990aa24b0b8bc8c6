"""Surface eigenrays in a layered sound-speed profile: S → surface → P without turning (docs/physics.md §12b).

A ray of Snell's invariant ξ = cos θ / c from depth 0 to depth d crosses the profile's linear pieces; per piece
(depths a < b, c_a and c_b at its ends, s = sin θ = √(1 − ξ²c²), Δz = b − a, g·Δz = c_b − c_a), in forms that
stay exact for a zero gradient and for ξ = 0:

    x/ξ = Δz(c_a + c_b)/(s_a + s_b),   ∂x/∂ξ = x/ξ·(1 + ξ²(c_a²/s_a + c_b²/s_b)/(s_a + s_b)),
    T = Δz/c_a·Λ(gΔz/c_a) + ξ²Δz(c_a + c_b)/((s_a + s_b)(1 + s_b))·Λ(q),   Λ(a) = ln(1 + a)/a,
    L = Δz(c_a + c_b)/(c_b s_a + c_a s_b)·atan2(y, s_a s_b + ξ²c_a c_b)/y,   y = ξ·gΔz(c_a + c_b)/(c_b s_a + c_a s_b),

with q = ξ²·gΔz·(c_a + c_b)/((s_a + s_b)(1 + s_b)): T = ln(c_b(1 + s_a)/(c_a(1 + s_b)))/g and
L = (asin ξc_b − asin ξc_a)/(gξ) rewritten through log1p and atan2 of their small arguments. The path from a source
at depth d_S up to the surface and down to d_P covers x(ξ) = ξ·(x/ξ)(d_S) + ξ·(x/ξ)(d_P), which grows from 0 at
ξ = 0; a safeguarded Newton search (bisection where Newton leaves the bracket) finds the ξ that covers a given
horizontal distance.
"""
from __future__ import annotations

import math

import numpy as np

from ._numba import njit, prange

#: Columns of :func:`surface_eigenrays`' output: ξ (s/m), one-way time (s), path length (m), tube area per steradian
#: at P (m²), horizontal distance from S to the surface point (m), sin θ at S, at P and at the surface, c at P (m/s).
E_XI, E_TIME, E_PATH, E_SPREAD, E_XUP, E_SIN_SRC, E_SIN_DST, E_SIN_TOP, E_C_DST = range(9)
EIGEN_WIDTH = 9
#: Newton steps at most (each at least halves the bracket when Newton leaves it), and the horizontal distance (m)
#: within which a ray has arrived.
EIGEN_ITERATIONS, EIGEN_TOL_M = 100, 1e-9


@njit(cache=True, nogil=True)
def _speed(z, c, d):
    """c at depth d of the profile (knots z (m,) from 0, speeds c (m,)): linear between knots, held beyond."""
    m = z.shape[0]
    if d <= z[0]:
        return c[0]
    for j in range(m - 1):
        if d <= z[j + 1]:
            return c[j] + (c[j + 1] - c[j]) * (d - z[j]) / (z[j + 1] - z[j])
    return c[m - 1]


@njit(cache=True, nogil=True)
def _log1p_over(a):
    if abs(a) < 1e-9:
        return 1.0 - 0.5 * a
    return math.log1p(a) / a


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _piece(z, c, j, xi, d_end):
    """(Δz, c_a, c_b, s_a, s_b) of piece j clipped at ``d_end`` (it starts above it); s NaN where the ray turns."""
    bottom = d_end if j + 1 >= z.shape[0] else min(d_end, z[j + 1])
    ca, cb = c[j], _speed(z, c, bottom)
    pa, pb = 1.0 - (xi * ca) ** 2, 1.0 - (xi * cb) ** 2
    if not (pa > 0.0 and pb > 0.0):
        return bottom - z[j], ca, cb, math.nan, math.nan
    return bottom - z[j], ca, cb, math.sqrt(pa), math.sqrt(pb)


@njit(cache=True, nogil=True)
def _x_terms(dz, ca, cb, sa, sb, xi):
    """A piece's x/ξ and ∂x/∂ξ."""
    q = dz * (ca + cb) / (sa + sb)
    return q, q * (1.0 + xi * xi * (ca * ca / sa + cb * cb / sb) / (sa + sb))


@njit(cache=True, nogil=True)
def _leg(z, c, xi, d_end):
    """(x/ξ, ∂x/∂ξ, T, L) of the ray of invariant ξ from depth 0 to ``d_end``; NaN where it turns on the way."""
    x_xi, dx, t, length = 0.0, 0.0, 0.0, 0.0
    for j in range(z.shape[0]):
        if d_end <= z[j]:
            break
        dz, ca, cb, sa, sb = _piece(z, c, j, xi, d_end)
        if not sa == sa:
            return math.nan, math.nan, math.nan, math.nan
        q, dq = _x_terms(dz, ca, cb, sa, sb, xi)
        x_xi += q
        dx += dq
        g_dz = cb - ca
        r = xi * xi * g_dz * (ca + cb) / ((sa + sb) * (1.0 + sb))
        t += dz / ca * _log1p_over(g_dz / ca) + xi * xi * dz * (ca + cb) / ((sa + sb) * (1.0 + sb)) * _log1p_over(r)
        den = cb * sa + ca * sb
        y = xi * g_dz * (ca + cb) / den
        xq = sa * sb + xi * xi * ca * cb
        ratio = (1.0 - (y / xq) ** 2 / 3.0) / xq if abs(y) < 1e-9 * xq else math.atan2(y, xq) / y
        length += dz * (ca + cb) / den * ratio
    return x_xi, dx, t, length


@njit(cache=True, nogil=True)
def _leg_x(z, c, xi, d_end):
    """(x/ξ, ∂x/∂ξ) of :func:`_leg` alone (the search needs no time or length)."""
    x_xi, dx = 0.0, 0.0
    for j in range(z.shape[0]):
        if d_end <= z[j]:
            break
        dz, ca, cb, sa, sb = _piece(z, c, j, xi, d_end)
        if not sa == sa:
            return math.nan, math.nan
        q, dq = _x_terms(dz, ca, cb, sa, sb, xi)
        x_xi += q
        dx += dq
    return x_xi, dx


@njit(cache=True, nogil=True)
def _solve(z, c, d_src, d_dst, x, c_max):
    """ξ of the surface ray from depth d_src to d_dst covering x, or NaN when no unturned ray reaches it."""
    start = x / math.sqrt(x * x + (d_src + d_dst) ** 2) / _speed(z, c, d_src)      # the straight ray's, to start
    return newton_xi(z, c, (d_src, d_dst, 1.0), x, start, (1.0 - 1e-12) / c_max)


@njit(cache=True, nogil=True)
def _pair_x(z, c, xi, legs):
    """(x/ξ, ∂x/∂ξ) of the path ``legs`` = (d_a, d_b, sign): the ray of invariant ξ from depth 0 to d_a plus
    (sign +1: up to the surface and down again) or less (−1: between two depths) the one from 0 to d_b."""
    d_a, d_b, sign = legs
    a, b = _leg_x(z, c, xi, d_a), _leg_x(z, c, xi, d_b)
    return a[0] + sign * b[0], a[1] + sign * b[1]


@njit(cache=True, nogil=True)
def newton_xi(z, c, legs, x, start, hi):
    """ξ in (0, hi) of the path ``legs`` (:func:`_pair_x`) that covers the horizontal distance x, or NaN when even
    ξ = hi falls short: a safeguarded Newton search from ``start`` (bisection where Newton leaves the bracket)."""
    top = _pair_x(z, c, hi, legs)
    if not (hi * top[0] >= x):
        return math.nan
    lo, xi = 0.0, start
    if not xi < hi:
        xi = 0.5 * hi
    for _ in range(EIGEN_ITERATIONS):
        q, dq = _pair_x(z, c, xi, legs)
        f = xi * q - x
        if abs(f) < EIGEN_TOL_M:
            return xi
        if f < 0.0:
            lo = xi
        else:
            hi = xi
        step = xi - f / dq
        xi = step if lo < step < hi else 0.5 * (lo + hi)
    return xi


@njit(cache=True, nogil=True, parallel=True)
def surface_eigenrays(z, c, d_src, d_dst, x, out):
    """The surface eigenray of every point: from depth ``d_src`` up to the surface and down to ``d_dst`` over the
    horizontal distance ``x`` (all (n,), m).

    Parameters
    ----------
    z, c : (m,) float64
        The profile's knots (depths from 0, m) and speeds there (m/s); linear between knots, held beyond.
    d_src, d_dst, x : (n,) float64
        Source depth, point depth and horizontal distance, m.
    out : (n, EIGEN_WIDTH) float64
        Written: the columns ``E_*`` (ξ, time, path, A₂ = (x/ξ)·(∂x/∂ξ)·sin θ_S·sin θ_P / c_S², x_up, the three
        sines, c at P); time NaN where no unturned ray reaches the point.
    """
    for i in prange(x.shape[0]):
        xi, t, length, spread, x_up, s_src, s_dst, s_top2, c_dst = _eigenray(z, c, d_src[i], d_dst[i], x[i])
        out[i, E_XI], out[i, E_C_DST] = xi, c_dst
        if not xi == xi:
            for k in range(1, EIGEN_WIDTH - 1):
                out[i, k] = math.nan
            continue
        out[i, E_TIME], out[i, E_PATH], out[i, E_SPREAD], out[i, E_XUP] = t, length, spread, x_up
        out[i, E_SIN_SRC], out[i, E_SIN_DST], out[i, E_SIN_TOP] = s_src, s_dst, math.sqrt(s_top2)


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _eigenray(z, c, d_src, d_dst, x):
    """(ξ, T, L, A₂, x_up, sin θ_S, sin θ_P, sin²θ at the surface, c_P) of the surface ray from depth d_src to d_dst
    over x (:func:`surface_eigenrays`); ξ NaN (and the rest unset but c_P) where no unturned ray reaches it."""
    xi = _solve(z, c, d_src, d_dst, x, _c_max(z, c, d_src, d_dst))
    c_src, c_dst = _speed(z, c, d_src), _speed(z, c, d_dst)
    if not xi == xi:
        return xi, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, c_dst
    up, down = _leg(z, c, xi, d_src), _leg(z, c, xi, d_dst)
    s_src, s_dst = math.sqrt(1.0 - (xi * c_src) ** 2), math.sqrt(1.0 - (xi * c_dst) ** 2)
    spread = (up[0] + down[0]) * (up[1] + down[1]) * s_src * s_dst / (c_src * c_src)
    return (xi, up[2] + down[2], up[3] + down[3], spread, xi * up[0], s_src, s_dst, 1.0 - (xi * c[0]) ** 2,
            c_dst)


@njit(cache=True, nogil=True, parallel=True)
def surface_reach(z, c, xi, d_src, out):
    """Horizontal distance (m) from a source at depth ``d_src`` (n,) up to where its ray of invariant ``xi`` (n,)
    meets the surface, into ``out`` (n,); profile ``z``, ``c`` as for :func:`surface_eigenrays`."""
    for i in prange(xi.shape[0]):
        out[i] = xi[i] * _leg(z, c, xi[i], d_src[i])[0]


#: Columns of :func:`curved_mixed`'s output: weight (without the beam's gains and σ), travel time (s), its extent (s),
#: cos θi, cos θs, the bistatic azimuth φ (rad; 0 unless asked for), the horizontal distance from the sonar to the
#: surface point (m) and the surface ray's launch direction u₂ (3 columns from ``M_U2``, world, z up).
M_W, M_T, M_EXT, M_COS_I, M_COS_S, M_PHI, M_XUP, M_U2 = range(8)
MIX_WIDTH = 10


@njit(cache=True, nogil=True)
def _c_max(z, c, d_src, d_dst):
    """The fastest c between the surface and the deeper of the two depths."""
    deepest = max(d_src, d_dst)
    out = max(c[0], max(_speed(z, c, d_src), _speed(z, c, d_dst)))
    for j in range(z.shape[0]):
        if z[j] < deepest:
            out = max(out, c[j])
    return out


@njit(cache=True, nogil=True, parallel=True)
def curved_mixed(hits, launch, poses, face_normals, medium, weighting, out):
    """The one-bounce paths (S → P → surface → S and back) of a curved fan's direct hits, without the beam's gains, σ
    or blocking (docs/physics.md §12b).

    Per lit hit P: the surface eigenray from the sonar to P (:func:`surface_eigenrays`), and

        w = |R_s|²·e^(−α'(L₁ + L₂))·ds·dβ / (max(A₂, R_min²)·cos θi),

    at T₁ + T₂ (one-way times), with |R_s|² = exp(−4(k·h_w)²·sin²θg), θi from the direct ray's arrival and θs from
    the surface ray's (its direction back from P); zero where no unturned eigenray exists, or either cosine is not
    positive. The beam's gains Γ²(u₁)·Γ²_rx(u₂) + Γ²(u₂)·Γ²_rx(u₁) (u₁ the direct ray's launch, u₂ the surface ray's:
    ξ·c_S horizontally towards P, upwards, written to ``M_U2``) are multiplied in after this kernel
    (:func:`~sonar_embree.kernels.rays.weigh_pairs`). The
    extent is the direct echo's ΔT₁ (half its two-way extent) times 1 + (p₂·f)/(p₁·f) (at most 11), p the rays'
    directions at P and f the horizontal direction away from the sonar in the facet's plane.

    Parameters
    ----------
    hits : :data:`~sonar_embree.kernels.args.CurvedHits`
        Per ray of the fan (n,): hit point (n, 3) (local, m), triangle (int32), unit direction of arrival (n, 3),
        path length L₁ (float32, m), two-way time 2T₁ (s), two-way extent (s), whether it is lit (bool).
    launch : :data:`~sonar_embree.kernels.args.Launch`
        Each ray's cell dβ (n,) (rad) and row (n,) int64 (2·ping + side).
    poses : :data:`~sonar_embree.kernels.args.Poses`
    face_normals : (f, 3) float64
    medium : :data:`~sonar_embree.kernels.args.Medium`
        The profile's knots ``z`` (from depth 0, m) and speeds ``c`` (m/s), and the surface's local height (m).
    weighting : :data:`~sonar_embree.kernels.args.MixedWeighting`
        Two-way absorption (Np/m), the fan's ds, R_min (m), k·h_w and whether to write φ.
    out : (n, MIX_WIDTH) float64
        Written, the columns ``M_*``.
    """
    lit = hits.lit
    for i in prange(lit.shape[0]):
        for k in range(MIX_WIDTH):
            out[i, k] = 0.0
        out[i, M_T] = math.inf
        if lit[i]:
            _mixed_one(i, hits, launch, poses, face_normals, medium, weighting, out)


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _mixed_one(i, hits, launch, poses, face_normals, medium, weighting, out):
    """Row i of :func:`curved_mixed` (a lit hit): the surface eigenray (:func:`_surface_leg`), the facet's cosines,
    the weight and extent."""
    two_way, ds, r_min, kh, want_phi = weighting
    b = launch.row[i] // 2
    hx, hy, xi, t2, l2, spread, x_up, s_top2, c_src, s_src, c_dst, s_dst = _surface_leg(i, b, hits, poses, medium,
                                                                                         r_min)
    if not xi == xi:                                          # no unturned eigenray
        return
    u2 = (hx * xi * c_src, hy * xi * c_src, s_src)              # S → surface, world (z up)
    v = (-hx * xi * c_dst, -hy * xi * c_dst, s_dst)             # P → where the surface path comes from
    n0, n1, n2, cos_i, cos_s = _facet_cosines(i, hits, face_normals, v)
    n = (n0, n1, n2)
    if not (cos_i > 0.0 and cos_s > 0.0):
        return
    w = (math.exp(-4.0 * kh * kh * s_top2)
         * math.exp(-0.5 * two_way * (np.float64(hits.path[i]) + l2)) * ds * launch.dbeta[i] / (spread * cos_i))
    if not w > 0.0:
        return
    out[i, M_W], out[i, M_T] = w, 0.5 * hits.time[i] + t2
    out[i, M_U2], out[i, M_U2 + 1], out[i, M_U2 + 2] = u2
    out[i, M_EXT] = _mixed_extent(i, hits, n, hx, hy, v)
    out[i, M_COS_I], out[i, M_COS_S], out[i, M_XUP] = cos_i, cos_s, x_up
    if want_phi:
        out[i, M_PHI] = _mixed_phi(i, hits, n, v)


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _surface_leg(i, b, hits, poses, medium, r_min):
    """The surface eigenray from ping b's sonar to hit i: (h_x, h_y, ξ (NaN: none), T₂ (s), L₂ (m), max(A₂, R_min²),
    x_up (m), sin²θ at the surface, c and sin θ at the sonar, c and sin θ at the hit)."""
    point, pos = hits.point, poses.pos
    z, c, z_s = medium
    hx, hy = point[i, 0] - pos[b, 0], point[i, 1] - pos[b, 1]
    x = math.sqrt(hx * hx + hy * hy)
    if x > 0.0:
        hx, hy = hx / x, hy / x
    else:                                                   # straight below: any azimuth (ξ = 0)
        hx, hy = 1.0, 0.0
    d_src, d_dst = z_s - pos[b, 2], z_s - point[i, 2]
    xi, t2, l2, spread, x_up, s_src, s_dst, s_top2, c_dst = _eigenray(z, c, d_src, d_dst, x)
    c_src = _speed(z, c, d_src) if xi == xi else math.nan
    return hx, hy, xi, t2, l2, max(spread, r_min * r_min), x_up, s_top2, c_src, s_src, c_dst, s_dst


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _facet_cosines(i, hits, face_normals, v):
    """(n₀, n₁, n₂ facing the arrival, cos θi of the direct arrival, cos θs along ``v``) of hit i (scalars: Numba's
    parfors take a tuple returned by an inlined function for a shape)."""
    p, a = hits.prim[i], hits.arrival
    n0, n1, n2 = face_normals[p, 0], face_normals[p, 1], face_normals[p, 2]
    a0, a1, a2 = a[i, 0], a[i, 1], a[i, 2]
    if n0 * a0 + n1 * a1 + n2 * a2 > 0.0:
        n0, n1, n2 = -n0, -n1, -n2
    return n0, n1, n2, -(n0 * a0 + n1 * a1 + n2 * a2), n0 * v[0] + n1 * v[1] + n2 * v[2]


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _mixed_extent(i, hits, n, hx, hy, v):
    """The one-bounce echo's travel-time extent: the direct echo's ΔT₁ × (1 + min(|p₂·f| / |p₁·f|, 10))."""
    a = hits.arrival
    n0, n1, n2 = n
    nf = n0 * hx + n1 * hy
    f0, f1, f2 = hx - n0 * nf, hy - n1 * nf, -n2 * nf              # away from the sonar, in the facet
    p1 = a[i, 0] * f0 + a[i, 1] * f1 + a[i, 2] * f2
    p2 = -(v[0] * f0 + v[1] * f1 + v[2] * f2)
    return 0.5 * hits.extent[i] * (1.0 + min(abs(p2) / max(abs(p1), 1e-12), 10.0))


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _mixed_phi(i, hits, n, v):
    """The bistatic azimuth of hit i: between its arrival reversed and ``v``, in the facet of normal ``n``."""
    a = hits.arrival
    return _azimuth(n[0], n[1], n[2], a[i, 0], a[i, 1], a[i, 2], v[0], v[1], v[2])


@njit(cache=True, nogil=True)
def _azimuth(n0, n1, n2, a0, a1, a2, v0, v1, v2):
    """Angle between −a and v projected on the plane of normal n (0 when either is along n)."""
    na, nv = -(n0 * a0 + n1 * a1 + n2 * a2), n0 * v0 + n1 * v1 + n2 * v2
    b0, b1, b2 = -a0 - na * n0, -a1 - na * n1, -a2 - na * n2
    t0, t1, t2 = v0 - nv * n0, v1 - nv * n1, v2 - nv * n2
    bb, tt = b0 * b0 + b1 * b1 + b2 * b2, t0 * t0 + t1 * t1 + t2 * t2
    if bb <= 1e-24 or tt <= 1e-24:
        return 0.0
    return math.acos(min(max((b0 * t0 + b1 * t1 + b2 * t2) / math.sqrt(bb * tt), -1.0), 1.0))
