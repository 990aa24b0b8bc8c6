"""Real coordinates (issue: real surveys; docs/physics.md §15): CRS, navigation from lat/lon logs, lat/lon XTF.

Every position is checked against pyproj's own forward transform from WGS 84 (built here, not through
sonar_embree.io.geo), and the XTF files are written with pyxtf's structures or read back by pyxtf.
"""
import ctypes
import datetime as dt

import numpy as np
import pyproj
import pytest

import sonar_embree as se

UTM32N = "EPSG:32632"
LAT0, LON0 = 54.30, 9.50                              # Kiel Bight: UTM zone 32 north


def _forward(lon, lat, crs=UTM32N):
    return pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(lon, lat)


def _fixes(n=6):
    lat = LAT0 + 1.8e-5 * np.arange(n)                 # ≈ 2 m north per second, a little east
    lon = LON0 + 0.6e-5 * np.arange(n)
    stamps = [dt.datetime(2026, 5, 1, 12, 0, 0, 250000, tzinfo=dt.timezone.utc) + dt.timedelta(seconds=1.0 * i)
              for i in range(n)]
    return lat, lon, stamps


def test_lat_lon_csv_with_iso_times_projects_as_pyproj_does(tmp_path):
    lat, lon, stamps = _fixes()
    path = tmp_path / "nav.csv"
    rows = [f"{t.isoformat().replace('+00:00', 'Z')},{a:.9f},{o:.9f},18.5,12.0" for t, a, o in zip(stamps, lat, lon)]
    path.write_text("time,lat_deg,lon_deg,depth_m,heading_deg\n" + "\n".join(rows) + "\n")
    traj = se.Trajectory.from_csv(path)
    x, y = _forward(lon, lat)
    assert traj.crs == UTM32N                                            # the UTM zone of the first fix
    np.testing.assert_allclose(traj.positions_m[:, 0], x, atol=0.01, rtol=0)
    np.testing.assert_allclose(traj.positions_m[:, 1], y, atol=0.01, rtol=0)
    np.testing.assert_array_equal(traj.positions_m[:, 2], -18.5)
    np.testing.assert_allclose(traj.times_s, np.arange(6.0))
    assert traj.start_time == "2026-05-01T12:00:00.250000+00:00"
    speed = np.linalg.norm(traj.velocity_m_s, axis=1)                  # from the times: it moves during the ping
    np.testing.assert_allclose(speed, np.hypot(np.diff(x).mean(), np.diff(y).mean()), rtol=1e-3)
    other = se.Trajectory.from_csv(path, crs="EPSG:25832")               # ETRS89 / UTM 32N: a given CRS is used
    x2, _ = _forward(lon, lat, "EPSG:25832")
    np.testing.assert_allclose(other.positions_m[:, 0], x2, atol=0.01, rtol=0)


def _write_xtf_with_pyxtf(path, lat, lon, stamps, depth=21.0, heading=33.0):
    """A minimal lat/lon XTF from pyxtf's own ctypes structures: one channel of 4 samples per ping."""
    import pyxtf

    fh = pyxtf.XTFFileHeader()
    fh.FileFormat, fh.SystemType, fh.NavUnits, fh.NumberOfSonarChannels = 0x7B, 1, 3, 1
    fh.ChanInfo[0].TypeOfChannel, fh.ChanInfo[0].BytesPerSample, fh.ChanInfo[0].SampleFormat = 1, 2, 3
    with open(path, "wb") as f:
        f.write(bytes(fh))
        for i, (a, o, t) in enumerate(zip(lat, lon, stamps)):
            ph, ch = pyxtf.XTFPingHeader(), pyxtf.XTFPingChanHeader()
            ph.MagicNumber, ph.HeaderType, ph.NumChansToFollow, ph.PingNumber = 0xFACE, 0, 1, i
            ph.Year, ph.Month, ph.Day, ph.Hour, ph.Minute, ph.Second = t.year, t.month, t.day, t.hour, t.minute, t.second
            ph.HSeconds = t.microsecond // 10000
            ph.SensorXcoordinate, ph.SensorYcoordinate, ph.SensorDepth = o, a, depth
            ph.SensorHeading, ph.SensorPitch, ph.SensorRoll, ph.SensorSpeed = heading, 1.5, -2.0, 4.0
            ch.NumSamples = 4
            data = np.zeros(4, np.uint16).tobytes()
            ph.NumBytesThisRecord = ctypes.sizeof(ph) + ctypes.sizeof(ch) + len(data)
            f.write(bytes(ph) + bytes(ch) + data)


