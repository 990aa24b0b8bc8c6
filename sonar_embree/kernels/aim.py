"""Kernels of the object-aimed rays (docs/physics.md §7b): which objects each row's beam can see, the lattice of
rays aimed at each and the fan's hits those lattices replace (their echoes are the fan's kernel's,
:func:`~.rays.fan_echoes` with each ray's own layout).

A row is (ping, side) as in the fan (r = 2·b + side). Its body-frame directions are
(s, side·√(1 − s²)·cos β, √(1 − s²)·sin β), whose solid angle element is exactly ds·dβ; an object's lattice is a
uniform grid of cells in (s, β) tiling the part of the object's bounding cone inside the row's span, so its
weights are exact solid angles, as the fan's are. A slender object (a cable, a pipe, a strip) gets cells a fraction
of its width (at its far side) and casts only those its projection can cover: the cells within one of the box each
short segment of its oriented bounding box projects to (:func:`cover_cells`).
"""
from __future__ import annotations

import math

from ._numba import njit, prange

#: Columns of the lattice table: first s, s step, first β, β step (rad), cells in s, cells in β, rays cast (every
#: cell, or a slender object's covered cells) and the offset of its cell mask (−1: every cell is cast).
S0, HS, B0, HB, NS, NB, NC, MASK = range(8)
LATTICE_WIDTH = 8
#: MASK of a lattice whose cells the object's width makes finer (a slender object in this row) until its mask is
#: placed: only its covered cells are cast.
SLENDER = -2.0
#: Cells a slender object's lattice may span before its covered cells are counted; beyond, the fan sees it.
MAX_MASK_CELLS = 1 << 22
#: Columns of an aimed ray's layout: s, cos β, sin β, dβ, ds.
LAYOUT_WIDTH = 5


@njit(cache=True, nogil=True)
def _lattice(v0, v1, v2, up0, up1, up2, side, radius, cell_m, span, rx, n_across, dr_m, max_rays, out):
    """The lattice of one object (bounding sphere of ``radius`` at body-frame offset v) in one row; NS = 0 when it
    gets none (out of range or span, the sonar inside its sphere, or too big to aim at: the fan sees it). Where
    ``cell_m`` (a slender object's largest cell at its far side, m; inf: not slender) is finer than the cone's cells,
    the cells shrink to it and MASK = :data:`SLENDER`: its cells are counted once trimmed (:func:`_trim`) and its
    covered cells against its budget (:func:`cover_cells`).
    ``span`` = (s_lo, s_hi, β_lo, β_hi, max range, along-track step cap, elevation step cap, κ); ``rx`` the row's
    receive shift δ (the span widens to cover the receive lobe too); ``up`` the world's vertical in the body frame.

    Curved rays (κ > 0, the largest ray curvature |dc/dz|/c of a sound-speed profile, 1/m) stay in their launch
    direction's vertical plane and leave within κ·L/2 of their chord over a path L (the tangent turns by at most
    κ per metre; the chord is its mean): the cone widens by ``bend`` = 0.6·κ·(D + ρ) in elevation, mapped to s
    and β by the elevation direction's body components (and bend² for what that linearisation leaves out)."""
    out[NS] = 0.0
    out[NB] = 0.0
    out[NC] = 0.0
    out[MASK] = -1.0
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
    thin = cell_m / (d + radius)
    slender = thin < max(hs, hb)                    # cells wider than the object's width allows: slender here
    if slender:
        hs, hb = min(hs, thin), min(hb, thin)
    ns = math.ceil((s_hi - s_lo) / hs - 1e-9)
    nb = math.ceil((b_hi - b_lo) / hb - 1e-9)
    if not slender and ns * nb > max_rays:          # too big to aim at: the fan sees it (a slender one: once trimmed)
        return
    out[S0] = s_lo
    out[HS] = (s_hi - s_lo) / ns
    out[B0] = b_lo
    out[HB] = (b_hi - b_lo) / nb
    out[NS] = ns
    out[NB] = nb
    out[NC] = ns * nb
    if slender:
        out[MASK] = SLENDER


