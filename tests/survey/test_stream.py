"""Streaming a line in blocks (issue: real surveys): the same bits as in memory, kill and resume, refusals.

The stores are read back with xarray/zarr and the XTF files compared byte for byte.
"""
import os
import sys

import numpy as np
import pytest
import xarray as xr

import sonar_embree as se
from sonar_embree.survey import stream

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
    (tmp_path / "mem").mkdir()
    rec.to_xtf(tmp_path / "mem" / "s.xtf", scale=1.0)             # the same name (the header's ThisFileName)
    assert (tmp_path / "s.xtf").read_bytes() == (tmp_path / "mem" / "s.xtf").read_bytes()


class _Killed(Exception):
    pass


def _render_killed_at(monkeypatch, pings_done, *args, **kw):
    """``render_line(*args, **kw)`` killed just before it counts ``pings_done`` pings as done (that block's data
    written, its progress not); the progress writer is restored after."""
    saved = stream._save_progress

    def dies(path, progress):
        if progress["pings_done"] == pings_done:
            raise _Killed
        saved(path, progress)

    monkeypatch.setattr(stream, "_save_progress", dies)
    try:
        with pytest.raises(_Killed):
            se.stream.render_line(*args, **kw)
    finally:
        monkeypatch.setattr(stream, "_save_progress", saved)


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
    done = []
    real = stream.simulate
    monkeypatch.setattr(stream, "simulate", lambda *a, **k: done.append(k["ping_offset"]) or real(*a, **k))
    se.stream.render_line(_scene(), LINE, cut, SONAR, **kw)
    assert done == [16, 24]                                    # only the blocks not done are simulated again
    assert _files(cut) == _files(whole)


def test_xtf_is_cut_back_on_resume(tmp_path, monkeypatch):
    kw = dict(block_pings=8, xtf_scale=1.0, start_time=START)
    for d in "ab":                                            # the same XTF name in two folders (ThisFileName)
        (tmp_path / d).mkdir()
    se.stream.render_line(_scene(), LINE, tmp_path / "a.zarr", SONAR, xtf_path=tmp_path / "a" / "l.xtf", **kw)
    _render_killed_at(monkeypatch, 16, _scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=tmp_path / "b" / "l.xtf",
                      **kw)
    a_xtf, b_xtf = tmp_path / "a" / "l.xtf", tmp_path / "b" / "l.xtf"
    assert b_xtf.stat().st_size > a_xtf.stat().st_size * 16 / 30 - 1   # block 2 in
    se.stream.render_line(_scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=b_xtf, **kw)
    assert b_xtf.read_bytes() == a_xtf.read_bytes()


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


# --- issue 33: never a byte of what the stream did not write ------------------------------------------------
def test_a_users_folder_is_refused_and_survives(tmp_path):
    """Finding 1: a non-empty folder that is not a streamed line is refused before any work, its files intact, with
    overwrite=True too (issue 49: overwrite replaces only what the project wrote)."""
    mine = tmp_path / "mydata"
    (mine / "sub").mkdir(parents=True)
    (mine / "thesis.tex").write_text("years of work")
    (mine / "sub" / "fig.pdf").write_bytes(b"%PDF")
    with pytest.raises(se.ConfigError, match=r"mydata: not empty and not a streamed line \(found 'sub'\)"):
        se.stream.render_line(_scene(), LINE[:4], mine, SONAR, block_pings=4, start_time=START)
    assert (mine / "thesis.tex").read_text() == "years of work" and (mine / "sub" / "fig.pdf").exists()
    with pytest.raises(se.ConfigError, match=r"mydata: not empty and not a streamed line \(found 'sub'\)"):
        se.stream.render_line(_scene(), LINE[:4], mine, SONAR, block_pings=4, start_time=START, overwrite=True)
    assert (mine / "thesis.tex").read_text() == "years of work" and (mine / "sub" / "fig.pdf").exists()
    killed = tmp_path / "killed.zarr"                      # killed while writing its very first progress
    killed.mkdir()
    (killed / "stream.json.tmp").write_text('{"fingerprint": "')
    se.stream.render_line(_scene(), LINE[:4], killed, SONAR, block_pings=4, start_time=START)
    assert stream._progress(str(killed))["pings_done"] == 4
    afile = tmp_path / "notes.txt"
    afile.write_text("keep")
    with pytest.raises(se.ConfigError, match="notes.txt: exists and is not a folder"):
        se.stream.render_line(_scene(), LINE[:4], afile, SONAR, block_pings=4)
    assert afile.read_text() == "keep"


