"""Geometry: side separation, shadows (docs/physics.md §6), UTM-scale precision (§8)."""
import numpy as np
import pytest

import sonar_embree as se
from conftest import H, box, flat_scene, line_along_x


def test_port_and_starboard_agree_over_flat_floor(flat_record):
    np.testing.assert_allclose(flat_record.port, flat_record.starboard, rtol=1e-9, atol=0)
    assert flat_record.starboard.max() > 0


def test_object_to_starboard_shows_in_starboard_only():
    traj = line_along_x(n_pings=3)
    # heading +x: starboard is −y
    target = box((4.0, 2.0, 2.0), (0.0, -20.0, 1.0))
    base = se.simulate(flat_scene(), traj)
    scene = flat_scene().add(target, material=se.Material(backscatter_db=-10), label="box")
    with_box = se.simulate(scene, traj)
    np.testing.assert_array_equal(with_box.port, base.port)
    diff = np.abs(with_box.starboard - base.starboard).max(axis=0)
    assert diff.max() > 10 * base.starboard.max(axis=0)[diff.argmax()]
    # no floor at all: the port channel is silent
    alone = se.simulate(se.Scene().add(target, label="box"), traj)
    assert np.all(alone.port == 0.0) and alone.starboard.max() > 0


def test_box_shadow_slant_extent():
    """A 1 m high wall at ground range x = 20 m: floor shadow 22.361–24.369 m (docs/physics.md §6)."""
    x, height, thick = 20.0, 1.0, 0.01
    scene = flat_scene().add(box((12.0, thick, height), (0.0, -(x - thick / 2), height / 2)), label="wall")
    sonar = se.Sonar()
    pulse = se.Pulse.cw(duration_s=100e-6, taper=0.0)
    rec = se.simulate(scene, line_along_x(n_pings=2), sonar, pulse)
    ref = se.simulate(flat_scene(), line_along_x(n_pings=2), sonar, pulse)
    r = rec.slant_range_m
    win = (r > 21.0) & (r < 26.0)
    dark = (rec.starboard[0] < 1e-6 * ref.starboard[0]) & win
    idx = np.nonzero(dark)[0]
    assert idx.size > 50 and np.all(np.diff(idx) == 1), "one contiguous shadow expected"
    r_start = np.hypot(x, H)                      # 22.361 m: last visible floor point
    r_top = np.hypot(x, H - height)
    r_end = H * r_top / (H - height)               # 24.369 m
    assert r_start == pytest.approx(22.361, abs=1e-3) and r_end == pytest.approx(24.369, abs=1e-3)
    bin_m = rec.acquisition.range_bin_m
    # the echo of the last lit floor point lasts a pulse length cτ/2 beyond it
    assert r[idx[0]] == pytest.approx(r_start + pulse.range_extent_m(se.Acquisition.of(sonar).sound_speed_m_s),
                                      abs=2 * bin_m)
    assert r[idx[-1] + 1] == pytest.approx(r_end, abs=2 * bin_m)
    # the port side sees the plain floor
    np.testing.assert_allclose(rec.port, ref.port, rtol=1e-12)


def _sloped_terrain(offset):
    nx, ny, res = 61, 41, 2.0
    x = np.arange(nx) * res - 60.0
    y = np.arange(ny) * res - 40.0
    xx, yy = np.meshgrid(x, y)
    z = 0.06 * yy + 0.02 * xx + 0.4 * np.sin(xx / 7.0) * np.cos(yy / 5.0)  # sloped facets everywhere
    return se.seafloor.from_heights(z + offset[2], res, (x[0] + offset[0], y[0] + offset[1]))


def test_utm_coordinates_give_the_same_record():
    offset = np.array([512_000.0, 5_412_000.0, 0.0])
    sonar = se.Sonar(max_range_m=40.0)
    local = se.simulate(se.Scene().add(_sloped_terrain((0, 0, 0)), label="floor"),
                        se.Trajectory.line((-5, 3, 12), (5, 3.5, 12), 4), sonar)
    utm = se.simulate(se.Scene().add(_sloped_terrain(offset), label="floor"),
                      se.Trajectory.line(tuple(offset + (-5, 3, 12)), tuple(offset + (5, 3.5, 12)), 4), sonar)
    for a, b in ((local.port, utm.port), (local.starboard, utm.starboard)):
        sig = a > 1e-6 * a.max()
        assert sig.sum() > 1000
        np.testing.assert_array_equal(a > 0, b > 0)
        assert np.max(np.abs(10 * np.log10(a[sig] / b[sig]))) < 0.05
