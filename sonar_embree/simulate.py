"""Orchestration: the only module that knows the order of the stages.

Per ping: pose → probe cast (where does range change fast?) → ray fan placed for the
range resolution → one Embree call for both sides → echo intensity per ray (Numba)
→ linear fractional-delay splatting (Numba). After all pings: one FFT convolution
with the pulse intensity. The result equals PHYSICS.md eq. (1) sampled at t_n.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from . import beam, kernels, pulses
from .config import FanSettings, Pulse, Sonar
from .errors import ConfigError
from .processing import absorption_np_per_m, convolve_time
from .raycast import RayCaster
from .record import Record
from .scene import Scene
from .trajectory import Trajectory

log = logging.getLogger(__name__)

PORT, STARBOARD = 0, 1
_SIDE_SIGN = {PORT: -1, STARBOARD: +1}


@dataclass(frozen=True, eq=False)
class FanPlan:
    """Everything about the ray fan that does not depend on the pose."""

    s: np.ndarray            # (n_az,) along-track direction cosines
    ds: float                # their spacing
    probe_beta: np.ndarray   # (m,) probe depressions (uniform), also the cell edges
    probe_body: np.ndarray   # (2m, 3) body-frame probe directions, port then starboard (_ping adds nadir)
    dr_target_m: float
    max_step_rad: float
    slope_cap_m_rad: float
    max_rays: int

    @classmethod
    def build(cls, sonar: Sonar, fan: FanSettings) -> "FanPlan":
        s, ds = beam.azimuth_samples(sonar.wavelength_m, sonar.length_m, fan.azimuth_oversample,
                                     fan.azimuth_nulls)
        lo, hi = beam.elevation_span_rad(sonar.wavelength_m, sonar.height_m, sonar.tilt_rad)
        m = max(int(math.ceil((hi - lo) / math.radians(fan.probe_step_deg))) + 1, 3)
        probe = np.linspace(lo, hi, m)
        body = np.concatenate([beam.fan_body([0.0], probe, -1), beam.fan_body([0.0], probe, +1)])
        return cls(s, ds, probe, body, sonar.range_bin_m / fan.rays_per_bin,
                   math.radians(fan.max_step_deg), 10.0 * sonar.max_range_m, fan.max_rays_per_side)


def _check_inputs(scene, trajectory, sonar, pulse, fan):
    for name, value, cls in (("scene", scene, Scene), ("trajectory", trajectory, Trajectory),
                             ("sonar", sonar, Sonar), ("pulse", pulse, Pulse), ("fan", fan, FanSettings)):
        if not isinstance(value, cls):
            raise ConfigError(f"simulate: {name} must be a sonar_embree.{cls.__name__}, got {type(value).__name__}")
    if not scene.objects:
        raise ConfigError("simulate: the scene is empty; add a mesh or a seafloor")


def _ping(caster: RayCaster, plan: FanPlan, sonar: Sonar, rot: np.ndarray, pos_local: np.ndarray,
          two_way_np: float, out: np.ndarray) -> float:
    """Render one ping's two impulse trains into ``out`` (2, n_samples); return the altitude (m, NaN if none)."""
    max_r = sonar.max_range_m
    m = plan.probe_beta.shape[0]
    probe_dirs = np.concatenate([plan.probe_body @ rot.T, [[0.0, 0.0, -1.0]]])
    ph = caster.cast(pos_local, probe_dirs, max_r)
    probe_r = np.where(ph.tri >= 0, ph.range_m, np.nan)
    altitude = probe_r[-1]

    dirs, gam, dom, chan = [], [], [], []
    for side in (PORT, STARBOARD):
        r_side = probe_r[side * m:(side + 1) * m]
        dens = beam.elevation_density(plan.probe_beta, r_side, plan.dr_target_m, plan.max_step_rad,
                                      plan.slope_cap_m_rad)
        beta, dbeta = beam.place_rays(plan.probe_beta, dens, plan.max_rays)
        dirs.append(beam.fan_body(plan.s, beta, _SIDE_SIGN[side]))
        gam.append(beam.fan_directivity(plan.s, beta, sonar))
        dom.append(np.tile(dbeta * plan.ds, plan.s.shape[0]))
        chan.append(np.full(plan.s.shape[0] * beta.shape[0], side, dtype=np.int64))
    dirs = np.concatenate(dirs) @ rot.T
    gam, dom, chan = np.concatenate(gam), np.concatenate(dom), np.concatenate(chan)

    hits = caster.cast(pos_local, dirs, max_r)
    sel = np.nonzero(hits.echo & (gam != 0.0))[0]
    if sel.size:
        r = hits.range_m[sel]
        mu = caster.compiled.mu[hits.object_id[sel]]
        w = np.empty(sel.size)
        kernels.lambert_intensity(r, hits.cos_inc[sel], gam[sel], dom[sel], mu, two_way_np,
                                  sonar.wavelength_m, w)
        delay = r * (2.0 * sonar.sample_rate_hz / sonar.sound_speed_m_s)
        kernels.splat_linear(chan[sel], delay, w, out)
    return float(altitude)


