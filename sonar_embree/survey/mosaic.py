"""Georeferenced mosaics of side-scan records and the seafloor truth beneath them (docs/physics.md §15).

Each sample is placed where the record's ground truth says its echo came from: the centre-line hit at its
slant range (``Labels.ground_range_m``, the true geometry over any relief, not a flat-floor assumption),
along the horizontal direction of the channel's side (the body's starboard axis, negated for port). Several
records (survey lines) are averaged pixel by pixel. The truth is the scene's height at each pixel centre,
from a vertical ray cast through the scene (for a DEM: the DEM resampled onto the mosaic grid).
"""
from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np

from ..errors import ConfigError
from ..io.files import atomic_write
from ..io.geotiff import MAX_GRID_PIXELS, GridAccumulator
from ..raycast import RayCaster
from ..record import Record
from ..scene import TiledDEM
from ..trajectory import body_to_world


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
    values : str
        What ``intensity`` holds (:func:`mosaic`'s ``values``): "intensity", "normalised" or "codes".
    units : str
        Its unit ("1" unit-source intensity, "uPa^2" with a source level, "1" for normalised and codes).
    """

    intensity: np.ndarray
    height_m: np.ndarray
    count: np.ndarray
    x0_m: float
    y0_m: float
    pixel_m: float
    crs: str | None
    values: str = "intensity"
    units: str = "1"

    def centres(self):
        """(x (nx,), y (ny,)) world coordinates of the pixel centres, m (y decreasing: north-up)."""
        ny, nx = self.count.shape
        return (self.x0_m + (np.arange(nx) + 0.5) * self.pixel_m, self.y0_m - (np.arange(ny) + 0.5) * self.pixel_m)

    def to_geotiff(self, path) -> None:
        """Write the mosaic as a two-band GeoTIFF with its CRS: the values (named by ``values``, unit ``units``) and
        height_m (m); NaN (the nodata value) where no sample; average overviews down to about 256 pixels."""
        from ..io.geotiff import write_grid

        write_grid(path, np.stack([self.intensity, self.height_m]), self.x0_m, self.y0_m, self.pixel_m, self.crs,
                   names=(self.values, "height_m"), units=(self.units, "m"), overviews=True)

    def save_png(self, path, dynamic_range_db: float | None = None) -> None:
        """A quick-look PNG of the values (grey, north-up, dB; transparent where no sample); atomic. Intensities
        and codes: white at the 99.5th percentile, black ``dynamic_range_db`` (default 40) below. Normalised values
        (a uniform floor at 1): the median mid-grey, ``dynamic_range_db`` (default 20) spanning black to white, as a
        mosaic is looked at (a bright target and its shadow stand out; a uniform floor is grey, not white)."""
        import imageio.v3 as iio

        normalised = self.values == "normalised"
        dynamic_range_db = (20.0 if normalised else 40.0) if dynamic_range_db is None else dynamic_range_db
        v = self.intensity
        lit = np.isfinite(v) & (v > 0)
        grey = np.zeros(v.shape, dtype=np.uint8)
        if lit.any():
            db = 10.0 * np.log10(v[lit])
            top = np.median(db) + dynamic_range_db / 2 if normalised else np.percentile(db, 99.5)
            grey[lit] = np.round(255 * np.clip((db - top + dynamic_range_db) / dynamic_range_db, 0, 1))
        alpha = np.where(np.isfinite(v), 255, 0).astype(np.uint8)
        img = np.stack([grey, alpha], axis=-1)
        atomic_write(path, lambda tmp: iio.imwrite(tmp, img, extension=".png"), suffix=".png")


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


def _placed(t_pos, rot, ground_range, heights, port, starboard, weight):
    """(x, y, value, height, weight) of the samples of a block of pings that have a seafloor point, flat arrays."""
    x, y = _side_xy(t_pos, rot, ground_range)
    ok = np.isfinite(x) & np.isfinite(y)
    return x[ok], y[ok], np.stack([port, starboard])[ok], np.asarray(heights, dtype=np.float64)[ok], weight[ok]


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


#: What :func:`mosaic` can place: the record's intensity, the same divided by the line's mean at each grazing
#: angle (empirical normalisation), or the receiver's codes.
MOSAIC_VALUES = ("intensity", "normalised", "codes")


def _raw_blocks(source, values: str, block: int = 1000):
    """(positions, rotations, ground range, heights, port, starboard) of a Record or a streamed line's store (a
    path or an xarray Dataset with labels), a block of pings at a time; port/starboard the record's intensities,
    or its receiver's codes (``values="codes"``)."""
    if isinstance(source, Record):
        _check(source)
        t, lab = source.trajectory, source.labels
        if values == "codes":
            if source.samples is None:
                raise ConfigError("mosaic: values='codes' needs a record from a sonar with a Receiver")
            sides = (source.samples[:, 0], source.samples[:, 1])
        else:
            sides = (source.port, source.starboard)
        yield t.positions_m, t.rotations(), lab.ground_range_m, lab.height_m, *sides
        return

    ds = _dataset(source)
    names = ("port_samples", "starboard_samples") if values == "codes" else ("port", "starboard")
    if names[0] not in ds:
        raise ConfigError("mosaic: values='codes' needs a store from a sonar with a Receiver")
    for a in range(0, ds.sizes["ping"], block):
        d = ds.isel(ping=slice(a, a + block))
        pos = np.column_stack([d["x_m"].values, d["y_m"].values, d["z_m"].values])
        rot = body_to_world(d["heading_deg"].values, d["pitch_deg"].values, d["roll_deg"].values)
        yield (pos, rot, d["label_ground_range_m"].values, d["label_height_m"].values, d[names[0]].values,
               d[names[1]].values)


