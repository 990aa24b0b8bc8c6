"""Device presets: common side-scan sonars from their public datasheets (docs/physics.md §14–15).

Each :class:`Device` holds what a manufacturer's datasheet states — carrier, one-way −3 dB beamwidths,
depression (tilt), range settings, pulse; :meth:`Sonar.preset <sonar_embree.Sonar.preset>` builds the sonar
whose membrane has exactly those beamwidths (:meth:`Sonar.from_beamwidths`, rule "exact") and
:meth:`Pulse.preset <sonar_embree.Pulse.preset>` its pulse. Datasheets rarely state a source level or the receiver's sampling: where a
field below is not from the cited document its ``assumed`` entry says so, and it is a representative value
for the class of device (source levels of 100 kHz–1 MHz side-scans lie between about 200 and 230 dB re
1 µPa at 1 m, Lurton 2010, §8.2).

The values were transcribed from the manufacturers' published datasheets named in ``source``; they
describe one configuration of each product line, and a user with the device's own calibration sheet
should override them (``Sonar.preset(name, source_level_db=…)``).
"""
from __future__ import annotations

import dataclasses
import math
import os
import tomllib
from dataclasses import dataclass

from ..errors import ConfigError
from .beam import sinc_root
from .receiver import Receiver


#: A device's time-varied gain, assumed (no datasheet found states one): 30·log10 R + 2αR, the law that levels a
#: pulse-limited seabed patch's echo (two-way spherical spreading, 40·log10 R, less the patch's growth along
#: track, 10·log10 R; docs/physics.md §19), with ``g0_db`` its gain at 1 m (dB; an operator's
#: setting, calibrated per line by the survey command).
DEVICE_TVG = dict(k=30, absorption=True, g0_db=20.0)


@dataclass(frozen=True)
class Device:
    """One side-scan sonar's datasheet values.

    Parameters
    ----------
    name : str
        Preset key.
    source : str
        The datasheet the values come from.
    platform : str
        "towfish" or "AUV".
    frequency_hz : float
        Carrier (centre) frequency, Hz.
    azimuth_deg, elevation_deg : float
        One-way −3 dB beamwidths along and across track, degrees.
    tilt_deg : float
        Depression of the beam axis below horizontal, degrees.
    ranges_m : tuple of float
        Range settings (slant range per side), m; the first is the preset's default. The sample rate is
        derived from the pulse (:meth:`Sonar.for_pulse`) unless given.
    pulse : tuple
        ("cw", duration_s) or ("lfm", duration_s, bandwidth_hz).
    source_level_db : float
        dB re 1 µPa at 1 m.
    assumed : tuple of str
        The fields not stated in ``source`` (representative values), or inferred from it (``note`` says how).
    ping_rates_hz : tuple of float
        The stated ping rate at each of ``ranges_m`` (0 where not stated); empty: none stated
        (:meth:`ping_rate_hz` then pings back to back).
    samples_per_channel : int or None
        Samples the device records per side and ping, when stated: its XTF is decimated to them (by the largest of
        each run; ``to_xtf(samples_per_channel=…)``, the survey command); the record keeps every sample.
    azimuth_two_way : bool
        ``azimuth_deg`` is the datasheet's two-way −3 dB width (converted to the one-way width by
        :attr:`azimuth_one_way_deg`).
    note : str
        How inferred fields were inferred.
    adc_bits : int
        Bits of the codes the device records (16 unless stated; ``"adc_bits"`` in ``assumed`` when not).
    full_scale_v : float
        The ADC's full scale, V (its XTF's VoltScale; 1 V assumed unless a record of the device shows it).
    """

    name: str
    source: str
    platform: str
    frequency_hz: float
    azimuth_deg: float
    elevation_deg: float
    tilt_deg: float
    ranges_m: tuple
    pulse: tuple
    source_level_db: float
    assumed: tuple = ()
    ping_rates_hz: tuple = ()
    samples_per_channel: int | None = None
    azimuth_two_way: bool = False
    note: str = ""
    adc_bits: int = 16
    full_scale_v: float = 1.0

    def receiver(self, gain: str = "tvg", *, g0_db: float = DEVICE_TVG["g0_db"], start_range_m: float = 0.0,
                 max_gain_db: float | None = None):
        """The device's receive chain (:class:`~sonar_embree.Receiver`) for a record of codes as it stores them:
        its ADC's bits (:attr:`adc_bits`), and what no datasheet found states, assumed (:data:`ASSUMED_RECEIVER`):
        a −190 dB re 1 V/µPa hydrophone; its full scale is :attr:`full_scale_v`; a band-pass as wide as its pulse's
        band (:attr:`band_hz`, assumed: a receiver matched to its pulse, so the noise it lets through is the pulse
        band's, not the whole sample band's; Lurton 2010, §3.4).

        ``gain="tvg"`` (default): what side-scan devices record, a time-varied gain G(R) = ``g0_db`` + 30·log10 R +
        2αR (:data:`DEVICE_TVG`) from ``start_range_m`` (near the first bottom return) up to ``max_gain_db``, so
        the water column before the first return stays dark; its level ``g0_db`` is an operator's setting (the
        survey command sets it per line so that the median seabed sits at a quarter of full scale,
        :func:`sonar_embree.runs.survey.line_receiver`). ``gain="agc"``: an AGC bringing the moving RMS to a
        quarter of full scale (every part of the record at one level, the water column included).
        ``Sonar.preset(name, receiver=device(name).receiver())``."""
        chain = dict(adc_bits=self.adc_bits, full_scale_v=self.full_scale_v, bandwidth_hz=self.band_hz,
                     **ASSUMED_RECEIVER)
        if gain == "agc":
            return Receiver(gain=dict(kind="agc", target=0.25), **chain)
        if gain != "tvg":
            raise ConfigError(f"Device.receiver: gain must be 'tvg' or 'agc', got {gain!r}")
        return Receiver(gain=dict(DEVICE_TVG, kind="tvg", g0_db=g0_db, start_range_m=start_range_m,
                                  max_gain_db=max_gain_db), **chain)

    @property
    def band_hz(self) -> float:
        """The pulse's band, Hz: an LFM's sweep, a CW pulse's 1/τ (the wider of the two)."""
        sweep = self.pulse[2] if self.pulse[0] == "lfm" else 0.0
        return max(float(sweep), 1.0 / float(self.pulse[1]))

    @property
    def azimuth_one_way_deg(self) -> float:
        """The one-way −3 dB along-track width, degrees: ``azimuth_deg``, or the one-way width of the membrane
        whose two-way −3 dB width it is (sinc(x₁) = 2^(−1/2), sinc(x₂) = 2^(−1/4): sin(θ₁/2) = sin(θ₂/2)·x₁/x₂)."""
        if not self.azimuth_two_way:
            return self.azimuth_deg

        s = math.sin(math.radians(0.5 * self.azimuth_deg)) * sinc_root(2 ** -0.5) / sinc_root(2 ** -0.25)
        return 2.0 * math.degrees(math.asin(s))

    def ping_rate_hz(self, range_m: float, sound_speed_m_s: float = 1500.0) -> float:
        """Pings per second at the range setting ``range_m``: the stated rate of that setting, else back to back
        (c/(2·R), the fastest a window of R allows)."""
        for r, rate in zip(self.ranges_m, self.ping_rates_hz):
            if abs(r - range_m) < 1e-9 and rate > 0:
                return float(rate)
        return sound_speed_m_s / (2.0 * float(range_m))


