"""Sea-surface multipath by the image method, for a flat surface (docs/physics.md §13).

With S the sonar, S' its mirror image in the surface z = z_s and X a scattering
point, the four paths are S→X→S (2r, the direct echoes), S→X→S' and S'→X→S
(r + r', equal by reciprocity: one echo of twice the weight), and S'→X→S' (2r').
Every leg is checked for visibility in the real, unmirrored scene, carries the
membrane's Γ of its direction as the real transducer sees it, 1/r spreading and
absorption, and each bounce multiplies the intensity by |R_s|² (Rayleigh roughness,
:class:`~sonar_embree.environment.SeaSurface`). The scattering at X is bistatic
(σ(θi, θs, φ) of the object's law).

- S'→X→S': the side-scan fan cast from S' with the mirrored attitude (its rays that
  go down from S' are the real fan's upward rays after the bounce), so the fan's
  ray budget, footprints and laws apply unchanged.
- S→X→S': from every direct echo, the leg X → S' through the surface point P,
  its weight w = Γ²(u1)·Γ²(u2)·σ(θi, θs, φ)·e^(−α'(r + r'))·|R_s|²·dΩ/(r'²·cos θi) and
  its travel-time extent from the footprint's motion along the ray cell.

With motion during the ping (docs/physics.md §16) every receive beam, the image's included, is turned by
δ = 2·v_fwd/c along track, so S→X→S' and S'→X→S differ: Γ²(u1)·Γ_rx²(u2) and Γ²(u2)·Γ_rx²(u1).
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from ..kernels import aim as aim_kernels
from ..kernels.args import Bistatic, Boxes, Fan, Hits, LegOut, Legs, MixedOut, Poses, Weighting
from .buffers import Buffers
from .echoes import Echoes
from .fan import BlockEchoes, cast_block, launch_body
from .gain import weigh_pairs
from ..config import Material
from ..raycast import RayCaster
from ..scene import Scene
from ..scene.meshes import heightfield_objects, object_slopes

#: Visibility rays start this far along their leg (m), off the surface they leave.
LEG_EPSILON_M = 1e-3
#: Up to this many objects, a visibility leg is cast only through the boxes of those it crosses.
MAX_LEG_BOXES = 16


def mirror(pos: np.ndarray, z_s: float) -> np.ndarray:
    """Positions (..., 3) mirrored in the plane z = z_s (same frame as ``pos``)."""
    out = np.array(pos, dtype=np.float64)
    out[..., 2] = 2.0 * z_s - out[..., 2]
    return out


def mirror_pose(rot: np.ndarray, pos_local: np.ndarray, z_s_local: float):
    """The image transducer: attitude with world z negated (an improper rotation) and position 2z_s − z."""
    rot_i = rot.copy()
    rot_i[:, 2, :] *= -1.0
    return rot_i, mirror(pos_local, z_s_local)


def _below_top(caster, z: float) -> bool:
    """Whether a leg starting at height z (local) can be blocked at all: the scene reaches above it."""
    return float(caster.compiled.bounds_local[1, 2]) > z + LEG_EPSILON_M * 1e-3


def can_block(caster, from_sonar: bool, pos_local) -> bool:
    """Whether the scene can block any upward leg: from the sonar, when the scene reaches above it; from a hit
    point, unless the scene is exactly level (every vertex at one height: such a leg leaves it at its top)."""
    lo, hi = caster.compiled.bounds_local[:, 2]
    return _below_top(caster, float(pos_local[:, 2].min())) if from_sonar else bool(hi > lo)


def block_legs(run, buf, ray_start, x, pos_local, from_sonar: bool, dirs, dist, w, prim=None,
               free_own: bool = False) -> None:
    """Zero the weights ``w`` (n,) of a block's echoes whose upward leg is blocked (see kernels.visibility_legs).

    Legs start at the sonar (``from_sonar``) or at the hit points ``x`` (n, 3) and run along ``dirs`` (n, 3)
    for ``dist`` (n,) m; ``buf`` holds the float32 rays. Nothing is done where nothing can block
    (:func:`can_block`); a leg is cast only through the objects' boxes it crosses (:func:`leg_boxes`).
    ``prim`` (n,), the echoes' triangles, lets a height-field floor they lie on be passed over where it cannot
    block: for a leg from x steeper than its steepest face, and, with ``free_own`` (the one-bounce legs of the
    direct fan), for the legs of an echo seen from above.
    """
    if not can_block(run.caster, from_sonar, pos_local):
        return
    n, c = w.shape[0], run.compiled
    idx, org, dr, ln = (buf.take("leg_idx", n, np.int64), buf.take("leg_org", (n, 3), np.float32),
                        buf.take("leg_dir", (n, 3), np.float32), buf.take("leg_len", n, np.float32))
    lo, hi, obj, slope = run.leg_boxes[prim is not None]
    legs = Legs(x, pos_local, from_sonar, dirs, dist, w, np.zeros(0, np.int32) if prim is None else prim, free_own,
                LEG_EPSILON_M)
    k = kernels.visibility_legs(ray_start, legs, Boxes(lo, hi, obj, slope), c.face_object, c.face_normals,
                                LegOut(buf.take("leg_t0", n), buf.take("leg_t1", n), idx, org, dr, ln))
    if k:
        w[idx[:k][run.caster.occluded(org[:k], dr[:k], ln[:k])]] = 0.0


def leg_boxes(compiled, with_heightfields: bool):
    """(lo (k, 3), hi (k, 3), obj (k,) int32, slope (k,)) boxes that hold the scene, for :func:`block_legs`: one
    per object (up to :data:`MAX_LEG_BOXES` objects, else one for all), widened by :data:`LEG_EPSILON_M`; ``obj``
    the object of a height field (−1 for other boxes, and for all without ``with_heightfields``) and ``slope`` its
    steepest face's tan. Made once per run (:class:`~sonar_embree.propagation.prepared.PreparedRun`)."""
    b = compiled.object_bounds
    obj, slope = np.arange(b.shape[0], dtype=np.int32), np.full(b.shape[0], np.inf)
    if b.shape[0] > MAX_LEG_BOXES:
        b, obj, slope = compiled.bounds_local[None], np.full(1, -1, np.int32), np.full(1, np.inf)
    elif with_heightfields:
        fields = heightfield_objects(compiled)
        obj = np.where(fields, obj, -1).astype(np.int32)
        slope = np.where(fields, object_slopes(compiled), np.inf)
    else:
        obj = np.full(b.shape[0], -1, np.int32)
    return (np.ascontiguousarray(b[:, 0] - LEG_EPSILON_M), np.ascontiguousarray(b[:, 1] + LEG_EPSILON_M), obj, slope)


