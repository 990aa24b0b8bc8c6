"""Per-object laws flattened into the arrays the kernels read, and the surface pass of each block."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from .driver import KINDS, law_weights

#: The most numbers a law reads per object (longer data go into ``LawTable.data``).
MAX_PARAMS = 4


@dataclass(frozen=True, eq=False)
class LawTable:
    """The scene's laws at one frequency, as the kernels read them.

    Attributes
    ----------
    kinds : tuple of type
        The distinct simple law classes, in order of first use.
    term_law : (n_terms, n_objects) int32
        Index into ``kinds`` of each object's k-th term (−1 where it has fewer terms).
    term_params : (n_terms, n_objects, MAX_PARAMS) float64
        Each term's ``params()``, zero-padded.
    data : (m,) float64
        Shared data of the terms (tables).
    """

    kinds: tuple
    term_law: np.ndarray
    term_params: np.ndarray
    data: np.ndarray
    kind_of: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        """``kind_of`` (n_kinds,) int64: the driver's id of each of ``kinds`` (:data:`sonar_embree.laws.driver.KINDS`)."""
        object.__setattr__(self, "kind_of", np.array([KINDS.index(k) for k in self.kinds], dtype=np.int64))


def law_table(laws, frequency_hz: float | None = None) -> LawTable:
    """Group per-object laws (composites as their terms) for the kernels.

    Parameters
    ----------
    laws : sequence of law
        The law of each object.
    frequency_hz : float, optional
        The carrier, for tables with a frequency axis.
    """
    terms = [law.terms() for law in laws]
    n_terms = max((len(t) for t in terms), default=1)
    kinds, data = [], []
    term_law = np.full((n_terms, len(laws)), -1, dtype=np.int32)
    params = np.zeros((n_terms, len(laws), MAX_PARAMS))
    for o, object_terms in enumerate(terms):
        for j, term in enumerate(object_terms):
            if frequency_hz is not None:
                term = term.at_frequency(frequency_hz)
            if type(term) not in kinds:
                kinds.append(type(term))
            term_law[j, o] = kinds.index(type(term))
            p = term.params(data)
            params[j, o, :len(p)] = p
    unknown = [k.__name__ for k in kinds if k not in KINDS]
    if unknown:
        raise ConfigError(f"scattering law {unknown[0]} has no scalar sigma in sonar_embree.laws.driver.KINDS")
    return LawTable(tuple(kinds), term_law, params, np.asarray(data, dtype=np.float64))


def apply_laws(table: LawTable, compiled, prim: np.ndarray, cos_i: np.ndarray, weight: np.ndarray,
               points_local: np.ndarray | None = None) -> None:
    """Multiply each echo weight by its surface's σ(θi)/cos θi, map and texture.

    One kernel per simple law the scene uses; composite laws sum their terms into a
    factor first. Maps and texture run only when the scene has them (then
    ``points_local`` is needed).

    Parameters
    ----------
    table : LawTable
        The scene's laws at the carrier (:func:`law_table`, made once per run).
    compiled : CompiledScene
    prim : (n,) int32
        Triangle hit by each ray, −1 for none.
    cos_i : (n,) float64
        cos θi of each hit.
    weight : (n,) float64
        Weights without the law (e.g. :func:`sonar_embree.kernels.fan_echoes`), multiplied in place.
    points_local : (n, 3) float64, optional
        Hit points in the scene's local frame, m (maps and texture).
    """
    t = table
    fo = compiled.face_object
    if t.term_law.shape[0] == 1:
        law_weights(prim, cos_i, fo, t.term_law[0], t.kind_of, t.term_params[0], t.data, weight, weight, False)
    else:
        factor = np.zeros_like(weight)
        for j in range(t.term_law.shape[0]):
            law_weights(prim, cos_i, fo, t.term_law[j], t.kind_of, t.term_params[j], t.data, weight, factor, True)
        np.multiply(weight, factor, out=weight)
    for detail in (compiled.maps, compiled.textures):
        if detail is not None:
            detail.apply(compiled, prim, points_local, weight)
