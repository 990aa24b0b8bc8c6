"""Curved rays in a sound-speed profile (docs/physics.md §12) against an independent ray map.

The reference integrates Snell's ray integrals numerically over depth (x = ∫ cot θ dz,
L = ∫ dz / sin θ, T = ∫ dz / (c sin θ), cos θ = ξ·c(z)) for launch angles θ0, without the
simulator's closed-form arcs. Over a flat floor the expected intensity per launch cell is

    dI = Γ⁴(θ0, φ)·μ·e^(−2α'L)·cos²θ0 / (x·|∂x/∂θ0|) dθ0 dφ

(Lambert σ = μ sin²θh, floor area dA = x|∂x/∂θ0| dθ0 dφ, tube area per steradian
A_Ω = x|∂x/∂θ0| sin θh / cos θ0 both ways), with ∂x/∂θ0 by central differences here, and a
rectangular pulse τ sums it over 2T ∈ (t − τ, t].
"""
import numpy as np
import pytest

import analytic
import naive
import sonar_embree as se
from sonar_embree.propagation.fan import FanPlan
from sonar_embree.raycast.embree import EmbreeCaster
from sonar_embree.propagation.prepared import prepare
from sonar_embree.propagation.refraction import cast_refracted
from sonar_embree.sonars.sidescan import SideScanFrontEnd
from sonar_embree.kernels import args as A

H, DEPTH, C_SONAR, GRAD, MU_DB, TAU, FS, TILT, RANGE = 10.0, 20.0, 1500.0, 0.5, -20.0, 100e-6, 50e3, 10.0, 80.0


def _profile(gradient=GRAD):
    """c = C_SONAR at the sonar (depth DEPTH, z = H), the floor at z = 0 (depth DEPTH + H)."""
    return se.SoundSpeedProfile.linear(C_SONAR - gradient * DEPTH, gradient, depth_m=300.0, surface_z_m=H + DEPTH)


def _sonar(profile):
    return se.Acquisition(se.Sonar(tilt_deg=TILT, max_range_m=RANGE, sample_rate_hz=FS),
                          se.Environment(sound_speed=profile))


def _scene():
    return se.Scene().add(se.seafloor.flat((500.0, 300.0)), material=se.Material(backscatter_db=MU_DB),
                          label="seafloor")


def _record(profile, moving=False):
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2)     # 2 m/s; the references here are stop-and-hop
    line = line if moving else line.stop_and_hop()
    return se.simulate(_scene(), line, _sonar(profile), se.Pulse.cw(duration_s=TAU, taper=0.0),
                       start_time="2000-01-01")


def ray_map(theta0, gradient=GRAD, n=4001):
    """Horizontal distance x, path length L and one-way time T at the floor for launch angles θ0 (quadrature)."""
    z = np.linspace(0.0, H, n)                                       # depth below the sonar
    c = C_SONAR + gradient * z
    xi = np.cos(theta0)[:, None] / C_SONAR
    sin_t = np.sqrt(np.clip(1.0 - (xi * c) ** 2, 0.0, None))
    ok = sin_t[:, -1] > 1e-6                                          # reaches the floor
    sin_t = np.where(ok[:, None], sin_t, 1.0)
    # the integrands are smooth for rays that reach the floor: composite Simpson over depth
    w = np.full(n, 2.0)
    w[1::2], w[0], w[-1] = 4.0, 1.0, 1.0
    w *= (z[1] - z[0]) / 3.0
    x = (xi * c / sin_t) @ w
    L = (1.0 / sin_t) @ w
    T = (1.0 / (c * sin_t)) @ w
    nan = np.where(ok, 1.0, np.nan)
    return x * nan, L * nan, T * nan


