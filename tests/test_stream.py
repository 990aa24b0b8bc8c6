"""Streaming a line in blocks (issue: real surveys): the same bits as in memory, kill and resume, refusals.

The stores are read back with xarray/zarr and the XTF files compared byte for byte.
"""
import os
import sys

import numpy as np
import pytest
import xarray as xr

import sonar_embree as se
from sonar_embree import stream

START = "2026-05-01T12:00:00Z"


def _scene():
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 1.0))
    box.apply_translation((0.0, -12.0, 0.5))
    return se.Scene().add(se.seafloor.flat((300.0, 300.0)), label="seafloor").add(box, label="box")


LINE = se.Trajectory.line((-10.0, 0.0, 10.0), (10.0, 0.0, 10.0), 30)
SONAR = se.Sonar(max_range_m=25.0)


def _files(path):
    out = {}
    for root, _, names in os.walk(path):
        for n in names:
            with open(os.path.join(root, n), "rb") as fh:
                out[os.path.relpath(os.path.join(root, n), path)] = fh.read()
    return out


def test_streamed_line_equals_the_in_memory_run(tmp_path):
    kw = dict(labels=True, speckle=True, seed=4, start_time=START)
    se.stream.render_line(_scene(), LINE, tmp_path / "s.zarr", SONAR, block_pings=8, xtf_path=tmp_path / "s.xtf",
                          xtf_scale=1.0, **kw)
    rec = se.simulate(_scene(), LINE, SONAR, **kw)
    ds = xr.open_zarr(tmp_path / "s.zarr")
    assert ds["port"].encoding["chunks"] == (8, rec.port.shape[1])          # one chunk per block
    for name in ("port", "starboard", "altitude_m", "x_m", "ping_time_s", "label_kind", "label_ground_range_m"):
        np.testing.assert_array_equal(ds[name].values, rec.to_xarray()[name].values, err_msg=name)
    rec.to_xtf(tmp_path / "m.xtf", scale=1.0)
    assert (tmp_path / "s.xtf").read_bytes() == (tmp_path / "m.xtf").read_bytes()


class _Killed(Exception):
    pass


def test_killed_and_resumed_gives_the_same_bytes(tmp_path, monkeypatch):
    kw = dict(block_pings=8, xtf_path=None, start_time=START)
    whole = tmp_path / "whole.zarr"
    se.stream.render_line(_scene(), LINE, whole, SONAR, **kw)
    cut = tmp_path / "cut.zarr"
    saved = stream._save_progress
    calls = []

    def dies_on_the_third_block(path, progress):           # after block 3's data is written, before it counts
        calls.append(progress["pings_done"])
        if progress["pings_done"] == 24:
            raise _Killed
        saved(path, progress)

    monkeypatch.setattr(stream, "_save_progress", dies_on_the_third_block)
    with pytest.raises(_Killed):
        se.stream.render_line(_scene(), LINE, cut, SONAR, **kw)
    monkeypatch.undo()
    assert stream._progress(str(cut))["pings_done"] == 16
    sim = sys.modules["sonar_embree.simulate"]
    done = []
    real = sim.simulate
    monkeypatch.setattr(sim, "simulate", lambda *a, **k: done.append(k["ping_offset"]) or real(*a, **k))
    se.stream.render_line(_scene(), LINE, cut, SONAR, **kw)
    assert done == [16, 24]                                    # only the blocks not done are simulated again
    assert _files(cut) == _files(whole)


def test_xtf_is_cut_back_on_resume(tmp_path, monkeypatch):
    kw = dict(block_pings=8, xtf_scale=1.0, start_time=START)
    se.stream.render_line(_scene(), LINE, tmp_path / "a.zarr", SONAR, xtf_path=tmp_path / "a.xtf", **kw)
    saved = stream._save_progress

    def dies(path, progress):
        if progress["pings_done"] == 16:
            raise _Killed
        saved(path, progress)

    monkeypatch.setattr(stream, "_save_progress", dies)
    with pytest.raises(_Killed):
        se.stream.render_line(_scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=tmp_path / "b.xtf", **kw)
    monkeypatch.undo()
    assert (tmp_path / "b.xtf").stat().st_size > (tmp_path / "a.xtf").stat().st_size * 16 / 30 - 1   # block 2 in
    se.stream.render_line(_scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=tmp_path / "b.xtf", **kw)
    assert (tmp_path / "b.xtf").read_bytes() == (tmp_path / "a.xtf").read_bytes()


def test_other_inputs_are_refused_unless_started_over(tmp_path):
    path = tmp_path / "s.zarr"
    se.stream.render_line(_scene(), LINE[:8], path, SONAR, block_pings=4, start_time=START)
    other = se.Sonar(max_range_m=20.0)
    with pytest.raises(se.ConfigError, match="s.zarr: holds a streamed line of other inputs"):
        se.stream.render_line(_scene(), LINE[:8], path, other, block_pings=4, start_time=START)
    se.stream.render_line(_scene(), LINE[:8], path, other, block_pings=4, start_time=START, resume=False)
    assert xr.open_zarr(path)["port"].shape[1] == se.simulate(_scene(), LINE[:1], other).port.shape[1]
    with pytest.raises(se.ConfigError, match="block_pings must be an integer"):
        se.stream.render_line(_scene(), LINE, path, SONAR, block_pings=0)
    with pytest.raises(se.ConfigError, match="ping_offset is not a streaming option"):
        se.stream.render_line(_scene(), LINE, path, SONAR, ping_offset=3)