def test_an_unrelated_xtf_survives(tmp_path):
    """Finding 2: the XTF path is part of the fingerprint (a resume with another XTF is refused) and a fresh
    stream does not start over a file it did not write."""
    kw = dict(block_pings=8, xtf_scale=1.0, start_time=START)
    other = tmp_path / "other.xtf"
    other.write_bytes(b"a user's survey" * 100)
    before = other.read_bytes()
    with pytest.raises(se.ConfigError, match="other.xtf: exists and was not written by this stream"):
        se.stream.render_line(_scene(), LINE[:16], tmp_path / "a.zarr", SONAR, xtf_path=other, **kw)
    assert not (tmp_path / "a.zarr" / "stream.json").exists()
    se.stream.render_line(_scene(), LINE[:16], tmp_path / "a.zarr", SONAR, xtf_path=tmp_path / "a.xtf", **kw)
    with pytest.raises(se.ConfigError, match=r"holds a streamed line of other inputs \(its XTF was .*a.xtf"):
        se.stream.render_line(_scene(), LINE[:16], tmp_path / "a.zarr", SONAR, xtf_path=other, **kw)
    assert other.read_bytes() == before
    # its own XTF may be started over (resume=False): it is the stream's
    se.stream.render_line(_scene(), LINE[:16], tmp_path / "a.zarr", SONAR, xtf_path=tmp_path / "a.xtf",
                          resume=False, **kw)


def _cut_after_two_blocks(tmp_path, monkeypatch, name):
    _render_killed_at(monkeypatch, 24, _scene(), LINE, tmp_path / f"{name}.zarr", SONAR,
                      xtf_path=tmp_path / f"{name}.xtf", block_pings=8, xtf_scale=1.0, start_time=START)


