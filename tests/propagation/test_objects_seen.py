"""Every object in the beam is seen (issue 34): rays aimed at the objects, not only the floor's fan.

References are written here: the echo energy of a Lambertian sphere is the quadrature over its lit surface of
Γ⁴(u)·μ·cos²θi·e^(−2αR)/R⁴ dA (docs/physics.md eq. 1 with dA = R²dΩ/cos θi), which for a sphere small against
the beam is Γ⁴·e^(−2αR)·(2πa²μ/3)/R⁴ (∫ cos²θ over a hemisphere: 2πa²/3).
"""
import numpy as np
import pytest
import trimesh

import sonar_embree as se
import analytic
from analytic import cylinder_quadrature, gamma_membrane, patch_quadrature, sidescan_gamma, sphere_quadrature
from sonar_embree import sonars
from sonar_embree.propagation.echoes import merged
from sonar_embree.propagation.prepared import prepare
from sonar_embree.raycast import RayCaster
from sonar_embree.scene import survey_origin

H = 10.0          # sonar altitude over the flat floor at z = 0, m
MU_DB = -10.0     # the sphere's Lambert strength
DX = 0.02         # ping spacing, m


def _ball_mesh(a, centre):
    ball = trimesh.creation.icosphere(subdivisions=5, radius=a)
    ball.apply_translation(centre)
    return ball


def _ball_scene(a, y, z, floor=True):
    """A Lambertian ball of radius ``a`` at (0, y, z) over a flat floor at z = 0 (or alone)."""
    scene = se.Scene()
    if floor:
        scene.add(se.seafloor.flat((120, 120)), label="seafloor")
    return scene.add(_ball_mesh(a, (0.0, y, z)), label="ball", material=se.Material(backscatter_db=MU_DB))