def test_xtf_navigation_written_by_pyxtf_projects_as_pyproj_does(tmp_path):
    lat, lon, stamps = _fixes()
    path = tmp_path / "nav.xtf"
    _write_xtf_with_pyxtf(path, lat, lon, stamps)
    traj = se.Trajectory.from_xtf(path)
    x, y = _forward(lon, lat)
    assert traj.crs == UTM32N and traj.start_time == "2026-05-01T12:00:00.250000+00:00"
    np.testing.assert_allclose(traj.positions_m, np.column_stack([x, y, np.full(6, -21.0)]), atol=0.01, rtol=0)
    np.testing.assert_allclose(traj.times_s, np.arange(6.0))
    gamma = pyproj.Proj(UTM32N).get_factors(lon[0], lat[0]).meridian_convergence   # true north to grid north
    np.testing.assert_allclose([traj.heading_deg[0], traj.pitch_deg[0], traj.roll_deg[0]], [33.0 - gamma, 1.5, -2.0],
                               atol=1e-4)                            # the file's true heading, in the grid
    with pytest.raises(se.ConfigError, match="no sonar pings"):
        empty = tmp_path / "empty.xtf"
        empty.write_bytes(bytes(__import__("pyxtf").XTFFileHeader()))
        se.Trajectory.from_xtf(empty)


def _georeferenced_record():
    x0, y0 = _forward(LON0, LAT0)
    floor = se.seafloor.flat((200.0, 200.0), z_m=-30.0, center_m=(x0, y0))
    scene = se.Scene().add(floor, label="seafloor")
    line = se.Trajectory.line((x0 - 4.0, y0, -20.0), (x0 + 4.0, y0, -20.0), 5, speed_m_s=2.0)
    line = se.Trajectory(line.positions_m, line.heading_deg, times_s=line.times_s, velocity_m_s=line.velocity_m_s,
                         crs=32632, start_time="2026-05-01T12:00:00Z")
    return se.simulate(scene, line, se.Sonar(max_range_m=30.0))


def test_lat_lon_xtf_reads_back_in_pyxtf_with_positions_speed_and_times(tmp_path):
    """The XTF of a georeferenced record: NavUnits 3, longitude/latitude as pyproj inverts the positions (1 cm ≈
    1e-7°), speed in knots, real times from the trajectory's start time, depth below z = 0."""
    import pyxtf

    rec = _georeferenced_record()
    assert rec.attrs["crs"] == UTM32N and rec.attrs["start_time"] == "2026-05-01T12:00:00+00:00"
    path = tmp_path / "line.xtf"
    rec.to_xtf(path)
    header, packets = pyxtf.xtf_read(str(path))
    pings = packets[pyxtf.XTFHeaderType.sonar]
    assert header.NavUnits == 3 and len(pings) == 5
    back = pyproj.Transformer.from_crs(UTM32N, "EPSG:4326", always_xy=True)
    lon, lat = back.transform(rec.trajectory.positions_m[:, 0], rec.trajectory.positions_m[:, 1])
    np.testing.assert_allclose([p.SensorXcoordinate for p in pings], lon, atol=1e-7, rtol=0)
    np.testing.assert_allclose([p.SensorYcoordinate for p in pings], lat, atol=1e-7, rtol=0)
    np.testing.assert_allclose([p.SensorSpeed for p in pings], 2.0 * 3600 / 1852, rtol=1e-6)
    np.testing.assert_allclose([p.SensorDepth for p in pings], 20.0)
    assert [(p.Hour, p.Minute, p.Second) for p in pings] == [(12, 0, i) for i in range(5)]   # 2 m apart at 2 m/s
    again = se.Trajectory.from_xtf(path)                                 # and our reader inverts it (1 cm)
    np.testing.assert_allclose(again.positions_m, rec.trajectory.positions_m, atol=0.01, rtol=0)


def test_record_file_keeps_the_crs(tmp_path):
    rec = _georeferenced_record()
    rec.save(tmp_path / "r.npz")
    back = se.Record.load(tmp_path / "r.npz")
    assert back.trajectory == rec.trajectory
    assert back.trajectory.crs == UTM32N and back.trajectory.start_time == "2026-05-01T12:00:00+00:00"


