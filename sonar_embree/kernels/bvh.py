"""A linear BVH over a triangle mesh and its first-hit traversal: the kernels of the CUDA caster (docs/physics.md
§8b).

The hierarchy is Karras's (T. Karras, "Maximizing parallelism in the construction of BVHs, octrees, and k-d
trees", Proc. High-Performance Graphics 2012, 33–37): triangles sorted by the 30-bit Morton code of their
centroids, each internal node i covering a run of sorted keys whose split is the first position where the
highest differing bit of the keys changes; ties between equal codes are broken by the key's index. Internal
nodes are 0 … n − 2 (0 the root), leaves n − 1 … 2n − 2 (leaf n − 1 + k holds the k-th sorted triangle). Boxes
are float32, taken from the float32 vertices the ray test uses, so they hold their triangles exactly.

The traversal (:func:`first_hit`) is written once, as functions that Numba compiles for whichever target calls
them (``register_jitable``): :func:`traverse_cpu` runs it on the CPU threads, :func:`cuda_traverse` on a GPU
(compiled on first use, so that nothing loads ``numba.cuda`` unless a CUDA caster is made). The device code
uses no builtin min/max (numba 0.68's CUDA target does not compile them). The boxes are tested in float32; the
ray test is Möller–Trumbore (T. Möller and B. Trumbore, "Fast, minimum storage ray-triangle intersection",
Journal of Graphics Tools 2(1), 21–28, 1997) in float64 on the float32 vertices, with a barycentric slack of
:data:`EDGE_SLACK`, so that a ray through an edge shared by two triangles hits one of them rather than slipping
between.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ._numba import cuda_module, njit, prange, register_jitable

#: Nodes a traversal can hold pending: at most one per level and the root; the depth is at most 62 (30 code
#: bits, 32 index bits).
STACK_DEPTH = 96
#: Barycentric slack of the ray–triangle test (float64, dimensionless): a ray through an edge shared by two triangles
#: hits one of them. In float32 the test erred by several 10⁻⁶ for a ray 40 m from a 1 m triangle (3 rays in
#: 200 000 slipped through the demo's floor); in float64 on the float32 vertices it errs by ~10⁻¹⁵.
EDGE_SLACK = 1e-9
#: Relative slack on a box's exit distance: float32 rounding of (lo − o)/d must not cull a box the ray grazes
#: (Ize 2013, "Robust BVH ray traversal", takes 1 + 2γ₃; this is 14 times that).
BOX_SLACK = np.float32(1e-5)
_F0, _F1, _TINY = np.float32(0.0), np.float32(1.0), np.float32(1e-30)


@njit(cache=True, nogil=True)
def _spread10(x):
    """The low 10 bits of ``x`` spread to every third bit of a 30-bit word."""
    x &= 0x3FF
    x = (x | (x << 16)) & 0x30000FF
    x = (x | (x << 8)) & 0x300F00F
    x = (x | (x << 4)) & 0x30C30C3
    x = (x | (x << 2)) & 0x9249249
    return x


@njit(cache=True, nogil=True, parallel=True)
def morton_codes(lo, hi, codes):
    """30-bit Morton codes of the triangles' box centres in the mesh's bounds.

    Parameters
    ----------
    lo, hi : (n, 3) float32
        Each triangle's bounding box, m.
    codes : (n,) int64
        Written with the codes (x in the highest of each three bits).
    """
    n = lo.shape[0]
    b_lo, b_hi = np.empty(3), np.empty(3)
    for q in range(3):
        b_lo[q] = lo[:, q].min()
        b_hi[q] = hi[:, q].max()
    for i in prange(n):
        code = 0
        for q in range(3):
            span = b_hi[q] - b_lo[q]
            c = 0.5 * (float(lo[i, q]) + float(hi[i, q]))
            u = (c - b_lo[q]) / span if span > 0.0 else 0.5
            k = min(max(int(u * 1024.0), 0), 1023)
            code |= _spread10(k) << (2 - q)
        codes[i] = code


@njit(cache=True, nogil=True)
def _delta(codes, i, j):
    """Karras's δ(i, j): the length of the common prefix of sorted keys i and j (codes, then indices), −1 outside."""
    n = codes.shape[0]
    if j < 0 or j >= n:
        return -1
    a, b = codes[i], codes[j]
    if a == b:
        return 64 + _clz64(i ^ j)
    return _clz64(a ^ b)


