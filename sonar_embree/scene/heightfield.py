"""Which objects of a scene are height fields, and the objects' bounding boxes (docs/physics.md §13).

A height field here is a mesh that is the graph z = f(x, y) of one continuous function over its own xy
bounding rectangle: every vertical line through the rectangle crosses it exactly once. Seafloors made by
:mod:`sonar_embree.scene.seafloor` are; a wreck, a box or a seafloor turned about z is not (the test is
conservative: a mesh it does not recognise is treated as any other object). Multipath uses it to skip
visibility legs that such a floor provably cannot block (:func:`sonar_embree.propagation.multipath.block_legs`).
"""
from __future__ import annotations

import numpy as np

#: Relative tolerance of the area test (an integer cover count is told apart far more finely).
AREA_RTOL = 1e-6


def is_heightfield(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Whether the mesh is a height field over its xy bounding rectangle.

    Sufficient conditions, all checked: every face looks up (its projected area, counter-clockwise, is > 0);
    no directed edge is used twice (the projection is one-to-one along every edge); every edge without its
    reverse (a boundary edge) lies on one side of the rectangle; and the projected areas add up to the
    rectangle's. The projection is then a map of constant degree over the rectangle (orientation kept, the
    boundary on its border), and the area sum says that degree is 1.

    Parameters
    ----------
    vertices : (v, 3) float64
        m, any frame with z up.
    faces : (f, 3) int
        The object's triangles (indices into ``vertices``; other vertices are ignored).
    """
    f = np.asarray(faces, dtype=np.int64)
    x, y = vertices[:, 0], vertices[:, 1]
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    cross = (x[b] - x[a]) * (y[c] - y[a]) - (y[b] - y[a]) * (x[c] - x[a])
    if f.shape[0] == 0 or not np.all(cross > 0.0):
        return False
    used = np.zeros(vertices.shape[0], dtype=bool)
    used[f.ravel()] = True
    lo, hi = np.array([x[used].min(), y[used].min()]), np.array([x[used].max(), y[used].max()])
    area = float(np.prod(hi - lo))
    if not (area > 0.0 and abs(0.5 * float(cross.sum()) - area) <= AREA_RTOL * area):
        return False
    return _edges_bound_rectangle(np.column_stack([x, y]), f, lo, hi)


def _edges_bound_rectangle(xy: np.ndarray, f: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """No directed edge twice, and every edge without its reverse on one side of the rectangle [lo, hi]."""
    nv = np.int64(xy.shape[0])
    start = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    end = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    key = np.sort(start * nv + end)
    if np.any(key[1:] == key[:-1]):
        return False
    rev = end * nv + start
    at = np.minimum(np.searchsorted(key, rev), key.shape[0] - 1)
    open_ = key[at] != rev
    tol = 1e-9 * float(np.max(hi - lo))
    p, q = xy[start[open_]], xy[end[open_]]
    on_side = np.zeros(p.shape[0], dtype=bool)
    for axis in (0, 1):
        for bound in (lo[axis], hi[axis]):
            on_side |= (np.abs(p[:, axis] - bound) <= tol) & (np.abs(q[:, axis] - bound) <= tol)
    return bool(np.all(on_side))


def object_bounds(vertices: np.ndarray, faces: np.ndarray, face_object: np.ndarray, n_objects: int) -> np.ndarray:
    """(n_objects, 2, 3) min and max corner of each object's triangles, m (an object without faces: +inf, −inf);
    objects share no vertices (as in a :class:`~sonar_embree.scene.CompiledScene`).

    One pass over the vertices (grouped by object with a stable sort, which is linear on a compiled scene's
    already grouped vertices), not one per object."""
    out = np.empty((n_objects, 2, 3))
    out[:, 0], out[:, 1] = np.inf, -np.inf
    vert_obj = np.full(vertices.shape[0], -1, dtype=np.int64)
    vert_obj[faces.ravel()] = np.repeat(face_object, 3)
    used = np.flatnonzero(vert_obj >= 0)
    if used.size == 0:
        return out
    order = used[np.argsort(vert_obj[used], kind="stable")]
    objs = vert_obj[order]
    starts = np.flatnonzero(np.concatenate(([True], objs[1:] != objs[:-1])))
    v = vertices[order]
    out[objs[starts], 0] = np.minimum.reduceat(v, starts, axis=0)
    out[objs[starts], 1] = np.maximum.reduceat(v, starts, axis=0)
    return out
