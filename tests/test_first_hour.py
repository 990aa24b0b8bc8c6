"""A new user's first hour (issue 19): each defect a user met, as a behaviour that can fail."""
import json
import os
import re
import resource
import socket
import subprocess
import sys
import urllib.error
import urllib.request

import numpy as np
import pytest
import trimesh

import sonar_embree as se
from sonar_embree.io.owner import MANIFEST, OutputFolder
from sonar_embree import batch
from sonar_embree.runs import cli
from sonar_embree.scene import write_obj
from conftest import box

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _multi_object_obj(path):
    floor = trimesh.creation.box((40.0, 40.0, 0.2))
    floor.apply_translation((0.0, 0.0, -0.1))
    rock = trimesh.creation.icosphere(2, 0.8)
    rock.apply_translation((0.0, -8.0, 0.5))
    pipe = trimesh.creation.cylinder(0.3, 6.0)
    pipe.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
    pipe.apply_translation((0.0, 8.0, 0.3))
    write_obj(path, [("seafloor", floor), ("rock", rock), ("pipe", pipe)])


SWEEP = """\
[sweep]
seeds = 1
outputs = ["png", "labels", "coco"]
pings_per_task = 4
[sonar]
max_range_m = 16.0
[[scenes]]
  [[scenes.objects]]
  path = "scene.obj"
[[trajectories]]
start = [-1.0, 0.0, 6.0]
end = [1.0, 0.0, 6.0]
n_pings = 6
"""


@pytest.fixture(scope="module")
def multi_sweep(tmp_path_factory):
    d = tmp_path_factory.mktemp("multi")
    _multi_object_obj(d / "scene.obj")
    (d / "sweep.toml").write_text(SWEEP)
    return d / "sweep.toml"


# --- 1: COCO categories from every labelled object; the whole sweep checked before work ---------------
def test_multi_object_obj_sweep_without_instances_writes_coco(multi_sweep, tmp_path, capsys):
    from pycocotools.coco import COCO

    out = tmp_path / "out"
    assert cli.main(["batch", str(multi_sweep), "-o", str(out), "--workers", "1", "--no-progress"]) == 0
    coco = COCO(str(out / "coco.json"))
    assert [c["name"] for c in coco.loadCats(coco.getCatIds())] == ["pipe", "rock"]
    names = {a["object_label"] for a in coco.loadAnns(coco.getAnnIds())}
    assert names == {"pipe", "rock"}


