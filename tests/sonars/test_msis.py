"""The mechanically scanning imaging sonar (issue: other scanning sonars) against geometry and an independent
quadrature of docs/physics.md §3 eq. (1) with the MSIS beam, written here.

Head frame: x along the bearing, y to its right, z down; the beam axis a = (cos δ, 0, sin δ) (δ the tilt), its
membrane's narrow axis across the scan e_h = y, its vertical axis e_v = (−sin δ, 0, cos δ). One-way gain
Γ(u) = sinc(k·lx/2·u·e_h)·sinc(k·ly/2·u·e_v) on the baffled side u·a > 0, lx and ly from the −3 dB widths
(sinc(π·L/λ·sin(θ3/2)) = 1/√2).
"""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import sonar_embree as se
from sonar_embree.sonars.msis import polar_image

H, MU_DB, TAU, FS = 10.0, -20.0, 50e-6, 100e3


def _floor():
    return se.Scene().add(se.seafloor.flat((200.0, 200.0)), material=se.Material(backscatter_db=MU_DB),
                          label="seafloor")


def _still(n, z=H):
    return se.Trajectory(np.tile([[0.0, 0.0, z]], (n, 1)), heading_deg=30.0, times_s=np.arange(n, dtype=float))


def test_bearing_schedule_full_circle_and_sector():
    full = se.MSIS(step_deg=45.0, start_bearing_deg=10.0)
    np.testing.assert_allclose(full.bearings_deg(np.arange(10)), (10.0 + 45.0 * np.arange(10)) % 360.0)
    sector = se.MSIS(step_deg=30.0, sector_deg=90.0, start_bearing_deg=0.0)      # −45 … 45 and back
    np.testing.assert_allclose(sector.bearings_deg(np.arange(8)), np.array([-45, -15, 15, 45, 15, -15, -45, -15]) % 360)
    with pytest.raises(se.ConfigError, match="step_deg = 60 exceeds the sector of 45"):
        se.MSIS(step_deg=60.0, sector_deg=45.0)
    with pytest.raises(se.ConfigError, match="horizontal_beamwidth_deg"):
        se.MSIS(horizontal_beamwidth_deg=-1.0)


def test_first_return_at_every_bearing_is_the_altitude():
    """A still head over a flat floor, 16 bearings: the first echo at 2h/c (its side lobes reach straight down)."""
    rec = se.simulate(_floor(), _still(16), se.MSIS(step_deg=22.5, sample_rate_hz=FS),
                      se.Pulse.cw(duration_s=TAU, taper=0.0))
    assert rec.data.shape[:2] == (16, 1) and rec.channels == ("beam",)
    dt = rec.time_s[1]
    first = np.array([rec.time_s[np.flatnonzero(rec.data[k, 0] > 0)[0]] for k in range(16)])
    assert np.all(np.abs(first - 2 * H / rec.acquisition.sound_speed_m_s) <= dt)


def _membrane(width_deg, lam):
    x0 = brentq(lambda x: math.sin(x) / x - 2 ** -0.5, 1e-9, math.pi)
    return x0 * lam / (math.pi * math.sin(math.radians(width_deg) / 2))


def _quadrature(t, sonar, tilt_deg):
    """Expected intensity of a flat Lambert floor at times t for a rectangular pulse TAU: ∫ Γ⁴ μ cos²θi
    e^(−2α'R) / R⁴ dA over the ring c(t − τ) < 2R ≤ ct, on a polar grid around the head."""
    lam, k = se.Acquisition.of(sonar).wavelength_m, se.Acquisition.of(sonar).wavenumber_rad_m
    lx, ly = _membrane(sonar.horizontal_beamwidth_deg, lam), _membrane(sonar.vertical_beamwidth_deg, lam)
    d = math.radians(tilt_deg)
    rho = np.concatenate([np.linspace(0, 2, 801)[:-1], np.linspace(2, 30, 5601)])
    phi = np.unique(np.concatenate([np.linspace(-0.1, 0.1, 801), np.linspace(-np.pi, np.pi, 1441)]))
    p, f = rho[:, None], phi[None, :]
    r = np.sqrt(p ** 2 + H ** 2)
    ux, uy, uz = p * np.cos(f) / r, p * np.sin(f) / r, H / r
    along_axis = ux * math.cos(d) + uz * math.sin(d)
    g = np.sinc(k * lx / 2 * uy / np.pi) * np.sinc(k * ly / 2 * (-ux * math.sin(d) + uz * math.cos(d)) / np.pi)
    g = np.where(along_axis > 0, g, 0.0)
    alpha = se.Acquisition.of(sonar).alpha_db_per_m * math.log(10) / 10
    dens = g ** 4 * 10 ** (MU_DB / 10) * (H / r) ** 2 * np.exp(-2 * alpha * r) / r ** 4
    per_rho = np.trapezoid(dens, phi, axis=1) * rho
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (per_rho[1:] + per_rho[:-1]) * np.diff(rho))])
    c = se.Acquisition.of(sonar).sound_speed_m_s
    two_r = 2 * np.sqrt(rho ** 2 + H ** 2)
    return np.interp(c * t, two_r, cum, left=0, right=cum[-1]) - np.interp(c * (t - TAU), two_r, cum, left=0,
                                                                          right=cum[-1])


