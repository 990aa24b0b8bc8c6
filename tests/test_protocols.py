"""Declared protocols (issue 36, item 4): each stage asks its collaborators through a declared interface with one
default, never by probing attributes."""
import ast
import dataclasses
import os

import numpy as np
import pytest
import trimesh

import sonar_embree as se
from sonar_embree import sonars
from sonar_embree.config import FanSettings, Transducer
from sonar_embree.laws import LAWS, Composite, Summable
from sonar_embree.propagation.echoes import Echoes, merged
from sonar_embree.sonars.base import FrontEnd

PACKAGE = os.path.join(os.path.dirname(__file__), os.pardir, "sonar_embree")
#: Where a ``hasattr`` would be dispatch on a collaborator's type (the stages of a ping).
#: Every module of the package: none may dispatch on a collaborator's type by probing its attributes.
SOURCES = sorted(os.path.join(d, f) for d, _, fs in os.walk(PACKAGE) for f in fs if f.endswith(".py"))


def _trees():
    for p in SOURCES:
        yield os.path.relpath(p, PACKAGE), ast.parse(open(p, encoding="utf-8").read())


def test_no_module_dispatches_on_hasattr():
    """No ``hasattr(x, name)`` or ``getattr(x, name, default)`` anywhere in the package (survey/ and runs/ too)."""
    found = [f"{name}:{n.lineno}" for name, tree in _trees() for n in ast.walk(tree)
             if isinstance(n, ast.Call) and (getattr(n.func, "id", None) == "hasattr"
                                             or getattr(n.func, "id", None) == "getattr" and len(n.args) == 3)]
    assert found == []


def test_no_module_dispatches_on_a_class_name_or_a_sonar_type():
    """No comparison with ``type(x).__name__`` and no ``isinstance(x, <sonar type>)`` outside the sonar types' own
    registry: a sonar type says what it models through its declared flags and methods."""
    names = {c.__name__ for c in sonars.SONAR_TYPES}
    found = []
    for name, tree in _trees():
        if name.startswith("sonars" + os.sep):
            continue
        for n in ast.walk(tree):
            if isinstance(n, ast.Compare) and any(
                    isinstance(side, ast.Attribute) and side.attr == "__name__"
                    and isinstance(side.value, ast.Call) and getattr(side.value.func, "id", None) == "type"
                    for side in [n.left, *n.comparators]):
                found.append(f"{name}:{n.lineno} compares a class name")
            if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "isinstance" and len(n.args) == 2:
                kinds = n.args[1].elts if isinstance(n.args[1], ast.Tuple) else [n.args[1]]
                if any(getattr(k, "id", getattr(k, "attr", None)) in names for k in kinds):
                    found.append(f"{name}:{n.lineno} isinstance of a sonar type")
    assert found == []


@pytest.mark.parametrize("sonar_cls", sonars.SONAR_TYPES)
def test_every_front_end_follows_the_protocol(sonar_cls):
    sonar = sonar_cls().for_pulse(se.Pulse.cw())
    front = sonars.front_end(se.Acquisition.of(sonar), FanSettings())
    assert isinstance(front, FrontEnd)
    assert type(front).cast is not FrontEnd.cast                          # the one part without a default
    assert front.channels == sonar.channels and front.synth_channels >= len(front.channels)
    assert front.beamforms == (front.beam_power is not None)
    if front.beamforms:
        assert front.beam_power.shape == (len(front.channels), front.synth_channels)
    rot = np.repeat(np.eye(3)[None], 3, axis=0)
    mounted = front.mount(rot, np.arange(3))
    assert mounted.shape == (3, 3, 3)
    np.testing.assert_allclose(np.einsum("pij,pkj->pik", mounted, mounted), rot, atol=1e-12)   # rotations


def test_the_protocol_defaults():
    class Bare(FrontEnd):
        channels = ("a", "b", "c")

    f, rot = Bare(), np.zeros((2, 3, 3))
    assert f.mount(rot, np.arange(2)) is rot and f.label_lines(None) is None
    assert f.synth_channels == 3 and not f.beamforms and not f.supports_labels and not f.aims
    with pytest.raises(NotImplementedError, match="Bare.cast"):
        f.cast(None, rot, None, 1.0, False, False, {})
    with pytest.raises(NotImplementedError, match="Bare forms no beams"):
        f.beamform(None, None, None)


@pytest.mark.parametrize("sonar_cls", sonars.SONAR_TYPES)
def test_every_sonar_type_declares_what_its_front_end_models(sonar_cls):
    assert issubclass(sonar_cls, Transducer)
    for flag in ("tilted", "models_surface", "models_refraction", "models_clutter_and_volume", "forms_beams"):
        assert isinstance(getattr(sonar_cls, flag), bool), flag
    assert sonar_cls.tilted == ("tilt_deg" in {f.name for f in dataclasses.fields(sonar_cls)})


