"""A swell over a sound-speed profile (docs/physics.md §13c) against an independent ray-shooting quadrature.

The reference shoots rays over a fine grid of launch elevations θ (above the horizontal) and azimuths φ from the sonar
through a linear profile c(d) = c_S + g·(d − d_S) with the textbook circular-arc ray integrals (Jensen et al. 2011,
ch. 3: x = (s_a − s_b)/(ξg), T = ln(c_b(1 + s_a)/(c_a(1 + s_b)))/g, L = (asin ξc_b − asin ξc_a)/(ξg) for a ray rising
from depth a to b, s = √(1 − ξ²c²)), meets the smooth swell z = z_s + (H/2)·sin(2πy/Λ) (root of the straight ray in
the few decimetres it spans, the exact normal there), mirrors the ray and follows it down to the flat floor; none of
the simulator's kernels, its mesh or its band. The tube comes from central differences of the landing point in θ
and φ. Over a flat Lambert floor (σ = μ·cos θi·cos θs), per launch cell dθ dφ:

    two bounces:  Γ⁴(u)·μ·e^(−2α'L)·cos²θ / J                          at 2T,  J = |∂X/∂θ × ∂X/∂φ|,
    one bounce:   2Γ²(u)Γ²(u_d)·μ·e^(−α'(L + L_d))·cos θ·cos θ_d / (x_d·|∂x_d/∂θ_d|)   at T + T_d,

u_d the direct ray from the sonar down to the landing point (θ_d below the horizontal, found on the direct ray map
x_d(θ_d)); a mirror surface (|R| = 1); a rectangular pulse τ sums each over its arrival time in (t − τ, t].
"""
import numpy as np
import pytest

import analytic
import sonar_embree as se

H, DEPTH, C_SONAR, GRAD, MU_DB, TAU, FS, TILT, RANGE = 10.0, 20.0, 1500.0, 0.5, -20.0, 100e-6, 50e3, 0.0, 70.0
LY = 0.003                     # a membrane lower than λ: no null in elevation, every upward ray is in the fan
SWELL_H, SWELL_L = 0.6, 120.0
Y0 = 0.25 * SWELL_L            # the sonar under a crest: its one-bounce onset 2·0.3 m earlier than a flat surface's


def _surface(swell=True):
    return se.SeaSurface(z_m=H + DEPTH, swell_height_m=SWELL_H if swell else 0.0, swell_length_m=SWELL_L,
                         swell_direction_deg=90.0)


def _record(surface="swell", profile=True, oversample=8.0):
    surf = None if surface is None else _surface(surface == "swell")
    prof = se.SoundSpeedProfile.linear(C_SONAR - GRAD * DEPTH, GRAD, depth_m=300.0, surface_z_m=H + DEPTH)
    env = se.Environment(sound_speed=prof if profile else None, surface=surf)
    sonar = se.Acquisition(se.Sonar(tilt_deg=TILT, height_m=LY, max_range_m=RANGE, sample_rate_hz=FS), env)
    scene = se.Scene().add(se.seafloor.flat((400.0, 400.0), center_m=(0.0, Y0)),
                           material=se.Material(backscatter_db=MU_DB), label="seafloor")
    line = se.Trajectory.line((-0.05, Y0, H), (0.05, Y0, H), 2).stop_and_hop()
    return se.simulate(scene, line, sonar, se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01",
                       fan=se.FanSettings(azimuth_oversample=oversample))


def _speed(depth):
    return C_SONAR + GRAD * (depth - DEPTH)


def _arc(xi, d_a, d_b):
    """(x, T, L) of the circular arc of invariant ξ between depths d_a and d_b (either order), NaN where it turns."""
    lo, hi = np.minimum(d_a, d_b), np.maximum(d_a, d_b)
    c_lo, c_hi = _speed(lo), _speed(hi)
    s_lo, s_hi = np.sqrt(1.0 - (xi * c_lo) ** 2), np.sqrt(1.0 - (xi * c_hi) ** 2)   # NaN: the ray turns
    x = (s_hi - s_lo) / (xi * GRAD)
    t = np.log(c_hi * (1.0 + s_lo) / (c_lo * (1.0 + s_hi))) / GRAD
    length = (np.arcsin(xi * c_hi) - np.arcsin(xi * c_lo)) / (xi * GRAD)
    return np.abs(x), np.abs(t), np.abs(length)


