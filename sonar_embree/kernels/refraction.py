"""Curved rays in a layered sound-speed profile, marched chord by chord (docs/physics.md §12).

A ray in a layer where c = c_top + g·(depth − top) keeps Snell's invariant ξ = cos θ / c
(θ the grazing angle, signed: positive going down) and turns at the constant rate
dθ/ds = −κ, κ = ξg, along its arc length s. From θa, after an arc length Δs
(θb = θa − κΔs, θm = (θa + θb)/2):

    Δx = Δs·cos θm·sinc(κΔs/2),   Δdepth = Δs·sin θm·sinc(κΔs/2),
    Δt = (asinh tan θa − asinh tan θb) / g     (= Δs·ξ / cos θm as κΔs → 0),

the closed-form arcs of Jensen et al. (*Computational Ocean Acoustics*, 2nd ed., 2011, ch. 3)
written so that they stay exact for g → 0 and through a turning point (θ changes sign).
Each step is one chord, short enough that it stands off its arc by at most a given sagitta
(Δs ≤ √(8·sagitta/|κ|)), cast as one Embree segment; knots end a step, so a chord never
crosses one. A chord's hit is then moved onto the arc: Newton's method on the arc length
puts it on the hit triangle's plane (so the sagitta costs no accuracy, only the rare ray that
the chord and the arc see differently at an edge), with the arc's tangent as the incident
direction.

The tube spreading needs J = ∂x/∂ξ at constant depth: over a layer segment from θa to θb
it is X̃/(sin θa·sin θb) with X̃ = Δx/ξ, so that the ray tube's area per steradian is
A_Ω = X̃_total·|M| / c0², M = sin θ0·sin θh·J (A_Ω = R² for straight rays).

Per-ray state, ``state[i]`` (:data:`STATE_WIDTH` columns): position (local frame, m) ×3,
path length L (m); then at the start of the current layer segment: T (s), L (m),
depth (m), sin θ, the horizontal coordinate along the ray's azimuth (m) and X̃ (m²/s);
P = sin θ0·J of the finished segments; ra = sin θ0 / sin θ at the segment's start (1 on the
first); cos θ and sin θ (θ itself is never needed: its sign is sin θ's, and the library's atan2 of
every launch cost a fifth of the launch kernel). Times and X̃ are evaluated only at knots and hits, from the segment's start in one
closed form (X̃ = Δx/ξ from the positions). ``ray[i]``: horizontal direction (2), ξ (s/m),
sin θ0, c0. Turning by u = κΔs, the offsets use sin u / u and (1 − cos u)/u, as
polynomials for the small u of a chord (no transcendental functions on the hot path).
"""
from __future__ import annotations

import math

import numpy as np

from ._numba import REFIT_MIN_COS, REFIT_REL_TOL, njit, prange
from .rays import fan_cell, row_rays

#: Columns of a ray's marching state (see the module docstring).
STATE_WIDTH = 14
#: Newton steps that move a chord's hit onto the arc, and the step (m) below which it has arrived.
NEWTON_STEPS = 4
NEWTON_TOL_M = 1e-6
# state columns: position, L; at the segment's start T, L, depth, sin θ, horizontal coordinate, X̃; P; ra
S_L, S_T0, S_L0, S_D0, S_SN0, S_XH0, S_X0, S_P, S_RA = 3, 4, 5, 6, 7, 8, 9, 10, 11
# and cos θ, sin θ of the current θ (carried by the exact rotations, not recomputed)
S_CT, S_ST = 12, 13
#: Below this turn u (rad) sin u / u and (1 − cos u)/u are taken from their series (error < u⁶/5040).
SERIES_MAX_U = 0.05
#: Columns of a ray's constants: h_x, h_y, ξ, sin θ0, c0.
RAY_WIDTH = 5
#: Smallest |sin θ| divided by at a layer crossing (a turning point exactly on a knot).
MIN_SIN = 1e-12
# Helpers that take arrays are inlined (inline='always'): a call per ray with array arguments costs reference
# counting that the threads contend for (measured: the chord kernel 1.6× slower); scalar helpers stay calls.
#: Closed-form steps a ray outside the scene's height range may take in one call (knots and turns).
MAX_SKIPS = 64


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _layer(layers, k):
    """Layer k as scalars, (top depth (m), c at the top (m/s), gradient (s⁻¹), bottom depth (m; inf for the last)):
    what the per-step helpers take, so that they are called without an array (no reference counting per ray)."""
    return layers[k, 0], layers[k, 1], layers[k, 2], layers[k + 1, 0] if k < layers.shape[0] - 1 else math.inf


