"""Seabed features (sonar_embree.scene.features): their geometry against the closed forms written here, the boulder
sizes against their power law, the labels of a seabed, and a boulder's shadow against the tangent-ray closed form."""
import math

import numpy as np
import pytest
from scipy import stats

import sonar_embree as se
from sonar_embree.errors import ConfigError
from sonar_embree.scene import features as F


def _grid(n=801, size=40.0):
    x = np.linspace(-size / 2, size / 2, n)
    return np.meshgrid(x, x)


@pytest.mark.parametrize("asym", [0.5, 0.7, 0.85])
def test_sand_waves_asymmetry_slopes_and_crest_direction(asym):
    lam, h, heading = 8.0, 0.6, 30.0
    t = np.linspace(0.0, 3 * lam, 30001)                                 # a transect across the crests
    hd = math.radians(heading)
    x, y = t * math.cos(hd), -t * math.sin(hd)                            # across = x cos h − y sin h = t
    z, mask = F.sand_waves(x, y, lam, h, heading, asym)
    assert mask.all() and z.min() == pytest.approx(0.0, abs=1e-9) and z.max() == pytest.approx(h, abs=1e-6)
    slope = np.gradient(z, t)
    up, down = slope[slope > 0], slope[slope < 0]
    assert np.mean(-down) / np.mean(up) == pytest.approx(asym / (1 - asym), rel=0.02)   # lee / stoss
    assert -down.min() == pytest.approx(math.pi * h / (2 * (1 - asym) * lam), rel=1e-3)  # steepest lee slope
    along = F.sand_waves(x + 5.0 * math.sin(hd), y + 5.0 * math.cos(hd), lam, h, heading, asym)[0]
    np.testing.assert_allclose(along, z, atol=1e-9)                      # constant along the crests


def test_trawl_mark_depth_width_and_ends():
    xx, yy = _grid()
    z, mask = F.trawl_mark(xx, yy, (-10.0, 0.0), (10.0, 0.0), depth_m=0.2, width_m=1.0, separation_m=4.0)
    col = np.argmin(np.abs(xx[0]))                                       # x = 0: across both grooves
    prof, ys = z[:, col], yy[:, col]
    assert prof[np.argmin(np.abs(ys - 2.0))] == pytest.approx(-0.2, abs=1e-3)
    assert np.interp(2.5, ys, prof) == pytest.approx(-0.1, abs=2e-3)   # half depth at half the width
    assert np.interp(0.0, ys, prof) > -1e-3                               # between the doors: untouched
    assert np.all(z[np.abs(xx) > 10.05] == 0.0) and mask[np.argmin(np.abs(ys - 2.0)), col]
    with pytest.raises(ConfigError, match="same point"):
        F.trawl_mark(xx, yy, (1.0, 1.0), (1.0, 1.0))


def test_scour_and_outcrop():
    xx, yy = _grid()
    z, m = F.scour(xx, yy, (3.0, -2.0), 5.0, 0.5)
    r = np.hypot(xx - 3.0, yy - 2.0 * -1)
    assert z.min() == pytest.approx(-0.5, abs=1e-3) and np.all(np.abs(z[r >= 5.0]) < 1e-12) and m.sum() > 0
    np.testing.assert_allclose(z[r < 5.0], -0.5 * (1 - (r[r < 5.0] / 5.0) ** 2) ** 2, atol=1e-12)
    z, m = F.outcrop(xx, yy, (0.0, 0.0), (16.0, 10.0), 1.2, roughness=0.2, seed=1)
    inner = np.hypot(xx / 8.0, yy / 5.0) < 0.7
    assert np.all(z[~m] == 0.0) and 0.9 < z[inner].mean() < 1.5 and z[inner].std() > 0.01


