"""The figure scripts run from a fresh install and write their PNGs (at reduced size)."""
import json
import os
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest

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
    # sections other benchmarks recorded after the generated ones survive a re-run; the stale ones do not
    (tmp_path / "benchmarks.md").write_text("# old\n\n## Flat floor\nstale row\n\n## What the quality setting "
                                            "does\nold text\n\n## Issue 99: before and after\nkept row\n")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "bench_speed_vs_error.py"), "--quick",
                           "-o", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert sorted(os.listdir(tmp_path)) == ["benchmarks.md", "speed_vs_error.png"]
    md = (tmp_path / "benchmarks.md").read_text()
    for needle in ("Flat floor", "Shipwreck", "per 100 000 rays", "pings/s", "| footprint | 1 |"):
        assert needle in md
    assert "stale row" not in md and "old text" not in md
    assert md.endswith("\n## Issue 99: before and after\nkept row\n") and md.count("## What the quality") == 1
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
    example = iio.imread(out / "example.png")
    waterfall = iio.imread(out / "dataset" / "00000" / "waterfall.png")
    labels = iio.imread(out / "dataset" / "00000" / "labels.png")
    assert labels.ndim == 2 and set(np.unique(labels)) <= {0, 1, 2, 3}  # class indices, one channel
    assert example.shape == (waterfall.shape[0] + 4 + labels.shape[0], waterfall.shape[1], 3)
    np.testing.assert_array_equal(example[:waterfall.shape[0], :, 0], waterfall)


def test_physics_plots_script_writes_beam_pattern_and_ping(tmp_path):
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "physics_plots.py"), "-o", str(tmp_path),
                           "--pings", "8"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["beam_pattern.png", "ping.png"]
    for name in ("beam_pattern.png", "ping.png"):
        img = iio.imread(tmp_path / name)
        assert img.ndim == 3 and img.shape[1] > 800 and img.std() > 10  # a drawn figure, not a blank page


def _ripple_period_m(rec, lo_m=25.0, hi_m=50.0, step_m=0.05):
    """Strongest period (m) of the starboard seafloor intensity along ground range, over all pings."""
    from sonar_embree.signal.labels import SEAFLOOR
    from sonar_embree.signal.processing import tvg_gain

    x = rec.starboard * tvg_gain(rec.time_s, rec.acquisition.sound_speed_m_s, rec.acquisition.alpha_db_per_m)
    grid = np.arange(lo_m, hi_m, step_m)
    spec = np.zeros(4 * grid.size // 2 + 1)
    for p in range(rec.n_pings):
        floor = rec.labels.kind[1, p] == SEAFLOOR
        g, y = rec.labels.ground_range_m[1, p, floor], x[p, floor]
        order = np.argsort(g)
        y = np.interp(grid, g[order], y[order])
        spec += np.abs(np.fft.rfft((y / y.mean() - 1) * np.hanning(grid.size), n=4 * grid.size)) ** 2
    f = np.fft.rfftfreq(4 * grid.size, step_m)
    band = (f > 0.2) & (f < 3.0)
    return 1.0 / f[band][np.argmax(spec[band])], spec[band].max() / np.median(spec[band])


def test_shipwreck_script_shows_highlight_shadow_texture_and_the_bend(tmp_path):
    import sonar_embree as se
    from sonar_embree import shipwreck
    from sonar_embree.signal.labels import OBJECT, SEAFLOOR, SHADOW
    from sonar_embree.signal.processing import tvg_gain

    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "paper_shipwreck.py"), "-o", str(tmp_path),
                           "--pings", "64", "--floor-size", "110", "--records"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    pngs = ["fig8_fm_baseband_straight", "fig9_cw_incoherent_curved", "fig9_straight_vs_curved", "fig9_tracks"]
    records = ["fig8_fm_baseband_straight", "fig9_cw_incoherent_curved", "fig9_cw_incoherent_straight"]
    assert sorted(os.listdir(tmp_path)) == sorted([f"{n}.png" for n in pngs] + [f"{n}.npz" for n in records])
    for name in pngs:
        assert iio.imread(tmp_path / f"{name}.png").std() > 10
    recs = {n: se.Record.load(tmp_path / f"{n}.npz") for n in records}
    for name, rec in recs.items():
        port = rec.port * tvg_gain(rec.time_s, rec.acquisition.sound_speed_m_s, rec.acquisition.alpha_db_per_m)
        kind = rec.labels.kind[0]  # the wreck lies to port
        floor = np.median(port[kind == SEAFLOOR])
        assert (kind == OBJECT).mean() > 0.02 and (kind == SHADOW).mean() > 0.05, name
        assert np.median(port[kind == OBJECT]) > 4.0 * floor, name    # highlight: +6 dB over the floor
        assert np.median(port[kind == SHADOW]) < 0.01 * floor, name   # shadow: −20 dB under it
    # seafloor texture: the ripples (0.8 m, crests at 30°) repeat every 0.8 m / sin 30° = 1.6 m across track
    period, contrast = _ripple_period_m(recs["fig8_fm_baseband_straight"])
    assert abs(period - 0.8 / np.sin(np.radians(30.0))) < 0.1 and contrast > 100
    # Fig. 9 runs along the curved pass, which moves the wreck's leading edge by metres in the waterfall
    curved, straight = recs["fig9_cw_incoherent_curved"], recs["fig9_cw_incoherent_straight"]
    kw = dict(shipwreck.PAPER_PASS, n_pings=64, ping_rate_hz=63 * 1.0 / 79.9)
    assert curved.trajectory == shipwreck.curved_pass(**kw) and straight.trajectory == shipwreck.straight_pass(**kw)
    on_c, on_s = curved.labels.kind[0] == OBJECT, straight.labels.kind[0] == OBJECT
    both = on_c.any(axis=1) & on_s.any(axis=1)
    r = curved.slant_range_m
    shift = (r[np.argmax(on_c, axis=1)] - r[np.argmax(on_s, axis=1)])[both]
    assert both.sum() > 20 and np.max(np.abs(shift)) > 3.0 and np.median(np.abs(shift)) > 1.0


