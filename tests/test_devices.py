"""Device presets (se.devices): each reproduces its cited one-way −3 dB beamwidths through the membrane model.

Reference written here: a baffled membrane of length L has one-way directivity sinc(π·L/λ·sin θ) (Kinsler et al.,
ch. 8), so its −3 dB full width θ3 solves sinc(π·L/λ·sin(θ3/2)) = 1/√2, found by brentq.
"""
import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq

import sonar_embree as se


def _width_deg(size_m, wavelength_m):
    f = lambda half: np.sinc(size_m / wavelength_m * np.sin(half)) - 1 / np.sqrt(2)   # np.sinc(x) = sin(πx)/(πx)
    return 2 * np.degrees(brentq(f, 1e-9, np.pi / 2))


@pytest.mark.parametrize("name", sorted(se.devices.DEVICES))
def test_preset_reproduces_its_cited_beamwidths(name):
    d = se.devices.DEVICES[name]
    s = se.Sonar.preset(name)
    assert _width_deg(s.length_m, s.wavelength_m) == pytest.approx(d.azimuth_deg, rel=0.05)
    assert _width_deg(s.height_m, s.wavelength_m) == pytest.approx(d.elevation_deg, rel=0.05)
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
    from test_environment import _write

    from sonar_embree import runconfig

    text = _write(tmp_path).read_text()
    start, end = text.index("[sonar]"), text.index("[environment]")
    text = text[:start] + "[sonar]\npreset = \"starfish-450f\"\nmax_range_m = 40.0\n\n" + text[end:]
    a, b = text.index("[pulse]"), text.index("[simulation]")
    (tmp_path / "p.toml").write_text(text[:a] + text[b:])
    cfg = runconfig.load_run_config(tmp_path / "p.toml")
    assert cfg.sonar == se.Sonar.preset("starfish-450f", max_range_m=40.0, environment=cfg.sonar.environment)
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
