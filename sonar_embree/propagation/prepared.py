"""One run's prepared state, by name (issue 51, item 4): what a :func:`~sonar_embree.simulate` call builds once
before its first block, and the cache a caller may hand from run to run.

:class:`PreparedRun` holds the scene's ray caster (its BVH), the law table at the carrier, the rays aimed at
objects (:class:`~sonar_embree.propagation.aim.AimPlan`), the visibility boxes and the sea surface's caster and
strips where the medium has a surface, the frozen clutter scatterers and the seafloor's own caster for ground
truth. It is built by :func:`prepare` and read, never filled, by the stages: nothing is kept on the scene, so a
scene holds no caster and no reference cycle, and a run's state ends with the run.

Runs share what they may only when asked: a :class:`RunCache` handed to each (``simulate(..., cache=...)``) keeps
the builds that depend on the scene alone or on the scene and a number (casters, law tables by carrier, clutter by
seed, visibility boxes, surfaces by surface and range) for its most recent compiled scenes; the line renderers,
the sweep's workers and the replay's fit hand one. The set-up that depends on the sonar's fan (the aim plan) is
made per run.
"""
from __future__ import annotations

import dataclasses
import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from ..laws.table import LawTable, law_table
from ..raycast import Caster
from .aim import AimPlan
from .clutter import ClutterField, clutter_field
from .multipath import leg_boxes, surface_mesh, surface_strips


class RunCache:
    """What runs on the same compiled scenes may share, handed to each on request (``simulate(..., cache=...)``).

    Keeps the builds of its ``scenes`` most recent compiled scenes (default 2: a streamed line over a tiled DEM
    moves from one set of tiles to the next), keyed by the compiled scene itself and what the build depends on;
    an older scene's builds (its BVHs) are freed when it leaves. Safe to share between threads. Sent to another
    process it arrives empty (BVHs are not sent: each process builds its own).
    """

    def __init__(self, scenes: int = 2):
        if isinstance(scenes, bool) or not isinstance(scenes, int) or scenes < 1:
            raise ValueError(f"RunCache: scenes must be an integer >= 1, got {scenes!r}")
        self.scenes = scenes
        self._kept: OrderedDict = OrderedDict()   # compiled scene → {key: build}
        self._lock = threading.RLock()

    def get(self, compiled, key, make):
        """``make()`` for ``compiled`` and ``key``, built once while the scene is kept."""
        with self._lock:
            builds = self._kept.pop(compiled, None)
            if builds is None:
                builds = {}
                while len(self._kept) >= self.scenes:
                    self._kept.popitem(last=False)
            self._kept[compiled] = builds               # the most recent last
            if key not in builds:
                builds[key] = make()
            return builds[key]

    def clear(self) -> None:
        """Drop every build (the BVHs freed at once)."""
        with self._lock:
            self._kept.clear()

    def __reduce__(self):
        return RunCache, (self.scenes,)


def _kept(cache: RunCache | None, compiled, key, make):
    return make() if cache is None else cache.get(compiled, key, make)


@dataclass(frozen=True, eq=False)
class SeafloorCaster:
    """A caster over a scene's seafloor objects alone (ground truth's shadows behind objects): ``caster`` and
    ``faces`` (f',) int64, the scene's triangle of each of its triangles (None: the scene's own, every object is
    seafloor); ``caster`` None without any seafloor."""

    caster: Caster | None
    faces: np.ndarray | None


@dataclass(frozen=True, eq=False)
class PreparedRun:
    """Everything one run builds before its first block, by name.

    Attributes
    ----------
    caster : Caster
        The scene's ray caster (its ``compiled`` the scene's local arrays).
    laws : tuple
        Each object's scattering law at the carrier (its bistatic σ for the sea surface's paths).
    law_table : LawTable
        The same laws tabled for the kernels (:func:`sonar_embree.laws.table.law_table`).
    aim : AimPlan or None
        The objects rays are aimed at, for the front end's fan (None: none, or the type does not aim).
    leg_boxes : tuple or None
        The visibility boxes without and with height fields (:func:`~sonar_embree.propagation.multipath.leg_boxes`),
        where the medium has a sea surface.
    surface_caster : Caster or None
        The sea surface meshed over the scene ± the range, where it is a swell or scatters itself.
    surface_law_table : LawTable or None
        The surface mesh's law at the carrier (its own backscatter).
    surface_strips : object or None
        The swell's mesh grid (:meth:`~sonar_embree.environment.SeaSurface.strips`), where the surface is a swell.
    clutter : ClutterField or None
        The scene's frozen clutter scatterers for the run's seed.
    seafloor : SeafloorCaster or None
        The seafloor's own caster, where ground truth is made.
    """

    caster: Caster
    laws: tuple
    law_table: LawTable
    aim: AimPlan | None = None
    leg_boxes: tuple | None = None
    surface_caster: Caster | None = None
    surface_law_table: LawTable | None = None
    surface_strips: object = None
    clutter: ClutterField | None = None
    seafloor: SeafloorCaster | None = None

    @property
    def compiled(self):
        """The scene's compiled arrays (the caster's)."""
        return self.caster.compiled