STEP = SWELL_L / 24.0          # the swell as meshed: nodes every Λ/24 across the crests, linear between


def _node_z(i):
    return 0.5 * SWELL_H * np.sin(2.0 * np.pi * i * STEP / SWELL_L)


def _surface_depth(y):
    """Depth of the meshed swell below the mean surface at y (negative at a crest), m, and its slope dz/dy."""
    i = np.floor(y / STEP)
    f = y / STEP - i
    slope = (_node_z(i + 1) - _node_z(i)) / STEP
    return -(_node_z(i) * (1.0 - f) + _node_z(i + 1) * f), slope


def _bounce(theta, phi):
    """Rays launched θ above the horizontal at azimuth φ (towards forward from outboard, +y): the landing point on
    the floor (x, y), one-way time T and path L, and the launch direction's cos θ; NaN where a leg turns."""
    xi = np.cos(theta) / C_SONAR
    lo, hi = np.full(theta.shape, -SWELL_H), np.full(theta.shape, SWELL_H)
    for _ in range(60):                                    # the depth where the rising arc meets the swell
        mid = 0.5 * (lo + hi)
        y = Y0 + _arc(xi, DEPTH, mid)[0] * np.cos(phi)
        above = mid < _surface_depth(y)[0]                # past the surface: the crossing is deeper
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    d = 0.5 * (lo + hi)
    x_up, t_up, l_up = _arc(xi, DEPTH, d)
    p = np.stack([x_up * np.sin(phi), Y0 + x_up * np.cos(phi)])
    cos_h = xi * _speed(d)
    u = np.stack([cos_h * np.sin(phi), cos_h * np.cos(phi), np.sqrt(1.0 - cos_h ** 2)])       # world, z up
    slope = _surface_depth(p[1])[1]                       # dz/dy of the facet
    n = np.stack([np.zeros_like(slope), -slope, np.ones_like(slope)]) / np.sqrt(1.0 + slope ** 2)
    r = u - 2.0 * (u * n).sum(axis=0) * n
    horiz = np.hypot(r[0], r[1])
    xi2 = np.where(r[2] < 0, horiz / _speed(d), np.nan)
    x_dn, t_dn, l_dn = _arc(xi2, d, DEPTH + H)
    land = p + x_dn * np.stack([r[0], r[1]]) / horiz
    return land, t_up + t_dn, l_up + l_dn


def _direct_map():
    """The direct rays from the sonar down to the floor: (θ below the horizontal, x, T, L, ∂x/∂θ) on a fine grid, by
    increasing x."""
    th = np.radians(np.concatenate([np.linspace(2.0, 30.0, 6001)[:-1], np.linspace(30.0, 89.999, 3000)]))
    x, t, length = _arc(np.cos(th) / C_SONAR, DEPTH, DEPTH + H)
    dx = np.gradient(x, th)
    ok = np.isfinite(x)
    order = np.argsort(x[ok])                             # by distance, for the interpolation
    return tuple(a[ok][order] for a in (th, x, t, length, dx))


def _windowed(t, times, dens, theta):
    """Σ over the launch cells between neighbouring θ of their energy (trapezoid of dens·dθ) arriving in (t − τ, t],
    each cell's energy spread evenly over the times its two rays bound (a facet's edge may fold the times back)."""
    e = 0.5 * (dens[1:] + dens[:-1]) * np.abs(np.diff(theta))
    ta, tb = np.minimum(times[1:], times[:-1]), np.maximum(times[1:], times[:-1])
    dt = 0.05 / FS
    n = t.size * 20 + 40
    i0 = np.clip(((ta - t[0] + TAU) / dt).astype(np.int64), 0, n - 1)
    i1 = np.clip(((tb - t[0] + TAU) / dt).astype(np.int64), 0, n - 1)
    wide = i1 > i0
    mass = np.bincount(i0[~wide], e[~wide], n)
    rate = np.bincount(i0[wide], e[wide] / (i1 - i0)[wide], n) - np.bincount(i1[wide], e[wide] / (i1 - i0)[wide], n)
    cum = np.concatenate([[0.0], np.cumsum(mass + np.cumsum(rate))])   # energy arrived before each grid time

    def before(x):
        return np.interp((x - t[0] + TAU) / dt, np.arange(n + 1), cum)
    return before(t) - before(t - TAU)