_JSF_NOTE = ("15-bit codes: EdgeTech's JSF stores the envelope as one (signed) short per sample (MB-System's JSF "
             "reader), codes 0 … 32767")
_MST_NOTE = ("as its XTF records it (a public Sea Scan HDS 600 kHz AUV record): 2-byte samples, codes up to 32767, 1024 "
             "samples per side decimated by MAX, VoltScale 5 V (MillivoltScale 5000), TVG applied by the device "
             "(ProcessingFlags 4); its native .MST format holds 6-bit codes in bytes (MB-System); the record's "
             "frequency differs, so these are inferred for the ARC Scout")
_CM2 = "C-MAX, CM2 Sidescan Sonar, Towfish Specification, Issue 7; CM2 user manual"
_CM2_NOTE = ("tilt and vertical width inferred from the stated vertical coverage (−10° through −90° each side); the "
             "manual's adjustable 10°/20° depression is not used; 53 µs is the stated pulse at 50 m, used at every "
             "range; "
             "the widths at 325 and 780 kHz give membranes of the stated 0.37 and 0.21 m, the 1.0° at 100 kHz one of "
             "0.55 m against the stated 0.37 m (the preset keeps the stated width)")
_YF = "Imagenex Technology, YellowFin 872 side scan sonar manual (rev. Feb 2011)"
#: The source levels assumed for the presets at 900 kHz and at 1.8 MHz, dB re 1 µPa at 1 m, within the 210–230 dB
#: that general references give for high-frequency sonars (no datasheet found states one). An inference from the
#: level budget (docs/physics.md §19): at these frequencies the thermal noise rules (−15 + 20·log10 f(kHz) dB re
#: 1 µPa²/Hz, 50 dB at 1.8 MHz) and absorption reaches 1 dB/m; with the 200–210 dB assumed before, a flat seabed
#: flown at a tenth of the first range sank into the noise halfway across that range, which a device sold with
#: that setting does not do. The lowest level of the range that keeps it heard there is taken.
HF_SOURCE_LEVEL_DB, VHF_SOURCE_LEVEL_DB = 220.0, 230.0

