"""Is the set-up physically meaningful? Checks made before any ping is simulated.

Errors (:class:`~sonar_embree.errors.ConfigError`) where a run cannot mean anything:
the sonar under the seafloor or inside a closed object, nothing of the scene within
range of any ping. One-line warnings (logging, naming the key and the plausible
range) where a value is legal but implausible: a frequency or range off by a unit,
a tilt in radians, an altitude beyond the range window, a scene that stands on its
side (a Y-up export), an object seen only from behind its faces (inverted normals).
Each costs a few rays per ping, nothing next to the fan.
"""
from __future__ import annotations

import logging
import os

import numpy as np

from .errors import ConfigError
from .validation import _warned, warn_once  # noqa: F401 (one set of warned messages per process)

log = logging.getLogger(__name__)

#: Pings from which a run is a waterfall whose along-track gaps are worth a warning (:func:`check_ping_spacing`).
MIN_IMAGE_PINGS = 10

#: (low, high) plausible values of side-scan sonar settings, for the warnings.
PLAUSIBLE = {"frequency_hz": (20e3, 3e6), "max_range_m": (2.0, 1500.0), "tilt_deg": (2.0, 60.0)}
#: Share of the scene's area that faces up or down below which the scene looks stood on its side.
MIN_HORIZONTAL_AREA = 0.2
#: Share of an object's first hits on back faces above which it looks inverted.
MAX_BACK_FACE_SHARE = 0.5


def physical_memory_bytes() -> int | None:
    """This machine's physical memory, bytes (None where the OS does not say)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


#: Bytes a cast ray holds while its block is in flight (directions and origins, hits, echoes and their
#: weights; measured: 0.5 GB for the 1.9 M rays of a default forward-looking ping).
BYTES_PER_RAY = 250


class RaysMemoryError(ConfigError):
    """A block of rays that cannot fit in half this machine's memory (:func:`check_rays_memory`); a run casts a
    block of several pings that raises it again a ping at a time."""


def rays_memory_budget() -> int | None:
    """Rays that fit in half this machine's memory at :data:`BYTES_PER_RAY` each (None where the OS does not say)."""
    have = physical_memory_bytes()
    return None if have is None else int(0.5 * have) // BYTES_PER_RAY


def check_rays_memory(n_rays: int, n_pings: int, what: str) -> None:
    """Refuse, before they are cast, a block of rays that cannot fit in half this machine's memory
    (:class:`RaysMemoryError`)."""
    have = physical_memory_bytes()
    need = int(n_rays) * BYTES_PER_RAY
    if have is not None and need > 0.5 * have:
        raise RaysMemoryError(
            f"{what}: {n_pings} ping(s) need {n_rays} rays, about {need / 2**30:.1f} GiB in memory, more than half "
            f"this machine's {have / 2**30:.1f} GiB; lower the quality, the range or (a forward-looking sonar) "
            "n_elements")


def check_sonar(sonar) -> None:
    """Warn about legal but implausible :class:`~sonar_embree.config.Sonar` values (unit slips)."""
    f_lo, f_hi = PLAUSIBLE["frequency_hz"]
    if not f_lo <= sonar.frequency_hz <= f_hi:
        warn_once(f"Sonar.frequency_hz = {sonar.frequency_hz:g} Hz is outside the side-scan range "
                  f"{f_lo / 1e3:g} kHz – {f_hi / 1e6:g} MHz (a value in kHz?)")
    r_lo, r_hi = PLAUSIBLE["max_range_m"]
    if not r_lo <= sonar.max_range_m <= r_hi:
        warn_once(f"Sonar.max_range_m = {sonar.max_range_m:g} m is outside the plausible {r_lo:g}–{r_hi:g} m "
                  "(a range in km?)")
    if not sonar.tilted:  # a sonar type without a tilt (an echo sounder looks down)
        return
    t_lo, t_hi = PLAUSIBLE["tilt_deg"]
    if 0.0 < sonar.tilt_deg < 1.6:
        warn_once(f"Sonar.tilt_deg = {sonar.tilt_deg:g}° looks like radians ({np.degrees(sonar.tilt_deg):.1f}°); "
                  f"side-scan tilts are {t_lo:g}–{t_hi:g}°")
    elif sonar.tilt_deg > t_hi:
        warn_once(f"Sonar.tilt_deg = {sonar.tilt_deg:g}° is steeper than the plausible {t_lo:g}–{t_hi:g}°")


