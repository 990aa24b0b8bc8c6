"""Speckle from ping to ping (issue 52; issue 53, item 2; docs/physics.md §4, "Along-track strips").

Over a flat floor, frozen scatterers seen from two pings d apart are correlated as the van Cittert–Zernike theorem
says for a displaced aperture: the field's correlation is ρ = ∫B(u − δ/2)·B(u + δ/2)·e^(−j2k·d·u) du / ∫B(u)² du,
B(u) = sinc²(D·u/λ) the membrane's two-way amplitude pattern along track (u the along-track direction cosine, np.sinc
normalised), and the intensities' correlation coefficient is |ρ|² (circular Gaussian speckle). δ is how far the
second ping's beam points from the first's in u at the floor: d/R when the sonar moves on (the footprint moves with
it; for R → ∞ the familiar ∫B²·e^(−j2kdu) / ∫B²), plus Δψ·cos β when the vehicle's heading changes by Δψ between
pings (attitude jitter: a turn about the vertical moves a point at depression β by Δψ·cos β in u). The simulator
must follow it for any pulse: before the strips, pings 2 cm apart at 600 kHz with a 30 µs pulse were correlated 0.15
against 0.87.
"""
import math

import numpy as np
import pytest
from scipy.integrate import quad

import sonar_embree as se

F0, D, H = 600e3, 0.19, 8.0
LAM = 1500.0 / F0
K = 2.0 * math.pi / LAM
BAND_M = (13.0, 19.0)                  # slant ranges compared, m
SONAR = se.Sonar(frequency_hz=F0, length_m=D, max_range_m=19.5)


def _closed_form(d_m, turn_rad):
    """|ρ|² of two pings d_m apart whose heading also turns by turn_rad, averaged over the band's slant ranges (the
    floor H below: depression β with sin β = H/R)."""
    b = lambda u: np.sinc(D * u / LAM) ** 2                                 # noqa: E731
    lim = 6.0 * LAM / D
    norm = quad(lambda u: b(u) ** 2, -lim, lim, limit=400, points=[0.0])[0]
    out = []
    for r in np.linspace(*BAND_M, 7):
        delta = d_m / r + turn_rad * math.sqrt(1.0 - (H / r) ** 2)
        f = lambda u, part: b(u - delta / 2) * b(u + delta / 2) * part(2 * K * d_m * u)   # noqa: E731
        re = quad(f, -lim, lim, args=(np.cos,), limit=800, points=[0.0])[0]
        im = quad(f, -lim, lim, args=(np.sin,), limit=800, points=[0.0])[0]
        out.append((re * re + im * im) / norm ** 2)
    return float(np.mean(out))


def _adjacent_correlation(tau_s, d_m, yaw_deg=0.0, n=120):
    """The simulated intensity correlation of adjacent pings (starboard, the band), each normalised by the
    speckle-free record, pooled over the line; pings stop and hop, the heading alternates ±yaw_deg."""
    x = d_m * np.arange(n)
    pos = np.stack([x, np.zeros(n), np.full(n, H)], axis=1)
    heading = 90.0 + yaw_deg * (-1.0) ** np.arange(n)
    traj = se.Trajectory(pos, heading, np.zeros(n), np.zeros(n), 0.1 * np.arange(n))
    scene = se.Scene().add(se.seafloor.flat((60.0, 60.0)), label="seafloor")
    pulse = se.Pulse.cw(duration_s=tau_s)
    rec = se.simulate(scene, traj, SONAR, pulse, speckle=True, seed=3)
    mean = se.simulate(scene, traj, SONAR, pulse)
    band = (rec.slant_range_m > BAND_M[0]) & (rec.slant_range_m < BAND_M[1])
    ratio = rec.starboard[:, band] / mean.starboard[:, band]
    return float(np.corrcoef(ratio[:-1].ravel(), ratio[1:].ravel())[0, 1])


@pytest.mark.parametrize("tau_us, d_over_d", [(30, 0.1), (30, 0.3), (200, 0.3), (20, 0.05), (100, 0.6),
                                               (100, 1.3)])
def test_adjacent_pings_are_as_coherent_as_a_displaced_aperture(tau_us, d_over_d):
    """Within 0.05 of |ρ|² for d/D from 0.05 to 1.3 and pulses from 20 to 200 µs."""
    d = d_over_d * D
    got, want = _adjacent_correlation(tau_us * 1e-6, d), _closed_form(d, 0.0)
    assert got == pytest.approx(want, abs=0.05), (got, want)


def test_attitude_jitter_decorrelates_as_the_turned_beam_says():
    """The heading alternating ±0.15° between pings 2 cm apart (the beam turns 0.3°, a quarter of its width, one
    way and the other in turn): |ρ|² falls from the straight line's, as the closed form with δ = d/R ± 0.3°·cos β
    (the two pairs' mean) says, within 0.05."""
    d, yaw = 0.1 * D, 0.15
    turn = math.radians(2 * yaw)
    straight, jittered = _closed_form(d, 0.0), 0.5 * (_closed_form(d, turn) + _closed_form(d, -turn))
    assert straight - jittered > 0.2                                          # the jitter matters here
    got = _adjacent_correlation(100e-6, d, yaw_deg=yaw)
    assert got == pytest.approx(jittered, abs=0.05), (got, jittered)