def quadrature(t, alpha_db_m, gradient=GRAD):
    """Expected intensity at sample times t (s) of the flat floor under the profile (independent of the code)."""
    th = np.radians(np.concatenate([np.linspace(4.0, 30.0, 2601)[:-1], np.linspace(30.0, 89.99, 1200)]))
    x, L, T = ray_map(th, gradient)
    d = 1e-6
    dxd = (ray_map(th + d, gradient)[0] - ray_map(th - d, gradient)[0]) / (2 * d)
    ok = np.isfinite(x) & np.isfinite(dxd)
    th, x, L, T, dxd = th[ok], x[ok], L[ok], T[ok], dxd[ok]
    phi = np.unique(np.concatenate([np.linspace(-0.12, 0.12, 241), np.linspace(-np.pi / 2, np.pi / 2, 181)]))
    u_f = np.cos(th)[:, None] * np.sin(phi)[None]
    u_s = np.cos(th)[:, None] * np.cos(phi)[None]
    gamma = analytic.gamma_membrane(u_f, u_s, np.broadcast_to(np.sin(th)[:, None], u_f.shape), tilt_deg=TILT)
    alpha_np = alpha_db_m * np.log(10) / 10
    dens = (np.trapezoid(gamma ** 4, phi, axis=1) * 10 ** (MU_DB / 10) * np.exp(-2 * alpha_np * L)
            * np.cos(th) ** 2 / (x * np.abs(dxd)))
    order = np.argsort(2 * T)
    tt, g = 2 * T[order], dens[order]
    th_o = th[order]
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.abs(np.diff(th_o)))])

    def C(x_):
        return np.interp(x_, tt, cum, left=0.0, right=cum[-1])

    return C(t) - C(t - TAU)


@pytest.fixture(scope="module")
def records():
    return _record(_profile()), _record(None)


def test_first_arrival_per_launch_angle_against_the_ray_map():
    """Every boresight ray's echo lands where and when the quadrature ray map puts it (one sample, 1 cm)."""
    profile = _profile()
    sonar = _sonar(profile)
    front = SideScanFrontEnd(se.Acquisition.of(sonar), se.FanSettings())
    compiled = _scene().compiled(np.zeros(3))
    run = prepare(EmbreeCaster(compiled), front, sonar.frequency_hz, RANGE, 0)
    rot = se.Trajectory.line((0.0, 0.0, H), (1.0, 0.0, H), 2).rotations()[:1]
    pos = np.array([[0.0, 0.0, H]]) - compiled.origin_m
    blk = cast_refracted(run, front.plan, rot, pos, sonar.environment, front.two_way_np_per_m, RANGE, sonar,
                         True, {})
    plan = front.plan
    a0 = int(np.flatnonzero(plan.s == 0.0)[0])
    n_el = np.diff(blk.el_start)
    checked = 0
    for row in (0, 1):
        j = np.arange(n_el[row])
        rays = blk.ray_start[row] + a0 * n_el[row] + j
        beta = blk.beta[blk.el_start[row] + j]
        ok = blk.weight[rays] > 0
        x_ref, _, t_ref = ray_map(beta[ok])
        hit = blk.point_m[rays[ok]]
        np.testing.assert_allclose(blk.time_s[rays[ok]], 2 * t_ref, atol=1.0 / FS)
        np.testing.assert_allclose(np.hypot(hit[:, 0], hit[:, 1]), np.abs(x_ref), atol=0.01)  # β > 90°: past nadir
        checked += ok.sum()
    assert checked > 200
    # the nadir echo: T = ∫dz/c = ln(c_floor / c_sonar) / g; straight rays would arrive 2 samples later at 1500 m/s
    t_nadir = 2 * np.log((C_SONAR + GRAD * H) / C_SONAR) / GRAD
    assert abs(blk.time_s[blk.weight > 0].min() - t_nadir) < 0.5 / FS


def test_expected_intensity_matches_the_ray_map_quadrature(records):
    rec, straight = records
    t = rec.time_s
    ref = quadrature(t, rec.acquisition.alpha_db_per_m)
    sim = rec.starboard[0]
    onset = 2 * np.log((C_SONAR + GRAD * H) / C_SONAR) / GRAD
    keep = (ref > 1e-3 * ref.max()) & (np.abs(t - onset) > 2.0 / FS) & (np.abs(t - onset - TAU) > 2.0 / FS)
    keep &= t < 2 * RANGE / C_SONAR - 2 * TAU
    err = 10 * np.log10(sim[keep] / ref[keep])
    assert keep.sum() > 2500
    assert np.max(np.abs(err)) < 0.5, np.max(np.abs(err))
    # and the profile matters here: the straight-ray record misses the same reference by more than 0.5 dB
    off = 10 * np.log10(straight.starboard[0][keep] / ref[keep])
    assert np.max(np.abs(off)) > 1.0