@np.errstate(invalid="ignore", divide="ignore")
def quadrature(t, alpha_db_m):
    """(one bounce, two bounces) expected intensity at sample times t (s) on one side."""
    mu, alpha = 10 ** (MU_DB / 10), alpha_db_m * np.log(10) / 10
    theta = np.radians(np.concatenate([np.linspace(0.5, 20.0, 2400)[:-1], np.linspace(20.0, 89.9, 1200)]))
    phis = np.unique(np.concatenate([np.linspace(-0.06, 0.06, 61), np.linspace(-np.pi / 2, np.pi / 2, 121)]))
    th_d, x_d, t_d, l_d, dx_d = _direct_map()
    one, two, h = np.zeros_like(t), np.zeros_like(t), 1e-6
    for j, phi in enumerate(phis):
        ph = np.full(theta.shape, phi)
        land, tb, lb = _bounce(theta, ph)
        dth = (_bounce(theta + h, ph)[0] - _bounce(theta - h, ph)[0]) / (2 * h)
        dph = (_bounce(theta, ph + h)[0] - _bounce(theta, ph - h)[0]) / (2 * h)
        jac = np.abs(dth[0] * dph[1] - dth[1] * dph[0])
        g = analytic.gamma_membrane(np.cos(theta) * np.sin(phi), np.cos(theta) * np.cos(phi), -np.sin(theta),
                                    ly=LY, tilt_deg=TILT)
        wt = np.trapezoid(np.eye(phis.size)[j], phis)                       # φ's trapezoid weight
        two_d = g ** 4 * mu * np.exp(-2 * alpha * lb) * np.cos(theta) ** 2 / jac
        rel = land - np.array([[0.0], [Y0]])
        xd = np.hypot(rel[0], rel[1])                       # the direct ray back to the sonar
        at = [np.interp(xd, x_d, a, left=np.nan, right=np.nan) for a in (th_d, t_d, l_d, dx_d)]
        phi_d = np.arctan2(rel[0], rel[1])
        gd = analytic.gamma_membrane(np.cos(at[0]) * np.sin(phi_d), np.cos(at[0]) * np.cos(phi_d), np.sin(at[0]),
                                     ly=LY, tilt_deg=TILT)
        one_d = (2 * g ** 2 * gd ** 2 * mu * np.exp(-alpha * (lb + at[2])) * np.cos(theta) * np.cos(at[0])
                 / (xd * np.abs(at[3])))
        for dens, times, acc in ((two_d, 2 * tb, two), (one_d, tb + at[1], one)):
            ok = np.isfinite(dens) & np.isfinite(times)
            for run in np.split(np.flatnonzero(ok), np.flatnonzero(np.diff(np.flatnonzero(ok)) > 1) + 1):
                if run.size > 1:                          # each unbroken run of lit launch angles
                    acc += wt * _windowed(t, times[run], dens[run], theta[run])
    return one, two


@np.errstate(invalid="ignore", divide="ignore")
def folds():
    """Arrival times (s) at both ends of each jump of the one- and two-bounce arrival time against launch angle (in
    the across-track plane): where a ray crosses from one facet to the next, its mirror turns by twice the step in
    slope, and the landing point, hence the time, jumps; the records fold there (both the simulator's and this
    reference's): (first, last) time of each jump, left out of the sample-by-sample comparison."""
    theta = np.radians(np.linspace(0.5, 89.9, 40000))
    land, tb, _ = _bounce(theta, np.zeros_like(theta))
    th_d, x_d, t_d, _, _ = _direct_map()
    rel = land - np.array([[0.0], [Y0]])
    one = tb + np.interp(np.hypot(rel[0], rel[1]), x_d, t_d, left=np.nan, right=np.nan)
    out = []
    for times in (one, 2 * tb):
        step = np.abs(np.diff(times))
        jump = np.flatnonzero(step > 20 * np.nanmedian(step))
        out += [(min(a, b), max(a, b)) for a, b in zip(times[jump], times[jump + 1]) if np.isfinite(a + b)]
    return out


