"""The sea surface: a flat pressure-release plane with Rayleigh roughness (docs/physics.md §13).

A flat pressure-release surface reflects with R_s = −1. With RMS wave height h_w the
coherent (specular) part of the reflection is |R_s| = exp(−2k²h_w² sin²θg), the
Rayleigh roughness (Kirchhoff) coefficient for Gaussian surface heights (Jensen,
Kuperman, Porter and Schmidt, *Computational Ocean Acoustics*, 2nd ed., 2011, ch. 1;
APL-UW TR 9407, 1994, surface section). From a wind speed U (m/s at 19.5 m) the fully
developed Pierson–Moskowitz sea has a significant wave height H_s = 0.21·U²/g and
h_w = H_s/4 (Pierson and Moskowitz, *J. Geophys. Res.* 69(24), 5181–5190, 1964).

A swell makes the surface wavy: one long-crested sinusoidal (linear, Airy) wave of height H (crest to
trough) and length Λ travelling towards ψ, z = z_s + (H/2)·sin(2π(x cos ψ + y sin ψ)/Λ), meshed and
reflected by Embree (:mod:`sonar_embree.propagation.multipath`); waves steeper than H/Λ = 1/7 break (Michell's limit;
Holthuijsen, *Waves in Oceanic and Coastal Waters*, Cambridge University Press, 2007, ch. 7) and are refused.

The surface also scatters back (the "surface line" of side-scan records, from 2d/c for a sonar d below it):
``backscatter`` gives its scattering strength, Chapman and Harris's wind-driven fit
(:class:`~sonar_embree.laws.ChapmanHarris`) or a Lambert level.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..laws import ChapmanHarris, Lambert
from ..validation import check_number

#: Standard gravity, m/s².
G_M_S2 = 9.80665

#: A swell's mesh strips are cut along the crests every this many strip widths (Λ/24): long thin triangles,
#: far fewer than a square grid's (3 M → 50 k over a 520 m × 320 m survey at Λ = 8 m).
CREST_CUT = 64


@dataclass(frozen=True, eq=False)
class SwellStrips:
    """The swell's mesh grid (:meth:`SeaSurface.mesh`), world frame: unit vectors across (``k``) and along (``c``)
    the crests, the nodes across (``a``, m, evenly spaced) and along (``b``, m, evenly spaced) them, and the height
    of each ``a`` node (``z``, m)."""

    k: np.ndarray
    c: np.ndarray
    a: np.ndarray
    b: np.ndarray
    z: np.ndarray


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
    swell_height_m : float
        Crest-to-trough height H of a swell, m (0: a flat mean surface, the image method).
    swell_length_m : float
        Its wavelength Λ, m.
    swell_direction_deg : float
        The direction it travels, degrees counterclockwise from +x.
    backscatter : str or float or None
        The surface's own backscatter (the surface line): ``"chapman-harris"`` (Chapman and Harris 1962, needs
        ``wind_speed_m_s``), a number (Lambert's law with μ in dB, σ = μ·cos θi·cos θs, θ from the vertical),
        or None (default: no surface line).
    """

    z_m: float
    rms_wave_height_m: float = 0.0
    wind_speed_m_s: float | None = None
    swell_height_m: float = 0.0
    swell_length_m: float = 40.0
    swell_direction_deg: float = 0.0
    backscatter: str | float | None = None

    def __post_init__(self):
        check_number("SeaSurface", "z_m", self.z_m)
        check_number("SeaSurface", "rms_wave_height_m", self.rms_wave_height_m, nonneg=True, hi=30.0)
        if self.wind_speed_m_s is not None:
            check_number("SeaSurface", "wind_speed_m_s", self.wind_speed_m_s, nonneg=True, hi=60.0)
            if self.rms_wave_height_m > 0:
                raise ConfigError("SeaSurface: give rms_wave_height_m or wind_speed_m_s, not both")
        check_number("SeaSurface", "swell_height_m", self.swell_height_m, nonneg=True, hi=30.0)
        check_number("SeaSurface", "swell_length_m", self.swell_length_m, positive=True, hi=2000.0)
        check_number("SeaSurface", "swell_direction_deg", self.swell_direction_deg)
        if self.swell_height_m > self.swell_length_m / 7.0:
            raise ConfigError(f"SeaSurface: a swell of height {self.swell_height_m:g} m and length "
                              f"{self.swell_length_m:g} m is steeper than 1/7 and would break")
        self.backscatter_law  # validates ``backscatter``

    @property
    def backscatter_law(self):
        """The scattering law of the surface line (a :mod:`sonar_embree.laws` law), or None without one."""
        b = self.backscatter
        if b is None:
            return None
        if isinstance(b, str):
            if b != "chapman-harris":
                raise ConfigError(f"SeaSurface.backscatter must be 'chapman-harris', a Lambert level in dB or None, "
                                  f"got {b!r}")
            if self.wind_speed_m_s is None:
                raise ConfigError("SeaSurface: backscatter 'chapman-harris' needs wind_speed_m_s")
            return ChapmanHarris(self.wind_speed_m_s)
        check_number("SeaSurface", "backscatter", b, lo=-300.0, hi=30.0)
        return Lambert(float(b))

    @property
    def is_flat(self) -> bool:
        """True without a swell (the image method applies)."""
        return self.swell_height_m == 0.0

    @property
    def lowest_z_m(self) -> float:
        """World z of the swell's troughs, m (z_m for a flat surface)."""
        return float(self.z_m - 0.5 * self.swell_height_m)

    def height_at(self, x_m, y_m):
        """World z of the surface over world (x, y), m (any shapes that broadcast)."""
        psi = math.radians(self.swell_direction_deg)
        phase = 2.0 * math.pi * (np.asarray(x_m) * math.cos(psi) + np.asarray(y_m) * math.sin(psi))
        return self.z_m + 0.5 * self.swell_height_m * np.sin(phase / self.swell_length_m)

    def mesh(self, x_range_m, y_range_m, origin_m=(0.0, 0.0, 0.0)):
        """The swell as a triangle mesh covering world x and y ranges (m), in the frame shifted by ``origin_m``.

        Strips along the crests (the height is constant along a crest, so the strips are exact there), Λ/24 wide
        across them (the sinusoid's chords stand off it by < 1 % of H), cut every ``CREST_CUT`` strip widths
        along the crests; normals up. The grid is :meth:`strips`: quad (ia, ib) is faces q and n_q + q,
        q = ib·(na − 1) + ia (the first where the along-strip fraction ≤ the across one).
        """
        import trimesh

        if self.is_flat:                                             # two triangles
            v = np.array([[x, y, self.z_m] for x in x_range_m for y in y_range_m]) - np.asarray(origin_m, float)
            return trimesh.Trimesh(v, [[0, 2, 3], [0, 3, 1]], process=False)
        g = self.strips(x_range_m, y_range_m)
        ga, gb = np.meshgrid(g.a, g.b)
        xy = ga[..., None] * g.k + gb[..., None] * g.c
        z = np.broadcast_to(g.z, ga.shape)
        v = np.concatenate([xy, z[..., None]], axis=-1).reshape(-1, 3) - np.asarray(origin_m, float)
        na = g.a.size
        i = (np.arange(g.b.size - 1)[:, None] * na + np.arange(na - 1)[None, :]).ravel()
        faces = np.concatenate([np.stack([i, i + 1, i + na + 1], 1), np.stack([i, i + na + 1, i + na], 1)])
        return trimesh.Trimesh(v, faces, process=False)

    def strips(self, x_range_m, y_range_m) -> "SwellStrips":
        """The grid of :meth:`mesh` (world frame) over x and y ranges (m), for a swell."""
        step = self.swell_length_m / 24.0
        psi = math.radians(self.swell_direction_deg)
        k, c = np.array([math.cos(psi), math.sin(psi)]), np.array([-math.sin(psi), math.cos(psi)])
        corners = np.array([[x, y] for x in x_range_m for y in y_range_m], dtype=float)
        a_lo, a_hi = (corners @ k).min(), (corners @ k).max()     # across the crests (the phase), along them
        b_lo, b_hi = (corners @ c).min(), (corners @ c).max()
        a = np.arange(math.floor(a_lo / step), math.ceil(a_hi / step) + 1) * step
        b = np.linspace(b_lo, b_hi, max(2, math.ceil((b_hi - b_lo) / (CREST_CUT * step)) + 1))
        z = self.z_m + 0.5 * self.swell_height_m * np.sin(2.0 * math.pi * a / self.swell_length_m)
        return SwellStrips(k, c, a, b, z)

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
