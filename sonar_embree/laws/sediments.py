"""Sediment presets (docs/physics.md §10, §10b, §10b′).

**The bare names are the physical models** (issue 52): ``"fine sand"``, ``"coarse sand"``, ``"gravel"`` and
``"rock"`` are the elastic small-slope model's sediments (fine sand, coarse sand, sandy gravel, rock:
:func:`sonar_embree.laws.small_slope.small_slope_sediment`, Jackson & Richardson 2007 ch. 13, APL-UW TM 2-00), and
``"mud"`` and ``"sandy mud"``, which the small-slope set does not hold, the APL-UW model at their grain sizes
(8 φ and 5.5 φ: :class:`sonar_embree.laws.apl_uw.AplUw`, APL-UW TR 9407); both fall off towards low grazing as
real records do. ``"concrete"`` and ``"steel"`` (man-made surfaces, no seabed model) stay the engineering presets.
The engineering presets of every class are kept under ``"lambert-kirchhoff <name>"`` and as the constants below
(:data:`FINE_SAND`, …): before issue 52 the bare names gave them.

Each engineering preset is the two-component model σ = μ·cos θi·cos θs + σ_K (Jackson,
Winebrenner and Ishimaru 1986; APL-UW TR 9407, 1994):

- the Kirchhoff term's normal-incidence reflection coefficient R0 = (ρν − 1)/(ρν + 1)
  uses the density ratio ρ and sound-speed ratio ν of the APL-UW regressions on the mean
  grain size Mz (in φ = −log2(d/1 mm)): APL-UW TR 9407 (*High-Frequency Ocean
  Environmental Acoustic Models Handbook*, Applied Physics Laboratory, University of
  Washington, 1994), the piecewise polynomials for ρ(Mz) and ν(Mz) (also used by
  F. W. Bentrem et al., "High-frequency acoustic sediment classification in shallow
  water", arXiv:physics/0607146, 2006); rock takes TR 9407's rock values ρ = 2.5,
  ν = 2.5;
- the Lambert μ follows the published span of about −40 dB (mud) to −10 dB (rock) with
  Mackenzie's −27 dB between sand and mud (K. V. Mackenzie, J. Acoust. Soc. Am. 33,
  1498, 1961; X. Lurton, *An Introduction to Underwater Acoustics*, 2nd ed., Springer
  2010, ch. 3 on seafloor backscatter: 10·log μ ≈ −40 dB for soft mud to −10 dB for rock). These are
  representative class values, not a site's measurement: bring a measured curve with
  :class:`sonar_embree.laws.Tabulated` where one exists;
- the facet slope s (RMS, per axis) widens the near-nadir lobe with coarser grain; it
  is a chosen value per class (the geometric-optics limit of TR 9407's roughness
  spectrum depends on the site), stated in each preset.

Both terms are frequency independent, so each preset's ``reference_db`` holds at any
carrier; it is quoted at 100 kHz and ``reference_grazing_deg``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from . import Composite, Kirchhoff, Lambert
from .apl_uw import AplUw, apl_class, apl_density_ratio, apl_sound_speed_ratio
from .small_slope import small_slope_sediment
from .composite import Summable


@dataclass(frozen=True)
class Sediment(Summable):
    """A seafloor class: σ = Lambert(μ) + Kirchhoff(R0(ρ, ν), s).

    Parameters
    ----------
    name : str
    lambert_db : float
        10·log10 μ, dB.
    density_ratio, sound_speed_ratio : float
        ρ and ν of the sediment against water (R0 = (ρν − 1)/(ρν + 1)).
    slope_rms : float
        RMS facet slope per axis of the Kirchhoff term.
    mean_grain_size_phi : float
        Mz in φ (NaN for rock and man-made surfaces).
    reference_grazing_deg : float
        The grazing angle at which ``reference_db`` is quoted.
    source : str
        Where the numbers come from.
    """

    name: str
    lambert_db: float
    density_ratio: float
    sound_speed_ratio: float
    slope_rms: float
    mean_grain_size_phi: float = math.nan
    reference_grazing_deg: float = 30.0
    source: str = ""

    def __post_init__(self):
        if not (self.density_ratio > 0 and self.sound_speed_ratio > 0):
            raise ConfigError(f"Sediment {self.name!r}: density and sound-speed ratios must be > 0")

    def terms(self) -> tuple:
        return (Lambert(self.lambert_db),
                Kirchhoff.from_impedances(self.density_ratio, self.sound_speed_ratio, self.slope_rms))

    def sigma(self, cos_i, cos_s, phi_rad=0.0):
        """Bistatic σ: the sum of the two terms' (as their :class:`~sonar_embree.laws.Composite`)."""
        return Composite(self.terms()).sigma(cos_i, cos_s, phi_rad)

    @property
    def reference_db(self) -> float:
        """Monostatic backscatter strength 10·log10 σ at ``reference_grazing_deg`` (any frequency), dB."""
        c = math.sin(math.radians(self.reference_grazing_deg))
        return float(10.0 * np.log10(self.sigma(c, c)))


