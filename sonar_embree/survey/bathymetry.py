"""Bathymetry from an interferometric side-scan record: a point cloud and its grid (docs/physics.md §18b).

Every sample of a receiver pair's record (:class:`~sonar_embree.ReceiverArray`, ``Record.element_data``) gives a
depression θ (:mod:`sonar_embree.signal.interferometry`) and, at the sample's slant range R = c·t/2, a point
R·(cos θ outward, sin θ down) in the side's across-track plane of that ping's body frame (straight rays), turned
into the world by the ping's attitude. The points are gridded north-up like the mosaic
(:class:`~sonar_embree.survey.mosaic.Mosaic`: mean height per pixel), written as a GeoTIFF beside the scene's
truth (:func:`~sonar_embree.survey.mosaic.write_truth`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..io.files import atomic_write
from ..signal.interferometry import baseline_geometry, cross_spectrum, depression_angle
from .mosaic import Mosaic, _Accumulator


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

    def grid(self, pixel_m: float = 0.5, bounds_m=None) -> Mosaic:
        """The soundings' mean height per pixel of a north-up grid (``Mosaic.height_m``; ``intensity`` holds the mean
        coherence, ``count`` the soundings), over ``bounds_m`` (xmin, ymin, xmax, ymax) or the points' extent."""
        if not pixel_m > 0:
            raise ConfigError(f"PointCloud.grid: pixel_m must be > 0, got {pixel_m!r}")
        if self.xyz_m.shape[0] == 0:
            raise ConfigError("PointCloud.grid: no soundings to grid (nothing passed the coherence threshold)")
        x, y, z = self.xyz_m.T
        bounds = (x.min(), y.min(), x.max(), y.max()) if bounds_m is None else tuple(map(float, bounds_m))
        acc = _Accumulator(bounds, float(pixel_m))
        acc.check_size()
        acc.add(x, y, self.coherence, z)
        m = acc.result(self.crs)
        return Mosaic(m.intensity, m.height_m, m.count, m.x0_m, m.y0_m, m.pixel_m, m.crs, "coherence", "1")

    def to_xyz(self, path) -> None:
        """Write the soundings as text, one ``x y z`` row (world m) per sounding under a ``# x_m y_m z_m`` header;
        atomic (an existing file without that header is not replaced)."""
        def write(tmp):
            np.savetxt(tmp, self.xyz_m, fmt="%.4f", header="x_m y_m z_m", comments="# ")
        atomic_write(path, write, suffix=".xyz")


def interferometric_points(record, pair=(0, 1), window=(1, 5), min_coherence: float = 0.0,
                           reference_deg: float | None = None) -> PointCloud:
    """The soundings of a record's receiver ``pair`` (element indices of its :class:`~sonar_embree.ReceiverArray`).

    Parameters
    ----------
    record : Record
        With ``element_data`` (a side-scan with a ``receive_array``).
    pair : (int, int)
        The reference element and the baselined one.
    window : (int, int)
        Pings and samples averaged in the cross product (:func:`~sonar_embree.signal.interferometry.cross_spectrum`).
    min_coherence : float
        Samples whose coherence is below this are left out.
    reference_deg : float, optional
        The depression the phase is unwrapped about, degrees; default the sonar's tilt.
    """
    arr = record.sonar.receive_array
    if record.element_data is None or arr is None:
        raise ConfigError("interferometric_points: the record has no element data (simulate a Sonar with a "
                          "receive_array)")
    i, j = (int(v) for v in pair)
    if not (0 <= i < arr.n_elements and 0 <= j < arr.n_elements and i != j):
        raise ConfigError(f"interferometric_points: pair {tuple(pair)!r} must be two of the "
                          f"{arr.n_elements} elements")
    b, beta = baseline_geometry(arr.positions_m[i], arr.positions_m[j])
    ref = math.radians(record.sonar.tilt_deg if reference_deg is None else float(reference_deg))
    rot = record.trajectory.rotations()
    r = record.slant_range_m
    parts = []
    for ch, side in enumerate((-1.0, 1.0)):
        z = np.asarray(record.element_data[:, ch])
        cross, coh = cross_spectrum(z[:, i], z[:, j], window)
        theta = depression_angle(np.angle(cross), b, beta, record.sonar.wavelength_m, ref)
        keep = np.isfinite(theta) & (coh >= min_coherence) & (r[None, :] > 0)
        ping, sample = np.nonzero(keep)
        th = theta[keep]
        body = np.stack([np.zeros_like(th), side * r[sample] * np.cos(th), r[sample] * np.sin(th)], axis=1)
        xyz = record.trajectory.positions_m[ping] + np.einsum("nij,nj->ni", rot[ping], body)
        parts.append((xyz, np.full(ping.size, ch), ping, sample, coh[keep]))
    cols = [np.concatenate(c) for c in zip(*parts)]
    return PointCloud(cols[0].reshape(-1, 3), cols[1].astype(np.int64), cols[2].astype(np.int64),
                      cols[3].astype(np.int64), cols[4], record.trajectory.crs)


__all__ = ["PointCloud", "interferometric_points"]
