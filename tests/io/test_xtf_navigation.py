"""Issue 50: an XTF's navigation as readers use it. A towed sonar's position is written once (the sensor laid
back, Layback 0: readers that lay the sensor back by Layback do not do it twice), and headings are true headings
(the grid heading turned by the meridian convergence), checked against geodesic bearings computed here."""
import dataclasses
import math

import numpy as np
import pyproj
import pytest
import pyxtf

import sonar_embree as se
from sonar_embree.io.geo import to_lonlat, utm_crs

GEOD = pyproj.Geod(ellps="WGS84")


def _record(origin, heading_deg=90.0, length=200.0, n=21, towed=False):
    """A speckle-free line of ``n`` pings ``length`` m long on the grid heading ``heading_deg``, placed on the
    Earth at ``origin`` (lat, lon)."""
    h = math.radians(heading_deg)
    d = np.array([math.sin(h), math.cos(h), 0.0]) * length / 2
    traj = se.Trajectory.line(tuple(-d + [0, 0, 10.0]), tuple(d + [0, 0, 10.0]), n)
    if towed:
        traj = traj.with_layback(cable_out_m=30.0, tow_point_z_m=20.0)
    scene = se.Scene().add(se.seafloor.flat((2 * length, 2 * length)), label="seafloor")
    rec = se.simulate(scene, traj, se.Sonar(max_range_m=15.0), se.Pulse.cw(), start_time="2026-05-01T12:00:00Z")
    return dataclasses.replace(rec, attrs={**rec.attrs, "geo_origin_deg": list(origin)})


def _pings(rec, tmp_path):
    rec.to_xtf(tmp_path / "line.xtf")
    return pyxtf.xtf_read(str(tmp_path / "line.xtf"))[1][pyxtf.XTFHeaderType.sonar]


def _reader_position(p):
    """Where a reader following the X41 specification puts the sensor: its Sensor fields, laid back by Layback
    (m) against its heading when Layback is not zero."""
    lon, lat = p.SensorXcoordinate, p.SensorYcoordinate
    if p.Layback:
        lon, lat, _ = GEOD.fwd(lon, lat, (p.SensorHeading + 180.0) % 360.0, p.Layback)
    return lon, lat


def test_a_towed_sensor_is_where_readers_put_it(tmp_path):
    rec = _record((54.5, 10.2), towed=True)
    pings = _pings(rec, tmp_path)
    crs = utm_crs(10.2, 54.5)
    e0, n0 = pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(10.2, 54.5)
    pos = rec.trajectory.positions_m
    lon, lat = to_lonlat(crs, pos[:, 0] + e0, pos[:, 1] + n0)
    ship = rec.trajectory.ship_positions_m
    apart = np.hypot(*(ship[:, :2] - pos[:, :2]).T)
    assert np.all(apart > 20.0)                                               # the fish is well behind the ship
    for k, p in enumerate(pings):
        rlon, rlat = _reader_position(p)
        assert GEOD.inv(rlon, rlat, lon[k], lat[k])[2] < 1.0
        assert p.Layback == 0.0 and p.CableOut == 30


@pytest.mark.parametrize("origin,heading", [((54.5, 10.2), 90.0), ((54.5, 10.2), 30.0), ((60.0, 11.95), 90.0),
                                            ((60.0, 11.95), 0.0)], ids=["54N-east", "54N-030", "60N-edge-east",
                                                                        "60N-edge-north"])
def test_headings_are_true_headings(tmp_path, origin, heading):
    """On straight legs at 54.5° N (1.2° from zone 32's central meridian) and at the zone's edge at 60° N (2.6°
    of convergence), SensorHeading is the geodesic bearing of the track within 0.5°; read back into the grid, the
    heading is the grid heading."""
    rec = _record(origin, heading)
    pings = _pings(rec, tmp_path)
    lon = np.array([p.SensorXcoordinate for p in pings])
    lat = np.array([p.SensorYcoordinate for p in pings])
    bearing = np.mod(GEOD.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])[0], 360.0)
    written = np.array([p.SensorHeading for p in pings])
    miss = (written[:-1] - bearing + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(miss)) < 0.5
    grid_gap = (written[0] - heading + 180.0) % 360.0 - 180.0
    assert abs(grid_gap) > (0.8 if origin[0] < 55 else 2.0)                 # the convergence is really there
    back = se.Trajectory.from_xtf(tmp_path / "line.xtf")
    np.testing.assert_allclose((back.heading_deg - heading + 180.0) % 360.0 - 180.0, 0.0, atol=0.05)


