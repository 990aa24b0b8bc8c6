"""Seabed features with geometry, shadows and labels (docs/guide/scenes.md, "Seabed features").

Height-field features act on a grid's heights and return where they are (a mask), so that a seafloor can be split
into labelled objects; boulders are meshes of their own:

- :func:`sand_waves`: asymmetric bedforms, crests along a heading, a gentle stoss side and a steep lee side (the
  crest at ``asymmetry`` of the wavelength; 0.5 symmetric). Sand waves are metres to hundreds of metres long,
  megaripples 0.6–10 m (Ashley, "Classification of large-scale subaqueous bedforms", J. Sediment. Petrol. 60,
  160–172, 1990), lee slopes up to the angle of repose, some 30°;
- :func:`trawl_mark`: a pair of parallel grooves cut by trawl doors, each a Gaussian trough of a depth and a full
  width at half depth (door marks are some 0.1–0.3 m deep and 0.5–2 m wide: Lucchetti and Sala, "Impact and
  performance of Mediterranean fishing gear by side-scan sonar technology", Can. J. Fish. Aquat. Sci. 69,
  1806–1816, 2012);
- :func:`scour`: a scour pit around an object, depth d within radius a: d·(1 − (r/a)²)² (smooth at its rim);
- :func:`outcrop`: a rock outcrop, a raised plateau of rough rock (Perlin relief) with soft edges;
- :func:`dress` (:func:`sonar_embree.seafloor.dress`): fine roughness for a coarse DEM, upsampled by cubic
  splines with a power-law (fractal) relief of a given RMS at the scales below the DEM's spacing, so that its
  facets do not show;
- :func:`boulders`: a boulder field, a Poisson process of a density per m² with diameters from a power law
  N(>D) ∝ D^(−b) above D_min (the size-frequency law of boulder fields; Golombek and Rapp, J. Geophys. Res.
  102(E2), 4117–4129, 1997, use its exponential cousin), each an ellipsoid a third buried in the floor.

:func:`seabed` puts them together into a :class:`~sonar_embree.Scene` with one seafloor object per feature class
(``seafloor``, ``seafloor/sand_wave``, ``seafloor/trawl_mark``, ``seafloor/scour``, ``seafloor/outcrop``) and the
boulders as ``boulders``: the ground truth then names the feature under every sample and the boulders' shadows.
"""
from __future__ import annotations

import math

import numpy as np
import trimesh

from ..config import Material
from ..errors import ConfigError
from ..laws import sediments
from ..validation import check_number
from .meshes import Scene
from .seafloor import dress, from_heights, grid_shape, perlin_noise


def _across(x, y, heading_deg: float):
    """Distance across lines running along ``heading_deg`` (clockwise from north), m."""
    h = math.radians(heading_deg)
    return x * math.cos(h) - y * math.sin(h)


def sand_waves(x, y, wavelength_m: float, height_m: float, crest_heading_deg: float = 0.0,
               asymmetry: float = 0.7):
    """Heights (m) of asymmetric bedforms on grids ``x``, ``y`` (m), trough at 0, crest at ``height_m``.

    The profile across the crests rises as a half cosine over ``asymmetry``·λ (the stoss side) and falls over the
    rest (the lee side): mean slopes h/(aλ) up and h/((1 − a)λ) down, the steepest lee slope πh/(2(1 − a)λ).
    Returns (heights, mask), the mask true everywhere.
    """
    check_number("sand_waves", "wavelength_m", wavelength_m, positive=True)
    check_number("sand_waves", "height_m", height_m, lo=0.0)
    check_number("sand_waves", "asymmetry", asymmetry, lo=0.05, hi=0.95)
    p = (_across(x, y, crest_heading_deg) / wavelength_m) % 1.0
    a = asymmetry
    z = np.where(p < a, 0.5 * (1.0 - np.cos(np.pi * p / a)), 0.5 * (1.0 + np.cos(np.pi * (p - a) / (1.0 - a))))
    return height_m * z, np.ones(np.shape(z), dtype=bool)


def trawl_mark(x, y, start_m, end_m, depth_m: float = 0.15, width_m: float = 1.0, separation_m: float = 0.0):
    """Grooves along the segment ``start_m`` → ``end_m`` (x, y in m): one, or two ``separation_m`` apart (the
    trawl's doors). Each a Gaussian trough of ``depth_m`` and full width at half depth ``width_m``. Returns
    (heights ≤ 0, mask within a width of a groove)."""
    check_number("trawl_mark", "depth_m", depth_m, lo=0.0)
    check_number("trawl_mark", "width_m", width_m, positive=True)
    check_number("trawl_mark", "separation_m", separation_m, lo=0.0)
    a, b = np.asarray(start_m, dtype=float)[:2], np.asarray(end_m, dtype=float)[:2]
    length = float(np.linalg.norm(b - a))
    if length == 0.0:
        raise ConfigError("trawl_mark: start_m and end_m are the same point")
    t = (b - a) / length
    along = (x - a[0]) * t[0] + (y - a[1]) * t[1]
    side = -(x - a[0]) * t[1] + (y - a[1]) * t[0]
    inside = (along >= 0.0) & (along <= length)
    s = width_m / (2.0 * math.sqrt(2.0 * math.log(2.0)))
    offsets = (0.0,) if separation_m == 0.0 else (-0.5 * separation_m, 0.5 * separation_m)
    z, mask = np.zeros(np.shape(x)), np.zeros(np.shape(x), dtype=bool)
    for o in offsets:
        d = side - o
        z = np.minimum(z, np.where(inside, -depth_m * np.exp(-0.5 * (d / s) ** 2), 0.0))
        mask |= inside & (np.abs(d) <= width_m)
    return z, mask