def simulate(scene: Scene, trajectory: Trajectory, sonar: Sonar | None = None, pulse: Pulse | None = None, *,
             speckle: bool = False, seed: int = 0, fan: FanSettings | None = None,
             progress: bool = False) -> Record:
    """Simulate a side-scan survey of ``scene`` along ``trajectory``.

    Parameters
    ----------
    scene : Scene
        Geometry and materials (world metres).
    trajectory : Trajectory
        One pose per ping.
    sonar : Sonar, optional
        Transducer, range window and medium; default :class:`Sonar` ().
    pulse : Pulse, optional
        Transmitted pulse; default 100 µs rectangular CW.
    speckle : bool
        False: the expected intensity (the paper's speckle-free "perfect sonar
        image"). True needs the full signal chain, which is not built yet.
    seed : int
        Random seed (recorded; used by speckle modes).
    fan : FanSettings, optional
        Ray density; default :class:`FanSettings` ().
    progress : bool
        Show a progress bar over pings (tqdm, on stderr).

    Returns
    -------
    Record
        ``port`` and ``starboard`` (n_pings, n_samples) linear intensity for a unit
        source (on-axis intensity 1 at 1 m), sampled at ``time_s``.

    Notes
    -----
    Implements E[I](t) = ∬ |p(t − 2R/c)|² Γ⁴ σ(θi) 10^(−2αR/10) / R⁴ dA (PHYSICS.md
    eq. 1) with one ray of solid angle dΩ standing for dA = R² dΩ / cos θi.
    """
    sonar = Sonar() if sonar is None else sonar
    pulse = Pulse.cw() if pulse is None else pulse
    fan = FanSettings() if fan is None else fan
    _check_inputs(scene, trajectory, sonar, pulse, fan)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"simulate: seed must be a non-negative integer, got {seed!r}")
    if speckle:
        raise ConfigError("simulate: speckle=True needs the coherent signal chain, which this version "
                          "does not have yet; use speckle=False")

    compiled = scene.compiled()
    caster = RayCaster(compiled)
    plan = FanPlan.build(sonar, fan)
    n_p, n_s = len(trajectory), sonar.n_samples
    raw = np.zeros((n_p, 2, n_s))
    altitude = np.full(n_p, np.nan)
    rots = trajectory.rotations()
    pos_local = trajectory.positions_m - compiled.origin_m
    two_way = absorption_np_per_m(sonar.absorption_db_per_m)

    pings = range(n_p)
    if progress:
        from tqdm.auto import tqdm
        pings = tqdm(pings, desc="pings", unit="ping")
    for i in pings:
        altitude[i] = _ping(caster, plan, sonar, rots[i], pos_local[i], two_way, raw[i])

    shaped = convolve_time(raw, pulses.intensity_kernel(pulse, sonar.sample_rate_hz))
    np.maximum(shaped, 0.0, out=shaped)  # FFT round-off only; intensities are non-negative
    return Record(port=shaped[:, PORT], starboard=shaped[:, STARBOARD],
                  time_s=np.arange(n_s) / sonar.sample_rate_hz, trajectory=trajectory,
                  sonar=sonar, pulse=pulse, altitude_m=altitude,
                  attrs={"speckle": bool(speckle), "seed": int(seed), "mode": "expected_intensity"})
