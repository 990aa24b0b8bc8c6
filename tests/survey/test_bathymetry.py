"""Interferometric side-scan (docs/physics.md §18b): a vertical receiver pair over a flat floor and over a 10° slope.
The phase difference against the closed form Δφ = −(2π/λ)(|X − p_b| − |X − p_0|), X the floor point at the
sample's slant range in the across-track plane (a quadratic's root, written here); the soundings' depth error
below 1 % of the slant range where the SNR (the speckle-free record over the noise) is above 20 dB; the gridded
GeoTIFF beside the scene's truth, read back with rasterio."""
import dataclasses
import math

import numpy as np
import pytest
import rasterio
import trimesh

import sonar_embree as se
from sonar_embree.io.owner import MANIFEST
from sonar_embree.errors import ConfigError
from sonar_embree.signal.interferometry import baseline_geometry, cross_spectrum, depression_angle
from sonar_embree.survey import bathymetry
from sonar_embree.survey.bathymetry import interferometric_points
from sonar_embree.survey.mosaic import write_truth

F0, C, H = 300e3, 1500.0, 10.0
LAM = C / F0
NOISE_DB_PER_HZ = -188.0    # unit-source record units: the SNR crosses 20 dB inside the range window


def _scene(slope_deg):
    """A floor rising to starboard (−y) at ``slope_deg``: z = tan(slope)·(−y)."""
    floor = se.seafloor.flat(size_m=(30, 160))
    v = floor.vertices.copy()
    v[:, 2] = math.tan(math.radians(slope_deg)) * (-v[:, 1])
    sc = se.Scene()
    sc.add(trimesh.Trimesh(v, floor.faces), material=se.Material(backscatter_db=-20), label="seafloor")
    return sc


def _across(r, slope_deg, side):
    """The floor's across-track distance s at slant range r from (0, 0, H): s² + (H − side·m·s)² = r², m = tan slope
    (side +1 starboard, where the floor rises; −1 port, where it falls)."""
    m = side * math.tan(math.radians(slope_deg))
    with np.errstate(invalid="ignore"):                                       # NaN before the floor's first return
            return (H * m + np.sqrt(H * H * m * m - (1 + m * m) * (H * H - r * r))) / (1 + m * m)


def _simulate(slope_deg, noise=NOISE_DB_PER_HZ, speckle=True):
    arr = se.ReceiverArray.vertical(LAM) if speckle else None
    sonar = se.Sonar(frequency_hz=F0, length_m=0.1, height_m=0.005, tilt_deg=30, max_range_m=60, receive_array=arr)
    traj = se.Trajectory.line(start=(-1, 0, H), end=(1, 0, H), n_pings=5)
    return se.simulate(_scene(slope_deg), traj, sonar, se.Pulse.cw(duration_s=50e-6), speckle=speckle, seed=1,
                       noise_db_per_hz=noise)


@pytest.fixture(scope="module", params=[0.0, 10.0], ids=["flat", "slope10"])
def case(request):
    rec = _simulate(request.param)
    clean = _simulate(request.param, noise=None, speckle=False)
    snr = clean.data / (10 ** (NOISE_DB_PER_HZ / 10) * rec.sonar.sample_rate_hz)   # (pings, sides, samples)
    return request.param, rec, snr


def test_the_phase_difference_is_the_closed_form(case):
    slope, rec, snr = case
    r = rec.slant_range_m
    for ch, side in ((0, -1.0), (1, 1.0)):
        z = rec.element_data[:, ch]
        dphi = np.angle(cross_spectrum(z[:, 0], z[:, 1], (1, 5))[0])
        s = _across(r, slope, side)
        x = np.stack([np.zeros_like(s), s, -(H - side * math.tan(math.radians(slope)) * s)], axis=1)  # from p_0
        want = -2 * np.pi / LAM * (np.linalg.norm(x - [0, 0, LAM], axis=1) - r)
        good = (snr[:, ch].min(0) > 100) & (r > 14)
        assert good.sum() > 1000
        miss = np.angle(np.exp(1j * (dphi - want)))[:, good]
        bins = np.array_split(np.arange(good.sum()), 12)                            # about 2 m each
        means = [np.angle(np.mean(np.exp(1j * miss[:, b]))) for b in bins]
        np.testing.assert_allclose(means, 0.0, atol=0.05)


