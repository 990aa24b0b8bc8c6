"""Front-end kernels of the side-scan fan: ray placement, directions, propagation per hit (docs/physics.md §2, §3, §7)."""
from __future__ import annotations

import math

import numpy as np

from ._numba import REFIT_MIN_COS, REFIT_REL_TOL, njit, prange


@njit(cache=True, nogil=True)
def place_rows(edges, density, el_start, beta, dbeta):
    """Elevation rays of every row with the wanted density per cell; their cells tile the span.

    Parameters
    ----------
    edges : (m,) float64
        Cell edges in rad (increasing), shared by all rows.
    density : (rows, m − 1) float64
        Wanted rays per radian in each cell.
    el_start : (rows + 1,) int64
        Row r gets n = el_start[r + 1] − el_start[r] ≥ 0 rays (0: a side without rays; fewer than the density
        asks for scales it down uniformly).
    beta, dbeta : (el_start[-1],) float64
        Written with each ray's depression (the middle of its cell) and cell width, rad.
    """
    m = edges.shape[0]
    cum = np.empty(m)
    for r in range(density.shape[0]):
        cum[0] = 0.0
        for c in range(m - 1):
            cum[c + 1] = cum[c] + density[r, c] * (edges[c + 1] - edges[c])
        n = el_start[r + 1] - el_start[r]
        total = cum[m - 1]
        c = 0
        lo = edges[0]
        for j in range(n):
            if j == n - 1:
                hi = edges[m - 1]
            else:
                target = total * (j + 1) / n
                while c < m - 2 and cum[c + 1] < target:
                    c += 1
                span = cum[c + 1] - cum[c]
                f = (target - cum[c]) / span if span > 0.0 else 0.0
                hi = edges[c] + f * (edges[c + 1] - edges[c])
            beta[el_start[r] + j] = 0.5 * (lo + hi)
            dbeta[el_start[r] + j] = hi - lo
            lo = hi


@njit(cache=True, nogil=True)
def _fmax(a, b):
    """np.fmax: the larger, NaN only if both are NaN."""
    if math.isnan(a):
        return b
    if math.isnan(b):
        return a
    return max(a, b)


@njit(cache=True, nogil=True)
def _row_density(beta, r, dr_target, max_step, slope_cap, empty_factor, edge_factor, raw, edge, out):
    """One probe line of :func:`elevation_density` (``raw``, ``edge``: (m − 1,) scratch)."""
    n_c = beta.shape[0] - 1
    for j in range(n_c):
        raw[j] = abs(r[j + 1] - r[j]) / (beta[j + 1] - beta[j])
    for j in range(n_c):
        neigh = _fmax(raw[j - 1] if j > 0 else np.nan, raw[j + 1] if j < n_c - 1 else np.nan)
        slope = raw[j]
        jump = math.isfinite(slope) and math.isfinite(neigh) and slope > 4.0 * neigh
        if jump:
            slope = neigh
        live = math.isfinite(r[j]) or math.isfinite(r[j + 1])
        partial = (not math.isfinite(slope)) and live
        if partial:
            slope = neigh
        edge[j] = jump or partial
        near = live or (j > 0 and (math.isfinite(r[j - 1]) or math.isfinite(r[j]))) or \
            (j < n_c - 1 and (math.isfinite(r[j + 1]) or math.isfinite(r[j + 2])))
        out[j] = min(slope, slope_cap) if math.isfinite(slope) else 0.0
        raw_floor = 1.0 / max_step if near else 1.0 / (empty_factor * max_step)
        out[j] = max(raw_floor, out[j] / dr_target)   # the edge floor is applied below, once edges are known
    for j in range(n_c):
        if edge[j] or (j > 0 and edge[j - 1]) or (j < n_c - 1 and edge[j + 1]):
            out[j] = max(out[j], edge_factor / max_step)


