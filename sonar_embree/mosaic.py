"""Georeferenced mosaics of side-scan records and the seafloor truth beneath them (docs/physics.md §15).

Each sample is placed where the record's ground truth says its echo came from: the centre-line hit at its
slant range (``Labels.ground_range_m``, the true geometry over any relief, not a flat-floor assumption),
along the horizontal direction of the channel's side (the body's starboard axis, negated for port). Several
records (survey lines) are averaged pixel by pixel. The truth is the scene's height at each pixel centre,
from a vertical ray cast through the scene (for a DEM: the DEM resampled onto the mosaic grid).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ConfigError


@dataclass(frozen=True)
class Mosaic:
    """A north-up raster over the survey.

    Attributes
    ----------
    intensity : (ny, nx) float64
        Mean record intensity of the samples placed in each pixel (the record's unit), NaN where none.
    height_m : (ny, nx) float64
        Mean world z of the seafloor points those samples came from, m, NaN where none.
    count : (ny, nx) int64
        Samples placed in each pixel.
    x0_m, y0_m : float
        World x and y of the upper-left (north-west) corner, m.
    pixel_m : float
        Pixel size, m.
    crs : str or None
        The records' CRS.
    """

    intensity: np.ndarray
    height_m: np.ndarray
    count: np.ndarray
    x0_m: float
    y0_m: float
    pixel_m: float
    crs: str | None

    def centres(self):
        """(x (nx,), y (ny,)) world coordinates of the pixel centres, m (y decreasing: north-up)."""
        ny, nx = self.count.shape
        return (self.x0_m + (np.arange(nx) + 0.5) * self.pixel_m, self.y0_m - (np.arange(ny) + 0.5) * self.pixel_m)

    def to_geotiff(self, path) -> None:
        """Write the mosaic as a two-band GeoTIFF (intensity, height_m; NaN where no sample) with its CRS."""
        from .io.geotiff import write_grid

        write_grid(path, np.stack([self.intensity, self.height_m]), self.x0_m, self.y0_m, self.pixel_m, self.crs,
                   names=("intensity", "height_m"))


def sample_positions(record):
    """World (x, y) of every sample of a side-scan record with labels, (2, pings, samples) each (port, starboard),
    NaN where the sample has no seafloor point (water column)."""
    if record.labels is None:
        raise ConfigError("mosaic: the record has no ground truth; simulate it with labels=True")
    if tuple(record.channels) != ("port", "starboard"):
        raise ConfigError(f"mosaic: side-scan records only (channels {', '.join(record.channels)})")
    t = record.trajectory
    side = t.rotations()[:, :2, 1]                                  # body starboard axis, horizontal part
    norm = np.linalg.norm(side, axis=1)
    if np.any(norm < 1e-6):
        raise ConfigError("mosaic: a ping is rolled 90°: its sides have no horizontal direction")
    side = side / norm[:, None]
    g = record.labels.ground_range_m.astype(np.float64)             # (2, pings, samples)
    sign = np.array([-1.0, 1.0])[:, None, None]
    x = t.positions_m[None, :, 0, None] + sign * g * side[None, :, 0, None]
    y = t.positions_m[None, :, 1, None] + sign * g * side[None, :, 1, None]
    return x, y


def mosaic(records, pixel_m: float = 0.5, bounds_m=None) -> Mosaic:
    """Average the samples of one or more side-scan records (with labels) onto a north-up grid.

    Parameters
    ----------
    records : Record or sequence of Record
        Survey lines, simulated with ``labels=True``, in one CRS.
    pixel_m : float
        Pixel size, m.
    bounds_m : (xmin, ymin, xmax, ymax), optional
        The mosaic's extent in world metres; default: every placed sample, snapped out to whole pixels.
    """
    records = [records] if not isinstance(records, (list, tuple)) else list(records)
    if not records:
        raise ConfigError("mosaic: no records")
    if not (isinstance(pixel_m, (int, float)) and 0 < pixel_m < 1e4):
        raise ConfigError(f"mosaic: pixel_m must be a positive size in m, got {pixel_m!r}")
    crs = {r.trajectory.crs for r in records}
    if len(crs) > 1:
        raise ConfigError(f"mosaic: the records are in different CRSs ({', '.join(sorted(map(str, crs)))})")
    placed = []
    for r in records:
        x, y = sample_positions(r)
        values = np.stack([r.port, r.starboard])
        ok = np.isfinite(x) & np.isfinite(y)
        placed.append((x[ok], y[ok], values[ok], r.labels.height_m[ok].astype(np.float64)))
    x, y, v, z = (np.concatenate(c) for c in zip(*placed))
    if x.size == 0:
        raise ConfigError("mosaic: no sample of the records has a seafloor point")
    return _grid(x, y, v, z, float(pixel_m), bounds_m, crs.pop())


def _grid(x, y, v, z, pixel, bounds, crs) -> Mosaic:
    """Bin placed samples into pixels: sums and counts by np.bincount."""
    if bounds is None:
        bounds = (x.min(), y.min(), x.max(), y.max())
    x0, y1 = np.floor(bounds[0] / pixel) * pixel, np.ceil(bounds[3] / pixel) * pixel
    nx = max(1, int(np.ceil((bounds[2] - x0) / pixel)))
    ny = max(1, int(np.ceil((y1 - bounds[1]) / pixel)))
    col, row = np.floor((x - x0) / pixel).astype(np.int64), np.floor((y1 - y) / pixel).astype(np.int64)
    inside = (col >= 0) & (col < nx) & (row >= 0) & (row < ny)
    cell = row[inside] * nx + col[inside]
    count = np.bincount(cell, minlength=nx * ny)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = [np.where(count > 0, np.bincount(cell, w[inside], nx * ny) / count, np.nan).reshape(ny, nx)
                for w in (v, z)]
    return Mosaic(mean[0], mean[1], count.reshape(ny, nx), float(x0), float(y1), pixel, crs)


def truth(scene, grid: Mosaic, caster=None) -> np.ndarray:
    """The scene's height under each pixel centre of ``grid``, (ny, nx) m (NaN where nothing is below): the first
    hit of a vertical ray cast down from above the scene (for a DEM, the DEM resampled onto the grid)."""
    from .raycast import RayCaster

    cx, cy = grid.centres()
    xx, yy = np.meshgrid(cx, cy)
    compiled = scene.compiled()
    top = float(scene.bounds[1, 2]) + 1.0
    depth = top - float(scene.bounds[0, 2]) + 1.0
    origins = np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, top)]) - compiled.origin_m
    hits = (caster or RayCaster)(compiled).cast(origins, np.broadcast_to([0.0, 0.0, -1.0], origins.shape), depth)
    z = np.where(hits.tri >= 0, top - hits.range_m, np.nan)
    return z.reshape(xx.shape)


def write_truth(path, scene, grid: Mosaic) -> np.ndarray:
    """Write :func:`truth` on the mosaic's grid as a one-band GeoTIFF (height_m, NaN where nothing); returns it."""
    from .io.geotiff import write_grid

    z = truth(scene, grid)
    write_grid(path, z, grid.x0_m, grid.y0_m, grid.pixel_m, grid.crs, names=("height_m",))
    return z
