"""sonar_embree: a physically based side-scan sonar simulator.

Any mesh scene and vehicle path in; calibrated port/starboard time series and
waterfalls out. Embree casts each ping's fan of rays, Numba kernels bin the echoes.

>>> import sonar_embree as se
>>> scene = se.Scene().add(se.seafloor.flat(size_m=(400, 200)), label="seafloor")
>>> rec = se.simulate(scene, se.Trajectory.line((0, 0, 10), (20, 0, 10), 5), se.Sonar(), se.Pulse.cw())
"""
from ._version import __version__

from . import assets, laws, raycast
from .instrument import devices
from .io import geo
from .survey import bathymetry, mosaic, planning, replay, stream
from .laws import sediments
from .config import FanSettings, Material, Pulse, SignalChain, Sonar
from .environment import AmbientNoise, Environment, SeaSurface, SoundSpeedProfile
from .errors import ConfigError, SceneError, SonarEmbreeError
from .signal.labels import Labels
from .trajectory.motion import Motion
from .laws.maps import BackscatterMap
from .laws.clutter import Clutter
from .laws.texture import KTexture
from .instrument.array import ReceiverArray
from .instrument.receiver import AGC, TVG, Receiver
from .record import Record
from .runs import batch, demo, runconfig, sweep  # not cli: python -m sonar_embree.runs.cli runs it
from .scene import Scene, TiledDEM, features, seafloor, shipwreck
from .simulate import simulate
from .sonars import MSIS, EchoSounder, ForwardLooking
from .trajectory import Trajectory

__all__ = ["AGC", "AmbientNoise", "BackscatterMap", "Clutter", "Receiver", "ReceiverArray", "bathymetry", "TVG", "KTexture", "sediments", "ConfigError", "EchoSounder", "ForwardLooking", "MSIS", "Environment", "SeaSurface", "SoundSpeedProfile", "assets", "devices", "FanSettings", "Labels", "Material", "Motion", "Pulse", "Record", "Scene", "SceneError", "TiledDEM",
           "SignalChain", "Sonar", "SonarEmbreeError", "Trajectory", "batch", "demo", "features", "geo", "laws", "mosaic", "planning", "replay", "stream", "raycast", "runconfig", "seafloor", "shipwreck", "simulate", "sweep",
           "__version__"]
