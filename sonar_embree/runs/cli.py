"""The ``sonar-embree`` command line: ``demo``, ``render`` and ``batch``.

Errors in the user's input print one line (``sonar-embree: error: …``) and exit
with status 2; no traceback.
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
import os
import sys

from ..errors import SonarEmbreeError
from ..record import registry
from ..io.owner import OutputFolder
from .. import assets
from ..config import FanSettings, Material
from ..laws import sediments
from ..scene import Scene, seafloor
from ..config import SignalChain
from ..raycast import BvhCaster, CudaCaster, EmbreeCaster
from ..simulate import simulate
from ..survey.replay import FIT_CLASSES, replay
from ..survey.stream import render_record
from .runconfig import load_run_config

log = logging.getLogger(__name__)

EPILOG = """\
Outputs (in OUT/): waterfall.png (port mirrored on the left, starboard on the right,
first ping at the top) and record.npz (port/starboard linear intensity for a unit
source, time axis, poses; read it with sonar_embree.Record.load).
"""

RENDER_HELP = """\
CONFIG.toml describes the scene, trajectory and sonar; keys map 1:1 onto the Python
dataclasses (units in the key names):

  [sonar]       frequency_hz, length_m, height_m, tilt_deg, max_range_m,
                sample_rate_hz, sound_speed_m_s, absorption_db_per_m (default:
                Francois-Garrison from temperature_c, salinity_ppt, depth_m, ph)
  [pulse]       kind = "cw" | "lfm" | "exp_chirp", duration_s, taper (0 rectangle
                ... 1 Blackman-Harris; default 0.1); lfm: bandwidth_hz, center_hz;
                exp_chirp: f_start_hz, f_stop_hz
  [fan]         quality (1: flat floor within 0.2 dB; 0.5 faster; 2-4 references),
                or explicitly rays_per_bin, azimuth_oversample, azimuth_nulls,
                max_step_deg, probe_step_deg, max_rays_per_side
  [simulation]  speckle (false), band ("baseband"|"carrier"), detection
                ("coherent"|"incoherent"), matched_filter (default: on for FM),
                tvg (false), noise_db_per_hz, lowpass_hz, speckle_cell_m, seed (0)
  [trajectory]  kind = "line": start, end, n_pings, speed_m_s, pitch_deg, roll_deg, heading_deg
                kind = "waypoints": waypoints, n_pings, speed_m_s, pitch_deg, roll_deg
                kind = "csv": path (columns time_s,x_m,y_m,z_m,heading_deg,pitch_deg,roll_deg,
                optional vx_m_s,vy_m_s,vz_m_s; else the velocity from time_s)
                (all: motion_during_ping = true (default) | false for stop-and-hop)
  [[objects]]   path = mesh file (OBJ/PLY/STL/GLB, metres; up_axis = "z" (default)
                or "y" for a Y-up export; GLB/glTF are read y up as specified)  or
                seafloor = "flat" | "perlin" | "ripples" and its arguments (size_m, ...)  or
                [objects.seabed] size_m, resolution_m, bedforms, trawl_marks, scours, outcrops,
                boulder_field (labelled features, se.features.seabed);
                optional label, material = { backscatter_db = -27 }, and for mesh files
                is_seafloor (default: label "seafloor" or "seafloor/...", for ground-truth
                shadows) and materials = { name = { backscatter_db = -15 }, ... } per object
  [output]      formats, each true/false: png (default true), npz (true), zarr, xtf,
                labels, coco, polar (MSIS), fan (forward-looking), soundings and
                bathymetry (a receive_array's interferometric soundings, soundings.xyz, and
                their grid, bathymetry.tif, at bathymetry_pixel_m = 0.5 m);
                display: scale ("db"|"gamma"), dynamic_range_db (35), gamma,
                ground_range, tvg (display only; default true), reference_percentile
                (99.99: the level shown white), floor_headroom_db (12: white at least
                this far above the median), max_columns (1024 per side);
                geo_origin_deg = [lat, lon]: where a local scene's origin lies (XTF in lat/lon)

