"""A flat sea surface over a sound-speed profile (docs/physics.md §12b) against an independent ray-map quadrature.

The reference integrates Snell's ray integrals numerically over depth (x = ∫ cot θ dz, L = ∫ dz / sin θ,
T = ∫ dz / (c sin θ), cos θ = ξ·c(z)) for launch angles θ at the sonar: the direct ray down to the floor, and
the surface ray up to the surface and down to the floor (the image source in the mirrored profile), without the
simulator's closed forms or its eigenray search. Over a flat Lambert floor (σ = μ·cos θi·cos θs, θ from the
vertical), per direct launch cell dθ₁ dφ (floor area dA = x|∂x₁/∂θ₁| dθ₁ dφ, tube areas A = x|∂x/∂θ| sin θ_h / cos θ):

    direct:       Γ⁴(u₁)·μ·e^(−2α'L₁)·cos²θ₁ / (x₁|∂x₁/∂θ₁|)                 at 2T₁,
    one bounce:   2Γ²(u₁)Γ²(u₂)·μ·e^(−α'(L₁ + L₂))·cos θ₁·cos θ₂ / (x|∂x₂/∂θ₂|)   at T₁ + T₂ (θ₂ where x₂ = x₁),
    two bounces:  Γ⁴(u₂)·μ·e^(−2α'L₂)·cos²θ₂ / (x₂|∂x₂/∂θ₂|) per dθ₂ dφ          at 2T₂,

with u₁ = (cos θ₁ sin φ, cos θ₁ cos φ, sin θ₁) and u₂ = (cos θ₂ sin φ, cos θ₂ cos φ, −sin θ₂) (forward, outboard,
down; a mirror surface, |R| = 1), and a rectangular pulse τ sums each over its arrival time in (t − τ, t].
"""
import numpy as np
import pytest

import analytic
import sonar_embree as se
from sonar_embree.propagation import curved_surface

H, DEPTH, C_SONAR, GRAD, MU_DB, TAU, FS, TILT, RANGE = 10.0, 20.0, 1500.0, 0.5, -20.0, 100e-6, 50e3, 10.0, 80.0


def _profile():
    return se.SoundSpeedProfile.linear(C_SONAR - GRAD * DEPTH, GRAD, depth_m=300.0, surface_z_m=H + DEPTH)


def _record(surface=True, profile=True):
    env = se.Environment(sound_speed=_profile() if profile else None,
                         surface=se.SeaSurface(z_m=H + DEPTH) if surface else None)
    sonar = se.Acquisition(se.Sonar(tilt_deg=TILT, max_range_m=RANGE, sample_rate_hz=FS), env)
    scene = se.Scene().add(se.seafloor.flat((500.0, 300.0)), material=se.Material(backscatter_db=MU_DB),
                           label="seafloor")
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2).stop_and_hop()
    return se.simulate(scene, line, sonar, se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")


def _speed(depth):
    return C_SONAR + GRAD * (depth - DEPTH)


def _simpson(d0, d1, f, n=2001):
    """∫ f(d) dd from d0 to d1 (composite Simpson, f of (rays, n) depths)."""
    d = np.linspace(d0, d1, n)
    w = np.full(n, 2.0)
    w[1::2], w[0], w[-1] = 4.0, 1.0, 1.0
    return f(d[None, :]) @ (w * (d1 - d0) / (3.0 * (n - 1)))


def _integrals(xi, d0, d1):
    """(x, L, T) of rays of invariant ξ (rays, 1) between depths d0 and d1, NaN where one turns."""
    def sin_t(d):
        return np.sqrt(np.clip(1.0 - (xi * _speed(d)) ** 2, 1e-300, None))
    ok = (xi[:, 0] * _speed(max(d0, d1)) < 1.0) & (xi[:, 0] * _speed(min(d0, d1)) < 1.0)
    x = _simpson(d0, d1, lambda d: xi * _speed(d) / sin_t(d))
    L = _simpson(d0, d1, lambda d: 1.0 / sin_t(d))
    T = _simpson(d0, d1, lambda d: 1.0 / (_speed(d) * sin_t(d)))
    nan = np.where(ok, 1.0, np.nan)
    return x * nan, L * nan, T * nan


def direct_map(theta):
    """(x, L, T) at the floor of rays launched θ below the horizontal."""
    return _integrals(np.cos(theta)[:, None] / C_SONAR, DEPTH, DEPTH + H)


def surface_map(theta):
    """(x, L, T) at the floor of rays launched θ above the horizontal, turned down by the surface."""
    xi = np.cos(theta)[:, None] / C_SONAR
    up, down = _integrals(xi, 0.0, DEPTH), _integrals(xi, 0.0, DEPTH + H)
    return tuple(a + b for a, b in zip(up, down))


def _dx(fmap, theta, d=1e-6):
    return (fmap(theta + d)[0] - fmap(theta - d)[0]) / (2 * d)


PHI = np.unique(np.concatenate([np.linspace(-0.12, 0.12, 241), np.linspace(-np.pi / 2, np.pi / 2, 181)]))


def _gamma(theta, up):
    c = np.cos(theta)[:, None]
    down = np.broadcast_to((-1.0 if up else 1.0) * np.sin(theta)[:, None], (len(theta), PHI.size))
    return analytic.gamma_membrane(c * np.sin(PHI)[None], c * np.cos(PHI)[None], down, tilt_deg=TILT)


def _windowed(t, times, dens, theta):
    """Σ over the cells of dens·dθ whose arrival lies in (t − τ, t] (dens (cells,) per radian at ``times``)."""
    order = np.argsort(times)
    tt, g, th = times[order], dens[order], theta[order]
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.abs(np.diff(th)))])
    def C(x):
        return np.interp(x, tt, cum, left=0.0, right=cum[-1])
    return C(t) - C(t - TAU)