@njit(cache=True, nogil=True)
def _clz64(x):
    """Leading zeros of a non-negative 64-bit integer (64 for 0)."""
    n = 1                                   # the sign bit
    bit = np.int64(1) << 62
    while bit > 0 and (x & bit) == 0:
        n += 1
        bit >>= 1
    return n


@njit(cache=True, nogil=True)
def _range_and_split(codes, i):
    """Karras's construction of internal node i: (first, last, split) of its run of sorted keys."""
    d = 1 if _delta(codes, i, i + 1) - _delta(codes, i, i - 1) > 0 else -1
    d_min = _delta(codes, i, i - d)
    l_max = 2
    while _delta(codes, i, i + l_max * d) > d_min:
        l_max *= 2
    ln = 0
    t = l_max // 2
    while t >= 1:
        if _delta(codes, i, i + (ln + t) * d) > d_min:
            ln += t
        t //= 2
    j = i + ln * d
    d_node = _delta(codes, i, j)
    s = 0
    t = (ln + 1) // 2
    while True:
        if _delta(codes, i, i + (s + t) * d) > d_node:
            s += t
        if t == 1:
            break
        t = (t + 1) // 2
    split = i + s * d + min(d, 0)
    return min(i, j), max(i, j), split


@njit(cache=True, nogil=True, parallel=True)
def lbvh_children(codes, child):
    """The children of every internal node of the linear BVH over sorted ``codes``.

    Parameters
    ----------
    codes : (n,) int64
        Morton codes in ascending order, n ≥ 2.
    child : (n − 1, 2) int32
        Written with the left and right child of each internal node (≥ n − 1: a leaf).
    """
    n = codes.shape[0]
    for i in prange(n - 1):
        first, last, split = _range_and_split(codes, i)
        child[i, 0] = split + n - 1 if split == first else split
        child[i, 1] = split + 1 + n - 1 if split + 1 == last else split + 1


@njit(cache=True, nogil=True)
def lbvh_boxes(child, leaf_lo, leaf_hi, box):
    """Node boxes bottom-up: leaves from their triangles, each internal node the union of its children.

    Parameters
    ----------
    child : (n − 1, 2) int32
        As :func:`lbvh_children`.
    leaf_lo, leaf_hi : (n, 3) float32
        Boxes of the sorted triangles.
    box : (2n − 1, 6) float32
        Written with (lo, hi) of every node.
    """
    n = leaf_lo.shape[0]
    for k in range(n):
        for q in range(3):
            box[n - 1 + k, q] = leaf_lo[k, q]
            box[n - 1 + k, 3 + q] = leaf_hi[k, q]
    if n < 2:
        return
    order = np.empty(n - 1, dtype=np.int64)    # internal nodes in post-order: children before parents
    stack = np.empty(2 * n, dtype=np.int64)
    top, m = 0, 0
    stack[0] = 0
    visited = np.zeros(n - 1, dtype=np.bool_)
    while top >= 0:
        node = stack[top]
        if visited[node]:
            top -= 1
            order[m] = node
            m += 1
            continue
        visited[node] = True
        for c in range(2):
            if child[node, c] < n - 1:
                top += 1
                stack[top] = child[node, c]
    for k in range(m):
        node = order[k]
        a, b = child[node, 0], child[node, 1]
        for q in range(3):
            box[node, q] = min(box[a, q], box[b, q])
            box[node, 3 + q] = max(box[a, 3 + q], box[b, 3 + q])


@register_jitable
def _smaller(a, b):
    """min(a, b), written out: the builtin does not compile for numba's CUDA target (numba 0.68)."""
    return a if a < b else b


@register_jitable
def _larger(a, b):
    """max(a, b), written out (as :func:`_smaller`)."""
    return a if a > b else b


@register_jitable
def _slab(o, inv, lo, hi):
    """The entry and exit distance of a ray along one axis through [lo, hi]."""
    t0 = (lo - o) * inv
    t1 = (hi - o) * inv
    return _smaller(t0, t1), _larger(t0, t1)