Relative paths are relative to CONFIG.toml; asset:NAME names a shipped file.
Examples: sonar-embree examples (list), sonar-embree render asset:anchor_mine.toml -o OUT,
sonar-embree examples --copy anchor_mine.toml my_scene.toml (to edit).
"""


BATCH_HELP = """\
SWEEP.toml holds [sonar], [pulse], [fan] and [simulation] as in render configs
(base settings; no seed), and:

  [sweep]         name, seeds (list, or a count n for 0..n-1), pings_per_task (32),
                  complex (false: keep complex baseband in Zarr/npz, coherent speckle only),
                  outputs (of "zarr", "xtf", "png", "labels", "coco", "npz";
                  default zarr, xtf, png, coco)
  [vary]          "table.field" = [values, ...]; every combination is a job
  [[scenes]]      name, and [[scenes.objects]]: a mesh path or a seafloor (as in
                  render configs; a seafloor without seed takes the job's seed), or
                  placed instances of a mesh: path, label, count + region =
                  [[x0, x1], [y0, y1]] + yaw_deg = [lo, hi], or poses = [[x, y, yaw_deg], ...];
                  z_m (height above the floor), material = {backscatter_db = [lo, hi]}
  [[trajectories]] as [trajectory] of render configs, plus name
  [png]           scale, dynamic_range_db, gamma, tvg, reference_percentile,
                  floor_headroom_db, max_columns (defaults as render's [output])

Jobs = scenes x trajectories x [vary] combinations x seeds. Outputs per job in
OUT/<id>/: record.zarr, record.xtf, waterfall.png, labels.png, coco.json, record.npz,
job.json; OUT/sweep.json and OUT/coco.json for the whole batch. Same sweep, same
bits, whatever the number of workers. Examples: sonar-embree batch asset:detection.toml
-o OUT (mines on ripples, COCO) and asset:reconstruction.toml (three overlapping lines
with height truth); sonar-embree examples --copy detection.toml . to edit one.
"""


SURVEY_HELP = r"""Simulate a survey: each navigation log is one line, projected into the DEM's CRS, its heading
taken from the track when it has none, resampled at the device's ping rate, towed behind the navigation with
--layback or --cable-out, and streamed (resumable) into OUT/line_KK/ as line.zarr, line.xtf (lat/lon, ship and
sensor positions) and line.png. Then OUT/mosaic.tif (normalised values and placed heights, units, overviews),
OUT/mosaic.png (a quick look), OUT/truth.tif (the DEM on the mosaic's grid) and OUT/survey.json. The device
records its codes at its ADC's bits where stated (EdgeTech 15, Marine Sonic 6, else 16); its gain is assumed (no
datasheet states it): an AGC.

example:
  sonar-embree survey --dem harbour.tif --nav line1.csv --nav line2.csv --device edgetech-4125-400 \
      --range 75 --cable-out 40 -o out/harbour
"""


REPLAY_HELP = """\
Replay a recorded side-scan line: read REAL.xtf's navigation, attitude, altitude, frequency, range, samples per
channel and sample format; simulate the same line over a flat floor of --sediment; write OUT/replay.xtf (the same
layout, every header kept), OUT/report.json and OUT/report.png. --dem or --scene replays it over that seabed
instead, the sonar where the file's navigation puts it.
- The report compares: level against range and grazing angle, the noise floor, the scintillation index and the
  level histogram per range band, and the correlation along range and along track.
- --fit picks the sediment class and the gain offset that match best, calibrating the simulator to your sonar.

example:
  sonar-embree replay line07.xtf --fit -o out/line07
"""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="sonar-embree",
                                description="Physically based side-scan sonar simulator (Embree ray casting).",
                                epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-v", "--verbose", action="store_true", help="log progress details to stderr")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    d = sub.add_parser("demo", help="render the built-in anchor-mine scene (paper §4.1) in seconds",
                       description="Render the paper's anchor-mine test scene: three spheres and a cube "
                                   "moored above a seafloor, default 400 kHz sonar; speckle-free unless the "
                                   "signal-chain options ask for speckle.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    d.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder (created if missing)")
    d.add_argument("--pings", type=int, default=240, help="number of pings over the 24 m track (default 240)")
    d.add_argument("--overwrite", action="store_true", help="replace the outputs of an earlier run in OUT")
    d.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    _add_chain_options(d)

    r = sub.add_parser("render", help="render a scene + trajectory + sonar described in a TOML file",
                       description="Render the run described by CONFIG.toml.", epilog=RENDER_HELP + "\n" + EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("config", metavar="CONFIG.toml", help="run description (see below), or asset:NAME.toml")
    r.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder (created if missing)")
    r.add_argument("--overwrite", action="store_true", help="replace the outputs of an earlier run in OUT")
    r.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    r.add_argument("--workers", type=int, metavar="N", help="render the line's blocks on N worker processes of a "
                   "local Dask cluster (same data bits; default: this process)")
    r.add_argument("--scheduler", metavar="ADDRESS", help="render the line's blocks on a running Dask scheduler "
                   "(tcp://host:8786)")
    _add_chain_options(r)

    b = sub.add_parser("batch", help="render a sweep of scenes x trajectories x settings x seeds on Dask",
                       description="Expand SWEEP.toml into jobs and render them on Dask (a LocalCluster "
                                   "unless --scheduler is given). Each job is written whole into OUT/<job id>/.",
                       epilog=BATCH_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    b.add_argument("sweep", metavar="SWEEP.toml", help="sweep description (see below), or asset:NAME.toml")
    b.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder (new, empty, or --resume)")
    b.add_argument("--scheduler", metavar="ADDRESS", help="address of a running Dask scheduler (tcp://host:8786)")
    b.add_argument("--workers", type=int, metavar="N", help="worker processes of the local cluster "
                                                            "(default: CPU count, at most 8)")
    b.add_argument("--resume", action="store_true", help="continue a batch in OUT: keep finished jobs, redo the rest")
    b.add_argument("--dashboard", nargs="?", const=":8787", metavar="ADDRESS",
                   help="serve the local cluster's Dask dashboard (default address :8787; off unless given)")
    b.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    _add_survey_parser(sub)
    _add_replay_parser(sub)
    x = sub.add_parser("examples", help="list the shipped scenes, configs and sweeps, or copy one out",
                       description="The files shipped with the package. Configs and sweeps name their meshes "
                                   "as asset:NAME, so a copy works from any folder; render or batch them as "
                                   "asset:NAME.toml or as the copy.")
    x.add_argument("--copy", nargs=2, metavar=("NAME", "DEST"), help="copy a shipped file to DEST (a file or folder)")
    return p


def _add_replay_parser(sub) -> None:
    p = sub.add_parser("replay", help="simulate a recorded XTF line over a flat floor and compare (report, fit)",
                       description=REPLAY_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("xtf", metavar="REAL.xtf", help="the recorded line (navigation, attitude, altitude, settings)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder (new or empty)")
    floor = p.add_mutually_exclusive_group()
    floor.add_argument("--flat", action="store_true", help="a flat seafloor at each ping's altitude (the default)")
    floor.add_argument("--dem", metavar="DEM.tif", help="a GeoTIFF DEM (projected metres, z = 0 the sea surface) of "
                                                        "--sediment; the sonar where the file's navigation puts it")
    floor.add_argument("--scene", metavar="RUN.toml", help="the scene of a run configuration (its objects and "
                                                           "materials); the sonar where the file's navigation puts it")
    p.add_argument("--sediment", default="apl-uw fine sand", help="the floor's sediment preset (default "
                                                                   "'apl-uw fine sand')")
    p.add_argument("--fit", action="store_true", help="fit the gain offset and the sediment class "
                                                      "(among --classes)")
    p.add_argument("--classes", default=",".join(FIT_CLASSES), help="comma-separated sediment presets --fit tries")
    p.add_argument("--clutter-densities", metavar="N,N,…", help="with --fit: clutter densities per m² to try too "
                                                              "(0: none), e.g. 0,10,40,160")
    p.add_argument("--gain-db", type=float, help="the gain offset, dB (default: the median level difference)")
    p.add_argument("--device", metavar="PRESET", help="a device preset for the beam and pulse")
    p.add_argument("--seed", type=int, default=0, help="speckle seed (default 0)")
    p.add_argument("--overwrite", action="store_true", help="replace an earlier replay's files in OUT")


def _add_survey_parser(sub) -> None:
    s = sub.add_parser("survey", help="a DEM + navigation logs + a device preset -> per line XTF, Zarr, PNG and "
                                      "the survey's mosaic", description=SURVEY_HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("--config", metavar="SURVEY.toml", help="a [survey] table with the keys dem, nav (a path or a "
                                                           "list), device, range_m, ping_rate_hz, layback_m, "
                                                           "cable_out_m, pixel_m, quality, speckle; flags given "
                                                           "as well override it")
    s.add_argument("--dem", metavar="DEM.tif", help="GeoTIFF DEM, projected CRS in metres, z = 0 the sea surface; "
                                                   "or a mesh file (OBJ/PLY/STL/GLB, projected metres) with --crs")
    s.add_argument("--nav", action="append", metavar="LOG",
                   help="navigation log of one line (.csv: time, lat_deg/lon_deg (or latitude/longitude, lat/lon) or "
                        "x_m/y_m, depth_m or z_m (or --depth-m/--altitude-m), "
                        "optional heading_deg; .xtf); repeat for more lines")
    s.add_argument("--crs", metavar="EPSG", help="with a mesh --dem: its projected CRS (e.g. 32631)")
    s.add_argument("--plan", metavar="POLYGON.csv", help="instead of --nav: a polygon (x_m, y_m in the DEM's CRS, or "
                                                         "lat_deg, lon_deg) covered by planned parallel lines")
    height = s.add_mutually_exclusive_group()
    height.add_argument("--depth-m", "--depth", type=float, metavar="M", dest="depth",
                        help="the sonar's depth below the surface, m: a planned survey's, or a log's without a depth "
                             "column (a ship's GPS log: time, lat, lon)")
    height.add_argument("--altitude-m", type=float, metavar="M", dest="altitude",
                        help="a log without a depth column flown this high above the DEM, m (as towfish are flown)")
    s.add_argument("--speed", type=float, metavar="M_S", help="with --plan: survey speed, m/s (default 2)")
    s.add_argument("--overlap", type=float, help="with --plan: swath overlap between lines (default 0.2)")
    s.add_argument("--device", metavar="PRESET", help="device preset, e.g. edgetech-4125-400 "
                                                                     "(see docs/guide/sonars.md, Device presets)")
    s.add_argument("--range", type=float, metavar="M", dest="range_m", help="range setting, m (default: the "
                                                                           "preset's first)")
    s.add_argument("--ping-rate", type=float, metavar="HZ", help="pings per second (default: the device's rate "
                                                                 "for the range, else back to back)")
    tow = s.add_mutually_exclusive_group()
    tow.add_argument("--layback", type=float, metavar="M", help="towed: the sonar this far behind the navigation")
    tow.add_argument("--cable-out", type=float, metavar="M", help="towed: this much cable from the surface")
    s.add_argument("--labels", action=argparse.BooleanOptionalAction, default=None,
                   help="write each line's per-sample ground truth into its Zarr (default: on; off: lines a few times "
                        "smaller, and no mosaic, which places its samples by the truth)")
    s.add_argument("--sediment", metavar="PRESET", help="the seabed's sediment, e.g. 'apl-uw fine sand' (default: "
                                                        "the DEM's material)")
    s.add_argument("--gain", choices=("tvg", "agc"), help="the receiver's gain: the device's TVG, set per line so "
                   "the median seabed sits at a quarter of full scale (default), or an AGC")
    s.add_argument("--pixel", type=float, metavar="M", help="mosaic pixel, m (default 0.5)")
    s.add_argument("--quality", type=float, help="ray budget (default 1)")
    s.add_argument("--speckle", action="store_true", default=None, help="coherent speckle (default: expected "
                                                                        "intensity)")
    s.add_argument("-o", "--output", required=True, metavar="OUT", help="output folder (new, empty or an earlier "
                                                                        "survey's: resumed)")
    s.add_argument("--overwrite", action="store_true", help="replace what is in OUT")
    s.add_argument("--workers", type=int, metavar="N", help="render each line's blocks on N worker processes "
                   "(1: this process; default: workers from 8 CPUs and 4096 pings a line)")
    s.add_argument("--scheduler", metavar="ADDRESS", help="render each line's blocks on a running Dask scheduler "
                   "(tcp://host:8786)")
    s.add_argument("--no-progress", action="store_true", help="hide the progress bars")


def _survey(args) -> list:
    """``sonar-embree survey``: the config's [survey] table (if any), overridden by the flags given."""
    from .survey import load_survey_config, run_survey

    kw = load_survey_config(args.config) if args.config else {}
    flags = dict(dem=args.dem, navs=args.nav, device=args.device, range_m=args.range_m, ping_rate_hz=args.ping_rate,
                 layback_m=args.layback, cable_out_m=args.cable_out, pixel_m=args.pixel, quality=args.quality,
                 speckle=args.speckle, plan=args.plan, depth_m=args.depth, altitude_m=args.altitude, gain=args.gain,
                 labels=args.labels, sediment=args.sediment,
                 speed_m_s=args.speed, overlap=args.overlap,
                 crs=args.crs)
    kw.update({k: v for k, v in flags.items() if v is not None})
    for key, flag in (("dem", "--dem"), ("device", "--device")):
        if key not in kw:
            raise SonarEmbreeError(f"survey: give {flag} (or a --config with it)")
    if "navs" not in kw and "plan" not in kw:
        raise SonarEmbreeError("survey: give --nav or --plan (or a --config with nav or plan)")
    return run_survey(kw.pop("dem"), kw.pop("navs", None), args.output, kw.pop("device"), overwrite=args.overwrite,
                      progress=not args.no_progress, workers=_checked_workers(args.workers), scheduler=args.scheduler,
                      **kw)


def _examples(args) -> list:
    import shutil


    if args.copy is None:
        return [f"{kind}/{name}\t{assets.path(name)}" for kind in assets.KINDS for name in assets.names(kind)]
    name, dest = args.copy
    src = assets.path(name)
    target = os.path.join(dest, os.path.basename(src)) if os.path.isdir(dest) else dest
    try:
        with open(src, "rb") as fh, open(target, "xb") as out:    # "x": never over an existing file, even racing
            shutil.copyfileobj(fh, out)
    except FileExistsError:
        raise SonarEmbreeError(f"{target}: exists; choose another destination") from None
    return [target]


def _add_chain_options(p):
    g = p.add_argument_group("signal chain (override [simulation]; see sonar_embree.SignalChain)")
    g.add_argument("--speckle", action=argparse.BooleanOptionalAction, default=None,
                   help="simulate signals with speckle (default: the expected intensity)")
    g.add_argument("--band", choices=("baseband", "carrier"), help="synthesis band (speckle only)")
    g.add_argument("--detection", choices=("coherent", "incoherent"), help="detection (incoherent: carrier)")
    g.add_argument("--matched-filter", action=argparse.BooleanOptionalAction, default=None,
                   help="pulse compression (default: on for FM pulses)")
    g.add_argument("--tvg", action=argparse.BooleanOptionalAction, default=None, help="perfect TVG")
    g.add_argument("--noise-db-per-hz", type=float, metavar="DB", help="receiver noise spectral density")
    g.add_argument("--lowpass-hz", type=float, metavar="HZ", help="low-pass FIR cut-off after detection")
    g.add_argument("--seed", type=int, help="seed of the speckle and noise")
    p.add_argument("--start-time", metavar="ISO8601",
                   help="time of the first ping, e.g. 2026-05-01T09:30:00Z (default: now); in the record, XTF and Zarr")
    p.add_argument("--quality", type=float, metavar="Q",
                   help="ray density, trading error for speed (overrides [fan] quality; default 1)")
    p.add_argument("--caster", choices=tuple(CASTERS), default="embree",
                   help="ray caster: embree (default), bvh (the project's BVH on the CPU), cuda (the same on a CUDA "
                        "GPU, through numba.cuda)")


#: The ray casters ``--caster`` names (docs/physics.md §8b).
CASTERS = {"embree": EmbreeCaster, "bvh": BvhCaster, "cuda": CudaCaster}

_CHAIN_FLAGS = ("speckle", "band", "detection", "matched_filter", "tvg", "noise_db_per_hz", "lowpass_hz", "seed")


def _chain(args, base=None):
    """The signal chain of ``base`` (default: SignalChain()) with the command-line overrides."""
    import dataclasses


    base = SignalChain() if base is None else base
    overrides = {k: getattr(args, k) for k in _CHAIN_FLAGS if getattr(args, k) is not None}
    if ("band" in overrides and overrides["band"] == "carrier") or "detection" in overrides:
        overrides.setdefault("speckle", True)
    return dataclasses.replace(base, **overrides)


def _fan(args, base=None):
    """The fan settings of ``base`` (default: FanSettings()) with ``--quality`` applied."""
    import dataclasses


    base = FanSettings() if base is None else base
    return base if args.quality is None else dataclasses.replace(base, quality=args.quality)


#: What ``sonar-embree demo`` writes.
DEMO_FORMATS = ("npz", "png", "xtf")


def kernels_compiled(roots=None) -> bool:
    """Whether Numba's cache holds compiled kernels (index files ``*.nbi``) in ``roots`` (default: beside this
    package's kernels, and under ``NUMBA_CACHE_DIR``): a first run compiles them, about a minute on 2 cores."""
    import glob

    if roots is None:
        here = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "kernels")
        roots = [os.path.join(here, "__pycache__")] + ([os.environ["NUMBA_CACHE_DIR"]] if os.environ.get(
            "NUMBA_CACHE_DIR") else [])
    return any(glob.glob(os.path.join(r, "**", "*.nbi"), recursive=True) for r in roots)


def _run(args) -> list:
    if args.command == "examples":
        return _examples(args)
    if not kernels_compiled():
        log.warning("compiling the simulation kernels for this machine, once (about a minute; later runs start "
                    "at once)")
    if args.command == "batch":
        from . import batch

        ids = batch.run(args.sweep, args.output, scheduler=args.scheduler, workers=_checked_workers(args.workers),
                        resume=args.resume, progress=not args.no_progress, dashboard=args.dashboard)
        return [os.path.join(args.output, i) for i in ids]
    if args.command == "survey":
        return _survey(args)
    if args.command == "replay":
        classes = [c.strip() for c in args.classes.split(",") if c.strip()] if args.fit else None
        densities = _densities(args.clutter_densities)
        replay(args.xtf, args.output, sediment=args.sediment, fit_classes=classes, gain_db=args.gain_db,
               device=args.device, seed=args.seed, overwrite=args.overwrite, scene=_replay_scene(args),
               fit_densities=densities, inputs=[args.dem, args.scene])
        return [os.path.join(args.output, f) for f in ("replay.xtf", "report.json", "report.png")
                if os.path.exists(os.path.join(args.output, f))]
    if args.command == "demo":
        return _demo(args)
    return _render(args)


def _demo(args) -> list:
    """``sonar-embree demo``: the anchor-mine scene into OUT (claimed before any work)."""
    from .demo import DEMO_ORIGIN_DEG, DEMO_PNG, anchor_mine_setup

    if args.pings < 1:
        raise SonarEmbreeError(f"--pings must be >= 1, got {args.pings}")
    with OutputFolder.claim(args.output, registry.file_names(DEMO_FORMATS), overwrite=args.overwrite,
                            command="demo") as out:
        scene, traj, sonar, pulse = anchor_mine_setup(n_pings=args.pings)
        rec = simulate(scene, traj, sonar, pulse, chain=_chain(args), fan=_fan(args), progress=not args.no_progress,
                       start_time=args.start_time, caster=CASTERS[args.caster])
        rec = dataclasses.replace(rec, attrs={**rec.attrs, "geo_origin_deg": list(DEMO_ORIGIN_DEG)})
        return registry.write_set(rec, out, DEMO_FORMATS, registry.WriteOptions(DEMO_PNG))


def _render(args) -> list:
    """``sonar-embree render``: a TOML run into OUT (the folder and every option checked before any work)."""
    cfg = load_run_config(args.config)
    o = cfg.output
    if not o.formats():
        raise SonarEmbreeError(f"{args.config}: [output] every format is false; nothing to write")
    workers = _checked_workers(args.workers)
    kw = dict(chain=_chain(args, cfg.chain), fan=_fan(args, cfg.fan), progress=not args.no_progress,
              start_time=args.start_time, labels=o.needs_labels(), caster=CASTERS[args.caster])
    with OutputFolder.claim(args.output, registry.file_names(o.formats()), overwrite=args.overwrite,
                            inputs=[args.config], command="render") as out:
        if (workers or 1) > 1 or args.scheduler is not None:   # the blocks on Dask workers, joined here
            rec = render_record(cfg.scene, cfg.trajectory, cfg.sonar, cfg.pulse, workers=workers,
                                scheduler=args.scheduler, **kw)
        else:
            rec = simulate(cfg.scene, cfg.trajectory, cfg.sonar, cfg.pulse, **kw)
        if o.geo_origin_deg is not None:                      # a local scene placed on the Earth (its XTF in lat/lon)
            rec = dataclasses.replace(rec, attrs={**rec.attrs, "geo_origin_deg": list(o.geo_origin_deg)})
        return registry.write_set(rec, out, o.formats(), o.write_options())


def _checked_workers(workers, flag: str = "--workers"):
    """``--workers`` as given (None: the default), or a one-line error for a count below 1; a count beyond the
    CPUs is capped to them with a warning (each worker is a process: 1000 on 2 cores would only thrash)."""
    if workers is None:
        return None
    if workers < 1:
        raise SonarEmbreeError(f"{flag} must be >= 1, got {workers}")
    cpus = os.cpu_count() or 1
    if workers > cpus:
        log.warning("%s %d is more than the %d CPUs here; using %d", flag, workers, cpus, cpus)
        return cpus
    return workers


def _densities(text):
    """``--clutter-densities 0,10,40`` as (None, 10.0, 40.0) (0: no clutter); (None,) without it."""
    if not text:
        return (None,)
    try:
        values = [float(d) for d in text.split(",")]
    except ValueError:
        raise SonarEmbreeError(f"--clutter-densities must be numbers per m² separated by commas, got {text!r}") \
            from None
    if any(not (v >= 0) for v in values):
        raise SonarEmbreeError(f"--clutter-densities must be >= 0 per m², got {text!r}")
    return tuple(None if v == 0 else v for v in values)


def _replay_scene(args):
    """The seabed of ``replay --dem`` or ``--scene`` (None: the flat floor)."""
    if args.dem:
        return Scene().add(seafloor.from_dem(args.dem), label="seafloor", seafloor=True,
                           material=Material(scattering=sediments.preset(args.sediment)))
    return load_run_config(args.scene).scene if args.scene else None


def _configure_logging(verbose: bool) -> None:
    """Our messages at INFO with ``-v``, else warnings only; Dask's only with ``-v`` (errors always)."""
    logging.basicConfig(format="sonar-embree: %(message)s")
    level = logging.INFO if verbose else logging.WARNING
    logging.getLogger().setLevel(level)
    for handler in logging.getLogger().handlers:
        handler.setLevel(level)  # records propagated from Dask's loggers bypass the root logger's level
    for name in ("distributed", "dask", "bokeh", "tornado"):
        logging.getLogger(name).setLevel(logging.INFO if verbose else logging.ERROR)


def main(argv=None) -> int:
    """Entry point of ``sonar-embree``; returns the exit status."""
    args = _parser().parse_args(argv)
    _configure_logging(args.verbose)
    try:
        written = _run(args)
    except KeyboardInterrupt:
        print("sonar-embree: interrupted; no output was left half-written", file=sys.stderr)
        return 130
    except SonarEmbreeError as exc:
        print(f"sonar-embree: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"sonar-embree: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
