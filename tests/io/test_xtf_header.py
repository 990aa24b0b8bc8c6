"""XTF header fields as the X41 specification defines them (issue 35, build item 7), read back with pyxtf.

The expected values are written here from the specification's own words (Triton Imaging, eXtended Triton Format
rev. X41, CHANINFO, XTFPINGHEADER and XTFPINGCHANHEADER), quoted beside each check.
"""
import dataclasses
import math

import numpy as np
import pyxtf
import pytest
from scipy.optimize import brentq

import sonar_embree as se


def _width_deg(size_m, wavelength_m):
    """One-way −3 dB full width of a membrane of ``size_m``: sinc²(x₃) = 10^(−0.3), θ = 2·asin(x₃λ/(π·L))."""
    x3 = brentq(lambda x: (math.sin(x) / x) ** 2 - 10 ** -0.3, 1e-6, math.pi)
    return 2 * math.degrees(math.asin(x3 * wavelength_m / (math.pi * size_m)))


@pytest.fixture(scope="module")
def lines(tmp_path_factory):
    """(a TVG receiver's integer line, a float line with a flat sea surface, a towed line), written as XTF and read
    back with pyxtf: {name: (record, file header, sonar packets, path)}."""
    out = tmp_path_factory.mktemp("xtf")
    scene = se.Scene().add(se.seafloor.flat((300, 300), z_m=-22.0), label="seafloor")   # 10 m under the sonar
    traj = se.Trajectory.survey([(-3, 0, -12), (3, 0, -12)], 2.0, 4.0, crs=32631,
                                start_time="2026-05-01T12:00:07.25Z")
    rx = se.Receiver(gain=se.TVG(k=30.0, g0_db=20.0))
    recs = {"codes": se.simulate(scene, traj, se.Sonar(max_range_m=30.0, receiver=rx, source_level_db=215.0),
                                 speckle=False),
            "floats": se.simulate(scene, traj, se.Acquisition(se.Sonar(max_range_m=30.0), se.Environment(
                surface=se.SeaSurface(z_m=-2.0))), speckle=False),
            "towed": se.simulate(scene, traj.with_layback(cable_out_m=15.0), se.Sonar(max_range_m=30.0),
                                 speckle=False)}
    read = {}
    for name, rec in recs.items():
        path = out / f"{name}_line.xtf"
        rec.to_xtf(path)
        header, packets = pyxtf.xtf_read(str(path))
        read[name] = (rec, header, packets[pyxtf.XTFHeaderType.sonar], path)
    return read


def test_channel_info_as_the_spec_defines_it(lines):
    for name, (rec, header, _, path) in lines.items():
        s = rec.sonar
        assert header.ThisFileName.decode().rstrip("\x00") == path.name           # "ThisFileName": the file's name
        for ci in header.ChanInfo[:2]:
            assert ci.CorrectionFlags == 1            # "1 = sonar imagery stored as slant-range, 2 = ground range"
            assert ci.UniPolar == 1                   # "0 = data is polar, 1 = data is unipolar": intensities ≥ 0
            # "HorizBeamAngle: typically 1 degree or so" (along track); "BeamWidth: 3dB beam width, typically 50
            # degrees" (the vertical fan); "TiltAngle: typically 30 degrees" (depression)
            assert ci.HorizBeamAngle == pytest.approx(_width_deg(s.length_m, se.Acquisition.of(s).wavelength_m),
                                                      rel=1e-5)
            assert ci.BeamWidth == pytest.approx(_width_deg(s.height_m, se.Acquisition.of(s).wavelength_m), rel=1e-5)
            assert ci.TiltAngle == pytest.approx(s.tilt_deg)
            assert ci.BeamsPerArray == 1              # one beam a side, as devices write it (issue 50)
        assert header.NavUnits == 3                   # "0 = meters, 3 = degrees" (a line with a CRS)


