"""A flat sea surface over a sound-speed profile: the surface's paths along curved rays (docs/physics.md §12b).

Rays in a stratified ocean stay in their vertical plane and keep Snell's invariant ξ = cos θ / c (θ the grazing
angle). A flat surface at the profile's depth 0 turns a ray up into a ray down at the same grazing angle, so a
path that meets the surface once is a ray of the *unfolded* profile: the profile mirrored above its depth 0,
c(−d) = c(d), from the image transducer S' at the sonar's depth above the surface. Then, per echo at a point P:

- two bounces (S → surface → P → surface → S): the fan cast from S' through the unfolded profile
  (:func:`image_echoes`), its echoes × |R_s|⁴;
- one bounce (S → P → surface → S and back the other way): each direct echo of the fan with the surface
  eigenray from S' to P (:func:`surface_eigenrays`: ξ found on the closed forms per layer), weighted
  (Γ²(u₁)·Γ²_rx(u₂) + Γ²(u₂)·Γ²_rx(u₁))·|R_s|²·e^(−α'(L₁ + L₂))·ds·dβ / (A₂·cos θi) × σ(θi, θs, φ), at
  T₁ + T₂ (:func:`mixed_echoes`).

A₂ = (x/ξ)·(∂x/∂ξ)·sin θ₀·sin θ_P / c_S² is the surface ray's tube area per steradian at P (R² for straight rays),
with x the horizontal distance, θ₀ the launch and θ_P the arrival grazing angle. A surface eigenray that would
turn before P (ξ·c ≥ 1 on its way) is not found: that path is left out. The upward legs are checked for
blocking along their chords (the arcs bend by millimetres over tens of metres). The rays aimed at objects
(docs/physics.md §7b) give the direct path only; the fan's own rays give the objects' surface paths.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .. import kernels
from ..kernels.args import CurvedHits, Launch, Medium, MixedWeighting, Poses
from .gain import weigh_pairs
from ..environment import SoundSpeedProfile
from .buffers import Buffers
from .echoes import Echoes
from .fan import BlockEchoes, ray_cells
from .multipath import apply_bistatic, block_legs, can_block, mirror_pose, wants_azimuth, wave_kh
from .refraction import cast_refracted

#: The unfolded profile's depth 0 lies this far (m) above its mirrored deepest depth.
UNFOLD_MARGIN_M = 1000.0


def unfolded(profile: SoundSpeedProfile, surface_z_m: float) -> SoundSpeedProfile:
    """The profile mirrored about its depth 0 (the surface at world z ``surface_z_m``): depth 0 of the result is
    :data:`UNFOLD_MARGIN_M` above the profile's deepest depth D over the surface, so that c(D' − d) = c(D' + d) = the
    profile's c(d) (D' = D + margin) and every image transducer lies below it."""
    z, c = knots(profile)
    deep = float(z[-1]) + UNFOLD_MARGIN_M
    depth = np.concatenate([deep - z[::-1], deep + z[1:]])
    speed = np.concatenate([c[::-1], c[1:]])
    return SoundSpeedProfile(tuple(depth), tuple(speed), surface_z_m + deep)


def knots(profile: SoundSpeedProfile):
    """The profile as the eigenray kernels read it: knots from depth 0 (m) and the speeds there (m/s); c is held
    above the first depth, so a profile that starts deeper gets a knot at 0."""
    z, c = np.asarray(profile.depth_m, dtype=np.float64), np.asarray(profile.speed_m_s, dtype=np.float64)
    if z[0] > 0.0:
        z, c = np.concatenate([[0.0], z]), np.concatenate([[c[0]], c])
    return np.ascontiguousarray(z), np.ascontiguousarray(c)


@dataclasses.dataclass(frozen=True, eq=False)
class SurfaceRays:
    """Surface eigenrays S → surface → P, one per point (n,) each; NaN time where none was found.

    xi : Snell's invariant ξ, s/m.  time_s, path_m : one-way time (s) and path length (m).
    spread_m2 : A₂, the ray tube's area per steradian at P, m².  x_up_m : horizontal distance from S to where the
    ray meets the surface, m.  sin_src, sin_dst, sin_top : sine of the grazing angle at S, at P and at the surface.
    c_dst : sound speed at P, m/s.
    """

    xi: np.ndarray
    time_s: np.ndarray
    path_m: np.ndarray
    spread_m2: np.ndarray
    x_up_m: np.ndarray
    sin_src: np.ndarray
    sin_dst: np.ndarray
    sin_top: np.ndarray
    c_dst: np.ndarray


def surface_eigenrays(profile: SoundSpeedProfile, d_src, d_dst, x_m) -> SurfaceRays:
    """The rays from depth ``d_src`` up to the surface and down to depth ``d_dst`` that cover the horizontal
    distance ``x_m`` (all (n,), m, depths ≥ 0), without turning on the way (:func:`kernels.surface_eigenrays`)."""
    d_src, d_dst, x_m = (np.ascontiguousarray(a, dtype=np.float64) for a in (d_src, d_dst, x_m))
    out = np.empty((x_m.shape[0], kernels.EIGEN_WIDTH))
    kernels.surface_eigenrays(*knots(profile), d_src, d_dst, x_m, out)
    return SurfaceRays(*(np.ascontiguousarray(out[:, k]) for k in range(kernels.EIGEN_WIDTH)))


def surface_reach(profile: SoundSpeedProfile, xi, d_src) -> np.ndarray:
    """(n,) horizontal distance (m) from depth ``d_src`` up to where rays of invariant ``xi`` meet the surface."""
    out = np.empty(np.shape(xi))
    kernels.surface_reach(*knots(profile), np.ascontiguousarray(xi, dtype=np.float64),
                          np.ascontiguousarray(d_src, dtype=np.float64), out)
    return out


def _environment_unfolded(environment):
    """The medium the image transducer's rays cross: the unfolded profile, no surface."""
    return dataclasses.replace(environment, surface=None,
                               sound_speed=unfolded(environment.sound_speed, environment.profile_origin_z_m()))


