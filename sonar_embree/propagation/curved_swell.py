"""A swell over a sound-speed profile: the surface's paths along curved rays (docs/physics.md §13c).

The swell's rays (:mod:`sonar_embree.propagation.swell`: the image fan's upward rays, placed as for straight rays)
climb the profile in closed form to the band of the swell's troughs, run straight through it to the swell's mesh,
are mirrored in their facet, run straight back down to the band and are marched through the scene along the
profile (:mod:`sonar_embree.kernels.curved_swell`, :func:`~sonar_embree.propagation.refraction.march`). Per hit X:

- two bounces (S → P → X → P → S): w2 = Γ²(u)·Γ²_rx(u)·|R_s|⁴·e^(−α'L)·ds·dβ / max(A, R_min²) × σ(θi)/cos θi, at 2T,
  A the bounced tube's cross-section per steradian at X (the chain's closed forms differentiated, the facet a flat
  mirror as for straight rays) and L, T the path's length and one-way time;
- one bounce (S → P → X → S and back the other way, one echo): the direct leg X → S is the profile's unturned
  eigenray (tube area A_d at X), w1 = (Γ²(u)·Γ²_rx(u_d) + Γ²(u_d)·Γ²_rx(u))·|R_s|²·e^(−α'(L + L_d)/2)·ds·dβ /
  (max(A_d, R_min²)·cos θi) × σ(θi, θs, φ), at T + T_d.

Both legs from the sonar and from X back to it are checked for blocking along their chords, as under a flat surface
(§12b). The rays aimed at objects give their direct path only (as over a profile under a flat surface); labels
are refused with a profile. Speckle phases use the hits' straight distances (statistics, not the exact pattern).
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from ..kernels.curved_swell import (DIRECT_WIDTH, D_PATH, D_SIN_DST, D_SIN_SRC, D_SPREAD, D_TIME, D_XI, U_PATH,
                                    U_TIME, UP_WIDTH)
from ..laws import apply_laws
from .buffers import Buffers
from .curved_surface import knots
from .echoes import Echoes
from .fan import ray_cells
from .gain import weigh_by_beam, weigh_pairs
from .multipath import apply_bistatic, block_legs, wants_azimuth, wave_kh
from .refraction import SAGITTA_FRACTION, Marching, march
from .swell import image_fan, surface_hits, up_lines
from ..kernels.args import Fan

#: The image fan's rays are placed densely out to this many times the window (straight probes stand for the curved
#: paths, whose apparent ranges differ by the profile's spread of c and the bending).
PLACEMENT_MARGIN = 1.05


def swell_echoes(front, run, rot, pos_local, max_range_m, ids, clock, rx_shift=None):
    """(one-bounce, two-bounce) Echoes of a block off the swell over the medium's profile, in the rows of the
    image fan's upward rays, and each ray's azimuth line (:func:`~sonar_embree.propagation.swell.up_lines`); ``ids``
    each triangle's object id (None: not wanted), ``rx_shift`` (pings,) δ = 2·v_fwd/c (None: stop-and-hop)."""
    rx_shift = np.zeros(rot.shape[0]) if rx_shift is None else np.ascontiguousarray(rx_shift, dtype=np.float64)
    rot = np.ascontiguousarray(rot, dtype=np.float64)
    # placed from straight probes: a margin for the curved paths' longer or shorter ranges (the window itself is cut
    # by their times below)
    fan = image_fan(front, run.surface_strips, run.caster, rot, pos_local, PLACEMENT_MARGIN * max_range_m, clock,
                     rx_shift)
    fan["up"] = fan["rising"]                                      # every upward ray: the profile bends them
    fan["up_start"] = np.searchsorted(fan["up"], fan["ray_start"]).astype(np.int64)
    rays = _launch(front, fan, rot)
    legs = _bounce(front, run, rays, pos_local, max_range_m, clock)
    one, two = _weights(front, run, rays, legs, rot, pos_local, rx_shift, max_range_m)
    start = fan["up_start"]
    obj = [np.zeros(0, np.int32) if ids is None else
           np.where(w > 0, ids[np.maximum(legs["prim"], 0)], -1).astype(np.int32) for w in (one[0], two[0])]
    return (Echoes(2, start, one[1], one[2], one[0], legs["x"], obj[0]),
            Echoes(2, start, two[1], two[2], two[0], legs["x"], obj[1]), up_lines(fan))