def _apl(name: str, mz: float, lambert_db: float, slope: float) -> Sediment:
    return Sediment(name, lambert_db, apl_density_ratio(mz), apl_sound_speed_ratio(mz), slope, mz,
                    source=f"ρ, ν: APL-UW TR 9407 regressions at Mz = {mz:g} φ; μ: Lurton 2010 ch. 3 span")


#: Clay-silt mud, Mz = 8 φ (4 µm): μ −40 dB, s 0.05; ρ 1.146, ν 0.982.
MUD = _apl("mud", 8.0, -40.0, 0.05)
#: Sandy mud, Mz = 5.5 φ (22 µm): μ −35 dB, s 0.06.
SANDY_MUD = _apl("sandy mud", 5.5, -35.0, 0.06)
#: Fine sand, Mz = 2.5 φ (177 µm): μ −30 dB, s 0.1.
FINE_SAND = _apl("fine sand", 2.5, -30.0, 0.10)
#: Coarse sand, Mz = 0.5 φ (0.71 mm): μ −25 dB, s 0.15.
COARSE_SAND = _apl("coarse sand", 0.5, -25.0, 0.15)
#: Gravel, Mz = −1 φ (2 mm, the regressions' coarse end): μ −20 dB, s 0.2.
GRAVEL = _apl("gravel", -1.0, -20.0, 0.20)
#: Rock: ρ = ν = 2.5 (APL-UW TR 9407's rock), μ −13 dB, s 0.3.
ROCK = Sediment("rock", -13.0, 2.5, 2.5, 0.30, source="ρ = ν = 2.5: APL-UW TR 9407 rock; μ: Lurton 2010 ch. 3 span")
#: Smooth concrete (ρ 2.4, c 3700 m/s against 1.026, 1500 m/s: Kinsler et al., *Fundamentals of Acoustics*, 4th
#: ed., 2000, appendix tables of material properties), a glint with s 0.03 over a weak diffuse floor (μ −30 dB).
CONCRETE = Sediment("concrete", -30.0, 2.4 / 1.026, 3700.0 / 1500.0, 0.03,
                    source="ρ, c of concrete: Kinsler et al. 2000 App. C; s, μ chosen for a smooth cast surface")
#: Smooth steel (ρ 7.7, c 5900 m/s: Kinsler et al. 2000 appendix): R0 ≈ 0.93, s 0.02, μ −30 dB: a man-made glint.
STEEL = Sediment("steel", -30.0, 7.7 / 1.026, 5900.0 / 1500.0, 0.02,
                 source="ρ, c of steel: Kinsler et al. 2000 App. C; s, μ chosen for a smooth hull plate")

#: The engineering (Lambert + Kirchhoff) presets by name: ``"lambert-kirchhoff <name>"`` (the bare names before
#: issue 52).
LAMBERT_KIRCHHOFF = {s.name: s for s in (MUD, SANDY_MUD, FINE_SAND, COARSE_SAND, GRAVEL, ROCK, CONCRETE, STEEL)}

#: What each bare name is (TOML ``scattering = "fine sand"``): the physical model of the class (the module
#: docstring), or for the man-made surfaces their engineering preset.
PHYSICAL = {"mud": ("apl-uw", MUD.mean_grain_size_phi), "sandy mud": ("apl-uw", SANDY_MUD.mean_grain_size_phi),
            "fine sand": ("small-slope", "fine sand"), "coarse sand": ("small-slope", "coarse sand"),
            "gravel": ("small-slope", "sandy gravel"), "rock": ("small-slope", "rock"),
            "concrete": ("lambert-kirchhoff", "concrete"), "steel": ("lambert-kirchhoff", "steel")}

#: The bare names (every one of :data:`PHYSICAL`).
PRESETS = tuple(PHYSICAL)


def preset(name: str):
    """The preset called ``name`` (spaces or underscores), a one-line error naming the choices otherwise: a bare
    name is its class's physical model (:data:`PHYSICAL`), ``"lambert-kirchhoff <name>"`` the engineering preset,
    ``"apl-uw <class>"`` the APL-UW model's class (:func:`sonar_embree.laws.apl_uw.apl_class`), ``"small-slope
    <sediment>"`` the small-slope model's (:func:`sonar_embree.laws.small_slope.small_slope_sediment`)."""
    key = " ".join(str(name).replace("_", " ").strip().lower().split())
    if key.startswith("apl-uw "):
        return apl_class(key[len("apl-uw "):])
    if key.startswith("small-slope "):
        return small_slope_sediment(key[len("small-slope "):])
    if key.startswith("lambert-kirchhoff "):
        rest = key[len("lambert-kirchhoff "):]
        if rest not in LAMBERT_KIRCHHOFF:
            raise ConfigError(f"unknown sediment {name!r}; the Lambert + Kirchhoff presets are "
                              f"{sorted(LAMBERT_KIRCHHOFF)}")
        return LAMBERT_KIRCHHOFF[rest]
    if key not in PHYSICAL:
        raise ConfigError(f"unknown sediment {name!r}; one of {sorted(PHYSICAL)}, or 'lambert-kirchhoff', "
                          "'apl-uw' or 'small-slope' and a class")
    model, what = PHYSICAL[key]
    if model == "apl-uw":
        return AplUw.from_grain_size(what)
    return small_slope_sediment(what) if model == "small-slope" else LAMBERT_KIRCHHOFF[what]
