"""Ground-truth labels against geometry worked out by hand (docs/physics.md §6 shadow formula)."""
import numpy as np
import pytest

import naive
import sonar_embree as se
from conftest import H, box, flat_scene, line_along_x
from sonar_embree import kernels
from sonar_embree.kernels.args import Footprints, LabelOut
from sonar_embree.signal.labels import OBJECT, SEAFLOOR, SHADOW, WATER, Labels


@pytest.fixture(scope="module")
def wall_record():
    """A 2 m × 2 m × 1 m box to port whose near face is at ground range 19 m; pings over its middle."""
    scene = flat_scene().add(box((2.0, 2.0, 1.0), (0.0, 20.0, 0.5)), label="box")
    return se.simulate(scene, line_along_x(3, length=0.2), se.Sonar(max_range_m=30.0), labels=True)


def _runs(mask, r):
    idx = np.nonzero(mask)[0]
    return r[idx[0]], r[idx[-1]], idx.size


def test_flat_floor_labels_match_the_geometry(flat_record):
    rec = se.simulate(flat_scene(), line_along_x(2), se.Sonar(max_range_m=30.0), labels=True)
    lab, r = rec.labels, rec.slant_range_m
    dr = r[1]
    for side in range(2):
        for ping in range(2):
            kind = lab.kind[side, ping]
            below = (r + 0.5 * dr) <= H  # cells wholly nearer than the altitude: water column
            assert np.all(kind[below] == WATER)
            assert np.all(kind[~below] == SEAFLOOR)
            floor = r > H
            ground = np.sqrt(r[floor] ** 2 - H ** 2)
            np.testing.assert_allclose(lab.ground_range_m[side, ping][floor], ground, atol=2e-4)
            np.testing.assert_allclose(lab.height_m[side, ping][floor], 0.0, atol=1e-5)
            assert np.all(np.isnan(lab.height_m[side, ping][below]))
    assert np.all(lab.object_id[lab.kind == SEAFLOOR] == 0)
    assert not lab.shadow.any() and not lab.highlight.any()
    assert lab.names == ("seafloor",) and lab.is_seafloor == (True,)


def test_box_highlight_and_shadow_follow_the_shadow_formula(wall_record):
    lab, r = wall_record.labels, wall_record.slant_range_m
    dr = r[1]
    h, height, x_near, x_far = H, 1.0, 19.0, 21.0
    r_lit_start = np.hypot(x_near, h - height)            # top of the near face: nearest point of the box
    r_top = np.hypot(x_far, h - height)                    # far top edge casts the shadow
    r_end = h * r_top / (h - height)                       # docs/physics.md: R_end = h·R_top/(h − H)
    for ping in range(3):
        kind = lab.kind[0, ping]                           # heading +x: +y is port
        lo, hi, _ = _runs(kind == OBJECT, r)
        assert abs(lo - r_lit_start) <= 2 * dr and abs(hi - r_top) <= 2 * dr  # within 2 samples
        s_lo, s_hi, _ = _runs(kind == SHADOW, r)
        assert abs(s_lo - r_top) <= 2 * dr and abs(s_hi - r_end) <= 2 * dr
        assert np.all(lab.object_id[0, ping][kind == OBJECT] == 1)
        assert np.all(lab.shadow_of[0, ping][kind == SHADOW] == 1)
        assert np.all(lab.object_id[0, ping][kind == SHADOW] == -1)
        # hidden floor: height 0 and ground range from the slant range
        sh = kind == SHADOW
        np.testing.assert_allclose(lab.height_m[0, ping][sh], 0.0, atol=1e-5)
        np.testing.assert_allclose(lab.ground_range_m[0, ping][sh], np.sqrt(r[sh] ** 2 - h ** 2), atol=2e-4)
        # the top face: height 1, ground range from the slant range
        top = (kind == OBJECT) & (r > np.hypot(x_near, h) + dr)
        np.testing.assert_allclose(lab.height_m[0, ping][top], height, atol=1e-5)
        np.testing.assert_allclose(lab.ground_range_m[0, ping][top], np.sqrt(r[top] ** 2 - (h - height) ** 2),
                                   atol=2e-4)
    assert not np.any(lab.kind[1] == OBJECT)  # nothing to starboard
    assert lab.highlight.sum() == (lab.kind == OBJECT).sum() and lab.shadow.sum() == (lab.kind == SHADOW).sum()


