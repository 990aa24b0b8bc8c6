"""Timing and jitter (docs/physics.md §16): pings by ping rate and speed, Gauss–Markov attitude and heave.

References here: ping k of a survey at arc length k·v/PRF and time k/PRF; back to back PRF = c/(2·R_max);
a first-order Gauss–Markov process has variance σ² and autocorrelation exp(−|Δt|/T) (Gelb 1974, §3.8).
"""
import dataclasses

import numpy as np
import pytest

import sonar_embree as se


def test_survey_pings_follow_rate_and_speed_on_a_line():
    t = se.Trajectory.survey([(0, 0, 10), (100, 0, 10)], speed_m_s=2.0, ping_rate_hz=5.0)
    assert len(t) == 251                                            # 100 m · 5 Hz / 2 m/s + 1
    np.testing.assert_allclose(t.times_s, np.arange(251) / 5.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(t.positions_m[:, 0], 0.4 * np.arange(251), atol=1e-9)
    assert np.all(t.heading_deg == 90.0)


def test_survey_back_to_back_by_default_and_refuses_overlapping_pings():
    sonar = se.Sonar(max_range_m=50.0)
    t = se.Trajectory.survey([(0, 0, 10), (30, 0, 10)], speed_m_s=1.5, sonar=sonar)
    prf = 1500.0 / (2 * 50.0)
    np.testing.assert_allclose(np.diff(t.times_s), 1 / prf, rtol=1e-12)
    np.testing.assert_allclose(np.diff(t.positions_m[:, 0]), 1.5 / prf, rtol=1e-9)
    with pytest.raises(se.ConfigError, match="faster than the sonar's 15 Hz"):
        se.Trajectory.survey([(0, 0, 10), (30, 0, 10)], speed_m_s=1.5, ping_rate_hz=16.0, sonar=sonar)
    with pytest.raises(se.ConfigError, match="give ping_rate_hz or the sonar"):
        se.Trajectory.survey([(0, 0, 10), (30, 0, 10)], speed_m_s=1.5)
    with pytest.raises(se.ConfigError, match="speed_m_s"):
        se.Trajectory.survey([(0, 0, 10), (30, 0, 10)], speed_m_s=0.0, ping_rate_hz=1.0)


def test_survey_on_a_curved_path_spaces_pings_by_arc_length():
    t = se.Trajectory.survey([(0, 0, 10), (20, 10, 10), (40, 0, 10), (60, 15, 10)], speed_m_s=2.0, ping_rate_hz=4.0)
    step = np.linalg.norm(np.diff(t.positions_m, axis=0), axis=1)
    np.testing.assert_allclose(step, 0.5, atol=2e-3)                # chords of 0.5 m arcs on a gentle curve
    assert np.ptp(t.heading_deg) > 40.0


@pytest.mark.parametrize("component, kwargs", [("yaw_deg", dict(yaw_rms_deg=2.0)),
                                               ("heave_m", dict(heave_rms_m=0.3)),
                                               ("roll_deg", dict(roll_rms_deg=1.5))])
def test_jitter_has_the_rms_and_correlation_time_asked_for(component, kwargs):
    from sonar_embree.trajectory.motion import jitter

    motion = se.Motion(correlation_s=2.0, **kwargs)
    dt, n = 0.1, 40000
    x = jitter(motion, np.arange(n) * dt, seed=11)[component]
    sigma = next(iter(kwargs.values()))
    assert np.std(x) == pytest.approx(sigma, rel=0.10)
    lag = int(2.0 / dt)                                              # at Δt = T the correlation is 1/e
    rho = np.corrcoef(x[:-lag], x[lag:])[0, 1]
    assert -lag * dt / np.log(rho) == pytest.approx(2.0, rel=0.10)
    rho1 = np.corrcoef(x[:-1], x[1:])[0, 1]
    assert -dt / np.log(rho1) == pytest.approx(2.0, rel=0.10)


def test_jitter_is_frozen_by_seed_and_applied_to_the_poses():
    line = se.Trajectory.survey([(0, 0, 10), (50, 0, 10)], speed_m_s=2.0, ping_rate_hz=2.0)
    motion = se.Motion(yaw_rms_deg=1.0, pitch_rms_deg=0.5, heave_rms_m=0.2, correlation_s=3.0)
    a, b, c = line.with_motion(motion, seed=1), line.with_motion(motion, seed=1), line.with_motion(motion, seed=2)
    assert a == b and a != c
    from sonar_embree.trajectory.motion import jitter

    d = jitter(motion, line.times_s, seed=1)
    np.testing.assert_array_equal(a.positions_m[:, 2], line.positions_m[:, 2] + d["heave_m"])
    np.testing.assert_allclose(a.heading_deg, (90.0 + d["yaw_deg"]) % 360.0)
    assert np.all(a.roll_deg == 0.0) and np.any(a.pitch_deg != 0.0)
    only_heave = jitter(se.Motion(heave_rms_m=0.2, correlation_s=3.0), line.times_s, seed=1)["heave_m"]
    np.testing.assert_array_equal(only_heave, d["heave_m"])              # one stream per component
    with pytest.raises(se.ConfigError, match="correlation_s"):
        se.Motion(correlation_s=0.0)
    with pytest.raises(se.ConfigError, match="roll_rms_deg"):
        se.Motion(roll_rms_deg=45.0)


def test_motion_during_the_ping_shifts_a_point_target_by_v_tau_over_2():
    """A 0.2 m ball on a dark floor at 40 m slant range: with the receiver moving on during the ping, the ball's
    along-track response (its echo over the floor's, in a range gate) peaks v·τ/2 earlier (τ = 2R/c) than
    stop-and-hop; centroids within 10 % of the ping spacing. The floor makes the ray budget place rays densely
    at the ball's range."""
    import trimesh

    r_slant, h, v, prf = 40.0, 10.0, 1.5, 15.0
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    ball.apply_translation((0.0, -np.sqrt(r_slant ** 2 - h ** 2), 0.1))        # starboard of a +x track

    def scene(with_ball):
        s = se.Scene().add(se.seafloor.flat((200.0, 200.0)), material=se.Material(backscatter_db=-40.0),
                           label="seafloor")
        return s.add(ball, material=se.Material(backscatter_db=0.0), label="ball") if with_ball else s

    sonar = se.Sonar(max_range_m=45.0, tilt_deg=10.0)
    moving = se.Trajectory.survey([(-1.5, 0, h), (1.5, 0, h)], speed_m_s=v, ping_rate_hz=prf, sonar=sonar)
    still = dataclasses.replace(moving, velocity_m_s=None)
    cent = {}
    for name, traj in (("moving", moving), ("still", still)):
        rec, bare = (se.simulate(scene(b), traj, sonar, se.Pulse.cw(), start_time="2000-01-01", quality=2.0)
                     for b in (True, False))
        gate = np.abs(rec.slant_range_m - (r_slant - 0.1)) < 0.3
        e = (rec.starboard - bare.starboard)[:, gate].sum(axis=1)
        cent[name] = np.sum(traj.positions_m[:, 0] * e) / e.sum()
        assert rec.attrs["motion_during_ping"] is (name == "moving")
    tau, spacing = 2 * r_slant / 1500.0, v / prf
    assert cent["still"] == pytest.approx(0.0, abs=0.1 * spacing)
    assert cent["still"] - cent["moving"] == pytest.approx(v * tau / 2, abs=0.1 * spacing)


def test_a_line_moves_during_the_ping_by_default_and_the_flat_floor_loses_the_beam_overlap():
    """``Trajectory.line`` knows its speed, so its pings carry the velocity (motion during the ping is on);
    ``stop_and_hop()`` drops it. Over a flat floor the moving record is the stop-and-hop one times the
    along-track overlap of the transmit beam and the receive beam turned by δ = 2v/c (docs/physics.md §16):
    ∫Γ²(u)Γ²(u − δ)du / ∫Γ⁴(u)du with Γ(u) = sinc(k·lx/2·u), u = sin ψ — quadrature here, within 0.03 dB."""
    from conftest import flat_scene

    v, h, sonar = 2.0, 10.0, se.Sonar(max_range_m=40.0)
    line = se.Trajectory.line((-0.5, 0, h), (0.5, 0, h), 2, speed_m_s=v)
    np.testing.assert_allclose(line.velocity_m_s, [[v, 0, 0], [v, 0, 0]], atol=1e-12)
    still = line.stop_and_hop()
    assert still.velocity_m_s is None and np.array_equal(still.positions_m, line.positions_m)
    one = se.Trajectory.line((0, 0, h), (0, 3, h), 1, speed_m_s=1.5)               # one ping still knows its course
    np.testing.assert_allclose(one.velocity_m_s, [[0, 1.5, 0]], atol=1e-12)
    assert se.Trajectory.line((0, 0, h), (0, 0, h), 1).velocity_m_s is None      # no length: no course
    moving_rec, still_rec = (se.simulate(flat_scene(), t, sonar, se.Pulse.cw(100e-6, taper=0.0),
                                         start_time="2000-01-01") for t in (line, still))
    assert moving_rec.attrs["motion_during_ping"] and not still_rec.attrs["motion_during_ping"]
    a = np.pi * sonar.frequency_hz * sonar.length_m / se.Acquisition.of(sonar).sound_speed_m_s          # k·lx/2
    delta = 2 * v / se.Acquisition.of(sonar).sound_speed_m_s
    u = np.linspace(-40 / a, 40 / a, 400_001)
    gamma = lambda x: np.sinc(a * x / np.pi)                                         # noqa: E731
    want_db = 10 * np.log10(np.trapezoid(gamma(u) ** 2 * gamma(u - delta) ** 2, u) / np.trapezoid(gamma(u) ** 4, u))
    assert want_db < -0.1                                                             # a loss the test can see
    band = (moving_rec.slant_range_m > 15.0) & (moving_rec.slant_range_m < 38.0)
    for side in ("starboard", "port"):
        got_db = 10 * np.log10(getattr(moving_rec, side)[:, band] / getattr(still_rec, side)[:, band])
        np.testing.assert_allclose(got_db, want_db, atol=0.03)


def test_motion_during_the_ping_in_toml(tmp_path):
    """``[trajectory] motion_during_ping = false`` asks for stop-and-hop; anything but a boolean is refused."""
    from sonar_embree.runs.runconfig import parse_trajectory

    table = {"kind": "line", "start": [0, 0, 10], "end": [4, 0, 10], "n_pings": 3, "speed_m_s": 1.5}
    assert parse_trajectory(table, "run.toml", str(tmp_path), "[trajectory]").velocity_m_s is not None
    assert parse_trajectory({**table, "motion_during_ping": False}, "run.toml", str(tmp_path),
                            "[trajectory]").velocity_m_s is None
    with pytest.raises(se.ConfigError, match="run.toml: \\[trajectory\\] motion_during_ping must be true or false"):
        parse_trajectory({**table, "motion_during_ping": "no"}, "run.toml", str(tmp_path), "[trajectory]")
    (tmp_path / "nav.csv").write_text("time_s,x_m,y_m,z_m\n0,0,0,10\n1,1.5,0,10\n")  # a navigation log: 1.5 m/s
    nav = {"kind": "csv", "path": "nav.csv"}
    np.testing.assert_allclose(parse_trajectory(nav, "run.toml", str(tmp_path), "[trajectory]").velocity_m_s,
                               [[1.5, 0, 0]] * 2)
    assert parse_trajectory({**nav, "motion_during_ping": False}, "run.toml", str(tmp_path),
                            "[trajectory]").velocity_m_s is None


def test_speckle_phase_follows_the_moving_receiver():
    """Speckle phases with motion during the ping: one echo on a lattice node X at two-way time t0, the receiver
    moving at v. The synthesised signal is the stop-and-hop one times e^(−j2π·Δ/λ), Δ = |X − (p + v·t0)| − |X − p|
    (the receiver where the echo arrives; docs/physics.md §16), to rounding."""
    from sonar_embree.propagation.echoes import Echoes
    from sonar_embree.signal.synthesis import ScattererLattice, WaveformTables

    cell, lam, c = 0.05, 1500.0 / 400e3, 1500.0
    x = np.array([40, -600, -100]) * cell                                        # a lattice node, world m
    p, v = np.zeros(3), np.array([2.0, 0.3, 0.0])
    t0 = 2 * np.linalg.norm(x - p) / c
    e = Echoes(2, np.array([0, 0, 1]), np.array([t0]), np.array([0.0]), np.array([1.0]), x[None], np.zeros(0, np.int32))
    tables = WaveformTables(np.ones(3, dtype=complex), 0.0, 1.0)
    out = {}
    for name, vel in (("still", None), ("moving", v[None])):
        out[name] = np.zeros((1, 2, 200), dtype=complex)
        ScattererLattice(cell, seed=5, n_tables=1).synthesise(e, np.zeros(3), p[None], lam, 1.0 / (t0 / 100),
                                                               0.0, tables, out[name], vel_rx=vel)
    delta = np.linalg.norm(x - (p + v * t0)) - np.linalg.norm(x - p)
    assert abs(2 * np.pi * delta / lam) > 1.0                                     # a phase the test can see
    still, moving = out["still"][0, 1], out["moving"][0, 1]
    assert np.abs(still).max() > 0 and np.all(out["moving"][0, 0] == 0)
    np.testing.assert_allclose(moving, still * np.exp(-2j * np.pi * delta / lam), rtol=1e-9, atol=1e-12)
