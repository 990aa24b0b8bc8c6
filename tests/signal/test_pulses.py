"""Pulses (docs/physics.md §5) and absorption (§3) against closed forms and independent formulas."""
import math

import numpy as np
import pytest

import analytic
import sonar_embree as se
from sonar_embree.signal import pulses
from sonar_embree.environment.francois_garrison import francois_garrison_db_per_m

F0 = 400e3


def _numeric_frequency(pulse, t):
    """f(t) = f0 + (1/2π)·dφ/dt by central differences of the baseband phase."""
    phase = np.unwrap(np.angle(pulses.complex_envelope(pulse, F0, t)))
    return F0 + np.gradient(phase, t) / (2 * np.pi)


def test_lfm_sweeps_linearly_through_the_band():
    p = se.Pulse.lfm(bandwidth_hz=20e3, duration_s=1e-3, taper=0.0)
    t = np.linspace(0, 1e-3, 20001)[:-1]
    f = _numeric_frequency(p, t)
    np.testing.assert_allclose(f[5:-5], 390e3 + 20e3 * t[5:-5] / 1e-3, atol=1.0)
    q = se.Pulse.lfm(bandwidth_hz=20e3, duration_s=1e-3, center_hz=300e3)
    assert q.frequency_span_hz(F0) == (290e3, 310e3)


@pytest.mark.parametrize("f_start, f_stop", [(380e3, 420e3), (420e3, 380e3)])
def test_exp_chirp_frequency_runs_from_start_to_stop_exponentially(f_start, f_stop):
    tau = 1e-3
    p = se.Pulse.exp_chirp(f_start, f_stop, tau, taper=0.0)
    t = np.linspace(0, tau, 40001)[:-1]
    f = _numeric_frequency(p, t)
    closed = f_start * (f_stop / f_start) ** (t / tau)   # f_s·κ^t, here with κ formed (it is small)
    np.testing.assert_allclose(f[5:-5], closed[5:-5], rtol=1e-6)
    assert f[5] == pytest.approx(f_start, rel=1e-3) and f[-5] == pytest.approx(f_stop, rel=1e-3)
    np.testing.assert_allclose(pulses.instantaneous_frequency_hz(p, F0, t), closed, rtol=1e-12)


def test_exp_chirp_with_equal_frequencies_is_exactly_cw():
    t = np.linspace(-1e-5, 2e-4, 5001)
    cw = pulses.complex_envelope(se.Pulse.cw(100e-6, 0.1), F0, t)
    ex = pulses.complex_envelope(se.Pulse.exp_chirp(F0, F0, 100e-6, 0.1), F0, t)
    assert np.array_equal(cw, ex)
    assert not se.Pulse.exp_chirp(F0, F0, 100e-6).is_fm


@pytest.mark.parametrize("f_start, f_stop, tau", [
    (400e3, 400e3 * (1 + 1e-13), 1e-3),    # κ → 1: ln κ ~ 1e-10 /s
    (400e3, 400e3 * (1 + 1e-7), 10e-3),
    (390e3, 410e3, 1e-3),                  # κ = e^50 per second
    (390e3, 410e3, 50e-6),                 # κ = e^1000 per second: overflows if formed
    (100e3, 900e3, 20e-6),                 # a huge sweep over a very short pulse
])
def test_exp_chirp_phase_is_stable_for_hard_parameters(f_start, f_stop, tau):
    p = se.Pulse.exp_chirp(f_start, f_stop, tau, taper=0.0)
    t = np.linspace(0, tau, 200001)
    phase = pulses.phase_offset_rad(p, F0, t)
    assert np.all(np.isfinite(phase))
    # independent: integrate f(t) − f0 numerically (trapezoid), f = f_s·exp(t·ln(f_e/f_s)/τ)
    f = f_start * np.exp(t * (math.log(f_stop / f_start) / tau))
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1] - 2 * F0) * np.diff(t))])
    np.testing.assert_allclose(phase, 2 * np.pi * integral, atol=2e-5 * max(1.0, abs(2 * np.pi * integral).max()))


def test_flat_top_envelope_and_energy():
    t = np.linspace(0, 1e-3, 100001)[:-1]
    rect = pulses.complex_envelope(se.Pulse.lfm(20e3, 1e-3, taper=0.0), F0, t)
    np.testing.assert_allclose(np.abs(rect), 1.0)                      # |p̃|² = 1 untapered
    tapered = np.abs(pulses.complex_envelope(se.Pulse.lfm(20e3, 1e-3, taper=0.2), F0, t))
    assert np.all(tapered >= 0) and np.all(tapered <= 1 + 1e-12)
    np.testing.assert_allclose(tapered[(t > 0.1e-3) & (t < 0.9e-3)], 1.0, atol=1e-13)  # flat between flanks
    assert np.all(tapered[(t < 0.09e-3) | (t > 0.91e-3)] < 1 - 1e-6)
    assert tapered[0] < 1e-4 and tapered[-1] < 1e-3


def test_pulse_validation():
    with pytest.raises(se.ConfigError, match="bandwidth_hz is required"):
        se.Pulse(kind="lfm")
    with pytest.raises(se.ConfigError, match="does not apply"):
        se.Pulse(kind="cw", bandwidth_hz=1e3)
    with pytest.raises(se.ConfigError, match="f_start_hz"):
        se.Pulse(kind="exp_chirp", f_stop_hz=1e3)
    with pytest.raises(se.ConfigError, match="f_stop_hz"):
        se.Pulse.exp_chirp(390e3, -1.0)
    with pytest.raises(se.ConfigError, match="below 0 Hz"):
        se.Pulse.lfm(bandwidth_hz=300e3, center_hz=100e3)


def test_francois_garrison_reproduces_physics_md():
    # docs/physics.md §3: 96 dB/km at 400 kHz, 10 °C, 35 ppt, pH 8; 94–124 dB/km over 4–20 °C.
    assert francois_garrison_db_per_m(400e3, 10, 35, 0, 8) * 1e3 == pytest.approx(96, abs=0.5)
    assert francois_garrison_db_per_m(400e3, 4, 35, 0, 8) * 1e3 == pytest.approx(94, abs=0.5)
    assert francois_garrison_db_per_m(400e3, 20, 35, 0, 8) * 1e3 == pytest.approx(124, abs=0.5)
    for t_c in (4, 10, 15, 20):
        for f in (100e3, 400e3, 900e3):
            fg = francois_garrison_db_per_m(f, t_c, 35, 0, 8) * 1e3
            am = analytic.ainslie_mccolm_db_per_km(f, t_c, 35, 0, 8)
            assert abs(fg / am - 1) < 0.10, (t_c, f, fg, am)


def test_sonar_absorption_default_and_override():
    assert se.Acquisition(se.Sonar()).alpha_db_per_m == pytest.approx(0.0961, abs=2e-4)
    assert se.Acquisition(se.Sonar(), se.Environment(absorption_db_per_m=0.05)).alpha_db_per_m == 0.05
    warm, cold = (se.Acquisition(se.Sonar(), se.Environment(temperature_c=t)) for t in (20, 4))
    assert warm.alpha_db_per_m > cold.alpha_db_per_m
    assert se.Acquisition(se.Sonar(frequency_hz=900e3)).alpha_db_per_m > 0.2
    with pytest.raises(se.ConfigError, match="Environment.temperature_c"):
        se.Environment(temperature_c=80)