@pytest.mark.parametrize("crs, match", [(4326, "not projected"), ("EPSG:999999", "unknown CRS"),
                                        (2.5, "EPSG code"), ("EPSG:2227", "US survey foot, not metres")])
def test_bad_crs_is_refused_with_its_value(crs, match):
    with pytest.raises(se.ConfigError, match=match):
        se.Trajectory(np.zeros((1, 3)), crs=crs)


def test_bad_navigation_csv_names_the_problem(tmp_path):
    both = tmp_path / "both.csv"
    both.write_text("x_m,lat_deg,y_m,z_m\n1,54,2,3\n")
    with pytest.raises(se.ConfigError, match="both.csv: give 'x_m' or 'lat_deg'"):
        se.Trajectory.from_csv(both)
    metres = tmp_path / "metres.csv"                                     # eastings in the latitude column
    metres.write_text("lat_deg,lon_deg,depth_m\n6017015.9,532538.5,20\n")
    with pytest.raises(se.ConfigError, match="metres.csv: latitude/longitude .* out of range"):
        se.Trajectory.from_csv(metres, crs=UTM32N)
    bad_time = tmp_path / "time.csv"
    bad_time.write_text("time,x_m,y_m,z_m\n12:00,0,0,0\n")
    with pytest.raises(se.ConfigError, match="time.csv: .*ISO 8601"):
        se.Trajectory.from_csv(bad_time)


def test_zarr_and_netcdf_carry_the_crs_and_lat_lon(tmp_path):
    """CF grid mapping: a ``crs`` variable whose WKT pyproj reads back as the record's CRS, channels naming it,
    per-ping longitude/latitude as pyproj inverts the positions; the same through NetCDF."""
    import xarray as xr

    rec = _georeferenced_record()
    rec.to_zarr(tmp_path / "line.zarr")
    rec.to_xarray().to_netcdf(tmp_path / "line.nc")
    back = pyproj.Transformer.from_crs(UTM32N, "EPSG:4326", always_xy=True)
    lon, lat = back.transform(rec.trajectory.positions_m[:, 0], rec.trajectory.positions_m[:, 1])
    for ds in (xr.open_zarr(tmp_path / "line.zarr"), xr.open_dataset(tmp_path / "line.nc")):
        assert pyproj.CRS.from_wkt(ds["crs"].attrs["crs_wkt"]).to_epsg() == 32632
        assert ds["starboard"].attrs["grid_mapping"] == "crs"
        np.testing.assert_allclose(ds["lon"].values, lon, atol=1e-9)
        np.testing.assert_allclose(ds["lat"].values, lat, atol=1e-9)
        assert ds["lat"].attrs["standard_name"] == "latitude"
        ds.close()


@pytest.mark.filterwarnings("ignore")  # pandas deprecations inside the reader
def test_pingmapper_reader_reads_the_lat_lon_xtf(tmp_path):
    """PINGMapper reads XTF through pingverter's xtf class: on our lat/lon XTF it finds NavUnits 3, projects to
    the same UTM zone, and its eastings, northings, speed and depth are ours (1 cm, float32 knots)."""
    from pingverter.xtf_class import xtf

    rec = _georeferenced_record()
    rec.to_xtf(tmp_path / "line.xtf")
    reader = xtf(str(tmp_path / "line.xtf"))
    reader.metaDir, reader.tempC = str(tmp_path), 10.0                # what PINGMapper sets before parsing
    reader._getFileLen()
    reader._parseFileHeader()
    reader._parsePingHeader()
    df = reader.header_dat
    assert reader.nav_units == 3 and reader.humDat["epsg"] == UTM32N
    for beam in (2, 3):                                                 # port and starboard
        d = df[df["beam"] == beam]
        np.testing.assert_allclose(d["e"], rec.trajectory.positions_m[:, 0], atol=0.01, rtol=0)
        np.testing.assert_allclose(d["n"], rec.trajectory.positions_m[:, 1], atol=0.01, rtol=0)
        np.testing.assert_allclose(d["speed_ms"], 2.0, rtol=1e-5)
        np.testing.assert_allclose(d["inst_dep_m"], 20.0)


