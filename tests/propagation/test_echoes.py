"""The echo contract: the back end reads only Echoes (travel times), whatever made them."""
import numpy as np
import pytest

import sonar_embree as se
from sonar_embree.signal import pulses
from sonar_embree.propagation.echoes import Echoes
from sonar_embree.signal.synthesis import ExpectedSynthesis


@pytest.mark.parametrize("n_channels", [1, 2, 3])
def test_back_end_from_hand_made_echoes(n_channels):
    """One point echo per row at a chosen travel time: the expected-intensity back end puts exactly its
    weight, spread by the unit echo's kernel, at that time on that row, for any channel count."""
    sonar = se.Sonar().for_pulse(se.Pulse.cw(taper=0.0))
    pulse = se.Pulse.cw(taper=0.0)
    chain = se.SignalChain().resolved(se.Acquisition.of(sonar), pulse)
    fs = sonar.sample_rate_hz
    n_p, n_s = 2, 400
    rows = n_p * n_channels
    t = (50.0 + 37.0 * np.arange(rows)) / fs          # a whole sample each: no interpolation between samples
    w = 1.0 + np.arange(rows)
    e = Echoes(n_channels, np.arange(rows + 1, dtype=np.int64), t, np.zeros(rows), w, np.zeros((0, 3)),
               np.zeros(0, np.int32))
    assert e.n_pings == n_p
    kernel, lead = pulses.expected_kernel(pulse, sonar.frequency_hz, fs, chain.matched_filter)
    back = ExpectedSynthesis(sonar, pulse, chain, (n_p, n_channels, n_s), None, (kernel, lead))
    back.add_block(e, 0, 0, np.zeros(3), np.zeros((n_p, 3)), {})
    out, cplx = back.finish()
    assert cplx is None and out.shape == (n_p, n_channels, n_s)
    flat = out.reshape(rows, n_s)
    for r in range(rows):
        k = int(round(t[r] * fs))
        want = np.zeros(n_s)
        want[k - lead:k - lead + kernel.size] = w[r] * kernel
        np.testing.assert_allclose(flat[r], want, rtol=1e-12, atol=1e-12 * w[r])  # t·fs is whole up to round-off
