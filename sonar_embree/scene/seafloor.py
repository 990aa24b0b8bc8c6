"""Seafloors as ``trimesh.Trimesh`` (world metres, z up, normals up): procedural ones, and measured ones from a
DEM raster (:func:`from_dem`) or an ASCII XYZ grid (:func:`from_xyz`).

The procedural ones are centred on ``center_m`` (default the origin) and deterministic for a seed.
"""
from __future__ import annotations

import math
import os

import numpy as np
import trimesh
from scipy.ndimage import map_coordinates

from ..errors import ConfigError
from ..validation import check_number
from .. import checks
from ..laws.texture import gaussian_field_at
from .tolerance import TOLERANCE


def _size(size_m):
    try:
        sx, sy = (float(v) for v in size_m)
    except (TypeError, ValueError):
        raise ConfigError(f"seafloor size_m must be (x, y) in m, got {size_m!r}") from None
    if not (sx > 0 and sy > 0 and math.isfinite(sx) and math.isfinite(sy)):
        raise ConfigError(f"seafloor size_m must be positive and finite, got {size_m!r}")
    return sx, sy


def _center(center_m):
    try:
        cx, cy = (float(v) for v in center_m)
    except (TypeError, ValueError):
        raise ConfigError(f"seafloor center_m must be (x, y) in m, got {center_m!r}") from None
    if not (math.isfinite(cx) and math.isfinite(cy)):
        raise ConfigError(f"seafloor center_m must be finite, got {center_m!r}")
    return cx, cy


#: Most Perlin octaves accepted; octaves finer than the grid are not drawn (they add no detail).
MAX_OCTAVES = 24


#: The most vertices a generated seafloor grid may have (some 1.5 GB once meshed and compiled).
MAX_GRID_VERTICES = 20_000_000


def grid_shape(sx, sy, resolution_m, what: str = "seafloor"):
    """(nx, ny) vertices of a ``sx`` × ``sy`` m grid at ``resolution_m``; a size or resolution that is not a
    positive finite number, or a grid beyond :data:`MAX_GRID_VERTICES`, is a one-line error naming it."""
    for name, v in (("resolution_m", resolution_m), ("size_m", sx), ("size_m", sy)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) or not (v > 0 and math.isfinite(v)):
            raise ConfigError(f"{what} {name} must be > 0 m, got {v!r}")
    nx = max(int(math.ceil(sx / resolution_m)) + 1, 2)
    ny = max(int(math.ceil(sy / resolution_m)) + 1, 2)
    if nx * ny > MAX_GRID_VERTICES:
        raise ConfigError(f"{what} of {sx}x{sy} m at resolution_m={resolution_m} needs {nx * ny:.3g} vertices "
                          f"(at most {MAX_GRID_VERTICES:.0e}); coarsen it or make it smaller")
    return nx, ny


def flat(size_m=(400.0, 200.0), z_m: float = 0.0, center_m=(0.0, 0.0)) -> trimesh.Trimesh:
    """A horizontal rectangle of ``size_m`` = (x, y) metres at height ``z_m``, two triangles."""
    sx, sy = _size(size_m)
    cx, cy = _center(center_m)
    return from_heights(np.full((2, 2), float(z_m)), spacing_m=(sx, sy), origin_m=(cx - sx / 2, cy - sy / 2))


