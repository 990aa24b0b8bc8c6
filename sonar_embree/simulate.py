"""Orchestration: the only module that knows the order of the stages.

    inputs → setup (scene frame, caster, sonar type's front end, back end, truth)
    → per block of pings: front end (poses → rays → hits → physics per hit = Echoes)
                          → ground truth (optional) → back end (splat or speckle)
    → processing (lowpass, TVG) → Record

Each stage has one home: the front end in :mod:`sonar_embree.sonars` (and the
side-scan's ray budget in :mod:`sonar_embree.propagation.fan`, the laws in :mod:`sonar_embree.laws`),
the contract in :mod:`sonar_embree.propagation.echoes`, the back end in :mod:`sonar_embree.signal.synthesis`,
ground truth in :mod:`sonar_embree.signal.labels`, the tail in :mod:`sonar_embree.signal.processing`.
"""
from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from . import checks, kernels, sonars
from .propagation.clutter import check_clutter, clutter_echoes, element_gains
from .propagation.prepared import PreparedRun, RunCache, prepare, scene_caster
from .propagation.volume import VolumeBeam, volume_density
from .signal import processing, pulses
from .config import ARRAY_AZIMUTH_STEP_DEG, Acquisition, FanSettings, Pulse, SignalChain, Sonar, Transducer
from .environment import Environment
from .errors import ConfigError
from .signal.truth import GroundTruth
from .raycast import Caster, RayCaster
from .record import Record
from .scene import Scene, TiledDEM, survey_origin
from .signal.synthesis import ExpectedSynthesis, SpeckleSynthesis
from .trajectory import Trajectory, iso_utc
from .validation import check_bool

log = logging.getLogger(__name__)

#: Rays per block of pings (about): results do not depend on the block size.
BLOCK_RAYS = 2 ** 18
#: Pings of the first block, before the ray count per ping is known.
FIRST_BLOCK_PINGS = 4
#: Rays per block at most where a block is widened to a ping per thread (:func:`next_block_pings`).
MAX_BLOCK_RAYS = 2 ** 21


