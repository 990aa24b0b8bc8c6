"""Speckle (docs/physics.md §4): Rayleigh statistics, frozen to the surface, unbiased."""
import numpy as np
import pytest

import sonar_embree as se
from conftest import H, flat_scene

SONAR = se.Sonar(max_range_m=30.0)


@pytest.fixture(scope="module")
def independent_pings():
    """41 pings 2 m apart over a flat floor (independent speckle), and the expected intensity."""
    traj = se.Trajectory.line((-40.0, 0.0, H), (40.0, 0.0, H), 41)
    scene = flat_scene()
    expected = se.simulate(scene, traj, SONAR)
    speckled = se.simulate(scene, traj, SONAR, speckle=True, seed=11)
    band = expected.slant_range_m > 12.0
    ratio = np.concatenate([speckled.port[:, band] / expected.port[:, band],
                            speckled.starboard[:, band] / expected.starboard[:, band]])
    return ratio, expected, speckled, band


def test_fully_developed_speckle_statistics(independent_pings):
    ratio = independent_pings[0]
    assert ratio.size > 40_000
    assert abs(ratio.mean() - 1) < 0.05
    assert abs(ratio.std() / ratio.mean() - 1) < 0.1                    # contrast of an exponential
    assert abs(np.mean(10 * np.log10(ratio)) + 2.51) < 0.3               # mean of 10·log10 I/⟨I⟩
    assert abs(np.std(10 * np.log10(ratio)) - 5.57) < 0.3


def test_mean_of_speckled_pings_converges_to_speckle_free(independent_pings):
    ratio, expected, speckled, band = independent_pings
    n_lines, n = ratio.shape
    blocks = n // 50
    block_mean = ratio[:, :blocks * 50].reshape(n_lines, blocks, 50).mean(axis=2)  # ~1 m range blocks
    assert np.all(np.abs(block_mean.mean(axis=0) - 1) < 0.1)
    err = [np.sqrt(np.mean((ratio[:k].mean(axis=0) - 1) ** 2)) for k in (8, 32, 82)]
    assert err[0] > err[1] > err[2]                  # falls as 1/√N: err(82)/err(8) ≈ √(8/82) = 0.31
    assert err[2] < 0.5 * err[0]
    # nothing arrives before the first bottom return, speckle or not
    early = speckled.time_s < 2 * H / se.Acquisition(SONAR).sound_speed_m_s - 1 / speckled.sonar.sample_rate_hz
    assert np.all(speckled.starboard[:, early] == 0) and np.all(speckled.port[:, early] == 0)


def _pair(dx, seed=0, dy=0.0):
    traj = se.Trajectory(np.array([[0.0, 0.0, H], [dx, dy, H]]), heading_deg=[90.0, 90.0])
    return se.simulate(flat_scene(), traj, SONAR, speckle=True, seed=seed)


def _corr(a, b, expected):
    band = expected.slant_range_m > 12.0
    x = np.concatenate([a.port[band] / expected.port[0, band], a.starboard[band] / expected.starboard[0, band]])
    y = np.concatenate([b.port[band] / expected.port[0, band], b.starboard[band] / expected.starboard[0, band]])
    return np.corrcoef(x, y)[0, 1]


@pytest.fixture(scope="module")
def expected_line():
    return se.simulate(flat_scene(), se.Trajectory(np.array([[0.0, 0.0, H]]), heading_deg=[90.0]), SONAR)


def test_speckle_is_frozen_to_the_surface(expected_line):
    same = _pair(0.0)
    assert np.array_equal(same.starboard[0], same.starboard[1]) and np.array_equal(same.port[0], same.port[1])
    near = _pair(0.01)
    assert _corr(_Line(near, 0), _Line(near, 1), expected_line) > 0.8
    far = _pair(5.0)
    assert abs(_corr(_Line(far, 0), _Line(far, 1), expected_line)) < 0.2
    other = _pair(0.0, seed=1)
    assert abs(_corr(_Line(same, 0), _Line(other, 0), expected_line)) < 0.2
    # a sonar standing still sees a static image: the same record in a second run
    again = _pair(0.01)
    assert np.array_equal(near.starboard, again.starboard)


def test_speckle_moves_with_the_floor_not_with_the_sonar(expected_line):
    # Moving the sonar across track by 1 cm keeps the speckle of the same floor points:
    # the pattern shifts in range by ~1 cm (half a sample) instead of being redrawn
    # (a speckle drawn per ray per ping would give ~0 here).
    across = _pair(0.0, dy=0.01)
    assert _corr(_Line(across, 0), _Line(across, 1), expected_line) > 0.6


