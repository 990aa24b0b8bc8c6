"""The ``sonar-embree`` command line: ``demo``, ``render`` and ``batch``.

Errors in the user's input print one line (``sonar-embree: error: …``) and exit
with status 2; no traceback.
"""
from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading

from ..errors import SonarEmbreeError
from ..io.owner import INTERRUPTED

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
                sample_rate_hz (the instrument; type, preset, beam, levels)
  [environment] sound_speed_m_s, absorption_db_per_m (default: Francois-Garrison
                from temperature_c, salinity_ppt, depth_m, ph), surface, noise
  [pulse]       kind = "cw" | "lfm" | "exp_chirp", duration_s, taper (0 rectangle
                ... 1 Blackman-Harris; default 0.1); lfm: bandwidth_hz, center_hz;
                exp_chirp: f_start_hz, f_stop_hz
  [fan]         quality (1: flat floor within 0.2 dB; 0.5 faster; 2-4 references),
                or explicitly rays_per_bin, azimuth_oversample, azimuth_nulls,
                max_step_deg, probe_step_deg, max_rays_per_side, max_azimuth_step_deg
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
                their grid, bathymetry.tif, at bathymetry_pixel_m = 0.5 m), sas (the
                backprojected SAS image of an along-track receive_array, sas.tif, on
                sas_grid = { x_m = [min, max], y_m = [min, max], pixel_m = …,
                optional z_m, channel, taper (0.46: Hamming side lobes) });
                display: scale ("db"|"gamma"), dynamic_range_db (35), gamma,
                ground_range, tvg (display only; default true), reference_percentile
                (99.99: the level shown white), floor_headroom_db (12: white at least
                this far above the median), max_columns (1024 per side);
                geo_origin_deg = [lat, lon]: where a local scene's origin lies (XTF in lat/lon,
                GeoTIFFs in its UTM zone)

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
records its codes at its ADC's bits where stated (EdgeTech and Marine Sonic 15, else 16) through a TVG
(30 log R + 2 alpha R from just before the first bottom return, set per line so the median seabed sits at a
quarter of full scale: a dark water column, as devices record; --gain agc for an AGC). A ship's GPS log (time,
latitude, longitude) takes --depth-m or --altitude-m.

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
    p.add_argument("--classes", help="comma-separated sediment presets --fit tries (default: APL-UW coarse sand, fine "
                                     "sand, coarse silt and clay)")
    p.add_argument("--fit-beam", action="store_true", help="with --fit and no --device: fit the record's elevation "
                                                           "pattern too (tilt, vertical width); best with one class")
    p.add_argument("--fit-pulse", action="store_true", help="with --fit and no --device: fit the CW pulse length "
                                                            "from the correlation along range")
    p.add_argument("--fit-texture", action="store_true", help="with --fit: fit the floor's K-distributed texture "
                                                              "(shape ν) from the record's scintillation index")
    p.add_argument("--clutter-densities", metavar="N,N,…", help="with --fit: clutter densities per m² to try too "
                                                              "(0: none), e.g. 0,10,40,160")
    p.add_argument("--gain-db", type=float, help="the gain offset, dB (default: the median level difference)")
    p.add_argument("--device", metavar="PRESET", help="a device preset for the beam and pulse")
    p.add_argument("--seed", type=int, default=0, help="speckle seed (default 0)")
    p.add_argument("--overwrite", action="store_true", help="replace an earlier replay's files in OUT")
    p.add_argument("--no-progress", action="store_true", help="hide the fit's progress bar")


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
    p.add_argument("--caster", choices=CASTER_NAMES, default="embree",
                   help="ray caster: embree (default), bvh (the project's BVH on the CPU), cuda (the same on a CUDA "
                        "GPU, through numba.cuda)")


#: The ray casters ``--caster`` names (docs/physics.md §8b).
#: The ray casters ``--caster`` names (docs/physics.md §8b; :data:`sonar_embree.runs.commands.CASTERS`).
CASTER_NAMES = ("embree", "bvh", "cuda")


def _configure_logging(verbose: bool) -> None:
    """Our messages at INFO with ``-v``, else warnings only; Dask's only with ``-v`` (errors always)."""
    logging.basicConfig(format="sonar-embree: %(message)s")
    level = logging.INFO if verbose else logging.WARNING
    logging.getLogger().setLevel(level)
    for handler in logging.getLogger().handlers:
        handler.setLevel(level)  # records propagated from Dask's loggers bypass the root logger's level
    for name in ("distributed", "dask", "bokeh", "tornado"):
        logging.getLogger(name).setLevel(logging.INFO if verbose else logging.ERROR)


def _on_interrupt(signum, frame):
    """Ctrl-C: remembered (:data:`sonar_embree.io.owner.INTERRUPTED`), then raised as KeyboardInterrupt."""
    INTERRUPTED.set()
    raise KeyboardInterrupt


def main(argv=None) -> int:
    """Entry point of ``sonar-embree``; returns the exit status."""
    args = _parser().parse_args(argv)
    _configure_logging(args.verbose)
    here = threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is not \
        signal.SIG_IGN                               # (a shell's background job ignores Ctrl-C: so do we)
    previous = signal.signal(signal.SIGINT, _on_interrupt) if here else None
    try:
        return _run(args)
    finally:
        if here:
            signal.signal(signal.SIGINT, previous)
        INTERRUPTED.clear()


def _run(args) -> int:
    """Run the parsed command; its exit status (one line on stderr for an error or an interrupt)."""
    try:
        from . import commands                       # the simulator: imported only when a command runs

        written = commands.run(args)
        if INTERRUPTED.is_set():                     # a Ctrl-C swallowed on the way: the outputs were not written
            raise KeyboardInterrupt
    except KeyboardInterrupt:
        print("sonar-embree: interrupted; no output was left half-written", file=sys.stderr)
        return 130
    except SonarEmbreeError as exc:
        print(f"sonar-embree: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"sonar-embree: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
