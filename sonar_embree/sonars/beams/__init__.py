"""Beams evaluated from body-frame directions after the path kernels: the echo sounder's transducer.

A beam turns unit directions in the body frame (forward, starboard, down) into the one-way pressure directivity b;
no kernel knows it: the path kernels weigh rays with unit gain and the front end multiplies b²(u_tx)·b²(u_rx) in
afterwards (docs/physics.md §11). Each beam is one file here with one line in :data:`BEAMS`; a sonar type names its
beam by key (``EchoSounder(beam="square")``).
"""
from __future__ import annotations

from ...errors import ConfigError
from .base import Beam
from .piston import CircularPiston
from .square import SquarePiston


#: The beams by name; a new beam is a module here and one line.
BEAMS = {"piston": CircularPiston, "square": SquarePiston}


def beam_for(name: str, beamwidth_deg: float, wavelength_m: float):
    """The beam ``name`` (a :data:`BEAMS` key) with a one-way −3 dB full width ``beamwidth_deg`` at ``wavelength_m``."""
    if name not in BEAMS:
        raise ConfigError(f"beam must be one of {', '.join(repr(k) for k in BEAMS)}, got {name!r}")
    return BEAMS[name].of(beamwidth_deg, wavelength_m)


__all__ = ["BEAMS", "Beam", "CircularPiston", "SquarePiston", "beam_for"]
