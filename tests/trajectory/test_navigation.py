"""Navigation as surveyors mean it (issue 35, build item 2): heading from the track, resampling at the ping rate,
layback of a towed sonar, ship and sensor positions in the XTF, and a warning for pings spaced wider than the beam.

References here: a circle x = R·cos ωt, y = R·sin ωt has the heading atan2(−sin ωt, cos ωt) (clockwise from north =
+y) at every t; a straight taut cable of length C to a sonar D below its tow point lies back √(C² − D²); the two-way
−3 dB width of a membrane of length lx is 2·asin(x₃λ/(π·lx)), sinc⁴(x₃) = 10^(−0.3) (x₃ by brentq below).
"""
import logging

import numpy as np
import pyxtf
import pytest
from scipy.optimize import brentq

import sonar_embree as se

R, W = 60.0, 2.0 / 60.0        # circle radius (m) and turn rate (rad/s): 2 m/s


def _circle(t):
    return np.stack([R * np.cos(W * t), R * np.sin(W * t), np.full_like(t, -20.0)], axis=1)


def _write_log(path, t, xyz, heading=None, stamps=True):
    """A nav log CSV: ISO times (or time_s), x/y/z, optionally heading."""
    import datetime as dt

    t0 = dt.datetime(2026, 5, 1, 12, 0, 0, tzinfo=dt.timezone.utc)
    names = ["time" if stamps else "time_s", "x_m", "y_m", "z_m"] + ([] if heading is None else ["heading_deg"])
    rows = []
    for k, ti in enumerate(t):
        when = (t0 + dt.timedelta(seconds=float(ti))).isoformat() if stamps else repr(float(ti))
        rows.append([when] + [repr(float(v)) for v in xyz[k]] + ([] if heading is None else [repr(float(heading[k]))]))
    path.write_text(",".join(names) + "\n" + "".join(",".join(r) + "\n" for r in rows))
    return path


def test_heading_follows_a_curved_track_when_the_log_has_none(tmp_path, caplog):
    """A 1 Hz log on a 60 m circle at 2 m/s without a heading column: every ping's heading is the circle's tangent
    within 0.5° (ends included), with a one-line notice; before, every heading was 0 (north), silently."""
    t = np.arange(0.0, 60.0)
    with caplog.at_level(logging.WARNING):
        traj = se.Trajectory.from_csv(_write_log(tmp_path / "nav.csv", t, _circle(t)), crs=32631)
    want = np.degrees(np.arctan2(-np.sin(W * t), np.cos(W * t))) % 360.0
    err = (traj.heading_deg - want + 180.0) % 360.0 - 180.0
    assert np.abs(err).max() < 0.5, np.abs(err).max()
    assert any("no heading_deg column" in r.getMessage() for r in caplog.records)
    given = se.Trajectory.from_csv(_write_log(tmp_path / "h.csv", t, _circle(t), heading=np.full(t.size, 7.0)))
    assert np.all(given.heading_deg == 7.0)                              # a given heading is kept


def test_a_track_that_never_moves_has_no_heading(tmp_path):
    t = np.arange(3.0)
    with pytest.raises(se.ConfigError, match="never move"):
        se.Trajectory.from_csv(_write_log(tmp_path / "still.csv", t, np.zeros((3, 3)), stamps=False))


