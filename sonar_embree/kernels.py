"""Numba kernels: array in, array out, into buffers the caller allocated.

The only module that imports numba. Kernels read no globals, allocate nothing,
draw no random numbers and skip (never wrap) indices outside the buffer. Each has
a naive NumPy twin in ``tests/naive.py``. Compiled code is cached on disk.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def lambert_intensity(range_m, cos_inc, gamma, d_omega, mu, two_way_np_per_m, min_range_m, out):
    """Expected echo intensity of each ray on a Lambertian surface (PHYSICS.md §3).

    w = Γ⁴ · μ · cos θi · exp(−2α'R) · dΩ / R², with R bounded below by ``min_range_m``.

    Parameters
    ----------
    range_m : (n,) float64
        Slant range of the hit, m.
    cos_inc : (n,) float64
        cos θi; rays with cos θi ≤ 0 get 0.
    gamma : (n,) float64
        One-way directivity Γ of the ray's direction.
    d_omega : (n,) float64
        Solid angle of the ray, sr.
    mu : (n,) float64
        Linear Lambert coefficient of the surface hit.
    two_way_np_per_m : float
        Two-way absorption in Np/m (2α·ln10/10 for α in dB/m); 0 for none.
    min_range_m : float
        Lower bound on R (near-field guard).
    out : (n,) float64
        Written with the intensities (unit source: on-axis intensity 1 at 1 m).
    """
    for i in range(range_m.shape[0]):
        c = cos_inc[i]
        r = range_m[i]
        if not (c > 0.0) or not (r < math.inf):
            out[i] = 0.0
            continue
        if r < min_range_m:
            r = min_range_m
        g2 = gamma[i] * gamma[i]
        out[i] = g2 * g2 * mu[i] * c * math.exp(-two_way_np_per_m * range_m[i]) * d_omega[i] / (r * r)


@njit(cache=True, nogil=True)
def splat_linear(channel, delay_samples, weights, out):
    """Add each weight at a fractional sample position with linear interpolation weights.

    ``out[ch, j] += w·(1 − f)`` and ``out[ch, j + 1] += w·f`` with j = ⌊x⌋, f = x − j.
    Works for real or complex ``weights``/``out`` (coherent summation).

    Parameters
    ----------
    channel : (n,) int
        Row of ``out`` for each contribution (0 port, 1 starboard); others are skipped.
    delay_samples : (n,) float64
        Delay in samples from the first sample; NaN, negative or > n_samples − 1
        is skipped (nothing wraps around).
    weights : (n,) float64 or complex128
        Contribution of each ray.
    out : (n_channels, n_samples) float64 or complex128
        Accumulator, added to in place.
    """
    n_ch = out.shape[0]
    n = out.shape[1]
    for i in range(delay_samples.shape[0]):
        x = delay_samples[i]
        ch = channel[i]
        if not (x >= 0.0) or x > n - 1 or ch < 0 or ch >= n_ch:
            continue
        j = int(x)
        f = x - j
        w = weights[i]
        out[ch, j] += w * (1.0 - f)
        if j + 1 < n:
            out[ch, j + 1] += w * f


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
    n = out.shape[1]
    m = table.shape[0]
    span = (m - 1) / table_rate
    for i in range(delay_samples.shape[0]):
        x = delay_samples[i]
        ch = channel[i]
        if ch < 0 or ch >= n_ch or not (abs(x) < math.inf):
            continue
        lo = x + table_start
        first = int(math.ceil(lo))
        last = int(math.floor(lo + span))
        if first < 0:
            first = 0
        if last > n - 1:
            last = n - 1
        a = amplitude[i]
        for k in range(first, last + 1):
            u = (k - lo) * table_rate
            j = int(u)
            if j >= m - 1:
                if j == m - 1:
                    out[ch, k] += a * table[m - 1]
                continue
            f = u - j
            out[ch, k] += a * (table[j] * (1.0 - f) + table[j + 1] * f)


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
    scale = 1.0 / 9007199254740992.0  # 2**-53
    n_sub = gain.shape[1]
    for i in range(ijk.shape[0]):
        h = _node_hash(seed, ijk[i, 0], ijk[i, 1], ijk[i, 2])
        for s in range(n_sub):
            hs = _mix64(h + np.uint64(s) * _GOLDEN)
            u1 = (float(_mix64(hs ^ np.uint64(1)) >> np.uint64(11)) + 1.0) * scale
            u2 = float(_mix64(hs ^ np.uint64(2)) >> np.uint64(11)) * scale
            u3 = float(_mix64(hs ^ np.uint64(3)) >> np.uint64(11)) * scale
            r = math.sqrt(-math.log(u1))
            gain[i, s] = complex(r * math.cos(2.0 * math.pi * u2), r * math.sin(2.0 * math.pi * u2))
            position[i, s] = (s + u3) / n_sub


@njit(cache=True, nogil=True)
def gather_nodes(channel, points, weights, ranges, cell_m, slot_key, slot_epoch, epoch, slot_w, slot_wr,
                 slot_wr2, slot_rmin, slot_rmax, order):
    """Share every ray's echo among the 8 surrounding nodes of a cubic lattice (trilinear).

    Node (ch, i, j, k) sits at (i, j, k)·cell_m in world metres and collects, for
    channel ch, W = Σ w·b and WR = Σ w·b·R over the rays whose hit point p lies in
    one of its 8 cells, b the trilinear weight of p for that node (Σb = 1 per ray, so
    ΣW = Σw), WR2 = Σ w·b·R² and the least and greatest R (for the spread of those
    ranges). Nodes are kept in an open-addressing hash table owned by the caller;
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
    cell_m : float
        Lattice spacing, m.
    slot_key : (cap, 4) int64
        Hash table keys (ch, i, j, k); cap a power of two.
    slot_epoch : (cap,) int64
        Epoch stamp of each slot.
    epoch : int
        Stamp of this call (must differ from every earlier call on the same table).
    slot_w, slot_wr, slot_wr2, slot_rmin, slot_rmax : (cap,) float64
        Hash table values W, WR, WR2, min R and max R.
    order : (cap,) int64
        Written with the slots of the nodes in first-touch order.

    Returns
    -------
    int
        Number of nodes; their slots are ``order[:count]``. −1 when the nodes would
        fill more than half the table: the caller grows it and calls again with a
        new epoch.
    """
    cap = slot_epoch.shape[0]
    max_count = cap // 2
    mask = np.uint64(cap - 1)
    inv = 1.0 / cell_m
    count = 0
    for r in range(points.shape[0]):
        w = weights[r]
        if not (w > 0.0):
            continue
        fx = points[r, 0] * inv
        fy = points[r, 1] * inv
        fz = points[r, 2] * inv
        x0 = math.floor(fx)
        y0 = math.floor(fy)
        z0 = math.floor(fz)
        tx = fx - x0
        ty = fy - y0
        tz = fz - z0
        ch = channel[r]
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
                    wb = w * b
                    slot_w[si] = wb
                    slot_wr[si] = wb * ranges[r]
                    slot_wr2[si] = wb * ranges[r] * ranges[r]
                    slot_rmin[si] = ranges[r]
                    slot_rmax[si] = ranges[r]
                    order[count] = si
                    count += 1
                    break
                if (slot_key[si, 0] == ch and slot_key[si, 1] == ix and slot_key[si, 2] == iy
                        and slot_key[si, 3] == iz):
                    wb = w * b
                    slot_w[si] += wb
                    slot_wr[si] += wb * ranges[r]
                    slot_wr2[si] += wb * ranges[r] * ranges[r]
                    slot_rmin[si] = min(slot_rmin[si], ranges[r])
                    slot_rmax[si] = max(slot_rmax[si], ranges[r])
                    break
                s = (s + np.uint64(1)) & mask
    return count
