"""The baffled square piston of side L: b = sinc(k·L/2·u_fwd)·sinc(k·L/2·u_side) (the rectangular piston of Kinsler
et al., *Fundamentals of Acoustics*, 4th ed., §8.9, with equal sides; u the direction cosines with the aperture's
edges), 0 behind the baffle. Its one-way −3 dB full width θ3 in either principal plane gives
k·L/2·sin(θ3/2) = 1.39156 (sinc x = 1/√2); the main lobe's widest edge is its first null along a diagonal,
sin θ = √2·λ/L. Directivity index from the pattern's integral (10·log10(4π·L²/λ²) for a large
piston)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..directivity import membrane_directivity_index_db
from .base import Beam

#: k·L/2·sin(θ3/2) of a square piston at its one-way −3 dB point in a principal plane, sin(x)/x = 1/√2.
HALF_POWER_X = 1.39156


@dataclass(frozen=True)
class SquarePiston(Beam):
    """A baffled square piston of side ``side_m`` at wavelength λ, m."""

    side_m: float
    wavelength_m: float

    @classmethod
    def of(cls, beamwidth_deg: float, wavelength_m: float) -> "SquarePiston":
        half_k_l = HALF_POWER_X / math.sin(math.radians(beamwidth_deg) / 2.0)
        return cls(half_k_l * wavelength_m / math.pi, wavelength_m)

    @property
    def area_m2(self) -> float:
        return self.side_m ** 2

    @property
    def first_null_rad(self) -> float:
        return math.asin(min(math.sqrt(2.0) * self.wavelength_m / self.side_m, 1.0))

    def one_way(self, u_fwd, u_side, u_down) -> np.ndarray:
        """b of unit directions (n,) each; 0 behind the baffle."""
        a = math.pi * self.side_m / self.wavelength_m
        b = np.sinc(a * np.asarray(u_fwd) / math.pi) * np.sinc(a * np.asarray(u_side) / math.pi)
        return np.where(np.asarray(u_down) > 0, b, 0.0)

    @property
    def directivity_index_db(self) -> float:
        """DI = 10·log10(4π/∫ b² dΩ), dB (:func:`sonar_embree.instrument.directivity.membrane_directivity_index_db`)."""
        a = math.pi * self.side_m / self.wavelength_m
        return membrane_directivity_index_db(a, a)
