"""The ray-casting interface: every caster returns first hits the same way (docs/physics.md §8).

A caster takes float32 rays in the scene's local frame and returns, per ray, the
triangle hit and the float32 distance (:meth:`Caster.cast_raw`, the hot path).
:meth:`Caster.cast` refits every hit in float64 against its triangle's plane, so ranges,
normals and incidence are float64 whatever the caster. Grazing hits (|cos θi| below
:data:`GRAZING_COS`) and hits on the back of a face are flagged: they occlude the ray
but return no echo.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import REFIT_MIN_COS, REFIT_REL_TOL
from ..scene import CompiledScene

#: Hits whose |cos θi| is below this count as grazing: they occlude but return nothing.
GRAZING_COS = 1e-9

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


class Caster:
    """A ray caster over one :class:`CompiledScene` (implementations: Embree, a NumPy reference).

    Subclasses set ``self.compiled`` and implement :meth:`cast_raw`.
    """

    compiled: CompiledScene

    def cast_raw(self, origins_f32, directions_f32, max_range_m: float):
        """First hits, unrefined: the hot path of :mod:`sonar_embree.propagation.fan`.

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
        raise NotImplementedError

    def cast_segments(self, origins_f32, directions_f32, dists_f32):
        """First hits on segments of their own lengths (the chords of curved rays).

        Parameters
        ----------
        origins_f32, directions_f32 : (n, 3) float32, C-contiguous
            Segment starts (local frame, m) and unit directions.
        dists_f32 : (n,) float32
            Length of each segment, m.

        Returns
        -------
        prim, tfar
            As :meth:`cast_raw`; a hit beyond its segment's length is a miss.
        """
        if directions_f32.shape[0] == 0:
            return np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.float32)
        prim, tfar = self.cast_raw(origins_f32, directions_f32, float(np.max(dists_f32)))
        return np.where(tfar <= dists_f32, prim, -1).astype(np.int32), tfar

    def occluded(self, origins_f32, directions_f32, dists_f32):
        """Whether anything lies on each ray before its own distance (visibility of a leg).

        Parameters
        ----------
        origins_f32, directions_f32 : (n, 3) float32, C-contiguous
            Ray origins (local frame, m) and unit directions.
        dists_f32 : (n,) float32
            Length of each leg, m.

        Returns
        -------
        (n,) bool
        """
        if directions_f32.shape[0] == 0:
            return np.zeros(0, dtype=bool)
        prim, tfar = self.cast_raw(origins_f32, directions_f32, float(np.max(dists_f32)))
        return (prim >= 0) & (tfar < dists_f32)

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
        prim, tfar = self.cast_raw(np.ascontiguousarray(o, dtype=np.float32), d.astype(np.float32), max_range_m)
        tri = prim.astype(np.int64)
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
            t_emb = tfar.astype(np.float64)[idx]
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
