"""Orchestration: the only module that knows the order of the stages.

Per block of pings (:mod:`sonar_embree.fan`): poses → probe cast (where does range
change fast?) → ray fans placed for the range resolution → one Embree call for the
block → expected echo intensity and range footprint per ray (Numba). Then, by mode:

- speckle-free (``speckle=False``): footprint splatting of the intensities (each
  spread over the range interval its ray covers), one convolution with the pulse intensity (or, with matched
  filtering, the compressed pulse's |q|²): docs/physics.md eq. (1) sampled at t_n;
- speckle: the rays' intensities are gathered onto scatterers frozen to the
  surface (a world-fixed lattice, each node a complex Gaussian reflectivity), whose
  echoes are synthesised in complex baseband (exact delayed envelope and carrier
  phase) or as the real carrier signal (band-limited fractional delays), then
  detected coherently or incoherently.

Common tail: receiver noise, matched filter, detection, low-pass FIR, perfect TVG.
"""
from __future__ import annotations

import dataclasses
import logging
import math
import os
import time
from dataclasses import dataclass

import numpy as np

from . import checks, kernels, processing, pulses
from .config import FanSettings, Pulse, SignalChain, Sonar
from .environment import Environment
from .errors import ConfigError
from .fan import BlockEchoes, FanPlan, cast_block, label_block, object_echo_block
from .labels import Labels
from .processing import absorption_np_per_m, convolve_time
from .raycast import Caster, RayCaster
from .record import Record
from .trajectory import iso_utc
from .scene import Scene, survey_origin
from .trajectory import Trajectory

log = logging.getLogger(__name__)

PORT, STARBOARD = 0, 1
_SIDE_SIGN = {PORT: -1, STARBOARD: +1}


def memory_estimate_bytes(n_pings: int, n_samples: int, chain: SignalChain, labels: bool = False,
                          keep_complex: bool = False) -> int:
    """Peak memory of a :func:`simulate` call's record-sized arrays, bytes (an estimate, within ~20 %).

    The synthesis buffer (complex for coherent speckle), about three record-sized
    float64 arrays in processing (convolution, TVG, the port/starboard copies), the
    label arrays (25 bytes per sample) and the complex outputs.
    """
    cells = 2 * int(n_pings) * int(n_samples)
    per = (16 if chain.speckle and chain.detection == "coherent" else 8) + 3 * 8
    per += 25 if labels else 0
    per += 32 if keep_complex else 0
    return cells * per


def _physical_memory_bytes() -> int | None:
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def _check_memory(n_pings, n_samples, chain, labels, keep_complex) -> None:
    """Refuse, before any work, a record that cannot fit in this machine's memory."""
    need = memory_estimate_bytes(n_pings, n_samples, chain, labels, keep_complex)
    have = _physical_memory_bytes()
    if have is not None and need > 0.8 * have:
        per_ping = need / max(n_pings, 1)
        fit = int(0.5 * have / per_ping)
        raise ConfigError(f"simulate: {n_pings} pings x 2 channels x {n_samples} samples need about "
                          f"{need / 2**30:.1f} GiB in memory, more than this machine's {have / 2**30:.1f} GiB; "
                          f"simulate at most about {fit} pings at a time (Trajectory slices with ping_offset), "
                          "or render them as a batch (sonar-embree batch) that writes each job to disk")


def _check_inputs(scene, trajectory, sonar, pulse, fan):
    for name, value, cls in (("scene", scene, Scene), ("trajectory", trajectory, Trajectory),
                             ("sonar", sonar, Sonar), ("pulse", pulse, Pulse), ("fan", fan, FanSettings)):
        if not isinstance(value, cls):
            raise ConfigError(f"simulate: {name} must be a sonar_embree.{cls.__name__}, got {type(value).__name__}")
    if not scene.objects:
        raise ConfigError("simulate: the scene is empty; add a mesh or a seafloor")


