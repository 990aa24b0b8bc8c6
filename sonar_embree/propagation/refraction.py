"""Side-scan fans in a sound-speed profile: curved rays, chord by chord through the caster (docs/physics.md §12).

The block's rays are placed as for straight rays (:func:`~sonar_embree.propagation.fan.elevation_rows`),
from probes that are themselves curved rays (their apparent ranges c·T set the density, so rays
follow the record's range where refraction stretches or folds it), launched with the fan's
directions, and marched along their closed-form arcs (:mod:`sonar_embree.kernels.refraction`): each round
casts every live ray's next chord as one Embree segment; rays that hit stop, the others
move on until their one-way time passes the window. The echo of a hit carries the travel
time and path length of its arc, the ray tube's spreading A_Ω of the stratified ray map and
the launch direction's beam gain; the law and maps apply as for straight rays.

Labels assume straight rays and are refused with a profile
(:func:`~sonar_embree.checks.check_profile`); the speckle lattice takes the echoes' times for its envelopes and straight distances for its
phases (its statistics, not its exact pattern, hold in a profile).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import checks, kernels
from ..kernels.args import ArcWeighting, EchoOut, Fan, Poses, scene_arrays
from .aim import AimedEchoes, drop_aimed, keep_own, lattice_rays
from .buffers import Buffers
from .echoes import Echoes
from .gain import weigh_by_beam
from .fan import (BlockEchoes, FanPlan, drop_lines, elevation_rows, moving_lines, nadir_altitude,
                  probe_lines, rays_per_ping)
from ..laws import apply_laws

#: A chord stands off its arc by at most this many of the sonar's range bins (its hits are moved onto the arc;
#: the sagitta only decides which rays graze an edge).
SAGITTA_FRACTION = 1.0
#: Chords start this far (m) outside the scene's height range: a chord never starts on a surface.
BOX_MARGIN_M = 0.5
#: Rounds of chords after which marching stops with an error (a ray that never leaves the window).
MAX_ROUNDS = 100_000


@dataclass(frozen=True, eq=False)
class Marching:
    """What a block's curved rays need in every kernel: the profile in the scene's frame and the limits.

    Attributes
    ----------
    layers : (k, 3) float64
        :meth:`SoundSpeedProfile.layers`.
    z0 : float
        Local z of the profile's depth 0, m.
    box_z : (2,) float64
        Local z range where chords are cast: the scene's, widened by :data:`BOX_MARGIN_M`.
    sagitta_m : float
        Largest distance of a chord from its arc, m.
    t_max : float
        One-way time of the window's end, s.
    """

    layers: np.ndarray
    z0: float
    box_z: np.ndarray
    sagitta_m: float
    t_max: float

    @classmethod
    def of(cls, caster, environment, sagitta_m: float, t_max: float) -> "Marching":
        c = caster.compiled
        return cls(environment.sound_speed.layers(), environment.profile_origin_z_m() - float(c.origin_m[2]),
                   c.bounds_local[:, 2] + np.array([-BOX_MARGIN_M, BOX_MARGIN_M]), sagitta_m, t_max)

    @property
    def l_max(self) -> float:
        """Path length after which no ray can arrive within the window, m (t_max × the fastest c)."""
        return self.t_max * float(self.layers[:, 1].max())

    def launch(self, s, beta, el_start, rot, pos_local, buffers):
        """(state, lay, ray) of a fan's rays (:func:`~sonar_embree.kernels.refraction.arc_start`), in ``buffers``."""
        n = s.shape[0] * int(el_start[-1])
        state, lay = buffers.take("state", (n, kernels.STATE_WIDTH)), buffers.take("lay", n, np.int64)
        ray = buffers.take("ray", (n, kernels.RAY_WIDTH))
        kernels.arc_start(s, np.cos(beta), np.sin(beta), el_start, rot, pos_local, self.layers, self.z0, self.box_z,
                          self.l_max, state, lay, ray, kernels.NO_LAYOUT)
        return state, lay, ray


