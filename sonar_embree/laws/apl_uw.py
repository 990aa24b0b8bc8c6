"""The APL-UW high-frequency bottom backscattering model (docs/physics.md §10b).

σ(θ) = σ_r(θ) + σ_v(θ), θ the grazing angle, from six sediment parameters: the density ratio ρ, the sound-speed
ratio ν and the loss parameter δ of the sediment against the water, the strength w2 (cm⁴, h0 = 1 cm) and exponent
γ of the isotropic roughness spectrum W(K) = w2/(h0·K)^γ, and the volume parameter σ2 (APL-UW TR 9407, *High-
Frequency Ocean Environmental Acoustic Models Handbook*, Applied Physics Laboratory, University of Washington,
1994, section IV; D. R. Jackson and M. D. Richardson, *High-Frequency Seafloor Acoustics*, Springer, 2007,
ch. 13–14). With k the water's wavenumber, κ = (1 + iδ)/ν, P(θ) = √(κ² − cos²θ) and the Rayleigh reflection
coefficient R(θ) = (ρ sin θ − P)/(ρ sin θ + P):

- Kirchhoff roughness, near nadir: α = γ/2 − 1, C_h² = 2π·w·Γ(2 − α)·2^(−2α)/(α(1 − α)Γ(1 + α)),
  q_c = C_h²·2^(1−2α)·k^(2(1−α)), and
  σ_kr = b·q_c·|R(90°)|² / (8π·[cos^(4α)θ + a·q_c²·sin⁴θ]^((1+α)/(2α))), with
  a = [8α²Γ((1+α)/(2α)) / (Γ(1/2)Γ(1/α)Γ(1/(2α)))]^(2α) and b = a^((1+α)/(2α))·Γ(1/α)/(2α);
- small-roughness perturbation, away from nadir: σ_pr = 4k⁴ sin⁴θ·|Y|²·W(2k cos θ),
  Y = [(ρ − 1)² cos²θ + ρ² − κ²] / (ρ sin θ + P)²;
- the two joined as σ_r = (σ_kr^η + σ_pr^η)^(1/η), η = −2: the smaller of the two wherever they differ much
  (K. L. Williams and D. R. Jackson, "Bistatic bottom scattering: model, experiments, and model/data
  comparison", J. Acoust. Soc. Am. 103, 169–181, 1998). TR 9407 itself averages σ_pr over the large-scale
  slopes (composite roughness) between the two regimes; that average is not built here;
- sediment volume: σ_v = 5δσ2·|1 − R²|²·sin²θ / (ln 10·|P|²·Im P).

Parameters from the mean grain size Mz (φ) follow the handbook's regressions: ρ(Mz) and ν(Mz) piecewise
polynomials, δ from the attenuation k_p(Mz) in dB/(m·kHz) as δ = k_p·ν·c_ref·ln 10/(40 000 π) with
c_ref = 1528 m/s, w2 = 0.00207·(h/h0)² with h/h0 = (2.03846 − 0.26923 Mz)/(1 + 0.076923 Mz) (h/h0 = 0.5 from
Mz = 5), γ = 3.25, σ2 = 0.002 below Mz = 5.5 and 0.001 above (as coded in the Navy's CASS model, routine gsiz2des;
the classes and their use in K. B. Briggs, D. R. Jackson and K. Y. Moravan, *NRL-APL Grain Size Algorithm
Upgrade*, NRL/MR/7430-02-8274, 2002). The regressions hold for −1 ≤ Mz ≤ 9 φ and the model for 10–100 kHz;
above 100 kHz (most side-scan sonars) it is an extrapolation: the spectrum's power law is carried to the
shorter Bragg wavelengths and a warning says so once.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import gamma

from ..errors import ConfigError
from ..validation import check_number, warn_once
from .composite import Summable
from .tabulated import Tabulated

#: The handbook's frequency range, Hz.
VALID_FREQUENCY_HZ = (10e3, 100e3)
#: The grain sizes the regressions cover, φ.
VALID_GRAIN_SIZE_PHI = (-1.0, 9.0)
#: Grazing angles of the table a carrier's curve becomes, degrees: log-spaced below 1° (σ falls as a power of θ
#: there), 0.1° apart above and 0.02° apart at the nadir peak; linear in dB between them is within 0.05 dB of the
#: model at every class and carrier the tests try.
TABLE_GRAZING_DEG = np.concatenate([np.geomspace(0.01, 1.0, 60)[:-1], np.arange(1.0, 89.9, 0.1),
                                    np.arange(89.9, 90.0, 0.02), [90.0]])
#: The exponent of the Kirchhoff–perturbation interpolation (Williams and Jackson 1998).
ETA = -2.0
#: Roughness spectrum reference length h0, m (w2 is in cm⁴ at h0 = 1 cm).
H0_M = 0.01
#: Reference water sound speed of the loss-parameter regression, m/s.
C_REF_M_S = 1528.0


def apl_density_ratio(mz_phi: float) -> float:
    """APL-UW TR 9407 regression of the sediment/water density ratio on mean grain size Mz (φ), −1 ≤ Mz ≤ 9."""
    if mz_phi < 1.0:
        return 0.007797 * mz_phi ** 2 - 0.17057 * mz_phi + 2.3139
    if mz_phi < 5.3:
        return -0.0165406 * mz_phi ** 3 + 0.2290201 * mz_phi ** 2 - 1.1069031 * mz_phi + 3.0455
    return -0.0012973 * mz_phi + 1.1565


def apl_sound_speed_ratio(mz_phi: float) -> float:
    """APL-UW TR 9407 regression of the sediment/water sound-speed ratio on mean grain size Mz (φ), −1 ≤ Mz ≤ 9."""
    if mz_phi < 1.0:
        return 0.002709 * mz_phi ** 2 - 0.056452 * mz_phi + 1.2778
    if mz_phi < 5.3:
        return -0.0014881 * mz_phi ** 3 + 0.0213937 * mz_phi ** 2 - 0.1382798 * mz_phi + 1.3425
    return -0.0024324 * mz_phi + 1.0019


def apl_attenuation_db_m_khz(mz_phi: float) -> float:
    """APL-UW TR 9407 regression of the sediment's attenuation k_p on Mz (φ), dB/(m·kHz)."""
    if mz_phi < 0.0:
        return 0.4556
    if mz_phi < 2.6:
        return 0.4556 + 0.0245 * mz_phi
    if mz_phi < 4.5:
        return 0.1978 + 0.1245 * mz_phi
    if mz_phi < 6.0:
        return 8.0399 - 2.5228 * mz_phi + 0.20098 * mz_phi ** 2
    return 0.9431 - 0.2041 * mz_phi + 0.0117 * mz_phi ** 2


