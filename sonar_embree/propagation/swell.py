"""Sea-surface multipath off a wavy surface (a swell): one Embree reflection per ray (docs/physics.md §13).

For a flat surface the image method gives every path in closed form (:mod:`sonar_embree.propagation.multipath`). A swell
is meshed (:meth:`SeaSurface.mesh`) and the rays bounce on it:

- The image fan is placed as for the flat mean surface (its probes from the mirrored pose), so rays are
  dense where the bounced range changes fast. Each image ray's direction, mirrored back, is a real upward ray
  from the transducer S; it is cast against the surface mesh (to P, facet normal n_P), checked for anything
  of the scene on S→P, reflected (u_r = u − 2(u·n_P)n_P) and cast again through the scene (to X).
- Each facet is a flat mirror: the bounced ray is a straight ray of length R = |SP| + |PX| from S's image in
  the facet, so the two-bounce path S→P→X→P→S has the flat case's weight with that R, the law at X along u_r,
  Γ⁴ of the launch direction and |R_s|⁴ at P's grazing angle.
- The one-bounce paths S→P→X→S and S→X→P→S (equal by reciprocity, one echo of twice the weight) take the
  bounced ray to X and the direct leg back: w = 2·Γ²(u)·Γ²(u_d)·σ(θi, θs, φ)·|R_s|²·e^(−α'(R + r))·dΩ /
  (r²·cos θi), r = |X − S|, with the direct leg checked for visibility.

Speckle phases of the surface paths use the mean plane's image (statistics, not the exact pattern, hold).
The per-ray arithmetic between and after the casts is :mod:`sonar_embree.kernels.swell`.
"""
from __future__ import annotations

import math

import numpy as np

from .. import checks, kernels
from .buffers import Buffers
from .echoes import Echoes
from ..kernels import aim as K
from ..kernels.args import Bistatic, Bounce, Fan, Poses, SwellOut, Weighting
from .fan import drop_lines, elevation_rows, launch_body, moving_lines, probe_ranges
from .gain import weigh_pairs
from ..laws import apply_laws
from .multipath import (LEG_EPSILON_M, _below_top, wave_kh, apply_bistatic, block_legs, lambert_mu, mirror_pose,
                        wants_azimuth)


def _image_rows(caster, plan, rot_i, pos_i, pos_local, window_m, max_range_m):
    """Probe the image fan (rays from the image transducer, the mean surface a mirror) and place its elevation rays
    where the two-bounce range R or the one-bounce range (R + r)/2 lies in the window and changes fast.

    ``window_m``: the window with the swell's slack; ``max_range_m``: the farthest R probed. Returns
    (el_start, beta, dbeta, seconds in the caster), as :func:`sonar_embree.propagation.fan.probe_rows`."""
    big_r, dirs, t_embree = probe_ranges(caster, plan, rot_i, pos_i, max_range_m)
    r = np.linalg.norm(pos_i[:, None, :] + big_r[..., None] * dirs - pos_local[:, None, :], axis=2)
    lines = [np.where(v <= window_m, v, np.nan).reshape(2 * dirs.shape[0], -1) for v in (big_r, 0.5 * (big_r + r))]
    return (*elevation_rows(plan, np.concatenate(lines, axis=1)), t_embree)