def march(caster, m: Marching, state, lay, ray, clock, buffers: Buffers):
    """Follow every ray chord by chord until it hits or its path could no longer arrive before ``m.t_max``.

    Returns (hit_prim, hit, hit_len) of the block (:func:`~sonar_embree.kernels.refraction.arc_land`, then ``arc_advance``; hit_len inf
    where nothing was hit).

    Chords are cast only within ``m.box_z``; outside it rays move in closed form.
    """
    c = caster.compiled
    l_max = m.l_max
    n = state.shape[0]
    hit_prim = np.full(n, -1, dtype=np.int32)
    hit_len = np.full(n, np.inf, dtype=np.float32)
    hit = buffers.take("hit", (n, kernels.HIT_WIDTH))  # read only where hit_prim ≥ 0
    idx = np.arange(n, dtype=np.int64)
    for _ in range(MAX_ROUNDS):
        if idx.size == 0:
            return hit_prim, hit, hit_len
        k = idx.size
        nxt, nlay = buffers.take("nxt", (k, kernels.STATE_WIDTH)), buffers.take("nlay", k, np.int64)
        org, dirs = buffers.take("org", (k, 3), np.float32), buffers.take("dirs", (k, 3), np.float32)
        seg, live = buffers.take("seg", k, np.float32), buffers.take("live", k, np.bool_)
        kernels.arc_chord(idx, state, lay, ray, m.layers, m.z0, m.box_z, m.sagitta_m, l_max, nxt, nlay, org, dirs,
                          seg)
        t = time.perf_counter()
        prim, tfar = caster.cast_segments(org, dirs, seg)
        clock["embree"] = clock.get("embree", 0.0) + time.perf_counter() - t
        kernels.arc_land(idx, prim, tfar, state, lay, ray, nxt, m.layers, m.z0, c.vertices, c.faces, c.face_normals,
                         hit_prim, hit, hit_len)
        kernels.arc_advance(idx, prim, state, lay, nxt, nlay, l_max, live)   # the missed rays on, after the hits
        idx = idx[live]
    raise RuntimeError(f"curved rays still in flight after {MAX_ROUNDS} chords")  # pragma: no cover


def _probe_ranges(caster, plan, rot, pos_local, m: Marching, c_nom, clock, buffers):
    """Apparent range c·T (NaN: nothing in the window) of the curved probes, (rows, lines·m) as for straight ones."""
    rows, n_beta = 2 * rot.shape[0], plan.probe_beta.shape[0]
    lines = probe_lines(plan.edge_s, plan.ds)
    el = np.arange(rows + 1, dtype=np.int64) * n_beta
    state, lay, ray = m.launch(lines, np.tile(plan.probe_beta, rows), el, rot, pos_local, buffers)
    hit_prim, hit, _ = march(caster, m, state, lay, ray, clock, buffers)
    out = np.full(state.shape[0], np.nan)
    lit = np.flatnonzero(hit_prim >= 0)   # ``hit`` holds nothing for the other rays
    out[lit] = np.where(hit[lit, 6] <= m.t_max, c_nom * hit[lit, 6], np.nan)
    return out.reshape(rows, -1)


