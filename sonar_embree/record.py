"""Simulation results: :class:`Record`, its file format (npz) and its waterfall PNG."""
from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass, field

import numpy as np

from .config import Pulse, Sonar
from .errors import ConfigError
from .io.files import atomic_write
from .labels import Labels
from .trajectory import Trajectory

FORMAT_VERSION = 2


@dataclass(frozen=True, eq=False)
class Record:
    """Port and starboard time series of every ping, with their axes and poses.

    Attributes
    ----------
    port, starboard : (n_pings, n_samples) float64
        Linear intensity (unit source: on-axis intensity 1 at 1 m).
    time_s : (n_samples,) float64
        Time from the start of transmission, s.
    trajectory : Trajectory
        The pose of every ping.
    sonar : Sonar
    pulse : Pulse
    altitude_m : (n_pings,) float64
        Distance to the first surface straight below the sonar (NaN if none in range).
    attrs : dict
        Mode, seed and other settings.
    labels : Labels or None
        Per-sample ground truth (``simulate(labels=True)``), aligned with ``port`` and
        ``starboard``.
    port_complex, starboard_complex : (n_pings, n_samples) complex128 or None
        Detected complex baseband (``simulate(keep_complex=True)``); intensity = |·|².
    """

    port: np.ndarray
    starboard: np.ndarray
    time_s: np.ndarray
    trajectory: Trajectory
    sonar: Sonar
    pulse: Pulse
    altitude_m: np.ndarray
    attrs: dict = field(default_factory=dict)
    labels: Labels | None = None
    port_complex: np.ndarray | None = None
    starboard_complex: np.ndarray | None = None

    @property
    def slant_range_m(self) -> np.ndarray:
        """Slant range of each sample, R = c·t/2 (m), shape (n_samples,)."""
        return 0.5 * self.sonar.sound_speed_m_s * self.time_s

    @property
    def n_pings(self) -> int:
        return self.port.shape[0]

    @classmethod
    def concatenate(cls, parts) -> "Record":
        """Join records of consecutive pieces of one survey (simulated with ``ping_offset``)."""
        parts = list(parts)
        if not parts:
            raise ConfigError("Record.concatenate needs at least one record")
        first = parts[0]
        for p in parts[1:]:
            if p.sonar != first.sonar or p.pulse != first.pulse or not np.array_equal(p.time_s, first.time_s):
                raise ConfigError("Record.concatenate: the records differ in sonar, pulse or time axis")
        attrs = dict(first.attrs)
        if "rays_per_ping" in attrs:
            n = np.array([p.n_pings for p in parts], dtype=float)
            attrs["rays_per_ping"] = float(np.dot(n, [p.attrs["rays_per_ping"] for p in parts]) / n.sum())
        labels = None if first.labels is None else Labels.concatenate([p.labels for p in parts])
        cplx = {k: (None if getattr(first, k) is None else np.concatenate([getattr(p, k) for p in parts]))
                for k in ("port_complex", "starboard_complex")}
        return cls(np.concatenate([p.port for p in parts]), np.concatenate([p.starboard for p in parts]),
                   first.time_s, Trajectory.concatenate([p.trajectory for p in parts]), first.sonar, first.pulse,
                   np.concatenate([p.altitude_m for p in parts]), attrs, labels, **cplx)

    # ------------------------------------------------------------------ files
    def save(self, path) -> None:
        """Write the record to ``path`` (.npz); written atomically."""
        from ._version import __version__

        meta = {"format_version": FORMAT_VERSION, "package_version": __version__,
                "sonar": dataclasses.asdict(self.sonar), "pulse": dataclasses.asdict(self.pulse),
                "attrs": self.attrs}
        t = self.trajectory
        extra = {}
        if self.labels is not None:
            meta["labels"] = {"names": list(self.labels.names), "is_seafloor": list(self.labels.is_seafloor)}
            extra = {f"labels_{k}": getattr(self.labels, k) for k in Labels.ARRAYS}
        for k in ("port_complex", "starboard_complex"):
            if getattr(self, k) is not None:
                extra[k] = getattr(self, k)

        def write(tmp):
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, port=self.port, starboard=self.starboard, time_s=self.time_s,
                                    altitude_m=self.altitude_m, positions_m=t.positions_m,
                                    heading_deg=t.heading_deg, pitch_deg=t.pitch_deg, roll_deg=t.roll_deg,
                                    times_s=t.times_s, meta=np.array(json.dumps(meta)), **extra)

        atomic_write(path, write, suffix=".npz")

    @classmethod
    def load(cls, path) -> "Record":
        """Read a record written by :meth:`save`."""
        path = os.fspath(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                arrays = {k: z[k] for k in z.files if k != "meta"}
        except (OSError, ValueError, KeyError) as exc:
            raise ConfigError(f"{path}: not a sonar_embree record ({exc})") from None
        traj = Trajectory(arrays["positions_m"], arrays["heading_deg"], arrays["pitch_deg"],
                          arrays["roll_deg"], arrays["times_s"])
        labels = None
        if "labels" in meta:
            shape = arrays["labels_kind"].shape  # files of format 1 have no echo truth
            fill = {"echo_object": np.full(shape, -1, np.int32), "echo_intensity": np.zeros(shape, np.float32)}
            labels = Labels(**{k: arrays.get(f"labels_{k}", fill.get(k)) for k in Labels.ARRAYS},
                            names=tuple(meta["labels"]["names"]),
                            is_seafloor=tuple(meta["labels"]["is_seafloor"]))
        return cls(arrays["port"], arrays["starboard"], arrays["time_s"], traj, Sonar(**meta["sonar"]),
                   Pulse(**meta["pulse"]), arrays["altitude_m"], meta.get("attrs", {}), labels,
                   arrays.get("port_complex"), arrays.get("starboard_complex"))

    def to_xarray(self):
        """The record as an ``xarray.Dataset`` (see :func:`sonar_embree.io.dataset.to_xarray`)."""
        from .io.dataset import to_xarray

        return to_xarray(self)

    def to_zarr(self, path) -> None:
        """Write a Zarr store that ``xarray.open_zarr`` opens lazily; atomic (see :mod:`sonar_embree.io.dataset`)."""
        from .io.dataset import to_zarr

        to_zarr(self, path)

    def to_xtf(self, path, start=None, *, scale="auto", surface_z_m: float | None = None) -> None:
        """Write an XTF file (2 sonar channels, one packet per ping) that pyxtf reads; atomic.

        Samples are float32 intensity × ``scale`` ("auto": a power of ten that makes
        the image visible in viewers, written in the header); port is stored from far
        range to nadir, starboard from nadir outwards; ping times from ``start``
        (default ``attrs["start_time"]``). Conventions in :mod:`sonar_embree.io.xtf`.
        """
        from .io.xtf import to_xtf

        to_xtf(self, path, start=start, scale=scale, surface_z_m=surface_z_m)

    def to_coco(self, path, file_name: str = "waterfall.png", categories=None, max_columns: int | None = 1024):
        """Write COCO JSON with each object's box in the waterfall PNG ``file_name``; atomic.

        The PNG must be written with the same ``max_columns`` (:meth:`save_png`).
        See :func:`sonar_embree.io.coco.coco_dict`.
        """
        from .io.coco import coco_dict, write_json

        write_json(coco_dict(self, file_name, categories=categories, max_columns=max_columns), path)

    def waterfall(self, **kwargs) -> np.ndarray:
        """The waterfall as an 8-bit image; keywords as :func:`sonar_embree.waterfall.waterfall_image`."""
        from .waterfall import waterfall_image

        return waterfall_image(self, **kwargs)

    def save_png(self, path, **kwargs) -> None:
        """Write the waterfall PNG (port mirrored on the left, starboard on the right); atomic."""
        import imageio.v3 as iio

        img = self.waterfall(**kwargs)
        atomic_write(path, lambda tmp: iio.imwrite(tmp, img, extension=".png"), suffix=".png")