def from_heights(heights_m, spacing_m=1.0, origin_m=(0.0, 0.0)) -> trimesh.Trimesh:
    """A height-field mesh: ``heights_m[j, i]`` is z at x = x0 + i·dx, y = y0 + j·dy.

    Parameters
    ----------
    heights_m : (ny, nx) float
        Heights in m, ny, nx ≥ 2.
    spacing_m : float or (dx, dy)
        Grid spacing in m.
    origin_m : (x0, y0)
        World position of ``heights_m[0, 0]``.
    """
    z = np.asarray(heights_m, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 2:
        raise ConfigError(f"seafloor heights must be a 2-D array of at least 2x2, got shape {z.shape}")
    if not np.all(np.isfinite(z)):
        raise ConfigError("seafloor heights contain NaN or inf")
    dx, dy = (float(spacing_m), float(spacing_m)) if np.isscalar(spacing_m) else map(float, spacing_m)
    if not (dx > 0 and dy > 0):
        raise ConfigError(f"seafloor spacing_m must be > 0, got {spacing_m!r}")
    ny, nx = z.shape
    x = origin_m[0] + dx * np.arange(nx)
    y = origin_m[1] + dy * np.arange(ny)
    xx, yy = np.meshgrid(x, y)
    v = np.column_stack([xx.ravel(), yy.ravel(), z.ravel()])
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    # counter-clockwise seen from above: normals point up
    f = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return trimesh.Trimesh(v, f, process=False)


#: Values that rasters commonly use for "no data" (GDAL/ESRI -9999, -99999, int16 limits, float32 limits):
#: a DEM holding one of them exactly without declaring it would be meshed as a pit or a spike.
NODATA_SENTINELS = (-9999.0, -99999.0, -32767.0, -32768.0, float(np.finfo(np.float32).min),
                    float(np.finfo(np.float32).max))


def declared_nodata(z: np.ndarray, nodata, where: str) -> np.ndarray:
    """Heights ``z`` (ny, nx) with the value ``nodata`` (when given) as NaN; refused, naming the value, when it
    holds a common nodata sentinel (:data:`NODATA_SENTINELS`) exactly that was not declared, and naming the
    pixel, when one lies farther from the median height than any relief (a spike)."""
    z = np.asarray(z, dtype=np.float64)
    if nodata is not None:
        if isinstance(nodata, bool) or not isinstance(nodata, (int, float, np.number)):
            raise ConfigError(f"{where}: nodata must be a number, got {nodata!r}")
        z = np.where(z == float(nodata), np.nan, z)
    for value in NODATA_SENTINELS:
        n = int(np.count_nonzero(z == value))
        if n:
            raise ConfigError(f"{where}: {n} pixel(s) hold exactly {value:g}, a common nodata value the raster does "
                              f"not declare; pass nodata={value:g} (or set it in the file: gdal_edit.py -a_nodata "
                              f"{value:g})")

    if np.isfinite(z).any():
        off = np.abs(z - np.nanmedian(z))
        k = int(np.nanargmax(off))
        if off.flat[k] > TOLERANCE.max_height_offset_m:
            i, j = divmod(k, z.shape[1])
            raise ConfigError(f"{where}: pixel (row {i}, column {j}) holds {z[i, j]:.6g} m, "
                              f"{off[i, j]:.6g} m from the median height, beyond any relief (a spike or an "
                              "undeclared nodata value?); fix or remove it")
    return z


#: Memory a DEM's triangle takes once meshed, compiled and in Embree's BVH (measured: 0.4 GB per million).
DEM_BYTES_PER_TRIANGLE = 400


def check_dem_memory(shape, where: str) -> None:
    """Refuse, before reading its pixels, a raster of ``shape`` (ny, nx) whose whole mesh cannot fit in half this
    machine's memory, pointing at :class:`~sonar_embree.TiledDEM` (which meshes only the tiles in reach)."""
    n = 2 * max(shape[0] - 1, 0) * max(shape[1] - 1, 0)
    need, have = n * DEM_BYTES_PER_TRIANGLE, checks.physical_memory_bytes()
    if have is not None and need > 0.5 * have:
        raise ConfigError(f"{where}: {shape[1]} x {shape[0]} pixels make {n / 1e6:.1f} M triangles, about "
                          f"{need / 2**30:.1f} GiB once meshed, more than half this machine's {have / 2**30:.1f} GiB; "
                          "load it as se.TiledDEM(path) (meshed tile by tile as the pings need it)")


def from_dem(path, band: int = 1, nodata: float | None = None, dress_factor: int | None = None,
             dress_rms_m: float = 0.02) -> trimesh.Trimesh:
    """A seafloor from a digital elevation model raster (GeoTIFF, or anything GDAL reads; rasterio opens it).

    Vertices at the pixel centres (x = c + (j + ½)·a, y = f + (i + ½)·e of the raster's transform, so a
    north-up raster's first row is its northernmost), z the band's value in m (elevation up: the seabed
    below a sea-level datum is negative); nodata pixels are holes (no triangle touches them). The raster's
    CRS, when it has one, is kept in ``mesh.metadata["crs"]`` and becomes the scene's (:attr:`Scene.crs`); it
    must be projected, in metres. ``nodata``: a height that means "no data" beyond the one the raster declares;
    a common sentinel (-9999, …) held but not declared is refused. ``dress_factor``: :func:`dress` the DEM,
    ``dress_factor`` times finer with a relief of RMS ``dress_rms_m`` at the scales it cannot hold (a DEM without
    holes, square pixels).
    """
    from ..io.geotiff import raster_info, read_grid

    check_dem_memory(raster_info(path, band).shape, os.fspath(path))
    grid = read_grid(path, band)
    crs = None
    if grid.crs is not None:
        from ..io.geo import crs_name

        try:
            crs = crs_name(grid.crs)
        except ConfigError as exc:
            raise ConfigError(f"{os.fspath(path)}: {exc}") from None
    z = declared_nodata(grid.values, nodata, os.fspath(path))
    x, y = grid.x_m, grid.y_m
    if dress_factor is not None:
        x, y, z = _dressed(x, y, z, dress_factor, dress_rms_m, os.fspath(path))
    mesh = grid_mesh(x, y, z, where=os.fspath(path))
    mesh.metadata["crs"] = crs
    return mesh


def dress(heights_m, spacing_m: float, factor: int = 4, rms_m: float = 0.02, exponent: float = 3.0,
          seed: int = 0):
    """A coarse DEM upsampled ``factor`` times by cubic splines, plus a power-law relief of RMS ``rms_m`` at the
    wavelengths it cannot hold (shorter than twice its spacing): its spectrum ∝ K^(−exponent) from K = 1/(2Δ) to
    the new grid's Nyquist, none below. Returns (heights (factor·(ny − 1) + 1, factor·(nx − 1) + 1), new spacing).
    """
    z = np.asarray(heights_m, dtype=float)
    check_number("dress", "spacing_m", spacing_m, positive=True)
    check_number("dress", "factor", factor, lo=1, hi=64, integer=True)
    check_number("dress", "rms_m", rms_m, lo=0.0)
    if z.ndim != 2 or min(z.shape) < 2 or not np.all(np.isfinite(z)):
        raise ConfigError(f"dress: heights_m must be a finite 2-D grid of at least 2x2, got shape {z.shape}")
    ny, nx = (np.array(z.shape) - 1) * int(factor) + 1
    jj, ii = np.meshgrid(np.arange(ny) / factor, np.arange(nx) / factor, indexing="ij")
    fine = map_coordinates(z, [jj, ii], order=3, mode="nearest")
    d = spacing_m / factor
    ky, kx = np.fft.fftfreq(ny, d)[:, None], np.fft.fftfreq(nx, d)[None, :]
    k = np.hypot(kx, ky)
    shape = np.where(k > 1.0 / (2.0 * spacing_m), np.maximum(k, 1e-300) ** (-0.5 * exponent), 0.0)
    rng = np.random.default_rng([int(seed), 0xD4E55])
    rough = np.fft.ifft2(np.fft.fft2(rng.standard_normal((ny, nx))) * shape).real
    sd = float(rough.std())
    return fine + (rough * (rms_m / sd) if sd > 0 else 0.0), d


def _dressed(x, y, z, factor: int, rms_m: float, where: str):
    """The DEM's axes and heights after :func:`dress` (refused with holes or unequal spacings)."""
    dx, dy = float(abs(x[1] - x[0])), float(abs(y[1] - y[0]))
    if np.isnan(z).any() or abs(dx - dy) > 1e-9 * dx:
        raise ConfigError(f"{where}: dressing needs a DEM without holes and with square pixels "
                          f"({dx:g} × {dy:g} m, {int(np.isnan(z).sum())} holes)")
    fine, _ = dress(z, dx, factor, rms_m)
    return (np.linspace(x[0], x[-1], fine.shape[1]), np.linspace(y[0], y[-1], fine.shape[0]), fine)


def from_xyz(path, crs=None) -> trimesh.Trimesh:
    """A seafloor from an ASCII XYZ grid: one "x y z" point per line (blanks, commas or semicolons between
    them; lines that are not three numbers, such as a header, are skipped), the points on a regular grid in
    any order, missing grid points as holes. ``crs``: the CRS of x and y (kept as for :func:`from_dem`)."""
    path = os.fspath(path)
    pts = _xyz_points(path)
    xs, ys = np.unique(pts[:, 0]), np.unique(pts[:, 1])
    for name, axis in (("x", xs), ("y", ys)):
        step = np.diff(axis)
        if axis.size < 2 or np.ptp(step) > 1e-6 * max(step.min(), 1e-12) + 1e-9:
            raise ConfigError(f"{path}: the points are not on a regular grid in {name} (spacings "
                              f"{step.min() if step.size else 0:g} to {step.max() if step.size else 0:g} m)")
    z = np.full((ys.size, xs.size), np.nan)
    z[np.searchsorted(ys, pts[:, 1]), np.searchsorted(xs, pts[:, 0])] = pts[:, 2]
    z = declared_nodata(z, None, path)
    mesh = grid_mesh(xs, ys[::-1], z[::-1], where=path)    # rows north first, as a raster's: the same triangles
    if crs is not None:
        from ..io.geo import crs_name

        crs = crs_name(crs)
    mesh.metadata["crs"] = crs
    return mesh


def _xyz_points(path: str) -> np.ndarray:
    """(n, 3) points of an ASCII XYZ file."""
    try:
        with open(path, encoding="utf-8-sig") as fh:
            lines = fh.read().replace(",", " ").replace(";", " ").splitlines()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read XYZ grid ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a text XYZ grid") from None
    rows = []
    for line in lines:
        parts = line.split()
        try:
            if len(parts) == 3:
                rows.append([float(v) for v in parts])
        except ValueError:
            continue
    if len(rows) < 4:
        raise ConfigError(f"{path}: an XYZ grid needs at least 4 points of three numbers, found {len(rows)}")
    pts = np.array(rows)
    if not np.all(np.isfinite(pts)):
        raise ConfigError(f"{path}: the XYZ grid holds NaN or inf")
    return pts


def grid_mesh(x_m, y_m, z_m, where: str = "grid") -> trimesh.Trimesh:
    """A height-field mesh over the grid x (nx,) × y (ny,) with heights z (ny, nx); NaN heights are holes.

    Each grid cell is two triangles, kept where all three of their corners have a height; normals up whatever
    the order of x and y; vertices no triangle uses are dropped.
    """
    z = np.asarray(z_m, dtype=np.float64)
    ny, nx = z.shape
    if min(ny, nx) < 2:
        raise ConfigError(f"{where}: a grid needs at least 2x2 points, got {nx}x{ny}")
    xx, yy = np.meshgrid(np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64))
    v = np.column_stack([xx.ravel(), yy.ravel(), z.ravel()])
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    f = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    if (x_m[1] - x_m[0]) * (y_m[1] - y_m[0]) < 0:                      # x or y decreasing: turn the faces up
        f = f[:, ::-1]
    f = f[np.all(np.isfinite(v[f, 2]), axis=1)]
    if f.shape[0] == 0:
        raise ConfigError(f"{where}: no cell has heights at all its corners (all nodata?)")
    used, f = np.unique(f, return_inverse=True)
    return trimesh.Trimesh(v[used], f.reshape(-1, 3), process=False)


