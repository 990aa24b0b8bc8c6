"""Back-end kernels, speckle: the frozen scatterer lattice and its synthesis (docs/physics.md §4)."""
from __future__ import annotations

import math

import numpy as np

from ._numba import njit, prange
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
