"""Sound absorption in sea water: Francois & Garrison (1982).

R. E. Francois and G. R. Garrison, "Sound absorption based on ocean measurements.
Part II: Boric acid contribution and equation for total absorption", J. Acoust.
Soc. Am. 72(6), 1879–1890 (1982). Boric acid, magnesium sulphate and pure water
relaxations; valid for 0.2–1000 kHz, −2–22 °C (used to 40 °C), 30–35 ppt, any depth.
"""
from __future__ import annotations

import math


def francois_garrison_db_per_m(frequency_hz: float, temperature_c: float = 10.0, salinity_ppt: float = 35.0,
                               depth_m: float = 0.0, ph: float = 8.0) -> float:
    """One-way absorption α of sea water in dB/m (Francois–Garrison 1982).

    Parameters
    ----------
    frequency_hz : float
        Acoustic frequency, Hz.
    temperature_c : float
        Temperature, °C.
    salinity_ppt : float
        Salinity, ppt.
    depth_m : float
        Depth, m (pressure dependence of the MgSO4 and water terms).
    ph : float
        Acidity (boric-acid term).

    Returns
    -------
    float
        α in dB/m (0.0961 at 400 kHz, 10 °C, 35 ppt, 0 m, pH 8).
    """
    f = frequency_hz / 1e3  # kHz
    t, s, d = temperature_c, salinity_ppt, depth_m
    c = 1412.0 + 3.21 * t + 1.19 * s + 0.0167 * d
    # boric acid
    a1 = 8.86 / c * 10.0 ** (0.78 * ph - 5.0)
    f1 = 2.8 * math.sqrt(s / 35.0) * 10.0 ** (4.0 - 1245.0 / (t + 273.0))
    # magnesium sulphate
    a2 = 21.44 * s / c * (1.0 + 0.025 * t)
    p2 = 1.0 - 1.37e-4 * d + 6.2e-9 * d * d
    f2 = 8.17 * 10.0 ** (8.0 - 1990.0 / (t + 273.0)) / (1.0 + 0.0018 * (s - 35.0))
    # pure water
    if t <= 20.0:
        a3 = 4.937e-4 - 2.59e-5 * t + 9.11e-7 * t ** 2 - 1.5e-8 * t ** 3
    else:
        a3 = 3.964e-4 - 1.146e-5 * t + 1.45e-7 * t ** 2 - 6.5e-10 * t ** 3
    p3 = 1.0 - 3.83e-5 * d + 4.9e-10 * d * d
    f2f = f * f
    db_per_km = (a1 * f1 * f2f / (f1 * f1 + f2f) + a2 * p2 * f2 * f2f / (f2 * f2 + f2f) + a3 * p3 * f2f)
    return db_per_km / 1e3