def test_zero_gradient_profile_gives_todays_record_bit_for_bit(records):
    _, straight = records
    flat = se.SoundSpeedProfile((0.0, 100.0), (C_SONAR, C_SONAR))
    rec = _record(flat)
    assert np.array_equal(rec.data, straight.data)


# --- the kernels against their NumPy twins (tests/naive.py), in a three-layer profile of both signs ---
THREE = se.SoundSpeedProfile((0.0, 12.0, 20.0, 60.0), (1500.0, 1506.0, 1497.0, 1499.0), surface_z_m=24.0)
Z_SONAR, SLOPE, Z_CEILING = 14.0, np.radians(10.0), 22.5
# the sonar 10 m deep: rays cross the knots at 12 and 20 m on their way down to a floor tilted across track
# (its normal leans sideways: the footprint's azimuth term counts), or go up to a ceiling 1.5 m deep
FLOOR_N = np.array([0.0, np.sin(SLOPE), np.cos(SLOPE)])
CEILING_N = np.array([0.0, 0.0, -1.0])


def _planes_scene():
    import trimesh
    e1, e2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, np.cos(SLOPE), -np.sin(SLOPE)])
    quad = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    floor = trimesh.Trimesh(quad[:, :1] * 300 * e1 + quad[:, 1:] * 200 * e2, [[0, 1, 2], [0, 2, 3]], process=False)
    ceiling = trimesh.Trimesh(np.c_[quad * [300, 200], np.full(4, Z_CEILING)], [[0, 2, 1], [0, 3, 2]],
                              process=False)
    mat = se.Material(backscatter_db=MU_DB)
    return se.Scene().add(floor, material=mat, label="seafloor").add(ceiling, material=mat, label="ceiling")


@pytest.fixture(scope="module")
def three_layer_block():
    """One ping's fan in THREE between the tilted floor and the ceiling: the kernels' launch, hits and echoes."""
    from sonar_embree import kernels
    from sonar_embree.propagation.fan import probe_rows
    from sonar_embree.propagation.refraction import Buffers, Marching, march
    sonar = se.Acquisition(se.Sonar(tilt_deg=TILT, max_range_m=40.0, sample_rate_hz=FS),
                           se.Environment(sound_speed=THREE))
    front = SideScanFrontEnd(se.Acquisition.of(sonar), se.FanSettings())
    compiled = _planes_scene().compiled(np.zeros(3))
    caster = EmbreeCaster(compiled)
    rot = np.ascontiguousarray(se.Trajectory.line((0.0, 0.0, Z_SONAR), (1.0, 0.3, Z_SONAR), 2).rotations()[:1])
    pos = np.array([[0.0, 0.0, Z_SONAR]]) - compiled.origin_m
    el_start, beta, dbeta, _, _ = probe_rows(caster, front.plan, rot, pos, 45.0)
    n = front.plan.s.size * int(el_start[-1])
    layers, z0 = THREE.layers(), 24.0 - compiled.origin_m[2]
    state, lay, ray = np.empty((n, kernels.STATE_WIDTH)), np.empty(n, np.int64), np.empty((n, kernels.RAY_WIDTH))
    no_box = np.array([-np.inf, np.inf])  # the launch itself (march skips to the scene's heights)
    kernels.arc_start(front.plan.s, np.cos(beta), np.sin(beta), el_start, rot, pos, layers, z0, no_box, np.inf,
                      state, lay, ray, kernels.NO_LAYOUT)
    start = state.copy()
    t_max = 40.0 / se.Acquisition.of(sonar).sound_speed_m_s
    box = compiled.bounds_local[:, 2] + [-0.5, 0.5]
    hit_prim, hit, hit_len = march(caster, Marching(layers, z0, box, 0.02, t_max), state, lay, ray, {}, Buffers())
    lit = hit_prim >= 0                                       # the path length of each hit, also as float32
    assert lit.any() and np.all(np.isinf(hit_len[~lit]))
    np.testing.assert_array_equal(hit_len[lit], hit[lit, 7].astype(np.float32))
    return dict(front=front, sonar=sonar, caster=caster, rot=rot, pos=pos, el_start=el_start, beta=beta, dbeta=dbeta,
                layers=layers, z0=z0, start=start, ray=ray, hit_prim=hit_prim, hit=hit.copy(), t_max=t_max,
                face_object=compiled.face_object, origin=compiled.origin_m)