def image_fan(front, strips, caster, rot, pos_local, max_range_m, clock, rx_shift):
    """The image fan's rays cast up from the sonar to the swell: a dict of the fan, of the rays that reached it
    (``up``) and of every upward ray on the lines each ping counts (``rising``: curved rays may reach it too).

    A one-bounce echo at range (R + r)/2 in the window may have travelled R up to twice the range on its bounce
    (r ≤ R): the fan is cast out to that (``max_range_m`` of the result), its rays placed densely only where one of
    its paths lies within the window (:func:`_image_rows`)."""
    surface = front.sonar.environment.surface
    plan, keep = moving_lines(front.plan, rx_shift)                  # the lines under motion, as the direct fan's
    z_s = surface.z_m - float(caster.compiled.origin_m[2])
    rot_i, pos_i = mirror_pose(rot, pos_local, z_s)
    window_m = max_range_m * (1.0 + 1e-3) + 0.05 + 2.0 * surface.swell_height_m   # a wave moves a path by < 2H
    max_range_m = 2.0 * (max_range_m * (1.0 + 1e-3) + 0.05)
    el_start, beta, dbeta, t_probe = _image_rows(caster, plan, rot_i, pos_i, pos_local, window_m, max_range_m)
    clock["embree"] = clock.get("embree", 0.0) + t_probe
    n_az, buf = plan.s.shape[0], front.buffers
    ray_start = n_az * el_start
    n = int(ray_start[-1])
    dirs, org = buf.take("swell_dirs", (n, 3), np.float32), buf.take("swell_org", (n, 3), np.float32)
    # the real, upward rays from S: the image fan's directions with z negated, i.e. the fan of the real attitude
    kernels.fan_rays(plan.s, np.cos(beta), np.sin(beta), el_start, np.ascontiguousarray(rot), pos_local, dirs, org)
    prim_s, t1 = surface_hits(buf, caster.compiled.origin_m, strips, org, dirs, max_range_m)
    live = np.zeros(n, np.int32)                                       # −1: a line this ping does not count
    if keep is not None:
        drop_lines(prim_s, plan.s, keep, el_start)
        drop_lines(live, plan.s, keep, el_start)
    up = np.flatnonzero((prim_s >= 0) & (dirs[:, 2] > 0))
    return dict(el_start=el_start, ray_start=ray_start, beta=beta, dbeta=dbeta, dirs=dirs, prim_s=prim_s, t1=t1,
                up=up, up_start=np.searchsorted(up, ray_start).astype(np.int64), max_range_m=max_range_m, s=plan.s,
                rising=np.flatnonzero((live >= 0) & (dirs[:, 2] > 0)))


def surface_hits(buf, origin_m, g, org, dirs, max_range_m):
    """(facet, distance) of each ray's first hit on the swell's mesh of grid ``g``, in closed form
    (kernels.swell_surface_hits: the triangles :func:`~sonar_embree.propagation.multipath.surface_mesh` meshes, not
    cast)."""
    n = dirs.shape[0]
    prim, t = buf.take("swell_hit_prim", n, np.int32), buf.take("swell_hit_t", n, np.float32)
    kernels.swell_surface_hits(org, dirs, origin_m, g.k, float(g.a[0]), float(g.a[1] - g.a[0]), g.z,
                               float(g.b[0]), float(g.b[1] - g.b[0]), g.b.size, max_range_m, prim, t)
    return prim, t


def _bounce(front, run, swell, fan, pos_local, buf):
    """The rays that reached the swell, mirrored on their facets and cast through the scene (the leg S → P
    checked too): a dict of per-entry arrays, aligned with ``fan["up"]`` (working arrays from ``buf``)."""
    m = fan["up"].shape[0]
    u, p, ur = (buf.take(k, (m, 3)) for k in ("swell_u", "swell_p", "swell_ur"))
    org, dr = buf.take("swell_borg", (m, 3), np.float32), buf.take("swell_bdir", (m, 3), np.float32)
    kernels.swell_launch(fan["up_start"], fan["up"], fan["dirs"], fan["t1"], fan["prim_s"], pos_local,
                         swell.compiled.face_normals, LEG_EPSILON_M, u, p, ur, org, dr)
    seen = buf.take("swell_seen", m)
    seen[:] = 1.0
    if m and _below_top(run.caster, float(pos_local[:, 2].min())):      # S → P through the scene
        block_legs(run, buf, fan["up_start"], p, pos_local, True, u, fan["t1"][fan["up"]].astype(np.float64),
                   seen)
    prim, t2 = run.caster.cast_raw(org, dr, fan["max_range_m"])
    return dict(u=u, p=p, ur=ur, prim=prim, t2=t2, seen=seen)