_YF_ASSUMED = ("ranges_m", "pulse", "source_level_db", "adc_bits")
_YF_NOTE = ("the manual gives no range settings (coverage up to 400 m in all), pulse or source level; its beamwidths "
            "are taken as one-way −3 dB widths")

#: The receive chain's values no datasheet found states (:meth:`Device.receiver`): a representative hydrophone
#: sensitivity (the full scale is the device's :attr:`Device.full_scale_v`, 1 V unless a record shows it).
ASSUMED_RECEIVER = dict(sensitivity_db=-190.0)

DEVICES = {d.name: d for d in (
    Device("klein-3000-100", "Klein Associates, System 3000 Digital Side Scan Sonar datasheet (100 kHz channel)",
           "towfish", 100e3, 1.0, 40.0, 10.0, (150.0, 300.0, 600.0), ("cw", 400e-6), 228.0,
           ("source_level_db", "adc_bits")),
    Device("klein-3000-500", "Klein Associates, System 3000 Digital Side Scan Sonar datasheet (500 kHz channel)",
           "towfish", 500e3, 0.2, 40.0, 10.0, (50.0, 100.0, 150.0), ("cw", 100e-6), 219.0,
           ("source_level_db", "adc_bits")),
    Device("edgetech-4125-400", "EdgeTech 4125 Side Scan Sonar System datasheet (400 kHz, Full Spectrum CHIRP)",
           "towfish", 400e3, 0.46, 50.0, 20.0, (75.0, 150.0), ("lfm", 2e-3, 32e3), 210.0,
           ("source_level_db", "pulse duration"), adc_bits=15, note=_JSF_NOTE),
    Device("edgetech-4125-900", "EdgeTech 4125 Side Scan Sonar System datasheet (900 kHz, Full Spectrum CHIRP)",
           "towfish", 900e3, 0.28, 50.0, 20.0, (50.0, 75.0), ("lfm", 1e-3, 50e3), HF_SOURCE_LEVEL_DB,
           ("source_level_db", "pulse duration"), adc_bits=15, note=_JSF_NOTE),
    Device("starfish-450f", "Tritech StarFish 450F Side Scan Sonar datasheet (450 kHz CHIRP)",
           "towfish", 450e3, 0.8, 60.0, 30.0, (50.0, 100.0), ("lfm", 1e-3, 50e3), 210.0,
           ("source_level_db", "pulse duration", "adc_bits")),
    Device("marine-sonic-arc-900", "Marine Sonic Technology, Sea Scan ARC Scout (AUV) side-scan datasheet, 900 kHz",
           "AUV", 900e3, 0.2, 50.0, 10.0, (30.0, 60.0), ("cw", 20e-6), HF_SOURCE_LEVEL_DB, ("source_level_db",),
           samples_per_channel=1024, adc_bits=15, full_scale_v=5.0, note=_MST_NOTE),
    Device("marine-sonic-arc-1800", "Marine Sonic Technology, Sea Scan ARC Scout (AUV) side-scan datasheet, 1.8 MHz",
           "AUV", 1.8e6, 0.1, 50.0, 10.0, (15.0, 30.0), ("cw", 10e-6), VHF_SOURCE_LEVEL_DB, ("source_level_db",),
           samples_per_channel=1024, adc_bits=15, full_scale_v=5.0, note=_MST_NOTE),
    # C-MAX CM2: "CM2 Sidescan Sonar, Towfish Specification, Issue 7" and the CM2 user manual. Its horizontal
    # widths are two-way −3 dB. Vertical coverage "−10° through −90°": a fan 80° wide centred 50° down.
    Device("cmax-cm2-100", _CM2, "towfish", 100e3, 1.0, 80.0, 50.0, (100.0, 500.0), ("cw", 53e-6), 217.0,
           ("tilt_deg", "elevation_deg", "pulse duration", "adc_bits"), (6.9, 1.46), None, True, _CM2_NOTE),
    Device("cmax-cm2-325", _CM2, "towfish", 325e3, 0.45, 80.0, 50.0, (25.0, 150.0), ("cw", 53e-6), 217.0,
           ("tilt_deg", "elevation_deg", "pulse duration", "adc_bits"), (13.5, 4.8), None, True, _CM2_NOTE),
    Device("cmax-cm2-780", _CM2, "towfish", 780e3, 0.32, 80.0, 50.0, (12.5, 37.5), ("cw", 53e-6), 217.0,
           ("tilt_deg", "elevation_deg", "pulse duration", "adc_bits"), (), None, True, _CM2_NOTE),
    # Imagenex YellowFin 872, manual rev. Feb 2011: beamwidths (horizontal × vertical), 20° down, 1000 points a side.
    Device("imagenex-872-260", _YF, "towfish", 260e3, 2.2, 75.0, 20.0, (100.0, 200.0), ("cw", 100e-6), 210.0,
           _YF_ASSUMED, (), 1000, False, _YF_NOTE),
    Device("imagenex-872-330", _YF, "towfish", 330e3, 1.8, 60.0, 20.0, (60.0, 120.0), ("cw", 100e-6), 210.0,
           _YF_ASSUMED, (), 1000, False, _YF_NOTE),
    Device("imagenex-872-800", _YF, "towfish", 800e3, 0.7, 30.0, 20.0, (20.0, 40.0), ("cw", 50e-6), 210.0,
           _YF_ASSUMED, (), 1000, False, _YF_NOTE),
)}


