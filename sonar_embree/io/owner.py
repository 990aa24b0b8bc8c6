"""One owner for every output folder: a manifest of what a command wrote, so that it never replaces what it
did not write (docs/guide/datasets.md, "Output folders").

Every command that writes a folder (render, demo, batch, survey and its lines, replay) claims it through
:meth:`OutputFolder.claim`, which writes the folder's manifest (:data:`MANIFEST`) before anything else, so that a
killed run's folder is recognisably its own. The manifest lists each file or folder the run wrote with its size and
SHA-256 (a folder: a digest of its files' names, sizes and hashes), and each temporary the run is about to create,
listed before it exists; the next run removes only those. ``overwrite`` replaces only entries of the manifest whose
digest still matches; any other file in a target's place is refused, naming it, before any work. No name prefix is
reserved: a user's ``.tmp-notes`` or ``.old-photos`` is never touched. An input that is (or aliases, by inode) an
output is refused before any work.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import threading
import uuid

from ..errors import ConfigError
from .files import LOCK_NAME

#: Set by the command line's Ctrl-C handler (:func:`sonar_embree.runs.cli.main`): a KeyboardInterrupt can be lost
#: (raised inside a finaliser, as Numba's compiler runs some, Python prints it and goes on), so no output set is written
#: once it is set (:meth:`OutputFolder.write_set` raises KeyboardInterrupt instead).
INTERRUPTED = threading.Event()

#: The manifest's name inside an output folder.
MANIFEST = ".sonar-embree-manifest.json"
#: The manifest's ``format`` value: a file of that name without it is not ours and is refused.
FORMAT = "sonar_embree output manifest 1"
#: The manifest's next version, written whole and then renamed onto :data:`MANIFEST` (a kill between leaves it).
MANIFEST_NEW = MANIFEST + ".new"
#: How every manifest this package writes begins (``json.dump(sort_keys=True, indent=1)``): a file named
#: :data:`MANIFEST_NEW` that begins otherwise is a user's, and is refused, never replaced.
_HEAD = b'{\n "command": "'


#: An entry written before its content is complete (a streamed line): ours, its digest not yet known.
IN_PROGRESS = "in progress"
#: A folder entry that keeps its own manifest (a survey's line): ours while that manifest is.
MANAGED = "own manifest"


def _is_our_new(path: str) -> bool:
    """Whether ``path`` (a :data:`MANIFEST_NEW`) is one a killed save of ours left: empty, or begun as ours."""
    with open(path, "rb") as fh:
        head = fh.read(len(_HEAD))
    return _HEAD.startswith(head)


def digest(path: str) -> dict:
    """Size and SHA-256 of the file ``path``; of a folder, its files' count and a SHA-256 over their relative
    names, sizes and hashes (sorted)."""
    if os.path.isdir(path) and not os.path.islink(path):
        h, n = hashlib.sha256(), 0
        for root, dirs, files in os.walk(path):
            dirs.sort()
            for name in sorted(files):
                p = os.path.join(root, name)
                h.update(f"{os.path.relpath(p, path)}\0{_file_hash(p)}\n".encode())
                n += 1
        return {"kind": "folder", "files": n, "sha256": h.hexdigest()}
    return {"kind": "file", "size": os.path.getsize(path), "sha256": _file_hash(path)}


def _file_hash(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def refuse_aliases(outputs, inputs) -> None:
    """Refuse, before any work, an input that is an output path or a hard link of one (same inode), or that lies
    inside an output folder."""
    for src in inputs:
        if src is None or not os.path.exists(src):
            continue
        real = os.path.realpath(src)
        for out in outputs:
            if not os.path.exists(out):
                continue
            same = os.path.samefile(src, out)
            inside = os.path.isdir(out) and real.startswith(os.path.realpath(out) + os.sep)
            if same or inside:
                raise ConfigError(f"{out}: is the input {os.fspath(src)} (or holds it); the run would overwrite its "
                                  "own input, so choose another output folder")


def read_manifest(folder: str) -> dict | None:
    """The manifest of ``folder`` (None: none there); a file of its name that is not ours is refused."""
    path = os.path.join(folder, MANIFEST)
    if not os.path.lexists(path):
        return None
    try:
        with open(path, encoding="utf-8") as fh:
            man = json.load(fh)
    except (OSError, ValueError):
        man = None
    if not isinstance(man, dict) or man.get("format") != FORMAT or not isinstance(man.get("entries"), dict) \
            or not isinstance(man.get("pending"), list):
        raise ConfigError(f"{path}: not a sonar-embree manifest; the folder is not a sonar-embree output, so choose "
                          "another folder")
    return man


class OutputFolder:
    """A folder claimed by one run: its manifest, kept on disk after every change (atomically).

    Use :meth:`claim`; then :meth:`write_set` (files and folders written whole) or :meth:`reserve` and
    :meth:`record` (a file or folder written in place, as a streamed line is).
    """

    def __init__(self, path: str, manifest: dict, created: bool = False):
        self.path = path
        self._man = manifest
        self.created = created
        self.run_id = uuid.uuid4().hex[:12]

    def __enter__(self) -> "OutputFolder":
        return self

    def __exit__(self, kind, exc, tb) -> None:
        """A run that fails before writing anything leaves no folder its rerun refuses: an empty manifest is
        removed, and the folder too if this claim made it."""
        if kind is not None and not self._man["entries"]:
            self.forget()
            if self.created:
                with contextlib.suppress(OSError):
                    os.rmdir(self.path)

    # -- claiming ---------------------------------------------------------------------------------------------
    @staticmethod
    def check(path, names, *, overwrite: bool = False, resume: bool = False, inputs=(),
              command: str = "sonar-embree") -> dict | None:
        """What :meth:`claim` checks, writing nothing (validation before work); returns the folder's manifest.

        A new or empty folder passes. A folder holding anything else is refused unless ``overwrite`` (replace this
        project's earlier outputs) or ``resume`` (continue a run of the same ``command`` whose manifest is there).
        Either way each of
        ``names`` already present must be an entry of the folder's manifest, unchanged since it was written (or
        an entry written in place and not finished); anything else is refused naming it. Inputs equal to,
        hard-linked to or inside an output are refused.
        """
        path = os.path.abspath(os.fspath(path))
        if os.path.lexists(path) and not os.path.isdir(path):
            raise ConfigError(f"{path}: exists and is not a folder")
        names = list(names)
        refuse_aliases([path] + [os.path.join(path, n) for n in names], [os.fspath(i) for i in inputs if i])
        man = read_manifest(path) if os.path.isdir(path) else None
        new = os.path.join(path, MANIFEST_NEW)
        if os.path.lexists(new) and not (os.path.isfile(new) and _is_our_new(new)):
            raise ConfigError(f"{new}: not a sonar-embree manifest; the folder is not a sonar-embree output, so choose "
                              "another folder")
        skip = {MANIFEST, MANIFEST_NEW, LOCK_NAME, *(man or {}).get("pending", ())}
        held = sorted(n for n in (os.listdir(path) if os.path.isdir(path) else ()) if n not in skip)
        if held and not (overwrite or (resume and man is not None and man.get("command") == command)):
            hint = "add --overwrite to replace its earlier outputs" if man is not None else "add --overwrite"
            raise ConfigError(f"{path}: not empty (holds {held[0]!r}); choose another folder or {hint}")
        for name in names:
            _check_replaceable(path, name, man)
        return man

    @classmethod
    def claim(cls, path, names, *, overwrite: bool = False, resume: bool = False, inputs=(),
              command: str = "sonar-embree") -> "OutputFolder":
        """Own ``path`` for a run that will write ``names`` (entries of this folder), after :meth:`check`; the
        folder is made and its manifest written (the temporaries a killed run listed removed) before this
        returns. Used as a context manager, a run that fails before writing an entry leaves nothing."""
        path = os.path.abspath(os.fspath(path))
        man = cls.check(path, names, overwrite=overwrite, resume=resume, inputs=inputs, command=command)
        created = not os.path.isdir(path)
        try:
            os.makedirs(path, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"{path}: cannot create the folder ({exc.strerror})") from None
        out = cls(path, man or {"format": FORMAT, "command": command, "entries": {}, "pending": []}, created)
        out._man["command"] = command
        out._settle()
        out._drop_pending()
        return out

    # -- the manifest -----------------------------------------------------------------------------------------
    @property
    def entries(self) -> dict:
        return dict(self._man["entries"])

    def _save(self) -> None:
        """The manifest written whole to :data:`MANIFEST_NEW`, fsynced and renamed onto :data:`MANIFEST` (a kill
        leaves the old or the new one; a left-over :data:`MANIFEST_NEW` is recognised as ours by its head)."""
        tmp = os.path.join(self.path, MANIFEST_NEW)
        if os.path.lexists(tmp) and not (os.path.isfile(tmp) and _is_our_new(tmp)):
            raise ConfigError(f"{tmp}: not a sonar-embree manifest; it would be replaced, so move it away")
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump(self._man, fh, sort_keys=True, indent=1)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, os.path.join(self.path, MANIFEST))
        with contextlib.suppress(OSError):
            fd = os.open(self.path, os.O_RDONLY)
            os.fsync(fd)
            os.close(fd)

    def _settle(self) -> None:
        """Entries a killed run renamed into place but had not yet recorded (its digest already known as
        ``next``) are recorded as written."""
        for name, entry in self._man["entries"].items():
            target = os.path.join(self.path, name)
            if entry.get("state") == IN_PROGRESS and "next" in entry and os.path.lexists(target):
                if digest(target) == entry["next"]:
                    self._man["entries"][name] = entry["next"]

    def _drop_pending(self) -> None:
        """Remove the temporaries an earlier (killed) run listed, then save the manifest."""
        for name in self._man["pending"]:
            _remove(os.path.join(self.path, name))
        self._man["pending"] = []
        self._save()

    def reserve(self, name: str) -> str:
        """Record ``name`` as this run's, unfinished, before its first byte; return its path."""
        _check_replaceable(self.path, name, self._man)
        self._man["entries"][name] = {"state": IN_PROGRESS}
        self._save()
        return os.path.join(self.path, name)

    def record(self, *names: str) -> None:
        """Record the finished entries ``names`` with their digests (missing ones are dropped)."""
        for name in names:
            p = os.path.join(self.path, name)
            if os.path.lexists(p):
                self._man["entries"][name] = digest(p)
            else:
                self._man["entries"].pop(name, None)
        self._save()

    def record_managed(self, name: str) -> None:
        """Record the folder ``name`` as one with its own manifest (its files are checked by that)."""
        self._man["entries"][name] = {"state": MANAGED}
        self._save()

    def forget(self) -> None:
        """Remove the manifest (a run that wrote nothing leaves no folder that refuses a rerun)."""
        with contextlib.suppress(FileNotFoundError):
            os.unlink(os.path.join(self.path, MANIFEST))

    # -- writing ----------------------------------------------------------------------------------------------
    def write_set(self, names_and_writers) -> list:
        """Write several entries so that the new set lands together.

        ``names_and_writers``: (name, ``write(path)``) pairs; ``write`` makes a file or a folder at ``path``, a
        name in a private folder of this run (listed in the manifest before it exists); a writer that makes
        nothing leaves its entry out. Each target is checked again (ours and unchanged) before the renames.
        Returns the paths written. Nothing is written once :data:`INTERRUPTED` is set (a Ctrl-C that was lost).
        """
        if INTERRUPTED.is_set():
            raise KeyboardInterrupt
        pairs = list(names_and_writers)
        tmp_name = f".sonar-embree-{self.run_id}"
        self._man["pending"].append(tmp_name)
        self._save()
        tmp = os.path.join(self.path, tmp_name)
        try:
            os.mkdir(tmp)
            for name, write in pairs:
                try:
                    write(os.path.join(tmp, name))
                except OSError as exc:
                    raise OSError(exc.errno, exc.strerror or str(exc), os.path.join(self.path, name)) from None
            made = [name for name, _ in pairs if os.path.lexists(os.path.join(tmp, name))]
            for name in made:
                _check_replaceable(self.path, name, self._man)
            digests = {name: digest(os.path.join(tmp, name)) for name in made}
            for name in made:                               # ours from before the rename: a kill between is resumable
                self._man["entries"][name] = {"state": IN_PROGRESS, "next": digests[name]}
            self._save()
            for name in made:
                _replace(os.path.join(tmp, name), os.path.join(self.path, name), tmp)
                self._man["entries"][name] = digests[name]
        finally:
            _remove(tmp)
            self._man["pending"].remove(tmp_name)
            self._save()
        return [os.path.join(self.path, n) for n in made]


