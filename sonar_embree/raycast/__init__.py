"""Ray casting behind one interface (:class:`Caster`): Embree, and a NumPy reference for tests.

A GPU caster is one more subclass of :class:`Caster` implementing ``cast_raw``.
"""
from .base import GRAZING_COS, Caster, Hits
from .embree import EmbreeCaster
from .reference import NumpyCaster

#: The default caster (the name the rest of the package and older scripts use).
RayCaster = EmbreeCaster

__all__ = ["Caster", "EmbreeCaster", "GRAZING_COS", "Hits", "NumpyCaster", "RayCaster"]
