"""The speckle-free flat-floor return against independent quadrature of docs/physics.md eq. (1)–(2)."""
import numpy as np
import pytest
import sonar_embree as se

import analytic
from conftest import H


def test_reference_quadrature_reproduces_physics_md_numbers():
    # docs/physics.md §3: expected intensity of the 7.5 cm cell centred on R (default case).
    r = np.array([12.0, 13.74, 20.0, 29.24, 40.0, 50.0])
    published = np.array([-102.72, -101.35, -106.22, -115.70, -124.97, -132.16])
    got = 10 * np.log10(analytic.flat_floor_expected_intensity(r + 0.0375))
    np.testing.assert_allclose(got, published, atol=0.011)


@pytest.fixture(scope="module")
def reference(flat_record):
    r = flat_record.slant_range_m
    band = (r >= 11.0) & (r <= 49.0)
    return band, analytic.flat_floor_expected_intensity(r[band])


def test_mean_line_matches_analytic_within_half_db(flat_record, reference):
    band, expected = reference
    for channel in (flat_record.starboard, flat_record.port):
        mean_line = channel.mean(axis=0)[band]
        err_db = 10 * np.log10(mean_line / expected)
        assert np.all(np.isfinite(err_db))
        assert np.max(np.abs(err_db)) < 0.5, f"max error {np.max(np.abs(err_db)):.3f} dB"
        # The default fan is designed for <= 0.2 dB (issue 4 target); hold it there.
        assert np.max(np.abs(err_db)) < 0.2


def test_nothing_arrives_before_first_bottom_return(flat_record):
    t_first = 2 * H / flat_record.acquisition.sound_speed_m_s
    dt = 1 / flat_record.sonar.sample_rate_hz
    early = flat_record.time_s < t_first - dt
    assert early.sum() > 500
    assert np.all(flat_record.starboard[:, early] == 0.0)
    assert np.all(flat_record.port[:, early] == 0.0)
    # ...and the bottom return does start there (within one sample)
    first = np.argmax(flat_record.starboard[0] > 0)
    assert abs(flat_record.time_s[first] - t_first) <= dt


def test_no_nan_and_non_negative(flat_record):
    for x in (flat_record.port, flat_record.starboard):
        assert np.all(np.isfinite(x)) and np.all(x >= 0)
    np.testing.assert_allclose(flat_record.altitude_m, H, rtol=1e-9)


def test_axes(flat_record):
    s = flat_record.sonar
    assert flat_record.port.shape == (3, se.Acquisition.of(s).n_samples)
    np.testing.assert_allclose(np.diff(flat_record.time_s), 1 / s.sample_rate_hz)
    np.testing.assert_allclose(flat_record.slant_range_m, flat_record.time_s * se.Acquisition.of(s).sound_speed_m_s / 2)
    assert flat_record.slant_range_m[-1] == pytest.approx(s.max_range_m, abs=se.Acquisition.of(s).range_bin_m)