def test_soundings_are_within_one_percent_of_the_slant_range(case):
    slope, rec, snr = case
    cloud = interferometric_points(rec, window=(5, 11))
    r = rec.slant_range_m[cloud.sample]
    good = (snr[cloud.ping, cloud.channel, cloud.sample] > 100) & (r > 14)
    weak = (snr[cloud.ping, cloud.channel, cloud.sample] < 100) & (r > 14)
    assert good.sum() > 10_000 and weak.sum() > 1000                               # the noise is heard far out

    def rms(m):
        x, y, z = cloud.xyz_m[m].T
        err = (z - math.tan(math.radians(slope)) * (-y)) / r[m]
        return np.sqrt(np.mean(err ** 2)), np.mean(err)

    assert rms(good)[0] < 0.01 and abs(rms(good)[1]) < 0.003                      # and no bias
    assert rms(weak)[0] > 1.4 * rms(good)[0]                                       # the noise tells


def test_the_grid_lies_on_the_truth_in_geotiffs(case, tmp_path):
    slope, rec, snr = case
    cloud = interferometric_points(rec, window=(5, 11), min_coherence=0.9)
    grid = bathymetry.grid(cloud, pixel_m=1.0, bounds_m=(-2, -40, 2, 40))
    grid.to_geotiff(tmp_path / "bathy.tif")
    write_truth(tmp_path / "truth.tif", _scene(slope), grid)
    with rasterio.open(tmp_path / "bathy.tif") as a, rasterio.open(tmp_path / "truth.tif") as b:
        assert a.transform == b.transform and a.descriptions[1] == "height_m"
        got, want = a.read(2), b.read(1)
    across = np.abs(grid.centres()[1])[:, None] * np.ones_like(got)
    filled = np.isfinite(got) & (across >= 12)                                   # beyond the nadir's first returns
    assert filled.sum() > 100
    np.testing.assert_array_less(np.abs(got - want)[filled], 0.01 * np.hypot(across[filled], H))
    cloud.to_xyz(tmp_path / "points.xyz")
    back = np.loadtxt(tmp_path / "points.xyz")
    np.testing.assert_allclose(back, cloud.xyz_m, atol=1e-4)


def test_depression_angle_inverts_the_phase_and_its_sector():
    b, beta = baseline_geometry((0, 0, 0), (0, 0, 2 * LAM))
    assert b == pytest.approx(2 * LAM) and beta == pytest.approx(math.pi / 2)
    theta = np.radians(np.linspace(20, 40, 21))                  # inside the sector about 30°: ±(λ/2b) in sin θ
    dphi = np.angle(np.exp(1j * 2 * np.pi / LAM * b * np.cos(theta + beta)))
    np.testing.assert_allclose(depression_angle(dphi, b, beta, LAM, math.radians(30)), theta, atol=1e-12)
    b2, beta2 = baseline_geometry((0, 0.1, 0), (0, 0.1 + 0.01, 0.01))     # tilted 45°
    assert beta2 == pytest.approx(math.pi / 4)
    with pytest.raises(ConfigError, match="across track"):
        baseline_geometry((0, 0, 0), (0.1, 0, 0))
    with pytest.raises(ConfigError, match="window"):
        cross_spectrum(np.ones((2, 5)), np.ones((2, 5)), (0, 3))


def test_a_record_without_elements_is_refused(tmp_path):
    rec = se.simulate(_scene(0.0), se.Trajectory.line(start=(0, 0, H), end=(1, 0, H), n_pings=2),
                      se.Sonar(max_range_m=15))
    with pytest.raises(ConfigError, match="no element data"):
        interferometric_points(rec)
    (tmp_path / "mine.xyz").write_text("1 2 3\n")
    cloud = interferometric_points(_simulate(0.0, noise=None), window=(1, 3))
    with pytest.raises(ConfigError, match="not a XYZ file"):
        cloud.to_xyz(tmp_path / "mine.xyz")                                  # a user's file is not replaced
    assert (tmp_path / "mine.xyz").read_text() == "1 2 3\n"


