"""Sweeps: a TOML description of many simulations, expanded into jobs (for :mod:`sonar_embree.runs.batch`).

A sweep file holds the tables of a render config (``[sonar]``, ``[pulse]``,
``[fan]``, ``[simulation]`` without ``seed``) as the base settings, plus:

- ``[sweep]``: ``name``; ``seeds`` (a list, or a count n for 0 … n − 1);
  ``outputs`` (any of "zarr", "xtf", "png", "labels", "coco", "npz"; default
  zarr, xtf, png, coco); ``pings_per_task`` (pings per Dask task, default 32);
  ``complex`` (keep the complex baseband in Zarr/npz; coherent speckle only);
  ``start_time`` (ISO 8601 or a TOML date-time: the time of ping time 0 in XTF,
  Zarr and COCO; default 2000-01-01T00:00:00Z, fixed so a sweep's bytes do not
  depend on when it ran).
- ``[vary]``: ``"table.field" = [values]``; every combination is a job.
- ``[[scenes]]``: ``name`` and ``[[scenes.objects]]``. An object is a mesh
  ``path`` or a procedural ``seafloor`` (as in render configs; a seafloor without
  ``seed`` takes the job's seed), or a mesh ``path`` placed as instances:
  ``count`` random poses (``region = [[x0, x1], [y0, y1]]`` m, ``yaw_deg = [lo, hi]``)
  or listed ``poses = [[x, y, yaw_deg], …]`` (a 4th value: height above the floor,
  m). Instances rest on the seafloor (their lowest point at the floor's height
  under their origin, plus ``z_m``), are yawed about z (counter-clockwise from +x,
  degrees), labelled ``label#k`` and get a ``material`` whose values may be
  ``[lo, hi]`` ranges drawn per instance.
- ``[[trajectories]]``: tables like ``[trajectory]`` of a render config, with an
  optional ``name``.
- ``[png]``: waterfall options ``scale``, ``dynamic_range_db``, ``gamma``,
  ``tvg``, ``max_columns`` (slant range, so labels and boxes stay aligned).

Jobs are scenes × trajectories × [vary] combinations × seeds, in that order. Random
placements and floors draw from the job's seed only: the same sweep gives the
same jobs anywhere. Loading checks every key and value and builds each scene once
(first seed), so bad input stops before any job runs.
"""
from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import itertools
import json
import math
import os
from dataclasses import dataclass

import numpy as np

from ..config import Acquisition, FanSettings, Material, Pulse, SignalChain, Sonar, field_names
from ..environment import Environment
from ..errors import ConfigError, SonarEmbreeError
from ..record import registry
from ..scene import Scene, load_mesh
from ..trajectory import Trajectory
from . import runconfig
from ..raycast import RayCaster
from ..validation import iso_utc

TOP_KEYS = ("sweep", "sonar", "environment", "pulse", "fan", "simulation", "vary", "scenes", "trajectories", "png")
SWEEP_KEYS = ("name", "seeds", "outputs", "pings_per_task", "complex", "start_time")
#: Start time of a sweep's records unless ``[sweep] start_time`` says otherwise: fixed, so that the
#: same sweep gives the same bytes whenever it runs.
DEFAULT_SWEEP_START = "2000-01-01T00:00:00+00:00"
OUTPUTS = tuple(registry.FORMATS)
DEFAULT_OUTPUTS = ("zarr", "xtf", "png", "coco")
PNG_KEYS = ("scale", "dynamic_range_db", "gamma", "tvg", "reference_percentile", "floor_headroom_db", "max_columns")
PLACED_KEYS = ("path", "label", "material", "count", "region", "yaw_deg", "z_m", "poses", "up_axis")
TABLES = {"environment": Environment, "sonar": Sonar, "pulse": Pulse, "fan": FanSettings, "simulation": SignalChain}
DEFAULT_PINGS_PER_TASK = 32


@dataclass(frozen=True, eq=False)
class Job:
    """One simulation of a sweep: everything a worker needs besides the scene description."""

    index: int
    scene_index: int
    trajectory_index: int
    vary: tuple          # ((key, value), …)
    seed: int
    trajectory: Trajectory
    sonar: Sonar
    pulse: Pulse
    fan: FanSettings
    chain: SignalChain
    labels: bool
    keep_complex: bool = False
    start_time: str = DEFAULT_SWEEP_START
    environment: Environment = Environment()

    @property
    def id(self) -> str:
        """Folder name of the job's outputs."""
        return f"{self.index:05d}"

    def describe(self, sweep: "Sweep") -> dict:
        return {"id": self.id, "scene": sweep.scene_names[self.scene_index],
                "trajectory": sweep.trajectory_names[self.trajectory_index], "seed": self.seed,
                "vary": {k: v for k, v in self.vary}, "n_pings": len(self.trajectory)}


