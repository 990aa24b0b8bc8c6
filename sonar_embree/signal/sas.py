"""Synthetic-aperture image formation: time-domain backprojection (docs/physics.md §18c).

The reference image former of a receiver array's records: every image point x collects, over every ping p and
element k, the record s_pk at the bistatic delay τ = (|x − tx_p| + |x − rx_pk|)/c, turned back by e^(j2π·f0·τ),

    image(x) = Σ_p Σ_k s_pk(τ_pk(x))·e^(j2π·f0·τ_pk(x)),

motion-compensated by construction: the positions are the navigation's. A point target's image has along-track
resolution D/2 (its first null; D the element length, M. Soumekh, *Synthetic Aperture Radar Signal Processing*,
Wiley, 1999, ch. 4; J. C. Curlander and R. N. McDonough, *Synthetic Aperture Radar*, Wiley, 1991, §1.2) and
across-track c/(2B) after pulse compression. The records must be sampled densely enough along track: pings no
farther apart than D/4 for a single element (D/2 for the array's phase centres).
"""
from __future__ import annotations

import numpy as np
from scipy.signal import resample_poly
from scipy.spatial import cKDTree

from .. import kernels
from ..errors import ConfigError
from ..raycast import RayCaster
from ..validation import check_bool, check_number


def backprojection_image(data, t0_s: float, rate_hz: float, carrier_hz: float, sound_speed_m_s: float, tx, rx,
                         x_m, y_m, z_m: float = 0.0, upsample: int = 4, forward=None,
                         max_u: float | None = None, velocity=None, taper: float = 0.0) -> np.ndarray:
    """The backprojected image of element records on the grid ``x_m`` × ``y_m`` at height ``z_m``.

    Parameters
    ----------
    data : (pings, elements, samples) complex
        Baseband records, sample n at t0 + n/fs (pulse-compressed for a chirp).
    t0_s, rate_hz, carrier_hz, sound_speed_m_s : float
        First sample's time (s), sample rate (Hz), carrier (Hz), sound speed (m/s).
    tx : (pings, 3) float
        The transmitter's position per ping, m.
    rx : (pings, elements, 3) float
        Each element's position when it receives, m.
    x_m, y_m : (nx,), (ny,) float
        The image grid's axes, m.
    z_m : float
        The grid's height, m.
    upsample : int
        The records are first interpolated to this many times their rate (a polyphase low-pass,
        ``scipy.signal.resample_poly``), so that the kernel's linear interpolation between samples does not widen
        the range response: from a baseband record at fs = 2B (2 samples per c/(2B)) it moves a point's first null
        by about 5 %, upsampled twice by 1 %, four times by under 0.2 % (docs/benchmarks.md).
    forward : (pings, 3) float, optional
        Each ping's along-track unit vector (default +x).
    max_u : float, optional
        The processed band: a ping and element count for a pixel only where the mean of their along-track
        direction cosines to it is within ``max_u`` (default: all, whatever the angle).
    velocity : (pings, 3) float, optional
        The elements' velocity during each ping, m/s (default: stop-and-hop).
    taper : float
        Along-track weighting over the processed band, 1 − taper·(1 − cos(π·u/max_u)) in [0, 0.5] (0: uniform, the
        rect spectrum's −13.3 dB side lobe; 0.46: Hamming, −43 dB; 0.5: Hann, −31.5 dB; F. J. Harris, "On the use
        of windows for harmonic analysis with the discrete Fourier transform", *Proc. IEEE* 66, 1978).

    Returns
    -------
    (ny, nx) complex128
    """
    if isinstance(upsample, bool) or not isinstance(upsample, (int, np.integer)) or not 1 <= upsample <= 64:
        raise ConfigError(f"backprojection_image: upsample must be an integer in [1, 64], got {upsample!r}")
    d = np.ascontiguousarray(data, dtype=np.complex128)
    if upsample > 1:
        d = np.ascontiguousarray(resample_poly(d, int(upsample), 1, axis=-1))
        rate_hz = rate_hz * int(upsample)
    tx, rx = np.ascontiguousarray(tx, dtype=np.float64), np.ascontiguousarray(rx, dtype=np.float64)
    if d.ndim != 3 or tx.shape != (d.shape[0], 3) or rx.shape != d.shape[:2] + (3,):
        raise ConfigError(f"backprojection_image: data (pings, elements, samples) {d.shape}, tx (pings, 3) "
                          f"{tx.shape} and rx (pings, elements, 3) {rx.shape} disagree")
    for name, v in (("rate_hz", rate_hz), ("carrier_hz", carrier_hz), ("sound_speed_m_s", sound_speed_m_s)):
        check_number("backprojection_image", name, v, positive=True)
    x_m, y_m = _checked_grid(x_m, y_m, z_m, d.shape[:2])
    xx, yy = np.meshgrid(x_m, y_m)
    pixels = np.ascontiguousarray(np.stack([xx.ravel(), yy.ravel(), np.full(xx.size, float(z_m))], axis=1))
    out = np.empty(pixels.shape[0], dtype=np.complex128)
    fwd = np.tile([1.0, 0.0, 0.0], (d.shape[0], 1)) if forward is None else np.asarray(forward, dtype=np.float64)
    if fwd.shape != (d.shape[0], 3):
        raise ConfigError(f"backprojection_image: forward must be (pings, 3) = ({d.shape[0]}, 3), got {fwd.shape}")
    band = 2.0 if max_u is None else float(max_u)
    if not band > 0:
        raise ConfigError(f"backprojection_image: max_u must be > 0, got {max_u!r}")
    vel = np.zeros_like(tx) if velocity is None else np.ascontiguousarray(velocity, dtype=np.float64)
    if vel.shape != tx.shape or not np.all(np.isfinite(vel)):
        raise ConfigError(f"backprojection_image: velocity must be finite (pings, 3) = {tx.shape} m/s, got "
                          f"{vel.shape}")
    check_number("backprojection_image", "taper", taper, lo=0.0, hi=0.5)
    kernels.backproject(d, float(t0_s), float(rate_hz), float(carrier_hz), float(sound_speed_m_s), tx, rx, vel,
                        np.ascontiguousarray(fwd), band, float(taper), pixels, out)
    return out.reshape(xx.shape)


