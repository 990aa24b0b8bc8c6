"""XTF (Triton eXtended Triton Format) side-scan files, written with NumPy structured types.

One file header (1024 bytes, two sonar channels described) and one sonar packet
per ping: a 256-byte ping header, then per channel a 64-byte channel header and
its samples. Field layouts follow the public XTF specification (revision X41+);
pyxtf reads the files (tested).

Conventions of what is written:

- Device samples: a record from a sonar with a :class:`~sonar_embree.Receiver` is written as the device
  would store it: its integer ADC codes (uint16 as SampleFormat 3 "word", 2 bytes per sample, or uint8 as
  SampleFormat 8 "byte"), unipolar, VoltScale the ADC's full scale in volts, and the gain law in each
  channel header: GainCode = k of a TVG (20/30/40; 0 for AGC), InitialGainCode = its G0 in dB,
  MillivoltScale = full scale in mV. ``scale`` does not apply to them.
- Otherwise samples are 4-byte IEEE floats (SampleFormat 5): the record's linear intensity
  (unit source) times a scale factor, rounded to float32. ``scale="auto"``
  (default) is the power of ten that puts the 99.5th percentile of the positive
  samples between 100 and 1000 — raw unit-source intensities (~1e-12) show black
  in viewers; a number sets the factor, 1 keeps the raw values. The factor is
  written in the file header's note ("unit-source intensity x 1e+14").
- **Sample order**: starboard runs from time 0 (nadir) outwards; port runs from far
  range to nadir (its last sample is time 0), the XTF convention readers such as
  pyxtf assume, so ``hstack([port, starboard])`` is the waterfall.
- Navigation of a trajectory with a CRS (:mod:`sonar_embree.io.geo`) in latitude and longitude (NavUnits 3):
  SensorXcoordinate = longitude, SensorYcoordinate = latitude, WGS 84 degrees as float64; the Ship fields
  hold the ship's position of a towed sonar (:meth:`~sonar_embree.Trajectory.with_layback`; CableOut the straight
  cable's length, m), else the sensor's. The Sensor fields hold the towfish where it is, laid back already, so
  Layback is written 0: readers that lay the sensor back by a non-zero Layback (the X41 specification, Isis,
  OpenSidescan) would otherwise lay it back twice. Without a CRS, in metres (NavUnits 0): world x (east) and y
  (north). SensorHeading and ShipGyro are true headings (the grid heading turned by the meridian convergence,
  :func:`sonar_embree.io.geo.true_heading_deg`) where the positions are latitude/longitude.
- Navigation fixes as devices log them: where the trajectory holds its log's fix times
  (:attr:`~sonar_embree.Trajectory.fix_times_s`, a 1 Hz GPS log resampled at the ping rate), FixTime is the time of
  each ping's last fix and the Sensor and Ship positions are where the fish and the ship were at that time, held
  until the next fix, while depth, altitude, attitude and speed are the ping's own (the sensors devices sample
  every ping). Without fix times every ping is its own fix. A replay rebuilds the continuous track between the
  fixes (:func:`continuous_track`).
  SensorDepth = surface_z_m − z, positive down from the sea surface at world height
  ``surface_z_m`` (default: the sonar's own sea surface, ``environment.surface``); without one the depth of a
  georeferenced trajectory is −z (its vertical datum, z = 0, taken as the sea surface) when it lies below
  z = 0, otherwise unknown and written as 0, as devices without a pressure sensor do;
  SensorPrimaryAltitude = the record's nadir altitude (0 where none);
  SensorSpeed and ShipSpeed in knots from the trajectory (its velocity, else distance
  over time between pings); SensorHeading, SensorPitch, SensorRoll in degrees
  (docs/physics.md §1 is the XTF convention).
- SoundVelocity holds c/2 (the XTF convention); the channel header's SlantRange
  is the range window, TimeDuration its length, SecondsPerPing = SlantRange/SoundVelocity (the spec's
  "SlantRange/750", which readers build their range axis from), Frequency in kHz, ProcessingFlags 4 (TVG)
  where the samples are a TVG receiver's codes. CHANINFO: CorrectionFlags 1 (slant range), UniPolar 1
  (intensities and codes are ≥ 0), HorizBeamAngle the along-track and BeamWidth the vertical one-way −3 dB
  width (the spec's "typically 1 degree" and "3dB beam width, typically 50 degrees"), TiltAngle the
  depression, ThisFileName the file's name; BeamsPerArray 1 (one beam a side, as devices write it).
- As devices write them: TimeDuration = SecondsPerPing = 2R/c, EventNumber 0 (no event marked), each sonar
  packet padded with zeros to a multiple of 64 bytes (NumBytesThisRecord counts the padding).
- Ping times: ``start`` (default: the record's ``attrs["start_time"]``, set by
  :func:`~sonar_embree.simulate`) plus the trajectory's ``times_s``.
"""
from __future__ import annotations

import datetime as dt
import math
import os

import numpy as np

from ..instrument.beam import beamwidth_deg
from ..errors import ConfigError
from ..validation import check_bool
from .files import atomic_write
from .geo import to_lonlat, true_heading_deg
from ..validation import iso_utc

