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
"""
from __future__ import annotations

import numpy as np

from . import beam, kernels
from .echoes import Echoes, row_starts
from .fan import probe_rows
from .laws import apply_laws
from .multipath import LEG_EPSILON_M, bistatic_sigma, mirror_pose, occluded


def surface_caster(caster, surface, max_range_m: float):
    """An Embree caster of the swell's mesh over the scene's extent ± the range, in the scene's local frame.

    Kept with the scene's compiled arrays (built once per scene, surface and range).
    """
    from .raycast import RayCaster
    from .scene import Scene

    c = caster.compiled
    cache = c.__dict__.setdefault("_swell_casters", {})
    key = (surface, round(max_range_m, 6))
    if key not in cache:  # reflection points lie between the sonar and the scene: within its extent ± the range
        lo, hi = c.bounds_local[0, :2] + c.origin_m[:2], c.bounds_local[1, :2] + c.origin_m[:2]
        mesh = surface.mesh((lo[0] - max_range_m, hi[0] + max_range_m), (lo[1] - max_range_m, hi[1] + max_range_m))
        cache[key] = RayCaster(Scene().add(mesh, label="sea surface").compiled(c.origin_m))
    return cache[key]


def _gains(sonar, rot, side, u, shift=None):
    """(Γ, Γ_rx) of the channel's membrane (:func:`beam.directivity`) for world directions u (n, 3), rot (n, 3, 3)
    body → world, side −1 port, +1 starboard; Γ_rx takes the along-track cosine ``shift`` (n,) back (the receive
    beam moving during the ping, docs/physics.md §16), and is Γ itself when ``shift`` is None (stop-and-hop)."""
    e = np.einsum("nji,nj->ni", rot, u)                              # body: forward, starboard, down
    ct, st = np.cos(sonar.tilt_rad), np.sin(sonar.tilt_rad)
    height, bore = e[:, 2] * ct - side * e[:, 1] * st, side * e[:, 1] * ct + e[:, 2] * st
    k, lx, ly = sonar.wavenumber_rad_m, sonar.length_m, sonar.height_m
    g = beam.directivity(e[:, 0], height, bore, k, lx, ly)
    return g, (g if shift is None else beam.directivity(e[:, 0] - shift, height, bore, k, lx, ly))


def _bounce(front, caster, swell, rot, pos_local, max_range_m, clock):
    """The image fan's rays bounced on the swell: a dict of per-ray arrays of the rays that reach the scene."""
    plan = front.plan
    z_s = front.sonar.environment.surface.z_m - float(caster.compiled.origin_m[2])
    rot_i, pos_i = mirror_pose(rot, pos_local, z_s)
    # a one-bounce echo at range (R + r)/2 in the window may have travelled R up to twice the range on its bounce
    max_range_m = 2.0 * (max_range_m * (1.0 + 1e-3) + 0.05)
    el_start, beta, dbeta, _, t_probe = probe_rows(caster, plan, rot_i, pos_i, max_range_m)
    n_az, rows = plan.s.shape[0], el_start.shape[0] - 1
    n, per_row = n_az * int(el_start[-1]), n_az * np.diff(el_start)
    dirs, org = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32)
    kernels.fan_rays(plan.s, np.cos(beta), np.sin(beta), el_start, np.ascontiguousarray(rot_i), pos_i, dirs, org)
    dirs[:, 2] *= -1.0                                                # the real, upward ray (negation: exact)
    s_org32 = np.repeat(pos_local.astype(np.float32)[np.arange(rows) // 2], per_row, axis=0)
    prim_s, t1 = swell.cast_raw(s_org32, dirs, max_range_m)
    up = np.flatnonzero((prim_s >= 0) & (dirs[:, 2] > 0))            # per-ray bookkeeping only for these
    row = np.searchsorted(n_az * el_start, up, side="right") - 1
    u, s_org = dirs[up].astype(np.float64), pos_local[row // 2]
    t1 = t1[up].astype(np.float64)
    seen = ~occluded(caster, s_org, u, t1)                            # S→P through the scene
    up, row, u, s_org, t1 = up[seen], row[seen], u[seen], s_org[seen], t1[seen]
    j = up - n_az * el_start[row]
    n_el = np.diff(el_start)[row]
    cell = el_start[row] + j % n_el
    n_p = swell.compiled.face_normals[prim_s[up]]
    u_r = u - 2.0 * np.sum(u * n_p, axis=1)[:, None] * n_p
    p = s_org + t1[:, None] * u
    prim, t2 = caster.cast_raw((p + LEG_EPSILON_M * u_r).astype(np.float32), u_r.astype(np.float32), max_range_m)
    hit = (prim >= 0) & (t1 + t2 + LEG_EPSILON_M <= max_range_m)
    clock["embree"] = clock.get("embree", 0.0) + t_probe
    return dict(ray=up[hit], row=row[hit], s=plan.s[(j // n_el)[hit]], beta=beta[cell[hit]], dbeta=dbeta[cell[hit]],
                u=u[hit], n_p=n_p[hit], u_r=u_r[hit], R=(t1 + LEG_EPSILON_M + t2)[hit], prim=prim[hit],
                x=p[hit] + (LEG_EPSILON_M + t2[hit])[:, None] * u_r[hit], ray_start=n_az * el_start, rot_i=rot_i)


def _footprint(b, rot_i, n_x, cos_i):
    """dX/dβ of each bounced ray on the surface it hit, (n, 3) m/rad (the facet's image is a straight ray)."""
    side = np.where(b["row"] % 2 == 1, 1.0, -1.0)
    cpsi = np.sqrt(1.0 - b["s"] ** 2)
    f_body = np.stack([0.0 * cpsi, -side * cpsi * np.sin(b["beta"]), cpsi * np.cos(b["beta"])], axis=1)
    f = np.einsum("nij,nj->ni", rot_i[b["row"] // 2], f_body) * [1.0, 1.0, -1.0]   # ∂u/∂β of the real ray
    f_r = f - 2.0 * np.sum(f * b["n_p"], axis=1)[:, None] * b["n_p"]
    nf = np.sum(n_x * f_r, axis=1)
    return b["R"][:, None] * (f_r + b["u_r"] * (nf / np.maximum(cos_i, 1e-12))[:, None])


def _two_bounce(front, caster, b, g_u, rs2, cos_i, dx, shift=None):
    """S→P→X→P→S: the flat image path's weight with the unfolded range R (law applied); ``g_u`` (Γ, Γ_rx) of the
    launch directions (:func:`_gains`), ``shift`` (n,) δ of each echo's ping when moving during the ping (None:
    stop-and-hop)."""
    plan, s = front.plan, front.sonar
    g, g_rx = g_u
    g4 = g ** 4 if shift is None else g ** 2 * g_rx ** 2
    w = (g4 * np.exp(-front.two_way_np_per_m * b["R"]) * rs2 ** 2 * plan.ds * b["dbeta"]
         / np.maximum(b["R"], plan.min_range_m) ** 2)
    w = np.where(cos_i > 1e-9, w, 0.0)
    apply_laws(caster.compiled, s.frequency_hz, b["prim"], np.maximum(cos_i, 1e-9), w, b["x"])
    slope = np.minimum(np.abs(np.sum(b["u_r"] * dx, axis=1)), plan.slope_cap_m_rad)   # |dR/dβ|, R unfolded
    return w, 2.0 * b["R"] / s.sound_speed_m_s, 2.0 * slope * b["dbeta"] / s.sound_speed_m_s


def _azimuth(u_in, u_out, n_x, cos_i, cos_s):
    """Bistatic azimuth φ: the angle between −u_in and −u_out projected on the facet (0 when either is along n_x)."""
    bb = -u_in - cos_i[:, None] * n_x
    tt = -u_out - cos_s[:, None] * n_x
    nb, nt = np.linalg.norm(bb, axis=1), np.linalg.norm(tt, axis=1)
    ok = (nb > 1e-12) & (nt > 1e-12)
    return np.where(ok, np.arccos(np.clip(np.sum(bb * tt, axis=1) / np.where(ok, nb * nt, 1.0), -1, 1)), 0.0)


def _one_bounce(front, caster, b, rot, side, g_u, rs2, cos_i, dx, pos_local, shift=None):
    """S→P→X→S and S→X→P→S: the bounced ray in, the direct leg back, one echo of twice the weight (each with its
    own receive beam when moving during the ping: ``shift`` (n,) δ, None: stop-and-hop); ``rot`` (n, 3, 3) and
    ``side`` (n,) of each echo's ping and channel, ``g_u`` (Γ, Γ_rx) of its launch direction."""
    plan, s, c = front.plan, front.sonar, caster.compiled
    d = b["x"] - pos_local[b["row"] // 2]
    r = np.linalg.norm(d, axis=1)
    u_d = d / r[:, None]
    n_x = c.face_normals[b["prim"]]
    cos_s = -np.sum(n_x * u_d, axis=1)
    lit = (cos_i > 1e-9) & (cos_s > 1e-9)
    phi = _azimuth(b["u_r"], u_d, n_x, cos_i, cos_s)[lit] if any(getattr(law, "uses_azimuth", True)
                                                                 for law in c.laws) else 0.0
    sigma = np.zeros(r.shape[0])
    sigma[lit] = bistatic_sigma(c, s.frequency_hz, b["prim"][lit], cos_i[lit], cos_s[lit], phi)
    (g, g_rx), (gd, gd_rx) = g_u, _gains(s, rot, side, u_d, shift)
    g2 = 2.0 * g ** 2 * gd ** 2 if shift is None else g ** 2 * gd_rx ** 2 + gd ** 2 * g_rx ** 2
    w = (g2 * sigma * rs2 * np.exp(-0.5 * front.two_way_np_per_m * (b["R"] + r)) * plan.ds * b["dbeta"]
         / (np.maximum(r, plan.min_range_m) ** 2 * np.maximum(cos_i, 1e-9)))
    for detail in (c.maps, c.textures):
        if detail is not None:
            detail.apply(c, b["prim"], b["x"], w)
    on = np.flatnonzero(w > 0)
    w[on[occluded(caster, b["x"][on], -u_d[on], r[on])]] = 0.0        # the direct leg X→S
    slope = np.minimum(np.abs(np.sum((b["u_r"] + u_d) * dx, axis=1)), 2.0 * plan.slope_cap_m_rad)
    return w, (b["R"] + r) / s.sound_speed_m_s, slope * b["dbeta"] / s.sound_speed_m_s


def swell_echoes(front, caster, rot, pos_local, max_range_m, ids, clock, rx_shift=None):
    """(one-bounce, two-bounce) Echoes of a block off the swell, in the rows of the image fan; ``rx_shift``
    (pings,) δ = 2·v_fwd/c when moving during the ping (None or zeros: stop-and-hop)."""
    swell = surface_caster(caster, front.sonar.environment.surface, max_range_m)
    b = _bounce(front, caster, swell, rot, pos_local, max_range_m, clock)
    n_x = caster.compiled.face_normals[b["prim"]]
    cos_i = -np.sum(n_x * b["u_r"], axis=1)
    rs2 = front.sonar.environment.surface.reflection_intensity(np.abs(np.sum(b["u"] * b["n_p"], axis=1)),
                                                               front.sonar.wavenumber_rad_m)
    dx = _footprint(b, b["rot_i"], n_x, cos_i)
    start = row_starts(b["row"], b["ray_start"].shape[0] - 1)
    rot = np.asarray(rot, dtype=np.float64)[b["row"] // 2]
    side = np.where(b["row"] % 2 == 1, 1.0, -1.0)
    shift = None if rx_shift is None or not np.any(rx_shift) else np.asarray(rx_shift)[b["row"] // 2]
    g_u = _gains(front.sonar, rot, side, b["u"], shift)              # the launch direction's, shared by both paths
    out = []
    for w, t, ext in (_one_bounce(front, caster, b, rot, side, g_u, rs2, cos_i, dx, pos_local, shift),
                      _two_bounce(front, caster, b, g_u, rs2, cos_i, dx, shift)):
        obj = np.zeros(0, np.int32) if ids is None else np.where(w > 0, ids[b["prim"]], -1).astype(np.int32)
        out.append(Echoes(2, start, t, ext, w, b["x"], obj))
    return out[0], out[1]
