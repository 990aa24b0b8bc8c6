"""The side-scan's baffled rectangular membrane: b = sinc(k·lx/2·u_fwd)·sinc(k·ly/2·u_side), 0 behind the baffle
(Kinsler et al., *Fundamentals of Acoustics*, 4th ed., §8.9; docs/physics.md §2), lx along track and ly across, in
the elevation plane. Its one-way −3 dB full widths are :func:`~sonar_embree.instrument.beam.beamwidth_deg` of each
side; its directivity index the pattern's integral (:mod:`sonar_embree.instrument.directivity`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import kernels
from .. import beam
from ..directivity import membrane_directivity_index_db
from .base import Beam


@dataclass(frozen=True)
class Membrane(Beam):
    """A baffled rectangular membrane, given by k·lx/2 and k·ly/2 (rad) and the wavelength λ (m)."""

    half_k_lx: float
    half_k_ly: float
    wavelength_m: float
    separable = True

    @classmethod
    def of(cls, beamwidth_deg: float, wavelength_m: float) -> "Membrane":
        """The square membrane of one-way −3 dB full width ``beamwidth_deg`` (an echo sounder's)."""
        side = beam.membrane_size_for_beamwidth(math.radians(beamwidth_deg), wavelength_m)
        return cls.of_aperture(side, side, 2.0 * math.pi / wavelength_m)

    @classmethod
    def of_aperture(cls, length_m: float, height_m: float, wavenumber_rad_m: float) -> "Membrane":
        """The membrane ``length_m`` × ``height_m`` at wavenumber k (rad/m)."""
        k = wavenumber_rad_m
        return cls(0.5 * k * length_m, 0.5 * k * height_m, 2.0 * math.pi / k)

    def along(self, u) -> np.ndarray:
        return beam.sinc(self.half_k_lx * np.asarray(u, dtype=np.float64))

    def across(self, v) -> np.ndarray:
        return beam.sinc(self.half_k_ly * np.asarray(v, dtype=np.float64))

    def null_lines(self, u) -> np.ndarray:
        return beam.on_null(self.half_k_lx * np.asarray(u, dtype=np.float64))

    @property
    def area_m2(self) -> float:
        return 4.0 * self.half_k_lx * self.half_k_ly * (self.wavelength_m / (2.0 * math.pi)) ** 2

    @property
    def first_null_rad(self) -> float:
        lam = self.wavelength_m
        return beam.first_null_rad(2.0 * min(self.half_k_lx, self.half_k_ly) * lam / (2.0 * math.pi), lam)

    @property
    def kernel_form(self) -> tuple:
        return kernels.BEAM_SINC, float(self.half_k_lx), float(self.half_k_ly)

    @property
    def directivity_index_db(self) -> float:
        return membrane_directivity_index_db(float(self.half_k_lx), float(self.half_k_ly))