def test_failed_batch_leaves_no_folder_that_refuses_a_rerun(multi_sweep, tmp_path, capsys):
    """A sweep that fails mid-way (a later ping dives under the floor) leaves no sweep.json behind."""
    bad = multi_sweep.parent / "dive.toml"
    bad.write_text(SWEEP.replace("end = [1.0, 0.0, 6.0]", "end = [1.0, 0.0, -0.15]"))
    out = tmp_path / "out"
    assert cli.main(["batch", str(bad), "-o", str(out), "--workers", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "under" in err, err
    assert not out.exists() or not os.listdir(out)


# --- 4: quiet batches, no dashboard unless asked --------------------------------------------------------
def test_batch_is_quiet_on_success(multi_sweep, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "sonar_embree.runs.cli", "batch", str(multi_sweep), "-o",
                           str(tmp_path / "out"), "--workers", "1", "--no-progress"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.strip() == "", proc.stderr  # no Dask internals
    assert proc.stdout.split() == [str(tmp_path / "out" / "00000")]


def test_local_cluster_serves_no_dashboard():
    def listening(port):
        with socket.socket() as s:
            return s.connect_ex(("127.0.0.1", port)) == 0

    assert not listening(8787)
    from sonar_embree.survey.cluster import client_for

    with client_for(None, None, 1, None) as client:
        assert not listening(8787)
        link = client.dashboard_link
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(link, timeout=10)
        assert err.value.code == 404  # nothing is served, not even the status page


def test_local_workers_start_with_one_thread_and_glibcs_own_malloc_thresholds(monkeypatch):
    """One Numba thread per worker, and no ``MALLOC_TRIM_THRESHOLD_`` (Dask's default sets it, which makes every
    block's arrays fresh mmaps that fault in page by page: 20–45 % of a worker's ping, docs/benchmarks.md), even
    where an earlier Dask cluster left it set in this process, as a Nanny does before it spawns."""
    from sonar_embree.survey.cluster import client_for

    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")
    with client_for(None, None, 1, None) as client:
        env = next(iter(client.run(lambda: {k: os.environ.get(k) for k in (
            "NUMBA_NUM_THREADS", "MALLOC_TRIM_THRESHOLD_", "OPENBLAS_NUM_THREADS")}).values()))
    assert env == {"NUMBA_NUM_THREADS": "1", "MALLOC_TRIM_THRESHOLD_": None, "OPENBLAS_NUM_THREADS": "1"}
    assert os.environ["MALLOC_TRIM_THRESHOLD_"] == "65536"                  # this process's own is left as it was


def test_back_pressure_bounds_the_tasks_in_flight(multi_sweep, tmp_path):
    """40 tasks with at most 3 submitted at a time; the output equals the unbounded run."""
    from distributed import Client, LocalCluster

    text = SWEEP.replace("seeds = 1", "seeds = 5").replace("pings_per_task = 4", "pings_per_task = 1") \
        .replace("n_pings = 6", "n_pings = 8").replace('["png", "labels", "coco"]', '["npz"]')
    path = multi_sweep.parent / "many.toml"
    path.write_text(text)
    sweep = se.sweep.load_sweep(path)
    stats = {}
    os.makedirs(tmp_path / "a")
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as lc, \
            Client(lc) as client:
        batch._run_jobs(client, sweep, list(sweep.jobs), OutputFolder.claim(tmp_path / "a", []), False, 3, stats)
    assert stats["peak_in_flight"] == 3
    assert len([n for n in os.listdir(tmp_path / "a") if n.isdigit()]) == 5
    for job in sweep.jobs:
        direct = se.simulate(sweep.scenes[0].build(job.seed), job.trajectory, job.sonar, job.pulse, fan=job.fan,
                             chain=job.chain)
        np.testing.assert_array_equal(se.Record.load(tmp_path / "a" / job.id / "record.npz").port, direct.port)


# --- 7: memory estimated before any work ----------------------------------------------------------------
def test_ten_million_pings_are_refused_at_once_with_the_estimate():
    scene = se.Scene().add(se.seafloor.flat((50, 50)), label="seafloor")
    traj = se.Trajectory.line((0, 0, 10), (1000, 0, 10), n_pings=10_000_000)
    with pytest.raises(se.ConfigError) as err:
        se.simulate(scene, traj, se.Sonar())
    msg = str(err.value)
    assert len(msg.splitlines()) == 1 and "GiB" in msg and "batch" in msg
    est = float(re.search(r"about ([0-9.]+) GiB", msg).group(1))
    # 2 channels x 2667 samples x 8 bytes x 4 record-sized arrays per ping
    assert est == pytest.approx(1e7 * 2 * 2667 * 8 * 4 / 2**30, rel=0.01)


# --- 8: wrong files, overwrites, Ctrl-C ------------------------------------------------------------------
@pytest.mark.parametrize("ext, fmt", [(".obj", "OBJ"), (".stl", "STL"), (".ply", "PLY"), (".glb", "GLB")])
def test_a_png_renamed_as_a_mesh_is_named_as_not_that_format(tmp_path, ext, fmt):
    path = tmp_path / f"picture{ext}"
    path.write_bytes(open(os.path.join(ROOT, "docs", "demo.png"), "rb").read())
    with pytest.raises(se.SceneError, match=re.escape(f"{path}: not a valid {fmt} file")):
        se.Scene.load(path)


def test_latin1_bytes_in_an_obj_comment_load(tmp_path):
    path = tmp_path / "caf.obj"
    path.write_bytes(b"# caf\xe9 model\no rock\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert se.Scene.load(path).labels == ("caf",)  # one object: labelled by the file name


def test_latin1_byte_in_a_trajectory_csv_is_one_line(tmp_path):
    path = tmp_path / "nav.csv"
    path.write_bytes(b"x_m,y_m,z_m\n0,0,10\n1,0,1\xb00\n")
    with pytest.raises(se.ConfigError, match="not a UTF-8 text file"):
        se.Trajectory.from_csv(path)


RENDER = """\
[sonar]
max_range_m = 14.0
[trajectory]
start = [-1.0, 0.0, 6.0]
end = [1.0, 0.0, 6.0]
n_pings = 4
[[objects]]
seafloor = "flat"
size_m = [40.0, 40.0]
"""


def test_render_refuses_a_non_empty_folder_without_overwrite(tmp_path, capsys):
    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER)
    out = tmp_path / "out"
    assert cli.main(["render", str(cfg), "-o", str(out), "--no-progress"]) == 0
    before = (out / "record.npz").read_bytes()
    assert cli.main(["render", str(cfg), "-o", str(out), "--no-progress", "--seed", "3"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (out / "record.npz").read_bytes() == before
    (out / ".tmp-notes.npz").write_bytes(b"x" * 1000)  # a user's file with a name like a temporary's: kept
    assert cli.main(["render", str(cfg), "-o", str(out), "--no-progress", "--overwrite"]) == 0
    assert sorted(os.listdir(out)) == [MANIFEST, ".tmp-notes.npz", "record.npz", "waterfall.png"]
    assert (out / ".tmp-notes.npz").read_bytes() == b"x" * 1000


def test_disk_full_leaves_the_old_outputs_and_names_the_path(tmp_path):
    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER)
    out = tmp_path / "out"
    # the same mode first, so that numba's kernel cache is written before the disk "fills"
    assert cli.main(["render", str(cfg), "-o", str(out), "--no-progress", "--speckle"]) == 0
    old = {n: (out / n).read_bytes() for n in os.listdir(out)}

    def small_disk():  # writes beyond 20 kB fail with EFBIG, as on a full disk
        import signal
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    proc = subprocess.run([sys.executable, "-m", "sonar_embree.runs.cli", "render", str(cfg), "-o", str(out),
                           "--no-progress", "--overwrite", "--seed", "5", "--speckle"], capture_output=True,
                          text=True, timeout=300, preexec_fn=small_disk)
    assert proc.returncode == 2
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0], proc.stderr
    assert {n: (out / n).read_bytes() for n in os.listdir(out)} == old  # nothing new, nothing half-written


def test_ctrl_c_prints_one_line_and_leaves_nothing(tmp_path):
    import signal
    import time

    cfg = tmp_path / "run.toml"
    # long enough that no machine finishes before the signal (4000 plain pings at 14 m once took under 6 s): 4000
    # speckled pings at 40 m, about 20 s on 2 cores
    cfg.write_text(RENDER.replace("n_pings = 4", "n_pings = 4000\nspeed_m_s = 0.005")    # pings 2R/c apart at least
                   .replace("max_range_m = 14.0", "max_range_m = 40.0")
                   .replace("[40.0, 40.0]", "[100.0, 100.0]") + "[simulation]\nspeckle = true\n")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "sonar_embree.runs.cli", "render", str(cfg), "-o", str(out),
                             "--no-progress"], stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # as at a terminal
    # (a test run started in the background by a shell inherits SIGINT ignored; a user's terminal does not)
    time.sleep(6.0)
    for _ in range(20):       # an interrupt that lands while Numba compiles (a cold cache) can be lost: send again
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=3.0)
            break
        except subprocess.TimeoutExpired:
            continue
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130
    lines = [x for x in err.strip().splitlines() if "compiling the simulation kernels" not in x]   # a cold cache's
    assert lines == ["sonar-embree: interrupted; no output was left half-written"], err               # one notice
    assert not out.exists() or not os.listdir(out)


# --- 5: the repository is self-contained -----------------------------------------------------------------
def test_nothing_refers_outside_the_repository():
    hits = []
    for top in ("README.md", "sonar_embree", "docs", "scripts", "tests"):
        base = os.path.join(ROOT, top)
        paths = [base] if os.path.isfile(base) else [os.path.join(d, f) for d, _, fs in os.walk(base) for f in fs]
        for p in paths:
            if p.endswith((".py", ".md", ".toml", ".txt")) and not p.endswith("test_first_hour.py"):
                text = open(p, encoding="utf-8").read()
                if "shared/" in text or "PHYSICS.md" in text:
                    hits.append(p)
    assert hits == []
    physics = open(os.path.join(ROOT, "docs", "physics.md"), encoding="utf-8").read()
    for needle in ("## 1. Frames", "## 3. Echo strength", "(1)", "(2)", "−101.35 dB", "L = x·H/(h − H)",
                   "Francois", "## References"):
        assert needle in physics


# --- 2: physically wrong set-ups: an error where nothing can be meaningful, a warning where implausible ----
@pytest.fixture
def warnings_log(caplog):
    from sonar_embree import checks

    checks._warned.clear()
    caplog.set_level("WARNING", logger="sonar_embree.checks")
    yield caplog
    checks._warned.clear()


def _floor(size=60.0):
    return se.Scene().add(se.seafloor.flat((size, size)), label="seafloor")


def _line(z=10.0, x0=-1.0, x1=1.0, y=0.0, n=3):
    return se.Trajectory.line((x0, y, z), (x1, y, z), n_pings=n).stop_and_hop()


@pytest.mark.parametrize("scene, traj, sonar, message", [
    (_floor(), _line(z=-2.0), se.Sonar(max_range_m=20), "under the seafloor 'seafloor'"),
    (_floor().add(box((6, 6, 6), (0, 0, 4)), label="hull"), _line(z=2.0), se.Sonar(max_range_m=20),
     "inside the closed object 'hull'"),
    (_floor(), _line(x0=1000.0, x1=1002.0), se.Sonar(max_range_m=50), "nothing of the scene lies within"),
    (_floor(), _line(z=500.0), se.Sonar(max_range_m=50), "nothing of the scene lies within"),
    (_floor(), _line(), se.Sonar(max_range_m=0.04), "nothing of the scene lies within"),
])
def test_meaningless_set_ups_are_errors(scene, traj, sonar, message):
    with pytest.raises(se.ConfigError, match=re.escape(message)) as err:
        se.simulate(scene, traj, sonar)
    assert len(str(err.value).splitlines()) == 1


@pytest.mark.parametrize("sonar, traj, key", [
    (se.Sonar(frequency_hz=400.0, max_range_m=20), _line(), "Sonar.frequency_hz = 400 Hz"),
    (se.Sonar(tilt_deg=0.35, max_range_m=20), _line(), "Sonar.tilt_deg = 0.35° looks like radians (20.1°)"),
    (se.Sonar(max_range_m=600.0, sample_rate_hz=2000.0), _line(z=500.0), "flies 500 m above the scene"),
])
def test_implausible_values_warn_naming_the_key(warnings_log, sonar, traj, key):
    se.simulate(_floor(2000.0 if traj.positions_m[0, 2] > 100 else 60.0), traj, sonar)
    msgs = [r.getMessage() for r in warnings_log.records]
    assert any(key in m for m in msgs), msgs
    assert all(len(m.splitlines()) == 1 for m in msgs)


def test_a_unit_slip_in_range_warns_and_stops(warnings_log):
    with pytest.raises(se.ConfigError, match="nothing of the scene"):
        se.simulate(_floor(), _line(), se.Sonar(max_range_m=0.04))
    assert any("max_range_m = 0.04 m" in r.getMessage() and "km" in r.getMessage() for r in warnings_log.records)


def test_plausible_set_up_is_silent(warnings_log):
    se.simulate(_floor(), _line(), se.Sonar(max_range_m=20))
    assert warnings_log.records == []


def _y_up_floor():
    """A 40 m x 30 m floor exported with y up: it lies in the x-z plane, its normal along +y."""
    m = trimesh.Trimesh([[-20, 0, -15], [20, 0, -15], [20, 0, 15], [-20, 0, 15]], [[0, 2, 1], [0, 3, 2]])
    assert m.face_normals[0, 1] > 0.99
    return m


def test_y_up_obj_warns_and_loads_with_up_axis(tmp_path, warnings_log):
    path = tmp_path / "floor.obj"
    write_obj(path, [("seafloor", _y_up_floor())])
    on_side = se.Scene.load(path)
    assert np.ptp(on_side.bounds[:, 2]) == pytest.approx(30.0)  # read as is: a wall
    se.simulate(on_side, _line(z=2.0, y=-3.0), se.Sonar(max_range_m=20))
    assert any('up_axis = "y"' in r.getMessage() for r in warnings_log.records)
    scene = se.Scene.load(path, up_axis="y")
    np.testing.assert_allclose(scene.bounds, [[-20, -15, 0], [20, 15, 0]], atol=1e-9)
    assert scene.compiled().face_normals[:, 2].min() > 0.99  # (x, y, z) -> (x, -z, y) keeps the winding
    warnings_log.clear()
    rec = se.simulate(scene, _line(z=5.0), se.Sonar(max_range_m=12))
    assert rec.starboard.max() > 0 and not warnings_log.records


def test_glb_is_read_y_up_as_its_specification_says(tmp_path):
    path = tmp_path / "floor.glb"
    _y_up_floor().export(path)
    scene = se.Scene.load(path)
    np.testing.assert_allclose(scene.bounds, [[-20, -15, 0], [20, 15, 0]], atol=1e-6)
    assert np.ptp(se.Scene.load(path, up_axis="z").bounds[:, 2]) == pytest.approx(30.0)


def test_up_axis_in_toml_and_bad_values(tmp_path):
    write_obj(tmp_path / "floor.obj", [("seafloor", _y_up_floor())])
    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER.replace('seafloor = "flat"\nsize_m = [40.0, 40.0]', 'path = "floor.obj"\nup_axis = "y"'))
    assert np.ptp(se.runconfig.load_run_config(cfg).scene.bounds[:, 2]) < 1e-9
    cfg.write_text(RENDER.replace('seafloor = "flat"\nsize_m = [40.0, 40.0]', 'path = "floor.obj"\nup_axis = "x"'))
    with pytest.raises(se.SceneError, match="up_axis must be one of"):
        se.runconfig.load_run_config(cfg)