def _launch(b, s_az, beta_row, row):
    """World direction of the ray (s, β) of row ``row`` of the block's ping (fan axes as the kernels)."""
    side = 1.0 if row % 2 else -1.0
    c = np.sqrt(1 - s_az ** 2)
    return b["rot"][0] @ np.array([s_az, side * c * np.cos(beta_row), c * np.sin(beta_row)])


def _trace(b, u):
    """(landing point (3, local), one-way time, path, θ there, plane index) for launch direction u, by the twin."""
    sonar = b["pos"][0]
    depth0 = b["z0"] - sonar[2]
    hz = np.hypot(u[0], u[1])
    h = u[:2] / hz
    planes = []
    for n_, p_ in ((FLOOR_N, np.zeros(3)), (CEILING_N, np.array([0.0, 0.0, Z_CEILING]))):
        p_ = p_ - b["origin"]
        planes.append((n_[:2] @ h, n_[2], n_[:2] @ (sonar[:2] - p_[:2]) - n_[2] * p_[2]))
    out = naive.arc_trace(np.arcsin(-u[2]), depth0, hz / THREE.speed_at(depth0), b["layers"], planes, b["z0"])
    if out is None:
        return None
    w, x, d, L, T, th = out
    return np.r_[sonar[:2] + x * h, b["z0"] - d], T, L, th, w