@dataclass(frozen=True, eq=False)
class SceneSpec:
    """A scene description from a sweep, buildable for any seed (picklable: plain data)."""

    index: int
    name: str
    objects: tuple       # the [[scenes.objects]] tables
    source: str
    base: str

    def build(self, seed: int) -> Scene:
        """The scene for ``seed``: procedural floors and random placements drawn from it."""
        scene = Scene()
        placed = []
        for i, obj in enumerate(self.objects):
            where = f"scene {self.name!r} object #{i + 1}"
            if isinstance(obj, dict) and ("count" in obj or "poses" in obj):
                placed.append((i, obj, where))
                continue
            if isinstance(obj, dict) and "seafloor" in obj:
                obj = dict(obj)
                fn = runconfig.SEAFLOORS.get(obj["seafloor"])
                if fn is not None and "seed" in _params(fn) and "seed" not in obj:
                    obj["seed"] = int(seed)
            with _named(self.source, where):
                runconfig.add_object(scene, obj, self.source, self.base, where)
        caster = None
        if placed and scene.objects:  # instances rest on what lies below them (floors and fixed meshes)
            caster = RayCaster(scene.compiled())
        support = scene.compiled() if caster is not None else None
        top = scene.bounds[1, 2] + 1.0 if caster is not None else 0.0
        for i, obj, where in placed:
            with _named(self.source, where):
                self._place(scene, caster, support, top, seed, i, obj, where)
        return scene

    def _place(self, scene, caster, support, top, seed, i, obj, where):
        src = self.source
        mesh = load_mesh(runconfig._resolve(self.base, obj["path"]), obj.get("up_axis"))
        label = obj.get("label") or os.path.splitext(os.path.basename(obj["path"]))[0]
        rng = np.random.default_rng([int(seed), self.index, i])
        poses = _poses(obj, rng, src, where)
        mat_t = obj.get("material", {})
        for k, (x, y, yaw, z) in enumerate(poses):
            values = {key: (rng.uniform(*v) if isinstance(v, list) else v) for key, v in mat_t.items()}
            material = runconfig.parse_material(values, src, where)
            c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
            v = mesh.vertices @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
            ground = 0.0
            if caster is not None:
                o = np.array([[x, y, top]]) - support.origin_m
                hit = caster.cast(o, np.array([[0.0, 0.0, -1.0]]), 1e9)
                if hit.tri[0] < 0:
                    raise ConfigError(f"{src}: {where}: instance {k} at ({x:.2f}, {y:.2f}) m has no seafloor "
                                      "below it")
                ground = top - float(hit.range_m[0])
            m = mesh.copy()
            m.vertices = v + np.array([x, y, ground + z - v[:, 2].min()])
            scene.add(m, material=material, label=f"{label}#{k}", seafloor=False)


@contextlib.contextmanager
def _named(source: str, where: str):
    """Prefix errors that do not name the sweep file yet (mesh files, scene labels) with it."""
    try:
        yield
    except SonarEmbreeError as exc:
        if str(exc).startswith(source):
            raise
        raise type(exc)(f"{source}: {where}: {exc}") from None


def _params(fn):
    import inspect
    return inspect.signature(fn).parameters


def _pair(value, name, src, where):
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)
            or not value[0] <= value[1]):
        raise ConfigError(f"{src}: {where}: {name} must be [low, high] with low <= high, got {value!r}")
    return float(value[0]), float(value[1])


def _height(obj, src, where) -> float:
    z = obj.get("z_m", 0.0)
    if isinstance(z, bool) or not isinstance(z, (int, float)) or not math.isfinite(z):
        raise ConfigError(f"{src}: {where}: z_m must be a number (height above the floor, m), got {z!r}")
    return float(z)


