"""Record formats read back by independent readers: pyxtf for XTF, xarray/Zarr, json for COCO."""
import dataclasses
import datetime as dt
import json
import os

import dask.array
import numpy as np
import pytest
import pyxtf
import xarray as xr
from pycocotools.coco import COCO

import sonar_embree as se
from conftest import box, flat_scene
from sonar_embree.signal.labels import OBJECT, Labels


@pytest.fixture(scope="module")
def record():
    """A curved, rolling pass over a box, with labels and speckle, at UTM-like coordinates."""
    e0, n0 = 512_000.0, 5_412_000.0
    scene = se.Scene().add(se.seafloor.flat((120, 120), center_m=(e0, n0)), label="seafloor")
    scene.add(box((2.0, 2.0, 1.0), (e0 + 1.0, n0 + 12.0, 0.5)), label="crate#0")
    traj = se.Trajectory.through_waypoints([(e0 - 4, n0, 9.0), (e0, n0 + 0.5, 9.0), (e0 + 5, n0 + 0.7, 9.5)],
                                           n_pings=9, speed_m_s=1.5, roll_deg=2.0)
    return se.simulate(scene, traj, se.Sonar(max_range_m=25.0), speckle=True, seed=4, labels=True, tvg=True,
                       keep_complex=True)


def test_pyxtf_reads_channels_pings_samples_and_navigation(record, tmp_path):
    path = tmp_path / "run.xtf"
    record.to_xtf(path, start=dt.datetime(2026, 3, 4, 5, 6, 7), scale=1.0, surface_z_m=30.0)
    header, packets = pyxtf.xtf_read(str(path))
    assert header.NumberOfSonarChannels == 2
    assert [c.TypeOfChannel for c in header.sonar_info] == [1, 2]  # port, starboard
    pings = packets[pyxtf.XTFHeaderType.sonar]
    assert len(pings) == record.n_pings and set(packets) == {pyxtf.XTFHeaderType.sonar}
    t = record.trajectory
    for i, p in enumerate(pings):
        assert len(p.data) == 2
        # port is stored far range first (pyxtf's convention), starboard nadir first
        np.testing.assert_array_equal(p.data[0][::-1], record.port[i].astype(np.float32))
        np.testing.assert_array_equal(p.data[1], record.starboard[i].astype(np.float32))
        assert p.SensorXcoordinate == t.positions_m[i, 0] and p.SensorYcoordinate == t.positions_m[i, 1]
        assert p.SensorHeading == np.float32(t.heading_deg[i])
        assert p.SensorRoll == np.float32(t.roll_deg[i]) and p.SensorPitch == np.float32(t.pitch_deg[i])
        assert p.SensorDepth == np.float32(30.0 - t.positions_m[i, 2])
        assert p.PingNumber == i
        want = np.datetime64("2026-03-04T05:06:07") + np.timedelta64(int(t.times_s[i] * 100) * 10, "ms")
        assert p.get_time() == want
    # the waterfall as pyxtf users build it
    port = pyxtf.concatenate_channel(pings, header, 0)[::-1]
    np.testing.assert_array_equal(port[:, ::-1], record.port.astype(np.float32))
    assert not list(tmp_path.glob(".tmp-*"))


def test_xtf_speed_start_time_and_visible_samples(record, tmp_path):
    """Speed in knots from the trajectory, ping times from the record's start time, samples scaled to be seen."""
    path = tmp_path / "run.xtf"
    record.to_xtf(path)
    header, packets = pyxtf.xtf_read(str(path))
    pings = packets[pyxtf.XTFHeaderType.sonar]
    t = record.trajectory
    step = np.linalg.norm(np.diff(t.positions_m, axis=0), axis=1) / np.diff(t.times_s)
    assert 1.3 < step.mean() < 1.7  # through_waypoints(speed_m_s=1.5): the path is a little longer than the chords
    for i, p in enumerate(pings):
        assert p.SensorSpeed == pytest.approx(step[min(i, len(step) - 1)] / 0.514444, rel=0.2)
        assert p.SensorSpeed > 2.0  # knots, never 0
        assert p.SensorSpeed == pytest.approx(1.5 / 0.514444, rel=1e-6)  # the velocity it carries, 1.5 m/s
        assert p.SensorDepth == 0.0  # no sea surface given: unknown depth, not -z
    start = np.datetime64(record.attrs["start_time"].replace("+00:00", ""), "ms")
    assert abs(pings[0].get_time() - start) <= np.timedelta64(10, "ms")
    assert abs(start - np.datetime64(dt.datetime.now(dt.timezone.utc).replace(tzinfo=None), "ms")) \
        < np.timedelta64(3600, "s")  # simulate's default start: now
    factor = float(header.NoteString.decode().rsplit("x ", 1)[1]) if isinstance(header.NoteString, bytes) else \
        float(str(header.NoteString).rsplit("x ", 1)[1])
    data = np.array([p.data[1] for p in pings], dtype=np.float64)
    assert 100 <= np.percentile(data[data > 0], 99.5) < 1000  # a viewer shows it, not black
    np.testing.assert_allclose(data / factor, record.starboard, rtol=1e-6, atol=0)
    with pytest.raises(se.ConfigError, match="above the sea surface"):
        record.to_xtf(tmp_path / "bad.xtf", surface_z_m=5.0)
    with pytest.raises(se.ConfigError, match="scale"):
        record.to_xtf(tmp_path / "bad.xtf", scale=-1.0)