def _sample(b, count=40, seed=3):
    """Rays (index, row, s, β, dβ) that hit something, spread over both sides."""
    plan, el = b["front"].plan, b["el_start"]
    rng = np.random.default_rng(seed)
    out = []
    for row in (0, 1):
        n_el = el[row + 1] - el[row]
        for _ in range(count // 2):
            a, j = rng.integers(plan.s.size), rng.integers(n_el)
            i = plan.s.size * el[row] + a * n_el + j
            if b["hit_prim"][i] >= 0:
                out.append((i, row, plan.s[a], b["beta"][el[row] + j], b["dbeta"][el[row] + j]))
    return out


def _tube(b, s_az, beta, row, normal, eps=1e-6):
    """Finite differences of the twin: A_Ω = cos θi·|∂X/∂s × ∂X/∂β| and |∂T/∂β| (s/rad)."""
    up, dn = _trace(b, _launch(b, s_az, beta + eps, row)), _trace(b, _launch(b, s_az, beta - eps, row))
    sp, sm = _trace(b, _launch(b, s_az + eps, beta, row)), _trace(b, _launch(b, s_az - eps, beta, row))
    cross = np.cross(sp[0] - sm[0], up[0] - dn[0]) / (2 * eps) ** 2
    ref = _trace(b, _launch(b, s_az, beta, row))
    t_hat = np.r_[np.cos(ref[3]) * (ref[0][:2] - b["pos"][0, :2]) / np.hypot(*(ref[0][:2] - b["pos"][0, :2])),
                  -np.sin(ref[3])]
    cos_i = -t_hat @ normal
    return cos_i * np.linalg.norm(cross), abs(up[1] - dn[1]) / (2 * eps), t_hat, cos_i


def test_arc_start_matches_its_twin(three_layer_block):
    b = three_layer_block
    ref = naive.arc_start(b["front"].plan.s, b["beta"], b["el_start"], b["rot"], b["pos"], b["layers"], b["z0"])
    from sonar_embree.kernels.refraction import S_CT, S_ST
    np.testing.assert_allclose(b["ray"][:, :2], ref["h"], atol=1e-12)
    np.testing.assert_allclose(b["ray"][:, 2], ref["xi"], rtol=1e-12)
    np.testing.assert_allclose(np.arctan2(b["start"][:, S_ST], b["start"][:, S_CT]), ref["theta"], atol=1e-12)
    np.testing.assert_allclose(b["ray"][:, 4], ref["c0"], rtol=1e-12)


def test_marching_matches_the_plain_trigonometry_tracer(three_layer_block):
    """arc_chord + arc_land (through refraction.march) against naive.arc_trace, down to the tilted floor through
    two knots and up to the ceiling: the hit point, time, path, grazing angle and the tube area
    A_Ω = X̃·|M|/c0² against cos θi·|∂X/∂s × ∂X/∂β| by finite differences."""
    b = three_layer_block
    rays = _sample(b)
    kinds = set()
    for i, row, s_az, beta, _ in rays:
        ref = _trace(b, _launch(b, s_az, beta, row))
        h = b["hit"][i]
        kinds.add(ref[4])
        # Newton stops when its step is below 1 µm: the hit is within that of the twin's (1 ns in time)
        np.testing.assert_allclose(h[:3], ref[0], atol=2e-6)
        assert abs(h[7] - ref[2]) < 2e-6 and abs(h[6] - ref[1]) < 2e-9
        assert h[10] == pytest.approx(np.sin(ref[3]), abs=1e-9)
        area = _tube(b, s_az, beta, row, FLOOR_N if ref[4] == 0 else CEILING_N)[0]
        assert h[8] * abs(h[9]) / b["ray"][i, 4] ** 2 == pytest.approx(area, rel=1e-5)
    assert len(rays) >= 24 and kinds == {0, 1}                     # floor and ceiling hits both checked


@pytest.mark.parametrize("delta", [0.0, 3e-3])
def test_arc_echoes_matches_its_twin(three_layer_block, delta):
    """Weights (the kernel's unit gain times the membrane the beam stage applies after it, against the twin that
    weighs the membrane itself), times and footprints of the sampled rays; the footprint's time span is |∂T/∂β|·dβ
    both ways; stop-and-hop and moving during the ping (the receive beam turned by δ = 2v/c)."""
    from sonar_embree import kernels
    from sonar_embree.propagation.gain import weigh_by_beam
    b, plan, s = three_layer_block, three_layer_block["front"].plan, three_layer_block["sonar"]
    n = b["hit"].shape[0]
    out = [np.empty(n) for _ in range(5)]
    c = b["caster"].compiled
    rx_shift = np.full(b["rot"].shape[0], delta)
    fan = A.Fan(plan.s, plan.ds, np.cos(b["beta"]), np.sin(b["beta"]), b["dbeta"], b["el_start"])
    acq = se.Acquisition.of(s)
    kernels.arc_echoes(fan, A.Poses(b["rot"], b["pos"], rx_shift), b["hit_prim"], b["hit"], b["ray"],
                       A.scene_arrays(c), A.ArcWeighting(plan.tilt_rad, b["front"].two_way_np_per_m, plan.min_range_m,
                                                         b["t_max"], plan.slope_cap_m_rad, acq.sound_speed_m_s),
                       A.EchoOut(*out, np.empty((0, 3))), kernels.NO_LAYOUT)
    weigh_by_beam(plan.pattern, plan.tilt_rad, fan, rx_shift, out[3])
    rng_k, t_k, ext_k, w_k, _ = out
    rays = _sample(b, seed=7)
    prim = np.full(n, -1, np.int32)
    area, shift, T, L = np.ones(n), np.zeros(n), np.zeros(n), np.zeros(n)
    direction, c_hit = np.zeros((n, 3)), np.full(n, 1500.0)
    for i, row, s_az, beta, _ in rays:
        ref = _trace(b, _launch(b, s_az, beta, row))
        normal = FLOOR_N if ref[4] == 0 else CEILING_N
        area[i], dtdb, direction[i], cos_i = _tube(b, s_az, beta, row, normal)
        c_hit[i] = THREE.speed_at(b["z0"] - ref[0][2])
        shift[i] = dtdb * c_hit[i] * cos_i                                 # |n̂·δ⊥| = |∂T/∂β|·c·cos θi
        prim[i], T[i], L[i] = b["hit_prim"][i], ref[1], ref[2]
    acq = se.Acquisition.of(s)
    w, t, ext, rr = naive.arc_echoes(plan.s, plan.ds, b["beta"], b["dbeta"], b["el_start"], b["rot"], prim, None,
                                     direction, T, L, area, shift, c_hit, c.face_normals, acq.wavenumber_rad_m,
                                     s.length_m, s.height_m, s.tilt_rad, b["front"].two_way_np_per_m,
                                     plan.min_range_m, b["t_max"], plan.slope_cap_m_rad, acq.sound_speed_m_s,
                                     rx_shift)
    idx = np.array([r[0] for r in rays])
    lit = w[idx] > 0
    assert lit.sum() >= 10
    np.testing.assert_allclose(w_k[idx], w[idx], rtol=1e-4)
    np.testing.assert_allclose(t_k[idx][lit], t[idx][lit], atol=4e-9)        # the hits agree to 1 µm (above)
    np.testing.assert_allclose(rng_k[idx][lit], rr[idx][lit], atol=4e-6)
    np.testing.assert_allclose(ext_k[idx], ext[idx], rtol=1e-4, atol=1e-12)


def test_turn_series_meets_the_trigonometry():
    """The chord offsets use series of sin u/u and (1 − cos u)/u below SERIES_MAX_U: both sides of the switch."""
    from sonar_embree.kernels.refraction import SERIES_MAX_U, _turn
    for u in (1e-9, 1e-3, 0.9 * SERIES_MAX_U, 0.999 * SERIES_MAX_U, 1.001 * SERIES_MAX_U, 0.3):
        th, ds = 0.4, 7.0
        kap = u / ds
        got = _turn(np.cos(th), np.sin(th), kap, ds)
        tb = th - u
        half = 2 * np.sin(u / 2) / kap   # sin a − sin b = 2 cos((a+b)/2) sin((a−b)/2), free of cancellation
        want = (half * np.cos((th + tb) / 2), half * np.sin((th + tb) / 2), np.cos(tb), np.sin(tb))
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-15)


