"""Synthetic aperture sonar from the simulator's own element records (docs/physics.md §18a, §18c): an along-track
array of 8 elements of D = 4 cm at 100 kHz with a 20 kHz LFM, pings 15 cm apart (under N·D/2), imaged by
backprojection. A point scatterer's image has its first nulls at D/2 along track and c/(2B·cos ψ) across track on
the ground plane (ψ the grazing angle), and the rect spectrum's −13.26 dB side lobe; a flat floor's image is fully
developed speckle (contrast std/mean of intensity = 1); an alternating sway of D/2 between pings, not compensated,
lowers the point's image by the closed form |Σ w·χ(δτ)·e^(j2πf0·δτ)|/Σ w (δτ the path error of each ping and
element, χ the compressed LFM's zero-Doppler cut, w the two-way pattern's amplitude) and, compensated with the true
navigation, refocuses within 10 %."""
import dataclasses
import math
import os

import numpy as np
import pytest
import trimesh

import sonar_embree as se
from sonar_embree.propagation.clutter import clutter_field
from sonar_embree.signal.sas import image_masks, record_image, unaliased_band

C, F0, B, D, H = 1500.0, 100e3, 20e3, 0.04, 5.0
LAM = C / F0
ARRAY = se.ReceiverArray.along_track(8, D)
SONAR = se.Sonar(frequency_hz=F0, length_m=D, height_m=0.02, tilt_deg=20, max_range_m=20, receive_array=ARRAY)
PULSE = se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.0)
ACROSS = 13.6                                     # the targets' ground range, m (slant about 14.5 m)


def _trajectory(sway=None, step=0.15):
    """Pings ``step`` m apart (15 cm) over ±3.6 m (the element's synthetic aperture λR/D at 14.5 m is 5.4 m), at
    rest during each ping; ``sway`` (pings,) m moves each ping across track (towards port)."""
    x = np.arange(-3.6, 3.6 + 1e-9, step)
    pos = np.stack([x, np.zeros_like(x), np.full_like(x, H)], axis=1)
    if sway is not None:
        pos[:, 1] = sway(x.size)
    zeros = np.zeros(x.size)
    return se.Trajectory(pos, np.full(x.size, 90.0), zeros, zeros, x / 1.5)     # heading east: starboard is −y


def _points_scene(seed=7):
    """A 1 m² tile on starboard whose only echoes are clutter scatterers (point targets at known positions)."""
    tile = trimesh.Trimesh([[-0.5, -ACROSS - 0.5, 0], [0.5, -ACROSS - 0.5, 0], [0.5, -ACROSS + 0.5, 0],
                            [-0.5, -ACROSS + 0.5, 0]], [[0, 1, 2], [0, 2, 3]])
    sc = se.Scene()
    sc.add(tile, material=se.Material(backscatter_db=-150, clutter=se.Clutter(density_per_m2=2.0, strength_db=-20,
                                                                                spread_db=0.0)), label="tile")
    points = clutter_field(sc.compiled(np.zeros(3)), seed).points
    assert points.shape == (1, 3)                      # this seed's one scatterer: nothing else in its image
    return sc, points[0]


def _simulate(scene, traj, seed=7):
    return se.simulate(scene, traj, SONAR, PULSE, speckle=True, seed=seed)


@pytest.fixture(scope="module")
def point():
    sc, target = _points_scene()
    return sc, target, _simulate(sc, _trajectory())


def _first_null(offsets, amp):
    """The first local minimum of |image| on each side of the peak: (left, right) distances."""
    i = int(np.argmax(amp))
    right = next(j for j in range(i + 1, amp.size - 1) if amp[j] <= amp[j + 1])
    left = next(j for j in range(i - 1, 0, -1) if amp[j] <= amp[j - 1])
    return offsets[i] - offsets[left], offsets[right] - offsets[i]


#: The band record_image processes by default: elements D apart put the phase centres D/2 apart (the pings, 15 cm
#: apart, advance less than the array's 8·D/2), and a two-way phase sampled every D/2 does not alias up to
#: |u| = λ/(4·D/2) = λ/(2D), the real aperture's footprint L = λR/D.
BAND = LAM / (2 * D)


def _closed_form(target, pixels, true_nav, nav, max_u=BAND):
    """The image of a point at ``target`` at ``pixels`` (n, 3), formed with navigation ``nav`` from pings at
    ``true_nav`` (pings, 3): Σ_p Σ_k w·χ(δτ)·e^(j2πf0·δτ) over the pings and elements whose mean along-track
    direction cosine to the pixel is within ``max_u``; δτ the formed path's delay less the true one's,
    w = b(u_tx)·b(u_k)/(R_tx·R_k) with the membrane's along-track pattern b(u) = sinc(D·u/λ)."""
    rot = _trajectory().rotations()
    rx_true, rx_nav = (ARRAY.world_positions(rot, p)[:, ARRAY.n_elements:] for p in (true_nav, nav))
    r_tx = np.linalg.norm(target - true_nav, axis=1)[:, None]
    r_rx = np.linalg.norm(target - rx_true, axis=2)
    w = (np.sinc(D * (target[0] - true_nav[:, 0])[:, None] / r_tx / LAM)
         * np.sinc(D * (target[0] - rx_true[..., 0]) / r_rx / LAM) / (r_tx * r_rx))
    out = []
    for x in np.atleast_2d(pixels):
        d_tx, d_rx = np.linalg.norm(x - nav, axis=1)[:, None], np.linalg.norm(x - rx_nav, axis=2)
        u = 0.5 * ((x[0] - nav[:, 0])[:, None] / d_tx + (x[0] - rx_nav[..., 0]) / d_rx)
        dtau = (d_tx + d_rx - (r_tx + r_rx)) / C
        out.append(np.sum(np.where(np.abs(u) <= max_u, w * _chi(dtau) * np.exp(2j * np.pi * F0 * dtau), 0))
                   / np.sum(w))
    return np.array(out)


