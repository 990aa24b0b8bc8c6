"""Backscatter maps: a dB offset on an object's law per face, per vertex or from an image (docs/physics.md §10).

- per face: one dB value per triangle;
- per vertex: dB values at the vertices, interpolated barycentrically at the hit;
- image: a texture in dB looked up through the mesh's UV coordinates (barycentric UV at
  the hit, bilinear between texel centres, wrapped), the way a renderer samples a
  diffuse texture (M. Pharr, W. Jakob and G. Humphreys, *Physically Based Rendering*,
  4th ed., 2023, §10.4). UV (0, 0) is the image's lower-left corner (the OBJ/glTF
  convention as Blender writes it: v up, image rows top down).

The offset multiplies σ by 10^(dB/10) at each hit; the law's angle dependence is kept.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..kernels import njit, prange

MAP_KINDS = ("face", "vertex", "image")


@dataclass(frozen=True, eq=False)
class BackscatterMap:
    """A backscatter offset map of one object; build with :meth:`per_face`, :meth:`per_vertex` or :meth:`image`.

    Attributes
    ----------
    kind : {"face", "vertex", "image"}
    values_db : ndarray
        (n_faces,), (n_vertices,) or (rows, columns) offsets in dB.
    uv : (n_vertices, 2) float64 or None
        UV per vertex for an image map (None: the mesh's own UVs).
    """

    kind: str
    values_db: np.ndarray
    uv: np.ndarray | None = None

    def __post_init__(self):
        if not isinstance(self.kind, str) or self.kind not in MAP_KINDS:
            raise ConfigError(f"BackscatterMap.kind must be one of {MAP_KINDS}, got {self.kind!r}")
        v = np.asarray(self.values_db, dtype=np.float64)
        if v.ndim != (2 if self.kind == "image" else 1) or v.size == 0 or not np.all(np.isfinite(v)):
            raise ConfigError(f"BackscatterMap ({self.kind}): values_db must be a finite "
                              f"{'2-d image' if self.kind == 'image' else '1-d array'}, got shape {v.shape}")
        if np.any(np.abs(v) > 100):
            raise ConfigError(f"BackscatterMap ({self.kind}): offsets beyond ±100 dB (largest {np.abs(v).max():g}); "
                              "give dB, not linear values")
        object.__setattr__(self, "values_db", v)
        if self.uv is not None:
            uv = np.asarray(self.uv, dtype=np.float64)
            if uv.ndim != 2 or uv.shape[1] != 2 or not np.all(np.isfinite(uv)):
                raise ConfigError(f"BackscatterMap.uv must be finite, shaped (n_vertices, 2), got {uv.shape}")
            object.__setattr__(self, "uv", uv)

    @classmethod
    def per_face(cls, values_db) -> "BackscatterMap":
        """One offset per triangle, dB."""
        return cls("face", values_db)

    @classmethod
    def per_vertex(cls, values_db) -> "BackscatterMap":
        """One offset per vertex, dB, interpolated barycentrically."""
        return cls("vertex", values_db)

    @classmethod
    def image(cls, image, db_range=None, uv=None) -> "BackscatterMap":
        """An image texture through UV coordinates.

        Parameters
        ----------
        image : str, PathLike or (rows, columns) array
            An image file (read as grey levels 0…1) or an array: dB values, or grey
            levels 0…1 with ``db_range``.
        db_range : (float, float), optional
            dB at grey 0 and grey 1 (required for an image file).
        uv : (n_vertices, 2) array, optional
            UV per vertex; default the mesh's own (from an OBJ/GLB with UVs).
        """
        if isinstance(image, (str, os.PathLike)):
            if db_range is None:
                raise ConfigError(f"BackscatterMap.image({os.fspath(image)!r}): give db_range = (dB at black, "
                                  "dB at white)")
            image = read_grey(image)
        values = np.asarray(image, dtype=np.float64)
        if db_range is not None:
            lo, hi = (float(x) for x in db_range)
            values = lo + (hi - lo) * values
        return cls("image", values, uv)

    def corner_values(self, faces: np.ndarray) -> np.ndarray:
        """(f, 3) dB at each triangle's corners (face and vertex maps; sizes checked by ``Scene.add``)."""
        if self.kind == "face":
            return np.repeat(self.values_db[:, None], 3, axis=1)
        return self.values_db[faces]


def read_grey(path) -> np.ndarray:
    """An image file as grey levels in [0, 1], (rows, columns) float64 (colour: the mean of R, G, B)."""
    import imageio.v3 as iio

    try:
        img = np.asarray(iio.imread(os.fspath(path)))
    except Exception as exc:  # imageio raises many types for unreadable files
        raise ConfigError(f"{os.fspath(path)}: cannot read the image ({str(exc).splitlines()[0]})") from None
    scale = float(np.iinfo(img.dtype).max) if np.issubdtype(img.dtype, np.integer) else 1.0
    img = img.astype(np.float64) / scale
    return img[..., :3].mean(axis=-1) if img.ndim == 3 else img


@njit(cache=True, nogil=True)
def _texel(tex, off, h, w, u, v):
    """Bilinear, wrapped lookup of texture ``tex[off:off + h·w]`` (rows top down) at (u, v)."""
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5
    x0, y0 = math.floor(x), math.floor(y)
    fx, fy = x - x0, y - y0
    c0, r0 = int(x0) % w, int(y0) % h
    c1, r1 = (c0 + 1) % w, (r0 + 1) % h
    top = tex[off + r0 * w + c0] * (1.0 - fx) + tex[off + r0 * w + c1] * fx
    bot = tex[off + r1 * w + c0] * (1.0 - fx) + tex[off + r1 * w + c1] * fx
    return top * (1.0 - fy) + bot * fy


@njit(cache=True, nogil=True)
def barycentric(vertices, a, b, c, p):
    """Barycentric coordinates of point ``p`` (projected) in triangle (a, b, c) of ``vertices``."""
    e0x, e0y, e0z = vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1], vertices[b, 2] - vertices[a, 2]
    e1x, e1y, e1z = vertices[c, 0] - vertices[a, 0], vertices[c, 1] - vertices[a, 1], vertices[c, 2] - vertices[a, 2]
    px, py, pz = p[0] - vertices[a, 0], p[1] - vertices[a, 1], p[2] - vertices[a, 2]
    d00 = e0x * e0x + e0y * e0y + e0z * e0z
    d01 = e0x * e1x + e0y * e1y + e0z * e1z
    d11 = e1x * e1x + e1y * e1y + e1z * e1z
    d20 = px * e0x + py * e0y + pz * e0z
    d21 = px * e1x + py * e1y + pz * e1z
    den = d00 * d11 - d01 * d01
    b1 = (d11 * d20 - d01 * d21) / den
    b2 = (d00 * d21 - d01 * d20) / den
    return 1.0 - b1 - b2, b1, b2