@pytest.fixture(scope="module")
def records():
    return _record(), _record(None), _record("flat"), _record(profile=False)


def test_a_swell_over_a_profile_matches_the_ray_shooting_quadrature(records):
    """The surface's paths (the record less the one without a surface) within 0.5 dB of the quadrature sample by
    sample wherever they are within 30 dB of their peak, but a sample at the paths' onsets and the window's end and
    the folds at facet edges (``folds``; there the energy of each fold within 0.5 dB); the one-bounce onset within one
    sample. The swell and the profile both matter: a flat surface starts 20 samples early (the sonar is under a
    crest), and straight rays under the same swell miss the reference by more than 1 dB."""
    wet, dry, flat, straight = records
    t = wet.time_s
    one, two = quadrature(t, wet.acquisition.alpha_db_per_m)
    ref, sim = one + two, wet.starboard[0] - dry.starboard[0]
    keep = (ref > 1e-3 * ref.max()) & (t < 2 * RANGE / C_SONAR - 2 * TAU)
    edges = [t[np.argmax(part > 1e-3 * part.max())] for part in (one, two)]
    for e in edges:
        keep &= (np.abs(t - e) > 2.0 / FS) & (np.abs(t - e - TAU) > 2.0 / FS)
    fold = np.zeros(t.size, bool)
    for lo, hi in folds():
        near = (t > lo - 3.0 / FS) & (t < hi + TAU + 3.0 / FS)
        fold |= near
        if near.any() and ref[near].max() > 1e-3 * ref.max() and t[near][-1] < 2 * RANGE / C_SONAR - 2 * TAU:
            assert abs(10 * np.log10(sim[near].sum() / ref[near].sum())) < 0.5, (lo, hi)
    kept = keep & ~fold
    assert kept.sum() > 0.85 * keep.sum() and kept.sum() > 2000
    err = 10 * np.log10(sim[kept] / ref[kept])
    assert np.max(np.abs(err)) < 0.5, np.max(np.abs(err))
    onset = t[np.argmax(ref > 1e-3 * ref.max())]
    assert abs(t[np.argmax(sim > 1e-3 * ref.max())] - onset) <= 1.0 / FS
    flat_sim = flat.starboard[0] - dry.starboard[0]
    assert abs(t[np.argmax(flat_sim > 1e-3 * ref.max())] - onset) > 10.0 / FS
    straight_sim = straight.starboard[0] - _record(None, profile=False).starboard[0]
    off = 10 * np.log10(np.maximum(straight_sim[kept], 1e-300) / ref[kept])
    assert np.max(np.abs(off)) > 1.0, np.max(np.abs(off))


def _linear_knots():
    return np.array([0.0, 300.0]), np.array([_speed(0.0), _speed(300.0)])


