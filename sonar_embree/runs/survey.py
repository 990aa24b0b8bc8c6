"""A survey as a surveyor runs it: a DEM, navigation logs and a device preset → per line XTF, Zarr and a waterfall
PNG, and the survey's mosaic, bathymetry truth and quick look (``sonar-embree survey``; docs/guide/surveys.md).

Each navigation log (CSV with lat/lon or projected positions and times, or an XTF) is one line: projected into
the DEM's CRS, its heading taken from the track where it has none, resampled at the device's ping rate for the
range setting (its stated rate, else back to back), the sonar towed ``layback_m`` (or a ``cable_out_m`` cable)
behind it when given, and streamed with labels into the line's folder (resumable: a rerun continues each line
where it stopped). The preset's sonar records through the device's receiver (:meth:`Device.receiver`: its ADC's
bits where stated, its TVG set per line by :func:`line_receiver`, or an AGC with ``gain="agc"``).
"""
from __future__ import annotations

import dataclasses
import json
import logging
import math
import os

import numpy as np

from ..config import Acquisition, Material, Pulse, Sonar
from ..laws import sediments
from ..errors import ConfigError
from ..instrument import devices
from ..io.owner import OutputFolder
from ..io.geo import crs_name, from_lonlat
from ..io.geotiff import sample_points
from ..scene import Scene, TiledDEM, load_mesh, seafloor
from ..propagation.prepared import RunCache
from ..simulate import simulate
from ..survey import mosaic, stream
from ..survey.planning import line_trajectories, plan_lines
from ..trajectory import Trajectory, csv_header
from ..validation import check_number, read_numeric_csv
from .runconfig import _check_keys, _resolve, read_toml

log = logging.getLogger(__name__)

#: The file marking a folder as a survey's output (refused otherwise unless overwrite).
SUMMARY = "survey.json"