# --- set-up: TOML, CSV, record files, errors, and nothing run without a profile ---
def test_profile_from_toml_inline_and_from_a_csv_next_to_the_config(tmp_path):
    from sonar_embree.runs import runconfig
    from conftest import write_anchor_config as _write
    env = "sound_speed = { depth_m = [0.0, 50.0], speed_m_s = [1500.0, 1525.0], surface_z_m = 40.0 }\n"
    p = runconfig.load_run_config(_write(tmp_path, env=env)).environment.sound_speed
    assert (p.depth_m, p.speed_m_s, p.surface_z_m) == ((0.0, 50.0), (1500.0, 1525.0), 40.0)
    (tmp_path / "ctd.csv").write_text("depth_m,speed_m_s\n0,1500\n10,1502.5\n80,1490\n")
    env = "sound_speed = { csv = \"ctd.csv\", surface_z_m = 40.0 }\n"
    p = runconfig.load_run_config(_write(tmp_path, env=env)).environment.sound_speed
    assert p.speed_m_s == (1500.0, 1502.5, 1490.0) and p.surface_z_m == 40.0
    with pytest.raises(se.ConfigError, match="unknown key 'gradient'"):
        runconfig.load_run_config(_write(tmp_path, env="sound_speed = { gradient = 0.5 }\n"))
    with pytest.raises(se.ConfigError, match="give 'csv' or 'depth_m'"):
        runconfig.load_run_config(_write(tmp_path, env="sound_speed = { csv = \"ctd.csv\", depth_m = [0.0] }\n"))


def test_profile_survives_the_record_file(tmp_path):
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2)
    rec = se.simulate(_scene(), line, se.Acquisition(se.Sonar(max_range_m=20.0),
                                                     se.Environment(sound_speed=_profile())),
                      start_time="2000-01-01")
    rec.save(tmp_path / "r.npz")
    back = se.Record.load(tmp_path / "r.npz").environment.sound_speed
    assert (back.depth_m, back.speed_m_s, back.surface_z_m) == (_profile().depth_m, _profile().speed_m_s, H + DEPTH)


