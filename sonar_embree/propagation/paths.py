"""Path models: which acoustic paths a block of pings takes, chosen once per run from the medium (issue 51, item 1).

A front end casts its fan along one **direct model** (straight rays, :class:`Direct`, or curved rays in a
sound-speed profile, :class:`Refracted`) and adds the paths of each **surface model** the medium has: the flat
surface's image paths (:class:`FlatSurface`, docs/physics.md §13), the same over a profile
(:class:`RefractedFlatSurface`, §12b), a swell's meshed bounces (:class:`Swell`, §13b), the same over a profile
(:class:`RefractedSwell`, §13c) and the surface's own backscatter (:class:`SurfaceLine`).
:func:`path_models` is the one place that picks them; the front end composes what it gets, so a new path is one
class here and one line there. Each surface model returns its contributions tagged with their path (0 direct,
1 one bounce, 2 two bounces) and the echoes of the rays aimed at objects along its paths; the kernels they call are
today's (multipath, swell, curved_surface), so the records are the same bits as before the models existed.
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from . import curved_surface, curved_swell, multipath, refraction, swell
from .echoes import Echoes
from .fan import BlockEchoes, cast_block


class Contribution(NamedTuple):
    """A path's echoes in a block: ``echoes`` (Echoes), ``layout`` (the el_start of the fan they are aligned with,
    or None), ``path`` (0 direct, 1 one bounce, 2 two bounces) and, for echoes not aligned with a fan, each echo's
    azimuth line (``lines``, (n,) int64; None: not needed)."""

    echoes: Echoes
    layout: np.ndarray | None
    path: int
    lines: np.ndarray | None = None


class GlintRays(NamedTuple):
    """The rays aimed at objects through a swell, as a front end regroups their echoes: each echo's ``layout`` row
    (s, cos β, sin β, dβ, ds)."""

    layout: np.ndarray


class AimedContribution(NamedTuple):
    """The echoes of the rays aimed at objects along one path: ``echoes`` (None: the aimed rays' own), ``rays``
    (:class:`~sonar_embree.propagation.aim.AimedEchoes`) and ``path``."""

    echoes: Echoes | None
    rays: object
    path: int


def echoes_of(blk: BlockEchoes, face_object: np.ndarray | None = None) -> Echoes:
    """The echo contract of a fan's block (travel times 2R/c of straight rays, made by the fan's kernel); with
    ``face_object``, each echo's object id (−1 where unlit)."""
    ids = np.zeros(0, dtype=np.int32)
    if face_object is not None:
        ids = np.where((blk.prim >= 0) & (blk.weight > 0), face_object[np.maximum(blk.prim, 0)], -1).astype(np.int32)
    return Echoes(2, blk.ray_start, blk.time_s, blk.extent_s, blk.echo_weight, blk.point_m, ids)


@dataclasses.dataclass(frozen=True)
class Direct:
    """Straight rays from the sonar (:func:`~sonar_embree.propagation.fan.cast_block`)."""

    def cast(self, front, run, rot, pos_local, max_range_m, want_points, clock, rx_shift,
             surface: bool) -> BlockEchoes:
        """The block's fan (its points kept when ``want_points`` or a ``surface`` needs them)."""
        s = front.sonar
        return cast_block(run.caster, front.plan, rot, pos_local, front.two_way_np_per_m, max_range_m,
                          2.0 / s.sound_speed_m_s, want_points=want_points or surface, timings=clock,
                          laws=run.law_table, rx_shift=rx_shift, aim=run.aim)

    def rings(self, front, run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift):
        """An echo sounder's rings as straight rays (its front end's ``_straight``)."""
        return front._straight(run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift)


@dataclasses.dataclass(frozen=True)
class Refracted:
    """Curved rays through the medium's sound-speed profile (:func:`~sonar_embree.propagation.refraction.cast_refracted`;
    under a surface their arrival directions are kept for its paths)."""

    def cast(self, front, run, rot, pos_local, max_range_m, want_points, clock, rx_shift,
             surface: bool) -> BlockEchoes:
        s = front.sonar
        return refraction.cast_refracted(run, front.plan, rot, pos_local, s.environment, front.two_way_np_per_m,
                                         max_range_m, s, want_points or surface, clock, front.buffers, rx_shift,
                                         run.aim, keep_arrival=surface)

    def rings(self, front, run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift):
        """An echo sounder's rings as curved rays (its front end's ``_curved``)."""
        return front._curved(run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift)


def _surface_z_local(front, run) -> float:
    return front.sonar.environment.surface.z_m - float(run.compiled.origin_m[2])