_CHAN_INFO = np.dtype([
    ("TypeOfChannel", "u1"), ("SubChannelNumber", "u1"), ("CorrectionFlags", "<u2"), ("UniPolar", "<u2"),
    ("BytesPerSample", "<u2"), ("Reserved", "<u4"), ("ChannelName", "S16"), ("VoltScale", "<f4"),
    ("Frequency", "<f4"), ("HorizBeamAngle", "<f4"), ("TiltAngle", "<f4"), ("BeamWidth", "<f4"),
    ("OffsetX", "<f4"), ("OffsetY", "<f4"), ("OffsetZ", "<f4"), ("OffsetYaw", "<f4"), ("OffsetPitch", "<f4"),
    ("OffsetRoll", "<f4"), ("BeamsPerArray", "<u2"), ("SampleFormat", "u1"), ("ReservedArea2", "u1", 53)])

_FILE_HEADER = np.dtype([
    ("FileFormat", "u1"), ("SystemType", "u1"), ("RecordingProgramName", "S8"),
    ("RecordingProgramVersion", "S8"), ("SonarName", "S16"), ("SonarType", "<u2"), ("NoteString", "S64"),
    ("ThisFileName", "S64"), ("NavUnits", "<u2"), ("NumberOfSonarChannels", "<u2"),
    ("NumberOfBathymetryChannels", "<u2"), ("NumberOfSnippetChannels", "u1"), ("NumberOfForwardLookArrays", "u1"),
    ("NumberOfEchoStrengthChannels", "<u2"), ("NumberOfInterferometryChannels", "u1"), ("Reserved1", "u1"),
    ("Reserved2", "<u2"), ("ReferencePointHeight", "<f4"), ("ProjectionType", "u1", 12),
    ("SpheriodType", "u1", 10), ("NavigationLatency", "<i4"), ("OriginY", "<f4"), ("OriginX", "<f4"),
    ("NavOffsetY", "<f4"), ("NavOffsetX", "<f4"), ("NavOffsetZ", "<f4"), ("NavOffsetYaw", "<f4"),
    ("MRUOffsetY", "<f4"), ("MRUOffsetX", "<f4"), ("MRUOffsetZ", "<f4"), ("MRUOffsetYaw", "<f4"),
    ("MRUOffsetPitch", "<f4"), ("MRUOffsetRoll", "<f4"), ("ChanInfo", _CHAN_INFO, 6)])

_F4 = "<f4"
_PING_HEADER = np.dtype([
    ("MagicNumber", "<u2"), ("HeaderType", "u1"), ("SubChannelNumber", "u1"), ("NumChansToFollow", "<u2"),
    ("Reserved1", "<u2", 2), ("NumBytesThisRecord", "<u4"),
    ("Year", "<u2"), ("Month", "u1"), ("Day", "u1"), ("Hour", "u1"), ("Minute", "u1"), ("Second", "u1"),
    ("HSeconds", "u1"), ("JulianDay", "<u2"), ("EventNumber", "<u4"), ("PingNumber", "<u4"),
    ("SoundVelocity", _F4), ("OceanTide", _F4), ("Reserved2", "<u4"), ("ConductivityFreq", _F4),
    ("TemperatureFreq", _F4), ("PressureFreq", _F4), ("PressureTemp", _F4), ("Conductivity", _F4),
    ("WaterTemperature", _F4), ("Pressure", _F4), ("ComputedSoundVelocity", _F4), ("MagX", _F4), ("MagY", _F4),
    ("MagZ", _F4), ("AuxVal1", _F4), ("AuxVal2", _F4), ("AuxVal3", _F4), ("AuxVal4", _F4), ("AuxVal5", _F4),
    ("AuxVal6", _F4), ("SpeedLog", _F4), ("Turbidity", _F4), ("ShipSpeed", _F4), ("ShipGyro", _F4),
    ("ShipYcoordinate", "<f8"), ("ShipXcoordinate", "<f8"), ("ShipAltitude", "<u2"), ("ShipDepth", "<u2"),
    ("FixTimeHour", "u1"), ("FixTimeMinute", "u1"), ("FixTimeSecond", "u1"), ("FixTimeHsecond", "u1"),
    ("SensorSpeed", _F4), ("KP", _F4), ("SensorYcoordinate", "<f8"), ("SensorXcoordinate", "<f8"),
    ("SonarStatus", "<u2"), ("RangeToFish", "<u2"), ("BearingToFish", "<u2"), ("CableOut", "<u2"),
    ("Layback", _F4), ("CableTension", _F4), ("SensorDepth", _F4), ("SensorPrimaryAltitude", _F4),
    ("SensorAuxAltitude", _F4), ("SensorPitch", _F4), ("SensorRoll", _F4), ("SensorHeading", _F4),
    ("Heave", _F4), ("Yaw", _F4), ("AttitudeTimeTag", "<u4"), ("DOT", _F4), ("NavFixMilliseconds", "<u4"),
    ("ComputerClockHour", "u1"), ("ComputerClockMinute", "u1"), ("ComputerClockSecond", "u1"),
    ("ComputerClockHsec", "u1"), ("FishPositionDeltaX", "<i2"), ("FishPositionDeltaY", "<i2"),
    ("FishPositionErrorCode", "u1"), ("OptionalOffset", "<u4"), ("CableOutHundredths", "u1"),
    ("ReservedSpace2", "u1", 6)])

_CHAN_HEADER = np.dtype([
    ("ChannelNumber", "<u2"), ("DownsampleMethod", "<u2"), ("SlantRange", _F4), ("GroundRange", _F4),
    ("TimeDelay", _F4), ("TimeDuration", _F4), ("SecondsPerPing", _F4), ("ProcessingFlags", "<u2"),
    ("Frequency", "<u2"), ("InitialGainCode", "<u2"), ("GainCode", "<u2"), ("BandWidth", "<u2"),
    ("ContactNumber", "<u4"), ("ContactClassification", "<u2"), ("ContactSubNumber", "u1"),
    ("ContactType", "u1"), ("NumSamples", "<u4"), ("MillivoltScale", "<u2"), ("ContactTimeOffTrack", _F4),
    ("ContactCloseNumber", "u1"), ("Reserved2", "u1"), ("FixedVSOP", _F4), ("Weight", "<i2"),
    ("ReservedSpace", "u1", 4)])