def device(name) -> Device:
    """The preset ``name``: a key of :data:`DEVICES`, or a device file (a path ending in ``.toml``,
    :func:`load_device`: e.g. what ``replay --fit`` writes); one-line error naming the known ones otherwise."""
    if isinstance(name, (str, os.PathLike)) and os.fspath(name).endswith(".toml"):
        return load_device(name)
    try:
        return DEVICES[name]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown device preset {name!r}; one of {', '.join(sorted(DEVICES))}, or a device "
                          "file (.toml)") from None


#: The fields a device file must give (the rest take :class:`Device`'s defaults).
REQUIRED_FIELDS = ("name", "source", "platform", "frequency_hz", "azimuth_deg", "elevation_deg", "tilt_deg",
                   "ranges_m", "pulse", "source_level_db")


def load_device(path) -> Device:
    """The :class:`Device` of a device file: a TOML ``[device]`` table of :class:`Device`'s fields (lists for its
    tuples; ``pulse = ["cw", 5e-05]`` or ``["lfm", duration_s, bandwidth_hz]``), as :func:`device_toml` writes it.
    One-line errors naming the file and the key."""
    source = os.fspath(path)
    try:
        with open(source, "rb") as fh:
            table = tomllib.load(fh)
    except OSError as exc:
        raise ConfigError(f"{source}: cannot read the device file ({exc.strerror or exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: invalid TOML ({exc})") from None
    d = table.get("device")
    if set(table) != {"device"} or not isinstance(d, dict):
        raise ConfigError(f"{source}: a device file holds one [device] table, got {sorted(table)}")
    fields = {f.name for f in dataclasses.fields(Device)}
    unknown, missing = sorted(set(d) - fields), [k for k in REQUIRED_FIELDS if k not in d]
    if unknown or missing:
        raise ConfigError(f"{source}: [device] " + (f"unknown key {unknown[0]!r}" if unknown else
                                                    f"needs {missing[0]!r}"))
    kw = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
    _check_device(source, kw)
    return Device(**kw)


def _check_device(source: str, kw: dict) -> None:
    """A device file's numbers: one line naming the file and the key of one that cannot be."""
    for key, lo, hi in (("frequency_hz", 1e3, 1e7), ("azimuth_deg", 0.0, 179.0), ("elevation_deg", 0.0, 179.0),
                        ("tilt_deg", -90.0, 90.0), ("source_level_db", 150.0, 250.0)):
        v = kw[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo < v <= hi if lo >= 0 else lo <= v <= hi):
            raise ConfigError(f"{source}: [device] {key} must be a number in {'[' if lo < 0 else '('}{lo:g}, {hi:g}], "
                              f"got {v!r}")
    if not kw["ranges_m"] or not all(isinstance(r, (int, float)) and r > 0 for r in kw["ranges_m"]):
        raise ConfigError(f"{source}: [device] ranges_m must be a list of ranges > 0 m, got {list(kw['ranges_m'])!r}")
    p = kw["pulse"]
    ok = (len(p) == 2 and p[0] == "cw") or (len(p) == 3 and p[0] == "lfm" and isinstance(p[2], (int, float))
                                            and p[2] > 0)
    if not ok or not isinstance(p[1], (int, float)) or not 0 < p[1] < 1:
        raise ConfigError(f"{source}: [device] pulse must be [\"cw\", duration_s] or [\"lfm\", duration_s, "
                          f"bandwidth_hz], got {list(p)!r}")


def device_toml(d: Device) -> str:
    """The device file of ``d`` (:func:`load_device` reads it back to an equal :class:`Device`)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        return "[" + ", ".join(value(x) for x in v) + "]"

    lines = ["[device]"] + [f"{f.name} = {value(getattr(d, f.name))}" for f in dataclasses.fields(Device)
                            if getattr(d, f.name) is not None]
    return "\n".join(lines) + "\n"


__all__ = ["DEVICES", "Device", "device", "device_toml", "load_device"]