#: Grazing-angle bins of a line's normalisation profile, degrees, and how many span 0 … 90°.
GRAZING_BIN_DEG = 0.5
N_GRAZING = int(round(90.0 / GRAZING_BIN_DEG))


def _grazing_bins(pos, ground, heights) -> np.ndarray:
    """(2, pings, samples) int: each sample's grazing-angle bin (:data:`GRAZING_BIN_DEG`), from the sonar's height
    above the sample's seafloor point and its ground range (the labels' true geometry); −1 where no point."""
    below = np.asarray(pos, dtype=np.float64)[None, :, 2, None] - np.asarray(heights, dtype=np.float64)
    g = np.abs(np.asarray(ground, dtype=np.float64))
    with np.errstate(invalid="ignore"):
        psi = np.degrees(np.arctan2(below, g))
    ok = np.isfinite(psi) & (psi >= 0.0)
    return np.where(ok, np.minimum(np.floor(np.where(ok, psi, 0.0) / GRAZING_BIN_DEG), N_GRAZING - 1), -1).astype(
        np.int64)


def _range_compensated(source, pos, ground, heights, values) -> np.ndarray:
    """``values`` (2, pings, samples) × R³·10^(2αR/10), R the slant range to each sample's seafloor point: the
    spreading and absorption of a pulse-limited patch's echo taken out (the 30·log10 R + 2αR of a device's TVG),
    so that what is left depends on the grazing angle alone over a uniform floor, at any altitude."""
    below = np.asarray(pos, dtype=np.float64)[None, :, 2, None] - np.asarray(heights, dtype=np.float64)
    r = np.hypot(np.asarray(ground, dtype=np.float64), below)
    return np.asarray(values, dtype=np.float64) * r ** 3 * 10.0 ** (2.0 * _alpha(source) * r / 10.0)


def _alpha(source) -> float:
    """The one-way absorption of a record or a store, dB/m."""
    if isinstance(source, Record):
        return float(source.acquisition.alpha_db_per_m)
    return float(_dataset(source).attrs.get("simulation.alpha_db_per_m", 0.0))


def _line_profile(source) -> np.ndarray:
    """(2, grazing bins) the line's mean range-compensated intensity (:func:`_range_compensated`) at each grazing
    angle over its pings, per side, counting only samples with a seafloor point (the empirical normalisation of
    :func:`mosaic`: by grazing angle after the range's spreading and absorption, so that a change of altitude
    along the line leaves no band)."""
    sums, counts = np.zeros((2, N_GRAZING)), np.zeros((2, N_GRAZING))
    for pos, _, ground, heights, port, starboard in _raw_blocks(source, "intensity"):
        bins = _grazing_bins(pos, ground, heights)
        vals = _range_compensated(source, pos, ground, heights, np.stack([port, starboard]))
        for side in (0, 1):
            ok = bins[side] >= 0
            sums[side] += np.bincount(bins[side][ok], vals[side][ok], N_GRAZING)
            counts[side] += np.bincount(bins[side][ok], minlength=N_GRAZING)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)