@dataclasses.dataclass(frozen=True)
class FlatSurface:
    """A flat sea surface by the image method: the one-bounce (mixed) and two-bounce (image) paths, and the rays
    aimed at objects along both (docs/physics.md §13)."""

    def contributions(self, front, run, blk, direct, rot, pos_local, max_range_m, ids, want_points, clock,
                      rx_shift):
        z_s = _surface_z_local(front, run)
        image, iblk = multipath.image_echoes(front, run, rot, pos_local, z_s, max_range_m, clock, rx_shift,
                                             aim=run.aim)
        mixed = multipath.mixed_echoes(front, run, blk, rot, pos_local, z_s, rx_shift)
        if ids is not None:  # a one-bounce echo stands for its direct echo's point, a two-bounce one for its hit
            mixed = dataclasses.replace(mixed, object_id=direct.object_id)
            image = dataclasses.replace(image, object_id=echoes_of(iblk, ids).object_id)
        aimed = []
        if blk.aimed is not None:
            aimed.append(AimedContribution(
                multipath.mixed_aimed_echoes(front, run, blk.aimed, rot, pos_local, z_s, rx_shift), blk.aimed, 1))
        if iblk.aimed is not None:
            aimed.append(AimedContribution(multipath.image_aimed_echoes(front, run, iblk, rot, pos_local, z_s),
                                           iblk.aimed, 2))
        return [Contribution(mixed, blk.el_start, 1), Contribution(image, iblk.el_start, 2)], aimed


@dataclasses.dataclass(frozen=True)
class RefractedFlatSurface:
    """A flat surface over a sound-speed profile: the unfolded profile's image rays (docs/physics.md §12b)."""

    def contributions(self, front, run, blk, direct, rot, pos_local, max_range_m, ids, want_points, clock,
                      rx_shift):
        z_s = _surface_z_local(front, run)
        image, iblk = curved_surface.image_echoes(front, run, rot, pos_local, z_s, max_range_m, clock, rx_shift)
        mixed = curved_surface.mixed_echoes(front, run, blk, rot, pos_local, z_s, rx_shift)
        return [Contribution(mixed, blk.el_start, 1), Contribution(image, iblk.el_start, 2)], []


@dataclasses.dataclass(frozen=True)
class Swell:
    """A swell's meshed surface: one Embree reflection per ray, the rays aimed at objects through it (its glints)
    on their own paths (docs/physics.md §13b)."""

    def contributions(self, front, run, blk, direct, rot, pos_local, max_range_m, ids, want_points, clock,
                      rx_shift):
        mixed, image, glints, lines = swell.swell_echoes(front, run, rot, pos_local, max_range_m, ids, clock, rx_shift)
        return ([Contribution(mixed, None, 1, lines), Contribution(image, None, 2, lines)],  # the swell's own up rays
                [AimedContribution(e, GlintRays(layout), path) for e, layout, path in glints])


@dataclasses.dataclass(frozen=True)
class RefractedSwell:
    """A swell over a sound-speed profile: each ray climbs the profile, is mirrored in its facet and marched down
    through the scene (:mod:`~sonar_embree.propagation.curved_swell`, docs/physics.md §13c); the rays aimed at objects
    give their direct path only."""

    def contributions(self, front, run, blk, direct, rot, pos_local, max_range_m, ids, want_points, clock,
                      rx_shift):
        mixed, image, lines = curved_swell.swell_echoes(front, run, rot, pos_local, max_range_m, ids, clock, rx_shift)
        return [Contribution(mixed, None, 1, lines), Contribution(image, None, 2, lines)], []


@dataclasses.dataclass(frozen=True)
class SurfaceLine:
    """The sea surface's own backscatter, a direct path (:func:`~sonar_embree.propagation.multipath.surface_line`)."""

    def contributions(self, front, run, blk, direct, rot, pos_local, max_range_m, ids, want_points, clock,
                      rx_shift):
        line, lblk = multipath.surface_line(front, run, rot, pos_local, max_range_m, want_points, ids is not None,
                                            clock, rx_shift)
        return [Contribution(line, lblk.el_start, 0)], []


def path_models(environment) -> tuple:
    """(direct model, surface models) the medium ``environment`` makes: straight or curved rays, and a flat
    surface's image paths (over a profile: its unfolded rays), a swell's bounces and the surface line, in the
    order their echoes are kept."""
    direct = Refracted() if environment.refracts else Direct()
    surface = environment.surface
    if surface is None:
        return direct, ()
    if environment.refracts:
        bounce = RefractedFlatSurface() if surface.is_flat else RefractedSwell()
    else:
        bounce = FlatSurface() if surface.is_flat else Swell()
    return direct, (bounce,) + ((SurfaceLine(),) if surface.backscatter is not None else ())


def tags(parts) -> tuple | None:
    """The path tag of each part for :class:`~sonar_embree.propagation.multipath.PathEchoes`: None where each part's
    tag is its index (direct, one bounce, two bounces)."""
    paths = tuple(p.path for p in parts)
    return None if paths == tuple(range(len(paths))) else paths
