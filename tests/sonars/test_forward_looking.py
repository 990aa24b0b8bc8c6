"""The forward-looking multibeam sonar (sonar_embree.sonars.forward_looking) against closed forms written here.

A uniform line array of M elements at spacing d steered to u_k = sin θ_k has the array factor
AF_k(u) = sin(Mψ/2)/(M sin(ψ/2)), ψ = k·d·(u − u_k) [Urick 1983, §3.4; Van Trees 2002, ch. 2]: −3 dB where
Mψ/2 = 1.3916 (sinc² = 1/2), first nulls at u − u_k = ±λ/(M·d). Each element (and the transmitter) is a baffled
membrane d × h (analytic.gamma_membrane). The flat floor's boresight beam is eq. (1) integrated here on a polar
grid: ∫ Γ⁴·AF²·μ·cos²θi·e^(−2α'r)/r⁴ dA over the ring c(t − τ) < 2r ≤ ct.
"""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import analytic
import sonar_embree as se

F0, C, M, FOV, VBW, TILT, H = 900e3, 1500.0, 32, 60.0, 20.0, 10.0, 5.0
LAM = C / F0
TAU, FS = 50e-6, 100e3


def _sonar(n_beams=61, **kw):
    return se.ForwardLooking(frequency_hz=F0, n_beams=n_beams, field_of_view_deg=FOV, n_elements=M,
                             vertical_beamwidth_deg=VBW, tilt_deg=TILT, max_range_m=25.0, sample_rate_hz=FS, **kw)


def _af2(u, u_k):
    psi = 2 * np.pi / LAM * (LAM / 2) * (u - u_k)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = (np.sin(M * psi / 2) / (M * np.sin(psi / 2))) ** 2
    return np.where(np.abs(np.sin(psi / 2)) < 1e-12, 1.0, out)


def _height():
    """The membrane height whose one-way −3 dB width is VBW: sinc(π·h/λ·sin(VBW/2)) = 10^(−3/20)."""
    x = brentq(lambda x: np.sin(x) / x - 10 ** (-3 / 20), 0.1, 3.0, xtol=1e-14)
    return x * LAM / (np.pi * np.sin(np.radians(VBW / 2)))


def test_array_factor_steering_width_and_nulls():
    """ForwardLooking.array_factor against the closed form: peak 1 at u_k, −3 dB full width 2·1.3916·λ/(π·M·d)
    in u, first nulls at u_k ± λ/(M·d), for beams at boresight, 20° and the edge."""
    fls = _sonar()
    angles = fls.beam_angles_deg()
    for k in (30, 50, 60):
        u_k = math.sin(math.radians(angles[k]))
        u = u_k + np.linspace(-0.2, 0.2, 40001)
        af2 = fls.array_factor(u, se.Acquisition.of(fls).sound_speed_m_s)[k] ** 2
        np.testing.assert_allclose(af2, _af2(u, u_k), atol=1e-12)
        assert u[np.argmax(af2)] == pytest.approx(u_k, abs=1e-5)
        above = u[af2 >= 0.5]
        assert above.max() - above.min() == pytest.approx(2 * 1.3916 * LAM / (np.pi * M * LAM / 2), rel=1e-3)
        null = u_k + LAM / (M * LAM / 2)
        assert fls.array_factor([null], se.Acquisition.of(fls).sound_speed_m_s)[k, 0] == pytest.approx(0.0, abs=1e-9)
    assert angles[0] == -FOV / 2 and angles[-1] == FOV / 2 and angles[30] == 0.0


def _still():
    """One ping at (0, 0, H) heading east (+x forward, −y starboard)."""
    return se.Trajectory(np.array([[0.0, 0.0, H]]), heading_deg=np.array([90.0]), times_s=np.zeros(1))


def _ball_scene(x, y, z, radius=0.05):
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    ball.apply_translation((x, y, z))
    return se.Scene().add(ball, label="ball", material=se.Material(backscatter_db=0.0))