@njit(cache=True, nogil=True, parallel=True)
def elevation_density(beta, r, dr_target, max_step, slope_cap, empty_factor, edge_factor, out):
    """Rays per radian wanted in each probe cell of every probe line, from the probed slant ranges.

    Called through :func:`sonar_embree.instrument.beam.elevation_density`; its NumPy twin is in ``tests/naive.py``.
    The rules, per line: |dR/dβ| by finite differences; a cell four times steeper than both neighbours is a range
    jump and takes their slope, as does a cell with one end out of range; the slope is capped at ``slope_cap``;
    the density is at least 1/``max_step`` near anything in range (1/(``empty_factor``·``max_step``) elsewhere) and
    ``edge_factor``/``max_step`` at and beside jumps and silhouettes.

    Parameters
    ----------
    beta : (m,) float64
        Probe depressions, rad, increasing.
    r : (rows, m) float64
        Probed slant range, m, NaN where nothing is in range.
    dr_target, max_step, slope_cap, empty_factor, edge_factor : float
        Wanted range step (m), largest step near a surface (rad), cap on |dR/dβ| (m/rad), and the two factors.
    out : (rows, m − 1) float64
        Written with the density per cell, rays per radian.
    """
    for k in prange(r.shape[0]):
        raw, edge = np.empty(beta.shape[0] - 1), np.empty(beta.shape[0] - 1, dtype=np.bool_)
        _row_density(beta, r[k], dr_target, max_step, slope_cap, empty_factor, edge_factor, raw, edge, out[k])


@njit(cache=True, nogil=True, parallel=True)
def cos_sin(x, cos_x, sin_x):
    """cos and sin of every element of ``x`` (n,) into ``cos_x``, ``sin_x`` (n,): the fan's per-ray trigonometry
    spread over the threads rather than done by NumPy in the calling thread."""
    for i in prange(x.shape[0]):
        cos_x[i] = math.cos(x[i])
        sin_x[i] = math.sin(x[i])


@njit(cache=True, nogil=True)
def probe_rays(body, rot, pos, dirs, dirs32, origins32):
    """World directions of a block's probe rays (float64, and float32 for Embree) and their float32 origins.

    Parameters
    ----------
    body : (k, 3) float64
        Body-frame probe directions of a ping.
    rot : (pings, 3, 3) float64
        Body-to-world rotation per ping.
    pos : (pings, 3) float64
        Sonar position per ping in the scene's local frame, m.
    dirs : (pings, k, 3) float64
        Written with ``rot[b] @ body[j]``, summed as :func:`fan_rays` sums.
    dirs32, origins32 : (pings·k, 3) float32
        Written with ``dirs`` and the ping's position, for the caster.
    """
    k = body.shape[0]
    for b in range(rot.shape[0]):
        for j in range(k):
            for q in range(3):
                d = rot[b, q, 0] * body[j, 0] + rot[b, q, 1] * body[j, 1] + rot[b, q, 2] * body[j, 2]
                dirs[b, j, q] = d
                dirs32[b * k + j, q] = d
                origins32[b * k + j, q] = pos[b, q]


@njit(cache=True, nogil=True, parallel=True)
def fan_rays(s, cos_beta, sin_beta, el_start, rot, pos, dirs, origins):
    """Float32 origins and world directions of every ray of a block of pings, for Embree.

    Parameters
    ----------
    s : (n_az,) float64
        Along-track direction cosines.
    cos_beta, sin_beta : (el_start[-1],) float64
        cos β and sin β of the depression β of each row's elevation rays.
    el_start : (rows + 1,) int64
        Row offsets into ``cos_beta`` (rows = 2 × pings).
    rot : (pings, 3, 3) float64
        Body-to-world rotation per ping (columns forward, starboard, down).
    pos : (pings, 3) float64
        Sonar position per ping in the scene's local frame, m.
    dirs, origins : (n_az·el_start[-1], 3) float32
        Written with unit directions and origins.
    """
    n_az = s.shape[0]
    for r in prange(el_start.shape[0] - 1):
        b = r // 2
        side = 1.0 if r % 2 else -1.0
        n_el = el_start[r + 1] - el_start[r]
        base = n_az * el_start[r]
        for a in range(n_az):
            sa = s[a]
            cpsi = math.sqrt(1.0 - sa * sa)
            for j in range(n_el):
                d0 = sa
                d1 = side * cpsi * cos_beta[el_start[r] + j]
                d2 = cpsi * sin_beta[el_start[r] + j]
                i = base + a * n_el + j
                for q in range(3):
                    dirs[i, q] = rot[b, q, 0] * d0 + rot[b, q, 1] * d1 + rot[b, q, 2] * d2
                    origins[i, q] = pos[b, q]


@njit(cache=True, nogil=True)
def _sinc(x):
    if abs(x) < 1e-8:
        return 1.0 - x * x / 6.0
    return math.sin(x) / x