assert (_CHAN_INFO.itemsize, _FILE_HEADER.itemsize, _PING_HEADER.itemsize, _CHAN_HEADER.itemsize) == \
    (128, 1024, 256, 64)

PORT_CHANNEL, STARBOARD_CHANNEL = 1, 2  # XTF TypeOfChannel
CORRECTION_SLANT_RANGE = 1  # CHANINFO CorrectionFlags: "1 = sonar imagery stored as slant-range" (2: ground range)
PROCESSING_TVG = 4  # XTFPINGCHANHEADER ProcessingFlags: "4 = TVG; 8 = BAC&GAC; 16 = filter"
SAMPLE_FORMAT_FLOAT32 = 5
SAMPLE_FORMAT = {np.dtype(np.uint16): 3, np.dtype(np.uint8): 8}  # XTF word, byte
KNOT_M_S = 1852.0 / 3600.0
NAV_UNITS_METRES, NAV_UNITS_LATLON = 0, 3  # XTF file header NavUnits


def sample_scale(record, scale="auto") -> float:
    """The factor applied to the intensities written as XTF samples (see the module docstring)."""
    if scale == "auto":
        both = np.concatenate([np.ravel(record.port), np.ravel(record.starboard)])
        pos = both[both > 0]
        if not pos.size:
            return 1.0
        ref = float(np.percentile(pos, 99.5))
        return float(10.0 ** (2 - math.floor(math.log10(ref))))
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0 < scale < math.inf:
        raise ConfigError(f"to_xtf: scale must be 'auto' or a number > 0, got {scale!r}")
    return float(scale)


def speed_m_s(trajectory) -> np.ndarray:
    """(n,) speed of each ping, m/s: its velocity's norm when the trajectory has one, else the distance to its
    neighbours over the time between them."""
    if trajectory.velocity_m_s is not None:
        return np.linalg.norm(trajectory.velocity_m_s, axis=1)
    p, t = trajectory.positions_m, trajectory.times_s
    if len(t) < 2:
        return np.zeros(len(t))
    v = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)
    return np.concatenate([v[:1], 0.5 * (v[1:] + v[:-1]), v[-1:]])


def _file_header(record, factor: float, ints, file_name: str = "", n_s: int | None = None) -> np.ndarray:
    from .._version import __version__

    h = np.zeros((), dtype=_FILE_HEADER)
    h["FileFormat"], h["SystemType"] = 0x7B, 1
    h["RecordingProgramName"] = b"sonar_em"
    h["RecordingProgramVersion"] = __version__.encode()[:8]
    h["SonarName"] = b"sonar_embree"
    h["NoteString"] = (f"simulated side-scan, unit-source intensity x {factor:.6g}" if ints is None else
                       f"simulated side-scan, {record.sonar.receiver.adc_bits}-bit ADC codes").encode()[:64]
    h["NavUnits"] = NAV_UNITS_LATLON if geographic(record) is not None else NAV_UNITS_METRES
    h["NumberOfSonarChannels"] = 2
    s = record.sonar
    h["ThisFileName"] = file_name.encode()[:64]
    lam = record.acquisition.wavelength_m
    along, across = (beamwidth_deg(size, lam) for size in (s.length_m, s.height_m))   # one-way −3 dB
    for i, (kind, name) in enumerate(((PORT_CHANNEL, b"port"), (STARBOARD_CHANNEL, b"starboard"))):
        c = h["ChanInfo"][i]
        c["TypeOfChannel"], c["SubChannelNumber"] = kind, i
        c["CorrectionFlags"], c["UniPolar"] = CORRECTION_SLANT_RANGE, 1     # slant range; intensities are ≥ 0
        c["BytesPerSample"] = 4 if ints is None else ints.dtype.itemsize
        c["Reserved"] = record.port.shape[1] if n_s is None else n_s  # legacy samples-per-channel field
        c["ChannelName"], c["VoltScale"], c["Frequency"] = name, 1.0, s.frequency_hz / 1e3
        c["HorizBeamAngle"], c["TiltAngle"], c["BeamWidth"] = along, s.tilt_deg, across
        c["BeamsPerArray"] = 1                                           # one beam per side, as devices write
        c["SampleFormat"] = SAMPLE_FORMAT_FLOAT32 if ints is None else SAMPLE_FORMAT[ints.dtype]
        if ints is not None:
            c["VoltScale"] = record.sonar.receiver.full_scale_v
    for i in range(2, 6):
        h["ChanInfo"][i]["Reserved"] = 1024
    return h


def _start(record, start) -> dt.datetime:
    if start is None:
        start = record.attrs.get("start_time")
    try:
        return dt.datetime.fromisoformat(iso_utc(start))
    except ConfigError as exc:
        raise ConfigError(f"to_xtf: {exc}") from None