def test_a_point_scatterers_image_has_the_closed_form_resolutions(point):
    """Formed over the band the sampling holds (|u| ≤ λ/(2D): the real aperture's footprint L = λR/D; Hayes and
    Gough 2009: δx = λR/(2L) = D/2): along track the −3 dB width is D/2 within 10 %; across track the first null
    on the ground plane is c/(2B·cos ψ) within 10 %. Both are the textbook's rules; the image must also be the
    exact aperture sum's (closed form, each ping's and element's bistatic delay and pattern, over the same band):
    its first nulls and −3 dB widths within 5 %, its side lobe within 1 dB."""
    sc, target, rec = point
    nav = rec.trajectory.positions_m
    assert unaliased_band(nav, ARRAY.world_positions(rec.trajectory.rotations(), nav)[:, 8:],
                          rec.trajectory.rotations()[:, :, 0], LAM) == pytest.approx(BAND)
    d = np.linspace(-0.12, 0.12, 961)
    along = np.abs(record_image(rec, target[0] + d, [target[1]], target[2]))[0]
    across = np.abs(record_image(rec, [target[0]], target[1] + d, target[2]))[:, 0]
    assert abs(d[np.argmax(along)]) < 0.002 and abs(d[np.argmax(across)]) < 0.002   # focused on the point
    assert _width_3db(d, along) == pytest.approx(D / 2, rel=0.1)
    grazing = math.atan2(H - target[2], abs(target[1]))
    np.testing.assert_allclose(_first_null(d, across), C / (2 * B * math.cos(grazing)), rtol=0.1)
    for line, cut in ((along, [1, 0, 0]), (across, [0, 1, 0])):
        want = np.abs(_closed_form(target, target + d[:, None] * cut, nav, nav))
        np.testing.assert_allclose(_first_null(d, line), _first_null(d, want), rtol=0.05)
        assert _width_3db(d, line) == pytest.approx(_width_3db(d, want), rel=0.05)
    np.testing.assert_allclose(_side_lobe_db(across), _side_lobe_db(want), atol=1.0)
    assert _side_lobe_db(want) == pytest.approx(-13.26, abs=2.0)        # near the rect spectrum's


def test_motion_during_the_ping_is_undone_by_the_image_former(point):
    """At 1.5 m/s the elements move on by v·τ ≈ 2.9 cm while the echo of the point 14.5 m out travels (the
    records hear it there, docs/physics.md §16). Imaged stop-and-hop the point lands v·τ/2 along track off its place
    (the phase centre's shift); with the motion undone (the default) it is focused on the point within 2 mm at the
    still line's peak within 0.5 dB."""
    sc, target, still = point
    traj = _trajectory()
    v = 1.5
    rec = _simulate(sc, dataclasses.replace(traj, velocity_m_s=np.tile([v, 0.0, 0.0], (len(traj), 1))))
    d = np.linspace(-0.06, 0.06, 481)
    image = [np.abs(record_image(r, target[0] + d, [target[1]], target[2], motion=m))[0]
             for r, m in ((rec, True), (rec, False), (still, True))]
    shift = v * np.linalg.norm(target - traj.positions_m, axis=1).min() / C      # v·τ/2, τ = 2R/c
    assert abs(d[np.argmax(image[0])]) < 0.002
    assert shift > 0.01 and abs(abs(d[np.argmax(image[1])]) - shift) < 0.003
    assert abs(20 * np.log10(image[0].max() / image[2].max())) < 0.5


def _chi_weighted(delta, taper):
    """The compressed LFM's cut with its spectrum weighted by 1 − taper·(1 − cos(2π·f/B)): the cosine's two halves
    are the cut moved by ±1/B, (1 − taper)·χ(δ) + (taper/2)·(χ(δ − 1/B) + χ(δ + 1/B))."""
    return (1 - taper) * _chi(delta) + 0.5 * taper * (_chi(delta - 1 / B) + _chi(delta + 1 / B))


