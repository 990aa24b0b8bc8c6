"""Sweeps on real Dask clusters: same bits for any worker count, resumable after a kill, checked input."""
import filecmp
import json
import os
import signal
import subprocess
import sys
import time

import imageio.v3 as iio
import numpy as np
import pytest
import trimesh

import sonar_embree as se
from sonar_embree.io.owner import MANIFEST
from sonar_embree.runs import cli
from sonar_embree.signal.labels import OBJECT
from sonar_embree.runs.sweep import load_sweep

SWEEP = """\
[sweep]
name = "crates"
seeds = 3
outputs = ["zarr", "xtf", "png", "labels", "coco", "npz"]
pings_per_task = 4
complex = true

[sonar]
max_range_m = 16.0

[simulation]
speckle = true
noise_db_per_hz = -200.0

[vary]
"fan.quality" = [0.5, 0.75]

[[scenes]]
name = "ripples"
  [[scenes.objects]]
  seafloor = "ripples"
  size_m = [40.0, 40.0]
  resolution_m = 0.4
  wavelength_m = 1.6
  [[scenes.objects]]
  path = "crate.obj"
  label = "crate"
  count = 2
  region = [[-3.0, 3.0], [5.0, 10.0]]
  material = {backscatter_db = [-20.0, -10.0]}
  [[scenes.objects]]
  path = "crate.obj"
  label = "drum"
  poses = [[1.0, -7.0, 30.0]]

[[trajectories]]
name = "pass"
kind = "line"
start = [-4.0, 0.0, 7.0]
end = [4.0, 0.0, 7.0]
n_pings = 10
"""


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    trimesh.creation.box((1.5, 1.0, 0.8)).export(d / "crate.obj")
    (d / "sweep.toml").write_text(SWEEP)
    return d / "sweep.toml"


@pytest.fixture(scope="module")
def reference(sweep_file, tmp_path_factory):
    """The sweep on one local worker, through the command line."""
    out = tmp_path_factory.mktemp("ref") / "out"
    assert cli.main(["batch", str(sweep_file), "-o", str(out), "--workers", "1", "--no-progress"]) == 0
    return out


def _same_tree(a, b):
    cmp = filecmp.dircmp(a, b)
    assert not cmp.left_only and not cmp.right_only, (cmp.left_only, cmp.right_only)
    _, mismatch, errors = filecmp.cmpfiles(a, b, cmp.common_files, shallow=False)
    assert not mismatch and not errors, (a, mismatch, errors)
    for sub in cmp.common_dirs:
        _same_tree(os.path.join(a, sub), os.path.join(b, sub))


def test_jobs_are_the_product_of_scenes_trajectories_vary_and_seeds(sweep_file, reference):
    sweep = load_sweep(sweep_file)
    assert len(sweep.jobs) == 6 and sweep.categories == ("crate", "drum")
    assert [(j.seed, j.fan.quality) for j in sweep.jobs] == [(0, 0.5), (1, 0.5), (2, 0.5), (0, 0.75), (1, 0.75),
                                                            (2, 0.75)]
    assert sorted(p for p in os.listdir(reference) if p != MANIFEST) == [
        "00000", "00001", "00002", "00003", "00004", "00005", "coco.json", "sweep.json"]
    assert sorted(os.listdir(reference / "00000")) == ["coco.json", "job.json", "labels.png", "labels_preview.png",
                                                       "record.npz", "record.xtf", "record.zarr", "waterfall.png"]
    job = json.loads((reference / "00004" / "job.json").read_text())
    assert job == {"id": "00004", "scene": "ripples", "trajectory": "pass", "seed": 1,
                   "vary": {"fan.quality": 0.75}, "n_pings": 10}


def test_batch_output_equals_a_direct_simulation(sweep_file, reference):
    sweep = load_sweep(sweep_file)
    job = sweep.jobs[4]
    scene = sweep.scenes[0].build(job.seed)
    direct = se.simulate(scene, job.trajectory, job.sonar, job.pulse, fan=job.fan, chain=job.chain, labels=True,
                         keep_complex=True)
    rec = se.Record.load(reference / "00004" / "record.npz")
    np.testing.assert_array_equal(rec.port, direct.port)
    np.testing.assert_array_equal(rec.starboard, direct.starboard)
    np.testing.assert_array_equal(rec.labels.kind, direct.labels.kind)
    np.testing.assert_array_equal(rec.port_complex, direct.port_complex)
    assert rec.attrs["seed"] == 1 and rec.attrs["job"] == "00004"
    # random placements follow the seed: other seeds put the crates elsewhere
    a, b = (sweep.scenes[0].build(s) for s in (0, 1))
    assert not np.array_equal(a.objects[1].vertices, b.objects[1].vertices)
    np.testing.assert_array_equal(a.objects[3].vertices, b.objects[3].vertices)  # listed pose: fixed
    # instances rest on the floor
    assert abs(a.objects[3].vertices[:, 2].min()) < 0.2


