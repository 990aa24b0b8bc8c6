"""Composite laws: σ = Σ σ_k, the usual engineering seafloor model (docs/physics.md §10).

The sum of a diffuse (Lambert) and a specular (Kirchhoff) term is the classic
two-component seafloor model: the Kirchhoff term makes the near-nadir lobe, the
diffuse term the far swath (D. R. Jackson, D. P. Winebrenner and A. Ishimaru,
"Application of the composite roughness model to high-frequency bottom
backscattering", J. Acoust. Soc. Am. 79, 1410–1422, 1986; APL-UW TR 9407, 1994, which
adds a Kirchhoff and a small-roughness/volume term the same way). Any laws add:
``Lambert(-30) + Kirchhoff(0.5, 0.1)``.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError


class Summable:
    """Mixin: ``law_a + law_b`` is a :class:`Composite`; ``terms()`` lists the simple laws.

    ``uses_azimuth``: whether ``sigma`` depends on the bistatic azimuth φ (the multipath front end computes φ
    only for a scene with such a law); True unless a law says otherwise.
    """

    uses_azimuth = True

    def __add__(self, other):
        if not isinstance(other, Summable):
            return NotImplemented
        return Composite(self.terms() + other.terms())

    def terms(self) -> tuple:
        """The simple laws whose σ add up to this law's: ``(self,)`` for a simple law."""
        return (self,)

    def at_frequency(self, frequency_hz: float):
        """The law at the carrier ``frequency_hz`` (Hz): itself, unless its σ depends on the carrier."""
        return self


@dataclass(frozen=True)
class Composite(Summable):
    """σ(θi, θs, φ) = Σ σ_k of its terms (nested composites are flattened).

    Parameters
    ----------
    terms : tuple of laws
        Two or more laws of :mod:`sonar_embree.laws`.
    """

    terms_: tuple = ()

    def __init__(self, terms):
        flat = []
        for t in tuple(terms):
            if not isinstance(t, Summable):
                raise ConfigError(f"Composite terms must be scattering laws of sonar_embree.laws, got {t!r}")
            flat.extend(t.terms())
        if len(flat) < 2:
            raise ConfigError(f"Composite needs two or more terms, got {len(flat)}")
        object.__setattr__(self, "terms_", tuple(flat))

    def terms(self) -> tuple:
        return self.terms_

    @property
    def uses_azimuth(self) -> bool:
        """Whether any term's σ depends on φ."""
        return any(t.uses_azimuth for t in self.terms_)

    def at_frequency(self, frequency_hz: float) -> "Composite":
        """Each term at ``frequency_hz`` (for tabulated terms with a frequency axis)."""
        return Composite(tuple(t.at_frequency(frequency_hz)
                               for t in self.terms_))

    def sigma(self, cos_i, cos_s, phi_rad=0.0):
        """Σ of the terms' bistatic σ."""
        return sum(t.sigma(cos_i, cos_s, phi_rad) for t in self.terms_)
