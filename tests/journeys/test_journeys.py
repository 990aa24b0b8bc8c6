"""The journeys tier (issue 50): each command run end to end as a user runs it, from the command line, into a
folder that already holds the user's own files; what it writes opened with the programs users open it with
(pyxtf, xarray, rasterio) and checked for what a viewer shows: the water column dark against the seabed in the
stored codes, positions and true headings, ping timing, the waterfall drawn from the codes; and every XTF the
project writes replayed."""
import datetime as dt
import json
import os
import subprocess
import sys

import numpy as np
import pyproj
import pytest
import pyxtf
import rasterio
import xarray as xr

from sonar_embree.io.geotiff import write_grid

CRS, E0, N0 = "EPSG:32632", 560_000.0, 6_040_000.0                     # UTM 32N, some 54.5° N, 9.9° E
GEOD = pyproj.Geod(ellps="WGS84")
MINE = "my survey notes: do not lose\n"


def _cli(*args, timeout=600):
    """``sonar-embree ARGS`` in a fresh process, as a user types it; (exit status, stderr)."""
    proc = subprocess.run([sys.executable, "-m", "sonar_embree.runs.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)
    return proc.returncode, proc.stderr


def _users_folder(path):
    """A folder the user already keeps things in: a note and a dot-file next to where the outputs go."""
    path.mkdir(parents=True, exist_ok=True)
    (path / "notes.txt").write_text(MINE)
    (path / ".tmp-draft.txt").write_text(MINE)
    return path


def _untouched(path):
    assert (path / "notes.txt").read_text() == MINE and (path / ".tmp-draft.txt").read_text() == MINE


def _pings(path):
    header, packets = pyxtf.xtf_read(str(path))
    return header, packets[pyxtf.XTFHeaderType.sonar]


def _ping_seconds(pings):
    return np.array([dt.datetime(p.Year, p.Month, p.Day, p.Hour, p.Minute, p.Second).timestamp() + p.HSeconds / 100
                     for p in pings])


def _check_timing_and_headings(pings):
    """Pings at least 2R/c apart (as the file says: SlantRange and SoundVelocity = c/2), and each heading the
    geodesic bearing of the track within 0.5° on a straight leg."""
    c = pings[0].ping_chan_headers[1]
    gaps = np.diff(_ping_seconds(pings))
    assert np.median(gaps) >= c.SlantRange / pings[0].SoundVelocity - 0.011          # hundredths of a second
    lon = np.array([p.SensorXcoordinate for p in pings])
    lat = np.array([p.SensorYcoordinate for p in pings])
    moved = GEOD.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])
    far = np.flatnonzero(moved[2] > 0.05)
    bearing = np.mod(moved[0][far], 360.0)
    heading = np.array([pings[k].SensorHeading for k in far])
    assert np.max(np.abs((heading - bearing + 180.0) % 360.0 - 180.0)) < 0.5


def _replayed(xtf, out):
    """``replay`` of an XTF the project wrote: it runs, and its report is strict JSON."""
    code, err = _cli("replay", xtf, "-o", out)
    assert code == 0, err[-2000:]
    json.loads((out / "report.json").read_text(), parse_constant=lambda c: pytest.fail(f"bare {c} in report"))


def test_demo_journey(tmp_path):
    out = _users_folder(tmp_path / "work")
    code, err = _cli("demo", "-o", out, "--no-progress", "--pings", 80)
    assert code == 2 and "not empty" in err                           # a folder of the user's: refused at first
    code, err = _cli("demo", "-o", out, "--no-progress", "--pings", 80, "--overwrite")
    assert code == 0, err[-2000:]
    _untouched(out)
    header, pings = _pings(out / "record.xtf")
    assert header.NavUnits == 3 and len(pings) == 80
    _check_timing_and_headings(pings)
    assert (out / "waterfall.png").read_bytes()[:4] == b"\x89PNG"
    _replayed(out / "record.xtf", tmp_path / "replay")


def _dem_and_log(folder, seconds=8):
    """A 200 m × 160 m DEM 25 m deep with a mound, and a ship's GPS log (time, latitude, longitude) going east."""
    x = np.arange(200) + 0.5 - 100
    y = 80 - (np.arange(160) + 0.5)
    xx, yy = np.meshgrid(x, y)
    z = -25.0 + 3.0 * np.exp(-((xx - 5) ** 2 + (yy + 14) ** 2) / 30.0)
    write_grid(folder / "dem.tif", z, E0 - 100, N0 + 80, 1.0, CRS)
    lon, lat = pyproj.Transformer.from_crs(CRS, "EPSG:4326", always_xy=True).transform(
        E0 - 8 + 2.0 * np.arange(seconds + 1), np.full(seconds + 1, N0))
    t0 = dt.datetime(2026, 5, 1, 12, tzinfo=dt.timezone.utc)
    (folder / "gps.csv").write_text("time,latitude,longitude\n" + "".join(
        f"{(t0 + dt.timedelta(seconds=k)).isoformat()},{float(a)!r},{float(o)!r}\n"
        for k, (a, o) in enumerate(zip(lat, lon))))


