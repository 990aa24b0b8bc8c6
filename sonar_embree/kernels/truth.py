"""Ground-truth kernels: each centre-line sample labelled from the footprints that cover it (docs/physics.md §9)."""
from __future__ import annotations

import math

import numpy as np

from ._numba import njit, prange


@njit(cache=True, nogil=True)
def _along_line(px, py, pz, dx, dy, dz, ox, oy, oz, r_target, half_len):
    """Offset t along the footprint line P + t·d (unit d) where |P + t·d − O| = r_target, |t| ≤ half_len."""
    qx = px - ox
    qy = py - oy
    qz = pz - oz
    b = qx * dx + qy * dy + qz * dz
    c = qx * qx + qy * qy + qz * qz - r_target * r_target
    disc = b * b - c
    if disc <= 0.0:  # the line never reaches that range: its closest point
        t = -b
    else:  # the root nearest t = 0, in the form that does not cancel
        root = math.sqrt(disc)
        if b >= 0.0:
            t = -c / (b + root)
        else:
            t = c / (root - b)
    if t > half_len:
        t = half_len
    elif t < -half_len:
        t = -half_len
    return t


@njit(cache=True, nogil=True)
def _label_ray(dr, pt, dv, ox, oy, oz, side, half_len, origin_z, height_row, ground_row, n):
    t = _along_line(pt[0], pt[1], pt[2], dv[0], dv[1], dv[2], ox, oy, oz, n * dr, half_len)
    x = pt[0] + t * dv[0] - ox
    y = pt[1] + t * dv[1] - oy
    height_row[n] = pt[2] + t * dv[2] + origin_z
    g = math.sqrt(x * x + y * y)
    ground_row[n] = -g if x * side[0] + y * side[1] < 0.0 else g        # past nadir, on the other side: negative


def label_rows(el_start, dr, lit, lit_score, hidden, pos, outward, is_seafloor, origin_z, best, out):
    """Per-sample ground truth of a block of pings from its centre-line rays.

    A sample n (slant range n·dr) belongs to a ray when its range cell
    [(n − ½)·dr, (n + ½)·dr) overlaps the ray's footprint [R − ΔR/2, R + ΔR/2].
    Among the lit rays (score > 0) that claim it, the highest score
    (echo intensity per metre of range) wins: kind 1 (seafloor) or 2 (object),
    with that ray's object. Samples no lit ray claims but a hidden footprint
    does (the first seafloor surface behind a ray's first hit) become kind 3
    (shadow), with the occluding object in ``shadow_of``. The rest stay kind 0
    (water column: no surface at that range). Height and ground range are those
    of the point at range n·dr on the footprint's line (exact on planar facets); the ground range is negative
    where that point lies against the row's ``outward`` direction (a side-scan side hearing the seabed past
    nadir, on the other side of the track).

    Parameters
    ----------
    el_start : (rows + 1,) int64
        Ray offsets of each row (one label line of one ping).
    dr : float
        Slant-range spacing of the samples, m.
    lit : :data:`~sonar_embree.kernels.args.Footprints`
        First-hit range R (n,) (m), footprint ΔR (n,) (m), object (n,) int32, point (n, 3) (local frame, m) and
        unit direction of its footprint line (n, 3).
    lit_score : (n,) float64
        The first hit's score (0: not lit).
    hidden : :data:`~sonar_embree.kernels.args.Footprints`
        The same for the hidden seafloor hit (range NaN: none); its ``object`` is the occluder (the first hit's
        object).
    pos : (rows, 3) float64
        Sonar position of each row's ping, local frame, m.
    outward : (rows, 2) float64
        Each row's horizontal side direction (a side-scan side's outward unit vector; zeros: no side, never
        negative).
    is_seafloor : (n_objects,) bool
    origin_z : float
        World z of the local origin, m.
    best : (rows, n_s) float64
        Scratch.
    out : :data:`~sonar_embree.kernels.args.LabelOut`
        Written: kind (rows, n_s) int8, object_id and shadow_of (rows, n_s) int32, height and ground (rows, n_s)
        float32.
    """
    src = np.empty(best.shape, dtype=np.int64)
    label_kinds(el_start, dr, lit, lit_score, hidden, is_seafloor, best, out, src)
    label_heights(dr, lit, hidden, pos, outward, origin_z, src, out)