@pytest.mark.parametrize("caster", ["EmbreeCaster", "NumpyCaster"])
def test_shadow_behind_a_box_resting_on_the_floor_is_one_run(caster):
    """A 1 m cube on the floor (its bottom in the floor's plane) at ground range 14 m: label rays through its top
    leave through its bottom exactly where the floor is, and the floor under it (slant range up to √(14.5² + 10²))
    lies beyond its lit top, in its shadow. The hidden floor is found there whichever of the two coplanar faces a
    caster reports: the shadow is one run from the top's far edge to R_end = h·R_top/(h − 1), no water in it."""
    from sonar_embree import raycast

    scene = flat_scene().add(box((1.0, 1.0, 1.0), (0.0, 14.0, 0.5)), label="box")
    rec = se.simulate(scene, line_along_x(2, length=0.2), se.Sonar(max_range_m=25.0), quality=0.5, labels=True,
                      caster=getattr(raycast, caster))
    r, dr = rec.slant_range_m, rec.slant_range_m[1]
    r_top = np.hypot(14.5, H - 1.0)
    r_end = H * r_top / (H - 1.0)
    for ping in range(2):
        kind = rec.labels.kind[0, ping]                                  # +y is port
        assert np.all(kind[(r > r_top + 2 * dr) & (r < r_end - 2 * dr)] == SHADOW)
        assert np.count_nonzero(kind == SHADOW) >= (r_end - r_top) / dr - 4


def test_seafloor_caster_covers_exactly_the_seafloor():
    """prepared.seafloor_caster: the caster itself when every object is seafloor, none without a seafloor, else a
    caster of the same class over the seafloor's triangles, mapped back to the scene's, built once per RunCache."""
    from sonar_embree.propagation.prepared import RunCache, seafloor_caster
    from sonar_embree.raycast import EmbreeCaster, NumpyCaster

    scene = flat_scene().add(box((1.0, 1.0, 1.0), (0.0, 14.0, 0.5)), label="box")
    c = scene.compiled()
    for cls in (EmbreeCaster, NumpyCaster):
        caster, cache = cls(c), RunCache()
        assert seafloor_caster(caster, np.ones(2, bool)).caster is caster
        assert seafloor_caster(caster, np.ones(2, bool)).faces is None
        assert seafloor_caster(caster, np.zeros(2, bool)).caster is None
        got = seafloor_caster(caster, c.is_seafloor, cache)
        sea, faces = got.caster, got.faces
        assert type(sea) is cls and sea is not caster and seafloor_caster(caster, c.is_seafloor, cache) is got
        assert seafloor_caster(caster, c.is_seafloor).caster is not sea        # without a cache: built anew
        np.testing.assert_array_equal(faces, np.flatnonzero(c.face_object == 0))
        # straight down through the box's top: the full scene hits the box, the seafloor caster the floor under it
        o = np.array([[0.0, 14.0, 5.0]], np.float32) - c.origin_m.astype(np.float32)
        d = np.array([[0.0, 0.0, -1.0]], np.float32)
        p_all, t_all = caster.cast_raw(o, d, 10.0)
        p_sea, t_sea = sea.cast_raw(o, d, 10.0)
        assert c.face_object[p_all[0]] == 1 and c.face_object[faces[p_sea[0]]] == 0
        assert t_all[0] == pytest.approx(4.0) and t_sea[0] == pytest.approx(5.0)


def test_seafloor_is_chosen_by_label_or_explicitly():
    s = se.Scene().add(se.seafloor.flat((10, 10)), label="seafloor/sand")
    s.add(se.seafloor.flat((10, 10), z_m=-5), label="rock")
    s.add(se.seafloor.flat((10, 10), z_m=-9), label="bed", seafloor=True)
    assert s.compiled().is_seafloor.tolist() == [True, False, True]


def test_labels_survive_save_and_load(tmp_path, wall_record):
    wall_record.save(tmp_path / "r.npz")
    back = se.Record.load(tmp_path / "r.npz")
    for k in Labels.ARRAYS:
        np.testing.assert_array_equal(getattr(back.labels, k), getattr(wall_record.labels, k))
    assert back.labels.names == wall_record.labels.names
    assert back.labels.is_seafloor == wall_record.labels.is_seafloor


@pytest.mark.parametrize("source", ["echo", "centre"])
def test_boxes_cover_the_objects_pixels(wall_record, source):
    lab = wall_record.labels
    for cols in (None, 64):
        boxes = lab.boxes(cols, source=source)
        assert [b["label"] for b in boxes] == ["box"]
        x, y, w, hgt = boxes[0]["bbox"]
        sel = lab.echo_mask(1) if source == "echo" else (lab.kind == OBJECT) & (lab.object_id == 1)
        mask = lab.mask(sel, cols)
        np.testing.assert_array_equal(boxes[0]["mask"], mask)
        inside = np.zeros_like(mask)
        inside[y:y + hgt, x:x + w] = True
        assert mask.any() and not np.any(mask & ~inside)
        # tight: every edge of the box touches a pixel of the object
        assert mask[y].any() and mask[y + hgt - 1].any() and mask[:, x].any() and mask[:, x + w - 1].any()
        assert boxes[0]["shadow_bbox"] is not None
        # port is mirrored on the left half of the image
        assert x + w <= mask.shape[1] // 2