def test_hamming_weighting_lowers_the_side_lobes_as_the_closed_form_says(point):
    """record_image(taper=0.46): Hamming weighting along track (over the band ±max_u) and across the chirp's band
    in range. Along track the side lobe falls from the rect band's to below −40 dB (Hamming's −43 dB; Harris
    1978); across track it is the weighted cut's closed form within 2 dB (the 1 ms, 20 kHz chirp's own Fresnel
    ripple keeps it near −24 dB); both −3 dB widths grow by Hamming's 1.30/0.886 = 1.47 within 10 %."""
    sc, target, rec = point
    d = np.linspace(-0.2, 0.2, 1601)
    cuts = {}
    for taper in (0.0, 0.46):
        cuts[taper] = (np.abs(record_image(rec, target[0] + d, [target[1]], target[2], taper=taper))[0],
                       np.abs(record_image(rec, [target[0]], target[1] + d, target[2], taper=taper))[:, 0])
    (along0, across0), (along, across) = cuts[0.0], cuts[0.46]
    assert _side_lobe_db(along0) > -25.0 and _side_lobe_db(along) < -40.0
    delta = np.linspace(-4e-4, 4e-4, 8001)
    assert _side_lobe_db(across) == pytest.approx(_side_lobe_db(np.abs(_chi_weighted(delta, 0.46))), abs=2.0)
    assert _side_lobe_db(across) < _side_lobe_db(across0) - 8.0
    for wide, narrow in ((along, along0), (across, across0)):
        assert _width_3db(d, wide) / _width_3db(d, narrow) == pytest.approx(1.30 / 0.886, rel=0.1)
    with pytest.raises(se.ConfigError, match="taper"):
        record_image(rec, [target[0]], [target[1]], target[2], taper=0.7)


def _width_3db(d, amp):
    """The full width of |image| at 1/√2 of its peak, linearly interpolated, m."""
    i, half = int(np.argmax(amp)), amp.max() / math.sqrt(2)
    r = next(j for j in range(i, amp.size) if amp[j] < half)
    left = next(j for j in range(i, -1, -1) if amp[j] < half)
    right_x = d[r - 1] + (amp[r - 1] - half) / (amp[r - 1] - amp[r]) * (d[r] - d[r - 1])
    left_x = d[left + 1] - (amp[left + 1] - half) / (amp[left + 1] - amp[left]) * (d[left + 1] - d[left])
    return right_x - left_x


def _side_lobe_db(amp):
    """The highest local maximum but the peak, dB below the peak."""
    i = int(np.argmax(amp))
    lobes = [amp[j] for j in range(1, amp.size - 1) if amp[j] >= amp[j - 1] and amp[j] >= amp[j + 1] and j != i]
    return 20 * math.log10(max(lobes) / amp[i])


#: The floor patch the images look at (along, across track, m), centred on the targets' ground range: every
#: lattice node under the ±22° element beam radiates, so a whole floor would cost far more and add only far
#: side lobes to the images.
PATCH_M = (6.0, 4.0)


def _patch():
    return se.seafloor.flat(size_m=PATCH_M, center_m=(0.0, -ACROSS))


def test_a_flat_floors_image_is_fully_developed_speckle():
    floor = se.Scene()
    floor.add(_patch(), material=se.Material(backscatter_db=-20), label="seafloor")
    rec = _simulate(floor, _trajectory(), seed=5)
    x, y = np.arange(-1.5, 1.5, 0.01), np.arange(-ACROSS - 0.7, -ACROSS + 0.7, 0.01)
    intensity = np.abs(record_image(rec, x, y, 0.0)) ** 2
    trend = intensity.mean(axis=1, keepdims=True)             # the mean level along each range line
    contrast = np.std(intensity / trend) / np.mean(intensity / trend)
    assert contrast == pytest.approx(1.0, abs=0.05)


def _chi(delta):
    """The compressed LFM's zero-Doppler cut (Cook and Bernfeld 1967): (1 − |δ|/T)·sinc(B·δ·(1 − |δ|/T)), real."""
    t = PULSE.duration_s
    shrink = 1 - np.abs(delta) / t
    return shrink * np.sinc(B * delta * shrink)


def test_an_uncompensated_sway_defocuses_as_predicted_and_the_navigation_refocuses(point):
    sc, target, straight = point
    sway = lambda n: 0.5 * D * (np.arange(n) % 2)                              # D/2 between consecutive pings
    swayed = _simulate(sc, _trajectory(sway))
    true_nav = swayed.trajectory.positions_m
    nominal = straight.trajectory.positions_m
    at = lambda rec, nav: abs(record_image(rec, [target[0]], [target[1]], target[2], positions_m=nav,
                                           max_u=None)[0, 0])              # every ping and element, as below
    focused, refocused, blurred = at(straight, nominal), at(swayed, true_nav), at(swayed, nominal)
    assert refocused == pytest.approx(focused, rel=0.1)
    predicted = abs(_closed_form(target, target, true_nav, nominal, 2.0)[0])  # the path errors' closed form
    assert predicted < 0.5                                                        # a real defocus
    assert blurred / refocused == pytest.approx(predicted, rel=0.1)


