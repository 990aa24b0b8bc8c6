"""The receiver as devices build it (docs/physics.md §14–15), against closed forms written here: noise through
the receiver's band-pass (power N·B per sample, autocorrelation that of the band), the TVG's start range and
ceiling, and the logarithmic encoding."""
import math

import numpy as np
import pytest

import analytic
import sonar_embree as se
from sonar_embree.errors import ConfigError
from sonar_embree.signal import processing
from analytic import coates_db

F0, FS, B, WIND = 400e3, 200e3, 20e3, 10.0


def _sonar(bandwidth_hz, **kw):
    rx = se.Receiver(bandwidth_hz=bandwidth_hz)
    return se.Acquisition(se.Sonar(max_range_m=30.0, sample_rate_hz=FS, source_level_db=210.0, receiver=rx, **kw),
                          se.Environment(noise=se.AmbientNoise(wind_speed_m_s=WIND)))


def _water(sonar, speckle, keep_complex=False, pings=24):
    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0)), material=se.Material(backscatter_db=-27.0))
    rec = se.simulate(scene, se.Trajectory.line((0, 0, 25.0), (2.0, 0, 25.0), pings), sonar,
                      se.Pulse.cw(duration_s=200e-6), speckle=speckle, seed=4, keep_complex=keep_complex,
                      start_time="2000-01-01", **({"detection": "coherent"} if keep_complex else {}))
    water = rec.time_s < 2 * 24.0 / 1500.0                            # before any floor echo
    return rec, water


def _expected_db(bandwidth_hz):
    """NL − DI + 10·log10 B (µPa² per sample), DI by the brute quadrature of tests/analytic.py."""
    di = analytic.directivity_index_db(analytic.membrane_pattern(0.19, 0.0038, 1500.0 / F0))
    return coates_db(F0, WIND) - di + 10 * math.log10(bandwidth_hz)


@pytest.mark.parametrize("speckle", [False, True])
def test_noise_power_per_sample_is_nl_minus_di_plus_the_receivers_band(speckle):
    rec, water = _water(_sonar(B), speckle)
    assert 10 * np.log10(rec.data[:, :, water].mean()) == pytest.approx(_expected_db(B), abs=0.3)
    white, _ = _water(_sonar(None), speckle, pings=4)                   # without a band: the sample band, 10 dB more
    assert 10 * np.log10(white.data[:, :, water].mean()) == pytest.approx(_expected_db(FS), abs=0.3)


def test_noise_samples_are_correlated_as_the_band_makes_them():
    """The complex noise's normalised autocorrelation: an ideal band B gives sinc(B·τ); the filter built is near
    ideal (within 0.05), and equal to its taps' own autocorrelation within the estimate's scatter."""
    rec, water = _water(_sonar(B), True, keep_complex=True, pings=40)
    z = rec.complex_data[:, :, water].reshape(-1, water.sum())
    lags = np.arange(0, 21)
    r = np.array([np.mean(z[:, : z.shape[1] - k] * np.conj(z[:, k:])).real for k in lags])
    r /= r[0]
    ideal = np.sinc(B * lags / FS)
    assert np.max(np.abs(r - ideal)) < 0.05
    h = processing.band_taps(B, FS)
    own = np.correlate(h, h, mode="full")[h.size - 1:][: lags.size]
    assert np.max(np.abs(r - own / own[0])) < 0.03
    assert abs(r[10]) < 0.05 and abs(r[20]) < 0.05                     # the band's zeros, τ = k/B


def test_a_band_narrower_than_the_pulse_is_refused():
    with pytest.raises(ConfigError, match="bandwidth_hz = 2000 Hz is narrower than the pulse's band"):
        _water(_sonar(2e3), False, pings=2)


def test_tvg_start_range_and_ceiling():
    tvg = se.TVG(g0_db=10.0, k=30, start_range_m=5.0, max_gain_db=45.0, absorption=True)
    r = np.array([0.5, 2.0, 5.0, 10.0, 20.0, 40.0, 80.0])
    a = 0.1
    law = 10.0 + 30 * np.log10(np.maximum(r, 5.0)) + 2 * a * np.maximum(r, 5.0)
    np.testing.assert_allclose(tvg.gain_db(r, a), np.minimum(law, 45.0), rtol=0, atol=1e-12)
    assert tvg.gain_db(np.array([0.5]), a)[0] == pytest.approx(10 + 30 * math.log10(5) + 1.0)  # held before R0
    assert np.all(tvg.gain_db(np.array([40.0, 80.0]), a) == 45.0)                               # the ceiling
    with pytest.raises(ConfigError, match="TVG.start_range_m"):
        se.TVG(start_range_m=-1.0)


def test_noise_after_the_ceiling_is_flat_in_gain():
    """A receiver whose TVG hits its ceiling at 10 m: the noise-only codes beyond it keep one mean level."""
    rx = se.Receiver(gain=se.TVG(g0_db=20.0, k=30, max_gain_db=50.0, absorption=False), sensitivity_db=-160.0)
    sonar = se.Acquisition(se.Sonar(max_range_m=60.0, source_level_db=200.0, receiver=rx),
                           se.Environment(noise=se.AmbientNoise(wind_speed_m_s=WIND)))
    scene = se.Scene().add(se.seafloor.flat((10.0, 10.0)), material=se.Material(backscatter_db=-27.0))
    rec = se.simulate(scene, se.Trajectory.line((0, 0, 55.0), (1, 0, 55.0), 30), sonar, se.Pulse.cw(),
                      speckle=True, seed=2, start_time="2000-01-01")
    codes = rec.samples.astype(float)
    r = rec.slant_range_m
    near, far = codes[..., (r > 12) & (r < 25)].mean(), codes[..., (r > 38) & (r < 52)].mean()
    assert far == pytest.approx(near, rel=0.05)
    before = codes[..., (r > 2) & (r < 4)].mean()                   # 30 log R below the ceiling: 20 dB less at 3 m
    assert 20 * np.log10(near / before) == pytest.approx(50.0 - (20 + 30 * math.log10(3.0)), abs=1.5)


def test_logarithmic_encoding_against_its_twin():
    rx = se.Receiver(adc_bits=8, full_scale_v=2.0, encoding="log", log_range_db=60.0)
    v = np.concatenate([[0.0, 1e-9, 2e-3, 2.0, 5.0], np.geomspace(1e-4, 3.0, 200)])
    with np.errstate(divide="ignore"):
        twin = np.clip(np.rint((20 * np.log10(v / 2.0) + 60.0) / 60.0 * 255), 0, 255)
    np.testing.assert_array_equal(rx.digitise(v), twin.astype(np.uint8))
    assert rx.digitise(np.array([2.0]))[0] == 255 and rx.digitise(np.array([2e-3]))[0] == 0
    with pytest.raises(ConfigError, match="Receiver.encoding"):
        se.Receiver(encoding="mu-law")