def _paths(front, run, swell, fan, b, rot, pos_local, rx_shift, buf):
    """kernels.swell_paths over the bounced rays: a dict of its outputs (the one bounce without σ and legs)."""
    s, plan, c = front.sonar, front.plan, run.compiled
    m = fan["up"].shape[0]
    o = {k: buf.take("swell_" + k, m) for k in ("w1", "t1", "e1", "w2", "t2", "e2", "cos_i", "cos_s", "phi", "r")}
    o["x"], o["leg"] = buf.take("swell_x", (m, 3)), buf.take("swell_leg", (m, 3))
    o["mu"] = lambert_mu(c)                                        # Lambert's σ in the kernel
    o["want_phi"] = wants_azimuth(c) and o["mu"].shape[0] == 0
    bounce = Bounce(fan["up_start"], fan["up"], fan["ray_start"], b["u"], b["p"], b["ur"], fan["t1"], fan["prim_s"],
                    b["prim"], b["t2"], b["seen"], swell.compiled.face_normals, LEG_EPSILON_M)
    grid, rot = Fan(fan["s"], plan.ds, np.cos(fan["beta"]), np.sin(fan["beta"]), fan["dbeta"], fan["el_start"]), \
        np.ascontiguousarray(rot, dtype=np.float64)
    kernels.swell_paths(grid, bounce, Poses(rot, pos_local, rx_shift), c.face_normals,
                        Weighting(front.two_way_np_per_m, plan.min_range_m, fan["max_range_m"],
                                  plan.slope_cap_m_rad, 2.0 / s.sound_speed_m_s),
                        Bistatic(0.0, wave_kh(s), o["mu"], c.face_object, o["want_phi"], False),
                        SwellOut(o["x"], o["w1"], o["t1"], o["e1"], o["w2"], o["t2"], o["e2"], o["cos_i"], o["cos_s"],
                                 o["phi"], o["leg"], o["r"]), fan.get("layout", kernels.NO_LAYOUT))
    _beam(front, fan, grid, rot, rx_shift, o, buf)
    return o


def _beam(front, fan, grid, rot, rx_shift, o, buf):
    """The beam after the kernel (:func:`~sonar_embree.propagation.gain.weigh_pairs`): the two bounces × Γ²(u)·Γ_rx²(u),
    the one bounce × Γ²(u)·Γ_rx²(u_d) + Γ²(u_d)·Γ_rx²(u), u the launch from its image-fan cell (the mirror maps the
    image ray onto it), u_d = −leg towards the hit."""
    body = launch_body(grid, fan["ray_start"], fan.get("layout", kernels.NO_LAYOUT),
                       buf.take("swell_body", (int(fan["ray_start"][-1]), 3)))[fan["up"]]
    weigh_pairs(front.plan.pattern, front.plan.tilt_rad, fan["up_start"], body, -o["leg"], rot, rx_shift, o["w1"],
                o["w2"])


def _bounced_paths(front, run, swell, fan, rot, pos_local, rx_shift, buf):
    """The bounced rays' one- and two-bounce weights with their laws and legs: (bounce dict, paths dict)."""
    b = _bounce(front, run, swell, fan, pos_local, buf)
    o = _paths(front, run, swell, fan, b, rot, pos_local, rx_shift, buf)
    if o["mu"].shape[0] == 0:
        apply_bistatic(run.compiled, run.laws, b["prim"], o["x"], o["w1"], o["cos_i"], o["cos_s"],
                       o["phi"] if o["want_phi"] else None)
    block_legs(run, buf, fan["up_start"], o["x"], pos_local, False, o["leg"], o["r"], o["w1"],  # X → S
               b["prim"])
    apply_laws(run.law_table, run.compiled, b["prim"], o["cos_i"], o["w2"], o["x"])
    return b, o


