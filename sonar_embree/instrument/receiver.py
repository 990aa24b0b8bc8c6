"""The receive chain as a device records it: sensitivity, TVG or AGC, ADC (docs/physics.md §15).

From the record's mean-square pressure I(t) in µPa² (a sonar with a source level) to the integers a device
stores, per ping and channel::

    v(t)   = 10^(S/20)·√I(t)                       volts rms at the hydrophone's output, S in dB re 1 V/µPa
    g(t)   = G(R)/20 dB, R = c·t/2                 TVG: G(R) = min(G0 + k·log10 R' + 2αR', G_max), R' = max(R, R0, 1 m)
           = target·V_fs / √⟨(v)²⟩_window          or AGC: a centred moving mean over ``window_s``
    code   = clip(round(v·10^(g)/Δ), 0, 2^b − 1),  Δ = V_fs/(2^b − 1)       linear encoding
           = clip(round((20·log10(v·10^g/V_fs) + D)/D·(2^b − 1)), 0, 2^b − 1)  logarithmic, D dB

the ADC sampling the detected envelope (unipolar), rounding to the nearest level and clipping at full scale
V_fs. A TVG starts at a range R0 (the gain is held at G(R0) before it, as a device holds it until its TVG
start) and stops rising at a ceiling G_max (the amplifier's largest gain; beyond it noise and echoes are both
flat in gain). A logarithmic encoding spreads the codes over the top D dB below full scale (devices that store
8 bits usually do). The TVG law is the textbook one that undoes spreading (k = 40: two-way spherical spreading
of a point target, 30: of a seafloor's reverberation, 20: cylindrical) and absorption (Urick 1983, §12.5; Lurton,
*An Introduction to Underwater Acoustics*, 2nd ed., Springer, 2010, §9.2); the quantisation error of a
rounding ADC is uniform on ±Δ/2 with variance Δ²/12 (Widrow and Kollár, *Quantization Noise*, Cambridge
University Press, 2008, ch. 4).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..validation import check_bool, check_number, from_table, warn_once


#: Largest gain law, as a power of ten of the voltage factor, that keeps the gained volts finite in float64.
MAX_GAIN_DECADES = 250.0
#: Gain beyond which a TVG law is implausible for a device (side-scan receivers span some 100–150 dB of gain
#: in all; Lurton 2010, §9.2): a warning, not an error.
MAX_DEVICE_TVG_DB = 200.0


@dataclass(frozen=True)
class TVG:
    """Time-varied gain G(R) = g0_db + k·log10(R/1 m) + 2·α·R dB (α the sonar's one-way absorption, dB/m).

    Parameters
    ----------
    g0_db : float
        Gain at 1 m, dB (default 20 dB).
    k : float
        Spreading law: 20, 30 or 40 (dB per decade of range).
    absorption : bool
        Include the 2αR term (default True).
    start_range_m : float
        R0, m: the law starts there, the gain held at G(R0) before (default 0: from 1 m).
    max_gain_db : float or None
        G_max, dB: the ceiling of the gain (default None: none).
    """

    g0_db: float = 20.0
    k: float = 30.0
    absorption: bool = True
    start_range_m: float = 0.0
    max_gain_db: float | None = None

    def __post_init__(self):
        check_number("TVG", "g0_db", self.g0_db, lo=-100.0, hi=200.0)
        check_bool("TVG", "absorption", self.absorption)
        check_number("TVG", "start_range_m", self.start_range_m, lo=0.0, hi=1e5)
        if self.max_gain_db is not None:
            check_number("TVG", "max_gain_db", self.max_gain_db, lo=-100.0, hi=300.0)
        if self.k not in (20, 30, 40):
            raise ConfigError(f"TVG.k must be 20, 30 or 40 (dB per decade), got {self.k!r}")

    def check_range(self, max_range_m: float, alpha_db_per_m: float) -> None:
        """Refuse a gain G(R_max) whose voltage factor 10^(G/20) overflows float64 (an absorption in dB/km
        given as dB/m, say): the record would be all full-scale codes; warn above :data:`MAX_DEVICE_TVG_DB`."""
        g = float(self.gain_db(max_range_m, alpha_db_per_m))
        if g / 20.0 > MAX_GAIN_DECADES:
            raise ConfigError(f"Receiver TVG: the gain reaches {g:.0f} dB at max_range_m = {max_range_m:g} m with "
                              f"{alpha_db_per_m:g} dB/m absorption, beyond float64 (every sample would clip); lower "
                              "the absorption (a value in dB/km?) or max_range_m, or set TVG(absorption=False)")
        if g > MAX_DEVICE_TVG_DB:
            warn_once(f"Receiver TVG: the gain reaches {g:.0f} dB at max_range_m = {max_range_m:g} m, beyond "
                      f"the {MAX_DEVICE_TVG_DB:g} dB a device's TVG spans; the far range will clip")

    def gain_db(self, range_m: np.ndarray, alpha_db_per_m: float) -> np.ndarray:
        """G(R) in dB for slant ranges ``range_m`` (m; held at G(max(R0, 1 m)) below R0 and 1 m, and at the
        ceiling ``max_gain_db`` above it)."""
        r = np.maximum(np.asarray(range_m, dtype=float), max(self.start_range_m, 1.0))
        g = self.g0_db + self.k * np.log10(r) + (2.0 * alpha_db_per_m * r if self.absorption else 0.0)
        return g if self.max_gain_db is None else np.minimum(g, self.max_gain_db)


@dataclass(frozen=True)
class AGC:
    """Automatic gain control: each sample's gain brings the moving RMS of the signal to ``target``·V_fs, up
    to ``max_gain_db``.

    Parameters
    ----------
    window_s : float
        Length of the centred moving mean of v², s.
    target : float
        Wanted RMS as a fraction of full scale, in (0, 1).
    max_gain_db : float
        The amplifier's largest gain, dB (default 160 dB: a −180 dB re 1 V/µPa hydrophone brought from 1 µPa
        to 0.1 V). Without a bound, a record with no noise would have its round-off (1e-187 µPa²) stretched
        to full scale; a real amplifier saturates.
    """

    window_s: float = 5e-3
    target: float = 0.25
    max_gain_db: float = 160.0

    def check_range(self, max_range_m: float, alpha_db_per_m: float) -> None:
        """Nothing to refuse before a run: an AGC's gain follows the signal, bounded by ``max_gain_db``."""

    def __post_init__(self):
        check_number("AGC", "window_s", self.window_s, positive=True, hi=10.0)
        check_number("AGC", "target", self.target, positive=True, hi=1.0)
        check_number("AGC", "max_gain_db", self.max_gain_db, lo=0.0, hi=300.0)


