"""Back-end kernels, speckle: the frozen scatterer lattice and its synthesis (docs/physics.md §4)."""
from __future__ import annotations

import math

import numpy as np

from ._numba import njit, prange
from .rays import sin_cos_poly
from .splat import _splat_one

#: splitmix64 constants (Steele, Lea and Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014).
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
def _uniform(hs, k):
    """Uniform in [0, 1) with 53 bits from the k-th draw of scatterer hash hs."""
    return float(_mix64(hs ^ np.uint64(k)) >> np.uint64(11)) * (1.0 / 9007199254740992.0)  # 2**-53


@njit(cache=True, nogil=True)
def _frozen(h, s, n_sub):
    """Reflectivity g and stratified position v of scatterer s of the node with hash h (see
    :func:`frozen_scatterers`): Marsaglia's polar method, no sine or cosine."""
    hs = _mix64(h + np.uint64(s) * _GOLDEN)
    k = 2
    while True:  # accepted with probability π/4 per pair; a 20th pair is needed once in 10¹³
        a = 2.0 * _uniform(hs, k) - 1.0
        b = 2.0 * _uniform(hs, k + 1) - 1.0
        q = a * a + b * b
        if 0.0 < q < 1.0:
            break
        k += 2
    f = math.sqrt(-math.log(q) / q)
    return complex(a * f, b * f), (s + _uniform(hs, 1)) / n_sub


@njit(cache=True, nogil=True)
def frozen_scatterers(seed, ijk, gain, position):
    """Reflectivity and position of each node's scatterers, a pure function of (seed, node, index).

    Uniforms u_k ∈ [0, 1) come from a splitmix64 hash of the seed, the integer node
    coordinates, the scatterer index s and the draw k. Marsaglia's polar method (Marsaglia
    and Bray, SIAM Review 6, 1964): (a, b) = (2u_k − 1, 2u_{k+1} − 1) for k = 2, 4, … until
    0 < q = a² + b² < 1, then g = (a + jb)·√(−ln q / q). Since q is uniform on (0, 1) and
    (a, b)/√q uniform on the circle, |g|² = −ln q is exponential with E|g|² = 1 and the phase
    uniform: the complex Gaussian of Box–Muller without its sine and cosine. v = (s + u₁)/S
    is stratified-uniform on [0, 1). The same node gets the same values in every ping and run.

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


#: Slot-hash multipliers (odd 64-bit constants; only where a node sits in the table depends on them, not any value).
_K1 = np.uint64(0x9E3779B97F4A7C15)
_K2 = np.uint64(0xC2B2AE3D27D4EB4F)
_K3 = np.uint64(0x165667B19E3779F9)

#: Columns of a node row: W, R̄, M2, min R, max R.
NODE_WIDTH = 5
#: Slots of the small direct-mapped node cache behind the last-cell cache (a power of two): the strips of
#: neighbouring echoes cross the same few columns of nodes.
NODE_CACHE = 512
#: Entries of a cache: the last cell (ch, i, j, k) and its 8 node indices, then NODE_CACHE slots of (ch, i, j, k,
#: node index).
CACHE_WIDTH = 12 + 5 * NODE_CACHE


@njit(cache=True, nogil=True)
def _slot_of(ch, ix, iy, iz, mask):
    """First probe of node (ch, i, j, k) in a table of mask + 1 slots."""
    return _mix64((np.uint64(ix) * _K1) ^ (np.uint64(iy) * _K2) ^ (np.uint64(iz) * _K3) ^ np.uint64(ch)) & mask


@njit(cache=True, nogil=True, inline='always')
def _node_index(slots, epoch, ch, ix, iy, iz, nodes, node_key, count):
    """Index of node (ch, i, j, k) in this call's dense node list, appended empty if new: (index, count).

    A slot holds epoch·2³² + node index (8 bytes, so the table stays in cache); the
    key is compared in ``node_key``. The index is −1 when the list is full.
    """
    mask = np.uint64(slots.shape[0] - 1)
    s = _slot_of(ch, ix, iy, iz, mask)
    while True:
        si = np.int64(s)
        if (slots[si] >> 32) != epoch:
            if count >= nodes.shape[0]:
                return -1, count
            slots[si] = (epoch << 32) | count
            nodes[count, 0] = 0.0
            nodes[count, 1] = 0.0
            nodes[count, 2] = 0.0
            nodes[count, 3] = math.inf
            nodes[count, 4] = -math.inf
            node_key[count, 0] = ch
            node_key[count, 1] = ix
            node_key[count, 2] = iy
            node_key[count, 3] = iz
            return count, count + 1
        n = slots[si] & 0xFFFFFFFF
        if node_key[n, 0] == ch and node_key[n, 1] == ix and node_key[n, 2] == iy and node_key[n, 3] == iz:
            return n, count
        s = (s + np.uint64(1)) & mask


@njit(cache=True, nogil=True, inline='always')
def _add_to_node(nodes, n, wb, rr, e2, r_lo, r_hi):
    """Weighted Welford update of node row n with a share wb of an echo at range rr (no cancellation in σ²)."""
    w_new = nodes[n, 0] + wb
    delta = rr - nodes[n, 1]
    nodes[n, 1] += delta * (wb / w_new)
    nodes[n, 2] += wb * (delta * (rr - nodes[n, 1]) + e2)
    nodes[n, 0] = w_new
    nodes[n, 3] = min(nodes[n, 3], r_lo)
    nodes[n, 4] = max(nodes[n, 4], r_hi)


#: A point within this fraction of a cell from a lattice plane is put on it (:func:`_snapped`).
SNAP = 1e-3


@njit(cache=True, nogil=True, inline='always')
def _snapped(t):
    """A trilinear fraction t ∈ [0, 1) put to 0 or 1 within :data:`SNAP` of either: the shares stay a partition of
    one, and a floor on a lattice plane (z = 0, its hits a float32 rounding off it) fills one layer of nodes, not
    two of which one holds 10⁻⁵ of the weight and costs as much to synthesise."""
    if t < SNAP:
        return 0.0
    if t > 1.0 - SNAP:
        return 1.0
    return t


@njit(cache=True, nogil=True, inline='always')
def _uniform_spread(rr, ext):
    """(R, ΔR²/12, R − ΔR/2, R + ΔR/2): an echo spread uniformly over the extent ΔR about R."""
    return rr, ext * ext / 12.0, rr - 0.5 * ext, rr + 0.5 * ext


@njit(cache=True, nogil=True, inline='always')
def _cached_node(cache, ch, ix, iy, iz, slots, epoch, nodes, node_key, count):
    """:func:`_node_index` through the cache's direct-mapped node slots (``cache[12:]``, :data:`NODE_CACHE` rows of
    (ch, i, j, k, index); the slot from the node's low coordinate bits): (index, count), the same as without."""
    k = 12 + 5 * ((ix & 7) | ((iy & 7) << 3) | ((iz & 1) << 6) | ((ch & 3) << 7))
    if cache[k + 4] >= 0 and cache[k] == ch and cache[k + 1] == ix and cache[k + 2] == iy and cache[k + 3] == iz:
        return cache[k + 4], count
    n, count = _node_index(slots, epoch, ch, ix, iy, iz, nodes, node_key, count)
    if n >= 0:
        cache[k], cache[k + 1], cache[k + 2], cache[k + 3], cache[k + 4] = ch, ix, iy, iz, n
    return n, count


