"""Every Numba kernel against its naive NumPy twin (tests/naive.py)."""
import numpy as np
from scipy import stats
import pytest

import naive
import sonar_embree as se
from sonar_embree import kernels
from sonar_embree.signal import synthesis
from sonar_embree.kernels import args as A
from sonar_embree.kernels.args import Lattice, NodeTables, PathEnds, SpeckleEchoes, Waveform


def _splat_inputs(rng, n=4000, n_s=300):
    delay = rng.uniform(-5, n_s + 5, n)
    delay[:6] = [0.0, n_s - 1, n_s - 1 + 1e-9, -1e-12, np.nan, np.inf]
    channel = rng.integers(-1, 3, n)
    return channel, delay


def test_zero_width_splat_rows_is_linear_splatting(rng):
    """Point echoes (zero footprint) in splat_rows are linear fractional-delay splatting, per row."""
    channel, delay = _splat_inputs(rng)
    keep = (channel >= 0) & (channel < 2)
    channel, delay = channel[keep], delay[keep]
    w = rng.uniform(0, 1, delay.size)
    order = np.argsort(channel, kind="stable")
    ray_start = np.searchsorted(channel[order], [0, 1, 2])
    out = np.zeros((2, 300))
    kernels.splat_rows(ray_start, delay[order], np.zeros(delay.size), w[order], 1.0, out)
    ref = naive.splat_linear(channel, delay, w, np.zeros((2, 300)))
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)


def test_splat_conserves_weight_and_never_wraps():
    out = np.zeros((1, 10))
    kernels.splat_rows(np.array([0, 3]), np.array([-0.5, 3.25, 9.5]), np.zeros(3), np.array([7.0, 1.0, 5.0]), 1.0,
                       out)
    assert out.sum() == 1.0  # only the in-window contribution, no wrap-around of the negative delay
    np.testing.assert_allclose(out[0, 3:5], [0.75, 0.25])


def test_splat_table_matches_naive_complex_and_real(rng):
    channel, delay = _splat_inputs(rng, n=600)
    table = np.exp(1j * np.linspace(0, 20, 257)) * np.hanning(257)
    amp = rng.normal(size=delay.size) + 1j * rng.normal(size=delay.size)
    for start, rate in ((0.0, 64.0), (-2.0, 32.0)):
        out = np.zeros((2, 300), dtype=complex)
        kernels.splat_table(channel, delay, amp, table, start, rate, out)
        ref = naive.splat_table(channel, delay, amp, table, start, rate, np.zeros((2, 300), dtype=complex))
        np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)
    out = np.zeros((2, 300))
    kernels.splat_table(channel, delay, amp.real, table.real, -2.0, 32.0, out)
    ref = naive.splat_table(channel, delay, amp.real, table.real, -2.0, 32.0, np.zeros((2, 300)))
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)


def test_splat_table_is_a_fractional_delay_not_a_rounding():
    # A ramp table h(u) = u on [0, 4]: the sample k gets k − x exactly.
    table = np.linspace(0.0, 4.0, 4 * 16 + 1)
    out = np.zeros((1, 10))
    kernels.splat_table(np.zeros(1, dtype=np.int64), np.array([2.3]), np.array([1.0]), table, 0.0, 16.0, out)
    np.testing.assert_allclose(out[0, 3:7], [0.7, 1.7, 2.7, 3.7], atol=1e-12)
    assert np.all(out[0, :3] == 0) and np.all(out[0, 7:] == 0)


