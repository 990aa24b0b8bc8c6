"""sonar-embree survey (issue 35, item 1): a GeoTIFF DEM and a 1 Hz lat/lon navigation log without heading → per line
XTF, Zarr and PNG, the survey's mosaic, truth and quick look, each read back by its own reader."""
import datetime as dt
import json
import os
import subprocess
import sys

import numpy as np
import pyproj
import pyxtf
import rasterio
import xarray as xr

from sonar_embree.io.geotiff import write_grid

CRS, E0, N0 = "EPSG:32631", 500_000.0, 6_000_000.0


def _dem(path):
    """200 m × 120 m at 1 m, 20 m deep with a 2 m mound, north-up, upper-left corner (E0 − 100, N0 + 60)."""
    x = np.arange(200) + 0.5 - 100
    y = 60 - (np.arange(120) + 0.5)
    xx, yy = np.meshgrid(x, y)
    z = -20.0 + 2.0 * np.exp(-((xx - 5) ** 2 + (yy + 12) ** 2) / 20.0)
    write_grid(path, z, E0 - 100, N0 + 60, 1.0, CRS)


def _nav(path, seconds=10, speed=2.0):
    """A 1 Hz log eastwards through the DEM's middle at 2 m/s, 10 m deep, lat/lon and ISO times, no heading."""
    lon, lat = pyproj.Transformer.from_crs(CRS, "EPSG:4326", always_xy=True).transform(
        E0 - 10 + speed * np.arange(seconds + 1), np.full(seconds + 1, N0))
    t0 = dt.datetime(2026, 5, 1, 12, 0, 0, tzinfo=dt.timezone.utc)
    rows = [f"{(t0 + dt.timedelta(seconds=k)).isoformat()},{float(la)!r},{float(lo)!r},10.0" for k, (la, lo) in
            enumerate(zip(lat, lon))]
    path.write_text("time,lat_deg,lon_deg,depth_m\n" + "\n".join(rows) + "\n")