def check_scene(compiled) -> None:
    """Warn when the scene stands on its side (almost no area faces up or down: a Y-up export)."""
    flat = compiled.horizontal_area_share
    if flat < MIN_HORIZONTAL_AREA:
        warn_once(f"scene: only {100 * flat:.0f} % of its surface faces up or down, so it stands on its side; "
                  "a Y-up export? load it with up_axis = \"y\" (z is up here)")


def check_poses(caster, pos_local: np.ndarray) -> np.ndarray:
    """Refuse poses under the seafloor or inside a closed object; return the nadir altitude (NaN: none).

    A ray straight up from the sonar that first meets the back of a seafloor face
    means the sonar is under the seafloor; rays up and down that both first meet the
    back of one other object's faces mean the sonar is inside that closed object
    (a single sheet above the sonar, seen from below, is neither).
    """
    c = caster.compiled
    n = pos_local.shape[0]
    up = caster.cast(pos_local, np.broadcast_to([0.0, 0.0, 1.0], (n, 3)), 1e7)
    down = caster.cast(pos_local, np.broadcast_to([0.0, 0.0, -1.0], (n, 3)), 1e7)
    up_back = (up.tri >= 0) & (up.cos_inc < 0)
    obj_up = np.maximum(up.object_id, 0)
    inside = up_back & (c.is_seafloor[obj_up] | ((down.tri >= 0) & (down.cos_inc < 0)
                                                 & (down.object_id == up.object_id)))
    if inside.any():
        k = int(np.flatnonzero(inside)[0])
        obj = int(up.object_id[k])
        where = "under the seafloor" if c.is_seafloor[obj] else "inside the closed object"
        p = pos_local[k] + c.origin_m
        raise ConfigError(f"trajectory: ping {k} at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m is {where} "
                          f"{c.labels[obj]!r} (its surface is {up.range_m[k]:.2f} m above); check the "
                          "trajectory's z and the scene's up axis")
    return np.where(down.tri >= 0, down.range_m, np.nan)


def check_in_range(compiled, pos_local: np.ndarray, max_range_m: float, window_m: float | None = None) -> None:
    """Refuse a run where no ping has any of the scene's bounding box within ``max_range_m`` (the record's reach:
    the window, plus the pulse's length for a compressed pulse); the message quotes the configured ``window_m``
    (default ``max_range_m``)."""
    bounds_local, origin_m = compiled.bounds_local, compiled.origin_m
    gap = np.maximum(np.maximum(bounds_local[0] - pos_local, pos_local - bounds_local[1]), 0.0)
    dist = np.linalg.norm(gap, axis=1)
    if dist.size and dist.min() > max_range_m:  # max_range_m: the reach of the record
        k = int(np.argmin(dist))
        p = pos_local[k] + origin_m
        window = max_range_m if window_m is None else window_m
        reach = "" if abs(max_range_m - window) < 1e-9 * window else f", reach {max_range_m:.4g} m with the pulse"
        raise ConfigError(f"nothing of the scene lies within Sonar.max_range_m = {window:g} m{reach} of any ping "
                          f"(nearest: {dist[k]:.1f} m from ping {k} at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) m); "
                          "check the trajectory's coordinates and units")


def check_altitude(altitude_m: np.ndarray, max_range_m: float) -> None:
    """Warn when the floor below lies beyond most of the range window."""
    h = altitude_m[np.isfinite(altitude_m)]
    if h.size and np.median(h) > 0.8 * max_range_m:
        warn_once(f"trajectory: the sonar flies {np.median(h):.0f} m above the scene (median), beyond 80 % of "
                  f"Sonar.max_range_m = {max_range_m:g} m; side-scan sonars fly at 5–50 % of their range")


def _barycentric(n: int) -> np.ndarray:
    """(n, 3) points spread over a triangle (the R2 low-discrepancy sequence folded into it), as weights."""
    g = 1.32471795724474602596                                    # the plastic number (Roberts 2018, R2)
    uv = np.modf(0.5 + np.arange(1, n + 1)[:, None] / np.array([g, g * g]))[0]
    fold = uv.sum(axis=1) > 1.0
    uv[fold] = 1.0 - uv[fold]
    return np.column_stack([1.0 - uv.sum(axis=1), uv])


