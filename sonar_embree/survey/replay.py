"""Replay a recorded side-scan line and compare (docs/guide/surveys.md, "Replay and calibrate").

:func:`replay` reads a recorded XTF file, simulates the same line over a flat seafloor, writes the result in the
file's layout and reports the difference:

- what it reads: navigation and attitude (:meth:`~sonar_embree.Trajectory.from_xtf`), altitude, frequency, range,
  samples per channel, sample format and the TVG flag (:func:`sonar_embree.io.xtf.read_sonar`);
- how it simulates: the vehicle flies at each ping's recorded altitude over the plane z = 0, with the file's
  heading, pitch and roll. The sonar is the file's frequency, range and sound speed, on a device preset's beam
  when one is named.
- how it matches the file's layout: simulated at the simulator's own rate for the pulse (four samples per CW
  pulse length, :meth:`~sonar_embree.Sonar.for_pulse`) or the file's if that is higher, then decimated by the
  maximum to the file's samples per channel, as devices do and as the project's own device records are made. The
  file's TVG is applied when its flag is set: the GainCode's k (30 if none) and the InitialGainCode.

Levels are compared in dB of what is stored: 10·log10 of float samples (intensities) and 20·log10 of integer
codes (amplitudes). The measures (:func:`measures`), per file, are:

- the median level against slant range and against grazing angle (flat floor: sin θg = altitude/R);
- the noise floor in the water column;
- per range band, the scintillation index and a histogram of the level about its median;
- the correlation of the intensity at one and two samples along range, and one ping along track.

With ``fit``, :func:`fit` chooses the sediment class and the gain offset that bring the simulated measures closest
to the recorded ones, so a user calibrates the simulator to their own sonar:

- the offset is the median level difference over the floor;
- the class is the one whose level-against-grazing curve, after that offset, has the smallest RMS difference.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import logging
import math
import os

import numpy as np

from ..config import Material, Pulse, Sonar
from ..display import plotting
from ..environment import Environment
from ..errors import ConfigError
from ..instrument.beam import beamwidth_deg, membrane_size_for_beamwidth, sinc as beam_sinc
from ..instrument.devices import Device, device_toml
from ..io.owner import OutputFolder
from ..io.xtf import NAV_UNITS_LATLON, decimate, read_navigation, read_sonar, write_like
from ..laws import sediments
from ..laws.clutter import Clutter
from ..laws.texture import KTexture
from ..scene import Scene, seafloor
from ..simulate import simulate
from ..trajectory import Trajectory
from ..validation import warn_once

#: Range bands of the per-patch statistics and bins of the level curves.
N_BANDS, N_RANGE_BINS, GRAZING_BIN_DEG = 4, 32, 2.0
#: The classes a fit tries by default (APL-UW classes, docs/physics.md §10b).
FIT_CLASSES = ("apl-uw coarse sand", "apl-uw fine sand", "apl-uw coarse silt", "apl-uw clay")
#: Grazing angles the class fit compares, degrees (the near-nadir lobe and the shadows left out).
FIT_GRAZING_DEG = (4.0, 60.0)
#: The elevation pattern a fit without a device preset simulates its candidates with (tilt, degrees; membrane height
#: in wavelengths): nearly flat over the floor's angles (a quarter-wavelength membrane: its one-way pattern falls by
#: 0.9 dB from its boresight to 90° off), so that :func:`elevation_fit` can put any other in its place. Its boresight
#: is horizontal, so that its baffle shuts out the floor on the other side: tilted 45°, it heard the other side's
#: floor at the same range near nadir, which the fit's model left out (2 dB at 45° of grazing, the fit's width 5 %
#: narrow and its level 5–18 dB off towards the null; issue 52).
CALIBRATION_TILT_DEG, CALIBRATION_HEIGHT_WAVELENGTHS = 0.0, 0.25
#: The elevation patterns :func:`elevation_fit` tries: tilts (degrees) and one-way −3 dB vertical widths (degrees).
FIT_TILTS_DEG, FIT_WIDTHS_DEG = np.arange(0.0, 50.5, 0.5), np.arange(10.0, 101.0, 1.0)
#: Grazing angles the elevation fit compares, degrees.
FIT_ELEVATION_GRAZING_DEG = (4.0, 80.0)
#: The elevation fit leaves out the cells where the recorded level, less the calibration simulation's, lies more than
#: this far below its highest, dB: towards a null of the record's pattern a cell's level hangs on the null's exact
#: place and on speckle (issue 52; the beam a fit finds then replays the null's bins within 1 dB).
FIT_ELEVATION_DEPTH_DB = 15.0


def _elevation_db(depression_deg, tilt_deg, height_wavelengths, grazing_deg=None) -> np.ndarray:
    """Two-way elevation gain (dB, broadcast over the arguments) of a membrane ``height_wavelengths`` high tilted
    ``tilt_deg`` down, at depressions β below its horizontal: sinc⁴(k·ly/2·sin(β − δ)) in front of its baffle
    (cos(β − δ) > 0). With ``grazing_deg`` θ (a flat floor's), plus the floor on the other side at the same range,
    which lies 180° − 2θ + β below this side's horizontal (past nadir) and which a tilted, wide pattern hears near
    nadir through its baffle."""
    beta, tilt = np.asarray(depression_deg, dtype=np.float64), np.asarray(tilt_deg, dtype=np.float64)

    def power(b):
        off = np.radians(b - tilt)
        return beam_sinc(np.pi * np.asarray(height_wavelengths) * np.sin(off)) ** 4 * (np.cos(off) > 0.0)

    p = power(beta) if grazing_deg is None else power(beta) + power(180.0 - 2.0 * np.asarray(grazing_deg) + beta)
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(p)


#: Body-frame depression bins of the elevation fit's cells, degrees.
DEPRESSION_BIN_DEG = 1.0
#: The elevation fit uses a cell where both files hold at least this many floor samples.
MIN_CELL_SAMPLES = 16


def depression_cells(values: np.ndarray, line: Line) -> dict:
    """The floor's samples of ``values`` (pings, 2, samples) in cells of side, grazing angle (bins of
    :data:`GRAZING_BIN_DEG`) and depression below the body's horizontal (bins of :data:`DEPRESSION_BIN_DEG`). Over a
    flat floor a sample at grazing angle θ of a ping rolled φ (starboard down) left and came back at θ + φ below the
    port transducer's horizontal and θ − φ below the starboard's: the seabed's σ follows θ, the elevation pattern
    follows the depression. Roll is what tells them apart; without it the two angles are one and only the product
    σ(θ)·G(θ) is seen.

    Returns
    -------
    dict
        ``key`` (the cell's index: side, grazing bin, depression bin), ``count``, ``level_db`` (dB of the mean
        intensity of the cell's samples), ``grazing_deg`` and ``depression_deg`` (the cell's mean angles), each
        (cells,) over the cells that hold a sample.
    """
    s, r = line.settings, line.slant_range_m
    alt = np.where(s["altitude_m"] > 0.0, s["altitude_m"], np.nan)[:, None]
    lev = level_db(values, s["integer"])
    theta = np.degrees(np.arcsin(np.clip(alt / np.maximum(r[None, :], 1e-9), 0.0, 1.0)))
    roll = line.trajectory.roll_deg[:, None]
    n_g, n_d = int(round(90.0 / GRAZING_BIN_DEG)) + 1, int(round(180.0 / DEPRESSION_BIN_DEG)) + 1
    keys, lv, th, dep = [], [], [], []
    for side, sign in ((0, 1.0), (1, -1.0)):
        ok = (r[None, :] > alt * 1.02) & np.isfinite(lev[:, side])
        d = (theta + sign * roll)[ok]
        gi = np.clip((theta[ok] / GRAZING_BIN_DEG).astype(int), 0, n_g - 1)
        di = np.clip(np.floor((d + 90.0) / DEPRESSION_BIN_DEG).astype(int), 0, n_d - 1)
        keys.append((side * n_g + gi) * n_d + di)
        lv.append(10.0 ** (lev[:, side][ok] / 10.0))
        th.append(theta[ok])
        dep.append(d)
    k = np.concatenate(keys)
    used, inv = np.unique(k, return_inverse=True)
    count = np.bincount(inv).astype(float)
    mean = lambda x: np.bincount(inv, weights=np.concatenate(x)) / count  # noqa: E731
    with np.errstate(divide="ignore"):
        lvl = 10.0 * np.log10(mean(lv))
    return {"key": used, "count": count, "level_db": lvl, "grazing_deg": mean(th), "depression_deg": mean(dep)}


def elevation_fit(real: dict, sim: dict, wavelength_m: float) -> dict:
    """The tilt and vertical width whose two-way elevation pattern, put in place of the calibration beam's
    (:data:`CALIBRATION_TILT_DEG`), brings the simulated levels closest to the recorded ones, cell by cell of
    :func:`depression_cells` (``real`` and ``sim``: theirs).

    In a cell the two files differ by the two patterns' ratio at the cell's depression β and by the seabeds' σ at
    its grazing angle θ: level = level_cal + G(β; δ, ly) − G_cal(β) (+ σ_record(θ) − σ_candidate(θ)),
    G = 40·log10|sinc|. Every candidate of :data:`FIT_TILTS_DEG` × :data:`FIT_WIDTHS_DEG` is scored by the RMS of the
    recorded minus the candidate's levels after their mean difference (the gain), weighted by the cells' samples,
    over the cells within :data:`FIT_ELEVATION_GRAZING_DEG` that hold :data:`MIN_CELL_SAMPLES` in both files and lie
    within :data:`FIT_ELEVATION_DEPTH_DB` of the record's highest (the same cells for every candidate). A record
    whose roll varies leaves a wrong candidate seabed a residual the pattern cannot take up (σ follows θ, the pattern
    β), so the class chosen by this error is the record's.

    Returns
    -------
    dict
        ``tilt_deg``, ``vertical_beamwidth_deg`` (one-way −3 dB), ``height_m`` (the membrane's), ``error_db`` and
        ``gain_offset_db``.
    """
    _, ir, isim = np.intersect1d(real["key"], sim["key"], return_indices=True)
    n = np.minimum(real["count"][ir], sim["count"][isim])
    beta = real["depression_deg"][ir]
    g = real["grazing_deg"][ir]
    d = real["level_db"][ir] - sim["level_db"][isim] + _elevation_db(beta, CALIBRATION_TILT_DEG,
                                                                      CALIBRATION_HEIGHT_WAVELENGTHS, g)
    ok = (n >= MIN_CELL_SAMPLES) & (g >= FIT_ELEVATION_GRAZING_DEG[0]) & (g <= FIT_ELEVATION_GRAZING_DEG[1])
    ok &= np.isfinite(d)
    ok[ok] = d[ok] >= d[ok].max() - FIT_ELEVATION_DEPTH_DB if ok.any() else ok[ok]
    if ok.sum() < 4:
        raise ConfigError("replay: fewer than four grazing-angle cells hold both files' floor; no beam to fit")
    w = n[ok] / n[ok].sum()
    heights = np.array([membrane_size_for_beamwidth(math.radians(x), 1.0) for x in FIT_WIDTHS_DEG])
    model = _elevation_db(beta[ok][None, None, :], FIT_TILTS_DEG[:, None, None], heights[None, :, None],
                          g[ok][None, None, :])
    resid = d[ok][None, None, :] - model
    resid = np.where(np.isfinite(resid), resid, 1e3)                  # a null where the record has floor: no fit
    offset = np.sum(w * resid, axis=2)
    err = np.sqrt(np.sum(w * (resid - offset[..., None]) ** 2, axis=2))
    i, j = np.unravel_index(int(np.argmin(err)), err.shape)
    return {"tilt_deg": float(FIT_TILTS_DEG[i]), "vertical_beamwidth_deg": float(FIT_WIDTHS_DEG[j]),
            "height_m": float(heights[j] * wavelength_m), "error_db": float(err[i, j]),
            "gain_offset_db": float(offset[i, j])}


#: Two classes whose noise-free levels over a record's cells, each with its own best elevation pattern and gain,
#: differ by less than this RMS (dB) look alike (:func:`look_alikes`): a flat floor without a calibrated gain cannot
#: tell them apart, and their gains differ by their strengths' mean difference (APL-UW coarse sand, coarse silt and
#: clay at 400 kHz: their σ(θ) differ by a constant within 0.5 dB RMS from 5° to 60°, and a free pattern takes up
#: the rest).
LOOK_ALIKE_DB = 0.3


def _strength_db(law, grazing_deg: np.ndarray, frequency_hz: float) -> np.ndarray:
    """Monostatic backscatter strength 10·log10 σ of ``law`` (a sediment name or law) at ``grazing_deg``, dB."""
    law = (sediments.preset(law) if isinstance(law, str) else law).at_frequency(frequency_hz)
    c = np.sin(np.radians(grazing_deg))
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(law.sigma(c, c))


def look_alikes(cells: dict, chosen: str, beam: dict, classes, frequency_hz: float, wavelength_m: float) -> dict:
    """The classes of ``classes`` the record's ``cells`` (:func:`depression_cells`) cannot tell from ``chosen`` with
    the fitted ``beam`` (:func:`elevation_fit`'s): each class's noise-free levels (its σ at each cell's grazing angle,
    the calibration pattern at its depression) fitted by :func:`elevation_fit` to the chosen class's noise-free
    levels (its σ, the fitted pattern) come within :data:`LOOK_ALIKE_DB`. ``{class: gain offset that class would
    take, dB, relative to the chosen one's}``, the chosen class left out."""
    g, beta = cells["grazing_deg"], cells["depression_deg"]
    height = beam["height_m"] / wavelength_m
    want = dict(cells, level_db=_strength_db(chosen, g, frequency_hz) + _elevation_db(beta, beam["tilt_deg"], height,
                                                                                      g))
    out = {}
    for name in classes:
        if name == chosen:
            continue
        got = dict(cells, level_db=_strength_db(name, g, frequency_hz)
                   + _elevation_db(beta, CALIBRATION_TILT_DEG, CALIBRATION_HEIGHT_WAVELENGTHS, g))
        fit = elevation_fit(want, got, wavelength_m)
        if fit["error_db"] < LOOK_ALIKE_DB:
            out[name] = fit["gain_offset_db"]
    return out


#: A fit of a longer line simulates only :data:`FIT_RUNS` runs of :data:`FIT_RUN_PINGS` consecutive pings, centred at
#: evenly spaced quantiles of the line's altitudes (its geometries, not its length, decide the fit); the replay
#: that follows simulates every ping once.
FIT_RUNS, FIT_RUN_PINGS = 6, 32
#: The correlation length (m) of the K-distributed texture a --fit-texture replay puts on its floor: long against the
#: resolution cell, so that its bands' scintillation index is (1 + SI₀)(1 + 1/ν) − 1 (:func:`texture_fit`); the record
#: does not say its texture's own length.
TEXTURE_CORRELATION_M = 2.0
#: The CW pulse lengths ``--fit-pulse`` tries, s (a replay without a device otherwise takes 100 µs).
FIT_PULSES_S = (20e-6, 50e-6, 100e-6, 200e-6, 400e-6)
#: A fitted pulse at either end of :data:`FIT_PULSES_S` that misses the record's correlation by this much or more is
#: said in one line (the record lies outside what the candidates give: speckle-free, or smoothed along range).
PULSE_EDGE_ERROR = 0.05
#: Pulses whose correlation errors lie within this of the best one's are alike (:func:`pulse_fit`): shorter than the
#: file's sample spacing, a stored sample (the largest of its run) correlates with the next as little for 20 µs as
#: for 50 µs (a 600 kHz record of 1024 samples over 30 m, 39 µs apart: 0.0012 and 0.0014 off).
PULSE_TIE = 0.005


def fit_pings(line: Line, runs: int = FIT_RUNS, run_pings: int = FIT_RUN_PINGS) -> np.ndarray:
    """(n,) increasing indices of the pings a fit simulates: every ping of a line of up to ``runs·run_pings`` pings,
    else ``runs`` runs of ``run_pings`` consecutive pings centred at the pings whose altitudes are the line's
    evenly spaced altitude quantiles (lowest and highest included)."""
    n = line.settings["data"].shape[0]
    if n <= runs * run_pings:
        return np.arange(n)
    alt = line.settings["altitude_m"]
    order = np.argsort(alt, kind="stable")
    centres = order[np.round(np.linspace(0, n - 1, runs)).astype(int)]
    starts = np.clip(centres - run_pings // 2, 0, n - run_pings)
    return np.unique((starts[:, None] + np.arange(run_pings)[None, :]).ravel())


@dataclasses.dataclass(frozen=True)
class Line:
    """A recorded line: its :func:`~sonar_embree.io.xtf.read_sonar` settings and data, and its trajectory over the
    plane z = 0 (positions at each ping's altitude)."""

    settings: dict
    trajectory: Trajectory

    @classmethod
    def read(cls, path, scene: Scene | None = None) -> "Line":
        """The line of ``path``; over a flat floor at its altitudes, or, with a ``scene``, where its navigation puts
        it (z = −SensorDepth, x and y in the scene's CRS)."""
        s = read_sonar(path)
        keep = usable_pings(path, s["altitude_m"], need_altitude=scene is None)
        bad = int(np.sum(~np.isfinite(s["data"][keep])))
        if bad:
            warn_once(f"replay: {os.fspath(path)}: {bad} samples are NaN or infinite; the measures leave them out")
        s = {**s, "data": s["data"][keep], "altitude_m": s["altitude_m"][keep], "kept": keep}
        if scene is not None:
            return cls(s, Trajectory.from_xtf(path, crs=scene.crs, keep=keep))
        nav = Trajectory.from_xtf(path, keep=keep)
        pos = nav.positions_m.copy()
        pos[:, 2] = s["altitude_m"]
        return cls(s, dataclasses.replace(nav, positions_m=pos))

    def subset(self, pings: np.ndarray) -> "Line":
        """The line's pings ``pings`` ((n,) increasing indices of its kept pings) alone, as a line."""
        t, s = self.trajectory, self.settings
        fix = None if t.fix_times_s is None else t.fix_times_s[pings]
        traj = Trajectory(t.positions_m[pings], t.heading_deg[pings], t.pitch_deg[pings], t.roll_deg[pings],
                          t.times_s[pings], None if t.velocity_m_s is None else t.velocity_m_s[pings], t.crs,
                          t.start_time, None if t.ship_positions_m is None else t.ship_positions_m[pings], fix)
        return Line({**s, "data": s["data"][pings], "altitude_m": s["altitude_m"][pings]}, traj)

    def full(self, values: np.ndarray) -> np.ndarray:
        """(file pings, 2, samples): ``values`` of the kept pings in their places, zeros for the pings taken out."""
        keep = self.settings["kept"]
        out = np.zeros((keep.size,) + values.shape[1:], dtype=values.dtype)
        out[keep] = values
        return out

    @property
    def slant_range_m(self) -> np.ndarray:
        """(samples,) slant range of each stored sample, m."""
        s = self.settings
        return 0.5 * s["sound_speed_m_s"] * np.arange(s["samples_per_channel"]) / s["sample_rate_hz"]


def usable_pings(path, altitude_m: np.ndarray, need_altitude: bool = True) -> np.ndarray:
    """(pings,) bool: the pings of the XTF file ``path`` with a navigation fix (not latitude/longitude 0, 0, finite)
    and, if ``need_altitude``, an altitude (SensorPrimaryAltitude > 0). Real files have pings without them (the first
    before the GPS fix): they are taken out with a one-line warning saying how many; fewer than two left is refused."""
    nav = read_navigation(path)
    fix = np.isfinite(nav["x"]) & np.isfinite(nav["y"])
    if nav["nav_units"] == NAV_UNITS_LATLON:
        fix &= ~((nav["x"] == 0.0) & (nav["y"] == 0.0))
    alt = (np.isfinite(altitude_m) & (altitude_m > 0.0)) if need_altitude else np.ones(fix.size, bool)
    keep = fix & alt
    n, what = keep.size, "a navigation fix" + (" and an altitude (SensorPrimaryAltitude > 0)" if need_altitude else "")
    if keep.sum() < 2:
        raise ConfigError(f"{os.fspath(path)}: {int(keep.sum())} of {n} pings have {what}; a replay needs two at "
                          "least (no altitude: give a --dem or --scene)")
    if not keep.all():
        warn_once(f"replay: {os.fspath(path)}: took out {n - int(keep.sum())} of {n} pings without {what} "
                  f"({int(np.sum(~fix))} without a fix, {int(np.sum(~alt))} without an altitude); they are written "
                  "as zeros")
    return keep


def simulate_line(line: Line, law, *, device: str | None = None, pulse: Pulse | None = None, seed: int = 0,
                  gain_db: float = 0.0, clutter=None, scene: Scene | None = None,
                  elevation: tuple | None = None, texture: KTexture | None = None) -> np.ndarray:
    """The line simulated over a flat floor of ``law`` (a sediment name or law) with ``clutter`` and ``texture`` (a
    :class:`~sonar_embree.laws.texture.KTexture`, or none), or over ``scene`` as it is, in the file's layout:
    (pings, 2, samples) values as the file stores them (intensity, or amplitude for integer formats), ``gain_db``
    added. Without a ``device``, ``elevation`` = (tilt, degrees; membrane height, m) sets the beam's elevation
    pattern (default the :class:`~sonar_embree.Sonar`'s)."""
    s, traj = line.settings, line.trajectory
    pulse = pulse or (Pulse.preset(device) if device else Pulse.cw(duration_s=100e-6))
    rate = max(s["sample_rate_hz"], Sonar(frequency_hz=s["frequency_hz"]).for_pulse(pulse).sample_rate_hz)
    kw = dict(max_range_m=s["slant_range_m"], sample_rate_hz=rate)
    if elevation is not None and not device:
        kw.update(tilt_deg=float(elevation[0]), height_m=float(elevation[1]))
    water = Environment(sound_speed_m_s=s["sound_speed_m_s"])   # the file's sound speed
    sonar = (Sonar.preset(device, frequency_hz=s["frequency_hz"], sound_speed_m_s=water.sound_speed_m_s, **kw)
             if device else Sonar(frequency_hz=s["frequency_hz"], **kw))
    if scene is None:
        law = sediments.preset(law) if isinstance(law, str) else law
        xy = traj.positions_m[:, :2]
        size = np.ptp(xy, axis=0) + 2.2 * s["slant_range_m"]
        floor = seafloor.flat(tuple(size), center_m=tuple(xy.mean(axis=0)))
        scene = Scene().add(floor, material=Material(scattering=law, clutter=clutter, texture=texture),
                            label="seafloor")
    rec = simulate(scene, traj, sonar, pulse, speckle=True, seed=seed, start_time=traj.start_time or "2000-01-01",
                   environment=water)
    n = s["samples_per_channel"]
    data = np.stack([decimate(rec.data[:, ch, :], n, "max")[:, :n] for ch in (0, 1)], axis=1)
    if s["tvg"]:
        k = s["gain_code"] if s["gain_code"] in (20, 30, 40) else 30
        r = np.maximum(0.5 * water.sound_speed_m_s * np.arange(data.shape[2]) / s["sample_rate_hz"], 1.0)
        data = data * 10.0 ** ((s["initial_gain_db"] + k * np.log10(r) + 2 * rec.acquisition.alpha_db_per_m * r)
                               / 10.0)
    data = np.sqrt(data) if s["integer"] else data
    return data * 10.0 ** (gain_db / (20.0 if s["integer"] else 10.0))


def level_db(values: np.ndarray, integer: bool) -> np.ndarray:
    """dB of stored values: 20·log10 of codes, 10·log10 of intensities; −inf for zeros."""
    with np.errstate(divide="ignore"):
        return (20.0 if integer else 10.0) * np.log10(np.maximum(values, 0.0))


def _bins(x: np.ndarray, edges: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Median of the finite ``values`` in each bin of ``x`` (NaN where none)."""
    k = np.where(np.isfinite(values), np.digitize(x, edges) - 1, -1)
    return np.array([np.median(values[k == i]) if np.any(k == i) else np.nan for i in range(edges.size - 1)])


def _correlation(i: np.ndarray, axis: int, lag: int) -> float:
    """Correlation coefficient of intensities ``lag`` apart along ``axis`` (each range column standardised)."""
    z = (i - i.mean(axis=0)) / np.maximum(i.std(axis=0), 1e-300)
    a, b = (z[:-lag], z[lag:]) if axis == 0 else (z[:, :-lag], z[:, lag:])
    return float(np.mean(a * b))


def measures(values: np.ndarray, line: Line) -> dict:
    """The comparison measures of one file's values (pings, 2, samples) on ``line``'s geometry (module docstring)."""
    s, r = line.settings, line.slant_range_m
    alt = np.where(s["altitude_m"] > 0.0, s["altitude_m"], np.nan)[:, None]   # the file's, as recorded
    lev = level_db(values, s["integer"])
    inten = values ** 2 if s["integer"] else values
    floor = (r[None, :] > alt * 1.02) & np.isfinite(lev[:, 0]) & np.isfinite(lev[:, 1])
    water = r[None, :] < 0.9 * alt
    grazing = np.degrees(np.arcsin(np.clip(alt / np.maximum(r[None, :], 1e-9), 0.0, 1.0)))
    both = np.concatenate([lev[:, 0][floor], lev[:, 1][floor]])
    rr = np.broadcast_to(r, floor.shape)[floor]
    gg = grazing[floor]
    r_edges = np.linspace(0.0, s["slant_range_m"], N_RANGE_BINS + 1)
    g_edges = np.arange(0.0, 90.0 + GRAZING_BIN_DEG, GRAZING_BIN_DEG)
    out = {"range_m": (0.5 * (r_edges[1:] + r_edges[:-1])).tolist(),
           "level_vs_range_db": _bins(np.concatenate([rr, rr]), r_edges, both).tolist(),
           "grazing_deg": (0.5 * (g_edges[1:] + g_edges[:-1])).tolist(),
           "level_vs_grazing_db": _bins(np.concatenate([gg, gg]), g_edges, both).tolist(),
           "noise_floor_db": _finite_median(lev[np.broadcast_to(water[:, None, :], lev.shape)])}
    out.update(_patches(inten, lev, r, alt, s["slant_range_m"]))
    return out


def _finite_median(values: np.ndarray):
    """The median of the finite values (None: none), so that NaN samples never make a level NaN."""
    v = values[np.isfinite(values)]
    return float(np.median(v)) if v.size else None


def _patches(inten, lev, r, alt, r_max) -> dict:
    """Per range band of the floor: scintillation index (of the intensity, each range column divided by its mean
    over pings and sides), the share of deep fades (below :data:`DEEP_FADE` of that mean) and the skewness of
    10·log10 of it (Rayleigh speckle: 1 − e^(−0.1) = 9.5 % and −1.14), level histogram about the median,
    correlations."""
    lo = float(np.nanmax(alt)) * 1.05
    edges = np.linspace(lo, r_max, N_BANDS + 1)
    hist_edges = np.arange(-20.0, 16.0, 1.0)
    si, hists, c1, c2, ca, fades, skews = [], [], [], [], [], [], []
    for a, b in zip(edges[:-1], edges[1:]):
        cols = (r >= a) & (r < b)
        i = np.concatenate([inten[:, 0][:, cols], inten[:, 1][:, cols]], axis=0)
        d = np.concatenate([lev[:, 0][:, cols], lev[:, 1][:, cols]], axis=0)
        good = np.isfinite(d)
        norm = i / np.maximum(i.mean(axis=0), 1e-300)                   # each range column about its mean
        si.append(float(norm.var()) if i.size else None)
        fades.append(float(np.mean(norm < DEEP_FADE)) if i.size else None)
        skews.append(_skew_db(norm))
        hists.append(np.histogram(d[good] - np.median(d[good]), hist_edges)[0].tolist() if good.any() else [])
        c1.append(_correlation(i, 1, 1) if i.shape[1] > 2 else None)
        c2.append(_correlation(i, 1, 2) if i.shape[1] > 3 else None)
        ca.append(_correlation(inten[:, 1][:, cols], 0, 1) if inten.shape[0] > 2 and cols.any() else None)
    return {"band_edges_m": edges.tolist(), "scintillation_index": si, "histogram_edges_db": hist_edges.tolist(),
            "histograms": hists, "correlation_range_lag1": c1, "correlation_range_lag2": c2,
            "correlation_along_lag1": ca, "deep_fade_share": fades, "skew_db": skews}


#: A deep fade: an intensity below this share of its range column's mean (the texture statistics of issue 52).
DEEP_FADE = 0.1


def _skew_db(norm: np.ndarray):
    """The skewness of 10·log10 of the positive normalised intensities (None: fewer than 3)."""
    x = 10.0 * np.log10(norm[norm > 0])
    if x.size < 3 or not np.std(x) > 0:
        return None
    return float(np.mean((x - x.mean()) ** 3) / np.std(x) ** 3)


def gain_offset_db(real: dict, sim: dict) -> float:
    """The median level difference real − simulated over the range bins both fill, dB."""
    d = np.array(real["level_vs_range_db"], float) - np.array(sim["level_vs_range_db"], float)
    d = d[np.isfinite(d)]
    if d.size == 0:
        raise ConfigError("replay: the recorded and simulated lines share no range with floor echoes")
    return float(np.median(d))


def shape_error_db(real: dict, sim: dict, offset_db: float) -> float:
    """RMS of real − (simulated + offset) against grazing angle within :data:`FIT_GRAZING_DEG`, dB."""
    g = np.array(real["grazing_deg"])
    d = np.array(real["level_vs_grazing_db"], float) - np.array(sim["level_vs_grazing_db"], float) - offset_db
    keep = np.isfinite(d) & (g >= FIT_GRAZING_DEG[0]) & (g <= FIT_GRAZING_DEG[1])
    return float(np.sqrt(np.mean(d[keep] ** 2))) if keep.any() else math.inf


def scintillation_error_db(real: dict, sim: dict) -> float:
    """RMS over the range bands of 10·log10 of the recorded over the simulated scintillation index, dB."""
    a, b = _bands(real["scintillation_index"]), _bands(sim["scintillation_index"])
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 10.0 * np.log10(a / b)
    d = d[np.isfinite(d)]
    return float(np.sqrt(np.mean(d ** 2))) if d.size else math.inf


def texture_fit(real: dict, sim: dict) -> float:
    """The K-distribution shape ν that brings the simulated bands' scintillation index to the recorded one: a texture
    G ~ Gamma(ν, mean 1) on the simulated intensity I₀ (independent, correlated over many resolution cells) makes
    SI = (1 + SI₀)·(1 + 1/ν) − 1 (E[G²] = 1 + 1/ν), so per band 1/ν = (1 + SI_recorded)/(1 + SI_simulated) − 1; the
    median over the bands (Jakeman and Pusey 1976; Abraham and Lyons 2002, cited in
    :mod:`sonar_embree.laws.texture`). inf: the record is no heavier-tailed than the simulation (no texture)."""
    a, b = _bands(real["scintillation_index"]), _bands(sim["scintillation_index"])
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = (1.0 + a) / (1.0 + b) - 1.0
    inv = inv[np.isfinite(inv)]
    if inv.size == 0 or np.median(inv) <= 0.0:
        return math.inf
    return float(1.0 / np.median(inv))


def _bands(values) -> np.ndarray:
    """A measure's per-band values as floats, NaN for a band without one (None in the report)."""
    return np.array([np.nan if x is None else x for x in values], float)


def _band_mean(values) -> float:
    """The mean of a measure's bands that hold a value (NaN: none)."""
    v = _bands(values)
    return float(np.nanmean(v)) if np.isfinite(v).any() else math.nan


def pulse_fit(line: Line, real: dict, law, *, clutter=None, elevation=None, seed: int = 0,
              progress: bool = False) -> dict:
    """The CW pulse length of :data:`FIT_PULSES_S` whose simulation over ``law`` brings the correlation of neighbouring
    samples along range (the bands' mean, :func:`measures`) closest to the record's: the longer the pulse, the more
    samples share each scatterer and the more that correlation grows. ``{"pulse_s": s, "correlation_errors": {"… µs":
    |simulated − recorded|}}``; ``progress``: a bar over the lengths."""
    want = _band_mean(real["correlation_range_lag1"])
    errors = {}
    bar = candidates_bar(progress, len(FIT_PULSES_S))
    for d in FIT_PULSES_S:
        sim = measures(simulate_line(line, law, pulse=Pulse.cw(duration_s=d), clutter=clutter, elevation=elevation,
                                     seed=seed), line)
        errors[d] = abs(_band_mean(sim["correlation_range_lag1"]) - want)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    best = _likeliest_pulse(errors, 1.0 / line.settings["sample_rate_hz"])
    if best in (FIT_PULSES_S[0], FIT_PULSES_S[-1]) and not errors[best] < PULSE_EDGE_ERROR:
        warn_once(f"replay --fit-pulse: the record's correlation along range ({want:.2f}) lies beyond what "
                  f"{FIT_PULSES_S[0] * 1e6:g}–{FIT_PULSES_S[-1] * 1e6:g} µs pulses give (closest: "
                  f"{best * 1e6:g} µs, {errors[best]:.2f} off); is the record speckle-free, or filtered along range?")
    return {"pulse_s": best, "correlation_errors": {f"{d * 1e6:g} us": e for d, e in errors.items()}}


def _likeliest_pulse(errors: dict, spacing_s: float) -> float:
    """The pulse of ``errors`` ({length, s: correlation error}) with the smallest error; among those within
    :data:`PULSE_TIE` of it (alike at this file's sample ``spacing_s``), the one nearest the spacing (a device stores
    about one sample per resolution cell: finer samples would repeat, coarser lose resolution), said in one line with
    what it means for the gain (the seabed's echo energy grows with the pulse length)."""
    finite = {d: e for d, e in errors.items() if math.isfinite(e)}
    if not finite:
        return min(errors)
    low = min(finite.values())
    alike = sorted(d for d, e in finite.items() if e - low < PULSE_TIE)
    best = min(alike, key=lambda d: (abs(math.log(d / spacing_s)), d))
    if len(alike) > 1:
        warn_once(f"replay --fit-pulse: {', '.join(f'{d * 1e6:g}' for d in alike)} µs pulses correlate alike along "
                  f"range at this file's sample spacing ({spacing_s * 1e6:.3g} µs); the fit takes {best * 1e6:g} µs "
                  f"(nearest the spacing), and the gain follows the pulse's energy (up to "
                  f"{10 * math.log10(alike[-1] / alike[0]):.1f} dB between them)")
    return best


def fit(line: Line, real: dict, classes=FIT_CLASSES, densities=(None,), progress: bool = False,
        fit_beam: bool = False, fit_texture: bool = False, **kw) -> dict:
    """The class of ``classes``, the clutter density of ``densities`` (per m², None: no clutter; the clutter's
    strength law :class:`~sonar_embree.laws.clutter.Clutter`'s defaults) and the gain offset (dB) that bring the
    simulation closest to ``real`` (:func:`measures` of the recorded values). The error of a candidate is the RMS
    level difference against grazing angle after its offset (:func:`shape_error_db`), plus, when densities are
    fitted, the RMS ratio of the bands' scintillation indices in dB (:func:`scintillation_error_db`).

    Returns
    -------
    dict
        ``sediment``, ``clutter_density_per_m2``, ``gain_offset_db`` and ``errors_db`` {"class" or
        "class @ density": error, dB}; with ``fit_beam`` also ``elevation`` (:func:`elevation_fit`'s tilt, width and
        membrane height) and ``look_alike`` ({class: its gain offset less the chosen one's, dB}); with
        ``fit_texture`` also ``texture_shape`` (ν, :func:`texture_fit` against the chosen candidate on the fitted
        beam; inf: none). ``progress``: a bar over the candidates.

    ``fit_beam`` (no device preset): each candidate is simulated with the calibration beam and the record's elevation
    pattern is fitted as well, cell by cell of grazing angle and depression (:func:`elevation_fit`); the class is
    the one whose fit leaves the smallest error. The record's roll is what tells σ(θ) from the pattern; classes whose
    σ(θ) differ by a near constant remain alike (the gain takes it up): ``look_alike`` lists them with the gain each
    would take (:func:`look_alikes`), and the fit says so in one line.
    """
    errors, offsets, beams, sims = {}, {}, {}, {}
    s = line.settings
    wavelength = s["sound_speed_m_s"] / s["frequency_hz"]
    cal = _calibration_beam(line) if fit_beam else None
    real_cells = depression_cells(s["data"], line) if fit_beam else None
    bar = candidates_bar(progress, len(classes) * len(densities))
    for name in classes:
        for n in densities:
            clutter = None if n is None else Clutter(float(n))
            key = (name, n)
            values = simulate_line(line, name, clutter=clutter, elevation=cal, **kw)
            sim = sims[key] = measures(values, line)
            if cal is None:                                       # a device's beam: only the gain and the class
                offsets[key] = gain_offset_db(real, sim)
                errors[key] = shape_error_db(real, sim, offsets[key])
            else:                                                 # no device: the record's elevation pattern too
                beams[key] = elevation_fit(real_cells, depression_cells(values, line), wavelength)
                offsets[key], errors[key] = beams[key]["gain_offset_db"], beams[key]["error_db"]
            errors[key] += scintillation_error_db(real, sim) if len(densities) > 1 else 0.0
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    best = min(errors, key=errors.get)
    label = lambda k: k[0] if len(densities) == 1 else f"{k[0]} @ {k[1]}"  # noqa: E731
    out = {"sediment": best[0], "clutter_density_per_m2": best[1], "gain_offset_db": offsets[best],
           "errors_db": {label(k): v for k, v in errors.items()}}
    if best in beams:
        out["elevation"] = {k: beams[best][k] for k in ("tilt_deg", "vertical_beamwidth_deg", "height_m")}
        out["look_alike"] = _said_look_alikes(real_cells, best[0], out["elevation"], classes, s["frequency_hz"],
                                              wavelength)
    if fit_texture:                          # against the chosen candidate, on the fitted beam when there is one
        el = out.get("elevation")
        sim = sims[best] if el is None else measures(simulate_line(
            line, best[0], clutter=None if best[1] is None else Clutter(float(best[1])),
            elevation=(el["tilt_deg"], el["height_m"]), **kw), line)
        out["texture_shape"] = texture_fit(real, sim)
    return out


def _said_look_alikes(cells, chosen, beam, classes, frequency_hz, wavelength_m) -> dict:
    """:func:`look_alikes`, said in one line when there are any: the chosen class is then one of a group the record
    cannot tell apart, and its gain is that class's."""
    alike = look_alikes(cells, chosen, beam, classes, frequency_hz, wavelength_m)
    if alike:
        others = ", ".join(f"{k} ({v:+.1f} dB gain)" for k, v in alike.items())
        warn_once(f"replay --fit --fit-beam: over a flat floor, with the elevation pattern free, this record cannot "
                  f"tell {chosen} from {others}; give the class (--classes) or a calibrated device to choose")
    return alike


def _first_pulse(sub: Line, real: dict, law, fit_beam: bool, seed: int, progress: bool) -> dict:
    """:func:`pulse_fit` before the class and beam are known: over ``law`` (the first class), on the calibration
    beam when the beam is fitted too."""
    return pulse_fit(sub, real, law, elevation=_calibration_beam(sub) if fit_beam else None, seed=seed,
                     progress=progress)


def _calibration_beam(line: Line) -> tuple:
    """(tilt, degrees; membrane height, m) of the calibration beam at ``line``'s wavelength."""
    s = line.settings
    return CALIBRATION_TILT_DEG, CALIBRATION_HEIGHT_WAVELENGTHS * s["sound_speed_m_s"] / s["frequency_hz"]


def candidates_bar(progress: bool, n: int):
    """A tqdm bar over a fit's candidates (on stderr) when ``progress``, else None."""
    if not progress:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=n, desc="fit candidates", unit="candidate")


def _each_warning_once(fn):
    """``fn`` with each warning of the set-up checks logged once per call: a replay simulates its line once per fit
    candidate, and the line's own warnings (its navigation's gaps, say) would repeat for each."""
    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        seen = set()

        def once(record) -> bool:
            new = record.getMessage() not in seen
            seen.add(record.getMessage())
            return new

        log = logging.getLogger("sonar_embree.checks")
        log.addFilter(once)
        try:
            return fn(*args, **kwargs)
        finally:
            log.removeFilter(once)
    return wrapped


@_each_warning_once
def replay(path, out_dir, *, sediment: str = "apl-uw fine sand", fit_classes=None, gain_db: float | None = None,
           device: str | None = None, seed: int = 0, overwrite: bool = False, scene: Scene | None = None,
           fit_densities=(None,), inputs=(), progress: bool = False, fit_beam: bool = False,
           fit_texture: bool = False, fit_pulse: bool = False) -> dict:
    """Replay the XTF line ``path`` into ``out_dir``: ``replay.xtf`` (the file's layout, the simulated samples),
    ``report.json`` (both files' :func:`measures`, the sediment, the gain offset, the fit) and ``report.png``.

    Parameters
    ----------
    sediment : str
        The seafloor's sediment (a preset name of :mod:`sonar_embree.laws.sediments`, e.g. "apl-uw fine sand").
    fit_classes : sequence of str, optional
        Fit the sediment among these classes and the gain offset (:func:`fit`) on the pings of :func:`fit_pings`
        (runs across the line's altitudes); ``sediment`` is then ignored, and the chosen class replays every ping.
    fit_densities : sequence of float or None
        With ``fit_classes``: the clutter densities (per m²; None: none) the fit tries too.
    gain_db : float, optional
        The gain offset added to the simulation, dB; default: the median level difference over the whole line.
    device, seed
        A device preset for the beam and pulse; the speckle seed.
    inputs : sequence of path, optional
        Other input files (a DEM, a scene config): refused as outputs, like ``path``.
    progress : bool
        A bar over the fit's candidates (on stderr).
    fit_beam : bool
        With ``fit_classes`` and no ``device``: fit the record's elevation pattern too (tilt and vertical width,
        :func:`elevation_fit`), and replay with it.
    fit_pulse : bool
        With ``fit_classes`` and no ``device``: fit the CW pulse length from the correlation along range
        (:func:`pulse_fit`, on the fit's pings with the chosen class), and replay with it.
    fit_texture : bool
        With ``fit_classes``: fit the K-distribution shape ν of the floor's texture from the bands' scintillation
        index (:func:`texture_fit`), and replay with it (correlation length :data:`TEXTURE_CORRELATION_M`).
    scene : Scene, optional
        The seabed to replay the line over (a DEM's, a TOML's), where the file's navigation puts the sonar; its own
        materials hold (no ``sediment``, no fit). Default: a flat floor at each ping's altitude. The grazing angles
        of the report take the altitude over a level floor either way.
    """
    _check_options(fit_classes, fit_densities, gain_db, scene, fit_beam, device, fit_texture, fit_pulse)
    OutputFolder.check(out_dir, OUTPUTS, overwrite=overwrite, inputs=[path, *inputs])
    line = Line.read(path, scene)
    real = measures(line.settings["data"], line)
    _check_speckled(path, real)
    chosen = None
    if fit_classes:
        sub = line.subset(fit_pings(line))
        real_sub = measures(sub.settings["data"], sub)
        # the pulse first (the correlation along range hardly depends on the class or the beam): the level curves
        # the class and the beam are fitted on depend on it near nadir and through the device's decimation
        timing = _first_pulse(sub, real_sub, fit_classes[0], fit_beam, seed, progress) if fit_pulse else {}
        chosen = fit(sub, real_sub, fit_classes, fit_densities, device=device, seed=seed, progress=progress,
                     fit_beam=fit_beam, fit_texture=fit_texture,
                     pulse=Pulse.cw(duration_s=timing["pulse_s"]) if timing else None)
        chosen["pings_simulated"] = int(sub.settings["data"].shape[0])
        chosen.update(timing)
    name = chosen["sediment"] if chosen else (sediment if scene is None else "the scene's")
    density = chosen["clutter_density_per_m2"] if chosen else None
    beam = chosen.get("elevation") if chosen else None
    nu = chosen.get("texture_shape", math.inf) if chosen else math.inf
    pulse = Pulse.cw(duration_s=chosen["pulse_s"]) if chosen and "pulse_s" in chosen else None
    base = simulate_line(line, name, device=device, seed=seed, scene=scene, pulse=pulse,
                         clutter=None if density is None else Clutter(float(density)),
                         elevation=None if beam is None else (beam["tilt_deg"], beam["height_m"]),
                         texture=None if math.isinf(nu) else KTexture(nu, TEXTURE_CORRELATION_M, seed))
    offset = gain_db if gain_db is not None else gain_offset_db(real, measures(base, line))   # over the whole line
    values = _clip_warned(base * 10.0 ** (offset / (20.0 if line.settings["integer"] else 10.0)), line.settings)
    sim = measures(values, line)
    out = OutputFolder.claim(out_dir, OUTPUTS, overwrite=overwrite, inputs=[path, *inputs], command="replay")
    report = {"source": os.path.abspath(os.fspath(path)), "sediment": name, "clutter_density_per_m2": density,
              "gain_offset_db": offset, "texture_shape": nu,
              "fit": chosen, "shape_error_db": shape_error_db(real, sim, 0.0),
              "pings_taken_out": int(np.sum(~line.settings["kept"])),
              "settings": {k: v for k, v in line.settings.items() if k not in ("data", "altitude_m", "kept")},
              "recorded": real, "simulated": sim}
    writers = [("replay.xtf", lambda p: write_like(path, p, line.full(values))),
               ("report.json", lambda p: _write_json(report, p)),
               ("report.png", lambda p: _report_png(report, p))]           # left out without matplotlib
    if chosen and not device:                                              # the fit as a reusable device file
        text = device_toml(fitted_device(line, chosen, path, offset))
        writers.append(("device.toml", lambda p: _write_text(text, p)))
    out.write_set(writers)
    return report


def fitted_device(line: Line, chosen: dict, path, gain_offset_db: float) -> Device:
    """The :class:`~sonar_embree.instrument.devices.Device` a fit found (``replay --fit`` writes it as device.toml,
    which ``render``, ``survey`` and ``replay --device`` take): the file's carrier, range and samples; the replay's
    beam at the file's sound speed, with the fitted elevation pattern when ``--fit-beam`` ran; the fitted CW pulse
    (``--fit-pulse``, else the replay's 100 µs). A source level is not fitted (:data:`FITTED_SOURCE_LEVEL_DB`,
    assumed); the seabed's class, gain offset and texture are not the device's and go to its ``note``."""
    s = line.settings
    plain, lam = Sonar(frequency_hz=s["frequency_hz"]), s["sound_speed_m_s"] / s["frequency_hz"]
    el = chosen.get("elevation")
    width = el["vertical_beamwidth_deg"] if el else min(beamwidth_deg(plain.height_m, lam), 179.0)
    name = os.path.basename(os.fspath(path))
    nu = chosen.get("texture_shape")
    note = (f"fitted by sonar-embree replay --fit: seabed {chosen['sediment']}, gain offset {gain_offset_db:.2f} dB"
            + ("" if nu is None or math.isinf(nu) else f", K texture shape {nu:.3g}")
            + ("" if el else "; the elevation pattern is the replay's default membrane's (not fitted)"))
    return Device(name=f"fitted {name}", source=f"sonar-embree replay --fit of {name}", platform="towfish",
                  frequency_hz=float(s["frequency_hz"]), azimuth_deg=beamwidth_deg(plain.length_m, lam),
                  elevation_deg=float(width), tilt_deg=float(el["tilt_deg"] if el else plain.tilt_deg),
                  ranges_m=(float(s["slant_range_m"]),), pulse=("cw", float(chosen.get("pulse_s", 100e-6))),
                  source_level_db=FITTED_SOURCE_LEVEL_DB,
                  assumed=("source_level_db", "azimuth_deg") + (() if el else ("elevation_deg", "tilt_deg")),
                  samples_per_channel=int(s["samples_per_channel"]), note=note)


#: A record with a band whose scintillation index is below this is said to look speckle-free (Rayleigh speckle: 1; a
#: band of a few hundred samples of speckle is within 0.2 of it, an object only raises it).
SPECKLE_FREE_SI = 0.1


def _check_speckled(path, real: dict) -> None:
    """One line when the record looks speckle-free (a band's scintillation index far below Rayleigh's 1): a replay
    simulates speckle, so its texture and correlation measures cannot match such a record."""
    si = _bands(real["scintillation_index"])
    if np.isfinite(si).any() and np.nanmin(si) < SPECKLE_FREE_SI:
        warn_once(f"replay: {os.fspath(path)}: its scintillation index is {np.nanmin(si):.2g} in a range band, far "
                  "below the 1 of speckle; it looks speckle-free (a simulation without speckle?), and the replay "
                  "simulates speckle")


def _check_options(fit_classes, fit_densities, gain_db, scene, fit_beam=False, device=None,
                   fit_texture=False, fit_pulse=False) -> None:
    """The options, before any work: one line naming a value that cannot mean anything."""
    if fit_pulse and (not fit_classes or device):
        raise ConfigError("replay: --fit-pulse fits the pulse length with --fit and without --device (a device "
                          "preset brings its own pulse)")
    if fit_texture and not fit_classes:
        raise ConfigError("replay: --fit-texture fits the floor's texture with --fit (it needs the fitted class)")
    if fit_beam and (not fit_classes or device):
        raise ConfigError("replay: --fit-beam fits the elevation pattern with --fit and without --device (a device "
                          "preset brings its own beam)")
    if scene is not None and fit_classes:
        raise ConfigError("replay: --fit chooses the sediment of a flat floor; a --scene or --dem keeps its own")
    if fit_classes is not None and not [c for c in fit_classes if str(c).strip()]:
        raise ConfigError(f"replay: --fit needs at least one sediment class in --classes, got {list(fit_classes)!r}")
    if tuple(fit_densities) != (None,) and not fit_classes:
        raise ConfigError("replay: --clutter-densities are tried by the fit only; add --fit")
    if gain_db is not None and not (isinstance(gain_db, (int, float)) and abs(gain_db) <= MAX_GAIN_DB):
        raise ConfigError(f"replay: --gain-db must be a finite number of dB within ±{MAX_GAIN_DB:g}, got {gain_db!r}")


#: The largest gain offset a replay takes, dB (a file's codes span less than 100 dB; 1e308 overflows).
MAX_GAIN_DB = 200.0
#: The share of a file's integer samples that may clip at full scale before a replay warns.
CLIP_WARN_FRACTION = 0.01


def _clip_warned(values: np.ndarray, settings: dict) -> np.ndarray:
    """``values`` as the file will store them; warns when more than :data:`CLIP_WARN_FRACTION` of integer codes
    clip at full scale (the gain offset too high)."""
    if settings["integer"]:
        top = float(2 ** (8 * settings["bytes_per_sample"]) - 1)
        share = float(np.mean(values > top)) if values.size else 0.0
        if share > CLIP_WARN_FRACTION:
            warn_once(f"replay: {100 * share:.0f} % of the simulated codes clip at full scale ({top:.0f}); lower "
                      "--gain-db")
    return values


#: What a replay writes into its folder.
OUTPUTS = ("replay.xtf", "report.json", "report.png", "device.toml")
#: The source level a fitted device file states, dB re 1 µPa at 1 m (assumed: a replay fits a gain offset, not a
#: source level; the middle of the 200–230 dB of 100 kHz–1 MHz side-scans, Lurton 2010, §8.2).
FITTED_SOURCE_LEVEL_DB = 215.0


def _write_text(text: str, path) -> None:
    """``text`` into the file ``path`` (UTF-8)."""
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)


def _write_json(obj, path) -> None:
    """Strict JSON (RFC 8259): a value that is not finite is written as null."""
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(strict_json(obj), fh, indent=1, allow_nan=False)


def strict_json(obj):
    """``obj`` with every float that is not finite (NaN, ±inf) replaced by None, recursively."""
    if isinstance(obj, float) or isinstance(obj, np.floating):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return strict_json(obj.tolist())
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _report_png(report: dict, path: str) -> None:
    """Level against range and grazing angle, the scintillation index per band and a band's histogram, recorded
    beside simulated (needs matplotlib; without it the PNG is left out with a warning)."""
    rec, sim = report["recorded"], report["simulated"]
    mid = lambda e: (0.5 * (np.array(e[1:]) + np.array(e[:-1]))).tolist()      # noqa: E731
    band = N_BANDS // 2
    panels = [dict(x=rec["range_m"], lines=[("recorded", rec["level_vs_range_db"]), ("simulated",
                   sim["level_vs_range_db"], "--")], xlabel="slant range (m)", ylabel="level (dB)"),
              dict(x=rec["grazing_deg"], lines=[("recorded", rec["level_vs_grazing_db"]), ("simulated",
                   sim["level_vs_grazing_db"], "--")], xlabel="grazing angle (deg)", ylabel="level (dB)"),
              dict(x=mid(rec["band_edges_m"]), lines=[("recorded", rec["scintillation_index"], "o-"),
                   ("simulated", sim["scintillation_index"], "s--")], xlabel="band centre (m)",
                   ylabel="scintillation index"),
              dict(x=mid(rec["histogram_edges_db"]), lines=[("recorded", rec["histograms"][band]),
                   ("simulated", sim["histograms"][band], "--")], xlabel="level about the median (dB)",
                   ylabel="samples", title=f"band {band + 1} of {N_BANDS}")]
    try:
        plotting.line_panels_png(panels, path, title=f"replay: {report['sediment']}, gain offset "
                                                    f"{report['gain_offset_db']:.1f} dB")
    except ConfigError as exc:
        warn_once(f"replay: {exc}; report.png left out")


__all__ = ["FIT_CLASSES", "Line", "fit", "gain_offset_db", "measures", "replay", "scintillation_error_db",
           "shape_error_db", "simulate_line"]
