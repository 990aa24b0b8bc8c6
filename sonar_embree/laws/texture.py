"""Non-Rayleigh texture: a frozen Gamma modulation of the backscatter (docs/physics.md §10).

The intensity of a textured surface is I = G·E, E the exponential (Rayleigh) speckle
and G ~ Gamma(shape ν, mean 1) frozen to the surface, so that I is K-distributed with
scintillation index SI = E[I²]/E[I]² − 1 = 1 + 2/ν when the texture's correlation
length L spans many resolution cells; ν → ∞ is Rayleigh (E. Jakeman and P. N. Pusey,
"A model for non-Rayleigh sea echo", IEEE Trans. Antennas Propag. 24, 806–814, 1976;
D. A. Abraham and A. P. Lyons, "Novel physical interpretations of K-distributed
reverberation", IEEE J. Ocean. Eng. 27, 800–813, 2002, who report ν from below 1 on
patchy or rocky floors to tens on uniform sand).

G is built as a Gaussian copula: standard normal values hashed from a world-fixed cubic
lattice of spacing L (so the same seed gives the same texture in any run, block or
thread), interpolated trilinearly and renormalised to unit variance, then mapped
through Φ and the Gamma quantile function, so every point's G is exactly Gamma(ν, 1/ν).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..kernels import njit, prange

#: The copula's lookup table: z from −Z_MAX to Z_MAX in Z_POINTS steps.
Z_MAX, Z_POINTS = 8.5, 8193


@dataclass(frozen=True)
class KTexture:
    """A K-distribution texture: Gamma(ν) modulation with correlation length L, frozen to the surface.

    Parameters
    ----------
    shape : float
        ν > 0 (smaller: patchier, heavier tails; 1: exponential G); ``math.inf`` is no
        texture (Rayleigh, today's bits).
    correlation_m : float
        L, the lattice spacing of the underlying Gaussian field, m (> 0).
    seed : int
        The texture's seed (the same seed gives the same field in world coordinates).
    """

    shape: float = 3.0
    correlation_m: float = 5.0
    seed: int = 0

    def __post_init__(self):
        for name, top in (("shape", math.inf), ("correlation_m", math.inf)):
            v = getattr(self, name)
            ok = not isinstance(v, bool) and isinstance(v, (int, float)) and 0 < v and (v < top or name == "shape")
            if not ok or math.isnan(v):
                raise ConfigError(f"KTexture.{name} must be a number > 0{' (or inf)' if name == 'shape' else ''}, "
                                  f"got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"KTexture.seed must be an integer >= 0, got {self.seed!r}")

    @property
    def scintillation_index(self) -> float:
        """SI = 1 + 2/ν of the K-distributed intensity (L ≫ resolution cell)."""
        return 1.0 + 2.0 / self.shape

    def quantile_table(self) -> np.ndarray:
        """(Z_POINTS,) G at z = −Z_MAX … Z_MAX: the Gamma(ν, mean 1) quantile of Φ(z)."""
        from scipy.special import gammainccinv, gammaincinv, ndtr

        z = np.linspace(-Z_MAX, Z_MAX, Z_POINTS)
        lower = gammaincinv(self.shape, ndtr(np.minimum(z, 0.0)))
        upper = gammainccinv(self.shape, ndtr(-np.maximum(z, 0.0)))   # Φ(−z) keeps the upper tail's precision
        return np.where(z <= 0.0, lower, upper) / self.shape


@njit(cache=True, nogil=True)
def _mix(h):
    """splitmix64's finaliser (uint64)."""
    h ^= h >> np.uint64(30)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(27)
    h *= np.uint64(0x94D049BB133111EB)
    h ^= h >> np.uint64(31)
    return h


@njit(cache=True, nogil=True)
def lattice_normal(i, j, k, seed):
    """A standard normal value frozen to lattice node (i, j, k) of ``seed`` (Box–Muller on two hashes)."""
    h = _mix(np.uint64(seed) + np.uint64(0x9E3779B97F4A7C15))
    h = _mix(h ^ np.uint64(i & 0xFFFFFFFFFFFF))
    h = _mix(h ^ np.uint64(j & 0xFFFFFFFFFFFF))
    h = _mix(h ^ np.uint64(k & 0xFFFFFFFFFFFF))
    g = _mix(h ^ np.uint64(0xD1B54A32D192ED03))
    u1 = (float(h >> np.uint64(11)) + 0.5) * 2.0 ** -53
    u2 = float(g >> np.uint64(11)) * 2.0 ** -53
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@njit(cache=True, nogil=True)
def gaussian_field(x, y, z, seed):
    """Unit-variance Gaussian field at (x, y, z) in lattice units: trilinear, renormalised."""
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z)
    ix, iy, iz = int(fx), int(fy), int(fz)
    tx, ty, tz = x - fx, y - fy, z - fz
    acc, norm = 0.0, 0.0
    for c in range(8):
        dx, dy, dz = c & 1, (c >> 1) & 1, (c >> 2) & 1
        w = (tx if dx else 1.0 - tx) * (ty if dy else 1.0 - ty) * (tz if dz else 1.0 - tz)
        if w != 0.0:
            acc += w * lattice_normal(ix + dx, iy + dy, iz + dz, seed)
            norm += w * w
    return acc / math.sqrt(norm)


