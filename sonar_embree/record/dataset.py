"""A record as an xarray Dataset and as a Zarr store (the only module importing xarray)."""
from __future__ import annotations

import dataclasses
import json
import os
import shutil
import tempfile

import numpy as np

from ..signal.labels import KIND_NAMES, SIDES, Labels
from ..errors import ConfigError

#: Pings per Zarr chunk (each chunk holds whole pings).
PING_CHUNK = 256


#: The global attribute holding the record's metadata as JSON (sonar, pulse, settings; :meth:`Record.metadata`).
RECORD_ATTR = "sonar_embree_record"

#: CF conventions the datasets follow.
CONVENTIONS = "CF-1.10"


def _attr_value(v):
    """A value NetCDF can store: bool → 0/1, lists of those, everything else as is (None is dropped)."""
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (list, tuple)):
        return [_attr_value(x) for x in v]
    if isinstance(v, np.generic):
        return v.item()
    return v


def _flat_attrs(record) -> dict:
    """Global attributes: every sonar, environment, pulse and simulation setting, typed; unset (None) settings left out."""
    from .._version import __version__

    attrs = {"Conventions": CONVENTIONS, "title": "simulated side-scan sonar record",
             "source": f"sonar_embree {__version__} (ray-traced side-scan simulation)",
             "package": "sonar_embree", "package_version": __version__,
             "sample_order": "sample n at time n/fs from the start of transmission, both channels",
             "intensity_reference": ("unit source: on-axis intensity 1 at 1 m (docs/physics.md section 3)"
                                     if record.sonar.source_level_db is None else
                                     f"source level {record.sonar.source_level_db:g} dB re 1 uPa at 1 m: intensities in "
                                     "uPa^2 (docs/physics.md section 14)")}
    for group, obj in (("sonar", record.sonar), ("environment", record.environment), ("pulse", record.pulse)):
        for k, v in dataclasses.asdict(obj).items():
            if v is not None and not isinstance(v, dict):
                attrs[f"{group}.{k}"] = _attr_value(v)
    rx = record.sonar.receiver
    if rx is not None:
        for k, v in dataclasses.asdict(rx).items():
            for kk, vv in (v.items() if isinstance(v, dict) else ((None, v),)):
                if vv is not None:  # unset (a TVG without a ceiling, a receiver without a band)
                    attrs[f"receiver.{k}" + ("" if kk is None else f".{kk}")] = _attr_value(vv)
        attrs["receiver.gain.kind"] = type(rx.gain).__name__.lower()
    for k, v in record.attrs.items():
        if v is not None:
            attrs[f"simulation.{k}"] = _attr_value(v)
    return attrs


def _ping_coords(record) -> dict:
    """Per-ping coordinates: navigation, attitude and time (CF standard names where they exist)."""
    t = record.trajectory
    coords = {}
    for i, (axis, std, way) in enumerate((("x", "projection_x_coordinate", "east"),
                                          ("y", "projection_y_coordinate", "north"), ("z", None, "up"))):
        meta = {"units": "m", "long_name": f"sonar position, world {axis} ({way})"}
        if std:
            meta["standard_name"] = std
        coords[f"{axis}_m"] = (("ping",), t.positions_m[:, i], meta)
        if t.ship_positions_m is not None and axis != "z":          # towed: the ship's antenna ahead of it
            coords[f"ship_{axis}_m"] = (("ping",), t.ship_positions_m[:, i], {
                "units": "m", "long_name": f"ship (navigation) position, world {axis} ({way})"})
    for name, std, what in (("heading_deg", "platform_yaw", "clockwise from north"),
                            ("pitch_deg", "platform_pitch", "positive nose up"),
                            ("roll_deg", "platform_roll", "positive starboard down")):
        coords[name] = (("ping",), getattr(t, name), {"units": "degree", "standard_name": std,
                                                      "long_name": f"{name[:-4]}, {what}"})
    coords["ping_time_s"] = (("ping",), t.times_s, {"units": "s", "long_name": "ping time from start_time"})
    if t.fix_times_s is not None:
        coords["fix_time_s"] = (("ping",), t.fix_times_s, {"units": "s", "long_name": "time of the ping's last "
                                                           "navigation fix from start_time"})
    start = record.attrs.get("start_time")
    if start is not None:
        stamp = start.replace("+00:00", "")
        coords["ping_time"] = (("ping",), t.times_s, {"units": f"seconds since {stamp}", "calendar": "standard",
                                                      "standard_name": "time", "long_name": "ping time (UTC)"})
    if t.crs is not None:
        from ..io.geo import to_lonlat

        lon, lat = to_lonlat(t.crs, t.positions_m[:, 0], t.positions_m[:, 1])
        coords["lon"] = (("ping",), lon, {"units": "degrees_east", "standard_name": "longitude",
                                          "long_name": "sonar longitude (WGS 84)"})
        coords["lat"] = (("ping",), lat, {"units": "degrees_north", "standard_name": "latitude",
                                          "long_name": "sonar latitude (WGS 84)"})
    return coords


