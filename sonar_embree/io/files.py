"""Writing files safely: every output appears whole or not at all (docs: README "Outputs").

A writer writes into a temporary name beside its target (``.tmp-*``) and renames it
into place; a killed writer leaves only such temporaries, which :func:`clean_stale`
removes on the next run.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import tempfile


#: Prefixes of the temporaries that atomic writers leave only when killed (SIGKILL, power loss).
STALE_PREFIXES = (".tmp-", ".old-")


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


def atomic_write(path, write_fn, suffix=""):
    """Call ``write_fn(tmp_path)`` then rename onto ``path``: no half-written file is ever left."""
    path = os.fspath(path)
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=d, prefix=".tmp-", suffix=suffix or os.path.splitext(path)[1])
    os.close(fd)
    try:
        write_fn(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
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
