"""Calibrated levels and ambient noise (docs/physics.md §14) against the published formulas written here.

References, typed independently of the simulator:

- ambient noise (Coates 1990, as in Stojanovic 2007, eqs. 5–6), f in kHz, dB re 1 µPa²/Hz:
  turbulence 17 − 30 log f; shipping 40 + 20(s − 0.5) + 26 log f − 60 log(f + 0.03);
  wind 50 + 7.5 √w + 20 log f − 40 log(f + 0.4); thermal −15 + 20 log f; powers summed;
- receiving directivity index DI = 10 log10(4π/∫ b² dΩ) of the baffled membrane's pattern, by the brute quadrature
  of tests/analytic.py (Urick 1983, §3.6);
- the receiver band of a complex-baseband record is its sample rate fs: noise power per sample N0·fs;
- the reverberation form of the sonar equation for a flat floor and a rectangular pulse τ,
  RL = SL − 2TL + 10 log10(μ sin²θg) + 10 log10(A) + 40 log10 b_el(θ),
  TL = 20 log10 R + αR, A = R·Φ·(cτ/2)/cos θg, Φ = ∫ b_az⁴(φ) dφ (the equivalent two-way azimuth width).
"""
import dataclasses

import numpy as np
from scipy.special import j1
import pytest

import analytic
import sonar_embree as se
from analytic import coates_db


def _floor():
    return se.Scene().add(se.seafloor.flat((400.0, 200.0)), material=se.Material(backscatter_db=-27.0),
                          label="seafloor")


def test_thermal_noise_at_400_khz_is_37_db():
    """The thermal term alone at 400 kHz: −15 + 20 log10(400) = 37.04 dB re 1 µPa²/Hz."""
    quiet = se.AmbientNoise(wind_speed_m_s=0.0, shipping=0.0)
    assert quiet.terms_db(400e3)["thermal"] == pytest.approx(37.04, abs=0.005)
    assert quiet.spectral_density_db(400e3) == pytest.approx(37.0, abs=0.1)           # thermal dominates there


@pytest.mark.parametrize("frequency_hz", [100e3, 400e3, 900e3])
@pytest.mark.parametrize("wind", [2.0, 20.0])
def test_noise_only_samples_match_coates_times_band_minus_di(frequency_hz, wind):
    """Speckled record, the water column before the floor echo: mean power per sample = N(f)·fs / DI in µPa²."""
    lam = 1500.0 / frequency_hz
    sonar = se.Acquisition(se.Sonar(frequency_hz=frequency_hz, length_m=50 * lam, height_m=lam, max_range_m=30.0,
                     source_level_db=210.0), se.Environment(noise=se.AmbientNoise(wind_speed_m_s=wind),
                                                                        absorption_db_per_m=0.05))
    pulse = se.Pulse.cw(duration_s=100e-6)
    rec = se.simulate(_floor(), se.Trajectory.line((0, 0, 25.0), (2.0, 0, 25.0), 12), sonar, pulse,
                      speckle=True, seed=3, start_time="2000-01-01")
    fs = rec.sonar.sample_rate_hz
    water = rec.time_s < 2 * 24.0 / 1500.0                                  # before any floor echo
    measured = 10 * np.log10(rec.data[:, :, water].mean())
    di = analytic.directivity_index_db(analytic.membrane_pattern(50 * lam, lam, lam))
    expected = coates_db(frequency_hz, wind) - di + 10 * np.log10(fs)
    assert measured == pytest.approx(expected, abs=0.3)
    assert rec.attrs["intensity_unit"] == "uPa^2"


def test_wind_raises_the_noise_at_100_khz_only_where_it_dominates():
    """At 100 kHz wind (20 m/s) dominates thermal; at 900 kHz thermal hides the wind: the model, not a constant."""
    calm, storm = se.AmbientNoise(wind_speed_m_s=0.0), se.AmbientNoise(wind_speed_m_s=20.0)
    assert storm.spectral_density_db(100e3) - calm.spectral_density_db(100e3) > 10.0
    assert storm.spectral_density_db(900e3) - calm.spectral_density_db(900e3) < 0.5
    for f in (100e3, 400e3, 900e3):
        assert storm.spectral_density_db(f) == pytest.approx(coates_db(f, 20.0), abs=1e-9)


