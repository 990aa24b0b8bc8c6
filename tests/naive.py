"""Slow, obviously correct NumPy twins of every Numba kernel (sonar_embree.kernels)."""
import numpy as np


def lambert_intensity(range_m, cos_inc, gamma, d_omega, mu, two_way_np_per_m, min_range_m):
    """w = Γ⁴ μ cosθ exp(−a R) dΩ / max(R, Rmin)², 0 where cosθ ≤ 0 or R is not finite."""
    r = np.asarray(range_m, dtype=float)
    ok = (np.asarray(cos_inc) > 0) & np.isfinite(r)
    rr = np.where(ok, np.maximum(r, min_range_m), 1.0)
    w = gamma ** 4 * mu * cos_inc * np.exp(-two_way_np_per_m * np.where(ok, r, 0.0)) * d_omega / rr ** 2
    return np.where(ok, w, 0.0)


def splat_linear(channel, delay_samples, weights, out):
    """Linear fractional-delay splatting with np.add.at, out-of-window entries dropped."""
    n_ch, n = out.shape
    x = np.asarray(delay_samples, dtype=float)
    keep = np.isfinite(x) & (x >= 0) & (x <= n - 1) & (channel >= 0) & (channel < n_ch)
    x, ch, w = x[keep], channel[keep], weights[keep]
    j = np.floor(x).astype(int)
    f = x - j
    np.add.at(out, (ch, j), w * (1 - f))
    inside = j + 1 < n
    np.add.at(out, (ch[inside], j[inside] + 1), (w * f)[inside])
    return out
