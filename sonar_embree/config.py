"""Frozen, validated parameter sets: :class:`Sonar`, :class:`Pulse`, :class:`Material`,
:class:`FanSettings`.

SI units inside; degrees and dB only in field names that say so (``tilt_deg``,
``backscatter_db``). Every class validates itself in ``__post_init__`` and raises
:class:`~sonar_embree.errors.ConfigError` (a ``ValueError``) naming the field and value.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from .instrument.devices import device
from .instrument.beams import APERTURE_BEAMS, Beam, aperture_beam
from .environment import Environment
from .instrument.array import ReceiverArray, receive_array_of
from .instrument.receiver import Receiver, receiver_of
from .errors import ConfigError
from .laws import Lambert, Summable
from .laws.clutter import Clutter
from .laws.texture import KTexture
from .validation import check_number as _check_number, field_names  # noqa: F401 (field_names re-exported)
from .instrument.beam import beamwidth_deg, membrane_size_for_beamwidth


class Transducer:
    """What every sonar type shares: carrier, sample rate, range window, levels and receiver (the instrument alone).

    A sonar type's dataclass has the fields ``frequency_hz``, ``max_range_m`` and ``sample_rate_hz``; what depends
    on the water (c, λ, k, α, the beam at λ, the range bins) is resolved once per run by :class:`Acquisition`
    from the sonar and its medium (an :class:`~sonar_embree.environment.Environment`).
    """

    #: The record's channels, in order (a sonar type's own names).
    channels = ("port", "starboard")
    #: Whether the type looks sideways at a tilt ``tilt_deg`` (side-scan, MSIS, forward-looking); an echo sounder
    #: looks down. The set-up checks judge the tilt of such types only.
    tilted = True
    #: Whether its front end models the sea surface's paths (docs/physics.md §13) and curved rays (§12).
    models_surface = True
    models_refraction = True
    #: Whether its front end takes seabed clutter (point scatterers on the floor) and volume reverberation (the
    #: side-scan's alone: docs/physics.md §11, §18).
    models_clutter_and_volume = False
    #: Whether its record is one (ping, beam, sample) array of formed beams (a multibeam's) rather than one array a
    #: channel.
    forms_beams = False

    def dataset_coords(self, first_ping: int, n_pings: int) -> dict:
        """Coordinates the type adds to its record's dataset (name → (dims, values, CF attributes)): none here."""
        return {}

    def along_track_footprint_m(self, sound_speed_m_s: float) -> float | None:
        """The two-way −3 dB along-track footprint at the window's far end, m, in water of sound speed
        ``sound_speed_m_s`` (m/s), of a type with an along-track membrane (the side-scan's); None for the others (MSIS,
        forward-looking, echo sounder)."""
        return None

    #: Receive elements per side (:class:`~sonar_embree.ReceiverArray`); a side-scan's field, None for the others.
    receive_array = None

    def transducer_in(self, sound_speed_m_s: float) -> Beam:
        """The beam (:mod:`sonar_embree.instrument.beams`) in water of sound speed ``sound_speed_m_s`` (m/s; λ =
        c/f0)."""
        raise NotImplementedError(f"{type(self).__name__}.transducer_in")

    def directivity_index_in(self, sound_speed_m_s: float) -> float:
        """Receiving directivity index of the beam at sound speed ``sound_speed_m_s`` (m/s), dB (docs/physics.md
        §14)."""
        return self.transducer_in(sound_speed_m_s).directivity_index_db

    def speckle_cell_in(self, sound_speed_m_s: float) -> float:
        """Speckle lattice spacing by default at sound speed ``sound_speed_m_s`` (m/s), m: the beam's
        (:attr:`~sonar_embree.instrument.beams.Beam.speckle_cell_m`)."""
        return self.transducer_in(sound_speed_m_s).speckle_cell_m

    def check_sound_speed(self, sound_speed_m_s: float) -> None:
        """Refuse what the instrument cannot do in water of sound speed ``sound_speed_m_s`` (m/s); nothing by
        default."""

    def for_pulse(self, pulse: "Pulse") -> "Sonar":
        """This sonar with ``sample_rate_hz`` filled in for ``pulse`` when it is ``None``.

        fs = max(4/τ, 4·max|f − f0|) over the pulse's sweep, rounded up to 1 Hz: four
        samples per CW pulse length, twice the bandwidth of an FM sweep centred on
        f0 (the detected intensity's bandwidth), so matched filtering always works.
        """
        if self.sample_rate_hz is not None:
            return self
        f_lo, f_hi = pulse.frequency_span_hz(self.frequency_hz)
        off = max(abs(f_lo - self.frequency_hz), abs(f_hi - self.frequency_hz))
        fs = max(4.0 / pulse.duration_s, 4.0 * off)
        return dataclasses.replace(self, sample_rate_hz=float(math.ceil(fs * (1.0 - 1e-12))))

    def _check_levels(self, owner: str) -> None:
        """Validate ``source_level_db`` and ``self_noise_db_per_hz`` (a linear or µPa-at-1-m slip is refused)."""
        if self.source_level_db is not None:
            _check_number(owner, "source_level_db", self.source_level_db, lo=150.0, hi=250.0)
        if self.self_noise_db_per_hz is not None:
            _check_number(owner, "self_noise_db_per_hz", self.self_noise_db_per_hz, lo=-50.0, hi=150.0)
        object.__setattr__(self, "receiver", receiver_of(self.receiver))
        if self.receiver is not None and self.source_level_db is None:
            raise ConfigError(f"{owner}.receiver needs source_level_db: a receive chain digitises pressures (uPa), "
                              "a unit source has none")

    @property
    def level_scale(self) -> float:
        """10^(SL/10): µPa² per unit-source intensity (1.0 for a unit source)."""
        return 1.0 if self.source_level_db is None else 10.0 ** (self.source_level_db / 10.0)

    def _rate(self) -> float:
        if self.sample_rate_hz is None:
            raise ConfigError("Sonar.sample_rate_hz is None (derived from the pulse): use Sonar.for_pulse(pulse) "
                              "or give sample_rate_hz")
        return self.sample_rate_hz