def test_the_labels_hold_the_true_depth_of_every_interferometric_sample():
    """simulate(labels=True) with a receiver pair: each sample's ``height_m`` and ``ground_range_m`` are the floor
    point's (the closed form's), and the soundings lie on them."""
    slope = 10.0
    sonar = se.Sonar(frequency_hz=F0, length_m=0.1, height_m=0.005, tilt_deg=30, max_range_m=40,
                     receive_array=se.ReceiverArray.vertical(LAM))
    traj = se.Trajectory.line(start=(-1, 0, H), end=(1, 0, H), n_pings=5)
    rec = se.simulate(_scene(slope), traj, sonar, se.Pulse.cw(duration_s=50e-6), speckle=True, seed=1, labels=True)
    r = rec.slant_range_m
    far = r > 14
    for ch, side in ((0, -1.0), (1, 1.0)):
        s = _across(r[far], slope, side)
        np.testing.assert_allclose(rec.labels.ground_range_m[ch][:, far], s[None].repeat(5, 0), atol=0.02)
        np.testing.assert_allclose(rec.labels.height_m[ch][:, far], (side * math.tan(math.radians(slope)) * s)[None]
                                   .repeat(5, 0), atol=0.02)
    cloud = interferometric_points(rec, window=(5, 11))
    keep = r[cloud.sample] > 14
    truth = rec.labels.height_m[cloud.channel[keep], cloud.ping[keep], cloud.sample[keep]]
    err = (cloud.xyz_m[keep, 2] - truth) / r[cloud.sample[keep]]
    assert np.sqrt(np.mean(err ** 2)) < 0.01