def test_object_masks_sit_where_the_sas_image_shows_the_object():
    """A 1 m × 1 m × 0.5 m box on the floor: its mask spans the laid-over ground ranges of its near face's foot and
    its top's far edge, √(g² + h² − 2Hh) for a point at ground range g and height h (the sonar H above the plane),
    and along track its own extent; the image's brightest pixels fall inside the mask."""
    sc = se.Scene()
    sc.add(_patch(), material=se.Material(backscatter_db=-30), label="seafloor")
    sc.add(trimesh.creation.box(extents=(1.0, 1.0, 0.5)).apply_translation((0.0, -ACROSS, 0.25)),
           material=se.Material(backscatter_db=-10), label="box")
    rec = _simulate(sc, _trajectory(), seed=2)
    x, y = np.arange(-1.0, 1.0, 0.01), np.arange(-ACROSS - 1.0, -ACROSS + 1.0, 0.01)
    mask, names = image_masks(sc, rec, x, y)
    assert names[1] == "box" and set(np.unique(mask)) == {-1, 1}
    rows, cols = np.nonzero(mask == 1)
    laid = lambda g, h: math.sqrt(g * g + h * h - 2 * H * h)
    np.testing.assert_allclose([-y[rows].max(), -y[rows].min()], [laid(ACROSS - 0.5, 0.5), laid(ACROSS + 0.5, 0.5)],
                               atol=0.02)
    np.testing.assert_allclose([x[cols].min(), x[cols].max()], [-0.5, 0.5], atol=0.02)
    intensity = np.abs(record_image(rec, x, y, 0.0)) ** 2
    bright = intensity > np.percentile(intensity, 99.5)
    near = np.zeros_like(bright)                                       # the mask grown by a resolution cell
    for dr in range(-4, 5):
        for dc in range(-2, 3):
            near |= np.roll(mask == 1, (dr, dc), axis=(0, 1))
    assert np.mean(near[bright]) > 0.9


def test_image_masks_refuse_a_ragged_grid():
    sc, target = _points_scene()
    rec = _simulate(sc, _trajectory())
    with pytest.raises(se.ConfigError, match="uniformly spaced"):
        image_masks(sc, rec, [0.0, 0.1, 0.3], [0.0, 0.1])
    with pytest.raises(se.ConfigError, match="channel"):
        image_masks(sc, rec, [0.0, 0.1], [0.0, 0.1], channel="up")


def test_a_hole_in_the_floor_is_imaged_darker_than_the_floor():
    """A 0.8 m × 2.2 m hole in a flat floor (no scatterers at all) shows in the SAS image at least 13 dB below the
    floor around it at quality 1 (14.7 dB). The speckle lattice spreads each seabed echo over its fan line's strip,
    R·ds along track; an along-track array's fan takes lines 0.2° apart (config.ARRAY_AZIMUTH_STEP_DEG: 5 cm at
    14.5 m), so the floor beside the hole no longer reaches into it (9.4 dB down with the 1.5° of other wide beams,
    4.6 dB with the element's own 5.4°; docs/physics.md §4, "Limit")."""
    assert _hole_depth_db(se.Material(backscatter_db=-20)) < -13.0
    assert _hole_depth_db(se.Material(backscatter_db=-20), fan=se.FanSettings(max_azimuth_step_deg=1.5)) > -11.0


def _hole_depth_db(material, fan=None, step=0.15, taper=0.0) -> float:
    """The SAS image's mean intensity over a 0.8 m × 2.2 m hole in a floor of ``material`` (pixels 0.15 m and more
    from its edges) against the floor's beside it, dB (pings ``step`` m apart, weighting ``taper``)."""
    xs, ys = np.arange(-PATCH_M[0] / 2, PATCH_M[0] / 2, 0.1), np.arange(-ACROSS - 2.0, -ACROSS + 2.0, 0.1)
    z = np.zeros((ys.size, xs.size))
    z[(np.abs(ys + ACROSS)[:, None] < 1.1) & (np.abs(xs)[None, :] < 0.4)] = np.nan
    sc = se.Scene().add(se.seafloor.grid_mesh(xs, ys[::-1], z[::-1]), material=material, label="seafloor")
    rec = se.simulate(sc, _trajectory(step=step), SONAR, PULSE, speckle=True, seed=4, fan=fan)
    x, y = np.arange(-2.0, 2.0, 0.02), np.arange(-ACROSS - 1.2, -ACROSS + 1.2, 0.02)
    return _hole_to_floor_db(np.abs(record_image(rec, x, y, 0.0, taper=taper)) ** 2, x, y)


def _hole_to_floor_db(intensity, x, y, y_mid=-ACROSS, half_y=0.8) -> float:
    """Mean intensity over the dark pixels |y − y_mid| < half_y, |x| < 0.25 (by default the hole's inner ones)
    against the floor's at the same ranges 1.2–1.8 m along track from it, dB."""
    rows = np.abs(y - y_mid) < half_y
    hole = intensity[np.ix_(rows, np.abs(x) < 0.25)].mean()
    floor = intensity[np.ix_(rows, np.abs(np.abs(x) - 1.5) < 0.3)].mean()
    return float(10 * np.log10(hole / floor))