@njit(cache=True, nogil=True, parallel=True)
def texture_weights(prim, points, origin, face_object, tex_index, tex_inv_l, tex_seed, tables, weight):
    """``weight[i] *= G`` at each hit on a textured object.

    Parameters
    ----------
    prim : (n,) int32
        Triangle hit, −1 for none.
    points : (n, 3) float64
        Hit points in the local frame, m.
    origin : (3,) float64
        The local frame's world origin, m (the field is frozen in world coordinates).
    face_object : (f,) int32
    tex_index : (n_objects,) int32
        Row of ``tables`` per object, −1 for untextured.
    tex_inv_l : (n_objects,) float64
        1/L per object, 1/m.
    tex_seed : (n_objects,) int64
    tables : (n_tex, Z_POINTS) float64
        :meth:`KTexture.quantile_table` per texture.
    weight : (n,) float64
        Multiplied in place.
    """
    dz = 2.0 * Z_MAX / (Z_POINTS - 1)
    for i in prange(prim.shape[0]):
        t = prim[i]
        if t < 0 or weight[i] == 0.0:
            continue
        o = face_object[t]
        ti = tex_index[o]
        if ti < 0:
            continue
        s = tex_inv_l[o]
        g = gaussian_field((points[i, 0] + origin[0]) * s, (points[i, 1] + origin[1]) * s,
                           (points[i, 2] + origin[2]) * s, tex_seed[o])
        q = min(max((g + Z_MAX) / dz, 0.0), Z_POINTS - 1.000001)
        j = int(q)
        f = q - j
        weight[i] *= tables[ti, j] + f * (tables[ti, j + 1] - tables[ti, j])


@dataclass(frozen=True, eq=False)
class TextureTable:
    """The scene's textures as :func:`texture_weights` reads them (see its parameters)."""

    tex_index: np.ndarray
    tex_inv_l: np.ndarray
    tex_seed: np.ndarray
    tables: np.ndarray

    @classmethod
    def build(cls, textures) -> "TextureTable | None":
        """From the per-object textures (None or ν = ∞: untextured); None when no object has one."""
        textures = [None if t is None or math.isinf(t.shape) else t for t in textures]
        if all(t is None for t in textures):
            return None
        distinct = list(dict.fromkeys(t for t in textures if t is not None))
        index = np.array([-1 if t is None else distinct.index(t) for t in textures], dtype=np.int32)
        inv_l = np.array([0.0 if t is None else 1.0 / t.correlation_m for t in textures])
        seed = np.array([0 if t is None else t.seed for t in textures], dtype=np.int64)
        return cls(index, inv_l, seed, np.array([t.quantile_table() for t in distinct]))

    def apply(self, compiled, prim, points_local, weight) -> None:
        texture_weights(prim, points_local, compiled.origin_m, compiled.face_object, self.tex_index,
                        self.tex_inv_l, self.tex_seed, self.tables, weight)


__all__ = ["KTexture", "TextureTable"]


@njit(cache=True, nogil=True, parallel=True)
def gaussian_field_at(points, inv_l, seed, out):
    """out[i] = :func:`gaussian_field` at ``points[i]`` (m) × ``inv_l`` (1/m): the unit-variance field."""
    for i in prange(points.shape[0]):
        out[i] = gaussian_field(points[i, 0] * inv_l, points[i, 1] * inv_l, points[i, 2] * inv_l, seed)
