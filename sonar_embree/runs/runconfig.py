"""TOML run descriptions mapped 1:1 onto the dataclasses.

Tables: ``[sonar]`` (fields of :class:`Sonar`), ``[environment]`` (:class:`Environment`;
the medium's keys are still accepted in ``[sonar]``), ``[pulse]`` (:class:`Pulse`),
``[fan]`` (:class:`FanSettings`), ``[simulation]`` (:class:`SignalChain`: speckle,
band, detection, matched_filter, tvg, noise_db_per_hz, lowpass_hz, speckle_cell_m, seed),
``[trajectory]`` (``kind`` = "line" | "waypoints" | "csv" and that constructor's
arguments), ``[[objects]]`` (``path`` to a mesh file *or* ``seafloor`` =
"flat" | "perlin" | "ripples" with that function's arguments; optional ``label``,
``material = {backscatter_db = …}`` or ``{law = {kind = "kirchhoff", …}}`` and, for mesh files, ``is_seafloor`` and ``materials``, a table of
per-object materials by object name) and ``[output]``. Relative paths are taken
from the config file's folder. Any unknown key is an error naming it.
"""
from __future__ import annotations

import difflib
import inspect
import os
import warnings
from dataclasses import dataclass

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python < 3.11
    import tomli as tomllib

from .. import assets
from ..config import (LEGACY_MEDIUM_KEYS, Acquisition, FanSettings, Material, Pulse, SignalChain, Sonar, field_names,
                      split_medium)
from ..environment import Environment
from ..errors import ConfigError, SceneError, SonarEmbreeError
from ..record import registry
from ..laws import sediments
from ..laws import LAWS, AplUw, Clutter, Composite, KTexture, Tabulated
from ..laws.small_slope import small_slope_sediment
from ..laws.apl_uw import apl_class
from ..laws.maps import BackscatterMap
from ..scene import Scene, features, seafloor
from ..sonars import MSIS, EchoSounder, ForwardLooking
from ..trajectory import Trajectory
from ..display.waterfall import DISPLAY_DEFAULTS, check_display
from ..validation import check_number

SEAFLOORS = {"flat": seafloor.flat, "perlin": seafloor.perlin, "ripples": seafloor.ripples}
TRAJECTORY_KINDS = {
    "line": ("start", "end", "n_pings", "speed_m_s", "pitch_deg", "roll_deg", "heading_deg", "motion_during_ping"),
    "waypoints": ("waypoints", "n_pings", "speed_m_s", "pitch_deg", "roll_deg", "motion_during_ping"),
    "csv": ("path", "motion_during_ping"),
}
TOP_KEYS = ("sonar", "environment", "pulse", "fan", "simulation", "trajectory", "objects", "output")
OUTPUT_KEYS = tuple(registry.FORMATS) + ("scale", "dynamic_range_db", "gamma", "ground_range", "tvg", "reference_percentile",
               "floor_headroom_db", "max_columns", "geo_origin_deg", "bathymetry_pixel_m", "sas_grid")


