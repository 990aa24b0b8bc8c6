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

from ..propagation import curved_surface, multipath, refraction, swell
from ..propagation.aim import AimPlan
from ..propagation.buffers import Buffers
from ..config import FanSettings, Sonar
from ..propagation.echoes import Echoes
from ..propagation.fan import BlockEchoes, FanPlan, cast_block
from ..signal.processing import absorption_np_per_m
from .base import FrontEnd


class SideScanFrontEnd(FrontEnd):
    """Poses → echoes for a :class:`~sonar_embree.config.Sonar` (side-scan)."""

    channels = ("port", "starboard")
    supports_labels = True
    #: Whether rays are aimed at the scene's objects (:mod:`sonar_embree.propagation.aim`) besides the fan's.
    aims = True

    def __init__(self, sonar: Sonar, fan: FanSettings, sides=(True, True), elevation_nulls: int = 1):
        self.sonar = sonar
        self.plan = FanPlan.build(sonar, fan, sides, elevation_nulls)  # sides: which of port, starboard get rays
        self.two_way_np_per_m = absorption_np_per_m(sonar.alpha_db_per_m)
        env = sonar.environment
        self.buffers = Buffers() if env.refracts or env.surface is not None else None  # per-block temporaries
        self.quality, self.aims = fan.quality, self.aims and fan.aim_objects
        self._aim = (None, None)  # (compiled scene, its AimPlan)
        self.array = sonar.receive_array
        if self.array is not None:  # each side's elements are synthesised as channels of their own
            self.n_synth_channels = len(self.channels) * self.array.n_elements

    def receivers(self, rot: np.ndarray, pos_world: np.ndarray) -> np.ndarray | None:
        """The receive elements' world positions per ping, port's then starboard's (None: no array)."""
        return None if self.array is None else self.array.world_positions(rot, pos_world)

    def aim_plan(self, compiled) -> AimPlan | None:
        """The objects of ``compiled`` to aim rays at (built once per compiled scene); None for none."""
        if not self.aims:
            return None
        if self._aim[0] is not compiled:
            self._aim = (compiled, AimPlan.build(compiled, self.plan, self.quality, self._curvature()))
        return self._aim[1]

    def _curvature(self) -> float:
        """The largest curvature of a ray in the medium, 1/m: max |dc/dz| / min c of its profile (0: straight)."""
        env = self.sonar.environment
        if not env.refracts:
            return 0.0
        layers = env.sound_speed.layers()
        return float(np.abs(layers[:, 2]).max() / min(env.sound_speed.speed_m_s))

    def cast(self, caster, rot: np.ndarray, pos_local: np.ndarray, max_range_m: float, want_points: bool,
             want_ids: bool, clock: dict, rx_shift: np.ndarray | None = None):
        """Echoes of a block of pings, and the block's fan (for ground truth).

        Parameters
        ----------
        caster : Caster
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
        surface = self.sonar.environment.surface
        aim = self.aim_plan(caster.compiled)
        if self.sonar.environment.refracts:  # curved rays (under a flat surface: curved_surface)
            blk = refraction.cast_refracted(caster, self.plan, rot, pos_local, self.sonar.environment,
                                            self.two_way_np_per_m, max_range_m, self.sonar,
                                            want_points or surface is not None, clock, self.buffers, rx_shift, aim,
                                            keep_arrival=surface is not None)
        else:
            blk = cast_block(caster, self.plan, rot, pos_local, self.two_way_np_per_m, max_range_m,
                             2.0 / self.sonar.sound_speed_m_s, want_points=want_points or surface is not None,
                             timings=clock, frequency_hz=self.sonar.frequency_hz, rx_shift=rx_shift, aim=aim)
        ids = caster.compiled.face_object if want_ids else None
        if surface is None:
            direct = self._rows(echoes_of(blk, ids), blk.el_start)
            if blk.aimed is None:
                return direct, blk
            return multipath.PathEchoes([direct, self._aimed_rows(blk.aimed)], want_points, None, (0, 0)), blk
        return self._with_surface(caster, blk, rot, pos_local, max_range_m, ids, want_points, clock, rx_shift), blk

    def _with_surface(self, caster, blk, rot, pos_local, max_range_m, ids, want_points, clock,
                      rx_shift=None) -> multipath.PathEchoes:
        """Direct, one-bounce and two-bounce echoes of the block (and the surface line), kept as paths in the same
        rows (docs/physics.md §13)."""
        t0, before = time.perf_counter(), clock.get("embree", 0.0) + clock.get("rays", 0.0)
        direct = echoes_of(blk, ids)
        aimed = []                           # the rays aimed at objects, path by path: (echoes, their rays, path)
        if self.sonar.environment.refracts:  # a flat surface over a profile: the unfolded profile's rays
            z_s = self.sonar.environment.surface.z_m - float(caster.compiled.origin_m[2])
            image, iblk = curved_surface.image_echoes(self, caster, rot, pos_local, z_s, max_range_m, clock, rx_shift)
            mixed = curved_surface.mixed_echoes(self, caster, blk, rot, pos_local, z_s, rx_shift)
            layouts = [blk.el_start, blk.el_start, iblk.el_start]
        elif not self.sonar.environment.surface.is_flat:  # a swell: one Embree reflection per ray
            mixed, image, glints = swell.swell_echoes(self, caster, rot, pos_local, max_range_m, ids, clock, rx_shift)
            layouts = [blk.el_start, None, None]                      # the swell's paths: its own fan's up rays
            aimed += [(e, None, path) for e, path in glints]          # rays aimed at objects through the swell
        else:
            z_s = self.sonar.environment.surface.z_m - float(caster.compiled.origin_m[2])
            image, iblk = multipath.image_echoes(self, caster, rot, pos_local, z_s, max_range_m, clock, rx_shift,
                                                 aim=self.aim_plan(caster.compiled))
            mixed = multipath.mixed_echoes(self, caster, blk, rot, pos_local, z_s, rx_shift)
            if ids is not None:  # a one-bounce echo stands for its direct echo's point, a two-bounce one for its hit
                mixed = dataclasses.replace(mixed, object_id=direct.object_id)
                image = dataclasses.replace(image, object_id=echoes_of(iblk, ids).object_id)
            layouts = [blk.el_start, blk.el_start, iblk.el_start]
            if blk.aimed is not None:
                aimed.append((multipath.mixed_aimed_echoes(self, caster, blk.aimed, rot, pos_local, z_s, rx_shift),
                              blk.aimed, 1))
            if iblk.aimed is not None:
                aimed.append((multipath.image_aimed_echoes(self, caster, iblk, rot, pos_local, z_s), iblk.aimed, 2))
        parts, paths = [direct, mixed, image], None
        if self.sonar.environment.surface.backscatter is not None:  # the surface line: a direct path
            line, lblk = multipath.surface_line(self, caster, rot, pos_local, max_range_m, want_points,
                                                ids is not None, clock, rx_shift)
            parts, layouts, paths = parts + [line], layouts + [lblk.el_start], (0, 1, 2, 0)
        parts = [self._rows(e, el) for e, el in zip(parts, layouts)]
        if blk.aimed is not None:                     # the rays aimed at objects: their direct echoes too
            aimed.insert(0, (blk.aimed.echoes, blk.aimed, 0))
        for e, rays, path in aimed:
            parts, paths = parts + [self._aimed_rows(rays, e)], (paths or (0, 1, 2)) + (path,)
        cast = clock.get("embree", 0.0) + clock.get("rays", 0.0) - before  # the fans' casts, counted there
        clock["multipath"] = clock.get("multipath", 0.0) + time.perf_counter() - t0 - cast
        return multipath.PathEchoes(parts, want_points, self.buffers, paths)

    def _aimed_rows(self, aimed, echoes: Echoes | None = None) -> Echoes:
        """The echoes of the rays aimed at objects (:class:`~sonar_embree.propagation.aim.AimedEchoes`; ``echoes``:
        those of one of their paths, aligned with them) in this type's rows (the side-scan's: as cast)."""
        return aimed.echoes if echoes is None else echoes

    def _rows(self, e: Echoes, el_start) -> Echoes:
        """A path's echoes in this type's rows (the side-scan's: two per ping, as cast); ``el_start`` the layout
        of the fan they are aligned with (None: not aligned with one)."""
        return e


def echoes_of(blk: BlockEchoes, face_object: np.ndarray | None = None) -> Echoes:
    """The echo contract of a side-scan block (travel times 2R/c of straight rays, made by the fan's kernel)."""
    ids = np.zeros(0, dtype=np.int32)
    if face_object is not None:
        ids = np.where((blk.prim >= 0) & (blk.weight > 0), face_object[np.maximum(blk.prim, 0)], -1).astype(np.int32)
    return Echoes(2, blk.ray_start, blk.time_s, blk.extent_s, blk.echo_weight, blk.point_m, ids)
