"""Sound-speed profiles: the closed-form arcs of docs/physics.md §12 against quadrature of the ray integrals.

The reference integrates dx/dz = cot θ, ds/dz = 1/sin θ and dt/dz = 1/(c sin θ) with cos θ = ξ·c(z) (Snell)
numerically over depth, written here without the simulator's layer formulas.
"""
import numpy as np
import pytest
from scipy.integrate import quad

import sonar_embree as se
from sonar_embree.environment.profile import SoundSpeedProfile

THREE_LAYERS = SoundSpeedProfile((0.0, 20.0, 45.0, 80.0), (1500.0, 1510.0, 1495.0, 1497.0))


def _quadrature(profile, z0, theta0, z1):
    z_k, c_k = np.array(profile.depth_m), np.array(profile.speed_m_s)

    def c(z):
        return np.interp(z, z_k, c_k)

    xi = np.cos(theta0) / c(z0)
    pts = [z for z in z_k if z0 < z < z1]
    out = []
    for f in (lambda z: xi * c(z) / np.sqrt(1 - (xi * c(z)) ** 2),      # dx/dz
              lambda z: 1 / np.sqrt(1 - (xi * c(z)) ** 2),              # ds/dz
              lambda z: 1 / (c(z) * np.sqrt(1 - (xi * c(z)) ** 2))):    # dt/dz
        out.append(quad(f, z0, z1, points=pts or None, epsabs=0, epsrel=1e-12, limit=200)[0])
    return out


@pytest.mark.parametrize("theta_deg", [8.0, 20.0, 45.0, 70.0, 89.0])
def test_arcs_match_quadrature_across_layers_of_both_signs(theta_deg):
    th = np.radians(theta_deg)
    x, s, t = THREE_LAYERS.trace_down(5.0, [th], 70.0)
    ref = _quadrature(THREE_LAYERS, 5.0, th, 70.0)
    np.testing.assert_allclose([x[0], s[0], t[0]], ref, rtol=1e-8)


def test_linear_profile_first_arrival_against_quadrature_at_many_angles():
    """The issue's case: 1500 m/s at the sonar, gradient 0.5 s⁻¹; floor 40 m below the sonar."""
    p = SoundSpeedProfile.linear(1495.0, 0.5)
    th = np.radians(np.linspace(10, 90, 33))
    x, s, t = p.trace_down(10.0, th, 50.0)
    assert p.speed_at(10.0) == pytest.approx(1500.0)
    for k in range(th.size):
        np.testing.assert_allclose([x[k], s[k], t[k]], _quadrature(p, 10.0, th[k], 50.0), rtol=1e-8, atol=1e-12)
    # c grows with depth, so rays bend towards the slower water above: flatter, they land further out
    straight_x = 40.0 / np.tan(th[:-1])
    assert np.all(x[:-1] - straight_x > 1e-4)


def test_uniform_profile_is_the_straight_ray():
    p = SoundSpeedProfile((0.0, 100.0), (1480.0, 1480.0))
    th = np.radians([5.0, 30.0, 90.0])
    x, s, t = p.trace_down(2.0, th, 42.0)
    np.testing.assert_allclose(x, 40.0 / np.tan(th), atol=1e-9)
    np.testing.assert_allclose(s, 40.0 / np.sin(th))
    np.testing.assert_allclose(t, 40.0 / np.sin(th) / 1480.0)
    assert p.is_uniform and not THREE_LAYERS.is_uniform


def test_vertical_ray_and_turning_rays():
    p = SoundSpeedProfile.linear(1500.0, 0.5)
    x, s, t = p.trace_down(0.0, [np.pi / 2, np.radians(1.0)], 200.0)
    assert x[0] == 0.0 and s[0] == pytest.approx(200.0)
    assert t[0] == pytest.approx(np.log(1600.0 / 1500.0) / 0.5, rel=1e-12)       # ∫ dz / (c0 + g z)
    # cos 1° · 1600/1500 > 1: the ray turns before 200 m and never arrives
    assert np.cos(np.radians(1.0)) * 1600 / 1500 > 1 and np.isnan(x[1]) and np.isnan(t[1])


def test_profile_from_csv_and_errors(tmp_path):
    good = tmp_path / "ctd.csv"
    good.write_text("depth_m,speed_m_s\n0,1500\n10,1502.5\n30,1490\n")
    p = SoundSpeedProfile.from_csv(good)
    assert p.depth_m == (0.0, 10.0, 30.0) and p.speed_at(20.0) == pytest.approx(1496.25)
    cases = {"depth,speed\n0,1500\n": "columns depth_m, speed_m_s",
             "depth_m,speed_m_s\n0,1500\n5,fast\n": "row 3 is not numeric",
             "depth_m,speed_m_s\n0,1500\n0,1501\n": "strictly increasing",
             "depth_m,speed_m_s\n0,1.5\n10,1.5\n": "1300–1800 m/s"}
    for k, (text, needle) in enumerate(cases.items()):
        f = tmp_path / f"bad{k}.csv"
        f.write_text(text)
        with pytest.raises(se.ConfigError, match=needle) as info:
            SoundSpeedProfile.from_csv(f)
        assert str(f) in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(se.ConfigError, match="cannot read"):
        SoundSpeedProfile.from_csv(tmp_path / "missing.csv")
    with pytest.raises(se.ConfigError, match="same number"):
        SoundSpeedProfile((0.0, 1.0), (1500.0,))
    with pytest.raises(se.ConfigError, match="depth1_m > depth0_m"):
        p.trace_down(10.0, [0.5], 10.0)