# --- 13: inverted normals warn, and two-sided materials echo -----------------------------------------------
def test_an_inverted_two_triangle_floor_warns(warnings_log):
    """Issue 33, finding 3: the smallest inverted floor (two triangles) renders black, so it must warn as a
    large one does; the same floor the right way up does not."""
    floor = se.seafloor.flat((200.0, 200.0))
    flipped = trimesh.Trimesh(floor.vertices, floor.faces[:, ::-1], process=False)
    traj, sonar = _line(n=10), se.Sonar(max_range_m=40)
    se.simulate(se.Scene().add(floor, label="seafloor"), traj, sonar)
    assert warnings_log.records == []
    rec = se.simulate(se.Scene().add(flipped, label="seafloor"), traj, sonar)
    assert rec.data.max() == 0.0
    assert any("object 'seafloor' is seen from behind its faces" in r.getMessage() for r in warnings_log.records)


def test_inverted_box_warns_and_two_sided_echoes(warnings_log):
    box = trimesh.creation.box((2.0, 2.0, 1.0))
    box.apply_translation((0.0, -12.0, 0.5))
    inverted = box.copy()
    inverted.invert()
    traj, sonar = _line(n=3), se.Sonar(max_range_m=20)
    normal = se.simulate(se.Scene().add(box, label="box", material=se.Material(-10.0)), traj, sonar)
    assert warnings_log.records == []
    bad = se.simulate(se.Scene().add(inverted, label="box", material=se.Material(-10.0)), traj, sonar)
    assert any("object 'box' is seen from behind its faces" in r.getMessage() and "two_sided" in r.getMessage()
               for r in warnings_log.records)
    two = se.simulate(se.Scene().add(inverted, label="box", material=se.Material(-10.0, two_sided=True)), traj,
                      sonar)
    assert normal.starboard.max() > 0
    assert bad.starboard.max() < 1e-3 * normal.starboard.max()  # no echo from behind (only the far faces' rims)
    np.testing.assert_allclose(two.starboard, normal.starboard, rtol=1e-9, atol=0)  # two-sided: the same echo


