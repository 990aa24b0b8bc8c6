"""sonar_embree: a physically based side-scan sonar simulator.

Any mesh scene and vehicle path in; calibrated port/starboard time series and
waterfalls out. Embree casts each ping's fan of rays, Numba kernels bin the echoes.

>>> import sonar_embree as se
>>> scene = se.Scene().add(se.seafloor.flat(size_m=(400, 200)), label="seafloor")
>>> rec = se.simulate(scene, se.Trajectory.line((0, 0, 10), (20, 0, 10), 5), se.Sonar(), se.Pulse.cw())

The names below are loaded when first used (PEP 562), so that ``sonar-embree --help`` and a mistyped option answer
at once instead of after importing SciPy, Numba, Dask and xarray.
"""
import importlib
import sys
import types

from ._version import __version__

#: Public name → (module, attribute or None for the module itself), loaded on first use.
_LAZY = {
    "assets": (".assets", None), "laws": (".laws", None), "raycast": (".raycast", None),
    "devices": (".instrument.devices", None), "geo": (".io.geo", None),
    "bathymetry": (".survey.bathymetry", None), "mosaic": (".survey.mosaic", None),
    "planning": (".survey.planning", None), "replay": (".survey.replay", None), "stream": (".survey.stream", None),
    "sediments": (".laws.sediments", None),
    "FanSettings": (".config", "FanSettings"), "Material": (".config", "Material"), "Pulse": (".config", "Pulse"),
    "SignalChain": (".config", "SignalChain"), "Sonar": (".config", "Sonar"), "Acquisition": (".config", "Acquisition"),
    "AmbientNoise": (".environment", "AmbientNoise"), "Environment": (".environment", "Environment"),
    "SeaSurface": (".environment", "SeaSurface"), "SoundSpeedProfile": (".environment", "SoundSpeedProfile"),
    "ConfigError": (".errors", "ConfigError"), "SceneError": (".errors", "SceneError"),
    "SonarEmbreeError": (".errors", "SonarEmbreeError"),
    "Labels": (".signal.labels", "Labels"), "Motion": (".trajectory.motion", "Motion"),
    "BackscatterMap": (".laws.maps", "BackscatterMap"), "Clutter": (".laws.clutter", "Clutter"),
    "KTexture": (".laws.texture", "KTexture"), "ReceiverArray": (".instrument.array", "ReceiverArray"),
    "AGC": (".instrument.receiver", "AGC"), "TVG": (".instrument.receiver", "TVG"),
    "Receiver": (".instrument.receiver", "Receiver"), "Record": (".record", "Record"),
    "batch": (".runs.batch", None), "demo": (".runs.demo", None), "runconfig": (".runs.runconfig", None),
    "sweep": (".runs.sweep", None),  # not cli: python -m sonar_embree.runs.cli runs it
    "Scene": (".scene", "Scene"), "TiledDEM": (".scene", "TiledDEM"), "features": (".scene.features", None),
    "seafloor": (".scene.seafloor", None), "shipwreck": (".scene.shipwreck", None),
    "simulate": (".simulate", "simulate"), "RunCache": (".propagation.prepared", "RunCache"),
    "MSIS": (".sonars", "MSIS"), "EchoSounder": (".sonars", "EchoSounder"),
    "ForwardLooking": (".sonars", "ForwardLooking"), "Trajectory": (".trajectory", "Trajectory"),
}

__all__ = sorted(_LAZY) + ["__version__"]


def __getattr__(name):
    """Load a public name on first use (and keep it)."""
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'sonar_embree' has no attribute {name!r}") from None
    value = importlib.import_module(module, __name__)
    value = value if attr is None else getattr(value, attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


class _Package(types.ModuleType):
    """The package module: a submodule named like a public function (``simulate``) does not replace it when the
    import system binds the submodule onto the package."""

    def __setattr__(self, name, value):
        if isinstance(value, types.ModuleType) and _LAZY.get(name, (None, None))[1] is not None:
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
