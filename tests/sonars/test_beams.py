"""The echo sounder's beams (docs/physics.md §11): each evaluated from body-frame directions after the path
kernels; a new one is a file in instrument/beams/ and a line in BEAMS (the square piston was added so)."""
import numpy as np
import pytest
from scipy.optimize import brentq

import analytic
import sonar_embree as se
from conftest import flat_scene
from sonar_embree.sonars import EchoSounder
from sonar_embree.instrument.beams import BEAMS, SquarePiston, beam_for

H = 20.0


def _square_closed_form(u_fwd, u_side, side_m, lam):
    """sin(x)/x · sin(y)/y, x = π·L·u_fwd/λ (the rectangular piston, written here from the textbook)."""
    x, y = np.pi * side_m * u_fwd / lam, np.pi * side_m * u_side / lam
    return np.where(x == 0, 1.0, np.sin(x) / np.where(x == 0, 1.0, x)) * np.where(y == 0, 1.0, np.sin(y) / np.where(
        y == 0, 1.0, y))


def test_square_piston_beamwidth_null_and_directivity_index():
    lam = 1500.0 / 200e3
    sq = beam_for("square", 10.0, lam)
    assert isinstance(sq, SquarePiston)
    s3 = np.sin(np.radians(5.0))                                # the −3 dB point in a principal plane
    assert sq.one_way(np.array([s3]), np.array([0.0]), np.array([1.0]))[0] == pytest.approx(2 ** -0.5, abs=1e-4)
    assert sq.one_way(np.array([0.0]), np.array([s3]), np.array([1.0]))[0] == pytest.approx(2 ** -0.5, abs=1e-4)
    x3 = brentq(lambda x: np.sin(x) / x - 2 ** -0.5, 0.5, 2.0)
    assert sq.side_m == pytest.approx(x3 / np.pi * lam / s3, rel=1e-5)
    d = np.sqrt(2.0) * lam / sq.side_m                          # the diagonal's first null
    assert abs(sq.one_way(np.array([d / np.sqrt(2)]), np.array([d / np.sqrt(2)]), np.array([1.0]))[0]) < 1e-12
    assert sq.first_null_rad == pytest.approx(np.arcsin(d))
    assert sq.directivity_index_db == pytest.approx(
        analytic.directivity_index_db(analytic.membrane_pattern(sq.side_m, sq.side_m, lam)), abs=0.05)
    u = np.random.default_rng(1).normal(size=(500, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    want = np.where(u[:, 2] > 0, _square_closed_form(u[:, 0], u[:, 1], sq.side_m, lam), 0.0)
    np.testing.assert_allclose(sq.one_way(*u.T), want, rtol=1e-12, atol=1e-15)


def test_the_beams_are_registered_and_a_wrong_name_is_refused():
    assert set(BEAMS) == {"piston", "square", "membrane", "gaussian"}
    with pytest.raises(se.ConfigError,
                       match="EchoSounder.beam must be one of 'piston', 'square', 'membrane', 'gaussian', got 'cone'"):
        EchoSounder(beam="cone")


def test_the_beam_survives_the_record_file_and_toml(tmp_path):
    sonar = EchoSounder(beamwidth_deg=12.0, max_range_m=25.0, beam="square")
    rec = se.simulate(flat_scene(), se.Trajectory.line((0, 0, H), (1, 0, H), 2), sonar, start_time="2000-01-01")
    rec.save(tmp_path / "r.npz")
    assert se.Record.load(tmp_path / "r.npz").sonar.beam == "square"
    from sonar_embree.runs.runconfig import load_run_config
    (tmp_path / "run.toml").write_text('[sonar]\ntype = "echosounder"\nbeam = "square"\nmax_range_m = 25.0\n'
                                       '[trajectory]\nstart = [0.0, 0.0, 20.0]\nend = [1.0, 0.0, 20.0]\nn_pings = 2\n'
                                       '[[objects]]\nseafloor = "flat"\nsize_m = [40.0, 40.0]\n')
    assert load_run_config(tmp_path / "run.toml").sonar.beam == "square"


def test_square_echo_sounder_level_against_quadrature():
    """E[I](t) = ∫ g(R)|p|² dR, g(R) = σ(h/R)·10^(−2αR/10)/R³·∫ b⁴(θ, φ) dφ (cos θ = h/R, the square's b not
    symmetric about the axis: the azimuth integral is numerical); energy within 0.05 dB, sample by sample within
    0.1 dB at 10 samples per pulse length over the main lobe."""
    sonar = EchoSounder(frequency_hz=200e3, beamwidth_deg=10.0, max_range_m=30.0, sample_rate_hz=400e3, beam="square")
    rec = se.simulate(flat_scene(), se.Trajectory.line((0, 0, H), (1, 0, H), 2).stop_and_hop(), sonar,
                      se.Pulse.cw(duration_s=100e-6, taper=0.0), start_time="2000-01-01")
    side, lam = se.Acquisition.of(sonar).transducer.side_m, se.Acquisition.of(sonar).wavelength_m
    phi = np.linspace(0.0, np.pi / 2, 181)                     # b⁴ is even in both cosines: 4 × a quadrant

    def b4(theta):
        st = np.sin(theta)[:, None]
        return 4 * np.trapezoid(_square_closed_form(st * np.cos(phi), st * np.sin(phi), side, lam) ** 4, phi, axis=1)
    r = rec.slant_range_m
    want = analytic.down_looking_flat_floor(r, H, b4, se.Acquisition.of(sonar).alpha_db_per_m,
                                            se.Acquisition.of(sonar).sound_speed_m_s * 100e-6 / 2)
    got = rec.channel("down").mean(axis=0)
    band = (r > H) & (r < 25.0)
    assert abs(10 * np.log10(got[band].sum() / want[band].sum())) < 0.05
    lobe = want > 0.1 * want.max()
    assert lobe.sum() > 50
    assert np.max(np.abs(10 * np.log10(got[lobe] / want[lobe]))) < 0.1
    piston = se.simulate(flat_scene(), se.Trajectory.line((0, 0, H), (1, 0, H), 2).stop_and_hop(),
                         EchoSounder(frequency_hz=200e3, beamwidth_deg=10.0, max_range_m=30.0, sample_rate_hz=400e3),
                         se.Pulse.cw(duration_s=100e-6, taper=0.0), start_time="2000-01-01")
    assert np.max(np.abs(10 * np.log10(piston.channel("down").mean(axis=0)[lobe] / want[lobe]))) > 0.3