def check_back_faces(caster, pos_local: np.ndarray, max_range_m: float, samples: int = 48) -> None:
    """Warn about objects that a ray from the sonar meets mostly on the back of their faces.

    Rays from the first, middle and last ping aim at ``samples`` points of each object, spread
    over its faces (several on each face of a small mesh: a two-triangle plane gets as many
    as a large one); those whose first hit is that object count as front or back. An
    object seen mostly from behind (inverted normals) returns no echo, only a shadow.
    """
    c = caster.compiled
    if c.two_sided.all():
        return
    picks = np.unique([0, pos_local.shape[0] // 2, pos_local.shape[0] - 1])
    # objects' faces are contiguous in face_object (compiled in object order): no pass over every face
    bounds = np.searchsorted(c.face_object, np.arange(len(c.labels) + 1))
    for obj in range(len(c.labels)):
        if c.two_sided[obj]:
            continue
        faces = np.linspace(bounds[obj], bounds[obj + 1] - 1, samples).round().astype(int)   # repeats: few faces
        centres = np.einsum("nk,nkj->nj", _barycentric(samples), c.vertices[c.faces[faces]])
        org = np.repeat(pos_local[picks], faces.size, axis=0)
        d = np.tile(centres, (picks.size, 1)) - org
        dist = np.linalg.norm(d, axis=1)
        ok = (dist > 1e-6) & (dist <= max_range_m)
        if ok.sum() < 8:
            continue
        hit = caster.cast(org[ok], d[ok] / dist[ok, None], max_range_m)
        mine = (hit.object_id == obj) & (np.abs(hit.cos_inc) > 1e-3)
        back = (hit.cos_inc[mine] < 0).mean() if mine.sum() >= 8 else 0.0
        if back > MAX_BACK_FACE_SHARE:
            warn_once(f"object {c.labels[obj]!r} is seen from behind its faces ({100 * back:.0f} % of the rays "
                      "that reach it): inverted normals return no echo; fix its winding or give it "
                      "Material(two_sided=True)")


def check_setup(caster, sonar, pos_local: np.ndarray, reach_m: float | None = None) -> None:
    """Every check of this module, in order: warnings on values, then errors on the geometry.

    ``reach_m``: the farthest range whose echo can reach the record (the window plus
    a compressed pulse's lead); default ``sonar.max_range_m``.
    """
    c = caster.compiled
    check_sonar(sonar)
    check_scene(c)
    check_in_range(c, pos_local, sonar.max_range_m if reach_m is None else reach_m, sonar.max_range_m)
    check_altitude(check_poses(caster, pos_local), sonar.max_range_m)
    check_back_faces(caster, pos_local, sonar.max_range_m)


def check_ping_spacing(sonar, positions_m: np.ndarray) -> float | None:
    """Warn when a side-scan's pings are farther apart than its beam's footprint along track: the record then has
    gaps between pings (a navigation log taken row by row as pings, at 1 Hz where the device pings at 10 Hz).

    The footprint is the two-way −3 dB along-track width at the far end of the window, 2·R_max·tan(θ₃/2), θ₃ the
    full angle where sinc⁴ = ½ (:func:`sonar_embree.instrument.beam.beamwidth_deg`); the spacing is the
    median horizontal distance between consecutive pings. Runs of fewer than :data:`MIN_IMAGE_PINGS` pings (probes
    and tests, not images) are not judged. Returns the footprint (m), or None for sonars without an along-track
    membrane (MSIS, forward-looking, echo sounder) or runs not judged.
    """
    foot = sonar.along_track_footprint_m()
    if foot is None or positions_m.shape[0] < MIN_IMAGE_PINGS:
        return None
    step = float(np.median(np.hypot(*np.diff(positions_m[:, :2], axis=0).T)))
    if step > foot:
        log.warning("pings are %.3g m apart along track, wider than the beam's %.3g m footprint (two-way -3 dB) at "
                    "%.3g m range: the record has gaps; resample the navigation at the ping rate "
                    "(Trajectory.resampled)", step, foot, sonar.max_range_m)
    return foot


def check_ping_interval(sonar, times_s, n_pings: int) -> None:
    """Warn when pings come faster than the echoes of the range window return, 2·R_max/c: a real sonar's echoes
    of one ping would arrive after the next (the demo pinged every 50 ms with 53 ms of listening at 40 m). The
    interval judged is the median between consecutive pings; runs of fewer than :data:`MIN_IMAGE_PINGS` pings, and
    pings at one instant (stop and hop without times), are not."""
    if times_s is None or n_pings < MIN_IMAGE_PINGS:
        return
    listen = 2.0 * sonar.max_range_m / sonar.sound_speed_m_s
    step = float(np.median(np.diff(np.asarray(times_s, dtype=np.float64))))
    if 0.0 < step < listen * (1.0 - 1e-9):
        log.warning("pings are %.4g s apart, less than the %.4g s the echoes of %.4g m take to return (2R/c): a "
                    "sonar would hear one ping's echoes after the next; ping at most %.4g times a second or shorten "
                    "the range", step, listen, sonar.max_range_m, 1.0 / listen)


def check_side_scan_only(sonar, feature: str) -> None:
    """Refuse ``feature`` (clutter, volume reverberation) for a sonar type whose front end does not declare them
    (``models_clutter_and_volume``: the side-scan ``Sonar`` alone)."""
    if not sonar.models_clutter_and_volume:
        raise ConfigError(f"{feature} is simulated for the side-scan Sonar, not {sonar.type_name}")


def check_receiver_band(sonar, pulse) -> None:
    """Refuse a receiver band-pass narrower than the pulse's band, max(sweep, 1/τ): it would shape the echoes too,
    which the simulator does not model (it filters the noise only; docs/physics.md §14)."""
    rx = sonar.receiver
    if rx is None or rx.bandwidth_hz is None:
        return
    f_lo, f_hi = pulse.frequency_span_hz(sonar.frequency_hz)
    need = max(f_hi - f_lo, 1.0 / pulse.duration_s)
    if rx.bandwidth_hz < need:
        raise ConfigError(f"Receiver.bandwidth_hz = {rx.bandwidth_hz:g} Hz is narrower than the pulse's band "
                          f"({need:g} Hz): the echoes would be filtered too, which is not modelled; widen it")


def check_surface(compiled, sonar, pos_local: np.ndarray) -> None:
    """Refuse a sea surface the multipath model cannot honour (docs/physics.md §13).

    The sonar and every scene object must lie below the surface (the image paths assume
    nothing above it), and the sonar type must model the surface's paths (``models_surface``).
    """
    surface = sonar.environment.surface
    if surface is None:
        return
    if not sonar.models_surface:
        raise ConfigError(f"Environment.surface: the sea surface's paths are not modelled for {sonar.type_name}")
    z_s = surface.lowest_z_m - float(compiled.origin_m[2])  # a swell's troughs
    above = np.flatnonzero(pos_local[:, 2] >= z_s)
    if above.size:
        k = int(above[0])
        raise ConfigError(f"the sonar is at or above the sea surface (its lowest z = {surface.lowest_z_m:g} m) at ping "
                          f"{k}: z = {pos_local[k, 2] + compiled.origin_m[2]:g} m")
    if compiled.bounds_local[1, 2] > z_s:
        obj = compiled.face_object[np.flatnonzero(compiled.vertices[compiled.faces][:, :, 2].max(axis=1) > z_s)[0]]
        raise ConfigError(f"scene object {compiled.labels[obj]!r} reaches above the sea surface "
                          f"(its lowest z = {surface.lowest_z_m:g} m)")


def check_profile(compiled, sonar, pos_local: np.ndarray, labels: bool) -> None:
    """Refuse what the curved-ray path does not model (docs/physics.md §12): one-line errors.

    Curved rays are cast for the sonar types that model them (``models_refraction``), without labels (their
    shadows assume straight rays), from below the profile's depth 0.
    """
    env = sonar.environment
    if not env.refracts:
        return
    if not sonar.models_refraction:
        raise ConfigError(f"Environment.sound_speed: curved rays are not cast for {sonar.type_name}")
    if labels:
        raise ConfigError("ground-truth labels assume straight rays: not available with a sound-speed profile yet "
                          "(drop Environment.sound_speed or the labels)")
    z0 = env.profile_origin_z_m() - float(compiled.origin_m[2])
    above = np.flatnonzero(pos_local[:, 2] > z0)
    if above.size:
        k = int(above[0])
        raise ConfigError(f"the sonar is above the sound-speed profile's depth 0 (z = {env.profile_origin_z_m():g} m) "
                          f"at ping {k}: z = {pos_local[k, 2] + compiled.origin_m[2]:g} m")
