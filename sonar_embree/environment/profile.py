"""Sound-speed profiles and their rays: circular arcs in piecewise-linear layers (docs/physics.md §12).

In a layer where c(z) = c_a + g·(z − z_a) (z depth, positive down) Snell's invariant
ξ = cos θ / c(z) (θ the grazing angle) makes every ray a circular arc of radius
1/(ξ|g|). From θ0 to θ1 inside one layer (Jensen, Kuperman, Porter and Schmidt,
*Computational Ocean Acoustics*, 2nd ed., Springer 2011, ch. 3 (ray methods); Medwin and Clay,
*Fundamentals of Acoustical Oceanography*, Academic Press, 1998):

    Δx = |sin θ1 − sin θ0| / (ξ|g|),   Δs = |θ1 − θ0| / (ξ|g|),
    Δt = |ln[(sec θ1 + tan θ1) / (sec θ0 + tan θ0)]| / |g|,

and for g = 0 the straight line: Δx = Δz / tan θ, Δs = Δz / sin θ, Δt = Δs / c.

:meth:`SoundSpeedProfile.trace_down` is this ray map in NumPy (launch angle → range, path
length, travel time at a depth); the renderer marches the same arcs chord by chord through
Embree (:mod:`sonar_embree.propagation.refraction`, :mod:`sonar_embree.kernels.refraction`).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..validation import read_numeric_csv

#: Plausible sea-water sound speeds, m/s (fresh water at 0 °C ≈ 1403, warm deep brine ≈ 1560): a value
#: outside is an error, not a warning, because it is almost certainly a unit or column slip.
SPEED_RANGE_M_S = (1300.0, 1800.0)


@dataclass(frozen=True, eq=False)
class SoundSpeedProfile:
    """c(z) linear between the given depths and held beyond them (a CTD cast).

    Parameters
    ----------
    depth_m : (n,) float
        Depths below the surface, m, strictly increasing, ≥ 0.
    speed_m_s : (n,) float
        Sound speed at each depth, m/s, within :data:`SPEED_RANGE_M_S`.
    surface_z_m : float or None
        World z (up, the trajectory's frame) of depth 0, m. None: the
        :class:`~sonar_embree.environment.SeaSurface`'s ``z_m`` (one of the two is needed
        to place the profile in a scene).
    """

    depth_m: tuple
    speed_m_s: tuple
    surface_z_m: float | None = None

    def __post_init__(self):
        z = np.asarray(self.depth_m, dtype=float).ravel()
        c = np.asarray(self.speed_m_s, dtype=float).ravel()
        if z.size == 0 or z.size != c.size:
            raise ConfigError(f"SoundSpeedProfile: depth_m and speed_m_s need the same number (≥ 1) of values, "
                              f"got {z.size} and {c.size}")
        if not (np.all(np.isfinite(z)) and np.all(np.isfinite(c))):
            raise ConfigError("SoundSpeedProfile: depths and speeds must be finite")
        if z[0] < 0 or np.any(np.diff(z) <= 0):
            raise ConfigError(f"SoundSpeedProfile.depth_m must be ≥ 0 and strictly increasing, got {z.tolist()}")
        lo, hi = SPEED_RANGE_M_S
        bad = c[(c < lo) | (c > hi)]
        if bad.size:
            raise ConfigError(f"SoundSpeedProfile.speed_m_s must lie in {lo:g}–{hi:g} m/s (sea water), got "
                              f"{bad[0]:g}")
        if self.surface_z_m is not None and not np.isfinite(self.surface_z_m):
            raise ConfigError(f"SoundSpeedProfile.surface_z_m must be finite, got {self.surface_z_m!r}")
        object.__setattr__(self, "depth_m", tuple(z.tolist()))
        object.__setattr__(self, "speed_m_s", tuple(c.tolist()))

    @classmethod
    def linear(cls, speed_m_s: float, gradient_per_s: float, depth_m: float = 200.0,
               surface_z_m: float | None = None) -> "SoundSpeedProfile":
        """c(z) = speed + gradient·z (s⁻¹) from the surface to ``depth_m`` (m), held below."""
        return cls((0.0, depth_m), (speed_m_s, speed_m_s + gradient_per_s * depth_m), surface_z_m)

    @classmethod
    def from_csv(cls, path, surface_z_m: float | None = None) -> "SoundSpeedProfile":
        """A profile from a CSV with the header ``depth_m,speed_m_s`` (one row per depth, as a CTD export)."""
        path = os.fspath(path)
        _, vals = read_numeric_csv(path, ("depth_m", "speed_m_s"), what="sound-speed profile")
        z, c = vals.T
        try:
            return cls(tuple(z), tuple(c), surface_z_m)
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None

    def speed_at(self, depth_m):
        """c at ``depth_m`` (any shape), m/s."""
        return np.interp(depth_m, self.depth_m, self.speed_m_s)

    @property
    def is_uniform(self) -> bool:
        """True when c is the same at every depth (straight rays)."""
        return len(set(self.speed_m_s)) == 1

    def layers(self):
        """The profile as the renderer's layer table.

        Returns
        -------
        (k + 2, 3) float64
            Row j: depth of the layer's top (m; −inf for the first), c there (m/s) and the gradient
            dc/d(depth) (s⁻¹) down to the next row's top (+inf after the last); the first and last
            layers hold c constant.
        """
        z = np.asarray(self.depth_m)
        c = np.asarray(self.speed_m_s)
        g = np.diff(c) / np.diff(z) if z.size > 1 else np.zeros(0)
        top = np.concatenate(([-np.inf], z))
        ct = np.concatenate(([c[0]], c))
        gt = np.concatenate(([0.0], g, [0.0]))
        return np.ascontiguousarray(np.stack([top, ct, gt], axis=1))

    def _layers(self, z0: float, z1: float):
        """(top, bottom, c_top, gradient) of the linear pieces between depths z0 < z1."""
        knots = np.array(self.depth_m)
        cuts = np.concatenate(([z0], knots[(knots > z0) & (knots < z1)], [z1]))
        c = self.speed_at(cuts)
        return [(cuts[k], cuts[k + 1], c[k], (c[k + 1] - c[k]) / (cuts[k + 1] - cuts[k]))
                for k in range(cuts.size - 1)]

    def trace_down(self, depth0_m: float, grazing0_rad, depth1_m: float):
        """Rays launched downwards from ``depth0_m`` at grazing angles ``grazing0_rad``, followed to ``depth1_m``.

        Parameters
        ----------
        depth0_m, depth1_m : float
            Start and end depth, m, ``depth1_m > depth0_m``.
        grazing0_rad : (n,) float
            Launch grazing angles below the horizontal, rad, in (0, π/2].

        Returns
        -------
        x_m, s_m, t_s : (n,) float
            Horizontal distance, path length (m) and one-way travel time (s) at ``depth1_m``;
            NaN for rays that turn (cos θ would exceed 1) before reaching it.
        """
        if not depth1_m > depth0_m:
            raise ConfigError(f"trace_down needs depth1_m > depth0_m, got {depth0_m} and {depth1_m}")
        th0 = np.atleast_1d(np.asarray(grazing0_rad, dtype=float))
        xi = np.cos(th0) / self.speed_at(depth0_m)
        x, s, t = np.zeros_like(th0), np.zeros_like(th0), np.zeros_like(th0)
        for top, bottom, c_top, g in self._layers(float(depth0_m), float(depth1_m)):
            ca = np.clip(xi * c_top, -1.0, 1.0)
            cb = xi * (c_top + g * (bottom - top))
            turned = cb >= 1.0
            cb = np.where(turned, np.nan, cb)
            a, b = np.arccos(ca), np.arccos(cb)  # grazing angles at the layer's top and bottom
            dx, ds, dt = _layer_step(a, b, xi, c_top, g, bottom - top)
            x, s, t = x + dx, s + ds, t + dt
        return x, s, t


def _layer_step(a, b, xi, c_top, g, dz):
    """Δx, Δs, Δt across one layer from grazing a (top) to b (bottom); closed-form arcs, straight for g = 0.

    A vertical ray (ξ = 0) has Δx = 0, Δs = Δz and Δt = ln(c_bottom / c_top) / g.
    """
    if abs(g) < 1e-12:
        return dz / np.tan(a), dz / np.sin(a), dz / (np.sin(a) * c_top)
    vertical = xi < 1e-12
    k = np.where(vertical, 1.0, xi * abs(g))
    a_, b_ = np.where(vertical, 0.0, a), np.where(vertical, 0.0, b)
    dx = np.abs(np.sin(b_) - np.sin(a_)) / k
    ds = np.abs(b_ - a_) / k
    dt = np.abs(np.log((1.0 / np.cos(b_) + np.tan(b_)) / (1.0 / np.cos(a_) + np.tan(a_)))) / abs(g)
    c_bottom = c_top + g * dz
    return (np.where(vertical, 0.0, dx), np.where(vertical, dz, ds),
            np.where(vertical, np.log(c_bottom / c_top) / g, dt))
