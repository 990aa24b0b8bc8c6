"""The ray budget follows the scene and the quality setting (issue 4), and costs nothing where nothing echoes."""
import numpy as np
import pytest

import sonar_embree as se
from conftest import H, box, flat_scene, line_along_x


def _rays(scene, sonar=None, traj=None, **kw):
    rec = se.simulate(scene, traj or line_along_x(2), sonar or se.Sonar(max_range_m=40.0), **kw)
    return rec.attrs["rays_per_ping"], rec


def test_quality_scales_the_budget_and_defaults_to_one():
    n = {q: _rays(flat_scene(), quality=q)[0] for q in (0.25, 0.5, 1.0, 2.0)}
    assert n[0.25] < n[0.5] < n[1.0] < n[2.0]
    rec = _rays(flat_scene())[1]
    assert rec.attrs["quality"] == 1.0 and rec.attrs["rays_per_ping"] == n[1.0]
    assert se.FanSettings().resolved().rays_per_bin == 1.0
    assert se.FanSettings(quality=2, rays_per_bin=0.3).resolved().rays_per_bin == 0.3  # explicit fields win
    with pytest.raises(se.ConfigError, match="either quality or fan"):
        se.simulate(flat_scene(), line_along_x(1), quality=1.0, fan=se.FanSettings())
    with pytest.raises(se.ConfigError, match="quality"):
        se.FanSettings(quality=-1)


def test_rays_are_uniform_in_slant_range_on_the_floor():
    """Elevation rays per azimuth line grow with the slant-range extent of the floor in the window, not with angle."""
    n20 = _rays(flat_scene(), se.Sonar(max_range_m=20.0))[0]
    n40 = _rays(flat_scene(), se.Sonar(max_range_m=40.0))[0]
    n80 = _rays(se.Scene().add(se.seafloor.flat((400, 200)), label="f"), se.Sonar(max_range_m=80.0))[0]
    # (R_max − h) / bin rays per line plus a fixed part: the increments are in proportion 20 : 40
    assert (n80 - n40) / (n40 - n20) == pytest.approx(2.0, rel=0.15)


def test_nothing_in_range_costs_next_to_nothing():
    """A floor beyond the window gets the coarse empty-cell step: an all-zero record, and besides the fixed probe
    (0.2° steps over the 150° elevation span, both sides) a few hundred rays."""
    from sonar_embree.propagation.fan import FanPlan

    from conftest import decoy_above

    full = _rays(flat_scene())[0]
    traj = line_along_x(2, z=60.0)
    empty, rec = _rays(flat_scene().add(decoy_above(traj), label="decoy"), traj=traj)
    assert np.all(rec.port == 0) and np.all(rec.starboard == 0)
    probe = FanPlan.build(rec.acquisition, se.FanSettings()).n_probe
    assert empty - probe < 0.05 * (full - probe)


def test_density_follows_range_rate_and_refines_edges():
    """Per probe cell: |dR/dβ|/dr on the floor, the largest step where range changes slowly, a 4× finer step at an
    object's edges, 8× coarser where nothing is in range."""
    from sonar_embree.instrument import beam

    b = np.radians(np.arange(-30.0, 90.0, 0.2))
    r = H / np.sin(b)
    r[(b <= 0) | (r > 50.0)] = np.nan                        # sky and beyond the window
    obj = (b > np.radians(40)) & (b < np.radians(42))
    r[obj] = 12.0                                            # a face at constant range: two range jumps
    step, dr = np.radians(0.5), 0.01875
    d = beam.elevation_density(b, r, dr, step, 500.0, empty_step_factor=8.0, edge_density_factor=4.0)
    mid = 0.5 * (b[1:] + b[:-1])
    floor = np.isfinite(r[1:]) & np.isfinite(r[:-1]) & ~obj[1:] & ~obj[:-1]
    expect = np.maximum(H * np.cos(mid) / np.sin(mid) ** 2 / dr, 1 / step)   # |dR/dβ| = h·cosβ/sin²β
    smooth = floor & (np.abs(mid - np.radians(41)) > np.radians(3)) & (mid > np.radians(13))
    np.testing.assert_allclose(d[smooth], expect[smooth], rtol=0.01)
    edges = np.nonzero(np.diff(obj.astype(int)))[0]
    for e in edges:
        assert np.all(d[e - 1:e + 2] >= 4 / step - 1e-9)
    inside = obj[1:] & obj[:-1]
    assert np.all(d[inside][1:-1] >= 1 / step) and np.all(d[inside][2:-2] < 1.01 / step)  # a flat face: no refining
    sky = ~np.isfinite(r[1:]) & ~np.isfinite(r[:-1]) & (mid < np.radians(-5))
    np.testing.assert_allclose(d[sky], 1 / (8 * step))


def test_an_object_shows_at_its_range():
    rec = _rays(flat_scene().add(box((2, 2, 3), (0, -20, 1.5)), label="box", material=se.Material(-10)))[1]
    near_face = np.hypot(19.0, H - 3.0)  # the top edge of the near face returns first and brightest
    assert abs(rec.slant_range_m[np.argmax(rec.starboard[0])] - near_face) < 1.5


def test_cli_quality_flag(tmp_path):
    from sonar_embree.runs.cli import main

    assert main(["demo", "-o", str(tmp_path), "--pings", "2", "--quality", "0.5", "--no-progress"]) == 0
    rec = se.Record.load(tmp_path / "record.npz")
    assert rec.attrs["quality"] == 0.5
    assert main(["demo", "-o", str(tmp_path / "x"), "--quality", "0", "--no-progress"]) == 2
    assert not (tmp_path / "x").exists()


