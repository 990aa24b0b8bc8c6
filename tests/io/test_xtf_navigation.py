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
