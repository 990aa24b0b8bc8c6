"""A forward-looking multibeam imaging sonar (FLS): a wide transmit fan, N receive beams from a line array.

The receive array is a uniform line of M elements, spacing d, lying across the vehicle; each element (and the
transmitter) is a baffled rectangular membrane d wide and h high (docs/physics.md §2), so one element's fan is
wide horizontally (d ≈ λ/2) and ``vertical_beamwidth_deg`` high, depressed by ``tilt_deg``. Beam k is the array
steered to θ_k (degrees to starboard, uniform over the field of view) with the line array's closed form

    AF_k(u) = sin(M·ψ/2) / (M·sin(ψ/2)),   ψ = k·d·(u − u_k),   u_k = sin θ_k

(uniform weights; Urick, *Principles of Underwater Sound*, 3rd ed., 1983, §3.4; Van Trees, *Optimum Array
Processing*, 2002, ch. 2), u the direction cosine along the array. The expected intensity of beam k is
Σ_rays w·AF_k(u)², w the ray's echo weight with the elements' two-way pattern (§3).

The rays are the side-scan's fan (§7) turned a quarter round so that its along-track axis is the array's axis
and its starboard side looks forward: its azimuth lines are then lines of constant u, which the fan already
samples finely enough to integrate a band-limited pattern exactly (ds = λ/(2·M·d)/oversample over the whole
visible |u| < 1). Every azimuth line is synthesised as a channel of its own (the side-scan's back ends, laws,
environment, speckle and pulses, unchanged), and the beams are formed from those channels afterwards: a matrix
AF² on the expected intensities, or AF on the coherent complex signals (speckle then correlates between
neighbouring beams as a real beamformer's does). Receiver noise is added per beam after beamforming.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..instrument import beam
from ..config import FanSettings, Sonar, Transducer
from ..propagation.echoes import Echoes, row_of, row_starts
from ..errors import ConfigError
from ..instrument.receiver import Receiver
from ..instrument.beams import APERTURE_BEAMS
from ..validation import check_number
from .msis import ELEVATION_NULLS, HEAD_FROM_SIDESCAN, MIN_BEAMWIDTH_DEG, SideScanEquivalent, display_grey
from .sidescan import SideScanFrontEnd
from ..io.files import atomic_write

#: Probe lines across the fan, at least (the side-scan probes three: a wide fan needs them everywhere): one per
#: receive beam's null-to-null half width λ/(M·d) in u, at least this many.
MIN_PROBE_LINES = 33
#: Largest |u| of the fan (grazing along the array axis).
U_MAX = 0.999


@dataclass(frozen=True)
class ForwardLooking(SideScanEquivalent, Transducer):
    """A forward-looking multibeam imaging sonar.

    Parameters
    ----------
    frequency_hz : float
        Carrier frequency, Hz.
    n_beams : int
        Receive beams, steered uniformly in angle over the field of view.
    field_of_view_deg : float
        Horizontal span of the beams' steering angles, degrees (at most 170).
    n_elements : int
        Elements M of the receive line array.
    element_spacing_m : float or None
        Their spacing d, m (default λ/2; grating lobes inside the field of view are refused).
    vertical_beamwidth_deg : float
        One-way −3 dB vertical width of the elements' (and the transmitter's) fan, degrees.
    tilt_deg : float
        Depression of the fan's axis below the vehicle's horizontal plane, degrees.
    max_range_m, sample_rate_hz, source_level_db, self_noise_db_per_hz, receiver, beam
        As for :class:`~sonar_embree.Sonar` (``beam``: the pattern of the membrane of these widths, or a Gaussian).
    """

    #: Its record is one (ping, beam, sample) array of formed beams (:class:`~sonar_embree.config.Transducer`).
    forms_beams = True

    frequency_hz: float = 900e3
    n_beams: int = 256
    field_of_view_deg: float = 130.0
    n_elements: int = 128
    element_spacing_m: float | None = None
    vertical_beamwidth_deg: float = 20.0
    tilt_deg: float = 10.0
    max_range_m: float = 40.0
    sample_rate_hz: float | None = None
    source_level_db: float | None = None
    self_noise_db_per_hz: float | None = None
    receiver: Receiver | None = None
    beam: str = "membrane"

    def __post_init__(self):
        if self.beam not in APERTURE_BEAMS:
            raise ConfigError(f"ForwardLooking.beam must be one of {', '.join(repr(k) for k in APERTURE_BEAMS)}, "
                              f"got {self.beam!r}")
        for name, lo, hi in (("n_beams", 1, 4096), ("n_elements", 2, 4096)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise ConfigError(f"ForwardLooking.{name} must be an integer in [{lo}, {hi}], got {v!r}")
        check_number("ForwardLooking", "frequency_hz", self.frequency_hz, positive=True)
        check_number("ForwardLooking", "field_of_view_deg", self.field_of_view_deg, positive=True, hi=170.0)
        check_number("ForwardLooking", "vertical_beamwidth_deg", self.vertical_beamwidth_deg, lo=MIN_BEAMWIDTH_DEG,
                     hi=90.0)
        check_number("ForwardLooking", "tilt_deg", self.tilt_deg, lo=-89.0, hi=89.0)
        check_number("ForwardLooking", "max_range_m", self.max_range_m, positive=True)
        if self.sample_rate_hz is not None:
            check_number("ForwardLooking", "sample_rate_hz", self.sample_rate_hz, positive=True)
        if self.element_spacing_m is not None:
            check_number("ForwardLooking", "element_spacing_m", self.element_spacing_m, positive=True)
        self._check_levels("ForwardLooking")

    def check_sound_speed(self, sound_speed_m_s: float) -> None:
        """Refuse an element spacing that puts grating lobes inside the field of view at sound speed ``sound_speed_m_s``
        (m/s)."""
        u_edge = math.sin(math.radians(0.5 * self.field_of_view_deg))
        wavelength_m = sound_speed_m_s / self.frequency_hz
        d = self.spacing_in(sound_speed_m_s)
        if d * (1.0 + u_edge) >= wavelength_m:
            raise ConfigError(f"ForwardLooking.element_spacing_m = {d:g} m puts grating lobes inside the "
                              f"field of view (needs d < λ/(1 + sin(fov/2)) = {wavelength_m / (1.0 + u_edge):.4g} m "
                              f"at λ = {wavelength_m:.4g} m)")

    def spacing_in(self, sound_speed_m_s: float) -> float:
        """Element spacing d, m (λ/2 at sound speed ``sound_speed_m_s`` (m/s) unless given)."""
        if self.element_spacing_m is not None:
            return float(self.element_spacing_m)
        return sound_speed_m_s / self.frequency_hz / 2.0

    @property
    def channels(self) -> tuple:
        """The record's channels: one per beam, ``beam000`` … (port to starboard)."""
        return tuple(f"beam{k:03d}" for k in range(self.n_beams))

    def dataset_coords(self, first_ping: int, n_pings: int) -> dict:
        """Each beam's steering angle."""
        return {"beam_angle_deg": (("beam",), self.beam_angles_deg(),
                                   {"units": "degree", "long_name": "steering angle of the beam, to starboard"})}

    def beam_angles_deg(self) -> np.ndarray:
        """(n_beams,) steering angle θ_k of each beam, degrees to starboard of the vehicle's forward axis."""
        half = 0.5 * self.field_of_view_deg
        return np.linspace(-half, half, self.n_beams) if self.n_beams > 1 else np.zeros(1)

    def array_factor(self, u, sound_speed_m_s: float) -> np.ndarray:
        """(n_beams, n) AF_k(u) of the uniform line array at direction cosines ``u`` (n,) to starboard at sound speed
        ``sound_speed_m_s`` (m/s) (real: phase referred to the array's centre; 1 on the steering direction)."""
        u = np.asarray(u, dtype=np.float64)
        u_k = np.sin(np.radians(self.beam_angles_deg()))
        k = 2.0 * math.pi * self.frequency_hz / sound_speed_m_s
        psi = k * self.spacing_in(sound_speed_m_s) * (u[None, :] - u_k[:, None])
        m = self.n_elements
        num, den = np.sin(0.5 * m * psi), m * np.sin(0.5 * psi)
        small = np.abs(den) < 1e-12 * m
        with np.errstate(divide="ignore", invalid="ignore"):
            af = np.where(small, np.cos(0.5 * m * psi) / np.cos(0.5 * psi), num / den)   # ψ = 2πn: the limit
        return af

    def as_sidescan(self, sound_speed_m_s: float) -> Sonar:
        """The side-scan sonar whose starboard fan is one element's (d wide, h high) at sound speed ``sound_speed_m_s``
        (m/s), turned to look forward."""
        return Sonar(frequency_hz=self.frequency_hz, length_m=self.spacing_in(sound_speed_m_s),
                     height_m=beam.membrane_size_for_beamwidth(math.radians(self.vertical_beamwidth_deg),
                                                               sound_speed_m_s / self.frequency_hz),
                     tilt_deg=self.tilt_deg, max_range_m=self.max_range_m, sample_rate_hz=self.sample_rate_hz,
                     source_level_db=self.source_level_db,
                     self_noise_db_per_hz=self.self_noise_db_per_hz, receiver=self.receiver,
                     beam=self.beam)

    def directivity_index_in(self, sound_speed_m_s: float) -> float:
        """A beam's receiving DI: the element's (Urick §3.6) plus the array gain 10·log10 M against isotropic
        noise (elements at λ/2, Urick §3.4), dB."""
        element = self.as_sidescan(sound_speed_m_s).directivity_index_in(sound_speed_m_s)
        return element + 10.0 * math.log10(self.n_elements)