def test_two_workers_on_a_scheduler_give_identical_files(sweep_file, reference, tmp_path):
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        assert cli.main(["batch", str(sweep_file), "-o", str(tmp_path / "out"), "--scheduler",
                         cluster.scheduler_address, "--no-progress"]) == 0
    _same_tree(reference, tmp_path / "out")


def test_a_real_scheduler_and_two_worker_processes_give_identical_files(sweep_file, reference, tmp_path):
    """Not a LocalCluster: ``dask scheduler`` and two ``dask worker`` processes started on loopback as a cluster's
    nodes would be (one thread each, a memory limit, their own scratch folders), the batch and a streamed line sent
    by address; the batch's files equal the one-worker run's and the line's XTF and data the in-process line's, bit
    for bit; the workers' resident memory is reported."""
    from distributed import Client

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    sched_file = tmp_path / "scheduler.json"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [subprocess.Popen(dask + ["--host", "127.0.0.1", "--port", "0", "--dashboard-address", ":0",
                                      "--scheduler-file", str(sched_file)], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        for _ in range(600):
            if sched_file.exists() and sched_file.stat().st_size > 0:
                break
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        for k in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--nworkers", "1",
                 "--memory-limit", "2GiB", "--local-directory", str(tmp_path / f"w{k}"), "--name", f"w{k}"],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=120)
            assert cli.main(["batch", str(sweep_file), "-o", str(tmp_path / "out"), "--scheduler", address,
                             "--no-progress"]) == 0
            rss = client.run(lambda: __import__("psutil").Process().memory_info().rss)
            line = se.Trajectory.line((-6.0, 0.0, 7.0), (6.0, 0.0, 7.0), 24)
            floor = se.seafloor.ripples((40.0, 40.0), resolution_m=0.4, wavelength_m=1.6)
            scene = se.Scene().add(floor, label="seafloor")
            kw = dict(block_pings=6, speckle=True, seed=2, start_time="2000-01-01")
            for name, how in (("here", {"workers": 1}), ("there", {"scheduler": address})):
                se.stream.render_line(scene, line, tmp_path / name / "l.zarr", se.Sonar(max_range_m=16.0),
                                      xtf_path=tmp_path / name / "l.xtf", xtf_scale=1.0, **how, **kw)
        _same_tree(reference, tmp_path / "out")
        assert (tmp_path / "here" / "l.xtf").read_bytes() == (tmp_path / "there" / "l.xtf").read_bytes()
        np.testing.assert_array_equal(se.Record.load(tmp_path / "here" / "l.zarr").data,
                                      se.Record.load(tmp_path / "there" / "l.zarr").data)
        assert len(rss) == 2
        print("worker RSS (MiB):", sorted(round(v / 2 ** 20) for v in rss.values()))
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs:
            p.wait(timeout=60)


def test_killed_batch_resumes_to_the_same_files(sweep_file, reference, tmp_path):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "sonar_embree.runs.cli", "batch", str(sweep_file), "-o", str(out), "--workers", "1",
           "--no-progress"]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not (out / "00000").exists():
            assert proc.poll() is None and time.monotonic() < deadline, "batch ended before its first job"
            time.sleep(0.005)
        os.killpg(proc.pid, signal.SIGKILL)  # the driver, its cluster and workers: mid-way through the jobs
    finally:
        proc.wait()
    done = sorted(n for n in os.listdir(out) if n.isdigit())
    assert 1 <= len(done) < 6, done
    assert cli.main(["batch", str(sweep_file), "-o", str(out), "--no-progress"]) == 2  # not without --resume
    assert cli.main(["batch", str(sweep_file), "-o", str(out), "--resume", "--workers", "1", "--no-progress"]) == 0
    _same_tree(reference, out)
    assert [n for n in os.listdir(out) if n.startswith(".")] == [MANIFEST]     # no temporary left
    # a second resume has nothing left to do
    assert se.batch.run(sweep_file, out, resume=True) == []