def test_georeferenced_trajectory_csv_round_trip(tmp_path):
    """to_csv writes lat/lon and ISO times for a trajectory with a CRS and a start time; from_csv reads it back
    in the same (UTM) CRS to 1 mm and 1 µs."""
    traj = se.Trajectory.line((532000.0, 6017000.0, -20.0), (532040.0, 6017010.0, -20.0), 9)
    traj = se.Trajectory(traj.positions_m, traj.heading_deg, times_s=traj.times_s + 0.25,
                         velocity_m_s=traj.velocity_m_s, crs=UTM32N, start_time="2026-05-01T12:00:00Z")
    traj.to_csv(tmp_path / "nav.csv")
    header = (tmp_path / "nav.csv").read_text().splitlines()[0]
    assert header.startswith("time,lat_deg,lon_deg,z_m")
    back = se.Trajectory.from_csv(tmp_path / "nav.csv")
    assert back.crs == UTM32N and back.start_time == "2026-05-01T12:00:00.250000+00:00"
    np.testing.assert_allclose(back.positions_m, traj.positions_m, atol=1e-3, rtol=0)
    np.testing.assert_allclose(back.times_s + 0.25, traj.times_s, atol=1e-6)
    np.testing.assert_allclose(back.velocity_m_s, traj.velocity_m_s, atol=1e-9)
    plain = se.Trajectory.line((0.0, 0.0, 10.0), (4.0, 0.0, 10.0), 3)
    plain.to_csv(tmp_path / "plain.csv")
    assert se.Trajectory.from_csv(tmp_path / "plain.csv") == plain


def test_a_fast_pinging_xtf_reads_back_with_its_times(tmp_path):
    """Issue 33, finding 11: at 140 pings/s (legal at 5 m range) hundredths of a second cannot order the pings
    ("not strictly increasing"); NavFixMilliseconds, which the writer fills, refines them to 1 ms."""
    x0, y0 = _forward(LON0, LAT0)
    scene = se.Scene().add(se.seafloor.flat((100.0, 100.0), z_m=-30.0, center_m=(x0, y0)), label="seafloor")
    n, rate = 30, 140.0
    line = se.Trajectory.line((x0, y0, -27.0), (x0 + 1.5 * (n - 1) / rate, y0, -27.0), n, speed_m_s=1.5)
    line = se.Trajectory(line.positions_m, line.heading_deg, times_s=np.arange(n) / rate,
                         velocity_m_s=line.velocity_m_s, crs=32632, start_time="2026-05-01T12:00:00Z")
    rec = se.simulate(scene, line, se.Sonar(max_range_m=5.0))
    rec.to_xtf(tmp_path / "fast.xtf")
    back = se.Trajectory.from_xtf(tmp_path / "fast.xtf")
    assert np.all(np.diff(back.times_s) > 0)
    np.testing.assert_allclose(back.times_s, np.arange(n) / rate, atol=1.01e-3, rtol=0)


def test_truncated_and_corrupt_xtf_files_are_refused(tmp_path):
    """Finding 11: a file cut at 50 % silently gave half its pings, and NumBytesThisRecord = 0xffffffff one
    ping; both are now refused naming the packet and its byte offset."""
    rec = _georeferenced_record()
    rec.to_xtf(tmp_path / "line.xtf")
    data = (tmp_path / "line.xtf").read_bytes()
    assert se.io.xtf.check_packets(str(tmp_path / "line.xtf")) == 5
    (tmp_path / "cut.xtf").write_bytes(data[: len(data) // 2])
    with pytest.raises(se.ConfigError, match=r"cut.xtf: packet 2 at byte \d+ claims \d+ bytes, but \d+ remain; "
                                             r"the file is truncated"):
        se.Trajectory.from_xtf(tmp_path / "cut.xtf")
    bad = bytearray(data)
    bad[1024 + 10:1024 + 14] = (0xFFFFFFFF).to_bytes(4, "little")
    (tmp_path / "bad.xtf").write_bytes(bytes(bad))
    with pytest.raises(se.ConfigError, match=r"bad.xtf: packet 0 at byte 1024 claims 4294967295 bytes"):
        se.Trajectory.from_xtf(tmp_path / "bad.xtf")
    (tmp_path / "junk.xtf").write_bytes(data + b"\x00" * 20)
    with pytest.raises(se.ConfigError, match=r"junk.xtf: no XTF packet at byte \d+ \(magic number 0x0000"):
        se.Trajectory.from_xtf(tmp_path / "junk.xtf")
