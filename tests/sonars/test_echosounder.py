"""The sonar-type seam: a one-channel down-looking echo sounder over a flat floor (docs/physics.md §3, §11)."""
import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import j1

import sonar_embree as se
from conftest import flat_scene
from sonar_embree.sonars import EchoSounder

H = 20.0


def _piston(theta, beamwidth_deg):
    """2·J1(x)/x with ka chosen so that the one-way −3 dB full width is ``beamwidth_deg`` (solved here)."""
    x3 = brentq(lambda x: 2 * j1(x) / x - 2 ** -0.5, 0.5, 3.0)
    ka = x3 / np.sin(np.radians(beamwidth_deg) / 2)
    x = ka * np.sin(theta)
    return np.where(x < 1e-9, 1.0, 2 * j1(np.maximum(x, 1e-9)) / np.maximum(x, 1e-9))


@pytest.fixture(scope="module")
def sounding():
    sonar = EchoSounder(frequency_hz=200e3, beamwidth_deg=10.0, max_range_m=30.0)
    traj = se.Trajectory.line((0, 0, H), (1, 0, H), 2).stop_and_hop()   # the quadratures' model
    return se.simulate(flat_scene(), traj, sonar, se.Pulse.cw(duration_s=100e-6, taper=0.0),
                       start_time="2000-01-01")


def test_one_channel_and_first_return_at_2h_over_c(sounding):
    rec = sounding
    assert rec.channels == ("down",) and rec.data.shape[1] == 1
    with pytest.raises(se.ConfigError, match="no channel 'port'"):
        rec.port
    down = rec.channel("down")
    t0 = 2 * H / rec.acquisition.sound_speed_m_s
    dt = 1 / rec.sonar.sample_rate_hz
    first = rec.time_s[np.argmax(down[0] > 0)]
    assert abs(first - t0) <= dt
    assert np.all(down[:, rec.time_s < t0 - dt] == 0)
    np.testing.assert_allclose(rec.altitude_m, H, rtol=1e-9)


def _quadrature(rec):
    s = rec.sonar
    grid = np.linspace(H, 30.0, 400001)
    theta = np.arccos(H / grid)
    g = 2 * np.pi * _piston(theta, 10.0) ** 4 * 10 ** (-2.7) * (H / grid) ** 2 \
        * 10 ** (-2 * se.Acquisition.of(s).alpha_db_per_m * grid / 10) / grid ** 3
    cum = np.concatenate([[0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(grid))])
    r, ext = rec.slant_range_m, se.Acquisition.of(s).sound_speed_m_s * 100e-6 / 2
    return np.interp(r, grid, cum) - np.interp(r - ext, grid, cum)


def test_level_against_quadrature(sounding):
    """E[I](t) = ∫ g(R)|p|² dR, g(R) = 2π·b⁴(θ)·σ(h/R)·10^(−2αR/10)/R³, cos θ = h/R (flat floor, ring about nadir).

    The energy of the main lobe and the side lobes at the default rate; sample by sample
    at 10 samples per pulse length, where the lobe's steep edge is resolved in time.
    """
    rec = sounding
    band = (rec.slant_range_m > H) & (rec.slant_range_m < 25.0)
    want = _quadrature(rec)
    got = rec.channel("down").mean(axis=0)
    assert abs(10 * np.log10(got[band].sum() / want[band].sum())) < 0.05
    fine = se.simulate(flat_scene(), se.Trajectory.line((0, 0, H), (1, 0, H), 2).stop_and_hop(),
                       EchoSounder(frequency_hz=200e3, beamwidth_deg=10.0, max_range_m=30.0, sample_rate_hz=400e3),
                       se.Pulse.cw(duration_s=100e-6, taper=0.0), start_time="2000-01-01")
    want = _quadrature(fine)
    lobe = want > 0.1 * want.max()
    assert lobe.sum() > 50
    err_db = 10 * np.log10(fine.channel("down").mean(axis=0)[lobe] / want[lobe])
    assert np.max(np.abs(err_db)) < 0.1, np.max(np.abs(err_db))