def _logged_line(tmp_path, towed=False):
    """A 1 Hz GPS log of a turning track (time, lat, lon) resampled at 8 pings a second, as a survey makes its
    pings, and its record written as XTF."""
    crs = utm_crs(10.2, 54.5)
    e0, n0 = pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(10.2, 54.5)
    t = np.arange(11.0)
    xy = np.stack([e0 + 30 * np.sin(t / 10), n0 + 1.6 * t ** 1.2, np.full(t.size, 10.0)], axis=1)
    log = se.Trajectory(xy, 0.0, 0.0, 0.0, t, crs=crs, start_time="2026-05-01T12:00:00Z")
    traj = log.resampled(8.0)
    if towed:
        traj = traj.with_layback(cable_out_m=25.0, tow_point_z_m=20.0)
    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0), center_m=(e0, n0 + 10)), label="seafloor")
    rec = se.simulate(scene, traj, se.Sonar(max_range_m=15.0), se.Pulse.cw())
    path = tmp_path / "logged.xtf"
    rec.to_xtf(path)
    return log, rec, path


@pytest.mark.parametrize("towed", [False, True], ids=["hull", "towed"])
def test_fixes_are_held_between_pings_as_devices_log_them(tmp_path, towed):
    """A 1 Hz log and 8 pings a second: FixTime is the last fix's time (whole seconds here), the position is
    where the fish was then (within 1 cm, computed here from the pose at that time), repeated until the next fix;
    the ping times, depth and heading are each ping's own."""
    log, rec, path = _logged_line(tmp_path, towed)
    pings = pyxtf.xtf_read(str(path))[1][pyxtf.XTFHeaderType.sonar]
    ping_s = np.array([p.Second + p.HSeconds / 100 for p in pings])
    fix_s = np.array([p.FixTimeSecond + p.FixTimeHsecond / 100 for p in pings])
    np.testing.assert_array_equal(fix_s, np.floor(ping_s + 1e-9))           # the whole second before each ping
    assert len(set(ping_s)) == len(pings) == 81
    lon = np.array([p.SensorXcoordinate for p in pings])
    same = lon[1:] == lon[:-1]
    assert same.mean() == pytest.approx(70 / 80)                             # 7 of every 8 pings repeat the fix
    crs = rec.trajectory.crs
    whole, which = np.unique(fix_s - fix_s[0], return_inverse=True)
    fish = rec.trajectory.at_times(whole).positions_m[which]                 # where the fish was at each fix
    want = to_lonlat(crs, fish[:, 0], fish[:, 1])
    assert np.max(GEOD.inv(lon, [p.SensorYcoordinate for p in pings], *want)[2]) < 0.01
    assert np.ptp([p.SensorDepth for p in pings]) == 0 and len({p.SensorHeading for p in pings}) > 40


@pytest.mark.parametrize("towed", [False, True], ids=["hull", "towed"])
def test_a_replay_rebuilds_the_continuous_track_between_fixes(tmp_path, towed):
    """Read back, the held positions become a continuous track: every ping within 0.15 m of where it was
    simulated (the log's curvature over a second), no two pings at the same place, fix times kept."""
    log, rec, path = _logged_line(tmp_path, towed)
    back = se.Trajectory.from_xtf(path, crs=rec.trajectory.crs)
    miss = np.hypot(*(back.positions_m[:, :2] - rec.trajectory.positions_m[:, :2]).T)
    assert miss.max() < 0.15
    assert np.all(np.hypot(*np.diff(back.positions_m[:, :2], axis=0).T) > 0.05)
    np.testing.assert_allclose(back.fix_times_s, np.floor(back.times_s + 1e-9), atol=1e-9)
    held = np.hypot(*(np.repeat(back.positions_m[::8, :2], 8, axis=0)[:81] - rec.trajectory.positions_m[:, :2]).T)
    assert held.max() > 1.0                                                  # taken as logged, it would be wrong


def test_the_held_track_against_a_naive_rebuild():
    """continuous_track against a loop written here: fixes where the position changes, linear between them."""
    from sonar_embree.io.xtf import continuous_track

    rng = np.random.default_rng(3)
    t = np.arange(40) * 0.25
    fx, fy = rng.normal(size=11).cumsum(), rng.normal(size=11).cumsum()
    k = np.floor(t).astype(int)
    x, y = continuous_track(t, fx[k], fy[k], np.floor(t))
    for i, ti in enumerate(t):
        j = min(int(ti), 8)                                                   # the leg it lies on (last: 8→9)
        w = ti - j
        assert x[i] == pytest.approx(fx[j] + w * (fx[j + 1] - fx[j]))
        assert y[i] == pytest.approx(fy[j] + w * (fy[j + 1] - fy[j]))
    same = continuous_track(t, np.arange(40.0), np.zeros(40))               # every ping its own fix: as it is
    np.testing.assert_array_equal(same[0], np.arange(40.0))


def test_a_held_position_under_per_ping_fix_times_is_still_rebuilt():
    """Some devices stamp every ping with its own FixTime yet repeat the position until the GPS updates: the fixes
    are where the position changes, placed at the first ping that carries each."""
    from sonar_embree.io.xtf import continuous_track

    t = np.arange(12) * 0.25
    held = np.floor(t)                                                        # 1 Hz positions, x = the fix's second
    x, y = continuous_track(t, held, np.zeros(12), fix_s=t)
    np.testing.assert_allclose(x, t)                                         # the straight track between the fixes