@njit(cache=True, nogil=True)  # rows × objects of a few flops each: serial (a parallel kernel compiles slower)
def aim_lattices(centre, radius, cell_m, cover, cover_start, rot, pos, sides, span, rx_shift, n_across, dr_m, max_rays,
                 table):
    """The lattice of every candidate object in every row of a block.

    Parameters
    ----------
    centre : (k, 3) float64
        Bounding-sphere centres of the candidate objects, local frame, m.
    radius : (k,) float64
        Their radii, m.
    cell_m : (k,) float64
        A slender object's largest cell at its far side, m (inf: not slender, the cone's lattice alone).
    cover : (m, 3) float64
        Slender objects' cover points, local frame, m: slices of 4 corners of each one's oriented bounding box along
        its long axis; candidate k owns ``cover_start[k] … cover_start[k + 1] − 1``.
    cover_start : (k + 1,) int64
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
        Written: each lattice (:data:`S0` … :data:`MASK`); NS = 0 where none. A slender lattice (MASK =
        :data:`SLENDER`) is trimmed to the cells its cover points' box reaches (its NC and MASK are set again by
        :func:`cover_cells`).
    """
    for r in range(table.shape[0]):
        b = r // 2
        side = 1.0 if r % 2 else -1.0
        for k in range(table.shape[1]):
            table[r, k, NS] = 0.0
            table[r, k, NB] = 0.0
            table[r, k, NC] = 0.0
            table[r, k, MASK] = -1.0
            if not sides[r % 2]:
                continue
            w0 = centre[k, 0] - pos[b, 0]
            w1 = centre[k, 1] - pos[b, 1]
            w2 = centre[k, 2] - pos[b, 2]
            v0 = rot[b, 0, 0] * w0 + rot[b, 1, 0] * w1 + rot[b, 2, 0] * w2    # Rᵀ·w: body frame
            v1 = rot[b, 0, 1] * w0 + rot[b, 1, 1] * w1 + rot[b, 2, 1] * w2
            v2 = rot[b, 0, 2] * w0 + rot[b, 1, 2] * w1 + rot[b, 2, 2] * w2
            _lattice(v0, v1, v2, rot[b, 2, 0], rot[b, 2, 1], rot[b, 2, 2], side, radius[k], cell_m[k], span,
                     rx_shift[b], n_across, dr_m, max_rays, table[r, k])
            if table[r, k, MASK] == SLENDER:
                _trim(table[r, k], cover[cover_start[k]:cover_start[k + 1]], cell_m[k], rot[b], pos[b], side)


@njit(cache=True, nogil=True)
def _project(p, rot, pos, side):
    """(s, β) of the direction from the sonar at ``pos`` (rotation ``rot``) to the local point ``p``, on ``side``."""
    w0, w1, w2 = p[0] - pos[0], p[1] - pos[1], p[2] - pos[2]
    v0 = rot[0, 0] * w0 + rot[1, 0] * w1 + rot[2, 0] * w2
    v1 = rot[0, 1] * w0 + rot[1, 1] * w1 + rot[2, 1] * w2
    v2 = rot[0, 2] * w0 + rot[1, 2] * w1 + rot[2, 2] * w2
    return v0 / math.sqrt(v0 * v0 + v1 * v1 + v2 * v2), math.atan2(v2, side * v1)


@njit(cache=True, nogil=True)
def _cells(lat, pts, rot, pos, side):
    """(i0, i1, j0, j1): the lattice's cells (s index, β index; inclusive, clipped to the lattice) whose centres,
    where their rays go, lie within half a cell of the box of ``pts`` projected; i1 < i0 or j1 < j0 when none."""
    s_lo, s_hi, b_lo, b_hi = math.inf, -math.inf, math.inf, -math.inf
    for q in range(pts.shape[0]):
        sq, bq = _project(pts[q], rot, pos, side)
        s_lo, s_hi, b_lo, b_hi = min(s_lo, sq), max(s_hi, sq), min(b_lo, bq), max(b_hi, bq)
    i0 = max(math.ceil((s_lo - lat[S0]) / lat[HS] - 1.0), 0)
    i1 = min(math.floor((s_hi - lat[S0]) / lat[HS]), int(lat[NS]) - 1)
    j0 = max(math.ceil((b_lo - lat[B0]) / lat[HB] - 1.0), 0)
    j1 = min(math.floor((b_hi - lat[B0]) / lat[HB]), int(lat[NB]) - 1)
    return i0, i1, j0, j1