def test_up_legs_and_direct_eigenrays_against_the_circular_arcs():
    """kernels.swell_up_legs (the sonar up to the band) and kernels.direct_eigenrays (the sonar down to a point)
    against the circular arcs of the linear profile: the band point, its direction, time and path; the eigenray's ξ
    covers the distance, its time, path and tube area A = x·|∂x/∂θ|·sin θ_X / cos θ (central differences of the
    arcs); none where the ray would have to turn."""
    from sonar_embree import kernels
    z, c = _linear_knots()
    theta = np.radians([5.0, 30.0, 80.0])
    launch = np.column_stack([np.zeros(3), -np.cos(theta), np.sin(theta)])          # starboard (−y), upward
    pos = np.array([[0.0, 0.0, 10.0]])
    out = np.empty((3, 8))
    kernels.swell_up_legs(launch, np.zeros(3, np.int64), pos, z, c, 30.0, 0.4, out)
    x, t, length = _arc(np.cos(theta) / C_SONAR, DEPTH, 0.4)
    np.testing.assert_allclose(out[:, 1], -x, rtol=1e-9)
    np.testing.assert_allclose(out[:, 2], 29.6, rtol=1e-12)
    np.testing.assert_allclose(out[:, 6], t, rtol=1e-9)
    np.testing.assert_allclose(out[:, 7], length, rtol=1e-9)
    np.testing.assert_allclose(out[:, 5], np.sqrt(1 - (np.cos(theta) / C_SONAR * _speed(0.4)) ** 2), rtol=1e-12)
    th_d = np.radians([10.0, 45.0, 85.0])
    xd, td, ld = _arc(np.cos(th_d) / C_SONAR, DEPTH, DEPTH + H)
    eig = np.empty((4, 7))
    kernels.direct_eigenrays(z, c, np.full(4, DEPTH), np.full(4, DEPTH + H), np.append(xd, 1e4), eig)
    np.testing.assert_allclose(eig[:3, 0], np.cos(th_d) / C_SONAR, rtol=1e-9)
    np.testing.assert_allclose(eig[:3, 1], td, rtol=1e-9)
    np.testing.assert_allclose(eig[:3, 2], ld, rtol=1e-9)
    h = 1e-6
    dx = (_arc(np.cos(th_d + h) / C_SONAR, DEPTH, DEPTH + H)[0] - _arc(np.cos(th_d - h) / C_SONAR, DEPTH, DEPTH + H)[0])
    sin_x = np.sqrt(1 - (np.cos(th_d) / C_SONAR * _speed(DEPTH + H)) ** 2)
    np.testing.assert_allclose(eig[:3, 3], xd * np.abs(dx / (2 * h)) * sin_x / np.cos(th_d), rtol=1e-6)
    assert np.isnan(eig[3, 0])                                            # 10 km away: the ray would turn first


def test_the_bounce_mirrors_in_the_facet_and_the_tube_of_straight_rays_is_the_image_distance():
    """kernels.swell_bounce mirrors the band ray in its facet and runs it back down to the band; kernels.swell_tubes
    gives R² for straight rays off a tilted flat facet (the image source at R = |SP| + |PX|, per unit of s·β, the
    fan's solid angle)."""
    from sonar_embree import kernels
    n = np.array([0.0, -0.1, 1.0]) / np.hypot(0.1, 1.0)
    up = np.array([[0.0, -5.0, 29.0, 0.0, -0.6, 0.8, 0.01, 7.0]])
    p, ur, q2, band = np.empty((1, 3)), np.empty((1, 3)), np.empty((1, 3)), np.empty(1)
    kernels.swell_bounce(up, np.array([0], np.int32), np.array([1.5], np.float32), n[None], 29.0, p, ur, q2, band)
    u = up[0, 3:6]
    np.testing.assert_allclose(p[0], up[0, :3] + 1.5 * u)
    np.testing.assert_allclose(ur[0], u - 2 * (u @ n) * n)
    assert q2[0, 2] == 29.0 and band[0] == pytest.approx(1.5 + np.linalg.norm(q2[0] - p[0]))
    z, c = np.array([0.0, 300.0]), np.array([1500.0, 1500.0])             # uniform: straight rays
    rot = np.diag([1.0, -1.0, -1.0])[None]                                # body (fwd, stbd, down) → world, heading +x
    s, beta = 0.02, -np.radians(40.0)
    cpsi = np.sqrt(1 - s * s)
    u = rot[0] @ np.array([s, cpsi * np.cos(beta), cpsi * np.sin(beta)])
    sonar = np.array([0.0, 0.0, 10.0])
    pt = sonar + (29.5 - 10.0) / u[2] * u                                 # the facet's point, 0.5 m below depth 0
    r_up = np.linalg.norm(pt - sonar)
    uo = u - 2 * (u @ n) * n
    x = pt + uo * ((pt[2] - 0.0) / -uo[2])                                # down to the floor at local z = 0
    out = np.empty((1, 4))
    kernels.swell_tubes(np.array([[s, beta]]), np.array([1]), rot, np.array([[*sonar, 30.0]]), z, c,
                        np.array([[*pt, *n, 0.5]]), np.array([[*x, *uo, 30.0]]), out)
    r = r_up + np.linalg.norm(x - pt)
    assert out[0, 0] == pytest.approx(r * r, rel=1e-6)