@njit(cache=True, nogil=True, inline='always')
def _insert_ray(ch, px, py, pz, w, spread, cell_m, slots, epoch, nodes, node_key, count, cache):
    """Add one ray to the 8 nodes around its hit point (see :func:`gather_nodes`); the new node count or −1.

    ``spread`` = (R, variance, least, greatest) of the range (or time) its echo covers (:func:`_uniform_spread`).

    ``cache`` (CACHE_WIDTH,) int64 holds the last cell (ch, i, j, k) and its 8 node
    indices (−1: not looked up): about two in three consecutive rays share a cell; behind
    it, recently used nodes (:func:`_cached_node`). The caches only skip table lookups, so
    the sums and their order are unchanged.
    """
    if not (w > 0.0):
        return count
    fx = px / cell_m  # divide, not multiply by 1/cell: at 5e6 m the two differ in t by 1e-9
    fy = py / cell_m
    fz = pz / cell_m
    x0 = math.floor(fx)
    y0 = math.floor(fy)
    z0 = math.floor(fz)
    tx = _snapped(fx - x0)
    ty = _snapped(fy - y0)
    tz = _snapped(fz - z0)
    ix0 = np.int64(x0)
    iy0 = np.int64(y0)
    iz0 = np.int64(z0)
    if not (cache[0] == ch and cache[1] == ix0 and cache[2] == iy0 and cache[3] == iz0):
        cache[0] = ch
        cache[1] = ix0
        cache[2] = iy0
        cache[3] = iz0
        cache[4:12] = -1
    for c in range(8):
        dx = c & 1
        dy = (c >> 1) & 1
        dz = (c >> 2) & 1
        b = (tx if dx else 1.0 - tx) * (ty if dy else 1.0 - ty) * (tz if dz else 1.0 - tz)
        if not (b > 0.0):
            continue
        n = cache[4 + c]
        if n < 0:
            n, count = _cached_node(cache, ch, ix0 + dx, iy0 + dy, iz0 + dz, slots, epoch, nodes, node_key, count)
            if n < 0:
                return -1
            cache[4 + c] = n
        _add_to_node(nodes, n, w * b, spread[0], spread[1], spread[2], spread[3])
    return count


@njit(cache=True, nogil=True)
def gather_nodes(channel, points, weights, ranges, extents, cell_m, slots, epoch, nodes, node_key, cache):
    """Share every ray's echo among the 8 surrounding nodes of a cubic lattice (trilinear).

    Node (ch, i, j, k) sits at (i, j, k)·cell_m in world metres and collects, for
    channel ch, W = Σ w·b over the rays whose hit point p lies in one of its 8 cells,
    b the trilinear weight of p for that node (Σb = 1 per ray, so ΣW = Σw), the
    weighted mean range R̄ = Σ w·b·R / W, the centred second moment
    M2 = Σ w·b·((R − R̄)² + ΔR²/12) (each ray's echo spread uniformly over its extent
    ΔR; accumulated with Welford's update, so σ² = M2/W does not cancel) and the
    least and greatest R ∓ ΔR/2. Nodes are found through an open-addressing hash
    table owned by the caller (a slot belongs to this call when its epoch stamp
    equals ``epoch``, so tables are reused without clearing) and listed densely in
    first-touch order: deterministic, and read back sequentially.

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
    slots : (cap,) int64
        Hash table: epoch·2³² + node index per slot (−1: empty); cap a power of two.
    epoch : int
        Stamp of this call, 1 ≤ epoch < 2³¹ (must differ from every earlier call on the same table).
    nodes : (cap // 2, NODE_WIDTH) float64
        Written with W, R̄, M2, min R and max R of each node, in first-touch order.
    node_key : (cap // 2, 4) int64
        Written with each node's (ch, i, j, k).
    cache : (CACHE_WIDTH,) int64
        Scratch for the last cell and its nodes (see :func:`_insert_ray`).

    Returns
    -------
    int
        Number of nodes (rows ``0 … count − 1`` of ``nodes``); −1 when there would be
        more than ``nodes.shape[0]``: the caller grows the table and calls again with a
        new epoch.
    """
    cache[:] = -1
    count = 0
    for r in range(points.shape[0]):
        count = _insert_ray(channel[r], points[r, 0], points[r, 1], points[r, 2], weights[r],
                            _uniform_spread(ranges[r], extents[r]), cell_m, slots, epoch, nodes, node_key, count,
                            cache)
        if count < 0:
            return -1
    return count


#: Most points a strip is cut into (a guard against a runaway R·|a|/cell, far above any fan's).
MAX_SPREAD = 4096


@njit(cache=True, nogil=True, inline='always')
def _table_at(gain, r, s, s0, step):
    """Row r of a table ``gain`` on s = s0 + k·step at s, linear between its samples, 0 outside it."""
    x = (s - s0) / step
    n = gain.shape[1]
    if not (x >= 0.0 and x <= n - 1):
        return 0.0
    k = min(int(x), n - 2)
    t = x - k
    return gain[r, k] * (1.0 - t) + gain[r, k + 1] * t


@njit(cache=True, nogil=True, inline='always')
def _pattern_at(echoes, r, s):
    """Row r's along-track pattern P(s) (``gain``, ``s0``, ``step`` of
    :data:`~sonar_embree.kernels.args.SpeckleEchoes`), linear between its samples, 0 outside the table."""
    return _table_at(echoes.gain, r, s, echoes.s0, echoes.step)