class _ScattererLattice:
    """Scatterers frozen to the surface: a world-fixed cubic lattice (see :func:`kernels.speckle_block`).

    Every node holds :data:`SUB_SCATTERERS` point scatterers with independent frozen
    complex Gaussian reflectivities, sharing the node's echo W equally and placed in
    range at R̄ + √3·σ·(2v − 1), where R̄ and σ² are the W-weighted mean and variance
    of the ranges its rays' footprints cover and v a frozen stratified-uniform
    position in [0, 1), clipped to the least and greatest of those ranges (nothing
    arrives before the first surface). The echo energy keeps its place and spread in
    range, and neighbouring nodes' scatterers interleave, so the expected intensity
    has no comb at the lattice spacing. One hash table per worker thread; a table
    grows (and stays grown) when a ping's nodes would fill more than half of it.
    """

    SUB_SCATTERERS = 4

    def __init__(self, cell_m: float, seed: int, n_tables: int):
        self.cell_m = float(cell_m)
        self.seed = int(seed)
        self._alloc(max(int(n_tables), 1), 1 << 16)

    def _alloc(self, n_t, cap):
        self.key = np.zeros((n_t, cap, 4), dtype=np.int64)
        self.stamp = np.full((n_t, cap), -1, dtype=np.int64)
        self.epochs = np.zeros(n_t, dtype=np.int64)
        self.vals = [np.zeros((n_t, cap)) for _ in range(5)]  # W, WR, WR2, R_min, R_max
        self.order = np.zeros((n_t, cap), dtype=np.int64)

    def synthesise(self, e: BlockEchoes, origin_m, pos_world, wavelength_m: float, delay_per_m: float,
                   phase_cycles_per_m: float, synth: "_Synth", out):
        """Add the block's scatterer echoes to ``out`` (pings, 2, n) complex, h from ``synth``'s table."""
        status = np.zeros(pos_world.shape[0], dtype=np.int64)
        while True:
            kernels.speckle_block(e.ray_start, e.point_m, origin_m, e.weight, e.range_m, e.extent_m,
                                  np.ascontiguousarray(pos_world), self.seed, self.cell_m, wavelength_m, delay_per_m,
                                  phase_cycles_per_m, self.SUB_SCATTERERS, synth.table, synth.table_start,
                                  synth.table_rate, self.key, self.stamp, self.epochs, *self.vals, self.order,
                                  status, out)
            if np.all(status > 0):
                return
            self._alloc(self.key.shape[0], 2 * self.key.shape[1])
            status[status < 0] = 0


@dataclass(frozen=True, eq=False)
class _Synth:
    """Tables for synthesising one ping's signal."""

    table: np.ndarray
    table_start: float
    table_rate: float
    carrier_factor: int = 1               # carrier rate / record rate
    carrier_pulse: np.ndarray | None = None

    @classmethod
    def build(cls, sonar: Sonar, pulse: Pulse, chain: SignalChain) -> "_Synth":
        f0, fs = sonar.frequency_hz, sonar.sample_rate_hz
        if chain.band == "baseband":
            table, rate = pulses.envelope_table(pulse, f0, fs)
            return cls(table, 0.0, float(rate))
        f_hi = pulse.frequency_span_hz(f0)[1]
        factor = max(int(math.ceil(4.0 * f_hi / fs)), 2)
        table, start, rate = processing.sinc_interpolator()
        return cls(table, start, float(rate), factor, pulses.passband_analytic(pulse, f0, factor * fs))