def scene_caster(compiled, caster_cls: type, cache: RunCache | None = None) -> Caster:
    """A ``caster_cls`` caster (its BVH) over ``compiled``: built here, or taken from ``cache``."""
    return _kept(cache, compiled, ("caster", caster_cls), lambda: caster_cls(compiled))


def prepare(caster: Caster, front, frequency_hz: float, max_range_m: float, seed: int, labels: bool = False,
            cache: RunCache | None = None) -> PreparedRun:
    """The :class:`PreparedRun` of a run over the scene of ``caster`` (:func:`scene_caster`) with the front end
    ``front`` (its fan, aim and medium), the carrier ``frequency_hz`` (Hz), the range searched ``max_range_m`` (m),
    the chain's ``seed`` and whether ``labels`` are made; what ``cache`` holds is taken from it (and what it lacks
    is kept there)."""
    compiled, f = caster.compiled, float(frequency_hz)
    laws = _kept(cache, compiled, ("laws", f), lambda: tuple(law.at_frequency(f) for law in compiled.laws))
    parts = dict(laws=laws, law_table=_kept(cache, compiled, ("law table", f), lambda: law_table(laws, f)),
                 aim=front.aim_plan(compiled),
                 clutter=_kept(cache, compiled, ("clutter", int(seed)), lambda: clutter_field(compiled, int(seed))),
                 seafloor=seafloor_caster(caster, compiled.is_seafloor, cache) if labels else None)
    surface = front.sonar.environment.surface
    if surface is not None:
        parts.update(_surface_parts(compiled, surface, f, max_range_m, cache))
    return PreparedRun(caster, **parts)


def _surface_parts(compiled, surface, frequency_hz: float, max_range_m: float, cache) -> dict:
    """The visibility boxes, and the surface's mesh (a swell, or a surface that scatters itself), its law table and
    a swell's strips, over ``compiled`` ± ``max_range_m``."""
    parts = dict(leg_boxes=_kept(cache, compiled, ("leg boxes",),
                                 lambda: (leg_boxes(compiled, False), leg_boxes(compiled, True))))
    key = (surface, round(float(max_range_m), 6))
    if not surface.is_flat or surface.backscatter is not None:
        mesh = _kept(cache, compiled, ("surface",) + key, lambda: surface_mesh(compiled, surface, max_range_m))
        parts.update(surface_caster=mesh, surface_law_table=_kept(
            cache, compiled, ("surface laws", frequency_hz) + key, lambda: law_table(mesh.compiled.laws, frequency_hz)))
    if not surface.is_flat:
        parts["surface_strips"] = _kept(cache, compiled, ("strips",) + key,
                                        lambda: surface_strips(compiled, surface, max_range_m))
    return parts


def seafloor_caster(caster: Caster, is_seafloor, cache: RunCache | None = None) -> SeafloorCaster:
    """The :class:`SeafloorCaster` of ``caster``'s scene: ``caster`` itself when every object is seafloor, a
    caster of the same class over the seafloor objects only otherwise (a second BVH: labels of scenes with
    objects only)."""
    c, sea = caster.compiled, np.asarray(is_seafloor, dtype=bool)
    if not sea.any():
        return SeafloorCaster(None, None)
    if sea.all():
        return SeafloorCaster(caster, None)

    def make():
        faces = np.flatnonzero(sea[c.face_object])
        sub = dataclasses.replace(c, faces=c.faces[faces], face_normals=c.face_normals[faces],
                                  face_object=c.face_object[faces])
        return SeafloorCaster(type(caster)(sub), faces)
    return _kept(cache, c, ("seafloor", type(caster), sea.tobytes()), make)
