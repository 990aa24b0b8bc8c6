"""Kernels of the object-aimed rays (docs/physics.md §7b): which objects each row's beam can see, the lattice of
rays aimed at each and the fan's hits those lattices replace (their echoes are the fan's kernel's,
:func:`~.rays.fan_echoes` with each ray's own layout).

A row is (ping, side) as in the fan (r = 2·b + side). Its body-frame directions are
(s, side·√(1 − s²)·cos β, √(1 − s²)·sin β), whose solid angle element is exactly ds·dβ; an object's lattice is a
uniform grid of cells in (s, β) tiling the part of the object's bounding cone inside the row's span, so its
weights are exact solid angles, as the fan's are.
"""
from __future__ import annotations

import math

from ._numba import njit, prange

#: Columns of the lattice table: first s, s step, first β, β step (rad), rays in s, rays in β.
S0, HS, B0, HB, NS, NB = range(6)
LATTICE_WIDTH = 6
#: Columns of an aimed ray's layout: s, cos β, sin β, dβ, ds.
LAYOUT_WIDTH = 5


@njit(cache=True, nogil=True)
def _lattice(v0, v1, v2, up0, up1, up2, side, radius, span, rx, n_across, dr_m, max_rays, out):
    """The lattice of one object (bounding sphere of ``radius`` at body-frame offset v) in one row; NS = 0 when it
    gets none (out of range or span, the sonar inside its sphere, or too big to aim at: the fan sees it).
    ``span`` = (s_lo, s_hi, β_lo, β_hi, max range, along-track step cap, elevation step cap, κ); ``rx`` the row's
    receive shift δ (the span widens to cover the receive lobe too); ``up`` the world's vertical in the body frame.

    Curved rays (κ > 0, the largest ray curvature |dc/dz|/c of a sound-speed profile, 1/m) stay in their launch
    direction's vertical plane and leave within κ·L/2 of their chord over a path L (the tangent turns by at most
    κ per metre; the chord is its mean): the cone widens by ``bend`` = 0.6·κ·(D + ρ) in elevation, mapped to s
    and β by the elevation direction's body components (and bend² for what that linearisation leaves out)."""
    out[NS] = 0.0
    out[NB] = 0.0
    d = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if d <= radius * (1.0 + 1e-9) or d - radius > span[4]:
        return
    sin_g = radius / d
    gam = math.asin(sin_g)
    sc = v0 / d
    cpsi = math.sqrt(max(1.0 - sc * sc, 0.0))
    if sin_g >= 0.999 * cpsi:                       # the cone holds the along-track axis: no β interval
        return
    dbeta = math.asin(sin_g / cpsi)
    half_s = gam
    bend = 0.6 * span[7] * (d + radius)
    if bend > 0.0:                                  # curved rays: widen along the elevation direction
        zu = (up0 * v0 + up1 * v1 + up2 * v2) / d
        e_s = abs(up0 - zu * sc) / max(math.sqrt(max(1.0 - zu * zu, 0.0)), 1e-12)
        half_s += min(e_s, 1.0) * bend + bend * bend
        dbeta += bend / cpsi + bend * bend
    bc = math.atan2(v2, side * v1)
    s_lo = max(sc - half_s, span[0] + min(rx, 0.0))
    s_hi = min(sc + half_s, span[1] + max(rx, 0.0))
    b_lo = max(bc - dbeta, span[2])
    b_hi = min(bc + dbeta, span[3])
    if not (s_hi > s_lo and b_hi > b_lo):
        return
    h = 2.0 * gam / n_across
    hs = min(h, span[5])
    hb = min(h, span[6], 2.0 * gam * dr_m / (2.0 * radius))  # rays every dr in range over the object's depth
    ns = math.ceil((s_hi - s_lo) / hs - 1e-9)
    nb = math.ceil((b_hi - b_lo) / hb - 1e-9)
    if ns * nb > max_rays:                          # too big to aim at: the fan's own rays see it
        return
    out[S0] = s_lo
    out[HS] = (s_hi - s_lo) / ns
    out[B0] = b_lo
    out[HB] = (b_hi - b_lo) / nb
    out[NS] = ns
    out[NB] = nb