def _carrier_ping(synth: _Synth, sonar: Sonar, chain: SignalChain, buf, noise_bb, n_s):
    """Detect one ping synthesised on the carrier.

    ``buf`` (2, n_c) holds impulses C·e^(j2πf0τ) at the carrier rate (band-limited
    fractional delays); convolved with p̃(t)·e^(j2πf0 t) its real part is
    Re{C·p̃(t − τ)·e^(j2πf0 t)}. Returns complex baseband (coherent) or intensity
    (incoherent), shape (2, n_s), at the record rate.
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


def _speckle_block(e: BlockEchoes, a: int, lattice: _ScattererLattice, synth: _Synth, sonar: Sonar,
                   chain: SignalChain, origin_m, pos_world, n0, out, clock):
    """Synthesise the pings a … a + len(pos_world) − 1 of a block into ``out`` (pings, 2, n_s)."""
    fs, c, f0 = sonar.sample_rate_hz, sonar.sound_speed_m_s, sonar.frequency_hz
    n_b, _, n_s = out.shape
    if chain.band == "baseband":
        lattice.synthesise(e, origin_m, pos_world, sonar.wavelength_m, 2.0 * fs / c, 0.0, synth, out)  # coherent
    else:
        fc = synth.carrier_factor * fs
        buf = np.zeros((n_b, 2, (n_s - 1) * synth.carrier_factor + 1), dtype=np.complex128)
        lattice.synthesise(e, origin_m, pos_world, sonar.wavelength_m, 2.0 * fc / c, 2.0 * f0 / c, synth, buf)
    t = time.perf_counter()
    for b in range(n_b):
        noise = None
        if n0 is not None:  # per-ping stream: the same bits for any ping order, block or worker count
            rng = np.random.default_rng([chain.seed, 0x5EED_0015E, a + b])
            noise = processing.complex_noise(rng, (2, n_s), n0 * fs)
        if chain.band == "baseband":
            if noise is not None:
                out[b] += noise
        else:
            out[b] = _carrier_ping(synth, sonar, chain, buf[b], noise, n_s)
    dt = time.perf_counter() - t  # per-ping detection on the carrier is processing, not synthesis
    clock["processing"] = clock.get("processing", 0.0) + dt
    clock["synthesis"] = clock.get("synthesis", 0.0) - dt


def simulate(scene: Scene, trajectory: Trajectory, sonar: Sonar | None = None, pulse: Pulse | None = None, *,
             speckle: bool = False, band: str = "baseband", detection: str = "coherent",
             matched_filter: bool | None = None, tvg: bool = False, noise_db_per_hz: float | None = None,
             lowpass_hz: float | None = None, speckle_cell_m: float | None = None, seed: int = 0,
             fan: FanSettings | None = None, chain: SignalChain | None = None, quality: float | None = None,
             labels: bool = False, keep_complex: bool = False, ping_offset: int = 0, progress: bool = False,
             timings: dict | None = None, start_time=None, environment: Environment | None = None,
             caster: type | None = None) -> Record:
    """Simulate a side-scan survey of ``scene`` along ``trajectory``.

    Parameters
    ----------
    scene : Scene
        Geometry and materials (world metres).
    trajectory : Trajectory
        One pose per ping.
    sonar : Sonar, optional
        Transducer and range window (and its medium); default :class:`Sonar` ().
    environment : Environment, optional
        The medium (sound speed, water, absorption model); replaces ``sonar.environment``.
    pulse : Pulse, optional
        Transmitted pulse; default 100 µs rectangular CW.
    speckle, band, detection, matched_filter, tvg, noise_db_per_hz, lowpass_hz, speckle_cell_m, seed
        The signal chain; see :class:`SignalChain` (units in the names). Invalid
        combinations raise :class:`ConfigError`.
    fan : FanSettings, optional
        Ray density; default :class:`FanSettings` () (quality 1).
    quality : float, optional
        Shorthand for ``fan=FanSettings(quality=quality)``: scales every ray
        density (1: flat-floor error below 0.2 dB; 0.5 about twice as fast; see
        docs/benchmarks.md). Not allowed together with ``fan``.
    chain : SignalChain, optional
        The whole signal chain at once; overrides the keywords above.
    labels : bool
        Also compute per-sample ground truth (``Record.labels``, see
        :class:`~sonar_embree.labels.Labels`) from the fan's centre line, each hit
        followed through to the seafloor behind it (extra casts for that only).
    keep_complex : bool
        Also keep the detected complex baseband signal (``Record.port_complex``,
        ``starboard_complex``; |·|² is the intensity, TVG applied as its square
        root). Needs coherent speckle without ``lowpass_hz``.
    ping_offset : int
        Index of the first ping of ``trajectory`` within a longer survey. Per-ping
        random streams (receiver noise) are keyed by the survey's ping index, so a
        survey simulated in pieces gives the same bits as in one call.
    caster : type, optional
        The ray caster, a subclass of :class:`sonar_embree.raycast.Caster`; default
        :class:`~sonar_embree.raycast.EmbreeCaster` (``NumpyCaster``: the brute-force
        reference, for small scenes and tests).
    progress : bool
        Show a progress bar over pings (tqdm, on stderr).
    start_time : datetime or str, optional
        Time of the trajectory's time 0 (a ``datetime``, naive taken as UTC, or an
        ISO 8601 string); default: now. Stored as ``Record.attrs["start_time"]``
        (ISO 8601 UTC) and used for the ping times of XTF and Zarr outputs.
    timings : dict, optional
        If given, seconds spent are added under ``"setup"`` (BVH build and tables),
        ``"embree"`` (ray casting), ``"rays"`` (ray placement and echo weights),
        ``"synthesis"`` (binning echoes into samples), ``"labels"`` (ground truth,
        when asked for) and ``"processing"``
        (convolution, matched filter, detection, filters, TVG).

    Returns
    -------
    Record
        ``port`` and ``starboard`` (n_pings, n_samples) detected intensity for a unit
        source (on-axis intensity 1 at 1 m), sampled at ``time_s`` = n / fs.

    Notes
    -----
    Each ray of solid angle dΩ hitting at range R stands for dA = R² dΩ / cos θi and
    carries the expected intensity w = Γ⁴ σ(θi) 10^(−2αR/10) dΩ / (R² cos θi)
    (docs/physics.md eq. 1). Speckle-free: Σ w·|p(t − 2R/c)|². Speckle: every node of the
    lattice of :class:`SignalChain` ``speckle_cell_m`` collects W = Σ w·b (trilinear b)
    and echoes √W·g·e^(−j2k·R_node)·p̃(t − 2R̄/c), g a complex Gaussian frozen to
    the node and R̄ the W-weighted range of its rays, so E|Σ|² = Σ w·|p̃|².
    """
    t_start = time.perf_counter()
    sonar = Sonar() if sonar is None else sonar
    pulse = Pulse.cw() if pulse is None else pulse
    if quality is not None:
        if fan is not None:
            raise ConfigError("simulate: give either quality or fan, not both (FanSettings has a quality field)")
        fan = FanSettings(quality=quality)
    fan = FanSettings() if fan is None else fan
    if environment is not None:
        if not isinstance(environment, Environment):
            raise ConfigError(f"simulate: environment must be a sonar_embree.Environment, got {environment!r}")
        sonar = dataclasses.replace(sonar, environment=environment)
    _check_inputs(scene, trajectory, sonar, pulse, fan)
    if caster is not None and not (isinstance(caster, type) and issubclass(caster, Caster)):
        raise ConfigError(f"simulate: caster must be a subclass of sonar_embree.raycast.Caster, got {caster!r}")
    if isinstance(ping_offset, bool) or not isinstance(ping_offset, (int, np.integer)) or ping_offset < 0:
        raise ConfigError(f"simulate: ping_offset must be an integer >= 0, got {ping_offset!r}")
    start_iso = iso_utc(start_time)
    sonar = sonar.for_pulse(pulse)
    if chain is None:
        chain = SignalChain(speckle=speckle, band=band, detection=detection, matched_filter=matched_filter,
                            tvg=tvg, noise_db_per_hz=noise_db_per_hz, lowpass_hz=lowpass_hz,
                            speckle_cell_m=speckle_cell_m, seed=seed if not isinstance(seed, np.integer)
                            else int(seed))
    elif not isinstance(chain, SignalChain):
        raise ConfigError(f"simulate: chain must be a sonar_embree.SignalChain, got {type(chain).__name__}")
    chain = chain.resolved(sonar, pulse)
    _check_memory(len(trajectory), sonar.n_samples + (int(math.ceil(pulse.duration_s * sonar.sample_rate_hz))
                                                      if chain.matched_filter else 0), chain, labels, keep_complex)
    if keep_complex and not (chain.speckle and chain.detection == "coherent" and chain.lowpass_hz is None):
        raise ConfigError("simulate: keep_complex needs speckle=True, coherent detection and no lowpass_hz "
                          "(the complex signal exists only there)")

    compiled = scene.compiled(survey_origin(trajectory.positions_m))  # the frame where the rays are
    caster = (RayCaster if caster is None else caster).for_scene(compiled)  # built once per scene
    plan = FanPlan.build(sonar, fan)
    n_p, n_out = len(trajectory), sonar.n_samples
    # The compressed sample at t needs echoes up to t + τ: synthesise a pulse length past the window.
    n_s = n_out + (int(math.ceil(pulse.duration_s * sonar.sample_rate_hz)) if chain.matched_filter else 0)
    max_r = max(sonar.max_range_m, (n_s - 1) * sonar.sound_speed_m_s / (2.0 * sonar.sample_rate_hz))
    f0, fs, c = sonar.frequency_hz, sonar.sample_rate_hz, sonar.sound_speed_m_s
    altitude = np.full(n_p, np.nan)
    rots = trajectory.rotations()
    pos_local = trajectory.positions_m - compiled.origin_m
    checks.check_setup(caster, sonar, pos_local, max_r + c * pulse.duration_s / 2.0)
    two_way = absorption_np_per_m(sonar.alpha_db_per_m)
    n0 = None if chain.noise_db_per_hz is None else 10.0 ** (chain.noise_db_per_hz / 10.0)

    coherent = chain.detection == "coherent"
    if not chain.speckle:
        out = np.zeros((n_p, 2, n_s))
    else:
        lattice = _ScattererLattice(chain.speckle_cell_m, chain.seed, kernels.num_threads())
        synth = _Synth.build(sonar, pulse, chain)
        out = np.zeros((n_p, 2, n_s), dtype=np.complex128) if coherent else np.zeros((n_p, 2, n_s))
    n_rays = np.zeros(n_p, dtype=np.int64)
    if labels:
        truth = tuple(np.zeros((n_p, 2, n_out), dtype=Labels.DTYPES[k]) for k in Labels.ARRAYS)
    # expected intensity of a unit echo: the speckle-free record and the labels' object echoes share it
    echo_kernel = pulses.expected_kernel(pulse, f0, fs, chain.matched_filter) if labels or not chain.speckle \
        else None
    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=n_p, desc="pings", unit="ping")
    delay_per_m = 2.0 * fs / c
    clock = {} if timings is None else timings
    clock["setup"] = clock.get("setup", 0.0) + time.perf_counter() - t_start
    a, block = 0, 4
    while a < n_p:
        b = min(a + block, n_p)
        e = cast_block(caster, plan, rots[a:b], pos_local[a:b], two_way, max_r, want_points=chain.speckle,
                       timings=clock)
        altitude[a:b], n_rays[a:b] = e.altitude_m, e.n_rays
        if labels:
            t = time.perf_counter()
            label_block(caster, plan, e, rots[a:b], pos_local[a:b], compiled.is_seafloor, max_r, c / (2.0 * fs),
                        float(compiled.origin_m[2]), tuple(x[a:b] for x in truth[:5]))
            object_echo_block(e, compiled.face_object, compiled.is_seafloor, 2.0 * fs / c, *echo_kernel,
                              truth[5][a:b], truth[6][a:b])
            clock["labels"] = clock.get("labels", 0.0) + time.perf_counter() - t
        t = time.perf_counter()
        if not chain.speckle:
            kernels.splat_rows(e.ray_start, e.range_m * delay_per_m, e.extent_m * delay_per_m, e.weight,
                               out[a:b].reshape(2 * (b - a), n_s))
        else:
            _speckle_block(e, ping_offset + a, lattice, synth, sonar, chain, compiled.origin_m, trajectory.positions_m[a:b], n0,
                           out[a:b], clock)
        clock["synthesis"] = clock.get("synthesis", 0.0) + time.perf_counter() - t
        if bar is not None:
            bar.update(b - a)
        a = b  # blocks of ~256k rays: results do not depend on the block size
        block = int(np.clip(2 ** 18 // max(int(e.n_rays.max()), 1), 1, 64))
    if bar is not None:
        bar.close()

    t = time.perf_counter()
    if not chain.speckle:
        kernel, lead = echo_kernel
        intensity = convolve_time(out, kernel, lead)
        if n0 is not None:  # mean intensity of the noise after the matched filter
            gain = 1.0 / np.sum(np.abs(pulses.replica(pulse, f0, fs)) ** 2) if chain.matched_filter else 1.0
            intensity += n0 * fs * gain
        mode = "expected_intensity"
    else:
        if coherent:
            if chain.matched_filter:
                out = processing.matched_filter(out, pulses.replica(pulse, f0, fs))
            intensity = out.real ** 2 + out.imag ** 2
            if keep_complex:
                cplx = out[..., :n_out]
        else:
            intensity = out
        mode = "speckle"

    intensity = intensity[..., :n_out]
    time_s = np.arange(n_out) / fs
    if chain.lowpass_hz is not None:
        intensity = processing.lowpass(intensity, chain.lowpass_hz, fs)
    if chain.tvg:
        gain = processing.tvg_gain(time_s, c, sonar.alpha_db_per_m)
        intensity = intensity * gain
        if keep_complex:
            cplx = cplx * np.sqrt(gain)
    np.maximum(intensity, 0.0, out=intensity)  # FFT/FIR round-off only; intensities are non-negative
    if not np.isfinite(intensity).all():  # never reached by valid settings; never let NaN/inf into a record
        raise ConfigError("simulate: the record would hold NaN or infinite values; check the absorption, "
                          "noise and TVG settings")
    clock["processing"] = clock.get("processing", 0.0) + time.perf_counter() - t
    attrs = {"mode": mode, **dataclasses.asdict(chain), "alpha_db_per_m": sonar.alpha_db_per_m,
             "quality": fan.quality, "rays_per_ping": float(n_rays.mean()) if n_p else 0.0,
             "start_time": start_iso}
    if chain.speckle and chain.band == "carrier":
        attrs["carrier_rate_hz"] = synth.carrier_factor * fs
    truth_labels = None
    if labels:
        truth_labels = Labels(*(np.ascontiguousarray(x.transpose(1, 0, 2)) for x in truth), names=compiled.labels,
                              is_seafloor=tuple(bool(x) for x in compiled.is_seafloor))
    return Record(port=np.ascontiguousarray(intensity[:, PORT]),
                  starboard=np.ascontiguousarray(intensity[:, STARBOARD]),
                  time_s=time_s, trajectory=trajectory, sonar=sonar, pulse=pulse, altitude_m=altitude,
                  attrs=attrs, labels=truth_labels,
                  port_complex=np.ascontiguousarray(cplx[:, PORT]) if keep_complex else None,
                  starboard_complex=np.ascontiguousarray(cplx[:, STARBOARD]) if keep_complex else None)