def cast_refracted(run, plan: FanPlan, rot, pos_local, environment, two_way_np_per_m: float, max_range_m: float,
                   sonar, want_points: bool, clock: dict, buffers: Buffers | None = None,
                   rx_shift: np.ndarray | None = None, aim=None, keep_arrival: bool = False) -> BlockEchoes:
    """:func:`~sonar_embree.propagation.fan.cast_block` for curved rays in ``environment.sound_speed``.

    Parameters
    ----------
    run : PreparedRun
        The run's caster and laws (:class:`~sonar_embree.propagation.prepared.PreparedRun`).
    plan, rot, pos_local, two_way_np_per_m, max_range_m
        As for :func:`~sonar_embree.propagation.fan.cast_block`.
    environment : Environment
        With a non-uniform profile.
    sonar : Sonar
        Its sound speed sets the range axis (apparent range c·T), its range bin the chord length.
    want_points : bool
        Also return the hit points.
    clock : dict
        Seconds spent are added under ``"embree"`` and ``"rays"``.
    buffers : Buffers, optional
        Working arrays to reuse (a front end keeps one).
    rx_shift : (pings,) float64, optional
        Motion during the ping, δ = 2·v_fwd/c per ping (:func:`~sonar_embree.propagation.fan.cast_block`); None:
        stop-and-hop.
    aim : AimPlan, optional
        The objects to aim curved rays at (:mod:`sonar_embree.propagation.aim`, its cones widened by the rays' bending);
        None: the fan alone.
    keep_arrival : bool
        Keep each hit's incident direction (``BlockEchoes.arrival``, for the surface's paths).
    """
    buffers = Buffers() if buffers is None else buffers
    rx_shift = np.zeros(rot.shape[0]) if rx_shift is None else np.ascontiguousarray(rx_shift, dtype=np.float64)
    plan, keep = moving_lines(plan, rx_shift)
    t0, before = time.perf_counter(), clock.get("embree", 0.0)
    c_nom, caster = sonar.sound_speed_m_s, run.caster
    max_range_m = max_range_m * (1.0 + 1e-3) + 0.05
    pos_local = np.ascontiguousarray(pos_local, dtype=np.float64)
    rot = np.ascontiguousarray(rot, dtype=np.float64)
    m = Marching.of(caster, environment, SAGITTA_FRACTION * sonar.range_bin_m, max_range_m / c_nom)
    el_start, beta, dbeta = elevation_rows(plan, _probe_ranges(caster, plan, rot, pos_local, m, c_nom, clock, buffers))
    altitude, t_nadir = nadir_altitude(caster, pos_local, max_range_m)  # straight down is straight in any profile
    clock["embree"] = clock.get("embree", 0.0) + t_nadir
    n_az = plan.s.shape[0]
    n = n_az * int(el_start[-1])
    checks.check_rays_memory(n, rot.shape[0], "the curved-ray fan")
    cos_b, sin_b = np.cos(beta), np.sin(beta)
    state, lay, ray = m.launch(plan.s, beta, el_start, rot, pos_local, buffers)
    hit_prim, hit, tfar = march(caster, m, state, lay, ray, clock, buffers)
    arrival = np.ascontiguousarray(hit[:, 3:6]) if keep_arrival else None   # a copy: ``hit`` is a reused buffer
    if keep is not None:
        drop_lines(hit_prim, plan.s, keep, el_start)
    c = caster.compiled
    rng, t_s, ext, w, cos_i = (np.empty(n) for _ in range(5))
    pts = np.empty((n, 3) if want_points or c.needs_points else (0, 3))
    fan = Fan(plan.s, plan.ds, cos_b, sin_b, dbeta, el_start)
    kernels.arc_echoes(fan, Poses(rot, pos_local, rx_shift), hit_prim, hit, ray, scene_arrays(c),
                       ArcWeighting(plan.tilt_rad, two_way_np_per_m, plan.min_range_m, m.t_max,
                                    plan.slope_cap_m_rad, c_nom),
                       EchoOut(rng, t_s, ext, w, cos_i, pts), kernels.NO_LAYOUT)
    weigh_by_beam(plan.pattern, plan.tilt_rad, fan, rx_shift, w)       # the gain of each ray's launch direction
    apply_laws(run.law_table, c, hit_prim, cos_i, w, pts)
    if not plan.footprint:
        ext[:] = 0.0
    n_rays = rays_per_ping(plan, keep, el_start)
    aimed, kept = None, None
    if aim is not None:
        aimed = _aimed(run, aim, plan, rot, pos_local, rx_shift, m, two_way_np_per_m, max_range_m, sonar,
                       want_points, clock, buffers)
        if aimed.aimed.any():
            kept = drop_aimed(caster, aim, n_az * el_start, hit_prim, w, aimed.aimed)
            n_rays = n_rays + aimed.n_rays
        else:
            aimed = None
    clock["rays"] = clock.get("rays", 0.0) + time.perf_counter() - t0 - (clock["embree"] - before)
    return BlockEchoes(n_az * el_start, rng, t_s, ext, w, pts, altitude, n_rays, el_start, beta, dbeta, hit_prim, tfar,
                       aimed, kept, plan, arrival)


