"""Slow, obviously correct NumPy twins of every Numba kernel (sonar_embree.kernels)."""
import numpy as np


def lambert_intensity(range_m, cos_inc, gamma, d_omega, mu, two_way_np_per_m, min_range_m):
    """w = Γ⁴ μ cosθ exp(−a R) dΩ / max(R, Rmin)², 0 where cosθ ≤ 0 or R is not finite."""
    r = np.asarray(range_m, dtype=float)
    ok = (np.asarray(cos_inc) > 0) & np.isfinite(r)
    rr = np.where(ok, np.maximum(r, min_range_m), 1.0)
    w = gamma ** 4 * mu * cos_inc * np.exp(-two_way_np_per_m * np.where(ok, r, 0.0)) * d_omega / rr ** 2
    return np.where(ok, w, 0.0)


def splat_linear(channel, delay_samples, weights, out):
    """Linear fractional-delay splatting with np.add.at, out-of-window entries dropped."""
    n_ch, n = out.shape
    x = np.asarray(delay_samples, dtype=float)
    keep = np.isfinite(x) & (x >= 0) & (x <= n - 1) & (channel >= 0) & (channel < n_ch)
    x, ch, w = x[keep], channel[keep], weights[keep]
    j = np.floor(x).astype(int)
    f = x - j
    np.add.at(out, (ch, j), w * (1 - f))
    inside = j + 1 < n
    np.add.at(out, (ch[inside], j[inside] + 1), (w * f)[inside])
    return out


def splat_table(channel, delay_samples, amplitude, table, table_start, table_rate, out):
    """out[ch, n] += a·h(n − x) with h linearly interpolated from the table, for every n it covers."""
    n_ch, n = out.shape
    u_tab = table_start + np.arange(table.size) / table_rate
    for ch, x, a in zip(channel, delay_samples, amplitude):
        if not (0 <= ch < n_ch) or not np.isfinite(x):
            continue
        k = np.arange(n)
        u = k - x
        inside = (u >= u_tab[0]) & (u <= u_tab[-1])
        h = np.interp(u[inside], u_tab, table.real)
        if np.iscomplexobj(table):
            h = h + 1j * np.interp(u[inside], u_tab, table.imag)
        out[ch, k[inside]] += a * h
    return out


_M64 = np.uint64(0xFFFFFFFFFFFFFFFF)


def _mix64(z):
    z = np.asarray(z, dtype=np.uint64)
    with np.errstate(over="ignore"):
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def frozen_scatterers(seed, ijk, n_sub):
    """splitmix64 of (seed, i, j, k, s) → uniforms → Box–Muller and stratified positions, in NumPy uint64."""
    ijk = np.asarray(ijk, dtype=np.int64).astype(np.uint64)
    with np.errstate(over="ignore"):
        h = _mix64(np.uint64(seed) + np.uint64(0x9E3779B97F4A7C15))
        for col in range(3):
            h = _mix64(h ^ ijk[:, col])
        gain = np.empty((ijk.shape[0], n_sub), dtype=complex)
        position = np.empty((ijk.shape[0], n_sub))
        for s in range(n_sub):
            hs = _mix64(h + np.uint64(s) * np.uint64(0x9E3779B97F4A7C15))
            u1 = ((_mix64(hs ^ np.uint64(1)) >> np.uint64(11)).astype(float) + 1.0) * 2.0 ** -53
            u2 = (_mix64(hs ^ np.uint64(2)) >> np.uint64(11)).astype(float) * 2.0 ** -53
            u3 = (_mix64(hs ^ np.uint64(3)) >> np.uint64(11)).astype(float) * 2.0 ** -53
            gain[:, s] = np.sqrt(-np.log(u1)) * np.exp(2j * np.pi * u2)
            position[:, s] = (s + u3) / n_sub
    return gain, position


def gather_nodes(channel, points, weights, ranges, cell_m):
    """Trilinear sharing of each ray's weight among 8 lattice nodes, reduced with np.unique.

    Returns a dict {(ch, i, j, k): (W, WR, WR2, Rmin, Rmax)}.
    """
    f = np.asarray(points) / cell_m
    base = np.floor(f)
    t = f - base
    rows = []
    for c in range(8):
        d = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1])
        b = np.prod(np.where(d == 1, t, 1 - t), axis=1)
        ok = (b > 0) & (weights > 0)
        ijk = base[ok].astype(np.int64) + d
        rows.append((channel[ok], ijk, (weights * b)[ok], ranges[ok]))
    ch = np.concatenate([r[0] for r in rows])
    ijk = np.concatenate([r[1] for r in rows])
    wb = np.concatenate([r[2] for r in rows])
    rr = np.concatenate([r[3] for r in rows])
    keys = np.column_stack([ch, ijk])
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.ravel()
    out = {}
    w = np.bincount(inv, wb)
    wr = np.bincount(inv, wb * rr)
    wr2 = np.bincount(inv, wb * rr * rr)
    rmin = np.full(len(uniq), np.inf)
    rmax = np.full(len(uniq), -np.inf)
    np.minimum.at(rmin, inv, rr)
    np.maximum.at(rmax, inv, rr)
    for n, key in enumerate(map(tuple, uniq)):
        out[key] = (w[n], wr[n], wr2[n], rmin[n], rmax[n])
    return out