def perlin_noise(shape, cells, seed: int = 0, octaves: int = 4, persistence: float = 0.5):
    """Fractal 2-D gradient (Perlin) noise on a (ny, nx) grid, roughly in [−1, 1].

    ``cells`` = (cy, cx) lattice cells of the first octave across the grid.
    """
    ny, nx = shape
    rng = np.random.default_rng(seed)
    total = np.zeros(shape)
    amp, norm = 1.0, 0.0
    cy, cx = cells
    for _ in range(octaves):
        angles = rng.uniform(0.0, 2.0 * np.pi, size=(cy + 1, cx + 1))
        gx, gy = np.cos(angles), np.sin(angles)
        y = np.linspace(0.0, cy, ny, endpoint=False) + 0.5 * cy / ny
        x = np.linspace(0.0, cx, nx, endpoint=False) + 0.5 * cx / nx
        yi = np.minimum(y.astype(int), cy - 1)
        xi = np.minimum(x.astype(int), cx - 1)
        fy, fx = (y - yi)[:, None], (x - xi)[None, :]
        Y0, X0 = yi[:, None], xi[None, :]

        def dot(oy, ox):
            return gx[Y0 + oy, X0 + ox] * (fx - ox) + gy[Y0 + oy, X0 + ox] * (fy - oy)

        def fade(t):
            return t * t * t * (t * (t * 6 - 15) + 10)

        u, w = fade(fx), fade(fy)
        n0 = dot(0, 0) * (1 - u) + dot(0, 1) * u
        n1 = dot(1, 0) * (1 - u) + dot(1, 1) * u
        total += amp * (n0 * (1 - w) + n1 * w)
        norm += amp
        amp *= persistence
        cy, cx = 2 * cy, 2 * cx
    return total / norm * math.sqrt(2.0)


