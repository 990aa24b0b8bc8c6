"""Validation helpers shared by the frozen parameter dataclasses (one-line errors naming the field)."""
from __future__ import annotations

import csv
import logging
import math
import os
from dataclasses import fields

import numpy as np

from .errors import ConfigError


def check_number(owner: str, name: str, value, *, positive=False, nonneg=False,
                  lo=None, hi=None, integer=False) -> None:
    """Raise :class:`ConfigError` unless ``value`` is a finite number within bounds."""
    label = f"{owner}.{name}"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{label} must be a number, got {value!r}")
    if integer and int(value) != value:
        raise ConfigError(f"{label} must be an integer, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"{label} must be finite, got {value!r}")
    if positive and not value > 0:
        raise ConfigError(f"{label} must be > 0, got {value!r}")
    if nonneg and value < 0:
        raise ConfigError(f"{label} must be >= 0, got {value!r}")
    if lo is not None and value < lo:
        raise ConfigError(f"{label} must be >= {lo}, got {value!r}")
    if hi is not None and value > hi:
        raise ConfigError(f"{label} must be <= {hi}, got {value!r}")


def check_bool(owner: str, name: str, value, none_ok: bool = False) -> None:
    """Raise :class:`ConfigError` unless ``value`` is a real boolean (``True``/``False``, numpy's too; ``None``
    where ``none_ok``): a string such as "no" or "false" is truthy in Python and would silently mean true."""
    if value is None and none_ok:
        return
    if not isinstance(value, (bool, np.bool_)):
        what = "True, False or None" if none_ok else "True or False"
        raise ConfigError(f"{owner}.{name} must be {what} (a boolean, not a string or number), got {value!r}")


def field_names(cls) -> tuple[str, ...]:
    """Names of the constructor fields of a config dataclass (for TOML key checking)."""
    return tuple(f.name for f in fields(cls) if f.init)


def from_table(cls, table: dict, where: str):
    """``cls(**table)`` after a one-line error naming the first key that is not one of its fields."""
    unknown = sorted(set(table) - set(field_names(cls)))
    if unknown:
        raise ConfigError(f"{where}: unknown key {unknown[0]!r}; one of {', '.join(field_names(cls))}")
    return cls(**table)


def read_numeric_csv(path, required, optional=(), what="table", columns_hint=None):
    """A CSV with a header, as floats: (the columns read, (rows, columns) array).

    The columns are the ``optional`` ones the file has, then the ``required`` ones. One-line
    errors name the file: unreadable, ``required`` columns missing (``columns_hint`` spells
    them, default their names), or the first row that is not numeric (its line number).
    """
    path = os.fspath(path)
    try:
        with open(path, newline="") as fh:
            rows = list(csv.DictReader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the {what} ({exc})") from None
    if not rows or not set(required) <= set(rows[0]):
        raise ConfigError(f"{path}: a {what} needs the columns {columns_hint or ', '.join(required)}")
    cols = [c for c in optional if c in rows[0]] + list(required)
    vals = []
    for i, r in enumerate(rows):
        try:
            vals.append([float(r[c]) for c in cols])
        except (TypeError, ValueError):
            raise ConfigError(f"{path}: row {i + 2} is not numeric: {r}") from None
    return cols, np.array(vals)


def iso_utc(value=None) -> str:
    """A time as an ISO 8601 UTC string: ``None`` is now; a naive datetime is taken as UTC.

    Accepts a ``datetime.datetime``, a ``datetime.date`` (midnight) or an ISO 8601 string.
    """
    import datetime as dt

    if value is None:
        value = dt.datetime.now(dt.timezone.utc)
    elif isinstance(value, str):
        try:
            value = dt.datetime.fromisoformat(value.replace("Z", "+00:00"))
        except ValueError:
            raise ConfigError(f"start time {value!r} is not an ISO 8601 date-time "
                              "(e.g. 2026-05-01T12:00:00Z)") from None
    elif isinstance(value, dt.date) and not isinstance(value, dt.datetime):
        value = dt.datetime(value.year, value.month, value.day)
    if not isinstance(value, dt.datetime):
        raise ConfigError(f"start time must be a datetime or an ISO 8601 string, got {value!r}")
    if value.tzinfo is None:
        value = value.replace(tzinfo=dt.timezone.utc)
    return value.astimezone(dt.timezone.utc).isoformat()


#: Messages :func:`warn_once` has logged in this process.
_warned: set = set()


def warn_once(message: str) -> None:
    """Log ``message`` as a warning of ``sonar_embree.checks`` once per process (tasks of one batch repeat
    their checks)."""
    if message not in _warned:
        _warned.add(message)
        logging.getLogger("sonar_embree.checks").warning(message)