def _crs_variable(crs: str) -> tuple:
    """The CF grid-mapping variable of a projected CRS (its WKT, which GDAL and pyproj read back)."""
    from ..io.geo import crs_wkt

    wkt = crs_wkt(crs)
    return ((), np.int32(0), {"crs_wkt": wkt, "spatial_ref": wkt, "long_name": f"coordinate reference system {crs}",
                              "epsg_code": crs})


def to_xarray(record):
    """The record as a CF-style ``xarray.Dataset`` (writable as NetCDF with ``to_netcdf``).

    Variables: one per channel, ``port``, ``starboard`` for a side-scan (ping,
    sample), linear intensity (a multibeam, :class:`~sonar_embree.ForwardLooking`: one ``intensity`` (ping, beam,
    sample) with the coordinate ``beam_angle_deg``) (and ``port_complex``, ``starboard_complex`` when the record keeps them: NetCDF needs
    ``to_netcdf(..., auto_complex=True)`` for those); with a receiver array ``port_elements``, ``starboard_elements``
    (ping, element, sample) complex and the coordinates ``element_forward_m``, ``element_outward_m``,
    ``element_up_m`` (element); ``altitude_m`` (ping); with
    labels ``label_kind``, ``label_object_id``, ``label_shadow_of``,
    ``label_height_m``, ``label_ground_range_m`` (side, ping, sample). Coordinates
    ``time_s`` and ``slant_range_m`` (sample); per ping ``x_m``, ``y_m``, ``z_m``,
    ``heading_deg``, ``pitch_deg``, ``roll_deg``, ``ping_time_s`` and ``ping_time``
    (CF time, seconds since the record's start time), and ``lon``, ``lat`` (WGS 84) with a ``crs`` grid-mapping
    variable (its WKT) when the trajectory has a CRS; ``side``. Every variable has
    ``units`` and ``long_name``, and a CF ``standard_name`` where one exists.
    Attributes: ``Conventions``, every sonar, pulse and signal-chain setting that is
    set (``sonar.*``, ``pulse.*``, ``simulation.*`` including the seed; booleans as
    0/1) and the package version.
    """
    import xarray as xr

    sl = record.sonar.source_level_db

    def intensity(side):
        if sl is None:
            return {"units": "1", "long_name": f"{side} intensity for a unit source (linear)"}
        return {"units": "uPa2", "long_name": f"{side} mean-square pressure at the receiver, source level {sl:g} dB "
                                              "re 1 uPa at 1 m"}

    beams = record.sonar.forms_beams                                 # a multibeam: one (ping, beam, sample) array
    data = _beam_variables(record, intensity) if beams else _channel_variables(record, intensity)
    data |= {"altitude_m": (("ping",), record.altitude_m, {"units": "m", "standard_name": "height_above_sea_floor",
                                                          "long_name": "range to the first surface below the sonar"})}
    coords = {"time_s": (("sample",), record.time_s,
                         {"units": "s", "long_name": "time from the start of transmission"}),
              "slant_range_m": (("sample",), record.slant_range_m, {"units": "m", "long_name": "slant range c t / 2"}),
              **_ping_coords(record)}
    coords |= record.sonar.dataset_coords(int(record.attrs.get("first_ping", 0)), record.n_pings)
    if record.element_data is not None:
        offsets = np.asarray(record.sonar.receive_array.positions_m)
        for i, (axis, text) in enumerate((("forward", "along the vehicle's forward axis"),
                                          ("outward", "towards the side's look direction"), ("up", "upwards"))):
            coords[f"element_{axis}_m"] = (("element",), offsets[:, i], {
                "units": "m", "long_name": f"receive element's offset from the transmitter, {text}"})
    attrs = _flat_attrs(record)
    attrs["channels"] = "intensity" if beams else " ".join(record.channels)
    attrs[RECORD_ATTR] = json.dumps(record.metadata())   # what Record.load needs to open the store as a record
    if record.trajectory.crs is not None:  # CF: data on projected x, y name their grid mapping
        data["crs"] = _crs_variable(record.trajectory.crs)
        for ch in (("intensity",) if beams else record.channels):
            data[ch][2]["grid_mapping"] = "crs"
    if record.labels is not None:
        _label_variables(record.labels, data, coords, attrs, tuple(record.channels), beams)
    return xr.Dataset(data, coords=coords, attrs=attrs)