def test_profile_errors_name_the_problem():
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2)
    bent = se.SoundSpeedProfile.linear(1500.0, 0.5)
    with pytest.raises(se.ConfigError, match="depth 0 needs a height"):
        se.Environment(sound_speed=bent)
    with pytest.raises(se.ConfigError, match="uniform sound_speed profile at 1490 m/s disagrees"):
        se.Environment(sound_speed=se.SoundSpeedProfile((0.0,), (1490.0,)))
    with pytest.raises(se.ConfigError, match="surface_z_m must be finite"):
        se.SoundSpeedProfile((0.0,), (1490.0,), surface_z_m=float("inf"))
    env = se.Environment(sound_speed=_profile())
    with pytest.raises(se.ConfigError, match="labels assume straight rays"):
        se.simulate(_scene(), line, se.Acquisition(se.Sonar(max_range_m=20.0), env), start_time="2000-01-01",
                    labels=True)
    shallow = se.Environment(sound_speed=se.SoundSpeedProfile.linear(1500.0, 0.5, surface_z_m=H - 1.0))
    with pytest.raises(se.ConfigError, match="above the sound-speed profile's depth 0"):
        se.simulate(_scene(), line, se.Acquisition(se.Sonar(max_range_m=20.0), shallow), start_time="2000-01-01")
    assert se.simulate(_scene(), line, se.Acquisition(se.EchoSounder(), env), start_time="2000-01-01").data.max() > 0


def test_no_profile_runs_no_refraction_code(monkeypatch):
    from sonar_embree.propagation import refraction
    monkeypatch.setattr(refraction, "cast_refracted", lambda *a, **k: pytest.fail("refraction ran without a profile"))
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2)
    se.simulate(_scene(), line, se.Sonar(max_range_m=20.0), start_time="2000-01-01")
    flat = se.Environment(sound_speed=se.SoundSpeedProfile((0.0, 100.0), (1500.0, 1500.0)))
    se.simulate(_scene(), line, se.Acquisition(se.Sonar(max_range_m=20.0), flat), start_time="2000-01-01")


def test_speckle_in_a_profile_averages_to_the_expected_record(records):
    """Speckle takes the curved echoes' times for its envelopes (phases from straight distances): the mean
    speckled intensity over pings 0.2 m apart is the expected record of the same profile."""
    line = se.Trajectory.line((-3.0, 0.0, H), (3.0, 0.0, H), 31).stop_and_hop()
    rec = se.simulate(_scene(), line, _sonar(_profile()), se.Pulse.cw(duration_s=TAU, taper=0.0), speckle=True,
                      seed=3, start_time="2000-01-01")
    want = records[0].starboard.mean(axis=0)
    r_eq = rec.slant_range_m
    for lo, hi in ((12.0, 20.0), (20.0, 35.0), (35.0, 60.0)):
        w = (r_eq > lo) & (r_eq < hi)
        assert 10 * np.log10(rec.starboard[:, w].mean() / want[w].mean()) == pytest.approx(0.0, abs=0.3)


def test_curved_rays_move_during_the_ping_too():
    """In the profile, moving at 2 m/s costs the flat floor the same beam overlap as with straight rays
    (docs/physics.md §16: the horizontal slowness is conserved, so δ ≈ 2v/c0): the moving/still ratio against
    10·log10(∫Γ²(u)Γ²(u − δ)du / ∫Γ⁴(u)du) by quadrature, within 0.03 dB."""
    still, moving = _record(_profile()), _record(_profile(), moving=True)
    assert moving.attrs["motion_during_ping"] and not still.attrs["motion_during_ping"]
    s = still.sonar
    acq = se.Acquisition.of(s)
    a, delta = np.pi * s.frequency_hz * s.length_m / acq.sound_speed_m_s, 2 * 2.0 / acq.sound_speed_m_s
    u = np.linspace(-40 / a, 40 / a, 400_001)
    gamma = np.sinc(a * u / np.pi) ** 2
    want_db = 10 * np.log10(np.trapezoid(gamma * np.sinc(a * (u - delta) / np.pi) ** 2, u) / np.trapezoid(gamma ** 2, u))
    assert want_db < -0.1
    band = (still.slant_range_m > 15.0) & (still.slant_range_m < 70.0) & (still.starboard.min(axis=0) > 0)
    assert band.sum() > 100
    got_db = 10 * np.log10(moving.starboard[:, band] / still.starboard[:, band])
    np.testing.assert_allclose(got_db, want_db, atol=0.03)