def test_seafloor_gallery_orders_the_presets_and_draws_sigma(tmp_path):
    """Issue 14's figure, following the physics (issue 52): every floor drawn on one scale, the waterfalls' levels
    in the order of the floors' σ over the waterfalls' grazing angles (15°–45°) wherever the models set them 3 dB
    or more apart, and the pairs within 1 dB named as looking alike; σ(θ) on its curves; the migration figure."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "seafloor_gallery.py"), "-o", str(tmp_path),
                           "--pings", "4"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["gallery.json", "migration.png", "presets.png", "sigma.png"]
    for name in ("presets.png", "sigma.png", "migration.png"):
        img = iio.imread(tmp_path / name)
        assert img.ndim == 3 and img.shape[1] > 800 and img.std() > 10
    info = json.loads((tmp_path / "gallery.json").read_text())
    from sonar_embree.laws import sediments

    floors = ("mud", "sandy mud", "fine sand", "coarse sand", "gravel", "rock")
    sigma, level = info["floor_sigma_15_45_db"], info["floor_median_db"]
    g = np.linspace(15.0, 45.0, 31)                             # the models' σ, written here from their laws
    want = {n: 10 * np.log10(np.mean(10 ** (sediments.preset(n).backscatter_strength_db(g, 400e3) / 10)))
            for n in floors}
    for n in floors:
        assert sigma[n] == pytest.approx(want[n], abs=0.05), n
    checked = 0
    for i, a in enumerate(floors):
        for b in floors[i + 1:]:
            if abs(want[a] - want[b]) >= 3.0:
                assert (level[a] - level[b]) * (want[a] - want[b]) > 0, (a, b, level, want)
                checked += 1
    assert checked >= 8
    alike = {tuple(p) for p in info["look_alike"]}
    assert alike == {(a, b) for i, a in enumerate(floors) for b in floors[i + 1:] if abs(want[a] - want[b]) < 1.0}
    assert sorted(info["sigma_error_db"]) == sorted(["mud", "sandy mud", "fine sand", "coarse sand", "gravel",
                                                      "rock", "concrete", "steel"])
    assert max(info["sigma_error_db"].values()) < 0.3


def test_multipath_figure_shows_the_surface_paths(tmp_path):
    """Issue 15's figure: three waterfalls and a ping; the surface adds echoes never before the one-bounce onset."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "multipath_figure.py"), "-o", str(tmp_path),
                           "--pings", "4"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["multipath.json", "ping.png", "waterfalls.png"]
    for name in ("waterfalls.png", "ping.png"):
        img = iio.imread(tmp_path / name)
        assert img.ndim == 3 and img.shape[1] > 500 and img.std() > 10
    info = json.loads((tmp_path / "multipath.json").read_text())
    assert info["first_multipath_s"] >= info["one_bounce_onset_s"] - info["sample_s"]
    assert info["first_multipath_s"] < info["one_bounce_onset_s"] + 0.1 * info["one_bounce_onset_s"]