def test_frozen_scatterers_match_naive_and_are_rayleigh():
    ijk = np.stack(np.meshgrid(np.arange(-20, 20), np.arange(-20, 20), np.array([-1, 0, 5_000_000_000]),
                               indexing="ij"), -1).reshape(-1, 3).astype(np.int64)
    out = np.empty((ijk.shape[0], 4), dtype=complex)
    pos = np.empty((ijk.shape[0], 4))
    kernels.frozen_scatterers(3, ijk, out, pos)
    ref_gain, ref_pos = naive.frozen_scatterers(3, ijk, 4)
    np.testing.assert_allclose(out, ref_gain, rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(pos, ref_pos)
    for s in range(4):                                                     # stratified: one per quarter
        assert np.all((pos[:, s] >= s / 4) & (pos[:, s] < (s + 1) / 4))
        assert abs(pos[:, s].mean() - (s + 0.5) / 4) < 0.01
    i = np.abs(out.ravel()) ** 2
    assert abs(i.mean() - 1) < 0.05 and abs(i.std() - 1) < 0.07           # exponential intensity
    assert abs(np.mean(out)) < 0.03                                        # uniform phase
    assert stats.kstest(i, "expon").pvalue > 1e-3                          # the whole law, not two moments
    assert stats.kstest(np.angle(out.ravel()), "uniform", args=(-np.pi, 2 * np.pi)).pvalue > 1e-3
    other = np.empty_like(out)
    kernels.frozen_scatterers(4, ijk, other, pos)
    assert abs(np.corrcoef(np.abs(out.ravel()), np.abs(other.ravel()))[0, 1]) < 0.05


def test_gather_nodes_matches_naive(rng):
    n = 3000
    pts = rng.uniform(-1, 1, (n, 3)) * [3, 3, 0.3] + [512_000.0, 5_412_000.0, -20.0]
    pts[:50, 2] = -20.0  # on a lattice plane: zero weights must not create nodes
    ch = rng.integers(0, 2, n)
    w = rng.uniform(0, 1, n)
    w[:7] = 0.0
    r = rng.uniform(10, 50, n)
    ext = rng.uniform(0, 0.2, n)
    ext[:100] = 0.0
    cap = 1 << 16
    slots = np.full(cap, -1, dtype=np.int64)
    nodes = np.zeros((cap // 2, kernels.NODE_WIDTH))
    node_key = np.zeros((cap // 2, 4), dtype=np.int64)
    cache = np.zeros(kernels.CACHE_WIDTH, dtype=np.int64)
    for epoch in (1, 2):  # the second call reuses the table without clearing it
        k = kernels.gather_nodes(ch, pts, w, r, ext, 0.25, slots, epoch, nodes, node_key, cache)
        ref = naive.gather_nodes(ch, pts, w, r, ext, 0.25)
        assert k == len(ref)
        got = {tuple(node_key[i]): tuple(nodes[i]) for i in range(k)}
        assert got.keys() == ref.keys()
        for kk, vals in ref.items():
            np.testing.assert_allclose(got[kk], vals, rtol=1e-10, atol=1e-20)
    np.testing.assert_allclose(nodes[:k, 0].sum(), w.sum(), rtol=1e-12)  # ΣW = Σw
    first = {}                                         # listed in first-touch order: rays, then x, y, z corners
    for i in np.flatnonzero(w > 0):
        f = pts[i] / 0.25
        frac = f - np.floor(f)
        frac = np.where(frac < 1e-3, 0.0, np.where(frac > 1 - 1e-3, 1.0, frac))   # snapped onto a plane
        for dz, dy, dx in np.ndindex(2, 2, 2):
            t = np.abs(1 - np.array([dx, dy, dz]) - frac)
            if np.prod(t) > 0:
                first.setdefault((ch[i], *(np.floor(f).astype(np.int64) + [dx, dy, dz])), None)
    first = list(first)
    assert [tuple(node_key[i]) for i in range(k)] == first
    near = np.array([[512_000.1, 5_412_000.1, -20.0 + 1e-6], [512_000.1, 5_412_000.1, -20.0 - 1e-6]])
    for p in near:                                     # a float32 rounding off a plane: one layer of nodes, not two
        m = kernels.gather_nodes(np.zeros(1, np.int64), p[None], np.ones(1), np.ones(1), np.zeros(1), 0.25, slots,
                                 3 + int(p[2] < -20), nodes, node_key, cache)
        assert m == 4 and set(node_key[:m, 3]) == {-80}
    small = 1 << 10                                    # too small a table: says so instead of overfilling
    args = [np.full(small, -1, dtype=np.int64), 1, np.zeros((small // 2, kernels.NODE_WIDTH)),
            np.zeros((small // 2, 4), dtype=np.int64), cache]
    assert kernels.gather_nodes(ch, pts, w, r, ext, 0.25, *args) == -1


def _speckle_tables(n_tables, cap):
    """Hash tables, node lists and last-cell caches for :func:`kernels.speckle_block`."""
    return (np.full((n_tables, cap), -1, np.int64), np.zeros(n_tables, np.int64),
            np.zeros((n_tables, cap // 2, kernels.NODE_WIDTH)), np.zeros((n_tables, cap // 2, 4), np.int64),
            np.zeros((n_tables, kernels.CACHE_WIDTH), np.int64))


# --------------------------------------------------------------------------- ray fan kernels


def _block(rng, n_p=3):
    """A small block: random poses, random per-row elevation rays."""
    from scipy.spatial.transform import Rotation

    # body (forward, starboard, down) → world (x, −y, −z), then a random attitude
    rot = Rotation.from_euler("zyx", rng.uniform(-0.5, 0.5, (n_p, 3))).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    pos = rng.uniform(-1, 1, (n_p, 3)) + [0, 0, 10.0]
    counts = rng.integers(1, 40, 2 * n_p)
    el_start = np.concatenate(([0], np.cumsum(counts)))
    beta = rng.uniform(-0.3, 1.5, el_start[-1])
    dbeta = rng.uniform(1e-4, 3e-3, el_start[-1])
    s = np.array([-0.02, 0.0, 0.011])
    return s, beta, dbeta, el_start, rot, pos


def test_elevation_density_matches_naive_bit_for_bit(rng):
    """Jumps, silhouettes against nothing, lines with nothing in range and lines out of range at one end: the
    kernel's densities equal the whole-array twin's exactly (they set ray counts, so the records' bits)."""
    beta = np.sort(rng.uniform(-0.3, 1.5, 61))
    r = 10.0 / np.sin(np.clip(beta, 0.05, None)) + rng.normal(0.0, 0.3, (9, 61))
    r[1, 20:26] = 4.0                                   # an object: two range jumps
    r[2, ::7] = np.nan                                  # holes
    r[3] = np.nan                                       # nothing in range
    r[4, 40:] = np.nan                                  # a silhouette against nothing
    r[5, :3] = np.nan
    r[6, 30] = 80.0                                     # a single spike
    got = np.empty((9, 60))
    kernels.elevation_density(beta, r, 0.02, 0.01, 500.0, 8.0, 4.0, got)
    ref = naive.elevation_density(beta, r, 0.02, 0.01, 500.0, 8.0, 4.0)
    assert np.array_equal(got, ref)
    assert np.all(got[3] == 1.0 / (8.0 * 0.01))                # nothing in range: the coarse empty step


def test_cos_sin_matches_numpy(rng):
    x = rng.uniform(-4.0, 4.0, 1001)
    c, s = np.empty_like(x), np.empty_like(x)
    kernels.cos_sin(x, c, s)
    np.testing.assert_allclose(c, np.cos(x), rtol=0, atol=2e-16)
    np.testing.assert_allclose(s, np.sin(x), rtol=0, atol=2e-16)


def test_probe_rays_match_the_rotated_body_directions(rng):
    """probe_rays is rot·body per ping (NumPy's matmul as the twin, to rounding) with the ping's position."""
    body = rng.normal(size=(11, 3))
    rot = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(4)])
    pos = rng.normal(size=(4, 3)) * 50.0
    dirs, d32, o32 = np.empty((4, 11, 3)), np.empty((44, 3), np.float32), np.empty((44, 3), np.float32)
    kernels.probe_rays(body, rot, pos, dirs, d32, o32)
    np.testing.assert_allclose(dirs, np.matmul(body, rot.transpose(0, 2, 1)), rtol=0, atol=1e-14)
    assert np.array_equal(d32, dirs.reshape(-1, 3).astype(np.float32))
    assert np.array_equal(o32, np.repeat(pos, 11, axis=0).astype(np.float32))


def test_place_rows_matches_naive(rng):
    edges = np.linspace(-1.0, 1.5, 60)
    density = rng.uniform(0, 500, (4, 59))
    density[1, 10:30] = 0.0  # empty cells take no rays
    counts = np.array([1, 17, 300, 55])
    el_start = np.concatenate(([0], np.cumsum(counts)))
    beta, dbeta = np.empty(el_start[-1]), np.empty(el_start[-1])
    kernels.place_rows(edges, density, el_start, beta, dbeta)
    ref_b, ref_db = naive.place_rows(edges, density, counts)
    np.testing.assert_allclose(beta, ref_b, atol=1e-12)
    np.testing.assert_allclose(dbeta, ref_db, atol=1e-12)
    for r in range(4):  # each row's cells tile the span exactly
        assert dbeta[el_start[r]:el_start[r + 1]].sum() == pytest.approx(2.5, rel=1e-12)


def test_fan_rays_match_naive(rng):
    s, beta, _, el_start, rot, pos = _block(rng)
    n = s.size * el_start[-1]
    dirs, org = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32)
    kernels.fan_rays(s, np.cos(beta), np.sin(beta), el_start, rot, pos, dirs, org)
    np.testing.assert_allclose(dirs, naive.fan_directions(s, beta, el_start, rot), atol=1e-7)
    rows = np.repeat(np.arange(len(el_start) - 1), s.size * np.diff(el_start))
    np.testing.assert_allclose(org, pos[rows // 2], atol=1e-6)


@pytest.mark.parametrize("inverted", [False, True])
def test_fan_echoes_match_naive_on_sloped_facets(rng, inverted):
    """Hits on a tilted, bumpy mesh: range, footprint extent (against the secant of the cell) and weight, the
    kernel's (unit gain) times the membrane the beam stage applies after it (propagation.gain.weigh_by_beam)
    against the twin that weighs the membrane itself. Inverted: the same mesh with its faces turned away, in a
    two-sided material, gives the same echoes."""
    from sonar_embree.instrument.beams import Membrane
    from sonar_embree.laws import apply_laws, law_table
    from sonar_embree.propagation.gain import weigh_by_beam
    from sonar_embree.raycast import RayCaster

    heights = rng.uniform(-0.3, 0.3, (21, 21)) + np.linspace(0, 4, 21)[None, :]
    mesh = se.seafloor.from_heights(heights, spacing_m=4.0, origin_m=(-40, -40))
    if inverted:
        mesh.invert()
    scene = se.Scene().add(mesh, label="floor", material=se.Material(-20.0, two_sided=inverted))
    c = scene.compiled()
    two_sided = c.two_sided[c.face_object]
    caster = RayCaster(c)
    s, beta, dbeta, el_start, rot, pos = _block(rng)
    pos = pos - c.origin_m  # the local frame
    n = s.size * el_start[-1]
    dirs, org = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32)
    kernels.fan_rays(s, np.cos(beta), np.sin(beta), el_start, rot, pos, dirs, org)
    prim, tfar = caster.cast_raw(org, dirs, 60.0)
    assert (prim >= 0).sum() > 100
    mu_face = c.mu[c.face_object]
    k, lx, ly, tilt = 2 * np.pi / 0.00375, 0.19, 0.0038, np.radians(20)
    rng_k, ext_k, w_k, cos_k, pts = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty((n, 3))
    t_k = np.empty(n)
    per_m = 2 / 1500.0  # travel time and its extent come out in seconds
    shift = rng.uniform(-3e-3, 3e-3, rot.shape[0])  # motion during the ping (0: stop-and-hop)
    fan = A.Fan(s, 0.01, np.cos(beta), np.sin(beta), dbeta, el_start)
    kernels.fan_echoes(fan, A.Poses(rot, pos, shift), prim, tfar,
                       A.SceneArrays(c.vertices, c.faces, c.face_normals, two_sided),
                       A.DirectWeighting(tilt, 0.02, 0.004, 60.0, 500.0, per_m),
                       A.EchoOut(rng_k, t_k, ext_k, w_k, cos_k, pts), kernels.NO_LAYOUT)
    weigh_by_beam(Membrane(k * lx / 2, k * ly / 2, 2 * np.pi / k), tilt, fan, shift, w_k)
    ext_k = ext_k / per_m
    np.testing.assert_array_equal(t_k, rng_k * per_m)
    apply_laws(law_table(c.laws, 100e3), c, prim, cos_k, w_k)  # the scene's law (Lambert) multiplies σ/cos θi in
    rng_n, ext_n, w_n = naive.fan_echoes(s, 0.01, beta, dbeta, el_start, rot, pos, prim, c.vertices, c.faces,
                                         mu_face, k, lx, ly, tilt, 0.02, 0.004, 60.0, 500.0, two_sided, shift)
    hit = w_n > 0
    assert hit.sum() > 100
    np.testing.assert_array_equal(w_k > 0, hit)
    np.testing.assert_allclose(rng_k[hit], rng_n[hit], rtol=1e-12)
    np.testing.assert_allclose(w_k[hit], w_n[hit], rtol=1e-9)
    np.testing.assert_allclose(ext_k[hit], ext_n[hit], rtol=2e-3, atol=1e-9)
    rows = np.repeat(np.arange(len(el_start) - 1), s.size * np.diff(el_start))
    np.testing.assert_allclose(pts[hit], pos[rows[hit] // 2] + rng_n[hit, None] * dirs[hit], atol=1e-5)


def test_splat_rows_matches_naive_and_conserves_weight(rng):
    n_s = 50
    ray_start = np.array([0, 40, 40, 100])
    delay = rng.uniform(-5, n_s + 5, 100)
    width = rng.uniform(0, 8, 100)
    width[::7] = 0.0   # point echoes: linear splatting
    w = rng.uniform(0, 1, 100)
    w[::11] = 0.0
    got = np.zeros((3, n_s))
    kernels.splat_rows(ray_start, delay / 8.0, width / 8.0, w, 8.0, got)  # in seconds at 8 Hz
    ref = naive.splat_rows(ray_start, delay, width, w, np.zeros((3, n_s)))
    np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-9)
    assert np.all(got[1] == 0.0)
    inside = (delay - width / 2 >= 0) & (delay + width / 2 <= n_s - 1)
    one = np.zeros((1, n_s))
    kernels.splat_rows(np.array([0, int(inside.sum())]), delay[inside], width[inside], w[inside], 1.0, one)
    assert one.sum() == pytest.approx(w[inside].sum(), rel=1e-12)


@pytest.mark.parametrize("n_tables", [1, 2, 3])
def test_speckle_block_matches_naive_for_any_table_count(rng, n_tables):
    n_p, per_row = 4, 150
    ray_start = np.arange(2 * n_p + 1) * per_row
    ray_start[3:] -= 40  # an uneven row
    n = ray_start[-1]
    origin = np.array([512_000.0, 5_412_000.0, -20.0])
    pts = rng.uniform(-1, 1, (n, 3)) * [2, 2, 0.2]
    w = rng.uniform(0, 1, n)
    w[::9] = 0.0
    r = rng.uniform(10, 12, n)
    ext = rng.uniform(0, 0.05, n)
    pos = origin + rng.uniform(-1, 1, (n_p, 3)) + [0, 0, 10]
    table = np.exp(2j * np.pi * np.linspace(0, 1, 101)) * np.hanning(101)
    out = np.zeros((n_p, 2, 200), dtype=np.complex128)
    status = np.zeros(n_p, dtype=np.int64)
    rx = pos if n_tables != 2 else pos * [1.0, 1.0, -1.0] + [0.0, 0.0, 2.0 * (origin[2] + 15.0)]  # a surface image
    vel = np.zeros((n_p, 3)) if n_tables == 1 else rng.uniform(-0.1, 0.1, (n_p, 3))  # receiver moving on (per unit r)
    per_m = 2.5 if n_tables == 3 else 0.0              # 3: the moving receiver's own leg in the envelope too
    def speckle(tab, size, status, out):
        rx_each = np.ascontiguousarray(np.repeat(rx[:, None], 2, axis=1))  # one receiver per channel
        kernels.speckle_block(SpeckleEchoes(ray_start, pts, origin, w, r, ext, *NO_STRIPS),
                              PathEnds(pos, rx_each, vel, rx, per_m),
                              Lattice(7, 0.1, 0.00375, 4), Waveform(tab, -2.0, 10.0, 16.0, 533.3),
                              NodeTables(*_speckle_tables(n_tables, size)), status, out)

    speckle(table, 1 << 8, status, out)  # too small a table
    rays = ray_start[2::2] - ray_start[:-1:2]
    assert np.all(status <= -2) and np.all(-status - 2 < rays) and np.all(out == 0)  # says at which ray, writes nothing
    cap = synthesis.grown_capacity(1 << 8, status, ray_start)
    status[:] = 0
    speckle(table, cap, status, out)                    # grown once, from the rate the rays made nodes
    assert np.all(status == 1) and cap > 1 << 9, cap
    ref = naive.speckle_block(ray_start, pts + origin, w, r, ext, pos, 7, 0.1, 0.00375, 16.0, 533.3, 4, table,
                              -2.0, 10.0, np.zeros_like(out), pos_rx=rx, vel_rx=vel, time_per_m=per_m)
    assert np.abs(ref).max() > 0
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-11 * np.abs(ref).max())
    real_env = np.hanning(101) + 0j                      # a real envelope given as complex, and as reals (CW):
    same = [np.zeros_like(out) for _ in range(2)]        # WaveformTables passes the reals, for the same bits
    for tab, o in zip((real_env, np.ascontiguousarray(real_env.real)), same):
        speckle(tab, 1 << 12, np.zeros(n_p, dtype=np.int64), o)
    assert np.abs(same[0]).max() > 0 and np.array_equal(same[0].view(np.uint64), same[1].view(np.uint64))
    sonar, chain = se.Sonar().for_pulse(se.Pulse.cw()), se.SignalChain(speckle=True)
    assert synthesis.WaveformTables.build(sonar, se.Pulse.cw(), chain).table.dtype == np.float64


#: SpeckleEchoes' strips when there are none: every echo at its point.
NO_STRIPS = (np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), 0.0, 1.0, np.zeros(0, dtype=bool))


@pytest.mark.parametrize("n_tables", [1, 3])
def test_speckle_block_with_along_track_strips_matches_naive(rng, n_tables):
    """Echoes of a fan's lines spread over their strips (runs of one lattice cell taken together, the line's beam
    factor taken out and put back at every node) and a few aimed echoes left at their points, against the twin."""
    n_p, n_lines, n_el = 3, 5, 40
    origin = np.array([512_000.0, 5_412_000.0, -20.0])
    pos = origin + np.stack([0.3 * np.arange(n_p), np.zeros(n_p), np.full(n_p, 10.0)], axis=1)
    heading = np.array([np.cos(0.3), np.sin(0.3), 0.0])               # x̂ not along a lattice axis
    ds, s_lines = 0.02, 0.02 * (np.arange(n_lines) - 2)
    side = np.cross([0.0, 0.0, 1.0], heading)
    rows, pts, rng_m = [], [], []
    for b in range(n_p):
        for ch in range(2):
            y = (-1) ** ch * np.linspace(8.0, 12.0, n_el)                # across track, 10 cm apart
            p = (pos[b] - origin)[None, None] + s_lines[:, None, None] * 11.0 * heading + y[None, :, None] * side
            p[..., 2] = rng.uniform(-0.01, 0.01, p.shape[:2])             # a floor near z = 0 (local)
            pts.append(p.reshape(-1, 3))
            rows.append(pts[-1].shape[0])
    pts = np.concatenate(pts)
    ray_start = np.concatenate(([0], np.cumsum(rows))).astype(np.int64)
    n = pts.shape[0]
    ping = np.repeat(np.arange(2 * n_p) // 2, rows)
    r = np.linalg.norm(pts + origin - pos[ping], axis=1)
    w, ext = rng.uniform(0.5, 1, n), rng.uniform(0, 0.05, n)
    w[::17] = 0.0
    on = rng.uniform(size=n) > 0.1                                       # a tenth aimed: at their points
    grid = -0.08 + 0.0025 * np.arange(65)
    gain = np.repeat((np.sinc(grid / 0.05) ** 4)[None], 2 * n_p, axis=0)
    strips = (np.repeat(heading[None] * ds, 2 * n_p, axis=0), gain, np.sqrt(gain), -0.08, 0.0025, on)
    table = np.exp(2j * np.pi * np.linspace(0, 1, 101)) * np.hanning(101)
    out, status = np.zeros((n_p, 2, 400), dtype=np.complex128), np.zeros(n_p, dtype=np.int64)
    rx = np.ascontiguousarray(np.repeat(pos[:, None], 2, axis=1))
    kernels.speckle_block(SpeckleEchoes(ray_start, pts, origin, w, r, ext, *strips),
                          PathEnds(pos, rx, np.zeros((n_p, 3)), pos, 0.0), Lattice(7, 0.1, 0.00375, 4),
                          Waveform(table, -2.0, 10.0, 16.0, 533.3), NodeTables(*_speckle_tables(n_tables, 1 << 14)),
                          status, out)
    assert np.all(status == 1)
    ref = naive.speckle_block(ray_start, pts + origin, w, r, ext, pos, 7, 0.1, 0.00375, 16.0, 533.3, 4, table,
                              -2.0, 10.0, np.zeros_like(out), strips=strips)
    assert np.abs(ref).max() > 0
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    plain = naive.speckle_block(ray_start, pts + origin, w, r, ext, pos, 7, 0.1, 0.00375, 16.0, 533.3, 4, table,
                                -2.0, 10.0, np.zeros_like(out))
    assert np.abs(plain - ref).max() > 0.1 * np.abs(ref).max()          # the strips change the lattice


def _array_case(rng, n_p=3, n=600):
    """Echoes of ``n_p`` pings (two channels, ``n`` echoes) far from the origin, their transmitters and three
    receivers per channel moving during the ping: (n_p, ray_start, origin, points, w, r, ext, pos, receivers, vel)."""
    ray_start = np.linspace(0, n, 2 * n_p + 1).astype(np.int64)
    origin = np.array([512_000.0, 5_412_000.0, -20.0])
    pts = rng.uniform(-1, 1, (n, 3)) * [2, 2, 0.2]
    w, r, ext = rng.uniform(0, 1, n), rng.uniform(10, 12, n), rng.uniform(0, 0.05, n)
    pos = origin + rng.uniform(-1, 1, (n_p, 3)) + [0, 0, 10]
    receivers = pos[:, None, :] + rng.uniform(-0.3, 0.3, (n_p, 6, 3))
    return n_p, ray_start, origin, pts, w, r, ext, pos, receivers, rng.uniform(-0.1, 0.1, (n_p, 3))


def _array_strips(rng, n_p):
    """Strips for :func:`_array_case`: an along-track axis, and random two-way and receive tables of 41 samples."""
    axis = np.tile([0.05, 0.01, 0.0], (2 * n_p, 1))
    return axis, rng.uniform(0.2, 1.0, (2 * n_p, 41)), rng.uniform(0.2, 1.0, (2 * n_p, 41)), -1.0, 0.05, \
        np.zeros(0, dtype=bool)


def _array_across(rng, n_p):
    """Across-track axes (unit, random per row) and a random receive table of 81 samples on v ∈ [−1, 1]."""
    side = rng.normal(size=(2 * n_p, 3))
    return side / np.linalg.norm(side, axis=1, keepdims=True), rng.uniform(0.2, 1.0, 81), -1.0, 0.025


@pytest.mark.parametrize("n_tables, with_strips, with_across", [(1, False, False), (3, False, False),
                                                                (1, True, False), (1, False, True), (3, True, True)])
def test_speckle_block_with_receiver_arrays_matches_naive(rng, n_tables, with_strips, with_across):
    """Three receivers per channel, each on its own path and delay (docs/physics.md §18a), against the twin; with
    strips, each receiver's amplitude also takes the receive pattern at its own along-track cosine, with across
    axes at its own across-track cosine."""
    n_p, ray_start, origin, pts, w, r, ext, pos, receivers, vel = _array_case(rng)
    strips = _array_strips(rng, n_p) if with_strips else None
    across = _array_across(rng, n_p) if with_across else None
    table = np.exp(2j * np.pi * np.linspace(0, 1, 101)) * np.hanning(101)
    out, status = np.zeros((n_p, 6, 200), dtype=np.complex128), np.zeros(n_p, dtype=np.int64)
    kernels.speckle_block(SpeckleEchoes(ray_start, pts, origin, w, r, ext, *(strips or NO_STRIPS), *(across or ())),
                          PathEnds(pos, receivers, vel, pos, 2.5),
                          Lattice(7, 0.1, 0.00375, 4), Waveform(table, -2.0, 10.0, 16.0, 533.3),
                          NodeTables(*_speckle_tables(n_tables, 1 << (16 if with_strips else 12))), status, out)
    assert np.all(status == 1)
    ref = naive.speckle_block(ray_start, pts + origin, w, r, ext, pos, 7, 0.1, 0.00375, 16.0, 533.3, 4, table, -2.0,
                              10.0, np.zeros_like(out), vel_rx=vel, receivers=receivers, time_per_m=2.5, strips=strips,
                              across=across)
    assert np.abs(ref[:, 1]).max() > 0 and not np.allclose(ref[:, 0], ref[:, 1])   # the elements differ
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-11 * np.abs(ref).max())
    if with_across:                                                    # the across ratios change the record
        plain = naive.speckle_block(ray_start, pts + origin, w, r, ext, pos, 7, 0.1, 0.00375, 16.0, 533.3, 4, table,
                                    -2.0, 10.0, np.zeros_like(out), vel_rx=vel, receivers=receivers, time_per_m=2.5,
                                    strips=strips)
        assert np.abs(plain - ref).max() > 0.1 * np.abs(ref).max()


@pytest.mark.parametrize("n_tables, with_across", [(1, False), (3, False), (3, True)])
def test_speckle_block_shared_matches_naive(rng, n_tables, with_across):
    """Three receivers per channel from one draw of each node's scatterers: impulses on a grid of 1/8 sample, split
    linearly, each receiver at its own phase and delay, against the twin; with along-track strips, and across-track
    axes."""
    n_p, ray_start, origin, pts, w, r, ext, pos, receivers, vel = _array_case(rng)
    strips = _array_strips(rng, n_p)
    across = _array_across(rng, n_p) if with_across else None
    table = np.ones(3)                                             # not read: the shared kernel writes impulses
    out, status = np.zeros((n_p, 6, 8, 200), dtype=np.complex128), np.zeros(n_p, dtype=np.int64)
    kernels.speckle_block_shared(SpeckleEchoes(ray_start, pts, origin, w, r, ext, *strips, *(across or ())),
                                 PathEnds(pos, receivers, vel, pos, 2.5),
                                 Lattice(7, 0.1, 0.00375, 4), Waveform(table, -1.0, 1.0, 16.0, 0.0),
                                 NodeTables(*_speckle_tables(n_tables, 1 << 16)), status, out)
    assert np.all(status == 1)
    ref = naive.speckle_block_shared(ray_start, pts + origin, w, r, ext, pos, 7, 0.1, 0.00375, 16.0, 4,
                                     np.zeros_like(out), receivers, vel, 2.5, strips=strips, across=across)
    assert np.count_nonzero(ref) > 1000 and not np.allclose(ref[:, 0], ref[:, 1])   # the elements differ
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-11 * np.abs(ref).max())


def test_turn_is_the_unit_phasor_of_minus_two_pi_x(rng):
    """kernels.speckle.turn (fdlibm's polynomials after an exact reduction to the nearest quarter turn) against
    NumPy's e^(−j2πx) on [0, 1), the quarter turns and their neighbours included."""
    from numba import njit

    from sonar_embree.kernels.speckle import turn

    @njit
    def run(x, out):
        for i in range(x.shape[0]):
            out[i] = turn(x[i])

    q = np.arange(5) / 4
    x = np.concatenate([rng.uniform(0, 1, 200_000), q[:4], np.nextafter(q[1:], 0), np.nextafter(q[:4], 1)])
    out = np.empty(x.shape, dtype=np.complex128)
    run(x, out)
    assert np.abs(out - np.exp(-2j * np.pi * x)).max() < 1e-15


def test_sinc_rows_matches_libm_sin_over_x(rng):
    """kernels.sinc_rows (fdlibm's polynomials, vectorised) against NumPy's sin(x)/x: within 3 ulp, and within
    1e-21 of the sine near its zeros (the two-term reduction's residue of π/2), over the beams' argument range;
    sinc(0) = 1, even, and the entries beyond ``m`` or ``rows`` untouched."""
    from numba import njit

    @njit
    def run(a, rows, m):
        kernels.sinc_rows(a, rows, m)

    x = np.concatenate([rng.uniform(-hi, hi, 20000) for hi in (1e-7, 0.8, 4.0, 100.0, 1e4, 1e5)]
                       + [np.pi * np.arange(1, 3000), 0.5 * np.pi * np.arange(1, 3000), [0.0, 1e-300, 1e-8, -1e-8]])
    ref = np.ones_like(x)
    nz = x != 0
    ref[nz] = np.sin(x[nz]) / x[nz]
    a = np.stack([x, -x, np.full_like(x, 7.0)])
    run(a, 2, x.shape[0] - 1)
    err = np.abs(a[0] - ref)
    assert np.all(err[:-1] <= 3 * np.spacing(np.abs(ref[:-1])) + 1e-21 / np.maximum(np.abs(x[:-1]), 1.0))
    assert a[0, -4] == 1.0 and np.all(a[1, :-1] == a[0, :-1])             # sinc(0) = 1; even
    assert a[0, -1] == x[-1] and np.all(a[2] == 7.0)                      # beyond m and rows: untouched


def _aim_scene(rng):
    """A bumpy floor and three small objects abeam of poses near the origin."""
    import trimesh

    heights = rng.uniform(-0.2, 0.2, (21, 21))
    scene = se.Scene().add(se.seafloor.from_heights(heights, spacing_m=4.0, origin_m=(-40, -40)), label="seafloor")
    for i, (x, y, z) in enumerate([(0.1, -12.0, 2.0), (-0.1, 8.0, 0.3), (0.0, -20.0, 6.0)]):
        m = trimesh.creation.icosphere(2, radius=0.3) if i != 1 else trimesh.creation.box(extents=(0.4, 0.6, 0.5))
        m.apply_translation((x, y, z))
        scene.add(m, label=f"object{i}", material=se.Material(-12.0 - i))
    return scene


def test_aim_kernels_match_naive(rng):
    """The object-aimed rays (sonar_embree.propagation.aim): lattices, directions, echoes (kernels.fan_echoes with each
    ray's own layout, against the fan's naive twin per lattice, counting only hits on the lattice's own object) and the
    fan hits they replace."""
    from sonar_embree.propagation.aim import AimPlan, keep_own
    from sonar_embree.propagation.fan import FanPlan
    from sonar_embree.kernels import aim as K
    from sonar_embree.laws import apply_laws, law_table
    from sonar_embree.propagation.gain import weigh_by_beam
    from sonar_embree.raycast import RayCaster

    scene = _aim_scene(rng)
    c = scene.compiled()
    caster = RayCaster(c)
    from scipy.spatial.transform import Rotation

    # poses near the origin with small attitudes, so that the objects fall inside the narrow along-track span
    rot = Rotation.from_euler("zyx", rng.uniform(-0.01, 0.01, (6, 3))).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    pos = np.column_stack([rng.uniform(-0.1, 0.1, 6), rng.uniform(-0.5, 0.5, 6), np.full(6, 10.0)]) - c.origin_m
    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    plan = FanPlan.build(se.Acquisition.of(sonar), se.FanSettings())
    aim = AimPlan.build(c, plan, 1.0)
    span = aim.span.copy()
    span[4] = 50.0
    shift = rng.uniform(-3e-3, 3e-3, rot.shape[0])
    table = np.empty((2 * rot.shape[0], aim.objects.size, K.LATTICE_WIDTH))
    curved = span.copy()
    curved[7] = 3e-4                                  # a 0.45 s⁻¹ gradient at 1500 m/s: the cones widen
    for sp in (curved, span):                         # straight rays last: the rest of the test uses them
        K.aim_lattices(aim.centre, aim.radius, aim.cell_m, aim.cover, aim.cover_start, rot, pos, aim.sides, sp, shift,
                       aim.n_across, aim.dr_m, aim.max_rays, table)
        ref = naive.aim_lattices(aim.centre, aim.radius, rot, pos, aim.sides, sp, shift, aim.n_across, aim.dr_m,
                                 aim.max_rays)
        np.testing.assert_array_equal(table[..., K.NS] * table[..., K.NB], ref[..., 4] * ref[..., 5])
        lit = ref[..., 4] > 0
        np.testing.assert_allclose(table[lit][:, :4], ref[lit][:, :4], rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(table[..., K.NS] * table[..., K.NB], ref[..., 4] * ref[..., 5])
    lit = ref[..., 4] > 0
    assert lit.sum() >= 3 and not np.isfinite(aim.cell_m).any()         # compact objects: every cell cast
    np.testing.assert_allclose(table[lit][:, :4], ref[lit][:, :4], rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(table[..., K.NC], table[..., K.NS] * table[..., K.NB])

    counts = table[..., K.NC].astype(np.int64)
    start = np.concatenate(([0], np.cumsum(counts.ravel()))).astype(np.int64)
    n = int(start[-1])
    dirs, org, lay = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty((n, K.LAYOUT_WIDTH))
    K.aim_rays(table, start, rot, pos, np.zeros(0, np.uint8), dirs, org, lay)
    np.testing.assert_allclose(dirs, naive.aim_directions(table, rot), atol=1e-6)
    body = naive.aim_directions(table, np.tile(np.eye(3), (rot.shape[0], 1, 1)))   # (s, ±cψ cos β, cψ sin β)
    cpsi = np.sqrt(1 - lay[:, 0] ** 2)
    np.testing.assert_allclose(lay[:, 0], body[:, 0], rtol=1e-12, atol=1e-15)
    side = np.where(np.repeat(np.arange(table.shape[0]), counts.sum(axis=1)) % 2, 1.0, -1.0)
    np.testing.assert_allclose(side * lay[:, 1] * cpsi, body[:, 1], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(lay[:, 2] * cpsi, body[:, 2], rtol=1e-9, atol=1e-12)
    lattice = np.repeat(table.reshape(-1, K.LATTICE_WIDTH), counts.ravel(), axis=0)
    np.testing.assert_array_equal(lay[:, 3:], lattice[:, [K.HB, K.HS]])
    prim, tfar = caster.cast_raw(org, dirs, 50.0)

    out = [np.empty(n) for _ in range(5)]
    pts = np.empty((n, 3))
    fan = A.Fan(plan.s, plan.ds, np.zeros(0), np.zeros(0), np.zeros(0), start[::table.shape[1]])
    kernels.fan_echoes(fan, A.Poses(rot, pos, shift), prim, tfar, A.scene_arrays(c),
                       A.DirectWeighting(plan.tilt_rad, 0.02, plan.min_range_m, 50.0, plan.slope_cap_m_rad, 2 / 1500.0),
                       A.EchoOut(*out, pts), lay)
    weigh_by_beam(plan.pattern, plan.tilt_rad, fan, shift, out[3], lay)     # the beam after the kernel
    keep_own(c, aim, counts, prim, out[3], out[1], out[4])
    apply_laws(law_table(c.laws, sonar.frequency_hz), c, prim, out[4], out[3], pts)
    k_wave = 2 * np.pi / se.Acquisition.of(sonar).wavelength_m
    w_ref = np.zeros(n)
    r_ref = np.full(n, np.inf)
    for r in range(table.shape[0]):
        for j in range(table.shape[1]):
            a, b = start[r * table.shape[1] + j], start[r * table.shape[1] + j + 1]
            if a == b:
                continue
            s0, hs, b0, hb, ns, nb = table[r, j, :6]
            s = s0 + (np.arange(int(ns)) + 0.5) * hs
            beta = b0 + (np.arange(int(nb)) + 0.5) * hb
            el = np.array([0, int(nb), int(nb)] if r % 2 == 0 else [0, 0, int(nb)])
            p = r // 2
            rng_n, _, w_n = naive.fan_echoes(s, hs, beta, np.full(int(nb), hb), el, rot[p:p + 1], pos[p:p + 1],
                                             prim[a:b], c.vertices, c.faces, c.mu[c.face_object], k_wave,
                                             sonar.length_m, sonar.height_m, sonar.tilt_rad, 0.02, plan.min_range_m,
                                             50.0, plan.slope_cap_m_rad, rx_shift=shift[p:p + 1])
            own = (prim[a:b] >= 0) & (c.face_object[np.maximum(prim[a:b], 0)] == aim.objects[j])
            w_ref[a:b], r_ref[a:b] = np.where(own, w_n, 0.0), np.where(own & (w_n > 0), rng_n, np.inf)
    hit = w_ref > 0
    assert hit.sum() > 50
    np.testing.assert_array_equal(out[3] > 0, hit)
    np.testing.assert_allclose(out[3][hit], w_ref[hit], rtol=1e-9)
    np.testing.assert_allclose(out[0][hit], r_ref[hit], rtol=1e-12)
    assert ((prim >= 0) & ~hit).any()          # some rays hit something else first: they count nothing

    ray_start = np.array([0, 40, 90, 90, 200, 260, 300, 330, 400])
    fan_prim = rng.integers(-1, c.faces.shape[0], 400).astype(np.int32)
    aimed = rng.random((8, aim.objects.size)) < 0.6
    w = rng.random(400)
    got = w.copy()
    K.drop_aimed(ray_start, fan_prim, c.face_object, aim.cand_of_object, aimed, got)
    expect = naive.drop_aimed(ray_start, fan_prim, c.face_object, aim.cand_of_object, aimed, w)
    np.testing.assert_array_equal(got, expect)
    assert (got == 0).any() and (got > 0).any()


def _slender_scene():
    """A flat floor, a 2 cm cable 4 m long along track 12 m to starboard, another rising across it 9 m to port, a
    3 m × 2 cm flat strip 20 m to starboard and a 0.3 m ball (compact)."""
    import trimesh

    scene = se.Scene().add(se.seafloor.flat((80, 80)), label="seafloor")
    for name, (length, axis, centre) in {"along": (4.0, (1, 0, 0), (0.2, -12.0, 0.02)),
                                         "rising": (3.0, (1, -1, 0.3), (0.0, 9.0, 0.6))}.items():
        m = trimesh.creation.cylinder(radius=0.01, height=length, sections=16)
        m.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], np.asarray(axis, float)))
        scene.add(m.apply_translation(centre), label=name, material=se.Material(-10.0))
    scene.add(se.seafloor.flat((3.0, 0.02), center_m=(0.0, -20.0)), label="strip", material=se.Material(-10.0))
    return scene.add(trimesh.creation.icosphere(2, radius=0.3).apply_translation((0, -15, 1)), label="ball")


def test_slender_lattices_cover_and_rays_match_naive(rng):
    """Slender objects' lattices (finer cells, trimmed to their cover and refined to the width each row sees), their
    cell masks and the rays cast from them against plain NumPy; a ball stays compact (its lattice is the cone's)."""
    from scipy.spatial.transform import Rotation

    from sonar_embree.kernels import aim as K
    from sonar_embree.propagation.aim import SLENDER_RAYS, AimPlan, cover_masks
    from sonar_embree.propagation.fan import FanPlan

    c = _slender_scene().compiled()
    rot = Rotation.from_euler("zyx", rng.uniform(-0.01, 0.01, (5, 3))).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    pos = np.column_stack([rng.uniform(-0.3, 0.3, 5), rng.uniform(-0.5, 0.5, 5), np.full(5, 8.0)]) - c.origin_m
    plan = FanPlan.build(se.Acquisition.of(se.Sonar().for_pulse(se.Pulse.cw())), se.FanSettings())
    aim = AimPlan.build(c, plan, 1.0)
    assert np.isfinite(aim.cell_m).tolist() == [True, True, True, False]
    span = aim.span.copy()
    span[4] = 50.0
    shift = rng.uniform(-3e-3, 3e-3, rot.shape[0])
    table = np.empty((2 * rot.shape[0], aim.objects.size, K.LATTICE_WIDTH))
    K.aim_lattices(aim.centre, aim.radius, aim.cell_m, aim.cover, aim.cover_start, rot, pos, aim.sides, span, shift,
                   aim.n_across, aim.dr_m, aim.max_rays, table)
    ref = naive.aim_lattices(aim.centre, aim.radius, rot, pos, aim.sides, span, shift, aim.n_across, aim.dr_m,
                             aim.max_rays, (aim.cell_m, aim.cover, aim.cover_start, K.MAX_MASK_CELLS))
    np.testing.assert_array_equal(table[..., K.NS] * table[..., K.NB], ref[..., 4] * ref[..., 5])
    lit = ref[..., 4] > 0
    assert lit[:, :3].sum() >= 8 and lit[:, 3].sum() >= 2
    np.testing.assert_allclose(table[lit][:, :4], ref[lit][:, :4], rtol=1e-9, atol=1e-15)

    mask = cover_masks(aim, table, rot, pos)
    cells = naive.cover_cells(table, aim.cover, aim.cover_start, rot, pos, SLENDER_RAYS * aim.max_rays)
    marked = 0
    for r in range(table.shape[0]):
        for k in range(table.shape[1]):
            assert (table[r, k, K.MASK] >= 0) == (cells[r][k] is not None) and (k < 3 or cells[r][k] is None)
            if cells[r][k] is not None:
                off = int(table[r, k, K.MASK])
                np.testing.assert_array_equal(mask[off:off + cells[r][k].size].astype(bool), cells[r][k].ravel())
                assert table[r, k, K.NC] == cells[r][k].sum() < cells[r][k].size    # fewer rays than cells
                marked += cells[r][k].sum()
    assert marked > 100 and (table[:, :3, K.MASK] >= 0).sum() >= 8       # slender rows of all three
    counts = table[..., K.NC].astype(np.int64)
    start = np.concatenate(([0], np.cumsum(counts.ravel()))).astype(np.int64)
    dirs, org, lay = (np.empty((start[-1], w), t) for w, t in ((3, np.float32), (3, np.float32),
                                                              (K.LAYOUT_WIDTH, np.float64)))
    K.aim_rays(table, start, rot, pos, mask, dirs, org, lay)
    np.testing.assert_allclose(dirs, naive.aim_directions(table, rot, cells), atol=1e-6)


