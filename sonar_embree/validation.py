"""Validation helpers shared by the frozen parameter dataclasses (one-line errors naming the field)."""
from __future__ import annotations

import math
from dataclasses import fields

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


def field_names(cls) -> tuple[str, ...]:
    """Names of the constructor fields of a config dataclass (for TOML key checking)."""
    return tuple(f.name for f in fields(cls) if f.init)
