"""Writing files safely: every output appears whole or not at all (docs/guide/datasets.md).

A writer writes into a temporary name beside its target (``.tmp-*``) and renames it
into place; a killed writer leaves only such temporaries, which :func:`clean_stale`
removes on the next run.
"""
from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import tempfile

from ..errors import ConfigError


#: Prefixes of the temporaries that atomic writers leave only when killed (SIGKILL, power loss).
STALE_PREFIXES = (".tmp-", ".old-")
#: The lock file a writer holds in a folder it is writing (:func:`folder_lock`); never a user's file.
LOCK_NAME = ".sonar-embree.lock"
#: Names in an output folder that are the project's own bookkeeping, not outputs or a user's files.
OWN_NAMES = (LOCK_NAME,)


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


def clean_stale(folder) -> int:
    """Remove the temporaries a killed writer left in ``folder`` (files and folders); return how many."""
    n = 0
    for name in os.listdir(folder):
        if name.startswith(STALE_PREFIXES):
            path = os.path.join(folder, name)
            if os.path.isdir(path) and not os.path.islink(path):
                shutil.rmtree(path, ignore_errors=True)
            else:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(path)
            n += 1
    return n


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



def _replace(src: str, dst: str) -> None:
    """Rename ``src`` onto ``dst``; a folder in the way is moved aside first, then removed."""
    if os.path.isdir(dst) and not os.path.islink(dst):
        old = tempfile.mkdtemp(dir=os.path.dirname(dst), prefix=".old-")
        os.rmdir(old)
        os.replace(dst, old)
        os.replace(src, dst)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(src, dst)


def atomic_folder(folder: str, names_and_writers) -> list:
    """Write several files into ``folder`` so that the new set lands together.

    ``names_and_writers``: (file name, ``write(path)``) pairs. Each is written into a
    temporary folder inside ``folder``, then all are renamed into place (the old
    files stay until then). Returns the paths written.
    """
    os.makedirs(folder, exist_ok=True)
    clean_stale(folder)
    tmp = tempfile.mkdtemp(dir=folder, prefix=".tmp-")
    try:
        names = []
        for name, write in names_and_writers:
            try:
                write(os.path.join(tmp, name))
            except OSError as exc:
                raise OSError(exc.errno, exc.strerror or str(exc), os.path.join(folder, name)) from None
            names.append(name)
        for name in names:  # renames only
            _replace(os.path.join(tmp, name), os.path.join(folder, name))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return [os.path.join(folder, n) for n in names]


def atomic_job_folder(target: str, write_into) -> None:
    """Call ``write_into(tmp_folder)`` and rename the folder to ``target``: it appears whole or not at all."""
    tmp = tempfile.mkdtemp(dir=os.path.dirname(os.path.abspath(target)), prefix=".tmp-")
    try:
        write_into(tmp)
        os.replace(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