#: The most pixels of one backprojected image (as the mosaic's cap, :data:`sonar_embree.io.geotiff.MAX_GRID_PIXELS`:
#: its complex128 output alone is 16 bytes a pixel).
MAX_IMAGE_PIXELS = 100_000_000


def _checked_grid(x_m, y_m, z_m, shape) -> tuple:
    """The grid's axes as float arrays, after one-line errors for an empty or non-finite axis or height, a grid
    beyond :data:`MAX_IMAGE_PIXELS`, and no ping or element to form it from."""
    x_m, y_m = np.atleast_1d(np.asarray(x_m, dtype=float)), np.atleast_1d(np.asarray(y_m, dtype=float))
    for name, a in (("x_m", x_m), ("y_m", y_m)):
        if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
            raise ConfigError(f"backprojection_image: {name} must be a non-empty 1-D axis of finite metres")
    check_number("backprojection_image", "z_m", z_m)
    if x_m.size * y_m.size > MAX_IMAGE_PIXELS:
        raise ConfigError(f"backprojection_image: a grid of {y_m.size} x {x_m.size} pixels is beyond the "
                          f"{MAX_IMAGE_PIXELS:.0e} an image may hold; image a smaller area or coarser pixels")
    if shape[0] == 0 or shape[1] == 0:
        raise ConfigError(f"backprojection_image: no {'ping' if shape[0] == 0 else 'element'} to form the image "
                          "from")
    return x_m, y_m


def _checked_selection(values, n: int, what: str) -> np.ndarray:
    """Indices of ``what`` (None: all ``n``; a list of indices in [0, n); a bool mask of length n), or one line."""
    if values is None:
        return np.arange(n)
    v = np.asarray(values)
    if v.dtype == bool:
        if v.shape != (n,):
            raise ConfigError(f"record_image: a {what} mask must have {n} entries, got shape {v.shape}")
        v = np.flatnonzero(v)
    elif v.size and (not np.issubdtype(v.dtype, np.integer) or v.ndim != 1):
        raise ConfigError(f"record_image: {what} must be indices (integers) or a bool mask, got {values!r}")
    v = v.astype(np.int64).ravel()
    if v.size == 0:
        raise ConfigError(f"record_image: {what} selects none of the {n}")
    if v.min() < 0 or v.max() >= n:
        raise ConfigError(f"record_image: {what} {int(v.min() if v.min() < 0 else v.max())} is out of range "
                          f"(0 … {n - 1})")
    return v