@njit(cache=True, nogil=True, parallel=True)
def map_weights(prim, points, vertices, faces, corner_db, face_tex, corner_uv, tex, tex_off, tex_h, tex_w, weight):
    """``weight[i] *= 10^(dB/10)``, dB the map's offset at each hit (barycentric in its triangle).

    Parameters
    ----------
    prim : (n,) int32
        Triangle hit, −1 for none.
    points : (n, 3) float64
        Hit points, local frame, m.
    vertices : (v, 3) float64; faces : (f, 3) int32
    corner_db : (f, 3) float64
        Face and vertex maps' dB at each corner (0 elsewhere).
    face_tex : (f,) int32
        Image of each triangle, −1 for none.
    corner_uv : (f, 3, 2) float64
        UV at each corner of image-mapped triangles.
    tex : (m,) float64; tex_off, tex_h, tex_w : (n_images,) int64
        The images in dB, flattened row-major one after another.
    weight : (n,) float64
        Multiplied in place.
    """
    for i in prange(prim.shape[0]):
        t = prim[i]
        if t < 0 or weight[i] == 0.0:
            continue
        b0, b1, b2 = barycentric(vertices, faces[t, 0], faces[t, 1], faces[t, 2], points[i])
        db = b0 * corner_db[t, 0] + b1 * corner_db[t, 1] + b2 * corner_db[t, 2]
        k = face_tex[t]
        if k >= 0:
            u = b0 * corner_uv[t, 0, 0] + b1 * corner_uv[t, 1, 0] + b2 * corner_uv[t, 2, 0]
            v = b0 * corner_uv[t, 0, 1] + b1 * corner_uv[t, 1, 1] + b2 * corner_uv[t, 2, 1]
            db += _texel(tex, tex_off[k], tex_h[k], tex_w[k], u, v)
        weight[i] *= 10.0 ** (db / 10.0)


@dataclass(frozen=True, eq=False)
class MapTable:
    """A scene's maps as :func:`map_weights` reads them (see its parameters)."""

    corner_db: np.ndarray
    face_tex: np.ndarray
    corner_uv: np.ndarray
    tex: np.ndarray
    tex_off: np.ndarray
    tex_h: np.ndarray
    tex_w: np.ndarray

    @classmethod
    def build(cls, objects) -> "MapTable | None":
        """From the scene's objects (``backscatter_map``, ``uv``); None when none has a map."""
        if all(o.backscatter_map is None for o in objects):
            return None
        corner_db, face_tex, corner_uv, images = [], [], [], []
        for o in objects:
            m, nf = o.backscatter_map, o.faces.shape[0]
            image = m is not None and m.kind == "image"
            corner_db.append(m.corner_values(o.faces) if m is not None and not image
                             else np.zeros((nf, 3)))
            face_tex.append(np.full(nf, len(images) if image else -1, dtype=np.int32))
            corner_uv.append(o.uv[o.faces] if image else np.zeros((nf, 3, 2)))
            if image:
                images.append(m.values_db)
        sizes = [im.size for im in images]
        return cls(np.concatenate(corner_db), np.concatenate(face_tex), np.concatenate(corner_uv),
                   np.concatenate([im.ravel() for im in images]) if images else np.zeros(1),
                   np.cumsum([0] + sizes[:-1]).astype(np.int64),
                   np.array([im.shape[0] for im in images], dtype=np.int64),
                   np.array([im.shape[1] for im in images], dtype=np.int64))

    def apply(self, compiled, prim, points_local, weight) -> None:
        map_weights(prim, points_local, compiled.vertices, compiled.faces, self.corner_db, self.face_tex,
                    self.corner_uv, self.tex, self.tex_off, self.tex_h, self.tex_w, weight)