def quadrature(t, alpha_db_m):
    """(direct, one bounce, two bounces) expected intensity at sample times t (s)."""
    mu, alpha = 10 ** (MU_DB / 10), alpha_db_m * np.log(10) / 10
    th = np.radians(np.concatenate([np.linspace(3.0, 30.0, 2701)[:-1], np.linspace(30.0, 89.99, 1500)]))
    x1, L1, T1 = direct_map(th)
    dx1 = _dx(direct_map, th)
    th2 = np.radians(np.concatenate([np.linspace(1.0, 30.0, 2901)[:-1], np.linspace(30.0, 89.99, 1500)]))
    x2, L2, T2 = surface_map(th2)
    dx2 = _dx(surface_map, th2)
    g1, g2 = _gamma(th, False), _gamma(th2, True)
    direct = (np.trapezoid(g1 ** 4, PHI, axis=1) * mu * np.exp(-2 * alpha * L1) * np.cos(th) ** 2 / (x1 * np.abs(dx1)))
    two = (np.trapezoid(g2 ** 4, PHI, axis=1) * mu * np.exp(-2 * alpha * L2) * np.cos(th2) ** 2 / (x2 * np.abs(dx2)))
    ok2 = np.isfinite(x2) & np.isfinite(dx2)
    order = np.argsort(x2[ok2])                                   # the surface ray that meets each direct hit
    at = lambda a: np.interp(x1, x2[ok2][order], a[ok2][order], left=np.nan, right=np.nan)  # noqa: E731
    th_s, L_s, T_s, dx_s = at(th2), at(L2), at(T2), at(np.abs(dx2))
    g_s = _gamma(np.nan_to_num(th_s), True)
    one = (2 * np.trapezoid(g1 ** 2 * g_s ** 2, PHI, axis=1) * mu * np.exp(-alpha * (L1 + L_s)) * np.cos(th)
           * np.cos(th_s) / (x1 * dx_s))
    ok1, okm = np.isfinite(direct), np.isfinite(one)
    return (_windowed(t, 2 * T1[ok1], direct[ok1], th[ok1]), _windowed(t, (T1 + T_s)[okm], one[okm], th[okm]),
            _windowed(t, 2 * T2[ok2], two[ok2], th2[ok2]))


@pytest.fixture(scope="module")
def records():
    return _record(), _record(surface=False), _record(profile=False)


