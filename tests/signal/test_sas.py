"""Synthetic-aperture backprojection (docs/physics.md §18c): the kernel against its NumPy twin, and a point target's
image against the closed forms: along-track first null at D/2 (the element length's half), across-track at c/(2B),
the across-track side lobe of a rect spectrum, −13.26 dB. The records are written here from the closed-form echo of
a point, w(u)·sinc(B(t − τ))·e^(−j2πf0τ), with the element's two-way pattern w = sinc²(D·u/λ)."""
import math

import numpy as np
import pytest

import naive
from sonar_embree import kernels
from sonar_embree.errors import ConfigError
from sonar_embree.signal.sas import backprojection_image

C, F0, B, D, R0 = 1500.0, 100e3, 20e3, 0.1, 20.0
LAM = C / F0


def _records(x_target=0.0, sway=None):
    """A single element (transmit and receive), pings D/4 apart along x over ±2.5 main-lobe widths at R0, the
    target at (x_target, R0, 0); ``sway`` (pings,) m: each ping's true y, unknown to the image former."""
    half = 2.5 * LAM * R0 / D
    xs = np.arange(-half, half, D / 4)
    pos = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)
    true = pos.copy()
    if sway is not None:
        true[:, 1] = sway(xs.size)
    fs = 4 * B
    t0 = 2 * (R0 - 2.0) / C
    t = t0 + np.arange(int(4.0 * 2 / C * fs)) / fs
    target = np.array([x_target, R0, 0.0])
    r = np.linalg.norm(target - true, axis=1)
    u = (x_target - true[:, 0]) / r
    tau = 2 * r / C
    w = np.sinc(D * u / LAM) ** 2
    data = (w[:, None] * np.sinc(B * (t[None, :] - tau[:, None])) * np.exp(-2j * np.pi * F0 * tau)[:, None])
    return data[:, None, :], t0, fs, pos, pos[:, None, :]


def _first_null(offsets, amp):
    """The smallest |offset| > 0 where |image| has a local minimum."""
    mins = [i for i in range(1, amp.size - 1) if amp[i] <= amp[i - 1] and amp[i] <= amp[i + 1] and offsets[i] > 0]
    return offsets[mins[0]]


def test_the_kernel_matches_its_twin():
    rng = np.random.default_rng(0)
    data = rng.normal(size=(5, 3, 1000)) + 1j * rng.normal(size=(5, 3, 1000))
    tx = rng.uniform(-1, 1, (5, 3))
    rx = tx[:, None, :] + rng.uniform(-0.1, 0.1, (5, 3, 3))
    px = np.column_stack([rng.uniform(-2, 2, 300), rng.uniform(3, 6, 300), np.zeros(300)])
    out = np.empty(300, dtype=np.complex128)
    fwd = np.tile([1.0, 0.0, 0.0], (5, 1))
    vel = rng.uniform(-3, 3, (5, 3))
    for max_u, v, taper in ((2.0, None, 0.0), (0.3, None, 0.0), (0.3, vel, 0.0), (0.3, vel, 0.46)):
        kernels.backproject(data, 0.001, 50e3, F0, C, tx, rx, np.zeros((5, 3)) if v is None else v, fwd, max_u,
                            taper, px, out)                    # every ping and element, a band, moving, weighted
        want = naive.backproject(data, 0.001, 50e3, F0, C, tx, rx, px, fwd, max_u, vel=v, taper=taper)
        np.testing.assert_allclose(out, want, rtol=1e-9, atol=1e-9)
    assert np.abs(out - naive.backproject(data, 0.001, 50e3, F0, C, tx, rx, px, fwd, 0.3, vel=vel)).max() > 0.01 * \
        np.abs(out).max()                                                           # the weighting matters
    assert np.count_nonzero(out) > 200
    still = naive.backproject(data, 0.001, 50e3, F0, C, tx, rx, px, fwd, 0.3)
    assert np.abs(out - still).max() > 0.1 * np.abs(still).max()                 # the motion matters


def test_a_point_targets_image_has_the_closed_form_resolutions_and_side_lobe():
    data, t0, fs, tx, rx = _records()
    dx = np.linspace(-0.1, 0.1, 801)
    along = np.abs(backprojection_image(data, t0, fs, F0, C, tx, rx, dx, [R0]))[0]
    assert abs(dx[np.argmax(along)]) <= dx[1] - dx[0]
    assert _first_null(dx, along) == pytest.approx(D / 2, rel=0.10)
    dr = np.linspace(-0.15, 0.15, 1201)
    across = np.abs(backprojection_image(data, t0, fs, F0, C, tx, rx, [0.0], R0 + dr))[:, 0]
    null = _first_null(dr, across)
    assert null == pytest.approx(C / (2 * B), rel=0.10)
    side = across[(dr > null) & (dr < 2 * null)].max() / across.max()
    assert 20 * np.log10(side) == pytest.approx(-13.26, abs=1.0)


def test_bad_shapes_are_refused():
    data, t0, fs, tx, rx = _records()
    with pytest.raises(ConfigError, match="disagree"):
        backprojection_image(data, t0, fs, F0, C, tx[:-1], rx, [0.0], [R0])


def test_a_sway_defocuses_unless_the_true_navigation_is_used():
    """Pings swaying across track by Gaussian δ (σ = D/4, half an element length peak to peak, i.e. random phases
    4πδ/λ of many turns): imaged with the nominal straight track, the target's peak intensity falls to the
    incoherent share Σw²/(Σw)² of the focused one on average over sways (within a factor 2 over 8 sways); imaged
    with the true navigation, it refocuses to within 10 % of the still line's peak."""
    data, t0, fs, tx, rx = _records()
    dx = np.linspace(-0.05, 0.05, 41)
    still = np.abs(backprojection_image(data, t0, fs, F0, C, tx, rx, dx, [R0])).max()
    rng = np.random.default_rng(4)
    ratios = []
    for _ in range(8):
        sway = rng.normal(0.0, D / 4, tx.shape[0])
        swayed, _, _, _, _ = _records(sway=lambda n: sway)
        nominal = np.abs(backprojection_image(swayed, t0, fs, F0, C, tx, rx, dx, [R0])).max()
        true = tx.copy()
        true[:, 1] = sway
        refocused = np.abs(backprojection_image(swayed, t0, fs, F0, C, true, true[:, None, :], dx, [R0])).max()
        assert refocused == pytest.approx(still, rel=0.10)
        ratios.append((nominal / still) ** 2)
    u = -tx[:, 0] / np.hypot(tx[:, 0], R0)
    w = np.sinc(D * u / LAM) ** 2
    predicted = np.sum(w ** 2) / np.sum(w) ** 2
    assert 0.5 * predicted < np.mean(ratios) < 2.0 * predicted, (np.mean(ratios), predicted)
    assert max(ratios) < 20 * predicted
