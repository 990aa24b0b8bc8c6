"""Issue 49: the four ways the second adversarial run destroyed a user's files, each its own test (each failed on the
code before the ownership manifest), and the manifest's own rules: written first, temporaries listed before they
exist and removed only from that list, a changed or foreign entry refused, a failed run leaving nothing."""
import json
import os

import pytest

import sonar_embree as se
from sonar_embree.errors import ConfigError
from sonar_embree.io.owner import FORMAT, MANIFEST, OutputFolder, read_manifest
from sonar_embree.runs import cli

RENDER = """
[sonar]
max_range_m = 12.0
[pulse]
kind = "cw"
duration_s = 100e-6
[trajectory]
kind = "line"
start = [-1.0, 0.0, 6.0]
end = [1.0, 0.0, 6.0]
n_pings = 3
[[objects]]
seafloor = "flat"
size_m = [30.0, 30.0]
"""


def _recording(path):
    scene = se.Scene().add(se.seafloor.flat((200, 200)), label="seafloor")
    rec = se.simulate(scene, se.Trajectory.line((-3, 0, 6.0), (3, 0, 6.0), 10), se.Sonar(max_range_m=20.0),
                      se.Pulse.cw(duration_s=100e-6), start_time="2026-05-01T12:00:00Z")
    rec.to_xtf(path, scale=1.0)


def test_replay_refuses_its_recording_as_its_output(tmp_path):
    """Data loss 1: ``replay DIR/replay.xtf -o DIR --overwrite``: the recording itself is the output."""
    out = tmp_path / "out"
    out.mkdir()
    _recording(out / "replay.xtf")
    before = (out / "replay.xtf").read_bytes()
    assert cli.main(["replay", str(out / "replay.xtf"), "-o", str(out), "--overwrite"]) == 2
    assert (out / "replay.xtf").read_bytes() == before
    os.link(out / "replay.xtf", tmp_path / "elsewhere.xtf")              # the same file under another name
    other = tmp_path / "other"
    other.mkdir()
    os.link(out / "replay.xtf", other / "replay.xtf")
    assert cli.main(["replay", str(tmp_path / "elsewhere.xtf"), "-o", str(other), "--overwrite"]) == 2
    assert (out / "replay.xtf").read_bytes() == before


def test_replay_overwrite_keeps_a_users_report(tmp_path, capsys):
    """Data loss 2: ``replay --overwrite`` into a folder holding a user's report.json and report.png."""
    _recording(tmp_path / "rec.xtf")
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.json").write_text('{"my": "notes"}')
    (out / "report.png").write_bytes(b"\x89PNG my own plot")
    assert cli.main(["replay", str(tmp_path / "rec.xtf"), "-o", str(out), "--overwrite"]) == 2
    assert "report.json: not written by sonar-embree" in capsys.readouterr().err
    assert (out / "report.json").read_text() == '{"my": "notes"}'
    assert (out / "report.png").read_bytes() == b"\x89PNG my own plot"
    assert not (out / "replay.xtf").exists()


def test_render_overwrite_keeps_a_users_files_named_as_outputs(tmp_path, capsys):
    """Data loss 3: ``render --overwrite`` where record.npz and waterfall.png are a user's text files."""
    (tmp_path / "run.toml").write_text(RENDER)
    out = tmp_path / "out"
    out.mkdir()
    (out / "record.npz").write_text("my record")
    (out / "waterfall.png").write_text("my picture")
    assert cli.main(["render", str(tmp_path / "run.toml"), "-o", str(out), "--overwrite", "--no-progress"]) == 2
    assert "not written by sonar-embree" in capsys.readouterr().err
    assert (out / "record.npz").read_text() == "my record" and (out / "waterfall.png").read_text() == "my picture"


def test_render_keeps_dot_prefixed_files(tmp_path):
    """Data loss 4: ``render`` (no --overwrite) into a folder holding only .old-photos/img1.txt and .tmp-draft.txt:
    refused; with --overwrite, written beside them."""
    (tmp_path / "run.toml").write_text(RENDER)
    out = tmp_path / "out"
    (out / ".old-photos").mkdir(parents=True)
    (out / ".old-photos" / "img1.txt").write_text("holiday")
    (out / ".tmp-draft.txt").write_text("draft")
    assert cli.main(["render", str(tmp_path / "run.toml"), "-o", str(out), "--no-progress"]) == 2
    assert cli.main(["render", str(tmp_path / "run.toml"), "-o", str(out), "--no-progress", "--overwrite"]) == 0
    assert (out / ".old-photos" / "img1.txt").read_text() == "holiday"
    assert (out / ".tmp-draft.txt").read_text() == "draft"
    assert (out / "record.npz").exists()


def _write(text):
    def write(path):
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(text)
    return write