def surface_mesh(compiled, surface, max_range_m: float):
    """An Embree caster of the sea surface (a swell's mesh, or two triangles for a flat one) over the extent of
    ``compiled`` ± the range, in its local frame, two-sided, with the surface line's law (Lambert −27 dB where it
    has none: never read then). Made once per run (:class:`~sonar_embree.propagation.prepared.PreparedRun`)."""
    law = surface.backscatter_law
    material = Material(two_sided=True) if law is None else Material(two_sided=True, scattering=law)
    mesh = surface.mesh(*surface_extent(compiled, max_range_m))
    return RayCaster(Scene().add(mesh, material=material, label="sea surface").compiled(compiled.origin_m))


def surface_strips(compiled, surface, max_range_m: float):
    """The swell's mesh grid (:meth:`SeaSurface.strips`) over the extent :func:`surface_mesh` meshes for the same
    range."""
    return surface.strips(*surface_extent(compiled, max_range_m))


def surface_extent(compiled, max_range_m: float):
    """World (x range, y range) the sea surface is meshed over: reflection points lie between the sonar and the
    scene, within its extent ± the range."""
    lo = compiled.bounds_local[0, :2] + compiled.origin_m[:2]
    hi = compiled.bounds_local[1, :2] + compiled.origin_m[:2]
    return (lo[0] - max_range_m, hi[0] + max_range_m), (lo[1] - max_range_m, hi[1] + max_range_m)


