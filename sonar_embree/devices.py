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

from dataclasses import dataclass

from .errors import ConfigError


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
        The fields not stated in ``source`` (representative values).
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


DEVICES = {d.name: d for d in (
    Device("klein-3000-100", "Klein Associates, System 3000 Digital Side Scan Sonar datasheet (100 kHz channel)",
           "towfish", 100e3, 1.0, 40.0, 10.0, (150.0, 300.0, 600.0), ("cw", 400e-6), 228.0,
           ("source_level_db",)),
    Device("klein-3000-500", "Klein Associates, System 3000 Digital Side Scan Sonar datasheet (500 kHz channel)",
           "towfish", 500e3, 0.2, 40.0, 10.0, (50.0, 100.0, 150.0), ("cw", 100e-6), 219.0,
           ("source_level_db",)),
    Device("edgetech-4125-400", "EdgeTech 4125 Side Scan Sonar System datasheet (400 kHz, Full Spectrum CHIRP)",
           "towfish", 400e3, 0.46, 50.0, 20.0, (75.0, 150.0), ("lfm", 2e-3, 32e3), 210.0,
           ("source_level_db", "pulse duration")),
    Device("edgetech-4125-900", "EdgeTech 4125 Side Scan Sonar System datasheet (900 kHz, Full Spectrum CHIRP)",
           "towfish", 900e3, 0.28, 50.0, 20.0, (50.0, 75.0), ("lfm", 1e-3, 50e3), 210.0,
           ("source_level_db", "pulse duration")),
    Device("starfish-450f", "Tritech StarFish 450F Side Scan Sonar datasheet (450 kHz CHIRP)",
           "towfish", 450e3, 0.8, 60.0, 30.0, (50.0, 100.0), ("lfm", 1e-3, 50e3), 205.0,
           ("source_level_db", "pulse duration")),
    Device("marine-sonic-arc-900", "Marine Sonic Technology, Sea Scan ARC Scout (AUV) side-scan datasheet, 900 kHz",
           "AUV", 900e3, 0.2, 50.0, 10.0, (30.0, 60.0), ("cw", 20e-6), 205.0, ("source_level_db",)),
    Device("marine-sonic-arc-1800", "Marine Sonic Technology, Sea Scan ARC Scout (AUV) side-scan datasheet, 1.8 MHz",
           "AUV", 1.8e6, 0.1, 50.0, 10.0, (15.0, 30.0), ("cw", 10e-6), 200.0, ("source_level_db",)),
)}


def device(name: str) -> Device:
    """The preset ``name`` (a key of :data:`DEVICES`); one-line error naming the known ones otherwise."""
    try:
        return DEVICES[name]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown device preset {name!r}; one of {', '.join(sorted(DEVICES))}") from None


__all__ = ["DEVICES", "Device", "device"]