def test_surface_paths_in_a_profile_match_the_ray_map_quadrature(records):
    """Levels within 0.5 dB sample by sample wherever the paths' sum is within 30 dB of its peak (a sample from each
    path's onset and end left out), and the one-bounce onset within one sample; the surface's paths matter there
    (the direct path alone is off by more than 1 dB) and so does the profile (straight rays under the same surface
    are off by more than 1 dB)."""
    wet, dry, straight = records
    t = wet.time_s
    direct, one, two = quadrature(t, wet.acquisition.alpha_db_per_m)
    ref = direct + one + two
    sim = wet.starboard[0]
    edges = [2 * np.log(_speed(DEPTH + H) / C_SONAR) / GRAD]          # the direct onset (vertical ray)
    for part in (one, two):
        edges.append(t[np.argmax(part > 1e-3 * part.max())])
    keep = (ref > 1e-3 * ref.max()) & (t < 2 * RANGE / C_SONAR - 2 * TAU)
    for e in edges:
        keep &= (np.abs(t - e) > 2.0 / FS) & (np.abs(t - e - TAU) > 2.0 / FS)
    err = 10 * np.log10(sim[keep] / ref[keep])
    assert keep.sum() > 2000
    assert np.max(np.abs(err)) < 0.5, np.max(np.abs(err))                # measured: 0.023 dB
    added = sim - dry.starboard[0]
    onset_sim = t[np.argmax(added > 1e-3 * (one + two).max())]
    onset_ref = t[np.argmax(one + two > 1e-3 * (one + two).max())]
    assert abs(onset_sim - onset_ref) <= 1.0 / FS
    for other in (dry, straight):
        off = 10 * np.log10(other.starboard[0][keep] / ref[keep])
        assert np.max(np.abs(off)) > 1.0, np.max(np.abs(off))


def test_each_surface_path_starts_within_a_sample_of_the_quadrature(records, monkeypatch):
    """The one- and the two-bounce path alone (the other's echoes weighed zero), each against its own quadrature:
    the first sample above 10⁻³ of its peak within one sample, and its level within 0.5 dB over its 30 dB."""
    wet, dry, _ = records
    t = wet.time_s
    _, one, two = quadrature(t, wet.acquisition.alpha_db_per_m)
    for keep, ref in (("mixed_echoes", one), ("image_echoes", two)):
        drop = "image_echoes" if keep == "mixed_echoes" else "mixed_echoes"
        real = getattr(curved_surface, drop)

        def silenced(*a, real=real, **k):
            out = real(*a, **k)
            e = out[0] if isinstance(out, tuple) else out
            e.weight[:] = 0.0
            return out
        monkeypatch.setattr(curved_surface, drop, silenced)
        path = _record().starboard[0] - dry.starboard[0]
        monkeypatch.undo()
        first = t[np.argmax(path > 1e-3 * ref.max())]
        assert abs(first - t[np.argmax(ref > 1e-3 * ref.max())]) <= 1.0 / FS, keep
        lit = (ref > 1e-3 * ref.max()) & (t < 2 * RANGE / C_SONAR - 2 * TAU)
        lit &= np.abs(t - first) > 2.0 / FS
        assert lit.sum() > 500
        assert np.max(np.abs(10 * np.log10(path[lit] / ref[lit]))) < 0.5, keep