def _poses(obj, rng, src, where):
    """(k, 4) x, y, yaw_deg, height above floor."""
    if "poses" in obj:
        poses = obj["poses"]
        try:
            a = [list(map(float, p)) for p in poses]
        except (TypeError, ValueError):
            a = None
        if not isinstance(poses, list) or a is None or any(len(p) not in (3, 4) for p in a):
            raise ConfigError(f"{src}: {where}: poses must be a list of [x, y, yaw_deg] or [x, y, yaw_deg, z_m]")
        return [(p[0], p[1], p[2], p[3] if len(p) == 4 else _height(obj, src, where)) for p in a]
    count = obj["count"]
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise ConfigError(f"{src}: {where}: count must be an integer >= 0, got {count!r}")
    region = obj.get("region")
    if not isinstance(region, list) or len(region) != 2:
        raise ConfigError(f"{src}: {where}: random poses need region = [[x0, x1], [y0, y1]] (m)")
    (x0, x1), (y0, y1) = (_pair(r, "region", src, where) for r in region)
    yaw = _pair(obj.get("yaw_deg", [0.0, 360.0]), "yaw_deg", src, where)
    z = _height(obj, src, where)
    return [(rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(*yaw), z) for _ in range(count)]


@dataclass(frozen=True, eq=False)
class Sweep:
    """A loaded, checked sweep: its jobs and output options."""

    source: str
    name: str
    scenes: tuple        # SceneSpec per [[scenes]]
    trajectory_names: tuple
    jobs: tuple          # Job
    outputs: tuple
    pings_per_task: int
    png: dict
    categories: tuple    # COCO categories (labels of every non-seafloor object, before '#'), sorted
    start_time: str = DEFAULT_SWEEP_START   # ISO 8601, UTC: time of ping time 0 of every job
    inputs: str = ""     # digest of the files the sweep reads (meshes, trajectory CSVs)

    @property
    def scene_names(self) -> tuple:
        return tuple(s.name for s in self.scenes)

    @property
    def labels(self) -> bool:
        return "labels" in self.outputs or "coco" in self.outputs

    def manifest(self) -> dict:
        """What identifies the sweep's outputs (written as OUT/sweep.json, compared on resume)."""
        from .._version import __version__

        jobs = [j.describe(self) for j in self.jobs]
        body = {"name": self.name, "outputs": list(self.outputs),
                "complex": any(j.keep_complex for j in self.jobs), "pings_per_task": self.pings_per_task,
                "png": self.png, "categories": list(self.categories), "package_version": __version__,
                "settings": _job_settings_digest(self.jobs), "scenes": _scenes_digest(self.scenes),
                "trajectories": _digest([_poses_of(t) for t in {id(j.trajectory): j.trajectory
                                                               for j in self.jobs}.values()]),
                "input_files": self.inputs, "start_time": self.start_time, "jobs": jobs}
        return body

    def manifest_digest(self) -> str:
        """A short hash of :meth:`manifest` (names Dask keys of this sweep's tasks)."""
        return _digest(self.manifest())


def _digest(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()


def _poses_of(t: Trajectory) -> list:
    return [t.positions_m.tolist(), t.heading_deg.tolist(), t.pitch_deg.tolist(), t.roll_deg.tolist(),
            t.times_s.tolist()]


def _job_settings_digest(jobs) -> str:
    return _digest([[dataclasses.asdict(x) for x in (j.sonar, j.environment, j.pulse, j.fan, j.chain)] for j in jobs])


def _files_digest(paths) -> str:
    """SHA-256 over the contents of ``paths`` (in order): a resume notices an edited mesh or CSV."""
    h = hashlib.sha256()
    for path in paths:
        h.update(os.path.abspath(path).encode() + b"\0")
        try:
            with open(path, "rb") as fh:
                for chunk in iter(lambda: fh.read(1 << 20), b""):
                    h.update(chunk)
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read ({exc.strerror or exc})") from None
    return h.hexdigest()


def _input_files(base: str, data: dict) -> list:
    """Every file a sweep reads besides itself: meshes of [[scenes.objects]], CSVs of [[trajectories]]."""
    paths = []
    for sc in data.get("scenes", []):
        for obj in sc.get("objects", []) if isinstance(sc, dict) else []:
            if isinstance(obj, dict) and isinstance(obj.get("path"), str):
                paths.append(runconfig._resolve(base, obj["path"]))
    for t in data.get("trajectories", []):
        if isinstance(t, dict) and t.get("kind") == "csv" and isinstance(t.get("path"), str):
            paths.append(runconfig._resolve(base, t["path"]))
    return paths


def _start_time(value, src) -> str:
    """``[sweep] start_time`` (TOML datetime or ISO 8601 string) as an ISO 8601 UTC string."""
    try:
        return iso_utc(value)
    except ConfigError as exc:
        raise ConfigError(f"{src}: [sweep] start_time: {exc}") from None


def _scenes_digest(scenes) -> str:
    return _digest([[s.name, list(s.objects)] for s in scenes])


def _seeds(value, src):
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 1:
            raise ConfigError(f"{src}: [sweep] seeds must be a count >= 1 or a list of integers, got {value!r}")
        return list(range(value))
    if (not isinstance(value, list) or not value
            or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in value)):
        raise ConfigError(f"{src}: [sweep] seeds must be a count >= 1 or a list of integers >= 0, got {value!r}")
    if len(set(value)) != len(value):
        raise ConfigError(f"{src}: [sweep] seeds repeat a value: {value!r}")
    return list(value)


