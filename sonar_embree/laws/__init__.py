"""Scattering laws: σ(θi, θs, φ) per unit area per steradian (docs/physics.md §10).

A law is a frozen dataclass with

- ``sigma(cos_i, cos_s, phi_rad)``: the bistatic cross-section in NumPy (θ from the
  surface normal, φ the scattered direction's azimuth away from the backscatter
  direction: φ = 0 and θs = θi is monostatic);
- ``params()``: the numbers its kernel reads, per object (at most :data:`MAX_PARAMS`);
- ``kernel``: a Numba kernel that multiplies each monostatic echo weight by
  σ(θi, θi, 0)/cos θi for the hits on objects of this law (the ray's footprint
  dA = R²dΩ/cos θi is folded in analytically, so it never diverges at grazing).

:func:`apply_laws` (called by each sonar type's front end) runs each law's kernel once
per block for the laws the scene uses; a scene of one law pays for one pass. A new law is one
module here with such a class, plus its test.
"""
from __future__ import annotations

import numpy as np

from .kirchhoff import Kirchhoff
from .lambert import Lambert

#: The most numbers a law reads per object.
MAX_PARAMS = 4
#: The laws by the name a TOML ``law = { kind = "…", … }`` table gives.
LAWS = {"lambert": Lambert, "kirchhoff": Kirchhoff}


def law_table(laws) -> tuple:
    """Group per-object laws for the kernels.

    Parameters
    ----------
    laws : sequence of ScatteringLaw
        The law of each object.

    Returns
    -------
    kinds : tuple of type
        The distinct law classes, in order of first use.
    object_law : (n_objects,) int32
        Index into ``kinds`` per object.
    params : (n_objects, MAX_PARAMS) float64
        Each object's ``params()``, zero-padded.
    """
    kinds, object_law = [], np.zeros(len(laws), dtype=np.int32)
    params = np.zeros((len(laws), MAX_PARAMS))
    for i, law in enumerate(laws):
        if type(law) not in kinds:
            kinds.append(type(law))
        object_law[i] = kinds.index(type(law))
        p = law.params()
        params[i, :len(p)] = p
    return tuple(kinds), object_law, params


def apply_laws(compiled, prim: np.ndarray, cos_i: np.ndarray, weight: np.ndarray) -> None:
    """Multiply each echo weight by its surface's σ(θi)/cos θi: one kernel per law the scene uses.

    Parameters
    ----------
    compiled : CompiledScene
    prim : (n,) int32
        Triangle hit by each ray, −1 for none.
    cos_i : (n,) float64
        cos θi of each hit.
    weight : (n,) float64
        Weights without the law (e.g. :func:`sonar_embree.kernels.fan_echoes`), multiplied in place.
    """
    for k, law in enumerate(compiled.law_kinds):
        law.kernel(prim, cos_i, compiled.face_object, compiled.object_law, k, compiled.law_params, weight)


__all__ = ["Kirchhoff", "LAWS", "Lambert", "MAX_PARAMS", "apply_laws", "law_table"]
