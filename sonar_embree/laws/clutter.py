"""Discrete clutter: Poisson populations of sub-resolution point scatterers on a surface (docs/physics.md §10c).

Shell, gravel and small stones scatter as points, not as a continuum: a surface carries scatterers at the points of
a Poisson process of density n per m², each with its own backscattering cross-section σ_k (m²), frozen to the
surface with a frozen phase. Their strengths follow a log-normal law, 10·log10 σ_k normal with median
``strength_db`` and standard deviation ``spread_db`` (a heavy tail for a few dB of spread; the log-normal is the
usual model of clutter-strength distributions: D. A. Abraham, *Underwater Acoustic Signal Processing*, Springer,
2019, §7.4). A resolution cell holding N̄ = n·A of them has, with amplitudes a_k = √σ_k and independent uniform
phases (compound Poisson; docs/physics.md §10c),

    E[I] = N̄⟨a²⟩,   E[I²] = 2E[I]² + N̄⟨a⁴⟩,   SI = E[I²]/E[I]² − 1 = 1 + ⟨a⁴⟩/(N̄⟨a²⟩²),

and with a diffuse (Rayleigh) part of power P_d beside them SI = 1 + N̄⟨a⁴⟩/(N̄⟨a²⟩ + P_d)². For the log-normal
⟨σ²⟩/⟨σ⟩² = exp(s²) with s = spread_db·ln 10/10: heavy-tailed where N̄ is small, Rayleigh as N̄ grows, and no
correlation beyond the cell (J. W. Goodman, *Speckle Phenomena in Optics*, Roberts, 2007, §3.3; E. Jakeman and
P. N. Pusey, IEEE Trans. Antennas Propag. 24, 806–814, 1976).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..validation import check_number


@dataclass(frozen=True)
class Clutter:
    """Point scatterers on a surface, a Poisson process of ``density_per_m2`` with log-normal strengths.

    Parameters
    ----------
    density_per_m2 : float
        n, scatterers per m² of surface, in (0, 1e4].
    strength_db : float
        Median backscattering cross-section of one scatterer, dB re 1 m² (a 1 cm shell about −50 dB; a 5 cm stone
        about −35 dB), in [−120, 0].
    spread_db : float
        Standard deviation of 10·log10 σ_k, dB, in [0, 20] (0: all alike).
    """

    density_per_m2: float
    strength_db: float = -45.0
    spread_db: float = 5.0

    def __post_init__(self):
        check_number("Clutter", "density_per_m2", self.density_per_m2, positive=True, hi=1e4)
        check_number("Clutter", "strength_db", self.strength_db, lo=-120.0, hi=0.0)
        check_number("Clutter", "spread_db", self.spread_db, lo=0.0, hi=20.0)

    @property
    def _s(self) -> float:
        return self.spread_db * math.log(10.0) / 10.0

    @property
    def moment_ratio(self) -> float:
        """⟨σ²⟩/⟨σ⟩² = ⟨a⁴⟩/⟨a²⟩² = exp(s²)."""
        return math.exp(self._s ** 2)

    def draw(self, rng, n: int) -> np.ndarray:
        """σ_k of ``n`` scatterers, m²."""
        return 10.0 ** ((self.strength_db + self.spread_db * rng.standard_normal(n)) / 10.0)


__all__ = ["Clutter"]
