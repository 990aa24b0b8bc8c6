"""Lambert's law: σ = μ·cos θi·cos θs (docs/physics.md §3, §10).

Lambert's rule for diffuse seafloor backscatter, monostatic σ = μ·cos²θi; μ = −27 dB
is Mackenzie's average for sand and mud (K. V. Mackenzie, "Bottom reverberation for
530- and 1030-cps sound in deep water", J. Acoust. Soc. Am. 33, 1498–1504, 1961).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ..kernels import njit
from ..validation import check_number
from .composite import Summable


@njit(cache=True, nogil=True, inline="always")
def lambert_sigma(params, o, cos_i, data):
    """σ/cos θi of Lambert at incidence cos θi on object ``o``: μ·cos θi (``params[o, 0]`` the linear μ; ``data``
    unused). The scalar σ of :func:`sonar_embree.laws.driver.law_weights`."""
    return params[o, 0] * cos_i


@dataclass(frozen=True)
class Lambert(Summable):
    """Lambert's law σ = μ·cos θi·cos θs per unit area per steradian.

    Parameters
    ----------
    backscatter_db : float
        μ in dB (−27 dB: Mackenzie 1961; published μ spans about −10 dB for rock to
        −40 dB for mud).
    """

    backscatter_db: float = -27.0

    uses_azimuth = False  # σ depends on θi and θs only

    def __post_init__(self):
        check_number("Lambert", "backscatter_db", self.backscatter_db, lo=-300.0, hi=30.0)

    @property
    def mu(self) -> float:
        """Linear μ = 10^(backscatter_db/10)."""
        return 10.0 ** (self.backscatter_db / 10.0)

    def params(self, data: list | None = None) -> tuple:
        """Kernel parameters: (μ,)."""
        return (self.mu,)

    def sigma(self, cos_i, cos_s, phi_rad=0.0):
        """σ(θi, θs, φ) = μ·cos θi·cos θs (independent of φ); zero below the surface."""
        cos_i, cos_s = np.asarray(cos_i, dtype=float), np.asarray(cos_s, dtype=float)
        return self.mu * np.clip(cos_i, 0.0, None) * np.clip(cos_s, 0.0, None) + 0.0 * np.asarray(phi_rad)
