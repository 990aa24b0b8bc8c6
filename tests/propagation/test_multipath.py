"""Sea-surface multipath (docs/physics.md §13) against an independent quadrature of the four-path image sum.

Flat floor at z = 0, sonar at altitude h heading +x, flat surface a depth d above it; its mirror S' at height
h + 2d. For a floor point at ground distance ρ: r = √(ρ² + h²), r' = √(ρ² + (h + 2d)²). The paths and their
intensity per unit floor area (Lambert μ, bistatic σ = μ·cos θi·cos θs):

    S→X→S     Γ⁴(u1)·μ cos²θi·e^(−2α'r)/r⁴                         at L = 2r
    S→X→S' ×2 2·Γ²(u1)·Γ²(u2)·μ cos θi cos θs·|R_s|²·e^(−α'(r+r'))/(r² r'²)   at L = r + r'
    S'→X→S'   Γ⁴(u2)·μ cos²θs·|R_s|⁴·e^(−2α'r')/r'⁴                 at L = 2r'

with u1 = (X − S)/r, u2 the mirror of (X − S')/r' (the upward leg as the transducer sees it), cos θi = h/r,
cos θs = (h + 2d)/r'. A rectangular pulse of length τ makes the sample at t the integral over
c(t − τ) < L ≤ ct. The integrals over the floor are done here on a polar grid, without the simulator's code.
"""
import dataclasses

import numpy as np
import pytest

import analytic
import sonar_embree as se
from sonar_embree.scene.meshes import heightfield_objects

H, D, TILT, LY, TAU, MU_DB = 10.0, 4.0, 0.0, 0.0015, 50e-6, -20.0
FS = 100e3


def _sonar(surface=None, **kw):
    env = se.Environment(surface=surface) if surface is not None else se.Environment()
    return se.Acquisition(se.Sonar(tilt_deg=TILT, height_m=LY, max_range_m=35.0, sample_rate_hz=FS, **kw), env)


def _record(surface=None, extra=None, moving_m_s=None):
    scene = se.Scene().add(se.seafloor.flat((400.0, 200.0)), material=se.Material(backscatter_db=MU_DB),
                           label="seafloor")
    for mesh, mat, label in extra or ():
        scene.add(mesh, material=mat, label=label)
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2, speed_m_s=moving_m_s or 2.0)
    line = line if moving_m_s else line.stop_and_hop()
    return se.simulate(scene, line, _sonar(surface), se.Pulse.cw(duration_s=TAU, taper=0.0),
                       start_time="2000-01-01")


def _path_densities(rho, alpha_np, rs2=lambda sin_g: 1.0, delta=0.0):
    """φ-integrated intensity per unit ground distance of the three kinds of path, and their lengths L(ρ).

    ``delta``: the receive beam's along-track cosine shifted by δ = 2v/c (motion during the ping, docs/physics.md
    §16): each path's Γ²(tx)·Γ²(rx) becomes Γ²(tx)·Γ_rx²(rx), and S→X→S' and S'→X→S differ."""
    dense = np.linspace(-0.12, 0.12, 401)
    phi = np.unique(np.concatenate([dense, np.linspace(-np.pi / 2, np.pi / 2, 401)]))
    p, f = rho[:, None], phi[None, :]
    xy = np.stack([p * np.sin(f), -p * np.cos(f)], axis=-1)           # φ = 0: broadside starboard (−y)
    r, r2 = np.sqrt(rho ** 2 + H ** 2)[:, None], np.sqrt(rho ** 2 + (H + 2 * D) ** 2)[:, None]

    def gamma(vx, vy, vz, shift=0.0):                                 # starboard: side = −y, down = −z
        return analytic.gamma_membrane(vx - shift, -vy, -vz, ly=LY, tilt_deg=TILT)

    g1 = gamma(xy[..., 0] / r, xy[..., 1] / r, -H / r)
    g2 = gamma(xy[..., 0] / r2, xy[..., 1] / r2, (H + 2 * D) / r2)   # mirrored: the leg goes up
    g1r = gamma(xy[..., 0] / r, xy[..., 1] / r, -H / r, delta)
    g2r = gamma(xy[..., 0] / r2, xy[..., 1] / r2, (H + 2 * D) / r2, delta)
    mu, ci, cs = 10 ** (MU_DB / 10), H / r, (H + 2 * D) / r2
    sg = (H + 2 * D) / r2                                             # sin of the grazing angle at the surface
    dens = {"direct": g1 ** 2 * g1r ** 2 * mu * ci ** 2 * np.exp(-2 * alpha_np * r) / r ** 4,
            "mixed": (g1 ** 2 * g2r ** 2 + g2 ** 2 * g1r ** 2) * mu * ci * cs * rs2(sg)
            * np.exp(-alpha_np * (r + r2)) / (r * r2) ** 2,
            "image": g2 ** 2 * g2r ** 2 * mu * cs ** 2 * rs2(sg) ** 2 * np.exp(-2 * alpha_np * r2) / r2 ** 4}
    lengths = {"direct": 2 * r[:, 0], "mixed": (r + r2)[:, 0], "image": 2 * r2[:, 0]}
    return {k: np.trapezoid(v, phi, axis=1) * rho for k, v in dens.items()}, lengths


def quadrature(t, c, alpha_db_m, rs2=lambda sin_g: 1.0, delta=0.0):
    """Expected intensity of each path at the sample times t (s): {path: (n,) float}."""
    rho = np.concatenate([np.linspace(0, 2, 1001)[:-1], np.linspace(2, 40, 3801)])
    alpha_np = alpha_db_m * np.log(10) / 10
    dens, lengths = _path_densities(rho, alpha_np, rs2, delta)
    out = {}
    for k, g in dens.items():
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(rho))])
        L = lengths[k]

        def C(x):
            return np.interp(x, L, cum, left=0.0, right=cum[-1])

        out[k] = C(c * t) - C(c * (t - TAU))
    return out


@pytest.fixture(scope="module")
def records():
    return {"none": _record(), "flat": _record(se.SeaSurface(z_m=H + D))}


@pytest.fixture(scope="module")
def flat_quadrature(records):
    rec = records["flat"]
    return quadrature(rec.time_s, rec.acquisition.sound_speed_m_s, rec.acquisition.alpha_db_per_m)


def _edges(t, c, paths=("one", "two")):
    """Samples within one of an onset or its end (onset + τ): the peak at normal incidence passes there."""
    onsets = {"direct": 2 * H / c, "one": (2 * H + 2 * D) / c, "two": 2 * (H + 2 * D) / c}
    near = np.zeros(t.shape, dtype=bool)
    for p in paths:
        for edge in (onsets[p], onsets[p] + TAU):
            near |= np.abs(t - edge) <= 1.5 / FS
    return near


def test_four_path_image_sum_matches_quadrature(records, flat_quadrature):
    rec, q = records["flat"], flat_quadrature
    total = q["direct"] + q["mixed"] + q["image"]
    got = rec.starboard.mean(axis=0)
    c = rec.acquisition.sound_speed_m_s
    multi = ((q["mixed"] + q["image"]) > 0.1 * total) & ~_edges(rec.time_s, c)   # onset timing: tested below
    assert multi.sum() > 100
    err = 10 * np.log10(got[multi] / total[multi])
    assert np.max(np.abs(err)) < 0.5, np.max(np.abs(err))
    direct_only = records["none"].starboard.mean(axis=0)
    lit = (q["direct"] > 1e-3 * q["direct"].max()) & ~_edges(rec.time_s, c, ("direct",))
    assert np.max(np.abs(10 * np.log10(direct_only[lit] / q["direct"][lit]))) < 0.5    # the reference itself