def _ping_times(h, start: dt.datetime, times_s, fix_times_s) -> None:
    for i, (ts, fs) in enumerate(zip(times_s, fix_times_s)):
        when, fix = start + dt.timedelta(seconds=float(ts)), start + dt.timedelta(seconds=float(fs))
        h[i]["Year"], h[i]["Month"], h[i]["Day"] = when.year, when.month, when.day
        h[i]["Hour"], h[i]["Minute"], h[i]["Second"] = when.hour, when.minute, when.second
        h[i]["HSeconds"] = when.microsecond // 10000
        h[i]["FixTimeHour"], h[i]["FixTimeMinute"], h[i]["FixTimeSecond"] = fix.hour, fix.minute, fix.second
        h[i]["FixTimeHsecond"] = fix.microsecond // 10000                  # the last navigation fix's time
        h[i]["JulianDay"] = when.timetuple().tm_yday
        h[i]["NavFixMilliseconds"] = int(round(float(ts) * 1e3)) % 2**32


def to_xtf(record, path, start: dt.datetime | str | None = None, *, scale="auto",
           surface_z_m: float | None = None, samples: bool = True, samples_per_channel: int | None = None,
           decimation: str = "max") -> None:
    """Write ``record`` as an XTF file (atomic); conventions in this module's docstring.

    Parameters
    ----------
    record : Record
    path : str or PathLike
    start : datetime or str, optional
        Time of ping time 0 (naive: UTC); default the record's ``attrs["start_time"]``
        (the time it was simulated), else now.
    scale : "auto" or float
        Factor on the intensities written as floats (see :func:`sample_scale`).
    surface_z_m : float, optional
        World height of the sea surface, m, for SensorDepth = surface_z_m − z; every
        pose must lie below it. Default: no surface known, depth written as 0.
    samples : bool
        Write the device's integer samples when the record has them (default); False:
        the float intensities.
    samples_per_channel : int, optional
        Decimate each side to this many samples as a device does (the largest of each run, :func:`decimate`;
        a preset's :attr:`~sonar_embree.instrument.devices.Device.samples_per_channel`); default every sample.
    decimation : {"max", "mean"}
        How: each run's largest sample or its mean (:func:`decimate`), written as the channels' DownsampleMethod.
    """
    header, packets = xtf_bytes(record, start, scale=scale, surface_z_m=surface_z_m, samples=samples,
                                file_name=os.path.basename(os.fspath(path)), samples_per_channel=samples_per_channel,
                                decimation=decimation)

    def write(tmp):
        with open(tmp, "wb") as fh:
            fh.write(header)
            fh.write(packets)

    atomic_write(path, write, suffix=".xtf")


def xtf_bytes(record, start=None, *, scale="auto", surface_z_m=None, samples: bool = True, first_ping: int = 0,
              file_name: str = "", samples_per_channel: int | None = None, decimation: str = "max", line=None):
    """(file header, sonar packets) of ``record`` as XTF bytes (see :func:`to_xtf`); the packets' ping numbers
    start at ``first_ping`` (a block of a longer line, :mod:`sonar_embree.survey.stream`; ``line``, the whole
    line's :class:`~sonar_embree.Trajectory`, gives the positions of fixes taken before the block, default the
    record's own); ``file_name`` goes into the header's ThisFileName; ``samples_per_channel``: decimate each side to
    that many samples by ``decimation`` (:func:`decimate`)."""
    if tuple(record.channels) != ("port", "starboard"):
        names = ", ".join(record.channels[:3]) + (f", … ({len(record.channels)} channels)"
                                                   if len(record.channels) > 3 else "")
        raise ConfigError(f"to_xtf: XTF holds side-scan records (port and starboard); this record's channels are "
                          f"{names}")
    when = _start(record, start)
    check_bool("to_xtf", "samples", samples)
    ints = record.samples if samples and record.samples is not None else None
    factor = sample_scale(record, scale) if ints is None else 1.0
    t = record.trajectory
    sea = record.environment.surface
    surface_z_m = sea.z_m if surface_z_m is None and sea is not None else surface_z_m   # depth below its surface
    if surface_z_m is not None:
        if isinstance(surface_z_m, bool) or not isinstance(surface_z_m, (int, float)) or not math.isfinite(surface_z_m):
            raise ConfigError(f"to_xtf: surface_z_m must be a number (m), got {surface_z_m!r}")
        if np.any(t.positions_m[:, 2] > surface_z_m):
            raise ConfigError(f"to_xtf: the sonar rises to z = {t.positions_m[:, 2].max():.2f} m, above the sea "
                              f"surface at surface_z_m = {surface_z_m} m")
    sides = (record.port * factor, record.starboard * factor) if ints is None else (ints[:, 0], ints[:, 1])
    if samples_per_channel is not None:
        sides = tuple(decimate(s, samples_per_channel, decimation) for s in sides)
    fixes = held_fixes(record.trajectory if line is None else line, first_ping if line is not None else 0,
                       record.n_pings)
    packet = _packets(record, when, surface_z_m, ints, sides[0].shape[1], fixes)
    if samples_per_channel is not None and sides[0].shape[1] < record.data.shape[2]:
        for side in ("port_head", "stbd_head"):
            packet[side]["DownsampleMethod"] = DOWNSAMPLE_METHODS[decimation]
    packet["head"]["PingNumber"] += first_ping
    packet["port"], packet["stbd"] = sides[0][:, ::-1], sides[1]
    return _file_header(record, factor, ints, file_name, sides[0].shape[1]).tobytes(), packet.tobytes()


