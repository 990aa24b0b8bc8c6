"""The project's own ray caster: a linear BVH built in Numba, traversed on the CPU threads or on a CUDA GPU.

:class:`BvhCaster` runs the traversal on the CPU (Numba threads); :class:`CudaCaster` runs the same device
code on a GPU through ``numba.cuda`` (``simulate(..., caster=CudaCaster)``). Neither is the default: Embree is
faster on a CPU, and the GPU caster is optional (nothing in the package requires CUDA). The hierarchy and the
ray test are in :mod:`sonar_embree.kernels.bvh` (Karras 2012; Möller & Trumbore 1997). Hits agree with
Embree's to float32 (the tests: the reference-caster scenes, the CUDA path through numba's simulator).
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from ..errors import ConfigError
from ..scene import CompiledScene
from .base import Caster


def build_bvh(compiled: CompiledScene) -> tuple:
    """The linear BVH of a compiled scene's triangles.

    Returns
    -------
    tuple
        (box (2n − 1, 6) float32, child (n − 1, 2) int32, tri (n,) int32, v0, v1, v2 (n, 3) float32): node
        boxes, children, the triangle of each sorted leaf, and every triangle's vertices in the local frame, m.
    """
    v = np.asarray(compiled.vertices, dtype=np.float32)
    f = np.asarray(compiled.faces, dtype=np.int64)
    if f.shape[0] == 0:
        raise ConfigError("BvhCaster: the scene has no triangles")
    corners = v[f]                                            # (n, 3 vertices, 3)
    lo, hi = np.ascontiguousarray(corners.min(axis=1)), np.ascontiguousarray(corners.max(axis=1))
    codes = np.empty(f.shape[0], dtype=np.int64)
    kernels.morton_codes(lo, hi, codes)
    order = np.argsort(codes, kind="stable")
    child = np.empty((max(f.shape[0] - 1, 0), 2), dtype=np.int32)
    kernels.lbvh_children(np.ascontiguousarray(codes[order]), child)
    box = np.empty((2 * f.shape[0] - 1, 6), dtype=np.float32)
    kernels.lbvh_boxes(child, np.ascontiguousarray(lo[order]), np.ascontiguousarray(hi[order]), box)
    return (box, child, order.astype(np.int32), *(np.ascontiguousarray(corners[:, k]) for k in range(3)))


class BvhCaster(Caster):
    """First hits through the project's linear BVH on the CPU threads (the GPU caster's code, run by Numba)."""

    def __init__(self, compiled: CompiledScene):
        self.compiled = compiled
        self.bvh = build_bvh(compiled)

    def cast_raw(self, origins_f32, directions_f32, max_range_m: float):
        """As :meth:`Caster.cast_raw`: (n,) int32 triangle (−1: miss) and (n,) float32 distance."""
        n = directions_f32.shape[0]
        prim, tfar = np.empty(n, dtype=np.int32), np.empty(n, dtype=np.float32)
        kernels.traverse_cpu(*self.bvh, np.ascontiguousarray(origins_f32, dtype=np.float32),
                             np.ascontiguousarray(directions_f32, dtype=np.float32), np.float32(max_range_m), prim,
                             tfar)
        return prim, tfar


class CudaCaster(BvhCaster):
    """First hits through the linear BVH on a CUDA GPU (``numba.cuda``; its simulator where
    ``NUMBA_ENABLE_CUDASIM=1``). The BVH is built on the CPU and copied to the GPU once per scene."""

    def __init__(self, compiled: CompiledScene):
        if not kernels.cuda_available():
            raise ConfigError("CudaCaster: numba.cuda finds no GPU (install numba-cuda with a CUDA driver, or set "
                              "NUMBA_ENABLE_CUDASIM=1 for numba's simulator); use the default Embree caster")
        super().__init__(compiled)
        self.device = kernels.DeviceBvh(self.bvh)

    def cast_raw(self, origins_f32, directions_f32, max_range_m: float):
        """As :meth:`Caster.cast_raw`, on the GPU."""
        if directions_f32.shape[0] == 0:
            return np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.float32)
        return self.device.cast(np.ascontiguousarray(origins_f32, dtype=np.float32),
                                np.ascontiguousarray(directions_f32, dtype=np.float32), max_range_m)