@dataclass(frozen=True)
class Receiver:
    """A device's receive chain: hydrophone sensitivity, a gain law and an ADC.

    Parameters
    ----------
    sensitivity_db : float
        Receiving sensitivity with the preamplifier, dB re 1 V/µPa (typically −200 to −160).
    gain : TVG or AGC
        The gain law (default: 30·log10 R + 2αR from 20 dB at 1 m).
    adc_bits : int
        ADC resolution, 1 to 16 bits: samples are uint8 up to 8 bits, uint16 above.
    full_scale_v : float
        ADC full scale, V (the envelope clips there).
    encoding : {"linear", "log"}
        How codes map to volts: linear steps of Δ = V_fs/(2^b − 1), or logarithmic over the top
        ``log_range_db`` below full scale.
    log_range_db : float
        D, the dynamic range of the logarithmic encoding, dB (default 96).
    bandwidth_hz : float or None
        The receiver's band-pass around the carrier, Hz (its noise bandwidth B): the noise per sample is then
        N0·B, correlated as the filter makes it, instead of white over the record's sample band (default None:
        white over the band). At least the pulse's bandwidth (the echoes are taken to pass unchanged).
    """

    sensitivity_db: float = -180.0
    gain: TVG | AGC = TVG()
    adc_bits: int = 16
    full_scale_v: float = 1.0
    encoding: str = "linear"
    log_range_db: float = 96.0
    bandwidth_hz: float | None = None

    def __post_init__(self):
        check_number("Receiver", "sensitivity_db", self.sensitivity_db, lo=-260.0, hi=-100.0)
        check_number("Receiver", "full_scale_v", self.full_scale_v, positive=True, hi=1e3)
        if isinstance(self.adc_bits, bool) or not isinstance(self.adc_bits, (int, np.integer)) \
                or not 1 <= self.adc_bits <= 16:
            raise ConfigError(f"Receiver.adc_bits must be an integer in 1 … 16, got {self.adc_bits!r}")
        if self.encoding not in ("linear", "log"):
            raise ConfigError(f"Receiver.encoding must be 'linear' or 'log', got {self.encoding!r}")
        check_number("Receiver", "log_range_db", self.log_range_db, positive=True, hi=400.0)
        if self.bandwidth_hz is not None:
            check_number("Receiver", "bandwidth_hz", self.bandwidth_hz, positive=True, hi=1e8)
        object.__setattr__(self, "gain", _gain(self.gain))

    @property
    def dtype(self):
        """numpy dtype of the samples: uint8 up to 8 bits, else uint16."""
        return np.uint8 if self.adc_bits <= 8 else np.uint16

    @property
    def step_v(self) -> float:
        """Δ = V_fs/(2^b − 1), V."""
        return self.full_scale_v / (2 ** self.adc_bits - 1)

    def volts(self, intensity_upa2) -> np.ndarray:
        """Hydrophone output, V rms, for mean-square pressures in µPa²."""
        return 10.0 ** (self.sensitivity_db / 20.0) * np.sqrt(np.maximum(intensity_upa2, 0.0))

    def digitise(self, volts) -> np.ndarray:
        """The ADC: round to the nearest of 2^b levels (Δ apart, or D/(2^b − 1) dB apart with the logarithmic
        encoding), clip to [0, 2^b − 1]; ``dtype`` codes."""
        top = 2 ** self.adc_bits - 1
        v = np.asarray(volts, dtype=float)
        if self.encoding == "linear":
            code = np.rint(v / self.step_v)
        else:
            with np.errstate(divide="ignore"):
                level_db = 20.0 * np.log10(v / self.full_scale_v)
            code = np.rint((level_db + self.log_range_db) / self.log_range_db * top)
        return np.clip(code, 0, top).astype(self.dtype)

    def gained(self, volts: np.ndarray, time_s: np.ndarray, sound_speed_m_s: float, alpha_db_per_m: float,
               sample_rate_hz: float) -> np.ndarray:
        """``volts`` (…, n) after the gain law, time along the last axis."""
        g = self.gain
        if isinstance(g, TVG):
            return volts * 10.0 ** (g.gain_db(0.5 * sound_speed_m_s * time_s, alpha_db_per_m) / 20.0)
        from scipy.ndimage import uniform_filter1d

        n = max(int(round(g.window_s * sample_rate_hz)), 1)
        rms = np.sqrt(uniform_filter1d(volts * volts, n, axis=-1, mode="nearest"))
        with np.errstate(divide="ignore", invalid="ignore"):
            gain = np.minimum((g.target * self.full_scale_v) / rms, 10.0 ** (g.max_gain_db / 20.0))
        return np.where(rms > 0, volts * gain, 0.0)

    def samples(self, intensity_upa2, time_s, sonar) -> np.ndarray:
        """The device's integer samples (same shape as ``intensity_upa2``, µPa², time on the last axis)."""
        if isinstance(self.gain, TVG):
            self.gain.check_range(0.5 * sonar.sound_speed_m_s * float(np.max(time_s, initial=0.0)),
                                  sonar.alpha_db_per_m)
        v = self.gained(self.volts(intensity_upa2), time_s, sonar.sound_speed_m_s, sonar.alpha_db_per_m,
                        sonar.sample_rate_hz)
        return self.digitise(v)

    def header_codes(self) -> dict:
        """What a device writes in its XTF channel headers: the gain law as codes (see :mod:`.io.xtf`)."""
        g = self.gain
        tvg = isinstance(g, TVG)
        return {"InitialGainCode": int(round(min(max(g.g0_db, 0.0), 65535.0))) if tvg else 0,
                "GainCode": int(g.k) if tvg else 0, "MillivoltScale": int(round(min(1e3 * self.full_scale_v,
                                                                                    65535.0)))}


def _gain(value):
    """A TVG or AGC from itself or a dict ``{kind = "tvg" | "agc", …}`` (TOML, a record's metadata)."""
    if isinstance(value, (TVG, AGC)):
        return value
    if not isinstance(value, dict):
        raise ConfigError(f"Receiver.gain must be a sonar_embree.TVG or AGC, got {value!r}")
    value = dict(value)
    kind = value.pop("kind", "agc" if "window_s" in value or "target" in value else "tvg")
    cls = {"tvg": TVG, "agc": AGC}.get(kind)
    if cls is None:
        raise ConfigError(f"Receiver.gain: kind must be 'tvg' or 'agc', got {kind!r}")
    return from_table(cls, value, f"Receiver.gain ({kind})")


def receiver_of(value):
    """A Receiver from itself, None or a dict (TOML ``receiver = {…}``, a record's metadata)."""
    if value is None or isinstance(value, Receiver):
        return value
    if not isinstance(value, dict):
        raise ConfigError(f"Sonar.receiver must be a sonar_embree.Receiver or None, got {value!r}")
    return from_table(Receiver, value, "Sonar.receiver")


__all__ = ["AGC", "Receiver", "TVG"]
