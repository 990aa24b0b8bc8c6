"""Frozen, validated parameter sets: :class:`Sonar`, :class:`Pulse`, :class:`Material`,
:class:`FanSettings`.

SI units inside; degrees and dB only in field names that say so (``tilt_deg``,
``backscatter_db``). Every class validates itself in ``__post_init__`` and raises
:class:`~sonar_embree.errors.ConfigError` (a ``ValueError``) naming the field and value.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

from .errors import ConfigError


def _check_number(owner: str, name: str, value, *, positive=False, nonneg=False,
                  lo=None, hi=None, integer=False) -> None:
    """Raise :class:`ConfigError` unless ``value`` is a finite number within bounds."""
    label = f"{owner}.{name}"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{label} must be a number, got {value!r}")
    if integer and int(value) != value:
        raise ConfigError(f"{label} must be an integer, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"{label} must be finite, got {value!r}")
    if positive and not value > 0:
        raise ConfigError(f"{label} must be > 0, got {value!r}")
    if nonneg and value < 0:
        raise ConfigError(f"{label} must be >= 0, got {value!r}")
    if lo is not None and value < lo:
        raise ConfigError(f"{label} must be >= {lo}, got {value!r}")
    if hi is not None and value > hi:
        raise ConfigError(f"{label} must be <= {hi}, got {value!r}")


def field_names(cls) -> tuple[str, ...]:
    """Names of the constructor fields of a config dataclass (for TOML key checking)."""
    return tuple(f.name for f in fields(cls) if f.init)


@dataclass(frozen=True)
class Sonar:
    """A side-scan sonar with one rectangular membrane per side (PHYSICS.md §1–2).

    Parameters
    ----------
    frequency_hz : float
        Carrier (centre) frequency f0 in Hz.
    length_m : float
        Membrane length lx along track, in m (sets the azimuth beamwidth).
    height_m : float
        Membrane height ly, in m (sets the elevation beamwidth).
    tilt_deg : float
        Depression δ of the boresight below horizontal, in degrees, in [0, 90].
    max_range_m : float
        Slant range of the last recorded sample, in m.
    sample_rate_hz : float
        Sample rate of the recorded (detected) time series, in Hz.
    sound_speed_m_s : float
        Speed of sound c in m/s, constant over the water column.
    absorption_db_per_m : float
        One-way absorption α in dB/m; the two-way loss is 2αR dB. The default
        0.096 dB/m is Francois–Garrison at 400 kHz, 10 °C, 35 ppt (PHYSICS.md §3).
    """

    frequency_hz: float = 400e3
    length_m: float = 0.19
    height_m: float = 0.0038
    tilt_deg: float = 20.0
    max_range_m: float = 50.0
    sample_rate_hz: float = 40e3
    sound_speed_m_s: float = 1500.0
    absorption_db_per_m: float = 0.096

    def __post_init__(self):
        for name in ("frequency_hz", "length_m", "height_m", "max_range_m",
                     "sample_rate_hz", "sound_speed_m_s"):
            _check_number("Sonar", name, getattr(self, name), positive=True)
        _check_number("Sonar", "tilt_deg", self.tilt_deg, lo=0.0, hi=90.0)
        _check_number("Sonar", "absorption_db_per_m", self.absorption_db_per_m, nonneg=True)
        if self.n_samples > 50_000_000:
            raise ConfigError(
                f"Sonar.max_range_m={self.max_range_m} with sample_rate_hz={self.sample_rate_hz} "
                f"gives {self.n_samples} samples per ping; reduce one of them")

    # --- derived quantities (SI) ---
    @property
    def wavelength_m(self) -> float:
        """Acoustic wavelength λ = c / f0 in m."""
        return self.sound_speed_m_s / self.frequency_hz

    @property
    def wavenumber_rad_m(self) -> float:
        """Wavenumber k = 2π f0 / c in rad/m."""
        return 2.0 * math.pi * self.frequency_hz / self.sound_speed_m_s

    @property
    def tilt_rad(self) -> float:
        """Boresight depression δ in rad."""
        return math.radians(self.tilt_deg)

    @property
    def n_samples(self) -> int:
        """Samples per ping and side: t = 0 … 2·max_range/c inclusive."""
        return int(math.floor(2.0 * self.max_range_m / self.sound_speed_m_s * self.sample_rate_hz)) + 1

    @property
    def range_bin_m(self) -> float:
        """Slant-range spacing of the samples, c / (2 fs), in m."""
        return self.sound_speed_m_s / (2.0 * self.sample_rate_hz)

    @classmethod
    def from_beamwidths(cls, azimuth_deg: float = 1.0, elevation_deg: float = 50.0, *,
                        rule: str = "exact", **kwargs) -> "Sonar":
        """Build a sonar whose membrane gives the requested one-way −3 dB beamwidths.

        Parameters
        ----------
        azimuth_deg, elevation_deg : float
            Full one-way −3 dB widths in degrees (along track, across track).
        rule : {"exact", "small-angle"}
            ``"exact"`` solves sinc(k·L/2·sin(θ/2)) = 1/√2 for L, so the membrane
            has exactly the requested −3 dB width. ``"small-angle"`` uses
            L = 0.886·λ/θ (θ in rad), the rule behind the paper's 190 mm × 3.8 mm
            for 1° × 50° (whose exact widths are 1.002° × 51.84°).
        **kwargs
            Any other :class:`Sonar` field (frequency_hz, sound_speed_m_s, …).
        """
        from .beam import membrane_size_for_beamwidth

        for name, val in (("azimuth_deg", azimuth_deg), ("elevation_deg", elevation_deg)):
            _check_number("Sonar.from_beamwidths", name, val, positive=True, hi=179.0)
        if rule not in ("exact", "small-angle"):
            raise ConfigError(f"Sonar.from_beamwidths rule must be 'exact' or 'small-angle', got {rule!r}")
        f0 = kwargs.get("frequency_hz", cls.frequency_hz)
        c = kwargs.get("sound_speed_m_s", cls.sound_speed_m_s)
        _check_number("Sonar", "frequency_hz", f0, positive=True)
        _check_number("Sonar", "sound_speed_m_s", c, positive=True)
        lam = c / f0
        lx = membrane_size_for_beamwidth(math.radians(azimuth_deg), lam, rule)
        ly = membrane_size_for_beamwidth(math.radians(elevation_deg), lam, rule)
        return cls(length_m=lx, height_m=ly, **kwargs)


@dataclass(frozen=True)
class Pulse:
    """A transmitted pulse: its kind, length and envelope taper (PHYSICS.md §5).

    Use the constructors: ``Pulse.cw(duration_s=100e-6, taper=0.0)``.

    Parameters
    ----------
    kind : {"cw"}
        Waveform kind. Frequency-modulated pulses arrive with the signal chain.
    duration_s : float
        Pulse length τ in s.
    taper : float
        Fraction of the pulse covered by the two flanks of the flat-top
        Blackman–Harris envelope, in [0, 1]: 0 is a rectangle, 1 a full
        4-term Blackman–Harris window.
    """

    kind: str = "cw"
    duration_s: float = 100e-6
    taper: float = 0.0

    KINDS = ("cw",)

    def __post_init__(self):
        if self.kind not in self.KINDS:
            raise ConfigError(f"Pulse.kind must be one of {self.KINDS}, got {self.kind!r}")
        _check_number("Pulse", "duration_s", self.duration_s, positive=True)
        if self.duration_s > 1.0:
            raise ConfigError(f"Pulse.duration_s must be <= 1 s, got {self.duration_s!r}")
        _check_number("Pulse", "taper", self.taper, lo=0.0, hi=1.0)

    @classmethod
    def cw(cls, duration_s: float = 100e-6, taper: float = 0.0) -> "Pulse":
        """A continuous-wave (single-frequency) pulse of length ``duration_s`` (s)."""
        return cls(kind="cw", duration_s=duration_s, taper=taper)

    def range_extent_m(self, sound_speed_m_s: float) -> float:
        """Slant-range extent cτ/2 of the uncompressed pulse, in m."""
        return sound_speed_m_s * self.duration_s / 2.0


@dataclass(frozen=True)
class Material:
    """Acoustic surface properties of one object.

    Parameters
    ----------
    backscatter_db : float
        Lambert backscatter strength μ in dB (σ = μ·cos²θi per unit area per
        steradian). −27 dB is Mackenzie's value for sand/mud.
    """

    backscatter_db: float = -27.0

    def __post_init__(self):
        _check_number("Material", "backscatter_db", self.backscatter_db, hi=30.0)
        if self.backscatter_db < -300:
            raise ConfigError(f"Material.backscatter_db must be >= -300 dB, got {self.backscatter_db!r}")

    @property
    def mu(self) -> float:
        """Linear Lambert coefficient μ = 10^(backscatter_db/10)."""
        return 10.0 ** (self.backscatter_db / 10.0)


@dataclass(frozen=True)
class FanSettings:
    """How densely each ping's fan of rays samples the beam (PHYSICS.md §7).

    Parameters
    ----------
    rays_per_bin : float
        Elevation rays per range bin (c/2fs) where the scene's slant range changes
        fastest with depression angle. With linear splatting, 1 gives < 0.5 dB on a
        flat floor; the default 2 is comfortably below that.
    azimuth_oversample : float
        Azimuth rays per λ/(2·lx) step of the along-track direction cosine. Any
        value ≥ 1 integrates the sinc⁴ main lobe exactly; 2 keeps small objects
        from falling between rays.
    azimuth_nulls : int
        Azimuth span in units of the first-null direction cosine λ/lx (2 covers the
        main lobe and the first side lobe on each side).
    max_step_deg : float
        Largest elevation step in degrees, wherever the scene is smooth or empty.
    probe_step_deg : float
        Elevation step of the coarse probe cast that finds where range changes fast.
    max_rays_per_side : int
        Hard cap on elevation rays per azimuth line and side (a guard, not a budget).
    """

    rays_per_bin: float = 2.0
    azimuth_oversample: float = 2.0
    azimuth_nulls: int = 2
    max_step_deg: float = 0.1
    probe_step_deg: float = 0.05
    max_rays_per_side: int = 200_000

    def __post_init__(self):
        _check_number("FanSettings", "rays_per_bin", self.rays_per_bin, positive=True, hi=1000)
        _check_number("FanSettings", "azimuth_oversample", self.azimuth_oversample, lo=1.0, hi=64)
        _check_number("FanSettings", "azimuth_nulls", self.azimuth_nulls, integer=True, lo=1, hi=50)
        _check_number("FanSettings", "max_step_deg", self.max_step_deg, positive=True, hi=10)
        _check_number("FanSettings", "probe_step_deg", self.probe_step_deg, positive=True, hi=5)
        _check_number("FanSettings", "max_rays_per_side", self.max_rays_per_side, integer=True,
                      lo=16, hi=10_000_000)
