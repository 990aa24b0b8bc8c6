"""Device presets (se.devices): each reproduces its cited one-way −3 dB beamwidths through the membrane model.

Reference written here: a baffled membrane of length L has one-way directivity sinc(π·L/λ·sin θ) (Kinsler et al.,
ch. 8), so its −3 dB full width θ3 solves sinc(π·L/λ·sin(θ3/2)) = 1/√2, found by brentq.
"""
import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq

import sonar_embree as se


def _width_deg(size_m, wavelength_m, two_way=False):
    """−3 dB full width of the membrane: one-way sinc² = 1/2, two-way sinc⁴ = 1/2."""
    level = 2 ** -0.25 if two_way else 2 ** -0.5
    f = lambda half: np.sinc(size_m / wavelength_m * np.sin(half)) - level   # np.sinc(x) = sin(πx)/(πx)
    return 2 * np.degrees(brentq(f, 1e-9, np.pi / 2))


@pytest.mark.parametrize("name", sorted(se.devices.DEVICES))
def test_preset_reproduces_its_cited_beamwidths(name):
    d = se.devices.DEVICES[name]
    s = se.Sonar.preset(name)
    assert _width_deg(s.length_m, se.Acquisition.of(s).wavelength_m, d.azimuth_two_way) == pytest.approx(d.azimuth_deg,
                                                                                                         rel=0.05)
    assert _width_deg(s.height_m, se.Acquisition.of(s).wavelength_m) == pytest.approx(d.elevation_deg, rel=0.05)
    assert (s.frequency_hz, s.tilt_deg, s.max_range_m, s.source_level_db) == (d.frequency_hz, d.tilt_deg,
                                                                              d.ranges_m[0], d.source_level_db)
    assert d.source and set(d.assumed) <= {f.name for f in dataclasses.fields(d)} | {"pulse duration"}
    pulse = se.Pulse.preset(name)
    assert pulse.duration_s == d.pulse[1]


def test_presets_span_the_band_and_both_platforms():
    devs = se.devices.DEVICES.values()
    assert len(devs) >= 6 and {d.platform for d in devs} == {"towfish", "AUV"}
    f = [d.frequency_hz for d in devs]
    assert min(f) <= 100e3 and max(f) >= 1.8e6


def test_preset_overrides_errors_and_toml(tmp_path):
    s = se.Sonar.preset("edgetech-4125-400", max_range_m=75.0, source_level_db=205.0)
    assert s.max_range_m == 75.0 and s.source_level_db == 205.0
    with pytest.raises(se.ConfigError, match="unknown device preset 'edgetech-9999'"):
        se.Sonar.preset("edgetech-9999")
    from conftest import write_anchor_config as _write

    from sonar_embree import runconfig

    text = _write(tmp_path).read_text()
    start, end = text.index("[sonar]"), text.index("[environment]")
    text = text[:start] + "[sonar]\npreset = \"starfish-450f\"\nmax_range_m = 40.0\n\n" + text[end:]
    a, b = text.index("[pulse]"), text.index("[simulation]")
    (tmp_path / "p.toml").write_text(text[:a] + text[b:])
    cfg = runconfig.load_run_config(tmp_path / "p.toml")
    assert cfg.sonar == se.Sonar.preset("starfish-450f", max_range_m=40.0)
    assert cfg.pulse == se.Pulse.preset("starfish-450f")                 # the device's pulse
    (tmp_path / "q.toml").write_text(text.replace("starfish-450f", "starfish-9"))
    with pytest.raises(se.ConfigError, match="unknown device preset"):
        runconfig.load_run_config(tmp_path / "q.toml")


def test_a_preset_renders_a_flat_floor():
    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0)), label="seafloor")
    sonar = se.Sonar.preset("marine-sonic-arc-1800")
    rec = se.simulate(scene, se.Trajectory.line((0, 0, 5.0), (0.1, 0, 5.0), 2), sonar,
                      se.Pulse.preset("marine-sonic-arc-1800"), start_time="2000-01-01")
    assert rec.altitude_m == pytest.approx(5.0, abs=0.01)
    assert rec.attrs["intensity_unit"] == "uPa^2" and rec.data.max() > 0


def test_cm2_and_yellowfin_presets_carry_their_sourced_values():
    """C-MAX CM2: the two-way −3 dB widths (0.45° at 325 kHz, 0.32° at 780 kHz) give membranes as long as the
    stated arrays (0.37 m, 0.21 m) within 5 % (1.1 % and 4.4 %); its stated ping rates per range setting (13.5 /s at 25 m, 4.8 /s at
    150 m, 6.9 /s at 100 m at 100 kHz), back to back (c/2R) where none is stated; its 217 dB source level.
    YellowFin 872: 20° down, 1000 samples a side, its three frequencies."""
    for name, length in (("cmax-cm2-325", 0.37), ("cmax-cm2-780", 0.21)):
        assert se.Sonar.preset(name).length_m == pytest.approx(length, rel=0.05)
    d = se.devices.DEVICES["cmax-cm2-325"]
    assert (d.ping_rate_hz(25.0), d.ping_rate_hz(150.0)) == (13.5, 4.8)
    assert se.devices.DEVICES["cmax-cm2-100"].ping_rate_hz(100.0) == 6.9
    assert se.devices.DEVICES["cmax-cm2-780"].ping_rate_hz(37.5) == pytest.approx(1500.0 / 75.0)
    assert se.Sonar.preset("cmax-cm2-100").source_level_db == 217.0
    for f in (260, 330, 800):
        y = se.devices.DEVICES[f"imagenex-872-{f}"]
        assert (y.frequency_hz, y.tilt_deg, y.samples_per_channel) == (f * 1e3, 20.0, 1000)
        assert "ranges_m" in y.assumed and y.note


def test_a_devices_receiver_records_codes_in_its_own_range():
    """device(name).receiver(): EdgeTech's codes span 0 … 32767 (JSF: one signed short per sample), Marine Sonic's
    too, as its XTF stores them (2-byte words up to 32767 at 5 V full scale), others 16 bits with adc_bits marked
    assumed; a flat floor recorded through the Marine Sonic's receiver stays within its 15-bit range."""
    dev = se.devices.DEVICES
    assert dev["edgetech-4125-400"].receiver().adc_bits == 15 and dev["marine-sonic-arc-900"].receiver().adc_bits == 15
    assert dev["marine-sonic-arc-900"].receiver().full_scale_v == 5.0
    for d in dev.values():
        assert (d.adc_bits == 16) == ("adc_bits" in d.assumed)
    sonar = se.Sonar.preset("marine-sonic-arc-900", receiver=dev["marine-sonic-arc-900"].receiver(g0_db=-20.0))
    scene = se.Scene().add(se.seafloor.flat((200, 200)), label="seafloor")
    rec = se.simulate(scene, se.Trajectory.line((0, 0, 8), (1, 0, 8), 4), sonar, se.Pulse.preset("marine-sonic-arc-900"),
                      speckle=True)
    assert rec.samples.dtype == np.uint16 and rec.samples.max() <= 32767 and (rec.samples == 32767).mean() < 0.01