def surface_line(front, run, rot, pos_local, max_range_m, want_points, want_ids, clock,
                 rx_shift=None) -> tuple[Echoes, BlockEchoes]:
    """The sea surface's own backscatter S→P→S (the surface line): the fan cast at the surface with its law, each
    echo's leg S→P checked against the scene; object id −1 (water, not a scene object). Also the fan's block."""
    s = front.sonar
    surf = run.surface_caster
    blk = cast_block(surf, front.plan, rot, pos_local, front.two_way_np_per_m, max_range_m, 2.0 / s.sound_speed_m_s,
                     want_points=True, timings=clock, laws=run.surface_law_table, rx_shift=rx_shift)
    w = blk.weight
    if _below_top(run.caster, float(pos_local[:, 2].min())):                # something of the scene above the sonar
        lit = np.flatnonzero(w > 0)
        pos = np.repeat(pos_local, np.diff(blk.ray_start[::2]), axis=0)
        dirs = np.zeros((w.shape[0], 3))
        dirs[lit] = (blk.point_m[lit] - pos[lit]) / blk.range_m[lit, None]
        block_legs(run, front.buffers, blk.ray_start, blk.point_m, pos_local, True, dirs, blk.range_m, w)
    ids = np.full(w.shape[0] if want_ids else 0, -1, dtype=np.int32)
    return Echoes(2, blk.ray_start, blk.time_s, blk.extent_s, w, blk.point_m if want_points else np.zeros((0, 3)),
                  ids), blk


def image_echoes(front, run, rot, pos_local, z_s_local, max_range_m, clock,
                 rx_shift=None, aim=None) -> tuple[Echoes, BlockEchoes]:
    """S'→X→S': the fan cast from the image transducer, each echo × |R_s|⁴ and its real upward leg checked.

    The image moves along track as the sonar does: ``rx_shift`` (pings,) δ = 2·v_fwd/c (None: stop-and-hop).
    With ``aim`` (:class:`~sonar_embree.propagation.aim.AimPlan`) the image aims rays at the objects too (its block's
    ``aimed``; :func:`image_aimed_echoes`) and its fan's hits on them count nothing."""
    s = front.sonar
    rot_i, pos_i = mirror_pose(rot, pos_local, z_s_local)
    blk = cast_block(run.caster, front.plan, rot_i, pos_i, front.two_way_np_per_m, max_range_m,
                     2.0 / s.sound_speed_m_s, want_points=True, timings=clock, laws=run.law_table,
                     rx_shift=rx_shift, aim=aim)
    n, buf = blk.weight.shape[0], front.buffers
    w, up, leg = buf.take("image_w", n), buf.take("image_up", (n, 3)), buf.take("image_leg", n)
    w[:] = blk.echo_weight
    kernels.two_bounce(blk.ray_start, blk.point_m, pos_i, z_s_local, wave_kh(s), w, up, leg)
    block_legs(run, buf, blk.ray_start, blk.point_m, pos_local, True, up, leg, w)
    return Echoes(2, blk.ray_start, blk.time_s, blk.extent_s, w, blk.point_m, np.zeros(0, np.int32)), blk


def image_aimed_echoes(front, run, iblk, rot, pos_local, z_s_local) -> Echoes:
    """The two-bounce echoes of the rays the image transducer aimed at objects (``iblk.aimed``, from
    :func:`image_echoes`): × |R_s|⁴, their upward legs checked; object ids kept."""
    e = iblk.aimed.echoes
    _, pos_i = mirror_pose(rot, pos_local, z_s_local)
    n, buf = e.weight.shape[0], Buffers()
    w, up, leg = e.weight.copy(), np.empty((n, 3)), np.empty(n)
    kernels.two_bounce(e.ray_start, e.point_m, pos_i, z_s_local, wave_kh(front.sonar), w, up, leg)
    block_legs(run, buf, e.ray_start, e.point_m, pos_local, True, up, leg, w)
    return Echoes(2, e.ray_start, e.travel_time_s, e.extent_s, w, e.point_m, e.object_id)


