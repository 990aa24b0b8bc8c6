"""The figure scripts run from a fresh install and write their PNGs (at reduced size)."""
import json
import os
import subprocess
import sys

import imageio.v3 as iio
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_paper_modes_script_writes_every_mode(tmp_path):
    out = tmp_path / "modes"
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "paper_modes.py"), "-o", str(out),
                           "--pings", "3", "--max-range", "30"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    names = ["speckle_free", "lfm_baseband", "lfm_carrier", "cw_incoherent", "cw_coherent",
             "cw_incoherent_histogram", "modes"]
    assert sorted(os.listdir(out)) == sorted(f"{n}.png" for n in names)
    free = iio.imread(out / "speckle_free.png")
    speckled = iio.imread(out / "cw_coherent.png")
    assert free.shape == speckled.shape and free.shape[0] == 3
    # speckle makes neighbouring pixels differ far more than the smooth expected intensity
    assert np.std(np.diff(speckled.astype(float), axis=1)) > 3 * np.std(np.diff(free.astype(float), axis=1))


def test_bench_script_writes_report_and_plot(tmp_path):
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "bench_speed_vs_error.py"), "--quick",
                           "-o", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert sorted(os.listdir(tmp_path)) == ["benchmarks.md", "speed_vs_error.png"]
    md = (tmp_path / "benchmarks.md").read_text()
    for needle in ("Flat floor", "Shipwreck", "per 100 000 rays", "pings/s", "| footprint | 1 |"):
        assert needle in md
    assert iio.imread(tmp_path / "speed_vs_error.png").shape[0] > 100


def test_detection_dataset_script_writes_a_coco_dataset(tmp_path):
    out = tmp_path / "det"
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "make_detection_dataset.py"), "--quick",
                           "--workers", "1", "-o", str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    coco = json.loads((out / "dataset" / "coco.json").read_text())
    assert [c["name"] for c in coco["categories"]] == ["box", "cylinder_mine", "sphere_mine"]
    assert len(coco["images"]) == 2
    for im in coco["images"]:
        assert (out / "dataset" / im["file_name"]).exists()
        assert (out / "dataset" / im["file_name"]).with_name("labels.png").exists()
    names = {a["object_label"].split("#")[0] for a in coco["annotations"]}
    assert names == {"box", "cylinder_mine", "sphere_mine"}
    assert sorted(os.listdir(out / "meshes")) == ["box.obj", "cylinder_mine.obj", "sphere_mine.obj"]


def test_physics_plots_script_writes_beam_pattern_and_ping(tmp_path):
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "physics_plots.py"), "-o", str(tmp_path),
                           "--pings", "8"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["beam_pattern.png", "ping.png"]
    for name in ("beam_pattern.png", "ping.png"):
        img = iio.imread(tmp_path / name)
        assert img.ndim == 3 and img.shape[1] > 800 and img.std() > 10  # a drawn figure, not a blank page
