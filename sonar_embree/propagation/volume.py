"""Water-column volume reverberation (docs/physics.md §14b).

A water column of volume backscattering strength Sv (dB re 1 m⁻¹: σ_v = 10^(Sv/10) per m³ and steradian) returns,
to a unit source, from the shell at range r of thickness dr,

    dI = σ_v·Ψ_open(r)·e^(−2α'r)·dr / r²,   Ψ_open(r) = ∫ Γ⁴(u) [the water reaches r along u] dΩ,

Γ the side's one-way pattern (R. J. Urick, *Principles of Underwater Sound*, 3rd ed., 1983, §8.3: the volume
reverberation level SL − 40 log r + Sv + 10 log(cτ/2·Ψ·r²), with Ψ the equivalent two-way beam angle). The water is
bounded below by a level floor at the ping's nadir altitude h and above by the sea surface, when there is one, at
its depth d: a direction u blocks at r·(u·down) > h or r·(u·up) > d. Ψ_open comes from a quadrature of the
pattern over its main lobe and seven side lobes along track (the membrane's substitution of
:mod:`sonar_embree.instrument.directivity`), per ping, turned by its attitude. Per sample of the record, the
expected density ρ(t) = σ_v·Ψ_open(r)·(c/2)·e^(−2α'r)/r² at r = c·t/2 ≥ 1 m is what the back end adds:
- speckle-free: as a continuum of echoes convolved with the unit echo;
- with speckle: as circular Gaussian samples of variance ρ/fs convolved with the pulse's envelope.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


#: Along-track span of the quadrature, in first-null direction cosines λ/lx (Γ⁴ below −50 dB of the axis beyond).
AZIMUTH_NULLS = 8
#: Gauss–Legendre nodes per half side lobe along track.
NODES = 6
#: Midpoints across the side's plane (t from −90° to 90°): the floor's cut is a step in t, integrated to ~1/N_T.
N_T = 1024
#: The shell nearest the sonar the column starts at, m (the far-field formula means nothing closer).
MIN_RANGE_M = 1.0


@dataclass(frozen=True, eq=False)
class VolumeBeam:
    """Quadrature directions of both sides of a side-scan in its body frame: ``dirs`` (2, n, 3) and weights Γ⁴·dΩ
    (2, n), and σ_v (m⁻¹ sr⁻¹)."""

    dirs: np.ndarray
    weights: np.ndarray
    sigma_v: float
    cuts: dict = field(default_factory=dict, repr=False, compare=False)   # per attitude: sorted cosines, weights

    @classmethod
    def of(cls, sonar) -> "VolumeBeam | None":
        """The side-scan ``sonar``'s, or None when its water has no volume backscatter."""
        sv = sonar.environment.volume_backscatter_db
        if sv is None:
            return None
        k = sonar.wavenumber_rad_m
        a, b = 0.5 * k * sonar.length_m, 0.5 * k * sonar.height_m
        u_max = min(1.0, AZIMUTH_NULLS * sonar.wavelength_m / sonar.length_m)
        u, wu = _panels(-u_max, u_max, int(math.ceil(2.0 * a * u_max / math.pi)) + 2)
        t = (np.arange(N_T) + 0.5) * math.pi / N_T - 0.5 * math.pi
        wt = np.full(N_T, math.pi / N_T)
        uu, tt = np.meshgrid(u, t, indexing="ij")
        s = np.sqrt(1.0 - uu * uu)
        v, w = s * np.sin(tt), s * np.cos(tt)                           # along e2 and along the boresight
        gamma = sonar.transducer.one_way(uu.ravel(), v.ravel(), w.ravel())
        weight = gamma ** 4 * np.outer(wu, wt).ravel()
        dirs, d = [], sonar.tilt_rad
        for side in (-1.0, 1.0):
            bore = np.array([0.0, side * math.cos(d), math.sin(d)])
            e2 = np.array([0.0, -side * math.sin(d), math.cos(d)])
            dirs.append(uu.ravel()[:, None] * [1.0, 0.0, 0.0] + v.ravel()[:, None] * e2 + w.ravel()[:, None] * bore)
        return cls(np.stack(dirs), np.stack([weight, weight]), 10.0 ** (sv / 10.0))