def decimate(x, n: int, how: str = "max") -> np.ndarray:
    """(pings, ≤ n) one value per each of ``n`` nearly equal runs of the samples of ``x`` (pings, samples): the
    run's largest (``how="max"``, XTF DownsampleMethod 2) or its mean (``"mean"``), as a device decimates to its
    stated samples per side (``x`` as is when it has no more than ``n``). Integer codes keep their dtype (a mean
    rounded to the nearest code)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ConfigError(f"to_xtf: samples_per_channel must be an integer >= 1, got {n!r}")
    if how not in DOWNSAMPLE_METHODS:
        raise ConfigError(f"to_xtf: decimation must be one of {sorted(DOWNSAMPLE_METHODS)}, got {how!r}")
    if x.shape[1] <= n:
        return x
    edges = np.linspace(0, x.shape[1], n + 1).astype(np.int64)
    if how == "max":
        return np.maximum.reduceat(x, edges[:-1], axis=1)
    mean = np.add.reduceat(x.astype(np.float64), edges[:-1], axis=1) / np.diff(edges)
    return np.rint(mean).astype(x.dtype) if np.issubdtype(x.dtype, np.integer) else mean.astype(x.dtype)


#: A record attribute: (latitude, longitude) in degrees of the local frame's origin, for a record without a CRS
#: (a scene in local metres, the demo's): its x and y are then metres east and north of that point in its UTM zone.
GEO_ORIGIN_ATTR = "geo_origin_deg"


def geographic(record):
    """(CRS, (east, north) offset in m) that place the record's positions on the Earth, or None: the trajectory's
    CRS, else the UTM zone of ``attrs[GEO_ORIGIN_ATTR]`` with the local origin at that point."""
    if record.trajectory.crs is not None:
        return record.trajectory.crs, (0.0, 0.0)
    origin = record.attrs.get(GEO_ORIGIN_ATTR)
    if origin is None:
        return None
    from .geo import from_lonlat, utm_crs

    try:
        lat, lon = (float(v) for v in origin)
    except (TypeError, ValueError):
        raise ConfigError(f"to_xtf: attrs[{GEO_ORIGIN_ATTR!r}] must be (latitude, longitude) in degrees, "
                          f"got {origin!r}") from None
    if not (abs(lat) <= 84.0 and abs(lon) <= 180.0):
        raise ConfigError(f"to_xtf: attrs[{GEO_ORIGIN_ATTR!r}] = {origin!r} is not (latitude, longitude) in degrees "
                          "within the UTM zones")
    crs = utm_crs(lon, lat)
    e0, n0 = from_lonlat(crs, lon, lat)
    return crs, (float(e0), float(n0))


def held_fixes(trajectory, first: int = 0, n: int | None = None) -> dict:
    """The navigation a device logs for pings ``first`` … ``first + n`` of ``trajectory``: ``times_s`` (n,) of
    each ping's last fix (:attr:`~sonar_embree.Trajectory.fix_times_s`, else the ping's own time), and
    ``sensor_m`` and ``ship_m`` (n, 3): where the sonar and the ship were at that time (the trajectory interpolated
    there, :meth:`~sonar_embree.Trajectory.at_times`), held until the next fix."""
    t = trajectory
    span = slice(first, len(t) if n is None else first + n)
    ship = t.positions_m if t.ship_positions_m is None else t.ship_positions_m
    if t.fix_times_s is None:
        return dict(times_s=t.times_s[span], sensor_m=t.positions_m[span], ship_m=ship[span])
    fix, inverse = np.unique(t.fix_times_s[span], return_inverse=True)
    at = t.at_times(np.clip(fix, t.times_s[0], t.times_s[-1]))
    at_ship = at.positions_m if at.ship_positions_m is None else at.ship_positions_m
    return dict(times_s=t.fix_times_s[span], sensor_m=at.positions_m[inverse], ship_m=at_ship[inverse])


def _navigation(h, record, surface_z_m, fixes: dict) -> None:
    """The ping headers' navigation: Sensor and Ship positions of each ping's last fix (``fixes``,
    :func:`held_fixes`; lat/lon with a CRS or a geographic origin, :func:`geographic`), speeds, depth, altitude,
    attitude, and a towed sonar's CableOut (m, a taut cable)."""
    t, geo = record.trajectory, geographic(record)
    ship = fixes["ship_m"]                                                   # towed: the ship ahead
    for prefix, where in (("Sensor", fixes["sensor_m"]), ("Ship", ship)):
        x, y = where[:, 0], where[:, 1]
        if geo is not None:
            x, y = to_lonlat(geo[0], x + geo[1][0], y + geo[1][1])
        h[f"{prefix}Xcoordinate"], h[f"{prefix}Ycoordinate"] = x, y
        h[f"{prefix}Speed"] = speed_m_s(t) / KNOT_M_S
    if t.ship_positions_m is not None:                 # the sensor is written laid back already: Layback stays 0
        h["CableOut"] = np.clip(np.round(np.linalg.norm(ship - fixes["sensor_m"], axis=1)), 0, 65535)
    if t.crs is not None:
        surface_z_m = 0.0 if surface_z_m is None and np.all(t.positions_m[:, 2] <= 0.0) else surface_z_m
    h["SensorDepth"] = 0.0 if surface_z_m is None else surface_z_m - t.positions_m[:, 2]
    h["SensorPrimaryAltitude"] = np.nan_to_num(record.altitude_m, nan=0.0)
    heading = t.heading_deg if geo is None else true_heading_deg(
        geo[0], t.positions_m[:, 0] + geo[1][0], t.positions_m[:, 1] + geo[1][1], t.heading_deg)
    h["SensorHeading"], h["SensorPitch"], h["SensorRoll"] = heading, t.pitch_deg, t.roll_deg
    h["ShipGyro"] = heading


