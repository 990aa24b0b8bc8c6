"""GeoTIFF rasters in and out: the only module that imports rasterio (docs/physics.md §15).

A raster's affine transform maps pixel (column, row) corners to projected coordinates; pixel centres lie at
half pixels (x = c + (j + ½)·a, y = f + (i + ½)·e). North-up rasters (e < 0) hold their first row at the
largest northing. Rotated or sheared rasters are refused. The CRS is kept as "EPSG:…" where it has a code.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .files import atomic_write


@dataclass(frozen=True)
class Grid:
    """A regular grid of heights or values.

    Attributes
    ----------
    values : (ny, nx) float64
        One value per pixel, NaN where the raster has none (nodata).
    x_m : (nx,) float64
        Pixel-centre eastings (world x), m.
    y_m : (ny,) float64
        Pixel-centre northings (world y) of each row, m (decreasing for a north-up raster).
    crs : str or None
        The raster's CRS ("EPSG:…" or WKT), None when it has none.
    """

    values: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    crs: str | None


def read_grid(path, band: int = 1) -> Grid:
    """One band of a GeoTIFF (or any raster GDAL reads) as a :class:`Grid`, nodata as NaN."""
    info = raster_info(path, band)
    ny, nx = info.shape
    return Grid(read_window(info, slice(0, ny), slice(0, nx), band), info.x_m, info.y_m, info.crs)


@dataclass(frozen=True)
class RasterInfo:
    """A raster's size and georeferencing, read without its pixels: ``shape`` (ny, nx), the pixel-centre
    coordinates ``x_m`` (nx,) and ``y_m`` (ny,), and the CRS (as :class:`Grid`)."""

    path: str
    shape: tuple
    x_m: np.ndarray
    y_m: np.ndarray
    crs: str | None


def raster_info(path, band: int = 1) -> RasterInfo:
    """The size and georeferencing of a raster (no pixels read)."""
    import rasterio
    from rasterio.errors import RasterioError

    path = os.fspath(path)
    if isinstance(band, bool) or not isinstance(band, (int, np.integer)):
        raise ConfigError(f"{path}: band must be an integer (from 1), got {band!r}")
    try:
        with rasterio.open(path) as src:
            if not 1 <= band <= src.count:
                raise ConfigError(f"{path}: band {band} does not exist (the raster has {src.count})")
            t, shape = src.transform, (src.height, src.width)
            crs = None if src.crs is None else (f"EPSG:{src.crs.to_epsg()}" if src.crs.to_epsg() else src.crs.to_wkt())
    except RasterioError as exc:
        raise ConfigError(f"{path}: cannot read raster ({str(exc).splitlines()[0]})") from None
    _check_transform(path, t)
    return RasterInfo(path, shape, t.c + (np.arange(shape[1]) + 0.5) * t.a, t.f + (np.arange(shape[0]) + 0.5) * t.e,
                      crs)


def read_window(info: RasterInfo, rows: slice, cols: slice, band: int = 1) -> np.ndarray:
    """The values (NaN for nodata) of pixel rows × columns of a raster, as float64: a window read, so memory
    follows the window, not the raster."""
    import rasterio
    from rasterio.windows import Window

    from rasterio.errors import RasterioError

    win = Window(cols.start, rows.start, cols.stop - cols.start, rows.stop - rows.start)
    try:
        with rasterio.open(info.path) as src:
            return src.read(band, window=win, masked=True).astype(np.float64).filled(np.nan)
    except RasterioError as exc:                                  # a truncated or corrupt file, read at last
        why = str(exc.__cause__ or exc).splitlines()[0]
        raise ConfigError(f"{info.path}: cannot read raster pixels, truncated or corrupt? ({why})") from None


def sample_points(info: RasterInfo, x, y, band: int = 1) -> np.ndarray:
    """(n,) float64 values of the raster at the points (x, y) in its CRS: NaN for nodata and off the raster."""
    import rasterio

    x, y = np.asarray(x, float), np.asarray(y, float)
    with rasterio.open(info.path) as src:
        vals = np.array([v[0] for v in src.sample(zip(x, y), indexes=band, masked=True)], dtype=object)
        b = src.bounds
    out = np.array([np.nan if np.ma.is_masked(v) else float(v) for v in vals], dtype=np.float64)
    out[(x < b.left) | (x > b.right) | (y < b.bottom) | (y > b.top)] = np.nan
    return out


def _check_transform(path: str, t) -> None:
    if t.b != 0.0 or t.d != 0.0:
        raise ConfigError(f"{path}: rotated or sheared raster (transform {tuple(t)[:6]}); warp it north-up first")
    if t.a == 0.0 or t.e == 0.0:
        raise ConfigError(f"{path}: raster without a pixel size (transform {tuple(t)[:6]})")


def write_grid(path, values, x0_m: float, y0_m: float, pixel_m: float, crs=None, nodata: float = np.nan,
               names=None, units=None, overviews: bool = False) -> None:
    """Write a north-up float32 GeoTIFF (atomic): ``values`` (ny, nx) or (bands, ny, nx), ``values[…, i, j]`` at
    the pixel whose upper-left corner is (x0 + j·pixel, y0 − i·pixel), NaN written as ``nodata``; ``names`` and
    ``units`` (one per band) become the band descriptions and units; ``overviews``: average overviews, factors
    2, 4, … down to about 256 pixels on the smaller side (at least one level)."""
    import rasterio
    from rasterio.transform import Affine

    v = np.asarray(values, dtype=np.float32)
    v = v[None] if v.ndim == 2 else v
    if v.ndim != 3:
        raise ConfigError(f"GeoTIFF values must be 2-D or 3-D (bands, rows, columns), got shape {v.shape}")
    if not np.isnan(nodata):
        v = np.where(np.isnan(v), np.float32(nodata), v)
    profile = dict(driver="GTiff", width=v.shape[2], height=v.shape[1], count=v.shape[0], dtype="float32",
                   transform=Affine(pixel_m, 0.0, x0_m, 0.0, -pixel_m, y0_m), nodata=nodata,
                   crs=None if crs is None else rasterio.crs.CRS.from_user_input(crs))

    factors = []
    while overviews and (not factors or min(v.shape[1:]) // factors[-1] >= 512):
        factors.append(2 ** (len(factors) + 1))

    def write(tmp):
        from rasterio.enums import Resampling

        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(v)
            for i, name in enumerate(names or ()):
                dst.set_band_description(i + 1, name)
            for i, unit in enumerate(units or ()):
                dst.set_band_unit(i + 1, unit)
            if factors:
                dst.build_overviews(factors, Resampling.average)
                dst.update_tags(ns="rio_overview", resampling="average")

    atomic_write(path, write, suffix=".tif")


#: Largest north-up grid, pixels: its four float64 sums take 32 bytes a pixel (3.2 GB here).
MAX_GRID_PIXELS = 100_000_000


class GridAccumulator:
    """Sums and counts of placed samples per pixel of a north-up grid (np.bincount): the mosaic's and the
    interferometric soundings'. ``bounds`` (xmin, ymin, xmax, ymax) m, snapped out to whole pixels of ``pixel`` m;
    ``where`` names the caller in errors."""

    def __init__(self, bounds, pixel: float, where: str = "grid"):
        self.pixel, self.where = pixel, where
        self.x0, self.y0 = np.floor(bounds[0] / pixel) * pixel, np.ceil(bounds[3] / pixel) * pixel
        self.nx = max(1, int(np.ceil((bounds[2] - self.x0) / pixel)))
        self.ny = max(1, int(np.ceil((self.y0 - bounds[1]) / pixel)))
        self.sums = None

    def check_size(self) -> None:
        """Refuse a grid beyond :data:`MAX_GRID_PIXELS` before allocating it; then allocate the sums."""
        n = self.nx * self.ny
        if n > MAX_GRID_PIXELS:
            raise ConfigError(f"{self.where}: a grid of {self.nx} x {self.ny} pixels at pixel_m = {self.pixel:g} m "
                              f"needs {32 * n / 2**30:.1f} GiB (at most {MAX_GRID_PIXELS:.0e} pixels); use a larger "
                              "pixel_m or smaller bounds_m")
        self.sums = np.zeros((4, n))                                # count, weight, value, height

    def add(self, x, y, v, z, w=None) -> None:
        """Add samples at world (x, y) with a value ``v`` and a height ``z`` (each (n,)); with weights ``w`` (n,)
        the means are weighted (unit weights where none are given)."""
        col = np.floor((x - self.x0) / self.pixel).astype(np.int64)
        row = np.floor((self.y0 - y) / self.pixel).astype(np.int64)
        inside = (col >= 0) & (col < self.nx) & (row >= 0) & (row < self.ny)
        cell = row[inside] * self.nx + col[inside]
        size = self.nx * self.ny
        self.sums[0] += np.bincount(cell, minlength=size)
        w = np.ones(cell.size) if w is None else np.asarray(w, dtype=np.float64)[inside]
        self.sums[1] += np.bincount(cell, w, size)
        self.sums[2] += np.bincount(cell, w * np.asarray(v, dtype=np.float64)[inside], size)
        self.sums[3] += np.bincount(cell, w * z[inside], size)

    def means(self):
        """(mean value, mean height, count), each (ny, nx); NaN where no sample (weighted means where weights
        were given)."""
        count, norm = self.sums[0], self.sums[1]
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = [np.where((count > 0) & (norm > 0), s / norm, np.nan).reshape(self.ny, self.nx)
                    for s in self.sums[2:]]
        return mean[0], mean[1], count.astype(np.int64).reshape(self.ny, self.nx)