def record_image(record, x_m, y_m, z_m: float = 0.0, channel: str = "starboard", positions_m=None,
                 elements=None, pings=None, upsample: int = 4, max_u="auto", motion: bool = True,
                 taper: float = 0.0) -> np.ndarray:
    """The backprojected image of a simulated receiver-array record (``Record.element_data``) on a world grid.

    Parameters
    ----------
    record : Record
        Of a :class:`~sonar_embree.Sonar` with a ``receive_array``, kept complex (coherent speckle; an LFM pulse is
        compressed by default).
    x_m, y_m : (nx,), (ny,) float
        The image grid's world axes, m.
    z_m : float
        The grid's world height, m.
    channel : str
        The side imaged ("port" or "starboard").
    positions_m : (pings, 3) float, optional
        The navigation the image is formed with (default the record's own trajectory: motion-compensated with the
        true positions); the elements follow it at their body offsets with the record's attitudes.
    elements : sequence of int, optional
        The elements used (default all).
    pings : sequence of int or bool mask, optional
        The pings used (default all): a sub-aperture.
    upsample : int
        As for :func:`backprojection_image`.
    max_u : float, "auto" or None
        The processed band in along-track direction cosine (:func:`backprojection_image`). "auto": the band the
        record's along-track sampling holds without aliasing, λ/(4·d) with d the largest gap between the phase
        centres (tx + rx)/2 of consecutive pings and elements along track (D/2 apart for an array of elements D
        long and D apart whose pings advance N·D/2: a band of ±λ/(2D), the along-track resolution D/2); None:
        every ping and element, ambiguities included.
    motion : bool
        Undo the motion during the ping of a trajectory with a velocity: each element taken where it is when the
        echo of the pixel reaches it, v·2R/c on (the records' own convention, docs/physics.md §16). False, or a
        trajectory without a velocity: stop-and-hop, each element where it is at the ping's time.
    taper : float
        Side-lobe weighting in [0, 0.5], the cosine on a pedestal 1 − taper·(1 − cos(2π·x)) with x the place in
        the processed band from −1/2 to 1/2: along track over the band ±max_u (:func:`backprojection_image`) and,
        for an FM pulse, across its swept band in range (:func:`range_weighted`). 0 (default): uniform, side lobes
        −13.3 dB; 0.46: Hamming, −43 dB at 1.5 times the main lobe's width.

    Returns
    -------
    (ny, nx) complex128
    """
    arr = record.sonar.receive_array
    if record.element_data is None or arr is None:
        raise ConfigError("record_image: the record has no element data (simulate a Sonar with a receive_array)")
    if channel not in record.channels:
        raise ConfigError(f"record_image: no channel {channel!r} (the record has {', '.join(record.channels)})")
    ch = record.channels.index(channel)
    pos = record.trajectory.positions_m if positions_m is None else np.asarray(positions_m, dtype=float)
    if pos.shape != record.trajectory.positions_m.shape:
        raise ConfigError(f"record_image: positions_m must be (pings, 3) = {record.trajectory.positions_m.shape}, "
                          f"got {pos.shape}")
    n_el = arr.n_elements
    rx = arr.world_positions(record.trajectory.rotations(), pos)[:, ch * n_el:(ch + 1) * n_el]
    k = _checked_selection(elements, n_el, "elements")
    p = _checked_selection(pings, pos.shape[0], "pings")
    if not np.all(np.isfinite(pos[p])):
        raise ConfigError("record_image: positions_m holds values that are not finite")
    s = record.acquisition
    fwd = record.trajectory.rotations()[p][:, :, 0]
    if isinstance(max_u, str):
        if max_u != "auto":
            raise ConfigError(f"record_image: max_u must be a number, 'auto' or None, got {max_u!r}")
        max_u = unaliased_band(pos[p], rx[p][:, k], fwd, s.wavelength_m)
    check_bool("record_image", "motion", motion)
    vel = record.trajectory.velocity_m_s
    data = range_weighted(np.asarray(record.element_data[p, ch])[:, k], s.sample_rate_hz, record.pulse,
                          s.frequency_hz, taper)
    return backprojection_image(data, 0.0, s.sample_rate_hz, s.frequency_hz, s.sound_speed_m_s, pos[p],
                                rx[p][:, k], x_m, y_m, z_m, upsample, fwd, max_u,
                                None if vel is None or not motion else vel[p], taper)


