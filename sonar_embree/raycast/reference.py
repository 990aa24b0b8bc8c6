"""A NumPy reference caster: every ray against every triangle (Möller & Trumbore 1997).

T. Möller and B. Trumbore, "Fast, minimum storage ray-triangle intersection",
Journal of Graphics Tools 2(1), 21–28 (1997). Brute force in float64, so it is slow
(rays × triangles) and exact up to round-off: the tests use it to check the Embree
caster and the whole pipeline on small scenes; it is also the template for another
caster (a GPU one implements the same :meth:`cast_raw`).
"""
from __future__ import annotations

import numpy as np

from ..scene import CompiledScene
from .base import Caster

#: Ray × triangle pairs per chunk (bounds the temporary arrays to ~100 MB).
CHUNK_PAIRS = 2_000_000
#: Barycentric slack: a ray through an edge shared by two triangles hits one of them.
EDGE_EPS = 1e-12


class NumpyCaster(Caster):
    """First hits by brute force over all triangles (both faces; nearest distance in [0, max_range])."""

    def __init__(self, compiled: CompiledScene):
        self.compiled = compiled
        tri = compiled.vertices[compiled.faces]
        self._v0 = tri[:, 0]
        self._e1 = tri[:, 1] - tri[:, 0]
        self._e2 = tri[:, 2] - tri[:, 0]

    def cast_raw(self, origins_f32, directions_f32, max_range_m: float):
        """As :meth:`Caster.cast_raw`: (n,) int32 triangle (−1: miss) and (n,) float32 distance."""
        n = directions_f32.shape[0]
        prim = np.full(n, -1, dtype=np.int32)
        tfar = np.full(n, max_range_m, dtype=np.float32)
        step = max(1, CHUNK_PAIRS // max(self._v0.shape[0], 1))
        for a in range(0, n, step):
            o = np.asarray(origins_f32[a:a + step], dtype=np.float64)
            d = np.asarray(directions_f32[a:a + step], dtype=np.float64)
            prim[a:a + step], t = self._first_hits(o, d, float(max_range_m))
            tfar[a:a + step] = np.where(prim[a:a + step] >= 0, t, max_range_m)
        return prim, tfar

    def _first_hits(self, o, d, max_range_m):
        p = np.cross(d[:, None, :], self._e2[None])                 # (m, f, 3)
        det = np.einsum("fk,mfk->mf", self._e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = o[:, None, :] - self._v0[None]
            u = np.einsum("mfk,mfk->mf", s, p) * inv
            q = np.cross(s, self._e1[None])
            v = np.einsum("mk,mfk->mf", d, q) * inv
            t = np.einsum("fk,mfk->mf", self._e2, q) * inv
            ok = ((det != 0) & (u >= -EDGE_EPS) & (v >= -EDGE_EPS) & (u + v <= 1 + EDGE_EPS)
                  & (t >= 0) & (t <= max_range_m))
        t = np.where(ok, t, np.inf)
        best = np.argmin(t, axis=1)
        t_best = t[np.arange(t.shape[0]), best]
        hit = np.isfinite(t_best)
        return np.where(hit, best, -1).astype(np.int32), np.where(hit, t_best, max_range_m)