class _Line:
    """One ping of a two-ping record, with .port / .starboard as 1-D lines."""

    def __init__(self, rec, i):
        self.port, self.starboard = rec.port[i], rec.starboard[i]


def test_compressed_fm_speckle_is_rayleigh():
    """LFM 20 kHz / 1 ms, matched filter: the lattice follows the compressed cell c/(2B) = 3.75 cm (not lx/2 =
    9.5 cm, where the contrast was 1.04) and the speckle contrast is 1 ± 0.03 (docs/physics.md §10)."""
    pulse = se.Pulse.lfm(20e3, duration_s=1e-3)
    chain = se.SignalChain(speckle=True, matched_filter=True).resolved(se.Acquisition(SONAR), pulse)
    assert chain.speckle_cell_m == pytest.approx(se.Acquisition(SONAR).sound_speed_m_s / (2 * 20e3))
    assert se.SignalChain(speckle=True).resolved(se.Acquisition(SONAR),
                                                 se.Pulse.cw(duration_s=1e-3)).speckle_cell_m == \
        pytest.approx(SONAR.length_m / 2)                           # a long CW pulse: along track is finer
    traj = se.Trajectory.line((-40.0, 0.0, H), (40.0, 0.0, H), 41)
    scene = flat_scene()
    expected = se.simulate(scene, traj, SONAR, pulse, matched_filter=True)
    speckled = se.simulate(scene, traj, SONAR, pulse, speckle=True, matched_filter=True, seed=11)
    band = expected.slant_range_m > 12.0
    ratio = (speckled.data / expected.data)[:, :, band]
    assert ratio.size > 40_000
    assert abs(ratio.std() / ratio.mean() - 1) < 0.03 and abs(ratio.mean() - 1) < 0.05


def test_a_chirp_synthesised_as_impulses_is_the_splatted_chirp(monkeypatch):
    """A long pulse in baseband (LFM 32 kHz, 2 ms: 128 samples at fs = 2B) is synthesised as band-limited impulses
    convolved once with p̃ (synthesis.IMPULSE_MIN_SAMPLES): the complex signal before and after compression is the
    one made by splatting every scatterer with the whole tabulated pulse, within 0.5 % of the peak amplitude (the
    largest at the floor's sharp onset, whose tabulated pulse holds content beyond the record rate's band), with a
    difference of under 1e-4 of the signal's energy and the same energy within 0.1 %."""
    from sonar_embree.signal import synthesis

    pulse = se.Pulse.lfm(32e3, duration_s=2e-3)
    traj = se.Trajectory.line((0.0, 0.0, H), (1.0, 0.0, H), 3)
    kw = dict(speckle=True, seed=5, keep_complex=True)
    raw, fast = (se.simulate(flat_scene(), traj, SONAR, pulse, matched_filter=mf, **kw) for mf in (False, True))
    monkeypatch.setattr(synthesis, "IMPULSE_MIN_SAMPLES", 10 ** 9)          # every scatterer splatted with p̃
    raw_ref, ref = (se.simulate(flat_scene(), traj, SONAR, pulse, matched_filter=mf, **kw) for mf in (False, True))
    for got, want in ((raw, raw_ref), (fast, ref)):
        diff, energy = got.complex_data - want.complex_data, (np.abs(want.complex_data) ** 2).sum()
        assert np.abs(diff).max() < 5e-3 * np.abs(want.complex_data).max()
        assert (np.abs(diff) ** 2).sum() < 1e-4 * energy
        assert (np.abs(got.complex_data) ** 2).sum() == pytest.approx(energy, rel=1e-3)


def test_node_tables_grow_to_the_rate_their_rays_made_nodes():
    """A ping that filled its table at its k-th of n rays (status −2 − k) gets room for n/k times the nodes: the
    capacity times the next power of two of n/k, at least 2 and at most MAX_TABLE_GROWTH; the worst ping decides."""
    from sonar_embree.signal import synthesis

    ray_start = np.array([0, 500, 1000, 1300, 2000, 2400, 3000])       # 3 pings of 2 channels: 1000, 1000, 1000 rays
    grown = synthesis.grown_capacity
    assert grown(1 << 10, np.array([1, -2 - 400, 1]), ray_start) == 1 << 12          # 1000/400 = 2.5 → 4
    assert grown(1 << 10, np.array([-2 - 999, 1, 1]), ray_start) == 1 << 11          # 1.001 → at least twice
    assert grown(1 << 10, np.array([-2 - 700, -2 - 110, 1]), ray_start) == 1 << 14   # the worst: 9.1 → 16
    assert grown(1 << 10, np.array([-2, 1, 1]), ray_start) == 1 << 10 << 4           # full at the first: 16 at most