def test_source_level_scales_the_unit_source_record_exactly():
    """Noise off: the record with SL equals the unit-source record × 10^(SL/10) to float rounding."""
    line = se.Trajectory.line((0, 0, 10.0), (1, 0, 10.0), 3)
    unit = se.simulate(_floor(), line, se.Sonar(), se.Pulse.cw(), start_time="2000-01-01")
    loud = se.simulate(_floor(), line, se.Acquisition(se.Sonar(source_level_db=215.0), se.Environment(noise=None)),
                       se.Pulse.cw(), start_time="2000-01-01")
    np.testing.assert_allclose(loud.data, unit.data * 10 ** 21.5, rtol=1e-14, atol=0)
    assert unit.attrs["intensity_unit"] == "unit source" and unit.attrs["received_noise_db_per_hz"] is None
    noisy = se.simulate(_floor(), line, se.Sonar(source_level_db=215.0), se.Pulse.cw(), start_time="2000-01-01")
    assert np.all(noisy.data > loud.data)                                   # noise on by default with a level


def test_floor_snr_at_40_m_matches_the_sonar_equation():
    """Speckle-free, SL 210 dB, ambient noise: SNR of the floor at 40 m slant range within 0.5 dB of the sonar
    equation with the equivalent azimuth width and the elevation pattern at the floor's depression."""
    h, r, tau, sl = 10.0, 40.0, 200e-6, 210.0
    sonar = se.Acquisition(se.Sonar(max_range_m=45.0, source_level_db=sl, self_noise_db_per_hz=30.0),
                           se.Environment(noise=se.AmbientNoise(wind_speed_m_s=10.0)))
    rec = se.simulate(_floor(), se.Trajectory.line((0, 0, h), (0.2, 0, h), 2).stop_and_hop(), sonar,
                      se.Pulse.cw(duration_s=tau, taper=0.0), start_time="2000-01-01")
    fs, c, alpha = rec.sonar.sample_rate_hz, 1500.0, rec.acquisition.alpha_db_per_m
    noise = 10 ** ((coates_db(400e3, 10.0) - analytic.directivity_index_db(analytic.membrane_pattern(0.19, 0.0038,
                                                                                      0.00375))) / 10)
    noise = (noise + 10 ** 3.0) * fs                                          # + self-noise, over the band
    k = int(round((2 * r / c + tau) * fs))                                   # the pulse fully on the annulus at R
    snr = 10 * np.log10((rec.starboard[:, k].mean() - noise) / noise)
    kw = 2 * np.pi * 400e3 / c
    sin_g = h / r
    phi = np.linspace(-0.05, 0.05, 20001)
    big_phi = np.trapezoid(np.sinc(kw * 0.19 / 2 * np.sin(phi) / np.pi) ** 4, phi)
    b_el = np.sinc(kw * 0.0038 / 2 * np.sin(np.arcsin(sin_g) - np.radians(20.0)) / np.pi)
    area = r * big_phi * (c * tau / 2) / np.sqrt(1 - sin_g ** 2)
    rl = sl - 2 * (20 * np.log10(r) + alpha * r) + 10 * np.log10(10 ** -2.7 * sin_g ** 2 * area) + 40 * np.log10(b_el)
    assert snr == pytest.approx(rl - 10 * np.log10(noise), abs=0.5)
    assert rec.starboard[:, 5].mean() == pytest.approx(noise, rel=1e-9)      # the water column holds the noise