@njit(cache=True, nogil=True, inline='always')
def _cells(rr, ext, dr, n_s):
    """(first, last) sample whose range cell [(n − ½)·dr, (n + ½)·dr) overlaps the footprint [rr − ext/2,
    rr + ext/2] (last < first: none)."""
    lo = math.floor((rr - 0.5 * ext) / dr - 0.5) + 1.0
    hi = math.ceil((rr + 0.5 * ext) / dr + 0.5) - 1.0
    if hi < 0.0 or lo > n_s - 1.0:
        return 0, -1
    return int(max(lo, 0.0)), int(min(hi, n_s - 1.0))


@njit(cache=True, nogil=True, parallel=True)
def label_kinds(el_start, dr, lit, lit_score, hidden, is_seafloor, best, out, src):
    """The first pass of :func:`label_rows`: each sample's kind, object and occluder, and in ``src`` (rows, n_s)
    int64 the ray that labels it (j: lit ray j, n + j: hidden footprint j, −1: none) for :func:`label_heights`."""
    lit_range, lit_extent, lit_object = lit.range, lit.extent, lit.object
    hid_range, hid_extent, hid_object = hidden.range, hidden.extent, hidden.object
    kind, object_id, shadow_of = out.kind, out.object_id, out.shadow_of
    n_s, n = kind.shape[1], lit_range.shape[0]
    for r in prange(el_start.shape[0] - 1):
        for k in range(n_s):
            best[r, k] = 0.0
            kind[r, k] = 0
            object_id[r, k] = -1
            shadow_of[r, k] = -1
            src[r, k] = -1
        for j in range(el_start[r], el_start[r + 1]):      # the lit rays: the highest score wins
            if not (lit_score[j] > 0.0):
                continue
            n_lo, n_hi = _cells(lit_range[j], lit_extent[j], dr, n_s)
            for k in range(n_lo, n_hi + 1):
                score = lit_score[j]
                if score <= best[r, k]:
                    continue
                best[r, k] = score
                obj = lit_object[j]
                kind[r, k] = 1 if is_seafloor[obj] else 2
                object_id[r, k] = obj
                src[r, k] = j
        for j in range(el_start[r], el_start[r + 1]):      # then the hidden footprints: shadow where nothing is lit
            rr = hid_range[j]
            if not (rr == rr):
                continue
            n_lo, n_hi = _cells(rr, hid_extent[j], dr, n_s)
            for k in range(n_lo, n_hi + 1):
                if kind[r, k] != 0:
                    continue
                kind[r, k] = 3
                shadow_of[r, k] = hid_object[j]
                src[r, k] = n + j


@njit(cache=True, nogil=True, parallel=True)
def label_heights(dr, lit, hidden, pos, outward, origin_z, src, out):
    """The second pass of :func:`label_rows`: each labelled sample's height and ground range from the ray that
    labels it (``src`` of :func:`label_kinds`), NaN where none does."""
    height, ground = out.height, out.ground
    n_s, n = height.shape[1], lit.range.shape[0]
    for r in prange(src.shape[0]):
        ox = pos[r, 0]
        oy = pos[r, 1]
        oz = pos[r, 2]
        side = outward[r]
        for k in range(n_s):
            height[r, k] = np.nan
            ground[r, k] = np.nan
            j = src[r, k]
            if j < 0:
                continue
            if j < n:
                rr, ext, pt, dv = lit.range[j], lit.extent[j], lit.point[j], lit.dir[j]
            else:
                rr, ext, pt, dv = hidden.range[j - n], hidden.extent[j - n], hidden.point[j - n], hidden.dir[j - n]
            # |dR/dt| = |d·(P − O)|/R: half the footprint (plus half a cell) in t
            slope = abs(dv[0] * (pt[0] - ox) + dv[1] * (pt[1] - oy) + dv[2] * (pt[2] - oz)) / rr
            half_len = (0.5 * ext + dr) / max(slope, 1e-6)
            _label_ray(dr, pt, dv, ox, oy, oz, side, half_len, origin_z, height[r], ground[r], k)
