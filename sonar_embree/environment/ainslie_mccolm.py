"""Sound absorption in sea water: Ainslie & McColm (1998), a simplified formula.

M. A. Ainslie and J. G. McColm, "A simplified formula for viscous and chemical
absorption in sea water", J. Acoust. Soc. Am. 103(3), 1671–1672 (1998). The same
three relaxations as Francois–Garrison (boric acid, magnesium sulphate, pure water)
in a shorter form; within 10 % of Francois–Garrison over 10 Hz–1 MHz, −2–22 °C,
30–35 ppt (docs/physics.md §3).
"""
from __future__ import annotations

import math


def ainslie_mccolm_db_per_m(frequency_hz: float, temperature_c: float = 10.0, salinity_ppt: float = 35.0,
                            depth_m: float = 0.0, ph: float = 8.0) -> float:
    """One-way absorption α of sea water in dB/m (Ainslie & McColm 1998).

    Parameters
    ----------
    frequency_hz : float
        Acoustic frequency, Hz.
    temperature_c : float
        Temperature, °C.
    salinity_ppt : float
        Salinity, ppt.
    depth_m : float
        Depth, m.
    ph : float
        Acidity (boric-acid term).

    Returns
    -------
    float
        α in dB/m (0.1011 at 400 kHz, 10 °C, 35 ppt, 0 m, pH 8).
    """
    f = frequency_hz / 1e3  # kHz
    t, s, z = temperature_c, salinity_ppt, depth_m / 1e3  # z in km
    f1 = 0.78 * math.sqrt(s / 35.0) * math.exp(t / 26.0)  # boric acid relaxation, kHz
    f2 = 42.0 * math.exp(t / 17.0)                       # magnesium sulphate relaxation, kHz
    ff = f * f
    boric = 0.106 * f1 * ff / (f1 * f1 + ff) * math.exp((ph - 8.0) / 0.56)
    mgso4 = 0.52 * (1.0 + t / 43.0) * (s / 35.0) * f2 * ff / (f2 * f2 + ff) * math.exp(-z / 6.0)
    water = 0.00049 * ff * math.exp(-(t / 27.0 + z / 17.0))
    return (boric + mgso4 + water) / 1e3