@njit(cache=True, nogil=True, inline='always')
def _along_s(axis, r, dx, dy, dz):
    """(s, |a|, R): the along-track direction cosine s = d·x̂/|d| of the offset d = (dx, dy, dz) from the transmitter
    in row r (``axis`` a·x̂ per row), |a| and R = |d|; s = 2 (outside every table) where a or d is 0."""
    ax, ay, az = axis[r, 0], axis[r, 1], axis[r, 2]
    a = math.sqrt(ax * ax + ay * ay + az * az)
    rng = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not (a > 0.0 and rng > 0.0):
        return 2.0, a, rng
    return (dx * ax + dy * ay + dz * az) / (a * rng), a, rng


@njit(cache=True, nogil=True, inline='always')
def _strip_of(axis, r, px, py, pz, tx, cell_m):
    """How ping row r's strip through (px, py, pz) is cut (rows with strips only): (m, sx, sy, sz), m = ⌈R·|a|/cell⌉
    parts one step (sx, sy, sz) = (R·|a|/m)·x̂ apart (:func:`_gather_ping`)."""
    _, a, rng = _along_s(axis, r, px - tx[0], py - tx[1], pz - tx[2])
    m = min(max(int(math.ceil(rng * a / cell_m)), 1), MAX_SPREAD)
    step = rng * a / m
    return m, axis[r, 0] / a * step, axis[r, 1] / a * step, axis[r, 2] / a * step


#: Columns of a strip group (:func:`_gather_ping`): W, Σ w·(p − p₀) (3), mean time, M2, least and greatest time,
#: the lattice cell (i, j, k) of its first echo and that echo's point p₀ (3).
GROUP_WIDTH = 14


@njit(cache=True, nogil=True, inline='always')
def _group_add(grp, w, px, py, pz, rr, ext):
    """Add an echo of weight w at (px, py, pz), time rr spread over ext, to the group ``grp`` (weighted Welford; the
    points' sum taken about the first one's, so that the centre keeps its bits far from the origin)."""
    t, e2, lo, hi = _uniform_spread(rr, ext)
    w_new = grp[0] + w
    delta = t - grp[4]
    grp[4] += delta * (w / w_new)
    grp[5] += w * (delta * (t - grp[4]) + e2)
    grp[0] = w_new
    grp[1] += w * (px - grp[11])
    grp[2] += w * (py - grp[12])
    grp[3] += w * (pz - grp[13])
    grp[6] = min(grp[6], lo)
    grp[7] = max(grp[7], hi)


@njit(cache=True, nogil=True)
def _group_flush(grp, echoes, r, ch, tx, cell_m, slots, epoch, nodes, node_key, count, cache):
    """Spread the group's echoes, taken together at their weighted centre, over its strip (:func:`_gather_ping`)
    and empty it; the new node count or −1."""
    w = grp[0]
    if not (w > 0.0):
        return count
    px, py, pz = grp[11] + grp[1] / w, grp[12] + grp[2] / w, grp[13] + grp[3] / w
    m, ux, uy, uz = _strip_of(echoes.axis, r, px, py, pz, tx, cell_m)
    spread = (grp[4], grp[5] / w, grp[6], grp[7])
    for j in range(m):
        o = j - 0.5 * (m - 1)
        count = _insert_ray(ch, px + o * ux, py + o * uy, pz + o * uz, w / m, spread, cell_m, slots, epoch, nodes,
                            node_key, count, cache)
        if count < 0:
            return -1
    grp[:6] = 0.0
    grp[6], grp[7] = math.inf, -math.inf
    return count


@njit(cache=True, nogil=True, inline='always')
def _same_cell(grp, px, py, pz, cell_m):
    """Whether (px, py, pz) lies in the lattice cell of the group's first echo (and makes it the first echo of an
    empty group)."""
    i, j, k = math.floor(px / cell_m), math.floor(py / cell_m), math.floor(pz / cell_m)
    if grp[0] > 0.0:
        return grp[8] == i and grp[9] == j and grp[10] == k
    grp[8], grp[9], grp[10], grp[11], grp[12], grp[13] = i, j, k, px, py, pz
    return True


@njit(cache=True, nogil=True)
def _gather_ping(b, n_ch, echoes, tx, cell_m, slots, epoch, nodes, node_key, cache):
    """:func:`gather_nodes` on ping b's rays of ``echoes`` (:data:`~sonar_embree.kernels.args.SpeckleEchoes`),
    channel by channel (points local + origin); count, or −2 − k when the table filled at the ping's k-th ray (k
    from 0; the caller sizes the next table from it: :func:`sonar_embree.signal.synthesis.grown_capacity`).

    Where the rows have strips (``axis`` a·x̂ and the pattern P), an echo of weight w at range R from ``tx`` (the
    ping's transmitter, world m) and along-track cosine s stands for a strip R·|a| long along x̂, and weighs
    w' = w/P(s): its own line's beam factor taken out (an echo where P(s) = 0 carries nothing). Consecutive such
    echoes in one lattice cell (a line's neighbours across track) are taken together at their w'-weighted centre,
    with their times' moments and bounds (:func:`_group_add`); the group then becomes m = ⌈R·|a|/cell⌉ points
    evenly over its strip, j − (m − 1)/2 steps of R·|a|/m along x̂, each of weight ΣW'/m (:func:`_group_flush`).
    The node weights then hold what varies slowly along track (area, elevation pattern, scattering), every node
    under the strips is lit in every ping, and :func:`_emit_ping` puts the beam back at each node's own s. An echo
    not ``on_strip`` (of a ray aimed at an object, whose spacing is its own) stays at its point with weight w'.
    """
    ray_start, points, origin, weights, times, extents = echoes[:6]
    cache[:] = -1
    count = 0
    grp = np.zeros(GROUP_WIDTH)
    grp[6], grp[7] = math.inf, -math.inf
    strips = echoes.axis.shape[0] > 0
    for ch in range(n_ch):
        r = n_ch * b + ch
        for i in range(ray_start[r], ray_start[r + 1]):
            px, py, pz = points[i, 0] + origin[0], points[i, 1] + origin[1], points[i, 2] + origin[2]
            w, on_strip = weights[i], False
            if strips:
                p_s = _pattern_at(echoes, r, _along_s(echoes.axis, r, px - tx[0], py - tx[1], pz - tx[2])[0])
                w = w / p_s if p_s > 0.0 else 0.0
                on_strip = w > 0.0 and (echoes.on_strip.shape[0] == 0 or echoes.on_strip[i])
            if on_strip and not _same_cell(grp, px, py, pz, cell_m):
                count = _group_flush(grp, echoes, r, ch, tx, cell_m, slots, epoch, nodes, node_key, count, cache)
                _same_cell(grp, px, py, pz, cell_m)
            if on_strip:
                _group_add(grp, w, px, py, pz, times[i], extents[i])
            else:
                count = _insert_ray(ch, px, py, pz, w, _uniform_spread(times[i], extents[i]), cell_m, slots, epoch,
                                    nodes, node_key, count, cache)
            if count < 0:
                return -2 - (i - ray_start[n_ch * b])
        count = _group_flush(grp, echoes, r, ch, tx, cell_m, slots, epoch, nodes, node_key, count, cache)
        if count < 0:
            return -2 - (ray_start[r + 1] - ray_start[n_ch * b])
    return count


