"""What each ``sonar-embree`` command does (:mod:`sonar_embree.runs.cli` parses the arguments and calls
:func:`run`): the simulator's modules are imported here, when a command runs, so that ``--help`` and an argument
error answer at once."""
from __future__ import annotations

import dataclasses
import logging
import os
import shutil

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
from ..survey.cluster import capped_workers
from ..survey.stream import render_record
from .runconfig import load_run_config

log = logging.getLogger("sonar_embree.runs.cli")


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


CASTERS = {"embree": EmbreeCaster, "bvh": BvhCaster, "cuda": CudaCaster}

_CHAIN_FLAGS = ("speckle", "band", "detection", "matched_filter", "tvg", "noise_db_per_hz", "lowpass_hz", "seed")


def _chain(args, base=None):
    """The signal chain of ``base`` (default: SignalChain()) with the command-line overrides."""
    base = SignalChain() if base is None else base
    overrides = {k: getattr(args, k) for k in _CHAIN_FLAGS if getattr(args, k) is not None}
    if ("band" in overrides and overrides["band"] == "carrier") or "detection" in overrides:
        overrides.setdefault("speckle", True)
    return dataclasses.replace(base, **overrides)


def _fan(args, base=None):
    """The fan settings of ``base`` (default: FanSettings()) with ``--quality`` applied."""
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


def run(args) -> list:
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
        classes = ([c.strip() for c in (args.classes or ",".join(FIT_CLASSES)).split(",") if c.strip()]
                   if args.fit else None)
        densities = _densities(args.clutter_densities)
        replay(args.xtf, args.output, sediment=args.sediment, fit_classes=classes, gain_db=args.gain_db,
               device=args.device, seed=args.seed, overwrite=args.overwrite, scene=_replay_scene(args),
               fit_densities=densities, inputs=[args.dem, args.scene], progress=not args.no_progress,
               fit_beam=args.fit_beam, fit_texture=args.fit_texture, fit_pulse=args.fit_pulse)
        return [os.path.join(args.output, f) for f in ("replay.xtf", "report.json", "report.png", "device.toml")
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
              start_time=args.start_time, labels=o.needs_labels(), caster=CASTERS[args.caster],
              environment=cfg.environment)
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
    return capped_workers(workers, f"{flag} ")


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
