"""A Gaussian beam: one-way power b² = 2^−((u_fwd/a)² + (u_side/b)²), a and b the direction cosines of its one-way
−3 dB points (sin of half the full widths) in its two principal planes, 0 behind the baffle. The smooth, side-lobe-free
pattern of shaded (apodised) arrays and the usual idealisation of a measured main lobe (Urick, *Principles of
Underwater Sound*, 3rd ed., 1983, §3.5; Lurton, *An Introduction to Underwater Acoustics*, 2nd ed., 2010, §2.3.4).

For an echo sounder (``EchoSounder(beam="gaussian")``) it is circular, of the given width; for a side-scan, MSIS or
forward-looking element (``Sonar(beam="gaussian")``) it has the −3 dB widths of the rectangular membrane of the same
size, so only the lobes' shape changes. It has no nulls: its fan spans as far as the membrane's would (past the
membrane's first null the Gaussian is below −15 dB one way). Directivity index from the pattern's integral over the
baffled hemisphere (:func:`~sonar_embree.instrument.directivity.gaussian_directivity_index_db`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import kernels
from .. import beam
from ..directivity import gaussian_directivity_index_db
from .base import Beam

#: Where a membrane of the same −3 dB width has its first null, in units of the −3 dB direction cosine: π / 1.39156.
NULL_PER_HALF_WIDTH = math.pi / 1.39156


@dataclass(frozen=True)
class Gaussian(Beam):
    """A Gaussian beam with one-way −3 dB direction cosines ``a`` (along u_fwd) and ``b`` (along u_side) at λ, m."""

    a: float
    b: float
    wavelength_m: float
    separable = True

    @classmethod
    def of(cls, beamwidth_deg: float, wavelength_m: float) -> "Gaussian":
        """The circular beam of one-way −3 dB full width ``beamwidth_deg``."""
        u = math.sin(math.radians(beamwidth_deg) / 2.0)
        return cls(u, u, wavelength_m)

    @classmethod
    def of_aperture(cls, length_m: float, height_m: float, wavenumber_rad_m: float) -> "Gaussian":
        """The beam with the −3 dB widths of the membrane ``length_m`` × ``height_m`` at wavenumber k (rad/m)."""
        lam = 2.0 * math.pi / wavenumber_rad_m
        a, b = (math.sin(math.radians(beam.beamwidth_deg(size, lam)) / 2.0) for size in (length_m, height_m))
        return cls(a, b, lam)

    def along(self, u) -> np.ndarray:
        return np.exp(-0.5 * math.log(2.0) * (np.asarray(u, dtype=np.float64) / self.a) ** 2)

    def across(self, v) -> np.ndarray:
        return np.exp(-0.5 * math.log(2.0) * (np.asarray(v, dtype=np.float64) / self.b) ** 2)

    @property
    def kernel_form(self) -> tuple:
        q = math.sqrt(0.5 * math.log(2.0))                    # f(q·x) = exp(−(q·x)²) = 2^(−(x/a)²/2) with q/a
        return kernels.BEAM_GAUSS, q / self.a, q / self.b

    @property
    def first_null_rad(self) -> float:
        return math.asin(min(NULL_PER_HALF_WIDTH * max(self.a, self.b), 1.0))

    @property
    def area_m2(self) -> float:
        """The aperture area of the same directivity index, λ²·10^(DI/10)/(4π), m²."""
        return self.wavelength_m ** 2 * 10.0 ** (self.directivity_index_db / 10.0) / (4.0 * math.pi)

    @property
    def directivity_index_db(self) -> float:
        """DI = 10·log10(4π / ∫ b² dΩ) over the baffled hemisphere, dB (10·log10(4π·ln 2/(π·a·b)) for a narrow
        beam)."""
        return gaussian_directivity_index_db(float(self.a), float(self.b))