@njit(cache=True, nogil=True)
def _trim(lat, pts, cell_m, rot, pos, side):
    """Trim a slender object's lattice to the box of the cells its cover's segments reach (:func:`_cells`; only the
    segments inside the lattice count: a long cable across the beam's edge keeps the part in it), then refine its
    cells to the object's width as this row sees it (:func:`_seen_width`: a flat strip foreshortens) over
    ``cell_m``'s rays across; none beyond :data:`MAX_MASK_CELLS`."""
    i0, i1, j0, j1 = 1 << 62, -1, 1 << 62, -1
    for a in range(0, pts.shape[0] - 4, 4):
        a0, a1, b0, b1 = _cells(lat, pts[a:a + 8], rot, pos, side)
        if a1 >= a0 and b1 >= b0:
            i0, i1, j0, j1 = min(i0, a0), max(i1, a1), min(j0, b0), max(j1, b1)
    if i1 < i0 or j1 < j0:
        lat[NS] = 0.0
        lat[NB] = 0.0
        lat[NC] = 0.0
        return
    lat[S0] += i0 * lat[HS]
    lat[B0] += j0 * lat[HB]
    across = math.sqrt((pts[2, 0] - pts[0, 0]) ** 2 + (pts[2, 1] - pts[0, 1]) ** 2 + (pts[2, 2] - pts[0, 2]) ** 2)
    h = _seen_width(pts, rot, pos, side) * cell_m / max(across, 1e-300)
    if not h > 1e-12:                                 # seen exactly edge-on: the cone's cells
        h = math.inf
    ns = math.ceil((i1 - i0 + 1) * lat[HS] / min(lat[HS], h) - 1e-9)
    nb = math.ceil((j1 - j0 + 1) * lat[HB] / min(lat[HB], h) - 1e-9)
    if ns * nb > MAX_MASK_CELLS:
        ns, nb = 0, 0
    lat[HS] *= (i1 - i0 + 1) / max(ns, 1)
    lat[HB] *= (j1 - j0 + 1) / max(nb, 1)
    lat[NS] = ns
    lat[NB] = nb
    lat[NC] = ns * nb


