"""Numba kernels: array in, array out, into buffers the caller allocated.

The only module that imports numba (the scattering laws' kernels take ``njit`` and
``prange`` from here). Kernels read no global state (named constants only), allocate nothing,
draw no random numbers and skip (never wrap) indices outside the buffer. Each has
a naive NumPy twin in ``tests/naive.py``. Compiled code is cached on disk.
"""
from __future__ import annotations

import math
import os

# GNU OpenMP threads spin after each parallel region and steal the cores Embree's threads
# need next (measured: ~30 % slower casting on 2 cores); let them sleep unless the user chose.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np  # noqa: E402
import numba  # noqa: E402
from numba import njit, prange  # noqa: E402


#: The float64 refit of a hit: the range from the hit triangle's plane replaces Embree's float32
#: distance unless the ray is within this cosine of the plane or the two differ by more than
#: REFIT_REL_TOL·(1 m + distance) (then the plane is not the one hit: keep Embree's).
REFIT_MIN_COS = 1e-6
REFIT_REL_TOL = 1e-3


def num_threads() -> int:
    """Threads Numba's parallel kernels use (``NUMBA_NUM_THREADS``)."""
    return int(numba.get_num_threads())


@njit(cache=True, nogil=True)
def splat_table(channel, delay_samples, amplitude, table, table_start, table_rate, out):
    """Add a tabulated waveform, scaled and delayed, for every contribution.

    ``out[ch, n] += a · h(n − x)`` for every sample n where the waveform h is defined,
    with h read from ``table`` by linear interpolation (exact fractional delay up to
    the table resolution; nothing is rounded to the sample grid).

    Parameters
    ----------
    channel : (n,) int
        Row of ``out`` for each contribution; others are skipped.
    delay_samples : (n,) float64
        Delay x of each contribution in samples; NaN and ±inf are skipped. Parts of
        the waveform outside the record are dropped (nothing wraps around).
    amplitude : (n,) float64 or complex128
        Scale a of each contribution.
    table : (m,) float64 or complex128
        h(u) at u = table_start + i / table_rate (samples), i = 0 … m − 1; zero outside.
    table_start : float
        u of the first table entry, in samples (0 for a causal pulse, −half-width
        for a centred interpolation kernel).
    table_rate : float
        Table entries per sample.
    out : (n_channels, n_samples) complex128 or float64
        Accumulator, added to in place.
    """
    n_ch = out.shape[0]
    for i in range(delay_samples.shape[0]):
        ch = channel[i]
        if ch < 0 or ch >= n_ch:
            continue
        _splat_one(out[ch], delay_samples[i], amplitude[i], table, table_start, table_rate)


@njit(cache=True, nogil=True)
def _splat_one(row, x, a, table, table_start, table_rate):
    """row[k] += a·h(k − x) for every k the tabulated waveform h covers (see :func:`splat_table`)."""
    if not (abs(x) < math.inf):
        return
    n = row.shape[0]
    m = table.shape[0]
    span = (m - 1) / table_rate
    lo = x + table_start
    first = int(math.ceil(lo))
    last = int(math.floor(lo + span))
    if first < 0:
        first = 0
    if last > n - 1:
        last = n - 1
    for k in range(first, last + 1):
        u = (k - lo) * table_rate
        j = int(u)
        if j >= m - 1:
            if j == m - 1:
                row[k] += a * table[m - 1]
            continue
        f = u - j
        row[k] += a * (table[j] * (1.0 - f) + table[j + 1] * f)


# splitmix64 constants (Steele, Lea & Flood 2014), used as a counter-based hash.
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


@njit(cache=True, nogil=True)
def _mix64(z):
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@njit(cache=True, nogil=True)
def _node_hash(seed, ix, iy, iz):
    h = _mix64(np.uint64(seed) + _GOLDEN)
    h = _mix64(h ^ np.uint64(ix))
    h = _mix64(h ^ np.uint64(iy))
    return _mix64(h ^ np.uint64(iz))


