"""Interferometric side-scan: the angle of arrival from two receivers' phase difference (docs/physics.md §18b).

Two receivers a baseline b apart in the across-track plane hear an echo from the unit direction û with path
lengths differing by −b·û (the receiver the baseline points towards is nearer by b·û), so their complex baseband
signals (phase −2π·L/λ) differ in phase by

    Δφ = arg(z_b·z̄_0) = (2π/λ)·b·û = (2π/λ)·|b|·cos(θ + β),

θ the depression of û below the side's horizontal (outward) axis and β the baseline's elevation above it
(a vertical pair: β = 90°, Δφ = −(2π/λ)·|b|·sin θ). Δφ is known modulo 2π: it is unwrapped about the phase of a
reference depression (the transducer's tilt), which leaves an unambiguous sector of |Δ(cos(θ + β))| < λ/(2|b|)
around it. The cross product z_b·z̄_0 is averaged over a small window of samples and pings first (the standard
estimator; its phase noise falls as the coherence γ and the number of looks rise). Sources: Lurton, *An
Introduction to Underwater Acoustics*, 2nd ed., Springer, 2010, §8.3; G. Jin and D. Tang, "Uncertainties of
differential phase estimation associated with interferometric sonars", IEEE J. Oceanic Eng. 21(1), 53–63, 1996
(the phase-difference estimator and its variance).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter

from ..errors import ConfigError
from ..io.files import atomic_write
from ..io.geotiff import GridAccumulator, write_grid
from ..validation import check_number, warn_once


def cross_spectrum(z0: np.ndarray, zb: np.ndarray, window=(1, 5)):
    """The window-averaged cross product of two receivers and their coherence.

    Parameters
    ----------
    z0, zb : (pings, samples) complex
        The reference receiver's and the baselined receiver's complex baseband.
    window : (int, int)
        Pings and samples averaged (a centred box; odd sizes keep the estimate centred).

    Returns
    -------
    cross : (pings, samples) complex
        ⟨z_b·z̄_0⟩ over the window; its angle is Δφ (rad).
    coherence : (pings, samples) float
        |⟨z_b·z̄_0⟩| / √(⟨|z_0|²⟩·⟨|z_b|²⟩) in [0, 1] (NaN where both are silent).
    """
    z0, zb = np.asarray(z0), np.asarray(zb)
    if z0.shape != zb.shape or z0.ndim != 2:
        raise ConfigError(f"cross_spectrum: two (pings, samples) arrays of one shape needed, got {z0.shape} and "
                          f"{zb.shape}")
    w = tuple(int(v) for v in window)
    if len(w) != 2 or min(w) < 1:
        raise ConfigError(f"cross_spectrum: window must be two sizes >= 1 (pings, samples), got {window!r}")
    x = zb * np.conj(z0)
    cross = uniform_filter(x.real, w, mode="nearest") + 1j * uniform_filter(x.imag, w, mode="nearest")
    p0 = uniform_filter(np.abs(z0) ** 2, w, mode="nearest")
    pb = uniform_filter(np.abs(zb) ** 2, w, mode="nearest")
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.abs(cross) / np.sqrt(p0 * pb)
    return cross, coherence


def baseline_geometry(offset0, offset_b):
    """(|b| in m, β in rad) of the baseline from receiver offset ``offset0`` to ``offset_b``, each (forward,
    outward, up) m in the side's frame (:class:`~sonar_embree.ReceiverArray`); a baseline with a component along
    track is refused (the method measures the angle in the across-track plane)."""
    b = np.asarray(offset_b, dtype=float) - np.asarray(offset0, dtype=float)
    length = float(np.hypot(b[1], b[2]))
    if length == 0.0 or abs(b[0]) > 1e-9 * max(length, 1.0):
        raise ConfigError(f"interferometry: the baseline {tuple(b)} m must lie across track (forward component 0, "
                          "outward or up not both 0)")
    return length, math.atan2(b[2], b[1])


def depression_angle(dphi, baseline_m: float, elevation_rad: float, wavelength_m: float, reference_rad):
    """θ (rad, below the side's horizontal) of phase differences ``dphi`` (rad, any shape).

    Δφ is unwrapped about the phase of the ``reference_rad`` depression (a number, or an array of ``dphi``'s shape:
    a coarser pair's angles), then θ = arccos(Δφ·λ/(2π|b|)) − β (the branch with θ + β in [0, π]); NaN where the
    unwrapped phase is beyond the baseline's reach or the reference is NaN.
    """
    k = 2.0 * math.pi * baseline_m / wavelength_m
    ref = k * np.cos(np.asarray(reference_rad, dtype=float) + elevation_rad)
    unwrapped = ref + np.angle(np.exp(1j * (np.asarray(dphi) - ref)))
    c = unwrapped / k
    with np.errstate(invalid="ignore"):
        return np.where(np.abs(c) <= 1.0, np.arccos(np.clip(c, -1.0, 1.0)) - elevation_rad, np.nan)


@dataclass(frozen=True)
class PointCloud:
    """Interferometric soundings.

    Attributes
    ----------
    xyz_m : (n, 3) float64
        World positions, m.
    channel, ping, sample : (n,) int64
        Where each came from in the record.
    coherence : (n,) float64
        The pair's coherence there, in [0, 1].
    crs : str or None
        The record's CRS.
    """

    xyz_m: np.ndarray
    channel: np.ndarray
    ping: np.ndarray
    sample: np.ndarray
    coherence: np.ndarray
    crs: str | None = None

    def grid_arrays(self, pixel_m: float = 0.5, bounds_m=None) -> dict:
        """The soundings gridded north-up over ``bounds_m`` (xmin, ymin, xmax, ymax; default their extent):
        ``height_m`` and ``coherence`` (means per pixel, NaN where none), ``count`` (ny, nx), and the grid's
        upper-left corner ``x0_m``, ``y0_m`` and ``pixel_m`` (:class:`~sonar_embree.io.geotiff.GridAccumulator`)."""
        if isinstance(pixel_m, bool) or not (isinstance(pixel_m, (int, float)) and pixel_m > 0):
            raise ConfigError(f"soundings grid: pixel_m must be > 0, got {pixel_m!r}")
        if self.xyz_m.shape[0] == 0:
            raise ConfigError("soundings grid: no soundings to grid (nothing passed the coherence threshold)")
        x, y, z = self.xyz_m.T
        acc = GridAccumulator((x.min(), y.min(), x.max(), y.max()) if bounds_m is None else tuple(map(float, bounds_m)),
                              float(pixel_m), "soundings grid")
        acc.check_size()
        acc.add(x, y, self.coherence, z)
        coherence, height, count = acc.means()
        return {"height_m": height, "coherence": coherence, "count": count, "x0_m": float(acc.x0),
                "y0_m": float(acc.y0), "pixel_m": acc.pixel}

    def to_geotiff(self, path, pixel_m: float = 0.5, bounds_m=None) -> None:
        """Write the grid (:meth:`grid_arrays`) as a GeoTIFF with the record's CRS: bands height_m (m), coherence
        and count; NaN where no sounding; atomic."""
        g = self.grid_arrays(pixel_m, bounds_m)
        write_grid(path, np.stack([g["height_m"], g["coherence"], g["count"].astype(float)]), g["x0_m"], g["y0_m"],
                   g["pixel_m"], self.crs, names=("height_m", "coherence", "count"), units=("m", "1", "1"))

    def to_xyz(self, path) -> None:
        """Write the soundings as text, one ``x y z`` row (world m) per sounding under a ``# x_m y_m z_m`` header;
        atomic (an existing file without that header is not replaced)."""
        def write(tmp):
            np.savetxt(tmp, self.xyz_m, fmt="%.4f", header="x_m y_m z_m", comments="# ")
        atomic_write(path, write, suffix=".xyz")


def interferometric_points(record, pair=(0, 1), window=(5, 11), min_coherence: float = 0.0,
                           reference_deg: float | None = None, coarse_pair=None) -> PointCloud:
    """The soundings of a record's receiver ``pair`` (element indices of its :class:`~sonar_embree.ReceiverArray`).

    Each sample's depression θ (:func:`depression_angle`) at its slant range R = c·t/2 gives the point
    R·(cos θ outward, sin θ down) in the side's across-track plane of that ping's body frame (straight rays),
    turned into the world by the ping's attitude.

    Parameters
    ----------
    record : Record
        With ``element_data`` (a side-scan with a ``receive_array``).
    pair : (int, int)
        The reference element and the baselined one.
    window : (int, int)
        Pings and samples averaged in the cross product (:func:`cross_spectrum`).
    min_coherence : float
        Samples whose coherence is below this are left out (in [0, 1]). Soundings above the sonar (a phase
        unwrapped into the wrong sector: a pair longer than λ/2 without ``coarse_pair``) are left out with a
        one-line warning saying how many: a side-scan's seabed lies below it.
    reference_deg : float, optional
        The depression the phase is unwrapped about, degrees; default the sonar's tilt.
    coarse_pair : (int, int), optional
        A pair with a shorter baseline: its angles (unwrapped about ``reference_deg``) unwrap ``pair``'s, sample by
        sample, so that a long baseline's precision comes without its ambiguity (a long baseline's sector is
        λ/(2|b|) in cos(θ + β); the coarse pair's must hold the swath and be precise to within that).
    """
    arr = record.sonar.receive_array
    if record.element_data is None or arr is None:
        raise ConfigError("interferometric soundings: the record has no element data (simulate a Sonar with a "
                          "receive_array)")
    check_number("interferometric_points", "min_coherence", min_coherence, lo=0.0, hi=1.0)
    _check_baseline(arr, pair, coarse_pair, record.acquisition.wavelength_m)
    ref = math.radians(record.sonar.tilt_deg if reference_deg is None else float(reference_deg))
    rot, r = record.trajectory.rotations(), record.slant_range_m
    parts, above = [], 0
    for ch, side in enumerate((-1.0, 1.0)):
        z = np.asarray(record.element_data[:, ch])
        about = ref if coarse_pair is None else _angles(z, arr, coarse_pair, window, record.acquisition.wavelength_m,
                                                        ref)[0]
        theta, coh = _angles(z, arr, pair, window, record.acquisition.wavelength_m, about)
        keep = np.isfinite(theta) & (coh >= min_coherence) & (r[None, :] > 0)
        ping, sample = np.nonzero(keep)
        th = theta[keep]
        body = np.stack([np.zeros_like(th), side * r[sample] * np.cos(th), r[sample] * np.sin(th)], axis=1)
        xyz = record.trajectory.positions_m[ping] + np.einsum("nij,nj->ni", rot[ping], body)
        below = xyz[:, 2] < record.trajectory.positions_m[ping, 2]        # a seabed sounding lies below the sonar
        above += int(np.sum(~below))
        parts.append((xyz[below], np.full(int(below.sum()), ch), ping[below], sample[below], coh[keep][below]))
    if above:
        warn_once(f"interferometric soundings: {above} of {above + sum(p[0].shape[0] for p in parts)} lie above the "
                  "sonar (a phase unwrapped into the wrong sector); left out")
    cols = [np.concatenate(c) for c in zip(*parts)]
    return PointCloud(cols[0].reshape(-1, 3), cols[1].astype(np.int64), cols[2].astype(np.int64),
                      cols[3].astype(np.int64), cols[4], record.trajectory.crs)


def _check_baseline(arr, pair, coarse_pair, wavelength_m: float) -> None:
    """One warning when ``pair``'s baseline is longer than λ/2 and no ``coarse_pair`` unwraps it: its phase repeats
    within the half-space (a sector of λ/(2|b|) in cos(θ + β)), so soundings outside the sector about the reference
    land at wrong angles (issue 53)."""
    i, j = (int(v) for v in pair)
    if coarse_pair is not None or not (0 <= i < arr.n_elements and 0 <= j < arr.n_elements and i != j):
        return                                                        # (a bad pair is refused by _angles)
    b = float(np.hypot(*(np.asarray(arr.positions_m[j], float) - np.asarray(arr.positions_m[i], float))[1:]))
    if b > 0.5 * wavelength_m * (1.0 + 1e-9):
        warn_once(f"interferometric soundings: the pair {(i, j)} is {b * 1e3:.3g} mm apart, longer than λ/2 = "
                  f"{0.5e3 * wavelength_m:.3g} mm, and no coarse_pair unwraps it: its phase is ambiguous, so "
                  "soundings away from the tilt land at wrong angles (those above the sonar are dropped)")


def _angles(z, arr, pair, window, wavelength_m: float, reference_rad):
    """(θ, coherence), each (pings, samples), of one side's element signals ``z`` (pings, elements, samples) for
    the elements ``pair`` of ``arr``, unwrapped about ``reference_rad``."""
    i, j = (int(v) for v in pair)
    if not (0 <= i < arr.n_elements and 0 <= j < arr.n_elements and i != j):
        raise ConfigError(f"interferometric soundings: pair {tuple(pair)!r} must be two of the "
                          f"{arr.n_elements} elements")
    b, beta = baseline_geometry(arr.positions_m[i], arr.positions_m[j])
    cross, coh = cross_spectrum(z[:, i], z[:, j], window)
    return depression_angle(np.angle(cross), b, beta, wavelength_m, reference_rad), coh


__all__ = ["PointCloud", "baseline_geometry", "cross_spectrum", "depression_angle",
           "interferometric_points"]
