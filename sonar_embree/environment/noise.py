"""Ambient noise of the ocean: the empirical spectra of Coates, as summarised by Stojanovic (docs/physics.md §14).

Spectral densities in dB re 1 µPa²/Hz, f in kHz, wind speed w in m/s, shipping activity s in [0, 1]:

    turbulence  N_t = 17 − 30·log10 f
    shipping    N_s = 40 + 20·(s − 0.5) + 26·log10 f − 60·log10(f + 0.03)
    wind        N_w = 50 + 7.5·√w + 20·log10 f − 40·log10(f + 0.4)
    thermal     N_th = −15 + 20·log10 f

and the total is the sum of their powers (R. F. W. Coates, *Underwater Acoustic Systems*, Macmillan, 1990;
M. Stojanovic, "On the relationship between capacity and distance in an underwater acoustic communication
channel", ACM SIGMOBILE Mob. Comput. Commun. Rev. 11(4), 34–43, 2007, eqs. (5)–(6)). Above about 100 kHz the
thermal term (the molecular agitation of the water, Mellen 1952) dominates: 37.0 dB re 1 µPa²/Hz at 400 kHz.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..validation import check_number


@dataclass(frozen=True)
class AmbientNoise:
    """Isotropic ambient noise of the sea (Coates 1990 / Stojanovic 2007).

    Parameters
    ----------
    wind_speed_m_s : float
        Wind speed over the sea, m/s, in [0, 50] (the wind term's w).
    shipping : float
        Shipping activity s in [0, 1] (0.5: moderate).
    thermal : bool
        Include the thermal term (default True; it sets the floor above ~100 kHz).
    """

    wind_speed_m_s: float = 5.0
    shipping: float = 0.5
    thermal: bool = True

    def __post_init__(self):
        check_number("AmbientNoise", "wind_speed_m_s", self.wind_speed_m_s, lo=0.0, hi=50.0)
        check_number("AmbientNoise", "shipping", self.shipping, lo=0.0, hi=1.0)
        if not isinstance(self.thermal, bool):
            raise ConfigError(f"AmbientNoise.thermal must be true or false, got {self.thermal!r}")

    def terms_db(self, frequency_hz) -> dict:
        """Each term's spectral density at ``frequency_hz`` (Hz, scalar or array), dB re 1 µPa²/Hz."""
        f = np.asarray(frequency_hz, dtype=float) / 1e3
        terms = {"turbulence": 17.0 - 30.0 * np.log10(f),
                 "shipping": 40.0 + 20.0 * (self.shipping - 0.5) + 26.0 * np.log10(f) - 60.0 * np.log10(f + 0.03),
                 "wind": (50.0 + 7.5 * math.sqrt(self.wind_speed_m_s) + 20.0 * np.log10(f)
                          - 40.0 * np.log10(f + 0.4))}
        if self.thermal:
            terms["thermal"] = -15.0 + 20.0 * np.log10(f)
        return terms

    def spectral_density_db(self, frequency_hz):
        """Total spectral density (sum of the terms' powers) at ``frequency_hz``, dB re 1 µPa²/Hz."""
        return 10.0 * np.log10(sum(10.0 ** (v / 10.0) for v in self.terms_db(frequency_hz).values()))