# The coefficients of fdlibm's k_sin.c and k_cos.c: minimax polynomials with |sin y − y·(1 + z·S(z))| < 2⁻⁵⁸ and
# |cos y − (1 − z/2 + z²·C(z))| < 2⁻⁵⁸ on |y| ≤ π/4, z = y². fdlibm's notice: "Copyright (C) 1993 by Sun
# Microsystems, Inc. All rights reserved. Developed at SunPro, a Sun Microsystems, Inc. business. Permission to
# use, copy, modify, and distribute this software is freely granted, provided that this notice is preserved."
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@njit(cache=True, nogil=True, inline='always')
def sin_cos_poly(y):
    """(sin y, cos y) for |y| ≤ π/4 by fdlibm's k_sin and k_cos polynomials (no branch: loops of it vectorise)."""
    z = y * y
    sp = y + y * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    h = 0.5 * z
    w = 1.0 - h
    return sp, w + (((1.0 - w) - h) + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6))))))


@njit(cache=True, nogil=True, inline='always')
def _sinc_poly(x):
    """sin(x)/x without a branch, so that a loop of it vectorises: fdlibm's polynomials of sin and cos after the
    two-term Cody–Waite reduction y = |x| − n·π/2 (n·π/2 in 33 + 53 bits). Within 3 ulp of ``math.sin(x)/x`` for
    |x| < 10⁵, and the sine within 10⁻²¹ near its zeros (tests/test_kernels.py); the beams' arguments stay below
    k·L/2 (10⁴ for a 2 m array at 1 MHz)."""
    ax = abs(x)
    n = math.floor(ax * 0.6366197723675814 + 0.5)           # nearest multiple of π/2
    y = (ax - n * 1.57079632673412561417e+00) - n * 6.07710050650619224932e-11
    sp, cp = sin_cos_poly(y)
    q = int(n)
    out = (1.0 - (q & 2)) * (cp if q & 1 else sp)
    tiny = ax < 1e-8
    return 1.0 - x * x / 6.0 if tiny else out / (1.0 if tiny else ax)