def _echo_pair(fan, b, o, ids):
    """(one-bounce, two-bounce) Echoes of the bounced rays, in the rows of ``fan["up_start"]``."""
    out = []
    for w, t, ext in ((o["w1"], o["t1"], o["e1"]), (o["w2"], o["t2"], o["e2"])):
        obj = np.zeros(0, np.int32) if ids is None else np.where(w > 0, ids[np.maximum(b["prim"], 0)], -1).astype(
            np.int32)
        out.append(Echoes(2, fan["up_start"], t, ext, w, o["x"], obj))
    return out[0], out[1]


def swell_echoes(front, run, rot, pos_local, max_range_m, ids, clock, rx_shift=None):
    """(one-bounce, two-bounce) Echoes of a block off the swell, in the rows of the image fan's upward rays; those of
    the rays aimed at objects through the swell (a list of (Echoes, each echo's layout row (s, cos β, sin β, dβ, ds),
    path): 1 one bounce, 2 two bounces; empty without any); and each upward ray's azimuth line (:func:`up_lines`).
    ``rx_shift`` (pings,) δ = 2·v_fwd/c when moving during the ping (None or zeros: stop-and-hop)."""
    rx_shift = np.zeros(rot.shape[0]) if rx_shift is None else np.ascontiguousarray(rx_shift, dtype=np.float64)
    surface = front.sonar.environment.surface
    swell, strips = run.surface_caster, run.surface_strips
    fan = image_fan(front, strips, run.caster, rot, pos_local, max_range_m, clock, rx_shift)
    b, o = _bounced_paths(front, run, swell, fan, rot, pos_local, rx_shift, front.buffers)
    aim, aimed = run.aim, []
    if aim is not None:
        glints = _aimed(front, run, swell, strips, aim, rot, pos_local, rx_shift, fan["max_range_m"], ids)
        if glints is not None:                       # the fan's hits on those objects count nothing in those rows
            for w in (o["w1"], o["w2"]):
                K.drop_aimed(fan["up_start"], b["prim"], run.compiled.face_object, aim.cand_of_object, glints[2],
                             w)
            aimed = [(glints[0], glints[3], 1), (glints[1], glints[3], 2)]
    return (*_echo_pair(fan, b, o, ids), aimed, up_lines(fan))