def range_weighted(data, rate_hz: float, pulse, carrier_hz: float, taper: float) -> np.ndarray:
    """Compressed baseband records (…, samples) weighted across the FM pulse's swept band [f_lo, f_hi] (relative
    to the carrier) by 1 − taper·(1 − cos(2π·(f − f_c)/B)), f_c its centre and B its width; outside the band the
    edges' weight, on the records zero-padded to twice their length (no echo wraps round). A CW pulse, or taper 0,
    returns ``data`` as it is."""
    check_number("record_image", "taper", taper, lo=0.0, hi=0.5)
    if taper == 0.0 or not pulse.is_fm:
        return data
    lo, hi = pulse.frequency_span_hz(carrier_hz)
    n = data.shape[-1]
    f = np.fft.fftfreq(2 * n, 1.0 / rate_hz) + carrier_hz          # twice as long: nothing wraps round the end
    x = np.clip((f - 0.5 * (lo + hi)) / (hi - lo), -0.5, 0.5)
    weighted = np.fft.fft(data, 2 * n, axis=-1) * (1.0 - taper * (1.0 - np.cos(2.0 * np.pi * x)))
    return np.fft.ifft(weighted, axis=-1)[..., :n]


def unaliased_band(tx, rx, fwd, wavelength_m: float) -> float:
    """λ/(4·d), d the largest gap between consecutive phase centres (tx + rx)/2 along track (pings (pings, 3),
    elements (pings, elements, 3), forward unit vectors (pings, 3)): the largest |u| whose two-way phase, sampled
    at d, does not alias (4π·d·u/λ ≤ π). A single phase centre: no limit (2)."""
    centres = 0.5 * (tx[:, None, :] + rx)
    along = np.sort(np.einsum("pkj,pj->pk", centres - tx[:1, None, :], fwd).ravel())
    gaps = np.diff(along)
    return 2.0 if gaps.size == 0 or gaps.max() <= 0 else float(wavelength_m / (4.0 * gaps.max()))