def test_the_manifest_is_written_first_and_lists_sizes_and_hashes(tmp_path):
    out = OutputFolder.claim(tmp_path / "o", ["a.txt", "b"])
    man = read_manifest(str(tmp_path / "o"))
    assert man["format"] == FORMAT and man["entries"] == {} and man["pending"] == []

    def folder(path):
        os.mkdir(path)
        _write("inside")(os.path.join(path, "x.txt"))

    out.write_set([("a.txt", _write("hello")), ("b", folder)])
    entries = read_manifest(str(tmp_path / "o"))["entries"]
    import hashlib
    assert entries["a.txt"] == {"kind": "file", "size": 5, "sha256": hashlib.sha256(b"hello").hexdigest()}
    assert entries["b"]["kind"] == "folder" and entries["b"]["files"] == 1
    assert sorted(os.listdir(tmp_path / "o")) == [MANIFEST, "a.txt", "b"]


def test_overwrite_replaces_only_unchanged_entries(tmp_path):
    OutputFolder.claim(tmp_path, ["a.txt"]).write_set([("a.txt", _write("ours"))])
    with pytest.raises(ConfigError, match="not empty"):
        OutputFolder.claim(tmp_path, ["a.txt"])
    OutputFolder.claim(tmp_path, ["a.txt"], overwrite=True).write_set([("a.txt", _write("ours again"))])
    (tmp_path / "a.txt").write_text("edited by the user")
    with pytest.raises(ConfigError, match="a.txt: changed since sonar-embree wrote it"):
        OutputFolder.claim(tmp_path, ["a.txt"], overwrite=True)
    assert (tmp_path / "a.txt").read_text() == "edited by the user"
    (tmp_path / "b.txt").write_text("the user's")
    with pytest.raises(ConfigError, match="b.txt: not written by sonar-embree"):
        OutputFolder.claim(tmp_path, ["b.txt"], overwrite=True)


def test_a_killed_runs_temporaries_are_removed_by_name_only(tmp_path):
    """What a kill -9 leaves (the temporaries the manifest listed) goes on the next claim; nothing else does."""
    out = OutputFolder.claim(tmp_path, ["a.txt"])

    def killed(path):                                   # the run dies while writing: its temporary stays
        _write("half")(path)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        out.write_set([("a.txt", killed)])
    # a kill -9 would leave the pending entry and its folder: put them back as it would have
    man = json.loads((tmp_path / MANIFEST).read_text())
    man["pending"] = [".sonar-embree-deadbeef"]
    (tmp_path / MANIFEST).write_text(json.dumps(man))
    (tmp_path / ".sonar-embree-deadbeef").mkdir()
    (tmp_path / ".sonar-embree-deadbeef" / "a.txt").write_text("half")
    (tmp_path / ".sonar-embree-mine").mkdir()                                # a user's, with our prefix
    OutputFolder.claim(tmp_path, ["a.txt"], overwrite=True)
    assert sorted(os.listdir(tmp_path)) == [MANIFEST, ".sonar-embree-mine"]


def test_a_foreign_manifest_is_refused(tmp_path):
    (tmp_path / MANIFEST).write_text('{"my": "file"}')
    with pytest.raises(ConfigError, match="not a sonar-embree manifest"):
        OutputFolder.claim(tmp_path, ["a.txt"], overwrite=True)
    assert (tmp_path / MANIFEST).read_text() == '{"my": "file"}'


def test_a_failed_run_leaves_no_folder_that_refuses_its_rerun(tmp_path):
    with pytest.raises(RuntimeError):
        with OutputFolder.claim(tmp_path / "new", ["a.txt"]):
            raise RuntimeError("the simulation failed")
    assert not (tmp_path / "new").exists()


def test_a_killed_manifest_save_is_ours_a_users_file_of_its_name_is_not(tmp_path):
    """A kill between writing the manifest's next version and renaming it leaves MANIFEST.new, which the next run
    takes as its own (it begins as every manifest does); a user's file of that name is refused, never replaced."""
    from sonar_embree.io.owner import MANIFEST_NEW

    (tmp_path / "a").mkdir()
    (tmp_path / "a" / MANIFEST_NEW).write_text('{\n "command": "rend')                 # a torn save of ours
    OutputFolder.claim(tmp_path / "a", ["x.txt"]).write_set([("x.txt", _write("x"))])
    assert sorted(os.listdir(tmp_path / "a")) == [MANIFEST, "x.txt"]
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / MANIFEST_NEW).write_text("my notes")
    with pytest.raises(ConfigError, match="not a sonar-embree manifest"):
        OutputFolder.claim(tmp_path / "b", ["x.txt"], overwrite=True)
    assert (tmp_path / "b" / MANIFEST_NEW).read_text() == "my notes"


def test_an_entry_renamed_before_a_kill_is_recorded_on_the_next_claim(tmp_path):
    """A kill between a write's rename and its record leaves the entry in progress with its digest to be; the
    next claim finds the file whole and records it, so a resumed folder's manifest equals an unbroken run's."""
    out = OutputFolder.claim(tmp_path, ["a.txt"])
    out.write_set([("a.txt", _write("whole"))])
    whole = json.loads((tmp_path / MANIFEST).read_text())
    man = json.loads((tmp_path / MANIFEST).read_text())
    man["entries"]["a.txt"] = {"state": "in progress", "next": whole["entries"]["a.txt"]}
    (tmp_path / MANIFEST).write_text(json.dumps(man))
    OutputFolder.claim(tmp_path, ["a.txt"], resume=True, command="sonar-embree")
    assert json.loads((tmp_path / MANIFEST).read_text())["entries"] == whole["entries"]