def _channel_variables(record, intensity) -> dict:
    """One (ping, sample) variable per channel, with its complex signal and ADC codes when the record has them."""
    sl = record.sonar.source_level_db
    data = {ch: (("ping", "sample"), record.channel(ch), intensity(ch)) for ch in record.channels}
    for side in record.channels:
        z = record.channel(side, complex_=True)
        if z is not None:
            data[f"{side}_complex"] = (("ping", "sample"), z, {"units": "1" if sl is None else "uPa",
                                                              "long_name": f"{side} complex baseband, |.|^2 = {side}"})
    if record.element_data is not None:  # a receiver array: every element's complex series
        for i, side in enumerate(record.channels):
            data[f"{side}_elements"] = (("ping", "element", "sample"), record.element_data[:, i], {
                "units": "1" if sl is None else "uPa",
                "long_name": f"{side} complex baseband of each receive element (element 0: |.|^2 = {side})"})
    if record.samples is not None:  # the device's integers (Receiver), beside the physical intensity
        rx = record.sonar.receiver
        for i, side in enumerate(record.channels):
            data[f"{side}_samples"] = (("ping", "sample"), record.samples[:, i],
                                       {"units": "1", "long_name": f"{side} ADC codes ({rx.adc_bits} bits, "
                                                                   f"full scale {rx.full_scale_v:g} V) after the gain"})
    return data


def _beam_variables(record, intensity) -> dict:
    """A multibeam's ``intensity`` (ping, beam, sample), and ``intensity_complex`` / ``samples`` likewise."""
    dims = ("ping", "beam", "sample")
    data = {"intensity": (dims, record.data, intensity("beam"))}
    if record.complex_data is not None:
        data["intensity_complex"] = (dims, record.complex_data, {
            "units": "1" if record.sonar.source_level_db is None else "uPa",
            "long_name": "beam complex baseband, |.|^2 = intensity"})
    if record.samples is not None:
        rx = record.sonar.receiver
        data["samples"] = (dims, record.samples, {"units": "1", "long_name": f"beam ADC codes ({rx.adc_bits} bits, "
                                                                            f"full scale {rx.full_scale_v:g} V)"})
    return data


def _label_variables(lab, data, coords, attrs, channels=SIDES, beams: bool = False) -> None:
    """The labels as (side, ping, sample) variables of a side-scan, (beam, ping, sample) of a multibeam (on the
    intensity's beam dimension), (channel, ping, sample) of other types (an MSIS: its one channel is named
    "beam", a data variable, so the dimension cannot be)."""
    meta = {"kind": {"units": "1", "long_name": "what the sample sees",
                     "flag_values": np.arange(len(KIND_NAMES), dtype=lab.kind.dtype),
                     "flag_meanings": " ".join(KIND_NAMES)},
            "object_id": {"units": "1", "long_name": "index into labels.names of the echoing object, -1 none"},
            "shadow_of": {"units": "1", "long_name": "index into labels.names of the shadow's caster, -1 none"},
            "height_m": {"units": "m", "long_name": "world z of the surface point seen"},
            "ground_range_m": {"units": "m", "long_name": "horizontal range to the surface point seen, negative past nadir on the other side"},
            "echo_object": {"units": "1", "long_name": "index into labels.names of the strongest object echo, -1 none"},
            "echo_intensity": {"units": "1", "long_name": "expected intensity of that object echo, unit source"}}
    dim = "side" if tuple(channels) == tuple(SIDES) else ("beam" if beams else "channel")
    for k in Labels.ARRAYS:
        data[f"label_{k}"] = ((dim, "ping", "sample"), getattr(lab, k), meta[k])
    coords[dim] = ((dim,), list(channels), {"long_name": "sonar channel"})
    attrs["labels.names"] = list(lab.names)
    attrs["labels.is_seafloor"] = [int(x) for x in lab.is_seafloor]


def is_own_store(path: str) -> bool:
    """Whether the folder ``path`` is a Zarr store this package wrote (its consolidated metadata says so)."""
    import json

    try:
        with open(os.path.join(path, ".zmetadata"), encoding="utf-8") as fh:
            meta = json.load(fh)
        return meta["metadata"][".zattrs"].get("package") == "sonar_embree"
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return False