def test_zarr_opens_lazily_and_equals_the_record(record, tmp_path):
    path = tmp_path / "run.zarr"
    record.to_zarr(path)
    record.to_zarr(path)  # replacing an existing store is atomic too
    ds = xr.open_zarr(path)
    assert isinstance(ds.port.data, dask.array.Array)
    np.testing.assert_array_equal(ds.port.values, record.port)
    np.testing.assert_array_equal(ds.starboard.values, record.starboard)
    np.testing.assert_array_equal(ds.port_complex.values, record.port_complex)
    np.testing.assert_array_equal(ds.starboard_complex.values, record.starboard_complex)
    np.testing.assert_array_equal(ds.time_s.values, record.time_s)
    np.testing.assert_array_equal(ds.slant_range_m.values, record.slant_range_m)
    for i, axis in enumerate("xyz"):
        np.testing.assert_array_equal(ds[f"{axis}_m"].values, record.trajectory.positions_m[:, i])
    np.testing.assert_array_equal(ds.heading_deg.values, record.trajectory.heading_deg)
    np.testing.assert_array_equal(ds.altitude_m.values, record.altitude_m)
    for k in Labels.ARRAYS:
        np.testing.assert_array_equal(ds[f"label_{k}"].values, getattr(record.labels, k))
    assert ds.attrs["simulation.seed"] == 4 and ds.attrs["simulation.speckle"] == 1  # NetCDF has no booleans
    assert ds.attrs["sonar.max_range_m"] == 25.0 and ds.attrs["package_version"] == se.__version__
    assert ds.attrs["labels.names"] == ["seafloor", "crate#0"]
    assert sorted(os.listdir(tmp_path)) == ["run.zarr"]


def _cf_checks(ds):
    assert ds.attrs["Conventions"].startswith("CF-")
    assert not [k for k, v in ds.attrs.items() if v is None]
    assert not [k for k, v in ds.attrs.items() if isinstance(v, str) and k.startswith(("sonar.", "pulse."))
                and k not in ("pulse.kind", "sonar.beam")], "numbers stored as strings"   # names are strings
    for name, var in ds.variables.items():
        if name not in ("side",):
            assert "long_name" in var.attrs, name
    for name in ("x_m", "y_m", "z_m", "heading_deg", "pitch_deg", "roll_deg", "ping_time"):
        assert name in ds.coords and ds[name].dims == ("ping",), name
    assert ds.x_m.attrs["standard_name"] == "projection_x_coordinate" and ds.x_m.attrs["units"] == "m"
    assert ds.heading_deg.attrs["standard_name"] == "platform_yaw"
    assert ds.altitude_m.attrs["standard_name"] == "height_above_sea_floor"


def test_zarr_to_netcdf_round_trip(record, tmp_path):
    """xarray opens the Zarr, writes NetCDF with netCDF4, and reads back the same dataset (CF-style)."""
    plain = dataclasses.replace(record, complex_data=None)
    plain.to_zarr(tmp_path / "plain.zarr")
    ds = xr.open_zarr(tmp_path / "plain.zarr").load()
    _cf_checks(ds)
    ds.to_netcdf(tmp_path / "plain.nc")  # default engine, no options: every attribute is NetCDF-typed
    back = xr.open_dataset(tmp_path / "plain.nc").load()
    xr.testing.assert_identical(ds, back)
    assert back.ping_time.values[0] == np.datetime64(record.attrs["start_time"].replace("+00:00", ""), "ns")
    # complex baseband needs NetCDF's complex support, asked for explicitly
    record.to_zarr(tmp_path / "cplx.zarr")
    ds = xr.open_zarr(tmp_path / "cplx.zarr").load()
    ds.to_netcdf(tmp_path / "cplx.nc", engine="netcdf4", auto_complex=True)
    back = xr.open_dataset(tmp_path / "cplx.nc", engine="netcdf4", auto_complex=True).load()
    xr.testing.assert_identical(ds, back)


def test_coco_boxes_cover_the_label_mask(record, tmp_path):
    record.to_coco(tmp_path / "coco.json", max_columns=None)
    d = json.loads((tmp_path / "coco.json").read_text())
    assert d["categories"] == [{"id": 1, "name": "crate", "supercategory": "object"}]
    img = d["images"][0]
    assert (img["height"], img["width"]) == (record.n_pings, 2 * record.port.shape[1])
    assert d["info"]["date_created"] == record.attrs["start_time"]
    lab = record.labels
    want = lab.mask(lab.echo_mask(1), None)
    coco = COCO(str(tmp_path / "coco.json"))
    union = np.zeros_like(want)
    for ann in coco.loadAnns(coco.getAnnIds()):
        m = coco.annToMask(ann).astype(bool)  # pycocotools decodes our RLE
        x, y, w, h = ann["bbox"]
        assert m.sum() == ann["area"] > 0 and m[y:y + h, x:x + w].sum() == m.sum()
        assert not (union & m).any()  # pieces do not overlap
        union |= m
    np.testing.assert_array_equal(union, want)
    # the echo covers at least the centre line's geometric highlight
    centre = lab.mask((lab.kind == OBJECT) & (lab.object_id == 1), None)
    assert centre.any() and (want | centre).sum() <= want.sum() + 0.2 * centre.sum()