@njit(cache=True, nogil=True)
def _frozen(h, s, n_sub):
    """Reflectivity g and stratified position v of scatterer s of the node with hash h."""
    scale = 1.0 / 9007199254740992.0  # 2**-53
    hs = _mix64(h + np.uint64(s) * _GOLDEN)
    u1 = (float(_mix64(hs ^ np.uint64(1)) >> np.uint64(11)) + 1.0) * scale
    u2 = float(_mix64(hs ^ np.uint64(2)) >> np.uint64(11)) * scale
    u3 = float(_mix64(hs ^ np.uint64(3)) >> np.uint64(11)) * scale
    r = math.sqrt(-math.log(u1))
    return complex(r * math.cos(2.0 * math.pi * u2), r * math.sin(2.0 * math.pi * u2)), (s + u3) / n_sub


@njit(cache=True, nogil=True)
def frozen_scatterers(seed, ijk, gain, position):
    """Reflectivity and position of each node's scatterers, a pure function of (seed, node, index).

    g = √(−ln u₁) · e^(j2πu₂) and v = (s + u₃)/S with u₁ ∈ (0, 1], u₂, u₃ ∈ [0, 1)
    from a splitmix64 hash of the seed, the integer node coordinates and the
    scatterer index s, so E|g|² = 1, |g|² is exponential, the phase uniform and v
    stratified-uniform on [0, 1): the same node gets the same values in every ping and run.

    Parameters
    ----------
    seed : int
        Non-negative seed.
    ijk : (n, 3) int64
        Lattice coordinates of the nodes.
    gain : (n, S) complex128
        Written with S independent reflectivities per node.
    position : (n, S) float64
        Written with the scatterers' stratified positions v in [0, 1).
    """
    n_sub = gain.shape[1]
    for i in range(ijk.shape[0]):
        h = _node_hash(seed, ijk[i, 0], ijk[i, 1], ijk[i, 2])
        for s in range(n_sub):
            g, v = _frozen(h, s, n_sub)
            gain[i, s] = g
            position[i, s] = v


@njit(cache=True, nogil=True)
def gather_nodes(channel, points, weights, ranges, extents, cell_m, slot_key, slot_epoch, epoch, slot_w, slot_wr,
                 slot_wr2, slot_rmin, slot_rmax, order):
    """Share every ray's echo among the 8 surrounding nodes of a cubic lattice (trilinear).

    Node (ch, i, j, k) sits at (i, j, k)·cell_m in world metres and collects, for
    channel ch, W = Σ w·b over the rays whose hit point p lies in one of its 8 cells,
    b the trilinear weight of p for that node (Σb = 1 per ray, so ΣW = Σw), the
    weighted mean range R̄ = Σ w·b·R / W, the centred second moment
    M2 = Σ w·b·((R − R̄)² + ΔR²/12) (each ray's echo spread uniformly over its extent
    ΔR; accumulated with Welford's update, so σ² = M2/W does not cancel) and the
    least and greatest R ∓ ΔR/2. Nodes are kept in an open-addressing hash table owned by the caller;
    a slot belongs to this call when ``slot_epoch == epoch``, so tables are reused
    without clearing. Nodes are listed in first-touch order: deterministic.

    Parameters
    ----------
    channel : (n,) int64
        Receiving side of each ray.
    points : (n, 3) float64
        World coordinates of the hit points, m.
    weights : (n,) float64
        Expected echo intensity of each ray; rays with w ≤ 0 are skipped.
    ranges : (n,) float64
        Slant range of each ray, m.
    extents : (n,) float64
        Slant-range interval ΔR each ray's footprint covers, m.
    cell_m : float
        Lattice spacing, m.
    slot_key : (cap, 4) int64
        Hash table keys (ch, i, j, k); cap a power of two.
    slot_epoch : (cap,) int64
        Epoch stamp of each slot.
    epoch : int
        Stamp of this call (must differ from every earlier call on the same table).
    slot_w, slot_wr, slot_wr2, slot_rmin, slot_rmax : (cap,) float64
        Hash table values W, R̄, M2, min R and max R.
    order : (cap,) int64
        Written with the slots of the nodes in first-touch order.

    Returns
    -------
    int
        Number of nodes; their slots are ``order[:count]``. −1 when the nodes would
        fill more than half the table: the caller grows it and calls again with a
        new epoch.
    """
    max_count = slot_epoch.shape[0] // 2
    count = 0
    for r in range(points.shape[0]):
        count = _insert_ray(channel[r], points[r, 0], points[r, 1], points[r, 2], weights[r], ranges[r],
                            extents[r], cell_m, slot_key, slot_epoch, epoch, slot_w, slot_wr, slot_wr2,
                            slot_rmin, slot_rmax, order, count, max_count)
        if count < 0:
            return -1
    return count