def test_segment_turn_angle_series_matches_arctan2():
    """kernels.refraction._angle (a layer segment's turn θ − θb without the library call where it is small)
    against NumPy's arctan2, on both sides of the series' limit and in every quadrant."""
    from sonar_embree.kernels import refraction as kr

    rng = np.random.default_rng(7)
    y = np.concatenate([rng.uniform(-0.05, 0.05, 500), rng.uniform(-3.0, 3.0, 500), [0.0, 1e-300, -1e-12]])
    x = np.concatenate([rng.uniform(0.9, 1.0, 500), rng.uniform(-1.0, 1.0, 500), [1.0, 1.0, 1.0]])
    got = np.array([kr._angle(a, b) for a, b in zip(y, x)])
    np.testing.assert_allclose(got, np.arctan2(y, x), rtol=1e-14, atol=1e-300)
    assert np.sum(np.abs(y) < kr.SERIES_MAX_U * x) > 400                # the series branch is exercised


def test_arc_kernels_with_each_rays_own_layout_give_the_fans_bits(three_layer_block):
    """arc_start and arc_echoes with a per-ray layout (the curved rays aimed at objects, docs/physics.md §7b): the
    block's own fan written ray by ray (s, cos β, sin β, dβ, ds) gives the launch state and echoes of the fan's
    layout to the bit (which test_arc_start_matches_its_twin and test_arc_echoes_matches_its_twin check)."""
    from sonar_embree import kernels
    b, plan, s = three_layer_block, three_layer_block["front"].plan, three_layer_block["sonar"]
    el, n_az = b["el_start"], plan.s.size
    n = n_az * int(el[-1])
    row = np.repeat(np.arange(el.size - 1), n_az * np.diff(el))
    j = np.arange(n) - n_az * el[row]
    cell = el[row] + j % np.diff(el)[row]
    layout = np.column_stack([plan.s[j // np.diff(el)[row]], np.cos(b["beta"][cell]), np.sin(b["beta"][cell]),
                              b["dbeta"][cell], np.full(n, plan.ds)])
    no_box = np.array([-np.inf, np.inf])
    state, lay, ray = np.empty((n, kernels.STATE_WIDTH)), np.empty(n, np.int64), np.empty((n, kernels.RAY_WIDTH))
    kernels.arc_start(plan.s, np.zeros(0), np.zeros(0), n_az * el, b["rot"], b["pos"], b["layers"], b["z0"], no_box,
                      np.inf, state, lay, ray, layout)
    np.testing.assert_array_equal(state, b["start"])
    np.testing.assert_array_equal(ray, b["ray"])
    c = b["caster"].compiled
    args = (A.Poses(b["rot"], b["pos"], np.full(1, 2e-3)), b["hit_prim"], b["hit"], b["ray"], A.scene_arrays(c),
            A.ArcWeighting(plan.tilt_rad, b["front"].two_way_np_per_m, plan.min_range_m, b["t_max"],
                           plan.slope_cap_m_rad, se.Acquisition.of(s).sound_speed_m_s))
    fan, per_ray = [np.empty(n) for _ in range(5)], [np.empty(n) for _ in range(5)]
    kernels.arc_echoes(A.Fan(plan.s, plan.ds, np.cos(b["beta"]), np.sin(b["beta"]), b["dbeta"], el), *args,
                       A.EchoOut(*fan, np.empty((0, 3))), kernels.NO_LAYOUT)
    kernels.arc_echoes(A.Fan(plan.s, plan.ds, np.zeros(0), np.zeros(0), np.zeros(0), n_az * el), *args,
                       A.EchoOut(*per_ray, np.empty((0, 3))), layout)
    for x, y in zip(fan, per_ray):
        np.testing.assert_array_equal(x, y)
    assert np.count_nonzero(fan[3]) > 50