def test_resampling_keeps_the_log_at_its_own_times_and_follows_the_track(tmp_path):
    """Poses at the log's own times are the log's (to round-off); at 10 Hz the positions lie on the circle within
    1 cm (PCHIP through 2 m fixes), the pings 0.1 s apart, the CRS and the start time kept; a heading crossing north
    turns the short way."""
    t = np.arange(0.0, 30.0)
    log_ = se.Trajectory.from_csv(_write_log(tmp_path / "nav.csv", t, _circle(t)), crs=32631)
    back = log_.at_times(log_.times_s)
    for k in ("positions_m", "heading_deg", "pitch_deg", "roll_deg", "times_s", "velocity_m_s"):
        np.testing.assert_allclose(getattr(back, k), getattr(log_, k), rtol=0, atol=1e-9)
    fine = log_.resampled(10.0)
    assert len(fine) == 291 and (fine.crs, fine.start_time) == (log_.crs, log_.start_time)
    np.testing.assert_allclose(np.diff(fine.times_s), 0.1, atol=1e-12)
    np.testing.assert_allclose(fine.positions_m, _circle(fine.times_s), atol=0.01)
    turn = se.Trajectory(np.zeros((2, 3)), [350.0, 10.0], times_s=[0.0, 1.0]).at_times([0.5])
    assert turn.heading_deg[0] == pytest.approx(0.0, abs=1e-9) or turn.heading_deg[0] == pytest.approx(360.0)
    with pytest.raises(se.ConfigError, match="reach outside"):
        log_.at_times([-1.0, 0.0])
    with pytest.raises(se.ConfigError, match="ping_rate_hz"):
        log_.resampled(0.0)


def test_survey_keeps_its_crs_and_start_time():
    t = se.Trajectory.survey([(0, 0, -5), (20, 0, -5)], 2.0, 5.0, crs=32631, start_time="2026-05-01T12:00:00Z")
    assert t.crs == "EPSG:32631" and t.start_time.startswith("2026-05-01T12:00:00")


def test_layback_puts_the_sonar_behind_the_ship_along_its_track():
    """A ship running east 100 m then north: a sonar 30 m back lies on the track already run (20 m before the
    corner when the ship is 10 m past it), heading along its own leg; a 50 m taut cable to a sonar 30 m below the
    tow point lies back √(50² − 30²) = 40 m."""
    ship = np.array([[0.0, 0, -30], [50, 0, -30], [100, 0, -30], [100, 10, -30], [100, 60, -30]])
    traj = se.Trajectory(ship, 0.0, times_s=np.arange(5.0))
    towed = traj.with_layback(30.0)
    np.testing.assert_allclose(towed.ship_positions_m[:, :2], ship[:, :2])
    np.testing.assert_allclose(towed.ship_positions_m[:, 2], 0.0)                 # the tow point, at the surface
    np.testing.assert_allclose(towed.positions_m[:, :2], [[-30, 0], [20, 0], [70, 0], [80, 0], [100, 30]], atol=1e-9)
    np.testing.assert_allclose(towed.positions_m[:, 2], -30.0)
    np.testing.assert_allclose(towed.heading_deg, [90, 90, 90, 90, 0], atol=1e-9)
    cable = traj.with_layback(cable_out_m=50.0)
    np.testing.assert_allclose(cable.positions_m[:3, 0], ship[:3, 0] - 40.0, atol=1e-9)
    with pytest.raises(se.ConfigError, match="shorter than"):
        traj.with_layback(cable_out_m=20.0)
    with pytest.raises(se.ConfigError, match="one of them"):
        traj.with_layback()
    assert towed[1:3].ship_positions_m.shape == (2, 3)
    assert se.Trajectory.concatenate([towed[:2], towed[2:]]) == towed