def load_sweep(path) -> Sweep:
    """Read and check a sweep file; every error is one line naming the file and key."""
    src, data = runconfig.read_toml(path, "sweep")
    base = os.path.dirname(os.path.abspath(src))
    runconfig._check_keys("the top level", data, TOP_KEYS, src)

    name, seeds, outputs, ppt, keep_complex, png = _sweep_table(data, src)
    combos, settings = _settings(data, src, keep_complex)
    trajectories, traj_names = _trajectories(data, src, base)
    scenes, categories = _scenes(data, src, base, seeds)
    start = _start_time(data.get("sweep", {}).get("start_time", DEFAULT_SWEEP_START), src)
    labels = any(registry.FORMATS[o].needs_labels for o in outputs)
    jobs = []
    for si, ti, ci, seed in itertools.product(range(len(scenes)), range(len(trajectories)), range(len(combos)),
                                              seeds):
        s = settings[ci]
        chain = dataclasses.replace(s["simulation"], seed=int(seed))
        jobs.append(Job(len(jobs), si, ti, combos[ci], int(seed), trajectories[ti], s["sonar"], s["pulse"],
                        s["fan"], chain, labels, keep_complex, start, s["environment"]))
    return Sweep(src, name, tuple(scenes), tuple(traj_names), tuple(jobs), tuple(outputs), ppt, dict(png),
                 tuple(sorted(categories)), start, _files_digest(_input_files(base, data)))


def _sweep_table(data, src):
    """The [sweep] and [png] tables: name, seeds, outputs, pings per task, complex, png options."""
    sw = data.get("sweep", {})
    runconfig._check_keys("[sweep]", sw, SWEEP_KEYS, src)
    name = str(sw.get("name", os.path.splitext(os.path.basename(src))[0]))
    seeds = _seeds(sw.get("seeds", 1), src)
    outputs = sw.get("outputs", list(DEFAULT_OUTPUTS))
    if not isinstance(outputs, list) or not outputs or any(o not in OUTPUTS for o in outputs):
        raise ConfigError(f"{src}: [sweep] outputs must be a non-empty list of {list(OUTPUTS)}, got {outputs!r}")
    ppt = sw.get("pings_per_task", DEFAULT_PINGS_PER_TASK)
    if isinstance(ppt, bool) or not isinstance(ppt, int) or ppt < 1:
        raise ConfigError(f"{src}: [sweep] pings_per_task must be an integer >= 1, got {ppt!r}")
    keep_complex = sw.get("complex", False)
    if not isinstance(keep_complex, bool):
        raise ConfigError(f"{src}: [sweep] complex must be true or false, got {keep_complex!r}")
    png = data.get("png", {})
    runconfig._check_keys("[png]", png, PNG_KEYS, src)
    runconfig._build(src, "[png]", runconfig.OutputOptions, png)  # the render [output] checks, one place
    return name, seeds, outputs, ppt, keep_complex, png


def _settings(data, src, keep_complex):
    """Every combination of [vary] over the setting tables: (combos, the built settings of each)."""
    base_tables = {}
    for t, cls in TABLES.items():
        table = data.get(t, {})
        runconfig._check_keys(f"[{t}]", table, _keys(t), src)  # a sonar's against its type when built
        base_tables[t] = dict(table)
    if "seed" in base_tables["simulation"]:
        raise ConfigError(f"{src}: [simulation] seed is set per job by [sweep] seeds; remove it")

    vary = data.get("vary", {})
    if not isinstance(vary, dict):
        raise ConfigError(f"{src}: [vary] must be a table")
    for key, values in vary.items():
        table, _, fld = key.partition(".")
        if (table not in TABLES or fld not in _keys(table)
                or (table, fld) == ("simulation", "seed")):
            raise ConfigError(f"{src}: [vary] key {key!r} must be 'table.field' with table one of "
                              f"{list(TABLES)} and a field of it (seed comes from [sweep] seeds)")
        if not isinstance(values, list) or not values:
            raise ConfigError(f"{src}: [vary] {key!r} must be a non-empty list of values")
    combos = [tuple(zip(vary, c)) for c in itertools.product(*vary.values())] if vary else [()]
    return combos, [_build_combo(base_tables, combo, src, keep_complex) for combo in combos]


