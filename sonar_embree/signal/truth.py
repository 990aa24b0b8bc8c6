"""How ground truth is made: each ping's centre line cast again (:class:`GroundTruth`, :func:`label_block`,
:func:`object_echo_block`; the kernel :func:`sonar_embree.kernels.label_rows`). What it holds is
:class:`sonar_embree.signal.labels.Labels`.

Labels come from each ping's centre line (along-track angle 0), the geometric
truth of the waterfall row: the first surface at each sample's slant range that
faces the sonar, or the seafloor an object hides (shadow). See
:func:`sonar_embree.kernels.label_rows` for the exact rule.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .. import kernels
from ..kernels.args import Footprints, LabelOut
from ..propagation.echoes import Echoes, merged
from ..propagation.fan import BlockEchoes, FanPlan
from .labels import Labels
from .processing import convolve_time

#: Surfaces a label ray may pass (objects, back faces) looking for the seafloor behind its first hit.
MAX_HIDDEN_LAYERS = 8
#: The continued ray starts this far (m) past the previous hit, well above float32 round-off.
CONTINUE_EPS_M = 1e-3


def _footprint_lines(u, f, normals, range_m, dbeta, slope_cap):
    """Unit direction of each footprint's line on its facet, and its slant-range extent ΔR (m).

    The point P(β) = O + R(β)·u(β) moves along dP/dβ = R'·u + R·∂u/∂β on the plane,
    R' = R·(n̂·∂u/∂β)/cos θi.
    """
    cos_i = -np.einsum("ij,ij->i", u, normals)
    with np.errstate(divide="ignore", invalid="ignore"):
        r_prime = range_m * np.einsum("ij,ij->i", f, normals) / cos_i
        d = r_prime[:, None] * u + range_m[:, None] * f
        d /= np.linalg.norm(d, axis=1)[:, None]
    extent = np.minimum(np.abs(r_prime), slope_cap) * dbeta
    return np.nan_to_num(d), extent


def label_block(run, plan: FanPlan, e: BlockEchoes, rot: np.ndarray, pos_local: np.ndarray,
                is_seafloor: np.ndarray, max_range_m: float, dr_m: float, origin_z_m: float, out,
                lines=None) -> None:
    """Ground truth of a block of pings along each ping's label lines (side-scan: its centre lines, along-track
    angle 0, one per side).

    A label line is one azimuth line of one side of the block's fan (its rays and echoes are
    reused; weights carry the fan's azimuth factor, which scales every score alike).
    Each is followed past its first hit, through objects and back faces, to the
    first seafloor surface facing the sonar: where only such hidden footprints
    reach a sample, the sample is in shadow. See :func:`kernels.label_rows`.

    Parameters
    ----------
    run : PreparedRun
        The run's scene and its seafloor's own caster (``run.seafloor``,
        :class:`~sonar_embree.propagation.prepared.SeafloorCaster`).
    e : BlockEchoes
        The block's echoes (its elevation rows are reused).
    is_seafloor : (n_objects,) bool
    max_range_m : float
        Range window, m (hidden surfaces beyond it are not searched for).
    dr_m : float
        Slant range per sample, m.
    origin_z_m : float
        World z of the scene's local origin, m.
    out : tuple of 5 arrays (pings, channels, n_s)
        kind (int8), object_id, shadow_of (int32), height_m, ground_range_m (float32), written.
    lines : (sides, azimuth indices), optional
        Each channel's fan side (0 port, 1 starboard) and azimuth line (default :func:`centre_lines`).
    """
    max_range_m = max_range_m * (1.0 + 1e-3) + 0.05
    c = run.compiled
    rot = np.ascontiguousarray(rot, dtype=np.float64)
    pos_local = np.ascontiguousarray(pos_local, dtype=np.float64)
    # each label line's rays: its fan row's rays of one azimuth line (cast already)
    sides, az = centre_lines(plan) if lines is None else lines
    n_p, n_ch, n_az = rot.shape[0], len(sides), plan.s.shape[0]
    src = 2 * np.arange(n_p)[:, None] + np.asarray(sides)[None, :]          # (pings, channels): the fan's row
    n_el = np.diff(e.el_start)[src].ravel()
    el_start = np.concatenate(([0], np.cumsum(n_el))).astype(np.int64)
    n = int(el_start[-1])
    row = np.repeat(np.arange(n_p * n_ch), n_el)                           # the label row of each ray
    j = np.arange(n) - el_start[row]
    fan_row, line = src.ravel()[row], np.tile(np.asarray(az), n_p)[row]
    centre = n_az * e.el_start[fan_row] + line * np.diff(e.el_start)[fan_row] + j
    prim, tfar = e.prim[centre], e.tfar[centre]
    rng, w, dbeta = e.range_m[centre], e.weight[centre], e.dbeta[e.el_start[fan_row] + j]
    beta = e.beta[e.el_start[fan_row] + j]
    cos_b, sin_b = np.cos(beta), np.sin(beta)

    # float64 directions u and ∂u/∂β of every label ray, in the world frame
    b, side, sa = fan_row // 2, np.where(fan_row % 2, 1.0, -1.0), plan.s[line]
    cpsi = np.sqrt(1.0 - sa * sa)
    u = np.einsum("nij,nj->ni", rot[b], np.stack([sa, side * cpsi * cos_b, cpsi * sin_b], axis=1))
    f = np.einsum("nij,nj->ni", rot[b], np.stack([np.zeros(n), -side * cpsi * sin_b, cpsi * cos_b], axis=1))
    origin = pos_local[b]

    lit = w > 0.0
    pts = origin + np.where(lit, rng, 0.0)[:, None] * u
    lit_obj = np.where(prim >= 0, c.face_object[np.maximum(prim, 0)], -1).astype(np.int32)
    lit_dir, ext = np.zeros((n, 3)), np.zeros(n)  # footprints even where the fan splats point echoes
    if lit.any():
        lit_dir[lit], ext[lit] = _footprint_lines(u[lit], f[lit], c.face_normals[prim[lit]], rng[lit], dbeta[lit],
                                                  plan.slope_cap_m_rad)
    score = np.where(lit, w / np.maximum(ext, dr_m), 0.0)

    hid_r, hid_prim = _hidden_seafloor(c, run.seafloor, origin, u, prim, tfar, max_range_m)
    hid = np.nonzero(hid_prim >= 0)[0]
    hid_pt = np.zeros((n, 3))
    hid_dir = np.zeros((n, 3))
    hid_ext = np.zeros(n)
    if hid.size:
        nrm = c.face_normals[hid_prim[hid]]
        # float64 range from the hit triangle's plane (the float32 distance is only a guide)
        v0 = c.vertices[c.faces[hid_prim[hid], 0]]
        den = np.einsum("ij,ij->i", u[hid], nrm)
        r64 = np.einsum("ij,ij->i", v0 - origin[hid], nrm) / den
        good = ((np.abs(den) > kernels.REFIT_MIN_COS)
                & (np.abs(r64 - hid_r[hid]) <= kernels.REFIT_REL_TOL * (1.0 + hid_r[hid])))
        hid_r[hid] = np.where(good, r64, hid_r[hid])
        hid_pt[hid] = origin[hid] + hid_r[hid][:, None] * u[hid]
        hid_dir[hid], hid_ext[hid] = _footprint_lines(u[hid], f[hid], nrm, hid_r[hid], dbeta[hid],
                                                      plan.slope_cap_m_rad)
    rows, n_s = n_p * n_ch, out[0].shape[-1]
    flat = [a.reshape(rows, n_s) for a in out]
    kernels.label_rows(el_start, float(dr_m), Footprints(rng, ext, lit_obj, pts, lit_dir), score,
                       Footprints(hid_r, hid_ext, lit_obj, hid_pt, hid_dir), np.repeat(pos_local, n_ch, axis=0),
                       _outward(rot, sides, lines is None), np.ascontiguousarray(is_seafloor, dtype=np.bool_),
                       float(origin_z_m), np.empty((rows, n_s)), LabelOut(*flat))


def _outward(rot: np.ndarray, sides, side_scan: bool) -> np.ndarray:
    """(pings × channels, 2): each label row's horizontal outward direction (a side-scan side: the body's
    starboard axis, negated for port), so that a point past nadir gets a negative ground range; zeros for other
    sonars (their rows have no side)."""
    n_p, sides = rot.shape[0], np.asarray(sides)
    if not side_scan:
        return np.zeros((n_p * sides.size, 2))
    axis = rot[:, :2, 1]
    axis = axis / np.maximum(np.linalg.norm(axis, axis=1), 1e-12)[:, None]
    sign = np.where(sides == 1, 1.0, -1.0)
    return np.ascontiguousarray((sign[None, :, None] * axis[:, None, :]).reshape(-1, 2))


def _hidden_seafloor(compiled, seafloor, origin, u, prim, tfar, max_range_m: float):
    """(range (n,), NaN for none; triangle (n,) int64, −1 for none) of the first seafloor face that faces the sonar
    behind each ray's first hit (triangle ``prim``, −1: none, at ``tfar``), along u from ``origin``, within the
    range: the ray goes on through the seafloor's back faces, and through everything else, which is not cast at
    all (``seafloor``, :func:`~sonar_embree.propagation.prepared.seafloor_caster`: an object resting on the floor has
    faces in the floor's plane, and which of two coplanar faces a caster reports is its own choice)."""
    n = u.shape[0]
    hid_r, hid_prim = np.full(n, np.nan), np.full(n, -1, dtype=np.int64)
    sea, faces = seafloor.caster, seafloor.faces
    if sea is None:
        return hid_r, hid_prim
    normals = compiled.face_normals
    active = np.nonzero(prim >= 0)[0]
    t_cur = tfar[active].astype(np.float64)
    for _ in range(MAX_HIDDEN_LAYERS):
        if active.size == 0:
            break
        o = origin[active] + (t_cur + CONTINUE_EPS_M)[:, None] * u[active]
        p2, t2 = sea.cast_raw(o.astype(np.float32), u[active].astype(np.float32), max_range_m)
        if faces is not None:                                     # the seafloor's triangles → the scene's
            p2 = np.where(p2 >= 0, faces[np.maximum(p2, 0)], -1)
        total = t_cur + CONTINUE_EPS_M + t2
        ok = (p2 >= 0) & (total <= max_range_m)
        found = ok & (np.einsum("ij,ij->i", u[active], normals[np.maximum(p2, 0)]) < 0.0)
        hid_prim[active[found]], hid_r[active[found]] = p2[found], total[found]
        keep = ok & ~found
        active, t_cur = active[keep], total[keep]
    return hid_r, hid_prim


def centre_lines(plan: FanPlan):
    """The side-scan's label lines: (sides, azimuth indices) of its two channels, each side's boresight line."""
    a0 = int(np.flatnonzero(plan.s == 0.0)[0])
    return (0, 1), (a0, a0)


def object_echo_block(e: Echoes, is_seafloor: np.ndarray, rate_hz: float, kernel: np.ndarray, lead: int,
                      out_id: np.ndarray, out_value: np.ndarray, beams=None) -> None:
    """The strongest object echo at every sample of a block, from every echo of the block.

    Each object (not seafloor) echoing in the block has its echoes splatted and
    convolved with the pulse intensity on their own, exactly as the record is made;
    per sample the strongest object wins. This is what the waterfall shows of each
    object, so detection boxes and masks follow it (docs/physics.md §9).

    Parameters
    ----------
    e : Echoes
        The block's echoes, with ``object_id``.
    is_seafloor : (n_objects,) bool
    rate_hz : float
        Samples per second of travel time.
    kernel : (n_k,) float64
        Expected intensity of a unit echo (:func:`sonar_embree.signal.pulses.expected_kernel`).
    lead : int
        Kernel taps before the echo time.
    out_id : (pings, channels, n_out) int32
        Written: object index of the strongest object echo, −1 where none.
    out_value : (pings, channels, n_out) float32
        Written: its expected intensity (unit source, no TVG).
    beams : (channels, e.n_channels) float64, optional
        A beamformer's power weights (AF²) from the echoes' channels to the record's (default: the same).
    """
    n_p, n_ch, n_out = out_id.shape
    n_in = e.n_channels
    obj = np.where((e.object_id >= 0) & ~is_seafloor[np.maximum(e.object_id, 0)], e.object_id, -1)
    best = np.zeros((n_ch * n_p, n_out))
    best_id = np.full((n_ch * n_p, n_out), -1, dtype=np.int32)
    n_s = n_out + lead
    for k in np.unique(obj[obj >= 0]):
        buf = np.zeros((n_in * n_p, n_s))
        kernels.splat_rows(e.ray_start, e.travel_time_s, e.extent_s, np.where(obj == k, e.weight, 0.0), rate_hz,
                           buf)
        img = convolve_time(buf, kernel, lead)[:, :n_out]
        if beams is not None:
            img = np.matmul(beams, img.reshape(n_p, n_in, n_out)).reshape(n_p * n_ch, n_out)
        better = img > best
        best[better], best_id[better] = img[better], k
    out_id[...] = best_id.reshape(n_p, n_ch, n_out)
    out_value[...] = best.reshape(n_p, n_ch, n_out)


class GroundTruth:
    """Per-sample ground truth of a record, block by block (each channel's label line and object echoes).

    The front end (:class:`~sonar_embree.sonars.base.FrontEnd`) gives ``label_lines(plan)`` (its channels' sides
    and lines in the block's fan, :func:`label_block`; None: the side-scan's centre lines) and ``beam_power`` (a
    beamformer's AF² from its echo channels to its record's, :func:`object_echo_block`).

    Parameters
    ----------
    shape : (pings, channels, n_out)
    compiled : CompiledScene
    echo_kernel : (kernel, lead)
        The unit echo's expected intensity (shared with the speckle-free record).
    """

    def __init__(self, shape: tuple, compiled, echo_kernel):
        self.arrays = tuple(np.zeros(shape, dtype=Labels.DTYPES[k]) for k in Labels.ARRAYS)
        self.compiled = compiled
        self.kernel, self.lead = echo_kernel

    def add_block(self, front, run, blk, e: Echoes, a: int, rot, pos_local, max_range_m: float) -> None:
        """Labels of pings a … a + e.n_pings − 1 from the side-scan block ``blk`` and its echoes ``e``."""
        e = merged(e)
        b, c, s = a + e.n_pings, self.compiled, front.sonar
        label_block(run, blk.plan, blk, rot, pos_local, c.is_seafloor, max_range_m,
                    s.sound_speed_m_s / (2.0 * s.sample_rate_hz), float(c.origin_m[2]),
                    tuple(x[a:b] for x in self.arrays[:5]), front.label_lines(blk.plan))
        object_echo_block(e, c.is_seafloor, s.sample_rate_hz, self.kernel, self.lead, self.arrays[5][a:b],
                          self.arrays[6][a:b], front.beam_power)

    def labels(self) -> "Labels":
        """The :class:`Labels`, arrays (channels, pings, samples)."""
        return Labels(*(np.ascontiguousarray(x.transpose(1, 0, 2)) for x in self.arrays), names=self.compiled.labels,
                      is_seafloor=tuple(bool(x) for x in self.compiled.is_seafloor))