def test_timings_report_every_stage_without_changing_the_record():
    t = {}
    a = se.simulate(flat_scene(), line_along_x(2), se.Sonar(max_range_m=30.0), speckle=True, timings=t,
                    start_time="2026-01-01T00:00:00Z")
    b = se.simulate(flat_scene(), line_along_x(2), se.Sonar(max_range_m=30.0), speckle=True,
                    start_time="2026-01-01T00:00:00Z")
    assert set(t) == {"setup", "embree", "rays", "synthesis", "processing"}
    assert all(v >= 0 for v in t.values()) and t["embree"] > 0
    np.testing.assert_array_equal(a.starboard, b.starboard)
    assert a.attrs == b.attrs  # timings stay out of the record: same inputs, same bits


def test_moving_lines_add_the_receive_lobes_lines_on_the_same_lattice():
    """Under motion the block's fan takes ⌊|δ|/ds⌋ more lines of the lattice k·ds on δ's side, so that its cells end
    within half a spacing of the receive lobe's null as they do at the transmit lobe's (lines on a transmit null left
    out: they weigh nothing), the transmit lines unchanged to the bit; pings of one speed keep every line,
    pings of several speeds each keep the interval of their own lines; the forward-looking fan adds none."""
    from sonar_embree.propagation.fan import moving_lines, own_lines
    from sonar_embree import sonars

    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    plan = sonars.front_end(se.Acquisition.of(sonar), se.FanSettings()).plan
    ds, null = plan.ds, se.Acquisition.of(sonar).wavelength_m / sonar.length_m
    same, keep = moving_lines(plan, np.zeros(3))
    assert same is plan and keep is None
    delta = 2 * 10.0 / 1500.0
    moved, keep = moving_lines(plan, np.full(3, delta))
    assert keep is None
    new = np.setdiff1d(moved.s, plan.s)
    np.testing.assert_array_equal(moved.s, np.concatenate([plan.s, new]))            # added past the edge only
    np.testing.assert_allclose(new / ds, np.round(new / ds), atol=1e-9)             # on the lattice
    assert np.all(np.abs(np.sin(np.pi * new / null)) > 1e-6)                        # none on a transmit null
    edge = null + ds / 2 + np.floor(delta / ds) * ds                                 # the last cell's far edge
    assert moved.s[-1] == pytest.approx(edge - ds / 2) and abs(null + delta - edge) <= ds / 2   # the receive lobe's
    moved, keep = moving_lines(plan, np.array([-delta, 0.0, delta / 2]))
    assert moved.s[0] - ds / 2 <= -null - delta + ds / 2 and moved.s[-1] + ds / 2 >= null + delta / 2 - ds / 2
    own = own_lines(moved.s, keep)
    np.testing.assert_array_equal(own[1], np.isin(moved.s, plan.s))                 # δ = 0: the transmit lines
    assert own[0, 0] and not own[0, -1] and own[2, -1] and not own[2, 0]           # each its own side's lines
    assert moved.s[own[2]][-1] + ds / 2 >= null + delta / 2
    fls = sonars.front_end(se.Acquisition(se.ForwardLooking()).for_pulse(se.Pulse.cw()), se.FanSettings()).plan
    assert moving_lines(fls, np.full(3, delta))[0] is fls


def test_a_wide_fan_is_probed_on_its_own_lines_and_its_lines_are_at_most_the_azimuth_step_apart():
    """Issue 53, item 1: a narrow fan keeps its three probe lines (boresight and edges) and its oversampled spacing
    λ/(2·lx)/2 (the default side-scan's plan is unchanged); a wide one (a 4 cm element at 100 kHz, 22°) takes lines
    sin(1.5°) apart at most and is probed on lines of its own lattice, boresight and edges included, at most
    :data:`PROBE_MAX_DS` apart (never between its lines, where no ray goes)."""
    import math

    from sonar_embree.propagation.fan import PROBE_LINES, PROBE_MAX_DS, FanPlan, probe_lines

    np.testing.assert_array_equal(probe_lines(0.02, 0.005), PROBE_LINES * 0.02)
    for edge, ds in ((0.28125, 0.09375), (0.3, 0.01), (8 * 0.0262, 0.0262)):
        p = np.sort(probe_lines(edge, ds))
        steps = np.round(p / ds, 9)
        assert np.all(steps == np.round(steps)) and p[0] == -edge and p[-1] == edge and 0.0 in p
        assert np.diff(p).max() <= max(PROBE_MAX_DS, ds) + 1e-12
    fan = se.FanSettings().resolved()
    narrow = se.Acquisition(se.Sonar(sample_rate_hz=40e3))
    plan = FanPlan.build(narrow, fan)
    assert plan.ds == pytest.approx(narrow.wavelength_m / (4 * narrow.length_m), rel=1e-12)
    assert plan.probe_body.shape[0] == 2 * 3 * plan.probe_beta.size
    wide = se.Acquisition(se.Sonar(frequency_hz=100e3, length_m=0.04, sample_rate_hz=40e3))
    plan = FanPlan.build(wide, fan)
    assert plan.ds == pytest.approx(math.sin(math.radians(1.5)), rel=1e-9)
    lines = plan.probe_body.shape[0] // (2 * plan.probe_beta.size)
    assert lines >= math.ceil(2 * plan.edge_s / PROBE_MAX_DS)
    with pytest.raises(se.ConfigError, match="max_azimuth_step_deg"):
        se.FanSettings(max_azimuth_step_deg=0.0)
