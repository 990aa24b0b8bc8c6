"""Ground truth aligned sample for sample with a record: what each sample sees (:class:`Labels`).

How it is made is :mod:`sonar_embree.signal.truth` (:class:`~sonar_embree.signal.truth.GroundTruth`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..display.waterfall import waterfall_block
from ..io.files import atomic_write

#: ``Labels.kind`` values.
WATER, SEAFLOOR, OBJECT, SHADOW = 0, 1, 2, 3
KIND_NAMES = ("water", "seafloor", "object", "shadow")
SIDES = ("port", "starboard")
#: Colours of the label preview PNG, by kind: water black, seafloor grey, object yellow, shadow blue.
KIND_COLOURS = np.array([[0, 0, 0], [110, 110, 110], [255, 210, 0], [30, 90, 255]], dtype=np.uint8)
#: A sample belongs to an object's echo where that object's expected echo is at least this fraction
#: of its peak in the record (10 %, −10 dB) and stronger than any other object's there.
ECHO_FRACTION = 0.1


@dataclass(frozen=True, eq=False)
class Labels:
    """Per-sample ground truth, each array shaped (channels, n_pings, n_samples): the record's channels (a
    side-scan's side 0 port, 1 starboard; an MSIS's beam; a forward-looking sonar's beams).

    Attributes
    ----------
    kind : int8
        0 water column (no surface at this range), 1 seafloor, 2 object, 3 shadow.
    object_id : int32
        Index (into ``names``) of the object whose echo dominates the sample; −1 for
        water and shadow.
    shadow_of : int32
        For shadow samples the object that casts the shadow (the first surface the
        centre-line ray hits), else −1.
    height_m : float32
        World z of the surface point at the sample's slant range (for shadow: of the
        hidden seafloor), m; NaN for water.
    ground_range_m : float32
        Horizontal distance from the sonar to that point, m; NaN for water. Negative where the point lies on the
        other side of the track (a side-scan side hearing the seabed past nadir: near a DEM's edge, say), so that
        a sample is placed where its echo truly came from.
    echo_object : int32
        Object (not seafloor) whose expected echo, over every azimuth line of the
        fan, is the strongest at this sample; −1 where no object echoes. This is
        what the waterfall shows of the objects: boxes and masks follow it.
    echo_intensity : float32
        That object's expected echo intensity (unit source, no TVG); 0 where none.
    names : tuple of str
        Object labels of the scene, by object index.
    is_seafloor : tuple of bool
        Which objects are seafloor.
    """

    kind: np.ndarray
    object_id: np.ndarray
    shadow_of: np.ndarray
    height_m: np.ndarray
    ground_range_m: np.ndarray
    echo_object: np.ndarray
    echo_intensity: np.ndarray
    names: tuple
    is_seafloor: tuple

    ARRAYS = ("kind", "object_id", "shadow_of", "height_m", "ground_range_m", "echo_object", "echo_intensity")
    DTYPES = {"kind": np.int8, "object_id": np.int32, "shadow_of": np.int32, "height_m": np.float32,
              "ground_range_m": np.float32, "echo_object": np.int32, "echo_intensity": np.float32}

    def __post_init__(self):
        shape = self.kind.shape
        if len(shape) != 3 or shape[0] < 1:
            raise ConfigError(f"Labels arrays must be shaped (channels, n_pings, n_samples), got {shape}")
        for name in self.ARRAYS:
            if getattr(self, name).shape != shape:
                raise ConfigError(f"Labels.{name} has shape {getattr(self, name).shape}, expected {shape}")
        if len(self.names) != len(self.is_seafloor):
            raise ConfigError("Labels.names and Labels.is_seafloor differ in length")

    @property
    def highlight(self) -> np.ndarray:
        """(2, n_pings, n_samples) bool: samples whose echo comes from an object (not seafloor)."""
        return self.kind == OBJECT

    @property
    def shadow(self) -> np.ndarray:
        """(2, n_pings, n_samples) bool: seafloor hidden from the sonar by something nearer."""
        return self.kind == SHADOW

    def seafloor_class(self) -> np.ndarray:
        """(2, n_pings, n_samples) int32: the seafloor object (e.g. sediment class of
        :meth:`Scene.add_sediments`) under each seafloor sample, −1 elsewhere."""
        return np.where(self.kind == SEAFLOOR, self.object_id, -1).astype(np.int32)

    @property
    def objects(self) -> tuple:
        """Indices of the objects that are not seafloor."""
        return tuple(i for i, f in enumerate(self.is_seafloor) if not f)

    @classmethod
    def concatenate(cls, parts) -> "Labels":
        """Join labels of consecutive ping ranges of one survey."""
        parts = list(parts)
        arrays = {k: np.concatenate([getattr(p, k) for p in parts], axis=1) for k in cls.ARRAYS}
        return cls(**arrays, names=parts[0].names, is_seafloor=parts[0].is_seafloor)

    # ------------------------------------------------------------- waterfall
    def waterfall(self, name: str = "kind", max_columns: int | None = 1024) -> np.ndarray:
        """One label array in the layout of :meth:`Record.waterfall` (port mirrored on the left).

        When the waterfall averages blocks of samples into one column (``max_columns``),
        a column takes the value of the block's first sample that is not water (kind 0);
        float arrays take the block's first finite value.

        Returns
        -------
        (n_pings, 2·n_columns) array of the label's dtype.
        """
        if name not in self.ARRAYS:
            raise ConfigError(f"unknown label array {name!r}; one of {self.ARRAYS}")
        block = waterfall_block(self.kind.shape[2], max_columns)
        sides = []
        for side in range(self._image_channels()):
            a = getattr(self, name)[side]
            keep = self.kind[side] != WATER
            sides.append(_block_first(a, keep, block))
        return sides[0] if len(sides) == 1 else np.concatenate([sides[0][:, ::-1], sides[1]], axis=1)

    def _image_channels(self) -> int:
        """Channels of the waterfall image (2: port mirrored on the left; 1: the one channel)."""
        n = self.kind.shape[0]
        if n > 2:
            raise ConfigError(f"label images are waterfalls of one or two channels; these labels have {n} "
                              "(a multibeam's: use the arrays, channels × pings × samples)")
        return n

    def echo_mask(self, i: int, fraction: float = ECHO_FRACTION) -> np.ndarray:
        """(2, n_pings, n_samples) bool: where object ``i``'s echo is the strongest object echo and at
        least ``fraction`` of its peak in this record (what the waterfall shows of it)."""
        mine = self.echo_object == i
        if not mine.any():
            return mine
        peak = float(self.echo_intensity[mine].max())
        return mine & (self.echo_intensity >= fraction * peak) & (peak > 0)

    def boxes(self, max_columns: int | None = 1024, source: str = "echo") -> list:
        """Bounding boxes of every object in the waterfall image.

        Parameters
        ----------
        max_columns : int or None
            As :meth:`Record.waterfall`.
        source : {"echo", "centre"}
            "echo" (default): the object's echo as the waterfall shows it, from
            every azimuth line (:meth:`echo_mask`); "centre": the geometric truth of
            each ping's centre line (``kind == OBJECT``).

        Returns
        -------
        list of dict
            ``object`` (index), ``label``, ``bbox`` [x, y, width, height] in pixels
            (x the column, y the ping row; a box covers whole pixels), ``area``
            (pixels), ``mask`` (the object's (rows, columns) bool image) and
            ``shadow_bbox`` (the box of the shadow it casts along the centre lines,
            or None). Objects with no pixel are left out.
        """
        if source not in ("echo", "centre"):
            raise ConfigError(f"Labels.boxes source must be 'echo' or 'centre', got {source!r}")
        out = []
        for i in self.objects:
            sel = self.echo_mask(i) if source == "echo" else (self.kind == OBJECT) & (self.object_id == i)
            mask = self.mask(sel, max_columns)
            if not mask.any():
                continue
            shadow = self.mask((self.kind == SHADOW) & (self.shadow_of == i), max_columns)
            out.append({"object": i, "label": self.names[i], "bbox": _bbox(mask), "area": int(mask.sum()),
                        "mask": mask, "shadow_bbox": _bbox(shadow) if shadow.any() else None})
        return out

    def save_png(self, path, max_columns: int | None = 1024, preview: bool = True) -> None:
        """Write the kind of every waterfall pixel as a single-channel class-index PNG (0 water,
        1 seafloor, 2 object, 3 shadow: :data:`KIND_NAMES`) and, with ``preview``, a colour
        version beside it (``*_preview.png``); atomic."""
        import os

        import imageio.v3 as iio


        kind = self.waterfall("kind", max_columns).astype(np.uint8)
        atomic_write(path, lambda tmp: iio.imwrite(tmp, kind, extension=".png"), suffix=".png")
        if preview:
            root, ext = os.path.splitext(os.fspath(path))
            atomic_write(f"{root}_preview{ext}", lambda tmp: iio.imwrite(tmp, KIND_COLOURS[kind], extension=".png"),
                         suffix=".png")

    def mask(self, selected: np.ndarray, max_columns: int | None = 1024) -> np.ndarray:
        """A (2, n_pings, n_samples) bool selection as a waterfall image: a pixel is set when
        any of its samples is.

        Returns
        -------
        (n_pings, 2·n_columns) bool
        """
        block = waterfall_block(self.kind.shape[2], max_columns)
        sides = []
        for side in range(self._image_channels()):
            m = selected[side]
            pad = (-m.shape[1]) % block
            sides.append(np.pad(m, ((0, 0), (0, pad))).reshape(m.shape[0], -1, block).any(axis=2))
        return sides[0] if len(sides) == 1 else np.concatenate([sides[0][:, ::-1], sides[1]], axis=1)


def _block_first(a, keep, block):
    """Per block of columns: the first value where ``keep`` (else the first value)."""
    if block <= 1:
        return a.copy()
    n_p, n = a.shape
    pad = (-n) % block
    ap = np.pad(a, ((0, 0), (0, pad)), mode="edge").reshape(n_p, -1, block)
    kp = np.pad(keep, ((0, 0), (0, pad))).reshape(n_p, -1, block)
    first = np.argmax(kp, axis=2)  # 0 where no sample is kept: the block's first value
    return np.take_along_axis(ap, first[..., None], axis=2)[..., 0]


def _bbox(mask) -> list:
    rows = np.nonzero(mask.any(axis=1))[0]
    cols = np.nonzero(mask.any(axis=0))[0]
    return [int(cols[0]), int(rows[0]), int(cols[-1] - cols[0] + 1), int(rows[-1] - rows[0] + 1)]