def _aperture_sum(points, heard, pixels, traj, taper):
    """The weighted aperture sum H(x, q) of points q (m, 3) at pixels x (n, 3): Σ_p Σ_k over the pings and elements
    that hear q (``heard`` (m, pings, elements) bool) of w·χ_w(δτ)·e^(j2πf0·δτ)·a(u); w = b(u_tx)·b(u_k)/(R_tx·R_k)
    at q with the membrane's along-track pattern b(u) = sinc(D·u/λ), δτ the path to x less the path to q, χ_w the
    range-weighted cut and a(u) = 1 − taper·(1 − cos(π·u/BAND)) for |u| ≤ BAND (u the mean along-track cosine to
    x), else 0; (n, m) complex."""
    nav = traj.positions_m
    rx = ARRAY.world_positions(traj.rotations(), nav)[:, ARRAY.n_elements:]
    out = np.zeros((pixels.shape[0], points.shape[0]), dtype=complex)
    for p in range(nav.shape[0]):
        q_tx, q_rx = np.linalg.norm(points - nav[p], axis=1)[:, None], np.linalg.norm(points[:, None] - rx[p], axis=2)
        w = heard[:, p] * np.sinc(D * (points[:, 0] - nav[p, 0])[:, None] / q_tx / LAM) * np.sinc(
            D * (points[:, None, 0] - rx[p, :, 0]) / q_rx / LAM) / (q_tx * q_rx)                     # (m, elements)
        x_tx, x_rx = np.linalg.norm(pixels - nav[p], axis=1)[:, None], np.linalg.norm(pixels[:, None] - rx[p], axis=2)
        u = 0.5 * ((pixels[:, 0] - nav[p, 0])[:, None] / x_tx + (pixels[:, None, 0] - rx[p, :, 0]) / x_rx)
        a = np.where(np.abs(u) <= BAND, 1 - taper * (1 - np.cos(np.pi * u / BAND)), 0.0)           # (n, elements)
        dtau = ((x_tx + x_rx)[:, None] - (q_tx + q_rx)[None]) / C                               # (n, m, elements)
        out += np.einsum("nk,mk,nmk->nm", a, w, _chi_weighted(dtau, taper) * np.exp(2j * np.pi * F0 * dtau))
    return out


def _point_image(target, dx, dy, traj, taper):
    """:func:`_aperture_sum` of a point at ``target``, heard by every ping and element, on the grid target + (dx, dy)
    at its height; (ny, nx) complex."""
    xx, yy = np.meshgrid(target[0] + dx, target[1] + dy)
    px = np.stack([xx.ravel(), yy.ravel(), np.full(xx.size, target[2])], axis=1)
    heard = np.ones((1, traj.positions_m.shape[0], ARRAY.n_elements), bool)
    return _aperture_sum(target[None], heard, px, traj, taper)[:, 0].reshape(xx.shape)


def _closed_form_hole_depth_db(traj, taper) -> float:
    """The hole's depth in the image of a floor of independent scatterers: E|image(x)|² = n·Σ_q |h(x − q)|² over
    the floor's points q (the hole left out), h the point image of :func:`_point_image` at the hole's centre
    (taken as the same everywhere on the patch: 1 cm along, 2 cm across, out to ±5 m and the cut's ±0.9 m
    reach), a convolution of the floor's mask with |h|²; then :func:`_hole_to_floor_db` of it."""
    x, y = _floor_grid()
    floor = ~((np.abs(y + ACROSS)[:, None] < 1.1) & (np.abs(x)[None] < 0.4))
    return _hole_to_floor_db(_through_point_image(floor, traj, taper), x, y)


def _floor_grid():
    """The closed forms' grid over the patch, 1 cm along and 2 cm across track: (x (600,), y (200,)) m."""
    return np.arange(-3.0, 3.0, 0.01) + 0.005, -ACROSS + np.arange(-2.0, 2.0, 0.02) + 0.01


def _through_point_image(mask, traj, taper):
    """Σ_q |h(x − q)|² over the points q of ``mask`` (on :func:`_floor_grid`), h the point image at the patch's
    centre (:func:`_point_image`, out to ±5 m along and the cut's ±0.9 m reach): a convolution, (200, 600)."""
    from scipy.signal import fftconvolve

    psf = _point_image(np.array([0.0, -ACROSS, 0.0]), np.arange(-500, 501) * 0.01, np.arange(-45, 46) * 0.02, traj,
                       taper)
    return fftconvolve(mask.astype(float), np.abs(psf[::-1, ::-1]) ** 2, mode="same")


def test_with_uniform_phase_centres_and_weighting_a_hole_is_over_20_db_deep():
    """Issue 53, item 3. Pings N·D/2 = 16 cm apart put the 8 elements' phase centres on one 2 cm grid; at 15 cm
    (above) they repeat every 15 cm with a 1 cm step, whose grating lobes (each |Σ_k e^(j2π·m·2k/15)|/8 ≈ −24 dB,
    some six of them in the band) fill the hole with the floor's ghosts to about −16 dB whatever the simulator
    does. With uniform phase centres and Hamming weighting, the closed form (a floor of independent scatterers
    through the weighted aperture sum, :func:`_closed_form_hole_depth_db`) puts the hole about 32 dB down; a floor
    of exact point echoes comes within 3 dB of it, and the lattice's floor at quality 1 is at least 20 dB down
    (22.7 dB: its own leak near the hole's edges keeps it shallower than the closed form; docs/physics.md §18c)."""
    want = _closed_form_hole_depth_db(_trajectory(step=0.16), 0.46)
    points = _hole_depth_db(se.Material(backscatter_db=-150, clutter=se.Clutter(300.0, strength_db=-30.0,
                                                                                spread_db=0.0)), step=0.16, taper=0.46)
    lattice = _hole_depth_db(se.Material(backscatter_db=-20), step=0.16, taper=0.46)
    assert want < -25.0 and abs(points - want) < 3.0 and lattice < -20.0, (want, points, lattice)
    assert _hole_depth_db(se.Material(backscatter_db=-20), step=0.16) > lattice + 1.0      # the weighting matters


