"""Synthetic-aperture image formation: time-domain backprojection (docs/physics.md §18).

The reference image former of a receiver array's records: every image point x collects, over every ping p and
element k, the record s_pk at the bistatic delay τ = (|x − tx_p| + |x − rx_pk|)/c, turned back by e^(j2π·f0·τ),

    image(x) = Σ_p Σ_k s_pk(τ_pk(x))·e^(j2π·f0·τ_pk(x)),

motion-compensated by construction: the positions are the navigation's. A point target's image has along-track
resolution D/2 (its first null; D the element length, M. Soumekh, *Synthetic Aperture Radar Signal Processing*,
Wiley, 1999, ch. 4; J. C. Curlander and R. N. McDonough, *Synthetic Aperture Radar*, Wiley, 1991, §1.2) and
across-track c/(2B) after pulse compression. The records must be sampled densely enough along track: pings no
farther apart than D/4 for a single element (D/2 for the array's phase centres).
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from ..errors import ConfigError
from ..validation import check_number


def backprojection_image(data, t0_s: float, rate_hz: float, carrier_hz: float, sound_speed_m_s: float, tx, rx,
                         x_m, y_m, z_m: float = 0.0) -> np.ndarray:
    """The backprojected image of element records on the grid ``x_m`` × ``y_m`` at height ``z_m``.

    Parameters
    ----------
    data : (pings, elements, samples) complex
        Baseband records, sample n at t0 + n/fs (pulse-compressed for a chirp).
    t0_s, rate_hz, carrier_hz, sound_speed_m_s : float
        First sample's time (s), sample rate (Hz), carrier (Hz), sound speed (m/s).
    tx : (pings, 3) float
        The transmitter's position per ping, m.
    rx : (pings, elements, 3) float
        Each element's position when it receives, m.
    x_m, y_m : (nx,), (ny,) float
        The image grid's axes, m.

    Returns
    -------
    (ny, nx) complex128
    """
    d = np.ascontiguousarray(data, dtype=np.complex128)
    tx, rx = np.ascontiguousarray(tx, dtype=np.float64), np.ascontiguousarray(rx, dtype=np.float64)
    if d.ndim != 3 or tx.shape != (d.shape[0], 3) or rx.shape != d.shape[:2] + (3,):
        raise ConfigError(f"backprojection_image: data (pings, elements, samples) {d.shape}, tx (pings, 3) "
                          f"{tx.shape} and rx (pings, elements, 3) {rx.shape} disagree")
    for name, v in (("rate_hz", rate_hz), ("carrier_hz", carrier_hz), ("sound_speed_m_s", sound_speed_m_s)):
        check_number("backprojection_image", name, v, positive=True)
    xx, yy = np.meshgrid(np.asarray(x_m, dtype=float), np.asarray(y_m, dtype=float))
    pixels = np.ascontiguousarray(np.stack([xx.ravel(), yy.ravel(), np.full(xx.size, float(z_m))], axis=1))
    out = np.empty(pixels.shape[0], dtype=np.complex128)
    kernels.backproject(d, float(t0_s), float(rate_hz), float(carrier_hz), float(sound_speed_m_s), tx, rx, pixels,
                        out)
    return out.reshape(xx.shape)


__all__ = ["backprojection_image"]