@njit(cache=True, nogil=True)  # rows × objects of a few flops each: serial (a parallel kernel compiles slower)
def aim_lattices(centre, radius, rot, pos, sides, span, rx_shift, n_across, dr_m, max_rays, table):
    """The lattice of every candidate object in every row of a block.

    Parameters
    ----------
    centre : (k, 3) float64
        Bounding-sphere centres of the candidate objects, local frame, m.
    radius : (k,) float64
        Their radii, m.
    rot : (pings, 3, 3) float64
        Body-to-world rotations.
    pos : (pings, 3) float64
        Sonar positions, local frame, m.
    sides : (2,) bool
        Which sides (port, starboard) have rays.
    span : (8,) float64
        s_lo, s_hi (the fan's along-track cells), β_lo, β_hi (its elevation span, rad), the range searched (m),
        the largest along-track step (the fan's ds), the largest elevation step (rad) and the largest ray
        curvature κ (1/m; 0: straight rays).
    rx_shift : (pings,) float64
        δ per ping (motion during the ping): the span reaches δ further on that side.
    n_across : float
        Rays across an object's bounding cone (each direction).
    dr_m : float
        Wanted range step between neighbouring elevation rays on an object, m.
    max_rays : float
        An object needing more rays than this in a row is left to the fan.
    table : (2·pings, k, LATTICE_WIDTH) float64
        Written: each lattice (:data:`S0` … :data:`NB`); NS = 0 where none.
    """
    for r in range(table.shape[0]):
        b = r // 2
        side = 1.0 if r % 2 else -1.0
        for k in range(table.shape[1]):
            table[r, k, NS] = 0.0
            table[r, k, NB] = 0.0
            if not sides[r % 2]:
                continue
            w0 = centre[k, 0] - pos[b, 0]
            w1 = centre[k, 1] - pos[b, 1]
            w2 = centre[k, 2] - pos[b, 2]
            v0 = rot[b, 0, 0] * w0 + rot[b, 1, 0] * w1 + rot[b, 2, 0] * w2    # Rᵀ·w: body frame
            v1 = rot[b, 0, 1] * w0 + rot[b, 1, 1] * w1 + rot[b, 2, 1] * w2
            v2 = rot[b, 0, 2] * w0 + rot[b, 1, 2] * w1 + rot[b, 2, 2] * w2
            _lattice(v0, v1, v2, rot[b, 2, 0], rot[b, 2, 1], rot[b, 2, 2], side, radius[k], span, rx_shift[b], n_across,
                     dr_m, max_rays, table[r, k])


@njit(cache=True, nogil=True)
def _direction(table, r, k, j):
    """(s, cos β, sin β, side) of ray j of lattice (r, k): s-major, β fastest."""
    nb = int(table[r, k, NB])
    sa = table[r, k, S0] + (j // nb + 0.5) * table[r, k, HS]
    be = table[r, k, B0] + (j % nb + 0.5) * table[r, k, HB]
    return sa, math.cos(be), math.sin(be), 1.0 if r % 2 else -1.0


@njit(cache=True, nogil=True, parallel=True)
def aim_rays(table, start, rot, pos, dirs, origins, layout):
    """Float32 origins and world directions of every aimed ray of a block.

    Parameters
    ----------
    table : (rows, k, LATTICE_WIDTH) float64
        The lattices (:func:`aim_lattices`).
    start : (rows·k + 1,) int64
        Offset of lattice (r, k)'s rays at r·k + k (its NS·NB rays).
    rot, pos
        As for :func:`aim_lattices`.
    dirs, origins : (start[-1], 3) float32
        Written.
    layout : (start[-1], LAYOUT_WIDTH) float64
        Written with each ray's s, cos β, sin β, dβ and ds (what the paths built on a direct hit need of its ray:
        a beamformer's line interpolation, the one-bounce surface path).
    """
    n_k = table.shape[1]
    for r in prange(table.shape[0]):
        b = r // 2
        for k in range(n_k):
            base = start[r * n_k + k]
            for j in range(start[r * n_k + k + 1] - base):
                sa, cb, sb, side = _direction(table, r, k, j)
                layout[base + j, 0] = sa
                layout[base + j, 1] = cb
                layout[base + j, 2] = sb
                layout[base + j, 3] = table[r, k, HB]
                layout[base + j, 4] = table[r, k, HS]
                cpsi = math.sqrt(1.0 - sa * sa)
                d0, d1, d2 = sa, side * cpsi * cb, cpsi * sb
                for q in range(3):
                    dirs[base + j, q] = rot[b, q, 0] * d0 + rot[b, q, 1] * d1 + rot[b, q, 2] * d2
                    origins[base + j, q] = pos[b, q]


@njit(cache=True, nogil=True, parallel=True)
def drop_aimed(ray_start, prim, face_object, cand_of_object, aimed, weight):
    """Zero, in place, the weight of every fan ray whose first hit is on an object its row aims at (the aimed
    lattice counts that part of the integral instead: no double counting).

    Parameters
    ----------
    ray_start : (rows + 1,) int64
        The fan's row offsets.
    prim : (n,) int32
        The fan's hits.
    face_object : (f,) int32
    cand_of_object : (n_objects,) int32
        Candidate index of each object, −1 for none.
    aimed : (rows, k) bool
        Which candidates each row aims at.
    weight : (n,) float64
        The fan's weights, modified.
    """
    for r in prange(ray_start.shape[0] - 1):
        for i in range(ray_start[r], ray_start[r + 1]):
            t = prim[i]
            if t >= 0:
                k = cand_of_object[face_object[t]]
                if k >= 0 and aimed[r, k]:
                    weight[i] = 0.0