def test_at_quality_1_a_hole_is_as_deep_as_the_closed_form_makes_it():
    """Issue 53, item 3: with pings 15 cm apart the closed form (:func:`_closed_form_hole_depth_db`, unweighted)
    puts the hole 15.0 dB down: the floor's ghosts through the phase centres' 15 cm period (see the test below).
    A floor of exact point echoes (clutter points alone, 300 per m²: each echo the bistatic closed form,
    tests/signal/test_receiver_arrays.py) and the lattice's floor at quality 1 (an along-track array's lines
    0.2° apart, 5 cm at 14.5 m) both come within 1 dB of it (15.2 and 14.7 dB)."""
    want = _closed_form_hole_depth_db(_trajectory(), 0.0)
    points = _hole_depth_db(se.Material(backscatter_db=-150, clutter=se.Clutter(300.0, strength_db=-30.0,
                                                                                 spread_db=0.0)))
    lattice = _hole_depth_db(se.Material(backscatter_db=-20))
    assert want < -13.0 and abs(points - want) < 1.0 and abs(lattice - want) < 1.0, (want, points, lattice)


#: A box 1 m × 1 m × 0.5 m on the floor patch, 1 m nearer the track than the patch's centre, (lower, upper) corners:
#: its shadow on the floor abeam runs from 13.1 m to 13.1·H/(H − 0.5) = 14.56 m ground range, inside the patch.
BOX = (np.array([-0.5, -ACROSS + 0.5, 0.0]), np.array([0.5, -ACROSS + 1.5, 0.5]))
SHADOW_Y = -13.85                                   # the shadow's middle (ground range 13.85 m), y


def _crosses_box(a, b):
    """Whether the segments a → b (..., 3) pass through :data:`BOX` (the slab method), bool (...)."""
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (BOX[0] - a) / d, (BOX[1] - a) / d
    enter, leave = np.nanmax(np.minimum(t1, t2), axis=-1), np.nanmin(np.maximum(t1, t2), axis=-1)
    return (leave >= np.maximum(enter, 0.0)) & (enter <= 1.0)


def _closed_form_shadow_depth_db(traj, taper) -> float:
    """The box's shadow in the image of a floor of independent scatterers q: E|image(x)|² = n·Σ_q |H(x, q)|², H the
    aperture sum over the pings p and elements k for which both legs, transmitter → q → element, miss the box
    (:func:`_aperture_sum`). Floor points every ping and element hears add |h(x − q)|² (the point image at the
    patch's centre, a convolution as for the hole); the points some hear and some do not (the penumbra) are summed
    one by one at 5 × 5 pixels over the shadow; points none hears (under and behind the box) add nothing. Grid 1 cm
    along, 2 cm across over the patch; the floor's level from the convolution beside it."""
    x, y = _floor_grid()
    near = (np.abs(x)[None] < 1.5) & (y[:, None] > SHADOW_Y - 1.0) & (y[:, None] < BOX[1][1] + 0.1)
    yy, xx = np.meshgrid(y, x, indexing="ij")
    q = np.stack([xx[near], yy[near], np.zeros(near.sum())], axis=1)
    nav = traj.positions_m
    rx = ARRAY.world_positions(traj.rotations(), nav)[:, ARRAY.n_elements:]
    heard = ~_crosses_box(q[:, None, None], rx[None]) & ~_crosses_box(q[:, None], nav[None])[..., None]
    lit, some = np.ones(near.shape, bool), heard.any(axis=(1, 2)) & ~heard.all(axis=(1, 2))
    lit[near] = heard.all(axis=(1, 2))
    image = _through_point_image(lit, traj, taper)
    px, py = np.meshgrid(np.linspace(-0.2, 0.2, 5), SHADOW_Y + np.linspace(-0.3, 0.3, 5))
    pixels = np.stack([px.ravel(), py.ravel(), np.zeros(px.size)], axis=1)
    penumbra = np.sum(np.abs(_aperture_sum(q[some], heard[some], pixels, traj, taper)) ** 2, axis=1)
    shadow = image[np.searchsorted(y, py.ravel()), np.searchsorted(x, px.ravel())] + penumbra
    floor = image[np.ix_(np.abs(y - SHADOW_Y) < 0.35, np.abs(np.abs(x) - 1.5) < 0.3)].mean()
    return float(10 * np.log10(shadow.mean() / floor))


def _shadow_depth_db(material, step=0.16, taper=0.46) -> float:
    """The SAS image's shadow of a black :data:`BOX` (no echo of its own) on the floor patch of ``material`` against
    the floor beside it, dB (:func:`_hole_to_floor_db` over the shadow's middle; pings ``step`` m apart,
    weighting ``taper``)."""
    sc = se.Scene().add(_patch(), material=material, label="seafloor")
    sc.add(trimesh.creation.box(bounds=np.stack(BOX)), material=se.Material(backscatter_db=-150), label="box")
    rec = se.simulate(sc, _trajectory(step=step), SONAR, PULSE, speckle=True, seed=4)
    x, y = np.arange(-2.0, 2.0, 0.02), np.arange(SHADOW_Y - 0.6, SHADOW_Y + 0.6, 0.02)
    return _hole_to_floor_db(np.abs(record_image(rec, x, y, 0.0, taper=taper)) ** 2, x, y, SHADOW_Y, 0.35)