def _reflection(front, sin_top: np.ndarray, bounces: int) -> np.ndarray:
    """|R_s|^(2·bounces) = exp(−4·bounces·(k·h_w)²·sin²θg) of a rough surface (1 for a mirror)."""
    kh = wave_kh(front.sonar)
    return np.exp(-4.0 * bounces * kh * kh * sin_top ** 2)


def image_echoes(front, run, rot, pos_local, z_s_local: float, max_range_m: float, clock, rx_shift=None):
    """S → surface → P → surface → S: the fan cast from the image transducer through the unfolded profile, each
    echo × |R_s|⁴ (the grazing angle at the surface from ξ) and its real upward leg S → surface checked along its
    chord. Returns (Echoes aligned with the image fan's rays, its block)."""
    env = front.sonar.environment
    rot_i, pos_i = mirror_pose(rot, pos_local, z_s_local)
    blk = cast_refracted(run, front.plan, rot_i, pos_i, _environment_unfolded(env), front.two_way_np_per_m,
                         max_range_m, front.sonar, True, clock, Buffers(), rx_shift)
    w = blk.echo_weight.copy()
    lit = np.flatnonzero(w > 0)
    body, row, _ = ray_cells(blk.plan.s, blk.el_start, blk.beta, blk.dbeta)
    u = np.einsum("nij,nj->ni", rot_i[row[lit] // 2], body[lit])               # the image ray at S', world
    ping = row[lit] // 2
    prof = env.sound_speed
    d_s = z_s_local - pos_local[ping, 2]
    horiz = np.hypot(u[:, 0], u[:, 1])
    xi = horiz / prof.speed_at(d_s)
    w[lit] *= _reflection(front, np.sqrt(1.0 - (xi * prof.speed_at(0.0)) ** 2), 2)
    h = u[:, :2] / np.maximum(horiz, 1e-300)[:, None]
    _block_upward(run, blk.ray_start, ping, lit, h, surface_reach(prof, xi, d_s), pos_local, z_s_local, w)
    return Echoes(2, blk.ray_start, blk.time_s, blk.extent_s, w, blk.point_m, np.zeros(0, np.int32)), blk


def _block_upward(run, ray_start, ping, lit, h, x_up, pos_local, z_s_local, w, points=None, prim=None):
    """Zero ``w`` (n,) where the chord from the sonar up to the surface point (x_up from it along the horizontal
    unit vectors h, (k, 2), of the lit echoes ``lit``) is blocked, and with ``points`` (n, 3) the chord from each
    point up to it (its own height field passed over, as for straight legs: ``prim``)."""
    top = np.column_stack([pos_local[ping, :2] + h * x_up[:, None], np.full(lit.size, z_s_local)])
    n = w.shape[0]
    starts = [(pos_local[ping], True)] + ([(points[lit], False)] if points is not None else [])
    for start, from_sonar in starts:
        if not can_block(run.caster, from_sonar, pos_local):        # nothing reaches into any such leg
            continue
        leg = top - start
        dist = np.linalg.norm(leg, axis=1)
        dirs, lengths, x = np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3))
        dirs[lit], lengths[lit] = leg / np.maximum(dist, 1e-300)[:, None], dist
        x[lit] = start
        block_legs(run, Buffers(), ray_start, x, pos_local, from_sonar, dirs, lengths, w,
                   None if from_sonar else prim, not from_sonar)


