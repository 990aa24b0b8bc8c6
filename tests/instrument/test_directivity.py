"""The directivity index from the integral of the beam pattern (docs/physics.md §14), against a brute spherical
quadrature written in tests/analytic.py and the values quoted in the physics notes."""
import math

import numpy as np
import pytest
from scipy.special import j1

import analytic
import sonar_embree as se
from sonar_embree.instrument.directivity import membrane_directivity_index_db, piston_directivity_index_db
from sonar_embree.instrument.beams import CircularPiston, SquarePiston


@pytest.mark.parametrize("f, lx, ly", [(400e3, 0.19, 0.0038), (100e3, 0.5, 0.01), (200e3, 0.03, 0.03),
                                       (900e3, 0.1, 0.0017), (50e3, 0.02, 0.015)])
def test_membrane_di_is_the_pattern_integral_within_five_hundredths_of_a_db(f, lx, ly):
    lam = 1500.0 / f
    sonar = se.Sonar(frequency_hz=f, length_m=lx, height_m=ly)
    want = analytic.directivity_index_db(analytic.membrane_pattern(lx, ly, lam))
    assert se.Acquisition.of(sonar).directivity_index_db == pytest.approx(want, abs=0.05)


def test_the_values_the_physics_notes_quote_and_how_far_the_large_aperture_form_is_off():
    """28.23 dB (integral) against 28.10 (4π·lx·ly/λ²) for the default membrane; 24.11 against 24.46 dB for
    0.5 m × 10 mm at 100 kHz."""
    assert se.Acquisition(se.Sonar()).directivity_index_db == pytest.approx(28.23, abs=0.01)
    assert se.Acquisition(se.Sonar(frequency_hz=100e3, length_m=0.5,
                                   height_m=0.01)).directivity_index_db == pytest.approx(24.11,
                                                                                                          abs=0.01)
    large = 10 * math.log10(4 * math.pi * 0.19 * 0.0038 / (1500 / 400e3) ** 2)
    assert large == pytest.approx(28.10, abs=0.01)


@pytest.mark.parametrize("ka", [3.0, 10.0, 40.0])
def test_circular_piston_di_is_its_pattern_integral(ka):
    def pattern(u, v):
        x = ka * np.hypot(u, v)
        return np.where(x < 1e-9, 1.0, 2 * j1(x) / np.where(x < 1e-9, 1.0, x))
    assert CircularPiston(ka, 0.0075).directivity_index_db == pytest.approx(
        analytic.directivity_index_db(pattern, n_phi=64), abs=0.05)
    assert piston_directivity_index_db(400.0) == pytest.approx(20 * math.log10(400.0), abs=0.01)  # large ka


def test_square_piston_di_is_its_pattern_integral():
    sq = SquarePiston(0.04, 1500.0 / 200e3)
    assert sq.directivity_index_db == pytest.approx(
        analytic.directivity_index_db(analytic.membrane_pattern(0.04, 0.04, 1500.0 / 200e3)), abs=0.05)
    assert membrane_directivity_index_db(1e3, 1e3) == pytest.approx(10 * math.log10(4 * 1e6 / math.pi), abs=0.01)