def test_dress_adds_only_what_the_dem_cannot_hold():
    rng = np.random.default_rng(0)
    coarse = np.cumsum(rng.normal(size=(33, 41)), axis=1) * 0.05
    plain, d = F.dress(coarse, 2.0, factor=4, rms_m=0.0)
    assert d == 0.5 and plain.shape == (129, 161)
    np.testing.assert_allclose(plain[::4, ::4], coarse, atol=1e-9)       # the DEM's nodes are kept
    rough, _ = F.dress(coarse, 2.0, factor=4, rms_m=0.03, seed=2)
    added = rough - plain
    assert added.std() == pytest.approx(0.03, rel=1e-6)
    spec = np.abs(np.fft.fft2(added)) ** 2
    k = np.hypot(*np.meshgrid(np.fft.fftfreq(161, 0.5), np.fft.fftfreq(129, 0.5)))
    assert spec[k <= 1 / 4.0].sum() < 1e-20 * spec.sum()                 # nothing at wavelengths ≥ 2Δ of the DEM


def test_boulder_sizes_follow_the_truncated_power_law():
    d = F.boulder_sizes(np.random.default_rng(3), 4000, 0.3, 3.0, 2.5)
    cdf = lambda x: (1 - (0.3 / x) ** 2.5) / (1 - (0.3 / 3.0) ** 2.5)
    assert stats.kstest(d, cdf).pvalue > 0.01 and d.min() >= 0.3 and d.max() <= 3.0
    mesh, xy, dia = F.boulders((0, 50, 0, 40), 0.05, seed=1)
    assert len(dia) == pytest.approx(100, abs=35)                          # Poisson, mean 0.05 · 2000 m²
    assert mesh.bounds[0, 2] == pytest.approx(-0.2 * dia.max(), rel=0.2)  # a third of each height buried
    with pytest.raises(ConfigError, match="d_max_m"):
        F.boulders((0, 1, 0, 1), 0.1, d_min_m=1.0, d_max_m=0.5)


def test_a_seabed_carries_its_feature_labels_into_the_ground_truth():
    scene = F.seabed((60.0, 60.0), 0.25, center_m=(0.0, 25.0), trawl_marks=[dict(start_m=(-30, 22), end_m=(30, 22),
                     depth_m=0.2, width_m=1.5)], scours=[dict(centre_m=(0.0, 30.0), radius_m=3.0, depth_m=0.3)],
                     boulder_field=dict(density_per_m2=0.01, d_min_m=0.8, d_max_m=1.5))
    assert scene.labels == ("seafloor/scour", "seafloor/trawl_mark", "seafloor", "boulders")
    rec = se.simulate(scene, se.Trajectory.line((-1, 0, 10.0), (1, 0, 10.0), 3), se.Sonar(max_range_m=40.0),
                      se.Pulse.cw(), labels=True, start_time="2000-01-01")
    seen = {rec.labels.names[i] for i in np.unique(rec.labels.object_id) if i >= 0}
    assert {"seafloor/trawl_mark", "seafloor/scour", "seafloor"} <= seen


def test_a_boulders_shadow_ends_where_the_tangent_ray_meets_the_floor():
    """A 2 m boulder at 20 m ground range under a sonar 8 m up: the floor comes back at the slant range of the
    farthest floor point a ray over the boulder's top reaches, y_s = y_v·H/(H − z_v) over its vertices in the
    ping's plane (within a sample and 1 %)."""
    h, y0 = 8.0, 20.0
    rock = F._ellipsoid(2.0, np.random.default_rng(0))
    rock.apply_translation((0.0, y0, 0.1 * 2.0))
    floor = se.seafloor.flat((60.0, 40.0), center_m=(0.0, 25.0))              # on one side only
    sonar = se.Sonar(max_range_m=35.0, sample_rate_hz=100e3)
    line = se.Trajectory.line((0, 0, h), (0.01, 0, h), 2).stop_and_hop()
    pulse = se.Pulse.cw(duration_s=20e-6, taper=0.0)
    rec = se.simulate(se.Scene().add(floor, label="seafloor").add(rock, label="boulder"), line, sonar, pulse,
                      start_time="2000-01-01")
    bare = se.simulate(se.Scene().add(floor, label="seafloor"), line, sonar, pulse, start_time="2000-01-01")
    v = rock.vertices[(np.abs(rock.vertices[:, 0]) < 0.05) & (rock.vertices[:, 2] > 0)]
    y_s = np.max(v[:, 1] * h / (h - v[:, 2]))                                 # where the tangent ray lands
    r_s = math.hypot(h, y_s)
    r = rec.slant_range_m
    name = "port" if bare.port[0].max() > bare.starboard[0].max() else "starboard"
    side, ref = rec.channel(name), bare.channel(name)
    dark = (side[0] < 0.1 * ref[0]) & (r > math.hypot(h, y0))
    end = r[np.flatnonzero(dark)].max() if dark.any() else 0.0
    dr = 1500.0 / (2 * 100e3)
    assert end == pytest.approx(r_s, abs=dr + 0.01 * r_s), (end, r_s)


