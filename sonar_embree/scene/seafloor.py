"""Procedural seafloors as ``trimesh.Trimesh`` (world metres, z up, normals up).

All are centred on ``center_m`` (default the origin) and deterministic for a seed.
"""
from __future__ import annotations

import math

import numpy as np
import trimesh

from ..errors import ConfigError


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


def _grid_shape(sx, sy, resolution_m):
    if not (resolution_m > 0 and math.isfinite(resolution_m)):
        raise ConfigError(f"seafloor resolution_m must be > 0, got {resolution_m!r}")
    nx = max(int(math.ceil(sx / resolution_m)) + 1, 2)
    ny = max(int(math.ceil(sy / resolution_m)) + 1, 2)
    if nx * ny > 20_000_000:
        raise ConfigError(f"seafloor of {sx}x{sy} m at resolution_m={resolution_m} needs {nx * ny} vertices; coarsen it")
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
    nx, ny = _grid_shape(sx, sy, resolution_m)
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
    nx, ny = _grid_shape(sx, sy, resolution_m)
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

    from ..laws.texture import gaussian_field_at

    f = np.asarray(fractions, dtype=float)
    if f.ndim != 1 or f.size == 0 or np.any(~(f > 0)):
        raise ConfigError(f"sediment fractions must be positive numbers, got {fractions!r}")
    if not (isinstance(patch_m, (int, float)) and patch_m > 0):
        raise ConfigError(f"sediment patch_m must be > 0 m, got {patch_m!r}")
    field = np.empty(len(mesh.faces))
    gaussian_field_at(np.ascontiguousarray(mesh.triangles_center, dtype=np.float64), 1.0 / patch_m, int(seed), field)
    edges = ndtri(np.cumsum(f / f.sum())[:-1])
    return np.searchsorted(edges, field)
