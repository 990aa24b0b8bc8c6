"""Slow, obviously correct NumPy twins of every Numba kernel (sonar_embree.kernels)."""
import numpy as np


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
    """splitmix64 of (seed, i, j, k, s, draw) → uniforms → Marsaglia's polar method (pairs of draws 2, 3 / 4, 5 / …
    until one falls inside the unit disc) and stratified positions (draw 1), in NumPy uint64."""
    ijk = np.asarray(ijk, dtype=np.int64).astype(np.uint64)
    with np.errstate(over="ignore"):
        h = _mix64(np.uint64(seed) + np.uint64(0x9E3779B97F4A7C15))
        for col in range(3):
            h = _mix64(h ^ ijk[:, col])
        gain = np.empty((ijk.shape[0], n_sub), dtype=complex)
        position = np.empty((ijk.shape[0], n_sub))
        for s in range(n_sub):
            hs = _mix64(h + np.uint64(s) * np.uint64(0x9E3779B97F4A7C15))

            def u(k, hs=hs):
                return (_mix64(hs ^ np.uint64(k)) >> np.uint64(11)).astype(float) * 2.0 ** -53

            a = np.full(ijk.shape[0], np.nan)
            b = np.full(ijk.shape[0], np.nan)
            todo, k = np.ones(ijk.shape[0], dtype=bool), 2
            while todo.any():
                ak, bk = 2 * u(k) - 1, 2 * u(k + 1) - 1
                take = todo & (ak ** 2 + bk ** 2 < 1) & (ak ** 2 + bk ** 2 > 0)
                a[take], b[take] = ak[take], bk[take]
                todo &= ~take
                k += 2
            q = a ** 2 + b ** 2
            gain[:, s] = (a + 1j * b) * np.sqrt(-np.log(q) / q)
            position[:, s] = (s + u(1)) / n_sub
    return gain, position


def gather_nodes(channel, points, weights, ranges, extents, cell_m, moments=None):
    """Trilinear sharing of each ray's weight among 8 lattice nodes (a fraction within 10⁻³ of 0 or 1 put there),
    reduced with np.unique.

    Each ray's echo is uniform over R ± ΔR/2: second moment R² + ΔR²/12, support [R − ΔR/2, R + ΔR/2]; or, with
    ``moments`` = (variance, least, greatest) (n,) each, spread with that variance over those bounds.

    Returns a dict {(ch, i, j, k): (W, mean R, centred second moment M2, Rmin, Rmax)}.
    """
    var, lo, hi = ((extents ** 2 / 12, ranges - extents / 2, ranges + extents / 2) if moments is None
                   else moments)
    f = np.asarray(points) / cell_m
    base = np.floor(f)
    t = f - base
    t = np.where(t < 1e-3, 0.0, np.where(t > 1 - 1e-3, 1.0, t))   # within 10⁻³ of a lattice plane: on it
    rows = []
    for c in range(8):
        d = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1])
        b = np.prod(np.where(d == 1, t, 1 - t), axis=1)
        ok = (b > 0) & (weights > 0)
        ijk = base[ok].astype(np.int64) + d
        rows.append((channel[ok], ijk, (weights * b)[ok], ranges[ok], var[ok], lo[ok], hi[ok]))
    ch = np.concatenate([r[0] for r in rows])
    ijk = np.concatenate([r[1] for r in rows])
    wb = np.concatenate([r[2] for r in rows])
    rr = np.concatenate([r[3] for r in rows])
    vv, ll, hh = (np.concatenate([r[k] for r in rows]) for k in (4, 5, 6))
    keys = np.column_stack([ch, ijk])
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.ravel()
    out = {}
    w = np.bincount(inv, wb)
    wr = np.bincount(inv, wb * rr)
    mean = wr / w  # two-pass centred second moment
    m2 = np.bincount(inv, wb * ((rr - mean[inv]) ** 2 + vv))
    rmin = np.full(len(uniq), np.inf)
    rmax = np.full(len(uniq), -np.inf)
    np.minimum.at(rmin, inv, ll)
    np.maximum.at(rmax, inv, hh)
    for n, key in enumerate(map(tuple, uniq)):
        out[key] = (w[n], mean[n], m2[n], rmin[n], rmax[n])
    return out


def place_rows(edges, density, counts):
    """Per row: cell bounds at equal steps of the cumulative density (np.interp), rays at their middles."""
    beta, dbeta = [], []
    for dens, n in zip(density, counts):
        cum = np.concatenate(([0.0], np.cumsum(dens * np.diff(edges))))
        bounds = np.interp(np.linspace(0.0, cum[-1], n + 1), cum, edges)
        bounds[0], bounds[-1] = edges[0], edges[-1]
        beta.append(0.5 * (bounds[:-1] + bounds[1:]))
        dbeta.append(np.diff(bounds))
    return np.concatenate(beta), np.concatenate(dbeta)


def elevation_density(beta_rad, range_m, dr_target_m, max_step_rad, slope_cap_m_rad, empty_step_factor,
                      edge_density_factor):
    """The ray budget's density per probe cell, in whole-array NumPy (the library's before issue 37)."""
    beta = np.asarray(beta_rad, dtype=np.float64)
    r = np.asarray(range_m, dtype=np.float64)
    dbeta = np.diff(beta)
    slope = np.abs(np.diff(r, axis=-1)) / dbeta  # NaN where either end missed
    nan_col = np.full(r.shape[:-1] + (1,), np.nan)
    pad = np.concatenate((nan_col, slope, nan_col), axis=-1)
    left, right = pad[..., :-2], pad[..., 2:]
    with np.errstate(invalid="ignore"):
        neigh = np.fmax(left, right)  # NaN only if both are NaN
        jump = np.isfinite(slope) & np.isfinite(neigh) & (slope > 4.0 * neigh)
    slope = np.where(jump, neigh, slope)
    hit = np.isfinite(r)
    partial = ~np.isfinite(slope) & (hit[..., :-1] | hit[..., 1:])
    slope = np.where(partial, neigh, slope)
    live = hit[..., :-1] | hit[..., 1:]
    no = np.zeros(r.shape[:-1] + (1,), dtype=bool)
    live_pad = np.concatenate((no, live, no), axis=-1)
    near = live | live_pad[..., :-2] | live_pad[..., 2:]
    slope = np.where(np.isfinite(slope), np.minimum(slope, slope_cap_m_rad), 0.0)
    floor = np.where(near, 1.0 / max_step_rad, 1.0 / (empty_step_factor * max_step_rad))
    # edges of objects (range jumps, silhouettes against nothing) and their neighbours: a finer step
    edge = jump | partial
    edge_pad = np.concatenate((no, edge, no), axis=-1)
    edge = edge | edge_pad[..., :-2] | edge_pad[..., 2:]
    floor = np.where(edge, np.maximum(floor, edge_density_factor / max_step_rad), floor)
    return np.maximum(floor, slope / dr_target_m)