def test_echo_sounder_outputs_and_limits(sounding, tmp_path):
    rec = sounding
    rec.save(tmp_path / "r.npz")
    back = se.Record.load(tmp_path / "r.npz")
    assert back.channels == ("down",) and isinstance(back.sonar, EchoSounder)
    np.testing.assert_array_equal(back.data, rec.data)
    assert list(rec.to_xarray().data_vars)[0] == "down"
    assert rec.waterfall(max_columns=None).shape == (2, rec.data.shape[2])
    with pytest.raises(se.ConfigError, match="XTF holds side-scan records"):
        rec.to_xtf(tmp_path / "r.xtf")
    with pytest.raises(se.ConfigError, match="labels are made for side-scan"):
        se.simulate(flat_scene(), se.Trajectory.line((0, 0, H), (1, 0, H), 2), EchoSounder(), labels=True)
    with pytest.raises(se.ConfigError, match="EchoSounder.beamwidth_deg"):
        EchoSounder(beamwidth_deg=0.0)


def test_echo_sounder_speckle_mean_is_the_expected_intensity():
    """Frozen speckle through the channel-generic back end: E|Σ|² = Σ w|p|² (docs/physics.md §4), on the
    lobe's energy over 120 soundings 2.5 m apart (independent: the lattice cell is the piston radius, 2 cm).
    The lobe holds few resolution cells, so one sounding scatters by ~65 %; the mean's standard error is
    ~6 %, the bound 4 of them (the speckle statistics themselves are tested on the side-scan)."""
    sonar = EchoSounder(frequency_hz=200e3, beamwidth_deg=10.0, max_range_m=25.0)
    traj = se.Trajectory.line((-149, 0, H), (149, 0, H), 120)
    kw = dict(start_time="2000-01-01", quality=0.5)
    speckled = se.simulate(flat_scene(), traj, sonar, se.Pulse.cw(), speckle=True, seed=5, **kw)
    expected = se.simulate(flat_scene(), traj, sonar, se.Pulse.cw(), **kw)
    lobe = expected.channel("down").mean(axis=0) > 1e-4 * expected.channel("down").max()
    per_ping = speckled.channel("down")[:, lobe].sum(axis=1) / expected.channel("down")[:, lobe].sum(axis=1)
    assert per_ping.std() > 0.3                       # speckle is there, sounding to sounding
    assert abs(per_ping.mean() - 1.0) < 0.25          # and unbiased


def test_echo_sounder_moves_during_the_ping():
    """A 2° beam at 5 m/s: the receive beam turned by δ = 2v/c along track (docs/physics.md §16). The energy of
    the flat floor's echo, moving over still, against the quadrature ∫∫ b²(θ)·b²(θ_rx)·σ·e^(−2αR)/R⁴ dA over the
    same with b⁴, sin θ_rx = |(sin θ cos φ − δ, sin θ sin φ)|, within 0.03 dB."""
    v, bw = 5.0, 2.0
    sonar = EchoSounder(frequency_hz=200e3, beamwidth_deg=bw, max_range_m=30.0)
    line = se.Trajectory.line((0, 0, H), (2, 0, H), 2, speed_m_s=v)
    moving, still = (se.simulate(flat_scene(), t, sonar, se.Pulse.cw(duration_s=100e-6, taper=0.0),
                                 start_time="2000-01-01") for t in (line, line.stop_and_hop()))
    c, alpha = se.Acquisition.of(sonar).sound_speed_m_s, se.Acquisition.of(sonar).alpha_db_per_m * np.log(10) / 10
    theta = np.linspace(0.0, np.radians(4 * bw), 2001)[:, None]
    phi = np.linspace(0.0, 2 * np.pi, 721)[None, :]
    r = H / np.cos(theta)
    area_per = np.cos(theta) ** 2 * np.exp(-2 * alpha * r) / r ** 4 * H ** 2 * np.tan(theta) / np.cos(theta) ** 2
    sin_rx = np.hypot(np.sin(theta) * np.cos(phi) - 2 * v / c, np.sin(theta) * np.sin(phi))
    b2 = _piston(theta, bw) ** 2
    num = np.trapezoid(np.trapezoid(area_per * b2 * _piston(np.arcsin(np.minimum(sin_rx, 1)), bw) ** 2, phi, axis=1),
                       theta[:, 0])
    den = np.trapezoid(np.trapezoid(area_per * b2 * b2 * np.ones_like(phi), phi, axis=1), theta[:, 0])
    want_db = 10 * np.log10(num / den)
    assert want_db < -0.1
    got_db = 10 * np.log10(moving.channel("down").sum(axis=1) / still.channel("down").sum(axis=1))
    np.testing.assert_allclose(got_db, want_db, atol=0.03)
    assert moving.attrs["motion_during_ping"]