def test_a_sonar_type_that_declares_no_surface_or_profile_is_refused_them():
    """models_surface and models_refraction are read as declared (every shipped type models both now): a type that
    declares False gets a one-line error naming the environment's key and the type."""
    import dataclasses

    @dataclasses.dataclass(frozen=True)
    class Dry(se.EchoSounder):
        models_surface = False
        models_refraction = False

    from sonar_embree.sonars import FRONT_ENDS, EchoSounderFrontEnd
    scene = se.Scene().add(se.seafloor.flat(size_m=(60, 60)), label="seafloor")
    traj = se.Trajectory.line((0, 0, 10), (1, 0, 10), 2)
    FRONT_ENDS[Dry] = EchoSounderFrontEnd
    try:
        for env, key in ((se.Environment(surface=se.SeaSurface(z_m=20.0)), "Environment.surface"),
                         (se.Environment(sound_speed=se.SoundSpeedProfile.linear(1500.0, 0.1, surface_z_m=20.0)),
                          "Environment.sound_speed")):
            with pytest.raises(se.ConfigError, match=f"{key}: .* Dry"):
                se.simulate(scene, traj, Dry(max_range_m=20.0), se.Pulse.cw(), environment=env)
            se.simulate(scene, traj, se.EchoSounder(max_range_m=20.0), se.Pulse.cw(), environment=env)
    finally:
        del FRONT_ENDS[Dry]


@pytest.mark.parametrize("name, law", sorted(LAWS.items()))
def test_every_law_is_summable_and_has_a_carrier_form(name, law):
    assert issubclass(law, Summable) and callable(law.at_frequency)


def test_a_carrier_free_law_is_itself_at_any_carrier():
    lam = se.laws.Lambert(0.01)
    assert lam.at_frequency(1e5) is lam
    both = lam + se.laws.Kirchhoff(0.5, 0.1)
    assert isinstance(both, Composite) and both.at_frequency(4e5).terms() == both.terms()


def test_merged_echoes_are_themselves():
    e = Echoes(2, np.zeros(3, np.int64), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, 3)),
               np.zeros(0, np.int32))
    assert e.merged() is e and merged(e) is e and e.parts == (e,)


def test_a_run_prepares_its_state_by_name_and_shares_it_only_on_request():
    """Issue 51, item 4: a compiled scene keeps nothing of the runs over it (no caster, table or cache field); a
    run's caster, law table, aim plan, boxes and surfaces are the named fields of its PreparedRun; a RunCache
    handed from run to run shares them (the same objects), runs without one build their own, and a RunCache sent to
    another process arrives empty."""
    import pickle

    from sonar_embree.propagation.prepared import PreparedRun, RunCache, prepare, scene_caster
    from sonar_embree.raycast import NumpyCaster

    scene = se.Scene().add(se.seafloor.flat(size_m=(20, 20)), label="seafloor")
    scene.add(trimesh.creation.box((1.0, 1.0, 1.0)), label="box")
    c = scene.compiled(np.zeros(3))
    fields = {f.name for f in dataclasses.fields(c)}
    assert not fields & {"prepared", "casters", "cache"} and [k for k in vars(c) if k.startswith("_")] == []
    sonar = se.Acquisition(se.Sonar(), se.Environment(surface=se.SeaSurface(z_m=10.0, swell_height_m=0.4)))
    front = sonars.front_end(sonar.for_pulse(se.Pulse.cw()), se.FanSettings())
    cache = RunCache()
    runs = [prepare(scene_caster(c, NumpyCaster, cache), front, sonar.frequency_hz, 30.0, 1, True, cache)
            for _ in range(2)]
    alone = prepare(scene_caster(c, NumpyCaster), front, sonar.frequency_hz, 30.0, 1, True)
    for name in ("caster", "law_table", "leg_boxes", "surface_caster", "surface_strips", "seafloor"):
        assert getattr(runs[0], name) is getattr(runs[1], name) is not None, name
        assert getattr(alone, name) is not getattr(runs[0], name), name
    assert isinstance(alone, PreparedRun) and alone.aim is not None and alone.aim.objects.tolist() == [1]
    back = pickle.loads(pickle.dumps(cache))
    assert isinstance(back, RunCache) and back.scenes == cache.scenes and not back._kept
    with pytest.raises(ValueError, match="scenes"):
        RunCache(scenes=0)
    with pytest.raises(se.ConfigError, match="cache must be a sonar_embree.RunCache"):
        se.simulate(scene, se.Trajectory.line((0, 0, 5), (1, 0, 5), 2), cache={})


def test_no_lazy_caches_of_run_state():
    """No ``cached_property`` anywhere in the package (derived values are made when their owner is built), and an
    ``lru_cache`` only on a pure function of numbers and strings (every parameter annotated int, float or str): no
    cache keyed on a plan, a scene or a sonar that outlives its run."""
    plain = {"int", "float", "str"}
    found = []
    for name, tree in _trees():
        for n in ast.walk(tree):
            if isinstance(n, (ast.Name, ast.Attribute)) and getattr(n, "id", getattr(n, "attr", None)) == \
                    "cached_property":
                found.append(f"{name}:{n.lineno} cached_property")
            if not isinstance(n, ast.FunctionDef):
                continue
            cached = any("lru_cache" in ast.unparse(d) or ast.unparse(d).endswith(".cache") for d in n.decorator_list)
            args = n.args.args + n.args.kwonlyargs
            if cached and not all(a.annotation is not None and
                                  set(ast.unparse(a.annotation).replace(" ", "").split("|")) <= plain for a in args):
                found.append(f"{name}:{n.lineno} lru_cache on {n.name}({', '.join(a.arg for a in args)})")
    assert found == []
