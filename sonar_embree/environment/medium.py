"""The medium the sound travels in: sound speed, water properties, absorption and the sea surface.

With a sound-speed profile rays bend (docs/physics.md §12); :class:`Environment` is the medium's one home
(docs/physics.md §3, §13).
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError
from ..validation import check_number, field_names, from_table
from .ainslie_mccolm import ainslie_mccolm_db_per_m
from .francois_garrison import francois_garrison_db_per_m
from .noise import AmbientNoise
from .profile import SoundSpeedProfile
from .surface import SeaSurface

#: Absorption models by name: f(frequency_hz, temperature_c, salinity_ppt, depth_m, ph) → dB/m.
#: A new model is one module with such a function and one line here.
ABSORPTION_MODELS = {
    "francois-garrison": francois_garrison_db_per_m,
    "ainslie-mccolm": ainslie_mccolm_db_per_m,
}


@dataclass(frozen=True)
class Environment:
    """The water: constant sound speed, temperature, salinity, depth, pH and absorption.

    Parameters
    ----------
    sound_speed_m_s : float
        Speed of sound c in m/s: of the whole water column without a profile; with one, the speed
        the sonar assumes (its range axis 2R = c·t, wavelength and beam), best c at the sonar.
    temperature_c : float
        Water temperature, °C (absorption model).
    salinity_ppt : float
        Salinity, ppt (PSU) (absorption model).
    depth_m : float
        Water depth, m, for the pressure terms of the absorption model.
    ph : float
        Acidity, for the boric-acid term of the absorption model.
    absorption_model : str
        ``"francois-garrison"`` (default; Francois & Garrison 1982) or
        ``"ainslie-mccolm"`` (Ainslie & McColm 1998), see :data:`ABSORPTION_MODELS`.
    absorption_db_per_m : float or None
        One-way absorption α in dB/m (two-way loss 2αR dB), an explicit override of
        the model. ``None`` (default): the model at the sonar's frequency, 0.0961 dB/m
        for Francois–Garrison at 400 kHz, 10 °C, 35 ppt, pH 8.
    surface : SeaSurface or None
        The sea surface (multipath by the image method, docs/physics.md §13); None
        (default): an unbounded ocean, today's code path.
    sound_speed : SoundSpeedProfile or None
        c(depth) for curved rays (docs/physics.md §12); None (default) or a uniform profile
        (which must equal ``sound_speed_m_s``): straight rays, today's code path. Its depth 0 is
        its ``surface_z_m`` or the surface's ``z_m`` (which must agree). Under a flat surface the
        surface's paths follow curved rays too (§12b, a swell's §13c); the surface's own
        backscatter over a profile is refused.
    noise : AmbientNoise or None
        The sea's ambient noise (docs/physics.md §14), heard once the sonar has a source level
        (``Sonar.source_level_db``): default :class:`AmbientNoise` () (5 m/s wind, moderate
        shipping, thermal); None: a silent sea. A unit-source record never holds it.
    volume_backscatter_db : float or None
        Sv, the water column's volume backscattering strength, dB re 1 m⁻¹ (plankton, bubbles, suspended
        sediment: some −90 to −50 dB), in [−200, 0]: its reverberation fills the record between the transducer
        and the floor (docs/physics.md §14b; side-scan only). None (default): none.
    """

    sound_speed_m_s: float = 1500.0
    temperature_c: float = 10.0
    salinity_ppt: float = 35.0
    depth_m: float = 0.0
    ph: float = 8.0
    absorption_model: str = "francois-garrison"
    absorption_db_per_m: float | None = None
    surface: SeaSurface | None = None
    sound_speed: SoundSpeedProfile | None = None
    noise: AmbientNoise | None = AmbientNoise()
    volume_backscatter_db: float | None = None

    def __post_init__(self):
        check_number("Environment", "sound_speed_m_s", self.sound_speed_m_s, positive=True)
        check_number("Environment", "temperature_c", self.temperature_c, lo=-2.0, hi=40.0)
        check_number("Environment", "salinity_ppt", self.salinity_ppt, lo=0.0, hi=45.0)
        check_number("Environment", "depth_m", self.depth_m, lo=0.0, hi=12000.0)
        check_number("Environment", "ph", self.ph, lo=6.0, hi=9.5)
        if not isinstance(self.absorption_model, str) or self.absorption_model not in ABSORPTION_MODELS:
            raise ConfigError(f"Environment.absorption_model must be one of {', '.join(ABSORPTION_MODELS)}, "
                              f"got {self.absorption_model!r}")
        if self.absorption_db_per_m is not None:
            check_number("Environment", "absorption_db_per_m", self.absorption_db_per_m, nonneg=True, hi=100.0)
        if self.volume_backscatter_db is not None:
            check_number("Environment", "volume_backscatter_db", self.volume_backscatter_db, lo=-200.0, hi=0.0)
        if isinstance(self.surface, dict):  # from TOML ([environment] surface = {…}) or a record's metadata
            unknown = sorted(set(self.surface) - set(field_names(SeaSurface)))
            if unknown:
                raise ConfigError(f"Environment.surface: unknown key {unknown[0]!r}; one of "
                                  f"{', '.join(field_names(SeaSurface))}")
            object.__setattr__(self, "surface", SeaSurface(**self.surface))
        if self.surface is not None and not isinstance(self.surface, SeaSurface):
            raise ConfigError(f"Environment.surface must be a sonar_embree.SeaSurface or None, got {self.surface!r}")
        object.__setattr__(self, "sound_speed", _profile(self.sound_speed))
        object.__setattr__(self, "noise", _noise(self.noise))
        self._check_profile()

    def _check_profile(self):
        """A uniform profile must agree with sound_speed_m_s; a curved one needs its depth origin."""
        p = self.sound_speed
        if p is None:
            return
        if p.is_uniform:
            if abs(p.speed_m_s[0] - self.sound_speed_m_s) > 1e-9 * self.sound_speed_m_s:
                raise ConfigError(f"Environment: a uniform sound_speed profile at {p.speed_m_s[0]:g} m/s disagrees "
                                  f"with sound_speed_m_s={self.sound_speed_m_s:g}; give one of the two")
            return
        if p.surface_z_m is None and self.surface is None:
            raise ConfigError("Environment.sound_speed: the profile's depth 0 needs a height: give "
                              "SoundSpeedProfile(surface_z_m=…) or a surface")
        if self.surface is None:
            return
        if p.surface_z_m is not None and abs(p.surface_z_m - self.surface.z_m) > 1e-6:
            raise ConfigError(f"Environment: the profile's depth 0 (surface_z_m = {p.surface_z_m:g} m) and the sea "
                              f"surface (z_m = {self.surface.z_m:g} m) must be at the same height")
        if self.surface.backscatter is not None:
            raise ConfigError("Environment: the surface's own backscatter over a sound-speed profile is not modelled; "
                              "drop SeaSurface.backscatter or the profile")

    @property
    def refracts(self) -> bool:
        """True when rays bend (a profile that is not uniform)."""
        return self.sound_speed is not None and not self.sound_speed.is_uniform

    def profile_origin_z_m(self) -> float:
        """World z of the profile's depth 0, m (its own ``surface_z_m`` or the surface's)."""
        p = self.sound_speed
        return float(p.surface_z_m if p.surface_z_m is not None else self.surface.z_m)

    def alpha_db_per_m(self, frequency_hz: float) -> float:
        """One-way absorption at ``frequency_hz`` (Hz) in dB/m: the override or the model."""
        if self.absorption_db_per_m is not None:
            return float(self.absorption_db_per_m)
        return ABSORPTION_MODELS[self.absorption_model](frequency_hz, self.temperature_c, self.salinity_ppt,
                                                        self.depth_m, self.ph)


def _noise(value):
    """An AmbientNoise from itself, None/False (a silent sea), or a dict (TOML ``noise = {…}``, a record's metadata)."""
    if value is None or value is False or isinstance(value, AmbientNoise):
        return None if value is False else value
    if not isinstance(value, dict):
        raise ConfigError(f"Environment.noise must be a sonar_embree.AmbientNoise, None or false, got {value!r}")
    return from_table(AmbientNoise, value, "Environment.noise")


def _profile(value):
    """A SoundSpeedProfile from itself, None, or a dict (TOML ``sound_speed = {…}``, a record's metadata).

    The dict takes the profile's fields, or ``csv`` (a ``depth_m,speed_m_s`` file) with an optional
    ``surface_z_m``.
    """
    if value is None or isinstance(value, SoundSpeedProfile):
        return value
    if not isinstance(value, dict):
        raise ConfigError(f"Environment.sound_speed must be a sonar_embree.SoundSpeedProfile or None, got {value!r}")
    keys = field_names(SoundSpeedProfile) + ("csv",)
    unknown = sorted(set(value) - set(keys))
    if unknown:
        raise ConfigError(f"Environment.sound_speed: unknown key {unknown[0]!r}; one of {', '.join(keys)}")
    if "csv" in value:
        extra = sorted(set(value) - {"csv", "surface_z_m"})
        if extra:
            raise ConfigError(f"Environment.sound_speed: give 'csv' or {extra[0]!r}, not both")
        return SoundSpeedProfile.from_csv(value["csv"], value.get("surface_z_m"))
    return SoundSpeedProfile(**value)