def scour(x, y, centre_m, radius_m: float, depth_m: float):
    """A scour pit around ``centre_m`` (x, y): −d·(1 − (r/a)²)² within radius a.

    Returns (heights, mask r < a)."""
    check_number("scour", "radius_m", radius_m, positive=True)
    check_number("scour", "depth_m", depth_m, lo=0.0)
    r2 = ((x - centre_m[0]) ** 2 + (y - centre_m[1]) ** 2) / radius_m ** 2
    inside = r2 < 1.0
    return np.where(inside, -depth_m * (1.0 - r2) ** 2, 0.0), inside


def outcrop(x, y, centre_m, size_m, height_m: float, roughness: float = 0.3, seed: int = 0):
    """A rock outcrop: a plateau of ``height_m`` over an ellipse of full axes ``size_m`` (x, y) around
    ``centre_m``, its edge a smoothstep over the outer fifth, its top rough (Perlin relief of ``roughness``·height).
    Returns (heights ≥ 0, mask inside the ellipse)."""
    check_number("outcrop", "height_m", height_m, lo=0.0)
    check_number("outcrop", "roughness", roughness, lo=0.0, hi=1.0)
    ax, ay = 0.5 * float(size_m[0]), 0.5 * float(size_m[1])
    if not (ax > 0 and ay > 0):
        raise ConfigError(f"outcrop size_m must be positive, got {size_m!r}")
    r = np.sqrt(((x - centre_m[0]) / ax) ** 2 + ((y - centre_m[1]) / ay) ** 2)
    t = np.clip((1.0 - r) / 0.2, 0.0, 1.0)
    edge = t * t * (3.0 - 2.0 * t)
    ny, nx = np.shape(x)
    feature = 0.25 * min(ax, ay)                                   # the roughness's largest lumps
    cells = (max(1, round(float(np.ptp(y)) / feature)), max(1, round(float(np.ptp(x)) / feature)))
    noise = perlin_noise((ny, nx), cells, seed=seed)
    z = height_m * edge * (1.0 + roughness * (noise - noise.mean()))
    return np.maximum(z, 0.0), r < 1.0


def _ellipsoid(diameter: float, rng) -> trimesh.Trimesh:
    """A boulder: an icosphere scaled to axes D × 0.8D × 0.6D, its vertices jittered by 5 %, turned by a random
    yaw."""
    m = trimesh.creation.icosphere(subdivisions=2)
    v = m.vertices * (0.5 * diameter * np.array([1.0, 0.8, 0.6]))
    v *= 1.0 + 0.05 * rng.uniform(-1.0, 1.0, (v.shape[0], 1))
    yaw = rng.uniform(0.0, 2.0 * math.pi)
    c, s = math.cos(yaw), math.sin(yaw)
    v = v @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return trimesh.Trimesh(v, m.faces, process=False)


def boulder_sizes(rng, n: int, d_min_m: float, d_max_m: float, exponent: float) -> np.ndarray:
    """Diameters, m, of the truncated power law N(>D) ∝ D^(−b) on [d_min, d_max] (inverse CDF)."""
    u = rng.random(n)
    tail = (d_min_m / d_max_m) ** exponent
    return d_min_m * (1.0 - u * (1.0 - tail)) ** (-1.0 / exponent)


def boulders(extent_m, density_per_m2: float, d_min_m: float = 0.3, d_max_m: float = 3.0, exponent: float = 2.5,
             floor_z=0.0, seed: int = 0):
    """A boulder field over ``extent_m`` = (x0, x1, y0, y1): a Poisson number (density × area) of boulders at
    uniform positions, diameters from :func:`boulder_sizes`, each sunk to a third of its height into the floor
    (``floor_z``: a height or a function of (x, y)). Returns (mesh, centres (n, 2), diameters (n,))."""
    check_number("boulders", "density_per_m2", density_per_m2, positive=True, hi=10.0)
    check_number("boulders", "d_min_m", d_min_m, positive=True)
    check_number("boulders", "d_max_m", d_max_m, positive=True)
    check_number("boulders", "exponent", exponent, positive=True, hi=10.0)
    if d_max_m <= d_min_m:
        raise ConfigError(f"boulders: d_max_m = {d_max_m} must exceed d_min_m = {d_min_m}")
    x0, x1, y0, y1 = map(float, extent_m)
    rng = np.random.default_rng([int(seed), 0xB0],)
    n = rng.poisson(density_per_m2 * (x1 - x0) * (y1 - y0))
    xy = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
    d = boulder_sizes(rng, n, d_min_m, d_max_m, exponent)
    ground = floor_z if callable(floor_z) else (lambda x, y: np.full(np.shape(x), float(floor_z)))
    z = ground(xy[:, 0], xy[:, 1])
    parts = []
    for (x, y), dk, zk in zip(xy, d, z):
        m = _ellipsoid(dk, rng)
        m.apply_translation((x, y, zk + 0.3 * dk - 0.6 * dk / 3.0))
        parts.append(m)
    mesh = trimesh.util.concatenate(parts) if parts else None
    return mesh, xy, d