@njit(cache=True, nogil=True)
def _insert_ray(ch, px, py, pz, w, rr, ext, cell_m, slot_key, slot_epoch, epoch, slot_w, slot_wr, slot_wr2, slot_rmin,
                slot_rmax, order, count, max_count):
    """Add one ray to the 8 nodes around its hit point (see :func:`gather_nodes`); the new node count or −1."""
    if not (w > 0.0):
        return count
    mask = np.uint64(slot_epoch.shape[0] - 1)
    fx = px / cell_m  # divide, not multiply by 1/cell: at 5e6 m the two differ in t by 1e-9
    fy = py / cell_m
    fz = pz / cell_m
    x0 = math.floor(fx)
    y0 = math.floor(fy)
    z0 = math.floor(fz)
    tx = fx - x0
    ty = fy - y0
    tz = fz - z0
    e2 = ext * ext / 12.0  # variance of a uniform spread over the footprint
    r_lo = rr - 0.5 * ext
    r_hi = rr + 0.5 * ext
    for c in range(8):
        dx = c & 1
        dy = (c >> 1) & 1
        dz = (c >> 2) & 1
        b = (tx if dx else 1.0 - tx) * (ty if dy else 1.0 - ty) * (tz if dz else 1.0 - tz)
        if not (b > 0.0):
            continue
        ix = np.int64(x0) + dx
        iy = np.int64(y0) + dy
        iz = np.int64(z0) + dz
        s = _node_hash(np.uint64(ch), ix, iy, iz) & mask
        wb = w * b
        while True:
            si = np.int64(s)
            if slot_epoch[si] != epoch:
                if count >= max_count:
                    return -1
                slot_epoch[si] = epoch
                slot_key[si, 0] = ch
                slot_key[si, 1] = ix
                slot_key[si, 2] = iy
                slot_key[si, 3] = iz
                slot_w[si] = wb
                slot_wr[si] = rr
                slot_wr2[si] = wb * e2
                slot_rmin[si] = r_lo
                slot_rmax[si] = r_hi
                order[count] = si
                count += 1
                break
            if (slot_key[si, 0] == ch and slot_key[si, 1] == ix and slot_key[si, 2] == iy
                    and slot_key[si, 3] == iz):
                w_new = slot_w[si] + wb  # weighted Welford update: no cancellation in σ²
                delta = rr - slot_wr[si]
                slot_wr[si] += delta * (wb / w_new)
                slot_wr2[si] += wb * (delta * (rr - slot_wr[si]) + e2)
                slot_w[si] = w_new
                slot_rmin[si] = min(slot_rmin[si], r_lo)
                slot_rmax[si] = max(slot_rmax[si], r_hi)
                break
            s = (s + np.uint64(1)) & mask
    return count