def replace_dir(path, write_fn) -> None:
    """Call ``write_fn(tmp_dir_path)`` then move the finished folder onto ``path``: never half a store. What is
    at ``path`` must be nothing, an empty folder or a store this package wrote: anything else is refused."""
    path = os.path.abspath(os.fspath(path))
    parent = os.path.dirname(path)
    if not os.path.isdir(parent):
        raise ConfigError(f"{path}: its folder {parent} does not exist")
    if os.path.exists(path) and not (os.path.isdir(path) and (not os.listdir(path) or is_own_store(path))):
        raise ConfigError(f"{path}: exists and is not a Zarr store written by sonar_embree; it would be replaced, so "
                          "choose another path (or remove it yourself)")
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


def open_parts(path) -> dict:
    """What :meth:`Record.load` needs to open a Zarr store this package wrote (:meth:`Record.to_zarr`, a streamed
    line) as a record, lazily: the metadata (``meta``), ``data``, ``complex_data``, ``samples`` (ping, channel,
    sample), ``element_data`` (ping, channel, element, sample) and the labels' arrays (``labels``: name → (channel,
    ping, sample)) as dask arrays; the axes and poses
    (``time_s``, ``altitude_m``, ``positions_m``, ``heading_deg``, ``pitch_deg``, ``roll_deg``, ``times_s``,
    ``ship_positions_m``) read in full. A store without the record's metadata is refused in one line."""
    import xarray as xr


    if not is_own_store(path):
        raise ConfigError(f"{path}: not a Zarr store written by sonar_embree")
    ds = xr.open_zarr(path)
    if RECORD_ATTR not in ds.attrs:
        raise ConfigError(f"{path}: the store has no record metadata (written by an older sonar_embree)")
    meta = json.loads(ds.attrs[RECORD_ATTR])
    channels = tuple(meta.get("channels", ("port", "starboard")))
    _check_chunks(path, ds, [*channels, "intensity", *(f"{c}_complex" for c in channels)])
    data, cplx, ints = _lazy_arrays(ds, channels, ds.attrs.get("channels") == "intensity")
    n = ds.sizes["ping"]
    ship = (np.column_stack([ds["ship_x_m"].values, ds["ship_y_m"].values, np.zeros(n)])
            if "ship_x_m" in ds.coords else None)
    labels = {k: ds[f"label_{k}"].data for k in Labels.ARRAYS} if "labels" in meta else None
    names = [f"{ch}_elements" for ch in channels]
    elements = (xr.concat([ds[n] for n in names], dim="channel").transpose("ping", "channel", "element", "sample").data
                if all(n in ds for n in names) else None)
    return dict(meta=meta, data=data, complex_data=cplx, samples=ints, labels=labels, element_data=elements,
                time_s=ds["time_s"].values,
                altitude_m=ds["altitude_m"].values, positions_m=np.column_stack([ds[f"{a}_m"].values for a in "xyz"]),
                heading_deg=ds["heading_deg"].values, pitch_deg=ds["pitch_deg"].values,
                roll_deg=ds["roll_deg"].values, times_s=ds["ping_time_s"].values, ship_positions_m=ship,
                fix_times_s=ds["fix_time_s"].values if "fix_time_s" in ds.coords else None)


def _check_chunks(path, ds, names) -> None:
    """Refuse a store whose data variables ``names`` (those present) miss chunk files: Zarr reads a missing chunk
    as its fill value (NaN), so a deleted or never-written chunk would load as plausible-looking NaN pings."""
    for name in names:
        if name not in ds:
            continue
        var = ds[name]
        chunks = var.encoding.get("chunks") or var.shape
        want = int(np.prod([-(-n // max(c, 1)) for n, c in zip(var.shape, chunks)]))
        folder = os.path.join(os.fspath(path), name)
        have = sum(1 for f in os.listdir(folder) if not f.startswith(".")) if os.path.isdir(folder) else want
        if have < want:
            raise ConfigError(f"{path}: variable {name!r} lacks {want - have} of its {want} chunks (deleted, or a "
                              "streamed line not finished); the store is incomplete")


def _lazy_arrays(ds, channels, beams: bool):
    """(data, complex data or None, codes or None) of a store as (ping, channel, sample) dask arrays (stacked by
    xarray: batch.py stays the one module importing dask)."""
    import xarray as xr

    if beams:
        pick = [("intensity",), ("intensity_complex",), ("samples",)]
        return tuple(ds[n[0]].data if n[0] in ds else None for n in pick)
    out = []
    for suffix in ("", "_complex", "_samples"):
        names = [f"{ch}{suffix}" for ch in channels]
        out.append(xr.concat([ds[n] for n in names], dim="channel").transpose("ping", "channel", "sample").data
                   if all(n in ds for n in names) else None)
    return tuple(out)
