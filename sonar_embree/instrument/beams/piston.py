"""The baffled circular piston: b = 2·J1(ka·sin θ)/(ka·sin θ) (Kinsler et al., *Fundamentals of Acoustics*, 4th ed.,
§8.8), θ from the axis; its one-way −3 dB full width θ3 gives ka·sin(θ3/2) = 1.6163 and the first null is at
ka·sin θ = 3.8317 (the first zero of J1)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..directivity import piston_directivity_index_db
from .base import Beam
from scipy.special import j1

#: ka·sin(θ3/2) of a circular piston at its one-way −3 dB point, 2·J1(x)/x = 1/√2.
HALF_POWER_X = 1.6163
#: ka·sin θ of the first null, the first zero of J1.
FIRST_NULL_X = 3.8317


@dataclass(frozen=True)
class CircularPiston(Beam):
    """A baffled circular piston of radius a (``ka`` = k·a) at wavelength λ, m."""

    ka: float
    wavelength_m: float

    @classmethod
    def of(cls, beamwidth_deg: float, wavelength_m: float) -> "CircularPiston":
        return cls(HALF_POWER_X / math.sin(math.radians(beamwidth_deg) / 2.0), wavelength_m)

    @property
    def radius_m(self) -> float:
        return self.ka * self.wavelength_m / (2.0 * math.pi)

    @property
    def area_m2(self) -> float:
        return math.pi * self.radius_m ** 2

    @property
    def first_null_rad(self) -> float:
        return math.asin(min(FIRST_NULL_X / self.ka, 1.0))

    def one_way(self, u_fwd, u_side, u_down) -> np.ndarray:
        """b of unit directions (n,) each: x = ka·sin θ with sin θ = |(u_fwd, u_side)|; 0 behind the baffle."""
        x = self.ka * np.minimum(np.hypot(u_fwd, u_side), 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            b = np.where(np.abs(x) < 1e-8, 1.0, 2.0 * j1(x) / x)
        return np.where(np.asarray(u_down) > 0, b, 0.0)

    @property
    def speckle_cell_m(self) -> float:
        """The piston's radius a (its near-field resolution)."""
        return self.radius_m

    @property
    def directivity_index_db(self) -> float:
        """DI = 10·log10(4π/∫ b² dΩ), dB: the pattern's integral (:mod:`sonar_embree.instrument.directivity`);
        10·log10((ka)²) for large ka (Kinsler et al., §8.9)."""
        return piston_directivity_index_db(float(self.ka))