def _packets(record, when, surface_z_m, ints, n_s: int, fixes: dict) -> np.ndarray:
    """One sonar packet per ping of ``n_s`` samples per side with its headers filled in, the navigation of
    ``fixes`` (:func:`held_fixes`); the samples left to the caller (the record's time span in TimeDuration
    whatever ``n_s``)."""
    t, s = record.trajectory, record.sonar
    n_p = record.port.shape[0]
    kind = "<f4" if ints is None else ints.dtype.newbyteorder("<")
    fields = [("head", _PING_HEADER), ("port_head", _CHAN_HEADER), ("port", kind, (n_s,)), ("stbd_head", _CHAN_HEADER),
              ("stbd", kind, (n_s,))]
    size = sum(np.dtype([f]).itemsize for f in fields)
    if size % PACKET_ALIGN:                                          # zeros to a multiple of 64 bytes, as Isis pads
        fields.append(("pad", "u1", (PACKET_ALIGN - size % PACKET_ALIGN,)))
    packet = np.zeros(n_p, dtype=np.dtype(fields))
    h = packet["head"]
    h["MagicNumber"], h["HeaderType"], h["NumChansToFollow"] = 0xFACE, 0, 2
    h["NumBytesThisRecord"] = packet.dtype.itemsize
    _ping_times(h, when, t.times_s, fixes["times_s"])
    h["PingNumber"] = np.arange(n_p)                                # EventNumber stays 0: no event marked
    h["SoundVelocity"] = 0.5 * record.environment.sound_speed_m_s
    _navigation(h, record, surface_z_m, fixes)
    codes = {} if ints is None else s.receiver.header_codes()
    tvg = ints is not None and codes.get("GainCode", 0) > 0             # the codes carry the receiver's TVG
    for side, number in (("port_head", 0), ("stbd_head", 1)):
        c = packet[side]
        c["ChannelNumber"], c["SlantRange"] = number, s.max_range_m
        c["SecondsPerPing"] = s.max_range_m / h["SoundVelocity"]        # the spec's SlantRange/750: 2R/c
        c["TimeDuration"] = c["SecondsPerPing"]                           # as devices write it: 2R/c
        c["ProcessingFlags"] = PROCESSING_TVG if tvg else 0
        c["Frequency"] = min(int(round(s.frequency_hz / 1e3)), 65535)
        c["NumSamples"] = n_s
        for name, value in codes.items():
            c[name] = value
    return packet


#: Sonar packets are padded with zeros to a multiple of this many bytes (Isis and the devices' own XTF do so).
PACKET_ALIGN = 64

#: XTF channel headers' DownsampleMethod by decimation (the spec's 2 = MAX; a mean has no code of its own: 0).
DOWNSAMPLE_METHODS = {"max": 2, "mean": 0}

#: XTF packets start with this magic number (the spec's 0xFACE).
MAGIC = 0xFACE