def array_samples(sonar, oversample: float):
    """Direction cosines u of the fan's azimuth lines, along the side-scan's x axis (= −u to starboard), and
    their spacing: ds = λ/(2·M·d)/oversample over |u| ≤ :data:`U_MAX`, one line on boresight, for ``sonar`` a
    forward-looking :class:`~sonar_embree.config.Acquisition`."""
    ds = sonar.wavelength_m / (2.0 * sonar.n_elements * sonar.spacing_in(sonar.sound_speed_m_s)) / oversample
    m = int(math.floor(U_MAX / ds + 1e-9))
    return np.arange(-m, m + 1, dtype=np.float64) * ds, ds


class ForwardLookingFrontEnd(SideScanFrontEnd):
    """Poses → echoes for a :class:`ForwardLooking`: one element's fan looking forward, one channel per azimuth
    line; :meth:`beamform` turns those into the beams. Ground truth per beam: along the azimuth line nearest its
    steering direction, and the object echoes beamformed as the record is (:attr:`beam_power`)."""

    supports_labels = True
    #: Its rows are azimuth lines (one channel each, beamformed): no along-track strips across them.
    strips = False

    def __init__(self, sonar: ForwardLooking, fan: FanSettings):
        super().__init__(sonar.as_sidescan(), fan, sides=(False, True), elevation_nulls=ELEVATION_NULLS)
        s, ds = array_samples(sonar, fan.resolved().azimuth_oversample)
        aperture = sonar.n_elements * sonar.spacing_in(sonar.sound_speed_m_s)
        n_lines = max(MIN_PROBE_LINES, int(math.ceil(2.0 * s[-1] * aperture / sonar.wavelength_m)) + 1)
        lines = np.linspace(-s[-1], s[-1], n_lines)
        body = np.concatenate([beam.fan_body(lines, self.plan.probe_beta, side) for side in (-1, +1)])
        # its lines span the field of view, one synthesised channel each: none added under motion (δ ≪ the span)
        self.plan = dataclasses.replace(self.plan, s=s, ds=ds, probe_body=body, spans_motion=False)
        self.fls, self.channels = sonar, sonar.channels
        self.n_synth_channels = s.shape[0]
        self.af = sonar.array_factor(-s, sonar.sound_speed_m_s)      # u to starboard = −s (HEAD_FROM_SIDESCAN)
        self.beam_power = self.af ** 2

    def label_lines(self, plan):
        """Each beam's label line: the (starboard) azimuth line of the block's fan ``plan`` nearest its steering
        direction."""
        u_k = np.sin(np.radians(self.fls.beam_angles_deg()))
        az = np.argmin(np.abs(plan.s[None, :] + u_k[:, None]), axis=1)
        return (1,) * u_k.shape[0], tuple(int(a) for a in az)

    def mount(self, rot: np.ndarray, pings: np.ndarray) -> np.ndarray:
        """Body-to-world rotations of the side-scan fan whose starboard side looks along the vehicle's forward axis."""
        return np.einsum("pij,jk->pik", np.asarray(rot, dtype=np.float64), HEAD_FROM_SIDESCAN)

    def _rows(self, e: Echoes, el_start: np.ndarray | None, lines: np.ndarray | None = None) -> Echoes:
        """The side-scan layout's echoes as one row per ping and azimuth line: aligned with its rays (``el_start``),
        or, for a swell's paths, each echo on its own azimuth line (``lines``)."""
        if el_start is not None:
            return dataclasses.replace(e, n_channels=self.n_synth_channels,
                                       ray_start=azimuth_rows(el_start, self.plan.s.shape[0]))
        n_az = self.plan.s.shape[0]
        key = row_of(e.ray_start) // 2 * n_az + lines
        order = np.argsort(key, kind="stable")

        def part(x):
            return x[order] if x.shape[0] == e.weight.shape[0] else x

        return Echoes(n_az, row_starts(key[order], n_az * (e.ray_start.shape[0] - 1) // 2), e.travel_time_s[order],
                      e.extent_s[order], e.weight[order], part(e.point_m), part(e.object_id))

    def _aimed_rows(self, aimed, echoes: Echoes | None = None) -> Echoes:
        """The aimed rays' echoes shared between the two azimuth lines around each one's direction, linearly in s
        (weights 1 − f and f, f its fractional position between the lines): the beamformer then weighs it with AF²
        interpolated between the lines, so its response moves smoothly with its bearing (no snapping to a line,
        no dark bearing between lines; docs/physics.md §7b)."""
        e = aimed.echoes if echoes is None else echoes
        lit = np.flatnonzero(e.weight > 0.0)
        n_az = self.plan.s.shape[0]
        p = (aimed.layout[lit, 0] - self.plan.s[0]) / self.plan.ds
        a = np.clip(np.floor(p), 0, n_az - 2).astype(np.int64)
        f = np.clip(p - a, 0.0, 1.0)
        ping = row_of(e.ray_start)[lit] // 2
        rows = np.concatenate([ping * n_az + a, ping * n_az + a + 1])
        order = np.argsort(rows, kind="stable")
        src = np.concatenate([lit, lit])[order]
        w = np.concatenate([e.weight[lit] * (1.0 - f), e.weight[lit] * f])[order]
        start = row_starts(rows[order], n_az * (e.ray_start.shape[0] - 1) // 2)

        def part(x):
            return x[src] if x.shape[0] == e.weight.shape[0] else x

        return Echoes(n_az, start, e.travel_time_s[src], e.extent_s[src], w, part(e.point_m), part(e.object_id))

    def beamform(self, intensity, cplx, noise):
        """Beams (pings, n_beams, n_s) from the azimuth lines' intensities and, for coherent speckle, their complex
        signals; ``noise(shape, complex_)`` draws the receiver noise added per beam (or None)."""
        if cplx is not None:
            beams = np.matmul(self.af, cplx)
            if noise is not None:
                beams += noise(beams.shape, True)
            return beams.real ** 2 + beams.imag ** 2, beams
        out = np.matmul(self.beam_power, intensity)
        if noise is not None:
            out += noise(out.shape, False)
        return out, None


def azimuth_rows(el_start: np.ndarray, n_az: int) -> np.ndarray:
    """(pings·n_az + 1,) offsets of one row per ping and azimuth line into a side-scan block's rays (rows port,
    starboard per ping, azimuth-major: ray a·n_el + j of a row is azimuth line a, elevation j); the port rows are
    empty."""
    el_start = np.asarray(el_start, dtype=np.int64)
    lo, hi = el_start[1:-1:2], el_start[2::2]              # each ping's starboard row
    start = n_az * lo[:, None] + np.arange(n_az)[None, :] * (hi - lo)[:, None]
    return np.append(start.ravel(), n_az * el_start[-1]).astype(np.int64)


def fan_image(record, ping: int | None = None, pixel_m: float | None = None):
    """The usual forward-looking display: one ping's beams drawn as a fan, each sample at its slant range along its
    beam's steering angle (seen from above, the sonar at the bottom centre, forward up).

    Parameters
    ----------
    record : Record
        A :class:`ForwardLooking` record.
    ping : int, optional
        The ping (default: the middle one).
    pixel_m : float, optional
        Pixel size, m (default: max_range / 300).

    Returns
    -------
    image : (rows, columns) float64
        Row 0 farthest ahead; each pixel takes the sample of the beam steered nearest its direction at its
        distance, NaN outside the field of view (farther than half a beam spacing from the outer beams) or range.
    extent_m : (left, right, near, far)
        Starboard and forward coordinates of the image's edges, m (left negative: port).
    """
    s = record.sonar
    if not isinstance(s, ForwardLooking):
        raise ConfigError(f"fan_image: a ForwardLooking record is needed, got a {type(s).__name__} record")
    ping = record.n_pings // 2 if ping is None else int(ping)
    if not 0 <= ping < record.n_pings:
        raise ConfigError(f"fan_image: ping {ping} is not in the record's {record.n_pings} pings")
    pixel = s.max_range_m / 300.0 if pixel_m is None else float(pixel_m)
    half = 0.5 * math.radians(s.field_of_view_deg)
    n_y, n_x = int(math.ceil(s.max_range_m / pixel)), 2 * int(math.ceil(s.max_range_m * math.sin(half) / pixel))
    stbd = (np.arange(n_x) + 0.5 - n_x / 2) * pixel
    fwd = (n_y - np.arange(n_y) - 0.5) * pixel
    x, y = np.meshgrid(stbd, fwd)
    r, theta = np.hypot(x, y), np.degrees(np.arctan2(x, y))
    angles = s.beam_angles_deg()
    step = angles[1] - angles[0] if angles.size > 1 else s.field_of_view_deg
    k = np.clip(np.rint((theta - angles[0]) / step).astype(np.int64), 0, angles.size - 1)
    sample = np.rint(r / record.slant_range_m[1]).astype(np.int64)
    ok = (sample < record.data.shape[2]) & (np.abs(theta - angles[k]) <= 0.5 * step + 1e-9)
    image = np.full(r.shape, np.nan)
    image[ok] = record.data[ping, k[ok], sample[ok]]
    return image, (stbd[0] - 0.5 * pixel, stbd[-1] + 0.5 * pixel, 0.0, n_y * pixel)


def save_fan_png(record, path, ping: int | None = None, dynamic_range_db: float = 40.0) -> None:
    """Write :func:`fan_image` as an 8-bit PNG (atomic): display TVG R², dB, white at the 99.9th percentile,
    ``dynamic_range_db`` below it black (and outside the fan)."""
    import imageio.v3 as iio


    img, (left, right, near, far) = fan_image(record, ping)
    x = np.linspace(left, right, img.shape[1])
    y = np.linspace(far, near, img.shape[0])
    out = display_grey(img, np.add.outer(y ** 2, x ** 2), dynamic_range_db)
    atomic_write(path, lambda tmp: iio.imwrite(tmp, out, extension=".png"), suffix=".png")
