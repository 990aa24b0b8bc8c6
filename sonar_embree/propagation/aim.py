"""Rays aimed at the objects: every object in the beam is seen, whatever the fan's line spacing (docs/physics.md §7b).

The fan (:mod:`sonar_embree.propagation.fan`) places its rays where the floor needs them; an object narrower than its
azimuth-line spacing is sampled by luck. Each row (ping, side) therefore also aims a lattice of rays at every
object that is not seafloor and can echo inside the range window and the row's span: a uniform grid of cells in
the fan's own coordinates (s, β), whose solid angle is exactly ds·dβ, tiling the part of the object's bounding
cone inside the span, fine enough for ``n_across`` rays across the cone each way, the fan's largest steps and
one ray per wanted range step over the object's depth. The integral of eq. (1) is split exactly by what each
direction hits first: an aimed ray counts only where it hits its own object first, and the fan's rays that hit
an aimed object first count nothing (:func:`kernels.drop_aimed`). The lattice moves with the object in every ping,
so an object's echo changes smoothly from ping to ping. An object too big for ``max_rays`` (or holding the
sonar) is left to the fan, whose probes see it.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .. import checks, kernels
from .echoes import Echoes
from .gain import weigh_by_beam
from ..kernels import aim as K
from ..kernels.args import DirectWeighting, EchoOut, Fan, Poses, scene_arrays
from ..laws import apply_laws

#: Rays across an object's bounding cone, each way, at quality 1 (× √quality): balls of 2–25 cm within 0.3 dB
#: of their closed forms in every ping (16 gave 0.35 dB at four times the rays; docs/benchmarks.md).
RAYS_ACROSS = 8
#: The most rays one object gets in one row at quality 1 (× quality); a bigger object is left to the fan.
MAX_RAYS = 4096
#: Cells across a slender object's width at its far side, at quality 1 (× √quality): a cable, a pipe or a strip
#: thinner than the cone's cells is otherwise hit by one row of cells or none (docs/physics.md §7b). 6 puts 2 cm
#: cables within 0.25 dB and 1 cm strips within 0.7 dB of their quadratures (4: 1.0 dB at half the rays, 8: 0.35
#: dB at 1.7 times them; docs/benchmarks.md).
THIN_ACROSS = 6
#: An object is slender when its box's second extent is under this fraction of its bounding sphere's radius (two of
#: the cone's cells): a cable, a pipe, a strip, a mast.
SLENDER_WIDTH = 0.5
#: The most slices of a slender object's cover: a 1 km cable of 2 cm gets segments of 24 cm, whose projection
#: still bulges out of its corners' box by under a millimetre 20 m away (a cell there is 3 mm).
MAX_SLICES = 4096
#: A slender object may cast this many times :data:`MAX_RAYS` in a row (its covered cells only): a 2 m × 1 cm strip
#: across the beam 13 m out casts up to about 10,000.
SLENDER_RAYS = 8


@dataclass(frozen=True, eq=False)
class AimPlan:
    """The candidates of a compiled scene (objects not seafloor) and the density of their lattices."""

    objects: np.ndarray          # (k,) int32 scene object of each candidate
    centre: np.ndarray           # (k, 3) float64 bounding-sphere centre, local frame, m
    radius: np.ndarray           # (k,) float64 bounding-sphere radius, m
    cand_of_object: np.ndarray   # (n_objects,) int32 candidate of each object, −1 for none
    cell_m: np.ndarray           # (k,) float64 a slender object's largest cell at its far side, m; inf: not slender
    cover: np.ndarray            # (m, 3) float64 slender objects' box slices, 4 corners each, local frame, m
    cover_start: np.ndarray      # (k + 1,) int64 candidate k's cover points
    span: np.ndarray             # (8,) see kernels.aim.aim_lattices
    sides: np.ndarray            # (2,) bool
    n_across: float
    dr_m: float
    max_rays: float

    @classmethod
    def build(cls, compiled, plan, quality: float, kappa: float = 0.0) -> "AimPlan | None":
        """The plan of ``compiled`` for the fan ``plan`` (:class:`~sonar_embree.propagation.fan.FanPlan`), rays of
        curvature up to ``kappa`` (1/m); None when every object is seafloor (nothing to aim at: the fan alone, at no
        cost)."""
        span = (plan.s[0] - 0.5 * plan.ds, plan.s[-1] + 0.5 * plan.ds, plan.probe_beta[0], plan.probe_beta[-1],
                plan.ds, plan.max_step_rad)
        return cls.of(compiled, span, plan.sides, quality, plan.dr_target_m, kappa)

    @classmethod
    def of(cls, compiled, span, sides, quality: float, dr_m: float, kappa: float = 0.0) -> "AimPlan | None":
        """The plan of ``compiled`` for rows whose directions (s, ±√(1 − s²)·cos β, √(1 − s²)·sin β) span
        ``span`` = (s_lo, s_hi, β_lo, β_hi, largest s step, largest β step) on the ``sides`` (port, starboard)
        that have rays, with ``dr_m`` the wanted range step and ``kappa`` the largest curvature of a ray (1/m, a
        sound-speed profile's max |dc/dz|/c; 0: straight rays); None when every object is seafloor."""
        objects = np.flatnonzero(~np.asarray(compiled.is_seafloor)).astype(np.int32)
        if objects.size == 0:
            return None
        faces = np.flatnonzero(~np.asarray(compiled.is_seafloor)[compiled.face_object])   # the objects' own
        centre, radius = bounding_spheres(compiled, faces)
        cand = np.full(len(compiled.labels), -1, dtype=np.int32)
        cand[objects] = np.arange(objects.size, dtype=np.int32)
        s_lo, s_hi, b_lo, b_hi, hs, hb = (float(x) for x in span)
        q = float(quality)
        n_across = float(math.ceil(RAYS_ACROSS * math.sqrt(q)))
        cell_m, cover, cover_start = slender_boxes(compiled, faces, cand, radius[objects],
                                                   math.ceil(THIN_ACROSS * math.sqrt(q)))
        return cls(objects, centre[objects], radius[objects], cand, cell_m, cover, cover_start,
                   np.array([s_lo, s_hi, b_lo, b_hi, 0.0, hs, hb, float(kappa)]),
                   np.asarray(sides, dtype=bool), n_across, float(dr_m), float(MAX_RAYS * max(q, 1.0)))


def bounding_spheres(compiled, faces):
    """((n_objects, 3) centres, (n_objects,) radii) of the objects' bounding spheres: the centre of each object's
    box and the farthest of its vertices from it (m, local frame), over the triangles ``faces`` (others' radius 0)."""
    box = compiled.object_bounds
    centre = 0.5 * (box[:, 0] + box[:, 1])
    obj = np.repeat(compiled.face_object[faces], 3)
    v = compiled.vertices[compiled.faces[faces].ravel()]
    r2 = np.zeros(len(compiled.labels))
    np.maximum.at(r2, obj, ((v - centre[obj]) ** 2).sum(axis=1))
    return centre, np.sqrt(r2) * (1.0 + 1e-9) + 1e-6


def slender_boxes(compiled, faces, cand, radius, thin_across: int):
    """Which candidates are slender, and their cover: (k,) the largest cell at the far side (m; inf: not slender),
    (m, 3) cover points and (k + 1,) their offsets; ``faces`` the candidates' triangles, ``cand`` the candidate of
    each object (−1: none), ``radius`` (k,) their bounding spheres' radii.

    An object's box has the principal axes of its vertices (its extents e₁ ≥ e₂ ≥ e₃ along them); it is slender when
    e₂ is under :data:`SLENDER_WIDTH` of its radius ρ (about two of the cone's cells across it), and its largest cell
    is e₂/``thin_across``; in a row where that is finer than the lattice's own cells, its cells shrink to it
    (:func:`kernels.aim.aim_lattices`). Its cover is the box's cross-section (4 corners) at slices along e₁ no
    farther apart than e₂: each segment is then small against its range (:func:`kernels.aim.cover_cells`)."""
    k = radius.size
    n_v = compiled.vertices.shape[0]
    key = np.unique(np.repeat(cand[compiled.face_object[faces]], 3) * n_v + compiled.faces[faces].ravel())
    k_of, v = key // n_v, compiled.vertices[key % n_v]
    n = np.maximum(np.bincount(k_of, minlength=k), 1)[:, None]
    mid = np.stack([np.bincount(k_of, v[:, q], k) for q in range(3)], axis=1) / n
    d = v - mid[k_of]
    cov = np.stack([np.stack([np.bincount(k_of, d[:, a] * d[:, b], k) for b in range(3)], axis=1)
                    for a in range(3)], axis=1) / n[:, :, None]
    axes = np.linalg.eigh(cov)[1][:, :, ::-1]                            # columns: principal axes, longest first
    proj = np.einsum("ni,nij->nj", d, axes[k_of])
    lo, hi = np.full((k, 3), np.inf), np.full((k, 3), -np.inf)
    np.minimum.at(lo, k_of, proj)
    np.maximum.at(hi, k_of, proj)
    e = hi - lo
    slender = e[:, 1] < SLENDER_WIDTH * radius
    cell = np.where(slender, np.maximum(e[:, 1], 1e-6) / thin_across, np.inf)
    cover = [np.zeros((0, 3))] + [_slices(mid[j], axes[j], lo[j], hi[j]) for j in np.flatnonzero(slender)]
    counts = np.zeros(k, dtype=np.int64)
    counts[slender] = [c.shape[0] for c in cover[1:]]
    return cell, np.ascontiguousarray(np.concatenate(cover)), np.concatenate(([0], np.cumsum(counts)))


def _slices(mid, axes, lo, hi):
    """(4·slices, 3) the corners of a box's cross-sections (centre ``mid``, axes columns, extents ``lo`` … ``hi``
    along them) at slices along its first axis no farther apart than its second extent (lo[1] … hi[1] and lo[2] …
    hi[2] corners: the third minus the first corner spans the second extent), at most :data:`MAX_SLICES`."""
    e = hi - lo
    t = np.linspace(lo[0], hi[0], min(int(math.ceil(e[0] / max(e[1], 1e-6))), MAX_SLICES) + 1)
    corners = np.array([[lo[1], lo[2]], [lo[1], hi[2]], [hi[1], lo[2]], [hi[1], hi[2]]])
    local = np.concatenate([np.repeat(t, 4)[:, None], np.tile(corners, (t.size, 1))], axis=1)
    return mid + local @ axes.T


@dataclass(frozen=True, eq=False)
class AimedEchoes:
    """A block's aimed rays: their echoes (in the fan's rows), their rays, which candidates each row aims at, rays
    per ping."""

    echoes: Echoes
    layout: np.ndarray   # (n, 5) s, cos β, sin β, dβ, ds of each echo's ray (kernels.aim.LAYOUT_WIDTH)
    prim: np.ndarray     # (n,) int32 triangle each ray hit, −1 for none
    aimed: np.ndarray    # (rows, k) bool
    n_rays: np.ndarray   # (pings,) int64
    seconds_cast: float  # in the caster


def aim_block(caster, aim: AimPlan, plan, rot, pos_local, rx_shift, two_way_np_per_m: float, max_range_m: float,
              time_per_m: float, want_points: bool, laws) -> AimedEchoes:
    """Lattices, casts and echoes of every object aimed at in a block of pings: the fan's own kernel
    (:func:`kernels.fan_echoes`) with each ray's own layout, then only hits on the aimed object kept.

    Parameters
    ----------
    caster : Caster
    aim : AimPlan
    plan : FanPlan
    rot : (pings, 3, 3) float64; pos_local : (pings, 3) float64; rx_shift : (pings,) float64
    two_way_np_per_m, max_range_m, time_per_m : float
        As for :func:`sonar_embree.propagation.fan.cast_block` (``max_range_m`` the range searched).
    want_points : bool
        Keep the hit points (speckle, maps, textures).
    laws : LawTable
        The scene's laws at the carrier.
    """
    n_p, k = rot.shape[0], aim.objects.size
    table, start, counts, dirs, org, layout = lattice_rays(aim, rot, pos_local, rx_shift, max_range_m)
    t = time.perf_counter()
    prim, tfar = caster.cast_raw(org, dirs, max_range_m)
    seconds = time.perf_counter() - t
    n, c, none = layout.shape[0], caster.compiled, np.zeros(0)
    ray_start = np.ascontiguousarray(start[::k])
    rng, t_s, ext, w, cos_i = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    pts = np.empty((n, 3) if want_points or c.needs_points else (0, 3))
    fan = Fan(plan.s, plan.ds, none, none, none, ray_start)
    kernels.fan_echoes(fan, Poses(rot, pos_local, rx_shift), prim, tfar, scene_arrays(c),
                       DirectWeighting(plan.tilt_rad, two_way_np_per_m, plan.min_range_m, max_range_m,
                                       plan.slope_cap_m_rad, time_per_m),
                       EchoOut(rng, t_s, ext, w, cos_i, pts), layout)
    weigh_by_beam(plan.pattern, plan.tilt_rad, fan, rx_shift, w, layout)
    ids = keep_own(c, aim, counts, prim, w, t_s, cos_i)
    apply_laws(laws, c, prim, cos_i, w, pts)
    if not plan.footprint:
        ext[:] = 0.0
    echoes = Echoes(2, ray_start, t_s, ext, w, pts, ids)
    return AimedEchoes(echoes, layout, prim, counts > 0, counts.reshape(n_p, -1).sum(axis=1), seconds)


def keep_own(compiled, aim: AimPlan, counts, prim, weight, time_s, cos_i) -> np.ndarray:
    """Keep, in place, only the echoes of aimed rays whose first hit is the object they were aimed at (what they
    hit first elsewhere is the fan's); returns (n,) int32 the object each ray was aimed at."""
    obj = np.repeat(np.tile(aim.objects, counts.shape[0]), counts.ravel()).astype(np.int32)
    other = (prim < 0) | (compiled.face_object[np.maximum(prim, 0)] != obj)
    weight[other], time_s[other], cos_i[other] = 0.0, np.inf, 0.0
    return obj


def lattice_rays(aim: AimPlan, rot, pos_local, rx_shift, max_range_m: float):
    """The lattices of a block and their rays: (table (2·pings, k, LATTICE_WIDTH), ray offsets (2·pings·k + 1,),
    rays per lattice (2·pings, k), float32 directions and origins (n, 3), layout (n, LAYOUT_WIDTH): s, cos β,
    sin β, dβ, ds of each ray)."""
    n_p, k = rot.shape[0], aim.objects.size
    span = aim.span.copy()
    span[4] = max_range_m
    table = np.empty((2 * n_p, k, K.LATTICE_WIDTH))
    K.aim_lattices(aim.centre, aim.radius, aim.cell_m, aim.cover, aim.cover_start, rot, pos_local, aim.sides, span,
                   rx_shift, aim.n_across, aim.dr_m, aim.max_rays, table)
    mask = cover_masks(aim, table, rot, pos_local)
    counts = table[..., K.NC].astype(np.int64)
    start = np.concatenate(([0], np.cumsum(counts.ravel()))).astype(np.int64)
    n = int(start[-1])
    checks.check_rays_memory(n, n_p, "the rays aimed at objects")
    dirs, org = np.empty((n, 3), dtype=np.float32), np.empty((n, 3), dtype=np.float32)
    layout = np.empty((n, K.LAYOUT_WIDTH))
    K.aim_rays(table, start, rot, pos_local, mask, dirs, org, layout)
    return table, start, counts, dirs, org, layout


def cover_masks(aim: AimPlan, table, rot, pos_local) -> np.ndarray:
    """The slender lattices' cell masks of a block (:func:`kernels.aim.cover_cells`; MASK and NC set in ``table``);
    an empty mask, at no cost, where no lattice is slender."""
    slender = (table[..., K.NS] > 0) & (table[..., K.MASK] == K.SLENDER)
    if not slender.any():
        return np.zeros(0, dtype=np.uint8)
    cells = np.where(slender, table[..., K.NS] * table[..., K.NB], 0.0).astype(np.int64)
    table[..., K.MASK] = np.where(slender, np.cumsum(cells.ravel()).reshape(cells.shape) - cells, -1)
    mask = np.zeros(int(cells.sum()), dtype=np.uint8)
    K.cover_cells(table, aim.cover, aim.cover_start, rot, pos_local, SLENDER_RAYS * aim.max_rays, mask)
    return mask


def drop_aimed(caster, aim: AimPlan, ray_start, prim, weight, aimed) -> np.ndarray:
    """A copy of the fan's ``weight`` without the hits on objects their rows aim at (:func:`kernels.aim.drop_aimed`)."""
    out = weight.copy()
    K.drop_aimed(ray_start, prim, caster.compiled.face_object, aim.cand_of_object, aimed, out)
    return out
