"""Sea-surface multipath off a wavy surface (a swell): one Embree reflection per ray (docs/physics.md §13).

For a flat surface the image method gives every path in closed form (:mod:`sonar_embree.multipath`). A swell
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

import numpy as np

from . import kernels
from .echoes import Echoes
from .fan import drop_lines, elevation_rows, moving_lines, probe_ranges
from .laws import apply_laws
from .multipath import (LEG_EPSILON_M, _below_top, _wave_kh, apply_bistatic, block_legs, lambert_mu, mirror_pose,
                        surface_caster, surface_strips, wants_azimuth)


def _image_rows(caster, plan, rot_i, pos_i, pos_local, window_m, max_range_m):
    """Probe the image fan (rays from the image transducer, the mean surface a mirror) and place its elevation rays
    where the two-bounce range R or the one-bounce range (R + r)/2 lies in the window and changes fast.

    ``window_m``: the window with the swell's slack; ``max_range_m``: the farthest R probed. Returns
    (el_start, beta, dbeta, seconds in the caster), as :func:`sonar_embree.fan.probe_rows`."""
    big_r, dirs, t_embree = probe_ranges(caster, plan, rot_i, pos_i, max_range_m)
    r = np.linalg.norm(pos_i[:, None, :] + big_r[..., None] * dirs - pos_local[:, None, :], axis=2)
    lines = [np.where(v <= window_m, v, np.nan).reshape(2 * dirs.shape[0], -1) for v in (big_r, 0.5 * (big_r + r))]
    return (*elevation_rows(plan, np.concatenate(lines, axis=1)), t_embree)


def _image_fan(front, strips, caster, rot, pos_local, max_range_m, clock, rx_shift):
    """The image fan's rays cast up from the sonar to the swell: a dict of the fan and of the rays that reached it.

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
    prim_s, t1 = _surface_hits(buf, caster.compiled.origin_m, strips, org, dirs, max_range_m)
    if keep is not None:
        drop_lines(prim_s, plan.s, keep, el_start)
    up = np.flatnonzero((prim_s >= 0) & (dirs[:, 2] > 0))
    return dict(el_start=el_start, ray_start=ray_start, beta=beta, dbeta=dbeta, dirs=dirs, prim_s=prim_s, t1=t1,
                up=up, up_start=np.searchsorted(up, ray_start).astype(np.int64), max_range_m=max_range_m, s=plan.s)


def _surface_hits(buf, origin_m, g, org, dirs, max_range_m):
    """(facet, distance) of each ray's first hit on the swell's mesh of grid ``g``, in closed form
    (kernels.swell_surface_hits: the triangles :func:`~sonar_embree.multipath.surface_caster` meshes, not cast)."""
    n = dirs.shape[0]
    prim, t = buf.take("swell_hit_prim", n, np.int32), buf.take("swell_hit_t", n, np.float32)
    kernels.swell_surface_hits(org, dirs, origin_m, g.k, g.c, float(g.a[0]), float(g.a[1] - g.a[0]), g.z,
                               float(g.b[0]), float(g.b[1] - g.b[0]), g.b.size, max_range_m, prim, t)
    return prim, t


def _bounce(front, caster, swell, fan, pos_local):
    """The rays that reached the swell, mirrored on their facets and cast through the scene (the leg S → P
    checked too): a dict of per-entry arrays, aligned with ``fan["up"]``."""
    m, buf = fan["up"].shape[0], front.buffers
    u, p, ur = (buf.take(k, (m, 3)) for k in ("swell_u", "swell_p", "swell_ur"))
    org, dr = buf.take("swell_borg", (m, 3), np.float32), buf.take("swell_bdir", (m, 3), np.float32)
    kernels.swell_launch(fan["up_start"], fan["up"], fan["dirs"], fan["t1"], fan["prim_s"], pos_local,
                         swell.compiled.face_normals, LEG_EPSILON_M, u, p, ur, org, dr)
    seen = buf.take("swell_seen", m)
    seen[:] = 1.0
    if m and _below_top(caster, float(pos_local[:, 2].min())):      # S → P through the scene
        block_legs(caster, buf, fan["up_start"], p, pos_local, True, u, fan["t1"][fan["up"]].astype(np.float64),
                   seen)
    prim, t2 = caster.cast_raw(org, dr, fan["max_range_m"])
    return dict(u=u, p=p, ur=ur, prim=prim, t2=t2, seen=seen)


