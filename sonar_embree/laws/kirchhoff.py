"""Kirchhoff scattering from Gaussian facets, the geometric-optics limit (docs/physics.md §10).

A rough surface of isotropic Gaussian slopes (per-axis slope variance s²) seen at
high frequency scatters specularly from the facets that face the bisector of the
incident and scattered directions. With q = k_s − k_i,

    σ = |R0|²·|q|⁴ / (8π·s²·q_z⁴) · exp(−(q_x² + q_y²) / (2·s²·q_z²)),

monostatic σ(θ) = |R0|²/(8π s²)·sec⁴θ·exp(−tan²θ/(2 s²)): the near-nadir specular lobe
of sediments and the glint of smooth man-made surfaces. R0 = (Z2 − Z1)/(Z2 + Z1) is
the normal-incidence reflection coefficient (Z = ρc). Sources: D. R. Jackson and
M. D. Richardson, *High-Frequency Seafloor Acoustics* (Springer, 2007), §13.2 (the
Kirchhoff approximation); APL-UW TR 9407 (1994), the "Kirchhoff" term σ_kr.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ..errors import ConfigError
from ..kernels import njit
from ..validation import check_number
from .composite import Summable


@njit(cache=True, nogil=True, inline="always")
def kirchhoff_sigma(params, o, cos_i, data):
    """σ_K/cos θi of Kirchhoff's Gaussian facets at incidence cos θi on object ``o``:
    |R0|²/(8π s²)·sec⁵θ·exp(−tan²θ/(2 s²)); the exponential wins at grazing (0, never inf·0). ``params[o]``: |R0|²,
    s² (``data`` unused). The scalar σ of :func:`sonar_embree.laws.driver.law_weights`."""
    c = cos_i
    tan2 = (1.0 - c * c) / (c * c)
    s2 = params[o, 1]
    return params[o, 0] / (8.0 * math.pi * s2) * math.exp(-tan2 / (2.0 * s2)) / (c * c * c * c * c)


@dataclass(frozen=True)
class Kirchhoff(Summable):
    """Gaussian-facet Kirchhoff (geometric-optics) scattering.

    Parameters
    ----------
    reflection_coefficient : float
        Normal-incidence reflection coefficient R0 = (Z2 − Z1)/(Z2 + Z1), |R0| ≤ 1
        (sand against water: about 0.5; steel: about 0.94).
    slope_rms : float
        RMS facet slope per axis, s (a tangent; s² the per-axis slope variance),
        in (0, 2]. Small s: a narrow, strong specular lobe.
    """

    reflection_coefficient: float = 0.5
    slope_rms: float = 0.1


    def __post_init__(self):
        check_number("Kirchhoff", "reflection_coefficient", self.reflection_coefficient, lo=-1.0, hi=1.0)
        check_number("Kirchhoff", "slope_rms", self.slope_rms, positive=True, hi=2.0)

    @classmethod
    def from_impedances(cls, density_ratio: float, sound_speed_ratio: float, slope_rms: float = 0.1):
        """R0 from the sediment's density and sound speed relative to the water's."""
        for name, v in (("density_ratio", density_ratio), ("sound_speed_ratio", sound_speed_ratio)):
            if not (isinstance(v, (int, float)) and v > 0):
                raise ConfigError(f"Kirchhoff.{name} must be > 0, got {v!r}")
        z = density_ratio * sound_speed_ratio
        return cls((z - 1.0) / (z + 1.0), slope_rms)

    def params(self, data: list | None = None) -> tuple:
        """Kernel parameters: (|R0|², s²)."""
        return (self.reflection_coefficient ** 2, self.slope_rms ** 2)

    def sigma(self, cos_i, cos_s, phi_rad=0.0):
        """Bistatic σ(θi, θs, φ), φ the scattered azimuth from the backscatter direction."""
        cos_i, cos_s = np.asarray(cos_i, dtype=float), np.asarray(cos_s, dtype=float)
        sin_i, sin_s = np.sqrt(1.0 - cos_i ** 2), np.sqrt(1.0 - cos_s ** 2)
        qx = -sin_s * np.cos(phi_rad) - sin_i  # q/k: scattered minus incident direction
        qy = sin_s * np.sin(phi_rad)
        qz = cos_s + cos_i
        s2 = self.slope_rms ** 2
        q2 = qx ** 2 + qy ** 2 + qz ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            out = (self.reflection_coefficient ** 2 * q2 ** 2 / (8.0 * np.pi * s2 * qz ** 4)
                   * np.exp(-(qx ** 2 + qy ** 2) / (2.0 * s2 * qz ** 2)))
        return np.where((cos_i > 0) & (cos_s > 0), np.nan_to_num(out), 0.0)