def test_a_ray_started_at_its_own_origin_marches_as_a_fans_ray():
    """kernels.arc_start_at from a sonar's position along a fan ray's direction gives the state and constants of
    kernels.arc_start for that ray."""
    from sonar_embree import kernels
    layers = np.array([[-np.inf, 1490.0, 0.0], [0.0, 1490.0, 0.5], [50.0, 1515.0, 0.0]])
    rot = np.diag([1.0, -1.0, -1.0])[None]
    pos = np.array([[1.0, 2.0, 10.0]])
    s, beta = np.array([0.01]), np.array([0.3])
    el = np.array([0, 0, 1], np.int64)
    n = 1
    st, lay, ray = np.empty((n, kernels.STATE_WIDTH)), np.empty(n, np.int64), np.empty((n, kernels.RAY_WIDTH))
    kernels.arc_start(s, np.cos(beta), np.sin(beta), el, rot, pos, layers, 30.0, np.array([-1.0, 5.0]), 500.0, st,
                      lay, ray, kernels.NO_LAYOUT)
    cpsi = np.sqrt(1 - s[0] ** 2)
    u = rot[0] @ np.array([s[0], cpsi * np.cos(beta[0]), cpsi * np.sin(beta[0])])
    st2, lay2, ray2 = np.empty_like(st), np.empty_like(lay), np.empty_like(ray)
    kernels.arc_start_at(pos.copy(), u[None], layers, 30.0, np.array([-1.0, 5.0]), 500.0, st2, lay2, ray2)
    np.testing.assert_allclose(st2, st, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ray2, ray, rtol=1e-12)
    assert lay2[0] == lay[0]


@pytest.mark.parametrize("kind", ["msis", "forward-looking"])
@pytest.mark.parametrize("profile", [False, True])
def test_msis_and_the_forward_looking_sonar_take_a_swell(kind, profile):
    """The MSIS and the forward-looking sonar run the side-scan's path models (the forward-looking sonar regroups a
    swell's echoes by azimuth line before its beamformer), so a swell, straight or over a profile, changes nothing
    before the earliest one-bounce onset (2h + 2(d − H/2))/c (the sonar under a crest) and only adds energy after
    it; a box on the floor brings the rays aimed at it through the swell."""
    import trimesh

    prof = se.SoundSpeedProfile.linear(C_SONAR - GRAD * DEPTH, GRAD, depth_m=300.0, surface_z_m=H + DEPTH)
    scene = se.Scene().add(se.seafloor.flat((200.0, 200.0), center_m=(0.0, Y0)),
                           material=se.Material(backscatter_db=MU_DB), label="seafloor")
    scene.add(trimesh.creation.box((1.0, 1.0, 1.0)).apply_translation((12.0, Y0, 0.5)), label="box")
    line = se.Trajectory.line((-0.05, Y0, H), (0.05, Y0, H), 2).stop_and_hop()
    sonar = se.MSIS(max_range_m=40.0) if kind == "msis" else se.ForwardLooking(max_range_m=40.0)
    runs = [se.simulate(scene, line, se.Acquisition(sonar, se.Environment(sound_speed=prof if profile else None,
                                                                          surface=surface)),
                        start_time="2000-01-01") for surface in (None, _surface(True))]
    dry, wet = runs
    c_max = _speed(DEPTH + H) if profile else C_SONAR                  # no path is faster than the fastest water
    onset = (2 * H + 2 * (DEPTH - SWELL_H / 2)) / c_max
    before = dry.time_s < onset - 2.0 / dry.acquisition.for_pulse(dry.pulse).sample_rate_hz
    np.testing.assert_allclose(wet.data[:, :, before], dry.data[:, :, before], rtol=1e-9, atol=0)
    added = wet.data - dry.data
    assert np.all(added >= -1e-12 * dry.data.max()) and added.sum() > 1e-3 * dry.data.sum()
