"""Ray casting behind one interface (:class:`Caster`): Embree (the default), the project's own BVH on the CPU
or on a CUDA GPU (optional), and a NumPy reference for tests. A caster is a subclass of :class:`Caster`
implementing ``cast_raw``.
"""
from .base import GRAZING_COS, Caster, Hits
from .bvh import BvhCaster, CudaCaster
from .embree import EmbreeCaster
from .reference import NumpyCaster

#: The default caster (the name the rest of the package and older scripts use).
RayCaster = EmbreeCaster

__all__ = ["BvhCaster", "Caster", "CudaCaster", "EmbreeCaster", "GRAZING_COS", "Hits", "NumpyCaster", "RayCaster"]
