"""Every Numba kernel against its naive NumPy twin (tests/naive.py)."""
import numpy as np

import naive
from sonar_embree import kernels


def test_lambert_intensity_matches_naive(rng):
    n = 5000
    r = rng.uniform(0.0, 60.0, n)
    r[:5] = [np.inf, 0.0, 1e-6, 1e4, np.nan]
    cos_inc = rng.uniform(-0.5, 1.0, n)
    gamma = rng.uniform(-1, 1, n)
    d_omega = rng.uniform(0, 1e-4, n)
    mu = rng.uniform(0, 0.1, n)
    out = np.full(n, np.nan)
    kernels.lambert_intensity(r, cos_inc, gamma, d_omega, mu, 0.0442, 0.00375, out)
    ref = naive.lambert_intensity(r, cos_inc, gamma, d_omega, mu, 0.0442, 0.00375)
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=0)
    assert np.all(np.isfinite(out)) and np.all(out >= 0)
    assert out[(cos_inc <= 0)].max(initial=0) == 0.0


def test_lambert_intensity_deep_absorption_underflows_to_zero_not_nan():
    out = np.empty(1)
    kernels.lambert_intensity(np.array([5e4]), np.array([1.0]), np.array([1.0]), np.array([1.0]),
                              np.array([1.0]), 10.0, 0.0, out)
    assert out[0] == 0.0


def _splat_inputs(rng, n=4000, n_s=300):
    delay = rng.uniform(-5, n_s + 5, n)
    delay[:6] = [0.0, n_s - 1, n_s - 1 + 1e-9, -1e-12, np.nan, np.inf]
    channel = rng.integers(-1, 3, n)
    return channel, delay


def test_splat_linear_real_matches_naive(rng):
    channel, delay = _splat_inputs(rng)
    w = rng.uniform(0, 1, delay.size)
    out = np.zeros((2, 300))
    kernels.splat_linear(channel, delay, w, out)
    ref = naive.splat_linear(channel, delay, w, np.zeros((2, 300)))
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)


def test_splat_linear_complex_matches_naive(rng):
    channel, delay = _splat_inputs(rng)
    w = rng.normal(size=delay.size) + 1j * rng.normal(size=delay.size)
    out = np.zeros((2, 300), dtype=complex)
    kernels.splat_linear(channel, delay, w, out)
    ref = naive.splat_linear(channel, delay, w, np.zeros((2, 300), dtype=complex))
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)


def test_splat_conserves_weight_and_never_wraps():
    out = np.zeros((1, 10))
    kernels.splat_linear(np.zeros(3, dtype=np.int64), np.array([-0.5, 3.25, 9.5]), np.array([7.0, 1.0, 5.0]), out)
    assert out.sum() == 1.0  # only the in-window contribution, no wrap-around of the negative delay
    np.testing.assert_allclose(out[0, 3:5], [0.75, 0.25])