@njit(cache=True, nogil=True)
def _speed(lk, depth):
    """c at ``depth`` in the layer ``lk`` (:func:`_layer`), m/s."""
    g = lk[2]
    if g == 0.0:
        return lk[1]
    return lk[1] + g * (depth - lk[0])


@njit(cache=True, nogil=True)
def _layer_of(layers, depth):
    """Index of the layer holding ``depth`` (a depth on a knot belongs to the layer below it)."""
    k = 0
    while k + 1 < layers.shape[0] and depth >= layers[k + 1, 0]:
        k += 1
    return k


@njit(cache=True, nogil=True, parallel=True)
def arc_start(s, cos_beta, sin_beta, el_start, rot, pos, layers, z0, box_z, l_max, state, lay, ray,
              layout):
    """Launch state of every ray of a block of side-scan fans (directions as :func:`fan_rays`), moved in closed
    form to the scene's height range if it starts outside (:func:`_skip_outside`).

    Parameters
    ----------
    s, cos_beta, sin_beta, el_start, rot, pos
        The block's fan, as for :func:`~sonar_embree.kernels.rays.fan_rays` (float64).
    layers : (k, 3) float64
        Layer tops (depth, m; −inf first), c there (m/s), gradient (s⁻¹).
    z0 : float
        Local z of depth 0, m.
    box_z, l_max
        As for :func:`arc_chord`.
    state : (n, STATE_WIDTH) float64; lay : (n,) int64; ray : (n, RAY_WIDTH) float64
        Written.
    layout : (n, 5) or (0, 5) float64
        Each ray's own s, cos β, sin β (, dβ, ds): rays aimed at objects (:mod:`sonar_embree.propagation.aim`), row r's
        rays ``el_start[r] … el_start[r + 1] − 1``; ``s``, ``cos_beta``, ``sin_beta`` are then not read. No rows
        (``NO_LAYOUT``): the fan's layout.
    """
    n_az = s.shape[0]
    per_ray = layout.shape[0] > 0
    for r in prange(el_start.shape[0] - 1):
        b = r // 2
        side = 1.0 if r % 2 else -1.0
        n_el = el_start[r + 1] - el_start[r]
        base = el_start[r] if per_ray else n_az * el_start[r]
        depth = z0 - pos[b, 2]
        k = _layer_of(layers, depth)
        c0 = _speed(_layer(layers, k), depth)
        for i in range(base, base + (n_el if per_ray else n_az * n_el)):
            if per_ray:
                sa, cb, sb = layout[i, 0], layout[i, 1], layout[i, 2]
            else:
                sa = s[(i - base) // n_el]
                cb, sb = cos_beta[el_start[r] + (i - base) % n_el], sin_beta[el_start[r] + (i - base) % n_el]
            cpsi = math.sqrt(1.0 - sa * sa)
            e1 = side * cpsi * cb
            e2 = cpsi * sb
            ux = rot[b, 0, 0] * sa + rot[b, 0, 1] * e1 + rot[b, 0, 2] * e2
            uy = rot[b, 1, 0] * sa + rot[b, 1, 1] * e1 + rot[b, 1, 2] * e2
            uz = rot[b, 2, 0] * sa + rot[b, 2, 1] * e1 + rot[b, 2, 2] * e2
            _start_ray(state, ray, i, (pos[b, 0], pos[b, 1], pos[b, 2]), (ux, uy, uz), depth, c0)
            lay[i] = _skip_outside(state, i, k, ray, layers, z0, box_z[0], box_z[1], l_max)


@njit(cache=True, nogil=True, parallel=True)
def arc_start_at(origins, dirs, layers, z0, box_z, l_max, state, lay, ray):
    """Launch state of rays from their own origins (n, 3) (local frame, m) along their own world unit directions
    (n, 3) (a swell's mirrored rays, :mod:`sonar_embree.propagation.curved_swell`), moved in closed form to the
    scene's height range as :func:`arc_start`; ``layers``, ``z0``, ``box_z``, ``l_max`` and the outputs as there."""
    for i in prange(origins.shape[0]):
        depth = z0 - origins[i, 2]
        k = _layer_of(layers, depth)
        c0 = _speed(_layer(layers, k), depth)
        o, u = (origins[i, 0], origins[i, 1], origins[i, 2]), (dirs[i, 0], dirs[i, 1], dirs[i, 2])
        _start_ray(state, ray, i, o, u, depth, c0)
        lay[i] = _skip_outside(state, i, k, ray, layers, z0, box_z[0], box_z[1], l_max)


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _start_ray(state, ray, i, o, u, depth, c0):
    """Ray i's constants and marching state leaving point ``o`` (local, m) along the world unit direction ``u`` at
    ``depth`` (m), where c is ``c0`` (see the module docstring's columns)."""
    ox, oy, oz = o
    ux, uy, uz = u
    hz = math.sqrt(ux * ux + uy * uy)
    ray[i, 0] = ux / hz if hz > 0.0 else 1.0
    ray[i, 1] = uy / hz if hz > 0.0 else 0.0
    ray[i, 2] = hz / c0
    ray[i, 3] = -uz
    ray[i, 4] = c0
    state[i, 0] = ox
    state[i, 1] = oy
    state[i, 2] = oz
    for q in range(S_L, STATE_WIDTH):
        state[i, q] = 0.0
    state[i, S_D0] = depth
    state[i, S_SN0] = -uz
    state[i, S_XH0] = ox * ray[i, 0] + oy * ray[i, 1]
    state[i, S_RA] = 1.0
    state[i, S_CT] = hz
    state[i, S_ST] = -uz


@njit(cache=True, nogil=True)
def _turn(ca, sa, kappa, ds):
    """(Δx, Δdepth, cos θb, sin θb) after an arc length ``ds`` from θa (cos ``ca``, sin ``sa``), θb = θa − κ·ds.

    Δx = ds·(cos θa·S + sin θa·C), Δdepth = ds·(sin θa·S − cos θa·C) with S = sin u / u, C = (1 − cos u)/u,
    u = κ·ds (straight for u = 0).
    """
    u = kappa * ds
    if abs(u) < SERIES_MAX_U:
        u2 = u * u
        sinc_u = 1.0 - u2 * (1.0 / 6.0) * (1.0 - u2 * (1.0 / 20.0) * (1.0 - u2 * (1.0 / 42.0)))  # products:
        cosc_u = 0.5 * u * (1.0 - u2 * (1.0 / 12.0) * (1.0 - u2 * (1.0 / 30.0) * (1.0 - u2 * (1.0 / 56.0))))  # no divisions
    else:
        sinc_u = math.sin(u) / u
        cosc_u = (1.0 - math.cos(u)) / u
    cos_u = 1.0 - u * cosc_u
    sin_u = u * sinc_u
    return (ds * (ca * sinc_u + sa * cosc_u), ds * (sa * sinc_u - ca * cosc_u),
            ca * cos_u + sa * sin_u, sa * cos_u - ca * sin_u)


@njit(cache=True, nogil=True)
def _angle(y, x):
    """atan2(y, x); for |y| < SERIES_MAX_U·x (a layer segment's turn) from its series to z⁹, z = y/x (relative
    error < z¹⁰/11 < 10⁻¹⁴), without the library call."""
    if x > 0.0 and abs(y) < SERIES_MAX_U * x:
        z = y / x
        z2 = z * z
        return z * (1.0 - z2 * (1.0 / 3.0 - z2 * (0.2 - z2 * (1.0 / 7.0 - z2 * (1.0 / 9.0)))))
    return math.atan2(y, x)


@njit(cache=True, nogil=True)
def _boundary(lk, sa, xi, lo, hi):
    """Where a curved ray leaves depths [lo, hi] of the layer ``lk``: (cos θ, sin θ there, depth there), cos θ = ξc
    (Snell); ξc ≥ 1 at one edge means the ray turns before it and leaves by the other."""
    kappa = xi * lk[2]
    c_hi = _speed(lk, hi)
    c_lo = _speed(lk, lo)
    if kappa > 0.0:
        down = sa > 0.0 and xi * c_hi < 1.0
    else:
        down = not (sa < 0.0 and xi * c_lo < 1.0)
    cb = min(xi * (c_hi if down else c_lo), 1.0)
    sb = math.sqrt(1.0 - cb * cb)
    return cb, sb if down else -sb, hi if down else lo


@njit(cache=True, nogil=True)
def _stays(lk, depth, dd, sa, sb, xi, lo, hi):
    """Whether an arc from ``depth`` (sin θ ``sa``) to depth + ``dd`` (sin θ ``sb``) stays inside (lo, hi)."""
    d_end = depth + dd
    if not (lo < d_end < hi):
        return False
    if sa * sb > 0.0:
        return True
    g = lk[2]  # it turned on the way: at the depth where ξc = 1
    d_turn = lk[0] + (1.0 / xi - lk[1]) / g if g != 0.0 else depth
    return lo < d_turn < hi


@njit(cache=True, nogil=True)
def _step(lk, k, depth, ca, sa, xi, sagitta_m, ds_max, d_lo, d_hi):
    """One step of a ray in layer k (``lk``: :func:`_layer`) between depths ``d_lo`` and ``d_hi`` (stops, or ±inf),
    at most ``ds_max``.

    Returns (Δs, layer after, depth to snap to or NaN, Δx, Δdepth, cos θ and sin θ after): to the next
    knot or stop depth, to the chord limit (a chord of arc length Δs on radius 1/|κ| stands off the arc
    by Δs²|κ|/8, so Δs ≤ √(8·sagitta/|κ|)), or to ``ds_max``.
    """
    kappa = xi * lk[2]
    top, bot = lk[0], lk[3]
    lo = max(top, d_lo)
    hi = min(bot, d_hi)
    ds = ds_max
    if kappa != 0.0:
        ds = min(ds, math.sqrt(8.0 * sagitta_m / abs(kappa)))
    if ds < math.inf:  # the common case: a chord (or the rest of the window) that stays inside
        dx, dd, cb, sb = _turn(ca, sa, kappa, ds)
        if _stays(lk, depth, dd, sa, sb, xi, lo, hi):
            return ds, k, math.nan, dx, dd, cb, sb
    if kappa == 0.0:
        if sa > 0.0 and hi < math.inf:
            ds, d_b = (hi - depth) / sa, hi
        elif sa < 0.0 and lo > -math.inf:
            ds, d_b = (lo - depth) / sa, lo
        else:
            return math.inf, k, math.nan, math.inf, 0.0, ca, sa
    else:
        cb, sb, d_b = _boundary(lk, sa, xi, lo, hi)
        dth = _angle(sa * cb - ca * sb, ca * cb + sa * sb)  # θ − θb, well conditioned at any angle
        if dth * kappa < 0.0:
            dth = 0.0
        ds = dth / kappa
        dx, dd, _, _ = _turn(ca, sa, kappa, ds)
        return ds, k + 1 if d_b == bot else (k - 1 if d_b == top else k), d_b, dx, dd, cb, sb
    k_b = k + 1 if d_b == bot else (k - 1 if d_b == top else k)
    dx, dd, cb, sb = _turn(ca, sa, kappa, ds)
    return ds, k_b, d_b, dx, dd, cb, sb


@njit(cache=True, nogil=True)
def _seg_dt_xt(lk, d_a, s_a, d_b, s_b, dxh, ds, xi):
    """One-way time (s) and X̃ = Δx/ξ (m²/s) of a segment in the layer ``lk`` from depth ``d_a`` (sin θ ``s_a``)
    to ``d_b``.

    Δt = (asinh tan θa − asinh tan θb)/g with asinh tan θ = ln((1 + sin θ)/(ξc)), one logarithm taken on the
    side away from sin θ = ∓1, or ∫ds/c by the trapezoid where that difference is below 1e-5 (then exact to
    ~1e-11); straight rays Δs/c, a vertical ray in a gradient ln(c_b/c_a)/g.
    """
    g = lk[2]
    c_a = _speed(lk, d_a)
    if g == 0.0:
        return ds / c_a, ds * c_a
    c_b = _speed(lk, d_b)
    if xi == 0.0:
        return math.log(c_b / c_a) / g, 0.5 * ds * (c_a + c_b)
    if s_a + s_b >= 0.0:
        df = math.log((1.0 + s_a) * c_b / ((1.0 + s_b) * c_a))
    else:
        df = math.log((1.0 - s_b) * c_a / ((1.0 - s_a) * c_b))
    dt = df / g if abs(df) > 1e-5 else 2.0 * ds / (c_a + c_b)
    return dt, dxh / xi


@njit(cache=True, nogil=True, inline='always')
def _close_segment(out, o, k, ray, i, layers, depth_b, sin_b):
    """Ray i (state ``out[o]``) reached a knot at ``depth_b``: the finished layer segment's T, X̃ and J join
    the totals. (Rows are passed as array and index: a row view per ray costs reference counting that the
    threads contend for.)"""
    xh = out[o, 0] * ray[i, 0] + out[o, 1] * ray[i, 1]
    dt, xt = _seg_dt_xt(_layer(layers, k), out[o, S_D0], out[o, S_SN0], depth_b, sin_b, xh - out[o, S_XH0],
                        out[o, S_L] - out[o, S_L0], ray[i, 2])
    sb = math.copysign(max(abs(sin_b), MIN_SIN), sin_b)
    out[o, S_T0] += dt
    out[o, S_X0] += xt
    out[o, S_P] += out[o, S_RA] * xt / sb
    out[o, S_RA] = ray[i, 3] / sb
    out[o, S_L0] = out[o, S_L]
    out[o, S_D0] = depth_b
    out[o, S_SN0] = sin_b
    out[o, S_XH0] = xh


@njit(cache=True, nogil=True, inline='always')
def _advance(st, si, k, ray, i, layers, z0, sagitta_m, l_max, d_lo, d_hi, out, o):
    """One step of ray i from state ``st[si]`` (see :func:`_step`), at most to path length ``l_max``:
    ``out[o]`` gets the state after it; returns the layer after it."""
    depth = z0 - st[si, 2]
    ds, kn, d_b, dx, dd, cb, sb = _step(_layer(layers, k), k, depth, st[si, S_CT], st[si, S_ST], ray[i, 2],
                                        sagitta_m, max(l_max - st[si, S_L], 0.0) + 1e-6, d_lo, d_hi)
    for q in range(STATE_WIDTH):
        out[o, q] = st[si, q]
    if ds == math.inf:  # a straight ray that meets nothing: it is done
        out[o, S_L] = math.inf
        return k
    out[o, 0] += dx * ray[i, 0]
    out[o, 1] += dx * ray[i, 1]
    out[o, 2] = out[o, 2] - dd if math.isnan(d_b) else z0 - d_b  # on a knot or stop exactly
    out[o, S_CT] = cb
    out[o, S_ST] = sb
    out[o, S_L] += ds
    if kn != k:
        _close_segment(out, o, k, ray, i, layers, d_b, sb)
    return kn


@njit(cache=True, nogil=True, inline='always')
def _skip_outside(st, i, k, ray, layers, z0, z_lo, z_hi, l_max):
    """Move ray i that is above z_hi or below z_lo (outside the scene) to that height, in closed form.

    Nothing can be hit out there, so no chord is cast; ``st[i]`` is updated in place (``_advance`` reads a
    row's values before it writes them), the layer returned.
    """
    for _ in range(MAX_SKIPS):
        if st[i, S_L] >= l_max or z_lo <= st[i, 2] <= z_hi:
            break
        if st[i, 2] > z_hi:
            k = _advance(st, i, k, ray, i, layers, z0, math.inf, l_max, -math.inf, z0 - z_hi, st, i)
        else:
            k = _advance(st, i, k, ray, i, layers, z0, math.inf, l_max, z0 - z_lo, math.inf, st, i)
    return k


@njit(cache=True, nogil=True, parallel=True)
def arc_chord(idx, state, lay, ray, layers, z0, box_z, sagitta_m, l_max, nxt, nlay, org, dirs, seg_len):
    """The next chord of every live ray ``idx``: its state after it, and the chord as an Embree segment.

    A ray outside the scene's height range first moves to its edge in closed form
    (:func:`_skip_outside`, written into ``state``), so chords are cast only where there is
    something to hit.

    Parameters
    ----------
    idx : (m,) int64
        Live rays.
    state, lay, ray
        As written by :func:`arc_start` (updated for the skipped part).
    layers : (k, 3) float64; z0 : float
        As for :func:`arc_start`.
    box_z : (2,) float64
        Local z range outside which no chord is cast (the scene's, widened by a margin), m.
    sagitta_m : float
        Largest distance of a chord from its arc, m.
    l_max : float
        Path length after which a ray is not followed, m (the window's time × the fastest c).
    nxt : (m, STATE_WIDTH) float64; nlay : (m,) int64
        Written: the state and layer after the chord.
    org, dirs : (m, 3) float32; seg_len : (m,) float32
        Written: the chord's start (local frame, m), unit direction and length (m; 0 past ``l_max``).
    """
    for j in prange(idx.shape[0]):
        i = idx[j]
        lay[i] = _skip_outside(state, i, lay[i], ray, layers, z0, box_z[0], box_z[1], l_max)
        nlay[j] = _advance(state, i, lay[i], ray, i, layers, z0, sagitta_m, l_max, -math.inf, math.inf, nxt, j)
        vx = nxt[j, 0] - state[i, 0]
        vy = nxt[j, 1] - state[i, 1]
        vz = nxt[j, 2] - state[i, 2]
        n = math.sqrt(vx * vx + vy * vy + vz * vz)
        if state[i, S_L] >= l_max:
            n = 0.0
        org[j, 0] = state[i, 0]
        org[j, 1] = state[i, 1]
        org[j, 2] = state[i, 2]
        if n > 0.0:
            dirs[j, 0] = vx / n
            dirs[j, 1] = vy / n
            dirs[j, 2] = vz / n
        else:
            dirs[j, 0] = ray[i, 0]
            dirs[j, 1] = ray[i, 1]
            dirs[j, 2] = 0.0
        seg_len[j] = n


#: Columns of a hit: point (3, local m), incident direction (3), one-way time T (s), path length L (m),
#: X̃ (m²/s), M (m²/s), sin θ and cos θ at the hit, c at the hit (m/s).
HIT_WIDTH = 13


@njit(cache=True, nogil=True, inline='always')
def _refit(st, i, ux, uy, uz, t_emb, tri, vertices, faces, face_normals):
    """Float64 distance along the chord from ``st[i]`` (unit direction u) to the hit triangle's plane
    (Embree's where ill-conditioned)."""
    dn = ux * face_normals[tri, 0] + uy * face_normals[tri, 1] + uz * face_normals[tri, 2]
    num = 0.0
    for q in range(3):
        num += (vertices[faces[tri, 0], q] - st[i, q]) * face_normals[tri, q]
    if abs(dn) > REFIT_MIN_COS:
        t64 = num / dn
        if abs(t64 - t_emb) <= REFIT_REL_TOL * (1.0 + t_emb):
            return t64
    return t_emb


@njit(cache=True, nogil=True, parallel=True)
def arc_advance(idx, prim, state, lay, nxt, nlay, l_max, live):
    """Rays whose chord missed move to the chord's end; the chord's stage after the cast for them.

    Parameters
    ----------
    idx, state, lay, nxt, nlay, l_max
        As for :func:`arc_chord` (``state``, ``lay`` updated for the rays that missed).
    prim : (m,) int32
        Embree's answer for each chord (−1: missed).
    live : (m,) bool
        Written: whether the ray goes on (missed, and still short of ``l_max``): the next round's rays, without a
        pass over ``nxt`` in NumPy.
    """
    for j in prange(idx.shape[0]):
        i = idx[j]
        live[j] = False
        if prim[j] < 0:
            for q in range(STATE_WIDTH):
                state[i, q] = nxt[j, q]
            lay[i] = nlay[j]
            live[j] = nxt[j, S_L] < l_max


@njit(cache=True, nogil=True, parallel=True)
def arc_land(idx, prim, tfar, state, lay, ray, nxt, layers, z0, vertices, faces, face_normals, hit_prim, hit,
             hit_len):
    """Rays whose chord hit something stop there (``hit``); :func:`arc_advance` moves the others on (each ray is
    one or the other, so the two stages commute).

    Parameters
    ----------
    idx, state, lay, ray, nxt, layers, z0
        As for :func:`arc_chord` (read only here).
    prim : (m,) int32; tfar : (m,) float32
        Embree's answer for each chord.
    vertices, faces, face_normals
        The scene (local frame), for the float64 refit of the hit.
    hit_prim : (n,) int32; hit : (n, HIT_WIDTH) float64; hit_len : (n,) float32
        Written for the rays that hit: the triangle, the quantities of :data:`HIT_WIDTH` at the point
        where the arc meets the triangle's plane (:func:`_onto_arc`), from the closed forms, and the path length
        there (m, float32).
    """
    for j in prange(idx.shape[0]):
        i = idx[j]
        if prim[j] < 0:
            continue
        dx = nxt[j, 0] - state[i, 0]
        dy = nxt[j, 1] - state[i, 1]
        dz = nxt[j, 2] - state[i, 2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        tri = prim[j]
        t = 0.0
        if length > 0.0:
            t = _refit(state, i, dx / length, dy / length, dz / length, np.float64(tfar[j]), tri, vertices, faces,
                       face_normals)
        ds_chord = nxt[j, S_L] - state[i, S_L]
        s = min(max(t / length, 0.0), 1.0) * ds_chord if length > 0 else 0.0
        ca, sa = state[i, S_CT], state[i, S_ST]
        kappa = ray[i, 2] * layers[lay[i], 2]
        s, dx, dd, cb, sb = _onto_arc(state, i, ray, ca, sa, kappa, s, ds_chord, vertices, faces, face_normals, tri)
        _hit_of(state, i, lay[i], ray, layers, z0, s, dx, dd, cb, sb, hit)
        hit_prim[i], hit_len[i] = tri, np.float32(hit[i, 7])


@njit(cache=True, nogil=True, inline='always')
def _onto_arc(st, i, ray, ca, sa, kappa, s0, ds_chord, vertices, faces, face_normals, tri):
    """Arc length from the chord's start at which the arc meets the hit triangle's plane (Newton from s0), and
    :func:`_turn` there (Δx, Δdepth, cos θ, sin θ).

    Stops when a step is below :data:`NEWTON_TOL_M` (keeping the point it evaluated, whose turn is returned
    as it is); falls back to ``s0`` (the chord's own hit) if Newton leaves the chord or the arc runs along the
    plane.
    """
    v = faces[tri, 0]
    hn = ray[i, 0] * face_normals[tri, 0] + ray[i, 1] * face_normals[tri, 1]
    nz = face_normals[tri, 2]
    base = 0.0
    for q in range(3):
        base += (st[i, q] - vertices[v, q]) * face_normals[tri, q]
    s, at = s0, math.nan                               # at: the arc length whose turn (dx, dd, cb, sb) is held
    dx, dd, cb, sb = 0.0, 0.0, 1.0, 0.0
    for _ in range(NEWTON_STEPS):
        dx, dd, cb, sb = _turn(ca, sa, kappa, s)
        at = s
        fp = cb * hn - sb * nz
        if abs(fp) < REFIT_MIN_COS:
            s = s0
            break
        step = (base + dx * hn - dd * nz) / fp
        if abs(step) < NEWTON_TOL_M:
            break
        s -= step
    tol = REFIT_REL_TOL * (1.0 + ds_chord)
    if not -tol <= s <= ds_chord + tol:
        s = s0
    if s != at:
        dx, dd, cb, sb = _turn(ca, sa, kappa, s)
    return s, dx, dd, cb, sb


@njit(cache=True, nogil=True, inline='always')
def _hit_of(st, i, k, ray, layers, z0, s, dx, dd, cb, sb, out):
    """The :data:`HIT_WIDTH` quantities (into ``out[i]``) of the arc point an arc length ``s`` after the
    chord's start ``st[i]``, which the arc reaches by Δx, Δdepth with cos θ ``cb``, sin θ ``sb`` there
    (:func:`_turn`)."""
    hx, hy = ray[i, 0], ray[i, 1]
    out[i, 0] = st[i, 0] + dx * hx
    out[i, 1] = st[i, 1] + dx * hy
    out[i, 2] = st[i, 2] - dd
    out[i, 3] = cb * hx
    out[i, 4] = cb * hy
    out[i, 5] = -sb
    depth = z0 - out[i, 2]
    xh = out[i, 0] * hx + out[i, 1] * hy
    lk = _layer(layers, k)
    dt, xt = _seg_dt_xt(lk, st[i, S_D0], st[i, S_SN0], depth, sb, xh - st[i, S_XH0],
                        st[i, S_L] + s - st[i, S_L0], ray[i, 2])
    out[i, 6] = st[i, S_T0] + dt
    out[i, 7] = st[i, S_L] + s
    out[i, 8] = st[i, S_X0] + xt
    out[i, 9] = st[i, S_P] * sb + st[i, S_RA] * xt
    out[i, 10] = sb
    out[i, 11] = cb
    out[i, 12] = _speed(lk, depth)


@njit(cache=True, nogil=True, parallel=True)
def arc_echoes(fan, poses, hit_prim, hit, ray, scene, weighting, out, layout):
    """Weights of the curved rays of a block (docs/physics.md §12); the law multiplies σ(θi)/cos θi afterwards.

    w = exp(−2α'·L) · ds·dβ / max(A_Ω, R_min²),  A_Ω = X̃·|M| / c0²   (× Γ²·Γ_rx² of the launch direction by the beam),

    at two-way time 2T (apparent range c_nom·T), spread over the travel-time interval
    2·|n̂·δ⊥|·dβ / (c_h·cos θi) of its cell, δ⊥ the ray tube's sideways motion per dβ
    (−(M/c0)·n̂_v·∂θ0/∂β + (X̃/c0)·cos θ0·ĥ⊥·∂φ/∂β, n̂_v the normal of the ray in its vertical
    plane, ĥ⊥ the horizontal normal of that plane; the straight-ray footprint when c is constant).
    Misses, back faces (unless two-sided), grazing hits, hits after ``t_max`` and rays behind the
    baffle get w = 0. Arguments as for :func:`~sonar_embree.kernels.rays.fan_echoes` (``poses.pos`` and
    ``poses.rx_shift`` unread), plus
    ``hit_prim``, ``hit``, ``ray`` from :func:`arc_land` / :func:`arc_start`; ``weighting`` an
    :data:`~sonar_embree.kernels.args.ArcWeighting` with ``t_max`` (one-way, s) and ``c_nom`` (the sonar's sound
    speed, m/s). Outputs as there; points are the hit points.
    Γ_rx (applied after, :func:`sonar_embree.propagation.gain.weigh_by_beam`): the receive beam moved on during the
    ping, its along-track cosine shifted by δ = 2·v_fwd/c (docs/physics.md §16; the horizontal slowness is
    conserved, so the ray reaching the moved receiver leaves X with s − 2v·T/M ≈ s − 2v/c0). With ``layout``
    (:func:`arc_start`) each ray has its own s, β, dβ and ds.
    """
    el_start, rot = fan.el_start, poses.rot
    # the outputs as arrays, not group fields: Numba (0.6x parfors) drops writes through a group's field in a prange
    range_out, time_out, extent_out, weight_out, cos_out, points_out = out
    per_ray = layout.shape[0] > 0
    want_points = points_out.shape[0] == range_out.shape[0]
    cos_t = math.cos(weighting.tilt_rad)
    sin_t = math.sin(weighting.tilt_rad)
    for r in prange(el_start.shape[0] - 1):
        b, side, n_el, base, end = row_rays(r, el_start, fan.s.shape[0], per_ray)
        for i in range(base, end):
            sa, cb, sb, db, ds_i = fan_cell(i, base, el_start[r], n_el, fan, layout)
            cpsi = math.sqrt(1.0 - sa * sa)
            range_out[i] = math.inf
            time_out[i] = math.inf
            extent_out[i] = 0.0
            weight_out[i] = 0.0
            cos_out[i] = 0.0
            if want_points:
                for q in range(3):
                    points_out[i, q] = 0.0
            t = hit_prim[i]
            if t < 0:
                continue
            behind = cpsi * (cb * cos_t + sb * sin_t) <= 0.0              # cos(β − δ): behind the baffle
            cos_i = _arc_incidence(hit, i, t, scene, weighting, behind)
            if cos_i == 0.0:
                continue
            weight_out[i], range_out[i], time_out[i] = _arc_weight(hit, ray, i, weighting, ds_i, db)
            cos_out[i] = cos_i
            slope = _tube_shift(rot[b], side, cpsi, cb, sb, sa, hit[i], ray[i], scene.face_normals[t])
            extent_out[i] = _arc_extent(slope, cos_i, db, hit, i, weighting)
            if want_points:
                for q in range(3):
                    points_out[i, q] = hit[i, q]


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _arc_incidence(hit, i, t, scene, weighting, behind):
    """cos θi of curved ray i's hit on triangle t (two-sided: |n̂·u|), or 0 where it gives no echo (grazing, after
    ``weighting.t_max``, ``behind`` the baffle)."""
    face_normals, face_two_sided = scene.face_normals, scene.face_two_sided
    dn = 0.0
    for q in range(3):
        dn += hit[i, 3 + q] * face_normals[t, q]
    cos_i = -dn
    if cos_i < 0.0 and face_two_sided[t]:
        cos_i = dn
    if not (cos_i > 1e-9) or not (hit[i, 6] <= weighting.t_max) or behind:
        return 0.0
    return cos_i


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _arc_weight(hit, ray, i, weighting, ds_i, db):
    """(w, apparent range c_nom·T (m), two-way time 2T (s)) of curved ray i's hit (see :func:`arc_echoes`)."""
    c0 = ray[i, 4]
    area = hit[i, 8] * abs(hit[i, 9]) / (c0 * c0)
    min_range_m = weighting.min_range_m
    w = math.exp(-weighting.two_way_np_per_m * hit[i, 7]) * ds_i * db / max(area, min_range_m * min_range_m)
    return w, weighting.c_nom * hit[i, 6], 2.0 * hit[i, 6]


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _arc_extent(slope, cos_i, db, hit, i, weighting):
    """The travel-time extent (s) of curved ray i's cell: 2·min(|n̂·δ⊥|/cos θi, cap)·dβ / c_h."""
    return 2.0 * min(slope / cos_i, weighting.slope_cap_m_rad) * db / hit[i, 12]


@njit(cache=True, nogil=True, inline='always')
def _tube_shift(rot, side, cpsi, cb, sb, sa, h, ry, nrm):
    """|n̂·δ⊥| per radian of β (m/rad): the ray tube's sideways motion seen across the hit surface."""
    e1, e2 = side * cpsi * cb, cpsi * sb
    f1, f2 = -side * cpsi * sb, cpsi * cb  # ∂e/∂β in body axes (0, f1, f2)
    ux = rot[0, 0] * sa + rot[0, 1] * e1 + rot[0, 2] * e2
    uy = rot[1, 0] * sa + rot[1, 1] * e1 + rot[1, 2] * e2
    dux = rot[0, 1] * f1 + rot[0, 2] * f2
    duy = rot[1, 1] * f1 + rot[1, 2] * f2
    duz = rot[2, 1] * f1 + rot[2, 2] * f2
    cos0 = max(math.sqrt(ux * ux + uy * uy), 1e-12)
    c0 = ry[4]
    sh, ch = h[10], h[11]
    n_v = nrm[0] * sh * ry[0] + nrm[1] * sh * ry[1] + nrm[2] * ch
    n_p = -nrm[0] * ry[1] + nrm[1] * ry[0]
    d_theta = -duz / cos0
    d_phi_cos = (ux * duy - uy * dux) / cos0
    return abs(-(h[9] / c0) * n_v * d_theta + (h[8] / c0) * n_p * d_phi_cos)