def test_ping_and_channel_headers_as_the_spec_defines_them(lines):
    for name, (rec, _, pings, _) in lines.items():
        s = rec.sonar
        first = pings[0]
        # "FixTimeHour/Minute/Second/Hsecond: time of the most recent nav update": the nav fix at the ping
        assert (first.FixTimeHour, first.FixTimeMinute, first.FixTimeSecond, first.FixTimeHsecond) == (12, 0, 7, 25)
        for chan in first.ping_chan_headers:
            # "SecondsPerPing: amount of time, in seconds, from ping to ping (SlantRange/750)", 750 the SoundVelocity
            assert chan.SecondsPerPing == pytest.approx(chan.SlantRange / first.SoundVelocity, rel=1e-6)
            assert first.SoundVelocity == pytest.approx(se.Acquisition.of(s).sound_speed_m_s / 2)
            # "ProcessingFlags: 4 = TVG; 8 = BAC&GAC; 16 = filter": TVG only where the receiver applied one
            assert chan.ProcessingFlags == (4 if name == "codes" else 0)
    _, _, pings, _ = lines["floats"]                  # "SensorDepth: towfish depth (m)" below its sea surface
    assert pings[0].SensorDepth == pytest.approx(10.0)
    rec, _, pings, _ = lines["towed"]                  # "Layback: distance from ship to sensor (m)", "CableOut (m)"
    assert {p.Layback for p in pings} == {0.0}         # the Sensor fields are laid back already (issue 50)
    assert {p.CableOut for p in pings} == {15}