def test_moving_during_the_ping_turns_every_path_s_receive_beam(records):
    """Moving at 2 m/s, each path's record is the stop-and-hop one × its own beam-overlap loss (docs/physics.md
    §16): the ratio moving/still of the four-path sum against the same ratio of the quadrature with δ = 2v/c,
    within 0.03 dB where the surface paths carry at least half the intensity (there a receive beam left
    unturned on them would miss by more than 0.05 dB)."""
    still, v = records["flat"], 2.0
    moving = _record(se.SeaSurface(z_m=H + D), moving_m_s=v)
    c = still.acquisition.sound_speed_m_s
    q0, q1 = (quadrature(still.time_s, c, still.acquisition.alpha_db_per_m, delta=d) for d in (0.0, 2 * v / c))
    tot0, tot1 = (q["direct"] + q["mixed"] + q["image"] for q in (q0, q1))
    multi = ((q0["mixed"] + q0["image"]) > 0.5 * tot0) & ~_edges(still.time_s, c) & (tot0 > 1e-6 * tot0.max())
    assert multi.sum() > 100
    want = 10 * np.log10(tot1[multi] / tot0[multi])
    unturned = 10 * np.log10((q1["direct"] + q0["mixed"] + q0["image"])[multi] / tot0[multi])
    assert np.min(np.abs(want - unturned)) > 0.05                     # the test tells the two apart
    got = 10 * np.log10(moving.starboard.mean(axis=0)[multi] / still.starboard.mean(axis=0)[multi])
    np.testing.assert_allclose(got, want, atol=0.03)


def test_one_and_two_bounce_onsets(records, flat_quadrature):
    rec, c = records["flat"], records["flat"].acquisition.sound_speed_m_s
    t = rec.time_s
    extra = rec.starboard.mean(axis=0) - records["none"].starboard.mean(axis=0)
    first = t[np.flatnonzero(extra > 1e-9 * records["none"].starboard.max())[0]]
    assert abs(first - (2 * H + 2 * D) / c) <= 1.0 / FS                      # one bounce: (2h + 2d)/c
    q = flat_quadrature
    residual = extra - q["mixed"]                                             # what the mixed paths do not explain
    onset2 = 2 * (H + 2 * D) / c
    before, after = t < onset2 - 1.0 / FS, (t > onset2 + 1.0 / FS) & (t < onset2 + TAU)
    assert np.all(np.abs(residual[before]) < 0.05 * q["mixed"][before].max())
    assert np.all(residual[after] > 0.2 * q["image"][after])                  # two bounces: 2(h + 2d)/c
    assert q["image"][after].min() > 0.0


def test_rough_surface_scales_multipath_by_the_coherent_reflection(records):
    hw = 0.3e-3
    rough = _record(se.SeaSurface(z_m=H + D, rms_wave_height_m=hw))
    k = rough.acquisition.wavenumber_rad_m
    c, t = rough.acquisition.sound_speed_m_s, rough.time_s
    direct = records["none"].starboard.mean(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):  # 0/0 before the first bounce arrives
        ratio = (rough.starboard.mean(axis=0) - direct) / (records["flat"].starboard.mean(axis=0) - direct)
    window = (t > (2 * H + 2 * D) / c + 2 * TAU) & (t < 2 * (H + 2 * D) / c)   # one bounce only
    ell = c * (t[window] - TAU / 2)                                          # r + r' at broadside: solve for ρ
    rho = np.sqrt(((ell ** 2 - H ** 2 - (H + 2 * D) ** 2) ** 2 - 4 * H ** 2 * (H + 2 * D) ** 2) / (4 * ell ** 2))
    sin_g = (H + 2 * D) / np.sqrt(rho ** 2 + (H + 2 * D) ** 2)
    want = np.exp(-4 * k ** 2 * hw ** 2 * sin_g ** 2)
    assert want.min() < 10 ** (-0.2)                                          # the roughness matters here
    err = 10 * np.log10(ratio[window] / want)
    assert np.max(np.abs(err)) < 0.5, np.max(np.abs(err))


@pytest.mark.parametrize("surface", ["flat", "swell"])
@pytest.mark.parametrize("leg,plate_y,plate_z,blocked,kept", [
    # crosses the leg X → P (at z = 10.475–10.525 m it is 0.418–0.415·ρ out) for ρ = 2.4–7.2 m
    ("X to P", (-3.0, -1.0), H + 0.5, [(14.5, 15.5)], [(16.3, 17.7), (20.0, 34.0)]),
    # crosses the leg S → P (at z = 10.175–10.225 m it is 0.0097–0.0125·ρ out) for ρ = 4–20.6 m
    ("S to P", (-0.2, -0.05), H + 0.2, [(15.5, 18.0), (19.0, 24.0)], [(28.0, 34.0)]),
])
def test_occluder_shadows_only_the_surface_paths(records, leg, plate_y, plate_z, blocked, kept, surface):
    """A plate between the sonar and the surface shadows the surface paths whose leg it crosses (windows of
    R = ct/2 from the geometry: X, P and S' on one line, P at 4/18 of ρ); the direct echoes and every other
    surface path stay. The same for a 1 µm swell, whose legs are Embree reflections and casts
    (sonar_embree.propagation.swell): its unshadowed surface paths are a different sampling of the same paths (0.5 dB,
    as the quadrature test)."""
    import trimesh

    plate = trimesh.creation.box(extents=(60.0, plate_y[1] - plate_y[0], 0.05))
    plate.apply_translation((0.0, 0.5 * sum(plate_y), plate_z))
    sea = (se.SeaSurface(z_m=H + D) if surface == "flat"
           else se.SeaSurface(z_m=H + D, swell_height_m=1e-6, swell_length_m=20.0))
    rec = _record(sea, [(plate, se.Material(backscatter_db=-150.0), "plate")])
    r_eq = rec.slant_range_m
    got, flat, none = (x.starboard.mean(axis=0) for x in (rec, records["flat"], records["none"]))
    rtol = 1e-4 if surface == "flat" else 0.12                        # 0.5 dB

    def window(spans):
        return np.any([(r_eq > lo) & (r_eq < hi) for lo, hi in spans], axis=0)

    # the plate moves the adaptive ray budget a little (rtol) and adds its own −150 dB echo (atol)
    direct = window([(1.0, H + D - 0.5)])  # the plate's own echo lies nearer
    np.testing.assert_allclose(got[direct], none[direct], rtol=1e-4, atol=1e-9 * none.max())
    dark, lit = window(blocked), window(kept)
    for w in (dark, lit):
        assert w.sum() > 50 and np.all(flat[w] - none[w] > 0.05 * flat[w])   # multipath matters in both
    np.testing.assert_allclose(got[dark], none[dark], rtol=1e-4)
    np.testing.assert_allclose(got[lit], flat[lit], rtol=rtol)