def _pings_over(y, n_nulls=1.2):
    """Pings every 2 cm along x over the along-track span where the ball at |y| can be in the main lobe."""
    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    half = n_nulls * se.Acquisition.of(sonar).wavelength_m / sonar.length_m * np.hypot(y, H) + 0.02
    n = 2 * int(half / DX) + 1
    return se.Trajectory.line((-DX * (n // 2), 0, H), (DX * (n // 2), 0, H), n)


def ball_energy(scene, traj, sonar=None, quality=1.0, rx_shift=None, aim=True, label="ball"):
    """(pings,) Σ weight of the echoes on the object labelled ``label``, both channels (the front end's own
    echoes)."""
    sonar = se.Acquisition.of(sonar or se.Sonar()).for_pulse(se.Pulse.cw())
    front = sonars.front_end(sonar, se.FanSettings(quality=quality, aim_objects=aim))
    comp = scene.compiled(survey_origin(traj.positions_m))
    run = prepare(RayCaster(comp), front, sonar.frequency_hz, sonar.max_range_m, 0)
    n = len(traj)
    rots = front.mount(traj.rotations(), np.arange(n)) if hasattr(front, "mount") else traj.rotations()
    shift = np.zeros(n) if rx_shift is None else rx_shift
    out = np.zeros(n)
    for a in range(0, n, 8):  # blocks of 8 pings, as simulate casts them (memory)
        b = min(a + 8, n)
        e, _ = front.cast(run, rots[a:b], traj.positions_m[a:b] - comp.origin_m, sonar.max_range_m, False, True,
                          {}, rx_shift=shift[a:b])
        e = merged(e)
        row = np.repeat(np.arange(e.ray_start.size - 1), np.diff(e.ray_start))
        w = np.where(e.object_id == comp.labels.index(label), e.weight, 0.0)
        out[a:b] = np.bincount(row // e.n_channels, weights=w, minlength=b - a)
    return out


CASES = [  # radius (m), abeam (m, starboard is −y for a line along +x), height of the centre (m)
    (0.02, -45.0, 5.0), (0.05, -38.0, 5.0), (0.25, -10.0, 5.0),
    (0.02, -10.0, 0.02), (0.05, -25.0, 0.05), (0.25, -45.0, 0.25),
]


@pytest.mark.parametrize("a, y, z", CASES)
def test_sphere_echo_follows_the_two_way_pattern_in_every_ping(a, y, z):
    """Spheres of 2, 5 and 25 cm, in midwater (5 m over the floor) and resting on it, 10–45 m abeam, pings every
    2 cm, quality 1: the echo energy per ping is the quadrature of Γ⁴·σ over the sphere within 1 dB wherever that
    is within −20 dB of its peak, in every such ping (none dark)."""
    traj = _pings_over(y)
    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    got = ball_energy(_ball_scene(a, y, z), traj)
    ref = sphere_quadrature(a, (0.0, y, z), traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, MU_DB)
    inside = ref >= 0.01 * ref.max()
    assert inside.sum() >= 15
    err = 10 * np.log10(np.maximum(got[inside], 1e-300) / ref[inside])
    assert np.abs(err).max() < 1.0, (err.min(), err.max())


def test_a_small_sphere_has_the_lambert_sphere_level():
    """Abeam, a 5 cm ball far inside the beam: E = Γ⁴·e^(−2αR)·(2πa²μ/3)/R⁴ within 1 dB (the closed form, Γ at its
    centre)."""
    a, y, z = 0.05, -38.0, 5.0
    traj = se.Trajectory.line((0, 0, H), (0.02, 0, H), 2)
    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    got = ball_energy(_ball_scene(a, y, z), traj)[0]
    v = np.array([0.0, y, z - H])
    R = np.linalg.norm(v)
    u = v / R
    g = gamma_membrane(u[0], abs(u[1]), -u[2])
    acq = se.Acquisition.of(sonar)
    ref = g ** 4 * 10 ** (-2 * acq.alpha_db_per_m * R / 10) * (2 * np.pi * a * a * 10 ** (MU_DB / 10) / 3) / R ** 4
    assert abs(10 * np.log10(got / ref)) < 1.0


def test_a_ball_at_shallow_depression_is_seen_in_every_ping():
    """The issue's case: a 10 cm ball 25 m out at 5° depression, seen by 3 of 25 pings before, at quality 1 and 4."""
    y = -25.0
    z = H - 25.0 * np.tan(np.radians(5.0))
    traj = _pings_over(y)
    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    ref = sphere_quadrature(0.1, (0.0, y, z), traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, MU_DB)
    inside = ref >= 0.01 * ref.max()
    for q in (1.0, 4.0):
        got = ball_energy(_ball_scene(0.1, y, z), traj, quality=q)
        err = 10 * np.log10(np.maximum(got[inside], 1e-300) / ref[inside])
        assert np.abs(err).max() < 1.0, (q, err.min(), err.max())


def _msis_gamma(sonar, n):
    """Γ(u, ping) of an MSIS's membrane at its first ``n`` bearings, from its −3 dB widths (sin x/x = 1/√2 solved
    here). Head frame: x along the bearing ψ (clockwise from north, heading 0), y to its right, z down;
    Γ = sinc(k·lx/2·u_y)·sinc(k·ly/2·(−u_x sin δ + u_z cos δ)) on u_x cos δ + u_z sin δ > 0."""
    from scipy.optimize import brentq

    bearings = np.radians(sonar.bearings_deg(np.arange(n)))
    d = np.radians(sonar.tilt_deg)
    acq = se.Acquisition.of(sonar)
    lam, k = acq.wavelength_m, acq.wavenumber_rad_m
    x0 = brentq(lambda x: np.sin(x) / x - 2 ** -0.5, 1e-9, np.pi)
    lx, ly = (x0 * lam / (np.pi * np.sin(np.radians(w) / 2))
              for w in (sonar.horizontal_beamwidth_deg, sonar.vertical_beamwidth_deg))

    def gamma(u, ping):
        b = bearings[ping]
        ux = u[:, 0] * np.sin(b) + u[:, 1] * np.cos(b)
        uy = u[:, 0] * np.cos(b) - u[:, 1] * np.sin(b)
        uz = -u[:, 2]
        g = np.sinc(k * lx / 2 * uy / np.pi) * np.sinc(k * ly / 2 * (-ux * np.sin(d) + uz * np.cos(d)) / np.pi)
        return np.where(ux * np.cos(d) + uz * np.sin(d) > 0, g, 0.0)

    return gamma


def test_msis_sees_a_small_sphere_at_every_bearing_step():
    """MSIS (1.8° beam), a 5 cm ball 12 m out on the beam's axis, the head stepping 0.2°: the echo energy per step
    is the quadrature with the MSIS's beam within 1 dB at every step where it is within −20 dB of its peak.
    Head frame: x along the bearing ψ (clockwise from north, heading 0), y to its right, z down;
    Γ = sinc(k·lx/2·u_y)·sinc(k·ly/2·(−u_x sin δ + u_z cos δ)) on u_x cos δ + u_z sin δ > 0."""
    sonar = se.MSIS(step_deg=0.2, start_bearing_deg=26.0)
    n = 41
    psi0, rho, d = np.radians(30.0), 12.0, np.radians(sonar.tilt_deg)
    centre = (rho * np.sin(psi0), rho * np.cos(psi0), H - rho * np.tan(d))
    gamma = _msis_gamma(sonar, n)
    traj = se.Trajectory(np.tile([[0.0, 0.0, H]], (n, 1)), heading_deg=0.0, times_s=np.arange(n, dtype=float))
    scene = se.Scene().add(se.seafloor.flat((120, 120)), label="seafloor")
    scene.add(_ball_mesh(0.05, centre), label="ball", material=se.Material(backscatter_db=MU_DB))
    got = ball_energy(scene, traj, sonar)
    ref = sphere_quadrature(0.05, centre, traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, MU_DB, gamma=gamma)
    inside = ref >= 0.01 * ref.max()
    assert inside.sum() >= 10
    err = 10 * np.log10(np.maximum(got[inside], 1e-300) / ref[inside])
    assert np.abs(err).max() < 1.0, (err.min(), err.max())


def test_motion_shifts_a_small_objects_echo_by_v_tau_over_2():
    """At 10 m/s with motion during the ping (receive beam shifted by δ = 2v/c), the along-track centroid of a
    small ball's echo energy moves by −v·τ/2 (τ = 2R/c: the echo peaks when the ball lies halfway between the
    transmit and the receive positions) within 1 %: the aimed rays span the receive lobe as well as the transmit
    lobe, so the two-way pattern is not cut on one side."""
    a, y, z, v, c = 0.05, -38.0, 5.0, 10.0, 1500.0
    traj = _pings_over(y, n_nulls=2.5)
    scene = _ball_scene(a, y, z, floor=False)
    x = traj.positions_m[:, 0]
    still = ball_energy(scene, traj)
    moving = ball_energy(scene, traj, rx_shift=np.full(len(traj), 2 * v / c))
    shift = (moving @ x) / moving.sum() - (still @ x) / still.sum()
    tau = 2 * np.hypot(y, z - H) / c
    assert shift == pytest.approx(-v * tau / 2, rel=0.01)


def test_a_small_objects_labels_and_coco_box_cover_every_ping_of_its_echo(tmp_path):
    """A 10 cm ball 38 m out, 5 m over the floor, pings every 2 cm: its COCO annotation (pycocotools) is one piece
    covering every ping whose echo energy (the quadrature) is within −7 dB of its peak (−10 dB with a margin for
    the sample peak against the energy); before, its echo flickered in and out."""
    from pycocotools import mask as mask_util
    import json

    a, y, z = 0.1, -38.0, 5.0
    traj = _pings_over(y)
    sonar = se.Sonar(max_range_m=45.0)
    rec = se.simulate(_ball_scene(a, y, z), traj, sonar, labels=True)
    ref = sphere_quadrature(a, (0.0, y, z), traj.positions_m, rec.acquisition.alpha_db_per_m, MU_DB)
    rec.to_coco(tmp_path / "c.json")
    coco = json.loads((tmp_path / "c.json").read_text())
    balls = [an for an in coco["annotations"] if an["category_id"] == next(
        cat["id"] for cat in coco["categories"] if cat["name"] == "ball")]
    assert len(balls) == 1
    rows = np.flatnonzero(mask_util.decode(balls[0]["segmentation"]).any(axis=1))
    want = np.flatnonzero(ref >= 10 ** -0.7 * ref.max())
    assert want.size >= 10 and set(want) <= set(rows)
    assert np.all(np.diff(rows) == 1)


def test_aimed_rays_are_deterministic_across_blocks_and_cost_nothing_without_objects():
    """Same bits in one call and in two pieces (other blocks; ping_offset keys the speckle); a floor alone gives the
    same bits with and without aiming (nothing to aim at); ``aim_objects`` must be a bool."""
    scene = _ball_scene(0.05, -20.0, 2.0)
    traj = _pings_over(-20.0)
    kw = dict(speckle=True, seed=4)
    whole = se.simulate(scene, traj, **kw)
    half = len(traj) // 2
    parts = [se.simulate(scene, traj[:half], **kw), se.simulate(scene, traj[half:], ping_offset=half, **kw)]
    np.testing.assert_array_equal(whole.data, np.concatenate([p.data for p in parts]))
    assert whole.attrs["rays_per_ping"] > se.simulate(scene, traj, fan=se.FanSettings(aim_objects=False),
                                                      **kw).attrs["rays_per_ping"]
    floor = se.Scene().add(se.seafloor.flat((120, 120)), label="seafloor")
    np.testing.assert_array_equal(se.simulate(floor, traj[:4], **kw).data,
                                  se.simulate(floor, traj[:4], fan=se.FanSettings(aim_objects=False), **kw).data)
    with pytest.raises(se.ConfigError, match="aim_objects"):
        se.FanSettings(aim_objects="yes")


@pytest.mark.parametrize("edge, y, z", [(2.0, -20.0, 5.0), (0.5, -35.0, 3.0), (0.3, -15.0, 8.0)])
def test_a_midwater_box_in_a_profile_starts_at_its_closed_form_arrival(edge, y, z):
    """A box alone in a linear profile c = c_S + g·(z_S − z) (no floor in range), quality 1: the first sample above
    1 % of the echo's peak is within one sample of the first arrival 2·min T over the box's surface, with the
    exact travel time of a linear gradient T = acosh(1 + g²·|P − S|²/(2·c(P)·c(S)))/g."""
    c_s, g, fs, depth = 1500.0, 0.5, 50e3, 20.0
    profile = se.SoundSpeedProfile.linear(c_s - g * depth, g, depth_m=300.0, surface_z_m=H + depth)
    sonar = se.Acquisition(se.Sonar(tilt_deg=10.0, max_range_m=40.0, sample_rate_hz=fs),
                           se.Environment(sound_speed=profile))
    box = trimesh.creation.box(extents=(edge, edge, edge))
    box.apply_translation((0.0, y, z))
    line = se.Trajectory.line((-0.05, 0.0, H), (0.05, 0.0, H), 2).stop_and_hop()
    rec = se.simulate(se.Scene().add(box, label="box"), line, sonar, se.Pulse.cw(duration_s=100e-6, taper=0.0))
    trace = rec.starboard[0]
    onset = np.flatnonzero(trace > 1e-2 * trace.max())[0]
    u = np.linspace(-1.0, 1.0, 401)
    a, b = (x.ravel() for x in np.meshgrid(u, u))
    pts = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.zeros((a.size, 3))
            p[:, axis], p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = sign, a, b
            pts.append(p)
    P = np.concatenate(pts) * edge / 2 + [0.0, y, z]
    d2 = ((P - [0.0, 0.0, H]) ** 2).sum(axis=1)
    T = np.arccosh(1 + g * g * d2 / (2 * (c_s + g * (H - P[:, 2])) * c_s)) / g
    assert abs(onset - 2 * T.min() * fs) <= 1.0


def _fls_gamma(sonar, k_beam, heading_deg):
    """gamma(u, ping) whose fourth power is one FLS beam's two-way gain Γ_el⁴·AF_k²: the element, a d × h baffled
    membrane facing forward tilted down by δ (h from the vertical −3 dB width), transmits and receives; the
    array factor of M elements d apart, steered to θ_k, forms the receive beam (docs/physics.md §11). Vehicle
    frame per ping: forward (sin ψ, cos ψ, 0), starboard (cos ψ, −sin ψ, 0), down (0, 0, −1)."""
    from scipy.optimize import brentq

    acq = se.Acquisition.of(sonar)
    lam, k, d, m = acq.wavelength_m, acq.wavenumber_rad_m, sonar.spacing_in(acq.sound_speed_m_s), sonar.n_elements
    x0 = brentq(lambda x: np.sin(x) / x - 2 ** -0.5, 1e-9, np.pi)
    h = x0 * lam / (np.pi * np.sin(np.radians(sonar.vertical_beamwidth_deg) / 2))
    tilt, psi = np.radians(sonar.tilt_deg), np.radians(np.atleast_1d(heading_deg))
    u_k = np.sin(np.radians(sonar.beam_angles_deg()[k_beam]))

    def gamma(u, ping):
        p = psi[min(ping, psi.size - 1)]
        fwd = u[:, 0] * np.sin(p) + u[:, 1] * np.cos(p)
        stb = u[:, 0] * np.cos(p) - u[:, 1] * np.sin(p)
        down = -u[:, 2]
        el = np.sinc(k * d / 2 * stb / np.pi) * np.sinc(k * h / 2 * (-fwd * np.sin(tilt) + down * np.cos(tilt)) / np.pi)
        el = np.where(fwd * np.cos(tilt) + down * np.sin(tilt) > 0, el, 0.0)
        x = k * d * (stb - u_k) / 2
        af = np.where(np.abs(np.sin(x)) < 1e-12, 1.0, np.sin(m * x) / (m * np.sin(np.where(np.sin(x) == 0, 1, x))))
        return el * np.sqrt(np.abs(af))

    return gamma


def fls_beam_energy(scene, traj, sonar, label):
    """(pings, beams) energy of object ``label``'s echoes in each beam: Σ over azimuth lines of AF_k²·(the line's
    echo weights), as the speckle-free beamformer forms it from the lines' intensities."""
    front = sonars.front_end(se.Acquisition.of(sonar), se.FanSettings())
    comp = scene.compiled(survey_origin(traj.positions_m))
    run = prepare(RayCaster(comp), front, sonar.frequency_hz, sonar.max_range_m, 0)
    n = len(traj)
    rots = front.mount(traj.rotations(), np.arange(n))
    e, _ = front.cast(run, rots, traj.positions_m - comp.origin_m, sonar.max_range_m, False, True, {},
                      rx_shift=np.zeros(n))
    e = merged(e)
    row = np.repeat(np.arange(e.ray_start.size - 1), np.diff(e.ray_start))
    w = np.where(e.object_id == comp.labels.index(label), e.weight, 0.0)
    lines = np.bincount(row, weights=w, minlength=n * e.n_channels).reshape(n, e.n_channels)
    return lines @ front.beam_power.T


def test_fls_spheres_peak_in_their_nearest_beam_at_the_closed_form_level():
    """Forward-looking (128 elements at λ/2, 256 beams over 130°): balls of 3–5 cm at 15 bearings across the field
    of view (θ: the array's bearing, sin θ = u along the array), 12–26 m out on the fan's axis, each peak in the
    beam nearest its bearing, at the quadrature's level within 1 dB (before: 8 of 15 returned nothing)."""
    sonar = se.ForwardLooking(max_range_m=30.0).for_pulse(se.Pulse.cw())
    bearings = np.linspace(-58.0, 58.0, 15) + 0.13
    ranges = np.linspace(12.0, 26.0, 15)
    radii = np.linspace(0.03, 0.05, 15)
    tilt = np.radians(sonar.tilt_deg)
    scene = se.Scene()
    centres = []
    for i, (b, r, a) in enumerate(zip(np.radians(bearings), ranges, radii)):
        b = np.arcsin(np.sin(b) / np.cos(tilt))   # on the fan's axis: the array sees u = cos δ·sin(azimuth) = sin θ
        c = (r * np.cos(tilt) * np.sin(b), r * np.cos(tilt) * np.cos(b), H - r * np.sin(tilt))
        centres.append(c)
        scene.add(_ball_mesh(a, c), label=f"ball{i}", material=se.Material(backscatter_db=MU_DB))
    traj = se.Trajectory(np.array([[0.0, 0.0, H]]), heading_deg=0.0, times_s=np.zeros(1))
    angles = sonar.beam_angles_deg()
    for i, (b, a, c) in enumerate(zip(bearings, radii, centres)):
        energy = fls_beam_energy(scene, traj, sonar, f"ball{i}")[0]
        k = int(np.argmax(energy))
        assert k == int(np.argmin(np.abs(angles - b))), (b, angles[k])
        ref = sphere_quadrature(a, c, traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, MU_DB, n=120,
                                gamma=_fls_gamma(sonar, k, 0.0))[0]
        assert abs(10 * np.log10(energy[k] / ref)) < 1.0, (b, 10 * np.log10(energy[k] / ref))


def test_fls_sphere_swept_across_a_beam_traces_the_array_factor():
    """A 3 cm ball 15 m ahead swept across beam 128 in 0.05° steps (the vehicle turning): that beam's energy
    follows the quadrature within 1 dB wherever it is within −10 dB of its peak, no bearing inside the main lobe
    is dark, and the −3 dB width is the quadrature's within 5 % (before: dark every 0.224°, the line spacing)."""
    sonar = se.ForwardLooking(max_range_m=20.0).for_pulse(se.Pulse.cw())
    k0, r, a = 128, 15.0, 0.03
    theta0 = sonar.beam_angles_deg()[k0]
    tilt = np.radians(sonar.tilt_deg)
    c = (0.0, r * np.cos(tilt), H - r * np.sin(tilt))
    scene = se.Scene().add(_ball_mesh(a, c), label="ball", material=se.Material(backscatter_db=MU_DB))
    headings = -theta0 + np.arange(-1.2, 1.2001, 0.05)        # the ball's bearing is θ0 − (heading + θ0)
    traj = se.Trajectory(np.tile([[0.0, 0.0, H]], (headings.size, 1)), heading_deg=headings,
                         times_s=np.arange(headings.size, dtype=float))
    got = fls_beam_energy(scene, traj, sonar, "ball")[:, k0]
    ref = sphere_quadrature(a, c, traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, MU_DB, n=120,
                            gamma=_fls_gamma(sonar, k0, headings))
    main = ref >= 0.1 * ref.max()
    assert main.sum() >= 8 and np.all(got[main] > 0)
    err = 10 * np.log10(got[main] / ref[main])
    assert np.abs(err).max() < 1.0, (err.min(), err.max())

    def width(y):
        x = np.arange(y.size) * 0.05
        above = np.flatnonzero(y >= 0.5 * y.max())
        lo, hi = above[0], above[-1]
        f_lo = np.interp(0.5 * y.max(), [y[lo - 1], y[lo]], [x[lo - 1], x[lo]])
        f_hi = np.interp(0.5 * y.max(), [y[hi + 1], y[hi]], [x[hi + 1], x[hi]])
        return f_hi - f_lo

    assert width(got) == pytest.approx(width(ref), rel=0.05)


def test_echo_sounder_sees_a_small_ball_in_every_ping():
    """A single-beam echo sounder (200 kHz, 10° circular piston) passing over a 5 cm ball 8 m below, pings every
    5 cm: the echo energy per ping is the quadrature with b(θ) = 2·J1(ka·sin θ)/(ka·sin θ) (Kinsler et al. §8.8,
    ka·sin(θ3/2) = 1.6163, θ from straight down) within 1 dB wherever it is within −20 dB of its peak."""
    from scipy.special import j1

    sonar = se.EchoSounder().for_pulse(se.Pulse.cw())
    ka = 1.6163 / np.sin(np.radians(sonar.beamwidth_deg) / 2)
    a, centre = 0.05, (0.0, 0.3, 2.0)
    x = np.arange(-1.5, 1.5001, 0.05)
    traj = se.Trajectory(np.column_stack([x, np.zeros_like(x), np.full_like(x, H)]), heading_deg=90.0,
                         times_s=np.arange(x.size, dtype=float))

    def gamma(u, ping):
        arg = ka * np.sqrt(np.maximum(1 - u[:, 2] ** 2, 0.0))
        b = np.where(arg < 1e-8, 1.0, 2 * j1(arg) / np.where(arg < 1e-8, 1.0, arg))
        return np.where(u[:, 2] < 0, b, 0.0)

    scene = se.Scene().add(se.seafloor.flat((60, 60)), label="seafloor")
    scene.add(_ball_mesh(a, centre), label="ball", material=se.Material(backscatter_db=MU_DB))
    got = ball_energy(scene, traj, sonar)
    ref = sphere_quadrature(a, centre, traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, MU_DB, n=120,
                            gamma=gamma)
    inside = ref >= 0.01 * ref.max()
    assert inside.sum() >= 20
    err = 10 * np.log10(np.maximum(got[inside], 1e-300) / ref[inside])
    assert np.abs(err).max() < 1.0, (err.min(), err.max())


def _path_energy(scene, traj, sonar):
    """(pings, 3) Σ weight of the ball's echoes per path (direct, one bounce, two bounces)."""
    front = sonars.front_end(se.Acquisition.of(sonar), se.FanSettings())
    comp = scene.compiled(survey_origin(traj.positions_m))
    run = prepare(RayCaster(comp), front, sonar.frequency_hz, sonar.max_range_m, 0)
    n = len(traj)
    out = np.zeros((n, 3))
    for a in range(0, n, 8):
        b = min(a + 8, n)
        e, _ = front.cast(run, traj.rotations()[a:b], traj.positions_m[a:b] - comp.origin_m, sonar.max_range_m,
                          False, True, {}, rx_shift=np.zeros(b - a))
        e = merged(e)
        ping = np.repeat(np.arange(e.ray_start.size - 1), np.diff(e.ray_start)) // e.n_channels
        own = e.object_id == comp.labels.index("ball")
        for p in range(3):
            out[a:b, p] = np.bincount(ping, weights=np.where(own & (e.path == p), e.weight, 0.0), minlength=b - a)
    return out


def test_surface_paths_of_a_small_ball_follow_the_image_method():
    """Under a flat, mirror-like sea surface 5 m above the sonar, a 5 cm ball 30 m out: per ping, its one-bounce
    energy is the bistatic quadrature 2·∫ Γ²(u1)·Γ²(u2)·μ·cos θi·cos θs·e^(−α(r + r'))/(r²·r'²) dA over the points
    facing both S and its image S' (u1 from S to X, u2 from S to the surface point, the mirror of S'→X), and its
    two-bounce energy the monostatic quadrature seen from S' (the mirrored beam), both within 1 dB wherever within
    −20 dB of their peaks, in every ping (docs/physics.md §13 with §7b)."""
    z_s, a, centre = H + 5.0, 0.05, (0.0, -30.0, 4.0)
    sonar = se.Acquisition(se.Sonar(max_range_m=45.0), se.Environment(surface=se.SeaSurface(z_m=z_s))).for_pulse(
        se.Pulse.cw())
    traj = _pings_over(centre[1])
    scene = _ball_scene(a, centre[1], centre[2], floor=False)
    got = _path_energy(scene, traj, sonar)
    alpha = se.Acquisition.of(sonar).alpha_db_per_m
    image = traj.positions_m * [1, 1, -1] + [0, 0, 2 * z_s]

    def mirrored_gamma(u, ping):                     # the image's beam: the sonar's, mirrored in the surface
        return analytic.sidescan_gamma(u * [1, 1, -1], ping)

    two = analytic.sphere_quadrature(a, centre, image, alpha, MU_DB, n=160, gamma=mirrored_gamma)
    n = 160
    th, ph = (np.arange(n) + 0.5) * np.pi / n, (np.arange(2 * n) + 0.5) * np.pi / n
    T, P = np.meshgrid(th, ph, indexing="ij")
    nrm = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    dA = (a * a * np.sin(T) * (np.pi / n) ** 2).ravel()
    X = np.asarray(centre) + a * nrm
    one = []
    for s, s_img in zip(traj.positions_m, image):
        r1, r2 = np.linalg.norm(X - s, axis=1), np.linalg.norm(X - s_img, axis=1)
        u1, v = (X - s) / r1[:, None], (s_img - X) / r2[:, None]
        u2 = -v * [1, 1, -1]                         # S → P: the mirror of S' → X
        ci, cs = -(u1 * nrm).sum(axis=1), (v * nrm).sum(axis=1)
        g1, g2 = analytic.sidescan_gamma(u1, 0), analytic.sidescan_gamma(u2, 0)
        f = (2 * g1 ** 2 * g2 ** 2 * 10 ** (MU_DB / 10) * ci * cs * 10 ** (-alpha * (r1 + r2) / 10)
             / (r1 * r2) ** 2 * dA)
        one.append(f[(ci > 0) & (cs > 0)].sum())
    for k, ref in ((1, np.array(one)), (2, two)):
        inside = ref >= 0.01 * ref.max()
        assert inside.sum() >= 15
        err = 10 * np.log10(np.maximum(got[inside, k], 1e-300) / ref[inside])
        assert np.abs(err).max() < 1.0, (k, err.min(), err.max())


def test_a_small_ball_in_a_sound_speed_profile_is_seen_in_every_ping():
    """Curved rays (linear profile, 0.5 s⁻¹): a 5 cm ball 30 m out, 4 m over the floor, pings every 2 cm. Rays
    stay in their vertical plane and bend by at most κ·L/2 = 0.3° (κ = |g|/c) over 30 m, below the vertical beam's
    scale and across the narrow along-track beam, and the spreading changes by (κ·L)² ~ 10⁻⁴: the energy per ping
    is the straight-ray quadrature within 1 dB wherever within −20 dB of its peak, in every ping (the aimed
    curved rays; before, dark in most)."""
    g, depth = 0.5, 20.0
    profile = se.SoundSpeedProfile.linear(1500.0 - g * depth, g, depth_m=300.0, surface_z_m=H + depth)
    sonar = se.Acquisition(se.Sonar(), se.Environment(sound_speed=profile)).for_pulse(se.Pulse.cw())
    a, y, z = 0.05, -30.0, 4.0
    traj = _pings_over(y)
    got = ball_energy(_ball_scene(a, y, z), traj, sonar)
    ref = sphere_quadrature(a, (0.0, y, z), traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, MU_DB)
    inside = ref >= 0.01 * ref.max()
    assert inside.sum() >= 15
    err = 10 * np.log10(np.maximum(got[inside], 1e-300) / ref[inside])
    assert np.abs(err).max() < 1.0, (err.min(), err.max())



def _floor_hits(rx_shift, pings=None):
    """(along-track direction cosine s, weight, ping) of every echo over a flat floor, and the block, of the pings
    ``pings`` (default all) of a 4-ping line cast as one block, moving with receive shift ``rx_shift`` (one per
    ping of the line)."""
    sonar = se.Sonar().for_pulse(se.Pulse.cw())
    front = sonars.front_end(se.Acquisition.of(sonar), se.FanSettings())
    scene = se.Scene().add(se.seafloor.flat((200, 200)), label="seafloor")
    traj = se.Trajectory.line((-0.1, 0, H), (0.1, 0, H), 4)
    pings = np.arange(4) if pings is None else np.asarray(pings)
    comp = scene.compiled(survey_origin(traj.positions_m))
    run, rot = prepare(RayCaster(comp), front, sonar.frequency_hz, sonar.max_range_m, 0), traj.rotations()[pings]
    pos = traj.positions_m[pings] - comp.origin_m
    shift = np.asarray(rx_shift, dtype=float)[pings]
    _, blk = front.cast(run, rot, pos, sonar.max_range_m, True, False, {}, rx_shift=shift)
    ping = np.repeat(np.arange(2 * len(pings)) // 2, np.diff(blk.ray_start))
    lit = blk.weight > 0
    u = (blk.point_m[lit] - pos[ping[lit]]) / blk.range_m[lit, None]
    return np.einsum("ni,ni->n", u, rot[ping[lit], :, 0]), blk.weight[lit], ping[lit], blk


def test_the_fan_spans_the_receive_lobe_under_motion():
    """At 10 m/s (δ = 2v/c, two thirds of the default membrane's first null) the receive beam is turned by δ, and the
    fan spans the transmit and the receive main lobes: over a flat floor the weight-mean along-track direction
    cosine of the echoes is δ/2 within 1 % (Γ²(s)·Γ²(s − δ) is symmetric about δ/2), and the weight relative to
    stop-and-hop is ∫Γ²(s)Γ²(s − δ)ds / ∫Γ⁴ds (quadrature) within 0.3 %. A fan cut at the transmit lobe gave the
    mean 3 % short and the weight 0.9 % low."""
    sonar = se.Sonar()
    delta = 2 * 10.0 / 1500.0
    s_m, w_m, _, _ = _floor_hits(np.full(4, delta))
    s_0, w_0, _, _ = _floor_hits(np.zeros(4))
    assert (s_m @ w_m) / w_m.sum() == pytest.approx(delta / 2, rel=0.01)
    s = np.linspace(-1.0, 1.0, 2_000_001)
    acq = se.Acquisition.of(sonar)
    g2 = np.sinc(sonar.length_m / acq.wavelength_m * s) ** 2        # one-way power pattern Γ² along track
    g2_rx = np.sinc(sonar.length_m / se.Acquisition.of(sonar).wavelength_m * (s - delta)) ** 2
    assert w_m.sum() / w_0.sum() == pytest.approx((g2 @ g2_rx) / (g2 @ g2), rel=0.003)


def test_the_lines_each_ping_counts_do_not_depend_on_its_block():
    """Pings of different speeds (δ of both signs) in one block: each counts only its own lines (the lines added
    for the others are dropped as misses), so its echoes and its ray count are those it gets cast alone, to the
    bit."""
    shifts = np.array([0.0, 0.004, -0.009, 0.013])
    _, w_all, ping_all, blk = _floor_hits(shifts)
    assert blk.plan.s.size > sonars.front_end(se.Acquisition(se.Sonar()).for_pulse(se.Pulse.cw()),
                                              se.FanSettings()).plan.s.size
    for p in range(4):
        _, w_1, _, one = _floor_hits(shifts, [p])
        np.testing.assert_array_equal(np.sort(w_all[ping_all == p]), np.sort(w_1))
        assert blk.n_rays[p] == one.n_rays[0]


@pytest.mark.parametrize("env", ["direct", "flat surface", "swell", "profile", "msis"])
def test_a_line_of_changing_speed_has_the_same_bits_in_any_blocks(env):
    """Speed changing from ping to ping (δ of both signs, up to 10 m/s), moving during the ping: one call and the
    same line in two pieces give the same record and labels to the bit, on every path (the fan's lines under
    motion are each ping's own)."""
    environment = {"flat surface": se.Environment(surface=se.SeaSurface(z_m=14.0)),
                   "swell": se.Environment(surface=se.SeaSurface(z_m=14.0, swell_height_m=0.3, swell_length_m=10.0)),
                   "profile": se.Environment(sound_speed=se.SoundSpeedProfile([0.0, 30.0], [1480.0, 1500.0], surface_z_m=14.0))
                   }.get(env, se.Environment())
    scene = _ball_scene(0.1, -8.0, 1.0)
    n = 6
    x = np.linspace(0.0, 0.3, n)
    v = np.zeros((n, 3))
    v[:, 0] = [0.0, 3.0, -4.0, 10.0, 6.0, -10.0]
    traj = se.Trajectory(np.stack([x, np.zeros(n), np.full(n, H)], axis=1), heading_deg=np.full(n, 90.0),
                         velocity_m_s=v)
    sonar = (se.Acquisition(se.MSIS(max_range_m=15.0), environment) if env == "msis"
             else se.Acquisition(se.Sonar(max_range_m=15.0), environment))
    kw = dict(labels=env != "profile", speckle=False)          # no labels with curved rays (refused)
    whole = se.simulate(scene, traj, sonar, **kw)
    parts = [se.simulate(scene, traj[:3], sonar, **kw), se.simulate(scene, traj[3:], sonar, ping_offset=3, **kw)]
    np.testing.assert_array_equal(whole.data, np.concatenate([p.data for p in parts], axis=0))
    for k in ("kind", "object_id", "height_m") if kw["labels"] else ():
        np.testing.assert_array_equal(getattr(whole.labels, k),
                                      np.concatenate([getattr(p.labels, k) for p in parts], axis=1))


def _swell_strip_paths(a, centre, positions, alpha, z_s, height, length, n=120):
    """(pings, 2) the one- and two-bounce energy of a Lambertian ball via a long-crested swell whose crests run along
    x, by quadrature: the swell is the mesh's profile z(y) = z_s + H/2·sin(2πy/Λ), linear between nodes Λ/24 apart;
    each strip i is a plane mirror (normal n_i, M_i = I − 2·n_i·n_iᵀ, S'_i the sonar's image), and a surface point X
    of the ball counts for strip i where the segment S'_i → X crosses the plane within the strip. Per strip, as the
    flat image method: two bounces ∫Γ⁴(M_i·u')·μ·cos²θ'·10^(−2αr'/10)/r'⁴ dA seen from S'_i (u' = (X − S'_i)/r'),
    one bounce 2∫Γ²(u1)·Γ²(M_i·u')·μ·cos θi·cos θs·10^(−α(r1 + r')/10)/(r1²·r'²) dA."""
    step = length / 24.0
    th, ph = (np.arange(n) + 0.5) * np.pi / n, (np.arange(2 * n) + 0.5) * np.pi / n
    T, P = np.meshgrid(th, ph, indexing="ij")
    nrm = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    dA = (a * a * np.sin(T) * (np.pi / n) ** 2).ravel()
    X = np.asarray(centre) + a * nrm
    mu = 10 ** (MU_DB / 10)
    out = np.zeros((len(positions), 2))
    for i in range(int(np.floor((centre[1] - 10.0) / step)), int(np.ceil(10.0 / step))):   # the sonar is at y = 0
        y0, y1 = i * step, (i + 1) * step
        z0, z1 = (z_s + 0.5 * height * np.sin(2 * np.pi * y / length) for y in (y0, y1))
        nv = np.array([0.0, -(z1 - z0), step]) / np.hypot(step, z1 - z0)
        M = np.eye(3) - 2 * np.outer(nv, nv)
        p0 = np.array([0.0, y0, z0])
        c_img = np.asarray(centre) - 2 * ((np.asarray(centre) - p0) @ nv) * nv
        for k, s in enumerate(positions):
            q = s + (c_img - s) * ((p0 - s) @ nv) / ((c_img - s) @ nv)           # the centre's ray on the plane
            if not y0 - 1.0 < q[1] < y1 + 1.0:                                # far from this strip: no glint
                continue
            ds = (s - p0) @ nv
            if ds >= 0:
                continue
            s_img = s - 2 * ds * nv
            v = X - s_img
            r2 = np.linalg.norm(v, axis=1)
            dx = (X - p0) @ nv
            t = -(s_img - p0) @ nv / (v @ nv)                # S'_i + t·v on the plane
            yq = s_img[1] + t * v[:, 1]
            through = (dx < 0) & (t > 0) & (t < 1) & (yq >= y0) & (yq < y1)
            if not through.any():
                continue
            u2 = (v / r2[:, None]) @ M.T                      # the real launch direction from S
            cos_img = -np.sum(v / r2[:, None] * nrm, axis=1)   # facing S'_i
            g2 = analytic.sidescan_gamma(u2, 0)
            two = g2 ** 4 * mu * cos_img ** 2 * 10 ** (-2 * alpha * r2 / 10) / r2 ** 4 * dA
            out[k, 1] += two[through & (cos_img > 0)].sum()
            r1 = np.linalg.norm(X - s, axis=1)
            u1 = (X - s) / r1[:, None]
            ci = -np.sum(u1 * nrm, axis=1)
            g1 = analytic.sidescan_gamma(u1, 0)
            one = 2 * g1 ** 2 * g2 ** 2 * mu * ci * cos_img * 10 ** (-alpha * (r1 + r2) / 10) / (r1 * r2) ** 2 * dA
            out[k, 0] += one[through & (ci > 0) & (cos_img > 0)].sum()
    return out


def test_a_small_ball_seen_through_a_swell_follows_its_glints():
    """Under a long-crested swell (0.3 m high, 10 m long, crests along the track) 5 m above the sonar, a 5 cm ball
    30 m out: per ping its one- and two-bounce energy is the sum over the swell's strips of the flat image method
    with each strip as a tilted mirror (the quadrature above), within 1 dB wherever within −20 dB of its peak. The
    rays aimed at the ball's image in every strip that can mirror it (its glints) see it in every ping; before, only
    the swell's image fan saw it, by luck."""
    z_s, a, centre = H + 5.0, 0.05, (0.0, -30.0, 4.0)
    sea = se.SeaSurface(z_m=z_s, swell_height_m=0.3, swell_length_m=10.0, swell_direction_deg=90.0)
    sonar = se.Acquisition(se.Sonar(max_range_m=45.0), se.Environment(surface=sea)).for_pulse(se.Pulse.cw())
    traj = _pings_over(centre[1])
    got = _path_energy(_ball_scene(a, centre[1], centre[2], floor=False), traj, sonar)
    ref = _swell_strip_paths(a, centre, traj.positions_m, se.Acquisition.of(sonar).alpha_db_per_m, z_s, 0.3, 10.0)
    for k in (1, 2):
        inside = ref[:, k - 1] >= 0.01 * ref[:, k - 1].max()
        assert inside.sum() >= 15
        err = 10 * np.log10(np.maximum(got[inside, k], 1e-300) / ref[inside, k - 1])
        assert np.abs(err).max() < 1.0, (k, err.min(), err.max())


def _patch_scene(label, size, centre):
    """A flat Lambertian patch ``size`` (m) at ``centre`` (x, y) on z = 0, labelled ``label`` ("seafloor": the fan's
    rays alone; another label: an object, which rays are also aimed at), and nothing else."""
    return se.Scene().add(se.seafloor.flat(size, center_m=centre), label=label,
                          material=se.Material(backscatter_db=MU_DB))


def _within_1_db_of(ref, got, inside):
    err = 10 * np.log10(np.maximum(got[inside], 1e-300) / ref[inside])
    assert np.abs(err).max() < 1.0, np.round(err, 2)


def test_a_seabed_patch_off_boresight_in_a_wide_beam_is_heard_in_every_ping():
    """Issue 53, item 1: a 4 m × 2 m Lambertian seabed patch 20 m to starboard under a 22° beam (a 4 cm element at
    100 kHz), 10 m altitude, pings every 0.5 m over ±15 m, quality 1: its echo energy per ping is the quadrature of
    Γ⁴·μ·cos²θi·e^(−2αR)/R⁴ over it within 1 dB in every ping where that is within 10 dB of its peak, and so is the
    same patch as an object (aimed rays). Before: three probe lines per side left it unheard in 8 of those 21
    pings, and lines 5.4° apart (1.9 m at 20 m) left up to 3 dB between neighbouring pings."""
    sonar = se.Sonar(frequency_hz=100e3, length_m=0.04, max_range_m=30.0)
    x = np.arange(-15.0, 15.01, 0.5)
    traj = se.Trajectory(np.stack([x, 0 * x, np.full(x.size, H)], axis=1), 90.0, 0.0, 0.0, x / 1.5)
    acq = se.Acquisition.of(sonar.for_pulse(se.Pulse.cw()))

    def gamma(u, ping):
        return gamma_membrane(u[:, 0], np.abs(u[:, 1]), -u[:, 2], f0=100e3, c=acq.wavelength_m * 100e3, lx=0.04,
                              ly=sonar.height_m, tilt_deg=sonar.tilt_deg)

    ref = patch_quadrature((4.0, 2.0), (0.0, -20.0, 0.0), traj.positions_m, acq.alpha_db_per_m, MU_DB, gamma)
    inside = ref >= 0.1 * ref.max()
    assert inside.sum() >= 15
    for label in ("seafloor", "patch"):
        _within_1_db_of(ref, ball_energy(_patch_scene(label, (4.0, 2.0), (0.0, -20.0)), traj, sonar, label=label),
                        inside)


def test_a_seabed_patch_in_a_wide_beam_msis_is_heard_at_every_bearing_step():
    """The same for an MSIS with a 20° horizontal beam (200 kHz, 40° vertical) stepping 1° across a 3 m × 2 m patch
    12 m out on its sector's centre: the quadrature with the MSIS's beam (head frame as in
    :func:`_msis_gamma`) within 1 dB at every step where it is within 10 dB of its
    peak, for the seabed patch and the object. Before: up to 3.8 dB off."""
    sonar = se.MSIS(frequency_hz=200e3, horizontal_beamwidth_deg=20.0, vertical_beamwidth_deg=40.0, step_deg=1.0,
                    sector_deg=60.0, start_bearing_deg=0.0)
    n = 61
    gamma = _msis_gamma(sonar, n)
    acq = se.Acquisition.of(sonar)
    traj = se.Trajectory(np.tile([[0.0, 0.0, H]], (n, 1)), heading_deg=0.0, times_s=np.arange(n, dtype=float))
    ref = patch_quadrature((3.0, 2.0), (0.0, 12.0, 0.0), traj.positions_m, acq.alpha_db_per_m, MU_DB, gamma)
    inside = ref >= 0.1 * ref.max()
    assert inside.sum() >= 10
    for label in ("seafloor", "patch"):
        _within_1_db_of(ref, ball_energy(_patch_scene(label, (3.0, 2.0), (0.0, 12.0)), traj, sonar, label=label),
                        inside)


def test_a_seabed_patch_in_the_forward_looking_sonars_field_is_heard_in_every_ping():
    """The forward-looking sonar (130° field, its lines the beamformer's) sliding sideways past a 1 m × 1 m patch 18 m
    ahead: the record's energy per ping from the seabed patch within 1 dB of the same patch as an object (aimed
    rays) in every ping where that is within 10 dB of its peak."""
    x = np.arange(-4.0, 4.01, 0.25)
    traj = se.Trajectory(np.stack([x, 0 * x, np.full(x.size, 4.0)], axis=1), 0.0, 0.0, 0.0, 0.2 * np.arange(x.size))
    energy = {}
    for label in ("seafloor", "patch"):
        rec = se.simulate(_patch_scene(label, (1.0, 1.0), (0.0, 18.0)), traj, se.ForwardLooking(max_range_m=25.0),
                          se.Pulse.cw(duration_s=100e-6), start_time="2000-01-01")
        energy[label] = rec.data.reshape(len(traj), -1).sum(axis=1)
    inside = energy["patch"] >= 0.1 * energy["patch"].max()
    assert inside.sum() >= 15
    _within_1_db_of(energy["patch"], energy["seafloor"], inside)


CABLES = [  # radius, length (m), axis, abeam (m); each missed in some pings or all before slender objects
    (0.01, 6.0, (0.0, 1.0, 0.0), -20.0),   # across the track: unheard in half its pings, +5.6 dB in others
    (0.01, 2.0, (0.0, 1.0, 0.5), -7.8),    # rising across it: unheard
    (0.01, 6.0, (1.0, 0.0, 0.0), -20.0),   # along it: +0.8 dB
    (0.01, 12.0, (0.0, 1.0, 0.0), -20.0),  # 12 m across it: left to the fan, +1.1 to +8 dB
]


@pytest.mark.parametrize("rho, length, axis, y", CABLES)
def test_a_thin_cable_is_heard_at_its_closed_form_level_in_every_ping(rho, length, axis, y):
    """A 2 cm Lambertian cable 2–12 m long resting on the floor (or rising from it), 8–20 m abeam, pings every 6 cm,
    quality 1: its echo energy per ping is the quadrature of Γ⁴·μ·cos²θi·e^(−2αR)/R⁴ over its surface within 1 dB in
    every ping where that is within 10 dB of its peak. Before, the rays aimed at it tiled its bounding sphere's cone,
    8 × 8, so a cable far thinner than a cell was hit by one row of cells or none."""
    a = np.asarray(axis) / np.linalg.norm(axis)
    cable = trimesh.creation.cylinder(radius=rho, height=length, sections=64)
    cable.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], a))
    centre = (0.0, y, rho + 0.001 + 0.5 * length * a[2])
    scene = se.Scene().add(se.seafloor.flat((120, 120)), label="seafloor").add(
        cable.apply_translation(centre), label="cable", material=se.Material(backscatter_db=MU_DB))
    every = _pings_over(y, 1.0)
    traj = se.Trajectory(every.positions_m[::3], every.heading_deg[::3])
    acq = se.Acquisition.of(se.Sonar().for_pulse(se.Pulse.cw()))
    ref = cylinder_quadrature(rho, length, centre, a, traj.positions_m, acq.alpha_db_per_m, MU_DB, sidescan_gamma)
    inside = ref >= 0.1 * ref.max()
    assert inside.sum() >= 4
    _within_1_db_of(ref, ball_energy(scene, traj, label="cable"), inside)


@pytest.mark.parametrize("size, y", [((2.0, 0.01), -25.0), ((0.01, 2.0), -7.8)])
def test_a_thin_flat_strip_is_heard_at_its_closed_form_level_in_every_ping(size, y):
    """A 2 m × 1 cm Lambertian strip on the floor, along the track 25 m out (seen foreshortened to 4 mm) and across
    it 7.8 m out: the patch quadrature within 1 dB in every ping within 10 dB of its peak. Before: +7.0 dB along
    the track (one row of cells, each counted whole), unheard or up to +7 dB across it."""
    every = _pings_over(y, 1.0)
    traj = se.Trajectory(every.positions_m[::4], every.heading_deg[::4])
    acq = se.Acquisition.of(se.Sonar().for_pulse(se.Pulse.cw()))
    ref = patch_quadrature(size, (0.0, y, 0.0), traj.positions_m, acq.alpha_db_per_m, MU_DB, sidescan_gamma, n=400)
    inside = ref >= 0.1 * ref.max()
    assert inside.sum() >= 4
    _within_1_db_of(ref, ball_energy(_patch_scene("strip", size, (0.0, y)), traj, label="strip"), inside)


def test_a_very_long_thin_object_keeps_a_bounded_cover():
    """A 2 km × 1 cm strip is slender with a cell of a sixth of its width, and its cover holds at most
    aim.MAX_SLICES + 1 slices (4 corners each), not one per centimetre (800,000: 20 MB of corners)."""
    from sonar_embree.propagation import aim

    c = _patch_scene("strip", (2000.0, 0.01), (0.0, -20.0)).compiled()
    cell, cover, start = aim.slender_boxes(c, np.arange(c.faces.shape[0]), np.array([0]), np.array([1000.0]), 6)
    assert cell[0] == pytest.approx(0.01 / 6) and start.tolist() == [0, cover.shape[0]]
    assert cover.shape[0] == 4 * (aim.MAX_SLICES + 1)
    np.testing.assert_allclose(np.ptp(cover, axis=0)[:2], [2000.0, 0.01], rtol=1e-9)