def test_coco_needs_labels(flat_record, tmp_path):
    with pytest.raises(se.ConfigError, match="labels=True"):
        flat_record.to_coco(tmp_path / "c.json")
    assert not (tmp_path / "c.json").exists()


def test_complex_baseband_is_the_square_root_of_the_intensity(record, tmp_path):
    for z, i in ((record.port_complex, record.port), (record.starboard_complex, record.starboard)):
        assert z.dtype == np.complex128 and z.shape == i.shape
        np.testing.assert_allclose(np.abs(z) ** 2, i, rtol=1e-9, atol=1e-300)
    assert np.any(np.abs(np.angle(record.port_complex[record.port > 0])) > 1.0)  # a phase, not only a magnitude
    record.save(tmp_path / "r.npz")
    np.testing.assert_array_equal(se.Record.load(tmp_path / "r.npz").port_complex, record.port_complex)


@pytest.mark.parametrize("kw", [{}, {"speckle": True, "band": "carrier", "detection": "incoherent"},
                                {"speckle": True, "lowpass_hz": 5e3}])
def test_complex_output_only_where_it_exists(kw):
    scene = se.Scene().add(se.seafloor.flat((50, 50)), label="seafloor")
    with pytest.raises(se.ConfigError, match="keep_complex"):
        se.simulate(scene, se.Trajectory.line((0, 0, 5), (1, 0, 5), 2), keep_complex=True, **kw)


def test_writers_replace_their_own_kind_of_file_never_a_users(tmp_path):
    """Issue 33's class: every writer refuses a target it did not create. A user's document or folder given as
    an output path is refused and left byte for byte; the writer's own earlier output is replaced."""
    rec = se.simulate(se.Scene().add(se.seafloor.flat((60.0, 60.0)), label="seafloor"),
                      se.Trajectory.line((-1.0, 0.0, 10.0), (1.0, 0.0, 10.0), 3), se.Sonar(max_range_m=20.0),
                      labels=True, start_time="2026-05-01T12:00:00Z")
    thesis = tmp_path / "thesis.tex"
    thesis.write_text("\\documentclass{book} years of work")
    for write, what in ((lambda p: rec.save(p), "NPZ"), (lambda p: rec.to_xtf(p), "XTF"),
                        (lambda p: rec.save_png(p), "PNG"), (lambda p: rec.labels.save_png(p), "PNG"),
                        (lambda p: rec.trajectory.to_csv(p), "CSV")):
        with pytest.raises(se.ConfigError, match=f"thesis.tex: exists and is not a {what} file"):
            write(thesis)
    assert thesis.read_text() == "\\documentclass{book} years of work"
    for name, write in (("r.npz", rec.save), ("r.xtf", rec.to_xtf), ("r.png", rec.save_png),
                        ("nav.csv", rec.trajectory.to_csv)):
        write(tmp_path / name)
        write(tmp_path / name)                                          # its own file: replaced
    mine = tmp_path / "mydata"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    with pytest.raises(se.ConfigError, match="mydata: exists and is not a Zarr store written by sonar_embree"):
        rec.to_zarr(mine)
    assert (mine / "notes.txt").read_text() == "keep"
    (tmp_path / "empty").mkdir()
    rec.to_zarr(tmp_path / "empty")
    rec.to_zarr(tmp_path / "empty")                                     # its own store: replaced
    with pytest.raises(se.ConfigError, match="no/r.zarr: its folder .* does not exist"):
        rec.to_zarr(tmp_path / "no" / "r.zarr")


def test_a_full_disk_is_one_line_naming_the_file_not_its_temporary(tmp_path):
    """Issue 33, finding 12: the library's writers turn an OS error (here EFBIG from a file-size limit, as a
    full disk gives) into one line naming the output, not the hidden .tmp file, and leave nothing behind."""
    import subprocess
    import sys

    code = (
        "import resource, signal, sys\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        "import numpy as np, sonar_embree as se\n"
        "from sonar_embree.record.coco import write_json\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))\n"
        "try:\n"
        f"    write_json({{'images': ['x' * 100] * 100}}, {str(tmp_path / 'big.json')!r})\n"
        "except se.ConfigError as exc:\n"
        "    print(exc, file=sys.stderr); sys.exit(3)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 3, proc.stderr[-2000:]
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and err[0] == str(tmp_path / "big.json") + ": cannot write (File too large)", proc.stderr
    assert os.listdir(tmp_path) == []