def test_a_short_or_missing_xtf_is_refused_on_resume(tmp_path, monkeypatch):
    """Finding 2: an XTF shorter than the progress claims is refused (not padded with zeros); so is a missing
    one and one whose header is not the stream's."""
    kw = dict(block_pings=8, xtf_scale=1.0, start_time=START)
    _cut_after_two_blocks(tmp_path, monkeypatch, "b")
    xtf = tmp_path / "b.xtf"
    data = xtf.read_bytes()
    xtf.write_bytes(data[: len(data) // 3])
    with pytest.raises(se.ConfigError, match=r"b.xtf: holds \d+ bytes, fewer than the \d+ of the 16 pings done"):
        se.stream.render_line(_scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=xtf, **kw)
    xtf.write_bytes(b"X" + data[1:])
    with pytest.raises(se.ConfigError, match="b.xtf: its header is not the one this stream wrote"):
        se.stream.render_line(_scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=xtf, **kw)
    xtf.unlink()
    with pytest.raises(se.ConfigError, match="b.xtf: the XTF of this streamed line is missing"):
        se.stream.render_line(_scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=xtf, **kw)


def test_progress_is_fsynced_after_the_blocks_files(tmp_path, monkeypatch):
    """Finding 2: every block's XTF and Zarr files are fsynced before the progress that counts them, and the
    progress itself is fsynced (a power cut cannot count a block whose bytes are not on disk)."""
    order = []
    real_fsync, real_save = os.fsync, stream._save_progress
    monkeypatch.setattr(os, "fsync", lambda fd: order.append(os.readlink(f"/proc/self/fd/{fd}")) or real_fsync(fd))
    monkeypatch.setattr(stream, "_save_progress", lambda p, pr: order.append(("saved", pr["pings_done"]))
                        or real_save(p, pr))
    se.stream.render_line(_scene(), LINE[:16], tmp_path / "s.zarr", SONAR, block_pings=8,
                          xtf_path=tmp_path / "s.xtf", xtf_scale=1.0, start_time=START)
    i = order.index(("saved", 8))
    before = [p for p in order[:i] if isinstance(p, str)]
    assert str(tmp_path / "s.xtf") in before and any(p.endswith(os.path.join("port", "0.0")) for p in before)
    assert any(isinstance(p, str) and p.endswith("stream.json.tmp") for p in order[i:])


def test_the_stream_states_its_time_after_the_second_block(tmp_path, caplog):
    """Issue 33: the time a line will take (INFO; -v on the command line); issue 50: from its second block's pace,
    the first's holding the set-up and a first run's compilation."""
    caplog.set_level("INFO", logger="sonar_embree.survey.stream")
    se.stream.render_line(_scene(), LINE[:12], tmp_path / "s.zarr", SONAR, block_pings=4, start_time=START)
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("render_line: about")]
    assert len(lines) == 1 and "for the 4 pings left (" in lines[0] and "in the second block" in lines[0]


def test_a_huge_block_is_the_whole_line(tmp_path):
    """Finding 12: block_pings beyond the line is one block (no half store, no traceback)."""
    se.stream.render_line(_scene(), LINE[:5], tmp_path / "s.zarr", SONAR, block_pings=10**9, start_time=START)
    ds = xr.open_zarr(tmp_path / "s.zarr")
    assert ds["port"].shape[0] == 5 and ds["port"].encoding["chunks"][0] == 5
    with pytest.raises(se.ConfigError, match="resume must be True or False"):
        se.stream.render_line(_scene(), LINE[:5], tmp_path / "s.zarr", SONAR, resume="no")


_SMALL_DISK_STREAM = """
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
import sonar_embree as se
sys.path[:0] = [{tests!r}, {root!r}]
from test_stream import LINE, SONAR, START, _scene
resource.setrlimit(resource.RLIMIT_FSIZE, ({limit}, {limit}))   # writes beyond it fail as on a full disk
try:
    se.stream.render_line(_scene(), LINE, {store!r}, SONAR, block_pings=8, xtf_path={xtf!r}, xtf_scale=1.0,
                          start_time=START)
except se.ConfigError as exc:
    print(exc, file=sys.stderr)
    sys.exit(3)
"""


def test_a_full_disk_gives_one_line_and_the_resume_is_exact(tmp_path):
    """Finding 12: a full disk (a file-size limit here, so writes fail with EFBIG as on a full disk) was a raw
    OSError; now one line naming the file, and a run after space is freed resumes to the same bytes."""
    import subprocess

    kw = dict(block_pings=8, xtf_scale=1.0, start_time=START)
    for d in "ab":                                            # the same XTF name in two folders (ThisFileName)
        (tmp_path / d).mkdir()
    a_xtf, b_xtf = tmp_path / "a" / "l.xtf", tmp_path / "b" / "l.xtf"
    se.stream.render_line(_scene(), LINE, tmp_path / "a.zarr", SONAR, xtf_path=a_xtf, **kw)
    size = a_xtf.stat().st_size
    here = os.path.dirname(os.path.abspath(__file__))
    code = _SMALL_DISK_STREAM.format(tests=here, root=os.path.dirname(here), limit=size // 2,
                                     store=str(tmp_path / "b.zarr"), xtf=str(b_xtf))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 3, proc.stderr[-2000:]
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and "l.xtf: cannot write (File too large)" in err[0], proc.stderr
    assert 0 < stream._progress(str(tmp_path / "b.zarr"))["pings_done"] < len(LINE)
    se.stream.render_line(_scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=b_xtf, **kw)
    assert b_xtf.read_bytes() == a_xtf.read_bytes()
    assert _files(tmp_path / "b.zarr") == {k: v for k, v in _files(tmp_path / "a.zarr").items()
                                            if k != "stream.json"} | {"stream.json": (tmp_path / "b.zarr" /
                                                                                      "stream.json").read_bytes()}


def test_a_second_writer_is_refused(tmp_path):
    """Finding 12: a second writer of the same store is refused while the first holds its lock."""
    from sonar_embree.io.files import folder_lock

    (tmp_path / "t.zarr").mkdir()
    with folder_lock(tmp_path / "t.zarr"):
        with pytest.raises(se.ConfigError, match="t.zarr: another run is writing this folder now"):
            se.stream.render_line(_scene(), LINE[:4], tmp_path / "t.zarr", SONAR, block_pings=4)


def test_a_line_on_two_worker_processes_gives_the_same_bytes_and_resumes(tmp_path, monkeypatch):
    """The blocks rendered on a LocalCluster of two single-threaded worker processes, written here in ping order:
    the store and the XTF equal the in-process run's, byte for byte (speckle and labels on); a line killed in
    process after two blocks resumes on the workers to the same bytes."""
    kw = dict(block_pings=8, speckle=True, labels=True, seed=4, start_time=START, xtf_scale=1.0)
    here = tmp_path / "here"
    here.mkdir()
    se.stream.render_line(_scene(), LINE, here / "l.zarr", SONAR, xtf_path=here / "l.xtf", workers=1, **kw)
    there = tmp_path / "there"
    there.mkdir()
    se.stream.render_line(_scene(), LINE, there / "l.zarr", SONAR, xtf_path=there / "l.xtf", workers=2, **kw)
    data = lambda d: {k: v for k, v in _files(d / "l.zarr").items() if k != "stream.json"}  # noqa: E731 (its paths)
    assert data(there) == data(here)
    assert (there / "l.xtf").read_bytes() == (here / "l.xtf").read_bytes()
    cut = tmp_path / "cut"
    cut.mkdir()
    _render_killed_at(monkeypatch, 24, _scene(), LINE, cut / "l.zarr", SONAR, xtf_path=cut / "l.xtf", workers=1, **kw)
    se.stream.render_line(_scene(), LINE, cut / "l.zarr", SONAR, xtf_path=cut / "l.xtf", workers=2, **kw)
    assert data(cut) == data(here)
    assert (cut / "l.xtf").read_bytes() == (here / "l.xtf").read_bytes()


def test_a_whole_record_on_two_worker_processes_has_simulates_bits():
    """render_record: blocks of 7 pings on two worker processes, joined in ping order, equal one simulate() call
    (speckle, labels and the complex signal on): data, altitudes, the complex signal and every label array."""
    kw = dict(speckle=True, labels=True, seed=4, start_time=START, keep_complex=True)
    one = se.simulate(_scene(), LINE, SONAR, **kw)
    split = stream.render_record(_scene(), LINE, SONAR, block_pings=7, workers=2, **kw)
    for name in ("data", "altitude_m", "complex_data", "time_s"):
        assert np.array_equal(getattr(split, name), getattr(one, name)), name
    assert np.array_equal(split.trajectory.positions_m, one.trajectory.positions_m)
    for k, v in vars(one.labels).items():
        if isinstance(v, np.ndarray):
            assert np.array_equal(getattr(split.labels, k), v, equal_nan=True), k
    assert split.attrs["rays_per_ping"] == pytest.approx(one.attrs["rays_per_ping"], rel=1e-12)


def test_render_record_refuses_bad_options():
    with pytest.raises(se.ConfigError, match="render_record: workers must be an integer >= 1, got 0"):
        stream.render_record(_scene(), LINE, SONAR, workers=0)
    with pytest.raises(se.ConfigError, match="render_record: give one of workers, scheduler and client"):
        stream.render_record(_scene(), LINE, SONAR, workers=2, scheduler="tcp://127.0.0.1:1")
    with pytest.raises(se.ConfigError, match="render_record: block_pings must be an integer >= 1, got 0"):
        stream.render_record(_scene(), LINE, SONAR, block_pings=0, workers=2)
    with pytest.raises(se.ConfigError, match="ping_offset is set per block"):
        stream.render_record(_scene(), LINE, SONAR, workers=2, ping_offset=3)


def _xtf_seconds(path):
    import pyxtf

    _, packets = pyxtf.xtf_read(str(path))
    return np.array([q.Hour * 3600 + q.Minute * 60 + q.Second + q.HSeconds / 100.0
                     for q in packets[pyxtf.XTFHeaderType.sonar]])


def test_a_line_without_a_start_time_keeps_one_clock_across_blocks_and_a_resume(tmp_path, monkeypatch):
    """No start time given: every block's pings count from one start (the XTF's ping times step as the
    trajectory's, never by the time a block took to render), a resumed line's too. ``simulate``'s own "now" is
    made to move an hour per call, as it would move on between blocks."""
    sim = __import__("importlib").import_module("sonar_embree.simulate")
    real, hours = sim.iso_utc, iter(range(1, 24))
    moving = lambda v=None: real(v) if v is not None else f"2026-05-01T{next(hours):02d}:00:00Z"  # noqa: E731
    monkeypatch.setattr(sim, "iso_utc", moving)
    step = np.diff(LINE.times_s)
    se.stream.render_line(_scene(), LINE, tmp_path / "a.zarr", SONAR, xtf_path=tmp_path / "a.xtf", block_pings=8)
    np.testing.assert_allclose(np.diff(_xtf_seconds(tmp_path / "a.xtf")), step, atol=0.011)
    _render_killed_at(monkeypatch, 16, _scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=tmp_path / "b.xtf",
                      block_pings=8)
    monkeypatch.setattr(stream, "iso_utc", lambda v=None: real(v) if v is not None else "2026-05-02T00:00:00Z")
    se.stream.render_line(_scene(), LINE, tmp_path / "b.zarr", SONAR, xtf_path=tmp_path / "b.xtf", block_pings=8)
    np.testing.assert_allclose(np.diff(_xtf_seconds(tmp_path / "b.xtf")), step, atol=0.011)


def test_where_a_line_runs_by_default_and_bad_cluster_options(monkeypatch):
    """In this process below AUTO_MIN_PINGS pings or AUTO_MIN_BLOCKS blocks left or AUTO_MIN_CPUS CPUs, on worker
    processes above; workers=1 keeps it here; a scheduler or a client sends it out; one option at most."""
    monkeypatch.setattr(stream.os, "cpu_count", lambda: stream.AUTO_MIN_CPUS)
    n = stream.AUTO_MIN_PINGS
    assert stream._on_cluster(n, n // stream.AUTO_MIN_BLOCKS, None, None, None, None)
    assert not stream._on_cluster(n - 1, 64, None, None, None, None)
    assert not stream._on_cluster(n, n, None, None, None, None)                      # one block
    assert not stream._on_cluster(n, 64, {"pings_done": 64}, None, None, None)        # fewer left
    assert not stream._on_cluster(n, 64, None, 1, None, None)
    assert stream._on_cluster(10, 8, None, 2, None, None) and stream._on_cluster(10, 8, None, None, "tcp://x:1", None)
    monkeypatch.setattr(stream.os, "cpu_count", lambda: stream.AUTO_MIN_CPUS - 1)
    assert not stream._on_cluster(n, 64, None, None, None, None)
    with pytest.raises(se.ConfigError, match="workers must be an integer >= 1, got 0"):
        se.stream.render_line(_scene(), LINE, "unused.zarr", SONAR, workers=0)
    with pytest.raises(se.ConfigError, match="one of workers, scheduler and client"):
        se.stream.render_line(_scene(), LINE, "unused.zarr", SONAR, workers=2, scheduler="tcp://127.0.0.1:1")