def _aimed(run, aim, plan, rot, pos_local, rx_shift, m: Marching, two_way_np_per_m, max_range_m, sonar,
           want_points, clock, buffers) -> AimedEchoes:
    """The curved rays aimed at objects (docs/physics.md §7b, §12): each lattice's rays launched and marched as the
    fan's, weighted by :func:`kernels.arc_echoes` with each ray's own cell; only hits on the aimed object count."""
    n_p, k = rot.shape[0], aim.objects.size
    table, start, counts, _, _, layout = lattice_rays(aim, rot, pos_local, rx_shift, max_range_m)
    ray_start = np.ascontiguousarray(start[::k])
    before = clock.get("embree", 0.0)
    t_s, ext, w, pts, hit_prim, cos_i = layout_echoes(run, layout, ray_start, plan, rot, pos_local, rx_shift, m,
                                                      two_way_np_per_m, sonar, want_points, clock, buffers)
    weigh_by_beam(plan.pattern, plan.tilt_rad, Fan(plan.s, plan.ds, np.zeros(0), np.zeros(0), np.zeros(0), ray_start),
                  rx_shift, w, layout)
    obj = keep_own(run.compiled, aim, counts, hit_prim, w, t_s, cos_i)
    echoes = Echoes(2, ray_start, t_s, ext, w, pts, obj)
    return AimedEchoes(echoes, layout, hit_prim, counts > 0, counts.reshape(n_p, -1).sum(axis=1),
                       clock.get("embree", 0.0) - before)


def layout_echoes(run, layout, ray_start, plan, rot, pos_local, rx_shift, m: Marching, two_way_np_per_m, sonar,
                  want_points, clock, buffers):
    """Curved rays with each ray's own cell, launched, marched and weighted as the fan's (the laws applied).

    Parameters
    ----------
    layout : (n, 5) float64
        Each ray's s, cos β, sin β, dβ and ds (its direction (s, ±√(1 − s²)·cos β, √(1 − s²)·sin β) in the body
        frame of its row's ping, its solid angle ds·dβ); row r (2·ping + side) owns ``ray_start[r] …
        ray_start[r + 1] − 1``.
    run : PreparedRun
        The run's caster and laws.
    plan : FanPlan
        Its baffle (:attr:`~sonar_embree.propagation.fan.FanPlan.tilt_rad`: the rays are weighed with unit gain,
        the caller applies its beam), near-field bound, slope cap and footprint setting.
    rot, pos_local, rx_shift, m, two_way_np_per_m, sonar, want_points, clock, buffers
        As for :func:`cast_refracted` (``m`` the block's :class:`Marching`).

    Returns
    -------
    time_s, extent_s, weight : (n,) float64; points : (n, 3) or (0, 3) float64; prim : (n,) int32; cos_i : (n,)
    """
    n = layout.shape[0]
    state, lay = buffers.take("state", (n, kernels.STATE_WIDTH)), buffers.take("lay", n, np.int64)
    ray = buffers.take("ray", (n, kernels.RAY_WIDTH))
    none = np.zeros(0)
    kernels.arc_start(plan.s, none, none, ray_start, rot, pos_local, m.layers, m.z0, m.box_z, m.l_max, state, lay,
                      ray, layout)
    hit_prim, hit, _ = march(run.caster, m, state, lay, ray, clock, buffers)
    c = run.compiled
    rng, t_s, ext, w, cos_i = (np.empty(n) for _ in range(5))
    pts = np.empty((n, 3) if want_points or c.needs_points else (0, 3))
    kernels.arc_echoes(Fan(plan.s, plan.ds, none, none, none, ray_start), Poses(rot, pos_local, rx_shift), hit_prim,
                       hit, ray, scene_arrays(c), ArcWeighting(plan.tilt_rad, two_way_np_per_m, plan.min_range_m,
                                                               m.t_max, plan.slope_cap_m_rad, sonar.sound_speed_m_s),
                       EchoOut(rng, t_s, ext, w, cos_i, pts), layout)
    apply_laws(run.law_table, c, hit_prim, cos_i, w, pts)
    if not plan.footprint:
        ext[:] = 0.0
    return t_s, ext, w, pts, hit_prim, cos_i