@njit(cache=True, nogil=True, inline='always')
def sinc_rows(a, rows, m):
    """a[j, k] = sin(a[j, k])/a[j, k] for j < rows, k < m, in place (:func:`_sinc_poly`, vectorised)."""
    for j in range(rows):
        for k in range(m):
            a[j, k] = _sinc_poly(a[j, k])


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def row_rays(r, el_start, n_az, per_ray):
    """(ping, side ±1, elevation cells, first ray, end ray) of row ``r``: its rays are the fan's azimuth-major
    n_az·n_el from n_az·el_start[r], or with each ray's own layout (``per_ray``) el_start[r] … el_start[r + 1]."""
    n_el = el_start[r + 1] - el_start[r]
    base = el_start[r] if per_ray else n_az * el_start[r]
    return r // 2, 1.0 if r % 2 else -1.0, n_el, base, base + (n_el if per_ray else n_az * n_el)


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def ray_cell(i, base, first, n_el, s, ds, cos_beta, sin_beta, dbeta, layout):
    """(s, cos β, sin β, dβ, ds) of ray ``i`` of a row whose rays start at ``base``: its own (``layout`` rows, the
    rays aimed at objects) or the fan's, azimuth-major over the row's ``n_el`` elevation cells from ``first``."""
    if layout.shape[0] > 0:
        return layout[i, 0], layout[i, 1], layout[i, 2], layout[i, 3], layout[i, 4]
    e = first + (i - base) % n_el
    return s[(i - base) // n_el], cos_beta[e], sin_beta[e], dbeta[e], ds


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def fan_cell(i, base, first, n_el, fan, layout):
    """:func:`ray_cell` of a :data:`~sonar_embree.kernels.args.Fan` group."""
    return ray_cell(i, base, first, n_el, fan.s, fan.ds, fan.cos_beta, fan.sin_beta, fan.dbeta, layout)


@njit(cache=True, nogil=True)
def hit_terms(dn, num, fn, t_emb, two_sided, ahead, ds, db, weighting):
    """The physics of one hit of :func:`fan_echoes`, on scalars only (no array arguments: no reference counting per
    ray; docs/physics.md §2–3).

    Parameters
    ----------
    dn, num, fn : float
        n̂·u, n̂·(v₀ − S) and n̂·∂u/∂β (n̂ the triangle's normal, v₀ a vertex, S the sonar, u the ray's world
        direction).
    t_emb : float
        Embree's float32 distance, m.
    two_sided : bool
        The triangle scatters from both sides.
    ahead : bool
        The ray leaves the transducer's face, cos(β − δ) > 0 (its caller's direction test; behind the baffle: no
        echo).
    ds, db : float
        The ray's cell: its along-track width ds and elevation width dβ (rad); solid angle ds·dβ.
    weighting : :data:`~sonar_embree.kernels.args.DirectWeighting`
        Two-way absorption (Np/m), R_min, R_max (m), slope cap (m/rad), 2/c (s/m) (its tilt not read: ``ahead``).

    Returns
    -------
    (R (m), cos θi, w, travel-time extent (s)); w = 0: no echo (back face, grazing, beyond R_max, behind the
    baffle).
    """
    _, two_way_np_per_m, min_range_m, max_range_m, slope_cap_m_rad, time_per_m = weighting
    rr = t_emb
    if abs(dn) > REFIT_MIN_COS:
        t64 = num / dn
        if abs(t64 - t_emb) <= REFIT_REL_TOL * (1.0 + t_emb):
            rr = t64
    cos_i = -dn
    if cos_i < 0.0 and two_sided:
        cos_i = dn
    if not (cos_i > 1e-9) or not (rr <= max_range_m):
        return rr, 0.0, 0.0, 0.0
    if not ahead:  # behind the baffle
        return rr, 0.0, 0.0, 0.0
    rb = rr if rr > min_range_m else min_range_m
    w = math.exp(-two_way_np_per_m * rr) * ds * db / (rb * rb)
    slope = rr * abs(fn) / cos_i
    if slope > slope_cap_m_rad:
        slope = slope_cap_m_rad
    return rr, cos_i, w, slope * db * time_per_m


@njit(cache=True, nogil=True, parallel=True)
def fan_echoes(fan, poses, prim, tfar, scene, weighting, out, layout):
    """Propagation of every ray of a block: range, range extent, incidence and weight without the beam and the law.

    (docs/physics.md §2–3.) The beam multiplies Γ²·Γ_rx² in afterwards
    (:func:`sonar_embree.propagation.gain.weigh_by_beam`), the scattering law σ(θi)/cos θi
    (:mod:`sonar_embree.laws`).

    The hit range is the float64 intersection with the hit triangle's plane (Embree's
    float32 distance where that is ill-conditioned). A ray of cell ds × dβ on a
    surface of normal n̂ returns

        w = exp(−2α'R) · ds·dβ / max(R, R_min)²     (× Γ²_tx·Γ²_rx by the beam, × σ(θi)/cos θi by the law)

    spread over the slant-range interval R ± ΔR/2 its cell covers on the plane,
    ΔR = R·|n̂·∂u/∂β| / cos θi · dβ (at most ``slope_cap_m_rad``·dβ). Misses, back
    faces (unless two-sided: then cos θi = |n̂·u|), grazing hits (cos θi ≤ 1e-9), rays behind
    the baffle and hits beyond ``max_range_m`` get w = 0.

    Parameters
    ----------
    fan : :data:`~sonar_embree.kernels.args.Fan`
        The block's fan, as for :func:`fan_rays`; ``dbeta`` the cell width of each
        elevation ray, ``ds`` the azimuth spacing.
    poses : :data:`~sonar_embree.kernels.args.Poses`
        Rotations and positions per ping (``rx_shift`` not read: the beam applies it).
    prim : (n,) int32
        Triangle hit by each ray, −1 for a miss.
    tfar : (n,) float32
        Embree's hit distance, m.
    scene : :data:`~sonar_embree.kernels.args.SceneArrays`
        The scene in its local frame; ``face_two_sided`` the triangles that scatter from both sides.
    weighting : :data:`~sonar_embree.kernels.args.DirectWeighting`
        The baffle's tilt δ (rad), two-way absorption (Np/m), near-field range bound,
        range window, bound on |dR/dβ| (m/rad) and the two-way travel time per metre 2/c (s/m).
    out : :data:`~sonar_embree.kernels.args.EchoOut`
        Written with R (m), the travel time 2R/c (s, inf: no echo), the travel-time extent ΔR·2/c (s), w and
        cos θi (0 where w = 0), and the hit points (local frame, m) when ``points`` has n rows.
    layout : (n, 5) or (0, 5) float64
        Each ray's own s, cos β, sin β, dβ and ds (the rays aimed at objects, :mod:`sonar_embree.propagation.aim`), row
        r's rays ``el_start[r] … el_start[r + 1] − 1``; ``s``, ``ds``, ``cos_beta``, ``sin_beta``, ``dbeta`` are then
        not read. No rows (``NO_LAYOUT``): the fan's layout.
    """
    el_start = fan.el_start
    # the outputs as arrays, not group fields: Numba (0.6x parfors) drops writes through a group's field in a prange
    range_out, time_out, extent_out, weight_out, cos_out, points_out = out
    want_points = points_out.shape[0] == range_out.shape[0]
    cos_t, sin_t = math.cos(weighting.tilt_rad), math.sin(weighting.tilt_rad)
    per_ray = layout.shape[0] > 0
    for r in prange(el_start.shape[0] - 1):
        b, side, n_el, base, end = row_rays(r, el_start, fan.s.shape[0], per_ray)
        s_prev, cpsi = math.nan, 0.0
        for i in range(base, end):
            range_out[i] = math.inf
            time_out[i] = math.inf
            extent_out[i] = 0.0
            weight_out[i] = 0.0
            cos_out[i] = 0.0
            if want_points:
                points_out[i, 0] = 0.0
                points_out[i, 1] = 0.0
                points_out[i, 2] = 0.0
            t = prim[i]
            if t < 0:
                continue
            sa, cb, sb, db, ds_i = fan_cell(i, base, el_start[r], n_el, fan, layout)
            if sa != s_prev:
                s_prev = sa
                cpsi = math.sqrt(1.0 - sa * sa)
            e = (sa, side * cpsi * cb, cpsi * sb)
            f = (-side * cpsi * sb, cpsi * cb)  # ∂u/∂β in body axes (0, f1, f2)
            dn, num, fn = _plane_terms(poses, scene, b, t, e, f)
            ahead = cpsi * (cb * cos_t + sb * sin_t) > 0.0          # cos(β − δ) > 0: in front of the baffle
            rr, cos_i, wt, ext = hit_terms(dn, num, fn, np.float64(tfar[i]), scene.face_two_sided[t], ahead, ds_i, db,
                                           weighting)
            if cos_i == 0.0:
                continue
            range_out[i] = rr
            time_out[i] = rr * weighting.time_per_m
            weight_out[i] = wt
            cos_out[i] = cos_i
            extent_out[i] = ext
            if want_points:
                _write_point(points_out, i, poses, b, rr, e)


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _plane_terms(poses, scene, b, t, e, f):
    """(n̂·u, n̂·(v₀ − S), n̂·∂u/∂β) of triangle t for ping b's ray of body direction ``e`` (3-tuple) and
    ∂e/∂β = (0, f1, f2) (``f``), as :func:`hit_terms` takes them."""
    rot, pos = poses.rot, poses.pos
    vertices, faces, face_normals = scene.vertices, scene.faces, scene.face_normals
    e0, e1, e2 = e
    f1, f2 = f
    dn, num, fn = 0.0, 0.0, 0.0
    for q in range(3):
        nq = face_normals[t, q]
        dn += (rot[b, q, 0] * e0 + rot[b, q, 1] * e1 + rot[b, q, 2] * e2) * nq
        num += (vertices[faces[t, 0], q] - pos[b, q]) * nq
        fn += (rot[b, q, 1] * f1 + rot[b, q, 2] * f2) * nq
    return dn, num, fn


@njit(cache=True, nogil=True, inline='always')  # array arguments: see kernels/_numba.py
def _write_point(points, i, poses, b, rr, e):
    """points[i] = S + rr·R·e: the hit of ping b's ray of body direction ``e`` at range ``rr``."""
    rot, pos = poses.rot, poses.pos
    e0, e1, e2 = e
    points[i, 0] = pos[b, 0] + rr * (rot[b, 0, 0] * e0 + rot[b, 0, 1] * e1 + rot[b, 0, 2] * e2)
    points[i, 1] = pos[b, 1] + rr * (rot[b, 1, 0] * e0 + rot[b, 1, 1] * e1 + rot[b, 1, 2] * e2)
    points[i, 2] = pos[b, 2] + rr * (rot[b, 2, 0] * e0 + rot[b, 2, 1] * e1 + rot[b, 2, 2] * e2)


@njit(cache=True, nogil=True, parallel=True)
def beam_cosines(fan, tilt_rad, layout, v_out):
    """v = cos ψ·sin(β − δ) of every ray of a block: its direction cosine across the beam, in the elevation plane
    perpendicular to the boresight tilted δ = ``tilt_rad`` (a separable beam weighs it after the path kernels,
    :func:`sonar_embree.propagation.fan.weigh_by_beam`). ``fan`` and ``layout`` as for :func:`fan_echoes` (the rows
    of ``fan.el_start``, azimuth-major, or each ray's own cell); writes ``v_out`` (n,)."""
    s, ds, cos_beta, sin_beta, dbeta, el_start = fan
    n_az, per_ray = s.shape[0], layout.shape[0] > 0
    cos_t, sin_t = math.cos(tilt_rad), math.sin(tilt_rad)
    for r in prange(el_start.shape[0] - 1):
        _, _, n_el, base, end = row_rays(r, el_start, n_az, per_ray)
        for i in range(base, end):
            sa, cb, sb, _, _ = ray_cell(i, base, el_start[r], n_el, s, ds, cos_beta, sin_beta, dbeta, layout)
            v_out[i] = math.sqrt(1.0 - sa * sa) * (sb * cos_t - cb * sin_t)


@njit(cache=True, nogil=True, parallel=True)
def weigh_lines(el_start, n_az, line_gain, ray_gain, weight):
    """weight[i] ×= line_gain[ping, a]·ray_gain[i] for every ray i of a fan (rows 2·ping + side of ``el_start``,
    each azimuth-major: azimuth line a, then its elevation cells), in place."""
    for r in prange(el_start.shape[0] - 1):
        n_el, base, b = el_start[r + 1] - el_start[r], n_az * el_start[r], r // 2
        for a in range(n_az):
            g = line_gain[b, a]
            for j in range(n_el):
                i = base + a * n_el + j
                weight[i] *= g * ray_gain[i]


#: The separable beam forms the kernels evaluate (a beam's ``kernel_form`` = (kind, q_along, q_across), and the
#: fourth value of a plan's beam array): each one-way factor is f(q·x), x = s along track and v = cos ψ·sin(β − δ)
#: across, f = sinc (:data:`BEAM_SINC`, a membrane: q = k·lx/2, k·ly/2) or f(y) = exp(−y²) (:data:`BEAM_GAUSS`, a
#: Gaussian: q = √(ln 2/2)/a, √(ln 2/2)/b).
BEAM_SINC, BEAM_GAUSS = 0, 1


@njit(cache=True, nogil=True, inline='always')
def beam_factor(kind, y):
    """f(y) of the beam form ``kind`` (:data:`BEAM_SINC`: sin(y)/y, :data:`BEAM_GAUSS`: exp(−y²))."""
    if kind == BEAM_GAUSS:
        return math.exp(-y * y)
    return _sinc(y)


@njit(cache=True, nogil=True)
def factor_rows(kind, a, rows, m):
    """a[j, k] = f(a[j, k]) for j < rows, k < m, in place: the form ``kind``'s factor (sinc: :func:`sinc_rows`)."""
    if kind == BEAM_GAUSS:
        for j in range(rows):
            for k in range(m):
                a[j, k] = math.exp(-a[j, k] * a[j, k])
    else:
        sinc_rows(a, rows, m)


@njit(cache=True, nogil=True, inline='always')
def _across(kind, q, cpsi, sin_bd):
    return beam_factor(kind, q * cpsi * sin_bd)             # the argument as the membrane's kernels formed it


@njit(cache=True, nogil=True, parallel=True)
def weigh_fan(fan, tilt_rad, kind, p_along, p, line_gain, weight):
    """weight[i] ×= line_gain[ping, a]·e⁴ for every lit ray (weight > 0) of a fan, e the beam's across-track factor
    (:data:`BEAM_SINC`, :data:`BEAM_GAUSS` with its parameter ``p``; ``p_along`` not read: the line gains hold
    the along-track factors) at v = cos ψ·sin(β − δ), δ = ``tilt_rad``;
    ``fan`` as for :func:`fan_echoes` (rows 2·ping + side, azimuth-major over their elevation cells), in place.
    One pass, the factor only where there is an echo (:func:`sonar_embree.propagation.gain.weigh_by_beam`)."""
    s, ds, cos_beta, sin_beta, dbeta, el_start = fan
    n_az = s.shape[0]
    cos_t, sin_t = math.cos(tilt_rad), math.sin(tilt_rad)
    for r in prange(el_start.shape[0] - 1):
        first, n_el, b = el_start[r], el_start[r + 1] - el_start[r], r // 2
        for a in range(n_az):
            g, cpsi = line_gain[b, a], math.sqrt(1.0 - s[a] * s[a])
            for j in range(n_el):
                i = n_az * first + a * n_el + j
                if weight[i] > 0.0:
                    e = _across(kind, p, cpsi, sin_beta[first + j] * cos_t - cos_beta[first + j] * sin_t)
                    e2 = e * e
                    weight[i] *= g * (e2 * e2)


@njit(cache=True, nogil=True, parallel=True)
def weigh_rays(layout, ray_start, rx_shift, tilt_rad, kind, p_along, p_across, weight):
    """weight[i] ×= Γ²(u)·Γ_rx²(u) for every lit ray (weight > 0) with its own cell (``layout`` (n, 5): s, cos β,
    sin β, dβ, ds; rows 2·ping + side of ``ray_start``): Γ = along(s)·across(v), Γ_rx with s − δ of the ping's
    ``rx_shift`` δ, the beam form ``kind`` with ``p_along``, ``p_across`` (:data:`BEAM_SINC`,
    :data:`BEAM_GAUSS`); in place."""
    cos_t, sin_t = math.cos(tilt_rad), math.sin(tilt_rad)
    for r in prange(ray_start.shape[0] - 1):
        shift = rx_shift[r // 2]
        for i in range(ray_start[r], ray_start[r + 1]):
            if weight[i] > 0.0:
                sa = layout[i, 0]
                e = _across(kind, p_across, math.sqrt(1.0 - sa * sa), layout[i, 2] * cos_t - layout[i, 1] * sin_t)
                g, g_rx = beam_factor(kind, p_along * sa) * e, beam_factor(kind, p_along * (sa - shift)) * e
                weight[i] *= g * g * (g_rx * g_rx)


@njit(cache=True, nogil=True, parallel=True)
def launch_body(fan, layout, out):
    """Each ray's body-frame launch direction (s, side·cos ψ·cos β, cos ψ·sin β) into ``out`` (n, 3) (forward,
    starboard, down; side −1 on port rows, even): ``fan`` and ``layout`` as for :func:`beam_cosines` (the rows of
    ``fan.el_start``, azimuth-major over their elevation cells, or each ray's own cell, ``layout`` (n, 5), with the
    rows' rays in ``fan.el_start``)."""
    s, cos_beta, sin_beta, el_start = fan.s, fan.cos_beta, fan.sin_beta, fan.el_start
    n_az, per_ray = s.shape[0], layout.shape[0] > 0
    for r in prange(el_start.shape[0] - 1):
        _, side, n_el, base, end = row_rays(r, el_start, n_az, per_ray)
        if per_ray:
            for i in range(base, end):
                cpsi = math.sqrt(1.0 - layout[i, 0] * layout[i, 0])
                out[i, 0], out[i, 1], out[i, 2] = layout[i, 0], side * cpsi * layout[i, 1], cpsi * layout[i, 2]
            continue
        for a in range(n_az):                           # the grid line by line: no division per ray
            sa, first, i0 = s[a], el_start[r], base + a * n_el
            cpsi = math.sqrt(1.0 - sa * sa)
            for j in range(n_el):
                out[i0 + j, 0], out[i0 + j, 1] = sa, side * cpsi * cos_beta[first + j]
                out[i0 + j, 2] = cpsi * sin_beta[first + j]


#: Rows of :func:`weigh_pairs`' scratch: the arguments (then values) of the four factors it evaluates per echo (across
#: of u, across, along and along_rx of d), the launch's along and along_rx (kept while s repeats) and the two gates.
_PAIR_ROWS = 8


@njit(cache=True, nogil=True, parallel=True)
def weigh_pairs(ray_start, body, leg, rot, rx_shift, tilt_rad, kind, p_along, p_across, w_pair, w_mono):
    """The gains of paths that leave the sonar along one direction and return along another, after the path kernels
    (issue 51, item 2; docs/physics.md §2, §13, §16), in place, for every echo i of rows 2·ping + side:

        w_pair[i] ×= Γ²(u)·Γ_rx²(d) + Γ²(d)·Γ_rx²(u)   (where w_pair[i] > 0)
        w_mono[i] ×= Γ²(u)·Γ_rx²(u)                    (where w_mono has rows and w_mono[i] > 0)

    u = ``body[i]`` the launch direction in the body frame (forward, starboard, down), d = Rᵀ·``leg[i]`` the other
    leg's world direction at the sonar turned into it (R = ``rot`` of the row's ping). Γ = along(s)·across(v)·gate of
    the beam form ``kind`` (:data:`BEAM_SINC`, :data:`BEAM_GAUSS`) with ``p_along``, ``p_across``, v = e₂·cos δ −
    side·e₁·sin δ (δ = ``tilt_rad``), 0 behind the baffle (side·e₁·cos δ + e₂·sin δ ≤ 0); Γ_rx with s shifted by the
    ping's ``rx_shift``. The echoes go in chunks: the arguments of their four factors, which then go in one vectorised
    loop (:func:`factor_rows`), and the launch's two along-track factors, kept while its s repeats (a fan's
    elevation cells share their line's); then the weights. Its NumPy twins: ``tests/naive.py`` and, for any separable
    beam, :func:`sonar_embree.propagation.gain.weigh_pairs`."""
    form = (math.cos(tilt_rad), math.sin(tilt_rad), p_along, p_across, kind)
    for r in prange(ray_start.shape[0] - 1):
        sc = np.empty((_PAIR_ROWS, _PAIR_CHUNK))
        b, side = r // 2, 1.0 if r % 2 == 1 else -1.0
        carry = (math.nan, 0.0, 0.0)                    # the launch's s and its along-track factors
        for c0 in range(ray_start[r], ray_start[r + 1], _PAIR_CHUNK):
            c1 = min(c0 + _PAIR_CHUNK, ray_start[r + 1])
            carry = _pair_launch(c0, c1, body, side, rx_shift[b], form, carry, sc)
            _pair_leg(c0, c1, leg, rot, b, side, rx_shift[b], form, w_pair, sc)
            factor_rows(kind, sc, 4, c1 - c0)
            _pair_apply(c0, c1, w_pair, w_mono, sc)


#: Echoes per pass of :func:`weigh_pairs`.
_PAIR_CHUNK = 1024


@njit(cache=True, nogil=True)
def _pair_launch(c0, c1, body, side, shift, form, carry, sc):
    """The launch's across-track argument (sc row 0), its along-track factors (rows 4, 5) and gate (row 6) of echoes
    c0 … c1 − 1 on a ``side`` with the ping's receive shift; ``form`` = (cos and sin of the tilt, p_along,
    p_across, kind), ``carry`` = (s, along(s), along_rx(s)) of the last launch, returned moved on."""
    cos_t, sin_t, p_along, p_across, kind = form
    s_prev, ga, gar = carry
    for i in range(c0, c1):
        k = i - c0
        e0, e1, e2 = body[i, 0], body[i, 1], body[i, 2]
        if e0 != s_prev:
            s_prev, ga, gar = e0, beam_factor(kind, p_along * e0), beam_factor(kind, p_along * (e0 - shift))
        sc[0, k], sc[4, k], sc[5, k] = p_across * (e2 * cos_t - side * e1 * sin_t), ga, gar
        sc[6, k] = 1.0 if side * e1 * cos_t + e2 * sin_t > 0.0 else 0.0
    return s_prev, ga, gar


@njit(cache=True, nogil=True)
def _pair_leg(c0, c1, leg, rot, b, side, shift, form, w_pair, sc):
    """The other leg's three factors' arguments (sc rows 1–3) and gate (row 7) of echoes c0 … c1 − 1 of ping ``b``:
    d = Rᵀ·leg in the body frame; 0 where ``w_pair`` is not lit."""
    cos_t, sin_t, p_along, p_across, _ = form
    for i in range(c0, c1):
        k = i - c0
        sc[1, k], sc[2, k], sc[3, k], sc[7, k] = 0.0, 0.0, 0.0, 0.0
        if not w_pair[i] > 0.0:
            continue
        d0, d1, d2 = leg[i, 0], leg[i, 1], leg[i, 2]
        e0 = rot[b, 0, 0] * d0 + rot[b, 1, 0] * d1 + rot[b, 2, 0] * d2         # Rᵀ·d
        e1 = rot[b, 0, 1] * d0 + rot[b, 1, 1] * d1 + rot[b, 2, 1] * d2
        e2 = rot[b, 0, 2] * d0 + rot[b, 1, 2] * d1 + rot[b, 2, 2] * d2
        sc[1, k], sc[2, k], sc[3, k] = p_across * (e2 * cos_t - side * e1 * sin_t), p_along * e0, p_along * (e0 - shift)
        sc[7, k] = 1.0 if side * e1 * cos_t + e2 * sin_t > 0.0 else 0.0


@njit(cache=True, nogil=True)
def _pair_apply(c0, c1, w_pair, w_mono, sc):
    """The gains of echoes c0 … c1 − 1 from the factors in ``sc`` into their lit weights."""
    mono = w_mono.shape[0] > 0
    for i in range(c0, c1):
        k = i - c0
        g1, g1r = sc[4, k] * sc[0, k] * sc[6, k], sc[5, k] * sc[0, k] * sc[6, k]
        if mono and w_mono[i] > 0.0:
            w_mono[i] *= g1 * g1 * (g1r * g1r)
        if w_pair[i] > 0.0:
            g2, g2r = sc[2, k] * sc[1, k] * sc[7, k], sc[3, k] * sc[1, k] * sc[7, k]
            w_pair[i] *= g1 * g1 * g2r * g2r + g1r * g1r * g2 * g2
