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


def _side_xy(t_pos, rot, ground_range):
    """World (x, y), each (2, pings, samples), of samples at ``ground_range`` (2, pings, samples) along each side's
    horizontal direction (the body's starboard axis, negated for port) from the pings' positions ``t_pos``."""
    side = rot[:, :2, 1]                                            # body starboard axis, horizontal part
    norm = np.linalg.norm(side, axis=1)
    if np.any(norm < 1e-6):
        raise ConfigError("mosaic: a ping is rolled 90°: its sides have no horizontal direction")
    side = side / norm[:, None]
    g = np.asarray(ground_range, dtype=np.float64)
    sign = np.array([-1.0, 1.0])[:, None, None]
    return (t_pos[None, :, 0, None] + sign * g * side[None, :, 0, None],
            t_pos[None, :, 1, None] + sign * g * side[None, :, 1, None])


def _placed(t_pos, rot, ground_range, heights, port, starboard):
    """(x, y, value, height) of the samples of a block of pings that have a seafloor point, flat arrays."""
    x, y = _side_xy(t_pos, rot, ground_range)
    ok = np.isfinite(x) & np.isfinite(y)
    return x[ok], y[ok], np.stack([port, starboard])[ok], np.asarray(heights, dtype=np.float64)[ok]


def sample_positions(record):
    """World (x, y) of every sample of a side-scan record with labels, (2, pings, samples) each (port, starboard),
    NaN where the sample has no seafloor point (water column)."""
    _check(record)
    t = record.trajectory
    return _side_xy(t.positions_m, t.rotations(), record.labels.ground_range_m)


def _check(record) -> None:
    if record.labels is None:
        raise ConfigError("mosaic: the record has no ground truth; simulate it with labels=True")
    if tuple(record.channels) != ("port", "starboard"):
        raise ConfigError(f"mosaic: side-scan records only (channels {', '.join(record.channels)})")


def _blocks(source, block: int = 1000):
    """Blocks of placed samples of a Record, or of a streamed line's Zarr store (a path or an xarray Dataset
    with labels), read a block of pings at a time."""
    if hasattr(source, "trajectory"):
        _check(source)
        t, lab = source.trajectory, source.labels
        yield _placed(t.positions_m, t.rotations(), lab.ground_range_m, lab.height_m, source.port, source.starboard)
        return
    from .trajectory import body_to_world

    ds = _dataset(source)
    for a in range(0, ds.sizes["ping"], block):
        d = ds.isel(ping=slice(a, a + block))
        pos = np.column_stack([d["x_m"].values, d["y_m"].values, d["z_m"].values])
        rot = body_to_world(d["heading_deg"].values, d["pitch_deg"].values, d["roll_deg"].values)
        yield _placed(pos, rot, d["label_ground_range_m"].values, d["label_height_m"].values, d["port"].values,
                      d["starboard"].values)


def _dataset(source):
    import xarray as xr

    ds = source if isinstance(source, xr.Dataset) else xr.open_zarr(source)
    if "label_ground_range_m" not in ds:
        raise ConfigError("mosaic: the store has no ground truth; stream it with labels=True")
    return ds


def _crs_of(source):
    if hasattr(source, "trajectory"):
        return source.trajectory.crs
    ds = _dataset(source)
    return ds["crs"].attrs.get("epsg_code") if "crs" in ds else None


def mosaic(records, pixel_m: float = 0.5, bounds_m=None) -> Mosaic:
    """Average the samples of one or more side-scan lines (with labels) onto a north-up grid.

    Parameters
    ----------
    records : Record, Zarr store path or xarray Dataset, or a sequence of them
        Survey lines simulated with ``labels=True`` (stores streamed by :func:`sonar_embree.stream.render_line`
        are read a block of pings at a time), in one CRS.
    pixel_m : float
        Pixel size, m.
    bounds_m : (xmin, ymin, xmax, ymax), optional
        The mosaic's extent in world metres; default: every placed sample, snapped out to whole pixels (this
        reads the lines twice).
    """
    records = [records] if not isinstance(records, (list, tuple)) else list(records)
    if not records:
        raise ConfigError("mosaic: no records")
    if not (isinstance(pixel_m, (int, float)) and 0 < pixel_m < 1e4):
        raise ConfigError(f"mosaic: pixel_m must be a positive size in m, got {pixel_m!r}")
    crs = {_crs_of(r) for r in records}
    if len(crs) > 1:
        raise ConfigError(f"mosaic: the records are in different CRSs ({', '.join(sorted(map(str, crs)))})")
    if bounds_m is None:
        lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
        for r in records:
            for x, y, _, _ in _blocks(r):
                if x.size:
                    lo, hi = np.minimum(lo, [x.min(), y.min()]), np.maximum(hi, [x.max(), y.max()])
        if not np.all(np.isfinite(lo)):
            raise ConfigError("mosaic: no sample of the records has a seafloor point")
        bounds_m = (lo[0], lo[1], hi[0], hi[1])
    acc = _Accumulator(bounds_m, float(pixel_m))
    for r in records:
        for block in _blocks(r):
            acc.add(*block)
    return acc.result(crs.pop())


class _Accumulator:
    """Sums and counts of placed samples per pixel of a north-up grid (np.bincount)."""

    def __init__(self, bounds, pixel: float):
        self.pixel = pixel
        self.x0, self.y0 = np.floor(bounds[0] / pixel) * pixel, np.ceil(bounds[3] / pixel) * pixel
        self.nx = max(1, int(np.ceil((bounds[2] - self.x0) / pixel)))
        self.ny = max(1, int(np.ceil((self.y0 - bounds[1]) / pixel)))
        self.sums = np.zeros((3, self.nx * self.ny))                # count, value, height

    def add(self, x, y, v, z) -> None:
        col = np.floor((x - self.x0) / self.pixel).astype(np.int64)
        row = np.floor((self.y0 - y) / self.pixel).astype(np.int64)
        inside = (col >= 0) & (col < self.nx) & (row >= 0) & (row < self.ny)
        cell = row[inside] * self.nx + col[inside]
        size = self.nx * self.ny
        self.sums[0] += np.bincount(cell, minlength=size)
        self.sums[1] += np.bincount(cell, np.asarray(v, dtype=np.float64)[inside], size)
        self.sums[2] += np.bincount(cell, z[inside], size)

    def result(self, crs) -> Mosaic:
        count = self.sums[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = [np.where(count > 0, s / count, np.nan).reshape(self.ny, self.nx) for s in self.sums[1:]]
        return Mosaic(mean[0], mean[1], count.astype(np.int64).reshape(self.ny, self.nx), float(self.x0),
                      float(self.y0), self.pixel, crs)


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
