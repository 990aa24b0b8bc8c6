"""Batched ray casting with Embree (embreex). The only module that imports embreex.

Geometry enters Embree in float32 relative to the scene's local origin; every hit is
then re-intersected with its triangle's plane in float64, so ranges, normals and
incidence are float64 (docs/physics.md §8). Grazing hits (|cos θi| below
:data:`GRAZING_COS`) and hits on the back of a face are flagged: they occlude the ray
but return no echo.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from embreex import rtcore_scene as rtcs
from embreex.mesh_construction import TriangleMesh

from .kernels import REFIT_MIN_COS, REFIT_REL_TOL
from .scene import CompiledScene

#: Hits whose |cos θi| is below this count as grazing: they occlude but return nothing.
GRAZING_COS = 1e-9

#: Batches of at least this many rays are split over threads (Embree releases the GIL).
THREADED_MIN_RAYS = 16384


@dataclass(frozen=True, eq=False)
class Hits:
    """First hits of a batch of rays, flat arrays aligned with the rays.

    Attributes
    ----------
    tri : (n,) int64
        Triangle index, −1 for a miss (nothing within ``max_range``).
    range_m : (n,) float64
        Distance from the ray origin in m, ``inf`` for a miss.
    cos_inc : (n,) float64
        cos θi = −d·n̂ (positive for a front-facing hit), 0 for a miss.
    echo : (n,) bool
        True where the hit can return an echo (front-facing, not grazing).
    normal : (n, 3) float64
        Unit geometric normal of the triangle hit (0 for a miss).
    object_id : (n,) int32
        Index of the scene object hit (into ``CompiledScene.labels``), −1 for a miss.
    """

    tri: np.ndarray
    range_m: np.ndarray
    cos_inc: np.ndarray
    echo: np.ndarray
    normal: np.ndarray
    object_id: np.ndarray


class RayCaster:
    """An Embree BVH of a :class:`CompiledScene`, built once and cast many times."""

    def __init__(self, compiled: CompiledScene, threads: int | None = None):
        """Build the BVH. ``threads``: Embree calls in parallel per batch (default: the CPU count)."""
        self.compiled = compiled
        self._scene = rtcs.EmbreeScene()
        TriangleMesh(self._scene, compiled.vertices.astype(np.float32),
                     compiled.faces.astype(np.int32))
        self.threads = max(int(threads if threads is not None else (os.cpu_count() or 1)), 1)
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        one = np.zeros((1, 3), dtype=np.float32)
        self._scene.run(one, one + np.float32([0, 0, 1]), dists=np.ones(1, np.float32), output=0)  # build the BVH now

    @classmethod
    def for_scene(cls, compiled: CompiledScene) -> "RayCaster":
        """The caster of ``compiled``, built on first use and kept with it (freed with it)."""
        caster = compiled.__dict__.get("_caster")
        if caster is None:
            caster = cls(compiled)
            object.__setattr__(compiled, "_caster", caster)  # a cache, not state: CompiledScene stays immutable
        return caster

    def _run(self, origins_f32, directions_f32, max_range_m: float, output: int):
        n = directions_f32.shape[0]
        if self._pool is None or n < THREADED_MIN_RAYS:
            return self._scene.run(origins_f32, directions_f32, dists=np.full(n, max_range_m, dtype=np.float32),
                                   output=output)
        cuts = np.linspace(0, n, self.threads + 1).astype(int)  # each ray is independent: same bits for any split
        parts = list(self._pool.map(
            lambda ab: self._scene.run(origins_f32[ab[0]:ab[1]], directions_f32[ab[0]:ab[1]],
                                       dists=np.full(ab[1] - ab[0], max_range_m, dtype=np.float32), output=output),
            zip(cuts[:-1], cuts[1:])))
        if output == 0:
            return np.concatenate(parts)
        return {k: np.concatenate([np.asarray(p[k]) for p in parts]) for k in ("primID", "tfar")}

    def cast_raw(self, origins_f32, directions_f32, max_range_m: float):
        """Embree's first hits, unrefined: the hot path of :mod:`sonar_embree.fan`.

        Parameters
        ----------
        origins_f32, directions_f32 : (n, 3) float32, C-contiguous
            Ray origins (local frame, m) and unit directions.
        max_range_m : float
            Longest distance searched, m.

        Returns
        -------
        prim : (n,) int32
            Triangle index, −1 for a miss.
        tfar : (n,) float32
            Hit distance in m (float32 accuracy; refine in float64).
        """
        n = directions_f32.shape[0]
        if n == 0:
            return np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.float32)
        res = self._run(origins_f32, directions_f32, max_range_m, 1)
        return (np.ascontiguousarray(res["primID"], dtype=np.int32),
                np.ascontiguousarray(res["tfar"], dtype=np.float32))

    def cast(self, origins_local, directions, max_range_m: float) -> Hits:
        """First hit of each ray within ``max_range_m``.

        Parameters
        ----------
        origins_local : (n, 3) float64 or (3,) float64
            Ray origins in the scene's local frame (world minus ``origin_m``), m.
        directions : (n, 3) float64
            Unit directions.
        max_range_m : float
            Longest distance searched, m.

        Returns
        -------
        Hits
        """
        d = np.ascontiguousarray(directions, dtype=np.float64)
        n = d.shape[0]
        o = np.broadcast_to(np.asarray(origins_local, dtype=np.float64), (n, 3))
        res = self._run(np.ascontiguousarray(o, dtype=np.float32), d.astype(np.float32), max_range_m, 1)
        tri = np.asarray(res["primID"]).astype(np.int64)
        hit = tri >= 0
        range_m = np.full(n, np.inf)
        cos_inc = np.zeros(n)
        echo = np.zeros(n, dtype=bool)
        normal = np.zeros((n, 3))
        object_id = np.full(n, -1, dtype=np.int32)
        if np.any(hit):
            idx = np.nonzero(hit)[0]
            t = tri[idx]
            nrm = self.compiled.face_normals[t]
            dd = d[idx]
            dn = np.einsum("ij,ij->i", dd, nrm)
            v0 = self.compiled.vertices[self.compiled.faces[t, 0]]
            num = np.einsum("ij,ij->i", v0 - o[idx], nrm)
            t_emb = np.asarray(res["tfar"], dtype=np.float64)[idx]
            with np.errstate(divide="ignore", invalid="ignore"):
                t64 = num / dn
            # float64 plane intersection where well conditioned; Embree's distance otherwise
            good = np.isfinite(t64) & (np.abs(dn) > REFIT_MIN_COS) & (np.abs(t64 - t_emb) <= REFIT_REL_TOL * (1.0 + t_emb))
            range_m[idx] = np.where(good, t64, t_emb)
            cos_inc[idx] = -dn
            echo[idx] = (-dn > GRAZING_COS) & (range_m[idx] <= max_range_m)
            normal[idx] = nrm
            object_id[idx] = self.compiled.face_object[t]
        return Hits(tri, range_m, cos_inc, echo, normal, object_id)
