"""One driver for every scattering law: a single pass over the hits calls each hit's law's scalar σ
(docs/physics.md §10).

Each law module holds its class and its scalar ``*_sigma(params, o, cos_i, data)`` (σ(θi, θi, 0)/cos θi at one
hit on object ``o``, from its parameter row and the shared table data), inlined into the driver. A new law is its
module, one line in :data:`KINDS` and one branch in :func:`_sigma` (Numba calls functions, not a table of them: a
jitted function taken as an argument would be compiled again in every process, its disk cache never hit).
"""
from __future__ import annotations

from ..kernels import njit, prange
from .kirchhoff import Kirchhoff, kirchhoff_sigma
from .lambert import Lambert, lambert_sigma
from .tabulated import Tabulated, tabulated_sigma

#: The law classes the driver evaluates, by kind id (the index here); each id is a branch of :func:`_sigma`.
KINDS = (Lambert, Kirchhoff, Tabulated)


@njit(cache=True, nogil=True, inline="always")
def _sigma(kind, params, o, cos_i, data):
    """σ/cos θi of law kind ``kind`` (an index of :data:`KINDS`) at one hit on object ``o``."""
    if kind == 0:
        return lambert_sigma(params, o, cos_i, data)
    if kind == 1:
        return kirchhoff_sigma(params, o, cos_i, data)
    return tabulated_sigma(params, o, cos_i, data)


@njit(cache=True, nogil=True, parallel=True)
def law_weights(prim, cos_i, face_object, term_law, kind_of, params, data, weight, out, add):
    """``out[i] *=`` (or ``+=`` with ``add``) σ(θi)/cos θi of the law of each hit's object, for one term.

    Parameters
    ----------
    prim : (n,) int32
        Triangle hit by each ray, −1 for none.
    cos_i : (n,) float64
        cos θi of each hit.
    face_object : (f,) int32; term_law : (n_objects,) int32
        Object of each triangle and the scene's law index of each object's term (−1: none).
    kind_of : (n_laws,) int64
        The :data:`KINDS` id of each of the scene's law indices.
    params : (n_objects, k) float64
        The term's parameters per object (each law's ``params``).
    data : (m,) float64
        Shared table data.
    weight : (n,) float64
        Echo weights without the law: hits of weight 0 are skipped.
    out : (n,) float64
        ``weight`` itself (multiplied in place) or a factor array (``add``: summed into).
    add : bool
        Add σ/cos θi to ``out`` (composite laws) instead of multiplying it.
    """
    for i in prange(prim.shape[0]):
        t = prim[i]
        if t < 0 or weight[i] == 0.0:
            continue
        o = face_object[t]
        k = term_law[o]
        if k < 0:
            continue
        v = _sigma(kind_of[k], params, o, cos_i[i], data)
        if add:
            out[i] += v
        else:
            out[i] *= v
