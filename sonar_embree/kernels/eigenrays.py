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


@njit(cache=True, nogil=True)
def _leg(z, c, xi, d_end):
    """(x/ξ, ∂x/∂ξ, T, L) of the ray of invariant ξ from depth 0 to ``d_end``; NaN where it turns on the way."""
    x_xi, dx, t, length = 0.0, 0.0, 0.0, 0.0
    m = z.shape[0]
    for j in range(m):
        top = z[j]
        if d_end <= top:
            break
        bottom = d_end if j + 1 >= m else min(d_end, z[j + 1])
        dz = bottom - top
        ca, cb = c[j], _speed(z, c, bottom)
        pa, pb = 1.0 - (xi * ca) ** 2, 1.0 - (xi * cb) ** 2
        if not (pa > 0.0 and pb > 0.0):
            return math.nan, math.nan, math.nan, math.nan
        sa, sb = math.sqrt(pa), math.sqrt(pb)
        q = dz * (ca + cb) / (sa + sb)
        x_xi += q
        dx += q * (1.0 + xi * xi * (ca * ca / sa + cb * cb / sb) / (sa + sb))
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
    m = z.shape[0]
    for j in range(m):
        top = z[j]
        if d_end <= top:
            break
        bottom = d_end if j + 1 >= m else min(d_end, z[j + 1])
        ca, cb = c[j], _speed(z, c, bottom)
        pa, pb = 1.0 - (xi * ca) ** 2, 1.0 - (xi * cb) ** 2
        if not (pa > 0.0 and pb > 0.0):
            return math.nan, math.nan
        sa, sb = math.sqrt(pa), math.sqrt(pb)
        q = (bottom - top) * (ca + cb) / (sa + sb)
        x_xi += q
        dx += q * (1.0 + xi * xi * (ca * ca / sa + cb * cb / sb) / (sa + sb))
    return x_xi, dx


@njit(cache=True, nogil=True)
def _solve(z, c, d_src, d_dst, x, c_max):
    """ξ of the surface ray from depth d_src to d_dst covering x, or NaN when no unturned ray reaches it."""
    lo, hi = 0.0, (1.0 - 1e-12) / c_max
    uh, dh = _leg_x(z, c, hi, d_src), _leg_x(z, c, hi, d_dst)
    if not (hi * (uh[0] + dh[0]) >= x):
        return math.nan
    xi = 0.0
    for _ in range(EIGEN_ITERATIONS):
        up, down = _leg_x(z, c, xi, d_src), _leg_x(z, c, xi, d_dst)
        f = xi * (up[0] + down[0]) - x
        if abs(f) < EIGEN_TOL_M:
            return xi
        if f < 0.0:
            lo = xi
        else:
            hi = xi
        step = xi - f / (up[1] + down[1])
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
    top_speed = c[0]
    for i in prange(x.shape[0]):
        deepest = max(d_src[i], d_dst[i])
        c_max = max(top_speed, max(_speed(z, c, d_src[i]), _speed(z, c, d_dst[i])))
        for j in range(z.shape[0]):
            if z[j] < deepest:
                c_max = max(c_max, c[j])
        xi = _solve(z, c, d_src[i], d_dst[i], x[i], c_max)
        c_src, c_dst = _speed(z, c, d_src[i]), _speed(z, c, d_dst[i])
        out[i, E_XI], out[i, E_C_DST] = xi, c_dst
        if not xi == xi:
            for k in range(1, EIGEN_WIDTH - 1):
                out[i, k] = math.nan
            continue
        up, down = _leg(z, c, xi, d_src[i]), _leg(z, c, xi, d_dst[i])
        s_src, s_dst = math.sqrt(1.0 - (xi * c_src) ** 2), math.sqrt(1.0 - (xi * c_dst) ** 2)
        out[i, E_TIME], out[i, E_PATH] = up[2] + down[2], up[3] + down[3]
        out[i, E_SPREAD] = (up[0] + down[0]) * (up[1] + down[1]) * s_src * s_dst / (c_src * c_src)
        out[i, E_XUP] = xi * up[0]
        out[i, E_SIN_SRC], out[i, E_SIN_DST] = s_src, s_dst
        out[i, E_SIN_TOP] = math.sqrt(1.0 - (xi * top_speed) ** 2)


@njit(cache=True, nogil=True, parallel=True)
def surface_reach(z, c, xi, d_src, out):
    """Horizontal distance (m) from a source at depth ``d_src`` (n,) up to where its ray of invariant ``xi`` (n,)
    meets the surface, into ``out`` (n,); profile ``z``, ``c`` as for :func:`surface_eigenrays`."""
    for i in prange(xi.shape[0]):
        out[i] = xi[i] * _leg(z, c, xi[i], d_src[i])[0]