def test_beam_pattern_of_a_small_sphere_across_densely_steered_beams():
    """A 10 cm sphere 10 m ahead on boresight, seen by 401 beams steered 0.075° apart: the beams' echo energies
    trace AF_k(u0)² = AF²(u0 − u_k) (shift-invariant in u), times the element's Γ⁴(u0), constant here: the peak's
    steering within one beam of the sphere's direction, the −3 dB width within 5 %, the first nulls 20 dB down
    and the main lobe within 0.5 dB."""
    r, z = 10.0, H
    scene = _ball_scene(r, 0.0, z, 0.05)
    traj = _still()
    fls = se.ForwardLooking(frequency_hz=F0, n_beams=401, field_of_view_deg=30.0, n_elements=M,
                            vertical_beamwidth_deg=VBW, tilt_deg=0.0, max_range_m=15.0, sample_rate_hz=FS)
    rec = se.simulate(scene, traj, fls, se.Pulse.cw(duration_s=TAU, taper=0.0),
                      fan=se.FanSettings(azimuth_oversample=16.0), start_time="2000-01-01")
    energy = rec.data[0].sum(axis=1)
    assert energy.max() > 0
    u_k = np.sin(np.radians(fls.beam_angles_deg()))
    got, want = energy / energy.max(), _af2(0.0, u_k)
    assert abs(u_k[np.argmax(got)]) <= np.diff(u_k).max()
    width = lambda y: np.ptp(u_k[y >= 0.5])                                    # noqa: E731
    assert width(got) == pytest.approx(width(want), rel=0.05)
    null = np.abs(np.abs(u_k) - LAM / (M * LAM / 2)) < 0.002
    assert null.sum() >= 2 and got[null].max() < 0.01
    lobe = np.abs(u_k) < 0.8 * LAM / (M * LAM / 2)
    np.testing.assert_allclose(10 * np.log10(got[lobe]), 10 * np.log10(want[lobe]), atol=0.5)


def test_a_sphere_appears_in_its_beam_and_range_bin():
    """A 0.6 m sphere at 25° to starboard and 15 m: the brightest beam is the one steered nearest its direction cosine
    u = sin(25°)·cos(el) (a line array measures the cone angle), its echo starts at 2(R − a)/c within one sample."""
    az, rng, a = math.radians(25.0), 15.0, 0.3
    z = H - 2.0
    scene = _ball_scene(rng * math.cos(az), -rng * math.sin(az), z, a)   # world y is port: −y starboard
    traj = _still()
    fls = _sonar()
    rec = se.simulate(scene, traj, fls, se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")
    big_r = math.hypot(rng, H - z)
    u = math.sin(az) * rng / big_r
    k_want = int(np.argmin(np.abs(np.sin(np.radians(fls.beam_angles_deg())) - u)))
    k_got, _ = np.unravel_index(np.argmax(rec.data[0]), rec.data[0].shape)
    assert k_got == k_want
    beam = rec.data[0, k_got]
    first = rec.time_s[np.flatnonzero(beam > 1e-6 * beam.max())[0]]
    assert abs(first - 2 * (big_r - a) / C) <= 1.0 / FS


def _floor_quadrature(t, alpha_db_m, mu_db=-20.0):
    """Expected intensity of the boresight beam over a Lambert floor μ at altitude H, at times t (s)."""
    rho = np.concatenate([np.linspace(0, 2, 401)[:-1], np.linspace(2, 30, 2801)])
    phi = np.linspace(-np.pi, np.pi, 7201)             # the baffle (Γ = 0 behind it) lets in the floor behind nadir
    p, f = rho[:, None], phi[None, :]
    r = np.sqrt(p ** 2 + H ** 2)
    fwd, stb, down = p * np.cos(f) / r, p * np.sin(f) / r, H / r
    g = analytic.gamma_membrane(stb, fwd, down, f0=F0, c=C, lx=LAM / 2, ly=_height(), tilt_deg=TILT)
    alpha = alpha_db_m * np.log(10) / 10
    dens = g ** 4 * _af2(stb, 0.0) * 10 ** (mu_db / 10) * down ** 2 * np.exp(-2 * alpha * r) / r ** 4
    ring = np.trapezoid(dens, phi, axis=1) * rho
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (ring[1:] + ring[:-1]) * np.diff(rho))])
    L = 2 * r[:, 0]
    return np.interp(C * t, L, cum, left=0.0, right=cum[-1]) - np.interp(C * (t - TAU), L, cum, left=0.0,
                                                                          right=cum[-1])


