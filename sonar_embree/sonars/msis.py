"""A mechanically scanning imaging sonar (MSIS): one narrow fan beam on a head that steps each ping.

The transducer is a baffled rectangular membrane (docs/physics.md §2) whose narrow (horizontal) width sets the
beam's 1.8°-class bearing resolution and whose short (vertical) side the 30°-class fan; its axis is depressed by
``tilt_deg`` and turned by the head's bearing ψ (clockwise from the vehicle's forward axis, seen from above).
The head steps ``step_deg`` per ping over a full circle, or back and forth over a sector. Ping k's beam is
exactly one side of a side-scan sonar whose body is the head's frame: the side-scan's starboard beam looking
along the head's bearing, its along-track axis across the beam. So an MSIS ping is cast, weighted, splatted and
synthesised by the side-scan's own fan, kernels and back ends with the other side's rows left empty (the
"mount" of the front end turns each ping's body frame by R_z(ψ_k)·M), and every physics option (laws,
environment, speckle, pulses, levels, receiver) applies unchanged.
"""
from __future__ import annotations


import math
from dataclasses import dataclass

import numpy as np

from ..config import FanSettings, Sonar, Transducer
from ..propagation.echoes import Echoes, merged
from ..errors import ConfigError
from ..instrument.receiver import Receiver
from ..instrument.beams import APERTURE_BEAMS
from ..validation import check_number
from .sidescan import SideScanFrontEnd
from ..instrument.beam import membrane_size_for_beamwidth
from ..io.files import atomic_write

#: Side-scan body axes in the head's frame (columns: forward → −y, starboard → +x, down → +z): the side-scan's
#: starboard beam then looks along the head's x axis, its bearing.
HEAD_FROM_SIDESCAN = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
#: Narrowest one-way beamwidth accepted, degrees (a 0.1° beam at 900 kHz needs a 0.85 m aperture; narrower
#: values are unit slips, and their pattern is too narrow for any ray to sample).
MIN_BEAMWIDTH_DEG = 0.1
#: The fan reaches this many nulls of the vertical pattern (the baffle for a 30° beam): its side lobes light the
#: floor under the head, so the first return comes from straight below, as a real head's does.
ELEVATION_NULLS = 3


class SideScanEquivalent:
    """Mixin of the sonar types cast by a side-scan's fan (``as_sidescan(c)``): their beam and speckle lattice are
    the equivalent side-scan's."""

    def transducer_in(self, sound_speed_m_s: float):
        """The beam at sound speed ``sound_speed_m_s`` (m/s), in the equivalent side-scan's frame
        (:meth:`as_sidescan`)."""
        return self.as_sidescan(sound_speed_m_s).transducer_in(sound_speed_m_s)

    def speckle_cell_in(self, sound_speed_m_s: float) -> float:
        """The equivalent side-scan's lattice spacing (:meth:`sonar_embree.Sonar.speckle_cell_in`), m."""
        return self.as_sidescan(sound_speed_m_s).speckle_cell_in(sound_speed_m_s)

    @property
    def tilt_rad(self) -> float:
        return math.radians(self.tilt_deg)