@dataclass(frozen=True)
class OutputOptions:
    """What ``render`` writes (any format of :mod:`sonar_embree.record.registry`; default the waterfall PNG
    and the record .npz), and how the PNG looks
    (the display keywords of :func:`~sonar_embree.display.waterfall.waterfall_image`, checked here)."""

    png: bool = True
    polar: bool = False
    fan: bool = False
    npz: bool = True
    zarr: bool = False
    xtf: bool = False
    labels: bool = False
    coco: bool = False
    soundings: bool = False
    bathymetry: bool = False
    bathymetry_pixel_m: float = 0.5
    sas: bool = False
    sas_grid: dict | None = None  # the SAS image's grid (registry.check_sas_grid): needed with sas = true
    scale: str = DISPLAY_DEFAULTS["scale"]
    dynamic_range_db: float = DISPLAY_DEFAULTS["dynamic_range_db"]
    gamma: float = DISPLAY_DEFAULTS["gamma"]
    ground_range: bool = DISPLAY_DEFAULTS["ground_range"]
    tvg: bool = DISPLAY_DEFAULTS["tvg"]
    reference_percentile: float = DISPLAY_DEFAULTS["reference_percentile"]
    floor_headroom_db: float = DISPLAY_DEFAULTS["floor_headroom_db"]
    max_columns: int | None = DISPLAY_DEFAULTS["max_columns"]
    geo_origin_deg: tuple | None = None  # (lat, lon) of a local scene's origin: the XTF then holds lat/lon

    def __post_init__(self):
        for name in (*registry.FORMATS, "ground_range", "tvg"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be true or false, got {getattr(self, name)!r}")
        check_display(self.scale, self.dynamic_range_db, self.gamma, self.reference_percentile, self.max_columns,
                      self.floor_headroom_db)
        check_number("[output]", "bathymetry_pixel_m", self.bathymetry_pixel_m, positive=True)
        if self.sas_grid is not None:
            registry.check_sas_grid(self.sas_grid)
        elif self.sas:
            raise ConfigError("[output] sas = true needs sas_grid = { x_m = [min, max], y_m = [min, max], "
                              "pixel_m = … }")
        g = self.geo_origin_deg
        if g is not None and not (isinstance(g, (list, tuple)) and len(g) == 2
                                  and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in g)
                                  and abs(g[0]) <= 84.0 and abs(g[1]) <= 180.0):
            raise ConfigError(f"geo_origin_deg must be [latitude, longitude] in degrees (|lat| <= 84), got {g!r}")

    def formats(self) -> tuple:
        """The output formats switched on (names of :data:`sonar_embree.record.registry.FORMATS`)."""
        return tuple(n for n in registry.FORMATS if getattr(self, n))

    def needs_labels(self) -> bool:
        return any(registry.FORMATS[n].needs_labels for n in self.formats())

    def png_kwargs(self) -> dict:
        return {k: getattr(self, k) for k in DISPLAY_DEFAULTS}

    def write_options(self) -> "registry.WriteOptions":
        """What the writers need: the display keywords and the soundings grid's pixel."""
        return registry.WriteOptions(self.png_kwargs(), bathymetry_pixel_m=self.bathymetry_pixel_m,
                                     sas_grid=self.sas_grid)


@dataclass(frozen=True, eq=False)
class RunConfig:
    """A complete render job read from TOML."""

    scene: Scene
    trajectory: Trajectory
    sonar: Sonar
    pulse: Pulse
    fan: FanSettings
    chain: SignalChain
    output: OutputOptions
    environment: Environment = Environment()

    @property
    def acquisition(self) -> Acquisition:
        """The run's sonar in its medium (for the pulse's sample rate): c, λ, the beam, the noise."""
        return Acquisition(self.sonar.for_pulse(self.pulse), self.environment)


def _check_keys(where: str, table, allowed, source: str):
    if not isinstance(table, dict):
        raise ConfigError(f"{source}: {where} must be a table, got {type(table).__name__}")
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else f" (allowed: {', '.join(allowed)})"
            raise ConfigError(f"{source}: unknown key {key!r} in {where}{hint}")


def _build(source: str, where: str, fn, kwargs):
    try:
        return fn(**kwargs)
    except SonarEmbreeError as exc:
        raise type(exc)(f"{source}: {where}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{source}: {where}: {exc}") from None


#: ``[sonar] type`` → the sonar type's configuration class.
SONAR_TYPES = {"sidescan": Sonar, "msis": MSIS, "echosounder": EchoSounder, "forward_looking": ForwardLooking}


def table_keys(cls) -> tuple:
    """The keys a TOML table of ``cls`` may hold: its fields (``[sonar]``: also the medium's old keys)."""
    if cls is Sonar:
        return field_names(Sonar) + LEGACY_MEDIUM_KEYS + ("preset", "type")
    if cls in SONAR_TYPES.values():
        return field_names(cls) + ("type",)
    return field_names(cls)