def test_render_writes_soundings_and_their_grid(tmp_path, capsys):
    """``[output] soundings = true, bathymetry = true`` of a config with a vertical pair: soundings.xyz and
    bathymetry.tif (height, coherence, count) on the flat floor within 1 % of the range beyond the nadir; a sonar
    without an array is refused in one line. The local scene is placed on the Earth (``geo_origin_deg``): the
    GeoTIFF is in the origin's UTM zone with the origin at its projected point (pyproj here), as the XTF's lat/lon
    are; before, it had no CRS."""
    import pyproj

    from sonar_embree.runs.cli import main

    east, north = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32631", always_xy=True).transform(5.0, 43.0)

    def config(array):
        return (f'[sonar]\nfrequency_hz = {F0}\nlength_m = 0.1\nheight_m = 0.005\ntilt_deg = 30.0\n'
                f'max_range_m = 40.0\n{array}\n[pulse]\nkind = "cw"\nduration_s = 50e-6\n[simulation]\n'
                'speckle = true\nseed = 1\n[trajectory]\nkind = "line"\nstart = [-1.0, 0.0, 10.0]\n'
                'end = [1.0, 0.0, 10.0]\nn_pings = 5\n[[objects]]\nseafloor = "flat"\nsize_m = [30.0, 100.0]\n'
                'label = "seafloor"\n[output]\npng = false\nnpz = false\nsoundings = true\nbathymetry = true\n'
                'bathymetry_pixel_m = 1.0\ngeo_origin_deg = [43.0, 5.0]\n')

    (tmp_path / "ifsss.toml").write_text(config(f"receive_array = {{ kind = \"vertical\", baseline_m = {LAM} }}"))
    assert main(["render", str(tmp_path / "ifsss.toml"), "-o", str(tmp_path / "out"), "--no-progress"]) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [MANIFEST, "bathymetry.tif", "soundings.xyz"]
    xyz = np.loadtxt(tmp_path / "out" / "soundings.xyz")
    assert xyz.shape[1] == 3 and xyz.shape[0] > 5000
    with rasterio.open(tmp_path / "out" / "bathymetry.tif") as src:
        assert src.descriptions == ("height_m", "coherence", "count") and src.res == (1.0, 1.0)
        assert src.crs.to_epsg() == 32631 and abs(0.5 * (src.bounds.left + src.bounds.right) - east) < 3.0
        height, count = src.read(1), src.read(3)
        ys = np.asarray(src.xy(np.arange(src.height), np.zeros(src.height, dtype=int))[1]) - north
    far = (np.abs(ys)[:, None] > 14) & (np.abs(ys)[:, None] < 35) & (count > 20)
    assert far.sum() > 50
    np.testing.assert_array_less(np.abs(height[far]), 0.01 * 40.0)
    (tmp_path / "plain.toml").write_text(config(""))
    capsys.readouterr()
    assert main(["render", str(tmp_path / "plain.toml"), "-o", str(tmp_path / "plain"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "receive_array" in err and len(err.strip().splitlines()) == 1
    assert not any(p.is_file() for p in (tmp_path / "plain").rglob("*"))              # nothing half-written


def test_a_short_pair_unwraps_a_long_baseline():
    """Three receivers at 0, λ and 4λ up, over the 10° slope (each side its own angles): the 4λ pair alone is
    ambiguous over the swath (its sector about the tilt is a quarter of the λ pair's) and misplaces most soundings;
    unwrapped sample by sample by the λ pair's angles it is right everywhere, and more precise than the λ pair
    alone."""
    arr = se.ReceiverArray(((0.0, 0.0, 0.0), (0.0, 0.0, LAM), (0.0, 0.0, 4 * LAM)))
    sonar = se.Sonar(frequency_hz=F0, length_m=0.1, height_m=0.005, tilt_deg=30, max_range_m=60, receive_array=arr)
    traj = se.Trajectory.line(start=(-1, 0, H), end=(1, 0, H), n_pings=5)
    rec = se.simulate(_scene(10.0), traj, sonar, se.Pulse.cw(duration_s=50e-6), speckle=True, seed=1)

    def rms(**kw):
        cloud = interferometric_points(rec, **kw)
        r = rec.slant_range_m[cloud.sample]
        far = (r > 14) & (r < 45)
        x, y, z = cloud.xyz_m[far].T
        return np.sqrt(np.mean(((z - math.tan(math.radians(10.0)) * (-y)) / r[far]) ** 2))

    short, long_alone, long_unwrapped = rms(pair=(0, 1)), rms(pair=(0, 2)), rms(pair=(0, 2), coarse_pair=(0, 1))
    assert long_alone > 0.05
    assert long_unwrapped < 0.01 and long_unwrapped < 0.9 * short


def test_soundings_above_the_sonar_are_left_out_and_said(caplog):
    """Issue 49: a pair longer than λ/2 unwrapped about the tilt alone puts some soundings above the sonar (into
    soundings.xyz and bathymetry.tif, before); they are left out with a one-line count, and a NaN coherence
    threshold is refused."""
    arr = se.ReceiverArray(((0.0, 0.0, 0.0), (0.0, 0.0, 1.0667 * LAM)))           # as 4 mm at λ = 3.75 mm
    sonar = se.Sonar(frequency_hz=F0, length_m=0.1, height_m=0.005, tilt_deg=10, max_range_m=60, receive_array=arr)
    traj = se.Trajectory.line(start=(-1, 0, H), end=(1, 0, H), n_pings=5)
    rec = se.simulate(_scene(0.0), traj, sonar, se.Pulse.cw(duration_s=50e-6), speckle=True, seed=1)
    with caplog.at_level("WARNING"):
        cloud = interferometric_points(rec)
    assert cloud.xyz_m.shape[0] > 1000 and np.all(cloud.xyz_m[:, 2] < H)
    assert "lie above the sonar" in caplog.text
    assert "is 5.33 mm apart, longer than λ/2 = 2.5 mm, and no coarse_pair unwraps it" in caplog.text   # issue 53
    caplog.clear()
    with caplog.at_level("WARNING"):                     # a pair within λ/2, or a long one unwrapped: no warning
        short = se.ReceiverArray(((0.0, 0.0, 0.0), (0.0, 0.0, 0.4 * LAM), (0.0, 0.0, 1.0667 * LAM)))
        rec2 = se.simulate(_scene(0.0), traj, dataclasses.replace(sonar, receive_array=short),
                           se.Pulse.cw(duration_s=50e-6), speckle=True, seed=1)
        interferometric_points(rec2, pair=(0, 1))
        interferometric_points(rec2, pair=(0, 2), coarse_pair=(0, 1))
    assert "longer than λ/2" not in caplog.text
    with pytest.raises(ConfigError, match="min_coherence must be finite"):
        interferometric_points(rec, min_coherence=float("nan"))
