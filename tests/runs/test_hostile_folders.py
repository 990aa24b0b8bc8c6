"""Issue 49: one owner for every output. Every CLI command and every registered output format is run into folders
holding a user's files: at each of its output names, under dot-prefixed names, and its own input as an output. Not
one byte of a user's file may change.

The commands come from the CLI's parser and the formats from the registry, so a new command or format is covered
without editing the hostile cases: a command needs only a recipe here (a test fails until it has one), and a format
is rendered by the config its sonar type needs. What each command writes is learnt by running it into an empty folder
first; the user's files are then planted at exactly those names.
"""
import argparse
import datetime as dt
import hashlib
import os

import numpy as np
import pyproj
import pytest

import sonar_embree as se
from sonar_embree.io.geotiff import write_grid
from sonar_embree.io.owner import MANIFEST
from sonar_embree.record import registry
from sonar_embree.runs import cli

LAM = 1500.0 / 200e3

SIDESCAN = f"""
[sonar]
frequency_hz = 200e3
length_m = 0.1
height_m = 0.005
tilt_deg = 30.0
max_range_m = 20.0
receive_array = {{ kind = "vertical", baseline_m = {LAM} }}
[pulse]
kind = "cw"
duration_s = 100e-6
[simulation]
speckle = true
seed = 1
[trajectory]
kind = "line"
start = [-1.0, 0.0, 10.0]
end = [1.0, 0.0, 10.0]
n_pings = 4
[[objects]]
seafloor = "flat"
size_m = [30.0, 60.0]
label = "seafloor"
[[objects]]
path = "asset:anchor_mine.obj"
material = {{ backscatter_db = -15.0 }}
"""

#: The config a format needs: its sonar type's (the asset configs, made short), else the interferometric side-scan.
CONFIG_OF = {"polar": ("asset", "msis_harbour.toml", "n_pings = 200", "n_pings = 4"),
             "fan": ("asset", "fls_harbour.toml", "n_pings = 20", "n_pings = 2")}


def _groups() -> dict:
    """The registered formats grouped by the config that renders them (one render writes a group): its sonar
    type's for those in :data:`CONFIG_OF`, the interferometric side-scan's for every other."""
    groups: dict = {}
    for f in registry.FORMATS:
        groups.setdefault(f if f in CONFIG_OF else "sidescan", []).append(f)
    return groups


def _config(group: str, folder) -> str:
    """A TOML rendering the formats of ``group`` (:func:`_groups`) together, written in ``folder``."""
    fmts = _groups()[group]
    if group in CONFIG_OF:
        _, name, old, new = CONFIG_OF[group]
        text = open(se.assets.path(name), encoding="utf-8").read().replace(old, new)
        text = text[:text.index("[output]")]
    else:
        text = SIDESCAN
    text += "[output]\n" + "".join(f"{f} = {'true' if f in fmts else 'false'}\n" for f in registry.FORMATS)
    if "sas" in fmts:                                 # its grid: a patch of the starboard floor beside the track
        text += "sas_grid = { x_m = [-1.0, 1.0], y_m = [-12.0, -10.0], pixel_m = 0.25 }\n"
    path = os.path.join(folder, f"{group}.toml")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return path


def _dem_and_nav(folder):
    crs, e0, n0 = "EPSG:32631", 500_000.0, 6_000_000.0
    x = np.arange(80) + 0.5 - 40
    z = np.full((60, 80), -12.0) + 0.01 * x[None, :]
    write_grid(os.path.join(folder, "dem.tif"), z, e0 - 40, n0 + 30, 1.0, crs)
    lon, lat = pyproj.Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(
        e0 - 2 + 2.0 * np.arange(3), np.full(3, n0))
    t0 = dt.datetime(2026, 5, 1, 12, 0, 0, tzinfo=dt.timezone.utc)
    rows = "".join(f"{(t0 + dt.timedelta(seconds=k)).isoformat()},{float(a)!r},{float(o)!r},5.0\n"
                   for k, (a, o) in enumerate(zip(lat, lon)))
    with open(os.path.join(folder, "nav.csv"), "w", encoding="utf-8") as fh:
        fh.write("time,lat_deg,lon_deg,depth_m\n" + rows)
    return os.path.join(folder, "dem.tif"), os.path.join(folder, "nav.csv")