def mixed_echoes(front, run, blk: BlockEchoes, rot, pos_local, z_s_local: float, rx_shift=None) -> Echoes:
    """S → P → surface → S and back the other way, for every direct echo of the curved fan ``blk`` (cast with
    ``keep_arrival``), aligned with its rays: the surface eigenray from S to each hit point P
    (:func:`kernels.curved_mixed`), the beam's gains at both launch directions after it
    (:func:`~sonar_embree.propagation.gain.weigh_pairs`), σ(θi, θs, φ), both upward chords checked (docs/physics.md
    §12b). Every hit of the fan counts, those on objects its rows aim rays at too (the aimed rays give their direct
    echoes only)."""
    c, sonar = run.compiled, front.sonar
    n = blk.weight.shape[0]
    body, row, dbeta = ray_cells(blk.plan.s, blk.el_start, blk.beta, blk.dbeta)
    shift = np.zeros(rot.shape[0]) if rx_shift is None else np.asarray(rx_shift, dtype=np.float64)
    rot = np.ascontiguousarray(rot, dtype=np.float64)
    kh = wave_kh(sonar)
    want_phi = wants_azimuth(c)
    out = np.empty((n, kernels.MIX_WIDTH))
    kernels.curved_mixed(CurvedHits(blk.point_m, blk.prim, blk.arrival, blk.tfar, blk.time_s, blk.extent_s,
                                    (blk.prim >= 0) & (blk.weight > 0)),
                         Launch(dbeta, row), Poses(rot, pos_local, shift), c.face_normals,
                         Medium(*knots(sonar.environment.sound_speed), float(z_s_local)),
                         MixedWeighting(front.two_way_np_per_m, float(blk.plan.ds), front.plan.min_range_m, kh,
                                        want_phi), out)
    w = np.ascontiguousarray(out[:, kernels.M_W])
    u2 = out[:, kernels.M_U2:kernels.M_U2 + 3]                # the beam after the kernel: u₁ out, u₂ back, and
    weigh_pairs(front.plan.pattern, front.plan.tilt_rad, blk.ray_start, body, u2, rot, shift, w)   # the other way
    apply_bistatic(c, run.laws, blk.prim, blk.point_m, w, np.ascontiguousarray(out[:, kernels.M_COS_I]),
                   np.ascontiguousarray(out[:, kernels.M_COS_S]), out[:, kernels.M_PHI] if want_phi else None)
    lit = np.flatnonzero(w > 0)
    ping = row[lit] // 2
    rel = blk.point_m[lit, :2] - pos_local[ping, :2]
    h = rel / np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-300)[:, None]
    _block_upward(run, blk.ray_start, ping, lit, h, out[lit, kernels.M_XUP], pos_local, z_s_local, w, blk.point_m,
                  blk.prim)
    t = np.where(w > 0, out[:, kernels.M_T], np.inf)
    return Echoes(2, blk.ray_start, t, np.ascontiguousarray(out[:, kernels.M_EXT]), w, blk.point_m,
                  np.zeros(0, np.int32))