@njit(cache=True, nogil=True, inline='always')
def _node_beam(echoes, r, ix, iy, iz, cell_m, tx):
    """The along-track beam factor P(s) at node (i, j, k) of row r (1 without strips, :func:`_gather_ping`)."""
    axis = echoes.axis
    if axis.shape[0] == 0:
        return 1.0
    s = _along_s(axis, r, ix * cell_m - tx[0], iy * cell_m - tx[1], iz * cell_m - tx[2])[0]
    return _pattern_at(echoes, r, s)


@njit(cache=True, nogil=True, inline='always')
def _distance(ix, iy, iz, cell_m, pos):
    """|node (i, j, k)·cell − pos|, m."""
    ddx = ix * cell_m - pos[0]
    ddy = iy * cell_m - pos[1]
    ddz = iz * cell_m - pos[2]
    return math.sqrt(ddx * ddx + ddy * ddy + ddz * ddz)


@njit(cache=True, nogil=True, inline='always')
def _emit_node(nodes, node_key, q, pos_tx, pos_rx, gains, vel_rx, rx_ref, time_per_m, lattice, waveform, out):
    """Splat node q's ``n_sub`` frozen scatterers into each of its channel's receivers' rows of ``out`` (see
    :func:`speckle_block`): the node's phase and delay per receiver here, receiver k's amplitude times
    ``gains[k]`` (:func:`_element_gains`), its scatterers by :func:`_splat_scatterers`.

    Reads rows by index, never through a row view (kernels/_numba.py: views contend for the reference count).
    """
    seed, cell_m, wavelength_m, n_sub = lattice
    w = nodes[q, 0]
    t_mean = nodes[q, 1]  # the receiver has moved on by vel_rx·t̄ (0 when stop-and-hop: the same bits)
    sigma = math.sqrt(max(nodes[q, 2] / w, 0.0))
    ch = node_key[q, 0]
    ix = node_key[q, 1]
    iy = node_key[q, 2]
    iz = node_key[q, 3]
    h = _node_hash(seed, ix, iy, iz)
    spread = math.sqrt(3.0) * sigma
    d_tx = _distance(ix, iy, iz, cell_m, pos_tx)
    d_ref = 0.0
    if time_per_m != 0.0:  # each receiver's own leg, where it is when the echo arrives, for the echoes' still one
        d_ref = _distance(ix, iy, iz, cell_m, rx_ref)
    n_rx = gains.shape[0]
    for k in range(n_rx):
        j = ch * n_rx + k
        rx = (pos_rx[j, 0] + vel_rx[0] * t_mean, pos_rx[j, 1] + vel_rx[1] * t_mean, pos_rx[j, 2] + vel_rx[2] * t_mean)
        d_rx = _distance(ix, iy, iz, cell_m, rx)
        cycles = ((d_tx + d_rx) / wavelength_m) % 1.0  # monostatic: d + d = 2d exactly, the bits of 2d/λ
        base = math.sqrt(w / n_sub) * complex(math.cos(2.0 * math.pi * cycles), -math.sin(2.0 * math.pi * cycles))
        if gains[k] != 1.0:
            base *= gains[k]
        shift = (d_rx - d_ref) * time_per_m if time_per_m != 0.0 else 0.0
        _splat_scatterers(out, j, h, n_sub, base, t_mean, spread, nodes[q, 3], nodes[q, 4], shift, waveform)


@njit(cache=True, nogil=True, inline='always')
def _splat_scatterers(out, j, h, n_sub, base, t_mean, spread, t_lo, t_hi, shift, waveform):
    """Add a node's ``n_sub`` frozen scatterers (hash ``h``) to row ``j`` of ``out``: scatterer k at envelope time
    clip(t̄ + spread·(2v − 1), t_lo, t_hi) + ``shift`` (s) with amplitude ``base``·g (g, v of :func:`_frozen`), the
    ``waveform``'s extra carrier phase applied (see :func:`speckle_block`)."""
    table, table_start, table_rate, rate_hz, phase_cycles_per_s = waveform
    for sub in range(n_sub):
        g, v = _frozen(h, sub, n_sub)
        r_env = min(max(t_mean + spread * (2.0 * v - 1.0), t_lo), t_hi) + shift
        a = base * g
        if phase_cycles_per_s != 0.0:
            ph = 2.0 * math.pi * ((phase_cycles_per_s * r_env) % 1.0)
            a = a * complex(math.cos(ph), math.sin(ph))
        _splat_one(out, j, r_env * rate_hz, a, table, table_start, table_rate)


@njit(cache=True, nogil=True, inline='always')
def _beam_on(echoes, b, n_ch, nodes_t, key_t, q, cell_m, tx):
    """Put the along-track beam at node q's own s into its weight (:func:`_node_beam`; W and M2 scaled alike, so
    σ² = M2/W stays); whether the node radiates at all."""
    beam = _node_beam(echoes, n_ch * b + key_t[q, 0], key_t[q, 1], key_t[q, 2], key_t[q, 3], cell_m, tx)
    if beam != 1.0:
        nodes_t[q, 0] *= beam
        nodes_t[q, 2] *= beam
    return beam > 0.0