@dataclass(frozen=True)
class MSIS(SideScanEquivalent, Transducer):
    """A mechanically scanning imaging sonar.

    Parameters
    ----------
    frequency_hz : float
        Carrier frequency, Hz.
    horizontal_beamwidth_deg, vertical_beamwidth_deg : float
        One-way −3 dB full widths of the beam across the scan and in the vertical, degrees.
    tilt_deg : float
        Depression of the beam axis below the head's horizontal plane, degrees.
    step_deg : float
        Head rotation per ping, degrees (> 0).
    sector_deg : float
        Scanned sector, degrees: 360 a full circle (bearing = start + k·step), less a sector swept back and
        forth centred on ``start_bearing_deg``.
    start_bearing_deg : float
        Bearing of ping 0 (full circle) or the sector's centre, degrees clockwise from the vehicle's forward axis.
    max_range_m, sample_rate_hz, source_level_db, self_noise_db_per_hz, receiver, beam
        As for :class:`~sonar_embree.Sonar` (``beam``: the pattern of the membrane of these widths, or a Gaussian).
    """

    frequency_hz: float = 700e3
    horizontal_beamwidth_deg: float = 1.8
    vertical_beamwidth_deg: float = 30.0
    tilt_deg: float = 20.0
    step_deg: float = 1.8
    sector_deg: float = 360.0
    start_bearing_deg: float = 0.0
    max_range_m: float = 20.0
    sample_rate_hz: float | None = None
    source_level_db: float | None = None
    self_noise_db_per_hz: float | None = None
    receiver: Receiver | None = None
    beam: str = "membrane"

    channels = ("beam",)

    def __post_init__(self):
        if self.beam not in APERTURE_BEAMS:
            raise ConfigError(f"MSIS.beam must be one of {', '.join(repr(k) for k in APERTURE_BEAMS)}, "
                              f"got {self.beam!r}")
        for name, hi in (("horizontal_beamwidth_deg", 30.0), ("vertical_beamwidth_deg", 90.0),
                         ("step_deg", 90.0), ("sector_deg", 360.0)):
            check_number("MSIS", name, getattr(self, name), positive=True, hi=hi)
        for name in ("horizontal_beamwidth_deg", "vertical_beamwidth_deg"):
            check_number("MSIS", name, getattr(self, name), lo=MIN_BEAMWIDTH_DEG)
        check_number("MSIS", "frequency_hz", self.frequency_hz, positive=True)
        check_number("MSIS", "tilt_deg", self.tilt_deg, lo=-89.0, hi=89.0)
        check_number("MSIS", "start_bearing_deg", self.start_bearing_deg)
        check_number("MSIS", "max_range_m", self.max_range_m, positive=True)
        if self.sample_rate_hz is not None:
            check_number("MSIS", "sample_rate_hz", self.sample_rate_hz, positive=True)
        if self.sector_deg < 360.0 and self.step_deg > self.sector_deg:
            raise ConfigError(f"MSIS.step_deg = {self.step_deg:g} exceeds the sector of {self.sector_deg:g} degrees")
        self._check_levels("MSIS")

    def as_sidescan(self, sound_speed_m_s: float) -> Sonar:
        """The side-scan sonar whose starboard beam is this MSIS's beam at sound speed ``sound_speed_m_s`` (m/s) (head
        frame = its body frame)."""
        lam = sound_speed_m_s / self.frequency_hz
        return Sonar(frequency_hz=self.frequency_hz,
                     length_m=membrane_size_for_beamwidth(math.radians(self.horizontal_beamwidth_deg), lam),
                     height_m=membrane_size_for_beamwidth(math.radians(self.vertical_beamwidth_deg), lam),
                     tilt_deg=self.tilt_deg, max_range_m=self.max_range_m, sample_rate_hz=self.sample_rate_hz,
                     source_level_db=self.source_level_db,
                     self_noise_db_per_hz=self.self_noise_db_per_hz, receiver=self.receiver,
                     beam=self.beam)

    def dataset_coords(self, first_ping: int, n_pings: int) -> dict:
        """The head's bearing at each ping of a record that starts at survey ping ``first_ping``."""
        return {"bearing_deg": (("ping",), self.bearings_deg(first_ping + np.arange(n_pings)),
                                {"units": "degree", "long_name": "head bearing, clockwise from the vehicle's forward "
                                                                 "axis"})}

    def bearings_deg(self, pings) -> np.ndarray:
        """The head's bearing at each ping index (degrees in [0, 360), clockwise from the vehicle's forward axis)."""
        k = np.asarray(pings, dtype=np.float64)
        if self.sector_deg >= 360.0:
            return (self.start_bearing_deg + k * self.step_deg) % 360.0
        n = math.floor(self.sector_deg / self.step_deg + 1e-9)       # steps from one end of the sector to the other
        phase = np.mod(k, 2 * n)
        off = np.where(phase <= n, phase, 2 * n - phase) * self.step_deg
        return (self.start_bearing_deg - 0.5 * n * self.step_deg + off) % 360.0



class MSISFrontEnd(SideScanFrontEnd):
    """Poses → echoes for an :class:`MSIS`: the side-scan fan with its starboard side only, on the turning head."""

    channels = MSIS.channels
    supports_labels = True

    def __init__(self, sonar: MSIS, fan: FanSettings):
        super().__init__(sonar.as_sidescan(), fan, sides=(False, True), elevation_nulls=ELEVATION_NULLS)
        self.msis = sonar

    def mount(self, rot: np.ndarray, pings: np.ndarray) -> np.ndarray:
        """Body-to-world rotations of the head at ping indices ``pings``: the vehicle's, turned by the bearing about
        its down axis, then the side-scan's axes mapped onto the head's."""
        psi = np.radians(self.msis.bearings_deg(pings))
        c, s = np.cos(psi), np.sin(psi)
        turn = np.zeros((len(psi), 3, 3))
        turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1], turn[:, 2, 2] = c, -s, s, c, 1.0
        return np.einsum("pij,pjk,kl->pil", np.asarray(rot, dtype=np.float64), turn, HEAD_FROM_SIDESCAN)

    def label_lines(self, plan):
        """Ground truth along the beam's centre line: the starboard boresight line of the block's fan ``plan``."""
        return (1,), (int(np.flatnonzero(plan.s == 0.0)[0]),)

    def cast(self, run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift=None):
        """The side-scan block's echoes with its (empty) port rows dropped: one channel per ping."""
        e, blk = super().cast(run, rot, pos_local, max_range_m, want_points, want_ids, clock, rx_shift)
        e = merged(e)
        start = np.concatenate([e.ray_start[1::2], e.ray_start[-1:]])
        a = e.along
        along = None if a is None else a.rows(1, a.axis_rad.shape[0], 2)
        return Echoes(1, start, e.travel_time_s, e.extent_s, e.weight, e.point_m, e.object_id, e.path, along,
                      e.on_strip), blk