def _recording(folder) -> str:
    scene = se.Scene().add(se.seafloor.flat((200, 200)), label="seafloor",
                           material=se.Material(scattering=se.sediments.preset("apl-uw fine sand")))
    traj = se.Trajectory.line((-3, 0, 6.0), (3, 0, 6.0), 12)
    rec = se.simulate(scene, traj, se.Sonar(max_range_m=20.0), se.Pulse.cw(duration_s=100e-6),
                      start_time="2026-05-01T12:00:00Z")
    path = os.path.join(folder, "rec.xtf")
    rec.to_xtf(path, scale=1.0)
    return path


SWEEP = """
[sweep]
name = "tiny"
seeds = 1
outputs = ["png", "npz", "coco", "labels"]
pings_per_task = 4
[sonar]
max_range_m = 12.0
[[scenes]]
name = "flat"
  [[scenes.objects]]
  seafloor = "flat"
  size_m = [30.0, 30.0]
  [[scenes.objects]]
  path = "asset:moored_mine.obj"
  label = "mine"
  poses = [[0.0, -5.0, 0.0]]
[[trajectories]]
name = "pass"
start = [-1.0, 0.0, 6.0]
end = [1.0, 0.0, 6.0]
n_pings = 3
"""


def _recipe(command: str, inputs_dir):
    """(run(out, overwrite) → exit status, input files) of a CLI command: how a user would call it."""
    quiet = ["--no-progress"]
    if command == "demo":
        return (lambda out, ow: cli.main(["demo", "-o", out, "--pings", "2", *quiet] + (["--overwrite"] if ow else [])),
                [])
    if command.startswith("render:"):
        cfg = _config(command.split(":")[1], inputs_dir)
        return (lambda out, ow: cli.main(["render", cfg, "-o", out, *quiet] + (["--overwrite"] if ow else [])),
                [cfg])
    if command == "batch":
        sweep = os.path.join(inputs_dir, "sweep.toml")
        with open(sweep, "w", encoding="utf-8") as fh:
            fh.write(SWEEP)
        return (lambda out, ow: cli.main(["batch", sweep, "-o", out, "--workers", "1", *quiet]
                                         + (["--resume"] if ow else [])), [sweep])
    if command == "survey":
        dem, nav = _dem_and_nav(inputs_dir)
        return (lambda out, ow: cli.main(["survey", "--dem", dem, "--nav", nav, "--device", "cmax-cm2-325",
                                          "--ping-rate", "2", "--pixel", "1", "-o", out, *quiet]
                                         + (["--overwrite"] if ow else [])), [dem, nav])
    if command == "replay":
        xtf = _recording(inputs_dir)
        return (lambda out, ow: cli.main(["replay", xtf, "-o", out] + (["--overwrite"] if ow else [])), [xtf])
    if command == "examples":
        return (lambda out, ow: cli.main(["examples", "--copy", "anchor_mine.toml", _made(out)]), [])
    raise AssertionError(f"no hostile-folder recipe for the CLI command {command!r}: add one to _recipe")


def _made(out):
    os.makedirs(out, exist_ok=True)
    return out


def _cli_commands() -> list:
    parser = cli._parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sorted(sub.choices)


CASES = sorted([c for c in _cli_commands() if c != "render"] + [f"render:{g}" for g in _groups()])


def test_every_cli_command_and_format_is_a_hostile_case():
    """A command added to the CLI, or a format to the registry, is a case below without editing this file (render
    writes the formats a group at a time; every output name a run writes is then planted one at a time)."""
    assert set(_cli_commands()) <= {c.split(":")[0] for c in CASES}
    rendered = [f for c in CASES if c.startswith("render:") for f in _groups()[c.split(":")[1]]]
    assert sorted(rendered) == sorted(registry.FORMATS)
    for c in _cli_commands():                      # and has a recipe (an unknown command fails in _recipe)
        if c != "render":
            assert callable(_recipe(c, _scratch())[0])


