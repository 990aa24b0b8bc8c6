"""Issue 49: a survey's inputs checked before any line renders, its implausible set-ups warned, its summary
portable, and a survey killed at any point resumed by the same command."""
import datetime as dt
import json
import logging
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pyproj
import pytest

import sonar_embree as se

from sonar_embree.errors import ConfigError
from sonar_embree.io.geotiff import write_grid
from sonar_embree.io.owner import MANIFEST
from sonar_embree.runs.cli import main
from sonar_embree.runs.survey import run_survey

CRS, E0, N0 = "EPSG:32631", 500_000.0, 6_000_000.0


def _dem(path, hole=False):
    """80 m × 60 m at 1 m, 12 m deep; with ``hole``, nodata (NaN) over a 4 m × 4 m square under the track."""
    z = np.full((60, 80), -12.0)
    if hole:
        z[28:32, 38:42] = np.nan
    write_grid(path, z, E0 - 40, N0 + 30, 1.0, CRS)


def _nav(path, seconds=3, scale=None, times=True, rows=None):
    """A 1 Hz log eastwards at 2 m/s, 5 m deep: ISO times (``scale``: time_s, k·scale), or none."""
    lon, lat = pyproj.Transformer.from_crs(CRS, "EPSG:4326", always_xy=True).transform(
        E0 - 3 + 2.0 * np.arange(seconds + 1), np.full(seconds + 1, N0))
    t0 = dt.datetime(2026, 5, 1, 12, 0, 0, tzinfo=dt.timezone.utc)
    out = []
    for k, (a, o) in enumerate(zip(lat, lon)):
        t = "" if not times else f"{k * scale!r}," if scale else f"{(t0 + dt.timedelta(seconds=k)).isoformat()},"
        out.append(f"{t}{float(a)!r},{float(o)!r},5.0")
    out = out[:rows] if rows else out
    head = ("" if not times else "time_s," if scale else "time,") + "lat_deg,lon_deg,depth_m\n"
    path.write_text(head + "\n".join(out) + "\n")


def _survey(tmp_path, nav, out="out", **kw):
    return run_survey(tmp_path / "dem.tif", [nav], tmp_path / out, "cmax-cm2-325", ping_rate_hz=2.0, pixel_m=1.0,
                      progress=False, **kw)


def test_a_one_row_log_and_a_log_without_times_are_refused_before_any_work(tmp_path):
    _dem(tmp_path / "dem.tif")
    _nav(tmp_path / "one.csv", rows=1)
    with pytest.raises(ConfigError, match="one.csv: a navigation log needs two fixes at least, got 1"):
        _survey(tmp_path, tmp_path / "one.csv")
    _nav(tmp_path / "untimed.csv", times=False)
    with pytest.raises(ConfigError, match="untimed.csv: a survey's navigation log needs a time column"):
        _survey(tmp_path, tmp_path / "untimed.csv")
    assert not (tmp_path / "out").exists()


def test_milliseconds_typed_as_seconds_are_warned(tmp_path, caplog):
    _dem(tmp_path / "dem.tif")
    _nav(tmp_path / "ms.csv", seconds=2, scale=1000.0)                 # 2 m/s logged in ms: 0.002 m/s
    from sonar_embree.trajectory import Trajectory
    with caplog.at_level(logging.WARNING):
        Trajectory.from_csv(tmp_path / "ms.csv", crs=CRS)
    assert "are the times in seconds, not milliseconds?" in caplog.text
    caplog.clear()
    _nav(tmp_path / "s.csv", seconds=2, scale=1.0)
    with caplog.at_level(logging.WARNING):
        Trajectory.from_csv(tmp_path / "s.csv", crs=CRS)
    assert "are the times in seconds" not in caplog.text


def test_a_dem_hole_under_the_track_is_warned(tmp_path, caplog):
    _dem(tmp_path / "dem.tif", hole=True)
    _nav(tmp_path / "nav.csv", seconds=4)
    with caplog.at_level(logging.WARNING):
        _survey(tmp_path, tmp_path / "nav.csv")
    assert "lies over nodata holes" in caplog.text
    caplog.clear()
    _dem(tmp_path / "dem.tif")
    with caplog.at_level(logging.WARNING):
        _survey(tmp_path, tmp_path / "nav.csv", out="out2")
    assert "nodata holes" not in caplog.text