def wave_kh(sonar) -> float:
    """k·h_w of the sonar's sea surface."""
    return sonar.wavenumber_rad_m * sonar.environment.surface.wave_height_m


def bistatic_sigma(compiled, laws, prim, cos_i, cos_s, phi):
    """σ(θi, θs, φ) of each echo's object law (``laws``: each object's at the carrier; maps and texture are applied
    separately); ``prim`` (the echoes' triangles) may be None when every object has the same law."""
    if prim is None:
        return laws[0].sigma(cos_i, cos_s, phi)
    obj = compiled.face_object[prim]
    present = np.flatnonzero(np.bincount(obj, minlength=len(compiled.laws)))
    if present.shape[0] == 1:                                   # one law: no masks
        return laws[present[0]].sigma(cos_i, cos_s, phi)
    out = np.zeros(prim.shape[0])
    for o in present:
        k = obj == o
        out[k] = laws[o].sigma(cos_i[k], cos_s[k], phi[k] if np.ndim(phi) else phi)
    return out


def lambert_mu(compiled) -> np.ndarray:
    """Lambert's μ per object when every object has Lambert's law and there are no maps or texture (a kernel then
    applies σ = μ·cos θi·cos θs itself), else an empty array."""
    c = compiled
    return c.mu if c.maps is None and c.textures is None and bool(np.all(np.isfinite(c.mu))) else np.zeros(0)


def wants_azimuth(compiled) -> bool:
    """Whether any law of the scene reads the bistatic azimuth φ (it costs an arccos per echo)."""
    return any(law.uses_azimuth for law in compiled.laws)


def apply_bistatic(compiled, laws, prim, points, w, cos_i, cos_s, phi=None) -> None:
    """Multiply the lit weights ``w`` (n,) of bistatic echoes by σ(θi, θs, φ), the maps and the texture, in place;
    ``laws`` each object's law at the carrier, ``prim`` (n,) their triangles, ``points`` (n, 3) their scattering
    points, ``phi`` None when no law reads it. Only lit echoes are gathered; with one law and no maps, not even their
    triangles."""
    c = compiled
    lit = np.flatnonzero(w > 0)
    detail = [d for d in (c.maps, c.textures) if d is not None]
    at = prim[lit] if detail or any(law != c.laws[0] for law in c.laws) else None   # one law: no gathers
    w_lit = w[lit] * bistatic_sigma(c, laws, at, cos_i[lit], cos_s[lit], 0.0 if phi is None else phi[lit])
    for d in detail:
        d.apply(c, at, points[lit], w_lit)
    w[lit] = w_lit


def mixed_echoes(front, run, blk, rot, pos_local, z_s_local, rx_shift=None) -> Echoes:
    """S→X→S' and S'→X→S (one echo: twice the weight when stop-and-hop) of every direct echo of ``blk``, aligned
    with its rays; ``rx_shift`` (pings,) δ = 2·v_fwd/c turns each path's receive beam (docs/physics.md §16). The
    fan's hits on objects its rows aim rays at count nothing here (their aimed rays' own one-bounce echoes,
    :func:`mixed_aimed_echoes`, stand for them)."""
    plan = blk.plan
    w, t, ext = _mixed(front, run, front.buffers, blk.ray_start, blk.el_start, plan.s, np.cos(blk.beta),
                       np.sin(blk.beta), blk.dbeta, plan.ds, blk.range_m, blk.point_m, blk.prim, rot, pos_local,
                       z_s_local, rx_shift, kernels.NO_LAYOUT)
    if blk.aimed is not None and blk.aimed.aimed.any():
        aim = run.aim
        aim_kernels.drop_aimed(blk.ray_start, blk.prim, run.compiled.face_object, aim.cand_of_object,
                           blk.aimed.aimed, w)
    return Echoes(2, blk.ray_start, t, ext, w, blk.point_m, np.zeros(0, np.int32))


