"""A streamed line opened again as a record (issue 35, item 6): Record.load of a Zarr store, lazily, and a waterfall
PNG of any length at the ground's aspect."""
import numpy as np
import pytest

import sonar_embree as se

SONAR = se.Sonar(max_range_m=30.0)


def _scene():
    scene = se.Scene().add(se.seafloor.flat((200, 200)), label="seafloor")
    return scene.add(se.seafloor.flat((2, 2), z_m=0.5, center_m=(1.0, -12.0)), label="plate")


def test_a_streamed_line_opens_again_as_the_same_record_lazily(tmp_path):
    """render_line's store opened with Record.load: intensities and labels are dask arrays (nothing read yet) equal
    to the in-memory run's, with its axes, poses, sonar and pulse; its waterfall is the in-memory one's, bit for bit,
    drawn a block of pings at a time."""
    line = se.Trajectory.line((0, 0, 10), (3, 0, 10), 24)
    kw = dict(labels=True, speckle=True, seed=3)
    se.stream.render_line(_scene(), line, tmp_path / "l.zarr", SONAR, block_pings=8, **kw)
    rec = se.simulate(_scene(), line, SONAR, **kw)
    back = se.Record.load(tmp_path / "l.zarr")
    assert type(back.data).__module__.startswith("dask") and type(back.labels.kind).__module__.startswith("dask")
    np.testing.assert_array_equal(np.asarray(back.data), rec.data)
    np.testing.assert_array_equal(np.asarray(back.labels.object_id), rec.labels.object_id)
    np.testing.assert_array_equal(back.time_s, rec.time_s)
    np.testing.assert_array_equal(back.trajectory.positions_m, rec.trajectory.positions_m)
    assert back.sonar == rec.sonar and back.pulse == rec.pulse and back.labels.names == rec.labels.names
    np.testing.assert_array_equal(back.waterfall(), rec.waterfall())
    back.save_png(tmp_path / "l.png", aspect=True)
    assert (tmp_path / "l.png").stat().st_size > 0


def test_a_folder_that_is_not_our_store_is_refused_in_one_line(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("a user's folder")
    with pytest.raises(se.ConfigError, match="not a Zarr store written by sonar_embree"):
        se.Record.load(tmp_path / "mine")


@pytest.mark.parametrize("spacing_m, want_group, want_repeat", [(0.006, 6, 1), (0.15, 1, 4)])
def test_waterfall_rows_follow_the_ground_aspect(spacing_m, want_group, want_repeat):
    """With aspect=True a row stands for as much distance along track as a column across: columns of 2 samples ×
    c/(2·fs) = 0.0375 m (1601 samples, at most 1024 columns); pings 6 mm apart are averaged 6 to a row (0.0375/0.006 =
    6.25, rounded), pings 15 cm apart are each shown 4 times (0.15/0.0375); max_rows caps the rows."""
    n = 64
    rec = se.simulate(_scene(), se.Trajectory.line((0, 0, 10), (spacing_m * (n - 1), 0, 10), n), SONAR,
                      speckle=False)
    width = 2 * (rec.slant_range_m[1] - rec.slant_range_m[0])
    assert width == pytest.approx(0.0375)
    img = rec.waterfall(aspect=True)
    assert img.shape[0] == -(-n // want_group) * want_repeat
    plain = rec.waterfall()
    if want_group > 1:                                   # rows are means of groups of pings (intensity, then dB)
        assert img.shape[0] == 11 and plain.shape[0] == n
    else:
        np.testing.assert_array_equal(img[::want_repeat], plain)
    assert rec.waterfall(aspect=True, max_rows=20).shape[0] <= 20
    with pytest.raises(se.ConfigError, match="max_rows"):
        rec.waterfall(max_rows=0)


def test_render_line_draws_its_waterfall_png(tmp_path):
    """render_line(png_path=…) writes the line's waterfall at the ground's aspect from the store: the image that
    Record.load(store).waterfall(aspect=True) draws."""
    import imageio.v3 as iio

    line = se.Trajectory.line((0, 0, 10), (3, 0, 10), 24)
    se.stream.render_line(_scene(), line, tmp_path / "l.zarr", SONAR, block_pings=8, png_path=tmp_path / "l.png")
    img = iio.imread(tmp_path / "l.png")
    want = se.Record.load(tmp_path / "l.zarr").waterfall(aspect=True, max_rows=8192)
    np.testing.assert_array_equal(img, want)
    assert img.shape[0] > 24                         # pings 13 cm apart, columns 3.75 cm: rows repeated


def test_a_store_missing_a_chunk_is_refused_not_read_as_nan(tmp_path):
    """Issue 49: a chunk file deleted from a store loaded as NaN pings, silently; now one line names the variable."""
    import os

    scene = se.Scene().add(se.seafloor.flat((50.0, 50.0)))
    rec = se.simulate(scene, se.Trajectory.line((-1, 0, 5), (1, 0, 5), 3), se.Sonar(max_range_m=10.0), se.Pulse.cw(),
                      start_time="2000-01-01")
    rec.to_zarr(tmp_path / "r.zarr")
    assert np.array_equal(se.Record.load(tmp_path / "r.zarr").port, rec.port)
    os.remove(tmp_path / "r.zarr" / "starboard" / "0.0")
    with pytest.raises(se.ConfigError, match="'starboard' lacks 1 of its 1 chunks"):
        se.Record.load(tmp_path / "r.zarr")