def apl_spectral_strength_cm4(mz_phi: float) -> float:
    """APL-UW TR 9407 regression of the roughness spectral strength w2 on Mz (φ), cm⁴ (h0 = 1 cm)."""
    ratio = (2.03846 - 0.26923 * mz_phi) / (1.0 + 0.076923 * mz_phi) if mz_phi < 5.0 else 0.5
    return 0.00207 * ratio ** 2


@dataclass(frozen=True)
class AplUw(Summable):
    """A sediment in the APL-UW bottom backscattering model (see the module's docstring for the equations).

    Parameters
    ----------
    density_ratio : float
        ρ, sediment over water density, in (1, 3].
    sound_speed_ratio : float
        ν, sediment over water sound speed, in (0.9, 3].
    loss_parameter : float
        δ, the sediment wavenumber's imaginary over real part, in (0, 0.1].
    spectral_strength_cm4 : float
        w2 of the roughness spectrum W(K) = w2/(h0·K)^γ, cm⁴ (h0 = 1 cm), > 0.
    volume_parameter : float
        σ2, the sediment's volume scattering over its attenuation, in [0, 0.1].
    spectral_exponent : float
        γ, in (2, 4) (3.25 in the handbook).
    mean_grain_size_phi : float
        Mz, φ, when the parameters came from it (NaN otherwise; informative).
    water_sound_speed_m_s : float
        The water's sound speed that sets k = 2πf/c, m/s.

    Monostatic; bistatic as :class:`Tabulated` (the geometric mean of the two directions' strengths). It depends on
    the carrier, so a run takes it :meth:`at_frequency` (a table on :data:`TABLE_GRAZING_DEG`).
    """

    density_ratio: float
    sound_speed_ratio: float
    loss_parameter: float
    spectral_strength_cm4: float
    volume_parameter: float
    spectral_exponent: float = 3.25
    mean_grain_size_phi: float = math.nan
    water_sound_speed_m_s: float = 1500.0

    uses_azimuth = False

    def __post_init__(self):
        check_number("AplUw", "density_ratio", self.density_ratio, lo=1.0, hi=3.0)
        check_number("AplUw", "sound_speed_ratio", self.sound_speed_ratio, lo=0.9, hi=3.0)
        check_number("AplUw", "loss_parameter", self.loss_parameter, positive=True, hi=0.1)
        check_number("AplUw", "spectral_strength_cm4", self.spectral_strength_cm4, positive=True, hi=1.0)
        check_number("AplUw", "volume_parameter", self.volume_parameter, lo=0.0, hi=0.1)
        check_number("AplUw", "spectral_exponent", self.spectral_exponent, lo=2.01, hi=3.99)
        check_number("AplUw", "water_sound_speed_m_s", self.water_sound_speed_m_s, lo=1300.0, hi=1700.0)

    @classmethod
    def from_grain_size(cls, mz_phi: float, **overrides) -> "AplUw":
        """The handbook's parameters at mean grain size ``mz_phi`` (φ, −1 … 9); ``overrides`` replace any field."""
        check_number("AplUw", "mean_grain_size_phi", mz_phi, lo=VALID_GRAIN_SIZE_PHI[0], hi=VALID_GRAIN_SIZE_PHI[1])
        nu = apl_sound_speed_ratio(mz_phi)
        kw = dict(density_ratio=apl_density_ratio(mz_phi), sound_speed_ratio=nu,
                  loss_parameter=apl_attenuation_db_m_khz(mz_phi) * nu * C_REF_M_S * math.log(10.0) / (40e3 * math.pi),
                  spectral_strength_cm4=apl_spectral_strength_cm4(mz_phi),
                  volume_parameter=0.002 if mz_phi < 5.5 else 0.001, mean_grain_size_phi=float(mz_phi))
        return cls(**{**kw, **overrides})

    def components(self, grazing_rad, frequency_hz: float) -> dict:
        """σ_kr, σ_pr, σ_r, σ_v and σ (their sum) at grazing angles ``grazing_rad`` (rad, in (0, π/2]), linear."""
        g = np.asarray(grazing_rad, dtype=float)
        k = 2.0 * math.pi * frequency_hz / self.water_sound_speed_m_s
        rho, kappa = self.density_ratio, (1.0 + 1j * self.loss_parameter) / self.sound_speed_ratio
        s, c = np.sin(g), np.cos(g)
        p = np.sqrt(kappa ** 2 - c ** 2 + 0j)
        r = (rho * s - p) / (rho * s + p)
        kr = self._kirchhoff(s, c, k, abs((rho - kappa) / (rho + kappa)) ** 2)
        y = ((rho - 1.0) ** 2 * c ** 2 + rho ** 2 - kappa ** 2) / (rho * s + p) ** 2
        with np.errstate(divide="ignore"):
            pr = 4.0 * k ** 4 * s ** 4 * np.abs(y) ** 2 * self._spectrum(2.0 * k * c)
            rough = (kr ** ETA + pr ** ETA) ** (1.0 / ETA)
        vol = (5.0 * self.loss_parameter * self.volume_parameter * np.abs(1.0 - r * r) ** 2 * s ** 2
               / (math.log(10.0) * np.abs(p) ** 2 * p.imag))
        return {"kirchhoff": kr, "perturbation": pr, "roughness": rough, "volume": vol, "total": rough + vol}

    def _spectrum(self, wavenumber):
        """W(K) = w2/(h0·K)^γ in m⁴ for K in rad/m."""
        return self.spectral_strength_cm4 * 1e-8 / (H0_M * np.asarray(wavenumber)) ** self.spectral_exponent

    def _kirchhoff(self, s, c, k: float, r90_sq: float):
        """σ_kr of the power-law spectrum (TR 9407's Kirchhoff roughness cross-section)."""
        a_ = 0.5 * self.spectral_exponent - 1.0
        w = self.spectral_strength_cm4 * 1e-8 * H0_M ** -self.spectral_exponent  # W(K) = w/K^γ, SI
        ch2 = 2.0 * math.pi * w * gamma(2.0 - a_) * 2.0 ** (-2.0 * a_) / (a_ * (1.0 - a_) * gamma(1.0 + a_))
        qc = ch2 * 2.0 ** (1.0 - 2.0 * a_) * k ** (2.0 * (1.0 - a_))
        e = (1.0 + a_) / (2.0 * a_)
        a = (8.0 * a_ ** 2 * gamma(e) / (gamma(0.5) * gamma(1.0 / a_) * gamma(0.5 / a_))) ** (2.0 * a_)
        b = a ** e * gamma(1.0 / a_) / (2.0 * a_)
        return b * qc * r90_sq / (8.0 * math.pi * (c ** (4.0 * a_) + a * qc ** 2 * s ** 4) ** e)

    def backscatter_strength_db(self, grazing_deg, frequency_hz: float):
        """10·log10 σ at ``grazing_deg`` (degrees, in (0, 90]) and ``frequency_hz`` (Hz), dB re 1 m² per m² per sr."""
        return 10.0 * np.log10(self.components(np.radians(grazing_deg), frequency_hz)["total"])

    def at_frequency(self, frequency_hz: float) -> Tabulated:
        """The law at one carrier: a table of its strengths on :data:`TABLE_GRAZING_DEG` (a one-line warning
        outside the handbook's 10–100 kHz)."""
        check_number("AplUw", "frequency_hz", frequency_hz, positive=True)
        lo, hi = VALID_FREQUENCY_HZ
        if not lo <= frequency_hz <= hi:
            warn_once(f"AplUw at {frequency_hz / 1e3:g} kHz: the APL-UW model is stated for {lo / 1e3:g}–"
                      f"{hi / 1e3:g} kHz; beyond it the roughness spectrum's power law is extrapolated")
        db = np.clip(self.backscatter_strength_db(TABLE_GRAZING_DEG, frequency_hz), -300.0, 30.0)
        return Tabulated(tuple(TABLE_GRAZING_DEG), tuple(db))

    def params(self, data: list | None = None) -> tuple:
        """Not tabled directly: the law depends on the carrier."""
        raise ConfigError("AplUw: take the law at_frequency() first (its strength depends on the carrier)")

    def sigma(self, cos_i, cos_s, phi_rad=0.0):
        """Not defined without a carrier (see :meth:`at_frequency`)."""
        raise ConfigError("AplUw: take the law at_frequency() first (its strength depends on the carrier)")


#: Sediment classes by their Wentworth name at the class's centre grain size, φ (C. K. Wentworth, "A scale of grade
#: and class terms for clastic sediments", J. Geol. 30, 377–392, 1922): coarse sand … clay, within the regressions.
CLASSES_PHI = {"gravel": -1.0, "very coarse sand": -0.5, "coarse sand": 0.5, "medium sand": 1.5, "fine sand": 2.5,
               "very fine sand": 3.5, "coarse silt": 4.5, "medium silt": 5.5, "fine silt": 6.5,
               "very fine silt": 7.5, "clay": 9.0}


def apl_class(name: str) -> AplUw:
    """The APL-UW sediment of a class of :data:`CLASSES_PHI` (spaces or underscores; one-line error otherwise)."""
    key = str(name).replace("_", " ").strip().lower()
    if key not in CLASSES_PHI:
        raise ConfigError(f"unknown APL-UW sediment class {name!r}; one of {sorted(CLASSES_PHI)}")
    return AplUw.from_grain_size(CLASSES_PHI[key])


__all__ = ["AplUw", "CLASSES_PHI", "apl_class"]