def test_a_cubes_shadow_is_as_deep_as_the_closed_form_makes_it():
    """Issue 53, item 3: a box's shadow. A SAS image's shadow is not empty: each ping casts its own, and the floor
    that some pings see and others do not (the penumbra) is imaged partly focused into it. The closed form
    (:func:`_closed_form_shadow_depth_db`: each floor point heard only by the pings and elements whose legs miss the
    box) puts the shadow of a 1 m × 1 m × 0.5 m box 25.8 dB below the floor, with pings N·D/2 apart and Hamming
    weighting; the lattice's floor at quality 1 (24.7 dB) and a floor of exact point echoes (25.5 dB) within 1.5 dB
    of it (the closed form's own approximation, one point image for the whole lit floor, moves it by up to
    0.5 dB). The box is black: its own echo's side lobes would fill the shadow as well."""
    want = _closed_form_shadow_depth_db(_trajectory(step=0.16), 0.46)
    points = _shadow_depth_db(se.Material(backscatter_db=-150, clutter=se.Clutter(300.0, strength_db=-30.0,
                                                                                  spread_db=0.0)))
    lattice = _shadow_depth_db(se.Material(backscatter_db=-20))
    assert want < -20.0 and abs(points - want) < 1.5 and abs(lattice - want) < 1.5, (want, points, lattice)


def _envelope_lag_s(a, b, fs):
    """The lag (s) of |a| behind |b| (1-D records at ``fs`` Hz): the peak of their cross-correlation, interpolated
    64 times by zero-padding the spectrum."""
    n = 64 * 2 * a.size
    xc = np.fft.irfft(np.fft.rfft(np.abs(a), 2 * a.size) * np.conj(np.fft.rfft(np.abs(b), 2 * a.size)), n)
    lag = int(np.argmax(xc))
    return (lag if lag < n // 2 else lag - n) / (64 * fs)


@pytest.mark.parametrize("array", [None, ARRAY])
def test_a_moving_sonars_lattice_echo_arrives_on_its_moving_leg(array, seed=3):
    """Motion during the ping (docs/physics.md §16): the sonar transmits at p and hears an echo of travel time τ at
    p + v·τ, so a patch at along-track cosine u arrives (|X − p − v·τ| − |X − p|)/c ≈ −v·τ·u/c earlier than
    stop-and-hop puts it, in its envelope as in its phase. A patch 2 cm along and 20 cm across track, 3.7 m ahead at
    14.5 m (u = 0.25), at 5 m/s: 16 µs, a third of the compressed pulse. The lattice's envelope (a single channel,
    and an array's element from the shared emission) moves by the closed form within 15 % (measured 4–6 %; a
    point echo's, exact, 2 %); before, it kept 2R/c and moved by +0.4 to +0.8 µs (the receive beam's turn
    reweighting the patch). Narrow along track, so that the turn cannot move the patch's range centroid much."""
    x0, v, half = 3.7, 5.0, (0.01, 0.1)
    corners = [[x0 + a * half[0], -ACROSS + b * half[1], 0.0] for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    sc = se.Scene().add(trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]]), material=se.Material(backscatter_db=-20),
                        label="patch")
    x = np.array([-0.5, 0.0, 0.5])
    pos = np.stack([x, np.zeros(3), np.full(3, H)], axis=1)
    traj = se.Trajectory(pos, np.full(3, 90.0), np.zeros(3), np.zeros(3), x / v,
                         velocity_m_s=np.tile([v, 0.0, 0.0], (3, 1)))
    sonar = dataclasses.replace(SONAR, receive_array=array)
    recs = [se.simulate(sc, t, sonar, PULSE, speckle=True, seed=seed, keep_complex=True)
            for t in (traj, traj.stop_and_hop())]
    series = [r.complex_data[1, 1] if array is None else r.element_data[1, 1, 0] for r in recs]
    centre = np.array([x0, -ACROSS, 0.0])
    r = np.linalg.norm(centre - pos[1])
    want = (np.linalg.norm(centre - pos[1] - [v * 2 * r / C, 0.0, 0.0]) - r) / C
    got = _envelope_lag_s(*series, 1.0 / float(recs[0].time_s[1] - recs[0].time_s[0]))
    assert want < -15e-6 and abs(got - want) < 0.15 * abs(want), (got, want)


def test_a_local_scene_placed_on_the_earth_writes_its_sas_image_there(point, tmp_path):
    """A record in local metres with ``geo_origin_deg`` (its XTF in lat/lon): sas.tif is in the origin's UTM zone,
    the local origin at the origin's projected point (pyproj here), so the scatterer's pixel lies where its local
    position puts it. Before, the image had no CRS (a GIS could not place it beside the XTF)."""
    import pyproj
    import rasterio

    from sonar_embree.record import registry
    from sonar_embree.runs.runconfig import OutputOptions

    sc, target, rec = point
    assert rec.trajectory.crs is None
    rec = dataclasses.replace(rec, attrs={**rec.attrs, "geo_origin_deg": [43.0, 5.0]})
    east, north = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32631", always_xy=True).transform(5.0, 43.0)
    grid = {"x_m": [target[0] - 0.5, target[0] + 0.5], "y_m": [target[1] - 0.4, target[1] + 0.4], "pixel_m": 0.02,
            "z_m": float(target[2])}
    registry.write_each(rec, str(tmp_path), ("sas",), OutputOptions(sas=True, sas_grid=grid).write_options())
    with rasterio.open(tmp_path / "sas.tif") as f:
        assert f.crs.to_epsg() == 32631
        r, c = np.unravel_index(np.argmax(f.read(1)), (f.height, f.width))
        cx, cy = f.xy(r, c)
    assert abs(cx - east - target[0]) < 0.05 and abs(cy - north - target[1]) < 0.05


