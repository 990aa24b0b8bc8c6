"""The back end: echoes → received signal per (ping, channel), then detected intensity.

Reads only :class:`~sonar_embree.propagation.echoes.Echoes` (docs/physics.md §3–5):

- :class:`ExpectedSynthesis` (speckle-free): every echo's weight spread over the
  travel-time interval of its footprint, then one convolution with the pulse
  intensity (or the compressed pulse's |q|²): eq. (1) sampled at t_n;
- :class:`SpeckleSynthesis`: the echoes gathered onto scatterers frozen to the
  surface (:class:`ScattererLattice`), synthesised in complex baseband or as the
  real carrier signal, then detected coherently or incoherently.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft

from .. import kernels
from ..kernels.args import NO_ACROSS, Across, Lattice, NodeTables, PathEnds, SpeckleEchoes, Waveform
from ..propagation import multipath
from . import processing, pulses
from ..config import Pulse, SignalChain
from ..propagation.clutter import PointEchoes
from ..propagation.echoes import Echoes, merged, ping_slice, select
from .processing import convolve_time


#: No along-track strips: every echo at its point (:func:`strips`).
_NO_STRIPS = (np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), 0.0, 1.0, np.zeros(0, dtype=bool))


def strips(e: Echoes) -> tuple:
    """The kernel's view of the echoes' along-track strips (:attr:`~sonar_embree.propagation.echoes.Echoes.along`,
    None: none): axis, gain, receive gain, s0, step and which echoes lie on them
    (:data:`~sonar_embree.kernels.args.SpeckleEchoes`)."""
    a = e.along
    if a is None:
        return _NO_STRIPS
    rows = e.ray_start.shape[0] - 1
    if (a.axis_rad.shape[0] != rows or a.gain.shape != a.gain_rx.shape or a.gain.shape[0] != rows
            or e.on_strip.shape[0] not in (0, e.weight.shape[0])):
        raise ValueError(f"along-track strips for {a.axis_rad.shape[0]} rows and {e.on_strip.shape[0]} echoes, "
                         f"echoes in {rows} rows and {e.weight.shape[0]} echoes")   # a front end's bug, not input
    return (a.axis_rad, a.gain, a.gain_rx, float(a.s0), float(a.step),
            np.ascontiguousarray(e.on_strip, dtype=np.bool_))


#: Receivers closer than this to the reference receiver's along-track line take its across-track pattern, m.
ACROSS_OFF_LINE_M = 1e-6


def across(e: Echoes, pos_rx: np.ndarray, ref: np.ndarray, mirrored: bool = False) -> Across:
    """The kernel's view of the receive pattern across track (:data:`~sonar_embree.kernels.args.Across`): for
    receivers ``pos_rx`` (pings, rows, 3) of which any lies off the along-track line through ``ref`` (pings, 3), the
    echoes' across axes and table, each element then taking the pattern at its own direction; else none (a line of
    elements along track, or one receiver, keeps its bits and its cost). ``mirrored``: the receivers are images in
    the sea surface, whose arrivals come mirrored (the axes' vertical part turned over)."""
    a = e.along
    if a is None or a.side_axis is None or a.across is None or pos_rx.ndim != 3:
        return NO_ACROSS
    n_p = ref.shape[0]
    fwd = a.axis_rad[::max(a.axis_rad.shape[0] // max(n_p, 1), 1)][:n_p]
    fwd = fwd / np.linalg.norm(fwd, axis=1, keepdims=True)
    off = pos_rx - ref[:, None, :]
    off = off - np.einsum("prk,pk->pr", off, fwd)[..., None] * fwd[:, None, :]
    if not np.any(np.linalg.norm(off, axis=2) > ACROSS_OFF_LINE_M):
        return NO_ACROSS
    side = a.side_axis * [1.0, 1.0, -1.0] if mirrored else a.side_axis
    return Across(np.ascontiguousarray(side, dtype=np.float64), *a.across)


class ScattererLattice:
    """Scatterers frozen to the surface: a world-fixed cubic lattice (see :func:`kernels.speckle_block`).

    Every node holds :data:`SUB_SCATTERERS` point scatterers with independent frozen
    complex Gaussian reflectivities, sharing the node's echo W equally and placed in
    travel time at t̄ + √3·σ·(2v − 1), where t̄ and σ² are the W-weighted mean and
    variance of the times its echoes' footprints cover and v a frozen
    stratified-uniform position in [0, 1), clipped to the least and greatest of those
    times (nothing arrives before the first surface). The echo energy keeps its place
    and spread in time, and neighbouring nodes' scatterers interleave, so the expected
    intensity has no comb at the lattice spacing. One hash table per worker thread; a
    table grows (and stays grown) when a ping's nodes would fill more than half of it (:func:`grown_capacity`).
    """

    SUB_SCATTERERS = 4

    def __init__(self, cell_m: float, seed: int, n_tables: int):
        self.cell_m = float(cell_m)
        self.seed = int(seed)
        self._alloc(max(int(n_tables), 1), 1 << 16)

    def _alloc(self, n_t, cap):
        self.slots = np.full((n_t, cap), -1, dtype=np.int64)  # no slot belongs to any call yet
        self.epochs = np.zeros(n_t, dtype=np.int64)
        self.nodes = np.zeros((n_t, cap // 2, kernels.NODE_WIDTH))  # W, Wt, Wt2, t_min, t_max per node
        self.node_key = np.zeros((n_t, cap // 2, 4), dtype=np.int64)
        self.caches = np.zeros((n_t, kernels.CACHE_WIDTH), dtype=np.int64)

    def synthesise(self, e: Echoes, origin_m, pos_world, wavelength_m: float, rate_hz: float,
                   phase_cycles_per_s: float, synth: "WaveformTables", out, pos_rx=None, vel_rx=None,
                   rx_ref=None, time_per_m: float = 0.0, draw: int = 0, mirrored: bool = False):
        """Add the block's scatterer echoes to ``out`` (pings, channels, n) complex, h from ``synth``'s table.

        ``pos_world`` transmits and ``pos_rx`` (default: the same) receives, world m per ping, the receiver
        moving at ``vel_rx`` (m/s per ping; default at rest) during the ping. ``pos_rx`` may instead hold a
        receiver per output channel, (pings, channels, 3): an array's elements, each with its own path; then
        ``rx_ref`` (pings, 3) is the receiver the echoes' times were made for and ``time_per_m`` (1/c, s/m) delays
        each element's envelope by its path's difference (:func:`kernels.speckle_block`). An ``out`` of shape
        (pings, channels, S, n) takes the elements from one emission per node, sub-row s still to be delayed by
        s/S sample (:func:`kernels.speckle_block_shared`, :func:`delayed_sum`); elements off the reference's
        along-track line also take the receive pattern across track at their own directions (:func:`across`;
        ``mirrored``: the receivers are images in the sea surface). ``draw`` > 0 gives the nodes scatterers
        independent of draw 0's (the second of an array's two one-bounce paths, :meth:`SpeckleSynthesis._lattice`).
        """
        pos_world = np.ascontiguousarray(pos_world)
        pos_rx = pos_world if pos_rx is None else np.ascontiguousarray(pos_rx)
        ref = pos_rx if rx_ref is None else np.ascontiguousarray(rx_ref)
        if pos_rx.ndim == 2:  # one receiver heard on every channel
            pos_rx = np.ascontiguousarray(np.repeat(pos_rx[:, None, :], out.shape[1], axis=1))
        vel_rx = np.zeros_like(pos_world) if vel_rx is None else np.ascontiguousarray(vel_rx, dtype=np.float64)
        status = np.zeros(pos_world.shape[0], dtype=np.int64)
        if self.epochs.max() + 2 * status.size >= 2 ** 31:  # slots pack the epoch in 32 bits: start afresh
            self._alloc(self.slots.shape[0], self.slots.shape[1])
        kernel = kernels.speckle_block_shared if out.ndim == 4 else kernels.speckle_block
        off_line = across(e, pos_rx, ref, mirrored) if time_per_m != 0.0 else NO_ACROSS
        echoes = SpeckleEchoes(*map(_plain, (e.ray_start, e.point_m, origin_m, e.weight, e.travel_time_s,
                                             e.extent_s, *strips(e), *off_line)))
        ends = PathEnds(*map(_plain, (pos_world, pos_rx, vel_rx, ref)), float(time_per_m))
        while True:
            kernel(
                echoes, ends,
                Lattice(self.seed if draw == 0 else _draw_seed(self.seed, draw), self.cell_m, wavelength_m,
                        self.SUB_SCATTERERS),
                Waveform(synth.table, synth.table_start, synth.table_rate, rate_hz, phase_cycles_per_s),
                NodeTables(self.slots, self.epochs, self.nodes, self.node_key, self.caches), status, out)
            if np.all(status > 0):
                return
            self._alloc(self.slots.shape[0], grown_capacity(self.slots.shape[1], status, e.ray_start))
            status[status < 0] = 0


#: The most a node table grows at once (:func:`grown_capacity`).
MAX_TABLE_GROWTH = 16


def grown_capacity(cap: int, status: np.ndarray, ray_start: np.ndarray) -> int:
    """The next node-table capacity after pings failed with ``cap`` slots (:func:`kernels.speckle_block`: status
    −2 − k, the table full at the ping's k-th ray of ``ray_start``'s rows, channels·pings + 1): room for the nodes
    the worst ping's rays make at the rate its first k made them (a table holds half its slots), a power of two from
    2·cap to :data:`MAX_TABLE_GROWTH`·cap. Doubling alone re-gathered the first ping at every size (seven times for
    the 3.3 million nodes of a SAS ping at 100 kHz, about as long as the gather that then fits)."""
    n_p = status.shape[0]
    n_ch = (ray_start.shape[0] - 1) // max(n_p, 1)
    rays = ray_start[n_ch * np.arange(1, n_p + 1)] - ray_start[n_ch * np.arange(n_p)]
    failed = status < 0
    reached = np.maximum(-status[failed] - 2, 1)
    factor = float(np.max(rays[failed] / reached))
    return int(cap) << int(min(max(math.ceil(math.log2(max(factor, 2.0))), 1), int(math.log2(MAX_TABLE_GROWTH))))


def _plain(x):
    """An array argument of the speckle kernels as they are compiled for: C-contiguous and writeable (a copy of a
    strided or read-only one: each layout and flag would compile the kernels again, 10–30 s per process); other
    values unchanged."""
    return np.require(x, requirements=("C", "W")) if isinstance(x, np.ndarray) else x


def _draw_seed(seed: int, draw: int) -> int:
    """A lattice seed for draw ``draw`` of a run's seed: a 63-bit integer from NumPy's SeedSequence of both."""
    return int(np.random.SeedSequence([int(seed) & (2 ** 63 - 1), 0x4D1CED, int(draw)]).generate_state(1, np.uint64)[0]
               >> np.uint64(1))


#: A baseband pulse longer than this many samples (an FM pulse: 2·B·τ of them at fs = 2B) is synthesised as
#: band-limited impulses (a Kaiser-windowed sinc of ±IMPULSE_HALF_WIDTH samples, flat to 1e-4 up to fs/4, the band
#: of a complex baseband at fs = 2B) convolved once per ping with p̃ by FFT, instead of splatting every scatterer
#: with the whole pulse: the same signal (tested: the difference under −40 dB of its energy, at most 0.5 % of the
#: peak amplitude, at sharp onsets whose tabulated pulse holds content beyond the band), at a cost that no longer
#: grows with τ (an EdgeTech 4125 chirp: 150 → 34 ms per ping, docs/benchmarks.md).
IMPULSE_MIN_SAMPLES = 16
IMPULSE_HALF_WIDTH = 8


@dataclass(frozen=True, eq=False)
class WaveformTables:
    """Tables for synthesising one ping's signal."""

    table: np.ndarray
    table_start: float
    table_rate: float
    carrier_factor: int = 1               # carrier rate / record rate
    carrier_pulse: np.ndarray | None = None
    baseband_pulse: np.ndarray | None = None  # impulses splatted, then convolved with p̃(n/fs) (long pulses)

    @classmethod
    def build(cls, sonar, pulse: Pulse, chain: SignalChain) -> "WaveformTables":
        f0, fs = sonar.frequency_hz, sonar.sample_rate_hz
        if chain.band == "baseband":
            table, rate = pulses.envelope_table(pulse, f0, fs)
            if table.shape[0] / rate > IMPULSE_MIN_SAMPLES:  # a long pulse (a chirp): impulses, then one convolution
                interp, start, r = processing.sinc_interpolator(IMPULSE_HALF_WIDTH)
                return cls(interp, start, float(r), baseband_pulse=pulses.envelope_table(pulse, f0, fs, rate=1)[0])
            if not np.any(table.imag):  # a real envelope (CW): the splat multiplies by reals, with the same bits
                table = np.ascontiguousarray(table.real)
            return cls(table, 0.0, float(rate))
        f_hi = pulse.frequency_span_hz(f0)[1]
        factor = max(int(math.ceil(4.0 * f_hi / fs)), 2)
        table, start, rate = processing.sinc_interpolator()
        return cls(table, start, float(rate), factor, pulses.passband_analytic(pulse, f0, factor * fs))


def _carrier_ping(synth: WaveformTables, sonar, chain: SignalChain, buf, noise_bb, n_s):
    """Detect one ping synthesised on the carrier.

    ``buf`` (channels, n_c) holds impulses C·e^(j2πf0τ) at the carrier rate (band-limited
    fractional delays); convolved with p̃(t)·e^(j2πf0 t) its real part is
    Re{C·p̃(t − τ)·e^(j2πf0 t)}. Returns complex baseband (coherent) or intensity
    (incoherent), shape (channels, n_s), at the record rate.
    """
    f0, fs = sonar.frequency_hz, sonar.sample_rate_hz
    m = synth.carrier_factor
    fc = m * fs
    n_c = (n_s - 1) * m + 1
    x = convolve_time(buf, synth.carrier_pulse).real
    t_c = np.arange(n_c) / fc
    if noise_bb is not None:  # the receiver band's noise, interpolated to the carrier rate and modulated
        from scipy.signal import resample_poly

        up = resample_poly(noise_bb, m, 1, axis=-1)[:, :n_c]
        x += (up * np.exp(2j * np.pi * ((f0 * t_c) % 1.0))).real
    if chain.detection == "coherent":
        return processing.analytic_baseband(x, f0, fc, step=m)
    return processing.square_law(x, f0, fc)[:, ::m]


def _band(sonar):
    """The taps of the sonar's receiver band-pass at its sample rate, or None (:func:`processing.band_taps`)."""
    rx = sonar.receiver
    return processing.band_taps(None if rx is None else rx.bandwidth_hz, sonar.sample_rate_hz)


class ExpectedSynthesis:
    """Speckle-free: footprint splatting, then one convolution with the unit echo's intensity."""

    mode = "expected_intensity"

    def __init__(self, sonar, pulse: Pulse, chain: SignalChain, shape: tuple, n0, echo_kernel):
        self.sonar, self.pulse, self.chain, self.n0 = sonar, pulse, chain, n0
        self.out = np.zeros(shape)
        self.kernel, self.lead = echo_kernel

    def add_block(self, e: Echoes, a: int, survey_a: int, origin_m, pos_world, clock: dict, vel_world=None,
                  points=None, volume=None, receivers=None) -> None:
        """Splat the echoes of pings a … a + e.n_pings − 1 (``survey_a``: their index in the survey), the clutter's
        ``points`` (:class:`~sonar_embree.propagation.clutter.PointEchoes`, or None) and the water column's
        reverberation density ``volume`` (pings, channels, n_s) per s (or None): their expected intensities; the
        velocity ``vel_world`` moves only speckle phases and a receiver array's ``receivers`` need speckle
        (refused at set-up), so neither is needed here."""
        fs = self.sonar.sample_rate_hz
        b = a + e.n_pings
        parts = e.parts if points is None else e.parts + (points.echoes,)
        for part in parts:  # a block's paths one after the other: row by row, the merged order
            kernels.splat_rows(part.ray_start, part.travel_time_s, part.extent_s, part.weight, fs,
                               self.out[a:b].reshape(part.ray_start.shape[0] - 1, self.out.shape[-1]))
        if volume is not None:  # the water column: a continuum of echoes, ρ(t)·dt per sample
            self.out[a:b] += volume / fs

    def finish(self):
        """Detected intensity (pings, channels, n_s) and no complex signal."""
        intensity = convolve_time(self.out, self.kernel, self.lead)
        if self.n0 is not None:
            intensity += self._noise_mean(self.n0)
        return intensity, None

    def _noise_mean(self, n0: float) -> float:
        """Mean intensity of receiver noise of density ``n0`` after the receiver's band-pass and the matched filter:
        n0·fs·Σ|h|², h the two filters in turn."""
        f0, fs = self.sonar.frequency_hz, self.sonar.sample_rate_hz
        h = _band(self.sonar)
        if h is None:  # white over the band: the matched filter's Σ|h_mf|² = 1/Σ|r|²
            gain = 1.0 / np.sum(np.abs(pulses.replica(self.pulse, f0, fs)) ** 2) if self.chain.matched_filter else 1.0
            return n0 * fs * gain
        if self.chain.matched_filter:
            r = pulses.replica(self.pulse, f0, fs)
            h = np.convolve(h, np.conj(r[::-1]) / np.sum(np.abs(r) ** 2))
        return n0 * fs * float(np.sum(np.abs(h) ** 2))

    def noise_source(self, run):
        """For a beamformer: ``noise(shape, complex_)`` of the run's density on its outputs (the mean intensity)."""
        return lambda shape, complex_: np.full(shape, self._noise_mean(run.n0))


@dataclass(frozen=True, eq=False)
class _Ends:
    """A block's path ends: the scene's local origin (3,), the transmitter (pings, 3) and its velocity (pings, 3)
    or None, world m and m/s, and a receiver array's elements (pings, channels, 3) or None."""

    origin_m: np.ndarray
    pos_world: np.ndarray
    vel_world: np.ndarray | None
    receivers: np.ndarray | None


def _element_points(e: Echoes, row, cycles, ends: _Ends, sonar, n_out_ch: int):
    """The clutter's point echoes heard by every element: (echo index, output row, travel time (s), phase (cycles)),
    one per echo and element, each element's path |X − p_k − v·τ| replacing the return leg |X − p_tx| (docs/physics.md
    §18a; τ the echo's monostatic time, v the block's velocity or 0)."""
    n_ch = (e.ray_start.shape[0] - 1) // ends.pos_world.shape[0]
    n_el = n_out_ch // n_ch
    ping, ch = row // n_ch, row % n_ch
    x = e.point_m + ends.origin_m                                       # (n, 3) world
    d_ref = np.linalg.norm(x - ends.pos_world[ping], axis=1)
    k = np.arange(n_el)
    rx = ends.receivers[ping[:, None], ch[:, None] * n_el + k]          # (n, elements, 3)
    if ends.vel_world is not None:                                      # where each element is when the echo arrives
        rx = rx + (ends.vel_world[ping] * e.travel_time_s[:, None])[:, None, :]
    extra = np.linalg.norm(x[:, None, :] - rx, axis=2) - d_ref[:, None]  # (n, elements) m
    out_row = (ping[:, None] * n_out_ch + ch[:, None] * n_el + k).ravel()
    idx = np.repeat(np.arange(row.size), n_el)
    times = (e.travel_time_s[:, None] + extra / sonar.sound_speed_m_s).ravel()
    return idx, out_row, times, (cycles[:, None] - extra / sonar.wavelength_m).ravel() % 1.0


def _moving_points(e: Echoes, row, cycles, ends: _Ends, sonar):
    """The clutter's point echoes heard by a receiver moving at the block's velocity v during the ping: (travel time
    (s), phase (cycles)), the return leg |X − p − v·τ| replacing |X − p| (τ the echo's monostatic time; the lattice's
    nodes take the same leg for their phase, docs/physics.md §16)."""
    ping = row // e.n_channels
    x = e.point_m + ends.origin_m
    p = ends.pos_world[ping]
    extra = np.linalg.norm(x - p - ends.vel_world[ping] * e.travel_time_s[:, None], axis=1) - np.linalg.norm(x - p,
                                                                                                             axis=1)
    return e.travel_time_s + extra / sonar.sound_speed_m_s, (cycles - extra / sonar.wavelength_m) % 1.0


def _ends_of(ends: _Ends, a: int, b: int) -> _Ends:
    """The path ends of the block's pings a … b − 1."""
    return _Ends(ends.origin_m, ends.pos_world[a:b], None if ends.vel_world is None else ends.vel_world[a:b],
                 None if ends.receivers is None else ends.receivers[a:b])


def _points_of(points, a: int, b: int):
    """The clutter points of the block's pings a … b − 1: echoes, phases (cycles) and element gains."""
    e = points.echoes
    i0, i1 = int(e.ray_start[a * e.n_channels]), int(e.ray_start[b * e.n_channels])
    gain = None if points.element_gain is None else points.element_gain[i0:i1]
    return PointEchoes(ping_slice(e, a, b), points.cycles[i0:i1], gain)


#: A receiver array's scatterers are put on a grid of 1/ARRAY_DELAY_STEPS sample (each split linearly between its
#: two nearest grid times) and the fractions delayed once per row in the frequency domain (:func:`delayed_sum`):
#: within 0.01 dB and 0.001 rad of per-element synthesis at a compressed peak (0.002–0.009 dB measured), −50 dB of
#: the record's energy (the Kaiser-sinc table's own departure from an exact fractional delay; docs/benchmarks.md,
#: "Receiver arrays").
#: A power of two.
ARRAY_DELAY_STEPS = 16
#: Memory of the sub-rows a block of shared array synthesis fills at once, bytes (:func:`shared_chunk_pings`).
SHARED_BYTES = 1 << 27


def shared_chunk_pings(rows: int, n: int) -> int:
    """How many pings of ``rows`` rows of ``n`` samples fill :data:`SHARED_BYTES` of sub-rows (at least one per
    thread)."""
    per_ping = rows * ARRAY_DELAY_STEPS * n * 16
    return max(SHARED_BYTES // per_ping, kernels.num_threads(), 1)


def delayed_sum(shared, plain, pulse, lead: int):
    """Σ_s shared[..., s, :] delayed by s/S sample, plus ``plain``, convolved with ``pulse`` (``lead`` its taps before
    delay 0), in one pass through the frequency domain: the delays are exact for a band-limited signal (a phase ramp
    e^(−j2πν·s/S) over the FFT's frequencies ν, cycles per sample).

    Parameters
    ----------
    shared : (pings, rows, S, n) complex
        Impulses on a grid of 1/S sample, sub-row s still to be delayed by s/S (:func:`kernels.speckle_block_shared`).
    plain : (pings, rows, n) complex
        Band-limited impulses at their times (the clutter's points).
    pulse : (n_p,) complex
        The baseband pulse p̃(k/fs).
    lead : int
        Samples the impulses were delayed by (the output starts there).

    Returns
    -------
    (pings, rows, n) complex
        ``y[n] = Σ_k pulse[k]·x[n + lead − k]`` of the delayed sum x (:func:`~.processing.convolve_time`).
    """
    n, steps = plain.shape[-1], shared.shape[-2]
    n_fft = sfft.next_fast_len(n + pulse.shape[0] + IMPULSE_HALF_WIDTH, real=False)
    f = np.fft.fftfreq(n_fft)                                    # cycles per sample
    ramp = np.exp(-2j * np.pi * np.outer(np.arange(steps) / steps, f))
    x = np.einsum("prsf,sf->prf", sfft.fft(shared, n_fft, axis=-1), ramp) + sfft.fft(plain, n_fft, axis=-1)
    y = sfft.ifft(x * sfft.fft(pulse, n_fft), axis=-1)
    return np.ascontiguousarray(y[..., lead:lead + n])


class SpeckleSynthesis:
    """Frozen scatterers synthesised in baseband or on the carrier, then detected (docs/physics.md §4)."""

    mode = "speckle"

    def __init__(self, sonar, pulse: Pulse, chain: SignalChain, shape: tuple, n0):
        self.sonar, self.pulse, self.chain, self.n0 = sonar, pulse, chain, n0
        self.lattice = ScattererLattice(chain.speckle_cell_m, chain.seed, kernels.num_threads())
        self.band = _band(sonar)
        self.tables = WaveformTables.build(sonar, pulse, chain)
        coherent = chain.detection == "coherent"
        self.out = np.zeros(shape, dtype=np.complex128) if coherent else np.zeros(shape)

    def add_block(self, e: Echoes, a: int, survey_a: int, origin_m, pos_world, clock: dict, vel_world=None,
                  points=None, volume=None, receivers=None) -> None:
        """Synthesise pings a … a + e.n_pings − 1 (``survey_a``: their index in the survey, for noise), the
        clutter's ``points`` (:class:`~sonar_embree.propagation.clutter.PointEchoes`, or None) and the water column's
        reverberation density ``volume`` (pings, channels, n_s) per s (or None); the vehicle moves at ``vel_world``
        (pings, 3) m/s during them (None: at rest). ``receivers`` (pings, channels, 3), world m: a receiver array's
        element per synthesised channel, each on its own path (None: every channel receives at ``pos_world``)."""
        e = merged(e)
        s, chain, out = self.sonar, self.chain, self.out[a:a + e.n_pings]
        fs, f0 = s.sample_rate_hz, s.frequency_hz
        n_b, n_ch, n_s = out.shape
        ends = _Ends(origin_m, np.ascontiguousarray(pos_world), vel_world, receivers)
        if chain.band == "baseband" and self.tables.baseband_pulse is not None:
            self._impulses(e, ends, out, points)
        elif chain.band == "baseband":
            self._lattice(e, ends, fs, 0.0, out)  # coherent
            self._points(points, ends, fs, 0.0, out)
        else:
            m = self.tables.carrier_factor
            buf = np.zeros((n_b, n_ch, (n_s - 1) * m + 1), dtype=np.complex128)
            self._lattice(e, ends, m * fs, f0, buf)
            self._points(points, ends, m * fs, f0, buf)
        t = time.perf_counter()
        for b in range(n_b):
            noise = None
            if self.n0 is not None:  # per-ping stream: the same bits for any ping order, block or worker count
                rng = np.random.default_rng([chain.seed, 0x5EED_0015E, survey_a + b])
                noise = processing.band_noise(rng, (n_ch, n_s), self.n0 * fs, self.band)
            if volume is not None:
                reverb = self._reverberation(volume[b], survey_a + b)
                noise = reverb if noise is None else noise + reverb
            if chain.band == "baseband":
                if noise is not None:
                    out[b] += noise
            else:
                out[b] = _carrier_ping(self.tables, s, chain, buf[b], noise, n_s)
        dt = time.perf_counter() - t  # per-ping detection on the carrier is processing, not synthesis
        clock["processing"] = clock.get("processing", 0.0) + dt
        clock["synthesis"] = clock.get("synthesis", 0.0) - dt

    def _reverberation(self, density, survey_ping: int):
        """(channels, n_s) complex baseband volume reverberation of one ping: circular Gaussian samples of variance
        ρ/fs from its own stream, convolved with the pulse's envelope p̃(m/fs), so E|z|² = Σ ρ/fs·|p̃|²."""
        fs = self.sonar.sample_rate_hz
        rng = np.random.default_rng([self.chain.seed, 0x5E4A_C01, survey_ping])
        z = processing.complex_noise(rng, density.shape, 1.0) * np.sqrt(density / fs)
        return convolve_time(z, pulses.replica(self.pulse, self.sonar.frequency_hz, fs))

    def _points(self, points, ends: "_Ends", rate_hz: float, phase_cycles_per_s: float, out,
                delay_s: float = 0.0) -> None:
        """Add the clutter's point echoes to ``out`` (pings, channels, n) complex: √w·e^(j2π·cycles), times the
        carrier's e^(j2π·f0·t) on the carrier, splatted with the waveform table at t + ``delay_s``; with a receiver
        array, each element's at its own delay and phase (:func:`_element_points`); a moving receiver hears each
        point where it is when the echo arrives (:func:`_moving_points`)."""
        if points is None or points.echoes.weight.size == 0:
            return
        e = points.echoes
        row = np.repeat(np.arange(e.ray_start.shape[0] - 1), np.diff(e.ray_start))
        weight, times, cycles = e.weight, e.travel_time_s, points.cycles
        if ends.receivers is not None:
            idx, row, times, cycles = _element_points(e, row, cycles, ends, self.sonar, out.shape[1])
            weight = weight[idx] if points.element_gain is None else weight[idx] * points.element_gain.ravel() ** 2
        elif ends.vel_world is not None:
            times, cycles = _moving_points(e, row, cycles, ends, self.sonar)
        amp = np.sqrt(weight) * np.exp(2j * np.pi * cycles)
        if phase_cycles_per_s != 0.0:
            amp = amp * np.exp(2j * np.pi * ((phase_cycles_per_s * times) % 1.0))
        t = self.tables
        kernels.splat_table(row, (times + delay_s) * rate_hz, amp, t.table, t.table_start, t.table_rate,
                            out.reshape(-1, out.shape[-1]))

    def _impulses(self, e: Echoes, ends: "_Ends", out, points=None) -> None:
        """A long pulse in baseband: the scatterers as band-limited impulses (delayed by the interpolator's half
        width so that none loses its early taps), then one FFT convolution with p̃(n/fs) per block, added to
        ``out``. A receiver array's elements share each node's scatterers, their delays applied by FFT
        (:func:`kernels.speckle_block_shared`, :func:`delayed_sum`), a few pings at a time
        (:func:`shared_chunk_pings`); a receiver per channel keeps the splat and its bits."""
        fs, lead = self.sonar.sample_rate_hz, IMPULSE_HALF_WIDTH
        late = dataclasses.replace(e, travel_time_s=e.travel_time_s + lead / fs)
        n_b, rows, n = out.shape
        if ends.receivers is None or rows == (e.ray_start.shape[0] - 1) // max(n_b, 1):  # a receiver per channel
            buf = np.zeros((n_b, rows, n + lead), dtype=np.complex128)
            self._lattice(late, ends, fs, 0.0, buf)
            self._points(points, ends, fs, 0.0, buf, lead / fs)
            out += convolve_time(buf, self.tables.baseband_pulse, lead=lead)[..., :n]
            return
        chunk = shared_chunk_pings(rows, n + lead)
        for a in range(0, n_b, chunk):
            b = min(a + chunk, n_b)
            sub, sub_ends = ping_slice(late, a, b), _ends_of(ends, a, b)
            shared = np.zeros((b - a, rows, ARRAY_DELAY_STEPS, n + lead), dtype=np.complex128)
            buf = np.zeros((b - a, rows, n + lead), dtype=np.complex128)
            self._lattice(sub, sub_ends, fs, 0.0, shared)
            sub_points = None if points is None else _points_of(points, a, b)
            self._points(sub_points, sub_ends, fs, 0.0, buf, lead / fs)
            out[a:b] += delayed_sum(shared, buf, self.tables.baseband_pulse, lead)[..., :n]

    def _lattice(self, e: Echoes, ends: "_Ends", rate_hz: float, phase_cycles_per_s: float, out) -> None:
        """The lattice's echoes of every path: each its own gather and phase, the frozen scatterers shared; the
        receiver (or its image) moves at the block's velocity (or its mirror) during the ping; a receiver array's
        elements (or their images) each on their own path. The one-bounce echo stands for S→X→S' and S'→X→S, added
        in power (docs/physics.md §13); where an array's elements are off the transmitter the two differ, and each
        takes half the weight on its own legs, S→X→R_k' and S'→X→R_k, the second with its own scatterer draw (so
        that they still add in power)."""
        s, origin_m, pos, vel, rcv = self.sonar, ends.origin_m, ends.pos_world, ends.vel_world, ends.receivers
        moving = vel is not None and bool(np.any(vel))          # each receiver's own leg in the envelope too
        time_per_m = 1.0 / s.sound_speed_m_s if rcv is not None or moving else 0.0
        if e.path.shape[0] == 0:
            self.lattice.synthesise(e, origin_m, pos, s.wavelength_m, rate_hz, phase_cycles_per_s, self.tables,
                                    out, pos_rx=rcv, vel_rx=vel, rx_ref=pos, time_per_m=time_per_m)
            return
        z_s = s.environment.surface.z_m
        image = multipath.mirror(pos, z_s)
        rcv_image = None if rcv is None else multipath.mirror(rcv, z_s)
        v, v_image = (None, None) if vel is None else (vel, vel * [1.0, 1.0, -1.0])
        legs = [(0, pos, rcv if rcv is not None else pos, pos, v, 1.0, 0),
                (1, pos, rcv_image if rcv is not None else image, image, v_image, 1.0, 0),
                (2, image, rcv_image if rcv is not None else image, image, v_image, 1.0, 0)]
        if rcv is not None and np.any(rcv != pos[:, None, :]):       # elements off the transmitter: S'→X→R_k too
            legs[1:2] = [(1, pos, rcv_image, image, v_image, 0.5, 0), (1, image, rcv, pos, v, 0.5, 1)]
        for p, tx, rx, ref, vr, share, draw in legs:
            part = select(e, e.path == p)
            if share != 1.0:
                part = dataclasses.replace(part, weight=share * part.weight)
            self.lattice.synthesise(part, origin_m, tx, s.wavelength_m, rate_hz, phase_cycles_per_s, self.tables,
                                    out, pos_rx=rx, vel_rx=vr, rx_ref=ref, time_per_m=time_per_m, draw=draw,
                                    mirrored=ref is image)

    def noise_source(self, run):
        """For a beamformer: ``noise(shape, complex_)`` of the run's density on its outputs (pings, beams, n_s), each
        ping from its own stream keyed by its survey index (as :meth:`add_block`'s), matched-filtered as the
        signal was."""
        def noise(shape, complex_):
            fs, out = self.sonar.sample_rate_hz, np.empty(shape, dtype=np.complex128)
            for b in range(shape[0]):
                rng = np.random.default_rng([self.chain.seed, 0xBEA4F0, run.first_ping + b])
                out[b] = processing.band_noise(rng, shape[1:], run.n0 * fs, self.band)
            if self.chain.matched_filter:
                out = processing.matched_filter(out, pulses.replica(self.pulse, self.sonar.frequency_hz, fs))
            return out
        return noise

    def finish(self):
        """Detected intensity (pings, channels, n_s) and the complex signal (coherent) or None."""
        if self.chain.detection != "coherent":
            return self.out, None
        out = self.out
        if self.chain.matched_filter:
            f0, fs = self.sonar.frequency_hz, self.sonar.sample_rate_hz
            out = processing.matched_filter(out, pulses.replica(self.pulse, f0, fs))
        return out.real ** 2 + out.imag ** 2, out