def _paths(front, caster, swell, fan, b, rot, pos_local, rx_shift):
    """kernels.swell_paths over the bounced rays: a dict of its outputs (the one bounce without σ and legs)."""
    s, plan, c, buf = front.sonar, front.plan, caster.compiled, front.buffers
    m = fan["up"].shape[0]
    o = {k: buf.take("swell_" + k, m) for k in ("w1", "t1", "e1", "w2", "t2", "e2", "cos_i", "cos_s", "phi", "r")}
    o["x"], o["leg"] = buf.take("swell_x", (m, 3)), buf.take("swell_leg", (m, 3))
    o["mu"] = lambert_mu(c)                                        # Lambert's σ in the kernel
    o["want_phi"] = wants_azimuth(c) and o["mu"].shape[0] == 0
    kernels.swell_paths(fan["up_start"], fan["up"], fan["ray_start"], fan["el_start"], fan["s"], np.cos(fan["beta"]),
                        np.sin(fan["beta"]), fan["dbeta"], b["u"], b["p"], b["ur"], fan["t1"], fan["prim_s"], b["prim"],
                        b["t2"], b["seen"], swell.compiled.face_normals, c.face_normals,
                        np.ascontiguousarray(rot, dtype=np.float64), pos_local, rx_shift, plan.beam, plan.ds,
                        plan.min_range_m, front.two_way_np_per_m, plan.slope_cap_m_rad, s.sound_speed_m_s, _wave_kh(s),
                        fan["max_range_m"], LEG_EPSILON_M, o["want_phi"], o["mu"], c.face_object, o["x"], o["w1"],
                        o["t1"], o["e1"], o["w2"],
                        o["t2"], o["e2"], o["cos_i"], o["cos_s"], o["phi"], o["leg"], o["r"])
    return o


def swell_echoes(front, caster, rot, pos_local, max_range_m, ids, clock, rx_shift=None):
    """(one-bounce, two-bounce) Echoes of a block off the swell, in the rows of the image fan; ``rx_shift``
    (pings,) δ = 2·v_fwd/c when moving during the ping (None or zeros: stop-and-hop)."""
    rx_shift = np.zeros(rot.shape[0]) if rx_shift is None else np.ascontiguousarray(rx_shift, dtype=np.float64)
    swell = surface_caster(caster, front.sonar.environment.surface, max_range_m)
    fan = _image_fan(front, surface_strips(caster, front.sonar.environment.surface, max_range_m), caster, rot,
                     pos_local, max_range_m, clock, rx_shift)
    b = _bounce(front, caster, swell, fan, pos_local)
    o = _paths(front, caster, swell, fan, b, rot, pos_local, rx_shift)
    if o["mu"].shape[0] == 0:
        apply_bistatic(caster.compiled, front.sonar.frequency_hz, b["prim"], o["x"], o["w1"], o["cos_i"], o["cos_s"],
                       o["phi"] if o["want_phi"] else None)
    block_legs(caster, front.buffers, fan["up_start"], o["x"], pos_local, False, o["leg"], o["r"], o["w1"],  # X → S
               b["prim"])
    apply_laws(caster.compiled, front.sonar.frequency_hz, b["prim"], o["cos_i"], o["w2"], o["x"])
    out = []
    for w, t, ext in ((o["w1"], o["t1"], o["e1"]), (o["w2"], o["t2"], o["e2"])):
        obj = np.zeros(0, np.int32) if ids is None else np.where(w > 0, ids[np.maximum(b["prim"], 0)], -1).astype(
            np.int32)
        out.append(Echoes(2, fan["up_start"], t, ext, w, o["x"], obj))
    return out[0], out[1]