def test_the_demos_xtf_has_latitude_and_longitude(tmp_path):
    """`sonar-embree demo` writes record.xtf with NavUnits 3 and its local metres placed at its geographic origin
    (the Kiel Bight): the first ping's position is the origin's UTM coordinates plus the ping's offset, inverted by
    pyproj; a record's ``geo_origin_deg`` that is not (lat, lon) in degrees is refused in one line."""
    import subprocess
    import sys

    import pyproj

    from sonar_embree.runs.demo import DEMO_ORIGIN_DEG

    proc = subprocess.run([sys.executable, "-m", "sonar_embree.runs.cli", "demo", "--pings", "4", "--no-progress",
                           "-o", str(tmp_path / "demo")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    header, packets = pyxtf.xtf_read(str(tmp_path / "demo" / "record.xtf"))
    first = packets[pyxtf.XTFHeaderType.sonar][0]
    assert header.NavUnits == 3
    rec = se.Record.load(tmp_path / "demo" / "record.npz")
    lat0, lon0 = DEMO_ORIGIN_DEG
    utm = pyproj.CRS.from_dict({"proj": "utm", "zone": int((lon0 + 180) // 6) + 1, "ellps": "WGS84"})
    fwd = pyproj.Transformer.from_crs("EPSG:4326", utm, always_xy=True)
    e0, n0 = fwd.transform(lon0, lat0)
    x, y = rec.trajectory.positions_m[0, :2]
    lon, lat = fwd.transform(e0 + x, n0 + y, direction="INVERSE")
    assert (first.SensorXcoordinate, first.SensorYcoordinate) == pytest.approx((lon, lat), abs=1e-8)
    bad = dataclasses.replace(rec, attrs={**rec.attrs, "geo_origin_deg": [95.0, 10.0]})
    with pytest.raises(se.ConfigError, match="geo_origin_deg"):
        bad.to_xtf(tmp_path / "bad.xtf")


def test_an_xtf_decimated_to_the_devices_samples_per_channel(tmp_path):
    """to_xtf(samples_per_channel=1000) (the YellowFin 872's 1000 points a side): 1000 samples per channel in the
    packets and the header, each the largest of its run of the record's samples (np.maximum over the runs
    between ⌊k·n/1000⌋), the time span kept; a streamed line writes the same bytes."""
    scene = se.Scene().add(se.seafloor.flat((300, 300), z_m=-22.0), label="seafloor")
    traj = se.Trajectory.line((-1, 0, -12), (1, 0, -12), 6)
    sonar = se.Sonar.preset("imagenex-872-800", max_range_m=30.0,
                            receiver=se.devices.device("imagenex-872-800").receiver())
    kw = dict(speckle=True, seed=1, start_time="2026-05-01T12:00:00Z")
    rec = se.simulate(scene, traj, sonar, se.Pulse.preset("imagenex-872-800"), **kw)
    rec.to_xtf(tmp_path / "y.xtf", samples_per_channel=1000)
    header, packets = pyxtf.xtf_read(str(tmp_path / "y.xtf"))
    ping = packets[pyxtf.XTFHeaderType.sonar][2]
    n = rec.samples.shape[2]
    assert n > 1000 and header.ChanInfo[0].Reserved == 1000 and ping.ping_chan_headers[1].NumSamples == 1000
    edges = [k * n // 1000 for k in range(1001)]
    want = [rec.samples[2, 1, edges[k]:edges[k + 1]].max() for k in range(1000)]
    np.testing.assert_array_equal(ping.data[1], want)
    assert ping.ping_chan_headers[1].TimeDuration == pytest.approx(2 * 30.0 / rec.acquisition.sound_speed_m_s)  # 2R/c
    (tmp_path / "s").mkdir()
    se.stream.render_line(scene, traj, tmp_path / "y.zarr", sonar, se.Pulse.preset("imagenex-872-800"),
                          block_pings=4, xtf_path=tmp_path / "s" / "y.xtf", xtf_samples=1000, **kw)
    assert (tmp_path / "s" / "y.xtf").read_bytes()[1024:] == (tmp_path / "y.xtf").read_bytes()[1024:]


def test_shipped_side_scan_configs_write_latitude_and_longitude(tmp_path):
    """The shipped side-scan configs carry a geographic origin ([output] geo_origin_deg): rendered with xtf = true,
    the XTF has NavUnits 3 and positions near 54.45° N, 10.30° E; a malformed origin is a one-line error."""
    from sonar_embree import assets
    from sonar_embree.runs.cli import main
    from sonar_embree.runs.runconfig import load_run_config

    for name in ("anchor_mine", "anchor_mine_curved", "shipwreck_perlin_straight", "shipwreck_ripples_curved"):
        assert load_run_config(f"asset:{name}.toml").output.geo_origin_deg == [54.45, 10.30]
    text = open(assets.path("asset:anchor_mine.toml")).read()
    text = text.replace("n_pings = 240", "n_pings = 3").replace("[output]\n", "[output]\nxtf = true\n")
    (tmp_path / "a.toml").write_text(text)                       # its meshes are asset:NAME: they resolve anywhere
    assert main(["render", str(tmp_path / "a.toml"), "-o", str(tmp_path / "out"), "--no-progress"]) == 0
    header, packets = pyxtf.xtf_read(str(tmp_path / "out" / "record.xtf"))
    first = packets[pyxtf.XTFHeaderType.sonar][0]
    assert header.NavUnits == 3 and abs(first.SensorYcoordinate - 54.45) < 1e-3 and abs(first.SensorXcoordinate - 10.30) < 1e-3
    (tmp_path / "b.toml").write_text(text.replace("[54.45, 10.30]", "[95.0, 10.0]"))
    with pytest.raises(se.ConfigError, match="geo_origin_deg"):
        load_run_config(tmp_path / "b.toml")


@pytest.mark.parametrize("how, code", [("max", 2), ("mean", 0)])
def test_decimation_by_max_and_mean_against_their_twins_and_the_header(tmp_path, how, code):
    """Each of the 700 samples per side is the largest, or the rounded mean, of its run of the record's codes
    (runs between ⌊k·n/700⌋, a loop written here); DownsampleMethod says which (the spec's 2 for MAX)."""
    from sonar_embree.io.xtf import decimate

    scene = se.Scene().add(se.seafloor.flat((300, 300), z_m=-22.0), label="seafloor")
    sonar = se.Sonar.preset("imagenex-872-800", max_range_m=30.0,
                            receiver=se.devices.device("imagenex-872-800").receiver())
    rec = se.simulate(scene, se.Trajectory.line((-1, 0, -12), (1, 0, -12), 3), sonar,
                      se.Pulse.preset("imagenex-872-800"), speckle=True, seed=2, start_time="2026-05-01T12:00:00Z")
    rec.to_xtf(tmp_path / "d.xtf", samples_per_channel=700, decimation=how)
    _, packets = pyxtf.xtf_read(str(tmp_path / "d.xtf"))
    ping = packets[pyxtf.XTFHeaderType.sonar][1]
    n = rec.samples.shape[2]
    edges = [k * n // 700 for k in range(701)]
    runs = [rec.samples[1, 1, edges[k]:edges[k + 1]].astype(float) for k in range(700)]
    want = [r.max() for r in runs] if how == "max" else [np.rint(r.mean()) for r in runs]
    np.testing.assert_array_equal(ping.data[1], want)
    assert ping.ping_chan_headers[1].DownsampleMethod == code
    floats = rec.data[:, 0]
    np.testing.assert_allclose(decimate(floats, 50, "mean")[0, 3], floats[0, (3 * n) // 50:(4 * n) // 50].mean(),
                               rtol=1e-12)
    with pytest.raises(se.ConfigError, match="decimation must be one of"):
        decimate(floats, 50, "median")


@pytest.mark.parametrize("name", sorted(se.devices.DEVICES))
def test_each_presets_xtf_fields_as_the_device_writes_them(tmp_path, name):
    """Issue 50, item 5, field by field against docs/guide/sonars.md's device table (the Marine Sonic's from a
    public Sea Scan record): sample width, samples per side and their decimation (DownsampleMethod 2, MAX), volt
    scales, TVG, one beam per array, TimeDuration = SecondsPerPing = 2R/c, EventNumber 0, packets padded to
    64 bytes."""
    d = se.devices.device(name)
    rng = d.ranges_m[0]
    sonar = se.Sonar.preset(name, max_range_m=rng, receiver=d.receiver())
    scene = se.Scene().add(se.seafloor.flat((4 * rng, 4 * rng)), label="seafloor")
    rec = se.simulate(scene, se.Trajectory.line((-1, 0, 0.1 * rng + 2), (1, 0, 0.1 * rng + 2), 3), sonar,
                      se.Pulse.preset(name), start_time="2026-05-01T12:00:00Z")
    rec.to_xtf(tmp_path / "l.xtf", samples_per_channel=d.samples_per_channel)
    header, packets = pyxtf.xtf_read(str(tmp_path / "l.xtf"))
    pings = packets[pyxtf.XTFHeaderType.sonar]
    want_bytes = 1 if d.adc_bits <= 8 else 2
    want_n = d.samples_per_channel or rec.data.shape[2]
    for ci in header.ChanInfo[:2]:
        assert ci.BytesPerSample == want_bytes and ci.VoltScale == pytest.approx(d.full_scale_v)
        assert ci.BeamsPerArray == 1 and ci.SampleFormat == (8 if want_bytes == 1 else 3)
    raw = (tmp_path / "l.xtf").read_bytes()
    pos = 1024
    for p in pings:
        assert p.NumBytesThisRecord % 64 == 0 and p.EventNumber == 0
        assert int.from_bytes(raw[pos + 10:pos + 14], "little") == p.NumBytesThisRecord
        pos += p.NumBytesThisRecord
        for c, data in zip(p.ping_chan_headers, p.data):
            assert c.NumSamples == want_n == data.size and data.max() <= 2 ** d.adc_bits - 1
            assert c.DownsampleMethod == (2 if d.samples_per_channel else 0)
            assert c.MillivoltScale == round(1000 * d.full_scale_v) and c.ProcessingFlags == 4 and c.GainCode == 30
            assert c.TimeDuration == pytest.approx(c.SecondsPerPing) and c.SecondsPerPing == pytest.approx(
                2 * rng / se.Acquisition.of(sonar).sound_speed_m_s, rel=1e-6)
    assert pos == len(raw)
    if name.startswith("marine-sonic"):
        assert (want_bytes, want_n, d.full_scale_v) == (2, 1024, 5.0)