def test_refraction_figure_ends_the_floor_at_the_ray_maps_shadow_edge(tmp_path):
    """Issue 15's refraction figure: three waterfalls and a ping; in the upward-refracting profile the floor's echo
    ends a pulse after the limiting ray of the closed-form ray map (straight rays light it to the window's end)."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "refraction_figure.py"), "-o", str(tmp_path),
                           "--pings", "2"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["ping.png", "refraction.json", "waterfalls.png"]
    for name in ("waterfalls.png", "ping.png"):
        img = iio.imread(tmp_path / name)
        assert img.ndim == 3 and img.shape[1] > 500 and img.std() > 10
    info = json.loads((tmp_path / "refraction.json").read_text())
    assert info["limiting_ray_s"] <= info["last_lit_s"] <= info["limiting_ray_s"] + info["pulse_s"] + 3 * info["sample_s"]


def test_device_figure_shows_noise_where_the_unit_source_record_is_silent(tmp_path):
    """Issue 16's figure: the unit-source image and the device's 16-bit codes of the same line; the device's water
    column holds noise codes where the unit-source record is (numerically) zero."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "device_figure.py"), "-o", str(tmp_path),
                           "--length", "1"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["device.json", "waterfalls.png"]
    img = iio.imread(tmp_path / "waterfalls.png")
    assert img.ndim == 3 and img.shape[1] > 500 and img.std() > 10
    info = json.loads((tmp_path / "device.json").read_text())
    assert info["dtype"] == "uint16" and info["ping_rate_hz"] == pytest.approx(10.0)
    assert info["median_code_water_column"] >= 1 and info["median_unit_source_water_column"] < 1e-20
    assert 0 < info["clipped_share"] < 0.05


def test_survey_script_writes_georeferenced_lines_mosaic_and_truth(tmp_path):
    import pyxtf
    import rasterio
    import xarray as xr

    out = tmp_path / "survey"
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "survey_from_dem.py"), "--quick", "-o",
                           str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = json.loads((out / "survey.json").read_text())
    assert summary["crs"] == "EPSG:32632" and summary["lines"] >= 2
    for name in ("mosaic.tif", "truth.tif", "dem.tif"):
        with rasterio.open(out / name) as src:
            assert src.crs.to_epsg() == 32632
    header, packets = pyxtf.xtf_read(str(out / "lines" / "line_00.xtf"))
    assert header.NavUnits == 3 and 9.0 < packets[pyxtf.XTFHeaderType.sonar][0].SensorXcoordinate < 10.0
    ds = xr.open_zarr(out / "lines" / "line_00.zarr")
    assert "crs" in ds and ds.sizes["ping"] == len(packets[pyxtf.XTFHeaderType.sonar])
    assert abs(summary["placed_height_error_m"]["median"]) < 0.1 and summary["placed_height_error_m"]["p95_abs"] < 0.5
    assert iio.imread(out / "survey.png").shape[0] > 100


def test_msis_figure_script_draws_both_scans(tmp_path):
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "msis_figure.py"), "-o", str(tmp_path),
                           "--pings", "20"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    stats = json.loads((tmp_path / "scan.json").read_text())
    assert set(stats) == {"still", "moving at 0.2 m/s"} and all(v["rays_per_ping"] > 1000 for v in stats.values())
    assert iio.imread(tmp_path / "polar.png").shape[0] > 100