@njit(cache=True, nogil=True)
def _seen_width(pts, rot, pos, side):
    """The angle a slender object's box spans across its own projected axis, seen from the row (its middle slice's
    4 corners, across the line from the first slice's centre to the last's; the larger of their s and β spans
    where that line is shorter, its axis pointing at the sonar), rad."""
    m = 4 * ((pts.shape[0] // 4) // 2)
    s0, b0, s1, b1 = 0.0, 0.0, 0.0, 0.0
    for q in range(4):
        sa, ba = _project(pts[q], rot, pos, side)
        sz, bz = _project(pts[pts.shape[0] - 4 + q], rot, pos, side)
        s0, b0, s1, b1 = s0 + 0.25 * sa, b0 + 0.25 * ba, s1 + 0.25 * sz, b1 + 0.25 * bz
    n_s, n_b = -(b1 - b0), s1 - s0                    # normal to the projected axis
    lo, hi, s_lo, s_hi, b_lo, b_hi = math.inf, -math.inf, math.inf, -math.inf, math.inf, -math.inf
    for q in range(m, m + 4):
        sq, bq = _project(pts[q], rot, pos, side)
        lo, hi = min(lo, n_s * sq + n_b * bq), max(hi, n_s * sq + n_b * bq)
        s_lo, s_hi, b_lo, b_hi = min(s_lo, sq), max(s_hi, sq), min(b_lo, bq), max(b_hi, bq)
    box = max(s_hi - s_lo, b_hi - b_lo)
    norm = math.sqrt(n_s * n_s + n_b * n_b)
    if norm <= box:                                   # the axis points at the sonar: a blob, the slice's larger span
        return box
    return (hi - lo) / norm


@njit(cache=True, nogil=True, parallel=True)
def cover_cells(table, cover, cover_start, rot, pos, max_rays, mask):
    """Mark the cells of every slender object's lattice that its projection can cover, and count them.

    A slender object lies inside the segments of its oriented bounding box between consecutive slices of
    ``cover`` (4 corners each, slices no farther apart than the box is wide); a segment, small against its range,
    projects inside the (s, β) box of its 8 corners up to second order (far under a cell), so every cell whose ray
    (its centre) can hit the object has its centre within half a cell of that box.

    Parameters
    ----------
    table : (rows, k, LATTICE_WIDTH) float64
        The lattices (:func:`aim_lattices`), MASK set to each slender lattice's offset in ``mask``. Written: NC, the
        cells marked; a lattice with more than ``max_rays`` gets none (NS = 0: the fan sees it).
    cover, cover_start
        As for :func:`aim_lattices`.
    rot, pos
        As for :func:`aim_lattices`.
    max_rays : float
    mask : (cells,) uint8
        Zeros; written: 1 for each cell cast, lattice (r, k) at MASK, s-major, β fastest.
    """
    for r in prange(table.shape[0]):
        side = 1.0 if r % 2 else -1.0
        for k in range(table.shape[1]):
            lat = table[r, k]
            if lat[MASK] < 0.0 or lat[NS] == 0.0:
                continue
            off, nb = int(lat[MASK]), int(lat[NB])
            for a in range(cover_start[k], cover_start[k + 1] - 4, 4):
                i0, i1, j0, j1 = _cells(lat, cover[a:a + 8], rot[r // 2], pos[r // 2], side)
                for i in range(i0, i1 + 1):
                    for j in range(j0, j1 + 1):
                        mask[off + i * nb + j] = 1
            n = 0
            for c in range(off, off + int(lat[NS]) * nb):
                n += mask[c]
            lat[NC] = n
            if n > max_rays:
                lat[NS] = 0.0
                lat[NC] = 0.0


@njit(cache=True, nogil=True, parallel=True)
def aim_rays(table, start, rot, pos, mask, dirs, origins, layout):
    """Float32 origins and world directions of every aimed ray of a block.

    Parameters
    ----------
    table : (rows, k, LATTICE_WIDTH) float64
        The lattices (:func:`aim_lattices`, :func:`cover_cells`).
    start : (rows·k + 1,) int64
        Offset of lattice (r, k)'s rays at r·k + k (its NC rays).
    rot, pos
        As for :func:`aim_lattices`.
    mask : (cells,) uint8
        The slender lattices' cells to cast (:func:`cover_cells`).
    dirs, origins : (start[-1], 3) float32
        Written.
    layout : (start[-1], LAYOUT_WIDTH) float64
        Written with each ray's s, cos β, sin β, dβ and ds (what the paths built on a direct hit need of its ray:
        a beamformer's line interpolation, the one-bounce surface path).
    """
    n_k = table.shape[1]
    for r in prange(table.shape[0]):
        b = r // 2
        side = 1.0 if r % 2 else -1.0
        for k in range(n_k):
            lat = table[r, k]
            base = start[r * n_k + k]
            n = start[r * n_k + k + 1] - base
            nb, off = int(lat[NB]), int(lat[MASK])
            c, j = -1, 0
            while j < n:                      # cells s-major, β fastest; a slender lattice's marked ones only
                c += 1
                if off >= 0 and mask[off + c] == 0:
                    continue
                sa = lat[S0] + (c // nb + 0.5) * lat[HS]
                be = lat[B0] + (c % nb + 0.5) * lat[HB]
                cb, sb = math.cos(be), math.sin(be)
                layout[base + j, 0] = sa
                layout[base + j, 1] = cb
                layout[base + j, 2] = sb
                layout[base + j, 3] = lat[HB]
                layout[base + j, 4] = lat[HS]
                cpsi = math.sqrt(1.0 - sa * sa)
                d0, d1, d2 = sa, side * cpsi * cb, cpsi * sb
                for q in range(3):
                    dirs[base + j, q] = rot[b, q, 0] * d0 + rot[b, q, 1] * d1 + rot[b, q, 2] * d2
                    origins[base + j, q] = pos[b, q]
                j += 1


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
