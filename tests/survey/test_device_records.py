"""Issue 50, item 1: a survey's XTF as the device would write it. Every preset records through a time-varied gain
that starts just before the first bottom return, set per line so that the median seabed sits near a quarter of
full scale: the water column stays dark (at least 20 dB below the seabed, as a real record's 33 dB), where the AGC
assumed before wrote both at one level."""
import datetime as dt

import numpy as np
import pyproj
import pytest
import pyxtf
import xarray as xr

from sonar_embree.instrument import devices
from sonar_embree.io.geotiff import write_grid
from sonar_embree.runs.survey import SEABED_FULL_SCALE, run_survey
from sonar_embree.survey.replay import replay

CRS, E0, N0 = "EPSG:32631", 500_000.0, 6_000_000.0


@pytest.fixture(scope="module")
def ground(tmp_path_factory):
    """A flat DEM 20 m deep, 300 m × 200 m, and a ship's 2 s GPS log (time, latitude, longitude) across it."""
    d = tmp_path_factory.mktemp("ground")
    write_grid(d / "dem.tif", np.full((200, 300), -20.0), E0 - 150, N0 + 100, 1.0, CRS)
    lon, lat = pyproj.Transformer.from_crs(CRS, "EPSG:4326", always_xy=True).transform(
        E0 - 2 + 2.0 * np.arange(3), np.full(3, N0))
    t0 = dt.datetime(2026, 5, 1, 12, tzinfo=dt.timezone.utc)
    (d / "gps.csv").write_text("time,latitude,longitude\n" + "".join(
        f"{(t0 + dt.timedelta(seconds=k)).isoformat()},{float(a)!r},{float(o)!r}\n" for k, (a, o) in
        enumerate(zip(lat, lon))))
    return d


def _sides(path):
    """(pings, 2, samples) codes nadir first, the altitude (pings,) and the range of each sample (samples,), m,
    as a reader has them from the file alone."""
    _, packets = pyxtf.xtf_read(str(path))
    pings = packets[pyxtf.XTFHeaderType.sonar]
    codes = np.stack([np.stack([p.data[0][::-1], p.data[1]]) for p in pings]).astype(float)
    chan = pings[0].ping_chan_headers[1]
    r = (np.arange(codes.shape[2]) + 0.5) * chan.SlantRange / codes.shape[2]
    return codes, np.array([p.SensorPrimaryAltitude for p in pings]), r, pings


@pytest.mark.parametrize("name", sorted(devices.DEVICES))
def test_every_presets_survey_has_a_dark_water_column(ground, tmp_path, name):
    """A ship's time/lat/lon log with --depth-m, the fish a tenth of its first range above the flat floor 20 m deep
    (at least 2 m), as side-scans are flown: the median seabed
    code at least 20 dB above the median water-column code before the first return, the median seabed between a
    sixteenth and a quarter of full scale (lower than a quarter where the bright near range would clip), at most
    5 % of the codes clipped, and the TVG written in the channel headers. The level budget (source level, noise
    in the receiver's band, directivity) puts the median seabed at least 20 dB above the water column's noise in
    the float record too: the contrast is the echoes', not the gain law's. The line's XTF replays with the device
    named, in its own layout (every preset's samples per side and decimation)."""
    d = devices.device(name)
    run_survey(ground / "dem.tif", [ground / "gps.csv"], tmp_path / "out", name, progress=False, pixel_m=2.0,
               depth_m=20.0 - max(0.1 * d.ranges_m[0], 2.0))
    codes, alt, r, pings = _sides(tmp_path / "out" / "line_00" / "line.xtf")
    water = np.broadcast_to(r[None, None, :] < 0.8 * alt[:, None, None], codes.shape)
    floor = np.broadcast_to(r[None, None, :] > 1.2 * alt[:, None, None], codes.shape)
    top = 2 ** d.adc_bits - 1
    seabed, column = np.median(codes[floor]), max(np.median(codes[water]), 0.5)   # 0.5: half a code step
    assert 20 * np.log10(seabed / column) >= 20.0, (seabed, column)
    assert top / 16 <= seabed <= SEABED_FULL_SCALE * top * 1.1 and np.mean(codes >= top) < 0.05
    chan = pings[0].ping_chan_headers[1]
    assert chan.ProcessingFlags == 4 and chan.GainCode == 30
    floats = xr.open_zarr(tmp_path / "out" / "line_00" / "line.zarr")["starboard"].values    # before the receiver
    r = (np.arange(floats.shape[1]) + 0.5) * chan.SlantRange / floats.shape[1]
    water, floor = r[None, :] < 0.8 * alt[:, None], r[None, :] > 1.2 * alt[:, None]
    margin = 10 * np.log10(np.median(floats[np.broadcast_to(floor, floats.shape)])
                           / np.median(floats[np.broadcast_to(water, floats.shape)]))
    assert margin >= 20.0, margin                # the level budget: the seabed well above the receiver's noise
    report = replay(tmp_path / "out" / "line_00" / "line.xtf", tmp_path / "replay", device=name)   # as a user would
    back = pyxtf.xtf_read(str(tmp_path / "replay" / "replay.xtf"))[1][pyxtf.XTFHeaderType.sonar]
    assert len(back) == len(pings) and len(back[0].data[1]) == len(pings[0].data[1])
    assert np.isfinite(report["gain_offset_db"])