def _panels(lo: float, hi: float, n: int):
    x, w = np.polynomial.legendre.leggauss(NODES)
    edges = np.linspace(lo, hi, n + 1)
    half, mid = 0.5 * np.diff(edges), 0.5 * (edges[1:] + edges[:-1])
    return (mid[:, None] + half[:, None] * x).ravel(), (half[:, None] * w).ravel()


def _cut(vb: VolumeBeam, rot: np.ndarray, ch: int):
    """For one attitude and side: the downward cosines (sorted) of the directions that point down with their
    cumulative weights, and likewise the upward ones; kept per attitude (a steady line sorts once)."""
    key = (rot.tobytes(), ch)
    if key not in vb.cuts:
        if len(vb.cuts) > 4096:
            vb.cuts.clear()
        z = vb.dirs[ch] @ rot[2]                                          # world up component of each direction
        parts = []
        for cos in (-z, z):
            keep = cos > 0.0
            order = np.argsort(cos[keep])
            parts.append((cos[keep][order], np.concatenate([[0.0], np.cumsum(vb.weights[ch][keep][order])])))
        vb.cuts[key] = (float(vb.weights[ch].sum()), parts)
    return vb.cuts[key]


def open_angle(vb: VolumeBeam, rot: np.ndarray, altitude_m: float, depth_m: float | None,
               range_m: np.ndarray) -> np.ndarray:
    """(2, n) Ψ_open at slant ranges ``range_m`` (n,) of one ping with body-to-world ``rot`` (3, 3): the pattern's
    weight of the directions along which water reaches each range (floor ``altitude_m`` below, NaN: none; the
    surface ``depth_m`` above, None: none): a direction of downward cosine q is cut beyond h/q."""
    out = np.empty((2, range_m.size))
    with np.errstate(divide="ignore"):
        inv_r = 1.0 / range_m
    for ch in (0, 1):
        total, ((down, cum_down), (up, cum_up)) = _cut(vb, rot, ch)
        psi = np.full(range_m.size, total)
        for bound, cos, cum in ((altitude_m, down, cum_down), (depth_m, up, cum_up)):
            if bound is not None and np.isfinite(bound):
                psi -= cum[-1] - cum[np.searchsorted(cos, bound * inv_r, side="left")]
        out[ch] = psi
    return out


def volume_density(vb: VolumeBeam, sonar, rot, pos_z, altitude_m, n_samples: int) -> np.ndarray:
    """(pings, 2, n_samples) the expected volume-reverberation density ρ(t_n), unit-source intensity per s, of a
    block: ``rot`` (pings, 3, 3), sonar heights ``pos_z`` (pings,) world m, ``altitude_m`` (pings,)."""
    fs, c = sonar.sample_rate_hz, sonar.sound_speed_m_s
    r = 0.5 * c * np.arange(n_samples) / fs
    two_way = 2.0 * sonar.alpha_db_per_m * math.log(10.0) / 10.0
    with np.errstate(divide="ignore"):
        radial = np.where(r >= MIN_RANGE_M, vb.sigma_v * 0.5 * c * np.exp(-two_way * r) / r ** 2, 0.0)
    surf = sonar.environment.surface
    out = np.empty((rot.shape[0], 2, n_samples))
    for b in range(rot.shape[0]):
        depth = None if surf is None else float(surf.z_m - pos_z[b])
        out[b] = open_angle(vb, rot[b], float(altitude_m[b]), depth, r) * radial
    return out


__all__ = ["AZIMUTH_NULLS", "MIN_RANGE_M", "VolumeBeam", "open_angle", "volume_density"]