def test_coco_dataset_loads_and_masks_match_the_labels(reference):
    """pycocotools reads the merged dataset; every annotation's mask is a connected piece of its object's echo."""
    from pycocotools.coco import COCO
    from scipy import ndimage

    coco = COCO(str(reference / "coco.json"))
    coco.info()  # needs the info block
    assert [c["name"] for c in coco.loadCats(coco.getCatIds())] == ["crate", "drum"]
    assert len(coco.getImgIds()) == 6 and coco.getAnnIds(), "no object is visible"
    per_object = {}
    for ann in coco.loadAnns(coco.getAnnIds()):
        im = coco.loadImgs(ann["image_id"])[0]
        m = coco.annToMask(ann).astype(bool)
        assert m.shape == (im["height"], im["width"]) and m.sum() == ann["area"] > 0
        x, y, w, h = ann["bbox"]
        assert m[y:y + h, x:x + w].sum() == m.sum()
        assert ndimage.label(m, structure=np.ones((3, 3)))[1] == 1  # one connected piece per annotation
        cat = coco.loadCats(ann["category_id"])[0]["name"]
        assert ann["object_label"].split("#")[0] == cat
        key = (im["file_name"], ann["object_label"])
        per_object[key] = per_object.get(key, np.zeros_like(m)) | m
    for (file_name, label), union in per_object.items():
        rec = se.Record.load(reference / file_name.replace("waterfall.png", "record.npz"))
        lab = rec.labels
        np.testing.assert_array_equal(union, lab.mask(lab.echo_mask(lab.names.index(label)), 1024))
        kinds = iio.imread(reference / file_name.replace("waterfall.png", "labels.png"))
        assert kinds.ndim == 2  # class indices, read back exactly
        np.testing.assert_array_equal(kinds, lab.waterfall("kind", 1024))


@pytest.mark.parametrize("edit, message", [
    (("[sonar]", "[sonar]\nbeam_width = 3"), "unknown key 'beam_width' in [sonar]"),
    (("[sweep]", "[sweep]\nworkers = 3"), "unknown key 'workers' in [sweep]"),
    (('path = "crate.obj"\n  label = "crate"', 'path = "missing.obj"\n  label = "crate"'), "missing.obj"),
    (("max_range_m = 16.0", "max_range_m = -16.0"), "max_range_m"),
    (('"fan.quality" = [0.5, 0.75]', '"fan.quality" = [0.5, -1.0]'), "quality"),
    (('"fan.quality"', '"fan.qualty"'), "fan.qualty"),
    (("count = 2", "count = -2"), "count"),
    (("backscatter_db = [-20.0, -10.0]", "backscatter_db = [-10.0, -20.0]"), "backscatter_db"),
    (("region = [[-3.0, 3.0], [5.0, 10.0]]", "region = [[300.0, 301.0], [5.0, 10.0]]"), "no seafloor below"),
    (("seeds = 3", "seeds = [1, 1]"), "seeds"),
    (("speckle = true", "speckle = false"), "complex"),
    (('outputs = ["zarr"', 'outputs = ["tiff", "zarr"'), "outputs"),
    (("[sweep]", "[png]\ndynamic_range_db = -40.0\n[sweep]"), "[png]: waterfall dynamic_range_db"),
])
def test_bad_sweeps_stop_before_any_work_naming_the_problem(sweep_file, tmp_path, capsys, edit, message):
    bad = tmp_path / "bad.toml"
    text = SWEEP.replace(*edit)
    assert text != SWEEP
    bad.write_text(text)
    os.symlink(sweep_file.parent / "crate.obj", tmp_path / "crate.obj")
    out = tmp_path / "out"
    assert cli.main(["batch", str(bad), "-o", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and str(bad) in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_resume_refuses_another_sweep(sweep_file, reference, tmp_path, capsys):
    other = tmp_path / "other.toml"
    other.write_text(SWEEP.replace("n_pings = 10", "n_pings = 12"))
    os.symlink(sweep_file.parent / "crate.obj", tmp_path / "crate.obj")
    assert cli.main(["batch", str(other), "-o", str(reference), "--resume", "--no-progress"]) == 2
    assert "different sweep" in capsys.readouterr().err
