"""The beam protocol: what a front end asks of a beam (:mod:`sonar_embree.sonars.beams`)."""
from __future__ import annotations

import math

import numpy as np


class Beam:
    """The beam protocol (a frozen dataclass built from the one-way −3 dB full width and the wavelength).

    Attributes
    ----------
    first_null_rad : float
        The widest angle from the axis of the main lobe's edge (its first null), rad: the modelled cone reaches
        a few of these.
    area_m2 : float
        The aperture's area, m² (directivity index, speckle cell).
    """

    first_null_rad: float
    area_m2: float
    wavelength_m: float

    def one_way(self, u_fwd, u_side, u_down) -> np.ndarray:
        """b of unit directions (n,) each, 0 behind the baffle (u_down ≤ 0)."""
        raise NotImplementedError

    @property
    def directivity_index_db(self) -> float:
        """DI = 10·log10(4π·A/λ²) of a large baffled aperture of area A, dB (Kinsler et al., §8.9; Urick, ch. 3): the
        fallback of a beam without its own pattern integral (the piston and the square have theirs)."""
        return 10.0 * math.log10(4.0 * math.pi * self.area_m2 / self.wavelength_m ** 2)

    @property
    def speckle_cell_m(self) -> float:
        """The speckle lattice's default spacing, m: half the aperture's width, √A/2 (a square's half side; the
        circular piston takes its radius)."""
        return 0.5 * math.sqrt(self.area_m2)