def _feather(ground) -> np.ndarray:
    """(2, pings, samples) weights of the samples in overlaps: the distance from the nearer end of the swath,
    nadir or far range (a triangle over each side's ground ranges), so two lines' swaths blend smoothly."""
    g = np.abs(np.asarray(ground, dtype=np.float64))
    far = np.nanmax(g, axis=-1, keepdims=True, initial=0.0)
    return np.maximum(np.minimum(g, far - g), 1e-3 * np.maximum(far, 1e-9))


def _blocks(source, values: str = "intensity", block: int = 1000):
    """Blocks of placed samples (x, y, value, height, weight) of a Record or a streamed line's store, a block of
    pings at a time; ``values`` as for :func:`mosaic` (weights: feathering for "normalised", else 1)."""
    profile = _line_profile(source) if values == "normalised" else None
    for pos, rot, ground, heights, port, starboard in _raw_blocks(source, "codes" if values == "codes" else
                                                                  "intensity", block):
        weight = np.ones(np.shape(ground))
        if profile is not None:
            bins = _grazing_bins(pos, ground, heights)
            ref = np.stack([np.where(bins[k] >= 0, profile[k][np.maximum(bins[k], 0)], np.nan) for k in (0, 1)])
            comp = _range_compensated(source, pos, ground, heights, np.stack([port, starboard]))
            with np.errstate(invalid="ignore", divide="ignore"):
                port, starboard = (c / np.where(p > 0, p, np.nan) for c, p in zip(comp, ref))
            weight = _feather(ground)
        yield _placed(pos, rot, ground, heights, port, starboard, weight)


def _dataset(source):
    import os

    import xarray as xr

    if isinstance(source, xr.Dataset):
        ds = source
    elif isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        if not os.path.isdir(path):
            raise ConfigError(f"mosaic: {path}: no such Zarr store (a folder written by to_zarr or render_line)")
        try:
            ds = xr.open_zarr(path)
        except Exception as exc:                                    # zarr/xarray raise many types
            raise ConfigError(f"mosaic: {path}: not a readable Zarr store ({type(exc).__name__})") from None
    else:
        raise ConfigError(f"mosaic: records must be Records, Zarr store paths or xarray Datasets, got "
                          f"{type(source).__name__}")
    if "label_ground_range_m" not in ds:
        raise ConfigError("mosaic: the store has no ground truth; stream it with labels=True")
    return ds


def _crs_of(source):
    if isinstance(source, Record):
        return source.trajectory.crs
    ds = _dataset(source)
    return ds["crs"].attrs.get("epsg_code") if "crs" in ds else None


#: The largest mosaic pixel, m (a pixel wider than any swath holds nothing to look at).
MAX_PIXEL_M = 1e4


def check_pixel(pixel_m, what: str) -> None:
    """A mosaic pixel: a number of metres in (0, :data:`MAX_PIXEL_M`), or a one-line error saying which bound."""
    if isinstance(pixel_m, bool) or not isinstance(pixel_m, (int, float)) or not math.isfinite(pixel_m) \
            or pixel_m <= 0:
        raise ConfigError(f"{what} must be a positive number of metres, got {pixel_m!r}")
    if pixel_m >= MAX_PIXEL_M:
        raise ConfigError(f"{what} must be below {MAX_PIXEL_M:g} m (wider than any swath), got {pixel_m!r}")