def run_survey(dem, navs, out, device: str, *, range_m: float | None = None, ping_rate_hz: float | None = None,
               layback_m: float | None = None, cable_out_m: float | None = None, pixel_m: float = 0.5,
               quality: float = 1.0, speckle: bool = False, overwrite: bool = False, progress: bool = True,
               plan=None, depth_m: float | None = None, speed_m_s: float = 2.0, overlap: float = 0.2,
               crs=None, workers: int | None = None, scheduler: str | None = None,
               altitude_m: float | None = None, gain: str = "tvg", labels: bool = True,
               sediment: str | None = None) -> list:
    """Run the survey; returns the files written (the summary last).

    Parameters
    ----------
    dem : str or PathLike
        A GeoTIFF DEM in a projected CRS (metres; z = 0 the sea surface), read tile by tile; or a mesh file
        (OBJ, PLY, STL, GLB in projected metres, z up) taken whole as the seafloor, in ``crs``.
    navs : sequence of str or PathLike
        Navigation logs, one per line (.csv as :meth:`Trajectory.from_csv`, .xtf as :meth:`Trajectory.from_xtf`);
        empty with ``plan``.
    out : str or PathLike
        Output folder: new, empty, or an earlier survey's (its survey.json); anything else is refused unless
        ``overwrite``.
    device : str
        A preset of :data:`sonar_embree.instrument.devices.DEVICES`: its sonar, pulse and ping rates.
    range_m, ping_rate_hz : float, optional
        The range setting (default the preset's first) and the ping rate (default the device's for that range).
    layback_m, cable_out_m : float, optional
        A towed sonar (:meth:`Trajectory.with_layback`): its horizontal distance behind the navigation, or the
        cable out from the surface.
    pixel_m : float
        The mosaic's pixel, m.
    quality, speckle
        As for :func:`~sonar_embree.simulate`.
    overwrite, progress : bool
    plan : str or PathLike, optional
        Instead of logs: a polygon CSV (columns x_m, y_m in the DEM's CRS, or lat_deg, lon_deg) covered by
        parallel lines (:func:`~sonar_embree.survey.planning.plan_lines`, ``overlap`` of the swaths) flown at
        ``speed_m_s`` with the sonar ``depth_m`` below the surface.
    labels : bool
        Write each line's per-sample ground truth into its Zarr. The mosaic places its samples by it: without
        labels no mosaic or truth is made (said in one line).
    sediment : str, optional
        The seabed's sediment (a preset of :mod:`sonar_embree.laws.sediments`, e.g. "apl-uw fine sand"); default
        the DEM's or mesh's own material.
    gain : {"tvg", "agc"}
        The receiver's gain law: the device's TVG, set per line (:func:`line_receiver`), or an AGC.
    depth_m, altitude_m : float, optional
        For logs without a height column (a ship's GPS: time, lat, lon): the sonar at a constant ``depth_m`` below
        the surface, or flown at a constant ``altitude_m`` above the DEM (as towfish are flown; NaN holes bridged
        along the track). ``depth_m`` is also the planned survey's depth.
    crs : int or str, optional
        The CRS of a mesh ``dem`` (an EPSG code or a CRS string); needed for latitude/longitude logs.
    workers, scheduler : optional
        Where each line's blocks are rendered (:func:`~sonar_embree.survey.stream.render_line`).
    """
    navs = [os.fspath(n) for n in ([navs] if isinstance(navs, (str, os.PathLike)) else (navs or []))]
    if bool(navs) == (plan is not None):
        raise ConfigError("survey: give navigation logs or a planned polygon (one of them)")
    out = os.path.abspath(os.fspath(out))
    inputs = [os.fspath(dem), *navs, plan]
    OutputFolder.check(out, [SUMMARY], overwrite=overwrite, resume=True, inputs=inputs, command="survey")
    mosaic.check_pixel(pixel_m, "survey: --pixel")
    tiles = _seabed(dem, crs, sediment)
    sonar, pulse, rate = _device(device, range_m, ping_rate_hz)
    samples = devices.device(device).samples_per_channel       # the device's decimation (XTF), when stated
    if gain not in ("tvg", "agc"):
        raise ConfigError(f"survey: gain must be 'tvg' or 'agc', got {gain!r}")
    if depth_m is not None and altitude_m is not None:
        raise ConfigError("survey: give the sonar's depth (--depth-m) or its altitude (--altitude-m), not both")
    depth = 0.0 if altitude_m is not None else depth_m                 # a placeholder, replaced by the altitude's
    if plan is not None:
        sources = _planned(plan, tiles.crs, sonar.max_range_m, overlap, depth, speed_m_s, rate)
    else:
        sources = [(nav, _line(nav, tiles.crs, rate, depth)) for nav in navs]
    if altitude_m is not None:
        sources = [(nav, at_altitude(tiles, traj, altitude_m, nav)) for nav, traj in sources]
    for nav, traj in sources:
        _warn_holes(tiles, traj, nav)
    names = [f"line_{k:02d}" for k in range(len(sources))]
    with OutputFolder.claim(out, names + list(PRODUCTS) + [SUMMARY], overwrite=overwrite, resume=True,
                            inputs=inputs, command="survey") as top:
        return _run_lines(top, names, sources, tiles, sonar, pulse, samples, overwrite, pixel_m, dict(
            speckle=speckle, quality=quality, progress_bar=progress, workers=workers, scheduler=scheduler),
            summary={"device": device, "gain": gain, "labels": bool(labels), "sediment": sediment,
                     "range_m": sonar.max_range_m, "ping_rate_hz": rate, "layback_m": layback_m,
                     "cable_out_m": cable_out_m, "adc_bits": sonar.receiver.adc_bits,
                     "dem": os.path.abspath(os.fspath(dem)), "crs": tiles.crs},
            tow=(layback_m, cable_out_m, altitude_m))