def test_flat_floor_matches_the_quadrature_of_eq1():
    """Within 30 dB of the peak (the vertical pattern's null at 35.7° from the axis, 12 m here, lies 57 dB down;
    beside it the ray sampling's relative error grows past 1 dB), away from the onset's edges."""
    sonar = se.MSIS(step_deg=90.0, sample_rate_hz=FS, max_range_m=25.0)
    rec = se.simulate(_floor(), _still(4).stop_and_hop(), sonar, se.Pulse.cw(duration_s=TAU, taper=0.0))
    q = _quadrature(rec.time_s, sonar, sonar.tilt_deg)
    c = se.Acquisition.of(sonar).sound_speed_m_s
    edge = np.abs(rec.time_s - 2 * H / c) <= 1.5 / FS
    edge |= np.abs(rec.time_s - 2 * H / c - TAU) <= 1.5 / FS
    ok = (q > 1e-3 * q.max()) & ~edge
    err = 10 * np.log10(rec.data[:, 0].mean(axis=0)[ok] / q[ok])
    assert ok.sum() > 500 and np.max(np.abs(err)) < 0.5, np.max(np.abs(err))


def test_a_ring_wall_appears_at_its_distance_at_every_bearing_of_the_image():
    """A vertical ring wall of radius D around a still head (nothing else within range): in the polar image,
    each bearing's first lit pixel lies at D, within one pixel."""
    import trimesh

    d_wall, pixel = 7.0, 0.1
    wall = trimesh.creation.annulus(r_min=d_wall, r_max=d_wall + 0.5, height=30.0, sections=256)
    scene = se.Scene().add(wall, label="wall")
    rec = se.simulate(scene, _still(40, z=0.0), se.MSIS(step_deg=9.0, max_range_m=12.0))
    img, ext = polar_image(rec, pixel_m=pixel)
    n = img.shape[0]
    for az in np.radians(np.arange(0.0, 360.0, 9.0) + 4.5):
        steps = np.arange(0.0, 11.0, pixel / 4)
        cols = np.clip(((steps * np.sin(az)) - ext[0]) / pixel, 0, n - 1).astype(int)
        rows = np.clip((ext[3] - steps * np.cos(az)) / pixel, 0, n - 1).astype(int)
        lit = np.flatnonzero(np.nan_to_num(img[rows, cols]) > 0)
        assert lit.size and abs(steps[lit[0]] - d_wall) <= pixel * 1.5, (np.degrees(az), steps[lit[0]])


def test_msis_record_round_trips_and_exports():
    rec = se.simulate(_floor(), _still(3), se.MSIS(step_deg=10.0))
    import tempfile, os
    d = tempfile.mkdtemp()
    rec.save(os.path.join(d, "r.npz"))
    back = se.Record.load(os.path.join(d, "r.npz"))
    assert back.sonar == rec.sonar and np.array_equal(back.data, rec.data)
    ds = rec.to_xarray()
    assert "beam" in ds and ds["beam"].dims == ("ping", "sample")
    np.testing.assert_allclose(ds["bearing_deg"].values, [0.0, 10.0, 20.0])          # the head's bearing per ping


def test_toml_sonar_type_msis_renders(tmp_path):
    """[sonar] type = "msis" with its own keys (the shipped config, shortened); unknown types and a side-scan key
    in an MSIS table are refused naming them."""
    from sonar_embree.runs import runconfig

    cfg = runconfig.load_run_config("asset:msis_harbour.toml")
    assert isinstance(cfg.sonar, se.MSIS) and cfg.sonar.step_deg == 1.8 and len(cfg.trajectory) == 200
    rec = se.simulate(cfg.scene, cfg.trajectory[:3], cfg.sonar, cfg.pulse, chain=cfg.chain)
    assert rec.channels == ("beam",) and rec.data.shape[:2] == (3, 1)
    bad = tmp_path / "bad.toml"
    text = (runconfig.assets.path("asset:msis_harbour.toml") and
            open(runconfig.assets.path("asset:msis_harbour.toml")).read())
    bad.write_text(text.replace('type = "msis"', 'type = "sector_scanner"'))
    with pytest.raises(se.ConfigError, match="unknown sonar type 'sector_scanner'"):
        runconfig.load_run_config(bad)
    bad.write_text(text.replace("step_deg = 1.8", "step_deg = 1.8\nlength_m = 0.2"))
    with pytest.raises(se.ConfigError, match="length_m"):
        runconfig.load_run_config(bad)


