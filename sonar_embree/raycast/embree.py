"""The Embree caster (embreex): the only module that imports embreex.

Geometry enters Embree in float32 relative to the scene's local origin; the float64
refit of every hit is the interface's (:class:`sonar_embree.raycast.Caster`).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from embreex import rtcore_scene as rtcs
from embreex.mesh_construction import TriangleMesh

from .. import kernels
from ..scene import CompiledScene
from .base import Caster

#: Batches of at least this many rays are split over threads (Embree releases the GIL).
THREADED_MIN_RAYS = 16384


class EmbreeCaster(Caster):
    """An Embree BVH of a :class:`CompiledScene`, built once and cast many times."""

    def __init__(self, compiled: CompiledScene, threads: int | None = None):
        """Build the BVH. ``threads``: Embree calls in parallel per batch (default: the threads Numba's kernels run
        on at each call, ``kernels.set_num_threads``, so that the caster a scene keeps follows a later change of
        it; a single-threaded worker process casts on one)."""
        self.compiled = compiled
        self._scene = rtcs.EmbreeScene()
        TriangleMesh(self._scene, compiled.vertices.astype(np.float32),
                     compiled.faces.astype(np.int32))
        self._fixed = None if threads is None else max(int(threads), 1)
        size = self._fixed if self._fixed is not None else kernels.max_threads()
        self._pool = ThreadPoolExecutor(size) if size > 1 else None
        one = np.zeros((1, 3), dtype=np.float32)
        self._scene.run(one, one + np.float32([0, 0, 1]), dists=np.ones(1, np.float32), output=0)  # build the BVH now

    @property
    def threads(self) -> int:
        """Embree calls in parallel per batch now: the fixed count, or Numba's current thread count."""
        return self._fixed if self._fixed is not None else kernels.num_threads()

    def _run(self, origins_f32, directions_f32, dists_f32, output: int | None, query: str = "INTERSECT"):
        n, threads = directions_f32.shape[0], self.threads
        if self._pool is None or threads < 2 or n < THREADED_MIN_RAYS:
            return self._scene.run(origins_f32, directions_f32, dists=dists_f32, query=query, output=output)
        cuts = np.linspace(0, n, threads + 1).astype(int)  # each ray is independent: same bits for any split
        parts = list(self._pool.map(
            lambda ab: self._scene.run(origins_f32[ab[0]:ab[1]], directions_f32[ab[0]:ab[1]],
                                       dists=dists_f32[ab[0]:ab[1]], query=query, output=output),
            zip(cuts[:-1], cuts[1:])))
        if output != 1:
            return np.concatenate(parts)
        return {k: np.concatenate([np.asarray(p[k]) for p in parts]) for k in ("primID", "tfar")}

    def occluded(self, origins_f32, directions_f32, dists_f32):
        """Embree's occlusion query (any hit before each ray's own distance); as :meth:`Caster.occluded`.

        Embree writes into the distances it is given: a contiguous float32 ``dists_f32`` is overwritten."""
        if directions_f32.shape[0] == 0:
            return np.zeros(0, dtype=bool)
        return np.asarray(self._run(origins_f32, directions_f32, np.ascontiguousarray(dists_f32, dtype=np.float32),
                                    None, "OCCLUDED")) >= 0

    def cast_segments(self, origins_f32, directions_f32, dists_f32):
        """Embree's first hits on segments of their own lengths; as :meth:`Caster.cast_segments`.

        Embree writes each hit distance into the distances it is given: a contiguous float32 ``dists_f32`` is
        overwritten (the returned ``tfar`` may be that array)."""
        if directions_f32.shape[0] == 0:
            return np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.float32)
        res = self._run(origins_f32, directions_f32, np.ascontiguousarray(dists_f32, dtype=np.float32), 1)
        return (np.ascontiguousarray(res["primID"], dtype=np.int32),
                np.ascontiguousarray(res["tfar"], dtype=np.float32))

    def cast_raw(self, origins_f32, directions_f32, max_range_m: float):
        """Embree's first hits, unrefined; as :meth:`Caster.cast_raw`."""
        n = directions_f32.shape[0]
        if n == 0:
            return np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.float32)
        res = self._run(origins_f32, directions_f32, np.full(n, max_range_m, dtype=np.float32), 1)
        return (np.ascontiguousarray(res["primID"], dtype=np.int32),
                np.ascontiguousarray(res["tfar"], dtype=np.float32))