def sonar_class(source: str, where: str, sonar_table: dict):
    """The sonar type a ``[sonar]`` table asks for (``type``, default "sidescan")."""
    kind = sonar_table.get("type", "sidescan")
    if not isinstance(kind, str) or kind not in SONAR_TYPES:
        raise ConfigError(f"{source}: {where}: unknown sonar type {kind!r} (one of {', '.join(SONAR_TYPES)})")
    return SONAR_TYPES[kind]


def _dataclass_table(data, name, cls, source):
    table = data.get(name, {})
    _check_keys(f"[{name}]", table, table_keys(cls), source)
    return _build(source, f"[{name}]", cls, table)


def build_sonar(source: str, where: str, sonar_table: dict, environment: Environment) -> tuple:
    """(the sonar of a ``[sonar]`` table (its ``type``), the medium ``environment``): a side-scan table's old medium
    keys are moved into the medium, with a warning."""
    cls = sonar_class(source, where, sonar_table)
    _check_keys(where, sonar_table, table_keys(cls), source)
    if cls is not Sonar:
        return _build(source, where, cls, {k: v for k, v in sonar_table.items() if k != "type"}), environment
    both = [k for k in LEGACY_MEDIUM_KEYS if k in sonar_table and getattr(environment, k) != getattr(Environment(), k)]
    if both:
        raise ConfigError(f"{source}: {where}: {both[0]!r} is given in both [sonar] and [environment]; "
                          "keep it in [environment]")
    kwargs = {k: v for k, v in sonar_table.items() if k not in ("preset", "type")}
    old = [k for k in LEGACY_MEDIUM_KEYS if k in kwargs]
    if old:
        verb = "belongs" if len(old) == 1 else "belong"
        warnings.warn(f"{source}: {where}: {', '.join(old)} {verb} in [environment] (read from [sonar] for now)",
                      FutureWarning, stacklevel=2)
        kwargs, environment = split_medium(kwargs, "Sonar", environment)
    if "preset" in sonar_table:  # a device's sonar; the table's other keys override it
        return _build(source, where, lambda **kw: Sonar.preset(sonar_table["preset"], **kw), kwargs), environment
    return _build(source, where, Sonar, kwargs), environment


def _resolve(base: str, path) -> str:
    """A config's path: ``asset:NAME`` (a shipped file), absolute, or relative to the config's folder."""
    if not isinstance(path, str):
        raise ConfigError(f"path must be a string, got {path!r}")
    if path.startswith(assets.PREFIX):
        return assets.path(path)
    return path if os.path.isabs(path) else os.path.join(base, path)


def read_toml(path, what: str):
    """(the file's path, its TOML tables): ``asset:NAME`` resolved; one-line errors naming the file."""
    source = os.fspath(path)
    if source.startswith(assets.PREFIX):
        source = assets.path(source)
    try:
        with open(source, "rb") as fh:
            return source, tomllib.load(fh)
    except OSError as exc:
        raise ConfigError(f"{source}: cannot read {what} ({exc.strerror or exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: invalid TOML ({exc})") from None