def _run_lines(top, names, sources, tiles, sonar, pulse, samples, overwrite, pixel_m, kw, summary, tow) -> list:
    """Every line, then the products and the summary (last: it marks the survey done)."""
    written, lines, cache = [], [], RunCache()          # lines over the same tiles share their BVHs
    for name, (nav, traj) in zip(names, sources):
        if tow[0] is not None or tow[1] is not None:
            traj = traj.with_layback(tow[0], cable_out_m=tow[1])
            if tow[2] is not None:                                 # the fish, not the ship, flies at the altitude
                traj = at_altitude(tiles, traj, tow[2], nav)
        rx = (line_receiver(summary["device"], sonar, pulse, tiles, traj) if summary["gain"] == "tvg"
              else devices.device(summary["device"]).receiver("agc"))
        files = _render_line(top, name, tiles, traj, dataclasses.replace(sonar, receiver=rx), pulse, samples,
                             overwrite, {**kw, "labels": summary["labels"], "cache": cache})
        written += list(files.values())
        lines.append({"nav": os.path.abspath(nav), "pings": len(traj), "gain": dataclasses.asdict(rx.gain),
                      "files": {k: os.path.relpath(v, top.path) for k, v in files.items()}})   # relative to survey.json
    if summary["labels"]:
        written += _products(top, tiles, [line["files"]["zarr"] for line in lines], pixel_m)
    else:
        log.warning("survey: without labels no mosaic is made (it places each sample by the ground truth)")
    summary = {**summary, "lines": lines}
    return written + top.write_set([(SUMMARY, lambda p: _write_json(summary, p))])


#: The survey's products beside its lines.
PRODUCTS = ("mosaic.tif", "mosaic.png", "truth.tif")
#: Line files, by kind.
LINE_FILES = {"zarr": "line.zarr", "xtf": "line.xtf", "png": "line.png"}


def _seabed_heights(tiles, x, y) -> np.ndarray:
    """(n,) the seabed's height under the points (x, y), m; NaN over holes and off the seabed."""
    if isinstance(tiles, TiledDEM):
        z = sample_points(tiles.info, x, y, tiles.band)
        if tiles.nodata is not None:
            z[z == tiles.nodata] = np.nan
        return z
    return mosaic.heights_at(tiles, x, y)


def _seabed_material(tiles):
    return tiles.material if isinstance(tiles, TiledDEM) else tiles.objects[0].material


#: Where a line's TVG starts, as a fraction of its median altitude: just before the first bottom return.
TVG_START_FRACTION = 0.9
#: Where a line's median seabed sits in its codes, as a fraction of full scale (an operator's usual setting) ...
SEABED_FULL_SCALE = 0.25
#: ... unless the seabed's bright near range would then clip: its :data:`SEABED_PEAK_PERCENTILE` th percentile is
#: held at this fraction of full scale (an operator lowers the gain rather than saturate the picture).
SEABED_PEAK_FULL_SCALE, SEABED_PEAK_PERCENTILE = 0.8, 95.0