def test_surface_eigenrays_against_the_ray_integrals():
    """surface_eigenrays on a profile with a zero-gradient, a falling and a rising layer: the ray it finds covers
    the horizontal distance asked for, and its time, path length, surface point and tube area A₂ equal the ray
    integrals of the same launch angle (Simpson over depth, ∂x/∂θ by central differences), A₂ = x|∂x/∂θ₀|·sin θ_P /
    cos θ₀; A₂ = R² with a uniform profile; a point no unturned ray reaches has none (NaN)."""
    depth, speed = (0.0, 10.0, 30.0, 200.0), (1500.0, 1500.0, 1490.0, 1530.0)
    prof = se.SoundSpeedProfile(depth, speed)

    def c_at(d):
        return np.interp(d, depth, speed)

    def leg(xi, d1, n=40001):
        d = np.linspace(0.0, d1, n)
        s = np.sqrt(1.0 - (xi * c_at(d)) ** 2)
        w = np.full(n, 2.0)
        w[1::2], w[0], w[-1] = 4.0, 1.0, 1.0
        w *= d1 / (3.0 * (n - 1))
        return (xi * c_at(d) / s) @ w, (1.0 / s) @ w, (1.0 / (c_at(d) * s)) @ w

    d_src, d_dst = np.array([25.0, 25.0, 5.0]), np.array([60.0, 60.0, 45.0])
    x = np.array([0.0, 40.0, 120.0])
    ray = curved_surface.surface_eigenrays(prof, d_src, d_dst, x)
    for k in range(3):
        c0 = c_at(d_src[k])
        th0 = np.arccos(ray.xi[k] * c0)

        def total(th):
            xi = np.cos(th) / c0
            up, down = leg(xi, d_src[k]), leg(xi, d_dst[k])
            return up[0] + down[0], up[1] + down[1], up[2] + down[2], up[0]
        xs, ls, ts, xu = total(th0)
        assert xs == pytest.approx(x[k], abs=1e-6)
        assert ray.time_s[k] == pytest.approx(ts, rel=1e-9) and ray.path_m[k] == pytest.approx(ls, rel=1e-9)
        assert ray.x_up_m[k] == pytest.approx(xu, abs=1e-6)
        if x[k] > 0:
            d = 1e-6
            dxdth = (total(th0 + d)[0] - total(th0 - d)[0]) / (2 * d)
            sin_p = np.sqrt(1.0 - (ray.xi[k] * c_at(d_dst[k])) ** 2)
            assert ray.spread_m2[k] == pytest.approx(xs * abs(dxdth) * sin_p / np.cos(th0), rel=1e-6)
    flat = curved_surface.surface_eigenrays(se.SoundSpeedProfile((0.0, 100.0), (1500.0, 1500.0)), d_src, d_dst, x)
    np.testing.assert_allclose(flat.spread_m2, x ** 2 + (d_src + d_dst) ** 2, rtol=1e-9)
    np.testing.assert_allclose(flat.time_s, np.hypot(x, d_src + d_dst) / 1500.0, rtol=1e-10)
    far = curved_surface.surface_eigenrays(prof, np.array([5.0]), np.array([150.0]), np.array([1e5]))
    assert np.isnan(far.time_s[0])


