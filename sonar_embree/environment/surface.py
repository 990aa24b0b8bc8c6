"""The sea surface: a flat pressure-release plane with Rayleigh roughness (docs/physics.md §13).

A flat pressure-release surface reflects with R_s = −1. With RMS wave height h_w the
coherent (specular) part of the reflection is |R_s| = exp(−2k²h_w² sin²θg), the
Rayleigh roughness (Kirchhoff) coefficient for Gaussian surface heights (Jensen,
Kuperman, Porter and Schmidt, *Computational Ocean Acoustics*, 2nd ed., 2011, ch. 1;
APL-UW TR 9407, 1994, surface section). From a wind speed U (m/s at 19.5 m) the fully
developed Pierson–Moskowitz sea has a significant wave height H_s = 0.21·U²/g and
h_w = H_s/4 (Pierson and Moskowitz, *J. Geophys. Res.* 69(24), 5181–5190, 1964).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..validation import check_number

#: Standard gravity, m/s².
G_M_S2 = 9.80665


@dataclass(frozen=True)
class SeaSurface:
    """A horizontal sea surface at world height ``z_m`` (z up, the trajectory's frame).

    Parameters
    ----------
    z_m : float
        World z of the mean surface, m (above the sonar and the whole scene).
    rms_wave_height_m : float
        RMS wave height h_w, m (0: a mirror).
    wind_speed_m_s : float or None
        Wind speed at 19.5 m, m/s: sets h_w of a fully developed sea when
        ``rms_wave_height_m`` is 0 (give one or the other).
    """

    z_m: float
    rms_wave_height_m: float = 0.0
    wind_speed_m_s: float | None = None

    def __post_init__(self):
        check_number("SeaSurface", "z_m", self.z_m)
        check_number("SeaSurface", "rms_wave_height_m", self.rms_wave_height_m, nonneg=True, hi=30.0)
        if self.wind_speed_m_s is not None:
            check_number("SeaSurface", "wind_speed_m_s", self.wind_speed_m_s, nonneg=True, hi=60.0)
            if self.rms_wave_height_m > 0:
                raise ConfigError("SeaSurface: give rms_wave_height_m or wind_speed_m_s, not both")

    @property
    def wave_height_m(self) -> float:
        """h_w: the given RMS wave height, or the Pierson–Moskowitz one of the wind, m."""
        if self.wind_speed_m_s is not None:
            return 0.21 * self.wind_speed_m_s ** 2 / G_M_S2 / 4.0
        return float(self.rms_wave_height_m)

    def reflection_intensity(self, sin_grazing, wavenumber_rad_m: float):
        """|R_s|² = exp(−4k²h_w² sin²θg) of one bounce at grazing angles with sines ``sin_grazing``."""
        kh = wavenumber_rad_m * self.wave_height_m
        return np.exp(-4.0 * kh * kh * np.square(sin_grazing))

    def reflection_db(self, grazing_deg: float, wavenumber_rad_m: float) -> float:
        """20·log10 |R_s| of one bounce at ``grazing_deg``, dB (0 for a mirror)."""
        return float(10.0 * np.log10(self.reflection_intensity(math.sin(math.radians(grazing_deg)),
                                                               wavenumber_rad_m)))