# --- 13: no NaN or inf in a record; one-line errors instead of tracebacks ---------------------------------
def test_tvg_that_would_overflow_is_refused_and_display_tvg_never_overflows(tmp_path):
    sonar = se.Acquisition(se.Sonar( max_range_m=20.0), se.Environment(absorption_db_per_m=100.0))
    with pytest.raises(se.ConfigError, match="SignalChain.tvg: the gain"):
        se.simulate(_floor(), _line(), sonar, tvg=True)
    rec = se.simulate(_floor(), _line(), sonar)  # legal without TVG (all echoes underflow to ~0)
    assert np.isfinite(rec.starboard).all()
    img = rec.waterfall()  # the display TVG works in decades: no inf * 0
    assert img.dtype == np.uint8
    strong = se.simulate(_floor(), _line(),
                         se.Acquisition(se.Sonar( max_range_m=20.0), se.Environment(absorption_db_per_m=2.0)))
    assert np.isfinite(strong.starboard).all() and strong.waterfall().max() > 100  # the floor is seen


@pytest.mark.parametrize("table, message", [
    ('seafloor = "flat"\nsize_m = [40.0, 40.0]\ncenter_m = [1.0]', "center_m must be (x, y)"),
    ('seafloor = "perlin"\nsize_m = [40.0, 40.0]\noctaves = 100', "octaves must be an integer in 1..24"),
    ('seafloor = "perlin"\nsize_m = [40.0, 40.0]\noctaves = 2.5', "octaves must be an integer"),
])
def test_floor_arguments_are_one_line_errors(tmp_path, capsys, table, message):
    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER.replace('seafloor = "flat"\nsize_m = [40.0, 40.0]', table))
    assert cli.main(["render", str(cfg), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err


def test_many_perlin_octaves_cost_nothing_beyond_the_grid():
    few = se.seafloor.perlin((40, 40), resolution_m=1.0, octaves=6)
    many = se.seafloor.perlin((40, 40), resolution_m=1.0, octaves=24)
    np.testing.assert_array_equal(few.vertices, many.vertices)  # 2 cells -> 40 points: 5 octaves are useful


def test_quality_above_its_limit_names_quality(capsys, tmp_path):
    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER)
    assert cli.main(["render", str(cfg), "-o", str(tmp_path / "out"), "--quality", "40", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "FanSettings.quality must be <= 32" in err and "azimuth" not in err
    se.FanSettings(quality=32).resolved()  # the largest accepted resolves


def test_a_string_for_a_placed_height_is_one_line(multi_sweep, tmp_path, capsys):
    bad = multi_sweep.parent / "height.toml"
    bad.write_text(SWEEP + '  [[scenes.objects]]\n  path = "scene.obj"\n  label = "crate"\n'
                   '  poses = [[0.0, 5.0, 0.0]]\n  z_m = "1"\n')
    assert cli.main(["batch", str(bad), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "z_m must be a number" in err and str(bad) in err and len(err.splitlines()) == 1


# --- 3: one robust display default ------------------------------------------------------------------------
@pytest.mark.parametrize("speckle", [False, True])
def test_display_defaults_show_the_floor_grey_and_highlights_white(tmp_path, speckle):
    import imageio.v3 as iio

    traj = se.Trajectory.line((-4.0, 0.0, 10.0), (4.0, 0.0, 10.0), n_pings=40)
    sonar = se.Sonar(max_range_m=40)
    floor = se.simulate(_floor(120.0), traj, sonar, speckle=speckle, seed=1)
    floor.save_png(tmp_path / "floor.png")
    img = iio.imread(tmp_path / "floor.png")
    assert (img >= 250).mean() < 0.01  # not clipped white (27 % before)
    seen = img[img > 0]
    assert 60 < np.median(seen) < 220  # a grey floor
    crate = box((1.5, 1.5, 1.0), (0.0, -20.0, 0.5))
    rec = se.simulate(_floor(120.0).add(crate, label="crate", material=se.Material(-10.0)), traj, sonar,
                      speckle=speckle, seed=1, labels=True)
    img = rec.waterfall()
    lab = rec.labels
    hi = lab.mask(lab.echo_mask(1), 1024)
    assert np.median(img[hi]) > np.median(img[~hi & (img > 0)]) + 40  # the highlight stands out
    assert img[hi].max() >= 250
    # a record with TVG applied already is not compensated twice
    tvg = se.simulate(_floor(120.0), traj, sonar, speckle=speckle, seed=1, tvg=True)
    np.testing.assert_array_equal(tvg.waterfall(), floor.waterfall())


# --- 13: the FM expected-intensity kernel by FFT --------------------------------------------------------
@pytest.mark.parametrize("pulse", [se.Pulse.lfm(20e3, 1e-3), se.Pulse.lfm(20e3, 3e-3, taper=0.0),
                                   se.Pulse.exp_chirp(390e3, 410e3, 2e-3)])
def test_fft_expected_kernel_equals_the_direct_correlation_sum(pulse):
    """Cell averages of |q(t)|², q(t) = Σ_m p̃(t + m/fs) p̃*(m/fs) / Σ|p̃|², summed directly here."""
    import math

    from sonar_embree.signal import pulses

    f0, fs, ov = 400e3, 40e3, 16
    kernel, lead = pulses.expected_kernel(pulse, f0, fs, True, oversample=ov)
    rep = pulses.complex_envelope(pulse, f0, np.arange(int(math.ceil(pulse.duration_s * fs))) / fs)
    rep = rep[: np.nonzero(rep)[0][-1] + 1]
    n_k = 2 * lead + 1
    t = ((np.arange(n_k * ov) + 0.5) / ov - 0.5 - lead) / fs
    q = sum(pulses.complex_envelope(pulse, f0, t + m / fs) * np.conj(r) for m, r in enumerate(rep))
    want = (np.abs(q / np.sum(np.abs(rep) ** 2)) ** 2).reshape(n_k, ov).mean(axis=1)
    assert lead == int(math.ceil(pulse.duration_s * fs)) + 1
    np.testing.assert_allclose(kernel, want, rtol=0, atol=1e-12 * want.max())
    assert 0.85 < want.max() <= 1.0  # unit gain at the peak, less the averaging over a sample cell


# --- 6: the README works from any folder; examples ship with the package --------------------------------
def _readme_api_snippet():
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    section = text.split("## The API in ten lines", 1)[1]
    return section.split("```python", 1)[1].split("```", 1)[0]


def test_readme_api_snippet_runs_from_a_temporary_folder(tmp_path):
    code = _readme_api_snippet()
    assert "se.assets.path(" in code and "assets/" not in code
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["run.npz", "run.png"]
    rec = se.Record.load(tmp_path / "run.npz")
    assert rec.n_pings == 100 and rec.starboard.max() > 0


def test_examples_list_and_copy_and_render_anywhere(tmp_path, capsys):
    assert cli.main(["examples"]) == 0
    listed = capsys.readouterr().out
    for name in ("anchor_mine.obj", "moored_mine.obj", "wreck.obj", "anchor_mine.toml", "detection.toml",
                 "reconstruction.toml"):
        assert name in listed
        assert os.path.isfile(se.assets.path(name))
    assert cli.main(["examples", "--copy", "anchor_mine.toml", str(tmp_path)]) == 0
    copy = tmp_path / "anchor_mine.toml"
    cfg = se.runconfig.load_run_config(copy)  # its meshes are asset:NAME: found from the copy too
    assert "mine" in cfg.scene.labels
    with pytest.raises(se.ConfigError, match="no shipped asset 'nope.obj'"):
        se.assets.path("nope.obj")


def test_anchor_mine_config_is_a_useful_image(tmp_path):
    """The config the README says to copy: 240 pings past the mine, which shows with its shadow."""
    cfg = se.runconfig.load_run_config("asset:anchor_mine.toml")
    assert len(cfg.trajectory) >= 200
    step = np.linalg.norm(np.diff(cfg.trajectory.positions_m, axis=0), axis=1).max()
    assert step < 0.01 * 26.0  # pings closer than the ~1° beam's footprint at the mine's range


def test_example_sweeps_check_and_cover_their_purpose():
    from sonar_embree.record.coco import category_of

    det = se.sweep.load_sweep("asset:detection.toml")
    assert det.categories == ("mine",) and {"coco", "labels"} <= set(det.outputs) and len(det.jobs) >= 4
    batch.preflight(det)  # one ping of the scene rendered and every output written
    scene = det.scenes[0].build(det.jobs[0].seed)
    mines = [o for o in scene.objects if category_of(o.label) == "mine"]
    assert len(mines) == 3
    rec = se.sweep.load_sweep("asset:reconstruction.toml")
    assert "labels" in rec.outputs and len(rec.trajectory_names) >= 3
    ys = sorted({float(j.trajectory.positions_m[0, 1]) for j in rec.jobs})
    sonar = rec.jobs[0].sonar
    h = rec.jobs[0].trajectory.positions_m[0, 2]
    swath = np.sqrt(sonar.max_range_m ** 2 - h ** 2)  # ground range reached on each side of a line
    assert all(0 < b - a < 2 * swath - 10.0 for a, b in zip(ys, ys[1:]))  # neighbours overlap by > 10 m
    batch.preflight(rec)


# --- 11: detection boxes follow the echo the waterfall shows --------------------------------------------
def test_echo_box_spans_the_pings_the_two_way_beam_gives():
    """A 0.3 m post 15 m to starboard, pings 2 cm apart: its echo spans the pings where the two-way azimuth
    pattern, integrated over the post's lit half (Lambert: σ dA ∝ cos²φ · a dφ at the point a·sin φ along
    track), is within 10 dB of its peak (quadrature here), far more than the centre line's geometric box."""
    from scipy import integrate

    a, h, y = 0.15, 10.0, -15.0
    post = trimesh.creation.cylinder(radius=a, height=1.0, sections=48)
    post.apply_translation((0.0, y, 0.5))
    spacing = 0.02
    traj = se.Trajectory.line((-1.0, 0.0, h), (1.0, 0.0, h), n_pings=101)
    sonar = se.Sonar(max_range_m=22.0)
    rec = se.simulate(_floor().add(post, label="post", material=se.Material(-10.0)), traj, sonar, labels=True)
    lab = rec.labels
    (echo,) = lab.boxes(None)
    (centre,) = lab.boxes(None, source="centre")
    rows_echo, rows_centre = echo["bbox"][3], centre["bbox"][3]

    # independent reference: I(x) = ∫ Γ⁴((x + a sin φ)/R) cos²φ dφ over the lit half, Γ the azimuth sinc
    k = 2 * np.pi * sonar.frequency_hz / se.Acquisition.of(sonar).sound_speed_m_s
    R = np.hypot(abs(y) - a, h - 1.0)
    g4 = lambda u: np.sinc(k * sonar.length_m / 2 * u / R / np.pi) ** 4  # noqa: E731

    def intensity(x):
        return integrate.quad(lambda p: g4(x + a * np.sin(p)) * np.cos(p) ** 2, -np.pi / 2, np.pi / 2)[0]

    x = traj.positions_m[:, 0]
    expected = int((np.array([intensity(v) for v in x]) >= 0.1 * intensity(0.0)).sum())
    assert abs(rows_echo - expected) <= 2, (rows_echo, expected)  # 23 against 25 at quality 1, 25 at 2
    assert rows_echo > 1.5 * rows_centre, (rows_echo, rows_centre)
    assert expected * spacing > 2 * a + 0.15  # the beam, not the post, sets the span


# --- 13: resume refuses a folder rendered from other inputs ---------------------------------------------
def test_resume_refuses_changed_mesh_contents_and_attitude(tmp_path, capsys):
    _multi_object_obj(tmp_path / "scene.obj")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP)
    out = tmp_path / "out"
    assert cli.main(["batch", str(sweep), "-o", str(out), "--workers", "1", "--no-progress"]) == 0
    assert cli.main(["batch", str(sweep), "-o", str(out), "--resume", "--no-progress"]) == 0  # unchanged: fine
    capsys.readouterr()
    original = (tmp_path / "scene.obj").read_bytes()
    (tmp_path / "scene.obj").write_bytes(original.replace(b"o rock", b"o rock\n# edited"))
    assert cli.main(["batch", str(sweep), "-o", str(out), "--resume", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "different sweep" in err and "input_files" in err, err
    (tmp_path / "scene.obj").write_bytes(original)
    sweep.write_text(SWEEP.replace("n_pings = 6", "n_pings = 6\nroll_deg = 2.0"))
    assert cli.main(["batch", str(sweep), "-o", str(out), "--resume", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "different sweep" in err and "trajectories" in err, err


def test_a_second_batch_of_the_same_folder_is_refused_while_the_first_runs(tmp_path, capsys):
    """Issue 33, finding 12: two runs of one folder: the second is refused in one line (the first holds its
    lock) and touches nothing; with the first done, the lock is gone and a resume runs."""
    from sonar_embree.io.files import LOCK_NAME, folder_lock

    _multi_object_obj(tmp_path / "scene.obj")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP)
    out = tmp_path / "out"
    assert cli.main(["batch", str(sweep), "-o", str(out), "--workers", "1", "--no-progress"]) == 0
    (out / ".tmp-being-written").mkdir()                 # what the first run is writing now
    with folder_lock(out):
        assert cli.main(["batch", str(sweep), "-o", str(out), "--resume", "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert "another run is writing this folder now" in err and err.count("\n") == 1, err
        assert (out / ".tmp-being-written").is_dir()
    assert not (out / LOCK_NAME).exists()
    assert cli.main(["batch", str(sweep), "-o", str(out), "--resume", "--no-progress"]) == 0


# --- 13: far, unrelated geometry costs the survey no precision -------------------------------------------
@pytest.mark.parametrize("far_m", [1e4, 1e6, 1e8])
def test_a_stray_box_far_away_leaves_the_record_unchanged(far_m):
    """Before, the local origin followed the scene's bounds: a 1 m box at 10⁸ m moved it 5·10⁷ m away and
    the record changed by 71 %; now the frame sits where the rays are."""
    traj = se.Trajectory.line((-1.0, 0.0, 10.0), (1.0, 0.0, 10.0), n_pings=4)

    def scene(stray):
        s = _floor().add(box((2, 2, 1), (1, -12, 0.5)), label="crate", material=se.Material(-10.0))
        return s.add(box((1, 1, 1), (far_m, 0, 0)), label="stray") if stray else s

    ref = se.simulate(scene(False), traj, se.Sonar(max_range_m=25), speckle=True, seed=1, labels=True)
    rec = se.simulate(scene(True), traj, se.Sonar(max_range_m=25), speckle=True, seed=1, labels=True)
    np.testing.assert_array_equal(rec.starboard, ref.starboard)
    np.testing.assert_array_equal(rec.port, ref.port)
    np.testing.assert_array_equal(rec.labels.kind, ref.labels.kind)


def test_a_million_row_trajectory_csv_is_refused_in_one_line(tmp_path, capsys):
    n = 1_000_000
    t = np.arange(n) * 0.1
    rows = np.column_stack([t, 0.2 * t, np.zeros(n), np.full(n, 10.0)])
    path = tmp_path / "nav.csv"
    with open(path, "w") as fh:
        fh.write("time_s,x_m,y_m,z_m\n")
        np.savetxt(fh, rows, fmt="%.3f", delimiter=",")
    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER.replace('start = [-1.0, 0.0, 6.0]\nend = [1.0, 0.0, 6.0]\nn_pings = 4',
                                  'kind = "csv"\npath = "nav.csv"'))
    assert cli.main(["render", str(cfg), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "1000000 pings" in err and "GiB" in err, err
    assert not (tmp_path / "out").exists()


def test_render_start_time_is_recorded(tmp_path, capsys):
    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER)
    out = tmp_path / "out"
    assert cli.main(["render", str(cfg), "-o", str(out), "--no-progress", "--start-time", "2026-05-01T09:30:00Z"]) == 0
    assert se.Record.load(out / "record.npz").attrs["start_time"] == "2026-05-01T09:30:00+00:00"
    assert cli.main(["render", str(cfg), "-o", str(tmp_path / "o2"), "--no-progress", "--start-time", "May 1st"]) == 2
    assert "not an ISO 8601 date-time" in capsys.readouterr().err


@pytest.mark.parametrize("old, new, what", [
    ('[sonar]\n', '[sonar]\ntype = ["msis"]\n', "unknown sonar type ['msis']"),
    ('[trajectory]\n', '[trajectory]\nkind = ["line"]\n', "kind must be one of"),
    ('seafloor = "flat"', 'seafloor = ["flat"]', "seafloor must be one of"),
    ('[sonar]\n', '[environment]\nabsorption_model = ["x"]\n[sonar]\n', "absorption_model"),
    ('[sonar]\n', '[sonar]\nsource_level_db = 210.0\nreceiver = { gain = { kind = "tvg", absorption = "false" } }\n',
     "TVG.absorption must be True or False")])
def test_toml_values_of_the_wrong_type_give_one_line(tmp_path, capsys, old, new, what):
    """Issue 33, findings 7 and 12: a list where a name is expected was a TypeError traceback (unhashable), and
    "false" as a string was taken as true; each is one line naming the key, exit status 2."""
    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER.replace(old, new, 1))
    assert cli.main(["render", str(cfg), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert what in err and err.count("\n") == 1 and "Traceback" not in err, err


def test_a_lost_ctrl_c_still_leaves_nothing(tmp_path, monkeypatch):
    """A KeyboardInterrupt raised inside a finaliser (as Numba's compiler runs some) is printed and lost, and the
    command would go on to write its outputs. The Ctrl-C handler remembers the interrupt: no output set is written
    once it is set, and the command ends with the interrupt's one line and status 130."""
    import signal

    from sonar_embree.io import owner

    cfg = tmp_path / "run.toml"
    cfg.write_text(RENDER)
    calls = []

    def lost(*args, **kwargs):                 # the handler ran, its KeyboardInterrupt was swallowed
        handler = signal.getsignal(signal.SIGINT)
        try:
            handler(signal.SIGINT, None)
        except KeyboardInterrupt:
            calls.append("swallowed")
        return real(*args, **kwargs)

    from sonar_embree.runs import commands
    real = commands.simulate
    monkeypatch.setattr("sonar_embree.runs.commands.simulate", lost)
    # as at a terminal: a test run started in the background by a shell inherits SIGINT ignored, and the command
    # then (rightly) leaves Ctrl-C alone
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    out = tmp_path / "out"
    try:
        status = cli.main(["render", str(cfg), "-o", str(out), "--no-progress"])
    finally:
        signal.signal(signal.SIGINT, previous)
    assert status == 130
    assert calls == ["swallowed"] and (not out.exists() or not [n for n in os.listdir(out) if n != MANIFEST])
    assert not owner.INTERRUPTED.is_set()                       # cleared for the next command in this process
    monkeypatch.setattr(commands, "simulate", real)
    assert cli.main(["render", str(cfg), "-o", str(tmp_path / "next"), "--no-progress"]) == 0
