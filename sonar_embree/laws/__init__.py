"""Scattering laws: σ(θi, θs, φ) per unit area per steradian (docs/physics.md §10).

A law is a frozen dataclass with

- ``sigma(cos_i, cos_s, phi_rad)``: the bistatic cross-section in NumPy (θ from the
  surface normal, φ the scattered direction's azimuth away from the backscatter
  direction: φ = 0 and θs = θi is monostatic);
- ``params()``: the numbers its kernel reads, per object (at most :data:`MAX_PARAMS`);
- ``kernel``: a Numba kernel that multiplies each monostatic echo weight by
  σ(θi, θi, 0)/cos θi for the hits on objects of this law (the ray's footprint
  dA = R²dΩ/cos θi is folded in analytically, so it never diverges at grazing).

The echo stage (:mod:`sonar_embree.fan`) calls each law's kernel once per block for
the laws the scene uses; a scene of one law pays for one pass. A new law is one
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


__all__ = ["Kirchhoff", "LAWS", "Lambert", "MAX_PARAMS", "law_table"]