def load_run_config(path) -> RunConfig:
    """Read and validate a TOML run description; raises a one-line ``ConfigError``/``SceneError``."""
    source, data = read_toml(path, "config")
    base = os.path.dirname(os.path.abspath(source))
    _check_keys("the top level", data, TOP_KEYS, source)

    profile = data.get("environment", {}).get("sound_speed")
    if isinstance(profile, dict) and "csv" in profile:  # a CTD file next to the config
        profile["csv"] = _resolve(base, profile["csv"])
    environment = _dataclass_table(data, "environment", Environment, source)
    sonar_table = data.get("sonar", {})
    if isinstance(sonar_table.get("preset"), str) and sonar_table["preset"].endswith(".toml"):
        sonar_table = {**sonar_table, "preset": _resolve(base, sonar_table["preset"])}   # a device file by it
    sonar, environment = build_sonar(source, "[sonar]", sonar_table, environment)
    pulse = _dataclass_table(data, "pulse", Pulse, source)
    if "preset" in sonar_table and "pulse" not in data:  # the device's own pulse
        pulse = Pulse.preset(sonar_table["preset"])
    fan = _dataclass_table(data, "fan", FanSettings, source)

    chain = _dataclass_table(data, "simulation", SignalChain, source)
    # the sonar in its medium (an array's grating lobes at this λ, the samples per ping at this c)
    acquisition = _build(source, "[sonar]", Acquisition, {"sonar": sonar.for_pulse(pulse), "environment": environment})
    try:
        chain.resolved(acquisition, pulse)  # combinations of sonar, medium, pulse and chain, before any work
    except SonarEmbreeError as exc:
        raise ConfigError(f"{source}: [simulation]: {exc}") from None
    out = data.get("output", {})
    _check_keys("[output]", out, OUTPUT_KEYS, source)
    output = _build(source, "[output]", OutputOptions, out)

    traj_t = data.get("trajectory", {})
    if not traj_t:
        raise ConfigError(f"{source}: missing [trajectory] table")
    traj = parse_trajectory(traj_t, source, base, "[trajectory]")

    objects = data.get("objects", [])
    if not isinstance(objects, list) or not objects:
        raise ConfigError(f"{source}: needs at least one [[objects]] entry (a mesh path or a seafloor)")
    scene = Scene()
    for i, obj in enumerate(objects):
        add_object(scene, obj, source, base, f"[[objects]] #{i + 1}")

    return RunConfig(scene, traj, sonar, pulse, fan, chain, output, environment)


def parse_trajectory(table, source: str, base: str, where: str) -> Trajectory:
    """A :class:`Trajectory` from a ``[trajectory]``-style table (``kind`` and that constructor's keys)."""
    if not isinstance(table, dict):
        raise ConfigError(f"{source}: {where} must be a table")
    traj_t = dict(table)
    kind = traj_t.pop("kind", "line")
    if not isinstance(kind, str) or kind not in TRAJECTORY_KINDS:
        raise ConfigError(f"{source}: {where} kind must be one of {list(TRAJECTORY_KINDS)}, got {kind!r}")
    _check_keys(f"{where} (kind {kind!r})", traj_t, TRAJECTORY_KINDS[kind], source)
    moving = traj_t.pop("motion_during_ping", True)
    if not isinstance(moving, bool):
        raise ConfigError(f"{source}: {where} motion_during_ping must be true or false, got {moving!r}")
    if kind in ("line", "waypoints"):
        if kind == "line":
            traj = _build(source, where, Trajectory.line, traj_t)
        else:
            traj = _build(source, where, Trajectory.through_waypoints,
                          {"waypoints_m": traj_t.pop("waypoints", None), **traj_t})
        return traj if moving else traj.stop_and_hop()
    try:
        traj = Trajectory.from_csv(_resolve(base, traj_t.get("path")))
    except ConfigError as exc:
        raise ConfigError(f"{source}: {where}: {exc}") from None
    return traj if moving else traj.stop_and_hop()


def parse_law(law, source: str, where: str, base: str = ""):
    """A scattering law: a sediment name (``"fine sand"``), ``{ kind = "kirchhoff", … }``,
    ``{ kind = "tabulated", csv = "curve.csv" }`` (or its angles and dB) or ``{ kind = "composite", terms = [ … ] }``."""
    if isinstance(law, str):
        return _build(source, where, sediments.preset, {"name": law})
    kinds = list(LAWS) + ["composite"]
    if not isinstance(law, dict) or law.get("kind") not in kinds:
        raise ConfigError(f"{source}: {where} must be a sediment name or a table with kind one of {kinds}, "
                          f"got {law!r}")
    law = dict(law)
    kind = law.pop("kind")
    if kind == "composite":
        _check_keys(where, law, ("terms",), source)
        terms = law.get("terms")
        if not isinstance(terms, list):
            raise ConfigError(f"{source}: {where} terms must be a list of laws")
        return _build(source, where, Composite,
                      {"terms": [parse_law(t, source, f"{where} term #{i + 1}", base) for i, t in enumerate(terms)]})
    if kind == "apl-uw" and ("sediment" in law or "mean_grain_size_phi" in law):
        return _apl_uw(law, source, where)
    if kind == "small-slope" and "sediment" in law:
        _check_keys(where, law, ("sediment", "integral"), source)
        return _build(source, where, small_slope_sediment, {"name": law["sediment"],
                                                             "integral": law.get("integral", "exact")})
    if kind == "tabulated" and "csv" in law:
        _check_keys(where, law, ("csv",), source)
        return _build(source, where, Tabulated.from_csv, {"path": _resolve(base, law["csv"])})
    _check_keys(where, law, field_names(LAWS[kind]), source)
    return _build(source, where, LAWS[kind], law)


