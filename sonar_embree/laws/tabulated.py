"""Tabulated backscatter: σ(θg[, f]) from (grazing angle, dB) pairs (docs/physics.md §10).

For curves nobody has a closed form for: the APL-UW model curves (APL-UW TR 9407, *High-
Frequency Ocean Environmental Acoustic Models Handbook*, 1994; D. R. Jackson and M. D.
Richardson, *High-Frequency Seafloor Acoustics*, Springer 2007, ch. 13), or a curve
measured with one's own sonar. The backscatter strength 10·log10 σ is interpolated
linearly in dB between the tabulated grazing angles and held beyond the first and
last; with a frequency axis, linearly in dB between frequencies (held beyond) at the
sonar's carrier, once per run.

A table is monostatic. Its bistatic extension is the reciprocal geometric mean
σ(θi, θs) = √(σ(θi)·σ(θs)), which is exact for Lambert's law and the usual
assumption when only a monostatic curve is known.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..kernels import njit
from ..validation import read_numeric_csv
from .composite import Summable


@njit(cache=True, nogil=True)
def _table_db(data, off, n, g):
    """dB at grazing angle ``g`` (rad) of the table at ``data[off:off + 2n]`` (angles, then dB)."""
    if g <= data[off]:
        return data[off + n]
    if g >= data[off + n - 1]:
        return data[off + 2 * n - 1]
    lo, hi = 0, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if data[off + mid] <= g:
            lo = mid
        else:
            hi = mid
    f = (g - data[off + lo]) / (data[off + hi] - data[off + lo])
    return data[off + n + lo] + f * (data[off + n + hi] - data[off + n + lo])


@njit(cache=True, nogil=True, inline="always")
def tabulated_sigma(params, o, cos_i, data):
    """σ(θg)/cos θi of a table at incidence cos θi on object ``o``, θg = asin(cos θi): ``params[o]``: offset and
    length n of the object's table in ``data`` (n grazing angles in rad, then n values in dB). The scalar σ of
    :func:`sonar_embree.laws.driver.law_weights`."""
    db = _table_db(data, int(params[o, 0]), int(params[o, 1]), math.asin(min(cos_i, 1.0)))
    return 10.0 ** (db / 10.0) / cos_i


def _as_tuple(name, values, ndim):
    arr = np.asarray(values, dtype=float)
    if arr.ndim != ndim or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise ConfigError(f"Tabulated.{name} must be a non-empty {ndim}-d array of finite numbers, got {values!r}")
    return arr


@dataclass(frozen=True)
class Tabulated(Summable):
    """σ(θg) (or σ(θg, f)) from a table of backscatter strengths.

    Parameters
    ----------
    grazing_deg : sequence of float
        Grazing angles θg = 90° − θi in degrees, strictly increasing within [0, 90].
    backscatter_db : sequence of float, or 2-d
        10·log10 σ at those angles, dB re 1 m² per m² per sr; shaped
        (n_frequencies, n_angles) with ``frequency_hz``.
    frequency_hz : sequence of float, optional
        Frequencies of the rows of ``backscatter_db``, Hz, strictly increasing.
    """

    grazing_deg: tuple
    backscatter_db: tuple
    frequency_hz: tuple | None = None

    uses_azimuth = False  # σ depends on θi and θs only

    def __post_init__(self):
        g = _as_tuple("grazing_deg", self.grazing_deg, 1)
        db = _as_tuple("backscatter_db", self.backscatter_db, 1 if self.frequency_hz is None else 2)
        if np.any(np.diff(g) <= 0) or g[0] < 0 or g[-1] > 90:
            raise ConfigError(f"Tabulated.grazing_deg must increase strictly within [0, 90] degrees, got {g.tolist()}")
        if db.shape[-1] != g.size:
            raise ConfigError(f"Tabulated.backscatter_db has {db.shape[-1]} angles, grazing_deg {g.size}")
        if np.any(db > 30) or np.any(db < -300):
            raise ConfigError("Tabulated.backscatter_db must lie within [-300, 30] dB")
        object.__setattr__(self, "grazing_deg", tuple(g.tolist()))
        object.__setattr__(self, "backscatter_db", tuple(map(tuple, db.tolist())) if db.ndim == 2 else
                           tuple(db.tolist()))
        if self.frequency_hz is not None:
            f = _as_tuple("frequency_hz", self.frequency_hz, 1)
            if f.size != db.shape[0] or np.any(np.diff(f) <= 0) or f[0] <= 0:
                raise ConfigError(f"Tabulated.frequency_hz must be {db.shape[0]} increasing frequencies > 0 Hz, "
                                  f"got {f.tolist()}")
            object.__setattr__(self, "frequency_hz", tuple(f.tolist()))

    @classmethod
    def from_csv(cls, path) -> "Tabulated":
        """A table from a CSV file with a header: ``grazing_deg,backscatter_db`` and optionally ``frequency_hz``
        (one row per frequency and angle; every frequency on the same angles)."""
        path = os.fspath(path)
        cols, vals = read_numeric_csv(path, ("grazing_deg", "backscatter_db"), ("frequency_hz",), "backscatter table",
                                      "grazing_deg, backscatter_db [, frequency_hz]")
        try:
            if "frequency_hz" not in cols:
                return cls(tuple(vals[:, 0]), tuple(vals[:, 1]))
            freqs = np.unique(vals[:, 0])
            grid = [vals[vals[:, 0] == f] for f in freqs]
            angles = grid[0][np.argsort(grid[0][:, 1]), 1]
            if any(not np.array_equal(np.sort(g[:, 1]), angles) for g in grid):
                raise ConfigError("every frequency must list the same grazing angles")
            db = [g[np.argsort(g[:, 1]), 2] for g in grid]
            return cls(tuple(angles), np.array(db), tuple(freqs))
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None

    def at_frequency(self, frequency_hz: float) -> "Tabulated":
        """The table at one frequency (linear in dB between tabulated frequencies, held beyond them)."""
        if self.frequency_hz is None:
            return self
        db = np.array(self.backscatter_db)
        row = [np.interp(frequency_hz, self.frequency_hz, db[:, j]) for j in range(db.shape[1])]
        return Tabulated(self.grazing_deg, tuple(row))

    def params(self, data: list | None = None) -> tuple:
        """Kernel parameters: the table's offset and length in ``data`` (which it extends)."""
        if self.frequency_hz is not None:
            raise ConfigError("Tabulated: a table with a frequency axis must be taken at_frequency() first")
        off = len(data)
        data.extend(np.radians(self.grazing_deg).tolist())
        data.extend(self.backscatter_db)
        return (float(off), float(len(self.grazing_deg)))

    def backscatter_strength_db(self, grazing_deg):
        """Monostatic 10·log10 σ at ``grazing_deg`` (interpolated, held beyond the table)."""
        if self.frequency_hz is not None:
            raise ConfigError("Tabulated: a table with a frequency axis must be taken at_frequency() first")
        return np.interp(grazing_deg, self.grazing_deg, self.backscatter_db)

    def sigma(self, cos_i, cos_s, phi_rad=0.0):
        """σ(θi, θs, φ) = √(σ(θi)·σ(θs)) (independent of φ); zero below the surface."""
        cos_i, cos_s = np.asarray(cos_i, dtype=float), np.asarray(cos_s, dtype=float)
        gi = np.degrees(np.arcsin(np.clip(cos_i, 0.0, 1.0)))
        gs = np.degrees(np.arcsin(np.clip(cos_s, 0.0, 1.0)))
        db = 0.5 * (self.backscatter_strength_db(gi) + self.backscatter_strength_db(gs))
        return np.where((cos_i > 0) & (cos_s > 0), 10.0 ** (db / 10.0), 0.0) + 0.0 * np.asarray(phi_rad)


__all__ = ["Tabulated"]