# --------------------------------------------------------------------------- ray fan
#
# A block of pings has rows r = 2·b + side (b the ping in the block, side 0 port,
# 1 starboard). Row r has n_el[r] elevation rays per azimuth line; its rays are
# azimuth-major from ``n_az·el_start[r]``: ray i = n_az·el_start[r] + a·n_el[r] + j.


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
        Row r gets n = el_start[r + 1] − el_start[r] ≥ 1 rays (fewer than the density
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


@njit(cache=True, nogil=True, parallel=True)
def fan_echoes(s, ds, cos_beta, sin_beta, dbeta, el_start, rot, pos, prim, tfar, vertices, faces, face_normals,
               face_two_sided, beam, two_way_np_per_m, min_range_m, max_range_m, slope_cap_m_rad, range_out, extent_out,
               weight_out, cos_out, points_out):
    """Propagation of every ray of a block: range, range extent, incidence and weight without the law.

    (docs/physics.md §2–3.) The scattering law multiplies σ(θi)/cos θi in afterwards
    (:mod:`sonar_embree.laws`).

    The hit range is the float64 intersection with the hit triangle's plane (Embree's
    float32 distance where that is ill-conditioned). A ray of cell ds × dβ on a
    surface of normal n̂ returns

        w = Γ⁴ · exp(−2α'R) · ds·dβ / max(R, R_min)²     (× σ(θi)/cos θi by the law)

    spread over the slant-range interval R ± ΔR/2 its cell covers on the plane,
    ΔR = R·|n̂·∂u/∂β| / cos θi · dβ (at most ``slope_cap_m_rad``·dβ). Misses, back
    faces (unless two-sided: then cos θi = |n̂·u|), grazing hits (cos θi ≤ 1e-9) and
    hits beyond ``max_range_m`` get w = 0.

    Parameters
    ----------
    s, ds, cos_beta, sin_beta, dbeta, el_start, rot, pos
        The block's fan, as for :func:`fan_rays`; ``dbeta`` the cell width of each
        elevation ray, ``ds`` the azimuth spacing.
    prim : (n,) int32
        Triangle hit by each ray, −1 for a miss.
    tfar : (n,) float32
        Embree's hit distance, m.
    vertices : (v, 3) float64; faces : (f, 3) int32; face_normals : (f, 3) float64
        The scene in its local frame.
    face_two_sided : (f,) bool
        Triangles that scatter from both sides (two-sided materials).
    beam : (4,) float64
        k·lx/2, k·ly/2, tilt δ (rad) and 0 (reserved).
    two_way_np_per_m, min_range_m, max_range_m, slope_cap_m_rad : float
        Two-way absorption (Np/m), near-field range bound, range window and bound
        on |dR/dβ| (m/rad).
    range_out, extent_out, weight_out, cos_out : (n,) float64
        Written with R (m), ΔR (m), w and cos θi (0 where w = 0).
    points_out : (n, 3) or (0, 3) float64
        Written with the hit points (local frame, m) when it has n rows.
    """
    n_az = s.shape[0]
    want_points = points_out.shape[0] == range_out.shape[0]
    cos_t = math.cos(beam[2])
    sin_t = math.sin(beam[2])
    for r in prange(el_start.shape[0] - 1):
        b = r // 2
        side = 1.0 if r % 2 else -1.0
        n_el = el_start[r + 1] - el_start[r]
        base = n_az * el_start[r]
        for a in range(n_az):
            sa = s[a]
            cpsi = math.sqrt(1.0 - sa * sa)
            g_az = _sinc(beam[0] * sa)
            for j in range(n_el):
                i = base + a * n_el + j
                range_out[i] = math.inf
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
                cb = cos_beta[el_start[r] + j]
                sb = sin_beta[el_start[r] + j]
                e0 = sa
                e1 = side * cpsi * cb
                e2 = cpsi * sb
                f1 = -side * cpsi * sb  # ∂u/∂β in body axes (0, f1, f2)
                f2 = cpsi * cb
                dn = 0.0
                num = 0.0
                fn = 0.0
                for q in range(3):
                    dq = rot[b, q, 0] * e0 + rot[b, q, 1] * e1 + rot[b, q, 2] * e2
                    nq = face_normals[t, q]
                    dn += dq * nq
                    num += (vertices[faces[t, 0], q] - pos[b, q]) * nq
                    fn += (rot[b, q, 1] * f1 + rot[b, q, 2] * f2) * nq
                t_emb = np.float64(tfar[i])
                rr = t_emb
                if abs(dn) > REFIT_MIN_COS:
                    t64 = num / dn
                    if abs(t64 - t_emb) <= REFIT_REL_TOL * (1.0 + t_emb):
                        rr = t64
                cos_i = -dn
                if cos_i < 0.0 and face_two_sided[t]:
                    cos_i = dn
                if not (cos_i > 1e-9) or not (rr <= max_range_m):
                    continue
                if cpsi * (cb * cos_t + sb * sin_t) <= 0.0:  # cos(β − δ): behind the baffle
                    continue
                g = g_az * _sinc(beam[1] * cpsi * (sb * cos_t - cb * sin_t))  # sin(β − δ)
                g2 = g * g
                rb = rr if rr > min_range_m else min_range_m
                range_out[i] = rr
                weight_out[i] = g2 * g2 * math.exp(-two_way_np_per_m * rr) * ds * dbeta[el_start[r] + j] / (rb * rb)
                cos_out[i] = cos_i
                slope = rr * abs(fn) / cos_i
                if slope > slope_cap_m_rad:
                    slope = slope_cap_m_rad
                extent_out[i] = slope * dbeta[el_start[r] + j]
                if want_points:
                    points_out[i, 0] = pos[b, 0] + rr * (rot[b, 0, 0] * e0 + rot[b, 0, 1] * e1 + rot[b, 0, 2] * e2)
                    points_out[i, 1] = pos[b, 1] + rr * (rot[b, 1, 0] * e0 + rot[b, 1, 1] * e1 + rot[b, 1, 2] * e2)
                    points_out[i, 2] = pos[b, 2] + rr * (rot[b, 2, 0] * e0 + rot[b, 2, 1] * e1 + rot[b, 2, 2] * e2)


@njit(cache=True, nogil=True)
def _hat_integral(x):
    """∫_{−∞}^{x} max(0, 1 − |u|) du."""
    if x <= -1.0:
        return 0.0
    if x < 0.0:
        return 0.5 * (x + 1.0) * (x + 1.0)
    if x < 1.0:
        return 1.0 - 0.5 * (1.0 - x) * (1.0 - x)
    return 1.0


@njit(cache=True, nogil=True)
def _splat_box(row, x, width, w, n):
    """Add weight w spread uniformly over [x − width/2, x + width/2] (samples), linearly interpolated."""
    if not (w != 0.0) or not (abs(x) < math.inf):
        return
    if width < 1e-6:
        if x < 0.0 or x > n - 1:
            return
        j = int(x)
        f = x - j
        row[j] += w * (1.0 - f)
        if j + 1 < n:
            row[j + 1] += w * f
        return
    scale = w / width
    lo = max(x - 0.5 * width, 0.0)  # the part outside the record is dropped, as for a point echo
    hi = min(x + 0.5 * width, n - 1.0)
    if not (hi > lo):
        return
    first = int(math.floor(lo))
    last = min(int(math.floor(hi)) + 1, n - 1)
    for k in range(first, last + 1):
        row[k] += scale * (_hat_integral(hi - k) - _hat_integral(lo - k))


@njit(cache=True, nogil=True, parallel=True)
def splat_rows(ray_start, delay_samples, width_samples, weights, out):
    """Footprint splatting of every row of a block: each ray's weight spread over its delay interval.

    ``out[r, k] += w/W · ∫_{x−W/2}^{x+W/2} Λ(u − k) du`` (Λ the linear-interpolation
    hat), which conserves Σw for intervals inside the record, falls back to linear
    splatting for W → 0, and drops (never wraps) what lies outside the record.
    Rows are independent, so the result does not depend on the thread count.

    Parameters
    ----------
    ray_start : (rows + 1,) int64
        Rays of row r are ``ray_start[r] … ray_start[r + 1] − 1``.
    delay_samples, width_samples : (n,) float64
        Centre and width of each ray's delay interval, in samples.
    weights : (n,) float64
        Echo of each ray (zero: skipped).
    out : (rows, n_samples) float64
        Accumulator, added to in place.
    """
    n = out.shape[1]
    for r in prange(ray_start.shape[0] - 1):
        for i in range(ray_start[r], ray_start[r + 1]):
            _splat_box(out[r], delay_samples[i], width_samples[i], weights[i], n)


@njit(cache=True, nogil=True, parallel=True)
def speckle_block(ray_start, points, origin, weights, times, extents, pos_world, seed, cell_m, wavelength_m,
                  rate_hz, phase_cycles_per_s, n_sub, table, table_start, table_rate, slot_key, slot_epoch,
                  epochs, slot_w, slot_wr, slot_wr2, slot_rmin, slot_rmax, order, status, out):
    """Speckle of a block of pings: rays → frozen lattice scatterers → delayed waveforms, one ping per task.

    For each ping: :func:`gather_nodes` on the ping's echoes (channel by channel),
    then every node's ``n_sub`` scatterers, with the reflectivity g and stratified
    position v of :func:`frozen_scatterers`, at envelope travel time

        t = clip(t̄ + √3·σ·(2v − 1), t_min, t_max),  σ² = M2/W,

    with amplitude √(W/n_sub)·g·e^(−j2π·(2R_node/λ mod 1))·e^(j2π·(φ·t mod 1)), R_node
    the node's distance from the sonar and φ = ``phase_cycles_per_s``; each adds
    a·h(k − t·rate_hz) to its channel's row. Pings are split into one contiguous
    chunk per hash table; a ping's result depends only on its own rays, so the
    output does not depend on the number of tables or threads.

    Parameters
    ----------
    ray_start : (channels·pings + 1,) int64
        Row offsets of the block (row channels·b + ch: channel ch of ping b).
    points : (n, 3) float64
        Hit points in the scene's local frame, m; ``origin`` (3,) float64 makes them world.
    weights, times, extents : (n,) float64
        Expected intensity, two-way travel time (s) and its extent (s) of every echo.
    pos_world : (pings, 3) float64
        Sonar position per ping, world m.
    seed : int; cell_m, wavelength_m : float
        Speckle seed, lattice spacing (m) and acoustic wavelength (m).
    rate_hz, phase_cycles_per_s : float
        Output samples per second of travel time; extra carrier cycles per second.
    n_sub : int
        Scatterers per node.
    table, table_start, table_rate
        The waveform h, as for :func:`splat_table`.
    slot_key : (T, cap, 4) int64; slot_epoch : (T, cap) int64; epochs : (T,) int64
    slot_w, slot_wr, slot_wr2, slot_rmin, slot_rmax : (T, cap) float64; order : (T, cap) int64
        T hash tables (see :func:`gather_nodes`), reused without clearing.
    status : (pings,) int64
        0: to do (set to 1 when done, −1 when its table was too small: grow the
        tables, reset to 0 and call again; nothing was written for that ping).
    out : (pings, channels, n_samples) complex128
        Accumulator.
    """
    n_p = pos_world.shape[0]
    n_ch = out.shape[1]
    n_t = slot_key.shape[0]
    max_count = slot_epoch.shape[1] // 2
    root3 = math.sqrt(3.0)
    for t in prange(n_t):
        for b in range(t * n_p // n_t, (t + 1) * n_p // n_t):
            if status[b] != 0:
                continue
            epochs[t] += 1
            ep = epochs[t]
            count = 0
            for ch in range(n_ch):
                r = n_ch * b + ch
                for i in range(ray_start[r], ray_start[r + 1]):
                    count = _insert_ray(ch, points[i, 0] + origin[0], points[i, 1] + origin[1],
                                        points[i, 2] + origin[2], weights[i], times[i], extents[i], cell_m,
                                        slot_key[t], slot_epoch[t], ep, slot_w[t], slot_wr[t], slot_wr2[t],
                                        slot_rmin[t], slot_rmax[t], order[t], count, max_count)
                    if count < 0:
                        break
                if count < 0:
                    break
            if count < 0:
                status[b] = -1
                continue
            for q in range(count):
                si = order[t, q]
                w = slot_w[t, si]
                r_mean = slot_wr[t, si]
                sigma = math.sqrt(max(slot_wr2[t, si] / w, 0.0))
                ix = slot_key[t, si, 1]
                iy = slot_key[t, si, 2]
                iz = slot_key[t, si, 3]
                ddx = ix * cell_m - pos_world[b, 0]
                ddy = iy * cell_m - pos_world[b, 1]
                ddz = iz * cell_m - pos_world[b, 2]
                cycles = (2.0 * math.sqrt(ddx * ddx + ddy * ddy + ddz * ddz) / wavelength_m) % 1.0
                base = math.sqrt(w / n_sub) * complex(math.cos(2.0 * math.pi * cycles),
                                                      -math.sin(2.0 * math.pi * cycles))
                h = _node_hash(seed, ix, iy, iz)
                row = out[b, slot_key[t, si, 0]]
                for sub in range(n_sub):
                    g, v = _frozen(h, sub, n_sub)
                    r_env = min(max(r_mean + root3 * sigma * (2.0 * v - 1.0), slot_rmin[t, si]), slot_rmax[t, si])
                    a = base * g
                    if phase_cycles_per_s != 0.0:
                        ph = 2.0 * math.pi * ((phase_cycles_per_s * r_env) % 1.0)
                        a = a * complex(math.cos(ph), math.sin(ph))
                    _splat_one(row, r_env * rate_hz, a, table, table_start, table_rate)
            status[b] = 1


@njit(cache=True, nogil=True)
def _along_line(px, py, pz, dx, dy, dz, ox, oy, oz, r_target, half_len):
    """Offset t along the footprint line P + t·d (unit d) where |P + t·d − O| = r_target, |t| ≤ half_len."""
    qx = px - ox
    qy = py - oy
    qz = pz - oz
    b = qx * dx + qy * dy + qz * dz
    c = qx * qx + qy * qy + qz * qz - r_target * r_target
    disc = b * b - c
    if disc <= 0.0:  # the line never reaches that range: its closest point
        t = -b
    else:  # the root nearest t = 0, in the form that does not cancel
        root = math.sqrt(disc)
        if b >= 0.0:
            t = -c / (b + root)
        else:
            t = c / (root - b)
    if t > half_len:
        t = half_len
    elif t < -half_len:
        t = -half_len
    return t


@njit(cache=True, nogil=True)
def _label_ray(dr, px, py, pz, dx, dy, dz, ox, oy, oz, half_len, origin_z, height_row, ground_row, n):
    t = _along_line(px, py, pz, dx, dy, dz, ox, oy, oz, n * dr, half_len)
    x = px + t * dx - ox
    y = py + t * dy - oy
    height_row[n] = pz + t * dz + origin_z
    ground_row[n] = math.sqrt(x * x + y * y)


@njit(cache=True, nogil=True, parallel=True)
def label_rows(el_start, dr, lit_range, lit_extent, lit_score, lit_object, lit_point, lit_dir, hid_range, hid_extent,
               hid_object, hid_point, hid_dir, pos, is_seafloor, origin_z, best, kind, object_id, shadow_of,
               height, ground):
    """Per-sample ground truth of a block of pings from its centre-line rays.

    A sample n (slant range n·dr) belongs to a ray when its range cell
    [(n − ½)·dr, (n + ½)·dr) overlaps the ray's footprint [R − ΔR/2, R + ΔR/2].
    Among the lit rays (score > 0) that claim it, the highest score
    (echo intensity per metre of range) wins: kind 1 (seafloor) or 2 (object),
    with that ray's object. Samples no lit ray claims but a hidden footprint
    does (the first seafloor surface behind a ray's first hit) become kind 3
    (shadow), with the occluding object in ``shadow_of``. The rest stay kind 0
    (water column: no surface at that range). Height and ground range are those
    of the point at range n·dr on the footprint's line (exact on planar facets).

    Parameters
    ----------
    el_start : (rows + 1,) int64
        Ray offsets of each row (row = 2·ping + side).
    dr : float
        Slant-range spacing of the samples, m.
    lit_range, lit_extent, lit_score : (n,) float64
        First-hit range R (m), footprint ΔR (m) and score (0: not lit).
    lit_object : (n,) int32
        Object of the first hit.
    lit_point, lit_dir : (n, 3) float64
        First-hit point (local frame, m) and unit direction of its footprint line.
    hid_range, hid_extent, hid_object, hid_point, hid_dir
        The same for the hidden seafloor hit (range NaN: none); ``hid_object`` is
        the occluder (the first hit's object).
    pos : (pings, 3) float64
        Sonar positions, local frame, m.
    is_seafloor : (n_objects,) bool
    origin_z : float
        World z of the local origin, m.
    best : (rows, n_s) float64
        Scratch.
    kind : (rows, n_s) int8; object_id, shadow_of : (rows, n_s) int32; height, ground : (rows, n_s) float32
        Written.
    """
    n_s = kind.shape[1]
    for r in prange(el_start.shape[0] - 1):
        b = r // 2
        ox = pos[b, 0]
        oy = pos[b, 1]
        oz = pos[b, 2]
        for n in range(n_s):
            best[r, n] = 0.0
            kind[r, n] = 0
            object_id[r, n] = -1
            shadow_of[r, n] = -1
            height[r, n] = np.nan
            ground[r, n] = np.nan
        for layer in range(2):
            for j in range(el_start[r], el_start[r + 1]):
                if layer == 0:
                    if not (lit_score[j] > 0.0):
                        continue
                    rr = lit_range[j]
                    ext = lit_extent[j]
                    pt = lit_point[j]
                    dv = lit_dir[j]
                else:
                    rr = hid_range[j]
                    if not (rr == rr):
                        continue
                    ext = hid_extent[j]
                    pt = hid_point[j]
                    dv = hid_dir[j]
                lo = math.floor((rr - 0.5 * ext) / dr - 0.5) + 1.0
                hi = math.ceil((rr + 0.5 * ext) / dr + 0.5) - 1.0
                if hi < 0.0 or lo > n_s - 1.0:
                    continue
                n_lo = int(max(lo, 0.0))
                n_hi = int(min(hi, n_s - 1.0))
                # |dR/dt| = |d·(P − O)|/R: half the footprint (plus half a cell) in t
                slope = abs(dv[0] * (pt[0] - ox) + dv[1] * (pt[1] - oy) + dv[2] * (pt[2] - oz)) / rr
                half_len = (0.5 * ext + dr) / max(slope, 1e-6)
                for n in range(n_lo, n_hi + 1):
                    if layer == 0:
                        score = lit_score[j]
                        if score <= best[r, n]:
                            continue
                        best[r, n] = score
                        obj = lit_object[j]
                        kind[r, n] = 1 if is_seafloor[obj] else 2
                        object_id[r, n] = obj
                    else:
                        if kind[r, n] != 0:
                            continue
                        kind[r, n] = 3
                        shadow_of[r, n] = hid_object[j]
                    _label_ray(dr, pt[0], pt[1], pt[2], dv[0], dv[1], dv[2], ox, oy, oz, half_len,
                               origin_z, height[r], ground[r], n)