@njit(cache=True, nogil=True)
def _emit_ping(b, n_ch, count, nodes_t, key_t, echoes, ends, n_rx, lattice, waveform, out_b):
    """Every node 0 … count − 1 of ping b's table into ``out_b`` (:func:`_emit_node`), each with the along-track
    beam at its own s where the echoes have strips (:func:`_beam_on`), the ping's ends
    (:data:`~sonar_embree.kernels.args.PathEnds`) taken once (views made once per ping, not per node)."""
    tx, rx, v_rx, ref, time_per_m = ends.tx[b], ends.rx[b], ends.vel_rx[b], ends.rx_ref[b], ends.time_per_m
    gains = np.ones(n_rx)
    apart = _any_apart(rx, ref) if time_per_m != 0.0 else False
    for q in range(count):
        if _beam_on(echoes, b, n_ch, nodes_t, key_t, q, lattice.cell_m, tx):
            if apart:                                 # receivers on their own paths: each its own receive pattern
                _element_gains(echoes, n_ch * b, key_t, q, _seen_from(key_t, nodes_t, q, lattice.cell_m, v_rx), ref,
                               rx, gains)
            _emit_node(nodes_t, key_t, q, tx, rx, gains, v_rx, ref, time_per_m, lattice, waveform, out_b)


@njit(cache=True, nogil=True, inline='always')
def _any_apart(rx, ref):
    """Whether any receiver (rows of ``rx``) is away from ``ref`` (the receiver the echoes were made for)."""
    for j in range(rx.shape[0]):
        if rx[j, 0] != ref[0] or rx[j, 1] != ref[1] or rx[j, 2] != ref[2]:
            return True
    return False


@njit(cache=True, nogil=True, inline='always')
def _seen_from(key_t, nodes_t, q, cell_m, vel):
    """Node q's place less vel·t̄ (t̄ its mean time): where the receivers, at their places at the ping's time,
    see it when its echo arrives (as they move on by vel·t̄)."""
    t = nodes_t[q, 1]
    return (key_t[q, 1] * cell_m - vel[0] * t, key_t[q, 2] * cell_m - vel[1] * t, key_t[q, 3] * cell_m - vel[2] * t)


@njit(cache=True, nogil=True, inline='always')
def _element_gains(echoes, row0, key_t, q, x, ref, rx, gains):
    """``gains[k]`` = Γ_rx(s_k)/Γ_rx(s) for each receiver k of node q's channel (rows ch·n + k of ``rx``, n =
    gains.shape[0]; :func:`_pattern_ratios` in row ``row0`` + the channel): s_k the receiver's own along-track
    cosine to the node seen at ``x`` (:func:`_seen_from`), s that of ``ref``, the receiver the echo's weight was
    made for (the transmitter or its image), 1 without strips; times the across factor's ratio at each receiver's
    own direction where the echoes have one (:func:`_across_ratios`)."""
    ch, n = key_t[q, 0], gains.shape[0]
    r = row0 + ch
    if echoes.axis.shape[0] == 0:
        for k in range(n):                          # by index: a slice is a view, whose count threads contend for
            gains[k] = 1.0
    else:
        for k in range(n):
            j = ch * n + k
            gains[k] = _along_s(echoes.axis, r, x[0] - rx[j, 0], x[1] - rx[j, 1], x[2] - rx[j, 2])[0]
        _pattern_ratios(echoes, r, _along_s(echoes.axis, r, x[0] - ref[0], x[1] - ref[1], x[2] - ref[2])[0], gains)
    _across_ratios(echoes, r, x, ref, rx, ch, gains)


@njit(cache=True, nogil=True, inline='always')
def _across_at(echoes, r, x, at):
    """The receive pattern's across factor |Γ(v)| (:func:`_across_table`) at a receiver at ``at`` for a node at ``x``,
    v the cosine of x − at with row r's across axis ``side`` (:data:`~sonar_embree.kernels.args.Across`)."""
    return _across_table(echoes, _cosine_to(x, at, _side_of(echoes, r)))


@njit(cache=True, nogil=True, inline='always')
def _across_table(echoes, v):
    """|Γ(v)| from ``echoes.across`` on v0 + k·v_step, linear between its samples, 0 outside."""
    table = echoes.across
    x = (v - echoes.v0) / echoes.v_step
    n = table.shape[0]
    if x < 0.0 or x > n - 1:
        return 0.0
    i = min(int(x), n - 2)
    t = x - i
    return table[i] * (1.0 - t) + table[i + 1] * t


@njit(cache=True, nogil=True, inline='always')
def _side_of(echoes, r):
    """Row r's across axis v̂ as a 3-tuple; (0, 0, 0) without across axes."""
    if echoes.side.shape[0] == 0:
        return 0.0, 0.0, 0.0
    return echoes.side[r, 0], echoes.side[r, 1], echoes.side[r, 2]


@njit(cache=True, nogil=True, inline='always')
def _across_ratios(echoes, r, x, ref, rx, ch, gains):
    """In place, ``gains[k]`` times |Γ(v_k)|/|Γ(v)| (:func:`_across_at`, row r): receiver k of channel ch (row
    ch·n + k of ``rx``, n = gains.shape[0]) sees the node at ``x`` along its own direction, ``ref`` (the receiver
    the echo's weight was made for) along v. Nothing without across axes or where |Γ(v)| is 0; v_k = v gives 1
    exactly (a receiver at the reference keeps its bits)."""
    if echoes.side.shape[0] == 0:
        return
    g = _across_at(echoes, r, x, ref)
    if g <= 0.0:
        return
    n = gains.shape[0]
    for k in range(n):
        j = ch * n + k
        gains[k] *= _across_at(echoes, r, x, (rx[j, 0], rx[j, 1], rx[j, 2])) / g


@njit(cache=True, nogil=True, inline='always')
def _unit_axis(axis, r):
    """Row r's forward axis x̂ (``axis`` = |a|·x̂ per row), a 3-tuple; (0, 0, 0) without strips."""
    if axis.shape[0] == 0:
        return 0.0, 0.0, 0.0
    a = math.sqrt(axis[r, 0] * axis[r, 0] + axis[r, 1] * axis[r, 1] + axis[r, 2] * axis[r, 2])
    return axis[r, 0] / a, axis[r, 1] / a, axis[r, 2] / a


