"""Every output format in one registry: the API, ``render`` and ``batch`` all write through it.

A format is a file name and a ``write(record, path, options)``; each writer is
atomic on its own (:mod:`sonar_embree.io.files`). A new format is one writer function
and one :class:`OutputFormat` line in :data:`FORMATS`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..errors import ConfigError
from ..io.geotiff import write_grid
from ..io.owner import OutputFolder
from ..io.xtf import geographic, to_xtf
from ..signal.interferometry import interferometric_points
from ..signal.sas import record_image
from ..sonars.forward_looking import save_fan_png
from ..sonars.msis import save_polar_png


@dataclass(frozen=True)
class WriteOptions:
    """What the writers need beyond the record.

    Attributes
    ----------
    display : dict
        Waterfall display keywords (:func:`sonar_embree.display.waterfall.waterfall_image`,
        ``max_columns`` included): the PNG, and the columns of the label PNG and COCO boxes.
    categories : sequence of str, optional
        COCO categories (default: the record's objects).
    image_id : int
        COCO image id.
    bathymetry_pixel_m : float
        The soundings grid's pixel, m (the bathymetry GeoTIFF).
    sas_grid : dict, optional
        The SAS image's grid (the ``sas`` output): ``x_m`` and ``y_m`` ([min, max] world m), ``pixel_m`` and
        optionally ``z_m`` (the grid's world height, default 0), ``channel`` ("port" or "starboard", default
        starboard) and ``taper`` (side-lobe weighting in [0, 0.5], default 0; 0.46 is Hamming's,
        :func:`~sonar_embree.signal.sas.record_image`); :func:`check_sas_grid`.
    cache : dict
        What one record's writers share (its soundings, made once for both outputs that need them).
    """

    display: dict = field(default_factory=dict)
    categories: tuple | None = None
    image_id: int = 0
    bathymetry_pixel_m: float = 0.5
    sas_grid: dict | None = None
    cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def max_columns(self):
        return self.display.get("max_columns", 1024)


def _npz(rec, path, o):
    rec.save(path)


def _png(rec, path, o):
    rec.save_png(path, **o.display)


def _labels(rec, path, o):
    rec.labels.save_png(path, o.max_columns)


def _coco(rec, path, o):
    from .coco import coco_dict, write_json

    write_json(coco_dict(rec, "waterfall.png", categories=o.categories, image_id=o.image_id,
                         max_columns=o.max_columns), path)


def _zarr(rec, path, o):
    from .dataset import to_zarr

    to_zarr(rec, path)


def _polar(rec, path, o):
    save_polar_png(rec, path)


def _fan(rec, path, o):
    save_fan_png(rec, path)


def _xtf(rec, path, o):
    to_xtf(rec, path)


def _placed(rec):
    """(CRS, east and north offsets in m) of a record's world frame: its trajectory's CRS, else the UTM zone of a
    local scene placed with ``geo_origin_deg`` (its origin there, as its XTF's lat/lon,
    :func:`~sonar_embree.io.xtf.geographic`), else (None, 0, 0): the GeoTIFFs in local metres."""
    geo = geographic(rec)
    return (None, 0.0, 0.0) if geo is None else (geo[0], geo[1][0], geo[1][1])


def _soundings(rec, o: WriteOptions):
    """The interferometric soundings of a record's elements 0 and 1 (coherence at least 0.5), made once per record
    for the options' writers, or a one-line error."""
    if rec.element_data is None or rec.element_data.shape[2] < 2:
        raise ConfigError("outputs 'soundings' and 'bathymetry' need a sonar with a receive_array of at least two "
                          "elements across track (an interferometer)")
    held = o.cache.get("soundings")
    if held is None or held[0] is not rec:
        o.cache["soundings"] = held = (rec, interferometric_points(rec, min_coherence=0.5))
    return held[1]


def _xyz(rec, path, o):
    _soundings(rec, o).to_xyz(path)


def _bathymetry(rec, path, o):
    crs, east, north = _placed(rec)
    points = _soundings(rec, o)
    replace(points, xyz_m=points.xyz_m + [east, north, 0.0], crs=crs).to_geotiff(path, o.bathymetry_pixel_m)


#: The most pixels a SAS image may have (a backprojection costs pings × elements per pixel).
MAX_SAS_PIXELS = 4_000_000
#: The keys of ``[output] sas_grid`` and whether each is needed.
SAS_GRID_KEYS = {"x_m": True, "y_m": True, "pixel_m": True, "z_m": False, "channel": False, "taper": False}


def check_sas_grid(grid, where: str = "[output] sas_grid") -> dict:
    """``grid`` (:attr:`WriteOptions.sas_grid`) with its defaults, or a one-line error naming the key."""
    if not isinstance(grid, dict):
        raise ConfigError(f"{where} must be a table with x_m = [min, max], y_m = [min, max] and pixel_m, got {grid!r}")
    unknown = [k for k in grid if k not in SAS_GRID_KEYS]
    missing = [k for k, need in SAS_GRID_KEYS.items() if need and k not in grid]
    if unknown or missing:
        raise ConfigError(f"{where}: " + (f"unknown key {unknown[0]!r}" if unknown else f"needs {missing[0]!r}"))
    out = {"z_m": 0.0, "channel": "starboard", "taper": 0.0, **grid}
    for k in ("x_m", "y_m"):
        v = out[k]
        if not (isinstance(v, (list, tuple)) and len(v) == 2 and all(_number(x) for x in v) and v[0] < v[1]):
            raise ConfigError(f"{where}: {k} must be [min, max] in metres with min < max, got {v!r}")
    if not (_number(out["pixel_m"]) and out["pixel_m"] > 0) or not _number(out["z_m"]):
        raise ConfigError(f"{where}: pixel_m must be a number > 0 and z_m a number, got {out['pixel_m']!r}, "
                          f"{out['z_m']!r}")
    if out["channel"] not in ("port", "starboard"):
        raise ConfigError(f"{where}: channel must be 'port' or 'starboard', got {out['channel']!r}")
    if not (_number(out["taper"]) and 0.0 <= out["taper"] <= 0.5):
        raise ConfigError(f"{where}: taper must be a number in [0, 0.5] (0.46: Hamming), got {out['taper']!r}")
    n = _sas_axes(out)
    if n[0].size * n[1].size > MAX_SAS_PIXELS:
        raise ConfigError(f"{where}: {n[0].size} × {n[1].size} pixels; at most {MAX_SAS_PIXELS} (a larger pixel_m "
                          "or a smaller area)")
    return out


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def _sas_axes(grid: dict):
    """(x, y) pixel centres of a checked grid, each from its min by pixel_m (world m)."""
    p = float(grid["pixel_m"])
    return tuple(lo + p * (0.5 + np.arange(max(int(np.floor((hi - lo) / p + 1e-9)), 1))) for lo, hi in
                 (grid["x_m"], grid["y_m"]))


def _sas(rec, path, o):
    """The backprojected SAS image (:func:`sonar_embree.signal.sas.record_image`) of a receiver-array record on
    ``o.sas_grid``: a north-up GeoTIFF in the record's CRS (:func:`_placed`), bands intensity (|image|²) and its
    level in dB."""
    if o.sas_grid is None:
        raise ConfigError("output 'sas' needs [output] sas_grid = { x_m = [min, max], y_m = [min, max], pixel_m = … }")
    g = check_sas_grid(o.sas_grid)
    x, y = _sas_axes(g)
    intensity = np.abs(record_image(rec, x, y, float(g["z_m"]), g["channel"], taper=float(g["taper"]))) ** 2
    with np.errstate(divide="ignore"):
        db = 10.0 * np.log10(intensity)
    p = float(g["pixel_m"])
    crs, east, north = _placed(rec)
    write_grid(path, np.stack([intensity, np.where(np.isfinite(db), db, np.nan)])[:, ::-1], float(x[0] - p / 2) + east,
               float(y[-1] + p / 2) + north, p, crs, names=("intensity", "level_db"), units=("1", "dB"))


@dataclass(frozen=True)
class OutputFormat:
    """One output format: its name (the key in configs), its file name and its writer."""

    name: str
    file_name: str
    write: Callable
    needs_labels: bool = False
    description: str = ""


#: The formats, in the order they are written.
FORMATS = {f.name: f for f in (
    OutputFormat("zarr", "record.zarr", _zarr, description="CF-style Zarr store (xarray, NetCDF-writable)"),
    OutputFormat("xtf", "record.xtf", _xtf, description="eXtended Triton Format, pyxtf-readable"),
    OutputFormat("png", "waterfall.png", _png, description="8-bit waterfall image"),
    OutputFormat("polar", "polar.png", _polar, description="8-bit polar display of an MSIS scan (MSIS only)"),
    OutputFormat("fan", "fan.png", _fan, description="8-bit fan display of a forward-looking ping (the middle one)"),
    OutputFormat("labels", "labels.png", _labels, needs_labels=True, description="per-pixel class image"),
    OutputFormat("coco", "coco.json", _coco, needs_labels=True, description="COCO boxes and masks"),
    OutputFormat("npz", "record.npz", _npz, description="the whole record (Record.load)"),
    OutputFormat("soundings", "soundings.xyz", _xyz,
                 description="interferometric soundings, x y z (a receive_array's elements 0 and 1)"),
    OutputFormat("bathymetry", "bathymetry.tif", _bathymetry,
                 description="the soundings gridded: height, coherence, count (GeoTIFF)"),
    OutputFormat("sas", "sas.tif", _sas,
                 description="the backprojected SAS image of a receive_array record on [output] sas_grid (GeoTIFF)"),
)}


def check(names, where: str = "outputs") -> tuple:
    """The format names, validated (one-line error naming an unknown one)."""
    names = tuple(names)
    for n in names:
        if not isinstance(n, str) or n not in FORMATS:
            raise ConfigError(f"{where}: unknown output format {n!r} (known: {', '.join(FORMATS)})")
    return names


def _wanted(rec, names) -> list:
    """The formats ``names`` in writing order; each that needs labels finds them in ``rec``."""
    wanted = [FORMATS[n] for n in FORMATS if n in check(names)]
    for f in wanted:
        if f.needs_labels and rec.labels is None:
            raise ConfigError(f"output {f.name!r} needs labels: simulate with labels=True")
    return wanted


def write_each(rec, folder: str, names, options: WriteOptions | None = None) -> list:
    """Write the formats ``names`` of ``rec`` into ``folder``, each file atomically; return the paths."""
    options = WriteOptions() if options is None else options
    paths = []
    for f in _wanted(rec, names):
        path = os.path.join(folder, f.file_name)
        f.write(rec, path, options)
        paths.append(path)
    return paths


def file_names(names) -> list:
    """The file names the formats ``names`` write (what a run claims in its folder before any work)."""
    return [FORMATS[n].file_name for n in check(names)]


def write_set(rec, folder, names, options: WriteOptions | None = None, *, overwrite: bool = False) -> list:
    """Write the formats into ``folder`` so that the new set lands together (:meth:`OutputFolder.write_set`).

    ``folder`` is an :class:`~sonar_embree.io.owner.OutputFolder` a run claimed before its work, or a path,
    claimed here: new or empty, or (``overwrite``) holding earlier outputs of this project that its manifest
    lists unchanged; a user's file in a target's place is refused, never replaced."""
    options = WriteOptions() if options is None else options
    wanted = _wanted(rec, names)
    if not isinstance(folder, OutputFolder):
        folder = OutputFolder.claim(folder, [f.file_name for f in wanted], overwrite=overwrite, command="write_set")
    return folder.write_set([(f.file_name, (lambda p, f=f: f.write(rec, p, options))) for f in wanted])