def _apl_uw(law: dict, source: str, where: str):
    """``{ kind = "apl-uw", sediment = "fine sand" }`` or ``{ kind = "apl-uw", mean_grain_size_phi = 2.5, … }``
    (the handbook's parameters at that grain size, any of them overridden)."""
    if "sediment" in law:
        _check_keys(where, law, ("sediment",), source)
        return _build(source, where, apl_class, {"name": law["sediment"]})
    _check_keys(where, law, field_names(AplUw), source)
    mz = law.pop("mean_grain_size_phi")
    return _build(source, where, lambda **kw: AplUw.from_grain_size(mz, **kw), law)


def parse_material(table, source: str, where: str, base: str = "") -> Material:
    """A ``material`` table: ``backscatter_db``, ``two_sided``, ``scattering`` (or ``law``, see
    :func:`parse_law`), ``texture = { shape = …, correlation_m = …, seed = … }`` and
    ``clutter = { density_per_m2 = …, strength_db = …, spread_db = … }``."""
    _check_keys(f"{where} material", table, field_names(Material) + ("law",), source)
    table = dict(table)
    if "law" in table:
        if "scattering" in table:
            raise ConfigError(f"{source}: {where} material: give scattering or law (the same thing), not both")
        warnings.warn(f"{source}: {where} material: 'law' is now called 'scattering'", FutureWarning,
                      stacklevel=2)
        table["scattering"] = parse_law(table.pop("law"), source, f"{where} material law", base)  # named as given
    elif "scattering" in table:
        table["scattering"] = parse_law(table["scattering"], source, f"{where} material scattering", base)
    if "texture" in table:
        tex = table["texture"]
        _check_keys(f"{where} material texture", tex, field_names(KTexture), source)
        table["texture"] = _build(source, f"{where} material texture", KTexture, tex)
    if "clutter" in table:
        _check_keys(f"{where} material clutter", table["clutter"], field_names(Clutter), source)
        table["clutter"] = _build(source, f"{where} material clutter", Clutter, table["clutter"])
    return _build(source, f"{where} material", Material, table)


def seafloor_mesh(obj: dict, source: str, where: str):
    """The mesh of a procedural ``seafloor = "kind"`` entry (its other keys are the function's arguments)."""
    obj = dict(obj)
    kind = obj.pop("seafloor")
    if not isinstance(kind, str) or kind not in SEAFLOORS:
        raise ConfigError(f"{source}: {where} seafloor must be one of {list(SEAFLOORS)}, got {kind!r}")
    fn = SEAFLOORS[kind]
    _check_keys(f"{where} (seafloor {kind!r})", obj, tuple(inspect.signature(fn).parameters), source)
    return _build(source, where, fn, obj)