def image_masks(scene, record, x_m, y_m, z_m: float = 0.0, channel: str = "starboard", spacing_m=None,
                caster=None):
    """The scene's objects (not the seafloor) where a ground-plane SAS image of ``record`` shows them.

    Every object's surface is sampled (points at most ``spacing_m`` apart, default half the grid's pixel); a point
    on the imaged side, facing and visible (an occlusion ray) from the ping that passes closest to it, is placed
    where the image puts its echo: at its along-track position and at the ground range on the plane z = ``z_m``
    with its own slant range, √(ρ² − (z_sonar − z_m)²). An object above the plane is laid over towards the track,
    as its echo is (docs/physics.md §18c).

    Parameters
    ----------
    scene : Scene
        The simulated scene.
    record : Record
        Its record (the trajectory and sonar; no element data needed).
    x_m, y_m : (nx,), (ny,) float
        The image grid's axes (pixel centres, uniformly spaced), world m.
    z_m : float
        The image plane's height, m.
    channel : str
        The side imaged.
    spacing_m : float, optional
        The surface sampling, m.
    caster : type, optional
        The ray caster (default Embree).

    Returns
    -------
    mask : (ny, nx) int32
        The object index (into ``names``) at each pixel, −1 for none.
    names : tuple of str
        The scene's object labels.
    """
    if channel not in ("port", "starboard"):
        raise ConfigError(f"image_masks: channel must be 'port' or 'starboard', got {channel!r}")
    x_m, y_m = np.asarray(x_m, dtype=float), np.asarray(y_m, dtype=float)
    dx, dy = _step(x_m, "x_m"), _step(y_m, "y_m")
    compiled = scene.compiled()
    pts, obj, normal, two_sided = _surface_points(compiled, spacing_m or 0.5 * min(abs(dx), abs(dy)))
    pos = record.trajectory.positions_m - compiled.origin_m
    rot = record.trajectory.rotations()
    p = cKDTree(pos[:, :2]).query(pts[:, :2])[1]                     # the ping passing closest (a straight track)
    d = pts - pos[p]
    rho = np.linalg.norm(d, axis=1)
    side = 1.0 if channel == "starboard" else -1.0
    fwd, out = _horizontal(rot[:, :, 0])[p], _horizontal(rot[:, :, 1])[p] * side    # per ping, then per point
    lit = (np.einsum("ij,ij->i", d, rot[:, :, 1][p]) * side > 0) & (two_sided | (np.einsum("ij,ij->i", normal, d) < 0))
    seen = np.zeros(rho.size, dtype=bool)
    u = (d[lit] / rho[lit, None]).astype(np.float32)
    seen[lit] = ~(caster or RayCaster)(compiled).occluded(np.ascontiguousarray(pos[p[lit]], dtype=np.float32),
                                                          np.ascontiguousarray(u),
                                                          (rho[lit] - 2e-3).astype(np.float32))
    height = pos[p, 2] + compiled.origin_m[2] - z_m
    with np.errstate(invalid="ignore"):
        g = np.sqrt(rho ** 2 - height ** 2)
    at = pos[p] + compiled.origin_m + np.einsum("ij,ij->i", d, fwd)[:, None] * fwd + g[:, None] * out
    col, row = np.rint((at[:, 0] - x_m[0]) / dx), np.rint((at[:, 1] - y_m[0]) / dy)
    keep = seen & np.isfinite(g) & (col >= 0) & (col < x_m.size) & (row >= 0) & (row < y_m.size)
    mask = np.full((y_m.size, x_m.size), -1, dtype=np.int32)
    mask[row[keep].astype(np.int64), col[keep].astype(np.int64)] = obj[keep]
    return mask, tuple(compiled.labels)


def _step(axis, name: str) -> float:
    """The uniform spacing of a grid axis (refused when not uniform)."""
    if axis.ndim != 1 or axis.size < 2 or not np.allclose(np.diff(axis), axis[1] - axis[0], rtol=1e-6, atol=1e-9):
        raise ConfigError(f"image_masks: {name} must be uniformly spaced pixel centres (at least 2)")
    return float(axis[1] - axis[0])


def _horizontal(v):
    """Rows of ``v`` (n, 3) with z dropped, unit length."""
    h = v * [1.0, 1.0, 0.0]
    return h / np.linalg.norm(h, axis=1, keepdims=True)


def _surface_points(compiled, spacing: float):
    """Points at most ``spacing`` apart on every object face (a barycentric grid per triangle, local frame): (points
    (n, 3), their object (n,), their face's unit normal (n, 3), whether it is two-sided (n,))."""
    faces = np.flatnonzero(~compiled.is_seafloor[compiled.face_object])
    tri = compiled.vertices[compiled.faces[faces]]
    edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    steps = np.maximum(np.ceil(edge / spacing), 1).astype(np.int64)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    parts = []
    for n in np.unique(steps):
        a, b = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = a + b <= n
        w = np.stack([n - a[keep] - b[keep], a[keep], b[keep]], axis=1) / n        # (m, 3) barycentric
        sel = np.flatnonzero(steps == n)
        pts = np.einsum("mk,fkj->fmj", w, tri[sel]).reshape(-1, 3)
        parts.append((pts, np.repeat(sel, w.shape[0])))
    if not parts:
        return np.zeros((0, 3)), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros(0, bool)
    pts, idx = (np.concatenate(c) for c in zip(*parts))
    f = faces[idx]
    return pts, compiled.face_object[f], normal[idx], compiled.two_sided[compiled.face_object[f]]


__all__ = ["backprojection_image", "image_masks", "record_image", "unaliased_band"]