def next_block_pings(rays_per_ping: int) -> int:
    """Pings of the next block, its pings casting up to ``rays_per_ping`` rays each: about :data:`BLOCK_RAYS` rays,
    but a ping per thread while under :data:`MAX_BLOCK_RAYS` and half of the memory budget of
    :func:`~sonar_embree.checks.rays_memory_budget` (the synthesis kernels run a ping per thread: a block of one ping
    leaves the other cores idle), and never more than the budget holds, 1 to 64. Results do not depend on it."""
    r, budget = max(rays_per_ping, 1), checks.rays_memory_budget()
    wide = MAX_BLOCK_RAYS if budget is None else min(MAX_BLOCK_RAYS, budget // 2)
    n = min(max(BLOCK_RAYS // r, min(kernels.num_threads(), wide // r), 1), 64)
    return n if budget is None else max(min(n, budget // r), 1)


def _cast(run: "_Run", a: int, b: int, speckle: bool, labels: bool, clock: dict):
    """(b, echoes, fan) of pings a … b − 1 (``run.front.cast``); a block of several pings whose rays cannot fit in
    memory (:class:`~sonar_embree.checks.RaysMemoryError`) is cast as its first ping alone (b = a + 1): only a ping
    that cannot fit alone is refused."""
    try:
        return (b, *run.front.cast(run.prepared, run.rots[a:b], run.pos_local[a:b], run.max_r, speckle, labels, clock,
                                   rx_shift=run.rx_shift[a:b]))
    except checks.RaysMemoryError:
        if b - a == 1:
            raise
    return _cast(run, a, a + 1, speckle, labels, clock)


def memory_estimate_bytes(n_pings: int, n_samples: int, chain: SignalChain, labels: bool = False,
                          keep_complex: bool = False, n_channels: int = 2) -> int:
    """Peak memory of a :func:`simulate` call's record-sized arrays, bytes (an estimate, within ~20 %).

    The synthesis buffer (complex for coherent speckle), about three record-sized
    float64 arrays in processing (convolution, TVG, the port/starboard copies), the
    label arrays (25 bytes per sample) and the complex outputs.
    """
    cells = int(n_channels) * int(n_pings) * int(n_samples)
    per = (16 if chain.speckle and chain.detection == "coherent" else 8) + 3 * 8
    per += 25 if labels else 0
    per += 32 if keep_complex else 0
    return cells * per


def _check_memory(n_pings, n_samples, chain, labels, keep_complex, n_channels) -> None:
    """Refuse, before any work, a record that cannot fit in this machine's memory."""
    need = memory_estimate_bytes(n_pings, n_samples, chain, labels, keep_complex, n_channels)
    have = checks.physical_memory_bytes()
    if have is not None and need > 0.8 * have:
        per_ping = need / max(n_pings, 1)
        fit = int(0.5 * have / per_ping)
        raise ConfigError(f"simulate: {n_pings} pings x {n_channels} channels x {n_samples} samples need about "
                          f"{need / 2**30:.1f} GiB in memory, more than this machine's {have / 2**30:.1f} GiB; "
                          f"simulate at most about {fit} pings at a time (Trajectory slices with ping_offset), "
                          "or render them as a batch (sonar-embree batch) that writes each job to disk")


#: A run whose first block projects longer than this logs its time estimate (INFO, ``-v`` on the command line).
ESTIMATE_LOG_S = 30.0


def time_estimate_s(elapsed_s: float, done: int, total: int, pace_s: float) -> float:
    """The run's whole time: what has elapsed, plus the pings left at ``pace_s`` a ping."""
    return elapsed_s + pace_s * max(total - done, 0)


def _log_time_estimate(elapsed_s: float, done: int, total: int, pace_s: float, first: bool) -> None:
    """The whole run's time, when it is long: after the second block, at its pace (the first block's includes the
    set-up and a first run's kernel compilation: an estimate from it came out 20 times too long); after the first
    block, from its pace, only when it is the last chance (the run has two blocks at most)."""
    total_s = time_estimate_s(elapsed_s, done, total, pace_s)
    if total_s > ESTIMATE_LOG_S:
        log.info("simulate: about %.0f s for %d pings (%.1f ms per ping in the %s block)", total_s, total,
                 1e3 * pace_s, "first" if first else "second")


def tile_reach_m(sonar) -> float:
    """How far from the sonar a DEM's tiles are needed: the range window with a margin, m."""
    return 1.05 * sonar.max_range_m + 1.0


def _check_inputs(scene, trajectory, sonar, pulse, fan):
    sonar = sonar.sonar if isinstance(sonar, Acquisition) else sonar   # the instrument the user gave
    for name, value, cls in (("scene", scene, Scene), ("trajectory", trajectory, Trajectory),
                             ("sonar", sonar, sonars.SONAR_TYPES), ("pulse", pulse, Pulse), ("fan", fan, FanSettings)):
        if not isinstance(value, cls):
            names = " or ".join(f"sonar_embree.{c.__name__}" for c in (cls if isinstance(cls, tuple) else (cls,)))
            raise ConfigError(f"simulate: {name} must be a {names}, got {type(value).__name__}")
    if not scene.objects:
        raise ConfigError("simulate: the scene is empty; add a mesh or a seafloor")
    if scene.crs is not None and trajectory.crs is not None and scene.crs != trajectory.crs:
        raise ConfigError(f"simulate: the trajectory's CRS {trajectory.crs} differs from the scene's {scene.crs}; "
                          f"read the navigation with crs={scene.crs!r}")


def simulate(scene: Scene, trajectory: Trajectory, sonar: Sonar | None = None, pulse: Pulse | None = None, *,
             speckle: bool = False, band: str = "baseband", detection: str = "coherent",
             matched_filter: bool | None = None, tvg: bool = False, noise_db_per_hz: float | None = None,
             lowpass_hz: float | None = None, speckle_cell_m: float | None = None, seed: int = 0,
             fan: FanSettings | None = None, chain: SignalChain | None = None, quality: float | None = None,
             labels: bool = False, keep_complex: bool = False, ping_offset: int = 0, progress: bool = False,
             timings: dict | None = None, start_time=None, environment: Environment | None = None,
             caster: type | None = None, cache: RunCache | None = None) -> Record:
    """Simulate a side-scan survey of ``scene`` along ``trajectory``.

    Parameters
    ----------
    scene : Scene or TiledDEM
        Geometry and materials (world metres); a :class:`TiledDEM` gives the scene of its tiles within reach
        of the trajectory.
    trajectory : Trajectory
        One pose per ping.
    sonar : Sonar, EchoSounder, MSIS, ForwardLooking or Acquisition, optional
        The sonar type, its transducer and range window; default
        :class:`Sonar` () (side-scan: channels port and starboard). An
        :class:`~sonar_embree.config.Acquisition` brings its medium along (then leave ``environment`` out).
    environment : Environment, optional
        The medium (sound speed, water, absorption model, sea surface, profile, noise); default
        :class:`Environment` (). The run pairs it with the sonar once (:class:`~sonar_embree.config.Acquisition`).
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
        :class:`~sonar_embree.signal.labels.Labels`) from the fan's centre line, each hit
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
    cache : RunCache, optional
        What runs over the same scene may share (its BVH, law tables, clutter, surface meshes): hand the same
        :class:`~sonar_embree.RunCache` to each run of a loop over one scene. Without one (default) the run
        builds what it needs and frees it when it ends.
    progress : bool
        Show a progress bar over pings (tqdm, on stderr).
    start_time : datetime or str, optional
        Time of the trajectory's time 0 (a ``datetime``, naive taken as UTC, or an
        ISO 8601 string); default: the trajectory's ``start_time`` (navigation logs), else now. Stored as
        ``Record.attrs["start_time"]``
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
        ``data`` (n_pings, n_channels, n_samples) detected intensity for a unit source
        (on-axis intensity 1 at 1 m), sampled at ``time_s`` = n / fs; ``port`` and
        ``starboard`` name the side-scan's channels.

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
    for name, flag in (("labels", labels), ("keep_complex", keep_complex), ("progress", progress)):
        check_bool("simulate", name, flag)
    sonar, pulse, fan, chain = _resolve(sonar, pulse, fan, quality, chain, environment, caster, cache, ping_offset,
                                        dict(speckle=speckle, band=band, detection=detection,
                                             matched_filter=matched_filter, tvg=tvg, noise_db_per_hz=noise_db_per_hz,
                                             lowpass_hz=lowpass_hz, speckle_cell_m=speckle_cell_m, seed=seed))
    if isinstance(scene, TiledDEM):  # the tiles within reach of the whole trajectory
        scene = scene.scene_around(trajectory.positions_m, tile_reach_m(sonar))
    _check_inputs(scene, trajectory, sonar, pulse, fan)
    if trajectory.crs is None and scene.crs is not None:  # its metres are the scene's (a DEM's)
        trajectory = dataclasses.replace(trajectory, crs=scene.crs)
    run = _Run.setup(scene, trajectory, sonar, pulse, fan, chain, labels, keep_complex, caster, ping_offset, cache)
    clock = {} if timings is None else timings
    clock["setup"] = clock.get("setup", 0.0) + time.perf_counter() - t_start
    bar = progress_bar(progress, len(trajectory))
    a, block = 0, FIRST_BLOCK_PINGS if run.front.synth_channels <= 2 else min(kernels.num_threads(), FIRST_BLOCK_PINGS)
    while a < len(trajectory):
        b, e, blk = _cast(run, a, min(a + block, len(trajectory)), chain.speckle, labels, clock)
        run.altitude[a:b], run.n_rays[a:b] = blk.altitude_m, blk.n_rays
        if run.truth is not None:
            t = time.perf_counter()
            run.truth.add_block(run.front, run.prepared, blk, e, a, run.rots[a:b], run.pos_local[a:b], run.max_r)
            clock["labels"] = clock.get("labels", 0.0) + time.perf_counter() - t
        t = time.perf_counter()
        vel = None if trajectory.velocity_m_s is None else trajectory.velocity_m_s[a:b]
        run.back.add_block(e, a, ping_offset + a, run.prepared.compiled.origin_m, trajectory.positions_m[a:b], clock,
                           vel,
                           points=None if run.prepared.clutter is None else _clutter_block(run, a, b),
                           volume=None if run.volume is None else _volume_block(run, trajectory, a, b),
                           receivers=run.front.receivers(run.rots[a:b], trajectory.positions_m[a:b]))
        clock["synthesis"] = clock.get("synthesis", 0.0) + time.perf_counter() - t
        if bar is not None:
            bar.update(b - a)
        nxt = next_block_pings(int(blk.n_rays.max()))
        now = time.perf_counter()
        if a == 0:
            first_end, first_n = now, b
            if b < len(trajectory) <= b + nxt:                 # one block left: no second pace to wait for
                _log_time_estimate(now - t_start, b, len(trajectory), (now - t_start) / b, True)
        elif a == first_n and b < len(trajectory):
            _log_time_estimate(now - t_start, b, len(trajectory), (now - first_end) / (b - a), False)
        a, block = b, nxt
    if bar is not None:
        bar.close()
    t = time.perf_counter()
    intensity, cplx, samples, elements = _process(run, keep_complex)
    clock["processing"] = clock.get("processing", 0.0) + time.perf_counter() - t
    if not np.any(intensity):
        checks.warn_once(f"simulate: the record is all zero: no echo reached any of its {len(trajectory)} pings; "
                         "check the sonar's beam (tilt, beamwidths), its range and the scene's normals")
    return _record(run, intensity, cplx, samples, trajectory, fan,
                   iso_utc(start_time if start_time is not None else trajectory.start_time), elements)


def _array_lines(sonar, fan):
    """``fan`` with lines at most :data:`~sonar_embree.config.ARRAY_AZIMUTH_STEP_DEG`/quality apart for a receive
    array with an element ahead of or behind the transmitter (a SAS), unless ``max_azimuth_step_deg`` is given: its
    image resolves the strips' reach along track (docs/physics.md §4, "Limit")."""
    arr = sonar.receive_array if isinstance(sonar, Transducer) else None   # (a wrong type is named later)
    if not isinstance(fan, FanSettings) or fan.max_azimuth_step_deg is not None or arr is None:
        return fan
    if not any(p[0] != 0.0 for p in arr.positions_m):                # no element ahead of or behind the transmitter
        return fan
    return dataclasses.replace(fan, max_azimuth_step_deg=min(ARRAY_AZIMUTH_STEP_DEG / fan.quality, 30.0))


def _resolve(sonar, pulse, fan, quality, chain, environment, caster, cache, ping_offset, chain_kwargs):
    """Defaults and validation of :func:`simulate`'s settings: (sonar for the pulse, pulse, fan, resolved chain)."""
    sonar = Sonar() if sonar is None else sonar
    pulse = Pulse.cw() if pulse is None else pulse
    if quality is not None:
        if fan is not None:
            raise ConfigError("simulate: give either quality or fan, not both (FanSettings has a quality field)")
        fan = FanSettings(quality=quality)
    fan = FanSettings() if fan is None else fan
    fan = _array_lines(sonar.sonar if isinstance(sonar, Acquisition) else sonar, fan)
    if isinstance(sonar, Acquisition):      # a sonar already in its medium
        if environment is not None and environment != sonar.environment:
            raise ConfigError("simulate: give the medium once: as environment or in the Acquisition, not both")
        sonar, environment = sonar.sonar, sonar.environment
    environment = Environment() if environment is None else environment
    if not isinstance(environment, Environment):
        raise ConfigError(f"simulate: environment must be a sonar_embree.Environment, got {environment!r}")
    if caster is not None and not (isinstance(caster, type) and issubclass(caster, Caster)):
        raise ConfigError(f"simulate: caster must be a subclass of sonar_embree.raycast.Caster, got {caster!r}")
    if cache is not None and not isinstance(cache, RunCache):
        raise ConfigError(f"simulate: cache must be a sonar_embree.RunCache, got {cache!r}")
    if isinstance(ping_offset, bool) or not isinstance(ping_offset, (int, np.integer)) or ping_offset < 0:
        raise ConfigError(f"simulate: ping_offset must be an integer >= 0, got {ping_offset!r}")

    if not isinstance(sonar, sonars.SONAR_TYPES) or not isinstance(pulse, Pulse):
        return sonar, pulse, fan, chain  # _check_inputs names the wrong type
    sonar = Acquisition(sonar.for_pulse(pulse), environment)   # the sonar in this run's medium, resolved once
    if chain is None:
        seed = chain_kwargs["seed"]
        chain = SignalChain(**{**chain_kwargs, "seed": int(seed) if isinstance(seed, np.integer) else seed})
    elif not isinstance(chain, SignalChain):
        raise ConfigError(f"simulate: chain must be a sonar_embree.SignalChain, got {type(chain).__name__}")
    return sonar, pulse, fan, chain.resolved(sonar, pulse)


@dataclass(eq=False)
class _Run:
    """Everything one :func:`simulate` call sets up before its first block."""

    sonar: object
    pulse: Pulse
    chain: SignalChain
    prepared: PreparedRun  # what the run builds before its first block: caster, law table, aim plan, …
    front: object
    back: object
    truth: GroundTruth | None
    rots: np.ndarray
    pos_local: np.ndarray
    max_r: float
    n_out: int
    altitude: np.ndarray
    n_rays: np.ndarray
    n0: float | None = None  # receiver noise density, unit-source intensity per Hz
    rx_shift: np.ndarray | None = None  # motion during the ping: δ = 2·v_fwd/c per ping
    first_ping: int = 0  # the trajectory's first ping within a longer survey (ping_offset)
    volume: VolumeBeam | None = None  # the water column's reverberation beam, if it has any

    @classmethod
    def setup(cls, scene, trajectory, sonar, pulse, fan, chain, labels, keep_complex, caster,
              ping_offset: int = 0, cache: RunCache | None = None) -> "_Run":
        front = sonars.front_end(sonar, fan)
        # channels synthesised: the record's, or a beamformer's inputs (forward-looking: one per azimuth line)
        n_p, n_ch, n_out = len(trajectory), front.synth_channels, sonar.n_samples
        # The compressed sample at t needs echoes up to t + τ: synthesise a pulse length past the window.
        n_s = n_out + (int(math.ceil(pulse.duration_s * sonar.sample_rate_hz)) if chain.matched_filter else 0)
        _check_memory(n_p, n_s, chain, labels, keep_complex, n_ch)
        if keep_complex and not (chain.speckle and chain.detection == "coherent" and chain.lowpass_hz is None):
            raise ConfigError("simulate: keep_complex needs speckle=True, coherent detection and no lowpass_hz "
                              "(the complex signal exists only there)")
        if front.beamforms and chain.speckle and chain.detection != "coherent":
            raise ConfigError(f"simulate: {sonar.type_name} forms its beams from complex signals; its speckle "
                              "needs detection='coherent'")
        _check_array(sonar, chain)
        if labels and not front.supports_labels:
            raise ConfigError(f"simulate: labels are made for side-scan, MSIS and forward-looking sonars, not "
                              f"{sonar.type_name}")
        compiled = scene.compiled(survey_origin(trajectory.positions_m))  # the frame where the rays are
        caster = scene_caster(compiled, RayCaster if caster is None else caster, cache)
        c, fs = sonar.sound_speed_m_s, sonar.sample_rate_hz
        max_r = max(sonar.max_range_m, (n_s - 1) * c / (2.0 * fs))
        pos_local = trajectory.positions_m - compiled.origin_m
        checks.check_setup(caster, sonar, pos_local, max_r + c * pulse.duration_s / 2.0)
        checks.check_ping_spacing(sonar, pos_local)
        checks.check_ping_interval(sonar, trajectory.times_s, len(trajectory))
        checks.check_receiver_band(sonar, pulse)
        checks.check_surface(compiled, sonar, pos_local)
        checks.check_profile(compiled, sonar, pos_local, labels)
        check_clutter(compiled, sonar)
        prepared = prepare(caster, front, sonar.frequency_hz, max_r, chain.seed, labels, cache)
        n0 = _noise_density(sonar, chain)
        # expected intensity of a unit echo: the speckle-free record and the labels' object echoes share it
        kernel = (pulses.expected_kernel(pulse, sonar.frequency_hz, fs, chain.matched_filter)
                  if labels or not chain.speckle else None)
        back_n0 = None if front.beamforms else n0  # a beamformer adds the noise to its beams
        back = (SpeckleSynthesis(sonar, pulse, chain, (n_p, n_ch, n_s), back_n0) if chain.speckle
                else ExpectedSynthesis(sonar, pulse, chain, (n_p, n_ch, n_s), back_n0, kernel))
        truth = GroundTruth((n_p, len(front.channels), n_out), compiled, kernel) if labels else None
        rots = _mounted(front, trajectory, ping_offset)
        return cls(sonar, pulse, chain, prepared, front, back, truth, rots, pos_local, max_r, n_out,
                   np.full(n_p, np.nan), np.zeros(n_p, dtype=np.int64), n0, 2.0 * trajectory.forward_speed_m_s(rots) / c,
                   ping_offset, _volume_beam(sonar))


def _check_array(sonar, chain: SignalChain) -> None:
    """Refuse what a receiver array cannot be simulated with: its elements differ in phase, so they need coherent
    speckle in full (no low-pass on the intensity), and the water column's reverberation is not yet made per
    element."""
    if sonar.receive_array is None:
        return
    if not (chain.speckle and chain.detection == "coherent" and chain.lowpass_hz is None):
        raise ConfigError("simulate: a receive_array needs speckle=True, detection='coherent' and no lowpass_hz "
                          "(its elements differ in phase, which only the coherent signal holds)")
    if sonar.environment.volume_backscatter_db is not None:
        raise ConfigError("simulate: Environment.volume_backscatter_db is not simulated per element of a "
                          "receive_array; leave one of them out")


def _clutter_block(run: _Run, a: int, b: int):
    """The clutter echoes of pings a … b − 1 (:func:`sonar_embree.propagation.clutter.clutter_echoes`), with a
    receiver array each element's pattern along its own direction (:func:`~sonar_embree.propagation.clutter
    .element_gains`)."""
    rot, pos = run.rots[a:b], run.pos_local[a:b]
    points = clutter_echoes(run.prepared.clutter, run.sonar, run.prepared.caster, rot, pos, run.max_r,
                            processing.absorption_np_per_m(run.sonar.alpha_db_per_m))
    rx = run.front.receivers(rot, pos)
    return points if rx is None else element_gains(points, run.sonar, rot, pos, rx)


def _volume_beam(sonar) -> VolumeBeam | None:
    """The water column's reverberation beam (side-scan only; refused for another sonar type)."""
    if sonar.environment.volume_backscatter_db is None:
        return None
    checks.check_side_scan_only(sonar, "Environment.volume_backscatter_db")
    return VolumeBeam.of(sonar)


def _volume_block(run: _Run, trajectory, a: int, b: int):
    """The volume reverberation density of pings a … b − 1 (:func:`sonar_embree.propagation.volume.volume_density`),
    on the back end's samples."""
    return volume_density(run.volume, run.sonar, run.rots[a:b], trajectory.positions_m[a:b, 2], run.altitude[a:b],
                          run.back.out.shape[-1])


def _mounted(front, trajectory, ping_offset: int) -> np.ndarray:
    """Each ping's body-to-world rotation of the transducer: the vehicle's, turned by the front end's mount
    (an MSIS head's bearing at the ping's index) when it has one."""
    return front.mount(trajectory.rotations(), ping_offset + np.arange(len(trajectory)))



def _noise_density(sonar, chain: SignalChain) -> float | None:
    """Receiver noise N0 in unit-source intensity per Hz (the back end adds it before the source level scales the
    record): the chain's N0 (record units) plus, with a source level, the sea's and the receiver's (docs/physics.md
    §14). None: no noise."""
    n0 = 0.0 if chain.noise_db_per_hz is None else 10.0 ** (chain.noise_db_per_hz / 10.0)
    n0 = (n0 + sonar.noise_density()) / sonar.level_scale
    return n0 if n0 > 0.0 else None


def progress_bar(progress: bool, n_pings: int, done: int = 0):
    """A tqdm bar over pings (on stderr) when ``progress``, starting at ``done``; else None."""
    if not progress:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=n_pings, initial=done, desc="pings", unit="ping")


def _process(run: _Run, keep_complex: bool):
    """The common tail: crop to the window, source level, lowpass, the receiver's samples, perfect TVG; intensity
    (pings, channels, n_out), complex and the device's integer samples (or None), and a receiver array's element
    signals (pings, channels, elements, n_out) (or None; element 0 of each channel gives its intensity)."""
    sonar, chain, n_out = run.sonar, run.chain, run.n_out
    intensity, cplx = run.back.finish()
    if run.front.beamforms:
        intensity, cplx = run.front.beamform(intensity, cplx, None if run.n0 is None else run.back.noise_source(run))
    elements = None
    if sonar.receive_array is not None:  # element 0 of each channel is the record's channel
        n_el = sonar.receive_array.n_elements
        elements = cplx[..., :n_out].reshape(cplx.shape[0], -1, n_el, n_out)
        intensity, cplx = intensity[:, ::n_el], cplx[:, ::n_el]
    intensity = intensity[..., :n_out]
    cplx = cplx[..., :n_out] if keep_complex else None
    if sonar.source_level_db is not None:  # unit source → µPa²: one scale, after the noise went in (scaled down)
        intensity = intensity * sonar.level_scale
        cplx = None if cplx is None else cplx * math.sqrt(sonar.level_scale)
        elements = None if elements is None else elements * math.sqrt(sonar.level_scale)
    if chain.lowpass_hz is not None:
        intensity = processing.lowpass(intensity, chain.lowpass_hz, sonar.sample_rate_hz)
    samples = None
    if sonar.receiver is not None:  # the device's integers, from the physical pressures (before display TVG)
        samples = sonar.receiver.samples(intensity, np.arange(n_out) / sonar.sample_rate_hz, sonar)
    if chain.tvg:
        gain = processing.tvg_gain(np.arange(n_out) / sonar.sample_rate_hz, sonar.sound_speed_m_s,
                                   sonar.alpha_db_per_m)
        intensity = intensity * gain
        if keep_complex:
            cplx = cplx * np.sqrt(gain)
        if elements is not None:
            elements = elements * np.sqrt(gain)
    np.maximum(intensity, 0.0, out=intensity)  # FFT/FIR round-off only; intensities are non-negative
    if not np.isfinite(intensity).all():  # never reached by valid settings; never let NaN/inf into a record
        raise ConfigError("simulate: the record would hold NaN or infinite values; check the absorption, "
                          "noise and TVG settings")
    return intensity, cplx, samples, elements


def _record(run: _Run, intensity, cplx, samples, trajectory, fan, start_iso: str, elements=None) -> Record:
    sonar, chain = run.sonar, run.chain
    attrs = {"mode": run.back.mode, **dataclasses.asdict(chain), "alpha_db_per_m": sonar.alpha_db_per_m,
             "quality": fan.quality, "rays_per_ping": float(run.n_rays.mean()) if len(trajectory) else 0.0,
             "start_time": start_iso,
             "intensity_unit": "unit source" if sonar.source_level_db is None else "uPa^2",
             "received_noise_db_per_hz": (None if run.n0 is None
                                          else 10.0 * math.log10(run.n0 * sonar.level_scale)),
             "motion_during_ping": trajectory.velocity_m_s is not None, "crs": trajectory.crs,
             "first_ping": int(run.first_ping)}
    if chain.speckle and chain.band == "carrier":
        attrs["carrier_rate_hz"] = run.back.tables.carrier_factor * sonar.sample_rate_hz
    return Record(np.ascontiguousarray(intensity), np.arange(run.n_out) / sonar.sample_rate_hz, trajectory,
                  sonar.sonar, run.pulse, run.altitude, attrs, None if run.truth is None else run.truth.labels(),
                  None if cplx is None else np.ascontiguousarray(cplx), channels=tuple(run.front.channels),
                  samples=samples, element_data=None if elements is None else np.ascontiguousarray(elements),
                  environment=sonar.environment)