@njit(cache=True, nogil=True, inline='always')
def _pattern_ratios(echoes, r, s, s_k):
    """In place, each receiver's along-track cosine ``s_k[k]`` → Γ_rx(s_k)/Γ_rx(s), the receive pattern
    (``gain_rx`` of :data:`~sonar_embree.kernels.args.SpeckleEchoes`, row r, linear between its samples, 0 outside)
    at its own direction against the reference receiver's s; 1 where s_k = s (a receiver at the reference: its
    bits kept) or Γ_rx(s) is 0."""
    gain, s0, n = echoes.gain_rx, echoes.s0, echoes.gain_rx.shape[1]
    per_step = 1.0 / echoes.step
    g = _table_at(gain, r, s, s0, echoes.step)
    inv_g = 1.0 / g if g > 0.0 else 0.0
    for k in range(s_k.shape[0]):
        x = (s_k[k] - s0) * per_step
        if inv_g == 0.0 or s_k[k] == s:
            s_k[k] = 1.0
        elif x >= 0.0 and x <= n - 1:
            i = min(int(x), n - 2)
            t = x - i
            s_k[k] = (gain[r, i] * (1.0 - t) + gain[r, i + 1] * t) * inv_g
        else:
            s_k[k] = 0.0


@njit(cache=True, nogil=True, inline='always')
def turn(x):
    """e^(−j2π·x) for 0 ≤ x < 1 without libm: x − n/4 (n the nearest quarter, exact) times 2π, then fdlibm's sine
    and cosine polynomials on |y| ≤ π/4 (kernels/rays.py) and the quarter turn n·π/2 by swapping and signs. Within
    4·10⁻¹⁶ of NumPy's (tests/kernels/test_kernels.py), at a fifth of the time of a sine and a cosine."""
    n = math.floor(4.0 * x + 0.5)
    sp, cp = sin_cos_poly(2.0 * math.pi * (x - 0.25 * n))
    q = int(n)
    odd = (q & 1) == 1
    return complex((1 - 2 * (((q + 1) >> 1) & 1)) * (sp if odd else cp),   # quarter turns, without a branch
                   (2 * ((q >> 1) & 1) - 1) * (cp if odd else sp))


@njit(cache=True, nogil=True, inline='always')
def _node_impulses(nodes, q, ijk, lattice, rate, amps, where):
    """Node q's (at lattice index ``ijk``) ``n_sub`` frozen scatterers on the reference path: amplitude √(W/n_sub)·g
    into ``amps`` and envelope time × ``rate`` into ``where`` (:func:`_splat_scatterers`' times, without a
    waveform)."""
    n_sub = lattice.n_sub
    h = _node_hash(lattice.seed, ijk[0], ijk[1], ijk[2])
    w, t_mean = nodes[q, 0], nodes[q, 1]
    spread = math.sqrt(3.0) * math.sqrt(max(nodes[q, 2] / w, 0.0))
    amp = math.sqrt(w / n_sub)
    for sub in range(n_sub):
        g, v = _frozen(h, sub, n_sub)
        amps[sub] = amp * g
        where[sub] = min(max(t_mean + spread * (2.0 * v - 1.0), nodes[q, 3]), nodes[q, 4]) * rate


@njit(cache=True, nogil=True, inline='always')
def _emit_node_shared(nodes, node_key, q, ends_b, lattice, rate, shift, out, scratch, echoes, row0):
    """Node q heard by each of its channel's receivers (:func:`speckle_block_shared`): its scatterers once
    (:func:`_node_impulses`), every receiver's phase, delay and receive pattern at once (:func:`_receivers`), then
    each scatterer as an impulse at its time per receiver (:func:`_add_impulse`). ``rate``: sub-rows per second
    (S·fs); ``shift``: log2 S; ``scratch`` = (amplitudes, times, the receivers' arrays of :func:`_receivers`)."""
    amps, where, per_rx = scratch
    ch = node_key[q, 0]
    _node_impulses(nodes, q, (node_key[q, 1], node_key[q, 2], node_key[q, 3]), lattice, rate, amps, where)
    _receivers(nodes, node_key, q, ends_b, lattice, rate, echoes, row0, per_rx)
    phase, delay = per_rx[0], per_rx[1]
    n_rx = phase.shape[0]
    for k in range(n_rx):
        for sub in range(amps.shape[0]):
            _add_impulse(out, ch * n_rx + k, where[sub] + delay[k], phase[k] * amps[sub], shift)


@njit(cache=True, nogil=True, inline='always')
def _receivers(nodes, node_key, q, ends_b, lattice, rate, echoes, row0, per_rx):
    """Node q for each receiver k of its channel, into ``per_rx`` = (phase, delay, cosine, across) (n_rx,) each:
    its phase and delay (:func:`_receiver_turns`), the phase times the receive pattern's ratios at the receiver's
    own direction against the reference receiver's, along track where the echoes have strips
    (:func:`_pattern_ratios`, row ``row0`` + the channel) and across track where they have across axes
    (:func:`_across_table`), the cosines from the distances the phase loop leaves in ``cosine``."""
    phase, delay, cosine, across_v = per_rx
    ch = node_key[q, 0]
    r = row0 + ch
    seen = _receiver_turns((node_key[q, 1], node_key[q, 2], node_key[q, 3]), nodes[q, 1], ch, ends_b, lattice, rate,
                           phase, delay, cosine)
    n_rx = phase.shape[0]
    side = _side_of(echoes, r)
    if echoes.side.shape[0] > 0:                                   # before the distances become along cosines
        _cosines(seen, ch, ends_b[1], side, cosine, across_v)
    if echoes.axis.shape[0] > 0:
        fwd = _unit_axis(echoes.axis, r)
        _cosines(seen, ch, ends_b[1], fwd, cosine, cosine)
        _pattern_ratios(echoes, r, _cosine_to(seen, ends_b[3], fwd), cosine)
        for k in range(n_rx):
            phase[k] *= cosine[k]
    if echoes.side.shape[0] > 0:
        g = _across_table(echoes, _cosine_to(seen, ends_b[3], side))
        if g > 0.0:
            for k in range(n_rx):
                phase[k] *= _across_table(echoes, across_v[k]) / g


@njit(cache=True, nogil=True, inline='always')
def _cosines(seen, ch, rx, axis, dist, out):
    """``out[k]`` = (seen − rx_k)·axis/dist[k] for receiver k of channel ch (row ch·n + k of ``rx``, n =
    out.shape[0]), ``dist`` its distances |seen − rx_k| (``out`` may be ``dist``: each entry read before written)."""
    n = out.shape[0]
    for k in range(n):
        j = ch * n + k
        out[k] = ((seen[0] - rx[j, 0]) * axis[0] + (seen[1] - rx[j, 1]) * axis[1] + (seen[2] - rx[j, 2]) * axis[2]) / \
            dist[k]