#: Attributes an :class:`Acquisition` never reads through to its sonar (its own fields, and Python's protocols:
#: pickling and copying look these up before the fields exist).
_OWN = frozenset({"sonar", "environment", "sound_speed_m_s", "wavelength_m", "wavenumber_rad_m", "alpha_db_per_m"})


@dataclass(frozen=True)
class Acquisition:
    """One sonar in one medium: what a run resolves once from (sonar, environment) (docs/physics.md §1).

    The sonar dataclasses hold the instrument alone; a run (:func:`sonar_embree.simulate`) takes the medium as its
    own input and pairs the two here. The sonar's fields and methods read through (``acq.frequency_hz`` is
    ``acq.sonar.frequency_hz``); what depends on the water is computed once, on construction.

    Parameters
    ----------
    sonar : Sonar, EchoSounder, MSIS or ForwardLooking
        The instrument.
    environment : Environment
        The medium (sound speed, absorption, surface, profile, noise); default :class:`Environment` ().

    Attributes
    ----------
    sound_speed_m_s : float
        c, m/s (the environment's nominal speed).
    wavelength_m, wavenumber_rad_m : float
        λ = c/f0 (m) and k = 2π f0/c (rad/m) at the carrier.
    alpha_db_per_m : float
        One-way absorption at f0, dB/m (:meth:`Environment.alpha_db_per_m`).
    """

    sonar: object
    environment: Environment = Environment()
    sound_speed_m_s: float = dataclasses.field(init=False)
    wavelength_m: float = dataclasses.field(init=False)
    wavenumber_rad_m: float = dataclasses.field(init=False)
    alpha_db_per_m: float = dataclasses.field(init=False)

    def __post_init__(self):
        if not isinstance(self.sonar, Transducer):
            raise ConfigError(f"Acquisition.sonar must be a sonar_embree sonar type, got {type(self.sonar).__name__}")
        if not isinstance(self.environment, Environment):
            raise ConfigError(f"Acquisition.environment must be a sonar_embree.Environment, got {self.environment!r}")
        c, f0 = self.environment.sound_speed_m_s, self.sonar.frequency_hz
        for name, value in (("sound_speed_m_s", c), ("wavelength_m", c / f0),
                            ("wavenumber_rad_m", 2.0 * math.pi * f0 / c),
                            ("alpha_db_per_m", self.environment.alpha_db_per_m(f0))):
            object.__setattr__(self, name, value)
        self.sonar.check_sound_speed(c)
        if self.sonar.sample_rate_hz is not None and self.n_samples > 50_000_000:
            raise ConfigError(f"{type(self.sonar).__name__}.max_range_m={self.sonar.max_range_m} with sample_rate_hz="
                              f"{self.sonar.sample_rate_hz} gives {self.n_samples} samples per ping at "
                              f"c = {c:g} m/s; reduce one of them")

    @classmethod
    def of(cls, sonar) -> "Acquisition":
        """``sonar`` itself if it is an acquisition, else ``sonar`` in the default :class:`Environment` ()."""
        return sonar if isinstance(sonar, Acquisition) else cls(sonar)

    def __getattr__(self, name: str):
        """The sonar's own field or method ``name`` (only called for what this object does not hold itself)."""
        if name in _OWN or name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.sonar, name)

    def for_pulse(self, pulse: "Pulse") -> "Acquisition":
        """This acquisition with the sonar's sample rate filled in for ``pulse`` (:meth:`Transducer.for_pulse`)."""
        sonar = self.sonar.for_pulse(pulse)
        return self if sonar is self.sonar else Acquisition(sonar, self.environment)

    def as_sidescan(self) -> "Acquisition":
        """The side-scan acquisition of an MSIS or forward-looking sonar's beam, in the same medium."""
        return Acquisition(self.sonar.as_sidescan(self.sound_speed_m_s), self.environment)

    @property
    def type_name(self) -> str:
        """The sonar type's class name, for messages (``"Sonar"``, ``"MSIS"``, …)."""
        return type(self.sonar).__name__

    @property
    def transducer(self) -> Beam:
        """The sonar's beam at this wavelength (:meth:`Transducer.transducer_in`)."""
        return self.sonar.transducer_in(self.sound_speed_m_s)

    @property
    def directivity_index_db(self) -> float:
        """Receiving directivity index at this wavelength, dB (:meth:`Transducer.directivity_index_in`)."""
        return self.sonar.directivity_index_in(self.sound_speed_m_s)

    @property
    def default_speckle_cell_m(self) -> float:
        """Speckle lattice spacing by default, m (:meth:`Transducer.speckle_cell_in`)."""
        return self.sonar.speckle_cell_in(self.sound_speed_m_s)

    def along_track_footprint_m(self) -> float | None:
        """The two-way −3 dB along-track footprint at the far range, m
        (:meth:`Transducer.along_track_footprint_m`)."""
        return self.sonar.along_track_footprint_m(self.sound_speed_m_s)

    def noise_density(self) -> float:
        """The received noise spectral density in µPa²/Hz: ambient/DI + self-noise (0 for a unit source)."""
        s = self.sonar
        if s.source_level_db is None:
            return 0.0
        n = 0.0
        if self.environment.noise is not None:
            n += 10.0 ** ((float(self.environment.noise.spectral_density_db(s.frequency_hz))
                           - self.directivity_index_db) / 10.0)
        if s.self_noise_db_per_hz is not None:
            n += 10.0 ** (s.self_noise_db_per_hz / 10.0)
        return n

    @property
    def n_samples(self) -> int:
        """Samples per ping and side: t = 0 … 2·max_range/c inclusive."""
        return int(math.floor(2.0 * self.sonar.max_range_m / self.sound_speed_m_s * self.sonar._rate())) + 1

    @property
    def range_bin_m(self) -> float:
        """Slant-range spacing of the samples, c / (2 fs), in m."""
        return self.sound_speed_m_s / (2.0 * self.sonar._rate())