def test_the_agc_stays_available():
    rx = devices.device("cmax-cm2-325").receiver("agc")
    assert type(rx.gain).__name__ == "AGC" and rx.gain.target == 0.25
    with pytest.raises(Exception, match="gain must be 'tvg' or 'agc'"):
        devices.device("cmax-cm2-325").receiver("tvh")


def test_a_flat_floors_mosaic_is_uniform_across_range_and_the_overlap(ground, tmp_path):
    """Issue 50: the survey's mosaic normalised by grazing angle, two lines' overlap feathered, pixel holes filled:
    over a flat floor every pixel with samples lies within 2 dB of 1, at every range and where the lines overlap;
    with one line flown lower at its end (a change of altitude), no band appears either."""
    import rasterio

    t0 = dt.datetime(2026, 5, 1, 12, tzinfo=dt.timezone.utc)
    for k, north in enumerate((0.0, -36.0)):
        lon, lat = pyproj.Transformer.from_crs(CRS, "EPSG:4326", always_xy=True).transform(
            E0 - 20 + 2.0 * np.arange(21), np.full(21, N0 + north))
        depth = np.linspace(12.0, 12.0 if k == 0 else 15.0, 21)
        (tmp_path / f"l{k}.csv").write_text("time,latitude,longitude,depth_m\n" + "".join(
            f"{(t0 + dt.timedelta(seconds=i)).isoformat()},{float(a)!r},{float(o)!r},{float(d)!r}\n"
            for i, (a, o, d) in enumerate(zip(lat, lon, depth))))
    run_survey(ground / "dem.tif", [tmp_path / "l0.csv", tmp_path / "l1.csv"], tmp_path / "out", "cmax-cm2-325",
               progress=False, pixel_m=1.0, ping_rate_hz=4.0)
    with rasterio.open(tmp_path / "out" / "mosaic.tif") as m:
        v = m.read(1)
        cols = (np.arange(m.width) + 0.5) * m.res[0] + m.bounds.left - E0
        rows = m.bounds.top - (np.arange(m.height) + 0.5) * m.res[1] - N0
    inner = (cols > -15) & (cols < 15)                                  # away from the lines' ends
    db = 10 * np.log10(v[:, inner])
    assert np.isfinite(db).sum() > 2000
    assert np.nanmax(np.abs(db)) < 2.0
    overlap = (rows < -8) & (rows > -28)                                # both swaths reach here
    assert np.isfinite(db[overlap]).mean() > 0.9 and np.nanmax(np.abs(db[overlap])) < 2.0
    png = __import__("imageio.v3", fromlist=["imread"]).imread(tmp_path / "out" / "mosaic.png")
    seen = png[..., 1] > 0
    assert 100 < np.median(png[..., 0][seen]) < 156                     # a uniform floor grey, not white


@pytest.mark.parametrize("name", sorted(devices.DEVICES))
def test_a_presets_receiver_passes_its_pulses_band(name):
    """The band-pass of a preset's receiver is its pulse's band (a chirp's sweep, a CW pulse's 1/τ), computed here
    from the preset's pulse, so the noise per sample is N·B, not N over the whole sample band."""
    import sonar_embree as se

    pulse = se.Pulse.preset(name)
    lo, hi = pulse.frequency_span_hz(devices.device(name).frequency_hz)
    want = max(hi - lo, 1.0 / pulse.duration_s)
    for gain in ("tvg", "agc"):
        assert devices.device(name).receiver(gain).bandwidth_hz == pytest.approx(want, rel=1e-12)


def test_assumed_source_levels_lie_within_the_general_references():
    """Every preset's source level is in 210–230 dB re 1 µPa at 1 m (the general references' range) or sourced."""
    for d in devices.DEVICES.values():
        assert "source_level_db" not in d.assumed or 210.0 <= d.source_level_db <= 230.0, d.name