def test_record_image_refuses_what_cannot_form_an_image(point):
    """Issue 49: no pings, a wrong-length mask, an element out of range, no elements, a NaN pixel or height and a
    grid beyond the pixel cap are one-line errors naming the value, not zeros or a MemoryError."""
    _, target, rec = point
    x, y = [target[0]], [target[1]]
    n = rec.n_pings
    for kw, match in ((dict(pings=[]), "pings selects none"), (dict(pings=np.ones(n + 1, bool)), "mask must have"),
                      (dict(elements=[0, 8]), "elements 8 is out of range"), (dict(elements=[]), "elements selects"),
                      (dict(x_m=[np.nan]), "x_m must be a non-empty"), (dict(z_m=np.nan), "z_m must be finite"),
                      (dict(x_m=np.zeros(100_000), y_m=np.zeros(100_000)), "beyond the")):
        args = {"x_m": x, "y_m": y, "z_m": target[2], **kw}
        with pytest.raises(se.ConfigError, match=match) as exc:
            record_image(rec, args.pop("x_m"), args.pop("y_m"), **args)
        assert "\n" not in str(exc.value)
    assert abs(record_image(rec, x, y, target[2], pings=np.ones(n, bool))[0, 0]) > 0


def test_the_sas_image_is_an_output_in_the_records_crs(point, tmp_path):
    """Issue 53: ``[output] sas = true`` with a ``sas_grid`` writes sas.tif, a north-up GeoTIFF whose pixels are
    record_image's intensity at their centres (read back with rasterio: the first band is |image|², the second its
    dB, the transform puts the brightest pixel on the scatterer); a missing or broken grid is a one-line error."""
    import rasterio

    from sonar_embree.record import registry
    from sonar_embree.runs.runconfig import OutputOptions

    sc, target, rec = point
    rec = dataclasses.replace(rec, trajectory=dataclasses.replace(rec.trajectory, crs="EPSG:32631"))
    grid = {"x_m": [target[0] - 0.5, target[0] + 0.5], "y_m": [target[1] - 0.4, target[1] + 0.4], "pixel_m": 0.02,
            "z_m": float(target[2])}
    opts = OutputOptions(png=False, npz=False, sas=True, sas_grid=grid)
    assert opts.formats() == ("sas",)
    paths = registry.write_each(rec, str(tmp_path), opts.formats(), opts.write_options())
    assert [os.path.basename(p) for p in paths] == ["sas.tif"]
    x = target[0] - 0.5 + 0.02 * (0.5 + np.arange(50))
    y = target[1] - 0.4 + 0.02 * (0.5 + np.arange(40))
    want = np.abs(record_image(rec, x, y, float(target[2]))) ** 2
    with rasterio.open(tmp_path / "sas.tif") as f:
        assert f.crs.to_epsg() == 32631 and f.descriptions == ("intensity", "level_db") and f.count == 2
        band = f.read(1)
        np.testing.assert_allclose(band, want[::-1].astype(np.float32), rtol=1e-6)
        r, c = np.unravel_index(np.argmax(band), band.shape)
        cx, cy = f.xy(r, c)                                          # the pixel's centre, world m
        assert abs(cx - target[0]) < 0.05 and abs(cy - target[1]) < 0.05
        np.testing.assert_allclose(f.read(2), 10 * np.log10(band), atol=1e-4)
    with pytest.raises(se.ConfigError, match="sas = true needs sas_grid"):
        OutputOptions(sas=True)
    with pytest.raises(se.ConfigError, match=r"sas_grid: x_m must be \[min, max\]"):
        OutputOptions(sas=True, sas_grid={**grid, "x_m": [1.0, 0.0]})
    with pytest.raises(se.ConfigError, match="sas_grid: unknown key 'pixel'"):
        OutputOptions(sas=True, sas_grid={"x_m": [0, 1], "y_m": [0, 1], "pixel": 0.1})
    with pytest.raises(se.ConfigError, match="at most 4000000"):
        OutputOptions(sas=True, sas_grid={**grid, "pixel_m": 1e-4})
    with pytest.raises(se.ConfigError, match=r"taper must be a number in \[0, 0.5\]"):
        OutputOptions(sas=True, sas_grid={**grid, "taper": 0.9})
    os.makedirs(tmp_path / "w")
    weighted = registry.write_each(rec, str(tmp_path / "w"), ("sas",),
                                   OutputOptions(sas=True, sas_grid={**grid, "taper": 0.46}).write_options())
    with rasterio.open(weighted[0]) as f:                                   # the grid's taper reaches the image
        np.testing.assert_allclose(f.read(1), (np.abs(record_image(rec, x, y, float(target[2]), taper=0.46)) ** 2)
                                   [::-1].astype(np.float32), rtol=1e-6)