@pytest.mark.parametrize("surface", ["flat", "swell"])
def test_legs_cast_through_boxes_only_change_nothing(monkeypatch, surface):
    """Visibility legs are cast only through the objects' boxes they cross, and a height-field floor is passed
    over where it cannot block (multipath.block_legs, docs/physics.md §13). On a rough floor with steep ridges
    (which shadow legs from behind them), a post reaching above the sonar and a floating plate (a height field
    too, seen from below, so it must still block), the record is the one with every leg cast through the whole
    scene's box."""
    import trimesh

    from sonar_embree.propagation import multipath

    def scene(objects=True):  # a rough floor with a steep ridge (slope 2) each side: shadows it casts itself
        x, y = np.meshgrid(np.linspace(-60.0, 60.0, 121), np.linspace(-60.0, 60.0, 241))
        z = 0.5 * np.sin(0.3 * x) * np.cos(0.2 * y) + np.maximum(0.0, 4.0 - 2.0 * np.abs(np.abs(y) - 14.0))
        floor = se.seafloor.from_heights(z, spacing_m=(1.0, 0.5), origin_m=(-60.0, -60.0))
        out = se.Scene().add(floor, material=se.Material(backscatter_db=MU_DB), label="seafloor")
        if objects:
            post = trimesh.creation.box(extents=(1.0, 1.0, 14.0))
            post.apply_translation((2.0, 9.0, 5.5))
            plate = se.seafloor.flat((8.0, 4.0), z_m=H + 2.0, center_m=(-2.0, -6.0))
            out.add(post, label="post").add(plate, material=se.Material(backscatter_db=-150.0), label="plate")
        return out

    sea = (se.SeaSurface(z_m=H + D) if surface == "flat"
           else se.SeaSurface(z_m=H + D, swell_height_m=0.3, swell_length_m=10.0))
    line = se.Trajectory.line((-0.5, 0.0, H), (0.5, 0.0, H), 3, speed_m_s=2.0)

    def run(s):
        return se.simulate(s, line, _sonar(sea), se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")

    s = scene()
    assert heightfield_objects(s.compiled(np.zeros(3))).tolist() == [True, False, True]
    boxed, clear = run(s), run(scene(objects=False))
    monkeypatch.setattr(multipath, "MAX_LEG_BOXES", 0)          # one box for all: every leg cast, none passed over
    whole = run(scene())
    np.testing.assert_allclose(boxed.data, whole.data, rtol=1e-12, atol=0.0)
    assert np.mean(np.abs(clear.data - boxed.data) > 1e-3 * clear.data) > 0.01   # the post and plate do block


def test_no_surface_runs_no_multipath_code_and_surface_errors(monkeypatch):
    from sonar_embree.propagation import multipath

    scene = se.Scene().add(se.seafloor.flat((100.0, 100.0)), label="seafloor")
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2).stop_and_hop()
    for name in ("image_echoes", "mixed_echoes", "merge"):      # model only what a scene needs
        monkeypatch.setattr(multipath, name, lambda *a, **k: pytest.fail("multipath ran without a surface"))
    timings = {}
    se.simulate(scene, line, se.Sonar(max_range_m=20.0), start_time="2000-01-01", timings=timings)
    assert "multipath" not in timings
    monkeypatch.undo()
    with pytest.raises(se.ConfigError, match="above the sea surface"):
        se.simulate(scene, line, _sonar(se.SeaSurface(z_m=H - 1.0)), start_time="2000-01-01")
    tall = se.Scene().add(se.seafloor.flat((100.0, 100.0)), label="seafloor")
    import trimesh
    mast = trimesh.creation.box(extents=(1.0, 1.0, 30.0))
    mast.apply_translation((0.0, -20.0, 15.0))
    tall.add(mast, label="mast")
    with pytest.raises(se.ConfigError, match="'mast' reaches above the sea surface"):
        se.simulate(tall, line, _sonar(se.SeaSurface(z_m=H + 2.0)), start_time="2000-01-01")
    for bad, needle in ((dict(z_m=float("nan")), "finite"), (dict(z_m=5.0, rms_wave_height_m=-1.0), ">= 0"),
                        (dict(z_m=5.0, rms_wave_height_m=0.1, wind_speed_m_s=5.0), "not both")):
        with pytest.raises(se.ConfigError, match=needle):
            se.SeaSurface(**bad)
    surf = se.SeaSurface(z_m=0.0, wind_speed_m_s=10.0)
    assert surf.wave_height_m == pytest.approx(0.21 * 100 / 9.80665 / 4)             # Pierson–Moskowitz H_s/4
    assert surf.reflection_db(90.0, 1.0) == pytest.approx(-20 * np.log10(np.e) * 2 * surf.wave_height_m ** 2)


def _mixed_legs(ray_start, fan, hits, rest, law, o, v, u2, layout):
    """kernels.mixed_legs with its arguments in named groups from the twin's flat ones: ``fan`` (s, cos β, sin β,
    dβ, el_start), ``rest`` (rot, pos, δ, z_s, normals, beam, ds, R_min, α', cap, c, k·h_w), ``law`` (want_phi,
    μ, face_object, want_legs), ``o`` the outputs by name."""
    from sonar_embree import kernels
    from sonar_embree.kernels.args import Bistatic, Fan, Hits, MixedOut, Poses, Weighting
    from sonar_embree.propagation.fan import launch_body

    rot, pos, rx_shift, z_s, normals, beam, ds, r_min, two_way, cap, c, kh = rest
    want_phi, mu, face_object, legs = law
    kernels.mixed_legs(ray_start, Fan(fan[0], ds, *fan[1:]), Hits(*hits), Poses(rot, pos, rx_shift), normals,
                       Weighting(two_way, r_min, np.inf, cap, 2.0 / c), Bistatic(z_s, kh, mu, face_object,
                                                                                     want_phi, legs),
                       MixedOut(o["time"], o["extent"], o["weight"], o["cos_i"], o["cos_s"], o["phi"], v, o["leg1"],
                                u2, o["leg2"]), layout)
    f = Fan(fan[0], ds, *fan[1:])                   # the beam after the kernel, as the front end applies it
    kernels.weigh_pairs(ray_start, launch_body(f, ray_start, layout), u2, rot, rx_shift, beam[2], int(beam[3]),
                        beam[0], beam[1], o["weight"], np.zeros(0))


