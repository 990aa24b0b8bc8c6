"""Bad input: a one-line error naming the file, key or value; no traceback from the CLI."""
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh

import sonar_embree as se
from sonar_embree.runs.cli import main

GOOD_TOML = """
[sonar]
max_range_m = 30.0
[trajectory]
kind = "line"
start = [0, 0, 10]
end = [2, 0, 10]
n_pings = 2
[[objects]]
seafloor = "flat"
size_m = [100, 100]
"""


def _cli_error(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1, err
    assert err.startswith("sonar-embree: error: ") and "Traceback" not in err
    return err


def _write(path, text, mode="w"):
    with open(path, mode) as fh:
        fh.write(text)
    return str(path)


@pytest.fixture
def bad_meshes(tmp_path):
    return {
        "missing": str(tmp_path / "nope.obj"),
        "unreadable": _write(tmp_path / "garbage.ply", b"ply\nformat binary_little_endian 1.0\n\xff\xfe junk", "wb"),
        "no_faces": _write(tmp_path / "points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"),
        "nan": _write(tmp_path / "nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"),
        "degenerate": _write(tmp_path / "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n"),
    }


@pytest.mark.parametrize("case, needle", [("missing", "not found"), ("unreadable", "cannot read"),
                                          ("no_faces", "no faces"), ("nan", "NaN"),
                                          ("degenerate", "degenerate")])
def test_bad_mesh_files(bad_meshes, case, needle, tmp_path, capsys):
    path = bad_meshes[case]
    with pytest.raises(se.SceneError) as exc:
        se.Scene.load(path)
    msg = str(exc.value)
    assert path in msg and needle in msg and "\n" not in msg
    cfg = _write(tmp_path / "run.toml", GOOD_TOML + f'[[objects]]\npath = "{path}"\n')
    err = _cli_error(capsys, ["render", cfg, "-o", str(tmp_path / "out")])
    assert path in err and needle in err
    assert not os.path.exists(tmp_path / "out")  # nothing half-written


def test_bad_trimesh_objects():
    with pytest.raises(se.SceneError, match="no faces"):
        se.Scene().add(trimesh.Trimesh(np.zeros((3, 3)), np.zeros((0, 3), int)), label="empty")
    with pytest.raises(se.SceneError, match="NaN"):
        se.Scene().add(trimesh.Trimesh([[0, 0, 0], [np.inf, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False),
                       label="inf")


@pytest.mark.parametrize("snippet, needle", [
    ("[sonar]\nfrequncy_hz = 1.0\n", "'frequncy_hz'"),
    ("[bogus]\nx = 1\n", "'bogus'"),
    ("[pulse]\nlength = 1.0\n", "'length'"),
])
def test_unknown_config_keys(tmp_path, capsys, snippet, needle):
    text = GOOD_TOML.replace("[sonar]\nmax_range_m = 30.0\n", snippet if snippet.startswith("[sonar]") else "")
    if not snippet.startswith("[sonar]"):
        text = snippet + text
    cfg = _write(tmp_path / "run.toml", text)
    err = _cli_error(capsys, ["render", cfg, "-o", str(tmp_path / "out")])
    assert needle in err and "run.toml" in err
    assert not os.path.exists(tmp_path / "out")


@pytest.mark.parametrize("line, needle", [
    ('scale = "log"', "scale"), ("dynamic_range_db = -30", "dynamic_range_db"), ("gamma = 0", "gamma"),
    ("reference_percentile = 120", "reference_percentile"), ("max_columns = 0", "max_columns"),
    ('tvg = "yes"', "tvg"),
])
def test_bad_display_values_stop_before_the_run(tmp_path, capsys, line, needle):
    cfg = _write(tmp_path / "run.toml", GOOD_TOML + f"[output]\n{line}\n")
    err = _cli_error(capsys, ["render", cfg, "-o", str(tmp_path / "out")])
    assert needle in err and "[output]" in err and "run.toml" in err
    assert not os.path.exists(tmp_path / "out")  # nothing simulated, nothing written


def test_misspelled_key_gets_a_suggestion(tmp_path, capsys):
    cfg = _write(tmp_path / "run.toml", GOOD_TOML.replace("max_range_m", "max_rnage_m"))
    err = _cli_error(capsys, ["render", cfg, "-o", str(tmp_path / "out")])
    assert "did you mean 'max_range_m'" in err


@pytest.mark.parametrize("field", ["max_range_m", "frequency_hz", "sample_rate_hz", "sound_speed_m_s",
                                   "length_m", "height_m"])
@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf")])
def test_impossible_sonar_values(field, value, tmp_path, capsys):
    with pytest.raises(se.ConfigError) as exc:
        if field == "sound_speed_m_s":          # the medium's: set in the environment
            se.Environment(**{field: value})
        else:
            se.Sonar(**{field: value})
    assert field in str(exc.value) and str(value) in str(exc.value)
    if np.isfinite(value):  # TOML: write it into a config too
        cfg = _write(tmp_path / "run.toml", GOOD_TOML.replace("max_range_m = 30.0", f"{field} = {value}"))
        assert field in _cli_error(capsys, ["render", cfg, "-o", str(tmp_path / "out")])


@pytest.mark.parametrize("kwargs", [{"duration_s": 0.0}, {"duration_s": -1e-4}, {"taper": 1.5}, {"taper": -0.1}])
def test_impossible_pulse_values(kwargs):
    with pytest.raises(se.ConfigError, match=next(iter(kwargs))):
        se.Pulse.cw(**kwargs)


def test_trajectory_with_no_pose(tmp_path, capsys):
    with pytest.raises(se.ConfigError, match="at least one pose"):
        se.Trajectory(np.zeros((0, 3)))
    with pytest.raises(se.ConfigError, match="n_pings"):
        se.Trajectory.line((0, 0, 0), (1, 0, 0), 0)
    csv = _write(tmp_path / "nav.csv", "x_m,y_m,z_m\n")
    with pytest.raises(se.ConfigError, match="at least one pose") as exc:
        se.Trajectory.from_csv(csv)
    assert csv in str(exc.value)
    cfg = _write(tmp_path / "run.toml", GOOD_TOML.replace("n_pings = 2", "n_pings = 0"))
    assert "n_pings" in _cli_error(capsys, ["render", cfg, "-o", str(tmp_path / "out")])


def test_missing_config_and_bad_toml(tmp_path, capsys):
    assert "nope.toml" in _cli_error(capsys, ["render", str(tmp_path / "nope.toml"), "-o", str(tmp_path)])
    cfg = _write(tmp_path / "broken.toml", "[sonar\n")
    assert "invalid TOML" in _cli_error(capsys, ["render", cfg, "-o", str(tmp_path / "o")])


def test_console_script_prints_one_line_without_traceback(tmp_path):
    cfg = _write(tmp_path / "run.toml", GOOD_TOML.replace("max_range_m = 30.0", "max_range_m = -5"))
    proc = subprocess.run([sys.executable, "-m", "sonar_embree.runs.cli", "render", cfg, "-o", str(tmp_path / "o")],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "Traceback" not in proc.stderr
    assert "max_range_m" in proc.stderr and "-5" in proc.stderr


def test_worker_counts_below_one_are_refused_and_beyond_the_cpus_capped(caplog, tmp_path, capsys):
    """Issue 49: --workers 0 and -1 were accepted and ignored; 1000 on 2 cores started 1000 processes."""
    import logging
    import os

    from sonar_embree.runs import cli, commands

    assert commands._checked_workers(None) is None and commands._checked_workers(1) == 1
    cpus = os.cpu_count() or 1
    with caplog.at_level(logging.WARNING):
        assert commands._checked_workers(1000) == cpus
    assert f"--workers 1000 is more than the {cpus} CPUs here; using {cpus}" in caplog.text
    for bad in ("0", "-1"):
        assert cli.main(["render", "asset:anchor_mine.toml", "-o", str(tmp_path / "o"), "--workers", bad]) == 2
        assert f"--workers must be >= 1, got {bad}" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    from sonar_embree.survey.cluster import capped_workers
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert capped_workers(1000, "batch") == cpus and capped_workers(1, "batch") == 1
    assert f"batch: workers=1000 is more than the {cpus} CPUs" in caplog.text      # the API's cap too


def test_a_first_run_says_it_compiles_the_kernels_once(tmp_path, monkeypatch, caplog):
    """Issue 50, item 6: a first run sat at 0/240 for a minute with no message while the kernels compiled; now it
    says so in one line, and only while Numba's cache holds no compiled kernel."""
    import logging

    from sonar_embree.runs import cli, commands

    (tmp_path / "empty").mkdir()
    (tmp_path / "cache" / "sonar_embree").mkdir(parents=True)
    (tmp_path / "cache" / "sonar_embree" / "rays.fan-1.py311.nbi").write_bytes(b"x")
    assert not commands.kernels_compiled([str(tmp_path / "empty")])
    assert commands.kernels_compiled([str(tmp_path / "cache")])
    for compiled, says in ((False, True), (True, False)):
        monkeypatch.setattr(commands, "kernels_compiled", lambda c=compiled: c)
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            assert cli.main(["demo", "-o", str(tmp_path / f"o{compiled}"), "--pings", "2", "--no-progress"]) == 0
        assert ("compiling the simulation kernels" in caplog.text) == says


def test_help_and_argument_errors_need_no_simulator_imports():
    """Issue 50, item 6: `sonar-embree --help` took 5–25 s importing SciPy, Dask and xarray; the parser module and
    the package now load none of them (the commands import them when they run; timed in docs/benchmarks.md)."""
    import subprocess
    import sys

    code = ("import sys, sonar_embree.runs.cli as c\n"
            "try:\n    c.main(['render', '--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = sorted(m for m in ('scipy', 'numba', 'dask', 'xarray', 'trimesh', 'embreex') if m in sys.modules)\n"
            "print('HEAVY', heavy)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120).stdout
    assert "HEAVY []" in out, out[-500:]