def test_flat_floor_boresight_beam_matches_quadrature():
    floor = se.Scene().add(se.seafloor.flat((200.0, 200.0)), material=se.Material(backscatter_db=-20.0),
                           label="seafloor")
    traj = _still()
    rec = se.simulate(floor, traj, _sonar(), se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")
    q = _floor_quadrature(rec.time_s, rec.acquisition.alpha_db_per_m)
    got = rec.data[0, 30]
    onset = np.abs(rec.time_s - 2 * H / C) <= 2.5 / FS
    # within 25 dB of the peak: at the vertical pattern's second null (5.5 m, 26 dB down) the fan's rays, placed
    # for range, sample the null's depth to 0.53 dB (docs/benchmarks.md)
    lit = (q > 10 ** -2.5 * q.max()) & ~onset & (rec.time_s < 2 * 24.0 / C)
    assert lit.sum() > 1500
    err = 10 * np.log10(got[lit] / q[lit])
    assert np.max(np.abs(err)) < 0.5, np.max(np.abs(err))


def test_fan_image_zarr_and_toml(tmp_path):
    """The shipped config loads as a ForwardLooking; the fan display puts a sphere's echo at its position within
    two pixels; the Zarr store holds one (ping, beam, sample) intensity with the steering angles; a swell and
    non-coherent speckle are refused naming what is missing."""
    import xarray as xr

    from sonar_embree.record import registry
    from sonar_embree.runs import runconfig
    from sonar_embree.sonars.forward_looking import fan_image

    cfg = runconfig.load_run_config("asset:fls_harbour.toml")
    assert isinstance(cfg.sonar, se.ForwardLooking) and cfg.sonar.n_beams == 256 and cfg.output.fan
    x, y, a = 12.0, -4.0, 0.3                                           # 4 m to starboard (world −y)
    rec = se.simulate(_ball_scene(x, y, H, a), _still(), _sonar(), se.Pulse.cw(duration_s=TAU, taper=0.0),
                      start_time="2000-01-01")
    img, (left, right, near, far) = fan_image(rec, pixel_m=0.05)
    row, col = np.unravel_index(np.nanargmax(img), img.shape)
    stbd, fwd = left + (col + 0.5) * 0.05, far - (row + 0.5) * 0.05
    assert math.hypot(stbd - 4.0 * (1 - a / math.hypot(x, y)), fwd - x * (1 - a / math.hypot(x, y))) < 2 * 0.05 + 0.02
    paths = registry.write_each(rec, str(tmp_path), ["fan", "zarr"])
    assert len(paths) == 2
    ds = xr.open_zarr(tmp_path / "record.zarr")
    assert ds["intensity"].dims == ("ping", "beam", "sample") and ds.sizes["beam"] == 61
    np.testing.assert_array_equal(ds["intensity"].values, rec.data)
    np.testing.assert_allclose(ds["beam_angle_deg"].values, rec.sonar.beam_angles_deg())
    with pytest.raises(se.ConfigError, match="coherent"):
        se.simulate(_ball_scene(x, y, H), _still(), _sonar(), speckle=True, detection="incoherent", band="carrier")
    with pytest.raises(se.ConfigError, match="grating lobes"):
        se.Acquisition(se.ForwardLooking(element_spacing_m=0.0015))
    with pytest.raises(se.ConfigError, match="n_beams"):
        se.ForwardLooking(n_beams=2.5)


@pytest.mark.parametrize("speckle", [False, True])
def test_receiver_noise_is_added_per_beam(speckle):
    """With a source level and nothing in view, each beam holds the receiver's noise N·fs (µPa²; N the ambient
    noise over the beam's DI, the element's plus 10·log10 M, and the self-noise): expected exactly, speckled
    within 5 % on average; and XTF is refused for a multibeam in one short line."""
    far = _ball_scene(-10.0, 0.0, 200.0)                 # in range, behind the baffle: the beams hear noise only
    traj = se.Trajectory(np.array([[0.0, 0.0, 200.0]]), heading_deg=np.array([90.0]), times_s=np.zeros(1))
    sonar = _sonar(source_level_db=200.0, self_noise_db_per_hz=20.0)
    rec = se.simulate(far, traj, sonar, se.Pulse.cw(duration_s=TAU, taper=0.0), speckle=speckle,
                      start_time="2000-01-01")
    amb = rec.environment.noise.spectral_density_db(F0)
    elem_di = analytic.directivity_index_db(analytic.membrane_pattern(LAM / 2, _height(), LAM))
    n = 10 ** ((amb - elem_di - 10 * np.log10(M)) / 10) + 10 ** 2.0
    if speckle:
        assert rec.data.mean() == pytest.approx(n * FS, rel=0.05)
    else:
        np.testing.assert_allclose(rec.data, n * FS, rtol=1e-9)
    with pytest.raises(se.ConfigError, match=r"beam000, beam001, beam002, … \(61 channels\)$"):
        rec.to_xtf("never.xtf")


def test_labels_per_beam_and_sample():
    """Ground truth per beam along the azimuth line nearest its steering direction: a 1 m ball 13 m ahead at
    18° is an object in the beams its cone angle spans and in no other, its shadow lies behind it in the same
    beams; the floor samples of the boresight beam sit at z = 0 and ground range √(R² − H²) (within a sample's
    footprint); the object echoes are beamformed as the record is (the ball's echo spreads into neighbours by
    the array's side lobes); the labels go through the Zarr store with a beam dimension."""
    import trimesh
    import xarray as xr

    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0)), label="seafloor")
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    ball.apply_translation((12.0, -4.0, 0.5))
    scene.add(ball, label="ball")
    fls = _sonar()
    rec = se.simulate(scene, _still(), fls, se.Pulse.cw(duration_s=TAU, taper=0.0), labels=True,
                      start_time="2000-01-01")
    lab = rec.labels
    assert lab.kind.shape == (61, 1, rec.data.shape[2])
    big_r = math.dist((0, 0, H), (12.0, -4.0, 0.5))
    u_c, half = 4.0 / big_r, math.asin(0.5 / big_r)                     # the centre's cosine to starboard
    u_k = np.sin(np.radians(fls.beam_angles_deg()))
    obj_beams = np.unique(np.argwhere(lab.kind[:, 0] == 2)[:, 0])
    assert obj_beams.size >= 3 and np.all(np.abs(u_k[obj_beams] - u_c) <= math.sin(half) + 0.01)
    for k in obj_beams:
        first_shadow = np.flatnonzero(lab.kind[k, 0] == 3)
        assert first_shadow.size and rec.slant_range_m[first_shadow[0]] > big_r - 0.5
    floor = (lab.kind[30, 0] == 1) & (rec.slant_range_m > H + 0.05)     # past the nadir sample's footprint
    assert floor.sum() > 1000
    r = rec.slant_range_m[floor]
    np.testing.assert_allclose(lab.height_m[30, 0][floor], 0.0, atol=0.02)
    np.testing.assert_allclose(lab.ground_range_m[30, 0][floor], np.sqrt(r ** 2 - H ** 2), atol=0.05)
    echo_beams = np.unique(np.argwhere(lab.echo_object[:, 0] == 1)[:, 0])
    assert set(obj_beams) <= set(echo_beams)
    ds = rec.to_xarray()
    assert ds["label_kind"].dims == ("beam", "ping", "sample")
    np.testing.assert_array_equal(ds["label_kind"].values, lab.kind)
    with pytest.raises(se.ConfigError, match="multibeam"):
        lab.waterfall()


