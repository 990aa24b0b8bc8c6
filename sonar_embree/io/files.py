"""Writing files safely: every output appears whole or not at all (docs/guide/datasets.md).

A writer writes into a temporary name beside its target (a new name, created exclusively: never a user's file)
and renames it into place. Folders of outputs have one owner, :mod:`sonar_embree.io.owner`.
"""
from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import tempfile

from ..errors import ConfigError


#: The lock file a writer holds in a folder it is writing (:func:`folder_lock`); never a user's file.
LOCK_NAME = ".sonar-embree.lock"


@contextlib.contextmanager
def folder_lock(folder):
    """Hold an exclusive lock on ``folder`` (its :data:`LOCK_NAME` file) while writing into it.

    A second writer of the same folder, in this process or another, is refused with a one-line
    :class:`~sonar_embree.errors.ConfigError`; the operating system drops the lock when its holder dies
    (``flock``), so a killed run never leaves the folder locked. The lock file is removed on release.
    """
    import fcntl

    lock = os.path.join(os.fspath(folder), LOCK_NAME)
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            same = os.path.exists(lock) and os.stat(lock).st_ino == os.fstat(fd).st_ino
        except OSError as exc:
            if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise
            same = False
        if not same:                                        # held, or released and removed under us
            raise ConfigError(f"{os.fspath(folder)}: another run is writing this folder now (it holds "
                              f"{LOCK_NAME}); wait for it to end")
        try:
            yield
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(lock)                             # while still held: the next writer makes a new one
    finally:
        os.close(fd)                                        # closing drops the lock


def fsync_path(path) -> None:
    """Flush a file (or a folder's entries) to the disk, so that a power loss cannot undo it."""
    fd = os.open(os.fspath(path), os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_json_durable(obj, path) -> None:
    """Write ``obj`` as JSON to ``path`` atomically and durably: a temporary beside it, fsynced, renamed onto
    ``path``, and the folder fsynced (after a crash the file holds either the old or the new whole object)."""
    path = os.fspath(path)
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as fh:
        json.dump(obj, fh, sort_keys=True)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    fsync_path(os.path.dirname(os.path.abspath(path)))


def os_error_line(exc: OSError, path) -> ConfigError:
    """A one-line error naming ``path`` for an operating-system failure (disk full, permission, …)."""
    what = exc.strerror or str(exc.__cause__ or exc).splitlines()[0]
    hint = "; free some space, then run again to resume" if exc.errno == errno.ENOSPC else ""
    return ConfigError(f"{os.fspath(path)}: cannot write ({what}){hint}")


#: The first bytes of each format the writers replace: an existing file that does not start so is not one the
#: project wrote (a user's document given as an output path) and is refused, never overwritten.
MAGIC = {".npz": (b"PK",), ".png": (b"\x89PNG",), ".tif": (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"),
         ".xtf": (b"\x7b",), ".json": (b"{", b"["), ".csv": (b"time_s,", b"time,"),
         ".obj": (b"#", b"o ", b"v ", b"g ", b"mtllib"), ".xyz": (b"# x_m y_m z_m",)}


def check_replaceable(path: str, suffix: str) -> None:
    """Refuse to replace an existing non-empty file at ``path`` that is not of the format being written
    (:data:`MAGIC`, by ``suffix``): the writers replace their own kind of file, never a foreign one."""
    magic = MAGIC.get(suffix.lower())
    if magic is None or not os.path.isfile(path) or os.path.getsize(path) == 0:
        return
    with open(path, "rb") as fh:
        head = fh.read(16).lstrip() if suffix.lower() == ".json" else fh.read(16)
    if not head.startswith(magic):
        raise ConfigError(f"{path}: exists and is not a {suffix[1:].upper()} file; it would be overwritten, so "
                          "choose another name (or remove it yourself)")


def atomic_write(path, write_fn, suffix=""):
    """Call ``write_fn(tmp_path)`` then rename onto ``path``: no half-written file is ever left. An existing
    file of another format (:func:`check_replaceable`), a folder in the way and a missing folder are refused."""
    path = os.fspath(path)
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        raise ConfigError(f"{path}: its folder {d} does not exist")
    if os.path.isdir(path):
        raise ConfigError(f"{path}: is a folder, not a file")
    check_replaceable(path, suffix or os.path.splitext(path)[1])
    try:
        fd, tmp = tempfile.mkstemp(dir=d, prefix=".tmp-", suffix=suffix or os.path.splitext(path)[1])
    except OSError as exc:
        raise os_error_line(exc, path) from None
    os.close(fd)
    try:
        write_fn(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError):                        # disk full, permissions: one line naming the target
            raise os_error_line(exc, path) from None
        raise