def fan_directions(s, beta, el_start, rot):
    """World unit directions of a block's rays: body (s, ±cosψ cosβ, cosψ sinβ) rotated, azimuth-major per row."""
    out = []
    for r in range(len(el_start) - 1):
        side = 1.0 if r % 2 else -1.0
        b = beta[el_start[r]:el_start[r + 1]]
        S, B = np.meshgrid(s, b, indexing="ij")
        c = np.sqrt(1 - S ** 2)
        body = np.stack([S, side * c * np.cos(B), c * np.sin(B)], axis=-1).reshape(-1, 3)
        out.append(body @ rot[r // 2].T)
    return np.concatenate(out)


def fan_echoes(s, ds, beta, dbeta, el_start, rot, pos, prim, vertices, faces, mu_face, k, lx, ly, tilt,
               two_way, min_range, max_range, slope_cap, two_sided=None, rx_shift=None):
    """Range, footprint extent and intensity per ray, by plain vector algebra.

    With ``rx_shift`` (pings,) the receiving membrane sees the along-track cosine s − δ of its ping
    (motion during the ping): Γ_tx²·Γ_rx² instead of Γ⁴.

    The extent is the difference of the plane ranges at the two edges of the ray's
    elevation cell (a secant, where the kernel uses the tangent).
    """
    d = fan_directions(s, beta, el_start, rot)
    n = d.shape[0]
    rows = np.repeat(np.arange(len(el_start) - 1), len(s) * np.diff(el_start))
    ping = rows // 2
    bb = np.concatenate([np.tile(beta[el_start[r]:el_start[r + 1]], len(s)) for r in range(len(el_start) - 1)])
    dbb = np.concatenate([np.tile(dbeta[el_start[r]:el_start[r + 1]], len(s)) for r in range(len(el_start) - 1)])
    ss = np.concatenate([np.repeat(s, el_start[r + 1] - el_start[r]) for r in range(len(el_start) - 1)])
    rng, ext, w = np.full(n, np.inf), np.zeros(n), np.zeros(n)
    for i in np.nonzero(prim >= 0)[0]:
        tri = vertices[faces[prim[i]]]
        nrm = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        nrm /= np.linalg.norm(nrm)
        o = pos[ping[i]]
        plane = lambda u: np.dot(tri[0] - o, nrm) / np.dot(u, nrm)  # noqa: E731
        R = plane(d[i])
        cos_i = -np.dot(d[i], nrm)
        if two_sided is not None and two_sided[prim[i]]:
            cos_i = abs(cos_i)  # a two-sided face scatters from its back as from its front
        if cos_i <= 1e-9 or R > max_range:
            continue
        rel = bb[i] - tilt
        cpsi = np.sqrt(1 - ss[i] ** 2)
        if cpsi * np.cos(rel) <= 0:
            continue
        g = np.sinc(k * lx / 2 * ss[i] / np.pi) * np.sinc(k * ly / 2 * cpsi * np.sin(rel) / np.pi)
        d_rx = 0.0 if rx_shift is None else rx_shift[ping[i]]
        g_rx = np.sinc(k * lx / 2 * (ss[i] - d_rx) / np.pi) * np.sinc(k * ly / 2 * cpsi * np.sin(rel) / np.pi)
        rng[i] = R
        w[i] = g ** 2 * g_rx ** 2 * mu_face[prim[i]] * cos_i * np.exp(-two_way * R) * ds * dbb[i] / max(R, min_range) ** 2
        side = 1.0 if rows[i] % 2 else -1.0
        edge = [rot[ping[i]] @ np.array([ss[i], side * cpsi * np.cos(x), cpsi * np.sin(x)])
                for x in (bb[i] - dbb[i] / 2, bb[i] + dbb[i] / 2)]
        ext[i] = min(abs(plane(edge[1]) - plane(edge[0])), slope_cap * dbb[i])
    return rng, ext, w


def splat_rows(ray_start, delay, width, weights, out, sub=4001):
    """Each ray's weight split over `sub` equally spaced points across its interval, each linearly splatted."""
    for r in range(len(ray_start) - 1):
        for i in range(ray_start[r], ray_start[r + 1]):
            if weights[i] == 0 or not np.isfinite(delay[i]):
                continue
            if width[i] < 1e-6:
                x, each = np.array([delay[i]]), weights[i]
            else:  # the part of the interval inside the record, [0, n − 1]
                lo = max(delay[i] - width[i] / 2, 0.0)
                hi = min(delay[i] + width[i] / 2, out.shape[1] - 1.0)
                if hi <= lo:
                    continue
                x = lo + (hi - lo) * (np.arange(sub) + 0.5) / sub
                each = weights[i] / width[i] * (hi - lo) / sub
            splat_linear(np.zeros(x.size, dtype=int), x, np.full(x.size, each), out[r:r + 1])
    return out


def _along_s(axis_row, d):
    """The along-track cosine of offsets d (n, 3) in a row of strips ``axis_row`` (3,) = |a|·x̂."""
    return d @ axis_row / (np.linalg.norm(axis_row) * np.linalg.norm(d, axis=1))


def _pattern(strips, row, s):
    """The row's tabulated along-track pattern at s, linear between samples, 0 outside (np.interp)."""
    axis, gain, _, s0, step, _ = strips
    grid = s0 + step * np.arange(gain.shape[1])
    return np.interp(s, grid, gain[row], left=0.0, right=0.0)


def _element_gains(strips, rows, x, ref, rx, across=None):
    """Γ_rx(s_k)/Γ_rx(s) per node (kernels.speckle._element_gains, ``gain_rx`` an amplitude table): nodes seen at x
    (n, 3) of strips rows ``rows``, s from the reference receiver ref (3,), s_k from each node's receiver rx
    (n, 3); 1 where Γ_rx(s) is 0 or s_k = s; times :func:`_across_gains` with ``across``."""
    out = _along_gains(strips, rows, x, ref, rx)
    return out if across is None else out * _across_gains(across, rows, x, ref, rx)


def _across_gains(across, rows, x, ref, rx):
    """|Γ(v_k)|/|Γ(v)| per node (kernels.speckle._across_ratios): ``across`` = (side (rows, 3), table, v0, step), v
    the cosine of the direction from ``ref`` to the node seen at x with its row's side axis, v_k that from rx; 1
    where |Γ(v)| is 0. The table linear between its samples, 0 outside."""
    side, table, v0, step = across
    grid = v0 + step * np.arange(table.shape[0])

    def at(d):
        v = np.sum(d * side[rows], axis=1) / np.linalg.norm(d, axis=1)
        return np.interp(v, grid, table, left=0.0, right=0.0)

    g = at(x - ref)
    return np.where(g > 0, at(x - rx) / np.where(g > 0, g, 1.0), 1.0)


def _along_gains(strips, rows, x, ref, rx):
    """The along-track part of :func:`_element_gains`."""
    if strips is None:
        return np.ones(x.shape[0])
    axis, _, gain_rx, s0, step, _ = strips
    grid = s0 + step * np.arange(gain_rx.shape[1])
    out = np.ones(x.shape[0])
    for i, r in enumerate(rows):
        s = _along_s(axis[r], (x[i] - ref)[None])[0]
        s_k = _along_s(axis[r], (x[i] - rx[i])[None])[0]
        g = np.interp(s, grid, gain_rx[r], left=0.0, right=0.0)
        if g > 0 and s_k != s:
            out[i] = np.interp(s_k, grid, gain_rx[r], left=0.0, right=0.0) / g
    return out


def strip_points(row, points, weights, ranges, extents, strips, tx, cell_m):
    """The echoes of one row (ping b, channel ch: strips row ``row``) as the lattice takes them: each weight w
    divided by the pattern P(s) at its own along-track cosine (0 where P is), the echoes on the strips taken
    together in runs of one lattice cell (weighted centre about the first point, time mean, variance and bounds,
    two-pass), each run cut
    into m = ⌈R·|a|/cell⌉ points along x̂, R its centre's distance from ``tx``; the others at their points.
    Returns points, weights, ranges and moments (variance, least, greatest), for :func:`gather_nodes`."""
    axis, gain, _, s0, step, on = strips
    a = axis[row]
    p_s = _pattern(strips, row, _along_s(a, points - tx))
    w = np.where(p_s > 0, weights / np.where(p_s > 0, p_s, 1.0), 0.0)
    keep = w > 0
    on = keep if on.shape[0] == 0 else keep & on
    lone = keep & ~on
    out = [(points[lone], w[lone], ranges[lone], extents[lone] ** 2 / 12, ranges[lone] - extents[lone] / 2,
            ranges[lone] + extents[lone] / 2)]
    idx = np.flatnonzero(on)
    cells = np.floor(points[idx] / cell_m)
    starts = np.flatnonzero(np.r_[True, np.any(np.diff(cells, axis=0) != 0, axis=1)]) if idx.size else []
    for g0, g1 in zip(starts, list(starts[1:]) + [idx.size]):
        j = idx[g0:g1]
        ww = w[j]
        W = ww.sum()
        c = points[j[0]] + (ww[:, None] * (points[j] - points[j[0]])).sum(0) / W
        mean = (ww * ranges[j]).sum() / W
        var = (ww * ((ranges[j] - mean) ** 2 + extents[j] ** 2 / 12)).sum() / W
        lo, hi = (ranges[j] - extents[j] / 2).min(), (ranges[j] + extents[j] / 2).max()
        length = np.linalg.norm(c - tx) * np.linalg.norm(a)
        m = max(int(np.ceil(length / cell_m)), 1)
        o = (np.arange(m) - (m - 1) / 2) * (length / m)
        out.append((c + o[:, None] * a / np.linalg.norm(a), np.full(m, W / m), np.full(m, mean), np.full(m, var),
                    np.full(m, lo), np.full(m, hi)))
    return [np.concatenate([x[k] for x in out]) for k in range(6)]


def _row_nodes(b, ray_start, points_world, weights, ranges, extents, cell_m, strips, tx):
    """The lattice nodes of ping b (both channels): plain trilinear sharing, or through :func:`strip_points`."""
    lo, mid, hi = ray_start[2 * b], ray_start[2 * b + 1], ray_start[2 * b + 2]
    if strips is None:
        ch = np.where(np.arange(lo, hi) < mid, 0, 1)
        return gather_nodes(ch, points_world[lo:hi], weights[lo:hi], ranges[lo:hi], extents[lo:hi], cell_m)
    parts = []
    for c, (a, z) in enumerate(((lo, mid), (mid, hi))):
        on = strips[5][a:z] if strips[5].shape[0] else strips[5]
        p, w, r, v, l, h = strip_points(2 * b + c, points_world[a:z], weights[a:z], ranges[a:z], extents[a:z],
                                        strips[:5] + (on,), tx, cell_m)
        parts.append((np.full(w.size, c), p, w, r, v, l, h))
    ch, p, w, r, v, l, h = (np.concatenate([x[k] for x in parts]) for k in range(7))
    return gather_nodes(ch, p, w, r, np.zeros_like(r), cell_m, moments=(v, l, h))


def speckle_block(ray_start, points_world, weights, ranges, extents, pos_world, seed, cell_m, wavelength_m,
                  delay_per_m, phase_cycles_per_m, n_sub, table, table_start, table_rate, out, pos_rx=None,
                  vel_rx=None, receivers=None, time_per_m=0.0, strips=None, across=None):
    """Per ping: naive gather → naive frozen scatterers → envelope ranges and amplitudes → naive splat_table
    (the receiver at rx + v·R̄ when each node's echo arrives, R̄ in the units the ranges are given in).
    ``receivers`` (pings, 2·n_rx, 3): n_rx receivers per channel, receiver k of channel ch writing row ch·n_rx + k,
    each delayed by (|X − rx_k − v·R̄| − |X − rx|)·time_per_m (with one receiver, rx_k = rx: its motion alone).
    ``strips`` (axis, gain, gain_rx, s0, step, on_strip): the
    echoes taken through :func:`strip_points`, every node's weight times the pattern at its own along-track cosine,
    and with receivers (time_per_m ≠ 0) each receiver's amplitude times :func:`_element_gains` (with ``across``,
    (side, table, v0, step), the across-track ratios too)."""
    n_rx = out.shape[1] // 2
    for b in range(pos_world.shape[0]):
        nodes = _row_nodes(b, ray_start, points_world, weights, ranges, extents, cell_m, strips, pos_world[b])
        if not nodes:
            continue
        keys = np.array(list(nodes.keys()))
        vals = np.array(list(nodes.values()))
        w, r_mean, m2, rmin, rmax = vals.T
        sigma = np.sqrt(m2 / w)
        if strips is not None:
            w = w * np.array([_pattern(strips, 2 * b + k[0], _along_s(strips[0][2 * b + k[0]],
                                                                     (k[1:] * cell_m - pos_world[b])[None])[0])
                              for k in keys])
        g, v = frozen_scatterers(seed, keys[:, 1:], n_sub)
        move = 0.0 if vel_rx is None else vel_rx[b] * r_mean[:, None]
        ref = (pos_world[b] if pos_rx is None else pos_rx[b]) + move             # (nodes, 3)
        x = keys[:, 1:] * cell_m
        d_ref = np.linalg.norm(x - (pos_world[b] if pos_rx is None else pos_rx[b]), axis=1)   # the still leg
        for k in range(n_rx):
            rx = ref if receivers is None else receivers[b, keys[:, 0] * n_rx + k] + move
            d_rx = np.linalg.norm(x - rx, axis=1)
            l_node = np.linalg.norm(x - pos_world[b], axis=1) + d_rx             # 2R for the direct path
            base = np.sqrt(w / n_sub) * np.exp(-2j * np.pi * ((l_node / wavelength_m) % 1))
            if time_per_m != 0.0 and receivers is not None:
                base = base * _element_gains(strips, 2 * b + keys[:, 0], x - move, pos_world[b] if pos_rx is None
                                             else pos_rx[b], receivers[b, keys[:, 0] * n_rx + k], across)
            r_env = np.clip(r_mean[:, None] + np.sqrt(3) * sigma[:, None] * (2 * v - 1), rmin[:, None],
                            rmax[:, None]) + ((d_rx - d_ref) * time_per_m)[:, None]
            amp = base[:, None] * g * np.exp(2j * np.pi * ((phase_cycles_per_m * r_env) % 1))
            splat_table(np.repeat(keys[:, 0] * n_rx + k, n_sub), r_env.ravel() * delay_per_m, amp.ravel(), table,
                        table_start, table_rate, out[b])
    return out


def speckle_block_shared(ray_start, points_world, weights, ranges, extents, pos_world, seed, cell_m, wavelength_m,
                         rate, n_sub, out, receivers, vel_rx, time_per_m, strips=None, across=None):
    """Per ping: the nodes of :func:`speckle_block`, each scatterer per receiver an impulse at
    (t + (|X − rx_k − v·R̄| − |X − tx|)·time_per_m)·rate·S on the grid of 1/S sample (S = out.shape[2]), split
    linearly between its two nearest grid times, grid time i written to out[b, row, i mod S, i // S]; the receivers move at
    ``vel_rx`` (the reference receiver is the transmitter)."""
    steps, n_rx = out.shape[2], out.shape[1] // 2
    for b in range(pos_world.shape[0]):
        nodes = _row_nodes(b, ray_start, points_world, weights, ranges, extents, cell_m, strips, pos_world[b])
        if not nodes:
            continue
        keys = np.array(list(nodes.keys()))
        w, r_mean, m2, rmin, rmax = np.array(list(nodes.values())).T
        sigma = np.sqrt(m2 / w)                                          # the beam scales W and M2 alike
        if strips is not None:
            w = w * np.array([_pattern(strips, 2 * b + k[0], _along_s(strips[0][2 * b + k[0]],
                                                                     (k[1:] * cell_m - pos_world[b])[None])[0])
                              for k in keys])
        g, v = frozen_scatterers(seed, keys[:, 1:], n_sub)
        x = keys[:, 1:] * cell_m - vel_rx[b] * r_mean[:, None]          # the node seen from the moved receivers
        d_tx = np.linalg.norm(keys[:, 1:] * cell_m - pos_world[b], axis=1)
        d_ref = d_tx                                                     # the still leg the times were made for
        r_env = np.clip(r_mean[:, None] + np.sqrt(3) * sigma[:, None] * (2 * v - 1), rmin[:, None], rmax[:, None])
        for k in range(n_rx):
            rows = keys[:, 0] * n_rx + k
            d_rx = np.linalg.norm(x - receivers[b, rows], axis=1)
            gain = _element_gains(strips, 2 * b + keys[:, 0], x, pos_world[b], receivers[b, rows], across)
            amp = (gain * np.sqrt(w / n_sub) * np.exp(-2j * np.pi * (((d_tx + d_rx) / wavelength_m) % 1)))[:, None] * g
            grid = (r_env + ((d_rx - d_ref) * time_per_m)[:, None]) * rate * steps
            lo = np.floor(grid)
            for i, a in ((lo, amp * (1 - (grid - lo))), (lo + 1, amp * (grid - lo))):
                i = i.astype(np.int64)
                row = np.repeat(rows, n_sub)
                ok = (i.ravel() // steps >= 0) & (i.ravel() // steps < out.shape[3])
                np.add.at(out[b], (row[ok], (i.ravel() % steps)[ok], (i.ravel() // steps)[ok]), a.ravel()[ok])
    return out


def label_rows(el_start, dr, lit_range, lit_extent, lit_score, lit_object, lit_point, lit_dir, hid_range, hid_extent,
               hid_object, hid_point, hid_dir, pos, outward, is_seafloor, origin_z, n_s):
    """Per sample: the best-scoring lit footprint whose range cell overlaps it, else the first hidden one."""
    rows = el_start.shape[0] - 1
    kind = np.zeros((rows, n_s), np.int8)
    obj = np.full((rows, n_s), -1, np.int32)
    shadow_of = np.full((rows, n_s), -1, np.int32)
    height = np.full((rows, n_s), np.nan, np.float32)
    ground = np.full((rows, n_s), np.nan, np.float32)
    cells_lo, cells_hi = (np.arange(n_s) - 0.5) * dr, (np.arange(n_s) + 0.5) * dr

    def point(p, d, o, r_target, ext, r):
        q = p - o
        b, c = d @ q, q @ q - r_target ** 2
        roots = np.array([-b + np.sqrt(max(b * b - c, 0.0)), -b - np.sqrt(max(b * b - c, 0.0))])
        t = roots[np.argmin(np.abs(roots))]
        half = (0.5 * ext + dr) / max(abs(b) / r, 1e-6)
        return p + np.clip(t, -half, half) * d

    for r in range(rows):
        o = pos[r]
        js = range(el_start[r], el_start[r + 1])
        for n in range(n_s):
            def overlaps(rr, ext):
                return cells_hi[n] > rr - 0.5 * ext and cells_lo[n] < rr + 0.5 * ext
            lit = [j for j in js if lit_score[j] > 0 and overlaps(lit_range[j], lit_extent[j])]
            if lit:
                j = lit[int(np.argmax([lit_score[j] for j in lit]))]
                kind[r, n] = 1 if is_seafloor[lit_object[j]] else 2
                obj[r, n] = lit_object[j]
                p = point(lit_point[j], lit_dir[j], o, n * dr, lit_extent[j], lit_range[j])
            else:
                hid = [j for j in js if np.isfinite(hid_range[j]) and overlaps(hid_range[j], hid_extent[j])]
                if not hid:
                    continue
                j = hid[0]
                kind[r, n] = 3
                shadow_of[r, n] = hid_object[j]
                p = point(hid_point[j], hid_dir[j], o, n * dr, hid_extent[j], hid_range[j])
            height[r, n] = p[2] + origin_z
            ground[r, n] = np.hypot(p[0] - o[0], p[1] - o[1]) * (-1.0 if (p[:2] - o[:2]) @ outward[r] < 0 else 1.0)
    return kind, obj, shadow_of, height, ground


def law_weights(prim, cos_i, face_object, object_law, law, params, weight, kind, data=None):
    """Twin of the laws' kernels: σ(θi)/cos θi on the hits of objects of law index ``law``, as a factor.

    ``kind`` "lambert": σ = μ cos²θ (params[:, 0] = μ); "kirchhoff": σ = R0²/(8π s²)·sec⁴θ·exp(−tan²θ/(2s²))
    (params[:, 0] = R0², params[:, 1] = s²); "tabulated": 10^(dB(θg)/10) with dB interpolated in the
    table at ``data[off:off + 2n]`` (params[:, 0] = off, params[:, 1] = n). Returns the factor (1 elsewhere).
    """
    out = np.ones_like(weight)
    for i in range(prim.shape[0]):
        if prim[i] < 0 or weight[i] == 0:
            continue
        o = face_object[prim[i]]
        if object_law[o] != law:
            continue
        theta = np.arccos(cos_i[i])
        if kind == "lambert":
            sigma = params[o, 0] * np.cos(theta) ** 2
        elif kind == "kirchhoff":
            s2 = params[o, 1]
            sigma = params[o, 0] / (8 * np.pi * s2) / np.cos(theta) ** 4 * np.exp(-np.tan(theta) ** 2 / (2 * s2))
        else:
            off, n = int(params[o, 0]), int(params[o, 1])
            sigma = 10 ** (np.interp(np.pi / 2 - theta, data[off:off + n], data[off + n:off + 2 * n]) / 10)
        out[i] = sigma / np.cos(theta)
    return out


def mixed_legs(x, r, ping, side, dbeta, prim, rot, pos, rx_shift, z_s, face_normals, beam, ds, min_range_m,
               two_way_np_per_m, slope_cap_m_rad, c, wave_kh):
    """The one-bounce legs of every direct echo in NumPy (twin of kernels.mixed_legs): a dict of its outputs."""
    def gain(u, shift=0.0):
        e = np.einsum("nji,nj->ni", rot[ping], u)
        ct, st = np.cos(beam[2]), np.sin(beam[2])
        height, bore = e[:, 2] * ct - side * e[:, 1] * st, side * e[:, 1] * ct + e[:, 2] * st
        along = np.sinc(beam[0] * (e[:, 0] - shift) / np.pi)
        return np.where(bore > 0, along * np.sinc(beam[1] * height / np.pi), 0.0)

    s = pos[ping]
    u1 = (x - s) / r[:, None]
    img = s * [1.0, 1.0, -1.0] + [0.0, 0.0, 2.0 * z_s]
    r2 = np.linalg.norm(img - x, axis=1)
    v = (img - x) / r2[:, None]
    leg1 = r2 * (z_s - x[:, 2]) / (img[:, 2] - x[:, 2])
    to_p = x + leg1[:, None] * v - s
    leg2 = np.linalg.norm(to_p, axis=1)
    u2 = to_p / leg2[:, None]
    n = face_normals[prim] * -np.sign(np.sum(face_normals[prim] * u1, axis=1))[:, None]
    cos_i, cos_s = -np.sum(n * u1, axis=1), np.sum(n * v, axis=1)
    d = rx_shift[ping]                                                    # S→X→S' receives along u2, S'→X→S along u1
    w = ((gain(u1) ** 2 * gain(u2, d) ** 2 + gain(u2) ** 2 * gain(u1, d) ** 2) * np.exp(-0.5 * two_way_np_per_m * (r + r2)) * ds * dbeta
         / (np.maximum(r2, min_range_m) ** 2 * cos_i) * np.exp(-4 * wave_kh ** 2 * v[:, 2] ** 2))
    e = np.einsum("nji,nj->ni", rot[ping], u1)
    f = np.einsum("nij,nj->ni", rot[ping], np.stack([0 * r, -side * e[:, 2], side * e[:, 1]], axis=1))
    dx = r[:, None] * (f - u1 * (np.sum(n * f, axis=1) / np.sum(n * u1, axis=1))[:, None])
    slope = np.minimum(np.abs(np.sum((u1 - v) * dx, axis=1)), 2 * slope_cap_m_rad)
    b = -u1 - cos_i[:, None] * n                                          # −u1 − ((−u1)·n)·n
    t = v - cos_s[:, None] * n
    nb, nt = np.linalg.norm(b, axis=1), np.linalg.norm(t, axis=1)
    ok = (nb > 1e-12) & (nt > 1e-12)
    phi = np.where(ok, np.arccos(np.clip(np.sum(b * t, axis=1) / np.where(ok, nb * nt, 1), -1, 1)), 0.0)
    return dict(time=(r + r2) / c, extent=slope * dbeta / c, weight=w, cos_i=cos_i, cos_s=cos_s, phi=phi, v=v,
                leg1=leg1, u2=u2, leg2=leg2)


def two_bounce(ray_start, x, pos_image, z_s, wave_kh, weight):
    """Image-fan weights × |R_s|⁴ and the real upward legs in NumPy (twin of kernels.two_bounce)."""
    ping = np.repeat(np.arange(len(ray_start) - 1), np.diff(ray_start)) // 2
    d = x - pos_image[ping]
    d /= np.linalg.norm(d, axis=1)[:, None]
    lit = weight > 0
    sin_g = np.abs(d[:, 2])
    w = np.where(lit, weight * np.exp(-4 * wave_kh ** 2 * sin_g ** 2) ** 2, weight)
    return w, d * [1.0, 1.0, -1.0], np.where(lit, (pos_image[ping, 2] - z_s) / sin_g, 0.0)


def merge_lit(parts):
    """Lit echoes of parts [(ray_start, time, extent, weight, point, id)] row by row, part by part, in NumPy by a
    stable sort on the row (twin of kernels.count_lit + kernels.merge_lit): (start, time, extent, weight, point,
    id, path)."""
    rows = np.concatenate([np.repeat(np.arange(len(p[0]) - 1), np.diff(p[0])) for p in parts])
    path = np.concatenate([np.full(len(p[3]), k) for k, p in enumerate(parts)])
    cols = [np.concatenate([p[c] for p in parts]) for c in range(1, 6)]
    keep = cols[2] > 0
    order = np.argsort(rows[keep], kind="stable")
    start = np.concatenate(([0], np.cumsum(np.bincount(rows[keep], minlength=len(parts[0][0]) - 1))))
    return (start, *[c[keep][order] for c in cols], path[keep][order])


def visibility_legs(ray_start, x, pos, from_sonar, dirs, dist, weight, box_lo, box_hi, box_obj, box_slope, free_own,
                    prim, face_object, face_normals, eps):
    """The legs to cast for visibility in NumPy (twin of kernels.visibility_legs): (index, origin, dir, length).
    Each box by the slab method over the leg's [eps, dist − eps], all legs at once; a leg is cast from its first
    box entry to its last box exit."""
    ping = np.repeat(np.arange(len(ray_start) - 1), np.diff(ray_start)) // 2
    o = pos[ping] if from_sonar else x
    own, above = np.full(len(dist), -1), np.zeros(len(dist), dtype=bool)
    if len(prim):
        own = face_object[prim]
        above = free_own & (np.sum(face_normals[prim] * (x - pos[ping]), axis=1) < 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        rise = np.full(len(dist), -np.inf) if from_sonar else dirs[:, 2] / np.hypot(dirs[:, 0], dirs[:, 1])
    start, end = np.full(len(dist), np.inf), np.full(len(dist), -np.inf)
    for lo, hi, obj, slope in zip(box_lo, box_hi, box_obj, box_slope):
        t0, t1 = np.full(len(dist), eps), dist - eps
        inside = np.ones(len(dist), dtype=bool)
        with np.errstate(divide="ignore", invalid="ignore"):
            for q in range(3):
                flat = dirs[:, q] == 0
                inside &= ~flat | ((o[:, q] >= lo[q]) & (o[:, q] <= hi[q]))
                ta, tb = (lo[q] - o[:, q]) / dirs[:, q], (hi[q] - o[:, q]) / dirs[:, q]
                t0 = np.where(flat, t0, np.maximum(t0, np.minimum(ta, tb)))
                t1 = np.where(flat, t1, np.minimum(t1, np.maximum(ta, tb)))
        hit = inside & (t0 <= t1) & ((obj < 0) | (obj != own) | ~(above | (rise > slope)))
        start, end = np.where(hit, np.minimum(start, t0), start), np.where(hit, np.maximum(end, t1), end)
    end = np.minimum(dist - eps, end + eps)
    with np.errstate(invalid="ignore"):
        i = np.flatnonzero((weight > 0) & (end - start > 0))
    return (i, (o[i] + start[i, None] * dirs[i]).astype(np.float32), dirs[i].astype(np.float32),
            (end - start)[i].astype(np.float32))


def swell_launch(ping, dirs, t1, prim_s, pos, surface_normals, eps):
    """The upward rays mirrored on the swell's facets in NumPy (twin of kernels.swell_launch): (u, P, u_r, float32
    origin and direction of the bounced ray); ``ping`` (m,) of each entry, the other arrays already gathered."""
    u = dirs.astype(np.float64)
    n = surface_normals[prim_s]
    ur = u - 2 * np.sum(u * n, axis=1)[:, None] * n
    p = pos[ping] + t1.astype(np.float64)[:, None] * u
    return u, p, ur, (p + eps * ur).astype(np.float32), ur.astype(np.float32)


def swell_paths(s_az, beta, dbeta, u, p, ur, t1, n_p, prim, t2, seen, face_normals, rot, pos, ping, side, shift,
                beam, ds, min_range_m, two_way_np_per_m, slope_cap_m_rad, c, wave_kh, max_range_m, eps):
    """The swell's one- and two-bounce paths in NumPy (twin of kernels.swell_paths), every array gathered per entry
    (s_az, beta, dbeta of its fan direction, n_p its facet's normal, ping, side and δ of its ping): a dict of the
    outputs, NaN-free only where they are written (w1, w2 and times everywhere)."""
    def gain(v, d=0.0):
        e = np.einsum("nji,nj->ni", rot[ping], v)
        ct, st = np.cos(beam[2]), np.sin(beam[2])
        height, bore = e[:, 2] * ct - side * e[:, 1] * st, side * e[:, 1] * ct + e[:, 2] * st
        return np.where(bore > 0, np.sinc(beam[0] * (e[:, 0] - d) / np.pi) * np.sinc(beam[1] * height / np.pi), 0.0)

    big_r = t1.astype(np.float64) + eps + t2.astype(np.float64)
    x = p + (eps + t2.astype(np.float64))[:, None] * ur
    n_x = face_normals[np.maximum(prim, 0)]
    cos_i = -np.sum(n_x * ur, axis=1)
    reach = (prim >= 0) & (seen > 0) & (big_r <= max_range_m)
    ok = reach & (cos_i > 1e-9)
    rs2 = np.exp(-4 * wave_kh ** 2 * np.sum(u * n_p, axis=1) ** 2)
    cpsi = np.sqrt(1 - s_az ** 2)                                   # ∂u/∂β in the body, then the world, mirrored
    f = np.einsum("nij,nj->ni", rot[ping], np.stack([0 * cpsi, -side * cpsi * np.sin(beta), cpsi * np.cos(beta)], 1))
    f_r = f - 2 * np.sum(f * n_p, axis=1)[:, None] * n_p
    dx = big_r[:, None] * (f_r + ur * (np.sum(n_x * f_r, axis=1) / np.maximum(cos_i, 1e-12))[:, None])
    g, g_rx = gain(u), gain(u, shift)
    w2 = g ** 2 * g_rx ** 2 * np.exp(-two_way_np_per_m * big_r) * rs2 ** 2 * ds * dbeta / np.maximum(big_r, min_range_m) ** 2
    d = x - pos[ping]
    r = np.linalg.norm(d, axis=1)
    ud = d / r[:, None]
    cos_s = -np.sum(n_x * ud, axis=1)
    w1 = ((g ** 2 * gain(ud, shift) ** 2 + gain(ud) ** 2 * g_rx ** 2) * rs2 * np.exp(-0.5 * two_way_np_per_m * (big_r + r))
          * ds * dbeta / (np.maximum(r, min_range_m) ** 2 * cos_i))
    bb, tt = -ur - cos_i[:, None] * n_x, -ud - cos_s[:, None] * n_x
    nb, nt = np.linalg.norm(bb, axis=1), np.linalg.norm(tt, axis=1)
    phi = np.arccos(np.clip(np.sum(bb * tt, axis=1) / (nb * nt), -1, 1))
    s1 = np.minimum(np.abs(np.sum((ur + ud) * dx, axis=1)), 2 * slope_cap_m_rad)
    s2 = np.minimum(np.abs(np.sum(ur * dx, axis=1)), slope_cap_m_rad)
    lit1 = ok & (cos_s > 1e-9)
    return dict(ok=ok, lit1=lit1, x=np.where(reach[:, None], x, p), w1=np.where(lit1, w1, 0.0), w2=np.where(ok, w2, 0.0),
                time1=np.where(ok, (big_r + r) / c, np.inf), time2=np.where(ok, 2 * big_r / c, np.inf),
                ext1=np.where(ok, s1 * dbeta / c, 0.0), ext2=np.where(ok, 2 * s2 * dbeta / c, 0.0),
                cos_i=np.where(ok, cos_i, 1.0), cos_s=cos_s, phi=phi, leg=-ud, r=r)


def arc_start(s, beta, el_start, rot, pos, layers, z0):
    """Launch of every ray in a profile (twin of kernels.arc_start): horizontal direction, ξ, θ0, c0 per ray."""
    u = fan_directions(s, beta, el_start, rot)
    rows = np.repeat(np.arange(len(el_start) - 1), len(s) * np.diff(el_start))
    depth = z0 - pos[rows // 2, 2]
    c0 = np.interp(depth, layers[1:, 0], layers[1:, 1])        # the profile's knots, held beyond
    hz = np.hypot(u[:, 0], u[:, 1])
    return dict(h=u[:, :2] / hz[:, None], xi=hz / c0, theta=np.arcsin(-u[:, 2]), c0=c0, depth=depth)


def _profile_speed(layers, depth):
    return np.interp(depth, layers[1:, 0], layers[1:, 1])


def arc_trace(theta0, depth0, xi, layers, planes, z0, s_max=300.0, n=30001):
    """A ray from depth0 at grazing θ0 (azimuth along +x) to the first of ``planes``, layer by layer.

    In each layer the arc is θ(s) = θa − κs, x(s) = xa + (sin θa − sin θ(s))/κ, depth(s) = da + (cos θ(s) −
    cos θa)/κ (a straight line for κ = 0), in plain trigonometry; the first root of n̂·(X(s) − p) over the
    planes (x, depth → local (x, 0, z0 − depth)) or of the layer's edges is found by a sign change on a 1 cm
    grid and brentq, the time by quad of ds/c(depth(s)). ``planes``: ((a, b, e), …), each the line
    a·x + b·z + e = 0 where a plane cuts the ray's vertical plane (x along the azimuth from the sonar, z up,
    z = z0 − depth). Returns (plane index, x, depth, L, T, θ) at the hit, or None.
    """
    from scipy.integrate import quad
    from scipy.optimize import brentq
    th, d, x, L, T = float(theta0), float(depth0), 0.0, 0.0, 0.0
    knots = layers[1:, 0]
    for _ in range(40):
        k = int(np.searchsorted(knots, d, side="right"))          # layer k: knots[k−1] ≤ d < knots[k]
        kap = xi * layers[k, 2]

        def pos(s, th=th, d=d, x=x, kap=kap):
            if kap == 0:
                return x + s * np.cos(th), d + s * np.sin(th)
            return x + (np.sin(th) - np.sin(th - kap * s)) / kap, d + (np.cos(th - kap * s) - np.cos(th)) / kap

        lo = knots[k - 1] if k > 0 else -np.inf
        hi = knots[k] if k < len(knots) else np.inf
        grid = np.linspace(1e-9, s_max - L, n)  # off the knot it starts on
        gx, gd = pos(grid)
        funcs = [lambda q, a=a, b=b, e=e: a * pos(q)[0] + b * (z0 - pos(q)[1]) + e for a, b, e in planes]
        funcs += [lambda q: pos(q)[1] - hi, lambda q: pos(q)[1] - lo]
        vals = [a * gx + b * (z0 - gd) + e for a, b, e in planes] + [gd - hi, gd - lo]
        first, which = np.inf, None
        for w, v in enumerate(vals):
            j = np.flatnonzero(np.sign(v[1:]) != np.sign(v[:-1]))
            if j.size and np.isfinite(v).all() and grid[j[0] + 1] < first:
                first, which = grid[j[0] + 1], (w, j[0])
        if which is None:
            return None
        w, j = which
        s = brentq(funcs[w], grid[j], grid[j + 1], xtol=1e-13)
        T += quad(lambda q: 1.0 / _profile_speed(layers, pos(q)[1]), 0.0, s, epsabs=0, epsrel=1e-12)[0]
        x, d = pos(s)
        L += s
        th -= kap * s
        if w < len(planes):
            return w, x, d, L, T, th
        d = hi if w == len(planes) else lo  # on the knot exactly: the next layer starts there
    return None


def arc_echoes(s, ds, beta, dbeta, el_start, rot, hit_prim, point, direction, T, L, area, shift_per_rad, c_hit,
               face_normals, k, lx, ly, tilt, two_way, min_range, t_max, slope_cap, c_nom, rx_shift=None):
    """Weights, times and extents of curved-ray hits by vector algebra (twin of kernels.arc_echoes).

    ``area`` (A_Ω) and ``shift_per_rad`` (|n̂·δ⊥| per dβ) are given per ray: the twin checks the beam, the
    baffle, the law-free weight, the travel time and the footprint built from them.
    """
    rows = np.repeat(np.arange(len(el_start) - 1), len(s) * np.diff(el_start))
    bb = np.concatenate([np.tile(beta[el_start[r]:el_start[r + 1]], len(s)) for r in range(len(el_start) - 1)])
    dbb = np.concatenate([np.tile(dbeta[el_start[r]:el_start[r + 1]], len(s)) for r in range(len(el_start) - 1)])
    ss = np.concatenate([np.repeat(s, el_start[r + 1] - el_start[r]) for r in range(len(el_start) - 1)])
    n = rows.shape[0]
    w, t, ext = np.zeros(n), np.full(n, np.inf), np.zeros(n)
    hit = hit_prim >= 0
    nrm = face_normals[np.maximum(hit_prim, 0)]
    cos_i = -np.sum(direction * nrm, axis=1)
    cpsi = np.sqrt(1 - ss ** 2)
    rel = bb - tilt
    g_el = np.sinc(k * ly / 2 * cpsi * np.sin(rel) / np.pi)
    g = np.sinc(k * lx / 2 * ss / np.pi) * g_el
    d = 0.0 if rx_shift is None else rx_shift[rows // 2]                 # the receive beam moved on (rows 2·ping + side)
    g_rx = np.sinc(k * lx / 2 * (ss - d) / np.pi) * g_el
    ok = hit & (cos_i > 1e-9) & (T <= t_max) & (cpsi * np.cos(rel) > 0)
    w[ok] = (g[ok] ** 2 * g_rx[ok] ** 2 * np.exp(-two_way * L[ok]) * ds * dbb[ok] / np.maximum(area[ok], min_range ** 2))
    t[ok] = 2 * T[ok]
    ext[ok] = 2 * np.minimum(shift_per_rad[ok] / cos_i[ok], slope_cap) * dbb[ok] / c_hit[ok]
    return w, t, ext, c_nom * T


def first_hits(org, dirs, vertices, faces, t_max):
    """First hit of each ray on a triangle mesh by brute force (Möller–Trumbore against every triangle; twin of
    kernels.swell_surface_hits): (triangle (n,), −1 for none; distance (n,), inf for none)."""
    v0, v1, v2 = (vertices[faces[:, q]] for q in range(3))
    e1, e2 = v1 - v0, v2 - v0
    prim, dist = np.full(len(org), -1), np.full(len(org), np.inf)
    for i, (o, d) in enumerate(zip(org, dirs)):
        p = np.cross(d, e2)
        det = np.sum(e1 * p, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = o - v0
            u = np.sum(s * p, axis=1) / det
            q = np.cross(s, e1)
            v = np.sum(q * d, axis=1) / det
            t = np.sum(q * e2, axis=1) / det
        ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= t_max)
        if ok.any():
            j = np.flatnonzero(ok)[np.argmin(t[ok])]
            prim[i], dist[i] = j, t[j]
    return prim, dist


def aim_lattices(centre, radius, rot, pos, sides, span, rx_shift, n_across, dr_m, max_rays, slender=None):
    """(2·pings, k, 6) lattices [s0, hs, β0, hβ, ns, nβ] of every object in every row, by plain vector algebra: the
    object's bounding cone (half-angle γ = asin(ρ/D) about its centre's body direction) spans s_c ± γ and
    β_c ± asin(sin γ / √(1 − s_c²)), clipped to the row's span (s widened by δ on its side); cells of at most
    2γ/n_across, the fan's steps and (in β) 2γ·dr/(2ρ); none beyond the range, inside the sphere, on the
    along-track axis or above ``max_rays``. With curved rays (span[7] = κ > 0) the cone widens by 0.6·κ·(D + ρ)
    along the elevation direction. ``slender`` = (cell_m, cover, cover_start, max_cells): where cell_m/(D + ρ) is
    finer than either step, both steps are at most that, then :func:`slender_trim` (up to max_cells of them)."""
    n_p, k = rot.shape[0], centre.shape[0]
    out = np.zeros((2 * n_p, k, 6))
    for r in range(2 * n_p):
        b, side = r // 2, (1.0 if r % 2 else -1.0)
        if not sides[r % 2]:
            continue
        v = (centre - pos[b]) @ rot[b]                      # body-frame offsets (Rᵀ·w per row vector)
        for j in range(k):
            d = np.linalg.norm(v[j])
            if d <= radius[j] * (1 + 1e-9) or d - radius[j] > span[4]:
                continue
            gam = np.arcsin(radius[j] / d)
            sc = v[j, 0] / d
            if np.sin(gam) >= 0.999 * np.sqrt(1 - sc ** 2):
                continue
            half_b, half_s = np.arcsin(np.sin(gam) / np.sqrt(1 - sc ** 2)), gam
            bend = 0.6 * span[7] * (d + radius[j])          # curved rays: |launch − chord| ≤ κ·L/2 (+ 20 %)
            if bend > 0:
                u, up = v[j] / d, rot[b][2]                   # the world's vertical in the body frame
                e_theta = up - (up @ u) * u                   # the elevation direction at u
                half_s += min(abs(e_theta[0]) / np.linalg.norm(e_theta), 1.0) * bend + bend ** 2
                half_b += bend / np.sqrt(1 - sc ** 2) + bend ** 2
            bc = np.arctan2(v[j, 2], side * v[j, 1])
            s_lo = max(sc - half_s, span[0] + min(rx_shift[b], 0))
            s_hi = min(sc + half_s, span[1] + max(rx_shift[b], 0))
            b_lo, b_hi = max(bc - half_b, span[2]), min(bc + half_b, span[3])
            if s_hi <= s_lo or b_hi <= b_lo:
                continue
            hs = min(2 * gam / n_across, span[5])
            hb = min(2 * gam / n_across, span[6], 2 * gam * dr_m / (2 * radius[j]))
            thin = slender is not None and slender[0][j] / (d + radius[j]) < max(hs, hb)
            if thin:
                hs, hb = min(hs, slender[0][j] / (d + radius[j])), min(hb, slender[0][j] / (d + radius[j]))
            ns, nb = np.ceil((s_hi - s_lo) / hs - 1e-9), np.ceil((b_hi - b_lo) / hb - 1e-9)
            if not thin and ns * nb > max_rays:
                continue
            out[r, j] = [s_lo, (s_hi - s_lo) / ns, b_lo, (b_hi - b_lo) / nb, ns, nb]
            if thin:
                cell_m, cover, start, max_cells = slender
                out[r, j] = slender_trim(out[r, j], cover[start[j]:start[j + 1]], cell_m[j], rot[b], pos[b], side,
                                         max_cells)
    return out


def aim_directions(table, rot, cells=None):
    """World directions of every lattice's rays (rows, then objects; s-major, β fastest), cell centres; with
    ``cells`` (:func:`cover_cells`) a slender lattice's marked cells only."""
    out = []
    for r in range(table.shape[0]):
        for k, row in enumerate(table[r]):
            ns, nb = int(row[4]), int(row[5])
            if ns == 0:
                continue
            s = row[0] + (np.arange(ns) + 0.5) * row[1]
            beta = row[2] + (np.arange(nb) + 0.5) * row[3]
            el = [0, nb, nb] if r % 2 == 0 else [0, 0, nb]
            d = fan_directions(s, beta, np.array(el), rot[r // 2:r // 2 + 1])
            keep = None if cells is None else cells[r][k]
            out.append(d if keep is None else d[keep.ravel()])
    return np.concatenate(out) if out else np.zeros((0, 3))


def _project(pts, rot, pos, side):
    """(s, β) of the directions from the sonar (``rot``, ``pos``) to the local points ``pts`` (n, 3), on ``side``."""
    v = (pts - pos) @ rot
    return v[:, 0] / np.linalg.norm(v, axis=1), np.arctan2(v[:, 2], side * v[:, 1])


def _reach(row, pts, rot, pos, side):
    """Inclusive cell ranges (s, β) of lattice ``row`` whose centres lie within half a cell of the box of ``pts``
    projected: centre (i + ½)·h from the start within [lo − h/2, hi + h/2]."""
    s, b = _project(pts, rot, pos, side)
    out = []
    for lo, hi, start, h, n in ((s.min(), s.max(), row[0], row[1], row[4]), (b.min(), b.max(), row[2], row[3], row[5])):
        out += [max(int(np.ceil((lo - start) / h - 1.0)), 0), min(int(np.floor((hi - start) / h)), int(n) - 1)]
    return tuple(out)


def slender_trim(row, pts, cell_m, rot, pos, side, max_cells):
    """A slender object's lattice ``row`` [s0, hs, β0, hβ, ns, nβ] trimmed to the box of the cells its cover's
    segments reach inside it (:func:`_reach` of each, clipped; segments outside left out) and
    refined to ``cell_m``/(its cross-section's corner distance) of the angle its middle slice spans across the
    line joining its end slices' centres (the larger span of s and β where that line is shorter; the lattice's own
    cells where the object is seen exactly edge-on)."""
    boxes = [_reach(row, pts[a:a + 8], rot, pos, side) for a in range(0, len(pts) - 4, 4)]
    boxes = np.array([b for b in boxes if b[1] >= b[0] and b[3] >= b[2]]).reshape(-1, 4)
    if boxes.shape[0] == 0:
        return np.zeros(6)
    i0, i1, j0, j1 = boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max()
    s, b = _project(pts, rot, pos, side)
    end = np.array([[s[:4].mean(), b[:4].mean()], [s[-4:].mean(), b[-4:].mean()]])
    m = 4 * ((len(pts) // 4) // 2)
    mid = np.stack([s[m:m + 4], b[m:m + 4]], axis=1)
    axis = end[1] - end[0]
    normal = np.array([-axis[1], axis[0]])
    if np.linalg.norm(normal) <= np.ptp(mid, axis=0).max():
        width = np.ptp(mid, axis=0).max()
    else:
        width = np.ptp(mid @ normal) / np.linalg.norm(normal)
    h = width * cell_m / np.linalg.norm(pts[2] - pts[0])
    h = h if h > 1e-12 else np.inf
    ns = int(np.ceil((i1 - i0 + 1) * row[1] / min(row[1], h) - 1e-9))
    nb = int(np.ceil((j1 - j0 + 1) * row[3] / min(row[3], h) - 1e-9))
    if ns * nb > max_cells:
        return np.zeros(6)
    return np.array([row[0] + i0 * row[1], row[1] * (i1 - i0 + 1) / ns, row[2] + j0 * row[3],
                     row[3] * (j1 - j0 + 1) / nb, ns, nb])


def cover_cells(table, cover, cover_start, rot, pos, max_rays):
    """Each slender lattice's cells to cast ((rows, k) list of (ns, nβ) bool arrays, None where every cell is cast):
    those whose centres lie within half a cell of the (s, β) box of a segment between consecutive 4-corner slices
    of its cover; a
    lattice of more than ``max_rays`` of them gets none (all False)."""
    out = [[None] * table.shape[1] for _ in range(table.shape[0])]
    for r in range(table.shape[0]):
        side = 1.0 if r % 2 else -1.0
        for k in range(table.shape[1]):
            row = table[r, k]
            if row[7] < 0 or row[4] == 0:                  # MASK: an offset for a slender lattice, −1 otherwise
                continue
            cells = np.zeros((int(row[4]), int(row[5])), dtype=bool)
            pts = cover[cover_start[k]:cover_start[k + 1]]
            for a in range(0, len(pts) - 4, 4):
                i0, i1, j0, j1 = _reach(row, pts[a:a + 8], rot[r // 2], pos[r // 2], side)
                if i1 >= i0 and j1 >= j0:                   # (a slice with a negative end would wrap)
                    cells[i0:i1 + 1, j0:j1 + 1] = True
            out[r][k] = cells if cells.sum() <= max_rays else np.zeros_like(cells)
    return out


def drop_aimed(ray_start, prim, face_object, cand_of_object, aimed, weight):
    """The fan's weights with the hits on each row's aimed objects set to 0."""
    out = weight.copy()
    for r in range(len(ray_start) - 1):
        for i in range(ray_start[r], ray_start[r + 1]):
            if prim[i] >= 0:
                k = cand_of_object[face_object[prim[i]]]
                if k >= 0 and aimed[r, k]:
                    out[i] = 0.0
    return out


def swell_glints(centre, radius, pos, k, a_nodes, z, reach_m, n_across, steps, max_rays):
    """Every glint by brute force over every strip (twin of kernels.swell_glints, which searches a window): a dict
    {(ping, object): list of (strip, [s0, hs, β0, hβ, ns, nβ])} in the crest frame (c along the crests, k across,
    ẑ up: u = s'·c + √(1 − s'²)(cos β'·k + sin β'·ẑ)), or the string "refused" (the object left to the fan)."""
    c = np.array([-k[1], k[0], 0.0])
    k3 = np.array([k[0], k[1], 0.0])
    out = {}
    for b in range(len(pos)):
        s = pos[b]
        for j in range(len(centre)):
            found = []
            for i in range(len(a_nodes) - 1):
                p0 = np.array([a_nodes[i] * k[0], a_nodes[i] * k[1], z[i]])
                edge = np.array([(a_nodes[i + 1] - a_nodes[i]) * k[0], (a_nodes[i + 1] - a_nodes[i]) * k[1],
                                 z[i + 1] - z[i]])
                nv = np.cross(edge, c)
                nv = nv / np.linalg.norm(nv) * np.sign(nv[2])            # the strip plane's upward normal
                if (s - p0) @ nv >= 0 or (centre[j] - p0) @ nv >= 0:
                    continue
                img = centre[j] - 2 * ((centre[j] - p0) @ nv) * nv
                v = img - s
                d = np.linalg.norm(v)
                if d - radius[j] > reach_m:
                    continue
                if d <= radius[j] * (1 + 1e-9):
                    found = "refused"
                    break
                gam = np.arcsin(radius[j] / d)
                sc = v @ c / d
                bc, db = np.arctan2(v[2], v @ k3), np.arcsin(np.sin(gam) / np.sqrt(1 - sc ** 2))
                a_s = s @ k3
                e = [np.arctan2(z[q] - s[2], a_nodes[q] - a_s) for q in (i, i + 1)]
                b_lo, b_hi = max(bc - db, min(e)), min(bc + db, max(e))
                if b_hi <= b_lo:
                    continue
                s_lo, s_hi = max(sc - gam, -1.0), min(sc + gam, 1.0)
                hs = min(2 * gam / n_across, steps[0])
                hb = min(2 * gam / n_across, steps[1], 2 * gam * steps[2] / (2 * radius[j]))
                ns, nb = np.ceil((s_hi - s_lo) / hs - 1e-9), np.ceil((b_hi - b_lo) / hb - 1e-9)
                if ns * nb > max_rays:
                    found = "refused"
                    break
                found.append((i, [s_lo, (s_hi - s_lo) / ns, b_lo, (b_hi - b_lo) / nb, ns, nb]))
            out[b, j] = found
    return out


def glint_rays(glints, ping, k, rot, pos, span, sides, rx_shift):
    """(world directions, body layout [s, cos β, sin β, dβ', ds'], row or −1) of every glint lattice's rays (twin of
    kernels.glint_rays): cell centres in the crest frame, s'-major, β' fastest."""
    c, k3 = np.array([-k[1], k[0], 0.0]), np.array([k[0], k[1], 0.0])
    dirs, lay, rows = [], [], []
    for g, row in enumerate(glints):
        ns, nb = int(row[5]), int(row[6])
        sp = np.repeat(row[1] + (np.arange(ns) + 0.5) * row[2], nb)
        bp = np.tile(row[3] + (np.arange(nb) + 0.5) * row[4], ns)
        cp = np.sqrt(1 - sp ** 2)
        u = sp[:, None] * c + cp[:, None] * (np.cos(bp)[:, None] * k3 + np.sin(bp)[:, None] * [0, 0, 1.0])
        b = ping[g]
        body = u @ rot[b]                                          # (forward, starboard, down)
        side = (body[:, 1] >= 0).astype(int)
        beta = np.arctan2(body[:, 2], np.abs(body[:, 1]))
        cpsi = np.sqrt(1 - body[:, 0] ** 2)
        inside = ((span[0] + min(rx_shift[b], 0) <= body[:, 0]) & (body[:, 0] <= span[1] + max(rx_shift[b], 0))
                  & (span[2] <= beta) & (beta <= span[3]))
        rows.append(np.where(np.asarray(sides)[side] & inside, 2 * b + side, -1))
        dirs.append(u)
        lay.append(np.column_stack([body[:, 0], np.abs(body[:, 1]) / cpsi, body[:, 2] / cpsi,
                                    np.full(len(u), row[4]), np.full(len(u), row[2])]))
    return np.concatenate(dirs), np.concatenate(lay), np.concatenate(rows)


def _eigen_leg(z, c, xi, d_end):
    """(x/ξ, ∂x/∂ξ, T, L) of rays of invariant ξ (n,) from depth 0 to d_end (n,) in NumPy: the textbook forms per
    piece (T = ln(c_b(1 + s_a)/(c_a(1 + s_b)))/g, L = (asin ξc_b − asin ξc_a)/(gξ); straight where g = 0)."""
    out = [np.zeros_like(xi) for _ in range(4)]
    for j in range(len(z)):
        bottom = np.minimum(d_end, z[j + 1]) if j + 1 < len(z) else d_end
        dz = np.maximum(bottom - z[j], 0.0)
        ca, cb = c[j] + 0 * xi, np.interp(bottom, z, c)
        g = np.where(dz > 0, (cb - ca) / np.where(dz > 0, dz, 1.0), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            sa, sb = np.sqrt(1 - (xi * ca) ** 2), np.sqrt(1 - (xi * cb) ** 2)
            flat = np.abs(g) < 1e-12
            x_xi = np.where(flat, dz * ca / sa, (sa - sb) / (xi * xi * g))
            tiny = np.abs(xi) < 1e-6                          # ξ → 0: the difference forms lose their digits
            x_xi = np.where(flat | tiny, dz * (ca + cb) / (sa + sb), x_xi)
            dx = x_xi + xi * xi * dz * (ca + cb) / (sa + sb) ** 2 * (ca * ca / sa + cb * cb / sb)
            t = np.where(flat, dz / (ca * sa), np.log(cb * (1 + sa) / (ca * (1 + sb))) / g)
            length = np.where(flat, dz / sa, (np.arcsin(xi * cb) - np.arcsin(xi * ca)) / (g * xi))
            length = np.where(~flat & tiny, dz * (ca + cb) / (cb * sa + ca * sb), length)
        for acc, v in zip(out, (x_xi, dx, t, length)):
            acc += np.where(dz > 0, v, 0.0)
    return out


def surface_eigenrays(z, c, d_src, d_dst, x, iterations=200):
    """Twin of kernels.surface_eigenrays: bisection on x(ξ) in NumPy, the same (n, 9) columns."""
    deepest = np.maximum(d_src, d_dst)
    c_max = np.max([np.where(zk <= deepest, ck, 0.0) for zk, ck in zip(z, c)]
                   + [np.interp(d_src, z, c), np.interp(d_dst, z, c)], axis=0)
    lo, hi = np.zeros_like(x), (1 - 1e-12) / c_max
    reach = hi * (_eigen_leg(z, c, hi, d_src)[0] + _eigen_leg(z, c, hi, d_dst)[0])
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        f = mid * (_eigen_leg(z, c, mid, d_src)[0] + _eigen_leg(z, c, mid, d_dst)[0]) - x
        lo, hi = np.where(f < 0, mid, lo), np.where(f < 0, hi, mid)
    xi = np.where(reach >= x, 0.5 * (lo + hi), np.nan)
    up, down = _eigen_leg(z, c, xi, d_src), _eigen_leg(z, c, xi, d_dst)
    c_src, c_dst = np.interp(d_src, z, c), np.interp(d_dst, z, c)
    s_src, s_dst = np.sqrt(1 - (xi * c_src) ** 2), np.sqrt(1 - (xi * c_dst) ** 2)
    return np.column_stack([xi, up[2] + down[2], up[3] + down[3],
                            (up[0] + down[0]) * (up[1] + down[1]) * s_src * s_dst / c_src ** 2, xi * up[0],
                            s_src, s_dst, np.sqrt(1 - (xi * c[0]) ** 2), c_dst])


def curved_mixed(hits, launch, poses, normals, medium, weighting):
    """Twin of kernels.curved_mixed in NumPy: (n, 7) columns w, t, extent, cos θi, cos θs, φ, x_up."""
    point, prim, arrival, path, time, extent, lit = hits
    body, dbeta, row = launch
    rot, pos, rx_shift = poses
    z, c, z_s = medium
    beam, two_way, ds, r_min, kh, want_phi = weighting
    n = lit.shape[0]
    out = np.zeros((n, 7))
    out[:, 1] = np.inf
    k = np.flatnonzero(lit)
    b, side = row[k] // 2, np.where(row[k] % 2 == 1, 1.0, -1.0)
    rel = point[k, :2] - pos[b, :2]
    x = np.hypot(rel[:, 0], rel[:, 1])
    h = np.where(x[:, None] > 0, rel / np.where(x > 0, x, 1.0)[:, None], [1.0, 0.0])
    d_src, d_dst = z_s - pos[b, 2], z_s - point[k, 2]
    ray = surface_eigenrays(z, c, d_src, d_dst, x)
    xi, t2, l2, spread, x_up, s_src, s_dst, s_top, c_dst = ray.T
    c_src = np.interp(d_src, z, c)
    u2 = np.column_stack([h * (xi * c_src)[:, None], s_src])
    v = np.column_stack([-h * (xi * c_dst)[:, None], s_dst])
    nrm = normals[prim[k]] * np.where(np.einsum("ij,ij->i", normals[prim[k]], arrival[k]) > 0, -1.0, 1.0)[:, None]
    cos_i, cos_s = -np.einsum("ij,ij->i", nrm, arrival[k]), np.einsum("ij,ij->i", nrm, v)
    e = np.einsum("nji,nj->ni", rot[b], u2)

    def gain(u, delta):
        ct, st = np.cos(beam[2]), np.sin(beam[2])
        g = (np.sinc(beam[0] * (u[:, 0] - delta) / np.pi)
             * np.sinc(beam[1] * (u[:, 2] * ct - side * u[:, 1] * st) / np.pi))
        return np.where(side * u[:, 1] * ct + u[:, 2] * st > 0, g, 0.0)
    g1, g1r, g2, g2r = gain(body[k], 0.0), gain(body[k], rx_shift[b]), gain(e, 0.0), gain(e, rx_shift[b])
    w = ((g1 ** 2 * g2r ** 2 + g1r ** 2 * g2 ** 2) * np.exp(-4 * kh ** 2 * s_top ** 2)
         * np.exp(-0.5 * two_way * (path[k].astype(float) + l2)) * ds * dbeta[k]
         / (np.maximum(spread, r_min ** 2) * cos_i))
    w = np.where(np.isfinite(xi) & (cos_i > 0) & (cos_s > 0), w, 0.0)
    ok = w > 0
    f = np.column_stack([h, np.zeros(len(k))])
    f -= nrm * np.einsum("ij,ij->i", nrm, f)[:, None]
    ratio = np.minimum(np.abs(np.einsum("ij,ij->i", v, f)) / np.maximum(np.abs(np.einsum("ij,ij->i", arrival[k], f)),
                                                                        1e-12), 10.0)
    bb = -arrival[k] - nrm * np.einsum("ij,ij->i", nrm, -arrival[k])[:, None]
    tt = v - nrm * np.einsum("ij,ij->i", nrm, v)[:, None]
    norm = np.sqrt(np.einsum("ij,ij->i", bb, bb) * np.einsum("ij,ij->i", tt, tt))
    phi = np.where(norm > 1e-24, np.arccos(np.clip(np.einsum("ij,ij->i", bb, tt) / np.maximum(norm, 1e-300), -1, 1)),
                   0.0)
    cols = (w, 0.5 * time[k] + t2, 0.5 * extent[k] * (1 + ratio), cos_i, cos_s, phi if want_phi else 0 * w, x_up)
    for j, col in enumerate(cols):
        out[k[ok], j] = col[ok]
    return out


def backproject(data, t0_s, rate_hz, carrier_hz, sound_speed_m_s, tx, rx, pixels, fwd=None, max_u=2.0, vel=None,
                taper=0.0):
    """Twin of kernels.backproject: every pixel's sum over pings and elements, vectorised over pixels with
    np.interp (zero outside the record), each ping and element kept where the mean u of its two along-track
    direction cosines is within ``max_u`` and weighted by 1 − taper·(1 − cos(π·u/max_u)); the element moved on
    by vel·2|x − tx|/c (vel None: at rest)."""
    n_p, n_k, n_s = data.shape
    out = np.zeros(pixels.shape[0], dtype=np.complex128)
    grid = t0_s + np.arange(n_s) / rate_hz
    fwd = np.tile([1.0, 0.0, 0.0], (n_p, 1)) if fwd is None else fwd
    for p in range(n_p):
        d_tx = np.linalg.norm(pixels - tx[p], axis=1)
        moved = 0.0 if vel is None else vel[p] * (2.0 * d_tx / sound_speed_m_s)[:, None]
        for k in range(n_k):
            d_rx = np.linalg.norm(pixels - rx[p, k] - moved, axis=1)
            u = 0.5 * ((pixels - tx[p]) @ fwd[p] / d_tx + (pixels - rx[p, k] - moved) @ fwd[p] / d_rx)
            tau = (d_tx + d_rx) / sound_speed_m_s
            inside = (tau >= grid[0]) & (tau < grid[-1]) & (np.abs(u) <= max_u)
            s = np.interp(tau, grid, data[p, k].real) + 1j * np.interp(tau, grid, data[p, k].imag)
            weight = 1.0 - taper * (1.0 - np.cos(np.pi * u / max_u))
            out += np.where(inside, weight * s * np.exp(2j * np.pi * carrier_hz * tau), 0.0)
    return out


def beam_cosines(s, cos_beta, sin_beta, el_start, tilt_rad, layout=None):
    """v = cos ψ·sin(β − δ) of every ray (kernels.beam_cosines): rows of ``el_start``, each azimuth-major over its
    elevation cells (or each ray's own s, cos β, sin β in ``layout``)."""
    if layout is not None and len(layout):
        sa, cb, sb = layout[:, 0], layout[:, 1], layout[:, 2]
    else:
        parts = []
        for r in range(len(el_start) - 1):
            cells = np.arange(el_start[r], el_start[r + 1])
            parts.append(np.stack(np.broadcast_arrays(s[:, None], cos_beta[cells][None, :],
                                                      sin_beta[cells][None, :]), axis=-1).reshape(-1, 3))
        sa, cb, sb = np.concatenate(parts).T
    return np.sqrt(1 - sa ** 2) * np.sin(np.arctan2(sb, cb) - tilt_rad)


def weigh_lines(el_start, n_az, line_gain, ray_gain, weight):
    """A copy of ``weight`` × line_gain[ping, azimuth line] × ray_gain (kernels.weigh_lines)."""
    out = weight.copy()
    i = 0
    for r in range(len(el_start) - 1):
        n_el = el_start[r + 1] - el_start[r]
        for a in range(n_az):
            out[i:i + n_el] *= line_gain[r // 2, a] * ray_gain[i:i + n_el]
            i += n_el
    return out


def weigh_fan(s, cos_beta, sin_beta, el_start, tilt_rad, across, line_gain, weight):
    """A copy of ``weight`` × line_gain[ping, azimuth line] × across(v)⁴ where weight > 0 (kernels.weigh_fan),
    ``across`` a NumPy function of v = cos ψ·sin(β − δ)."""
    v = beam_cosines(s, cos_beta, sin_beta, el_start, tilt_rad)
    gain = np.where(weight > 0, across(v) ** 4, 1.0)
    return weigh_lines(el_start, len(s), line_gain, gain, weight)


def weigh_pairs(ray_start, body, leg, rot, rx_shift, tilt_rad, along, across, w_pair, w_mono):
    """Copies of ``w_pair`` × (Γ²(u)·Γ_rx²(d) + Γ²(d)·Γ_rx²(u)) and ``w_mono`` × Γ²(u)·Γ_rx²(u) where they are > 0
    (kernels.weigh_pairs), echo by echo: u = body[i], d = Rᵀ·leg[i] in the body frame of the row's ping; each
    direction's angle off the side's boresight plane gives Γ = along(s)·across(v)·[in front of the baffle], the
    boresight on side ±1 being (0, ±cos δ, sin δ) and the elevation axis (0, ∓sin δ, cos δ); ``along`` and
    ``across`` NumPy functions."""
    w_pair, w_mono = np.array(w_pair, dtype=float), np.array(w_mono, dtype=float)
    for r in range(len(ray_start) - 1):
        b, side = r // 2, (1.0 if r % 2 == 1 else -1.0)
        boresight = np.array([0.0, side * np.cos(tilt_rad), np.sin(tilt_rad)])
        elevation = np.array([0.0, -side * np.sin(tilt_rad), np.cos(tilt_rad)])

        def gains(e):
            front = float(e @ boresight > 0)
            return (along(e[0]) * across(e @ elevation) * front,
                    along(e[0] - rx_shift[b]) * across(e @ elevation) * front)

        for i in range(ray_start[r], ray_start[r + 1]):
            g1, g1r = gains(np.asarray(body[i], float))
            if len(w_mono) and w_mono[i] > 0:
                w_mono[i] *= g1 ** 2 * g1r ** 2
            if w_pair[i] > 0:
                g2, g2r = gains(rot[b].T @ leg[i])
                w_pair[i] *= g1 ** 2 * g2r ** 2 + g2 ** 2 * g1r ** 2
    return w_pair, w_mono