def check_packets(path: str) -> int:
    """Walk an XTF file's packets by their ``NumBytesThisRecord`` and return how many there are; a packet that
    runs past the end of the file (a file cut short, a corrupt length such as 0xFFFFFFFF), one that does not
    start with the magic number, or a length too short for a packet header, is refused naming its byte offset."""
    size = os.path.getsize(path)
    with open(path, "rb") as fh:
        head = np.frombuffer(fh.read(_FILE_HEADER.itemsize), dtype=_FILE_HEADER, count=1)[0] \
            if size >= _FILE_HEADER.itemsize else None
        if head is None:
            raise ConfigError(f"{path}: shorter ({size} bytes) than an XTF file header (1024 bytes); truncated?")
        n_chan = int(head["NumberOfSonarChannels"]) + int(head["NumberOfBathymetryChannels"])
        pos = 1024 + 1024 * max(0, -(-(n_chan - 6) // 8))            # more than 6 channels: CHANINFO blocks follow
        count = 0
        while pos < size:
            fh.seek(pos)
            raw = fh.read(14)
            magic = int.from_bytes(raw[0:2], "little")
            n_bytes = int.from_bytes(raw[10:14], "little") if len(raw) == 14 else 0
            if len(raw) < 14 or magic != MAGIC:
                raise ConfigError(f"{path}: no XTF packet at byte {pos} (magic number {magic:#06x}, not 0xface); "
                                  "the file is corrupt or truncated")
            if n_bytes < 14 or pos + n_bytes > size:
                raise ConfigError(f"{path}: packet {count} at byte {pos} claims {n_bytes} bytes, but "
                                  f"{size - pos} remain; the file is truncated or corrupt")
            pos += n_bytes
            count += 1
    return count


def _times(pings) -> list:
    """UTC datetimes of the pings: date and time (hundredths of a second), refined by NavFixMilliseconds where
    the hundredths are too coarse to order the pings (over 100 pings/s) and the milliseconds agree with them."""
    coarse = [dt.datetime(p.Year, p.Month, p.Day, p.Hour, p.Minute, p.Second, 10000 * p.HSeconds,
                          tzinfo=dt.timezone.utc) for p in pings]
    if len(coarse) < 2 or all(b > a for a, b in zip(coarse, coarse[1:])):
        return coarse
    ms = np.array([int(p.NavFixMilliseconds) for p in pings], dtype=np.int64)
    step = np.diff(ms) % 2**32                                     # milliseconds wrap at 2³²
    fine = np.concatenate(([0], np.cumsum(step))) / 1e3
    lag = np.array([(c - coarse[0]).total_seconds() for c in coarse])
    if np.all(step > 0) and np.all(step < 2**31) and np.all(np.abs(fine - lag) <= 0.0101):
        return [coarse[0] + dt.timedelta(seconds=float(t)) for t in fine]
    return coarse


def _fix_times(pings, times: list) -> list | None:
    """UTC datetimes of each ping's navigation fix from its FixTime (hour, minute, second, hundredths) on the
    ping's date (the day before where the fix would come over 12 h after its ping: a fix before midnight), or None
    where every FixTime is blank (zero) or impossible."""
    if all(p.FixTimeHour == p.FixTimeMinute == p.FixTimeSecond == p.FixTimeHsecond == 0 for p in pings):
        return None
    out = []
    for p, when in zip(pings, times):
        try:
            fix = when.replace(hour=p.FixTimeHour, minute=p.FixTimeMinute, second=p.FixTimeSecond,
                               microsecond=10000 * p.FixTimeHsecond)
        except ValueError:
            return None
        out.append(fix - dt.timedelta(days=1) if (fix - when).total_seconds() > 43200 else fix)
    return out


def continuous_track(times_s, x, y, fix_s=None):
    """(x, y) (n,) at each ping's time, rebuilt from navigation held between fixes as devices log it (the same
    position repeated until the next fix), as processing packages rebuild it.

    The fixes are the pings where the logged position changes (a device that stamps every ping with its own
    FixTime but repeats the position still holds it); each is placed at its fix time (``fix_s``, s on the pings'
    clock; where missing or not increasing over the fixes, the time of its first ping) and the positions are
    interpolated linearly between fixes, extrapolated along the first and last legs. Navigation where every ping is
    its own fix comes back as it is.

    Parameters
    ----------
    times_s : (n,) float
        Ping times, s.
    x, y : (n,) float
        Logged positions (projected, m).
    fix_s : (n,) float, optional
        Each ping's fix time, s, on the clock of ``times_s``.
    """
    times_s, x, y = (np.asarray(a, dtype=np.float64) for a in (times_s, x, y))
    new = np.ones(x.size, bool)
    new[1:] = (x[1:] != x[:-1]) | (y[1:] != y[:-1])
    if new.all() or new.sum() < 2:
        return x, y
    at = times_s[new] if fix_s is None else np.asarray(fix_s, dtype=np.float64)[new]
    if np.any(np.diff(at) <= 0.0):
        at = times_s[new]
    out = []
    for v in (x[new], y[new]):
        lo, hi = (v[1] - v[0]) / (at[1] - at[0]), (v[-1] - v[-2]) / (at[-1] - at[-2])
        inside = np.interp(times_s, at, v)
        out.append(np.where(times_s < at[0], v[0] + lo * (times_s - at[0]),
                            np.where(times_s > at[-1], v[-1] + hi * (times_s - at[-1]), inside)))
    return out[0], out[1]


def _sonar_pings(path: str, what: str):
    """(file header, sonar pings, one header per ping) of the XTF file ``path`` read by pyxtf, after checking its
    packets; a missing, truncated or unreadable file, or one without sonar pings, is a one-line error."""
    import pyxtf

    if not os.path.isfile(path):
        raise ConfigError(f"{path}: no such XTF file")
    check_packets(path)
    try:
        header, packets = pyxtf.xtf_read(path, types=[pyxtf.XTFHeaderType.sonar])
    except (OSError, ValueError, RuntimeError, IndexError, KeyError, TypeError) as exc:
        why = ("its header's channel count does not match its pings' channels" if isinstance(exc, IndexError)
               else str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        raise ConfigError(f"{path}: cannot read XTF {what} ({why})") from None
    pings = [p[0] if isinstance(p, list) else p for p in packets.get(pyxtf.XTFHeaderType.sonar, [])]
    if not pings:                                               # one header per ping (pyxtf: per channel)
        raise ConfigError(f"{path}: the XTF file holds no sonar pings")
    return header, pings


def read_navigation(path) -> dict:
    """The navigation and attitude of every sonar ping of an XTF file, read by pyxtf.

    Returns
    -------
    dict
        ``nav_units`` (the file header's NavUnits: 3 latitude/longitude, else metres), ``x`` and ``y`` (n,)
        (longitude and latitude in degrees for NavUnits 3, else easting and northing in m), ``depth_m``,
        ``heading_deg``, ``pitch_deg``, ``roll_deg`` and ``speed_m_s`` (n,) from the ping headers' Sensor
        fields, and ``times`` (n,) UTC datetimes from their date and time (hundredths of seconds; refined by
        NavFixMilliseconds where pings come faster than 100 per second), and ``fix_times`` (n,) UTC datetimes of
        each ping's navigation fix (FixTime; None where the file leaves it blank). A truncated or corrupt file (a
        packet running past its end) is refused, never read in part.
    """
    path = str(path)
    header, pings = _sonar_pings(path, "navigation")

    def field(name):
        return np.array([float(getattr(p, name)) for p in pings])

    try:
        times = _times(pings)
        fixes = _fix_times(pings, times)
    except ValueError as exc:
        raise ConfigError(f"{path}: a ping has an invalid date or time ({exc})") from None
    return dict(nav_units=int(header.NavUnits), x=field("SensorXcoordinate"), y=field("SensorYcoordinate"),
                depth_m=field("SensorDepth"), heading_deg=field("SensorHeading"), pitch_deg=field("SensorPitch"),
                roll_deg=field("SensorRoll"), speed_m_s=field("SensorSpeed") * KNOT_M_S, times=times,
                fix_times=fixes)


def read_sonar(path) -> dict:
    """The settings and samples of an XTF file's side-scan pings, as a replay needs them (pyxtf reads it).

    Returns
    -------
    dict
        ``frequency_hz``, ``slant_range_m``, ``samples_per_channel``, ``sample_rate_hz`` (NumSamples/TimeDuration,
        the rate of what is stored), ``sound_speed_m_s`` (2·SoundVelocity), ``bytes_per_sample``, ``integer``
        (codes, not floats), ``tvg`` (ProcessingFlags' TVG bit), ``gain_code`` (a TVG's k, 0 if none),
        ``initial_gain_db`` (InitialGainCode), ``altitude_m`` (n,) and ``data`` (n, 2, samples) float64 with port
        turned nadir first (the stored values, not converted). A file whose pings differ in range, frequency or
        samples per channel is refused (a replay needs one layout), as are truncated files.
    """
    path = str(path)
    header, pings = _sonar_pings(path, "sonar pings")
    layouts = {(c.SlantRange, c.Frequency, c.NumSamples) for p in pings for c in p.ping_chan_headers[:2]}
    if len(layouts) != 1 or len(pings[0].data) < 2:
        raise ConfigError(f"{path}: its pings change range, frequency or samples per channel ({len(layouts)} "
                          "layouts) or hold fewer than two channels; a replay needs one two-channel layout")
    c, info = pings[0].ping_chan_headers[0], header.ChanInfo[0]
    if not (float(c.TimeDuration) > 0.0 and math.isfinite(float(c.TimeDuration))):
        raise ConfigError(f"{path}: its pings' TimeDuration is {float(c.TimeDuration)!r} s; a replay needs the time "
                          "the samples span (> 0)")
    if not (float(pings[0].SoundVelocity) > 0.0 and float(c.SlantRange) > 0.0):
        raise ConfigError(f"{path}: SoundVelocity {float(pings[0].SoundVelocity)!r} or SlantRange "
                          f"{float(c.SlantRange)!r} is not positive; a replay needs both")
    data = np.stack([np.stack([np.asarray(p.data[0], dtype=np.float64)[::-1], np.asarray(p.data[1], np.float64)])
                     for p in pings])
    return dict(frequency_hz=1e3 * float(c.Frequency), slant_range_m=float(c.SlantRange),
                samples_per_channel=int(c.NumSamples), sample_rate_hz=float(c.NumSamples) / float(c.TimeDuration),
                sound_speed_m_s=2.0 * float(pings[0].SoundVelocity), bytes_per_sample=int(info.BytesPerSample),
                integer=int(info.SampleFormat) != SAMPLE_FORMAT_FLOAT32, tvg=bool(c.ProcessingFlags & PROCESSING_TVG),
                gain_code=int(c.GainCode), initial_gain_db=float(c.InitialGainCode),
                altitude_m=np.array([float(p.SensorPrimaryAltitude) for p in pings]), data=data)


def _sonar_samples_at(raw: bytes, pos: int, bytes_per_sample: int) -> list:
    """(offset, count) of the two channels' samples of the sonar packet at byte ``pos`` (ping header 256 bytes,
    then per channel a 64-byte channel header with NumSamples, then its samples)."""
    out, at = [], pos + _PING_HEADER.itemsize
    for _ in range(2):
        chan = np.frombuffer(raw, dtype=_CHAN_HEADER, count=1, offset=at)[0]
        out.append((at + _CHAN_HEADER.itemsize, int(chan["NumSamples"])))
        at += _CHAN_HEADER.itemsize + int(chan["NumSamples"]) * bytes_per_sample
    return out


def write_like(source, path, data, *, overwrite: bool = False) -> None:
    """A copy of the XTF file ``source`` at ``path`` (atomic) with its sonar pings' samples replaced by ``data``
    (pings, 2, samples; port nadir first, as :func:`read_sonar` returns it): every header and every other packet
    kept byte for byte; the values cast to the file's sample format (float32, or codes rounded and clipped to
    their range). A ``path`` that exists is refused unless ``overwrite``."""
    source, path = os.fspath(source), os.fspath(path)
    if os.path.exists(path) and not overwrite:
        raise ConfigError(f"{path}: exists; pass overwrite=True (--overwrite) to replace it")
    check_packets(source)
    raw = bytearray(open(source, "rb").read())
    head = np.frombuffer(raw, dtype=_FILE_HEADER, count=1)[0]
    info = head["ChanInfo"][0]
    width = int(info["BytesPerSample"])
    kind = {(5, 4): np.dtype("<f4"), (3, 2): np.dtype("<u2"), (8, 1): np.dtype("u1")}.get(
        (int(info["SampleFormat"]), width), np.dtype("<u2") if width == 2 else np.dtype("u1") if width == 1
        else np.dtype("<f4"))
    n_chan = int(head["NumberOfSonarChannels"]) + int(head["NumberOfBathymetryChannels"])
    pos, ping = 1024 + 1024 * max(0, -(-(n_chan - 6) // 8)), 0
    while pos < len(raw):
        if raw[pos + 2] == 0:                                                # a sonar packet
            if ping >= data.shape[0]:
                raise ConfigError(f"write_like: {source} has more sonar pings than the {data.shape[0]} given")
            for ch, (off, n) in enumerate(_sonar_samples_at(raw, pos, width)):
                v = np.asarray(data[ping, ch][:n], dtype=np.float64)
                v = v[::-1] if ch == 0 else v                                  # port stored from far range
                if kind.kind == "u":
                    v = np.clip(np.rint(v), 0, np.iinfo(kind).max)
                raw[off:off + n * width] = v.astype(kind).tobytes()
            ping += 1
        pos += int.from_bytes(raw[pos + 10:pos + 14], "little")

    def write(tmp):
        with open(tmp, "wb") as fh:
            fh.write(bytes(raw))
    atomic_write(path, write, suffix=".xtf")