@register_jitable
def _box_entry(box, node, ox, oy, oz, ix, iy, iz, t_best):
    """Where the ray enters node's box, or −1 if it misses it or enters beyond ``t_best``."""
    a0, b0 = _slab(ox, ix, box[node, 0], box[node, 3])
    a1, b1 = _slab(oy, iy, box[node, 1], box[node, 4])
    a2, b2 = _slab(oz, iz, box[node, 2], box[node, 5])
    t_in = _larger(_larger(a0, a1), _larger(a2, _F0))
    t_out = _smaller(_smaller(b0, b1), b2) * (_F1 + BOX_SLACK)
    t_out = _smaller(t_out, t_best * (_F1 + BOX_SLACK))
    return t_in if t_in <= t_out else np.float32(-1.0)


@register_jitable
def _triangle(tri, v0, v1, v2, k, ox, oy, oz, dx, dy, dz, t_best):
    """Möller–Trumbore on triangle ``tri[k]`` in float64: the hit distance (float32), or −1 for no hit nearer
    than ``t_best``.

    The float32 vertices and ray are widened to float64, where their differences are exact: the two triangles of a
    shared edge see the same edge, and the barycentric tests err by ~10⁻¹⁵, far inside :data:`EDGE_SLACK`.
    """
    f = tri[k]
    ax, ay, az = np.float64(v0[f, 0]), np.float64(v0[f, 1]), np.float64(v0[f, 2])
    e1x, e1y, e1z = np.float64(v1[f, 0]) - ax, np.float64(v1[f, 1]) - ay, np.float64(v1[f, 2]) - az
    e2x, e2y, e2z = np.float64(v2[f, 0]) - ax, np.float64(v2[f, 1]) - ay, np.float64(v2[f, 2]) - az
    rx, ry, rz = np.float64(dx), np.float64(dy), np.float64(dz)
    px, py, pz = ry * e2z - rz * e2y, rz * e2x - rx * e2z, rx * e2y - ry * e2x
    det = e1x * px + e1y * py + e1z * pz
    if det == 0.0:
        return np.float32(-1.0)
    inv = 1.0 / det
    sx, sy, sz = np.float64(ox) - ax, np.float64(oy) - ay, np.float64(oz) - az
    u = (sx * px + sy * py + sz * pz) * inv
    if u < -EDGE_SLACK or u > 1.0 + EDGE_SLACK:
        return np.float32(-1.0)
    qx, qy, qz = sy * e1z - sz * e1y, sz * e1x - sx * e1z, sx * e1y - sy * e1x
    v = (rx * qx + ry * qy + rz * qz) * inv
    if v < -EDGE_SLACK or u + v > 1.0 + EDGE_SLACK:
        return np.float32(-1.0)
    t = np.float32((e2x * qx + e2y * qy + e2z * qz) * inv)
    return t if _F0 <= t <= t_best else np.float32(-1.0)


@register_jitable
def _inverse(d):
    """1/d, with a zero component taken as a tiny one of its sign (the slab test then stays finite)."""
    return _F1 / (d if abs(d) > _TINY else math.copysign(_TINY, d))


@register_jitable
def first_hit(box, child, tri, v0, v1, v2, ox, oy, oz, dx, dy, dz, t_max, stack):
    """The nearest triangle hit within ``t_max`` along one ray: (sorted-leaf triangle index or −1, distance).

    ``stack``: (:data:`STACK_DEPTH`,) int32 scratch. Boxes in float32, the triangle test in float64.
    """
    n_int = child.shape[0]
    ix, iy, iz = _inverse(dx), _inverse(dy), _inverse(dz)
    best, t_best = -1, t_max
    top = 0
    stack[0] = 0                               # the root (with a single triangle, its leaf)
    while top >= 0:
        node = stack[top]
        top -= 1
        if _box_entry(box, node, ox, oy, oz, ix, iy, iz, t_best) < _F0:
            continue
        if node >= n_int:
            t = _triangle(tri, v0, v1, v2, node - n_int, ox, oy, oz, dx, dy, dz, t_best)
            if t >= _F0 and (t < t_best or best < 0):
                best, t_best = tri[node - n_int], t
        else:                                  # depth ≤ 62 (30 code bits, 32 index bits): the stack never fills
            stack[top + 1] = child[node, 1]
            stack[top + 2] = child[node, 0]
            top += 2
    return best, t_best