def _scratch():
    import tempfile

    return tempfile.mkdtemp(prefix="sonar-embree-hostile-")


def _snapshot(folder) -> dict:
    """Every file under ``folder``: relative path → SHA-256 (the user's bytes)."""
    out = {}
    for root, _, files in os.walk(folder):
        for f in files:
            p = os.path.join(root, f)
            out[os.path.relpath(p, folder)] = hashlib.sha256(open(p, "rb").read()).hexdigest()
    return out


def _plant(path, is_dir: bool) -> None:
    """A user's file at ``path`` (a folder of that name holding one, where the command writes a folder)."""
    if is_dir:
        os.makedirs(path)
        path = os.path.join(path, "notes.txt")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(f"a user's own {os.path.basename(path)}: years of work\n")


@pytest.fixture(scope="module")
def learnt(tmp_path_factory):
    """Each case's run and inputs, and the names it writes (learnt from a run into an empty folder)."""
    cache = {}

    def get(case):
        if case not in cache:
            base = tmp_path_factory.mktemp(case.replace(":", "-"))
            run, inputs = _recipe(case, str(base))
            clean = os.path.join(base, "clean")
            assert run(clean, False) == 0
            names = {n: os.path.isdir(os.path.join(clean, n)) for n in os.listdir(clean) if n != MANIFEST}
            assert names, f"{case} wrote nothing"
            cache[case] = (run, inputs, names, base)
        return cache[case]
    return get


@pytest.mark.parametrize("case", CASES)
def test_a_users_file_at_any_output_name_survives_overwrite(case, learnt):
    """One of the user's files at each name the command writes, one name at a time, with --overwrite (batch:
    --resume): refused, every byte kept."""
    run, _, names, base = learnt(case)
    for k, (name, is_dir) in enumerate(sorted(names.items())):
        folder = os.path.join(base, f"users-{k}")
        os.makedirs(folder)
        _plant(os.path.join(folder, name), is_dir)
        before = _snapshot(folder)
        assert run(folder, True) != 0, f"{case} replaced the user's {name}"
        assert _snapshot(folder) == before, f"{case} changed the user's {name}"


@pytest.mark.parametrize("case", CASES)
def test_dot_prefixed_user_files_are_never_touched(case, learnt):
    """A folder holding only a user's dot-prefixed names (like temporaries' prefixes) is refused without
    --overwrite; with it the run writes beside them, and they keep every byte."""
    run, _, names, base = learnt(case)
    folder = os.path.join(base, "dots")
    for name in (".old-photos/img1.txt", ".tmp-draft.txt", ".sonar-embree-notes.txt", f".{sorted(names)[0]}"):
        os.makedirs(os.path.dirname(os.path.join(folder, name)), exist_ok=True)
        _plant(os.path.join(folder, name), False)
    before = _snapshot(folder)
    if case != "examples":                            # examples copies one named file into a folder: no claim
        assert run(folder, False) != 0
        assert _snapshot(folder) == before
    assert run(folder, True) == (2 if case == "batch" else 0)     # batch has no --overwrite: --resume refuses it
    after = _snapshot(folder)
    assert {k: after.get(k) for k in before} == before


@pytest.mark.parametrize("case", [c for c in CASES if c not in ("demo", "examples")])
def test_the_input_as_an_output_is_refused(case, learnt):
    """Each input hard-linked in at each output name (the same inode: the same file): refused before any work,
    the input unchanged."""
    run, inputs, names, base = learnt(case)
    assert inputs
    for i, src in enumerate(inputs):
        digest = hashlib.sha256(open(src, "rb").read()).hexdigest()
        for k, name in enumerate(n for n, d in sorted(names.items()) if not d):
            folder = os.path.join(base, f"alias-{i}-{k}")
            os.makedirs(folder)
            os.link(src, os.path.join(folder, name))
            assert run(folder, True) != 0, f"{case} overwrote its input {src} at {name}"
            assert hashlib.sha256(open(src, "rb").read()).hexdigest() == digest