def line_receiver(device: str, sonar, pulse, tiles, traj):
    """The device's receiver for one line, set as an operator sets it: its TVG (:meth:`Device.receiver`) starts
    at :data:`TVG_START_FRACTION` of the line's median altitude, and its level puts the median seabed of a flat
    floor of the line's seabed material at that altitude at :data:`SEABED_FULL_SCALE` of full scale, or lower where
    the bright near range would clip (:data:`SEABED_PEAK_FULL_SCALE`; one ping simulated, speckle-free, without a
    receiver). The water column before the first return keeps the
    receiver's own noise at the start gain: dark, as in a device's record."""
    alt = traj.positions_m[:, 2] - _seabed_heights(tiles, traj.positions_m[:, 0], traj.positions_m[:, 1])
    alt = float(np.nanmedian(alt)) if np.isfinite(alt).any() else sonar.max_range_m / 4
    alt = min(max(alt, 1.0), 0.9 * sonar.max_range_m)
    d = devices.device(device)
    probe = dataclasses.replace(sonar, receiver=None)
    size = 4.0 * sonar.max_range_m
    floor = Scene().add(seafloor.flat((size, size)), material=_seabed_material(tiles), label="seafloor")
    rec = simulate(floor, Trajectory.line((0.0, 0.0, alt), (0.1, 0.0, alt), 1), probe, pulse, speckle=False,
                   start_time="2000-01-01", progress=False)
    law = d.receiver(g0_db=0.0, start_range_m=TVG_START_FRACTION * alt).gain
    r = rec.slant_range_m
    on_floor = (r > 1.05 * alt) & np.all(rec.data[0] > 0, axis=0)
    if not on_floor.any():
        return d.receiver(start_range_m=TVG_START_FRACTION * alt)
    levels = 10.0 * np.log10(rec.data[0][:, on_floor]) + law.gain_db(r[on_floor], rec.acquisition.alpha_db_per_m)
    r0 = d.receiver()
    fs_db = 20.0 * np.log10(r0.full_scale_v) - r0.sensitivity_db
    g0 = min(fs_db + 20.0 * np.log10(SEABED_FULL_SCALE) - float(np.median(levels)),
             fs_db + 20.0 * np.log10(SEABED_PEAK_FULL_SCALE) - float(np.percentile(levels, SEABED_PEAK_PERCENTILE)))
    return d.receiver(g0_db=float(g0), start_range_m=TVG_START_FRACTION * alt)


def _render_line(top, name, tiles, traj, sonar, pulse, samples, overwrite, kw) -> dict:
    """One line streamed into its own folder (a manifest of its own, each file reserved before its first byte,
    resumed where a killed run stopped); returns its files' paths."""
    top.reserve(name)
    line = OutputFolder.claim(os.path.join(top.path, name), list(LINE_FILES.values()), overwrite=overwrite,
                              resume=True, command="survey line")   # resumes only a survey's line
    top.record_managed(name)
    files = {k: line.reserve(v) for k, v in LINE_FILES.items()}
    stream.render_line(tiles, traj, files["zarr"], sonar, pulse, xtf_path=files["xtf"], png_path=files["png"],
                       xtf_samples=samples, overwrite=overwrite, **kw)
    line.record(*LINE_FILES.values())
    return files


def _seabed(path, crs, sediment=None):
    """The survey's seabed: a GeoTIFF DEM tile by tile, or a mesh file whole (labelled seafloor) in ``crs``; of
    the ``sediment`` preset when given."""
    path = os.fspath(path)
    material = None if sediment is None else Material(scattering=sediments.preset(sediment))
    if os.path.splitext(path)[1].lower() in (".tif", ".tiff"):
        if crs is not None:
            raise ConfigError(f"{path}: a GeoTIFF DEM carries its own CRS; give crs only with a mesh")
        return TiledDEM(path, material=material)
    mesh = load_mesh(path)
    if crs is not None:
        mesh.metadata["crs"] = crs_name(crs)
    return Scene().add(mesh, label="seafloor", **({} if material is None else {"material": material}))


def _device(name: str, range_m, ping_rate_hz):
    """(sonar with the assumed receiver, the device's pulse, ping rate) of a preset at a range setting."""
    d = devices.device(name)
    rng = float(d.ranges_m[0] if range_m is None else range_m)
    sonar = Sonar.preset(name, max_range_m=rng, receiver=d.receiver())
    c = Acquisition(sonar).sound_speed_m_s        # the survey's medium: the default water
    rate = d.ping_rate_hz(rng, c) if ping_rate_hz is None else float(ping_rate_hz)
    limit = c / (2.0 * rng)
    if rate > limit * (1.0 + 1e-9):
        log.warning("survey: %.4g pings a second is faster than the %.4g at which the echoes of %.4g m return "
                    "(c/2R); pinging at %.4g", rate, limit, rng, limit)
        rate = limit
    return sonar, Pulse.preset(name), rate