def perlin(size_m=(200.0, 200.0), resolution_m: float = 0.5, relief_m: float = 0.1,
           feature_m: float = 20.0, octaves: int = 4, seed: int = 0, z_m: float = 0.0,
           center_m=(0.0, 0.0)) -> trimesh.Trimesh:
    """A Perlin-noise floor: ``relief_m`` peak to peak, largest features ``feature_m`` across.

    Parameters
    ----------
    size_m : (x, y)
        Extent in m.
    resolution_m : float
        Grid spacing in m (2 triangles per cell).
    relief_m : float
        Height difference between the lowest and highest vertex, in m.
    feature_m : float
        Lattice cell size of the first octave, in m.
    octaves : int
        Number of octaves (1 … 24), each half the size and amplitude of the previous;
        octaves finer than the grid (``resolution_m``) add nothing and are not drawn.
    seed : int
        Random seed (same seed, same floor).
    z_m : float
        Mean height in m.
    """
    sx, sy = _size(size_m)
    nx, ny = grid_shape(sx, sy, resolution_m)
    if isinstance(octaves, bool) or not isinstance(octaves, (int, np.integer)) or not 1 <= octaves <= MAX_OCTAVES:
        raise ConfigError(f"perlin octaves must be an integer in 1..{MAX_OCTAVES}, got {octaves!r}")
    if not (relief_m >= 0 and feature_m > 0):
        raise ConfigError("perlin needs relief_m >= 0 and feature_m > 0")
    cells = (max(1, int(round(sy / feature_m))), max(1, int(round(sx / feature_m))))
    # an octave whose lattice is finer than the grid adds no detail (and 2^octaves cells of memory)
    useful = 1 + int(math.floor(math.log2(max(nx / cells[1], ny / cells[0], 1.0))))
    n = perlin_noise((ny, nx), cells, seed=seed, octaves=min(int(octaves), useful))
    ptp = float(np.ptp(n))
    z = z_m + (n - n.mean()) * (relief_m / ptp if ptp > 0 else 0.0)
    cx, cy = _center(center_m)
    return from_heights(z, (sx / (nx - 1), sy / (ny - 1)), (cx - sx / 2, cy - sy / 2))