@njit(cache=True, nogil=True, inline='always')
def _cosine_to(seen, ref, axis):
    """The cosine of seen − ref with the unit ``axis``."""
    dx, dy, dz = seen[0] - ref[0], seen[1] - ref[1], seen[2] - ref[2]
    return (dx * axis[0] + dy * axis[1] + dz * axis[2]) / math.sqrt(dx ** 2 + dy ** 2 + dz ** 2)


@njit(cache=True, nogil=True, inline='always')
def _receiver_turns(ijk, t_mean, ch, ends_b, lattice, rate, phase, delay, dist):
    """For node (i, j, k) of channel ch and every receiver k of it, in a loop that vectorises: ``phase[k]`` =
    e^(−j2π·(|X − tx| + |X − rx_k − v·t̄|)/λ), ``delay[k]`` = (|X − rx_k − v·t̄| − |X − rx_ref|)·time_per_m
    × ``rate`` (grid steps) and ``dist[k]`` = |X − v·t̄ − rx_k|, the ping's ends ``ends_b`` = (tx, rx, v, rx_ref,
    time_per_m). Returns X − v·t̄, where the moving receivers see the node (a 3-tuple)."""
    tx, rx, vel, ref, time_per_m = ends_b
    cell_m = lattice.cell_m
    x0, y0, z0 = (ijk[0] * cell_m - vel[0] * t_mean, ijk[1] * cell_m - vel[1] * t_mean,
                  ijk[2] * cell_m - vel[2] * t_mean)
    d_tx = _distance(ijk[0], ijk[1], ijk[2], cell_m, tx)
    d_ref = _distance(ijk[0], ijk[1], ijk[2], cell_m, ref)        # the leg the echoes' times were made for
    n_rx = phase.shape[0]
    for k in range(n_rx):
        j = ch * n_rx + k
        d_rx = math.sqrt((x0 - rx[j, 0]) ** 2 + (y0 - rx[j, 1]) ** 2 + (z0 - rx[j, 2]) ** 2)
        cycles = (d_tx + d_rx) / lattice.wavelength_m
        phase[k] = turn(cycles - math.floor(cycles))              # x − ⌊x⌋ = x % 1.0, exactly
        delay[k] = (d_rx - d_ref) * time_per_m * rate
        dist[k] = d_rx
    return x0, y0, z0


@njit(cache=True, nogil=True, inline='always')
def _add_impulse(out, j, x, a, shift):
    """An impulse of amplitude a at time x (in 1/S sample, S = out.shape[1] a power of two) into row j of ``out``
    (rows, S, n): weights 1 − f and f (f = x − ⌊x⌋) at ⌊x⌋ and ⌊x⌋ + 1, each index i in sub-row i mod S of sample
    ⌊i/S⌋ (dropped outside the record); ``shift`` = log2 S."""
    n = out.shape[2]
    i = int(math.floor(x))
    f = x - i
    for ii, c in ((i, a * (1.0 - f)), (i + 1, a * f)):
        whole = ii >> shift
        if 0 <= whole < n:
            out[j, ii - (whole << shift), whole] += c


@njit(cache=True, nogil=True, inline='always')
def _log2(steps):
    """log2 of a power of two."""
    k = 0
    while (1 << k) < steps:
        k += 1
    return k


@njit(cache=True, nogil=True)
def _emit_ping_shared(b, n_ch, count, nodes_t, key_t, echoes, ends, lattice, rate, out_b, scratch):
    """:func:`_emit_ping` with one emission per node for all its receivers (:func:`_emit_node_shared`), the nodes
    in order of their mean time (each element's impulses then land near the last ones: about a quarter less time, docs/benchmarks.md)."""
    ends_b = (ends.tx[b], ends.rx[b], ends.vel_rx[b], ends.rx_ref[b], ends.time_per_m)
    shift = _log2(out_b.shape[1])                                 # once per ping, not per impulse
    order = np.argsort(nodes_t[:count, 1])
    for i in range(count):
        q = order[i]
        if _beam_on(echoes, b, n_ch, nodes_t, key_t, q, lattice.cell_m, ends_b[0]):
            _emit_node_shared(nodes_t, key_t, q, ends_b, lattice, rate, shift, out_b, scratch, echoes, n_ch * b)


@njit(cache=True, nogil=True, inline='always')
def _ping_nodes(b, t, n_ch, echoes, tx, cell_m, tables):
    """Ping b's lattice nodes in hash table t (a new epoch of it, :func:`_gather_ping`): their count, or −2 − k when
    the table filled at the ping's k-th ray."""
    slots, epochs, nodes, node_key, caches = tables
    epochs[t] += 1
    return _gather_ping(b, n_ch, echoes, tx, cell_m, slots[t], epochs[t], nodes[t], node_key[t], caches[t])