def polar_image(record, pixel_m: float | None = None):
    """The usual MSIS display: each ping's samples drawn at their slant range along the beam's bearing, around the
    first ping's position (the vehicle's later moves are not undone: the scan's distortion under motion shows).

    Parameters
    ----------
    record : Record
        An MSIS record.
    pixel_m : float, optional
        Pixel size, m (default: max_range / 200).

    Returns
    -------
    image : (n, n) float64
        Row 0 north, column 0 west; each pixel takes the sample of the ping whose beam azimuth is nearest its
        direction (one of them where a scan repeats) at its distance, NaN outside the range or the scanned
        sector (farther than a step from every beam).
    extent_m : (west, east, south, north)
        World coordinates of the image's edges, m.
    """
    s = record.sonar
    if not isinstance(s, MSIS):
        raise ConfigError(f"polar_image: an MSIS record is needed, got a {type(s).__name__} record")
    pixel = s.max_range_m / 200.0 if pixel_m is None else float(pixel_m)
    first = int(record.attrs.get("first_ping", 0))
    az = _beam_azimuths(record.trajectory, s.bearings_deg(first + np.arange(record.n_pings)))
    n = 2 * int(math.ceil(s.max_range_m / pixel))
    c = (np.arange(n) + 0.5 - n / 2) * pixel
    east, north = np.meshgrid(c, -c)
    r, theta = np.hypot(east, north), np.arctan2(east, north)          # azimuth clockwise from north
    order = np.argsort(az, kind="stable")
    k = _nearest_ping(az[order], theta)
    gap = np.abs(np.angle(np.exp(1j * (theta - az[order][k]))))
    ping = order[k]
    sample = np.rint(r / record.slant_range_m[1]).astype(np.int64)
    ok = (sample < record.data.shape[2]) & (gap <= math.radians(s.step_deg))
    image = np.full(r.shape, np.nan)
    image[ok] = record.data[ping[ok], 0, sample[ok]]
    x0, y0 = record.trajectory.positions_m[0, :2]
    half = n / 2 * pixel
    return image, (x0 - half, x0 + half, y0 - half, y0 + half)


def _beam_azimuths(trajectory, bearings_deg) -> np.ndarray:
    """(pings,) world azimuth of each ping's beam (clockwise from north, rad): the vehicle's heading turned by the
    bearing, through the full attitude."""
    psi = np.radians(bearings_deg)
    body = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], axis=1)
    world = np.einsum("pij,pj->pi", trajectory.rotations(), body)
    return np.arctan2(world[:, 0], world[:, 1])


def _nearest_ping(sorted_az: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Index into ``sorted_az`` of the azimuth nearest each ``theta`` (circular)."""
    i = np.searchsorted(sorted_az, theta)
    lo, hi = (i - 1) % len(sorted_az), i % len(sorted_az)
    d_lo = np.abs(np.angle(np.exp(1j * (theta - sorted_az[lo]))))
    d_hi = np.abs(np.angle(np.exp(1j * (theta - sorted_az[hi]))))
    return np.where(d_hi <= d_lo, hi, lo)


def save_polar_png(record, path, pixel_m: float | None = None, dynamic_range_db: float = 40.0) -> None:
    """Write :func:`polar_image` as an 8-bit PNG (atomic): display TVG R², dB, white at the 99.9th percentile,
    ``dynamic_range_db`` below it black (and outside the scan)."""
    import imageio.v3 as iio


    img, ext = polar_image(record, pixel_m)
    n = img.shape[0]
    c = (np.arange(n) + 0.5 - n / 2) * (ext[1] - ext[0]) / n
    atomic_write(path, lambda tmp: iio.imwrite(tmp, display_grey(img, np.add.outer(c ** 2, c ** 2), dynamic_range_db),
                                               extension=".png"), suffix=".png")


def display_grey(img, r2, dynamic_range_db: float) -> np.ndarray:
    """8-bit grey of a display image (NaN outside the scan): display TVG ``r2`` (R², m²), dB, white at the 99.9th
    percentile, ``dynamic_range_db`` below it black (and NaN)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        db = 10.0 * np.log10(img * r2)
    top = np.nanpercentile(db[np.isfinite(db)], 99.9) if np.isfinite(db).any() else 0.0
    grey = np.clip((db - top + dynamic_range_db) / dynamic_range_db, 0.0, 1.0)
    return np.nan_to_num(np.rint(255 * grey), nan=0.0).astype(np.uint8)
