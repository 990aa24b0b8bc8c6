"""The elastic small-slope seabed model: roughness and sediment-volume backscatter at every grazing angle.

D. R. Jackson and M. D. Richardson, *High-Frequency Seafloor Acoustics*, Springer, 2007, ch. 13 (§13.2, the
small-slope approximation; §13.3, volume perturbation theory), in the elastic form of APL-UW TM 2-00 (D. R. Jackson,
"Models for scattering from the sea-bed", 2000). Unlike the APL-UW handbook's model (TR 9407, :mod:`.apl_uw`) it
needs no join between a Kirchhoff and a perturbation regime: the small-slope approximation holds from grazing
incidence to nadir. Monostatic strengths (backscatter, azimuth 180°); the notation is the book's.

**Sediment.** ρ (density ratio), ν_p, δ_p (compressional speed ratio and loss parameter) and ν_t, δ_t (shear), so
that a_p = ν_p/(1 + iδ_p) and a_t = ν_t/(1 + iδ_t) are the complex speed ratios. The roughness spectrum is
W(K) = w₂/K^γ₂ (SI, m^(4−γ₂)); the volume fluctuations have the spectrum W_v(q) = w₃/(a²q_h² + q_z² + q₀²)^(γ₃/2)
with q₀ = 10⁻³ k and a correlation matrix between density, compressional and shear fluctuations.

**Roughness.** With θ the grazing angle and k = 2πf/c_w, the flat interface's reflection coefficient is
R = (Z − 1)/(Z + 1), Z = ρ sin θ (cos²2θ_t/P_p + sin²2θ_t/P_t), P_{p,t} = √(a_{p,t}⁻² − cos²θ), cos 2θ_t =
2a_t² cos²θ − 1. The small-slope cross-section is

    σ_r = |A|²/(2π q² q₃²) · ∫₀^∞ J₀(u) exp(−p u^(2α)) u du,   p = ½ C_h² q₃² q^(−2α),

with q = 2k cos θ (the horizontal Bragg wavenumber, regularised by 10⁻³k as TM 2-00 does at nadir), q₃ = 2k sin θ,
α = γ₂/2 − 1, C_h² = 2π w₂ Γ(2 − α) 2^(−2α)/(α(1 − α) Γ(1 + α)), and A the first-order elastic perturbation
amplitude (TM 2-00: a combination of the factors (1 ± R)² with elastic coefficients D₁ … D₄). The integral is
evaluated here by quadrature where the structure function decays within a few hundred oscillations of J₀, and by
its large-argument series (term by term from ∫ t^μ J₀(ρt) dt) where it does not.

**Volume.** First-order perturbation of the sediment below a flat interface, summed over the compressional and
shear waves down and up (TM 2-00), and capped as σ_v,eff = 1/(1/σ₀ + 1/σ_v) with σ₀ = 0.1.

Tested against published reference values of an independent implementation of the same model (eight sediments
from rock to silt at 20 and 300 kHz, 5–85°): tests/laws/test_small_slope.py. The model is stated here for
10 kHz – 1 MHz (the reference values are at 20 and 300 kHz; the power-law spectra are assumed to hold up to the
side-scan frequencies above); one warning per process outside that range.
"""
from __future__ import annotations

import ast
import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.special import gamma, j0, rgamma

from ..errors import ConfigError
from ..validation import check_number, warn_once
from .composite import Summable
from .tabulated import Tabulated