def _line(nav: str, crs, rate: float, depth_m=None):
    """The line of one navigation log: in the DEM's CRS (a log without heights at ``depth_m``), resampled at
    ``rate``."""
    if not os.path.isfile(nav):
        raise ConfigError(f"{nav}: no such navigation log")
    ext = os.path.splitext(nav)[1].lower()
    if ext not in (".csv", ".xtf"):
        raise ConfigError(f"{nav}: a navigation log is .csv or .xtf, got {ext or 'no extension'!r}")
    if ext == ".csv":
        _check_csv_times(nav)
    if ext == ".csv":
        traj = Trajectory.from_csv(nav, crs=crs, depth_m=depth_m)
    elif depth_m is not None:
        raise ConfigError(f"{nav}: an XTF log carries its own depths; give --depth-m or --altitude-m with CSV logs")
    else:
        traj = Trajectory.from_xtf(nav, crs=crs)
    if len(traj) < 2:
        raise ConfigError(f"{nav}: a navigation log needs two fixes at least, got {len(traj)}; a line runs between "
                          "them")
    if not float(traj.times_s[-1] - traj.times_s[0]) > 0.0:
        raise ConfigError(f"{nav}: every fix has the same time; a line needs time between its fixes")
    return traj.resampled(rate)


def at_altitude(tiles, traj, altitude_m: float, nav) -> Trajectory:
    """``traj`` flown ``altitude_m`` above the seabed under each ping (the DEM sampled there; pings over holes or
    off the DEM take the heights of their neighbours along the track)."""
    import dataclasses

    check_number("survey", "altitude_m", altitude_m, positive=True, hi=1e4)
    pos = traj.positions_m.copy()
    z = _seabed_heights(tiles, pos[:, 0], pos[:, 1])
    good = np.isfinite(z)
    if not good.any():
        raise ConfigError(f"{nav}: no ping of the line lies over the seabed, so it cannot fly at --altitude-m")
    k = np.arange(z.size)
    pos[:, 2] = np.interp(k, k[good], z[good]) + float(altitude_m)
    return dataclasses.replace(traj, positions_m=pos)


