"""Back-end kernels, synthetic aperture: time-domain backprojection of element records onto image points
(docs/physics.md §18c)."""
from __future__ import annotations

import math

from ._numba import njit, prange


@njit(cache=True, nogil=True, inline="always")
def _dist(a, b, m):
    """|a − b[m]|, m, for a point a (3,) and row m of b."""
    dx = a[0] - b[m, 0]
    dy = a[1] - b[m, 1]
    dz = a[2] - b[m, 2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, nogil=True, parallel=True)
def backproject(data, t0_s, rate_hz, carrier_hz, sound_speed_m_s, tx, rx, vel, fwd, max_u, taper, pixels, out):
    """Time-domain backprojection: ``out[m] = Σ_p Σ_k s_pk(τ)·e^(j2π·f0·τ)``, τ = (|x_m − tx_p| + |x_m − r_pk|)/c,
    r_pk = rx_pk + v_p·2|x_m − tx_p|/c the element where the echo of x_m reaches it (motion during the ping; v = 0:
    stop-and-hop), over the pings and elements that see x_m within ``max_u`` of broadside.

    s_pk is the complex baseband record of ping p and element k, read at (τ − t0)·fs by linear interpolation
    (zero outside the record); the phase is taken as 2π·(f0·τ mod 1). A ping and element count only where the
    mean of the transmit and receive direction cosines along track, u = ((x − tx)·f/|x − tx| + (x − rx)·f/|x − rx|)/2
    with f the ping's forward unit vector, has |u| ≤ ``max_u`` (the processed band; ≥ 1: every one), weighted by
    the cosine on a pedestal 1 − taper·(1 − cos(π·u/max_u)) (0: uniform; 0.46: Hamming; 0.5: Hann). Pixels are
    independent, so the result does not depend on the thread count.

    Parameters
    ----------
    data : (pings, elements, samples) complex128
        Baseband records (matched-filtered for a chirp), sample n at time t0 + n/fs.
    t0_s, rate_hz, carrier_hz, sound_speed_m_s : float
        Time of the first sample (s), sample rate (Hz), carrier f0 (Hz), sound speed (m/s).
    tx : (pings, 3) float64
        The transmitter's position at each ping, m.
    rx : (pings, elements, 3) float64
        Each element's position at the ping's time, m.
    vel : (pings, 3) float64
        The elements' velocity during each ping, m/s (zeros: stop-and-hop).
    fwd : (pings, 3) float64
        Each ping's forward (along-track) unit vector.
    max_u : float
        The largest |u| processed.
    taper : float
        The along-track weighting's depth, in [0, 0.5].
    pixels : (m, 3) float64
        Image points, m (the same frame).
    out : (m,) complex128
        The image, written.
    """
    n_p, n_k, n_s = data.shape
    for m in prange(pixels.shape[0]):
        acc = 0j
        x = pixels[m]
        for p in range(n_p):
            d_tx = _dist(x, tx, p)
            u_tx = ((x[0] - tx[p, 0]) * fwd[p, 0] + (x[1] - tx[p, 1]) * fwd[p, 1]
                    + (x[2] - tx[p, 2]) * fwd[p, 2]) / d_tx
            lag = 2.0 * d_tx / sound_speed_m_s                     # the monostatic time, as the records take it
            mx, my, mz = x[0] - vel[p, 0] * lag, x[1] - vel[p, 1] * lag, x[2] - vel[p, 2] * lag
            rx_p = rx[p]
            for k in range(n_k):
                ex, ey, ez = mx - rx_p[k, 0], my - rx_p[k, 1], mz - rx_p[k, 2]
                d_rx = math.sqrt(ex * ex + ey * ey + ez * ez)
                u = 0.5 * (u_tx + (ex * fwd[p, 0] + ey * fwd[p, 1] + ez * fwd[p, 2]) / d_rx)
                if abs(u) > max_u:
                    continue
                tau = (d_tx + d_rx) / sound_speed_m_s
                v = (tau - t0_s) * rate_hz
                i = int(math.floor(v))
                if i < 0 or i >= n_s - 1:
                    continue
                f = v - i
                s = data[p, k, i] * (1.0 - f) + data[p, k, i + 1] * f
                ph = 2.0 * math.pi * ((carrier_hz * tau) % 1.0)
                if taper > 0.0:
                    s *= 1.0 - taper * (1.0 - math.cos(math.pi * u / max_u))
                acc += s * complex(math.cos(ph), math.sin(ph))
        out[m] = acc