def test_levels_survive_the_record_file_and_dataset(tmp_path):
    """SL, self-noise and the ambient noise round-trip through the npz record; the dataset says µPa²."""
    sonar = se.Acquisition(se.Sonar(source_level_db=212.0, self_noise_db_per_hz=25.0),
                           se.Environment(noise=se.AmbientNoise(wind_speed_m_s=12.0, shipping=0.2)))
    rec = se.simulate(_floor(), se.Trajectory.line((0, 0, 10.0), (1, 0, 10.0), 2), sonar, se.Pulse.cw(),
                      start_time="2000-01-01")
    rec.save(tmp_path / "r.npz")
    back = se.Record.load(tmp_path / "r.npz")
    assert back.sonar == rec.sonar and back.environment.noise == se.AmbientNoise(12.0, 0.2)
    ds = rec.to_xarray()
    assert ds["starboard"].attrs["units"] == "uPa2" and "212" in ds.attrs["intensity_reference"]


@pytest.mark.parametrize("kwargs, needle", [
    (dict(source_level_db=1.0), "source_level_db"),                          # a linear value, not dB
    (dict(source_level_db=400.0), "source_level_db"),
    (dict(self_noise_db_per_hz=float("nan")), "self_noise_db_per_hz"),
])
def test_impossible_levels_are_refused(kwargs, needle):
    with pytest.raises(se.ConfigError, match=needle):
        se.Sonar(**kwargs)


@pytest.mark.parametrize("noise, needle", [
    (dict(wind_speed_m_s=-1.0), "wind_speed_m_s"), (dict(shipping=2.0), "shipping"), (dict(gust=1.0), "gust"),
    ("loud", "noise"),
])
def test_bad_noise_settings_are_refused(noise, needle):
    with pytest.raises(se.ConfigError, match=needle):
        se.Environment(noise=noise)


def test_noise_from_toml_and_off(tmp_path):
    """[environment] noise = {…} or noise = false; [sonar] source_level_db and self_noise_db_per_hz."""
    from conftest import write_anchor_config as _write

    from sonar_embree import runconfig

    cfg = runconfig.load_run_config(_write(tmp_path, sonar_extra="source_level_db = 205.0\nself_noise_db_per_hz = 20.0\n",
                                           env="noise = { wind_speed_m_s = 3.0, shipping = 0.1 }\n"))
    assert cfg.sonar.source_level_db == 205.0 and cfg.sonar.self_noise_db_per_hz == 20.0
    assert cfg.environment.noise == se.AmbientNoise(wind_speed_m_s=3.0, shipping=0.1)
    off = runconfig.load_run_config(_write(tmp_path, sonar_extra="source_level_db = 205.0\n", env="noise = false\n"))
    assert off.environment.noise is None and off.acquisition.noise_density() == 0.0
    assert se.Acquisition(dataclasses.replace(off.sonar, source_level_db=None), off.environment).noise_density() == 0.0
    assert cfg.acquisition.noise_density() > 0.0
    with pytest.raises(se.ConfigError, match="'gust'"):
        runconfig.load_run_config(_write(tmp_path, env="noise = { gust = 3.0 }\n"))


def test_echo_sounder_noise_uses_the_circular_piston_di():
    """EchoSounder: the same noise path with the DI of its piston's pattern, ka from the −3 dB width
    (2·J1(x)/x = 1/√2 at x = 1.6163)."""
    es = se.Acquisition(se.EchoSounder(max_range_m=30.0, source_level_db=200.0),
                        se.Environment(noise=se.AmbientNoise(wind_speed_m_s=8.0)))
    rec = se.simulate(_floor(), se.Trajectory.line((0, 0, 25.0), (1.0, 0, 25.0), 8), es, se.Pulse.cw(),
                      speckle=True, seed=5, start_time="2000-01-01")
    water = rec.time_s < 2 * 24.0 / 1500.0
    ka = 1.6163 / np.sin(np.radians(10.0) / 2)
    di = analytic.directivity_index_db(lambda u, v: 2 * j1(ka * np.hypot(u, v) + 1e-12) / (ka * np.hypot(u, v) + 1e-12),
                                       n_phi=64)
    expected = coates_db(200e3, 8.0) - di + 10 * np.log10(rec.sonar.sample_rate_hz)
    assert 10 * np.log10(rec.data[:, :, water].mean()) == pytest.approx(expected, abs=0.3)
