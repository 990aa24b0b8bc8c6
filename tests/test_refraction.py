"""Curved rays in a sound-speed profile (docs/physics.md §12) against an independent ray map.

The reference integrates Snell's ray integrals numerically over depth (x = ∫ cot θ dz,
L = ∫ dz / sin θ, T = ∫ dz / (c sin θ), cos θ = ξ·c(z)) for launch angles θ0, without the
simulator's closed-form arcs. Over a flat floor the expected intensity per launch cell is

    dI = Γ⁴(θ0, φ)·μ·e^(−2α'L)·cos²θ0 / (x·|∂x/∂θ0|) dθ0 dφ

(Lambert σ = μ sin²θh, floor area dA = x|∂x/∂θ0| dθ0 dφ, tube area per steradian
A_Ω = x|∂x/∂θ0| sin θh / cos θ0 both ways), with ∂x/∂θ0 by central differences here, and a
rectangular pulse τ sums it over 2T ∈ (t − τ, t].
"""
import numpy as np
import pytest

import analytic
import sonar_embree as se
from sonar_embree.fan import FanPlan
from sonar_embree.raycast.embree import EmbreeCaster
from sonar_embree.refraction import cast_refracted
from sonar_embree.sonars.sidescan import SideScanFrontEnd

H, DEPTH, C_SONAR, GRAD, MU_DB, TAU, FS, TILT, RANGE = 10.0, 20.0, 1500.0, 0.5, -20.0, 100e-6, 50e3, 10.0, 80.0


def _profile(gradient=GRAD):
    """c = C_SONAR at the sonar (depth DEPTH, z = H), the floor at z = 0 (depth DEPTH + H)."""
    return se.SoundSpeedProfile.linear(C_SONAR - gradient * DEPTH, gradient, depth_m=300.0, surface_z_m=H + DEPTH)


def _sonar(profile):
    return se.Sonar(tilt_deg=TILT, max_range_m=RANGE, sample_rate_hz=FS,
                    environment=se.Environment(sound_speed=profile))


def _scene():
    return se.Scene().add(se.seafloor.flat((500.0, 300.0)), material=se.Material(backscatter_db=MU_DB),
                          label="seafloor")


def _record(profile):
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2)
    return se.simulate(_scene(), line, _sonar(profile), se.Pulse.cw(duration_s=TAU, taper=0.0),
                       start_time="2000-01-01")


def ray_map(theta0, gradient=GRAD, n=4001):
    """Horizontal distance x, path length L and one-way time T at the floor for launch angles θ0 (quadrature)."""
    z = np.linspace(0.0, H, n)                                       # depth below the sonar
    c = C_SONAR + gradient * z
    xi = np.cos(theta0)[:, None] / C_SONAR
    sin_t = np.sqrt(np.clip(1.0 - (xi * c) ** 2, 0.0, None))
    ok = sin_t[:, -1] > 1e-6                                          # reaches the floor
    sin_t = np.where(ok[:, None], sin_t, 1.0)
    # the integrands are smooth for rays that reach the floor: composite Simpson over depth
    w = np.full(n, 2.0)
    w[1::2], w[0], w[-1] = 4.0, 1.0, 1.0
    w *= (z[1] - z[0]) / 3.0
    x = (xi * c / sin_t) @ w
    L = (1.0 / sin_t) @ w
    T = (1.0 / (c * sin_t)) @ w
    nan = np.where(ok, 1.0, np.nan)
    return x * nan, L * nan, T * nan


