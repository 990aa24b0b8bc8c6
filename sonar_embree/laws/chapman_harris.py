"""Chapman and Harris's sea-surface backscattering strength (docs/physics.md §13, the surface line).

R. P. Chapman and J. H. Harris, "Surface backscattering strengths measured with explosive sound sources",
J. Acoust. Soc. Am. 34, 1592–1597 (1962), fitted the backscattering strength of the wind-roughened sea surface
measured north of Bermuda (0.4–6.4 kHz, winds up to about 30 knots) as

    S_s = 3.3·β·log10(θg/30°) − 42.4·log10 β + 2.6 dB,   β = 158·(v·f^(1/3))^(−0.58),

θg the grazing angle in degrees, v the wind speed in knots, f the frequency in Hz. It is the usual empirical
surface scattering strength of reverberation models (also in APL-UW TR 9407, 1994, as the low-frequency
reference of its surface model). Above 6.4 kHz it is an extrapolation: a side-scan's surface line is then a
plausible level, not a prediction (bubbles dominate there; give a measured curve as a Lambert level instead).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..validation import check_number
from .composite import Summable
from .tabulated import Tabulated

#: Knots per m/s.
KNOTS_PER_M_S = 3600.0 / 1852.0
#: Grazing angles of the table a frequency's curve becomes, degrees: log-spaced (the law is linear in log θg),
#: held below the first; linear interpolation between them is within 1e-3 dB of the formula.
TABLE_GRAZING_DEG = np.geomspace(0.01, 90.0, 600)
#: Strengths are held within these bounds, dB (the fit goes to −∞ at grazing and past 0 dB for calm seas at
#: steep angles, where it was never measured).
STRENGTH_RANGE_DB = (-300.0, 0.0)


@dataclass(frozen=True)
class ChapmanHarris(Summable):
    """The wind-driven sea surface's backscattering strength of Chapman and Harris (1962).

    Parameters
    ----------
    wind_speed_m_s : float
        Wind speed, m/s (0.5–15.5 m/s: about 1–30 knots, the winds of the measurements).

    Monostatic (bistatic: the geometric mean of the two directions' strengths, as :class:`Tabulated`); it
    depends on the carrier, so a run takes it :meth:`at_frequency` (a table, held within
    :data:`STRENGTH_RANGE_DB`).
    """

    wind_speed_m_s: float

    uses_azimuth = False

    def __post_init__(self):
        check_number("ChapmanHarris", "wind_speed_m_s", self.wind_speed_m_s, lo=0.5, hi=15.5)

    def backscatter_strength_db(self, grazing_deg, frequency_hz: float):
        """S_s at ``grazing_deg`` (degrees, > 0) and ``frequency_hz`` (Hz), dB re 1 m² per m² per sr (unclipped)."""
        beta = 158.0 * (self.wind_speed_m_s * KNOTS_PER_M_S * frequency_hz ** (1.0 / 3.0)) ** -0.58
        return 3.3 * beta * np.log10(np.asarray(grazing_deg, dtype=float) / 30.0) - 42.4 * math.log10(beta) + 2.6

    def at_frequency(self, frequency_hz: float) -> Tabulated:
        """The law at one carrier: a table of its strengths on :data:`TABLE_GRAZING_DEG`."""
        check_number("ChapmanHarris", "frequency_hz", frequency_hz, positive=True)
        db = np.clip(self.backscatter_strength_db(TABLE_GRAZING_DEG, frequency_hz), *STRENGTH_RANGE_DB)
        return Tabulated(tuple(TABLE_GRAZING_DEG), tuple(db))

    def params(self, data: list | None = None) -> tuple:
        """Not tabled directly: the law depends on the carrier."""
        raise ConfigError("ChapmanHarris: take the law at_frequency() first (its strength depends on the carrier)")

    def sigma(self, cos_i, cos_s, phi_rad=0.0):
        """Not defined without a carrier (see :meth:`at_frequency`)."""
        raise ConfigError("ChapmanHarris: take the law at_frequency() first (its strength depends on the carrier)")


__all__ = ["ChapmanHarris", "KNOTS_PER_M_S"]