def test_pixel_is_checked_first_and_the_summary_paths_are_relative_to_it(tmp_path, capsys):
    _dem(tmp_path / "dem.tif")
    _nav(tmp_path / "nav.csv")
    base = ["survey", "--dem", str(tmp_path / "dem.tif"), "--nav", str(tmp_path / "nav.csv"), "--device",
            "cmax-cm2-325", "--ping-rate", "2", "--no-progress"]
    for bad, says in (("0", "positive"), ("1e5", "below 10000 m"), ("nan", "positive")):
        assert main(base + ["--pixel", bad, "-o", str(tmp_path / "bad")]) == 2
        assert says in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()                             # nothing rendered, nothing left
    assert main(base + ["--pixel", "1", "-o", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "survey.json").read_text())
    assert summary["lines"][0]["files"] == {"zarr": "line_00/line.zarr", "xtf": "line_00/line.xtf",
                                            "png": "line_00/line.png"}


def _kill_cmd(folder):
    return [sys.executable, "-m", "sonar_embree.runs.cli", "survey", "--dem", str(folder / "dem.tif"), "--nav",
            str(folder / "nav.csv"), "--device", "cmax-cm2-325", "--ping-rate", "4", "--pixel", "1", "--no-progress",
            "-o"]


@pytest.fixture(scope="module")
def unbroken(tmp_path_factory):
    """The inputs of the kill tests and their survey run once without a kill."""
    folder = tmp_path_factory.mktemp("unbroken")
    _dem(folder / "dem.tif")
    _nav(folder / "nav.csv", seconds=12)
    proc = subprocess.run(_kill_cmd(folder) + [str(folder / "clean")], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return folder


@pytest.mark.parametrize("marker", [MANIFEST, f"line_00/{MANIFEST}", "line_00/line.zarr/stream.json", "mosaic.tif"])
def test_a_survey_killed_at_any_point_resumes_with_the_same_command(tmp_path, unbroken, marker):
    """kill -9 once the survey has reached ``marker`` (its folder claimed, a line claimed, a block streamed, the
    products begun); the same command then finishes it, and the line equals an uninterrupted run's."""
    cmd = _kill_cmd(unbroken)
    proc = subprocess.Popen(cmd + [str(tmp_path / "out")], start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while not (tmp_path / "out" / marker).exists() and proc.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.002)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
    again = subprocess.run(cmd + [str(tmp_path / "out")], capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr[-2000:]
    for name in ("line_00/line.xtf", "mosaic.tif"):
        assert (tmp_path / "out" / name).read_bytes() == (unbroken / "clean" / name).read_bytes(), name
    assert not [n for n in os.listdir(tmp_path / "out") if n.startswith(".sonar-embree-") and n != MANIFEST]


def test_a_ping_rate_beyond_the_listening_time_is_lowered_with_a_notice(caplog):
    """Issue 50, item 7: a survey's pings never come faster than c/2R; simulate warns of a trajectory whose do,
    and the demo's own pings are 2R/c apart at least."""
    from sonar_embree.runs.demo import anchor_mine_setup
    from sonar_embree.runs.survey import _device

    with caplog.at_level(logging.WARNING):
        sonar, _, rate = _device("cmax-cm2-325", 25.0, 100.0)
    assert rate == pytest.approx(se.Acquisition.of(sonar).sound_speed_m_s / 50.0) and "pinging at" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert _device("cmax-cm2-325", 25.0, 10.0)[2] == 10.0
    assert "pinging at" not in caplog.text
    scene, traj, sonar, pulse = anchor_mine_setup()
    assert np.min(np.diff(traj.times_s)) >= 2 * sonar.max_range_m / se.Acquisition.of(sonar).sound_speed_m_s
    fast = se.Trajectory.line((-12.0, 0.0, 10.0), (12.0, 0.0, 10.0), 240)              # 50 ms apart at 40 m
    with caplog.at_level(logging.WARNING):
        se.simulate(se.Scene().add(se.seafloor.flat((60.0, 60.0))), fast[:40], sonar, pulse)
    assert "less than the 0.05333 s the echoes of 40 m take to return" in caplog.text


def _gps_log(path, names=("time", "latitude", "longitude"), seconds=4):
    """A ship's GPS log: time, lat, lon only (common column names), 1 Hz, east at 2 m/s."""
    lon, lat = pyproj.Transformer.from_crs(CRS, "EPSG:4326", always_xy=True).transform(
        E0 - 3 + 2.0 * np.arange(seconds + 1), np.full(seconds + 1, N0))
    t0 = dt.datetime(2026, 5, 1, 12, 0, 0, tzinfo=dt.timezone.utc)
    rows = [f"{(t0 + dt.timedelta(seconds=k)).isoformat()},{float(a)!r},{float(o)!r}" for k, (a, o) in
            enumerate(zip(lat, lon))]
    path.write_text(",".join(names) + "\n" + "\n".join(rows) + "\n")


def test_a_ships_gps_log_flies_at_a_depth_or_an_altitude(tmp_path, capsys):
    """Issue 50, item 3: a log of time, latitude, longitude (what a surveyor has) runs with --depth-m D (the sonar
    D below the surface) or --altitude-m H (H above the DEM, 12 m deep here); without either, one line says how."""
    import xarray as xr

    _dem(tmp_path / "dem.tif")
    _gps_log(tmp_path / "gps.csv")
    base = ["survey", "--dem", str(tmp_path / "dem.tif"), "--nav", str(tmp_path / "gps.csv"), "--device",
            "cmax-cm2-325", "--ping-rate", "2", "--pixel", "1", "--no-progress"]
    assert main(base + ["-o", str(tmp_path / "none")]) == 2
    assert "--depth-m D or --altitude-m H" in capsys.readouterr().err
    assert main(base + ["--depth-m", "4", "-o", str(tmp_path / "deep")]) == 0
    assert main(base + ["--altitude-m", "3", "-o", str(tmp_path / "alt")]) == 0
    deep = xr.open_zarr(tmp_path / "deep" / "line_00" / "line.zarr")
    alt = xr.open_zarr(tmp_path / "alt" / "line_00" / "line.zarr")
    np.testing.assert_allclose(deep["z_m"].values, -4.0)
    np.testing.assert_allclose(alt["z_m"].values, -12.0 + 3.0)
    np.testing.assert_allclose(alt["altitude_m"].values, 3.0, atol=0.01)
    with pytest.raises(SystemExit):                                    # argparse: not allowed together
        main(base + ["--depth-m", "4", "--altitude-m", "3", "-o", str(tmp_path / "both")])
    with pytest.raises(ConfigError, match="not both"):
        run_survey(tmp_path / "dem.tif", [tmp_path / "gps.csv"], tmp_path / "both", "cmax-cm2-325", depth_m=4.0,
                   altitude_m=3.0, progress=False)


def test_common_column_names_are_taken_and_a_clash_is_named(tmp_path):
    from sonar_embree.trajectory import Trajectory

    _gps_log(tmp_path / "a.csv", names=("Timestamp", "Lat", "Lon"))
    traj = Trajectory.from_csv(tmp_path / "a.csv", crs=CRS, depth_m=5.0)
    assert len(traj) == 5 and np.allclose(traj.positions_m[:, 2], -5.0)
    np.testing.assert_allclose(traj.positions_m[:, 0] - E0, -3 + 2.0 * np.arange(5), atol=0.01)
    (tmp_path / "b.csv").write_text("time_s,lat,latitude,lon,depth_m\n0,54,54,3,5\n")
    with pytest.raises(ConfigError, match="columns 'lat' and 'latitude' both give 'lat_deg'"):
        Trajectory.from_csv(tmp_path / "b.csv")


def test_every_preset_round_trips_through_a_device_file(tmp_path):
    """devices.device_toml then devices.device(path) gives back each shipped preset, field for field."""
    from sonar_embree.instrument.devices import DEVICES, device, device_toml

    for name, d in DEVICES.items():
        (tmp_path / f"{name}.toml").write_text(device_toml(d))
        assert device(str(tmp_path / f"{name}.toml")) == d, name
    text = device_toml(DEVICES["klein-3000-100"])                 # and a broken one is one line naming file and key
    for old, new, message in (("tilt_deg = ", "tilt_deg = 120.0 # ", r"\[device\] tilt_deg must be a number in \[-90"),
                              ('pulse = ["cw"', 'pulse = ["am"', r"\[device\] pulse must be"),
                              ("source_level_db", "# source_level_db", r"\[device\] needs 'source_level_db'")):
        (tmp_path / "bad.toml").write_text(text.replace(old, new))
        with pytest.raises(se.ConfigError, match="bad.toml: " + message):
            device(str(tmp_path / "bad.toml"))


def test_a_device_file_is_a_survey_device(tmp_path):
    """``survey --device FILE.toml`` takes a device file (what ``replay --fit`` writes): the same line as the preset
    it was written from, to the bit."""
    import dataclasses

    import xarray as xr

    from sonar_embree.instrument.devices import device, device_toml

    (tmp_path / "cm2.toml").write_text(device_toml(dataclasses.replace(device("cmax-cm2-325"), name="mine")))
    _dem(tmp_path / "dem.tif")
    _gps_log(tmp_path / "gps.csv")
    lines = {}
    for dev in ("cmax-cm2-325", str(tmp_path / "cm2.toml")):
        out = tmp_path / ("file" if dev.endswith(".toml") else "preset")
        assert main(["survey", "--dem", str(tmp_path / "dem.tif"), "--nav", str(tmp_path / "gps.csv"), "--device", dev,
                     "--ping-rate", "2", "--pixel", "1", "--depth-m", "4", "--no-progress", "--no-labels", "-o",
                     str(out)]) == 0
        lines[dev] = xr.open_zarr(out / "line_00" / "line.zarr")["starboard"].values
    a, b = lines.values()
    assert a.shape == b.shape and np.array_equal(a, b) and a.max() > 0


def test_labels_can_be_left_out_and_the_sediment_chosen(tmp_path, caplog):
    """Issue 50, item 6: --no-labels writes lines without ground truth (and, said in one line, no mosaic);
    --sediment sets the seabed's preset (a harder floor records brighter in floats); truth.tif's band has a
    unit."""
    import rasterio
    import xarray as xr

    _dem(tmp_path / "dem.tif")
    _gps_log(tmp_path / "gps.csv")
    base = ["survey", "--dem", str(tmp_path / "dem.tif"), "--nav", str(tmp_path / "gps.csv"), "--device",
            "cmax-cm2-325", "--ping-rate", "2", "--pixel", "1", "--depth-m", "4", "--no-progress", "--gain", "agc"]
    with caplog.at_level(logging.WARNING):
        assert main(base + ["--no-labels", "-o", str(tmp_path / "bare")]) == 0
    assert "without labels no mosaic" in caplog.text
    bare = xr.open_zarr(tmp_path / "bare" / "line_00" / "line.zarr")
    assert "label_kind" not in bare and not (tmp_path / "bare" / "mosaic.tif").exists()
    levels = {}
    for sed in ("apl-uw clay", "apl-uw coarse sand"):
        out = tmp_path / sed.replace(" ", "_")
        assert main(base + ["--sediment", sed, "-o", str(out)]) == 0
        ds = xr.open_zarr(out / "line_00" / "line.zarr")
        levels[sed] = float(np.median(ds["starboard"].values[:, -200:]))
        assert json.loads((out / "survey.json").read_text())["sediment"] == sed
    assert levels["apl-uw coarse sand"] > 3 * levels["apl-uw clay"]
    with rasterio.open(tmp_path / "apl-uw_clay" / "truth.tif") as t:
        assert t.units == ("m",) and t.descriptions == ("height_m",)