def test_a_survey_from_a_dem_and_a_nav_log_runs_from_the_cli(tmp_path):
    _dem(tmp_path / "dem.tif")
    _nav(tmp_path / "nav.csv")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "sonar_embree.runs.cli", "survey", "--dem", str(tmp_path / "dem.tif"), "--nav",
           str(tmp_path / "nav.csv"), "--device", "cmax-cm2-325", "--layback", "10", "--no-progress", "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "no heading_deg column" in proc.stderr                       # the one-line notice
    line = out / "line_00"
    # pings at the CM2's stated 13.5 /s at 25 m, 2 m/s apart: 0.148 m
    ds = xr.open_zarr(line / "line.zarr")
    step = np.hypot(np.diff(ds["x_m"].values), np.diff(ds["y_m"].values))
    np.testing.assert_allclose(np.median(step), 2.0 / 13.5, rtol=0.01)
    assert ds.sizes["ping"] == 136                                      # 10 s at 13.5 /s, both ends
    ds.to_netcdf(tmp_path / "line.nc", auto_complex=True)
    assert xr.open_dataset(tmp_path / "line.nc")["port"].shape == ds["port"].shape
    # XTF: lat/lon, ship 10 m ahead of the sensor, speed, 16-bit codes within full scale
    header, packets = pyxtf.xtf_read(str(line / "line.xtf"))
    pings = packets[pyxtf.XTFHeaderType.sonar]
    assert header.NavUnits == 3 and len(pings) == 136
    geod = pyproj.Geod(ellps="WGS84")
    apart = geod.inv([p.ShipXcoordinate for p in pings[20:]], [p.ShipYcoordinate for p in pings[20:]],
                     [p.SensorXcoordinate for p in pings[20:]], [p.SensorYcoordinate for p in pings[20:]])[2]
    np.testing.assert_allclose(apart, 10.0, atol=0.05)
    np.testing.assert_allclose([p.SensorSpeed * 1852 / 3600 for p in pings[5:-5]], 2.0, rtol=0.01)
    codes = np.concatenate([p.data[0] for p in pings] + [p.data[1] for p in pings])
    assert codes.dtype == np.uint16 and (codes == 65535).mean() < 0.01 and (codes > 0).mean() > 0.3   # TVG
    # the mosaic: CRS, inside the DEM, units, overviews; truth; PNGs
    with rasterio.open(out / "mosaic.tif") as m, rasterio.open(tmp_path / "dem.tif") as d:
        assert m.crs == d.crs and m.units == ("1", "m") and m.overviews(1)
        assert d.bounds.left <= m.bounds.left and m.bounds.right <= d.bounds.right
        assert d.bounds.bottom <= m.bounds.bottom and m.bounds.top <= d.bounds.top
    with rasterio.open(out / "truth.tif") as t:
        assert np.nanmin(t.read(1)) < -19.0
    for png in (out / "mosaic.png", line / "line.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((out / "survey.json").read_text())
    assert summary["ping_rate_hz"] == 13.5 and summary["lines"][0]["pings"] == 136
    # a rerun resumes (nothing to redo) and a foreign folder is refused in one line
    assert subprocess.run(cmd, capture_output=True, text=True, timeout=600).returncode == 0
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    bad = subprocess.run(cmd[:-1] + [str(tmp_path / "mine")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "not empty (holds 'notes.txt')" in bad.stderr
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"


def test_a_survey_toml_gives_the_same_keywords_and_refuses_unknown_keys(tmp_path):
    """[survey] in TOML: paths relative to the file, a nav list, numbers; an unknown key, a missing dem and a
    string where a number belongs are one-line errors naming the file and key."""
    import pytest

    import sonar_embree as se
    from sonar_embree.runs.survey import load_survey_config

    (tmp_path / "s.toml").write_text('[survey]\ndem = "dem.tif"\nnav = ["a.csv", "b.csv"]\ndevice = "cmax-cm2-325"\n'
                                     'layback_m = 10\nspeckle = true\n')
    kw = load_survey_config(tmp_path / "s.toml")
    assert kw == dict(dem=str(tmp_path / "dem.tif"), navs=[str(tmp_path / "a.csv"), str(tmp_path / "b.csv")],
                      device="cmax-cm2-325", layback_m=10, speckle=True)
    for text, match in (('[survey]\ndem = "d.tif"\nnav = "a.csv"\ndevice = "x"\nlayback = 3\n', "unknown key 'layback'"),
                        ('[survey]\nnav = "a.csv"\ndevice = "x"\n', "needs 'dem'"),
                        ('[survey]\ndem = "d.tif"\nnav = "a.csv"\ndevice = "x"\nrange_m = "75"\n', "range_m must be a number")):
        (tmp_path / "bad.toml").write_text(text)
        with pytest.raises(se.ConfigError, match=match) as err:
            load_survey_config(tmp_path / "bad.toml")
        assert "bad.toml" in str(err.value) and "\n" not in str(err.value)
    proc = subprocess.run([sys.executable, "-m", "sonar_embree.runs.cli", "survey", "--nav", "x.csv", "-o",
                           str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "give --dem" in proc.stderr


def test_a_planned_survey_covers_a_polygon(tmp_path):
    """--plan: a lat/lon polygon inside the DEM becomes planned lines (run in and out by the range), flown 10 m deep
    at 2 m/s at the device's rate; each line's XTF and the mosaic are written, the mosaic over the polygon."""
    _dem(tmp_path / "dem.tif")
    lon, lat = pyproj.Transformer.from_crs(CRS, "EPSG:4326", always_xy=True).transform(
        [E0 - 10, E0 + 10, E0 + 10, E0 - 10], [N0 - 5, N0 - 5, N0 + 5, N0 + 5])
    (tmp_path / "area.csv").write_text("lat_deg,lon_deg\n" + "".join(f"{float(a)!r},{float(o)!r}\n"
                                                                     for a, o in zip(lat, lon)))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "sonar_embree.runs.cli", "survey", "--dem", str(tmp_path / "dem.tif"),
                           "--plan", str(tmp_path / "area.csv"), "--depth", "10", "--device", "cmax-cm2-325",
                           "--no-progress", "-o", str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = json.loads((out / "survey.json").read_text())
    assert len(summary["lines"]) >= 1 and all(line["pings"] > 100 for line in summary["lines"])
    header, packets = pyxtf.xtf_read(str(out / "line_00" / "line.xtf"))
    assert header.NavUnits == 3 and len(packets[pyxtf.XTFHeaderType.sonar]) == summary["lines"][0]["pings"]
    with rasterio.open(out / "mosaic.tif") as m:
        assert m.bounds.left < E0 - 10 and m.bounds.right > E0 + 10


def test_a_survey_over_a_mesh_seabed_from_a_projected_log(tmp_path):
    """run_survey with a mesh file as the seabed (its CRS given) and a projected log with numeric times: the line
    streams at the given ping rate, the mosaic and truth carry the CRS, the truth is the mesh's depth."""
    import trimesh

    from sonar_embree.runs.survey import run_survey

    floor = trimesh.creation.box(extents=(120.0, 120.0, 1.0))
    floor.apply_translation((E0, N0, -20.5))                            # its top at z = −20
    floor.export(tmp_path / "seabed.ply")
    rows = "".join(f"{float(t)!r},{E0 - 10 + 2.0 * t!r},{N0!r},-12.0\n" for t in range(11))
    (tmp_path / "nav.csv").write_text("time_s,x_m,y_m,z_m\n" + rows)
    files = run_survey(tmp_path / "seabed.ply", [tmp_path / "nav.csv"], tmp_path / "out", "cmax-cm2-780",
                       ping_rate_hz=5.0, crs=32631, progress=False, pixel_m=1.0)
    assert files[-1].endswith("survey.json") and json.loads((tmp_path / "out" / "survey.json").read_text())[
        "lines"][0]["pings"] == 51
    with rasterio.open(tmp_path / "out" / "truth.tif") as t:
        assert t.crs.to_epsg() == 32631 and np.nanmax(np.abs(t.read(1) + 20.0)) < 1e-6


def test_a_survey_on_two_worker_processes_writes_the_same_line(tmp_path):
    """``--workers 2`` renders each line's blocks on two processes: the line's XTF and data equal the in-process
    survey's; ``--workers 0`` is refused in one line."""
    _dem(tmp_path / "dem.tif")
    _nav(tmp_path / "nav.csv")
    base = [sys.executable, "-m", "sonar_embree.runs.cli", "survey", "--dem", str(tmp_path / "dem.tif"), "--nav",
            str(tmp_path / "nav.csv"), "--device", "cmax-cm2-325", "--no-progress"]
    for name, workers in (("one", "1"), ("two", "2")):
        proc = subprocess.run(base + ["--workers", workers, "-o", str(tmp_path / name)], capture_output=True,
                              text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-2000:]
    line = "line_00/line.xtf"
    assert (tmp_path / "one" / line).read_bytes() == (tmp_path / "two" / line).read_bytes()
    one, two = (xr.open_zarr(tmp_path / d / "line_00" / "line.zarr") for d in ("one", "two"))
    np.testing.assert_array_equal(one["port"].values, two["port"].values)
    proc = subprocess.run(base + ["--workers", "0", "-o", str(tmp_path / "bad")], capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode != 0 and "--workers must be >= 1, got 0" in proc.stderr
