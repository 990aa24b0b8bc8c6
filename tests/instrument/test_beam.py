"""Rectangular-membrane beam pattern against docs/physics.md §2."""
import math

import numpy as np
import pytest

import sonar_embree as se
from sonar_embree.instrument import beam
from sonar_embree import kernels

LAM = 1500.0 / 400e3
K = 2 * np.pi / LAM


def _width_by_scan(size, level_db, power):
    """Full width where sinc^power(πL/λ sinθ) first drops below level, by brute-force scan."""
    theta = np.linspace(0, np.pi / 2, 2_000_001)
    g = beam.directivity(np.sin(theta), np.zeros_like(theta), np.ones_like(theta), K, size, 1e-9)
    if size < 0.01:  # elevation: use the height axis
        g = beam.directivity(np.zeros_like(theta), np.sin(theta), np.ones_like(theta), K, 1e-9, size)
    db = 10 * power / 2 * np.log10(np.abs(g) ** 2 + 1e-300)
    i = np.argmax(db < level_db)
    return 2 * np.degrees(theta[i])


@pytest.mark.parametrize("size, one_way, two_way", [(0.19, 1.002, 0.721), (0.0038, 51.84, 36.69)])
def test_minus_3db_widths(size, one_way, two_way):
    assert _width_by_scan(size, -3.0, 2) == pytest.approx(one_way, abs=0.005 * one_way)
    assert _width_by_scan(size, -3.0, 4) == pytest.approx(two_way, abs=0.005 * two_way)
    assert beam.beamwidth_deg(size, LAM) == pytest.approx(one_way, rel=2e-3)
    assert beam.beamwidth_deg(size, LAM, two_way=True) == pytest.approx(two_way, rel=2e-3)


def test_first_null_and_on_axis():
    assert math.degrees(beam.first_null_rad(0.19, LAM)) == pytest.approx(1.131, abs=1e-3)
    assert beam.directivity(np.array([0.0]), np.array([0.0]), np.array([1.0]), K, 0.19, 0.0038)[0] == 1.0


def test_baffle_and_no_nan_over_the_sphere(rng):
    u = rng.normal(size=(200_000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    u[:4] = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1, 0]]  # exact zeros of the sinc arguments
    g = beam.directivity(u[:, 0], u[:, 1], u[:, 2], K, 0.19, 0.0038)
    assert np.all(np.isfinite(g)) and np.all(np.abs(g) <= 1.0)
    assert np.all(g[u[:, 2] <= 0] == 0.0)
    assert g[0] == 1.0


def test_from_beamwidths_rules():
    exact = se.Sonar.from_beamwidths(1.0, 50.0)
    lam = se.Acquisition(exact).wavelength_m
    assert beam.beamwidth_deg(exact.length_m, lam) == pytest.approx(1.0, rel=1e-9)
    assert beam.beamwidth_deg(exact.height_m, lam) == pytest.approx(50.0, rel=1e-9)
    small = se.Sonar.from_beamwidths(1.0, 50.0, rule="small-angle")
    assert small.length_m == pytest.approx(0.190, abs=5e-4)
    assert small.height_m == pytest.approx(0.0038, abs=5e-5)
    with pytest.raises(se.ConfigError, match="rule"):
        se.Sonar.from_beamwidths(1.0, 50.0, rule="guess")


def test_fan_integrates_two_way_pattern():
    """Σ Γ⁴ dΩ over the fan equals an independent dense quadrature of ∫Γ⁴ dΩ."""
    sonar = se.Sonar()
    s, ds = beam.azimuth_samples(se.Acquisition.of(sonar).wavelength_m, sonar.length_m, 2.0, 4)
    lo, hi = beam.elevation_span_rad(se.Acquisition.of(sonar).wavelength_m, sonar.height_m, sonar.tilt_rad)
    edges = np.linspace(lo, hi, 200)
    b, db = np.empty(7800), np.empty(7800)
    kernels.place_rows(edges, np.full((1, 199), 3000.0), np.array([0, 7800]), b, db)
    assert db.sum() == pytest.approx(hi - lo, rel=1e-12)
    u = beam.fan_body(s, b, +1)  # (forward, starboard, down): boresight depressed by δ in the starboard plane
    d = np.radians(20.0)
    g = beam.directivity(u[:, 0], -u[:, 1] * np.sin(d) + u[:, 2] * np.cos(d), u[:, 1] * np.cos(d) + u[:, 2] * np.sin(d),
                         K, 0.19, 0.0038)
    fan = np.sum(g ** 4 * np.tile(db * ds, s.size))
    # independent: ψ, β grid with dΩ = cosψ dψ dβ
    psi = np.linspace(-0.2, 0.2, 2001)                       # 100 points per main lobe; 4× denser: same to 1e-11
    beta = np.linspace(lo, hi, 1001)
    P, B = np.meshgrid(psi, beta, indexing="ij")
    d = np.radians(20.0)
    u_f, u_s, u_d = np.sin(P), np.cos(P) * np.cos(B), np.cos(P) * np.sin(B)
    g = beam.directivity(u_f, -u_s * np.sin(d) + u_d * np.cos(d), u_s * np.cos(d) + u_d * np.sin(d), K, 0.19, 0.0038)
    ref = np.trapezoid(np.trapezoid(g ** 4 * np.cos(P), beta, axis=1), psi)
    assert fan == pytest.approx(ref, rel=2e-3)