def ripples(size_m=(200.0, 200.0), resolution_m: float = 0.1, wavelength_m: float = 0.8,
            height_m: float = 0.08, crest_heading_deg: float = 0.0, relief_m: float = 0.0,
            seed: int = 0, z_m: float = 0.0, center_m=(0.0, 0.0)) -> trimesh.Trimesh:
    """Sand ripples: a sinusoid of ``wavelength_m`` and crest-to-trough ``height_m`` whose
    crests run along ``crest_heading_deg`` (clockwise from north), optionally on top of a
    Perlin floor of ``relief_m`` peak to peak. Resolve the wavelength: resolution ≤ λ/4.
    """
    sx, sy = _size(size_m)
    if not (wavelength_m > 0 and height_m >= 0):
        raise ConfigError(f"ripples need wavelength_m > 0 and height_m >= 0, got {wavelength_m!r}, {height_m!r}")
    if resolution_m > wavelength_m / 4:
        raise ConfigError(f"ripples resolution_m={resolution_m} must be <= wavelength_m/4 = {wavelength_m / 4}")
    nx, ny = grid_shape(sx, sy, resolution_m)
    x = np.linspace(-sx / 2, sx / 2, nx)
    y = np.linspace(-sy / 2, sy / 2, ny)
    xx, yy = np.meshgrid(x, y)
    h = math.radians(crest_heading_deg)
    across = xx * math.cos(h) - yy * math.sin(h)  # distance across the crests
    z = z_m + 0.5 * height_m * np.sin(2 * np.pi * across / wavelength_m)
    if relief_m > 0:
        cells = (max(1, int(round(sy / 20.0))), max(1, int(round(sx / 20.0))))
        n = perlin_noise((ny, nx), cells, seed=seed)
        z = z + (n - n.mean()) * relief_m / max(float(np.ptp(n)), 1e-300)
    cx, cy = _center(center_m)
    return from_heights(z, (sx / (nx - 1), sy / (ny - 1)), (cx - sx / 2, cy - sy / 2))


