"""Files shipped inside the package: example scenes, run configs and sweeps.

>>> import sonar_embree as se
>>> se.assets.path("anchor_mine.obj")        # an absolute path, from any working folder
>>> se.assets.names("configs")               # ('anchor_mine.toml', ...)

Config and sweep files may name them as ``asset:NAME`` (``path = "asset:wreck.obj"``),
so a shipped config copied anywhere keeps working; ``sonar-embree examples`` lists
them and copies one out.
"""
from __future__ import annotations

import os
from importlib import resources

from ..errors import ConfigError

#: Sub-folders, by kind.
KINDS = ("scenes", "configs", "sweeps")
#: Prefix of a path that names a shipped file.
PREFIX = "asset:"


def _root():
    return resources.files(__name__)


def names(kind: str | None = None) -> tuple:
    """Names of the shipped files of one kind (``"scenes"``, ``"configs"``, ``"sweeps"``) or of all."""
    kinds = KINDS if kind is None else (kind,)
    out = []
    for k in kinds:
        if k not in KINDS:
            raise ConfigError(f"asset kind must be one of {list(KINDS)}, got {k!r}")
        out += sorted(e.name for e in _root().joinpath(k).iterdir() if e.is_file() and not e.name.startswith("."))
    return tuple(out)


def path(name: str) -> str:
    """Absolute path of a shipped file (``"anchor_mine.obj"``, ``"anchor_mine.toml"``, ``"asset:…"``)."""
    if not isinstance(name, str):
        raise ConfigError(f"asset name must be a string, got {name!r}")
    name = name[len(PREFIX):] if name.startswith(PREFIX) else name
    for k in KINDS:
        entry = _root().joinpath(k, name)
        if entry.is_file():
            return os.fspath(entry)
    raise ConfigError(f"no shipped asset {name!r} (there are: {', '.join(names())})")