def _warn_holes(tiles, traj, nav) -> None:
    """One line when pings of a line lie over the DEM's nodata holes or off the DEM: no seabed below them, so
    they hear nothing there (an altitude of NaN, a blank in the mosaic)."""
    if not isinstance(tiles, TiledDEM):
        return
    step = max(1, len(traj) // 2000)                            # at most some 2000 samples a line
    xy = traj.positions_m[::step, :2]
    z = _seabed_heights(tiles, xy[:, 0], xy[:, 1])
    holes = float(np.mean(~np.isfinite(z)))
    if holes > 0.0:
        log.warning("survey: %s: %.0f %% of the line lies over nodata holes of %s or off it: no seabed below those "
                    "pings (their altitude is NaN, the mosaic blank there)", nav, 100 * holes, tiles.path)


def _check_csv_times(nav: str) -> None:
    """A survey places its pings at the device's rate along the log's times: a log without a time column would be
    taken as fixes 1 s apart, so it is refused."""
    header = csv_header(nav)
    if "time" not in header and "time_s" not in header:
        raise ConfigError(f"{nav}: a survey's navigation log needs a time column (time: ISO 8601, or time_s: "
                          f"seconds); found {', '.join(header)}")


def _planned(plan, crs, range_m: float, overlap: float, depth_m, speed_m_s: float, rate: float) -> list:
    """(the polygon's path, trajectory) of each line planned over the polygon of ``plan``."""
    if depth_m is None:
        raise ConfigError("survey: a planned survey needs depth_m (the sonar's depth below the surface, m)")
    plan = os.fspath(plan)
    cols, v = read_numeric_csv(plan, (), ("x_m", "y_m", "lat_deg", "lon_deg"), "survey polygon",
                               "x_m, y_m (the DEM's CRS) or lat_deg, lon_deg")
    if {"x_m", "y_m"} <= set(cols):
        xy = v[:, [cols.index("x_m"), cols.index("y_m")]]
    elif {"lat_deg", "lon_deg"} <= set(cols):
        xy = np.column_stack(from_lonlat(crs, v[:, cols.index("lon_deg")], v[:, cols.index("lat_deg")]))
    else:
        raise ConfigError(f"{plan}: a survey polygon needs the columns x_m, y_m (the DEM's CRS) or lat_deg, lon_deg")
    lines = plan_lines(xy, range_m, overlap)
    trajs = line_trajectories(lines, -float(depth_m), speed_m_s, rate, crs=crs)
    return [(os.path.abspath(plan), t) for t in trajs]


def _products(top, tiles, stores, pixel_m: float) -> list:
    """The survey's normalised mosaic (GeoTIFF and quick look) and the DEM's truth on the same grid."""
    grid = mosaic.mosaic([os.path.join(top.path, s) for s in stores], pixel_m=pixel_m, values="normalised")
    return top.write_set([("mosaic.tif", grid.to_geotiff), ("mosaic.png", grid.save_png),
                          ("truth.tif", lambda p: mosaic.write_truth(p, tiles, grid))])


def _write_json(obj, path) -> None:
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(obj, fh, indent=2)


#: Keys of a survey TOML's ``[survey]`` table (the keywords of :func:`run_survey`; paths relative to the file).
SURVEY_KEYS = ("dem", "nav", "device", "range_m", "ping_rate_hz", "layback_m", "cable_out_m", "pixel_m", "quality",
               "speckle", "plan", "depth_m", "speed_m_s", "overlap", "crs", "altitude_m", "gain", "labels", "sediment")


def load_survey_config(path) -> dict:
    """The ``[survey]`` table of a TOML file as :func:`run_survey` keywords (dem, navs, device, …), paths resolved
    against the file's folder; unknown keys, a missing dem/nav/device and values of the wrong type are one-line
    errors naming the file and key."""
    source, data = read_toml(path, "survey config")
    _check_keys("the top level", data, ("survey",), source)
    table = data.get("survey")
    if table is None:
        raise ConfigError(f"{source}: no [survey] table")
    _check_keys("[survey]", table, SURVEY_KEYS, source)
    for key in ("dem", "device"):
        if key not in table:
            raise ConfigError(f"{source}: [survey] needs {key!r}")
    if ("nav" in table) == ("plan" in table):
        raise ConfigError(f"{source}: [survey] needs 'nav' or 'plan' (one of them)")
    base = os.path.dirname(os.path.abspath(source))
    navs = [] if "nav" not in table else table["nav"] if isinstance(table["nav"], list) else [table["nav"]]
    named = [("dem", table["dem"]), ("device", table["device"])] + [("nav", n) for n in navs]
    for key, value in named + ([("plan", table["plan"])] if "plan" in table else []):
        if not isinstance(value, str):
            raise ConfigError(f"{source}: [survey] {key} must be a string, got {value!r}")
    for key in ("range_m", "ping_rate_hz", "layback_m", "cable_out_m", "pixel_m", "quality", "depth_m", "altitude_m",
                "speed_m_s",
                "overlap"):
        v = table.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise ConfigError(f"{source}: [survey] {key} must be a number, got {v!r}")
    for key in ("speckle", "labels"):
        if not isinstance(table.get(key, False), bool):
            raise ConfigError(f"{source}: [survey] {key} must be true or false, got {table[key]!r}")
    for key in ("sediment", "gain"):
        if key in table and not isinstance(table[key], str):
            raise ConfigError(f"{source}: [survey] {key} must be a string, got {table[key]!r}")
    kw = {k: table[k] for k in SURVEY_KEYS[3:] if k in table}
    if "plan" in kw:
        kw["plan"] = _resolve(base, kw["plan"])
    else:
        kw["navs"] = [_resolve(base, n) for n in navs]
    return dict(dem=_resolve(base, table["dem"]), device=table["device"], **kw)