@pytest.mark.parametrize("device", ["cmax-cm2-325", "imagenex-872-330"])   # every sample; decimated to 1000
def test_survey_journey(tmp_path, device):
    """A ship's GPS log over a DEM with --altitude-m: the XTF as a viewer reads it (water column at least 20 dB
    below the seabed, the fish where the reader puts it, true headings, 2R/c between pings, the log's 1 Hz fixes
    held in FixTime and the positions), line.png drawn from the codes (dark water column), the mosaic and truth with their CRS and units, and
    the line's XTF replayed."""
    _dem_and_log(tmp_path)
    out = _users_folder(tmp_path / "survey")
    code, err = _cli("survey", "--dem", tmp_path / "dem.tif", "--nav", tmp_path / "gps.csv", "--device", device,
                     "--altitude-m", 4, "--pixel", 1, "--no-progress", "-o", out)
    assert code == 2 and "not empty" in err
    code, err = _cli("survey", "--dem", tmp_path / "dem.tif", "--nav", tmp_path / "gps.csv", "--device", device,
                     "--altitude-m", 4, "--pixel", 1, "--no-progress", "-o", out, "--overwrite")
    assert code == 0, err[-2000:]
    _untouched(out)
    header, pings = _pings(out / "line_00" / "line.xtf")
    codes = np.stack([np.stack([p.data[0][::-1], p.data[1]]) for p in pings]).astype(float)
    alt = np.array([p.SensorPrimaryAltitude for p in pings])
    n = codes.shape[2]
    r = (np.arange(n) + 0.5) * pings[0].ping_chan_headers[1].SlantRange / n
    water = np.broadcast_to(r[None, None, :] < 0.8 * alt[:, None, None], codes.shape)
    floor = np.broadcast_to(r[None, None, :] > 1.2 * alt[:, None, None], codes.shape)
    assert 20 * np.log10(np.median(codes[floor]) / max(np.median(codes[water]), 0.5)) >= 20.0
    assert all(p.Layback == 0.0 for p in pings)
    _check_timing_and_headings(pings)
    fix = np.array([60 * p.FixTimeMinute + p.FixTimeSecond + p.FixTimeHsecond / 100 for p in pings])
    np.testing.assert_array_equal(np.unique(fix), np.arange(9.0))          # the log's 1 Hz fixes, held
    assert np.all(fix <= np.mod(_ping_seconds(pings), 3600.0) + 1e-6)
    png = __import__("imageio.v3", fromlist=["imread"]).imread(out / "line_00" / "line.png")
    middle = png[:, png.shape[1] // 2 - 2:png.shape[1] // 2 + 2]
    assert middle.mean() < 10 and png.mean() > 40                        # a dark water column at nadir
    ds = xr.open_zarr(out / "line_00" / "line.zarr")
    assert ds.sizes["ping"] == len(pings)
    with rasterio.open(out / "mosaic.tif") as m, rasterio.open(out / "truth.tif") as t:
        assert m.crs.to_epsg() == 32632 and t.units == ("m",) and np.nanmin(t.read(1)) < -24.0
    _replayed(out / "line_00" / "line.xtf", tmp_path / "replay")


def test_render_journey(tmp_path):
    """A shipped config copied and rendered into the user's folder with XTF and Zarr: the Zarr opens with xarray
    and writes NetCDF, the XTF's pings are 2R/c apart, and the XTF replays."""
    cfg = tmp_path / "anchor_mine.toml"
    assert _cli("examples", "--copy", "anchor_mine.toml", cfg)[0] == 0
    text = cfg.read_text().replace("n_pings = 240", "n_pings = 40")
    cfg.write_text(text.replace("[output]", "[output]\nxtf = true\nzarr = true", 1) if "[output]" in text
                   else text + "\n[output]\nxtf = true\nzarr = true\ngeo_origin_deg = [54.4, 10.2]\n")
    out = _users_folder(tmp_path / "render")
    code, err = _cli("render", cfg, "-o", out, "--no-progress", "--overwrite")
    assert code == 0, err[-2000:]
    _untouched(out)
    ds = xr.open_zarr(out / "record.zarr")
    ds.to_netcdf(tmp_path / "r.nc", auto_complex=True)
    header, pings = _pings(out / "record.xtf")
    assert len(pings) == 40 == ds.sizes["ping"]
    gaps = np.diff(_ping_seconds(pings))
    assert np.median(gaps) >= pings[0].ping_chan_headers[1].SlantRange / pings[0].SoundVelocity - 0.011
    _replayed(out / "record.xtf", tmp_path / "replay")