#: The carrier frequencies the model is stated for, Hz (see the module docstring).
VALID_FREQUENCY_HZ = (10e3, 1e6)
#: Grazing angles a run's table starts from (:meth:`SmallSlope.at_frequency`), degrees: geometric below 5° (σ falls
#: as a power of the angle there), then every half degree; refined where linear interpolation in dB would miss the
#: model by more than :data:`TABLE_TOLERANCE_DB` (critical angles of hard sediments).
TABLE_GRAZING_DEG = np.concatenate([np.geomspace(0.02, 5.0, 60)[:-1], np.arange(5.0, 89.5, 0.5), [89.75]])
TABLE_TOLERANCE_DB = 0.01
#: The cap of the volume term (TM 2-00's σ₀).
SIGMA_0 = 0.1
#: Density–compressional fluctuations only, the correlation matrix of the unconsolidated sediments.
DENSITY_ONLY = ((1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def _bessel_integral(alpha: float, p: float) -> float:
    """∫₀^∞ J₀(u) exp(−p u^(2α)) u du for 0 < α < 1, p > 0.

    With u = t/p^(1/2α) it is p^(−1/α)·H(ρ), H(ρ) = ∫₀^∞ t J₀(ρt) exp(−t^(2α)) dt, ρ = p^(−1/2α). H is integrated
    by Gauss–Legendre panels of a quarter oscillation each (the first graded geometrically towards t = 0, where
    t^(2α) is not smooth) up to t where exp(−t^(2α)) < 1e-17 while ρ ≤ 40, and
    otherwise by its large-ρ series H(ρ) = Σₙ (−1)ⁿ/n! · 2^(2αn+1) Γ(1 + αn)/(Γ(−αn) ρ^(2αn+2)), n ≥ 1 (term by
    term from ∫₀^∞ t^μ J₀(ρt) dt = 2^μ Γ((1 + μ)/2)/(ρ^(μ+1) Γ((1 − μ)/2)), μ = 2αn + 1)."""
    rho = p ** (-0.5 / alpha)
    if rho <= 40.0:
        t_max = (39.2) ** (0.5 / alpha)
        panels = max(256, int(math.ceil(t_max * max(rho, 1.0) / (0.5 * math.pi))))
        x, w = np.polynomial.legendre.leggauss(16)
        edges = np.linspace(0.0, t_max, panels + 1)            # the first panel graded towards t = 0 (t^(2α) there)
        edges = np.concatenate(([0.0], edges[1] * 2.0 ** -np.arange(40.0, 0.0, -1.0), edges[1:]))
        panels = edges.size - 1
        mid, half = 0.5 * (edges[1:] + edges[:-1]), 0.5 * np.diff(edges)
        t = (mid[:, None] + half[:, None] * x[None, :]).ravel()
        h = float(np.sum(np.repeat(half, x.size) * np.tile(w, panels) * t * j0(rho * t) * np.exp(-t ** (2 * alpha))))
    else:
        h, n = 0.0, 1
        while n < 40:
            term = ((-1) ** n / math.factorial(n) * 2.0 ** (2 * alpha * n + 1) * math.gamma(1 + alpha * n)
                    * float(rgamma(-alpha * n)) / rho ** (2 * alpha * n + 2))   # 1/Γ: zero at Γ's poles
            h += term
            if n > 2 and abs(term) < 1e-15 * abs(h):
                break
            n += 1
    return p ** (-1.0 / alpha) * h


#: How :class:`SmallSlope` evaluates its integral: "exact" (:func:`_bessel_integral`, the default) or "prony"
#: (:func:`_prony_integral`, the published reference implementation's approximation).
INTEGRALS = ("exact", "prony")


def _prony_integral(alpha: float, p: float, n_samples: int = 100, n_terms: int = 10, floor: float = 1e-3) -> float:
    """∫₀^∞ J₀(u) exp(−p u^(2α)) u du as the reference implementation evaluates it (the MATLAB code whose outputs
    the OpenBST project publishes, hydroffice/hyo2_openbst, data/input/jackson2): exp(−p u^(2α)) sampled
    ``n_samples`` times on [0, u_max], where it falls to ``floor``, fitted by ``n_terms`` exponentials Σ aᵢ e^(bᵢu)
    (Prony: linear prediction, then the roots), each integrated in closed form, ∫₀^∞ J₀(u) e^(bu) u du =
    1/(b²(1 + b⁻²)^(3/2)) for Re b < 0. It is off the exact integral by up to 2.4 dB at 5° grazing (silt, 20 kHz);
    it is here to reproduce the published values, not as the default."""
    u_max = (abs(math.log(floor)) / p) ** (0.5 / alpha)
    u = np.linspace(0.0, u_max, n_samples)
    w = np.exp(-p * u ** (2 * alpha))
    lagged = np.stack([w[j:n_samples - n_terms + j] for j in range(n_terms)], axis=1)
    coef = np.linalg.lstsq(lagged, -w[n_terms:], rcond=None)[0]
    b = np.log(np.roots(np.concatenate(([1.0], coef[::-1]))).astype(complex)) / (u[1] - u[0])
    a = np.linalg.lstsq(np.exp(np.outer(u, b)), w.astype(complex), rcond=None)[0]
    return float(np.real(np.sum(a / (b ** 2 * (1 + b ** -2) ** 1.5))))


@dataclass(frozen=True)
class SmallSlope(Summable):
    """A sediment in the elastic small-slope model (the module's docstring gives the equations and sources).

    Parameters
    ----------
    density_ratio : float
        ρ, sediment over water density, in [1, 3].
    sound_speed_ratio, loss_parameter : float
        ν_p and δ_p of the compressional wave (ν_p in [0.9, 3], δ_p in [0, 0.1]).
    shear_speed_ratio, shear_loss_parameter : float
        ν_t and δ_t of the shear wave (ν_t in (0, 2], δ_t in [0, 2]; 0.002 and 1 for sands and silts: no shear).
    roughness_exponent, roughness_strength : float
        γ₂ in (2, 4) and w₂ > 0 (SI, m^(4−γ₂)) of the roughness spectrum W(K) = w₂/K^γ₂.
    volume_exponent, volume_strength : float
        γ₃ in (2, 4) and w₃ ≥ 0 of the volume fluctuations' spectrum.
    correlation : 3×3 tuple
        The fluctuations' correlation matrix (density, compressional, shear); default density–compressional only.
    aspect_ratio : float
        a, the volume fluctuations' horizontal over vertical scale ratio (1: isotropic).
    water_sound_speed_m_s : float
        c_w, which sets k = 2πf/c_w, m/s.
    integral : str
        "exact" (default: the integral to 10⁻¹⁰) or "prony": the published reference implementation's Prony
        approximation (:func:`_prony_integral`), which reproduces its published values within 0.01 dB at every
        angle, 5° included, where it is up to 0.52 dB off the exact law's total.

    It depends on the carrier, so a run takes it :meth:`at_frequency` (a table on :data:`TABLE_GRAZING_DEG`).
    """

    density_ratio: float
    sound_speed_ratio: float
    loss_parameter: float
    shear_speed_ratio: float
    shear_loss_parameter: float
    roughness_exponent: float
    roughness_strength: float
    volume_exponent: float
    volume_strength: float
    correlation: tuple = DENSITY_ONLY
    aspect_ratio: float = 1.0
    water_sound_speed_m_s: float = 1500.0
    integral: str = "exact"

    uses_azimuth = False

    def __post_init__(self):
        for name, lo, hi in (("density_ratio", 1.0, 3.0), ("sound_speed_ratio", 0.9, 3.0),
                             ("loss_parameter", 0.0, 0.1), ("shear_loss_parameter", 0.0, 2.0),
                             ("roughness_exponent", 2.01, 3.99), ("volume_exponent", 2.01, 3.99),
                             ("volume_strength", 0.0, 1.0), ("aspect_ratio", 0.01, 100.0),
                             ("water_sound_speed_m_s", 1300.0, 1700.0)):
            check_number("SmallSlope", name, getattr(self, name), lo=lo, hi=hi)
        if self.integral not in INTEGRALS:
            raise ConfigError(f"SmallSlope.integral must be one of {INTEGRALS}, got {self.integral!r}")
        check_number("SmallSlope", "shear_speed_ratio", self.shear_speed_ratio, positive=True, hi=2.0)
        check_number("SmallSlope", "roughness_strength", self.roughness_strength, positive=True, hi=1.0)
        corr = np.asarray(self.correlation, dtype=float)
        if corr.shape != (3, 3) or not np.all(np.isfinite(corr)) or not np.allclose(corr, corr.T):
            raise ConfigError(f"SmallSlope.correlation must be a symmetric 3×3 matrix, got {self.correlation!r}")
        object.__setattr__(self, "correlation", tuple(map(tuple, corr.tolist())))

    def _ratios(self):
        return (self.sound_speed_ratio / complex(1.0, self.loss_parameter),
                self.shear_speed_ratio / complex(1.0, self.shear_loss_parameter))

    def _interface(self, c: float, s: float) -> dict:
        """The flat interface at grazing cosine ``c`` and sine ``s``: P_p, P_t, cos 2θ_t, sin 2θ_t, R."""
        a_p, a_t = self._ratios()
        p_p, p_t = np.sqrt(a_p ** -2 - c * c + 0j), np.sqrt(a_t ** -2 - c * c + 0j)
        cos2 = 2.0 * a_t ** 2 * c * c - 1.0
        sin2 = np.sqrt(1.0 - cos2 ** 2 + 0j)
        z = self.density_ratio * s * (cos2 ** 2 / p_p + sin2 ** 2 / p_t)
        return {"p_p": p_p, "p_t": p_t, "cos2": cos2, "sin2": sin2, "r": (z - 1.0) / (z + 1.0)}

    def _amplitude(self, c: float, s: float, f: dict) -> complex:
        """A/(½k²): TM 2-00's elastic perturbation amplitude of backscatter (D₁ … D₄ on the (1 ± R)² terms)."""
        a_p, a_t, rho = *self._ratios(), self.density_ratio
        x = -c * c                                         # cos θs cos θi cos φ at φ = 180°
        cc = f["cos2"] ** 2
        d1 = (-1.0 + x + 1.0 / (a_p ** 2 * rho * cc)
              - a_t ** 2 * ((a_t ** -2 - 4.0 * c * c + 2.0 * x) * x + 2.0 * c ** 4) / (rho * cc))
        d23 = -4.0 * a_t ** 4 * s * f["p_t"] / cc * (f["p_p"] ** 2 * c * c + (c * c - x) * x)
        d4 = (2.0 * a_t ** 6 * rho * s * s * f["p_t"] ** 2 / cc
              * (2.0 * (a_t ** -2 - 2.0 * x) * x - 4.0 * c ** 4 * (1.0 - 2.0 * a_t ** 2 * a_p ** -2))
              - (rho - 1.0) * s * s)
        r = f["r"]
        return d1 * (1 + r) ** 2 + 2.0 * d23 * (1 - r) * (1 + r) + d4 * (1 - r) ** 2

    def roughness(self, grazing_rad: float, frequency_hz: float, interface: dict | None = None) -> tuple:
        """(σ_r, R) at one grazing angle (rad) and frequency (Hz): the small-slope cross-section and the flat
        interface's reflection coefficient (``interface``: :meth:`_interface` at that angle, when already made)."""
        k = 2.0 * math.pi * frequency_hz / self.water_sound_speed_m_s
        c, s = math.cos(grazing_rad), math.sin(grazing_rad)
        f = self._interface(c, s) if interface is None else interface
        q, q3 = k * math.sqrt(4.0 * c * c + 1e-6), 2.0 * k * s
        alpha = 0.5 * self.roughness_exponent - 1.0
        ch2 = (2.0 * math.pi * self.roughness_strength * gamma(2.0 - alpha) * 2.0 ** (-2.0 * alpha)
               / (alpha * (1.0 - alpha) * gamma(1.0 + alpha)))
        p = 0.5 * ch2 * q3 ** 2 * q ** (-2.0 * alpha)
        amp = 0.5 * k * k * self._amplitude(c, s, f)
        integral = _prony_integral(alpha, p) if self.integral == "prony" else _bessel_integral(alpha, p)
        return abs(amp) ** 2 / (2.0 * math.pi * q * q * q3 * q3) * integral, complex(f["r"])

    def volume(self, grazing_rad: float, frequency_hz: float, interface: dict | None = None) -> float:
        """σ_v at one grazing angle (rad) and frequency (Hz), before the cap (first-order volume perturbation;
        ``interface`` as for :meth:`roughness`)."""
        k = 2.0 * math.pi * frequency_hz / self.water_sound_speed_m_s
        a_p, a_t = self._ratios()
        c, s = math.cos(grazing_rad), math.sin(grazing_rad)
        f = self._interface(c, s) if interface is None else interface
        p1, p2, r = f["p_p"], f["p_t"], f["r"]
        t = (f["cos2"] * s / p1 * (1 - r), f["sin2"] * s / p2 * (1 - r))      # into the sediment: p and t waves
        down = np.array([[c, c, p2], [0, 0, 0], [-p1, -p2, c]], dtype=complex)     # columns: p, t, t's polarisation
        up = np.array([[-c, -c, p2], [0, 0, 0], [p1, p2, c]], dtype=complex)       # φ = 180°
        b = up.T @ down
        pairs = ((0, 0), (0, 1), (1, 0), (1, 1))                                    # (up wave, down wave): pp pt tp tt
        qv = [k * (up[:, m] - down[:, n]) for m, n in pairs]
        q3 = [k * ((p1, p2)[m] + (p1, p2)[n]) for m, n in pairs]
        w = [t[m] * t[n] for m, n in pairs]
        d_rho = np.array([a_p ** -2 - b[0, 0], b[0, 2], -b[2, 0], b[2, 2]])
        d_t = 2.0 * a_t ** 2 * np.array([2.0 * (b[0, 0] ** 2 - a_p ** -4), -2.0 * b[0, 2] * b[0, 1],
                                         2.0 * b[2, 0] * b[1, 0], -(b[2, 2] * b[1, 1] + b[2, 1] * b[1, 2])])
        d = np.stack([d_rho + 0.5 * d_t, np.array([2.0 * a_p ** -2, 0, 0, 0]), d_t], axis=1)
        corr, total = np.asarray(self.correlation), 0.0
        for i in range(4):
            for j in range(4):
                bragg = 0.5 * (qv[i] + np.conj(qv[j]))
                spec = self.volume_strength / (self.aspect_ratio ** 2 * (bragg[0] ** 2 + bragg[1] ** 2)
                                               + bragg[2] ** 2 + (1e-3 * k) ** 2) ** (0.5 * self.volume_exponent)
                total += (w[i] * np.conj(w[j]) * (d[i] @ corr @ np.conj(d[j])) * spec
                          / (q3[i] - np.conj(q3[j]))).imag
        return float(-0.5 * math.pi * k ** 4 * self.density_ratio ** 2 * total)

    def components(self, grazing_deg, frequency_hz: float) -> dict:
        """σ_r, σ_v (capped), σ (their sum), linear, and the reflection loss −20·log10|R| (dB) at ``grazing_deg``."""
        g = np.radians(np.atleast_1d(np.asarray(grazing_deg, dtype=float)))
        rough, refl, vol = (np.empty(g.size) for _ in range(3))
        for i, gi in enumerate(g):
            face = self._interface(math.cos(gi), math.sin(gi))           # shared by both terms
            rough[i], r = self.roughness(gi, frequency_hz, face)
            refl[i] = -20.0 * math.log10(abs(r))
            vol[i] = 1.0 / (1.0 / SIGMA_0 + 1.0 / self.volume(gi, frequency_hz, face))
        return {"roughness": rough, "volume": vol, "total": rough + vol, "reflection_loss_db": refl}

    def backscatter_strength_db(self, grazing_deg, frequency_hz: float):
        """10·log10 σ at ``grazing_deg`` (degrees, in (0, 90)) and ``frequency_hz`` (Hz), dB re 1 m² per m² per sr."""
        return 10.0 * np.log10(self.components(grazing_deg, frequency_hz)["total"])

    def at_frequency(self, frequency_hz: float) -> Tabulated:
        """The law at one carrier: a table of its strengths from :data:`TABLE_GRAZING_DEG`, refined until linear
        interpolation in dB is within :data:`TABLE_TOLERANCE_DB` of the model at every interval's middle (one warning
        per process outside :data:`VALID_FREQUENCY_HZ`). The same law at the same carrier is tabulated once per
        process (:func:`_table`, keyed by the law's numbers): a default seabed in every block of a streamed line costs
        one table, not one per block."""
        check_number("SmallSlope", "frequency_hz", frequency_hz, positive=True)
        lo, hi = VALID_FREQUENCY_HZ
        if not lo <= frequency_hz <= hi:
            warn_once(f"SmallSlope at {frequency_hz / 1e3:g} kHz: the small-slope seabed model is stated here for "
                      f"{lo / 1e3:g}–{hi / 1e3:g} kHz; beyond it its power-law spectra are extrapolated")
        return _table(repr(dataclasses.astuple(self)), float(frequency_hz))

    def tabulate(self, frequency_hz: float) -> Tabulated:
        """The table of :meth:`at_frequency`, built (no cache, no warning)."""
        g = TABLE_GRAZING_DEG
        db = self.backscatter_strength_db(g, frequency_hz)
        for _ in range(8):                                  # halve the intervals where the line misses the model
            mid = 0.5 * (g[1:] + g[:-1])
            at_mid = self.backscatter_strength_db(mid, frequency_hz)
            bad = np.abs(at_mid - 0.5 * (db[1:] + db[:-1])) > TABLE_TOLERANCE_DB
            if not bad.any():
                break
            order = np.argsort(np.concatenate([g, mid[bad]]))
            g, db = np.concatenate([g, mid[bad]])[order], np.concatenate([db, at_mid[bad]])[order]
        return Tabulated(tuple(g), tuple(np.clip(db, -300.0, 30.0)))

    def params(self, data: list | None = None) -> tuple:
        """Not tabled directly: the law depends on the carrier."""
        raise ConfigError("SmallSlope: take the law at_frequency() first (its strength depends on the carrier)")

    def sigma(self, cos_i, cos_s, phi_rad=0.0):
        """Not defined without a carrier (see :meth:`at_frequency`)."""
        raise ConfigError("SmallSlope: take the law at_frequency() first (its strength depends on the carrier)")


#: The correlation matrix of the rocks' fluctuations (density, compressional, shear): fully correlated, in the
#: proportions 1 : 3 : 4.
ROCK_CORRELATION = ((1.0, 3.0, 4.0), (3.0, 9.0, 12.0), (4.0, 12.0, 16.0))

#: The eight test sediments of the small-slope model (Jackson & Richardson 2007, ch. 13 and TM 2-00, as published
#: with the reference values of hydroffice/hyo2_openbst, data/input/jackson2): ρ, ν_p, δ_p, ν_t, δ_t, γ₂, w₂ (SI;
#: fine sand's 8.6e-5 is TR 9407's 0.00271 cm⁴ at γ₂ = 3.25), γ₃, w₃. Rocks take :data:`ROCK_CORRELATION`.
SEDIMENTS = {
    "rough rock": (2.5, 2.3, 0.00174, 1.3, 0.085, 2.75, 0.0001, 3.0, 0.0002),
    "rock": (2.5, 2.3, 0.00174, 1.31, 0.085, 3.0, 0.00025, 3.0, 0.00006),
    "cobble": (2.5, 1.8, 0.01374, 1.01, 0.1, 3.0, 0.00025, 3.0, 0.00152),
    "sandy gravel": (2.492, 1.337, 0.01705, 0.156, 0.2, 3.0, 0.00018, 3.0, 0.000377),
    "coarse sand": (2.231, 1.2503, 0.01638, 0.134, 0.075, 3.25, 0.00022, 3.0, 0.000362),
    "medium sand": (1.845, 1.1782, 0.01624, 0.002, 1.0, 3.25, 0.0001406, 3.0, 0.000359),
    "fine sand": (1.451, 1.1072, 0.01602, 0.002, 1.0, 3.25, 0.000086, 3.0, 0.000354),
    "silt": (1.149, 0.9873, 0.00386, 0.002, 1.0, 3.25, 0.0000164, 3.0, 0.00004269),
}


def small_slope_sediment(name: str, integral: str = "exact") -> SmallSlope:
    """The small-slope sediment ``name`` of :data:`SEDIMENTS` (spaces or underscores; one-line error otherwise),
    its integral evaluated as ``integral`` says (:class:`SmallSlope`)."""
    key = str(name).replace("_", " ").strip().lower()
    if key not in SEDIMENTS:
        raise ConfigError(f"unknown small-slope sediment {name!r}; one of {sorted(SEDIMENTS)}")
    v = SEDIMENTS[key]
    return SmallSlope(*v, correlation=ROCK_CORRELATION if key.endswith("rock") else DENSITY_ONLY, integral=integral)


@functools.lru_cache(maxsize=32)
def _table(fields: str, frequency_hz: float) -> Tabulated:
    """:meth:`SmallSlope.tabulate` of the law whose fields' ``repr`` is ``fields``: a pure function of numbers (the
    table depends on nothing else), so it is kept."""
    return SmallSlope(*ast.literal_eval(fields)).tabulate(frequency_hz)


__all__ = ["INTEGRALS", "SEDIMENTS", "SmallSlope", "TABLE_GRAZING_DEG", "VALID_FREQUENCY_HZ", "small_slope_sediment"]