@njit(cache=True, nogil=True, parallel=True)
def speckle_block(echoes, ends, lattice, waveform, tables, status, out):
    """Speckle of a block of pings: rays → frozen lattice scatterers → delayed waveforms, one ping per task.

    For each ping: :func:`gather_nodes` on the ping's echoes (channel by channel; each
    spread over its along-track strip where an ``axis`` is given, :func:`_gather_ping`),
    then every node's ``n_sub`` scatterers, with the reflectivity g and stratified
    position v of :func:`frozen_scatterers`, at envelope travel time

        t = clip(t̄ + √3·σ·(2v − 1), t_min, t_max),  σ² = M2/W,

    with amplitude √(W/n_sub)·g·e^(−j2π·(L_node/λ mod 1))·e^(j2π·(φ·t mod 1)), L_node
    the node's distance from the transmitter plus that to the receiver where it is when the
    node's echo arrives, rx + v·t̄ (2R for the direct path of a sonar at rest; motion during the
    ping, docs/physics.md §16) and φ = ``phase_cycles_per_s``; each adds
    a·h(k − t·rate_hz) to its channel's row. Pings are split into one contiguous
    chunk per hash table; a ping's result depends only on its own rays, so the
    output does not depend on the number of tables or threads.

    Parameters
    ----------
    echoes : :data:`~sonar_embree.kernels.args.SpeckleEchoes`
        ``ray_start`` (channels·pings + 1,) int64, the row offsets of the block (row channels·b + ch: channel ch of
        ping b); ``points`` (n, 3) float64, hit points in the scene's local frame (m), ``origin`` (3,) float64
        making them world; ``weights``, ``times``, ``extents`` (n,) float64: expected intensity, two-way travel time
        (s) and its extent (s) of every echo; ``axis`` (rows, 3), ``gain`` (rows, n_tab), ``s0``, ``step``:
        each row's forward axis times the fan's line spacing and its along-track pattern on s0 + k·step, every echo
        ``on_strip`` ((n,) bool; (0,): all) then spread over its strip, the along-track beam taken out and put back
        at every node (:func:`_gather_ping`, :func:`_emit_ping`); an empty ``axis`` (0, 3): each echo at its point.
    ends : :data:`~sonar_embree.kernels.args.PathEnds`
        ``tx`` (pings, 3) float64: the transmitting position per ping, world m; ``rx`` (pings, channels·n_rx, 3)
        float64: the receiving positions, n_rx per channel of the echoes (receiver k of channel ch writes row
        ch·n_rx + k of ``out``; one per channel for a single receiver; the mirror image in the sea surface for a
        surface leg): the node phase is (|X − tx| + |X − rx − v·t̄|)/λ; ``vel_rx`` (pings, 3): the receivers'
        velocity per ping, world m per unit of ``times`` (zeros: stop-and-hop); ``rx_ref`` (pings, 3): the
        receiver the echoes' times were made for, still, and ``time_per_m`` (units of ``times`` per m, 1/c; 0:
        none): each receiver's envelope is delayed by (|X − rx − v·t̄| − |X − rx_ref|)·time_per_m, its own
        bistatic path where it is when the echo arrives (docs/physics.md §16, §18a).
    lattice : :data:`~sonar_embree.kernels.args.Lattice`
        Speckle ``seed`` (int), lattice spacing ``cell_m`` (m), acoustic wavelength (m) and scatterers per node
        ``n_sub``.
    waveform : :data:`~sonar_embree.kernels.args.Waveform`
        The waveform h (``table``, ``table_start``, ``table_rate``, as for :func:`splat_table`), output samples per
        second of travel time ``rate_hz`` and extra carrier cycles per second.
    tables : :data:`~sonar_embree.kernels.args.NodeTables`
        ``slots`` (T, cap) int64, ``epochs`` (T,) int64, ``nodes`` (T, cap // 2, NODE_WIDTH) float64, ``node_key``
        (T, cap // 2, 4) int64, ``caches`` (T, CACHE_WIDTH) int64: T hash tables, node lists and last-cell caches
        (see :func:`gather_nodes`), reused without clearing.
    status : (pings,) int64
        0: to do (set to 1 when done, −2 − k when its table filled at the ping's k-th ray: grow the tables,
        reset to 0 and call again; nothing was written for that ping).
    out : (pings, channels·n_rx, n_samples) complex128
        Accumulator.
    """
    cell_m = lattice.cell_m
    slots, nodes, node_key = tables.slots, tables.nodes, tables.node_key
    n_p = ends.tx.shape[0]
    n_ch = (echoes.ray_start.shape[0] - 1) // max(n_p, 1)  # the echoes' channels; each heard by n_rx receivers
    n_rx = out.shape[1] // max(n_ch, 1)
    n_t = slots.shape[0]
    for t in prange(n_t):
        for b in range(t * n_p // n_t, (t + 1) * n_p // n_t):
            if status[b] != 0:
                continue
            count = _ping_nodes(b, t, n_ch, echoes, ends.tx[b], cell_m, tables)
            if count < 0:
                status[b] = count
                continue
            _emit_ping(b, n_ch, count, nodes[t], node_key[t], echoes, ends, n_rx, lattice, waveform, out[b])
            status[b] = 1


@njit(cache=True, nogil=True, parallel=True)
def speckle_block_shared(echoes, ends, lattice, waveform, tables, status, out):
    """:func:`speckle_block` for receiver arrays in baseband: every node's scatterers drawn once for all receivers,
    as impulses whose fractional delays the caller applies in the frequency domain.

    The same gather and nodes; each node's ``n_sub`` scatterers take their amplitude √(W/n_sub)·g and envelope time
    t once (:func:`_node_impulses`); each receiver, moved to rx + v·t̄, adds them times its own phase
    e^(−j2π·(|X − tx| + |X − rx − v·t̄|)/λ) at t + (|X − rx − v·t̄| − |X − rx_ref|)·time_per_m as impulses on a
    grid of 1/S sample, split linearly between the two nearest grid times (:func:`_add_impulse`). ``out`` (pings,
    channels·n_rx, S, n_samples) complex128 holds grid time i in sub-row i mod S of sample ⌊i/S⌋: sub-row s is
    still to be delayed by s/S sample, and the waveform to be applied (both once per row by FFT,
    :func:`sonar_embree.signal.synthesis.delayed_sum`). Of ``waveform`` only ``rate_hz`` is read; its carrier phase
    must be 0 (baseband). Cost: one gather, the scatterers once and 2·n_sub writes per receiver and node, where
    :func:`speckle_block` splats every scatterer's tabulated waveform once per receiver.
    """
    cell_m = lattice.cell_m
    slots, nodes, node_key = tables.slots, tables.nodes, tables.node_key
    n_p = ends.tx.shape[0]
    n_ch = (echoes.ray_start.shape[0] - 1) // max(n_p, 1)
    n_rx = out.shape[1] // max(n_ch, 1)
    n_t = slots.shape[0]
    for t in prange(n_t):
        scratch = (np.zeros(lattice.n_sub, dtype=np.complex128), np.zeros(lattice.n_sub),
                   (np.zeros(n_rx, dtype=np.complex128), np.zeros(n_rx), np.ones(n_rx), np.zeros(n_rx)))
        for b in range(t * n_p // n_t, (t + 1) * n_p // n_t):
            if status[b] != 0:
                continue
            count = _ping_nodes(b, t, n_ch, echoes, ends.tx[b], cell_m, tables)
            if count < 0:
                status[b] = count
                continue
            _emit_ping_shared(b, n_ch, count, nodes[t], node_key[t], echoes, ends, lattice,
                              waveform.rate_hz * out.shape[2], out[b], scratch)
            status[b] = 1