def test_polar_png_output_is_the_msis_display(tmp_path):
    """The "polar" output writes the polar display of an MSIS record (8-bit, black outside the scan), and refuses
    other sonar types naming the need."""
    from sonar_embree.record import registry

    rec = se.simulate(_floor(), _still(40), se.MSIS(step_deg=9.0, max_range_m=15.0))
    (path,) = registry.write_each(rec, str(tmp_path), ["polar"])
    import imageio.v3 as iio

    img = iio.imread(path)
    assert img.dtype == np.uint8 and img.shape == (400, 400)
    assert img[0, 0] == 0 and img[200, 200] == 0 and img[200, 200 + 150].max() > 0   # corner, centre, the floor
    side = se.simulate(_floor(), _still(2), se.Sonar(max_range_m=15.0))
    with pytest.raises(se.ConfigError, match="an MSIS record is needed"):
        registry.write_each(side, str(tmp_path), ["polar"])


def test_labels_along_the_beam(tmp_path):
    """Ground truth along each ping's beam centre line: a box 8 m from a still head is an object in the pings
    whose bearing points at it (and a shadow behind it), floor samples sit at z = 0 and ground range √(R² − h²);
    the one-channel label image is the ping × sample waterfall."""
    import trimesh

    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    box.apply_translation((8.0 * np.sin(np.radians(30.0)), 8.0 * np.cos(np.radians(30.0)), 0.5))  # ahead: heading 30°
    scene = _floor().add(box, label="box")
    rec = se.simulate(scene, _still(40), se.MSIS(step_deg=9.0, max_range_m=15.0), labels=True)
    lab = rec.labels
    assert lab.kind.shape == (1, 40, rec.data.shape[2])
    bearings = rec.sonar.bearings_deg(np.arange(40))
    hit = np.flatnonzero((lab.kind[0] == 2).any(axis=1))
    assert hit.size and np.all(np.minimum(bearings[hit], 360.0 - bearings[hit]) <= 9.0)
    assert (lab.kind[0, hit] == 3).any()
    floor = (lab.kind[0] == 1) & (rec.slant_range_m > H + 0.05)          # past the nadir sample's footprint
    r = np.broadcast_to(rec.slant_range_m, floor.shape)[floor]
    np.testing.assert_allclose(lab.height_m[0][floor], 0.0, atol=0.02)
    np.testing.assert_allclose(lab.ground_range_m[0][floor], np.sqrt(r ** 2 - H ** 2), atol=0.05)
    assert lab.waterfall(max_columns=None).shape == (40, rec.data.shape[2])
    lab.save_png(tmp_path / "labels.png")


def test_msis_labels_export_and_read_back(tmp_path, capsys):
    """Issue 33, finding 5: an MSIS record with labels goes to xarray, Zarr, a streamed line and the CLI (it
    raised "variables {'beam'} are found in both data_vars and coords" after the render); the labels read back
    on a `channel` dimension, equal to the record's."""
    import xarray as xr
    import trimesh

    from sonar_embree.runs import cli

    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    box.apply_translation((8.0 * np.sin(np.radians(30.0)), 8.0 * np.cos(np.radians(30.0)), 0.5))  # ahead
    scene = _floor().add(box, label="box")
    sonar = se.MSIS(step_deg=9.0, max_range_m=15.0)
    rec = se.simulate(scene, _still(12), sonar, labels=True)
    ds = rec.to_xarray()
    assert ds["label_kind"].dims == ("channel", "ping", "sample") and list(ds["channel"].values) == ["beam"]
    assert ds["beam"].dims == ("ping", "sample")
    rec.to_zarr(tmp_path / "r.zarr")
    back = xr.open_zarr(tmp_path / "r.zarr")
    np.testing.assert_array_equal(back["label_kind"].values, rec.labels.kind)
    assert (rec.labels.kind == 2).any()                                # the box is in the labels
    se.stream.render_line(scene, _still(12), tmp_path / "s.zarr", sonar, block_pings=5, labels=True)
    np.testing.assert_array_equal(xr.open_zarr(tmp_path / "s.zarr")["label_kind"].values, rec.labels.kind)
    cfg = tmp_path / "msis.toml"
    text = open(se.assets.path("asset:msis_harbour.toml")).read()
    cfg.write_text(text.replace("[output]", "[output]\nlabels = true", 1).replace("n_pings = 200",
                                                                                          "n_pings = 3"))
    out = tmp_path / "out"
    assert cli.main(["render", str(cfg), "-o", str(out), "--no-progress"]) == 0, capsys.readouterr().err
    assert "label_kind" in xr.open_zarr(out / "record.zarr")
