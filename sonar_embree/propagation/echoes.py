"""The echo contract between the front end and the back end (docs/physics.md §3, §4).

The front end (a sonar type's ray fan, the caster, the scattering laws) turns poses
into :class:`Echoes`; the back end (splatting, speckle synthesis, processing, the
Record) reads nothing else. Times, not ranges: with refraction or multipath the
travel time is not 2R/c, and the back end never needs R.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


#: Paths of :attr:`Echoes.path`: 0 direct S→X→S, 1 one bounce (S→X→S' and S'→X→S), 2 two bounces S'→X→S'
#: (S' the sonar's mirror image in the sea surface; docs/physics.md §13).
PATHS = ("direct", "one bounce", "two bounces")


@dataclass(frozen=True, eq=False)
class AlongTrack:
    """Where a fan's echoes lie along track, row by row: the back end's speckle spreads each echo over its strip
    (docs/physics.md §4, "Along-track footprints").

    A fan's azimuth lines follow one another along the body's forward axis x̂, ``ds`` apart in the along-track
    direction cosine s, so an echo at range R stands for a strip R·ds long along x̂. Its weight holds the two-way
    along-track beam factor P(s) of its own line; spread over the strip, each part takes P at its own s instead
    (the pattern tabulated here), so that the lattice's node weights follow the beam itself, not the lines' steps.

    Attributes
    ----------
    axis_rad : (rows, 3) float64
        x̂ (world, unit) times the lines' spacing ds (rad), per row.
    gain : (rows, n_tab) float64
        P(s) = Γ²(s)·Γ_rx²(s − δ) per row (δ the ping's receive-beam turn) at s = s0 + k·step; 0 outside.
    gain_rx : (rows, n_tab) float64
        Its receive factor alone, as an amplitude |Γ_rx(s − δ)|: a receiver array's element k takes Γ_rx at its own
        along-track cosine s_k instead of the transmitter's s (docs/physics.md §18a).
    s0, step : float
        The table's first s and its spacing.
    side_axis : (rows, 3) float64 or None
        Each row's unit across axis v̂ (world): the beam's second axis, in the elevation plane and perpendicular to
        the boresight (:class:`~sonar_embree.instrument.beams.base.Beam`); None: not tabulated.
    across : (table (n,) float64, v0, step) or None
        The receive pattern's across factor as an amplitude |Γ(v)| on v = v0 + k·step: an element off the
        transmitter's along-track line takes it at its own direction (docs/physics.md §18a).
    """

    axis_rad: np.ndarray
    gain: np.ndarray
    gain_rx: np.ndarray
    s0: float
    step: float
    side_axis: np.ndarray | None = None
    across: tuple | None = None

    def rows(self, r0: int, r1: int, every: int = 1) -> "AlongTrack":
        """Rows r0, r0 + every, … < r1 (a block's pings, or one channel of each)."""
        side = None if self.side_axis is None else self.side_axis[r0:r1:every]
        return AlongTrack(self.axis_rad[r0:r1:every], self.gain[r0:r1:every], self.gain_rx[r0:r1:every], self.s0,
                          self.step, side, self.across)


@dataclass(frozen=True, eq=False)
class Echoes:
    """Every echo of a block of pings, flat arrays in rows of (ping, channel).

    Row ``r = n_channels·b + ch`` (b the ping in the block, ch the channel) owns
    echoes ``ray_start[r] … ray_start[r + 1] − 1``. Echoes of weight 0 return nothing.

    Attributes
    ----------
    n_channels : int
        Channels per ping (side-scan: 2, port then starboard).
    ray_start : (rows + 1,) int64
        Row offsets.
    travel_time_s : (n,) float64
        Two-way travel time of each echo, s (inf: none).
    extent_s : (n,) float64
        Spread in travel time of the surface the echo stands for (its footprint), s.
    weight : (n,) float64
        Expected received intensity (unit source), docs/physics.md eq. (1).
    point_m : (n, 3) float64 or (0, 3)
        Scattering points in the scene's local frame, m (when the back end needs them: speckle).
    object_id : (n,) int32 or (0,)
        Scene object of each echo, −1 for none (when ground truth needs it).
    path : (n,) int8 or (0,)
        Sea-surface path of each echo (:data:`PATHS`), or empty when every echo is direct.
    along : AlongTrack or None
        Each row's along-track strips (speckle spreads the echoes of the fan's lines over them, :class:`AlongTrack`);
        None: each echo at its point.
    on_strip : (n,) bool or (0,)
        Which echoes stand for a strip of the fan's lines (those of rays aimed at objects have their own, finer
        spacing and stay at their points); empty: every echo does.
    """

    n_channels: int
    ray_start: np.ndarray
    travel_time_s: np.ndarray
    extent_s: np.ndarray
    weight: np.ndarray
    point_m: np.ndarray
    object_id: np.ndarray
    path: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int8))
    along: AlongTrack | None = None
    on_strip: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    @property
    def n_pings(self) -> int:
        return (self.ray_start.shape[0] - 1) // self.n_channels

    @property
    def parts(self) -> tuple:
        """The block's paths one after the other (:class:`~sonar_embree.propagation.multipath.PathEchoes`): one."""
        return (self,)

    def merged(self) -> "Echoes":
        """The one :class:`Echoes` of the block: itself (a front end's paths kept apart merge into one)."""
        return self


def merged(e) -> Echoes:
    """The one :class:`Echoes` of a block: ``e`` itself, or the merge of a block whose paths a front end kept
    apart (:class:`sonar_embree.propagation.multipath.PathEchoes`, merged on first use)."""
    return e.merged()


def row_of(ray_start: np.ndarray) -> np.ndarray:
    """(n,) int: the row (channels·ping + channel) of every echo of offsets ``ray_start``."""
    return np.repeat(np.arange(ray_start.shape[0] - 1), np.diff(ray_start))


def row_starts(rows: np.ndarray, n_rows: int) -> np.ndarray:
    """(n_rows + 1,) int64 offsets of echoes sorted by their ``rows`` (the inverse of :func:`row_of`)."""
    return np.concatenate(([0], np.cumsum(np.bincount(rows, minlength=n_rows)))).astype(np.int64)


def select(e: Echoes, keep: np.ndarray) -> Echoes:
    """The echoes where ``keep`` (n,) bool is true, in the same rows (points and ids kept when present)."""
    start = row_starts(row_of(e.ray_start)[keep], e.ray_start.shape[0] - 1)

    def part(a):
        return a[keep] if a.shape[0] == keep.shape[0] else a

    return Echoes(e.n_channels, start, e.travel_time_s[keep], e.extent_s[keep], e.weight[keep], part(e.point_m),
                  part(e.object_id), part(e.path), e.along, part(e.on_strip))


def ping_slice(e: Echoes, a: int, b: int) -> Echoes:
    """The echoes of the block's pings a … b − 1 (rows a·channels … b·channels − 1), offsets from 0."""
    r0, r1 = a * e.n_channels, b * e.n_channels
    i0, i1 = int(e.ray_start[r0]), int(e.ray_start[r1])

    def part(x):
        return x[i0:i1] if x.shape[0] == e.weight.shape[0] else x

    along = None if e.along is None else e.along.rows(r0, r1)
    return Echoes(e.n_channels, e.ray_start[r0:r1 + 1] - i0, e.travel_time_s[i0:i1], e.extent_s[i0:i1],
                  e.weight[i0:i1], part(e.point_m), part(e.object_id), part(e.path), along, part(e.on_strip))
