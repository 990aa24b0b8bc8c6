"""The project's own BVH caster (issue 37 item 5): the Karras hierarchy against a recursive twin, its boxes, its
hits against Embree and the reference caster, the whole pipeline through it, and the CUDA build of the same code
through numba's CUDA simulator (a subprocess: the simulator is chosen when numba loads)."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh

import sonar_embree as se
from conftest import box, flat_scene
from sonar_embree import kernels
from sonar_embree.raycast import BvhCaster, CudaCaster, EmbreeCaster, NumpyCaster
from sonar_embree.raycast.bvh import build_bvh

HERE = os.path.dirname(os.path.abspath(__file__))


def _reference_scene(rng):
    """The reference-caster test scene (tests/raycast/test_reference_caster.py): a rough height field and a box."""
    heights = rng.uniform(-0.3, 0.3, (9, 9))
    floor = se.seafloor.from_heights(heights, spacing_m=6.0, origin_m=(-24, -24))
    return se.Scene().add(floor, label="seafloor").add(box((1.0, 2.0, 1.0), (0.0, -12.0, 0.5)), label="box")


def _rays(rng, c, n):
    d = rng.normal(size=(n, 3))
    d[:, 2] = -np.abs(d[:, 2])
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = np.broadcast_to(np.array([0.0, 0.0, 10.0]) - c.origin_m, (n, 3))
    return np.ascontiguousarray(o, dtype=np.float32), np.ascontiguousarray(d, dtype=np.float32)


def _recursive_tree(keys, first, last):
    """The binary radix tree by its definition: split a run of sorted unique keys where the highest bit in which
    its ends differ turns from 0 to 1. Leaves are ("leaf", k); a node is (left, right)."""
    if first == last:
        return ("leaf", first)
    bit = (int(keys[first]) ^ int(keys[last])).bit_length() - 1
    split = first
    while not (int(keys[split + 1]) >> bit) & 1:
        split += 1
    return (_recursive_tree(keys, first, split), _recursive_tree(keys, split + 1, last))


def _kernel_tree(child, node, n):
    if node >= n - 1:
        return ("leaf", node - (n - 1))
    return (_kernel_tree(child, child[node, 0], n), _kernel_tree(child, child[node, 1], n))


@pytest.mark.parametrize("n, spread", [(2, 4), (3, 1), (97, 2 ** 30), (500, 64), (300, 1)])
def test_the_linear_bvh_is_the_radix_tree_of_its_keys(rng, n, spread):
    """Karras's parallel construction gives the tree the recursive highest-bit split gives, duplicates (ties broken
    by position) included; spread 1: every code equal."""
    codes = np.sort(rng.integers(0, spread, n)).astype(np.int64)
    child = np.empty((n - 1, 2), dtype=np.int32)
    kernels.lbvh_children(codes, child)
    keys = [(int(c) << 32) | k for k, c in enumerate(codes)]      # codes, then positions: unique keys
    assert _kernel_tree(child, 0, n) == _recursive_tree(keys, 0, n - 1)


def test_morton_codes_interleave_the_quantised_box_centres(rng):
    """kernels.morton_codes against its twin: each box centre quantised to 10 bits per axis in the mesh's bounds,
    the bits of x, y and z interleaved one by one (x highest), written out bit by bit here."""
    lo = rng.uniform(-50.0, 50.0, (300, 3)).astype(np.float32)
    hi = lo + rng.uniform(0.0, 3.0, (300, 3)).astype(np.float32)
    lo[:, 2] = hi[:, 2] = 1.5                                   # a flat axis: its coordinate is the middle, 512
    got = np.empty(300, dtype=np.int64)
    kernels.morton_codes(lo, hi, got)
    b_lo, b_hi = lo.min(axis=0).astype(float), hi.max(axis=0).astype(float)
    for i in range(300):
        centre = 0.5 * (lo[i].astype(float) + hi[i].astype(float))
        q = [min(max(int((centre[a] - b_lo[a]) / (b_hi[a] - b_lo[a]) * 1024.0), 0), 1023) if b_hi[a] > b_lo[a]
             else 512 for a in range(3)]
        want = sum(((q[a] >> bit) & 1) << (3 * bit + 2 - a) for bit in range(10) for a in range(3))
        assert got[i] == want, i


def test_boxes_hold_their_triangles_and_children(rng):
    c = _reference_scene(rng).compiled()
    box_, child, tri, v0, v1, v2 = build_bvh(c)
    n = tri.shape[0]
    corners = np.asarray(c.vertices, dtype=np.float32)[c.faces][tri]
    np.testing.assert_array_equal(box_[n - 1:, :3], corners.min(axis=1))
    np.testing.assert_array_equal(box_[n - 1:, 3:], corners.max(axis=1))
    for k in range(2):
        assert np.all(box_[:n - 1, :3] <= box_[child[:, k], :3]) and np.all(box_[:n - 1, 3:] >= box_[child[:, k], 3:])
    assert sorted(tri) == list(range(n))                           # every triangle in one leaf
    assert sorted(np.concatenate([child.ravel(), [0]])) == list(range(2 * n - 1))   # a tree: each node one parent
    np.testing.assert_array_equal(v1, np.asarray(c.vertices, dtype=np.float32)[c.faces[:, 1]])


def test_bvh_caster_agrees_with_embree_and_the_reference_ray_by_ray(rng):
    c = _reference_scene(rng).compiled()
    o32, d32 = _rays(rng, c, 4000)
    pe, te = EmbreeCaster(c).cast_raw(o32, d32, 40.0)
    pb, tb = BvhCaster(c).cast_raw(o32, d32, 40.0)
    pn, tn = NumpyCaster(c).cast_raw(o32, d32, 40.0)
    assert (pe >= 0).sum() > 1000 and (pe < 0).sum() > 100
    for p, t in ((pe, te), (pn, tn)):
        same = p == pb
        assert same.mean() > 0.999                  # a ray through a shared edge may pick either triangle
        hit = same & (p >= 0)
        np.testing.assert_allclose(tb[hit], t[hit], rtol=2e-6)
    np.testing.assert_array_equal(tb[pb < 0], np.float32(40.0))


def test_rays_aimed_at_every_shared_edge_and_vertex_from_afar_all_hit():
    """Watertight: a flat 1 m-gridded floor, rays from 50–70 m aimed at the vertices and at points a quarter, half
    and three quarters along every interior edge. Each hits (a float32 ray test with a slack of 1e-6 let 4 % of
    them through; the test in float64 on the float32 vertices lets none), as each does in Embree."""
    floor = se.seafloor.from_heights(np.zeros((41, 41)), 1.0, (-20.0, -20.0))
    c = se.Scene().add(floor, label="seafloor").compiled()
    v, f = np.asarray(c.vertices), np.asarray(c.faces)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    edges = edges[np.all(np.abs(v[edges][:, :, :2] + c.origin_m[:2]) < 19.5, axis=(1, 2))]
    pts = np.concatenate([v[edges[:, 0]] * (1 - w) + v[edges[:, 1]] * w for w in (0.0, 0.25, 0.5, 0.75)])
    caster = BvhCaster(c)
    for o in ([0.0, -60.0, 12.0], [45.0, 30.0, 8.0], [-50.0, 10.0, 5.0]):
        o = np.array(o) - c.origin_m
        d = pts - o
        d /= np.linalg.norm(d, axis=1)[:, None]
        o32, d32 = np.broadcast_to(o, d.shape).astype(np.float32), d.astype(np.float32)
        assert np.all(EmbreeCaster(c).cast_raw(o32, d32, 200.0)[0] >= 0)
        assert np.all(caster.cast_raw(o32, d32, 200.0)[0] >= 0)


@pytest.mark.parametrize("n_faces", [1, 2])
def test_one_and_two_triangle_scenes(n_faces):
    """The smallest trees: one triangle (the root is its leaf) and two (one internal node)."""
    v = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])[:n_faces]
    c = se.Scene().add(trimesh.Trimesh(v, faces, process=False), label="plate").compiled()
    o = (np.array([[0.5, -0.5, 3.0], [-0.5, 0.5, 3.0], [5.0, 5.0, 3.0]]) - c.origin_m).astype(np.float32)
    d = np.tile(np.array([0.0, 0.0, -1.0], dtype=np.float32), (3, 1))
    pb, tb = BvhCaster(c).cast_raw(o, d, 10.0)
    pe, te = EmbreeCaster(c).cast_raw(o, d, 10.0)
    np.testing.assert_array_equal(pb, pe)
    assert pb[0] == 0 and pb[2] == -1 and (pb[1] == 1) == (n_faces == 2)
    np.testing.assert_allclose(tb[pb >= 0], 3.0, rtol=1e-6)


def test_cuda_caster_without_a_gpu_is_a_one_line_error(monkeypatch):
    monkeypatch.setattr(kernels, "cuda_available", lambda: False)
    c = flat_scene().compiled()
    with pytest.raises(se.ConfigError, match="CudaCaster: numba.cuda finds no GPU.*NUMBA_ENABLE_CUDASIM"):
        CudaCaster(c)


CUDA_SCRIPT = """
import json, sys
import numpy as np
sys.path.insert(0, {here!r})
from test_bvh_caster import _reference_scene, _rays
from sonar_embree.raycast import CudaCaster, EmbreeCaster
rng = np.random.default_rng(7)
c = _reference_scene(rng).compiled()
o, d = _rays(rng, c, 600)
pc, tc = CudaCaster(c).cast_raw(o, d, 40.0)
pe, te = EmbreeCaster(c).cast_raw(o, d, 40.0)
same = (pc == pe)
hit = same & (pe >= 0)
empty = len(CudaCaster(c).cast_raw(o[:0], d[:0], 1.0)[0])
print(json.dumps(dict(same=float(same.mean()), hits=int(hit.sum()), misses=int((pe < 0).sum()),
                      rel=float(np.max(np.abs(tc[hit] / te[hit] - 1.0))), empty=empty)))
"""


def test_cuda_caster_through_numbas_cuda_simulator():
    """The CUDA kernel (device functions, local stack, one ray per thread, the copies to and from the device) run
    by numba's CUDA simulator on the reference scene: the same hits as Embree to float32."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    out = subprocess.run([sys.executable, "-c", CUDA_SCRIPT.format(here=HERE)], env=env, capture_output=True,
                         text=True, timeout=600, cwd=os.path.dirname(HERE))
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["same"] > 0.995 and r["hits"] > 200 and r["misses"] > 20 and r["empty"] == 0
    assert r["rel"] < 2e-6