@pytest.mark.parametrize("band", ["baseband", "carrier"])
def test_beamformed_speckle_is_fully_developed_in_either_band(band):
    """Coherent speckle beamformed from the azimuth lines' complex signals, synthesised in baseband or on the
    carrier: per sample exponential intensity about the expected record (mean 1, contrast 1, within 5 % / 10 %)."""
    floor = se.Scene().add(se.seafloor.flat((200.0, 200.0)), material=se.Material(backscatter_db=-20.0),
                           label="seafloor")
    traj = se.Trajectory.line((0.0, 0.0, H), (30.0, 0.0, H), 4).stop_and_hop()
    sonar = se.ForwardLooking(n_elements=16, n_beams=33, field_of_view_deg=60.0, max_range_m=14.0)
    expected = se.simulate(floor, traj, sonar)
    speckled = se.simulate(floor, traj, sonar, speckle=True, band=band, seed=2)
    band_ = (expected.slant_range_m > 6.0) & (expected.slant_range_m < 13.0)
    ratio = speckled.data[:, :, band_] / expected.data[:, :, band_]
    assert ratio.size > 40_000
    assert abs(ratio.mean() - 1) < 0.05 and abs(ratio.std() / ratio.mean() - 1) < 0.1


def test_a_sweep_varies_the_forward_looking_sonar(tmp_path):
    """A batch sweep over the forward-looking sonar's own keys (here its beam count):
    every job's sonar is built from its [sonar] table and [vary] entries, checked before any work."""
    from sonar_embree.runs.sweep import load_sweep

    text = """\
[sweep]
name = "fls"
outputs = ["zarr", "npz"]

[sonar]
type = "forward_looking"
n_elements = 16
field_of_view_deg = 40.0
max_range_m = 8.0

[vary]
"sonar.n_beams" = [9, 17]

[[scenes]]
name = "flat"
  [[scenes.objects]]
  seafloor = "flat"
  size_m = [30.0, 30.0]

[[trajectories]]
name = "pass"
kind = "line"
start = [0.0, 0.0, 3.0]
end = [1.0, 0.0, 3.0]
n_pings = 2
"""
    (tmp_path / "s.toml").write_text(text)
    sweep = load_sweep(tmp_path / "s.toml")
    assert [(type(j.sonar).__name__, j.sonar.n_beams) for j in sweep.jobs] == [("ForwardLooking", 9),
                                                                              ("ForwardLooking", 17)]
    (tmp_path / "t.toml").write_text(text.replace('"sonar.n_beams" = [9, 17]', '"sonar.n_beams" = [0, 17]'))
    with pytest.raises(se.ConfigError, match="n_beams"):
        load_sweep(tmp_path / "t.toml")


