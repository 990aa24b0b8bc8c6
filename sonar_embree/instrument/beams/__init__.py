"""Beams evaluated from beam-frame directions after the path kernels (issue 51, item 2).

A beam turns unit directions in its frame (u_fwd along its first axis, u_side along its second, u_down along the
boresight) into the one-way pressure directivity b; the path kernels weigh rays with unit gain and the front end
multiplies b²(u_tx)·b²(u_rx) in afterwards (docs/physics.md §2, §11). Each beam is one file here with one line in
:data:`BEAMS`; a sonar type names its beam by key: an echo sounder's from its one-way width
(``EchoSounder(beam="square")``, :meth:`of`), a side-scan's, MSIS's or forward-looking element's from its aperture
(``Sonar(beam="gaussian")``, :meth:`of_aperture`; such a beam is separable, b = along(u_fwd)·across(u_side)).
"""
from __future__ import annotations

from ...errors import ConfigError
from .base import Beam
from .gaussian import Gaussian
from .membrane import Membrane
from .piston import CircularPiston
from .square import SquarePiston


#: The beams by name; a new beam is a module here and one line.
BEAMS = {"piston": CircularPiston, "square": SquarePiston, "membrane": Membrane, "gaussian": Gaussian}
#: The beams a side-scan, MSIS or forward-looking element can take (separable, made from an aperture).
APERTURE_BEAMS = tuple(name for name, cls in BEAMS.items() if cls.separable)


def beam_for(name: str, beamwidth_deg: float, wavelength_m: float):
    """The beam ``name`` (a :data:`BEAMS` key) with a one-way −3 dB full width ``beamwidth_deg`` at ``wavelength_m``."""
    if name not in BEAMS:
        raise ConfigError(f"beam must be one of {', '.join(repr(k) for k in BEAMS)}, got {name!r}")
    return BEAMS[name].of(beamwidth_deg, wavelength_m)


def aperture_beam(name: str, length_m: float, height_m: float, wavenumber_rad_m: float):
    """The separable beam ``name`` (one of :data:`APERTURE_BEAMS`) of an aperture ``length_m`` × ``height_m`` (m) at
    wavenumber k (rad/m)."""
    if name not in APERTURE_BEAMS:
        raise ConfigError(f"beam must be one of {', '.join(repr(k) for k in APERTURE_BEAMS)}, got {name!r}")
    return BEAMS[name].of_aperture(length_m, height_m, wavenumber_rad_m)


__all__ = ["APERTURE_BEAMS", "BEAMS", "Beam", "CircularPiston", "Gaussian", "Membrane", "SquarePiston",
           "aperture_beam", "beam_for"]