def test_an_object_above_the_sonar_blocks_the_surface_paths():
    """A plate between the sonar and the surface, over the whole floor: every path to the surface is blocked (its
    chords are checked), so the record equals that without a surface, bit for bit."""
    def record(surface):
        env = se.Environment(sound_speed=_profile(), surface=se.SeaSurface(z_m=H + DEPTH) if surface else None)
        sonar = se.Acquisition(se.Sonar(tilt_deg=TILT, max_range_m=60.0, sample_rate_hz=FS), env)
        plate = se.seafloor.flat((500.0, 300.0))
        plate.apply_translation((0.0, 0.0, H + 5.0))
        scene = (se.Scene().add(se.seafloor.flat((500.0, 300.0)), material=se.Material(backscatter_db=MU_DB),
                                label="seafloor")
                 .add(plate, material=se.Material(backscatter_db=MU_DB), label="plate"))
        line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2).stop_and_hop()
        return se.simulate(scene, line, sonar, se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")
    wet, dry = record(True), record(False)
    assert dry.data.max() > 0
    np.testing.assert_array_equal(wet.data, dry.data)


@pytest.mark.parametrize("surface, needle", [
    (dict(z_m=H + DEPTH + 1.0), "same height"),
    (dict(z_m=H + DEPTH, backscatter=-30.0), "backscatter"),
])
def test_what_a_surface_over_a_profile_does_not_model_is_refused(surface, needle):
    with pytest.raises(se.ConfigError, match=needle):
        se.Environment(sound_speed=_profile(), surface=se.SeaSurface(**surface))


def test_eigenray_kernel_matches_its_twin(rng):
    """kernels.surface_eigenrays against its NumPy twin (bisection on the textbook closed forms) on random
    profiles with a layer of zero gradient, random depths and distances (some far: out of reach, or reached by a
    ray running level in the flat layer, for both alike); and
    kernels.surface_reach against the twin's surface point."""
    import naive
    from sonar_embree import kernels

    for _ in range(3):
        z = np.concatenate([[0.0], np.sort(rng.uniform(1.0, 80.0, 3)), [120.0]])
        c = rng.uniform(1480.0, 1530.0, z.size)
        c[2] = c[1]                                                  # a layer of zero gradient
        n = 400
        d_src, d_dst = rng.uniform(0.5, 60.0, n), rng.uniform(0.5, 150.0, n)
        x = rng.uniform(0.0, 300.0, n)
        x[:5] = 0.0
        x[5:10] = 1e5                                    # out of reach, unless a ray runs level in a flat layer
        out = np.empty((n, kernels.EIGEN_WIDTH))
        kernels.surface_eigenrays(z, c, d_src, d_dst, x, out)
        ref = naive.surface_eigenrays(z, c, d_src, d_dst, x)
        np.testing.assert_array_equal(np.isnan(out[:, 1]), np.isnan(ref[:, 1]))
        assert np.isfinite(out[:5, 1]).all() and np.isfinite(out[:, 1]).sum() > n // 2
        ok = np.isfinite(ref[:, 1])
        np.testing.assert_allclose(out[ok], ref[ok], rtol=1e-7, atol=1e-9)
        reach = np.empty(int(ok.sum()))
        kernels.surface_reach(z, c, out[ok, 0], d_src[ok], reach)
        np.testing.assert_allclose(reach, ref[ok, 4], rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("want_phi", [False, True])
def test_curved_mixed_kernel_matches_its_twin(rng, want_phi):
    """kernels.curved_mixed against its NumPy twin on random tilted facets, attitudes, arrival directions, both
    sides, stop-and-hop and moving pings, a rough surface; unlit rays and rays with no eigenray left empty."""
    import naive
    from scipy.spatial.transform import Rotation

    from sonar_embree import kernels
    from sonar_embree.kernels.args import CurvedHits, Launch, Medium, MixedWeighting, Poses

    n_p, n = 3, 600
    rot = Rotation.from_euler("xyz", rng.uniform(-0.2, 0.2, (n_p, 3))).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    pos = np.column_stack([rng.uniform(-5, 5, (n_p, 2)), rng.uniform(8, 12, n_p)])
    row = np.sort(rng.integers(0, 2 * n_p, n)).astype(np.int64)
    point = np.column_stack([pos[row // 2, :2] + rng.uniform(-60, 60, (n, 2)), rng.uniform(-2, 3, n)])
    point[:3, :2] = pos[row[:3] // 2, :2]                              # straight below
    arrival = point - pos[row // 2] + rng.normal(0, 0.5, (n, 3))
    arrival /= np.linalg.norm(arrival, axis=1)[:, None]
    normals = rng.normal(size=(7, 3)) * [0.3, 0.3, 1.0]
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    body = rng.normal(size=(n, 3)) * [0.05, 1.0, 1.0]
    body /= np.linalg.norm(body, axis=1)[:, None]
    body[:, 1] = np.abs(body[:, 1]) * np.where(row % 2 == 1, 1.0, -1.0)
    hits = CurvedHits(point, rng.integers(0, 7, n).astype(np.int32), arrival, rng.uniform(5, 60, n).astype(np.float32),
                      rng.uniform(0.005, 0.08, n), rng.uniform(0, 1e-4, n), rng.random(n) < 0.85)
    z, c = np.array([0.0, 8.0, 40.0, 200.0]), np.array([1495.0, 1495.0, 1505.0, 1530.0])
    beam = np.array([0.5 * 1675.5 * 0.19, 0.5 * 1675.5 * 0.0038, np.radians(20.0), 0.0])
    dbeta, poses = rng.uniform(1e-4, 1e-2, n), Poses(rot, pos, np.array([0.0, 2e-3, -5e-3]))
    medium, weighting = Medium(z, c, 25.0), MixedWeighting(0.044, 0.01, 0.0375, 0.3, want_phi)
    out = np.empty((n, kernels.MIX_WIDTH))
    kernels.curved_mixed(hits, Launch(dbeta, row), poses, normals, medium, weighting, out)
    ray_start = np.searchsorted(row, np.arange(2 * n_p + 1)).astype(np.int64)
    w = np.ascontiguousarray(out[:, kernels.M_W])           # the beam after the kernel, as the front end applies it
    kernels.weigh_pairs(ray_start, body, out[:, kernels.M_U2:kernels.M_U2 + 3].copy(), rot, poses.rx_shift, beam[2],
                        int(beam[3]), beam[0], beam[1], w, np.zeros(0))
    out[:, kernels.M_W] = w
    ref = naive.curved_mixed(hits, (body, dbeta, row), poses, normals, medium, (beam, *weighting))
    lit = ref[:, 0] > 0
    assert lit.sum() > n // 6 and (~lit & hits.lit).sum() > 0
    np.testing.assert_array_equal(out[:, 0] > 0, lit)
    np.testing.assert_allclose(out[lit, :ref.shape[1]], ref[lit], rtol=1e-7, atol=1e-12)
    assert np.all(out[~lit, 0] == 0)