@njit(cache=True, nogil=True, parallel=True)
def traverse_cpu(box, child, tri, v0, v1, v2, origins, dirs, t_max, prim, tfar):
    """First hits of every ray through the BVH on the CPU threads (the GPU kernel's twin, same code).

    Parameters
    ----------
    box, child : the BVH (:func:`lbvh_boxes`, :func:`lbvh_children`)
    tri : (n,) int32
        Triangle of each sorted leaf.
    v0, v1, v2 : (n_faces, 3) float32
        The vertices of every triangle, m.
    origins, dirs : (m, 3) float32
        Rays.
    t_max : float32
        Longest distance searched, m.
    prim : (m,) int32
    tfar : (m,) float32
        Written with the triangle hit (−1: none) and its distance (``t_max`` for none).
    """
    for i in prange(origins.shape[0]):
        stack = np.empty(STACK_DEPTH, dtype=np.int32)
        prim[i], tfar[i] = first_hit(box, child, tri, v0, v1, v2, origins[i, 0], origins[i, 1], origins[i, 2],
                                          dirs[i, 0], dirs[i, 1], dirs[i, 2], t_max, stack)


def _traverse_one_ray(box, child, tri, v0, v1, v2, origins, dirs, t_max, prim, tfar):
    """The GPU kernel's body: one ray per thread, its first hit through the BVH (arguments as
    :func:`traverse_cpu`); ``cuda`` is this module's global, so that numba's simulator can stand in for it."""
    i = cuda.grid(1)
    if i < origins.shape[0]:
        stack = cuda.local.array(STACK_DEPTH, dtype=np.int32)
        p, t = first_hit(box, child, tri, v0, v1, v2, origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0],
                         dirs[i, 1], dirs[i, 2], t_max, stack)
        prim[i] = p
        tfar[i] = t


#: ``numba.cuda``, set by :func:`cuda_traverse` on first use (None until a CUDA caster is made).
cuda = None


@functools.lru_cache(maxsize=1)
def cuda_traverse():
    """The GPU kernel ``traverse[blocks, threads](box, child, tri, v0, v1, v2, origins, dirs, t_max, prim, tfar)``
    (arguments as :func:`traverse_cpu`), compiled by ``numba.cuda`` on first use."""
    global cuda
    cuda = cuda_module()
    return cuda.jit(_traverse_one_ray)


class DeviceBvh:
    """A BVH's arrays on the GPU and the launch of :func:`cuda_traverse` (``threads`` per block).

    Parameters
    ----------
    arrays : tuple
        (box, child, tri, v0, v1, v2) as :func:`traverse_cpu` takes them.
    """

    def __init__(self, arrays: tuple, threads: int = 128):
        cuda = cuda_module()
        self._cuda, self.threads = cuda, int(threads)
        self.arrays = tuple(cuda.to_device(np.ascontiguousarray(a)) for a in arrays)

    def cast(self, origins, dirs, t_max: float):
        """(prim (m,) int32, tfar (m,) float32) of float32 rays (m, 3), as :func:`traverse_cpu` writes them."""
        cuda, m = self._cuda, origins.shape[0]
        prim, tfar = cuda.device_array(m, dtype=np.int32), cuda.device_array(m, dtype=np.float32)
        blocks = (m + self.threads - 1) // self.threads
        cuda_traverse()[blocks, self.threads](*self.arrays, cuda.to_device(origins), cuda.to_device(dirs),
                                             np.float32(t_max), prim, tfar)
        return prim.copy_to_host(), tfar.copy_to_host()


def cuda_available() -> bool:
    """Whether numba.cuda sees a GPU (or runs its simulator, ``NUMBA_ENABLE_CUDASIM=1``); False if it cannot load."""
    try:
        return bool(cuda_module().is_available())
    except Exception:  # noqa: BLE001 - a broken CUDA install is "no GPU" here
        return False