def test_cli_renders_the_shipped_config_shortened(tmp_path):
    """``sonar-embree render`` on the shipped forward-looking config (2 pings, 33 beams from 16 elements, 12 m):
    the fan display, the record and the Zarr store are written; the record's beams are the config's."""
    import imageio.v3 as iio

    from sonar_embree.runs import cli, runconfig

    text = open(runconfig.assets.path("asset:fls_harbour.toml")).read()
    for old, new in (("n_pings = 20", "n_pings = 2"), ("n_beams = 256", "n_beams = 33"),
                     ("n_elements = 128", "n_elements = 16"), ("max_range_m = 30.0", "max_range_m = 12.0")):
        assert old in text
        text = text.replace(old, new)
    cfg = tmp_path / "fls.toml"
    cfg.write_text(text)
    out = tmp_path / "out"
    assert cli.main(["render", str(cfg), "-o", str(out), "--no-progress"]) == 0
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["fan.png", "record.npz", "record.zarr"]
    rec = se.Record.load(out / "record.npz")
    assert isinstance(rec.sonar, se.ForwardLooking) and rec.data.shape[:2] == (2, 33)
    img = iio.imread(out / "fan.png")
    assert img.ndim == 2 and img.max() == 255 and (img == 0).any()            # a fan on black


def test_memory_is_estimated_before_the_rays_are_cast(monkeypatch):
    """Issue 33, finding 10: a forward-looking ping's rays grow with n_elements (128: ~1.9 M, 0.5 GB) and a
    4096-element array ended in a MemoryError traceback. The fan's rays are counted after the probes and refused
    in one line when they cannot fit in half the machine's memory (a 0.2 GiB machine here); the count is the
    one the fan then casts. A vertical beam of 1e-9° (an all-zero record before) is refused."""
    from sonar_embree import checks

    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0)), label="seafloor")
    sonar = se.ForwardLooking(max_range_m=30.0)
    line = se.Trajectory.line((0.0, 0.0, 10.0), (0.1, 0.0, 10.0), 2)
    rec = se.simulate(scene, line, sonar)
    monkeypatch.setattr(checks, "physical_memory_bytes", lambda: 2 ** 30 // 5)
    with pytest.raises(se.ConfigError, match=r"the ray fan: 1 ping\(s\) need (\d+) rays, about 0.\d GiB in memory, "
                                             r"more than half this machine's 0.2 GiB; .* n_elements") as err:
        se.simulate(scene, line, sonar)
    n = int(err.value.args[0].split(" need ")[1].split(" rays")[0])
    from sonar_embree import sonars

    probes = sonars.front_end(se.Acquisition.of(sonar).for_pulse(se.Pulse.cw()), se.FanSettings()).plan.n_probe
    assert n + probes == rec.attrs["rays_per_ping"]                  # what the fan casts, less its probes
    with pytest.raises(se.ConfigError, match=r"vertical_beamwidth_deg must be >= 0.1, got 1e-09"):
        se.ForwardLooking(vertical_beamwidth_deg=1e-9)
    with pytest.raises(se.ConfigError, match=r"horizontal_beamwidth_deg must be >= 0.1"):
        se.MSIS(horizontal_beamwidth_deg=0.01)


def test_a_block_too_big_for_memory_is_cast_a_ping_at_a_time(monkeypatch):
    """Blocks hold several pings (4 at first; later a ping per thread where rays allow). On a machine where one
    ping's rays fit in half its memory but a block's do not, the run casts that block a ping at a time (same bits)
    instead of refusing it; a ping that does not fit alone is still refused in one line."""
    from sonar_embree import checks

    scene = se.Scene().add(se.seafloor.flat((100.0, 100.0)), label="seafloor")
    line = se.Trajectory.line((0.0, 0.0, 10.0), (0.3, 0.0, 10.0), 4)
    whole = se.simulate(scene, line, se.Sonar(max_range_m=30.0))
    rays = int(np.max(whole.attrs["rays_per_ping"]))
    monkeypatch.setattr(checks, "physical_memory_bytes", lambda: 3 * rays * checks.BYTES_PER_RAY)  # 1.5 pings
    small = se.simulate(scene, line, se.Sonar(max_range_m=30.0))
    assert np.array_equal(small.starboard, whole.starboard) and np.array_equal(small.port, whole.port)
    monkeypatch.setattr(checks, "physical_memory_bytes", lambda: rays * checks.BYTES_PER_RAY)     # half a ping
    with pytest.raises(checks.RaysMemoryError, match=r"the ray fan: 1 ping\(s\) need"):
        se.simulate(scene, line, se.Sonar(max_range_m=30.0))


def test_an_all_zero_record_warns(caplog):
    """Finding 10's class: a record without a single echo (a box in range but outside every beam) is never silent."""
    import trimesh

    from sonar_embree import checks

    checks._warned.clear()
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    box.apply_translation((15.0, 0.0, 10.0))                       # 15 m ahead of a side-scan, level with it
    caplog.set_level("WARNING", logger="sonar_embree.checks")
    rec = se.simulate(se.Scene().add(box, label="box"), se.Trajectory.line((0.0, 0.0, 10.0), (0.1, 0.0, 10.0), 2),
                      se.Sonar(max_range_m=20.0))
    assert rec.data.max() == 0.0
    assert any("the record is all zero" in r.getMessage() for r in caplog.records)
    checks._warned.clear()
