"""Rectangular-membrane directivity and the per-ping ray fan (docs/physics.md §2, §3, §7).

Body axes are (forward, starboard, down). A fan direction is parameterised by
``s`` = sin ψ, the along-track direction cosine, and the in-plane depression ``β``
below horizontal, measured towards the side's outboard direction:

    u = s·e_fwd + cos ψ·(cos β·e_side + sin β·e_down),   e_side = ±e_stbd

so dΩ = cos ψ dψ dβ = ds dβ. With boresight depressed by δ, u·e_x = s,
u·e_2 = cos ψ·sin(β − δ) and u·b = cos ψ·cos(β − δ).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from .. import kernels


def sinc(x):
    """sin(x)/x, equal to 1 at x = 0 (``np.sinc(x/π)``)."""
    return np.sinc(np.asarray(x, dtype=np.float64) / np.pi)


def directivity(u_along, u_height, u_bore, wavenumber_rad_m, length_m, height_m):
    """One-way pressure directivity Γ of a baffled rectangular membrane.

    Γ(u) = sinc(k·lx/2 · u·e_x) · sinc(k·ly/2 · u·e_2) · [u·b > 0]

    Parameters
    ----------
    u_along, u_height, u_bore : (n,) float
        Direction cosines of the unit direction u with the along-track axis e_x, the
        membrane-height axis e_2 and the boresight b.
    wavenumber_rad_m : float
        k = 2π f0 / c in rad/m.
    length_m, height_m : float
        Membrane length lx and height ly in m.

    Returns
    -------
    (n,) float
        Γ in [−1, 1]; the echo amplitude carries Γ², the intensity Γ⁴.
    """
    k = wavenumber_rad_m
    g = sinc(0.5 * k * length_m * np.asarray(u_along)) * sinc(0.5 * k * height_m * np.asarray(u_height))
    return np.where(np.asarray(u_bore) > 0.0, g, 0.0)


def sinc_root(level: float) -> float:
    """x in (0, π) with sinc(x) = sin(x)/x = level."""
    return brentq(lambda x: math.sin(x) / x - level, 1e-12, math.pi)



def beamwidth_deg(size_m: float, wavelength_m: float, level_db: float = -3.0,
                  two_way: bool = False) -> float:
    """Full beamwidth of the membrane axis of size ``size_m`` at ``level_db`` (exact).

    One-way intensity goes as sinc²(π·L/λ·sin θ); two-way as sinc⁴.

    Returns 180 when the pattern never falls to ``level_db`` inside the half-space.
    """
    power = 4.0 if two_way else 2.0
    x = sinc_root(10.0 ** (level_db / (10.0 * power)))
    s = x * wavelength_m / (math.pi * size_m)
    if s >= 1.0:
        return 180.0
    return 2.0 * math.degrees(math.asin(s))


def first_null_rad(size_m: float, wavelength_m: float) -> float:
    """Angle of the first null from boresight, asin(λ/L); π/2 if there is none."""
    s = wavelength_m / size_m
    return math.asin(s) if s < 1.0 else 0.5 * math.pi


def membrane_size_for_beamwidth(width_rad: float, wavelength_m: float, rule: str = "exact") -> float:
    """Membrane size L (m) whose one-way −3 dB full width is ``width_rad``.

    ``rule="exact"`` solves sinc(π·L/λ·sin(θ/2)) = 1/√2; ``"small-angle"`` returns
    0.886·λ/θ.
    """
    if rule == "small-angle":
        return 0.886 * wavelength_m / width_rad
    x = sinc_root(10.0 ** (-3.0 / 20.0))
    return x * wavelength_m / (math.pi * math.sin(0.5 * width_rad))


# --------------------------------------------------------------------------- fan


def azimuth_samples(wavelength_m: float, length_m: float, oversample: float, n_nulls: int, keep_nulls: bool = False):
    """Along-track direction cosines of the fan and their common spacing.

    Spacing ds = λ/(2·lx)/oversample integrates the band-limited sinc⁴ exactly
    (docs/physics.md §7); the span is ± ``n_nulls`` first nulls; the count is odd so
    one line lies on boresight. Rays exactly on a null (zero weight) are dropped, unless ``keep_nulls`` (a beam
    other than the membrane, sampled on its lattice, drops its own).

    Returns
    -------
    s : (n_az,) float
        sin ψ of each azimuth line.
    ds : float
        Spacing of ``s`` (the azimuth factor of each ray's solid angle).
    """
    ds = wavelength_m / (2.0 * length_m) / oversample
    s_max = min(n_nulls * wavelength_m / length_m, 0.999)
    m = int(math.floor(s_max / ds + 1e-9))
    s = np.arange(-m, m + 1, dtype=np.float64) * ds
    return (s if keep_nulls else s[~on_null(np.pi * length_m / wavelength_m * s)]), ds


def on_null(x) -> np.ndarray:
    """Where sinc(x) = sin(x)/x is exactly zero (x = π·lx·s/λ a nonzero multiple of π): rays there weigh 0."""
    x = np.asarray(x, dtype=np.float64)
    return (np.abs(np.sin(x)) < 1e-9) & (np.abs(x) > 1e-9)


def elevation_span_rad(wavelength_m: float, height_m: float, tilt_rad: float, n_nulls: int = 1):
    """Depression interval [β_lo, β_hi] of the fan: boresight ± the elevation pattern's ``n_nulls``-th null
    (sin θ = n·λ/ly; ± 90° when there is none), inside the baffled half-space."""
    half = first_null_rad(height_m / n_nulls, wavelength_m)
    half = min(half, 0.5 * math.pi - 1e-6)
    return tilt_rad - half, tilt_rad + half


def elevation_density(beta_rad, range_m, dr_target_m: float, max_step_rad: float, slope_cap_m_rad: float,
                      empty_step_factor: float = 1.0, edge_density_factor: float = 1.0):
    """Rays per radian wanted in each probe cell, from the probed slant ranges.

    Parameters
    ----------
    beta_rad : (m,) float
        Uniformly spaced probe depressions.
    range_m : (m,) or (rows, m) float
        Probed slant range per depression (one row per side and ping), NaN where
        the probe found nothing in range.
    dr_target_m : float
        Wanted slant-range step between neighbouring rays.
    max_step_rad : float
        Largest allowed step where a surface is in range.
    slope_cap_m_rad : float
        Upper bound on |dR/dβ| (grazing surfaces).
    empty_step_factor : float
        A cell with nothing in range at either end, nor in its neighbours, gets a
        step this many times ``max_step_rad``.
    edge_density_factor : float
        Cells at a range jump or a silhouette (one end in range, the other not),
        and their neighbours, get at least this many times ``1/max_step_rad``:
        objects are resolved finer than smooth floors.

    Returns
    -------
    (m − 1,) or (rows, m − 1) float
        Density per cell [β_j, β_j+1] in rays per radian.

    Notes
    -----
    |dR/dβ| per cell is the finite difference of the probe. A cell whose slope is
    four times both neighbours' is a range jump at an edge, not a surface, and takes
    its neighbours' slope; a cell with one end out of range takes its neighbours'.
    """
    beta = np.ascontiguousarray(beta_rad, dtype=np.float64)
    r = np.asarray(range_m, dtype=np.float64)
    flat = np.ascontiguousarray(r.reshape(-1, r.shape[-1]))
    out = np.empty((flat.shape[0], beta.shape[0] - 1))
    kernels.elevation_density(beta, flat, float(dr_target_m), float(max_step_rad), float(slope_cap_m_rad),
                              float(empty_step_factor), float(edge_density_factor), out)
    return out.reshape(r.shape[:-1] + (beta.shape[0] - 1,))


def fan_body(s, beta_rad, side: int):
    """Unit directions in body axes for every (s, β) pair of one side.

    Parameters
    ----------
    s : (n_az,) float
        Along-track direction cosines.
    beta_rad : (n_el,) float
        Depressions below horizontal.
    side : {−1, +1}
        −1 port, +1 starboard.

    Returns
    -------
    (n_az·n_el, 3) float
        Directions (forward, starboard, down), azimuth-major.
    """
    s = np.asarray(s, dtype=np.float64)[:, None]
    cpsi = np.sqrt(1.0 - s * s)
    cb, sb = np.cos(beta_rad)[None, :], np.sin(beta_rad)[None, :]
    d = np.empty((s.shape[0], cb.shape[1], 3))
    d[..., 0] = s
    d[..., 1] = side * cpsi * cb
    d[..., 2] = cpsi * sb
    return d.reshape(-1, 3)