def test_a_towed_lines_xtf_has_ship_and_sensor_positions_apart(tmp_path):
    """pyxtf reads the Ship coordinates at the ship's latitude/longitude and the Sensor ones at the sonar's, 30 m
    apart; the record keeps both through save/load."""
    from sonar_embree.io.geo import to_lonlat

    scene = se.Scene().add(se.seafloor.flat((400, 400)), label="seafloor")
    ship = se.Trajectory.survey([(-10, 0, 10), (10, 0, 10)], 2.0, 2.0, crs=32631)
    traj = ship.with_layback(30.0)
    rec = se.simulate(scene, traj, se.Sonar(max_range_m=20.0), speckle=False)
    rec.save(tmp_path / "r.npz")
    np.testing.assert_array_equal(se.Record.load(tmp_path / "r.npz").trajectory.ship_positions_m,
                                  traj.ship_positions_m)
    rec.to_xtf(tmp_path / "l.xtf")
    _, packets = pyxtf.xtf_read(str(tmp_path / "l.xtf"))
    pings = packets[pyxtf.XTFHeaderType.sonar]
    lon, lat = to_lonlat(traj.crs, traj.ship_positions_m[:, 0], traj.ship_positions_m[:, 1])
    np.testing.assert_allclose([p.ShipXcoordinate for p in pings], lon, atol=1e-9)
    np.testing.assert_allclose([p.ShipYcoordinate for p in pings], lat, atol=1e-9)
    lon_s, _ = to_lonlat(traj.crs, traj.positions_m[:, 0], traj.positions_m[:, 1])
    np.testing.assert_allclose([p.SensorXcoordinate for p in pings], lon_s, atol=1e-9)
    assert np.all(np.abs(np.array([p.ShipXcoordinate for p in pings]) - lon_s) > 1e-4)   # 30 m ≈ 4e-4° here


def test_pings_wider_apart_than_the_beam_are_warned_about(caplog):
    """Pings 2 m apart under the default 400 kHz, 0.19 m membrane with a 45 m window (two-way −3 dB footprint
    2·45·tan(asin(x₃λ/(π·lx))) = 0.57 m): a one-line warning naming both; 0.2 m apart, or fewer than ten pings (a
    probe, not a waterfall): none."""
    sonar = se.Sonar(max_range_m=45.0)
    x3 = brentq(lambda x: (np.sin(x) / x) ** 4 - 10 ** -0.3, 0.1, 3.0)           # sinc⁴ at −3 dB
    foot = 2 * 45.0 * np.tan(np.arcsin(x3 * se.Acquisition.of(sonar).wavelength_m / (np.pi * sonar.length_m)))
    scene = se.Scene().add(se.seafloor.flat((200, 200)), label="seafloor")
    with caplog.at_level(logging.WARNING):
        se.simulate(scene, se.Trajectory.line((0, 0, 10), (18, 0, 10), 10), sonar, speckle=False)
    msg = [r.getMessage() for r in caplog.records if "footprint" in r.getMessage()]
    assert len(msg) == 1 and "2 m apart" in msg[0] and f"{foot:.3g} m footprint" in msg[0]
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        se.simulate(scene, se.Trajectory.line((0, 0, 10), (1.8, 0, 10), 10), sonar, speckle=False)
        se.simulate(scene, se.Trajectory.line((0, 0, 10), (16, 0, 10), 9), sonar, speckle=False)   # a probe, not an image
    assert not [r for r in caplog.records if "footprint" in r.getMessage()]


def test_a_trajectory_prints_as_one_line_summary():
    """print(trajectory) of a 10 000-ping line is one short line (pings, span, times, CRS), not every array."""
    t = se.Trajectory.survey([(0, 0, -5), (2000, 0, -5)], 2.0, 10.0, crs=32631)
    text = repr(t)
    assert "\n" not in text and len(text) < 200 and "10001 pings" in text and "EPSG:32631" in text
    assert "x/y/z 0…2000, 0…0, -5…-5 m" in text


def test_out_of_range_quotes_the_configured_window():
    """A compressed chirp reaches a pulse length past the window; the error names the configured 75 m, and the
    reach separately (it said 78 m)."""
    scene = se.Scene().add(se.seafloor.flat((20, 20)), label="seafloor")
    far = se.Trajectory.line((500, 0, 10), (502, 0, 10), 3)
    with pytest.raises(se.ConfigError, match=r"max_range_m = 75 m, reach \d+\.?\d* m with the pulse of"):
        se.simulate(scene, far, se.Sonar(max_range_m=75.0), se.Pulse.lfm(bandwidth_hz=20e3, duration_s=4e-3),
                    speckle=False)
