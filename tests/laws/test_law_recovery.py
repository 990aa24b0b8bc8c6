"""σ(θ) recovered from a speckle-free flat-floor record matches each law's closed form (issue 14's check of
the scattering-law seam): the spreading, absorption, beam and footprint of docs/physics.md eq. (2) are undone
with the known geometry, computed here independently of the simulator."""
import numpy as np
import pytest

import analytic
import sonar_embree as se
from conftest import flat_scene, line_along_x

H, TILT, LY, TAU = 10.0, 50.0, 0.0015, 20e-6   # a broad beam looking at 50°: grazing 15°–90° all lit


def _recovered_sigma(material):
    sonar = se.Sonar(tilt_deg=TILT, height_m=LY, max_range_m=40.0, sample_rate_hz=200e3)
    rec = se.simulate(flat_scene(**material), line_along_x(n_pings=2, length=0.1), sonar,
                      se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")
    r_end = rec.slant_range_m
    ext = se.Acquisition.of(sonar).sound_speed_m_s * TAU / 2
    grazing = np.degrees(np.arcsin(H / np.clip(r_end - ext / 2, H, None)))
    pick = np.flatnonzero((r_end - ext > H + 1e-3) & (grazing >= 15.0))[::40]
    nodes, weights = np.polynomial.legendre.leggauss(6)
    r = (r_end[pick, None] - ext / 2) + nodes[None, :] * ext / 2            # Gauss points in each cell
    g1 = analytic.flat_floor_g(r.ravel(), h=H, alpha_db_m=rec.acquisition.alpha_db_per_m, sigma=lambda c: 1.0 + 0 * c,
                               ly=LY, tilt_deg=TILT).reshape(r.shape)
    cell = (g1 * weights).sum(axis=1) * ext / 2                             # ∫ g(R)/σ over the cell
    measured = rec.starboard.mean(axis=0)[pick] / cell
    centre = r_end[pick] - ext / 2
    return measured, H / centre, grazing[pick]


def test_lambert_sigma_recovered():
    sigma, cos_i, grazing = _recovered_sigma({"backscatter_db": -20.0})
    band = (grazing >= 15) & (grazing <= 75)
    assert band.sum() > 20
    want = 10 ** -2.0 * cos_i ** 2
    err = 10 * np.log10(sigma[band] / want[band])
    assert np.max(np.abs(err)) < 0.3, np.max(np.abs(err))


def test_kirchhoff_sigma_recovered_including_the_nadir_peak():
    r0, s = 0.6, 0.25
    sigma, cos_i, grazing = _recovered_sigma({"scattering": se.laws.Kirchhoff(r0, s)})
    theta = np.arccos(cos_i)
    want = analytic.kirchhoff_monostatic(theta, r0, s)
    band = (grazing >= 15) & (want > 1e-12)
    err = 10 * np.log10(sigma[band] / want[band])
    assert band.sum() > 20 and np.max(np.abs(err)) < 0.3, np.max(np.abs(err))
    peak = r0 ** 2 / (8 * np.pi * s ** 2)                                  # σ_K(0) = |R0|²/(8π s²)
    assert 10 * np.log10(sigma[np.argmax(grazing)] / peak) == pytest.approx(0.0, abs=0.3)
    assert grazing.max() > 85


def test_tabulated_sigma_recovered(tmp_path):
    """A table read from CSV (with a frequency axis, taken at the sonar's carrier): σ recovered within 0.3 dB."""
    angles = [10, 20, 35, 50, 65, 80, 90]
    rows = ["frequency_hz,grazing_deg,backscatter_db"]
    for f, shift in ((200e3, -6.0), (600e3, 2.0)):  # at the 400 kHz carrier, halfway: shift −2 dB
        rows += [f"{f},{g},{-35 + 0.3 * g + shift}" for g in angles]
    (tmp_path / "curve.csv").write_text("\n".join(rows) + "\n")
    law = se.laws.Tabulated.from_csv(tmp_path / "curve.csv")
    sigma, cos_i, grazing = _recovered_sigma({"scattering": law})
    want_db = np.interp(grazing, angles, [-37 + 0.3 * g for g in angles])    # written here, not read from the law
    band = (grazing >= 15) & (grazing <= 75)
    err = 10 * np.log10(sigma[band]) - want_db[band]
    assert band.sum() > 20 and np.max(np.abs(err)) < 0.3, np.max(np.abs(err))


def test_composite_sigma_recovered():
    """Lambert + Kirchhoff: the sum of the two closed forms, within 0.3 dB from 15° grazing to the nadir peak."""
    r0, s = 0.5, 0.2
    sigma, cos_i, grazing = _recovered_sigma({"scattering": se.laws.Lambert(-25.0) + se.laws.Kirchhoff(r0, s)})
    want = 10 ** -2.5 * cos_i ** 2 + analytic.kirchhoff_monostatic(np.arccos(cos_i), r0, s)
    band = grazing >= 15
    err = 10 * np.log10(sigma[band] / want[band])
    assert band.sum() > 20 and np.max(np.abs(err)) < 0.3, np.max(np.abs(err))
    assert grazing.max() > 85 and want[np.argmax(grazing)] > 10 * 10 ** -2.5   # the lobe is in the test
