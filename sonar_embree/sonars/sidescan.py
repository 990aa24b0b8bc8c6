"""The side-scan sonar type: two channels (port, starboard), one rectangular membrane each.

Its body-frame fan and ray budget are :mod:`sonar_embree.propagation.fan` (docs/physics.md §7),
its per-direction gain the baffled membrane of :mod:`sonar_embree.instrument.beam` (§2). It turns
a block of poses into :class:`~sonar_embree.propagation.echoes.Echoes` and, for ground truth,
keeps the block's fan (:class:`~sonar_embree.propagation.fan.BlockEchoes`).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..propagation import multipath, paths
from ..propagation.aim import AimPlan
from ..propagation.buffers import Buffers
from ..config import FanSettings, Sonar
from ..propagation.echoes import Echoes
from ..propagation.fan import FanPlan, along_track
from ..propagation.paths import echoes_of
from ..signal.processing import absorption_np_per_m
from .base import FrontEnd


class SideScanFrontEnd(FrontEnd):
    """Poses → echoes for a :class:`~sonar_embree.config.Sonar` (side-scan)."""

    channels = ("port", "starboard")
    supports_labels = True
    #: Whether rays are aimed at the scene's objects (:mod:`sonar_embree.propagation.aim`) besides the fan's.
    aims = True
    #: Whether speckle spreads the fan's echoes over their along-track strips
    #: (:class:`~sonar_embree.propagation.echoes.AlongTrack`): its rows must
    #: stay the side-scan's (a type that regroups them into lines turns them off).
    strips = True

    def __init__(self, sonar: Sonar, fan: FanSettings, sides=(True, True), elevation_nulls: int = 1):
        self.sonar = sonar
        self.plan = FanPlan.build(sonar, fan, sides, elevation_nulls)  # sides: which of port, starboard get rays
        self.two_way_np_per_m = absorption_np_per_m(sonar.alpha_db_per_m)
        env = sonar.environment
        self.buffers = Buffers() if env.refracts or env.surface is not None else None  # per-block temporaries
        self.direct_path, self.surface_paths = paths.path_models(env)     # the paths this medium makes, once
        self.quality, self.aims = fan.quality, self.aims and fan.aim_objects
        self.array = sonar.receive_array
        if self.array is not None:  # each side's elements are synthesised as channels of their own
            self.n_synth_channels = len(self.channels) * self.array.n_elements

    def receivers(self, rot: np.ndarray, pos_world: np.ndarray) -> np.ndarray | None:
        """The receive elements' world positions per ping, port's then starboard's (None: no array)."""
        return None if self.array is None else self.array.world_positions(rot, pos_world)

    def aim_plan(self, compiled) -> AimPlan | None:
        """The objects of ``compiled`` to aim rays at, None for none (made once per run:
        :func:`~sonar_embree.propagation.prepared.prepare`)."""
        if not self.aims:
            return None
        return AimPlan.build(compiled, self.plan, self.quality, self._curvature())

    def _curvature(self) -> float:
        """The largest curvature of a ray in the medium, 1/m: max |dc/dz| / min c of its profile (0: straight)."""
        env = self.sonar.environment
        if not env.refracts:
            return 0.0
        layers = env.sound_speed.layers()
        return float(np.abs(layers[:, 2]).max() / min(env.sound_speed.speed_m_s))

    def cast(self, run, rot: np.ndarray, pos_local: np.ndarray, max_range_m: float, want_points: bool,
             want_ids: bool, clock: dict, rx_shift: np.ndarray | None = None):
        """Echoes of a block of pings, and the block's fan (for ground truth).

        Parameters
        ----------
        run : PreparedRun
            The run's caster, laws and aim plan (:class:`~sonar_embree.propagation.prepared.PreparedRun`).
        rot : (pings, 3, 3) float64
            Body-to-world rotations.
        pos_local : (pings, 3) float64
            Sonar positions in the scene's local frame, m.
        max_range_m : float
            Farthest slant range searched, m.
        want_points, want_ids : bool
            Fill ``Echoes.point_m`` (speckle) and ``Echoes.object_id`` (ground truth).
        clock : dict
            Timings, as for :func:`~sonar_embree.propagation.fan.cast_block`.
        rx_shift : (pings,) float64, optional
            Motion during the ping (δ = 2·v_fwd/c per ping, :func:`~sonar_embree.propagation.fan.cast_block`) on every
            path.
        """
        blk = self.direct_path.cast(self, run, rot, pos_local, max_range_m, want_points, clock, rx_shift,
                                    bool(self.surface_paths))
        ids = run.compiled.face_object if want_ids else None
        along = along_track(self.plan, rot, rx_shift) if want_points and self.strips else None   # speckle's
        if not self.surface_paths:
            direct = dataclasses.replace(self._rows(echoes_of(blk, ids), blk.el_start), along=along)
            if blk.aimed is None:
                return direct, blk
            return multipath.PathEchoes([direct, self._aimed_rows(blk.aimed)], want_points, None, (0, 0)), blk
        return self._with_surface(run, blk, rot, pos_local, max_range_m, ids, want_points, clock, rx_shift,
                                  along), blk

    def _with_surface(self, run, blk, rot, pos_local, max_range_m, ids, want_points, clock,
                      rx_shift=None, along=None) -> multipath.PathEchoes:
        """The direct echoes of the block and those of each surface path model (:mod:`~sonar_embree.propagation.paths`),
        kept as paths in the same rows (docs/physics.md §13); then the rays aimed at objects, path by path."""
        t0, before = time.perf_counter(), clock.get("embree", 0.0) + clock.get("rays", 0.0)
        direct = echoes_of(blk, ids)
        parts, aimed = [paths.Contribution(direct, blk.el_start, 0)], []
        for model in self.surface_paths:
            more, more_aimed = model.contributions(self, run, blk, direct, rot, pos_local, max_range_m, ids,
                                                   want_points, clock, rx_shift)
            parts, aimed = parts + more, aimed + more_aimed
        if blk.aimed is not None:                     # the rays aimed at objects: their direct echoes too
            aimed.insert(0, paths.AimedContribution(blk.aimed.echoes, blk.aimed, 0))
        rows = [dataclasses.replace(self._rows(p.echoes, p.layout, p.lines), along=along) for p in parts]  # fan lines
        rows += [self._aimed_rows(a.rays, a.echoes) for a in aimed]
        tags = paths.tags(parts + aimed)
        cast = clock.get("embree", 0.0) + clock.get("rays", 0.0) - before  # the fans' casts, counted there
        clock["multipath"] = clock.get("multipath", 0.0) + time.perf_counter() - t0 - cast
        return multipath.PathEchoes(rows, want_points, self.buffers, tags)

    def _aimed_rows(self, aimed, echoes: Echoes | None = None) -> Echoes:
        """The echoes of the rays aimed at objects (:class:`~sonar_embree.propagation.aim.AimedEchoes`; ``echoes``:
        those of one of their paths, aligned with them) in this type's rows (the side-scan's: as cast)."""
        return aimed.echoes if echoes is None else echoes

    def _rows(self, e: Echoes, el_start, lines=None) -> Echoes:
        """A path's echoes in this type's rows (the side-scan's: two per ping, as cast); ``el_start`` the layout
        of the fan they are aligned with (None: not aligned with one), ``lines`` each echo's azimuth line where it is
        not (not needed here)."""
        return e