def test_a_dem_dressed_as_it_is_read(tmp_path):
    """from_dem(dress_factor=4): the mesh 4× finer, the DEM's nodes kept within the added relief's few σ, the relief's
    RMS as asked; a DEM with holes is refused."""
    from sonar_embree.io.geotiff import write_grid

    rng = np.random.default_rng(1)
    z = -20.0 + np.cumsum(rng.normal(size=(21, 31)), axis=0) * 0.1
    write_grid(tmp_path / "d.tif", z, 0.0, 40.0, 2.0, crs="EPSG:32631")
    plain = se.seafloor.from_dem(tmp_path / "d.tif")
    fine = se.seafloor.from_dem(tmp_path / "d.tif", dress_factor=4, dress_rms_m=0.05)
    assert len(fine.vertices) == (4 * 20 + 1) * (4 * 30 + 1) and len(plain.vertices) == 21 * 31
    bare = se.seafloor.from_dem(tmp_path / "d.tif", dress_factor=4, dress_rms_m=0.0)
    assert np.std(fine.vertices[:, 2] - bare.vertices[:, 2]) == pytest.approx(0.05, rel=1e-3)
    assert fine.metadata["crs"] == plain.metadata["crs"]
    z[3, 4] = np.nan
    write_grid(tmp_path / "h.tif", z, 0.0, 40.0, 2.0, crs="EPSG:32631")
    with pytest.raises(ConfigError, match="without holes"):
        se.seafloor.from_dem(tmp_path / "h.tif", dress_factor=2)


def test_a_seabed_from_toml(tmp_path):
    """``[[objects]] seabed = {…}`` in a run configuration: the labelled objects, the floor of the object's
    material; an unknown key is named."""
    from sonar_embree.runs.runconfig import load_run_config

    run = """
[sonar]
max_range_m = 30.0
[trajectory]
start = [-1.0, 0.0, 8.0]
end = [1.0, 0.0, 8.0]
n_pings = 3
[[objects]]
material = { backscatter_db = -25.0 }
[objects.seabed]
size_m = [40.0, 40.0]
resolution_m = 0.5
bedforms = { wavelength_m = 6.0, height_m = 0.2 }
trawl_marks = [{ start_m = [-20.0, 5.0], end_m = [20.0, 5.0] }]
boulder_field = { density_per_m2 = 0.01 }
"""
    (tmp_path / "run.toml").write_text(run)
    cfg = load_run_config(str(tmp_path / "run.toml"))
    assert cfg.scene.labels == ("seafloor/trawl_mark", "seafloor/sand_wave", "boulders")
    assert cfg.scene.objects[1].material.backscatter_db == -25.0
    (tmp_path / "bad.toml").write_text(run.replace("bedforms", "bedform"))
    with pytest.raises(ConfigError, match="bad.toml.*'bedform'"):
        load_run_config(str(tmp_path / "bad.toml"))
    for old, new, says in (("resolution_m = 0.5", "resolution_m = 0", "seabed resolution_m must be > 0 m, got 0"),
                           ("size_m = [40.0, 40.0]", "size_m = [1e6, 1e6]", "needs 4e\\+12 vertices"),
                           ("size_m = [40.0, 40.0]", "size_m = [40.0, nan]", "size_m must be > 0 m, got nan")):
        (tmp_path / "bad.toml").write_text(run.replace(old, new))           # issue 49: one line, at once
        with pytest.raises(ConfigError, match=f"bad.toml.*{says}") as exc:
            load_run_config(str(tmp_path / "bad.toml"))
        assert "\n" not in str(exc.value)