@dataclass(frozen=True)
class Sonar(Transducer):
    """A side-scan sonar with one rectangular membrane per side (docs/physics.md §1–2).

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
    sample_rate_hz : float or None
        Sample rate of the recorded (detected) time series, in Hz. ``None``
        (default) derives it from the pulse when simulating (:meth:`for_pulse`):
        max(4/τ, 4·the sweep's largest offset from f0), i.e. 40 kHz for the
        default 100 µs CW pulse and 2·B for an LFM of bandwidth B centred on f0.
    source_level_db : float or None
        Source level SL, dB re 1 µPa at 1 m on axis, in [150, 250]. ``None`` (default): a
        unit source (on-axis intensity 1 at 1 m), no noise. Set: the record is in µPa²
        (the unit-source record × 10^(SL/10)) and holds the medium's ambient noise
        and the receiver's self-noise (docs/physics.md §14).
    self_noise_db_per_hz : float or None
        The receiver's own noise as an equivalent input spectral density, dB re 1 µPa²/Hz
        (not reduced by the directivity index); heard only with a source level.
    receiver : Receiver or None
        The device's receive chain (sensitivity, TVG or AGC, ADC; docs/physics.md §15): the
        record then also holds the integer ``samples`` a device would store. Needs a source level.
    receive_array : ReceiverArray or None
        Receive elements per side (an interferometric or a synthetic-aperture side-scan; docs/physics.md §18):
        each element is synthesised along its own bistatic path, kept as ``Record.element_data`` (complex), and
        element 0's intensity is the record's channel. Needs coherent speckle. None: one receiver per side, at
        the transmitter.
    beam : str
        Each side's pattern (:data:`~sonar_embree.instrument.beams.APERTURE_BEAMS`): ``"membrane"`` (default, the
        baffled rectangular membrane lx × ly) or ``"gaussian"`` (a Gaussian of the membrane's −3 dB widths; no
        side lobes). Applied after the direct paths' kernels (:meth:`transducer_in`), inside the sea surface's.

    The medium is not the sonar's: a run takes it (``simulate(..., environment=)``, the ``[environment]`` table) and
    :class:`Acquisition` resolves c, λ, the beam and the range bins from the two.
    """

    #: Its front end takes seabed clutter and volume reverberation (:class:`Transducer`).
    models_clutter_and_volume = True

    frequency_hz: float = 400e3
    length_m: float = 0.19
    height_m: float = 0.0038
    tilt_deg: float = 20.0
    max_range_m: float = 50.0
    sample_rate_hz: float | None = None
    source_level_db: float | None = None
    self_noise_db_per_hz: float | None = None
    receiver: Receiver | None = None
    receive_array: ReceiverArray | None = None
    beam: str = "membrane"

    def __post_init__(self):
        self._check_levels("Sonar")
        object.__setattr__(self, "receive_array", receive_array_of(self.receive_array))
        if self.beam not in APERTURE_BEAMS:
            raise ConfigError(f"Sonar.beam must be one of {', '.join(repr(k) for k in APERTURE_BEAMS)}, "
                              f"got {self.beam!r}")
        for name in ("frequency_hz", "length_m", "height_m", "max_range_m"):
            _check_number("Sonar", name, getattr(self, name), positive=True)
        _check_number("Sonar", "tilt_deg", self.tilt_deg, lo=0.0, hi=90.0)
        if self.sample_rate_hz is not None:
            _check_number("Sonar", "sample_rate_hz", self.sample_rate_hz, positive=True)

    def speckle_cell_in(self, sound_speed_m_s: float) -> float:
        """Speckle lattice spacing by default, lx/2: the along-track resolution (docs/physics.md §4), m."""
        return 0.5 * self.length_m

    def along_track_footprint_m(self, sound_speed_m_s: float) -> float:
        """2·R_max·tan(θ₃/2), θ₃ the full two-way −3 dB along-track width at sound speed ``sound_speed_m_s``
        (sinc⁴ = ½, :func:`sonar_embree.instrument.beam.beamwidth_deg`), m."""
        width = beamwidth_deg(self.length_m, sound_speed_m_s / self.frequency_hz, -3.0, two_way=True)
        return self.max_range_m * 2.0 * math.tan(math.radians(0.5 * width))

    def transducer_in(self, sound_speed_m_s: float) -> Beam:
        """Each side's beam (:mod:`sonar_embree.instrument.beams`): ``beam`` of the aperture lx × ly in water of
        sound speed ``sound_speed_m_s`` (m/s; k = 2π f0/c).

        Its receiving directivity index DI = 10·log10(4π/∫ b² dΩ) is the integral of the power pattern over the
        hemisphere (Urick 1983, §3.6; :func:`sonar_embree.instrument.directivity.membrane_directivity_index_db`
        for the membrane): 28.23 dB for the default 190 mm × 3.8 mm at 400 kHz and 1500 m/s, where the
        large-aperture 10·log10(4π·lx·ly/λ²) gives 28.10 dB.
        """
        return aperture_beam(self.beam, self.length_m, self.height_m,
                             2.0 * math.pi * self.frequency_hz / sound_speed_m_s)

    @property
    def tilt_rad(self) -> float:
        """Boresight depression δ in rad."""
        return math.radians(self.tilt_deg)

    @classmethod
    def preset(cls, name: str, **overrides) -> "Sonar":
        """The side-scan sonar of a device preset (:data:`sonar_embree.instrument.devices.DEVICES`), e.g.
        ``Sonar.preset("edgetech-4125-400", max_range_m=75)``; ``overrides`` replace any field (and
        ``sound_speed_m_s``, the water in which the membrane has the device's beamwidths: 1500 m/s by default)."""
        d = device(name)
        kw = dict(frequency_hz=d.frequency_hz, tilt_deg=d.tilt_deg, max_range_m=d.ranges_m[0],
                  source_level_db=d.source_level_db)
        return cls.from_beamwidths(d.azimuth_one_way_deg, d.elevation_deg, rule="exact", **{**kw, **overrides})

    @classmethod
    def from_beamwidths(cls, azimuth_deg: float = 1.0, elevation_deg: float = 50.0, *,
                        rule: str = "exact", sound_speed_m_s: float = 1500.0, **kwargs) -> "Sonar":
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
        sound_speed_m_s : float
            The speed of sound c (m/s) at which the widths hold (λ = c/f0); 1500 m/s by default.
        **kwargs
            Any other :class:`Sonar` field (frequency_hz, tilt_deg, …).
        """
        for name, val in (("azimuth_deg", azimuth_deg), ("elevation_deg", elevation_deg)):
            _check_number("Sonar.from_beamwidths", name, val, positive=True, hi=179.0)
        if rule not in ("exact", "small-angle"):
            raise ConfigError(f"Sonar.from_beamwidths rule must be 'exact' or 'small-angle', got {rule!r}")
        f0 = kwargs.get("frequency_hz", cls.frequency_hz)
        _check_number("Sonar", "frequency_hz", f0, positive=True)
        _check_number("Sonar.from_beamwidths", "sound_speed_m_s", sound_speed_m_s, positive=True)
        lam = sound_speed_m_s / f0
        lx = membrane_size_for_beamwidth(math.radians(azimuth_deg), lam, rule)
        ly = membrane_size_for_beamwidth(math.radians(elevation_deg), lam, rule)
        return cls(length_m=lx, height_m=ly, **kwargs)



#: The medium's keywords that old ``[sonar]`` TOML tables (and saved records) held; the readers move them into the
#: :class:`Environment` with a deprecation warning (:func:`split_medium`). In Python the medium is a run's input:
#: ``simulate(..., environment=Environment(...))``.
LEGACY_MEDIUM_KEYS = ("sound_speed_m_s", "absorption_db_per_m", "temperature_c", "salinity_ppt", "depth_m", "ph")


def split_medium(table: dict, where: str, environment: Environment | None = None) -> tuple[dict, Environment]:
    """``table`` (a sonar's keywords, as old files and TOML tables held them) without its medium, and that medium:
    ``environment`` (default :class:`Environment` ()) or the table's own ``environment`` entry (a dict or an
    :class:`Environment`, as records written before the medium left the sonar hold it), with the old medium keys
    moved in. An error names a key whose value the environment refuses."""
    out = dict(table)
    env = out.pop("environment", None)
    env = environment if env is None else env
    env = Environment() if env is None else Environment(**env) if isinstance(env, dict) else env
    legacy = {k: out.pop(k) for k in LEGACY_MEDIUM_KEYS if k in out}
    try:
        return out, (dataclasses.replace(env, **legacy) if legacy else env)
    except ConfigError as exc:  # name the key as it was given
        raise ConfigError(str(exc).replace("Environment.", f"{where}.", 1)) from None


@dataclass(frozen=True)
class Pulse:
    """A transmitted pulse: its kind, length, envelope taper and sweep (docs/physics.md §5).

    Use the constructors: ``Pulse.cw(duration_s, taper)``,
    ``Pulse.lfm(bandwidth_hz, duration_s, taper, center_hz=None)`` and
    ``Pulse.exp_chirp(f_start_hz, f_stop_hz, duration_s, taper)``.

    Parameters
    ----------
    kind : {"cw", "lfm", "exp_chirp"}
        Continuous wave at the sonar's ``frequency_hz``; linear FM, instantaneous
        frequency f_s + κt with κ = B/τ; exponential chirp, instantaneous frequency
        f_s·κ^t with ln κ = ln(f_stop/f_start)/τ.
    duration_s : float
        Pulse length τ in s.
    taper : float
        Fraction of the pulse covered by the two flanks of the flat-top
        Blackman–Harris envelope, in [0, 1]: 0 is a rectangle, 1 a full
        4-term Blackman–Harris window. The default 0.1 follows the paper (every
        pulse windowed); a rectangle's discontinuous edges are only resolved by
        the sample rate they are synthesised at.
    bandwidth_hz : float or None
        Swept bandwidth B of a linear FM pulse, Hz (``lfm`` only).
    center_hz : float or None
        Centre frequency of a linear FM pulse, Hz; ``None`` is the sonar's
        ``frequency_hz`` (``lfm`` only).
    f_start_hz, f_stop_hz : float or None
        Start and stop frequencies of an exponential chirp, Hz (``exp_chirp`` only);
        equal values give a CW pulse at that frequency.
    """

    kind: str = "cw"
    duration_s: float = 100e-6
    taper: float = 0.1
    bandwidth_hz: float | None = None
    center_hz: float | None = None
    f_start_hz: float | None = None
    f_stop_hz: float | None = None

    KINDS = ("cw", "lfm", "exp_chirp")
    _KIND_FIELDS = {"cw": (), "lfm": ("bandwidth_hz", "center_hz"), "exp_chirp": ("f_start_hz", "f_stop_hz")}

    def __post_init__(self):
        if self.kind not in self.KINDS:
            raise ConfigError(f"Pulse.kind must be one of {self.KINDS}, got {self.kind!r}")
        _check_number("Pulse", "duration_s", self.duration_s, positive=True)
        if self.duration_s > 1.0:
            raise ConfigError(f"Pulse.duration_s must be <= 1 s, got {self.duration_s!r}")
        _check_number("Pulse", "taper", self.taper, lo=0.0, hi=1.0)
        for name in ("bandwidth_hz", "center_hz", "f_start_hz", "f_stop_hz"):
            value = getattr(self, name)
            if value is None:
                continue
            if name not in self._KIND_FIELDS[self.kind]:
                raise ConfigError(f"Pulse.{name} does not apply to kind={self.kind!r} "
                                  f"(it takes: {', '.join(self._KIND_FIELDS[self.kind]) or 'no sweep fields'})")
            _check_number("Pulse", name, value, positive=True, hi=100e6)
        if self.kind == "lfm":
            if self.bandwidth_hz is None:
                raise ConfigError("Pulse.bandwidth_hz is required for kind='lfm'")
            if self.center_hz is not None and self.bandwidth_hz >= 2.0 * self.center_hz:
                raise ConfigError(f"Pulse.bandwidth_hz={self.bandwidth_hz} sweeps below 0 Hz around "
                                  f"center_hz={self.center_hz}")
        if self.kind == "exp_chirp" and (self.f_start_hz is None or self.f_stop_hz is None):
            raise ConfigError("Pulse.f_start_hz and Pulse.f_stop_hz are required for kind='exp_chirp'")

    @classmethod
    def preset(cls, name: str) -> "Pulse":
        """The pulse of a device preset (:data:`sonar_embree.instrument.devices.DEVICES`): its CW or LFM pulse."""
        p = device(name).pulse
        return cls.cw(duration_s=p[1]) if p[0] == "cw" else cls.lfm(bandwidth_hz=p[2], duration_s=p[1])

    @classmethod
    def cw(cls, duration_s: float = 100e-6, taper: float = 0.1) -> "Pulse":
        """A continuous-wave pulse at the sonar's frequency, ``duration_s`` long (s)."""
        return cls(kind="cw", duration_s=duration_s, taper=taper)

    @classmethod
    def lfm(cls, bandwidth_hz: float, duration_s: float = 1e-3, taper: float = 0.1,
            center_hz: float | None = None) -> "Pulse":
        """A linear FM pulse sweeping ``bandwidth_hz`` (Hz) up through ``center_hz`` (default: the sonar's f0)."""
        return cls(kind="lfm", duration_s=duration_s, taper=taper, bandwidth_hz=bandwidth_hz, center_hz=center_hz)

    @classmethod
    def exp_chirp(cls, f_start_hz: float, f_stop_hz: float, duration_s: float = 1e-3,
                  taper: float = 0.1) -> "Pulse":
        """An exponential chirp from ``f_start_hz`` to ``f_stop_hz`` (Hz) over ``duration_s`` (s)."""
        return cls(kind="exp_chirp", duration_s=duration_s, taper=taper, f_start_hz=f_start_hz,
                   f_stop_hz=f_stop_hz)

    @property
    def is_fm(self) -> bool:
        """True for a pulse whose frequency changes (``lfm``, or ``exp_chirp`` with f_start ≠ f_stop)."""
        return self.kind == "lfm" or (self.kind == "exp_chirp" and self.f_start_hz != self.f_stop_hz)

    def frequency_span_hz(self, carrier_hz: float) -> tuple[float, float]:
        """Lowest and highest instantaneous frequency (Hz) for a sonar of frequency ``carrier_hz``."""
        if self.kind == "lfm":
            fc = carrier_hz if self.center_hz is None else self.center_hz
            return fc - 0.5 * self.bandwidth_hz, fc + 0.5 * self.bandwidth_hz
        if self.kind == "exp_chirp":
            return min(self.f_start_hz, self.f_stop_hz), max(self.f_start_hz, self.f_stop_hz)
        return carrier_hz, carrier_hz

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
        steradian). −27 dB is Mackenzie's value for sand/mud. Shorthand for
        ``scattering=Lambert(backscatter_db)``.
    two_sided : bool
        Scatter from both sides of every face (default False: faces seen from behind
        return nothing, as closed meshes need). For open surfaces of unknown
        winding: sheets, plates, meshes with inverted normals.
    scattering : scattering law, optional
        Any law of :mod:`sonar_embree.laws` (``Lambert``, ``Kirchhoff``,
        ``Tabulated``, their sums) or a sediment preset of :mod:`sonar_embree.laws.sediments`;
        default Lambert with ``backscatter_db``. Give one or the other (a TOML table's old
        ``law`` key is read as ``scattering``).
    texture : KTexture, optional
        Non-Rayleigh (K-distributed) texture frozen to the surface; default none
        (Rayleigh speckle).
    clutter : Clutter, optional
        Discrete point scatterers on the surface (shell, gravel), beside its law
        (:class:`sonar_embree.laws.clutter.Clutter`); default none.
    """

    backscatter_db: float = -27.0
    two_sided: bool = False
    scattering: object = None
    texture: object = None
    clutter: object = None

    def __post_init__(self):
        if not isinstance(self.two_sided, bool):
            raise ConfigError(f"Material.two_sided must be true or false, got {self.two_sided!r}")
        _check_number("Material", "backscatter_db", self.backscatter_db, hi=30.0)
        if self.backscatter_db < -300:
            raise ConfigError(f"Material.backscatter_db must be >= -300 dB, got {self.backscatter_db!r}")
        law = self.scattering
        if law is None:
            object.__setattr__(self, "scattering", Lambert(self.backscatter_db))
        elif not isinstance(law, Summable):
            raise ConfigError(f"Material.scattering must be a scattering law of sonar_embree.laws, got {law!r}")
        elif self.backscatter_db != -27.0 and law != Lambert(self.backscatter_db):
            raise ConfigError("Material: give backscatter_db or scattering, not both")
        elif isinstance(law, Lambert):
            object.__setattr__(self, "backscatter_db", law.backscatter_db)
        if self.texture is not None and not isinstance(self.texture, KTexture):
            raise ConfigError(f"Material.texture must be a sonar_embree.KTexture, got {self.texture!r}")
        if self.clutter is not None and not isinstance(self.clutter, Clutter):
            raise ConfigError(f"Material.clutter must be a sonar_embree.Clutter, got {self.clutter!r}")

    @property
    def law(self):
        """The scattering law (``scattering``)."""
        return self.scattering

    @property
    def mu(self) -> float:
        """Linear Lambert coefficient μ = 10^(backscatter_db/10) (NaN for another law)."""
        return self.scattering.mu if isinstance(self.scattering, Lambert) else math.nan


#: The largest angle between a fan's azimuth lines at quality 1, degrees (:class:`FanSettings`): a 4 m seabed patch
#: 20 m off a 22° beam's track within 1 dB of its aimed-ray echo in every ping (issue 53; 3 dB with the 5.4° of the
#: beam's own oversampled spacing).
AZIMUTH_STEP_DEG = 1.5
#: The same for a receive array spread along track (a SAS): lines 5 cm apart at 14.5 m, so that the speckle strips
#: (R·ds along track) do not reach across a hole or shadow the image resolves; the SAS test's 0.8 m hole then images
#: within 1 dB of a floor of exact point echoes (14.7 against 15.2 dB down; 9.4 dB at 1.5°), at 2–10 % more time
#: per 16-element ping (docs/benchmarks.md, "Receiver arrays").
ARRAY_AZIMUTH_STEP_DEG = 0.2


@dataclass(frozen=True)
class FanSettings:
    """How densely each ping's fan of rays samples the beam (docs/physics.md §7).

    One number, ``quality``, trades error for speed; every other field left at
    ``None`` follows from it (see :meth:`resolved`), and any field given explicitly
    wins. The default ``quality=1`` keeps a flat floor within 0.2 dB of the analytic
    return (docs/benchmarks.md); 0.5 is about twice as fast, 2 or 4 is for
    references.

    Parameters
    ----------
    quality : float
        Scales every ray density: elevation rays per range bin ≈ quality (on the
        steepest part of the scene), azimuth oversampling max(1, 2·quality) (objects
        need more azimuth lines than a floor), the azimuth span (main lobe for
        quality ≤ 1, first side lobes above), the largest elevation step
        0.5°/quality and the probe step 0.2°/max(1, quality).
    rays_per_bin : float or None
        Elevation rays per range bin (c/2fs) where the scene's slant range changes
        fastest with depression angle. Each ray's echo is spread over the range
        interval its cell covers on the surface, so fewer than one ray per bin
        still integrates a smooth surface accurately.
    azimuth_oversample : float or None
        Azimuth rays per λ/(2·lx) step of the along-track direction cosine. Any
        value ≥ 1 integrates the band-limited sinc⁴ pattern exactly; more keeps
        small objects from falling between rays.
    azimuth_nulls : int or None
        Azimuth span in units of the first-null direction cosine λ/lx (1: the main
        lobe, 99.6 % of the two-way energy; 2 adds the first side lobes).
    max_step_deg : float or None
        Largest elevation step in degrees, wherever the scene is smooth.
    max_azimuth_step_deg : float or None
        Largest angle between azimuth lines, degrees (default 1.5/quality, and :data:`ARRAY_AZIMUTH_STEP_DEG`/quality
        for a receive array spread along track): a wide beam (a 4 cm SAS element's 22°
        at 100 kHz) takes lines this close rather than its ``azimuth_oversample`` spacing, so a seabed patch a
        fraction of its footprint is sampled along track in every ping. Beams narrower than about 6° are unaffected.
    probe_step_deg : float or None
        Elevation step of the coarse probe cast (three azimuth lines per side, or lines
        at most 2° apart across a wide beam) that
        finds where range changes fast and where nothing is within range.
    max_rays_per_side : int
        Hard cap on elevation rays per azimuth line and side (a guard, not a budget).
    footprint : bool
        Spread each ray's echo over the slant-range interval its cell covers on the
        surface (default). False treats rays as point echoes with linear splatting,
        the docs/physics.md §7 baseline, which needs about one ray per range bin.
    aim_objects : bool
        Also aim rays at every object that is not seafloor in every ping where it can echo (default; docs/physics.md
        §7b): small objects are seen in every ping, whatever the fan's line spacing. False leaves them to the
        fan's rays alone (faster with many objects, but an object narrower than the line spacing is seen by luck).
    """

    quality: float = 1.0
    rays_per_bin: float | None = None
    azimuth_oversample: float | None = None
    azimuth_nulls: int | None = None
    max_step_deg: float | None = None
    probe_step_deg: float | None = None
    max_rays_per_side: int = 200_000
    max_azimuth_step_deg: float | None = None
    footprint: bool = True
    aim_objects: bool = True

    def __post_init__(self):
        for name in ("footprint", "aim_objects"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"FanSettings.{name} must be true or false, got {getattr(self, name)!r}")
        _check_number("FanSettings", "quality", self.quality, positive=True, hi=32)  # 2·quality azimuth ≤ 64
        if self.quality < 1.0 / 64:
            raise ConfigError(f"FanSettings.quality must be >= {1 / 64}, got {self.quality!r}")
        for name, kw in (("rays_per_bin", dict(positive=True, hi=1000)),
                         ("azimuth_oversample", dict(lo=1.0, hi=64)),
                         ("azimuth_nulls", dict(integer=True, lo=1, hi=50)),
                         ("max_step_deg", dict(positive=True, hi=10)),
                         ("probe_step_deg", dict(positive=True, hi=5)),
                         ("max_azimuth_step_deg", dict(positive=True, hi=30))):
            if getattr(self, name) is not None:
                _check_number("FanSettings", name, getattr(self, name), **kw)
        _check_number("FanSettings", "max_rays_per_side", self.max_rays_per_side, integer=True,
                      lo=16, hi=10_000_000)

    def resolved(self) -> "FanSettings":
        """These settings with every ``None`` filled in from ``quality``."""
        q = float(self.quality)
        derived = dict(rays_per_bin=q, azimuth_oversample=max(1.0, 2.0 * q), azimuth_nulls=1 if q <= 1.0 else 2,
                       max_step_deg=min(0.5 / q, 10.0), probe_step_deg=min(0.2 / max(q, 1.0), 5.0),
                       max_azimuth_step_deg=min(AZIMUTH_STEP_DEG / q, 30.0))
        return dataclasses.replace(self, **{k: v for k, v in derived.items() if getattr(self, k) is None})


#: Largest TVG gain, as a power of ten, that keeps a unit-source record finite in float64.
MAX_TVG_DECADES = 250.0


def _check_tvg(sonar: Sonar) -> None:
    """Refuse a TVG R⁴·10^(2αR/10) that would overflow float64 within the range window."""
    r = sonar.max_range_m
    decades = 4.0 * math.log10(r) + 2.0 * sonar.alpha_db_per_m * r / 10.0
    if decades > MAX_TVG_DECADES:
        raise ConfigError(f"SignalChain.tvg: the gain R^4 10^(2 alpha R / 10) reaches 1e{decades:.0f} at "
                          f"max_range_m = {r:g} m with {sonar.alpha_db_per_m:g} dB/m absorption, beyond float64; "
                          "lower Sonar.absorption_db_per_m or max_range_m, or set tvg = false")


def speckle_cell_for(sonar: Sonar, pulse: Pulse, compressed: bool) -> float:
    """The default speckle lattice spacing: the finest resolution cell (docs/physics.md §10), m.

    min(lx/2, δr) with δr = c/(2B) for a matched-filtered FM pulse of bandwidth B and
    cτ/2 otherwise: a lattice coarser than either leaves too few independent scatterers
    per resolution cell and the speckle contrast rises above 1 (1.04 at lx/2 = 9.5 cm
    for a 20 kHz LFM compressed to 3.75 cm; 1.00 at 3.75 cm; docs/benchmarks.md).
    """
    f_lo, f_hi = pulse.frequency_span_hz(sonar.frequency_hz)
    if compressed and pulse.is_fm:
        dr = sonar.sound_speed_m_s / (2.0 * (f_hi - f_lo))
    else:
        dr = pulse.range_extent_m(sonar.sound_speed_m_s)
    return min(sonar.default_speckle_cell_m, dr)


@dataclass(frozen=True)
class SignalChain:
    """How echoes become the record: speckle, band, detection and processing (docs/physics.md §4–5).

    The keyword arguments of :func:`sonar_embree.simulate` and the ``[simulation]``
    table of a run config map 1:1 onto these fields.

    Parameters
    ----------
    speckle : bool
        False: the expected intensity (the paper's speckle-free "perfect sonar
        image"; no complex arithmetic). True: scatterers with complex Gaussian
        reflectivity frozen to the surface, synthesised as signals.
    band : {"baseband", "carrier"}
        Synthesis of the speckle signal: complex baseband at the record rate, or the
        real carrier signal at a rate of ≥ 4× the highest pulse frequency.
    detection : {"coherent", "incoherent"}
        |analytic signal|², or square-law rectification and low-pass of the carrier
        signal (``band="carrier"`` only), scaled to the same level.
    matched_filter : bool or None
        Pulse compression by correlation with the transmitted pulse; ``None``: on for
        FM pulses, off for CW. Needs coherent detection.
    tvg : bool
        Multiply the intensity by R⁴·10^(2αR/10), R = c·t/2 (perfect TVG).
    noise_db_per_hz : float or None
        Receiver noise spectral density N0 in dB re (record intensity unit)/Hz:
        white complex Gaussian noise of intensity N0·fs per sample at the record rate
        fs, added before matched filtering. ``None``: no noise. In speckle-free mode
        its mean intensity is added.
    lowpass_hz : float or None
        Cut-off of a linear-phase low-pass FIR applied to the detected intensity at
        the record rate (below fs/2); ``None``: none.
    speckle_cell_m : float or None
        Spacing of the world-fixed lattice of scatterers, m; ``None``: the finest
        resolution cell (:func:`speckle_cell_for`): half the membrane length, lx/2,
        the distance over which a real aperture's speckle decorrelates as it moves
        along track, or the range resolution if finer (c/2B after pulse
        compression, cτ/2 otherwise). Each ray's echo is shared trilinearly
        among its 8 surrounding nodes, so speckle stays correlated for moves much
        smaller than a cell and is independent beyond it; the node's scatterers keep
        the mean and spread in range of the rays they stand for.
    seed : int
        Seed of the scatterers' reflectivity and of the noise.
    """

    speckle: bool = False
    band: str = "baseband"
    detection: str = "coherent"
    matched_filter: bool | None = None
    tvg: bool = False
    noise_db_per_hz: float | None = None
    lowpass_hz: float | None = None
    speckle_cell_m: float | None = None
    seed: int = 0

    BANDS = ("baseband", "carrier")
    DETECTIONS = ("coherent", "incoherent")

    def __post_init__(self):
        for name in ("speckle", "tvg"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"SignalChain.{name} must be True or False, got {getattr(self, name)!r}")
        if self.matched_filter is not None and not isinstance(self.matched_filter, bool):
            raise ConfigError(f"SignalChain.matched_filter must be True, False or None, got {self.matched_filter!r}")
        if self.band not in self.BANDS:
            raise ConfigError(f"SignalChain.band must be one of {self.BANDS}, got {self.band!r}")
        if self.detection not in self.DETECTIONS:
            raise ConfigError(f"SignalChain.detection must be one of {self.DETECTIONS}, got {self.detection!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2 ** 63:
            raise ConfigError(f"SignalChain.seed must be a non-negative integer, got {self.seed!r}")
        if self.noise_db_per_hz is not None:
            _check_number("SignalChain", "noise_db_per_hz", self.noise_db_per_hz, lo=-400.0, hi=200.0)
        if self.lowpass_hz is not None:
            _check_number("SignalChain", "lowpass_hz", self.lowpass_hz, positive=True)
        if self.speckle_cell_m is not None:
            _check_number("SignalChain", "speckle_cell_m", self.speckle_cell_m, positive=True, hi=10.0)
        if not self.speckle and (self.band != "baseband" or self.detection != "coherent"):
            raise ConfigError("SignalChain: speckle=False computes the expected intensity, which has no band or "
                              f"detection (got band={self.band!r}, detection={self.detection!r}); "
                              "set speckle=True to simulate signals")
        if self.detection == "incoherent" and self.band != "carrier":
            raise ConfigError("SignalChain: detection='incoherent' rectifies the real carrier signal; "
                              "use band='carrier' (or detection='coherent')")
        if self.detection == "incoherent" and self.matched_filter:
            raise ConfigError("SignalChain: matched_filter=True needs the phase, which incoherent detection "
                              "discards; use detection='coherent'")

    def resolved(self, sonar: Sonar, pulse: Pulse) -> "SignalChain":
        """This chain with ``matched_filter`` decided for ``pulse``, checked against ``sonar``."""
        if self.tvg:
            _check_tvg(sonar)
        rx = sonar.receiver
        if rx is not None:                                          # the device's gain law: refused before any ping
            rx.gain.check_range(sonar.max_range_m, sonar.alpha_db_per_m)
        mf = self.matched_filter
        if mf is None:
            mf = pulse.is_fm and self.detection == "coherent"
            if pulse.is_fm and self.detection == "incoherent":
                raise ConfigError("SignalChain: an FM pulse needs pulse compression, which incoherent detection "
                                  "cannot do; use detection='coherent' or set matched_filter=False")
        sonar = sonar.for_pulse(pulse)
        fs = sonar.sample_rate_hz
        f_lo, f_hi = pulse.frequency_span_hz(sonar.frequency_hz)
        if mf:
            off = max(abs(f_lo - sonar.frequency_hz), abs(f_hi - sonar.frequency_hz))
            if off >= 0.5 * fs:
                raise ConfigError(f"Sonar.sample_rate_hz={fs:g} is too low to matched-filter a pulse reaching "
                                  f"{off:g} Hz from the carrier; it needs > {2 * off:g} Hz")
        if self.lowpass_hz is not None and self.lowpass_hz >= 0.5 * fs:
            raise ConfigError(f"SignalChain.lowpass_hz={self.lowpass_hz:g} must be below half the sample rate "
                              f"({0.5 * fs:g} Hz)")
        if self.band == "carrier" and f_lo <= 0:
            raise ConfigError(f"Pulse sweeps down to {f_lo:g} Hz; a carrier signal needs positive frequencies")
        cell = speckle_cell_for(sonar, pulse, bool(mf)) if self.speckle_cell_m is None else self.speckle_cell_m
        return dataclasses.replace(self, matched_filter=bool(mf), speckle_cell_m=float(cell))