def sediment_classes(mesh: trimesh.Trimesh, fractions, patch_m: float = 20.0, seed: int = 0) -> np.ndarray:
    """A class per face from a smooth random field: patches of sediment classes.

    The field is the unit-variance Gaussian field of :mod:`sonar_embree.laws.texture`
    (lattice spacing ``patch_m``, frozen in world coordinates by ``seed``) at each face's
    centroid; class k takes the faces whose value falls between the normal quantiles
    Φ⁻¹(F_k−1) and Φ⁻¹(F_k) of the cumulative fractions, so class k covers about
    ``fractions[k]`` of a floor much larger than ``patch_m``.

    Parameters
    ----------
    mesh : trimesh.Trimesh
    fractions : sequence of float
        Share of the floor per class (normalised to sum 1), each > 0.
    patch_m : float
        Patch size (the field's correlation length), m.
    seed : int

    Returns
    -------
    (n_faces,) int
    """
    from scipy.special import ndtri


    f = np.asarray(fractions, dtype=float)
    if f.ndim != 1 or f.size == 0 or np.any(~(f > 0)):
        raise ConfigError(f"sediment fractions must be positive numbers, got {fractions!r}")
    if not (isinstance(patch_m, (int, float)) and patch_m > 0):
        raise ConfigError(f"sediment patch_m must be > 0 m, got {patch_m!r}")
    field = np.empty(len(mesh.faces))
    gaussian_field_at(np.ascontiguousarray(mesh.triangles_center, dtype=np.float64), 1.0 / patch_m, int(seed), field)
    edges = ndtri(np.cumsum(f / f.sum())[:-1])
    return np.searchsorted(edges, field)