def test_label_rows_matches_its_numpy_twin(rng):
    rows, n_s, dr = 4, 60, 0.25
    counts = rng.integers(0, 7, rows)
    el_start = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    n = int(el_start[-1])
    pos = rng.normal(size=(rows // 2, 3))

    def rays():
        rr = rng.uniform(1.0, 14.0, n)
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        u = rng.normal(size=(n, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        row = np.repeat(np.arange(rows), counts)
        pt = pos[row // 2] + rr[:, None] * u
        return rr, rng.uniform(0.0, 1.5, n), pt, d

    lr, le, lp, ld = rays()
    hr, he, hp, hd = rays()
    score = np.where(rng.random(n) < 0.7, rng.random(n), 0.0)
    hr[rng.random(n) < 0.5] = np.nan
    obj = rng.integers(0, 3, n).astype(np.int32)
    hobj = rng.integers(0, 3, n).astype(np.int32)
    floor = np.array([True, False, False])
    out = (np.zeros((rows, n_s), np.int8), np.zeros((rows, n_s), np.int32), np.zeros((rows, n_s), np.int32),
           np.zeros((rows, n_s), np.float32), np.zeros((rows, n_s), np.float32))
    pos_rows = np.repeat(pos, 2, axis=0)                                # each row's ping's position
    outward = np.tile([[0.0, -1.0], [0.0, 1.0]], (rows // 2, 1))      # port, starboard of a ping heading +x
    kernels.label_rows(el_start, dr, Footprints(lr, le, obj, lp, ld), score, Footprints(hr, he, hobj, hp, hd),
                       pos_rows, outward, floor, 2.5, np.empty((rows, n_s)), LabelOut(*out))
    want = naive.label_rows(el_start, dr, lr, le, score, obj, lp, ld, hr, he, hobj, hp, hd, pos_rows, outward, floor,
                            2.5, n_s)
    for got, ref in zip(out[:3], want[:3]):
        np.testing.assert_array_equal(got, ref)
    for got, ref in zip(out[3:], want[3:]):
        np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-4)
    assert np.any(out[0] == 3) and np.any(out[0] == 2) and np.any(out[0] == 1) and np.any(out[0] == 0)
    assert np.any(out[4] < 0) and np.any(out[4] > 0)                  # points on both sides of the rows' pings


def test_a_survey_in_pieces_equals_one_run_with_noise_speckle_and_labels():
    scene = flat_scene().add(box((2.0, 2.0, 1.0), (0.0, 12.0, 0.5)), label="box")
    traj = line_along_x(6, length=3.0)
    kw = dict(speckle=True, noise_db_per_hz=-190.0, seed=3, labels=True)
    sonar = se.Sonar(max_range_m=20.0)
    whole = se.simulate(scene, traj, sonar, **kw)
    parts = [se.simulate(scene, traj[a:b], sonar, ping_offset=a, **kw) for a, b in ((0, 2), (2, 6))]
    np.testing.assert_array_equal(np.concatenate([p.port for p in parts]), whole.port)
    np.testing.assert_array_equal(np.concatenate([p.starboard for p in parts]), whole.starboard)
    joined = Labels.concatenate([p.labels for p in parts])
    for k in Labels.ARRAYS:
        np.testing.assert_array_equal(getattr(joined, k), getattr(whole.labels, k))
    shifted = se.simulate(scene, traj[2:6], sonar, **kw)  # without the offset the noise differs
    assert not np.array_equal(shifted.port, parts[1].port)


def test_ping_offset_must_be_a_count():
    with pytest.raises(se.ConfigError, match="ping_offset"):
        se.simulate(flat_scene(), line_along_x(1), ping_offset=-1)


def test_an_echo_heard_past_nadir_is_labelled_on_its_true_side():
    """Issue 49: near a DEM's edge the port channel hears the starboard seabed past nadir; its labels (and the
    mosaic placed from them) put those echoes on starboard, at a negative ground range, not on a port side where
    no seabed exists."""
    from sonar_embree.survey.mosaic import sample_positions

    floor = se.seafloor.flat((60.0, 30.0), center_m=(0.0, -15.5))       # y in [-30.5, -0.5]: starboard only
    scene = se.Scene().add(floor, label="seafloor", seafloor=True)
    sonar = se.Sonar(frequency_hz=400e3, length_m=0.19, height_m=0.0038, tilt_deg=20, max_range_m=30)
    rec = se.simulate(scene, se.Trajectory.line((-1, 0, 10), (1, 0, 10), 3), sonar, se.Pulse.cw(duration_s=100e-6),
                      labels=True, start_time="2000-01-01")
    lab = rec.labels
    port_floor, stbd_floor = lab.kind[0] == 1, lab.kind[1] == 1
    assert port_floor.any() and rec.port.sum() > 0                       # the port channel does hear it
    np.testing.assert_array_less(lab.ground_range_m[0][port_floor], -0.49)
    assert np.all(lab.ground_range_m[1][stbd_floor] > 0.49)
    x, y = sample_positions(rec)
    assert np.all(y[0][port_floor] < -0.49) and np.all(y[1][stbd_floor] < -0.49)   # both on starboard (−y)