def add_object(scene: Scene, obj, source: str, base: str, where: str) -> None:
    """Add one ``[[objects]]`` entry (a mesh ``path`` or a procedural ``seafloor``) to ``scene``."""
    if not isinstance(obj, dict):
        raise ConfigError(f"{source}: {where} must be a table")
    obj = dict(obj)
    label = obj.pop("label", None)
    material = parse_material(obj.pop("material", {}), source, where, base)
    bmap = parse_map(obj.pop("backscatter_map", None), source, where, base)
    if sum(k in obj for k in ("path", "seafloor", "seabed")) != 1:
        raise ConfigError(f"{source}: {where} needs exactly one of 'path', 'seafloor' or 'seabed'")
    if "seabed" in obj:
        _check_keys(where, obj, ("seabed",), source)
        _add_seabed(scene, obj["seabed"], material, source, where)
        return
    if "path" in obj:
        _check_keys(where, obj, ("path", "is_seafloor", "materials", "up_axis"), source)
        is_floor = obj.get("is_seafloor")
        if is_floor is not None and not isinstance(is_floor, bool):
            raise ConfigError(f"{source}: {where} is_seafloor must be true or false, got {is_floor!r}")
        per_object = obj.get("materials", {})
        if not isinstance(per_object, dict):
            raise ConfigError(f"{source}: {where} materials must be a table of object name = {{ backscatter_db = … }}")
        per_object = {name: parse_material(t, source, f"{where} materials.{name}", base) for name, t in per_object.items()}
        try:
            scene.add(_resolve(base, obj["path"]), material=material, label=label, seafloor=is_floor,
                      materials=per_object, up_axis=obj.get("up_axis"), backscatter_map=bmap)
        except SceneError as exc:
            raise SceneError(f"{source}: {where}: {exc}") from None
    else:
        patches = {k: obj.pop(k) for k in ("sediments", "patch_m", "sediment_seed") if k in obj}
        mesh = seafloor_mesh(obj, source, where)
        if "sediments" in patches:
            _add_sediments(scene, mesh, patches, label or "seafloor", source, where)
        else:
            scene.add(mesh, material=material, label=label or "seafloor", seafloor=True, backscatter_map=bmap)


def _add_seabed(scene: Scene, table, material: Material, source: str, where: str) -> None:
    """``seabed = { size_m = [100, 100], resolution_m = 0.25, bedforms = {…}, trawl_marks = [{…}], … }``: the
    labelled seabed of :func:`sonar_embree.features.seabed`, its floor (and sand waves) of the object's material."""
    if not isinstance(table, dict):
        raise ConfigError(f"{source}: {where} seabed must be a table of sonar_embree.features.seabed's keywords")
    keys = tuple(k for k in inspect.signature(features.seabed).parameters if k not in ("materials", "scene"))
    _check_keys(f"{where} seabed", table, keys, source)
    _build(source, f"{where} seabed", features.seabed,
           {**table, "materials": {"seafloor": material, "sand_wave": material}, "scene": scene})


def _add_sediments(scene: Scene, mesh, patches: dict, label: str, source: str, where: str) -> None:
    """``sediments = { "fine sand" = 0.5, mud = 0.5 }``: preset name → share of the floor."""
    table = patches["sediments"]
    if not isinstance(table, dict) or not all(isinstance(v, (int, float)) for v in table.values()):
        raise ConfigError(f"{source}: {where} sediments must be a table of sediment name = share of the floor")
    sed = {name: (_build(source, f"{where} sediments", sediments.preset, {"name": name}), share)
           for name, share in table.items()}
    _build(source, where, scene.add_sediments, {"mesh": mesh, "sediments": sed, "label": label,
                                                "patch_m": patches.get("patch_m", 20.0),
                                                "seed": patches.get("sediment_seed", 0)})


def parse_map(table, source: str, where: str, base: str):
    """``backscatter_map = { image = "floor.png", db_range = [-6, 6] }`` or ``{ per_face = "db.npy" }`` /
    ``{ per_vertex = "db.npy" }`` (a NumPy file of dB values)."""
    if table is None:
        return None
    kinds = ("image", "per_face", "per_vertex")
    if not isinstance(table, dict) or sum(k in table for k in kinds) != 1:
        raise ConfigError(f"{source}: {where} backscatter_map needs exactly one of {list(kinds)}")
    _check_keys(f"{where} backscatter_map", table, kinds + ("db_range",), source)
    kind = next(k for k in kinds if k in table)
    path = _resolve(base, table[kind])
    if kind == "image":
        return _build(source, f"{where} backscatter_map", BackscatterMap.image,
                      {"image": path, "db_range": table.get("db_range")})
    try:
        values = np.load(path)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{source}: {where} backscatter_map: {path}: cannot read ({exc})") from None
    return _build(source, f"{where} backscatter_map", getattr(BackscatterMap, kind), {"values_db": values})