def mixed_aimed_echoes(front, run, aimed, rot, pos_local, z_s_local, rx_shift=None) -> Echoes:
    """The one-bounce echoes (:func:`mixed_echoes`) of the rays aimed at objects (``aimed``:
    :class:`~sonar_embree.propagation.aim.AimedEchoes`, with points), each with its own cell (layout); object ids
    kept."""
    e = aimed.echoes
    r = np.where(np.isfinite(e.travel_time_s), 0.5 * front.sonar.sound_speed_m_s * e.travel_time_s, np.inf)
    w, t, ext = _mixed(front, run, Buffers(), e.ray_start, e.ray_start, front.plan.s, np.zeros(0), np.zeros(0),
                       np.zeros(0), front.plan.ds, r, e.point_m, aimed.prim, rot, pos_local, z_s_local, rx_shift,
                       aimed.layout)
    return Echoes(2, e.ray_start, t, ext, w, e.point_m, e.object_id)


def _mixed(front, run, buf, ray_start, el_start, s_az, cos_b, sin_b, dbeta, ds, r, x, prim, rot, pos_local,
           z_s_local, rx_shift, layout):
    """(w, t, ext) (n,) of the one-bounce paths of direct hits (ranges ``r``, points ``x``, triangles ``prim``) in
    ``buf``: the kernel (:func:`kernels.mixed_legs`, the fan's layout or each ray's own ``layout``), the bistatic
    law and the visibility of both legs."""
    rx_shift = np.zeros(rot.shape[0]) if rx_shift is None else np.ascontiguousarray(rx_shift, dtype=np.float64)
    s, plan, c = front.sonar, front.plan, run.compiled
    n = r.shape[0]
    t, ext, w, cos_i, cos_s, phi, leg1, leg2 = (buf.take(k, n) for k in ("t", "ext", "w", "cos_i", "cos_s", "phi",
                                                                          "leg1", "leg2"))
    v, u2 = buf.take("v", (n, 3)), buf.take("u2", (n, 3))
    mu = lambert_mu(c)                                                       # σ in the kernel
    lambert = mu.shape[0] > 0
    want_phi = wants_azimuth(c) and not lambert
    legs = (can_block(run.caster, False, pos_local), can_block(run.caster, True, pos_local))
    fan, rot = Fan(s_az, ds, cos_b, sin_b, dbeta, el_start), np.ascontiguousarray(rot, dtype=np.float64)
    kernels.mixed_legs(ray_start, fan, Hits(r, x, prim), Poses(rot, pos_local, rx_shift), c.face_normals,
                       Weighting(front.two_way_np_per_m, plan.min_range_m, np.inf, plan.slope_cap_m_rad,
                                 2.0 / s.sound_speed_m_s),
                       Bistatic(z_s_local, wave_kh(s), mu, c.face_object, want_phi, any(legs)),
                       MixedOut(t, ext, w, cos_i, cos_s, phi, v, leg1, u2, leg2), layout)
    body = launch_body(fan, ray_start, layout, buf.take("body", (n, 3)))
    weigh_pairs(plan.pattern, plan.tilt_rad, ray_start, body, u2, rot, rx_shift, w)   # the beam: u1 out, S → P back
    if not lambert:
        apply_bistatic(c, run.laws, prim, x, w, cos_i, cos_s, phi if want_phi else None)
    if legs[0]:
        block_legs(run, buf, ray_start, x, pos_local, False, v, leg1, w, prim, True)
    if legs[1]:
        block_legs(run, buf, ray_start, x, pos_local, True, u2, leg2, w, prim, True)
    return w, t, ext


class PathEchoes:
    """A block's echoes kept as its paths (direct, one bounce, two bounces, the surface line), in the same rows.

    A back end that only adds echoes up (the speckle-free splatting) takes ``parts`` one after the other: row by
    row that is the merged order, so the same bits, without the merge. Everything else takes :meth:`merged`
    (:func:`sonar_embree.propagation.echoes.merged`), made on first use.
    """

    def __init__(self, parts, points: bool, buf: Buffers | None = None, paths=None):
        self.parts, self._args, self._merged = tuple(parts), (points, buf, paths), None
        self.n_channels = self.parts[0].n_channels

    @property
    def n_pings(self) -> int:
        return self.parts[0].n_pings

    def merged(self) -> Echoes:
        """The lit echoes of every path, row by row, tagged with their path (:func:`merge`)."""
        if self._merged is None:
            points, buf, paths = self._args
            self._merged = merge(self.parts, points, buf, paths)
        return self._merged