def test_mixed_legs_kernel_matches_naive(rng):
    """kernels.mixed_legs against its NumPy twin on random tilted faces, attitudes and both sides, in the block
    layout of a side-scan fan (rows 2·ping + side, azimuth-major rays over each row's elevation cells)."""
    import naive
    from scipy.spatial.transform import Rotation

    from sonar_embree import kernels

    n_p = 3
    rot = Rotation.from_euler("xyz", rng.uniform(-0.2, 0.2, (n_p, 3))).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    pos = np.column_stack([rng.uniform(-5, 5, (n_p, 2)), rng.uniform(8, 12, n_p)])
    normals = rng.normal(size=(7, 3)) * [0.3, 0.3, 1.0]
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    n_el = rng.integers(5, 20, 2 * n_p)                               # elevation cells per row
    n_az = 5                                                          # azimuth rays per row (the fan's)
    s_az = rng.uniform(-0.3, 0.3, n_az)
    el_start = np.concatenate(([0], np.cumsum(n_el))).astype(np.int64)
    ray_start = n_az * el_start
    n = int(ray_start[-1])
    row = np.repeat(np.arange(2 * n_p), n_el * n_az)
    j = np.arange(n) - ray_start[row]
    dbeta_cell = rng.uniform(1e-4, 1e-2, el_start[-1])
    beta_cell = rng.uniform(0.05, 1.4, el_start[-1])                  # depressions, down from the sonar
    beta_cell[::7] = 2.0                                              # 115° − 20° tilt: behind the baffle
    ping, side = row // 2, np.where(row % 2 == 1, 1.0, -1.0)
    cell, a = el_start[row] + j % n_el[row], j // n_el[row]
    dbeta = dbeta_cell[cell]
    prim = rng.integers(0, 7, n).astype(np.int32)
    cpsi = np.sqrt(1 - s_az[a] ** 2)                                  # the fan ray's body direction → world
    e = np.column_stack([s_az[a], side * cpsi * np.cos(beta_cell[cell]), cpsi * np.sin(beta_cell[cell])])
    r = rng.uniform(5, 60, n)
    x = pos[ping] + r[:, None] * np.einsum("nij,nj->ni", rot[ping], e)
    miss = (rng.random(n) < 0.1) | (beta_cell[cell] == 2.0)           # no direct echo (fan_echoes: r = inf)
    r[miss] = np.inf
    beam = np.array([0.5 * 1675.5 * 0.19, 0.5 * 1675.5 * 0.0038, np.radians(20.0), 0.0])
    rx_shift = np.array([0.0, 2e-3, -5e-3])                          # stop-and-hop and moving pings (δ = 2v/c)
    rest = (rot, pos, rx_shift, 15.0, normals, beam, 0.01, 0.0375, 0.044, 600.0, 1500.0, 0.3)
    keys = ("time", "extent", "weight", "cos_i", "cos_s", "phi", "leg1", "leg2")
    out, no_phi = ({k: np.full(n, np.nan) for k in keys} for _ in range(2))
    v, u2 = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    face_object = rng.integers(0, 3, 7).astype(np.int32)
    mu = np.array([0.01, 0.002, 0.05])
    lam, no_legs = ({k: np.full(n, np.nan) for k in keys} for _ in range(2))
    v_lam, u2_lam = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    for want_phi, o, mu_obj, legs, vv, uu in ((True, out, np.zeros(0), True, v, u2),
                                              (False, no_phi, np.zeros(0), True, v, u2),
                                              (False, lam, mu, True, v_lam, u2_lam),
                                              (False, no_legs, np.zeros(0), False, np.full((n, 3), np.nan),
                                               np.full((n, 3), np.nan))):
        _mixed_legs(ray_start, (s_az, np.cos(beta_cell), np.sin(beta_cell), dbeta_cell, el_start), (r, x, prim),
                    rest, (want_phi, mu_obj, face_object, legs), o, vv, uu, kernels.NO_LAYOUT)
    for k in keys:                          # without φ (a scene of laws that ignore it): the rest to the bit
        np.testing.assert_array_equal(no_phi[k], out[k] if k != "phi" else np.full(n, np.nan), err_msg=k)
        if k not in ("leg1", "leg2", "phi"):   # without the legs: none written, the rest to the bit
            np.testing.assert_array_equal(no_legs[k], out[k], err_msg=k)
    assert np.all(np.isnan(no_legs["leg1"])) and np.all(np.isnan(no_legs["leg2"]))
    # Lambert in the kernel: the weight × (μ·cos θi)·cos θs (cosines clipped at 0), as apply_bistatic does (the beam's
    # gains multiplied in after it: the same product in another order, within a few ulp)
    lit = out["weight"] > 0
    want = out["weight"].copy()
    want[lit] = out["weight"][lit] * (mu[face_object[prim[lit]]] * np.clip(out["cos_i"][lit], 0, None)
                                      * np.clip(out["cos_s"][lit], 0, None))
    np.testing.assert_allclose(lam["weight"], want, rtol=1e-15, atol=0)
    np.testing.assert_array_equal(v_lam, v)
    hit = ~miss
    ref = naive.mixed_legs(x[hit], r[hit], ping[hit], side[hit], dbeta[hit], prim[hit], *rest)
    for k in out:
        np.testing.assert_allclose(out[k][hit], ref[k], rtol=1e-9, atol=1e-12, err_msg=k)
    np.testing.assert_allclose(v[hit], ref["v"], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(u2[hit], ref["u2"], rtol=1e-12, atol=1e-14)
    assert np.all(out["weight"][miss] == 0) and np.all(np.isinf(out["time"][miss]))
    assert np.count_nonzero(out["weight"]) > n // 4 and np.count_nonzero(out["weight"][hit] == 0) > 0  # both ways


def test_swell_kernels_match_naive(rng):
    """kernels.swell_launch and kernels.swell_paths against their NumPy twins: upward fan rays of random attitudes
    on random facets, bounced onto random scene faces, some missed, blocked or beyond the range, both sides."""
    import naive
    from scipy.spatial.transform import Rotation

    from sonar_embree import kernels

    n_p, n_az, eps = 3, 5, 1e-3
    rot = Rotation.from_euler("xyz", rng.uniform(-0.2, 0.2, (n_p, 3))).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    pos = np.column_stack([rng.uniform(-5, 5, (n_p, 2)), rng.uniform(8, 12, n_p)])
    n_el = rng.integers(5, 20, 2 * n_p)
    el_start = np.concatenate(([0], np.cumsum(n_el))).astype(np.int64)
    ray_start = n_az * el_start
    n = int(ray_start[-1])
    row = np.repeat(np.arange(2 * n_p), n_el * n_az)
    j = np.arange(n) - ray_start[row]
    ping, side = row // 2, np.where(row % 2 == 1, 1.0, -1.0)
    s_az = rng.uniform(-0.3, 0.3, n_az)
    beta_cell, dbeta_cell = rng.uniform(-1.3, -0.05, el_start[-1]), rng.uniform(1e-4, 1e-2, el_start[-1])
    beta_cell[::9] = -2.0                                            # behind the baffle (20° tilt): Γ = 0
    cell, a = el_start[row] + j % n_el[row], j // n_el[row]
    cpsi = np.sqrt(1 - s_az[a] ** 2)                                 # the launch direction from the fan grid
    e = np.column_stack([s_az[a], side * cpsi * np.cos(beta_cell[cell]), cpsi * np.sin(beta_cell[cell])])
    dirs = np.einsum("nij,nj->ni", rot[ping], e).astype(np.float32)
    surf = rng.normal(size=(9, 3)) * [0.2, 0.2, 1.0]
    surf /= np.linalg.norm(surf, axis=1)[:, None]
    prim_s = np.where(rng.random(n) < 0.1, -1, rng.integers(0, 9, n)).astype(np.int32)
    t1 = np.abs((15.0 - pos[ping, 2]) / dirs[:, 2]).astype(np.float32)
    up = np.flatnonzero((prim_s >= 0) & (dirs[:, 2] > 0))
    up_start = np.searchsorted(up, ray_start).astype(np.int64)
    m = up.shape[0]
    u, p, ur = (np.full((m, 3), np.nan) for _ in range(3))
    org, dr = np.full((m, 3), np.nan, np.float32), np.full((m, 3), np.nan, np.float32)
    kernels.swell_launch(up_start, up, dirs, t1, prim_s, pos, surf, eps, u, p, ur, org, dr)
    ref = naive.swell_launch(ping[up], dirs[up], t1[up], prim_s[up], pos, surf, eps)
    for got, want in zip((u, p, ur, org, dr), ref):
        np.testing.assert_allclose(got, want, rtol=1e-6 if got.dtype == np.float32 else 1e-12, atol=1e-12)

    normals = rng.normal(size=(7, 3)) * [0.3, 0.3, 1.0]
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    normals[:, 2] = np.abs(normals[:, 2]) * [1, 1, 1, 1, 1, 1, -1]   # faces up, one down (cos θi < 0)
    prim = np.where(rng.random(m) < 0.1, -1, rng.integers(0, 7, m)).astype(np.int32)
    t2 = rng.uniform(1.0, 60.0, m).astype(np.float32)
    seen = np.where(rng.random(m) < 0.1, 0.0, 1.0)
    rx_shift = np.array([0.0, 2e-3, -5e-3])
    beam = np.array([0.5 * 1675.5 * 0.19, 0.5 * 1675.5 * 0.0038, np.radians(20.0), 0.0])
    consts = (beam, 0.01, 0.0375, 0.044, 600.0, 1500.0, 0.3, 90.0, eps)
    keys = ("w1", "time1", "ext1", "w2", "time2", "ext2", "cos_i", "cos_s", "phi", "r")
    out, no_phi = ({k: np.full(m, np.nan) for k in keys} for _ in range(2))
    x, leg = np.full((m, 3), np.nan), np.full((m, 3), np.nan)
    lam = {k: np.full(m, np.nan) for k in keys}
    face_object, mu = np.array([0, 1, 0, 1, 0, 1, 0], np.int32), np.array([0.01, 0.2])
    for want_phi, o, mu_obj in ((True, out, np.zeros(0)), (False, no_phi, np.zeros(0)), (False, lam, mu)):
        _swell_paths((s_az, np.cos(beta_cell), np.sin(beta_cell), dbeta_cell, el_start),
                     (up_start, up, ray_start, u, p, ur, t1, prim_s, prim, t2, seen, surf), normals,
                     (rot, pos, rx_shift), consts, (want_phi, mu_obj, face_object), x, o, leg, kernels.NO_LAYOUT)
    # each ray with its own layout (the rays aimed at objects via the swell): the fan grid's bits
    layout = np.column_stack([s_az[a], np.cos(beta_cell[cell]), np.sin(beta_cell[cell]), dbeta_cell[cell],
                              np.full(n, consts[1])])
    own = {k: np.full(m, np.nan) for k in keys}
    x_own, leg_own = np.full((m, 3), np.nan), np.full((m, 3), np.nan)
    _swell_paths((np.zeros(1), np.zeros(0), np.zeros(0), np.zeros(0), el_start),
                 (up_start, up, ray_start, u, p, ur, t1, prim_s, prim, t2, seen, surf), normals, (rot, pos, rx_shift),
                 consts, (True, np.zeros(0), face_object), x_own, own, leg_own, layout)
    for k in keys:
        np.testing.assert_array_equal(own[k], out[k], err_msg=k)
    for k in keys:                        # without φ (laws that ignore it): the rest to the bit, φ left at 0
        np.testing.assert_array_equal(no_phi[k], out[k] if k != "phi" else np.zeros(m), err_msg=k)
    sigma = mu[face_object[np.maximum(prim, 0)]] * np.maximum(out["cos_i"], 0) * np.maximum(out["cos_s"], 0)
    np.testing.assert_allclose(lam["w1"], np.where(out["w1"] > 0, out["w1"] * sigma, out["w1"]), rtol=1e-15,
                               atol=0)                          # Lambert's σ (the gains multiplied in after it)
    for k in keys[1:]:
        np.testing.assert_array_equal(lam[k], no_phi[k], err_msg=k)
    pu, cu = ping[up], cell[up]
    ref = naive.swell_paths(s_az[a[up]], beta_cell[cu], dbeta_cell[cu], u, p, ur, t1[up], surf[prim_s[up]], prim, t2,
                            seen, normals, rot, pos, pu, side[up], rx_shift[pu], *consts)
    for k in ("w1", "time1", "ext1", "w2", "time2", "ext2", "cos_i"):
        np.testing.assert_allclose(out[k], ref[k], rtol=1e-5, atol=1e-14, err_msg=k)   # Γ(u): grid vs float32 u
    ok, lit1 = ref["ok"], ref["lit1"]
    np.testing.assert_allclose(x, ref["x"], rtol=1e-12, atol=1e-12)
    for k in ("cos_s", "r"):
        np.testing.assert_allclose(out[k][ok], ref[k][ok], rtol=1e-12, atol=1e-14, err_msg=k)
    np.testing.assert_allclose(leg[ok], ref["leg"][ok], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(out["phi"][lit1], ref["phi"][lit1], rtol=1e-9, atol=1e-9)
    assert 0 < lit1.sum() < ok.sum() < m and np.count_nonzero(out["w1"]) > m // 4   # every branch is taken
    assert np.count_nonzero((out["w2"] == 0) & ok) > 0 and np.count_nonzero(rx_shift[pu][ok] != 0) > 0


def _swell_paths(fan, bounce, normals, poses, consts, law, x, o, leg, layout):
    """kernels.swell_paths with its arguments in named groups from the twin's flat ones: ``fan`` (s, cos β, sin β,
    dβ, el_start), ``bounce`` (up_start, up, ray_start, u, p, u_r, t1, prim_s, prim, t2, seen, surface normals),
    ``consts`` (beam, ds, R_min, α', cap, c, k·h_w, R_max, eps), ``law`` (want_phi, μ, face_object), ``o`` the
    outputs by name."""
    from sonar_embree import kernels
    from sonar_embree.kernels.args import Bistatic, Bounce, Fan, Poses, SwellOut, Weighting
    from sonar_embree.propagation.fan import launch_body

    beam, ds, r_min, two_way, cap, c, kh, r_max, eps = consts
    want_phi, mu, face_object = law
    kernels.swell_paths(Fan(fan[0], ds, *fan[1:]), Bounce(*bounce, eps), Poses(*poses), normals,
                        Weighting(two_way, r_min, r_max, cap, 2.0 / c), Bistatic(0.0, kh, mu, face_object,
                                                                                      want_phi, False),
                        SwellOut(x, o["w1"], o["time1"], o["ext1"], o["w2"], o["time2"], o["ext2"], o["cos_i"],
                                 o["cos_s"], o["phi"], leg, o["r"]), layout)
    up_start, up, ray_start = bounce[:3]                # the beam after the kernel, as the front end applies it
    body = launch_body(Fan(fan[0], ds, *fan[1:]), ray_start, layout)[up]
    kernels.weigh_pairs(up_start, body, -leg, poses[0], poses[2], beam[2], int(beam[3]), beam[0], beam[1], o["w1"],
                        o["w2"])


def _block(rng, n_p=3):
    """A random side-scan block layout: ray_start over 2·n_p rows, and each ray's ping."""
    counts = rng.integers(0, 40, 2 * n_p)
    counts[1] = 0                                                      # an empty row
    ray_start = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    return ray_start, np.repeat(np.arange(2 * n_p), counts) // 2


def test_two_bounce_kernel_matches_naive(rng):
    """kernels.two_bounce against its NumPy twin: |R_s|⁴ on lit echoes, the upward legs from the real sonar."""
    import naive

    from sonar_embree import kernels

    ray_start, ping = _block(rng)
    n = int(ray_start[-1])
    pos_i = np.column_stack([rng.uniform(-5, 5, (3, 2)), rng.uniform(18, 22, 3)])
    x = np.column_stack([rng.uniform(-30, 30, (n, 2)), rng.uniform(-1, 2, n)])
    w = np.where(rng.random(n) < 0.2, 0.0, rng.uniform(0.1, 1.0, n))
    up, leg = np.full((n, 3), np.nan), np.full(n, np.nan)
    got = w.copy()
    kernels.two_bounce(ray_start, x, pos_i, 15.0, 0.4, got, up, leg)
    ref_w, ref_up, ref_leg = naive.two_bounce(ray_start, x, pos_i, 15.0, 0.4, w)
    np.testing.assert_allclose(got, ref_w, rtol=1e-13)
    lit = w > 0
    np.testing.assert_allclose(up[lit], ref_up[lit], rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(leg, ref_leg, rtol=1e-13)
    assert np.all(got[lit] < w[lit]) and np.all(leg[~lit] == 0)


@pytest.mark.parametrize("direction_deg", [0.0, 25.0, 90.0])
def test_swell_surface_hits_match_brute_force(rng, direction_deg):
    """kernels.swell_surface_hits (the swell's mesh hit in closed form, strip by strip) against Möller–Trumbore on
    every triangle of SeaSurface.mesh: the same triangle (or its coplanar partner, on the quad's diagonal) and
    distance; rays up, down, level, from outside the mesh and too short to reach it."""
    import naive

    from sonar_embree import kernels

    sea = se.SeaSurface(z_m=5.0, swell_height_m=0.6, swell_length_m=6.0, swell_direction_deg=direction_deg)
    shift = np.array([1000.0, -2000.0, 3.0])                        # the local origin in world coordinates
    xr, yr = (990.0, 1012.0), (-2011.0, -1993.0)
    mesh, g = sea.mesh(xr, yr, origin_m=shift), sea.strips(xr, yr)
    n = 400
    org = np.column_stack([rng.uniform(-14.0, 16.0, n), rng.uniform(-12.0, 10.0, n), rng.uniform(-6.0, 1.5, n)])
    dirs = rng.normal(size=(n, 3))
    dirs[:, 2] = np.abs(dirs[:, 2]) * np.where(rng.random(n) < 0.15, -1.0, 1.0)
    dirs[:10, 2] = 0.0                                              # level rays: only in the band of heights
    org[:10, 2] = rng.uniform(1.7, 2.3, 10)
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    org32, dirs32 = org.astype(np.float32), dirs.astype(np.float32)
    prim, t = np.empty(n, np.int32), np.empty(n, np.float32)
    kernels.swell_surface_hits(org32, dirs32, shift, g.k, float(g.a[0]), float(g.a[1] - g.a[0]), g.z,
                               float(g.b[0]), float(g.b[1] - g.b[0]), g.b.size, 30.0, prim, t)
    ref_prim, ref_t = naive.first_hits(org32.astype(float), dirs32.astype(float), np.asarray(mesh.vertices),
                                       np.asarray(mesh.faces), 30.0)
    n_q = len(mesh.faces) // 2
    hit = ref_prim >= 0
    assert 0.3 * n < hit.sum() < n and np.any(dirs[:10, 2] == 0.0)
    np.testing.assert_array_equal(prim >= 0, hit)
    np.testing.assert_array_equal(prim[hit] % n_q, ref_prim[hit] % n_q)
    assert np.mean(prim[hit] == ref_prim[hit]) > 0.99
    np.testing.assert_allclose(t[hit], ref_t[hit], rtol=1e-6, atol=1e-6)


def test_merge_kernels_match_naive(rng):
    """kernels.count_lit + merge_lit against a stable sort by row: lit echoes only, part by part in each row."""
    import naive

    from sonar_embree import kernels

    parts = []
    for _ in range(3):
        ray_start, _ = _block(rng)
        n = int(ray_start[-1])
        w = np.where(rng.random(n) < 0.3, 0.0, rng.random(n))
        parts.append((ray_start, rng.random(n), rng.random(n), w, rng.random((n, 3)),
                      rng.integers(-1, 5, n).astype(np.int32)))
    rows = len(parts[0][0]) - 1
    counts = np.empty(rows, dtype=np.int64)
    kernels.count_lit(tuple(p[0] for p in parts), tuple(p[3] for p in parts), counts)
    start = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    m = int(start[-1])
    out = [np.empty(m), np.empty(m), np.empty(m), np.empty((m, 3)), np.empty(m, np.int32), np.empty(m, np.int8)]
    kernels.merge_lit(*(tuple(p[c] for p in parts) for c in range(6)), start, *out)
    ref = naive.merge_lit(parts)
    np.testing.assert_array_equal(start, ref[0])
    for got, want in zip(out, ref[1:]):
        np.testing.assert_array_equal(got, want)
    assert m < sum(len(p[3]) for p in parts) and set(np.unique(out[5])) == {0, 1, 2}


@pytest.mark.parametrize("from_sonar, free_own", [(False, False), (True, False), (False, True), (True, True)])
def test_visibility_legs_kernel_matches_naive(rng, from_sonar, free_own):
    """kernels.visibility_legs against its NumPy twin: legs cast from where they enter the first box they cross to
    where they leave the last; those crossing none, unlit and empty ones skipped; a height field of the echo's own
    passed over for a leg from it steeper than its slope, and (``free_own``) for an echo seen from above."""
    import naive

    from sonar_embree import kernels
    from sonar_embree.kernels.args import Boxes, LegOut, Legs

    ray_start, ping = _block(rng)
    n = int(ray_start[-1])
    pos = np.column_stack([rng.uniform(-5, 5, (3, 2)), rng.uniform(-1, 4, 3)])
    x = np.column_stack([rng.uniform(-30, 30, (n, 2)), rng.uniform(-1, 4, n)])
    dirs = rng.normal(size=(n, 3))
    dirs[:, 2] = np.abs(dirs[:, 2]) * np.where(rng.random(n) < 0.1, -1, 1)
    dirs[rng.random(n) < 0.05, 0] = 0.0                                 # legs parallel to a slab
    dirs[rng.random(n) < 0.02, :2] = 0.0                                # vertical legs
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    dist, w = rng.uniform(0.0, 20.0, n), np.where(rng.random(n) < 0.2, 0.0, 1.0)
    lo = np.array([[-40.0, -40.0, -1.5], [-5.0, 2.0, -1.0], [10.0, -20.0, 0.0]])
    hi = np.array([[40.0, 40.0, 0.5], [5.0, 12.0, 3.0], [20.0, -10.0, 2.0]])
    obj, slope = np.array([0, -1, 2], np.int32), np.array([0.6, np.inf, 1.5])
    face_object, normals = np.array([0, 1, 2, 0], np.int32), rng.normal(size=(4, 3))
    prim = rng.integers(0, 4, n).astype(np.int32)
    idx, org, dr, ln = (np.empty(n, np.int64), np.empty((n, 3), np.float32), np.empty((n, 3), np.float32),
                        np.empty(n, np.float32))
    span = np.empty(n), np.empty(n)
    counts = {}
    for p in (prim, prim[:0]):
        args = (ray_start, x, pos, from_sonar, dirs, dist, w, lo, hi, obj, slope, free_own, p, face_object, normals,
                1e-3)
        legs = Legs(x, pos, from_sonar, dirs, dist, w, p, free_own, 1e-3)
        k = kernels.visibility_legs(ray_start, legs, Boxes(lo, hi, obj, slope), face_object, normals,
                                    LegOut(*span, idx, org, dr, ln))
        ref = naive.visibility_legs(*args)
        assert 0 < k < int((w > 0).sum())
        for got, want in zip((idx[:k], org[:k], dr[:k], ln[:k]), ref):
            np.testing.assert_array_equal(got, want)
        counts[len(p)] = k
    if free_own or not from_sonar:                                      # some legs skipped for their own floor
        assert counts[n] < counts[0]


def test_speckle_with_a_surface_averages_to_the_expected_four_paths(records):
    """Each path gathers its own echoes onto the frozen lattice with its own phase (|X − tx| + |X − rx|)/λ: the
    mean speckled intensity over pings 0.2 m apart is the expected record, where one and two bounces dominate."""
    surface = se.SeaSurface(z_m=H + D)
    scene = se.Scene().add(se.seafloor.flat((400.0, 200.0)), material=se.Material(backscatter_db=MU_DB),
                           label="seafloor")
    line = se.Trajectory.line((-4.0, 0.0, H), (4.0, 0.0, H), 41).stop_and_hop()
    rec = se.simulate(scene, line, _sonar(surface), se.Pulse.cw(duration_s=TAU, taper=0.0), speckle=True,
                      seed=5, start_time="2000-01-01")
    want = records["flat"].starboard.mean(axis=0)
    r_eq = rec.slant_range_m
    for lo, hi in ((14.5, 17.5), (18.5, 24.0), (26.0, 34.0)):   # one bounce; two bounces begin; far range
        w = (r_eq > lo) & (r_eq < hi)
        assert 10 * np.log10(rec.starboard[:, w].mean() / want[w].mean()) == pytest.approx(0.0, abs=0.3)


def test_surface_survives_the_record_file(tmp_path):
    scene = se.Scene().add(se.seafloor.flat((100.0, 100.0)), label="seafloor")
    line = se.Trajectory.line((-0.5, 0.0, 6.0), (0.5, 0.0, 6.0), 2)
    surface = se.SeaSurface(z_m=9.0, rms_wave_height_m=0.001)
    rec = se.simulate(scene, line, se.Acquisition(se.Sonar(max_range_m=20.0), se.Environment(surface=surface)),
                      start_time="2000-01-01")
    rec.save(tmp_path / "r.npz")
    assert se.Record.load(tmp_path / "r.npz").environment.surface == surface


# --- a swell: the surface meshed and every surface path by one Embree reflection (sonar_embree.propagation.swell) ---
def test_a_flat_swell_mesh_gives_the_four_path_quadrature(flat_quadrature, monkeypatch):
    """A swell of 1 µm is a flat mesh: the bounced rays (a different sampling of the same paths: the one-bounce
    paths from the reflected rays rather than from the direct ones) must give the four-path image sum."""
    from sonar_embree.propagation import multipath
    for name in ("image_echoes", "mixed_echoes"):
        monkeypatch.setattr(multipath, name, lambda *a, **k: pytest.fail("the image method ran for a swell"))
    q = flat_quadrature
    rec = _record(se.SeaSurface(z_m=H + D, swell_height_m=1e-6, swell_length_m=20.0))
    total = q["direct"] + q["mixed"] + q["image"]
    c = rec.acquisition.sound_speed_m_s
    multi = ((q["mixed"] + q["image"]) > 0.1 * total) & ~_edges(rec.time_s, c)
    err = 10 * np.log10(rec.starboard.mean(axis=0)[multi] / total[multi])
    assert multi.sum() > 100 and np.max(np.abs(err)) < 0.5, np.max(np.abs(err))


def test_a_flat_swell_mesh_moves_during_the_ping_as_the_image_method_does(records):
    """The swell's paths turn their receive beams as the flat surface's do: a 1 µm swell, moving at 2 m/s over
    stop-and-hop, against the quadrature's moving/still ratio (as for the flat surface), within 0.05 dB."""
    flat = se.SeaSurface(z_m=H + D, swell_height_m=1e-6, swell_length_m=20.0)
    still, moving = _record(flat), _record(flat, moving_m_s=2.0)
    c = still.acquisition.sound_speed_m_s
    q0, q1 = (quadrature(still.time_s, c, still.acquisition.alpha_db_per_m, delta=d) for d in (0.0, 4.0 / c))
    tot0, tot1 = (q["direct"] + q["mixed"] + q["image"] for q in (q0, q1))
    multi = ((q0["mixed"] + q0["image"]) > 0.5 * tot0) & ~_edges(still.time_s, c) & (tot0 > 1e-6 * tot0.max())
    want = 10 * np.log10(tot1[multi] / tot0[multi])
    got = 10 * np.log10(moving.starboard.mean(axis=0)[multi] / still.starboard.mean(axis=0)[multi])
    assert np.min(want) < -0.1
    np.testing.assert_allclose(got, want, atol=0.05)


def test_a_swell_runs_the_reflection_path_and_modulates_the_multipath_along_track(monkeypatch):
    """Over one swell length the one-bounce energy changes with the facets above the sonar (it is largest under
    a crest or trough, where they are level), where a flat surface gives the same energy at every ping."""
    scene = se.Scene().add(se.seafloor.flat((400.0, 200.0)), material=se.Material(backscatter_db=MU_DB),
                           label="seafloor")
    length = 12.0
    line = se.Trajectory.line((0.0, 0.0, H), (length * 7 / 8, 0.0, H), 8)
    swell = se.SeaSurface(z_m=H + D, swell_height_m=0.6, swell_length_m=length)
    wavy = se.simulate(scene, line, _sonar(swell), se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")
    monkeypatch.undo()
    flat = se.simulate(scene, line, _sonar(se.SeaSurface(z_m=H + D)), se.Pulse.cw(duration_s=TAU, taper=0.0),
                       start_time="2000-01-01")
    direct = se.simulate(scene, line, _sonar(), se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")
    w = (flat.slant_range_m > 14.5) & (flat.slant_range_m < 17.5)               # one bounce, before two bounces
    e_wavy = 10 * np.log10((wavy.starboard[:, w] - direct.starboard[:, w]).sum(axis=1))
    e_flat = 10 * np.log10((flat.starboard[:, w] - direct.starboard[:, w]).sum(axis=1))
    assert np.ptp(e_flat) < 0.01 and np.ptp(e_wavy) > 6.0
    assert np.argmax(e_wavy) in (2, 6)                                           # x = Λ/4, 3Λ/4: crest, trough
    with pytest.raises(se.ConfigError, match="steeper than 1/7"):
        se.SeaSurface(z_m=0.0, swell_height_m=3.0, swell_length_m=20.0)
    with pytest.raises(se.ConfigError, match="lowest z"):
        se.simulate(scene, line, _sonar(se.SeaSurface(z_m=H + 0.2, swell_height_m=0.6, swell_length_m=length)),
                    start_time="2000-01-01")


# --- the surface line: the surface's own backscatter S→P→S (docs/physics.md §13) ---
MU_S_DB = -25.0


def line_quadrature(t, c, alpha_db_m, law_db=lambda sin_g: MU_S_DB + 20 * np.log10(sin_g)):
    """Expected intensity of the surface line at times t: the surface a distance D above the sonar, a surface point
    at ground distance ρ at r_s = √(ρ² + D²), seen along the upward u = (X − S)/r_s, grazing sin θg = D/r_s;
    Γ⁴(u)·σ(θg)·e^(−2α'r_s)/r_s⁴ per unit area with σ/cos θi = 10^(law_db/10)/sin θg, at L = 2r_s. ``law_db``: the
    monostatic strength in dB at sin θg (default Lambert: μ·sin²θg)."""
    rho = np.concatenate([np.linspace(0, 2, 1001)[:-1], np.linspace(2, 40, 3801)])
    dense = np.linspace(-0.12, 0.12, 401)
    phi = np.unique(np.concatenate([dense, np.linspace(-np.pi / 2, np.pi / 2, 401)]))
    p, f = rho[:, None], phi[None, :]
    r = np.sqrt(rho ** 2 + D ** 2)[:, None]
    g = analytic.gamma_membrane(p * np.sin(f) / r, p * np.cos(f) / r, -D / r, ly=LY, tilt_deg=TILT)
    sin_g = D / r
    alpha_np = alpha_db_m * np.log(10) / 10
    dens = np.trapezoid(g ** 4 * 10 ** (law_db(sin_g) / 10) * np.exp(-2 * alpha_np * r) / r ** 4, phi, axis=1) * rho
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(rho))])
    L = 2 * r[:, 0]
    return np.interp(c * t, L, cum, left=0.0, right=cum[-1]) - np.interp(c * (t - TAU), L, cum, left=0.0,
                                                                          right=cum[-1])


@pytest.fixture(scope="module")
def line_record():
    return _record(se.SeaSurface(z_m=H + D, backscatter=MU_S_DB))


def test_surface_line_matches_quadrature_and_starts_at_2d_over_c(records, flat_quadrature, line_record):
    rec, q = line_record, flat_quadrature
    c, t = rec.acquisition.sound_speed_m_s, rec.time_s
    q_line = line_quadrature(t, c, rec.acquisition.alpha_db_per_m)
    total = q["direct"] + q["mixed"] + q["image"] + q_line
    got = rec.starboard.mean(axis=0)
    near = np.zeros(t.shape, dtype=bool)
    for edge in (2 * D / c, 2 * D / c + TAU):
        near |= np.abs(t - edge) <= 1.5 / FS
    carries = (q_line > 0.1 * total) & ~near & ~_edges(t, c, ("direct", "one", "two"))
    assert carries.sum() > 100                                            # between 2d/c and the floor's 2h/c
    err = 10 * np.log10(got[carries] / total[carries])
    assert np.max(np.abs(err)) < 0.5, np.max(np.abs(err))
    first = t[np.flatnonzero(got > 1e-12 * got.max())[0]]
    assert abs(first - 2 * D / c) <= 1.0 / FS                             # the surface line's onset
    np.testing.assert_array_equal(got[t > 2 * H / c + 2 * TAU] >= records["flat"].starboard.mean(axis=0)[
        t > 2 * H / c + 2 * TAU], True)                                   # it adds to the four paths, never less


def test_surface_line_of_a_swell_and_its_shadow(line_record):
    """A 1 µm swell's surface line (the fan cast on its mesh) matches the flat one's; a plate just above the
    sonar over starboard darkens the starboard line and leaves port's."""
    import trimesh

    c = line_record.acquisition.sound_speed_m_s
    alone = (line_record.time_s > 2 * D / c + 2 * TAU) & (line_record.time_s < 2 * H / c - 2 * TAU)
    swell = _record(se.SeaSurface(z_m=H + D, swell_height_m=1e-6, swell_length_m=20.0, backscatter=MU_S_DB))
    np.testing.assert_allclose(swell.starboard.mean(axis=0)[alone], line_record.starboard.mean(axis=0)[alone],
                               rtol=0.12)
    plate = trimesh.creation.box(extents=(80.0, 39.9, 0.05))
    plate.apply_translation((0.0, -20.0, H + 0.5))                      # y < −0.05: starboard's upward rays
    shaded = _record(se.SeaSurface(z_m=H + D, backscatter=MU_S_DB), [(plate, se.Material(backscatter_db=-150.0),
                                                                          "plate")])
    assert line_record.starboard[:, alone].min() > 0
    assert shaded.starboard[:, alone].max() < 1e-6 * line_record.starboard[:, alone].max()
    np.testing.assert_allclose(shaded.port[:, alone], line_record.port[:, alone], rtol=1e-9)


def test_chapman_harris_law_and_surface_backscatter_settings(tmp_path):
    """ChapmanHarris against Chapman and Harris (1962) written here, S_s = 3.3β·log10(θ/30) − 42.4·log10 β + 2.6,
    β = 158·(v·f^(1/3))^(−0.58), v in knots (1 kn = 1852/3600 m/s); the surface line's settings."""
    law = se.laws.ChapmanHarris(wind_speed_m_s=7.0)
    v_kn, f = 7.0 * 3600 / 1852, 200e3
    beta = 158 * (v_kn * f ** (1 / 3)) ** -0.58
    for g in (2.0, 10.0, 30.0, 60.0):
        want = 3.3 * beta * np.log10(g / 30) - 42.4 * np.log10(beta) + 2.6
        assert float(law.at_frequency(f).backscatter_strength_db(g)) == pytest.approx(want, abs=1e-3)
        assert float(law.backscatter_strength_db(g, f)) == pytest.approx(want, abs=1e-12)
    s = se.SeaSurface(z_m=0.0, wind_speed_m_s=7.0, backscatter="chapman-harris")
    assert se.Environment(surface={"z_m": 0.0, "wind_speed_m_s": 7.0, "backscatter": "chapman-harris"}).surface == s
    assert s.backscatter_law == law and se.SeaSurface(z_m=0.0, backscatter=-30).backscatter_law == se.laws.Lambert(-30.0)
    for bad, needle in ((dict(backscatter="apl"), "'chapman-harris'"), (dict(backscatter="chapman-harris"),
                                                                         "needs wind_speed_m_s"),
                        (dict(backscatter=40.0), "backscatter")):
        with pytest.raises(se.ConfigError, match=needle):
            se.SeaSurface(z_m=0.0, **bad)
    with pytest.raises(se.ConfigError, match="wind_speed_m_s"):
        se.laws.ChapmanHarris(wind_speed_m_s=40.0)
    scene = se.Scene().add(se.seafloor.flat((100.0, 100.0)), label="seafloor")
    s = dataclasses.replace(s, z_m=9.0)
    rec = se.simulate(scene, se.Trajectory.line((-0.5, 0.0, 6.0), (0.5, 0.0, 6.0), 2),
                      se.Acquisition(se.Sonar(max_range_m=20.0), se.Environment(surface=s)), start_time="2000-01-01")
    assert rec.starboard[:, rec.slant_range_m < 5.9].max() > 0                 # the line, before the floor at 6 m
    rec.save(tmp_path / "r.npz")
    assert se.Record.load(tmp_path / "r.npz").environment.surface == s


def test_mixed_legs_with_each_rays_own_layout_matches_naive(rng):
    """kernels.mixed_legs for rays with their own s, β, dβ and ds (the rays aimed at objects, docs/physics.md §7b):
    the same twin, each ray's cell its own."""
    import naive
    from scipy.spatial.transform import Rotation

    from sonar_embree import kernels

    n_p, n = 3, 400
    rot = Rotation.from_euler("xyz", rng.uniform(-0.2, 0.2, (n_p, 3))).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    pos = np.column_stack([rng.uniform(-5, 5, (n_p, 2)), rng.uniform(8, 12, n_p)])
    normals = rng.normal(size=(7, 3)) * [0.3, 0.3, 1.0]
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    row = np.sort(rng.integers(0, 2 * n_p, n))
    ray_start = np.concatenate(([0], np.cumsum(np.bincount(row, minlength=2 * n_p)))).astype(np.int64)
    ping, side = row // 2, np.where(row % 2 == 1, 1.0, -1.0)
    s = np.repeat(rng.uniform(-0.02, 0.02, n // 4), 4)                 # runs of equal s, as a lattice has
    beta, dbeta, ds = rng.uniform(0.05, 1.4, n), rng.uniform(1e-4, 1e-2, n), rng.uniform(1e-4, 1e-2, n)
    layout = np.column_stack([s, np.cos(beta), np.sin(beta), dbeta, ds])
    cpsi = np.sqrt(1 - s ** 2)
    e = np.column_stack([s, side * cpsi * np.cos(beta), cpsi * np.sin(beta)])
    r = rng.uniform(5, 60, n)
    x = pos[ping] + r[:, None] * np.einsum("nij,nj->ni", rot[ping], e)
    miss = rng.random(n) < 0.1
    r[miss] = np.inf
    prim = rng.integers(0, 7, n).astype(np.int32)
    beam = np.array([0.5 * 1675.5 * 0.19, 0.5 * 1675.5 * 0.0038, np.radians(20.0), 0.0])
    rx_shift = np.array([0.0, 2e-3, -5e-3])
    keys = ("time", "extent", "weight", "cos_i", "cos_s", "phi", "leg1", "leg2")
    out = {k: np.full(n, np.nan) for k in keys}
    v, u2 = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    _mixed_legs(ray_start, (np.zeros(1), np.zeros(0), np.zeros(0), np.zeros(0), ray_start), (r, x, prim),
                (rot, pos, rx_shift, 15.0, normals, beam, 0.0, 0.0375, 0.044, 600.0, 1500.0, 0.3),
                (True, np.zeros(0), np.zeros(7, np.int32), True), out, v, u2, layout)
    hit = ~miss
    ref = naive.mixed_legs(x[hit], r[hit], ping[hit], side[hit], dbeta[hit], prim[hit], rot, pos, rx_shift, 15.0,
                           normals, beam, ds[hit], 0.0375, 0.044, 600.0, 1500.0, 0.3)
    for k in keys:
        np.testing.assert_allclose(out[k][hit], ref[k], rtol=1e-9, atol=1e-12, err_msg=k)
    assert np.all(out["weight"][miss] == 0) and np.count_nonzero(out["weight"]) > n // 4


def test_swell_glint_kernels_match_naive():
    """kernels.swell_glints (a window of strips) finds every glint that a brute-force search over every strip finds,
    with the same lattices, for random sonars and spheres under a steep swell; kernels.glint_rays places the same
    rays (directions, body-frame layouts and rows) as the NumPy twin."""
    import naive
    from sonar_embree import kernels

    rng = np.random.default_rng(7)
    sea = se.SeaSurface(z_m=0.0, swell_height_m=1.0, swell_length_m=8.0, swell_direction_deg=30.0)
    g = sea.strips((-60.0, 60.0), (-60.0, 60.0))
    pos = np.column_stack([rng.uniform(-10, 10, 4), rng.uniform(-10, 10, 4), rng.uniform(-8, -3, 4)])
    centre = np.column_stack([rng.uniform(-30, 30, 6), rng.uniform(-30, 30, 6), rng.uniform(-12, -2, 6)])
    radius = rng.uniform(0.02, 0.6, 6)
    steps, slope = np.array([0.005, 0.01, 0.0375]), np.pi * 1.0 / 8.0
    table, count = np.empty((4, 6, 16, kernels.GLINT_WIDTH)), np.empty((4, 6), np.int32)
    kernels.swell_glints(centre, radius, pos, g.k, float(g.a[0]), float(g.a[1] - g.a[0]), g.z, slope, 80.0, 8.0,
                         steps, 4096.0, table, count)
    ref = naive.swell_glints(centre, radius, pos, g.k, g.a, g.z, 80.0, 8.0, steps, 4096.0)
    n_glints = 0
    for (b, j), want in ref.items():
        if want == "refused" or len(want) > 16:
            assert count[b, j] == -1
            continue
        assert count[b, j] == len(want), (b, j)
        for q, (strip, lattice) in enumerate(want):
            assert table[b, j, q, kernels.G_STRIP] == strip
            np.testing.assert_allclose(table[b, j, q, 1:], lattice, rtol=1e-9, atol=1e-12)
        n_glints += len(want)
    assert n_glints >= 6                                  # the case has glints to compare
    ping, cand, slot = np.nonzero(np.arange(16)[None, None, :] < count[..., None])
    glints = table[ping, cand, slot]
    counts = (glints[:, kernels.G_NS] * glints[:, kernels.G_NB]).astype(np.int64)
    start = np.concatenate(([0], np.cumsum(counts)))
    rot = se.Trajectory(pos, rng.uniform(0, 360, 4), rng.uniform(-5, 5, 4), rng.uniform(-5, 5, 4)).rotations()
    span, sides, shift = np.array([-0.05, 0.05, -1.2, 1.5]), np.array([True, False]), np.array([0.0, 0.01, -0.02, 0.0])
    n = int(start[-1])
    dirs, org, lay, row = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty((n, 5)), np.empty(n, int)
    kernels.glint_rays(glints, ping.astype(np.int64), start, g.k, rot, pos, span, sides, shift, dirs, org, lay, row)
    want_dirs, want_lay, want_row = naive.glint_rays(glints, ping, g.k, rot, pos, span, sides, shift)
    np.testing.assert_allclose(dirs, want_dirs, rtol=0, atol=1e-6)
    np.testing.assert_allclose(lay, want_lay, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(row, want_row)
    np.testing.assert_array_equal(org, pos[np.repeat(ping, counts)].astype(np.float32))
    assert (row >= 0).any() and (row < 0).any()