def _keys(table: str) -> tuple:
    """The keys a setting table may hold; ``[sonar]``: those of every sonar type (``type`` picks one)."""
    if table == "sonar":
        return tuple(dict.fromkeys(k for cls in runconfig.SONAR_TYPES.values() for k in runconfig.table_keys(cls)))
    return runconfig.table_keys(TABLES[table])


def _build_combo(base_tables, combo, src, keep_complex) -> dict:
    tables = {t: dict(v) for t, v in base_tables.items()}
    for key, value in combo:
        t, _, fld = key.partition(".")
        tables[t][fld] = value
    where = "[vary] " + ", ".join(f"{k} = {v!r}" for k, v in combo) if combo else "base settings"
    built = {}
    for t, cls in TABLES.items():
        if t == "sonar":
            built[t], built["environment"] = runconfig.build_sonar(src, f"[sonar] ({where})", tables[t],
                                                                   built["environment"])
        else:
            built[t] = runconfig._build(src, f"[{t}] ({where})", cls, tables[t])
    acquisition = runconfig._build(src, f"[sonar] ({where})", Acquisition,
                                   {"sonar": built["sonar"].for_pulse(built["pulse"]),
                                    "environment": built["environment"]})
    try:
        chain = built["simulation"].resolved(acquisition, built["pulse"])
    except SonarEmbreeError as exc:
        raise ConfigError(f"{src}: {where}: {exc}") from None
    if keep_complex and not (chain.speckle and chain.detection == "coherent" and chain.lowpass_hz is None):
        raise ConfigError(f"{src}: [sweep] complex needs coherent speckle without lowpass_hz ({where})")
    return built


def _trajectories(data, src, base):
    trajs = data.get("trajectories", [])
    if not isinstance(trajs, list) or not trajs:
        raise ConfigError(f"{src}: needs at least one [[trajectories]] entry")
    trajectories, traj_names = [], []
    for i, t in enumerate(trajs):
        if not isinstance(t, dict):
            raise ConfigError(f"{src}: [[trajectories]] #{i + 1} must be a table")
        t = dict(t)
        traj_names.append(str(t.pop("name", f"trajectory{i}")))
        trajectories.append(runconfig.parse_trajectory(t, src, base, f"[[trajectories]] #{i + 1}"))
    return trajectories, traj_names


def _scenes(data, src, base, seeds):
    """The [[scenes]] (each built once with the first seed: every key, file and value checked) and the COCO
    categories (labels of every object that is not seafloor)."""
    scenes_t = data.get("scenes", [])
    if not isinstance(scenes_t, list) or not scenes_t:
        raise ConfigError(f"{src}: needs at least one [[scenes]] entry")
    scenes, categories = [], set()
    for i, sc in enumerate(scenes_t):
        where = f"[[scenes]] #{i + 1}"
        runconfig._check_keys(where, sc, ("name", "objects"), src)
        objs = sc.get("objects", [])
        if not isinstance(objs, list) or not objs:
            raise ConfigError(f"{src}: {where} needs at least one [[scenes.objects]] entry")
        for j, obj in enumerate(objs):
            if isinstance(obj, dict) and ("count" in obj or "poses" in obj):
                runconfig._check_keys(f"{where} object #{j + 1}", obj, PLACED_KEYS, src)
                if "path" not in obj:
                    raise ConfigError(f"{src}: {where} object #{j + 1}: placed instances need a mesh 'path'")
                label = obj.get("label") or os.path.splitext(os.path.basename(str(obj["path"])))[0]
                if "#" in label:
                    raise ConfigError(f"{src}: {where} object #{j + 1}: label {label!r} must not contain '#'")
                mat = obj.get("material", {})
                runconfig._check_keys(f"{where} object #{j + 1} material", mat, field_names(Material), src)
                for key, v in mat.items():  # both ends of a range must be valid materials
                    if isinstance(v, list):
                        _pair(v, f"material {key}", src, f"{where} object #{j + 1}")
                    for end in (v if isinstance(v, list) else [v]):
                        runconfig.parse_material({key: end}, src, f"{where} object #{j + 1}")
                categories.add(label)
        spec = SceneSpec(i, str(sc.get("name", f"scene{i}")), tuple(objs), src, base)
        built = spec.build(seeds[0])  # every key, file and value checked before any job runs
        categories |= {o.label.split("#", 1)[0] for o in built.objects if not o.seafloor}
        scenes.append(spec)
    return scenes, categories