def up_lines(fan) -> np.ndarray:
    """(m,) int64: the azimuth line of each of the image fan's upward rays ``fan["up"]`` (its rows' rays are
    azimuth-major over their elevation cells), for the sonar types that keep one channel per line."""
    up, ray_start = fan["up"], fan["ray_start"]
    row = np.searchsorted(ray_start, up, side="right") - 1
    n_el = np.diff(fan["el_start"])[row]
    return ((up - ray_start[row]) // np.maximum(n_el, 1)).astype(np.int64)


#: The most swell strips one object may be seen through from one ping (its glints); more leave it to the fan.
MAX_GLINTS = 16


def _glints(aim, surface, g, origin, pos_local, reach_m):
    """Every glint of the block (kernels.swell_glints): (lattices (e, GLINT_WIDTH), ping (e,), candidate (e,),
    (pings, k) bool where an object is left to the fan: too many glints, or one too big to aim at)."""
    n_p, k = pos_local.shape[0], aim.objects.size
    table, count = np.empty((n_p, k, MAX_GLINTS, kernels.GLINT_WIDTH)), np.empty((n_p, k), np.int32)
    slope = math.pi * surface.swell_height_m / surface.swell_length_m     # max |dz/da| of H/2·sin(2πa/Λ)
    steps = np.array([aim.span[5], aim.span[6], aim.dr_m])
    kernels.swell_glints(aim.centre + origin, aim.radius, pos_local + origin, g.k, float(g.a[0]),
                         float(g.a[1] - g.a[0]), g.z, slope, reach_m, aim.n_across, steps, aim.max_rays, table, count)
    ping, cand, slot = np.nonzero(np.arange(MAX_GLINTS)[None, None, :] < count[..., None])   # ping-major
    return table[ping, cand, slot], ping.astype(np.int64), cand, count < 0


def _glint_rays(aim, g, rot, pos_local, rx_shift, glints, ping, cand, refused):
    """The rays of the glints' lattices, grouped by fan row: (row offsets (rows + 1,), glint of each ray, float32
    directions and origins, layout, (rows, k) bool: which candidates each row aims at through the swell).

    A row aims at an object when some glint ray of it lies in the row (within the fan's span) and the object is
    not left to the fan in that ping (:func:`_glints`)."""
    n_p, k = rot.shape[0], aim.objects.size
    counts = (glints[:, kernels.G_NS] * glints[:, kernels.G_NB]).astype(np.int64)
    counts[refused[ping, cand]] = 0
    start = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    n = int(start[-1])
    checks.check_rays_memory(n, n_p, "the rays aimed at objects through the swell")
    dirs, org, layout = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32), np.empty((n, K.LAYOUT_WIDTH))
    row = np.empty(n, np.int64)
    kernels.glint_rays(glints, ping, start, g.k, rot, pos_local, aim.span[:4].copy(), aim.sides, rx_shift, dirs, org,
                       layout, row)
    glint = np.repeat(np.arange(ping.size), counts)
    keep = np.flatnonzero(row >= 0)
    order = keep[np.argsort(row[keep], kind="stable")]
    aimed = np.zeros((2 * n_p, k), bool)
    aimed[row[order], cand[glint[order]]] = True
    ray_start = np.searchsorted(row[order], np.arange(2 * n_p + 1)).astype(np.int64)
    return ray_start, glint[order], dirs[order], org[order], layout[order], aimed


def _aimed(front, run, swell, g, aim, rot, pos_local, rx_shift, reach_m, ids):
    """The rays aimed at objects through the swell (docs/physics.md §7b): per ping and object, each strip that can
    mirror it to the sonar (a glint) gets a lattice aimed at the object's image in the strip's plane, clipped to the
    directions that meet the strip; a ray counts only where its first hit on the swell is on that strip and its
    bounced ray first hits that object. (one-bounce Echoes, two-bounce Echoes, (rows, k) aimed) or None when no row
    aims at anything."""
    c = run.compiled
    rot = np.ascontiguousarray(rot, dtype=np.float64)
    glints, ping, cand, refused = _glints(aim, front.sonar.environment.surface, g, c.origin_m, pos_local, reach_m)
    ray_start, glint, dirs, org, layout, aimed = _glint_rays(aim, g, rot, pos_local, rx_shift, glints, ping, cand,
                                                             refused)
    if not aimed.any():
        return None
    buf = Buffers()
    prim_s, t1 = surface_hits(buf, c.origin_m, g, org, dirs, reach_m)
    na = g.a.size
    n_q = (na - 1) * (g.b.size - 1)
    own_strip = (prim_s % n_q) % (na - 1) == glints[glint, kernels.G_STRIP].astype(np.int64)
    up = np.flatnonzero((prim_s >= 0) & (dirs[:, 2] > 0) & own_strip)
    fan = dict(el_start=ray_start, ray_start=ray_start, beta=np.zeros(0), dbeta=np.zeros(0), dirs=dirs,
               prim_s=prim_s, t1=t1, up=up, up_start=np.searchsorted(up, ray_start).astype(np.int64),
               max_range_m=reach_m, s=np.zeros(1), layout=layout)
    b, o = _bounced_paths(front, run, swell, fan, rot, pos_local, rx_shift, buf)
    mine = c.face_object[np.maximum(b["prim"], 0)] == aim.objects[cand[glint[up]]]
    for w in (o["w1"], o["w2"]):                          # only hits on the aimed object count
        w[~mine | (b["prim"] < 0)] = 0.0
    one, two = _echo_pair(fan, b, o, ids)
    return one, two, aimed, layout[up]
