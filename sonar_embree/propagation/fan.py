"""The ray budget: where each ping's rays go, and their echoes (docs/physics.md §7).

Per block of pings: one Embree call for the probes (three azimuth lines per side, at
boresight and at the fan's edges, at a coarse elevation step, plus a nadir ray for the
altitude), a ray density per elevation cell from the probed slant ranges (rays uniform
in slant range where the scene's range changes fastest, a coarse step where it is
smooth, next to nothing where nothing is within range), one Embree call for every fan
of the block, and one Numba pass that turns hits into echoes. No Python loop touches
rays or samples.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from ..instrument import beam
from .. import checks, kernels
from ..kernels.args import DirectWeighting, EchoOut, Fan, Poses, scene_arrays
from .aim import aim_block, drop_aimed
from .gain import weigh_by_beam
from ..config import FanSettings, Sonar
from ..laws import apply_laws
from ..raycast import Caster
from .echoes import AlongTrack

#: A probe cell with nothing within range on both ends and both neighbours gets this
#: many times the largest step: next to no rays, yet no blind spot.
EMPTY_STEP_FACTOR = 8.0
#: Probe lines per side of a narrow fan, as fractions of its outermost azimuth: the boresight line and the fan's
#: edges, so that an object anywhere in the fan gets its edges refined.
PROBE_LINES = np.array([0.0, -1.0, 1.0])
#: The widest gap between probe lines, in sin ψ (about 2°): a wider fan is probed on lines this far apart at most,
#: so that a seabed patch off boresight in a wide beam (a 4 cm SAS element's 22° at 100 kHz) is seen by a probe in
#: every ping, not only when it lies under the boresight or an edge line (issue 53: a 4 m patch at 20 m went unheard
#: in 8 of 21 pings). A patch narrower than R·PROBE_MAX_DS (1 m at 30 m) may still fall between them.
PROBE_MAX_DS = 0.035


def probe_lines(edge_s: float, ds: float) -> np.ndarray:
    """(L,) sin ψ of the probe lines of a fan whose outermost line is at ±``edge_s`` and whose lines are ``ds``
    apart: :data:`PROBE_LINES` when they lie within :data:`PROBE_MAX_DS` of each other, else the lattice's lines
    k·ds from −edge to +edge (boresight included), k the largest whole number of spacings within
    :data:`PROBE_MAX_DS` (at least 1: no probe between the fan's own lines, where no ray goes)."""
    if edge_s <= PROBE_MAX_DS:
        return PROBE_LINES * edge_s
    k = max(1, int(PROBE_MAX_DS / ds + 1e-9))
    n = int(round(edge_s / ds))
    i = np.unique(np.concatenate([np.arange(0, n + 1, k), [n]]))
    return np.concatenate([-i[:0:-1], i]) * ds


#: Cells at object edges (range jumps, silhouettes) and their neighbours get this many times the density
#: of the largest step.
EDGE_DENSITY_FACTOR = 4.0


def azimuth_oversample(sonar: Sonar, fan: FanSettings) -> float:
    """The fan's azimuth oversampling: ``fan.azimuth_oversample`` (resolved settings), or more where its line spacing
    λ/(2·lx)/oversample would exceed sin(``fan.max_azimuth_step_deg``) (a wide beam)."""
    widest = sonar.wavelength_m / (2.0 * sonar.length_m) / math.sin(math.radians(fan.max_azimuth_step_deg))
    return max(float(fan.azimuth_oversample), widest)


@dataclass(frozen=True, eq=False)
class FanPlan:
    """Everything about the ray fan that does not depend on the pose."""

    s: np.ndarray            # (n_az,) along-track direction cosines
    ds: float                # their spacing
    probe_beta: np.ndarray   # (m,) probe depressions (uniform), also the cell edges
    probe_body: np.ndarray   # (2m, 3) body-frame probe directions: port, then starboard
    dr_target_m: float
    max_step_rad: float
    slope_cap_m_rad: float
    max_rays: int
    tilt_rad: float          # the boresight's depression δ, rad: the baffle the path kernels keep (no pattern in them)
    min_range_m: float       # near-field bound on R in the weights
    footprint: bool          # spread echoes over their cells' range intervals (else point echoes)
    sides: tuple = (True, True)  # which sides get rays (port, starboard); a side without has empty rows
    spans_motion: bool = True    # lines added for the receive beam's turn under motion (moving_lines)
    pattern: object = None       # each side's Beam (instrument.beams), weighed after the path kernels (gain.py)
    across: tuple = ()           # the pattern's across factor as a table (:func:`across_table`), made once per run

    @classmethod
    def build(cls, sonar: Sonar, fan: FanSettings, sides=(True, True), elevation_nulls: int = 1) -> "FanPlan":
        """The fan of ``sonar``: rays on the ``sides`` (port, starboard) that have them, in elevation out to the
        ``elevation_nulls``-th null of the membrane's vertical pattern (the baffle at most), on the membrane's
        azimuth lattice (a Gaussian beam of the same widths takes the same, less the lines on its own nulls)."""
        fan, pattern = fan.resolved(), sonar.transducer
        s, ds = beam.azimuth_samples(sonar.wavelength_m, sonar.length_m, azimuth_oversample(sonar, fan),
                                     fan.azimuth_nulls, keep_nulls=True)
        s = s[~pattern.null_lines(s)]                       # lines on the beam's own nulls weigh nothing
        lo, hi = beam.elevation_span_rad(sonar.wavelength_m, sonar.height_m, sonar.tilt_rad, elevation_nulls)
        m = max(int(math.ceil((hi - lo) / math.radians(fan.probe_step_deg))) + 1, 3)
        probe = np.linspace(lo, hi, m)
        lines = probe_lines(float(np.abs(s).max()), ds)
        body = np.concatenate([beam.fan_body(lines, probe, -1), beam.fan_body(lines, probe, +1)])
        return cls(s, ds, probe, body, sonar.range_bin_m / fan.rays_per_bin, math.radians(fan.max_step_deg),
                   10.0 * sonar.max_range_m, fan.max_rays_per_side, float(sonar.tilt_rad), sonar.wavelength_m,
                   fan.footprint, tuple(bool(x) for x in sides), pattern=pattern, across=across_table(pattern))

    @property
    def n_probe(self) -> int:
        """Probe rays per ping (both sides and the nadir ray)."""
        return self.probe_body.shape[0] + 1

    @property
    def edge_s(self) -> float:
        """sin ψ of the transmit span's outermost line: the probes' edge lines (:func:`probe_lines`)."""
        return float(np.abs(self.probe_body[:, 0]).max())


#: Samples of the along-track pattern table per line spacing (:func:`along_track`): linear interpolation of
#: Γ⁴ (sinc⁴ of a membrane) between them is within 0.3 % of its peak.
ALONG_TABLE_PER_LINE = 16


def along_track(plan: FanPlan, rot: np.ndarray, rx_shift: np.ndarray | None = None) -> AlongTrack:
    """The fan's along-track footprints of a block of pings (:class:`~sonar_embree.propagation.echoes.AlongTrack`).

    ``rot`` (pings, 3, 3) body-to-world rotations; ``rx_shift`` (pings,) the receive beam's turn δ (None: 0).
    The pattern table spans the block's lines and one spacing beyond each end (where an edge line's strip and
    the lattice's reach end), at :data:`ALONG_TABLE_PER_LINE` samples per spacing."""
    n_p = rot.shape[0]
    shift = np.zeros(n_p) if rx_shift is None else np.asarray(rx_shift, dtype=np.float64)
    lines = moving_lines(plan, shift)[0].s                       # with the lines a moving block adds
    step = plan.ds / ALONG_TABLE_PER_LINE
    s0 = float(lines.min()) - plan.ds
    s = s0 + step * np.arange(int(round((float(lines.max()) + plan.ds - s0) / step)) + 1)
    a = plan.pattern.along(s)
    a_rx = plan.pattern.along(s[None, :] - shift[:, None])
    gain = np.repeat((a * a)[None, :] * (a_rx * a_rx), 2, axis=0)
    gain_rx = np.repeat(np.abs(a_rx), 2, axis=0)                # Γ_rx alone, an amplitude
    axis = np.repeat(np.asarray(rot[:, :, 0], dtype=np.float64) * plan.ds, 2, axis=0)
    return AlongTrack(np.ascontiguousarray(axis), np.ascontiguousarray(gain), np.ascontiguousarray(gain_rx), s0,
                      float(step), side_axes(rot, plan.tilt_rad), plan.across)


#: Samples of the across-track pattern table per first-null angle's sine (:func:`across_table`): linear
#: interpolation of a membrane's sinc between them is within 0.02 % of its peak.
ACROSS_TABLE_PER_NULL = 64


def side_axes(rot: np.ndarray, tilt_rad: float) -> np.ndarray:
    """Each row's (2·ping + side: port, starboard) unit across axis v̂ in the world, (rows, 3): the beam's second
    axis (:class:`~sonar_embree.instrument.beams.base.Beam`), v̂ = (0, −side·sin δ, cos δ) in the body frame (forward,
    starboard, down; side −1 port, +1 starboard, δ the tilt), as :func:`~sonar_embree.propagation.gain.weigh_by_beam`
    takes v = e·v̂ for a ray's body direction e; ``rot`` (pings, 3, 3) body to world."""
    c, s = math.cos(tilt_rad), math.sin(tilt_rad)
    body = np.array([[0.0, s, c], [0.0, -s, c]])                  # port, starboard
    return np.ascontiguousarray(np.einsum("pij,sj->psi", np.asarray(rot, dtype=np.float64), body).reshape(-1, 3))


def across_table(pattern) -> tuple:
    """A side's receive pattern across track, |Γ(v)| for v in [−1, 1] at :data:`ACROSS_TABLE_PER_NULL` samples per
    sin of the first null's angle (at most 2¹⁶): (table, v0, step), for an element off the transmitter's line."""
    step = max(math.sin(min(pattern.first_null_rad, 0.5 * math.pi)) / ACROSS_TABLE_PER_NULL, 2.0 / 65535)
    n = int(math.ceil(2.0 / step)) + 1
    v = -1.0 + step * np.arange(n)
    return np.ascontiguousarray(np.abs(pattern.across(v)), dtype=np.float64), -1.0, float(step)


def moving_lines(plan: FanPlan, rx_shift: np.ndarray):
    """The azimuth lines of a block of pings moving during the ping (docs/physics.md §7c).

    The receive beam is turned by δ = 2·v_fwd/c (``rx_shift``, (pings,)), so the two-way pattern lives on the
    union of the transmit lines and those lines shifted by δ. The block's fan takes lines of the same lattice
    k·ds past the transmit span's edge (its outermost null) on δ's side, ⌊|δ|/ds⌋ of them (those on a transmit
    null weigh nothing and are left out): the span's cells then end within half a spacing of the receive lobe's
    edge, as they end at the transmit lobe's, the nearest the lattice comes to symmetric about δ/2 (a line more
    only adds the side lobes' tail on one side). Each ping counts only its own lines, so its bits do not
    depend on the other pings of its block.

    Returns
    -------
    plan : FanPlan
        ``plan`` with the block's lines (``plan`` itself when nothing moves or the fan does not follow motion).
    keep : (pings, 2) float64 or None
        The s-interval of each ping's own lines where they differ between the block's pings (its rays on the other
        lines are dropped: :func:`drop_lines`); None where every ping keeps every line.
    """
    if not plan.spans_motion or rx_shift is None or not np.any(rx_shift):
        return plan, None
    k = np.floor(np.abs(rx_shift) / plan.ds + 1e-9)
    lo, hi = np.where(rx_shift < 0, k, 0.0), np.where(rx_shift > 0, k, 0.0)
    moved, i0, i1 = _moved(plan, int(lo.max()), int(hi.max()))
    if lo.min() == lo.max() and hi.min() == hi.max():
        return moved, None
    return moved, np.stack([(i0 - lo - 0.5) * plan.ds, (i1 + hi + 0.5) * plan.ds], axis=1)


def _moved(plan: FanPlan, n_lo: int, n_hi: int):
    """The plan with ``n_lo`` lattice lines added below its span and ``n_hi`` above (:func:`moving_lines`), and the
    span's end indices i0, i1 (a few array operations on the plan's lines, made again for each block)."""
    i0, i1 = round(plan.s[0] / plan.ds), round(plan.s[-1] / plan.ds)
    null = plan.pattern.null_lines(plan.ds * np.array([i0 - 1, i1 + 1]))   # the span ends on a dropped null
    i0, i1 = i0 - int(null[0]), i1 + int(null[1])
    extra = [np.arange(i0 - n_lo, i0) * plan.ds, np.arange(i1 + 1, i1 + n_hi + 1) * plan.ds]
    extra = [x[~plan.pattern.null_lines(x)] for x in extra]
    return dataclasses.replace(plan, s=np.concatenate([extra[0], plan.s, extra[1]])), i0, i1


def own_lines(s: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(pings, n_az) bool: which of the block's lines ``s`` each ping counts (``keep`` from :func:`moving_lines`)."""
    return (s[None, :] >= keep[:, :1]) & (s[None, :] <= keep[:, 1:])


def drop_lines(prim: np.ndarray, s: np.ndarray, keep: np.ndarray, el_start: np.ndarray) -> None:
    """Mark the rays of each ping on lines it does not count as misses (``prim`` = −1, in place).

    ``prim`` (n,) the fan's hits, azimuth-major within each row of ``el_start`` (rows + 1,) (rows = 2·pings);
    ``s`` (n_az,) the block's lines; ``keep`` (pings, 2) from :func:`moving_lines`."""
    n_el = np.diff(el_start)
    own = np.repeat(own_lines(s, keep), 2, axis=0)                 # (rows, n_az)
    prim[~np.repeat(own.ravel(), np.repeat(n_el, s.shape[0]))] = -1


def ray_cells(s: np.ndarray, el_start: np.ndarray, beta: np.ndarray, dbeta: np.ndarray):
    """Each ray of a fan in its order: body-frame launch direction, row and elevation cell width.

    Parameters
    ----------
    s : (n_az,) float64
        The fan's lines (sin ψ).
    el_start : (rows + 1,) int64
        Elevation rays per row (row r = 2·ping + side: 0 port, 1 starboard); a row's rays are azimuth-major.
    beta, dbeta : (el_start[-1],) float64
        Depression of each elevation ray and its cell width, rad.

    Returns
    -------
    body : (n, 3) float64
        (s, ±√(1 − s²)·cos β, √(1 − s²)·sin β): forward, starboard, down.
    row : (n,) int64
    dbeta : (n,) float64
    """
    row, _, e = _grid(s.shape[0], el_start)
    grid = Fan(s, 0.0, np.cos(beta), np.sin(beta), dbeta, el_start)
    return launch_body(grid, s.shape[0] * el_start, kernels.NO_LAYOUT), row, dbeta[e]


def _grid(n_az: int, el_start: np.ndarray):
    """(row, azimuth line, elevation cell) (n,) int64 of each ray of a fan grid (rows of ``el_start``, each
    azimuth-major over its cells)."""
    n_el = np.diff(el_start)
    row = np.repeat(np.arange(n_el.shape[0]), n_az * n_el)
    j = np.arange(row.shape[0]) - n_az * el_start[row]
    per = np.maximum(n_el[row], 1)
    return row, j // per, el_start[row] + j % per


def launch_body(fan, ray_start: np.ndarray, layout: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The body-frame launch direction (n, 3) of each ray of a block (rows 2·ping + side of ``ray_start``):
    (s, ±cos ψ·cos β, cos ψ·sin β) from the grid of ``fan`` (:data:`~sonar_embree.kernels.args.Fan`: its ``s``,
    cos β, sin β and ``el_start``, each row azimuth-major over its cells), or from each ray's own cell where
    ``layout`` (n, 5: s, cos β, sin β, dβ, ds) has rows (:func:`kernels.launch_body`); into ``out`` (n, 3) when
    given (a block's working array)."""
    out = np.empty((int(ray_start[-1]), 3)) if out is None else out
    kernels.launch_body(fan if layout.shape[0] == 0 else fan._replace(el_start=ray_start), layout, out)
    return out


def rays_per_ping(plan: FanPlan, keep, el_start: np.ndarray) -> np.ndarray:
    """(pings,) rays each ping counts: its own lines × its elevation rays, and the probes."""
    n_el = np.diff(el_start).reshape(-1, 2).sum(axis=1)
    lines = plan.s.shape[0] if keep is None else own_lines(plan.s, keep).sum(axis=1)
    return lines * n_el + plan.n_probe


@dataclass(frozen=True, eq=False)
class BlockEchoes:
    """The echoes of every ray of a block of pings, aligned with the rays.

    Row r = 2·b + side (b the ping in the block, side 0 port, 1 starboard) owns rays
    ``ray_start[r] … ray_start[r + 1] − 1``. Rays that return nothing have weight 0.
    """

    ray_start: np.ndarray   # (rows + 1,) int64
    range_m: np.ndarray     # (n,) float64 slant range (inf: no echo)
    time_s: np.ndarray      # (n,) float64 two-way travel time 2R/c (inf: no echo)
    extent_s: np.ndarray    # (n,) float64 travel-time interval the ray's cell covers, 2ΔR/c
    weight: np.ndarray      # (n,) float64 expected intensity (docs/physics.md §3)
    point_m: np.ndarray     # (n, 3) float64 hit points in the local frame, or (0, 3)
    altitude_m: np.ndarray  # (pings,) nadir range, NaN if none
    n_rays: np.ndarray      # (pings,) rays cast per ping, probes included
    el_start: np.ndarray    # (rows + 1,) int64 elevation rays per row (one azimuth line)
    beta: np.ndarray        # (el_start[-1],) depression of each elevation ray, rad
    dbeta: np.ndarray       # (el_start[-1],) its cell width, rad
    prim: np.ndarray        # (n,) int32 triangle hit by each ray, −1 for none
    tfar: np.ndarray        # (n,) float32 Embree's hit distance, m
    aimed: object = None    # AimedEchoes of the rays aimed at objects (sonar_embree.propagation.aim), or None
    kept_weight: np.ndarray | None = None  # (n,) ``weight`` without the hits on aimed objects (None: none aimed)
    plan: FanPlan | None = None  # the block's fan: the plan's lines and those added under motion (moving_lines)
    arrival: np.ndarray | None = None  # (n, 3) curved rays' unit directions at their hits (keep_arrival), or None

    @property
    def echo_weight(self) -> np.ndarray:
        """(n,) the fan's weights as its echoes carry them: without the hits that aimed rays count instead."""
        return self.weight if self.kept_weight is None else self.kept_weight


def elevation_rows(plan: FanPlan, probe_r: np.ndarray):
    """Elevation rays of every row from the probed ranges.

    Parameters
    ----------
    plan : FanPlan
    probe_r : (rows, L·m) float64
        Probed slant range per row, probe line (:func:`probe_lines`, line-major) and
        probe depression, NaN for nothing in range. Each cell takes the densest
        line's density.

    Returns
    -------
    el_start : (rows + 1,) int64
    beta, dbeta : (el_start[-1],) float64
        Depression and cell width of each elevation ray, rad.
    """
    rows, m = probe_r.shape[0], plan.probe_beta.shape[0]
    dens = beam.elevation_density(plan.probe_beta, probe_r.reshape(-1, m), plan.dr_target_m, plan.max_step_rad,
                                  plan.slope_cap_m_rad, EMPTY_STEP_FACTOR, EDGE_DENSITY_FACTOR)
    dens = np.ascontiguousarray(dens.reshape(rows, -1, m - 1).max(axis=1))  # the densest line per cell
    total = dens @ np.diff(plan.probe_beta)
    counts = np.clip(np.ceil(total - 1e-9), 1, plan.max_rays).astype(np.int64)
    if not all(plan.sides):                                         # a one-sided fan: the other side's rows empty
        counts[~np.tile(np.asarray(plan.sides), rows // 2)] = 0
    el_start = np.concatenate(([0], np.cumsum(counts)))
    beta, dbeta = np.empty(el_start[-1]), np.empty(el_start[-1])
    kernels.place_rows(plan.probe_beta, np.ascontiguousarray(dens), el_start, beta, dbeta)
    return el_start, beta, dbeta


def probe_rows(caster: Caster, plan: FanPlan, rot: np.ndarray, pos_local: np.ndarray, max_range_m: float):
    """Probe a block of pings with straight rays and place the elevation rays of every row.

    Returns
    -------
    el_start, beta, dbeta
        As :func:`elevation_rows`.
    altitude : (pings,) float64
        Range of the nadir ray (world vertical), NaN if nothing is within ``max_range_m``.
    seconds : float
        Time spent in the caster.
    """
    probe_r, _, t_embree = probe_ranges(caster, plan, rot, pos_local, max_range_m)
    altitude, t_nadir = nadir_altitude(caster, pos_local, max_range_m)
    return (*elevation_rows(plan, probe_r.reshape(2 * rot.shape[0], -1)), altitude, t_embree + t_nadir)


def probe_ranges(caster: Caster, plan: FanPlan, rot: np.ndarray, pos_local: np.ndarray, max_range_m: float):
    """The probe rays of a block of pings cast from ``pos_local`` (pings, 3) with attitudes ``rot``: (ranges
    (pings, probes) float64, NaN for nothing within ``max_range_m``; world directions (pings, probes, 3);
    seconds in the caster). Probes per ping: :attr:`FanPlan.probe_body`, port then starboard."""
    n_p, k = rot.shape[0], plan.probe_body.shape[0]
    dirs, dirs32, org32 = np.empty((n_p, k, 3)), np.empty((n_p * k, 3), np.float32), np.empty((n_p * k, 3), np.float32)
    kernels.probe_rays(plan.probe_body, np.ascontiguousarray(rot, dtype=np.float64),
                       np.ascontiguousarray(pos_local, dtype=np.float64), dirs, dirs32, org32)
    t = time.perf_counter()
    prim, tfar = caster.cast_raw(org32, dirs32, max_range_m)
    t_embree = time.perf_counter() - t
    return np.where(prim >= 0, tfar.astype(np.float64), np.nan).reshape(dirs.shape[:2]), dirs, t_embree


def nadir_altitude(caster: Caster, pos_local: np.ndarray, max_range_m: float):
    """(altitude (pings,) float64: the range straight down, NaN if nothing within ``max_range_m``; seconds)."""
    t = time.perf_counter()
    nadir = caster.cast(pos_local, np.broadcast_to([0.0, 0.0, -1.0], (pos_local.shape[0], 3)), max_range_m)
    return np.where(nadir.tri >= 0, nadir.range_m, np.nan), time.perf_counter() - t  # world vertical, float64


def cast_block(caster: Caster, plan: FanPlan, rot: np.ndarray, pos_local: np.ndarray,
               two_way_np_per_m: float, max_range_m: float, time_per_m: float, want_points: bool = False,
               timings: dict | None = None, laws=None, rx_shift: np.ndarray | None = None,
               aim=None) -> BlockEchoes:
    """Probe, place and cast the fans of a block of pings and weight every echo.

    Parameters
    ----------
    caster : Caster
    plan : FanPlan
    rot : (pings, 3, 3) float64
        Body-to-world rotations.
    pos_local : (pings, 3) float64
        Sonar positions in the scene's local frame, m.
    two_way_np_per_m : float
        Two-way absorption, Np/m.
    max_range_m : float
        Echoes beyond this slant range are dropped (and not searched for).
    time_per_m : float
        Two-way travel time per metre of slant range, 2/c (s/m).
    want_points : bool
        Also return the hit points (the speckle lattice needs them).
    timings : dict, optional
        Seconds spent are added under ``"embree"`` (ray casting) and ``"rays"``
        (placing rays and weighting echoes).
    laws : LawTable
        The scene's scattering laws at the carrier (:attr:`~sonar_embree.propagation.prepared.PreparedRun.law_table`).
    rx_shift : (pings,) float64, optional
        Motion during the ping: the receive beam's along-track direction-cosine offset δ = 2·v_fwd/c
        per ping (default: zeros, stop-and-hop; see :func:`kernels.fan_echoes`).
    aim : AimPlan, optional
        The objects to aim rays at (:mod:`sonar_embree.propagation.aim`); None: the fan alone.
    """
    t0 = time.perf_counter()
    n_p = rot.shape[0]
    rx_shift = np.zeros(n_p) if rx_shift is None else np.ascontiguousarray(rx_shift, dtype=np.float64)
    plan, keep = moving_lines(plan, rx_shift)
    # hits a little beyond the window still reach into it with their footprints; the splatting crops them
    max_range_m = max_range_m * (1.0 + 1e-3) + 0.05
    pos_local = np.ascontiguousarray(pos_local, dtype=np.float64)
    el_start, beta, dbeta, altitude, t_embree = probe_rows(caster, plan, rot, pos_local, max_range_m)

    n_az = plan.s.shape[0]
    n = n_az * int(el_start[-1])
    checks.check_rays_memory(n, n_p, "the ray fan")
    dirs = np.empty((n, 3), dtype=np.float32)
    org = np.empty((n, 3), dtype=np.float32)
    rot = np.ascontiguousarray(rot, dtype=np.float64)
    cos_b, sin_b = np.empty_like(beta), np.empty_like(beta)
    kernels.cos_sin(beta, cos_b, sin_b)
    kernels.fan_rays(plan.s, cos_b, sin_b, el_start, rot, pos_local, dirs, org)
    t = time.perf_counter()
    prim, tfar = caster.cast_raw(org, dirs, max_range_m)
    t_embree += time.perf_counter() - t
    if keep is not None:
        drop_lines(prim, plan.s, keep, el_start)

    rng, t_s, ext, w, cos_i = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    c = caster.compiled
    pts = np.empty((n, 3) if want_points or c.needs_points else (0, 3))
    fan = Fan(plan.s, plan.ds, cos_b, sin_b, dbeta, el_start)
    kernels.fan_echoes(fan, Poses(rot, pos_local, rx_shift), prim, tfar, scene_arrays(c),
                       DirectWeighting(plan.tilt_rad, two_way_np_per_m, plan.min_range_m, max_range_m,
                                       plan.slope_cap_m_rad, time_per_m),
                       EchoOut(rng, t_s, ext, w, cos_i, pts), kernels.NO_LAYOUT)
    weigh_by_beam(plan.pattern, plan.tilt_rad, fan, rx_shift, w)
    apply_laws(laws, c, prim, cos_i, w, pts)
    if not plan.footprint:
        ext[:] = 0.0
    n_rays = rays_per_ping(plan, keep, el_start)
    aimed, kept = None, None
    if aim is not None:
        aimed = aim_block(caster, aim, plan, rot, pos_local, rx_shift, two_way_np_per_m, max_range_m, time_per_m,
                          want_points, laws)
        t_embree += aimed.seconds_cast
        if aimed.aimed.any():
            kept = drop_aimed(caster, aim, n_az * el_start, prim, w, aimed.aimed)
            n_rays = n_rays + aimed.n_rays
        else:                                  # nothing in reach to aim at: the fan's echoes alone, as without
            aimed = None
    if timings is not None:
        timings["embree"] = timings.get("embree", 0.0) + t_embree
        timings["rays"] = timings.get("rays", 0.0) + time.perf_counter() - t0 - t_embree
    return BlockEchoes(n_az * el_start, rng, t_s, ext, w, pts, altitude, n_rays, el_start, beta, dbeta, prim, tfar,
                       aimed, kept, plan)