def quadrature(t, alpha_db_m, gradient=GRAD):
    """Expected intensity at sample times t (s) of the flat floor under the profile (independent of the code)."""
    th = np.radians(np.concatenate([np.linspace(4.0, 30.0, 2601)[:-1], np.linspace(30.0, 89.99, 1200)]))
    x, L, T = ray_map(th, gradient)
    d = 1e-6
    dxd = (ray_map(th + d, gradient)[0] - ray_map(th - d, gradient)[0]) / (2 * d)
    ok = np.isfinite(x) & np.isfinite(dxd)
    th, x, L, T, dxd = th[ok], x[ok], L[ok], T[ok], dxd[ok]
    phi = np.unique(np.concatenate([np.linspace(-0.12, 0.12, 241), np.linspace(-np.pi / 2, np.pi / 2, 181)]))
    u_f = np.cos(th)[:, None] * np.sin(phi)[None]
    u_s = np.cos(th)[:, None] * np.cos(phi)[None]
    gamma = analytic.gamma_membrane(u_f, u_s, np.broadcast_to(np.sin(th)[:, None], u_f.shape), tilt_deg=TILT)
    alpha_np = alpha_db_m * np.log(10) / 10
    dens = (np.trapezoid(gamma ** 4, phi, axis=1) * 10 ** (MU_DB / 10) * np.exp(-2 * alpha_np * L)
            * np.cos(th) ** 2 / (x * np.abs(dxd)))
    order = np.argsort(2 * T)
    tt, g = 2 * T[order], dens[order]
    th_o = th[order]
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.abs(np.diff(th_o)))])

    def C(x_):
        return np.interp(x_, tt, cum, left=0.0, right=cum[-1])

    return C(t) - C(t - TAU)


@pytest.fixture(scope="module")
def records():
    return _record(_profile()), _record(None)


def test_first_arrival_per_launch_angle_against_the_ray_map():
    """Every boresight ray's echo lands where and when the quadrature ray map puts it (one sample, 1 cm)."""
    profile = _profile()
    sonar = _sonar(profile)
    front = SideScanFrontEnd(sonar, se.FanSettings())
    compiled = _scene().compiled(np.zeros(3))
    caster = EmbreeCaster.for_scene(compiled)
    rot = se.Trajectory.line((0.0, 0.0, H), (1.0, 0.0, H), 2).rotations()[:1]
    pos = np.array([[0.0, 0.0, H]]) - compiled.origin_m
    blk = cast_refracted(caster, front.plan, rot, pos, sonar.environment, front.two_way_np_per_m, RANGE, sonar,
                         True, {})
    plan = front.plan
    a0 = int(np.flatnonzero(plan.s == 0.0)[0])
    n_el = np.diff(blk.el_start)
    checked = 0
    for row in (0, 1):
        j = np.arange(n_el[row])
        rays = blk.ray_start[row] + a0 * n_el[row] + j
        beta = blk.beta[blk.el_start[row] + j]
        ok = blk.weight[rays] > 0
        x_ref, _, t_ref = ray_map(beta[ok])
        hit = blk.point_m[rays[ok]]
        np.testing.assert_allclose(blk.time_s[rays[ok]], 2 * t_ref, atol=1.0 / FS)
        np.testing.assert_allclose(np.hypot(hit[:, 0], hit[:, 1]), np.abs(x_ref), atol=0.01)  # β > 90°: past nadir
        checked += ok.sum()
    assert checked > 200
    # the nadir echo: T = ∫dz/c = ln(c_floor / c_sonar) / g; straight rays would arrive 2 samples later at 1500 m/s
    t_nadir = 2 * np.log((C_SONAR + GRAD * H) / C_SONAR) / GRAD
    assert abs(blk.time_s[blk.weight > 0].min() - t_nadir) < 0.5 / FS


def test_expected_intensity_matches_the_ray_map_quadrature(records):
    rec, straight = records
    t = rec.time_s
    ref = quadrature(t, rec.sonar.alpha_db_per_m)
    sim = rec.starboard[0]
    onset = 2 * np.log((C_SONAR + GRAD * H) / C_SONAR) / GRAD
    keep = (ref > 1e-3 * ref.max()) & (np.abs(t - onset) > 2.0 / FS) & (np.abs(t - onset - TAU) > 2.0 / FS)
    keep &= t < 2 * RANGE / C_SONAR - 2 * TAU
    err = 10 * np.log10(sim[keep] / ref[keep])
    assert keep.sum() > 2500
    assert np.max(np.abs(err)) < 0.5, np.max(np.abs(err))
    # and the profile matters here: the straight-ray record misses the same reference by more than 0.5 dB
    off = 10 * np.log10(straight.starboard[0][keep] / ref[keep])
    assert np.max(np.abs(off)) > 1.0


def test_zero_gradient_profile_gives_todays_record_bit_for_bit(records):
    _, straight = records
    flat = se.SoundSpeedProfile((0.0, 100.0), (C_SONAR, C_SONAR))
    rec = _record(flat)
    assert np.array_equal(rec.data, straight.data)