#: Feature classes of :func:`seabed`, in priority order (a face belongs to the first whose mask holds it).
CLASSES = ("outcrop", "scour", "trawl_mark", "sand_wave")


def seabed(size_m=(100.0, 100.0), resolution_m: float = 0.25, *, center_m=(0.0, 0.0), bedforms=None,
           trawl_marks=(), scours=(), outcrops=(), boulder_field=None, materials=None, seed: int = 0,
           scene: Scene | None = None):
    """A labelled seabed: a grid floor with the height features given, split into one seafloor object per feature
    class, and a boulder field as one more object.

    Parameters
    ----------
    size_m, resolution_m, center_m
        The floor's extent (x, y), grid spacing and centre, m.
    bedforms : dict, optional
        Keywords of :func:`sand_waves` (its crests cover the floor).
    trawl_marks, scours, outcrops : sequence of dict
        Keywords of :func:`trawl_mark`, :func:`scour` and :func:`outcrop`, one dict per feature.
    boulder_field : dict, optional
        Keywords of :func:`boulders` but ``extent_m`` and ``floor_z`` (the floor's).
    materials : dict, optional
        Material by class name ("seafloor", the classes of :data:`CLASSES`, "boulders"); defaults: Lambert −27 dB,
        rock (:data:`sonar_embree.laws.sediments.ROCK`) for outcrops and boulders.
    seed : int
    scene : Scene, optional
        Add the objects to this scene (default: a new one).

    Returns
    -------
    Scene
        Objects ``seafloor`` and ``seafloor/<class>`` (seafloor, for the ground truth's classes) and ``boulders``.
    """
    if np.ndim(size_m) != 1 or len(size_m) != 2:
        raise ConfigError(f"seabed size_m must be [x, y] in m, got {size_m!r}")
    grid_shape(size_m[0], size_m[1], resolution_m, "seabed")         # one-line errors before any allocation
    sx, sy = float(size_m[0]), float(size_m[1])
    nx, ny = int(round(sx / resolution_m)) + 1, int(round(sy / resolution_m)) + 1
    x0, y0 = center_m[0] - sx / 2, center_m[1] - sy / 2
    xx, yy = np.meshgrid(x0 + np.arange(nx) * resolution_m, y0 + np.arange(ny) * resolution_m)
    z = np.zeros_like(xx)
    masks = {}
    specs = {"sand_wave": [bedforms] if bedforms else [], "trawl_mark": list(trawl_marks),
             "scour": list(scours), "outcrop": [dict(o, seed=o.get("seed", seed + i)) for i, o in enumerate(outcrops)]}
    makers = {"sand_wave": sand_waves, "trawl_mark": trawl_mark, "scour": scour, "outcrop": outcrop}
    for name, kws in specs.items():
        for kw in kws:
            dz, m = makers[name](xx, yy, **kw)
            z = z + dz
            masks[name] = masks.get(name, np.zeros_like(m)) | m
    mats = {"seafloor": Material(), "outcrop": Material(scattering=sediments.ROCK),
            "boulders": Material(scattering=sediments.ROCK), **(materials or {})}
    mesh = from_heights(z, resolution_m, (x0, y0))
    cls = np.full(nx * ny, len(CLASSES))
    for k, name in reversed(list(enumerate(CLASSES))):
        if name in masks:
            cls[masks[name].ravel()] = k
    face_cls = cls[mesh.faces].min(axis=1)
    scene = Scene() if scene is None else scene
    for k, name in enumerate(CLASSES + ("",)):
        faces = np.flatnonzero(face_cls == k)
        if faces.size:
            label = "seafloor" if not name else f"seafloor/{name}"
            scene.add(mesh.submesh([faces], append=True), material=mats.get(name or "seafloor", mats["seafloor"]),
                      label=label, seafloor=True)
    if boulder_field:
        def ground(px, py):
            i = np.clip(np.rint((np.asarray(px) - x0) / resolution_m).astype(int), 0, nx - 1)
            j = np.clip(np.rint((np.asarray(py) - y0) / resolution_m).astype(int), 0, ny - 1)
            return z[j, i]
        rocks, _, _ = boulders((x0, x0 + sx, y0, y0 + sy), floor_z=ground, **{"seed": seed, **boulder_field})
        if rocks is not None:
            scene.add(rocks, material=mats["boulders"], label="boulders")
    return scene


__all__ = ["CLASSES", "boulder_sizes", "boulders", "dress", "outcrop", "sand_waves", "scour", "seabed", "trawl_mark"]
