"""Embree casting: hit data, back faces, grazing rays, shared edges, float64 ranges, determinism."""
import numpy as np
import pytest

import sonar_embree as se
from sonar_embree.raycast import BvhCaster, RayCaster
from conftest import box, flat_scene, line_along_x


#: Embree, and the project's own BVH (the GPU caster's code, run on the CPU): the same contract.
CASTERS = pytest.mark.parametrize("cls", [RayCaster, BvhCaster], ids=["embree", "bvh"])


def _caster(*meshes, cls=RayCaster):
    scene = se.Scene()
    for i, m in enumerate(meshes):
        scene.add(m, label=f"m{i}")
    return cls(scene.compiled()), scene.compiled()


@CASTERS
def test_hit_fields_and_back_faces(cls):
    caster, c = _caster(se.seafloor.flat((10, 10)), box((1, 1, 1), (3, 0, 2)), cls=cls)
    o = np.array([0.0, 0.0, 5.0]) - c.origin_m
    d = np.array([[0, 0, -1.0], [0.6, 0, -0.8], [0, 0, 1.0]])
    h = caster.cast(o, d, 100.0)
    assert h.tri[0] >= 0 and h.range_m[0] == pytest.approx(5.0, abs=1e-12)
    np.testing.assert_allclose(h.normal[0], [0, 0, 1])
    assert c.labels[h.object_id[0]] == "m0" and h.cos_inc[0] == pytest.approx(1.0)
    assert h.echo[0]
    assert h.tri[2] == -1 and np.isinf(h.range_m[2]) and h.object_id[2] == -1 and not h.echo[2]
    # from below the floor: the back face is hit, occludes, but returns no echo
    hb = caster.cast(np.array([0.0, 0.0, -1.0]) - c.origin_m, np.array([[0, 0, 1.0]]), 100.0)
    assert hb.tri[0] >= 0 and hb.cos_inc[0] < 0 and not hb.echo[0]


@CASTERS
def test_range_limit_and_grazing(cls):
    caster, c = _caster(se.seafloor.flat((100, 100)), cls=cls)
    o = np.array([0.0, 0.0, 1.0]) - c.origin_m
    h = caster.cast(o, np.array([[0, 0, -1.0]]), 0.5)
    assert h.tri[0] == -1                                   # beyond max range: a miss
    graze = caster.cast(np.array([0.0, 0.0, 0.0]) - c.origin_m, np.array([[1.0, 0, 0]]), 50.0)
    assert not graze.echo[0]                                # in-plane ray: never an echo


@CASTERS
def test_shared_edges_and_vertices_neither_leak_nor_double_count(cls):
    """Rays aimed exactly at the diagonal edge and the centre vertex of a gridded floor all hit once."""
    floor = se.seafloor.from_heights(np.zeros((3, 3)), 1.0, (-1.0, -1.0))   # shared edges through (0,0)
    caster, c = _caster(floor, cls=cls)
    targets = np.array([[0, 0, 0], [0.5, 0.5, 0], [-0.5, -0.5, 0], [0, 0.5, 0], [0.5, 0, 0], [-1, 1, 0.0]])
    o = np.array([0.3, -0.2, 3.0])
    d = targets - o
    d /= np.linalg.norm(d, axis=1)[:, None]
    h = caster.cast(o - c.origin_m, d, 10.0)
    assert np.all(h.tri >= 0) and np.all(h.echo)
    np.testing.assert_allclose(h.range_m, np.linalg.norm(targets - o, axis=1), rtol=1e-12)


@CASTERS
def test_float64_ranges_at_utm_scale_on_sloped_facets(cls):
    off = np.array([512_000.0, 5_412_000.0, 0.0])
    z = np.array([[0.0, 0.7], [0.3, 1.3]])
    caster, c = _caster(se.seafloor.from_heights(z, 10.0, (off[0], off[1])), cls=cls)
    o = off + [3.1, 4.7, 20.0]
    d = np.array([[0.05, 0.03, -1.0]])
    d /= np.linalg.norm(d)
    h = caster.cast(o - c.origin_m, d, 100.0)
    # exact plane intersection in float64, world coordinates
    v = np.array([[0, 0, 0.0], [10, 0, 0.7], [10, 10, 1.3], [0, 10, 0.3]]) + off
    for tri in ([0, 1, 2], [0, 2, 3]):
        p0, p1, p2 = v[tri]
        n = np.cross(p1 - p0, p2 - p0)
        t = np.dot(p0 - o, n) / np.dot(d[0], n)
        x = o + t * d[0] - p0
        if (x[0] >= -1e-9) and (x[1] >= -1e-9) and x[0] <= 10 and x[1] <= 10 and \
                np.dot(np.cross(p1 - p0, x), np.cross(x, p2 - p0)) >= 0:
            assert h.range_m[0] == pytest.approx(t, abs=1e-9)
            break
    else:
        pytest.fail("reference intersection not found")


def test_same_inputs_same_bits():
    scene = flat_scene().add(box((1, 1, 1), (0, -15, 0.5)), label="box")
    a = se.simulate(scene, line_along_x(n_pings=3), se.Sonar(max_range_m=20))
    b = se.simulate(scene, line_along_x(n_pings=3), se.Sonar(max_range_m=20))
    assert a.starboard.tobytes() == b.starboard.tobytes() and a.port.tobytes() == b.port.tobytes()


@pytest.mark.parametrize("mode", [{}, {"speckle": True}, {"speckle": True, "band": "carrier"},
                                  {"speckle": True, "band": "carrier", "detection": "incoherent"},
                                  {"speckle": True, "tvg": True, "lowpass_hz": 5e3}])
def test_empty_range_window_gives_zero_record(mode):
    from conftest import decoy_above

    traj = line_along_x(n_pings=2, z=80.0)
    with pytest.raises(se.ConfigError, match="nothing of the scene lies within"):
        se.simulate(flat_scene(), traj, se.Sonar(max_range_m=50), **mode)
    rec = se.simulate(flat_scene().add(decoy_above(traj), label="decoy"), traj, se.Sonar(max_range_m=50), **mode)
    assert np.all(rec.port == 0) and np.all(rec.starboard == 0) and np.all(np.isnan(rec.altitude_m))


def test_the_default_embree_caster_follows_numbas_thread_count():
    """A scene keeps its caster between runs: one built on two threads casts on one once Numba is set to one
    (bench_scale's "one thread" had cast on two), and a count given when it was built stays."""
    from sonar_embree import kernels

    caster, c = _caster(se.seafloor.flat((10, 10)))
    was = kernels.num_threads()
    try:
        kernels.set_num_threads(1)
        assert caster.threads == 1
        kernels.set_num_threads(kernels.max_threads())
        assert caster.threads == kernels.max_threads()
    finally:
        kernels.set_num_threads(was)
    assert RayCaster(c, threads=3).threads == 3