def mosaic(records, pixel_m: float = 0.5, bounds_m=None, values: str = "intensity") -> Mosaic:
    """Average the samples of one or more side-scan lines (with labels) onto a north-up grid.

    Parameters
    ----------
    records : Record, Zarr store path or xarray Dataset, or a sequence of them
        Survey lines simulated with ``labels=True`` (stores streamed by :func:`sonar_embree.survey.stream.render_line`
        are read a block of pings at a time), in one CRS.
    pixel_m : float
        Pixel size, m.
    bounds_m : (xmin, ymin, xmax, ymax), optional
        The mosaic's extent in world metres; default: every placed sample, snapped out to whole pixels (this
        reads the lines twice).
    values : {"intensity", "normalised", "codes"}
        What is averaged: the records' intensity; the same with the range's spreading and absorption taken out
        (R³·10^(2αR/10)) divided, line by line and side by side, by the line's mean at each grazing angle over its
        pings (an empirical normalisation, a surveyor's TVG and angle-varying gain: range and angle trends out, a uniform floor uniform, no band where the altitude changes; dimensionless), overlapping lines
        feathered by the distance from the nearer end of each swath (:func:`_feather`) and pixel-wide holes
        filled (:func:`fill_gaps`), as surveyors' mosaics are; or the receiver's codes (a sonar with a Receiver).
    """
    if values not in MOSAIC_VALUES:
        raise ConfigError(f"mosaic: values must be one of {', '.join(MOSAIC_VALUES)}, got {values!r}")
    records = _record_list(records)
    check_pixel(pixel_m, "mosaic: pixel_m")
    if bounds_m is not None:
        bounds_m = _checked_bounds(bounds_m)
    crs = {_crs_of(r) for r in records}
    if len(crs) > 1:
        raise ConfigError(f"mosaic: the records are in different CRSs ({', '.join(sorted(map(str, crs)))})")
    acc = GridAccumulator(_bounds_of(records) if bounds_m is None else bounds_m, float(pixel_m), "mosaic")
    acc.check_size()
    for r in records:
        for x, y, v, z, w in _blocks(r, values):
            acc.add(x, y, v, z, w if values == "normalised" else None)
    mean, height, count = acc.means()
    if values == "normalised":
        mean, height = fill_gaps(mean), fill_gaps(height)
    return Mosaic(mean, height, count, float(acc.x0), float(acc.y0), acc.pixel, crs.pop(), values,
                  _units(records[0], values))


