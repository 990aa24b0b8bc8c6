"""A record as an xarray Dataset and as a Zarr store (the only module importing xarray)."""
from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile

import numpy as np

from ..labels import KIND_NAMES, SIDES, Labels

#: Pings per Zarr chunk (each chunk holds whole pings).
PING_CHUNK = 256


def _flat_attrs(record) -> dict:
    from .. import __version__

    attrs = {"package": "sonar_embree", "package_version": __version__,
             "sample_order": "sample n at time n/fs from the start of transmission, both channels"}
    for group, obj in (("sonar", record.sonar), ("pulse", record.pulse)):
        for k, v in dataclasses.asdict(obj).items():
            attrs[f"{group}.{k}"] = v
    for k, v in record.attrs.items():
        attrs[f"simulation.{k}"] = v
    return attrs


def to_xarray(record):
    """The record as an ``xarray.Dataset``.

    Variables: ``port``, ``starboard`` (ping, sample) linear intensity (and
    ``port_complex``, ``starboard_complex`` when the record keeps them); ``x_m``,
    ``y_m``, ``z_m``, ``heading_deg``, ``pitch_deg``, ``roll_deg``, ``altitude_m``
    (ping); with labels ``label_kind``, ``label_object_id``, ``label_shadow_of``,
    ``label_height_m``, ``label_ground_range_m`` (side, ping, sample). Coordinates
    ``time_s`` and ``slant_range_m`` (sample), ``ping_time_s`` (ping), ``side``.
    Attributes: every sonar, pulse and signal-chain setting (``sonar.*``,
    ``pulse.*``, ``simulation.*`` including the seed) and the package version.
    """
    import xarray as xr

    t = record.trajectory
    data = {"port": (("ping", "sample"), record.port, {"units": "1", "long_name": "port intensity, unit source"}),
            "starboard": (("ping", "sample"), record.starboard,
                          {"units": "1", "long_name": "starboard intensity, unit source"}),
            "altitude_m": (("ping",), record.altitude_m, {"units": "m"})}
    for side in ("port", "starboard"):
        z = getattr(record, f"{side}_complex")
        if z is not None:
            data[f"{side}_complex"] = (("ping", "sample"), z, {"long_name": f"{side} complex baseband, |.|^2 = {side}"})
    for i, axis in enumerate("xyz"):
        data[f"{axis}_m"] = (("ping",), t.positions_m[:, i], {"units": "m"})
    for name in ("heading_deg", "pitch_deg", "roll_deg"):
        data[name] = (("ping",), getattr(t, name), {"units": "degree"})
    coords = {"time_s": (("sample",), record.time_s, {"units": "s"}),
              "slant_range_m": (("sample",), record.slant_range_m, {"units": "m"}),
              "ping_time_s": (("ping",), t.times_s, {"units": "s"})}
    attrs = _flat_attrs(record)
    if record.labels is not None:
        lab = record.labels
        for k in Labels.ARRAYS:
            data[f"label_{k}"] = (("side", "ping", "sample"), getattr(lab, k), {})
        data["label_kind"][2].update(flag_values=list(range(len(KIND_NAMES))), flag_meanings=" ".join(KIND_NAMES))
        data["label_height_m"][2]["units"] = data["label_ground_range_m"][2]["units"] = "m"
        coords["side"] = (("side",), list(SIDES))
        attrs["labels.names"] = list(lab.names)
        attrs["labels.is_seafloor"] = [int(x) for x in lab.is_seafloor]
    return xr.Dataset(data, coords=coords, attrs=attrs)


def replace_dir(path, write_fn) -> None:
    """Call ``write_fn(tmp_dir_path)`` then move the finished folder onto ``path``: never half a store."""
    path = os.path.abspath(os.fspath(path))
    parent = os.path.dirname(path)
    tmp = tempfile.mkdtemp(dir=parent, prefix=".tmp-")
    target = os.path.join(tmp, os.path.basename(path))
    old = None
    try:
        write_fn(target)
        if os.path.exists(path):
            old = tempfile.mkdtemp(dir=parent, prefix=".old-")
            os.replace(path, os.path.join(old, "x"))
        os.replace(target, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def to_zarr(record, path) -> None:
    """Write the record's :func:`to_xarray` dataset as a Zarr (format 2, consolidated) store; atomic.

    ``xarray.open_zarr(path)`` opens it lazily (dask arrays, whole pings per chunk).
    """
    ds = to_xarray(record)
    chunk = min(PING_CHUNK, record.n_pings)
    encoding = {name: {"chunks": tuple(chunk if d == "ping" else ds.sizes[d] for d in var.dims)}
                for name, var in ds.data_vars.items()}
    replace_dir(path, lambda tmp: ds.to_zarr(tmp, mode="w", zarr_format=2, consolidated=True, encoding=encoding))