def _check_replaceable(path: str, name: str, man: dict | None) -> None:
    """Refuse a target of ``name`` in ``path`` that the manifest ``man`` does not list as written and unchanged."""
    target = os.path.join(path, name)
    if not os.path.lexists(target):
        return
    entry = (man or {}).get("entries", {}).get(name)
    if entry is None:
        raise ConfigError(f"{target}: not written by sonar-embree (the folder's manifest does not list it); it "
                          "would be replaced, so move it away or choose another folder")
    if entry.get("state") == IN_PROGRESS:                     # recorded before its first byte: ours
        return
    if entry.get("state") == MANAGED and os.path.isdir(target) and read_manifest(target) is not None:
        return
    now = digest(target)
    if now == {k: entry.get(k) for k in now}:
        return
    raise ConfigError(f"{target}: changed since sonar-embree wrote it; it would be replaced, so move it away "
                      "or choose another folder")


def _replace(src: str, dst: str, scratch: str) -> None:
    """Rename ``src`` onto ``dst``; a folder in the way (ours, checked) is moved into ``scratch`` first."""
    if os.path.isdir(dst) and not os.path.islink(dst):
        os.replace(dst, os.path.join(scratch, ".replaced-" + os.path.basename(dst)))
    os.replace(src, dst)


def _remove(path: str) -> None:
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)