#: Parts :func:`merge` hands its kernels, the missing ones empty (their tuples' length is part of their compiled type).
MERGE_PARTS = 6


def merge(parts, points: bool, buf: Buffers | None = None, paths=None) -> Echoes:
    """The lit echoes of the paths ``parts`` (direct, one bounce, two bounces), row by row, each tagged with its path
    (its index in ``parts``, or ``paths[index]``: the surface line is a direct path; every part direct: no tags).

    Within a row, each part's echoes in their order, part by part. The hit points are kept when ``points``
    (speckle, maps), the object ids when every part has them, the along-track strips of the parts that have them
    (:func:`_strips`). With ``buf`` the result lives in its kept arrays
    (valid until the front end's next block).
    """
    rows = parts[0].ray_start.shape[0] - 1
    pad = max(MERGE_PARTS - len(parts), 0)                 # empty parts: one compiled signature for any count
    starts = tuple(e.ray_start for e in parts) + (np.zeros(rows + 1, dtype=np.int64),) * pad
    weights = tuple(e.weight for e in parts) + (np.zeros(0),) * pad
    counts = np.empty(rows, dtype=np.int64)
    kernels.count_lit(starts, weights, counts)
    start = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    m = int(start[-1])
    with_ids = all(e.object_id.shape[0] == e.weight.shape[0] for e in parts)
    take = (lambda name, shape, dtype=np.float64: np.empty(shape, dtype)) if buf is None else buf.take
    t, ext, w, path = (take("merged_t", m), take("merged_ext", m), take("merged_w", m),
                       take("merged_path", m, np.int8))
    pts = take("merged_pts", (m if points else 0, 3))
    ids = take("merged_ids", m if with_ids else 0, np.int32)
    kernels.merge_lit(starts, tuple(e.travel_time_s for e in parts) + weights[len(parts):],
                      tuple(e.extent_s for e in parts) + weights[len(parts):], weights,
                      tuple(_points(e) for e in parts) + (np.zeros((0, 3)),) * pad,
                      tuple(_ids(e) for e in parts) + (np.zeros(0, np.int32),) * pad, start, t, ext, w, pts, ids, path)
    along, on_strip = _strips(parts, path)
    if paths is not None:
        if not any(paths):                          # every part direct (the fan and the aimed rays): no tags
            return Echoes(parts[0].n_channels, start, t, ext, w, pts, ids, along=along, on_strip=on_strip)
        path[:] = np.asarray(paths, dtype=np.int8)[path]
    return Echoes(parts[0].n_channels, start, t, ext, w, pts, ids, path, along, on_strip)


def _strips(parts, part_of: np.ndarray):
    """The merged echoes' along-track strips (:attr:`Echoes.along`, the rows' of the parts that have them) and which
    echoes lie on them (:attr:`Echoes.on_strip`; empty when all or none do), ``part_of`` each echo's part."""
    marks = [e.along is not None for e in parts]
    if not any(marks):
        return None, np.zeros(0, dtype=bool)
    along = next(e.along for e in parts if e.along is not None)
    return along, (np.zeros(0, dtype=bool) if all(marks) else np.asarray(marks)[part_of])


def _points(e: Echoes) -> np.ndarray:
    """The echoes' points, or a (n, 3) stand-in where they are not kept (never read then)."""
    return e.point_m if e.point_m.shape[0] == e.weight.shape[0] else np.zeros((0, 3))


def _ids(e: Echoes) -> np.ndarray:
    """The echoes' object ids, or an empty stand-in (never read then)."""
    return e.object_id if e.object_id.shape[0] == e.weight.shape[0] else np.zeros(0, np.int32)