def fill_gaps(grid: np.ndarray, min_neighbours: int = 5) -> np.ndarray:
    """``grid`` (ny, nx) with each empty (NaN) pixel that has at least ``min_neighbours`` of its 8 neighbours set
    given their mean: the pixel-wide holes between far-range samples closed, the nadir gap and the edges left."""
    ok = np.isfinite(grid)
    pad_v, pad_n = np.pad(np.where(ok, grid, 0.0), 1), np.pad(ok.astype(np.float64), 1)
    ny, nx = grid.shape
    total = sum(pad_v[1 + dy:1 + dy + ny, 1 + dx:1 + dx + nx] for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    count = sum(pad_n[1 + dy:1 + dy + ny, 1 + dx:1 + dx + nx] for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    fill = ~ok & (count >= min_neighbours)
    out = grid.copy()
    out[fill] = total[fill] / count[fill]
    return out


def _bounds_of(records) -> tuple:
    """(xmin, ymin, xmax, ymax) of every placed sample of the records, m."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for r in records:
        for x, y, _, _, _ in _blocks(r):
            if x.size:
                lo, hi = np.minimum(lo, [x.min(), y.min()]), np.maximum(hi, [x.max(), y.max()])
    if not np.all(np.isfinite(lo)):
        raise ConfigError("mosaic: no sample of the records has a seafloor point")
    return lo[0], lo[1], hi[0], hi[1]


def _units(source, values: str) -> str:
    """The unit of the mosaic's values: uPa^2 for intensities with a source level, else 1."""
    if values != "intensity":
        return "1"
    level = (source.sonar.source_level_db if isinstance(source, Record)
             else _dataset(source).attrs.get("sonar.source_level_db"))
    return "1" if level is None else "uPa^2"


#: Largest mosaic grid, pixels (:data:`sonar_embree.io.geotiff.MAX_GRID_PIXELS`).
MAX_MOSAIC_PIXELS = MAX_GRID_PIXELS


def _record_list(records) -> list:
    """The lines to mosaic as a list of Records and xarray Datasets (a store's path opened): one record, store or
    dataset, or any iterable of them (a generator too)."""
    import os

    import xarray as xr

    if records is None:
        raise ConfigError("mosaic: no records (got None)")
    if isinstance(records, (Record, str, os.PathLike, xr.Dataset)):
        records = [records]
    try:
        records = list(records)
    except TypeError:
        raise ConfigError(f"mosaic: records must be a Record, a Zarr store path, a Dataset or a sequence of them, "
                          f"got {type(records).__name__}") from None
    if not records:
        raise ConfigError("mosaic: no records")
    return [r if isinstance(r, Record) else _dataset(r) for r in records]


def _checked_bounds(bounds_m) -> tuple:
    """(xmin, ymin, xmax, ymax) as finite floats with min < max, or a one-line error."""
    try:
        b = tuple(float(v) for v in bounds_m)
    except (TypeError, ValueError):
        raise ConfigError(f"mosaic: bounds_m must be (xmin, ymin, xmax, ymax) in m, got {bounds_m!r}") from None
    if len(b) != 4 or not all(np.isfinite(b)) or not (b[0] < b[2] and b[1] < b[3]):
        raise ConfigError(f"mosaic: bounds_m must be four finite numbers (xmin, ymin, xmax, ymax) with min < max, "
                          f"got {bounds_m!r}")
    return b


#: Grid rows per strip when the truth is taken from a TiledDEM (memory follows the strip's tiles).
TRUTH_STRIP_ROWS = 256


def truth(scene, grid: Mosaic, caster=None) -> np.ndarray:
    """The scene's height under each pixel centre of ``grid``, (ny, nx) m (NaN where nothing is below): the first
    hit of a vertical ray cast down from above the scene (for a DEM, the DEM resampled onto the grid). A
    :class:`~sonar_embree.TiledDEM` is taken strip by strip of grid rows, with the tiles under each strip."""
    cx, cy = grid.centres()
    if not isinstance(scene, TiledDEM):
        return _truth_of(scene, cx, cy, caster)
    out = np.full((cy.size, cx.size), np.nan)
    half = 0.5 * grid.pixel_m
    for a in range(0, cy.size, TRUTH_STRIP_ROWS):
        ys = cy[a:a + TRUTH_STRIP_ROWS]
        corners = np.array([[cx[0] - half, ys[-1] - half, 0.0], [cx[-1] + half, ys[0] + half, 0.0]])
        strip = scene.scene_around(corners, scene.pixel_m, empty_ok=True)
        if strip is not None:                                       # else no DEM data under this strip: NaN
            out[a:a + ys.size] = _truth_of(strip, cx, ys, caster)
    return out


def _truth_of(scene, cx, cy, caster=None) -> np.ndarray:
    xx, yy = np.meshgrid(cx, cy)
    return heights_at(scene, xx.ravel(), yy.ravel(), caster).reshape(xx.shape)


def heights_at(scene, x_m, y_m, caster=None) -> np.ndarray:
    """(n,) the scene's height under the points (x, y), m (NaN where nothing is below): the first hit of a vertical
    ray cast down from above the scene."""
    compiled = scene.compiled()
    top = float(scene.bounds[1, 2]) + 1.0
    depth = top - float(scene.bounds[0, 2]) + 1.0
    x, y = np.ravel(np.asarray(x_m, dtype=float)), np.ravel(np.asarray(y_m, dtype=float))
    origins = np.column_stack([x, y, np.full(x.size, top)]) - compiled.origin_m
    hits = (caster or RayCaster)(compiled).cast(origins, np.broadcast_to([0.0, 0.0, -1.0], origins.shape), depth)
    return np.where(hits.tri >= 0, top - hits.range_m, np.nan)


def write_truth(path, scene, grid: Mosaic) -> np.ndarray:
    """Write :func:`truth` on the mosaic's grid as a one-band GeoTIFF (height_m, NaN where nothing); returns it.

    ``scene``: a :class:`~sonar_embree.Scene` or a :class:`~sonar_embree.TiledDEM`, in the grid's CRS (two
    different CRSs are refused: the truth would be labelled with the wrong one)."""
    from ..io.geotiff import write_grid

    crs = scene.crs
    if crs is not None and grid.crs is not None and crs != grid.crs:
        raise ConfigError(f"write_truth: the scene is in {crs}, the mosaic grid in {grid.crs}; reproject one of them")
    z = truth(scene, grid)
    write_grid(path, z, grid.x0_m, grid.y0_m, grid.pixel_m, grid.crs, names=("height_m",), units=("m",))
    return z
