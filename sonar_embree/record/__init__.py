"""Simulation results: :class:`Record`, its file format (npz) and its waterfall PNG."""
from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass, field

import numpy as np

from ..config import Acquisition, Pulse, split_medium
from ..environment import Environment
from ..errors import ConfigError
from ..io.files import atomic_write
from ..signal.labels import Labels
from ..sonars import SONAR_TYPES
from ..trajectory import Trajectory
from ..display.waterfall import waterfall_image

FORMAT_VERSION = 2


@dataclass(frozen=True, eq=False)
class Record:
    """The time series of every ping and channel, with their axes and poses.

    Attributes
    ----------
    data : (n_pings, n_channels, n_samples) float64
        Linear intensity (unit source: on-axis intensity 1 at 1 m).
    time_s : (n_samples,) float64
        Time from the start of transmission, s.
    trajectory : Trajectory
        The pose of every ping.
    sonar : Sonar, EchoSounder, MSIS or ForwardLooking
        The sonar type and its settings (the instrument alone).
    pulse : Pulse
    altitude_m : (n_pings,) float64
        Distance to the first surface straight below the sonar (NaN if none in range).
    attrs : dict
        Mode, seed and other settings.
    labels : Labels or None
        Per-sample ground truth (``simulate(labels=True)``), aligned with the channels.
    complex_data : (n_pings, n_channels, n_samples) complex128 or None
        Detected complex baseband (``simulate(keep_complex=True)``); intensity = |·|².
    channels : tuple of str
        The channel names (side-scan: ``("port", "starboard")``); ``port``,
        ``starboard`` (and ``port_complex``, ``starboard_complex``) read them, shape
        (n_pings, n_samples).
    samples : (n_pings, n_channels, n_samples) uint8 or uint16, or None
        The integers the sonar's :class:`~sonar_embree.Receiver` stores (gain, ADC), beside the
        physical ``data``; None without a receiver.
    element_data : (n_pings, n_channels, n_elements, n_samples) complex128 or None
        A receiver array's complex baseband per element (:class:`~sonar_embree.ReceiverArray`; matched-filtered
        and TVG'd as ``complex_data``); element 0 is the channel's ``data``. None without an array.
    environment : Environment
        The medium the record was simulated in (sound speed, absorption, surface, profile, noise).
    """

    data: np.ndarray
    time_s: np.ndarray
    trajectory: Trajectory
    sonar: object
    pulse: Pulse
    altitude_m: np.ndarray
    attrs: dict = field(default_factory=dict)
    labels: Labels | None = None
    complex_data: np.ndarray | None = None
    channels: tuple = ("port", "starboard")
    samples: np.ndarray | None = None
    element_data: np.ndarray | None = None
    environment: Environment = Environment()

    def __post_init__(self):
        if self.data.ndim != 3 or self.data.shape[1] != len(self.channels):
            raise ConfigError(f"Record.data must have shape (pings, {len(self.channels)} channels, samples), "
                              f"got {self.data.shape}")
        if self.samples is not None and self.samples.shape != self.data.shape:
            raise ConfigError(f"Record.samples must have the shape of data {self.data.shape}, got {self.samples.shape}")
        e = self.element_data
        if e is not None and (e.ndim != 4 or e.shape[:2] != self.data.shape[:2] or e.shape[3] != self.data.shape[2]):
            raise ConfigError(f"Record.element_data must have shape (pings, channels, elements, samples) matching data "
                              f"{self.data.shape}, got {e.shape}")

    def channel(self, name: str, complex_: bool = False) -> np.ndarray:
        """The (n_pings, n_samples) series of channel ``name`` (the complex signal with ``complex_``)."""
        if name not in self.channels:
            raise ConfigError(f"this record has no channel {name!r} (it has {', '.join(self.channels)})")
        src = self.complex_data if complex_ else self.data
        return None if src is None else src[:, self.channels.index(name)]

    @property
    def port(self) -> np.ndarray:
        return self.channel("port")

    @property
    def starboard(self) -> np.ndarray:
        return self.channel("starboard")

    @property
    def port_complex(self):
        return self.channel("port", complex_=True)

    @property
    def starboard_complex(self):
        return self.channel("starboard", complex_=True)

    @property
    def acquisition(self) -> Acquisition:
        """The sonar in the record's medium: c, λ, k, α, the beam and its DI
        (:class:`~sonar_embree.config.Acquisition`)."""
        return Acquisition(self.sonar, self.environment)

    @property
    def slant_range_m(self) -> np.ndarray:
        """Slant range of each sample, R = c·t/2 (m), shape (n_samples,)."""
        return 0.5 * self.environment.sound_speed_m_s * self.time_s

    @property
    def n_pings(self) -> int:
        return self.data.shape[0]

    @classmethod
    def concatenate(cls, parts) -> "Record":
        """Join records of consecutive pieces of one survey (simulated with ``ping_offset``)."""
        parts = list(parts)
        if not parts:
            raise ConfigError("Record.concatenate needs at least one record")
        first = parts[0]
        for p in parts[1:]:
            if (p.sonar != first.sonar or p.pulse != first.pulse or p.channels != first.channels
                    or p.environment != first.environment or not np.array_equal(p.time_s, first.time_s)):
                raise ConfigError("Record.concatenate: the records differ in sonar, medium, pulse, channels or time "
                                  "axis")
        attrs = dict(first.attrs)
        if "rays_per_ping" in attrs:
            n = np.array([p.n_pings for p in parts], dtype=float)
            attrs["rays_per_ping"] = float(np.dot(n, [p.attrs["rays_per_ping"] for p in parts]) / n.sum())
        labels = None if first.labels is None else Labels.concatenate([p.labels for p in parts])
        cplx = None if first.complex_data is None else np.concatenate([p.complex_data for p in parts])
        ints = None if first.samples is None else np.concatenate([p.samples for p in parts])
        elements = None if first.element_data is None else np.concatenate([p.element_data for p in parts])
        return cls(np.concatenate([p.data for p in parts]), first.time_s,
                   Trajectory.concatenate([p.trajectory for p in parts]), first.sonar, first.pulse,
                   np.concatenate([p.altitude_m for p in parts]), attrs, labels, cplx, first.channels, ints, elements,
                   first.environment)

    # ------------------------------------------------------------------ files
    def metadata(self) -> dict:
        """What a file needs beside the arrays to make this record again: format, sonar, pulse, settings, channels,
        the trajectory's CRS and start time, the labels' names (JSON-serialisable)."""
        from .._version import __version__

        meta = {"format_version": FORMAT_VERSION, "package_version": __version__,
                "sonar": dataclasses.asdict(self.sonar), "environment": dataclasses.asdict(self.environment),
                "pulse": dataclasses.asdict(self.pulse),
                "attrs": self.attrs}
        meta["sonar_type"], meta["channels"] = type(self.sonar).__name__, list(self.channels)
        meta["trajectory"] = {"crs": self.trajectory.crs, "start_time": self.trajectory.start_time}
        if self.labels is not None:
            meta["labels"] = {"names": list(self.labels.names), "is_seafloor": list(self.labels.is_seafloor)}
        return meta

    def save(self, path) -> None:
        """Write the record to ``path`` (.npz); written atomically."""
        meta = self.metadata()
        t = self.trajectory
        extra = {}
        if self.labels is not None:
            extra = {f"labels_{k}": getattr(self.labels, k) for k in Labels.ARRAYS}
        if self.complex_data is not None:
            extra.update({f"{ch}_complex": self.channel(ch, complex_=True) for ch in self.channels})
        if self.samples is not None:
            extra["samples"] = self.samples
        if self.element_data is not None:
            extra["element_data"] = self.element_data
        if t.velocity_m_s is not None:
            extra["velocity_m_s"] = t.velocity_m_s
        if t.ship_positions_m is not None:
            extra["ship_positions_m"] = t.ship_positions_m
        if t.fix_times_s is not None:
            extra["fix_times_s"] = t.fix_times_s
        series = {ch: self.channel(ch) for ch in self.channels}

        def write(tmp):
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **series, time_s=self.time_s,
                                    altitude_m=self.altitude_m, positions_m=t.positions_m,
                                    heading_deg=t.heading_deg, pitch_deg=t.pitch_deg, roll_deg=t.roll_deg,
                                    times_s=t.times_s, meta=np.array(json.dumps(meta)), **extra)

        atomic_write(path, write, suffix=".npz")

    @classmethod
    def load(cls, path) -> "Record":
        """Read a record written by :meth:`save` (.npz), or open a Zarr store written by :meth:`to_zarr` or streamed
        by :func:`~sonar_embree.survey.stream.render_line` (a folder) lazily: its intensities (and labels) stay on disk
        as dask arrays, read a block of pings at a time by what uses them (:meth:`save_png` draws any length)."""
        path = os.fspath(path)
        if os.path.isdir(path):
            return cls._open_store(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                arrays = {k: z[k] for k in z.files if k != "meta"}
        except (OSError, ValueError, KeyError) as exc:
            raise ConfigError(f"{path}: not a sonar_embree record ({exc})") from None
        channels = tuple(meta.get("channels", ("port", "starboard")))
        parts = dict(arrays, data=np.stack([arrays[ch] for ch in channels], axis=1), labels=None,
                     complex_data=(np.stack([arrays[f"{ch}_complex"] for ch in channels], axis=1)
                                   if f"{channels[0]}_complex" in arrays else None))
        if "labels" in meta:
            shape = arrays["labels_kind"].shape  # files of format 1 have no echo truth
            fill = {"echo_object": np.full(shape, -1, np.int32), "echo_intensity": np.zeros(shape, np.float32)}
            parts["labels"] = {k: arrays.get(f"labels_{k}", fill.get(k)) for k in Labels.ARRAYS}
        return cls._assemble(meta, parts)

    @classmethod
    def _open_store(cls, path) -> "Record":
        """The record of a Zarr store, its arrays left on disk (:func:`sonar_embree.record.dataset.open_parts`)."""
        from .dataset import open_parts

        parts = open_parts(path)
        return cls._assemble(parts.pop("meta"), parts)

    @classmethod
    def _assemble(cls, meta: dict, p: dict) -> "Record":
        """A record from its :meth:`metadata` and its arrays ``p``: data, complex_data and samples (or None),
        labels (name → array, or None), time_s, altitude_m and the trajectory's positions_m, heading_deg,
        pitch_deg, roll_deg, times_s (velocity_m_s, ship_positions_m and fix_times_s when present)."""
        geo = meta.get("trajectory", {})
        traj = Trajectory(p["positions_m"], p["heading_deg"], p["pitch_deg"], p["roll_deg"], p["times_s"],
                          p.get("velocity_m_s"), geo.get("crs"), geo.get("start_time"), p.get("ship_positions_m"),
                          p.get("fix_times_s"))
        labels = None
        if p.get("labels") is not None:
            labels = Labels(**p["labels"], names=tuple(meta["labels"]["names"]),
                            is_seafloor=tuple(meta["labels"]["is_seafloor"]))
        sonar_cls = {c.__name__: c for c in SONAR_TYPES}[meta.get("sonar_type", "Sonar")]
        # files written before the medium left the sonar hold it in the sonar's table (older ones as its keys)
        table, env = split_medium(meta["sonar"], sonar_cls.__name__, meta.get("environment"))
        return cls(p["data"], p["time_s"], traj, sonar_cls(**table), Pulse(**meta["pulse"]), p["altitude_m"],
                   meta.get("attrs", {}), labels, p.get("complex_data"),
                   tuple(meta.get("channels", ("port", "starboard"))), p.get("samples"), p.get("element_data"), env)

    def to_xarray(self):
        """The record as an ``xarray.Dataset`` (see :func:`sonar_embree.record.dataset.to_xarray`)."""
        from .dataset import to_xarray

        return to_xarray(self)

    def to_zarr(self, path) -> None:
        """Write a Zarr store that ``xarray.open_zarr`` opens lazily; atomic (see
        :mod:`sonar_embree.record.dataset`)."""
        from .dataset import to_zarr

        to_zarr(self, path)

    def to_xtf(self, path, start=None, *, scale="auto", surface_z_m: float | None = None, samples: bool = True,
               samples_per_channel: int | None = None, decimation: str = "max") -> None:
        """Write an XTF file (2 sonar channels, one packet per ping) that pyxtf reads; atomic.

        A record with a receiver's integer ``samples`` is written as the device would (``samples=False``:
        floats). Float samples are intensity × ``scale`` ("auto": a power of ten that makes
        the image visible in viewers, written in the header); port is stored from far
        range to nadir, starboard from nadir outwards; ping times from ``start``
        (default ``attrs["start_time"]``); ``samples_per_channel`` decimates each side to that many samples as a
        device does, by each run's largest sample or its mean (``decimation``). Conventions in
        :mod:`sonar_embree.io.xtf`.
        """
        from ..io.xtf import to_xtf

        to_xtf(self, path, start=start, scale=scale, surface_z_m=surface_z_m, samples=samples,
               samples_per_channel=samples_per_channel, decimation=decimation)

    def to_coco(self, path, file_name: str = "waterfall.png", categories=None, max_columns: int | None = 1024):
        """Write COCO JSON with each object's box in the waterfall PNG ``file_name``; atomic.

        The PNG must be written with the same ``max_columns`` (:meth:`save_png`).
        See :func:`sonar_embree.record.coco.coco_dict`.
        """
        from .coco import coco_dict, write_json

        write_json(coco_dict(self, file_name, categories=categories, max_columns=max_columns), path)

    def waterfall(self, **kwargs) -> np.ndarray:
        """The waterfall as an 8-bit image; keywords as :func:`sonar_embree.display.waterfall.waterfall_image`."""
        return waterfall_image(self, **kwargs)

    def save_png(self, path, **kwargs) -> None:
        """Write the waterfall PNG (port mirrored on the left, starboard on the right); atomic."""
        import imageio.v3 as iio

        img = self.waterfall(**kwargs)
        atomic_write(path, lambda tmp: iio.imwrite(tmp, img, extension=".png"), suffix=".png")
