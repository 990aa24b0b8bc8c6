"""Sonar types: each declares its channels, its body-frame ray fan and its per-direction gain.

A sonar type is a configuration dataclass (its instrument) and a front end that
turns a block of poses into :class:`~sonar_embree.propagation.echoes.Echoes`. A new type is one
module here and one line in :data:`FRONT_ENDS`.
"""
from __future__ import annotations

from ..config import Sonar
from ..errors import ConfigError
from .echosounder import EchoSounder, EchoSounderFrontEnd
from .forward_looking import ForwardLooking, ForwardLookingFrontEnd
from .msis import MSIS, MSISFrontEnd
from .sidescan import SideScanFrontEnd

#: The front end of each sonar configuration class.
FRONT_ENDS = {Sonar: SideScanFrontEnd, EchoSounder: EchoSounderFrontEnd, MSIS: MSISFrontEnd,
              ForwardLooking: ForwardLookingFrontEnd}

SONAR_TYPES = tuple(FRONT_ENDS)


def front_end(acquisition, fan):
    """The front end of ``acquisition`` (an :class:`~sonar_embree.config.Acquisition` of a :data:`SONAR_TYPES`
    instance) with ray density ``fan``."""
    for cls, fe in FRONT_ENDS.items():
        if type(acquisition.sonar) is cls:
            return fe(acquisition, fan)
    raise ConfigError(f"simulate: sonar must be one of {', '.join(c.__name__ for c in SONAR_TYPES)}, "
                      f"got {type(acquisition.sonar).__name__}")


__all__ = ["EchoSounder", "FRONT_ENDS", "ForwardLooking", "MSIS", "SONAR_TYPES", "front_end"]