def _launch(front, fan, rot):
    """The upward rays' cells: body direction (m, 3), world direction (m, 3), row, s, β, dβ, and the layout rows
    (s, cos β, sin β, dβ, ds) the beam reads, aligned with ``fan["up"]``."""
    body, row, dbeta = ray_cells(fan["s"], fan["el_start"], fan["beta"], fan["dbeta"])
    up = fan["up"]
    body, row, dbeta = body[up], row[up], dbeta[up]
    side = np.where(row % 2 == 1, 1.0, -1.0)
    cpsi = np.sqrt(1.0 - body[:, 0] ** 2)
    cos_b, sin_b = side * body[:, 1] / cpsi, body[:, 2] / cpsi
    world = np.einsum("nij,nj->ni", rot[row // 2], body)
    ds = np.broadcast_to(np.asarray(front.plan.ds, dtype=np.float64), row.shape)
    layout = np.ascontiguousarray(np.column_stack([body[:, 0], cos_b, sin_b, dbeta, ds]))
    return dict(body=body, world=np.ascontiguousarray(world), row=row, beta=np.arctan2(sin_b, cos_b), layout=layout,
                start=fan["up_start"])


def _profile(front, run):
    """(knots z, speeds c, local z of depth 0, depth of the band) of the run's medium."""
    env = front.sonar.environment
    z, c = knots(env.sound_speed)
    z0 = env.profile_origin_z_m() - float(run.compiled.origin_m[2])
    return z, c, z0, env.surface.z_m - env.surface.lowest_z_m


def _bounce(front, run, rays, pos_local, max_range_m, clock):
    """Each upward ray climbed to the band, bounced off the swell and marched down through the scene: a dict of the
    hits (x, prim, arrival, c at X), the chain's totals (time_s, path_m one way), the surface points and facets."""
    z, c, z0, d_band = _profile(front, run)
    n = rays["row"].shape[0]
    up = np.empty((n, UP_WIDTH))
    kernels.swell_up_legs(rays["world"], rays["row"] // 2, pos_local, z, c, z0, d_band, up)
    ok = np.isfinite(up[:, U_TIME])
    org, dirs = up[:, :3].astype(np.float32), up[:, 3:6].astype(np.float32)
    org[~ok], dirs[~ok] = 0.0, (0.0, 0.0, -1.0)                  # turned before the band: meets no facet
    facet, dist = surface_hits(Buffers(), run.compiled.origin_m, run.surface_strips, org, dirs, max_range_m)
    facet = np.where(ok, facet, -1).astype(np.int32)
    p, ur, q2, band = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    normals = run.surface_caster.compiled.face_normals
    kernels.swell_bounce(up, facet, dist, normals, z0 - d_band, p, ur, q2, band)
    live = np.flatnonzero(np.isfinite(band))
    hits = _march_down(front, run, q2[live], ur[live], max_range_m, clock)
    c_band = float(np.interp(d_band, z, c))
    prim = np.full(n, -1, np.int32)
    x, arrival, c_x = np.zeros((n, 3)), np.zeros((n, 3)), np.ones(n)
    time_s, path_m = np.full(n, np.inf), np.full(n, np.inf)
    got = live[hits[0] >= 0]
    h = hits[1][hits[0] >= 0]
    prim[got], x[got], arrival[got], c_x[got] = hits[0][hits[0] >= 0], h[:, 0:3], h[:, 3:6], h[:, 12]
    time_s[got] = up[got, U_TIME] + band[got] / c_band + h[:, 6]
    path_m[got] = up[got, U_PATH] + band[got] + h[:, 7]
    facets = np.column_stack([p, normals[np.maximum(facet, 0)], np.full(n, d_band)])
    return dict(prim=prim, x=x, arrival=arrival, c_x=c_x, time_s=time_s, path_m=path_m, p=p, facets=facets,
                band_dir=up[:, 3:6], z=z, c=c, z0=z0)


def _march_down(front, run, origins, dirs, max_range_m, clock):
    """(triangle (k,) int32, hit (k, HIT_WIDTH)) of the mirrored rays marched from the band through the scene within
    twice the window (a one-bounce path may have travelled that far on its bounce)."""
    s = front.sonar
    m = Marching.of(run.caster, s.environment, SAGITTA_FRACTION * s.range_bin_m,
                    2.0 * (max_range_m * (1.0 + 1e-3) + 0.05) / s.sound_speed_m_s)
    k = origins.shape[0]
    buffers = Buffers()
    state, lay = buffers.take("state", (k, kernels.STATE_WIDTH)), buffers.take("lay", k, np.int64)
    ray = buffers.take("ray", (k, kernels.RAY_WIDTH))
    kernels.arc_start_at(np.ascontiguousarray(origins), np.ascontiguousarray(dirs), m.layers, m.z0, m.box_z, m.l_max,
                         state, lay, ray)
    hit_prim, hit, _ = march(run.caster, m, state, lay, ray, clock, buffers)
    return hit_prim, hit.copy()


def _weights(front, run, rays, legs, rot, pos_local, rx_shift, max_range_m):
    """((w, t, extent) of the one bounce, the same of the two bounces), (n,) each, aligned with the upward rays."""
    s, plan, cmp = front.sonar, front.plan, run.compiled
    t_win = (max_range_m * (1.0 + 1e-3) + 0.05) / s.sound_speed_m_s       # one way
    prim, x, a = legs["prim"], legs["x"], legs["arrival"]
    nrm = cmp.face_normals[np.maximum(prim, 0)]
    dn = np.einsum("ij,ij->i", nrm, a)
    n_f = np.where((dn > 0.0)[:, None], -nrm, nrm)                        # facing the arrival
    cos_i = np.where(dn > 0.0, np.where(cmp.face_two_sided[np.maximum(prim, 0)], dn, -dn), -dn)
    lit = (prim >= 0) & (cos_i > 1e-9) & (legs["time_s"] <= 2.0 * t_win)
    area, d_f = _tube(rays, legs, rot, pos_local, lit, n_f)
    lit &= np.isfinite(area)
    slope = np.abs(np.einsum("ij,ij->i", a, d_f)) / legs["c_x"]          # one-way s per rad of β
    sg = np.abs(np.einsum("ij,ij->i", legs["band_dir"], legs["facets"][:, 3:6]))
    cap = plan.slope_cap_m_rad / s.sound_speed_m_s
    cell = rays["layout"][:, 3] * rays["layout"][:, 4]
    two = _two_bounce(front, run, rays, legs, lit & (legs["time_s"] <= t_win), area, cos_i, cell, slope, cap, sg,
                      rx_shift)
    direct = _direct(legs, pos_local, rays["row"] // 2, lit)
    one = _one_bounce(front, run, rays, legs, direct, lit, n_f, cos_i, cell, d_f, cap, sg, rot, rx_shift, t_win)
    for w in (one[0], two[0]):                                           # the leg up from the sonar, its chord
        _block(run, rays["start"], pos_local[rays["row"] // 2], legs["p"], pos_local, w, None)
    _block(run, rays["start"], x, pos_local[rays["row"] // 2], pos_local, one[0], prim)    # X back to the sonar
    return one, two


def _tube(rays, legs, rot, pos_local, lit, n_f):
    """(A (n,), ∂X/∂β on the hit's facet (n, 3)) of the bounced ray tubes (kernels.swell_tubes), NaN where not lit."""
    n = lit.shape[0]
    hits = np.column_stack([legs["x"], legs["arrival"], legs["z0"] - legs["x"][:, 2]])
    hits[~lit, 6] = np.nan
    tube = np.empty((n, 4))
    sonar = np.column_stack([pos_local, np.full(pos_local.shape[0], legs["z0"])])
    kernels.swell_tubes(np.ascontiguousarray(np.column_stack([rays["body"][:, 0], rays["beta"]])), rays["row"], rot,
                        sonar, legs["z"], legs["c"], np.ascontiguousarray(legs["facets"]), hits, tube)
    d, a = tube[:, 1:4], legs["arrival"]
    na = np.einsum("ij,ij->i", n_f, a)
    d_f = d - a * (np.einsum("ij,ij->i", n_f, d) / np.where(na != 0.0, na, np.inf))[:, None]
    return tube[:, 0], d_f


def _two_bounce(front, run, rays, legs, lit, area, cos_i, cell, slope, cap, sg, rx_shift):
    """(w, t, extent) of S → P → X → P → S: |R_s|⁴·e^(−α'L)·ds·dβ / max(A, R_min²), then the beam Γ²·Γ²_rx of the launch
    direction and the law σ(θi)/cos θi."""
    kh, r_min = wave_kh(front.sonar), front.plan.min_range_m
    w = np.zeros(lit.shape[0])
    w[lit] = (np.exp(-front.two_way_np_per_m * legs["path_m"][lit] - 8.0 * kh * kh * sg[lit] ** 2) * cell[lit]
              / np.maximum(area[lit], r_min * r_min))
    _beam(front, rays, rx_shift, w)
    apply_laws(run.law_table, run.compiled, legs["prim"], cos_i, w, legs["x"])
    t = np.where(w > 0, 2.0 * legs["time_s"], np.inf)
    ext = np.where(w > 0, 2.0 * np.minimum(slope, cap) * rays["layout"][:, 3], 0.0)
    return w, t, ext


def _beam(front, rays, rx_shift, w):
    """w × Γ²(u)·Γ²_rx(u) of each ray's launch direction (the beam after the kernels)."""
    plan = front.plan
    z = np.zeros(0)
    weigh_by_beam(plan.pattern, plan.tilt_rad, Fan(plan.s, plan.ds, z, z, z, rays["start"]), rx_shift, w,
                  rays["layout"])


def _direct(legs, pos_local, ping, lit):
    """The direct legs S → X of the lit hits (kernels.direct_eigenrays): a dict of the eigenrays' columns and their
    world directions at S (``u``) and at X (``a``), (n, 3)."""
    n = lit.shape[0]
    s = pos_local[ping]
    rel = legs["x"][:, :2] - s[:, :2]
    x_h = np.hypot(rel[:, 0], rel[:, 1])
    d_src, d_dst = legs["z0"] - s[:, 2], legs["z0"] - legs["x"][:, 2]
    d_dst = np.where(lit, d_dst, d_src)                                 # equal depths: skipped
    out = np.empty((n, DIRECT_WIDTH))
    kernels.direct_eigenrays(legs["z"], legs["c"], np.ascontiguousarray(d_src), np.ascontiguousarray(d_dst),
                             np.ascontiguousarray(x_h), out)
    h = rel / np.maximum(x_h, 1e-300)[:, None]
    down = np.where(d_dst > d_src, -1.0, 1.0)                           # world z of travel from S to X
    cos_src, cos_dst = np.sqrt(1.0 - out[:, D_SIN_SRC] ** 2), np.sqrt(1.0 - out[:, D_SIN_DST] ** 2)
    u = np.column_stack([h * cos_src[:, None], down * out[:, D_SIN_SRC]])
    a = np.column_stack([h * cos_dst[:, None], down * out[:, D_SIN_DST]])
    return dict(ok=lit & np.isfinite(out[:, D_XI]), time_s=out[:, D_TIME], path_m=out[:, D_PATH],
                spread=out[:, D_SPREAD], u=u, a=a)


def _one_bounce(front, run, rays, legs, direct, lit, n_f, cos_i, cell, d_f, cap, sg, rot, rx_shift, t_win):
    """(w, t, extent) of S → P → X → S and back (one echo): |R_s|²·e^(−α'(L + L_d)/2)·ds·dβ / (max(A_d, R_min²)·
    cos θi), the gains of both launch directions and σ(θi, θs, φ)."""
    kh, r_min, cmp = wave_kh(front.sonar), front.plan.min_range_m, run.compiled
    cos_s = -np.einsum("ij,ij->i", n_f, direct["a"])
    ok = direct["ok"] & (cos_s > 1e-9) & (legs["time_s"] + direct["time_s"] <= 2.0 * t_win)
    w = np.zeros(lit.shape[0])
    w[ok] = (np.exp(-0.5 * front.two_way_np_per_m * (legs["path_m"][ok] + direct["path_m"][ok])
                    - 4.0 * kh * kh * sg[ok] ** 2) * cell[ok]
             / (np.maximum(direct["spread"][ok], r_min * r_min) * cos_i[ok]))
    weigh_pairs(front.plan.pattern, front.plan.tilt_rad, rays["start"], rays["body"], direct["u"],
                np.ascontiguousarray(rot, dtype=np.float64), rx_shift, w)   # out along one leg, back the other
    phi = _azimuth(n_f, legs["arrival"], -direct["a"]) if wants_azimuth(cmp) else None
    apply_bistatic(cmp, run.laws, legs["prim"], legs["x"], w, cos_i, cos_s, phi)
    a = legs["arrival"] + direct["a"]
    t = np.where(w > 0, legs["time_s"] + direct["time_s"], np.inf)
    ext = np.where(w > 0, np.minimum(np.abs(np.einsum("ij,ij->i", a, d_f)) / legs["c_x"], 2.0 * cap)
                   * rays["layout"][:, 3], 0.0)
    return w, t, ext


def _azimuth(n, u, v):
    """Angle between −u and v, both projected on the plane of normal n (n, 3) (0 when either is along n)."""
    b = -u + n * np.einsum("ij,ij->i", n, u)[:, None]
    t = v - n * np.einsum("ij,ij->i", n, v)[:, None]
    bb, tt = np.einsum("ij,ij->i", b, b), np.einsum("ij,ij->i", t, t)
    cos = np.einsum("ij,ij->i", b, t) / np.sqrt(np.maximum(bb * tt, 1e-300))
    return np.where((bb > 1e-24) & (tt > 1e-24), np.arccos(np.clip(cos, -1.0, 1.0)), 0.0)


def _block(run, start, frm, to, pos_local, w, prim):
    """Zero ``w`` where the chord from ``frm`` to ``to`` (n, 3) is blocked: from the sonar (``prim`` None) or from
    each hit point (its own height field passed over where it cannot block, ``prim``)."""
    lit = np.flatnonzero(w > 0)
    leg = to[lit] - frm[lit]
    dist, dirs = np.zeros(w.shape[0]), np.zeros((w.shape[0], 3))
    dist[lit] = np.linalg.norm(leg, axis=1)
    dirs[lit] = leg / np.maximum(dist[lit], 1e-300)[:, None]
    block_legs(run, Buffers(), start, np.ascontiguousarray(frm), pos_local, prim is None, dirs, dist, w, prim, False)