def test_bench_objects_script_reports_time_against_object_count_and_its_error():
    """scripts/bench_objects.py --quick: the table of ms/ping against the number of balls, aimed and fan only, and
    the reference ball's error both ways (dark pings only without the aimed rays); the cables' table and the
    reference cable's error (no dark ping)."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "bench_objects.py"), "--quick"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout
    assert "| objects | ms/ping, aimed |" in out and "\n| 10 |" in out
    aimed = next(line for line in out.splitlines() if line.startswith("| aimed + fan |"))
    assert aimed.split("|")[3].strip().startswith("0 of ")
    assert "| cables | ms/ping, aimed |" in out and "dark in 0 of the" in out    # the slender objects' section


def test_bench_swell_objects_script_reports_ms_per_ping_with_and_without_balls():
    """scripts/bench_swell_objects.py --quick: ms per ping under a swell with 0 and 10 balls, as JSON."""
    import json

    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "bench_swell_objects.py"), "--quick"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert set(out) == {"0", "10"} and all(v > 0 for v in out.values())


def test_bench_chirp_script_reports_the_chirp_beside_cw():
    """scripts/bench_chirp.py --quick: ms per ping of the preset chirp (compressed and not) and of the CW pulse of
    its resolution."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "bench_chirp.py"), "--quick"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = [line for line in proc.stdout.splitlines() if line.startswith("| ") and "ms/ping" not in line]
    assert len(rows) == 3 and all(float(r.split("|")[2]) > 0 for r in rows)


def test_bench_speckle_coherence_script_reports_the_correlation_against_its_closed_form():
    """scripts/bench_speckle_coherence.py --quick: one JSON line, the adjacent pings' correlation within 0.1 of the
    closed form (40 pings: a looser estimate than the test's) and positive times."""
    import json

    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "bench_speckle_coherence.py"), "--quick"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert len(rows) == 1 and abs(rows[0]["error"]) < 0.1 and rows[0]["synthesis_ms_per_ping"] > 0


def test_realism_figure_shows_heavier_tails_than_todays_line(tmp_path):
    """Issue 38's figure: today's line and the realistic one side by side; the realistic line's far band has the
    heavier tail (scintillation index) that clutter and the APL-UW fall-off give."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "realism_figure.py"), "-o", str(tmp_path),
                           "--length", "3"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["realism.json", "waterfalls.png"]
    img = iio.imread(tmp_path / "waterfalls.png")
    assert img.ndim == 3 and img.shape[1] > 500 and img.std() > 10
    info = json.loads((tmp_path / "realism.json").read_text())
    assert info["realistic"]["scintillation_index"][-1] > 2 * info["today"]["scintillation_index"][-1]


def test_sas_figure_resolves_the_mine_that_the_side_scan_blurs(tmp_path):
    """Issue 39's figure (--quick: the mine only): the side-scan panel beside the SAS panel with outlines; the SAS
    image concentrates the mine's echo: the share of its pixels within 10 dB of the brightest is under half the
    side-scan image's."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "sas_figure.py"), "-o", str(tmp_path),
                           "--quick"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["sas.json", "sas.png"]
    img = iio.imread(tmp_path / "sas.png")
    assert img.ndim == 3 and img.shape[1] > 500 and img.std() > 10
    info = json.loads((tmp_path / "sas.json").read_text())
    mine = info["anchor mine"]
    assert mine["elements_per_side"] == 8 and mine["pixels"] == 10_000
    assert mine["bright_fraction"]["sas"] < 0.5 * mine["bright_fraction"]["side_scan"]


def test_survey_xtf_figure_shows_the_tvgs_dark_water_column_beside_the_agc(tmp_path):
    """Issue 50: the survey's XTF drawn from its codes with pyxtf; the AGC writes the water column at the seabed's
    level, the device's TVG at least 20 dB below it."""
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "survey_xtf_figure.py"), "-o", str(tmp_path),
                           "--seconds", "3"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["xtf.json", "xtf_waterfalls.png"]
    img = iio.imread(tmp_path / "xtf_waterfalls.png")
    assert img.ndim == 3 and img.shape[1] > 500 and img.std() > 10
    info = json.loads((tmp_path / "xtf.json").read_text())
    assert abs(info["agc"]["contrast_db"]) < 3.0 and info["tvg"]["contrast_db"] > 20.0
    assert info["tvg"]["clipped_share"] < 0.05
