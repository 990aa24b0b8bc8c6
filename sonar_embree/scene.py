"""Scenes: labelled meshes with materials, held in float64 around a local origin.

trimesh is the only mesh reader. Geometry keeps its world coordinates in float64;
:meth:`Scene.compiled` subtracts a local origin (the bounds centre rounded to 1 m)
so UTM-sized coordinates keep full precision when they later reach Embree in
float32 (PHYSICS.md §8).
"""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass

import numpy as np
import trimesh

from .config import Material
from .errors import SceneError

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf", ".off")


@dataclass(frozen=True)
class SceneObject:
    """One labelled mesh of a scene: float64 world vertices (v, 3), int faces (f, 3)."""

    label: str
    vertices: np.ndarray
    faces: np.ndarray
    material: Material
    seafloor: bool = False


@dataclass(frozen=True, eq=False)
class CompiledScene:
    """Flat arrays of a whole scene in the local frame, as ray casting and echo terms need them.

    Attributes
    ----------
    origin_m : (3,) float64
        World position of the local origin.
    vertices : (v, 3) float64
        Vertices relative to ``origin_m``.
    faces : (f, 3) int32
        Triangles (indices into ``vertices``).
    face_normals : (f, 3) float64
        Unit geometric normals, from the float64 vertices.
    face_object : (f,) int32
        Object index of each triangle.
    labels : tuple of str
        Label per object.
    mu : (n_objects,) float64
        Linear Lambert coefficient per object.
    is_seafloor : (n_objects,) bool
        Which objects are seafloor (ground truth: their hidden parts are shadow).
    """

    origin_m: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    face_normals: np.ndarray
    face_object: np.ndarray
    labels: tuple
    mu: np.ndarray
    is_seafloor: np.ndarray


def _validate(vertices, faces, source: str):
    """Check and clean one mesh; return float64 vertices and int faces without degenerate triangles."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if f.size == 0 or v.size == 0:
        raise SceneError(f"{source}: mesh has no faces")
    if v.ndim != 2 or v.shape[1] != 3:
        raise SceneError(f"{source}: vertices must have shape (n, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise SceneError(f"{source}: faces must be triangles of shape (n, 3), got {f.shape}")
    if not np.all(np.isfinite(v)):
        raise SceneError(f"{source}: mesh has NaN or infinite vertex coordinates")
    if not np.issubdtype(f.dtype, np.integer) or f.min() < 0 or f.max() >= v.shape[0]:
        raise SceneError(f"{source}: face indices out of range")
    tri = v[f]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(cross, axis=1)
    scale = float(np.ptp(v, axis=0).max())
    good = area2 > 1e-12 * max(scale, 1e-300) ** 2
    if not np.any(good):
        raise SceneError(f"{source}: mesh has only degenerate (zero-area) triangles")
    if not np.all(good):
        log.info("%s: dropped %d degenerate triangles", source, int((~good).sum()))
    return v, f[good].astype(np.int64)


def load_mesh(path) -> trimesh.Trimesh:
    """One mesh file as a single ``trimesh.Trimesh`` (all its objects joined), checked like :meth:`Scene.add`."""
    path = os.fspath(path)
    parts = _meshes_from_file(path)
    mesh = parts[0][1] if len(parts) == 1 else trimesh.util.concatenate([m for _, m in parts])
    v, f = _validate(mesh.vertices, mesh.faces, path)
    return trimesh.Trimesh(v, f, process=False)


def write_obj(path, named_meshes, comment: str = "") -> None:
    """Write ``(name, trimesh.Trimesh)`` pairs as one OBJ, one ``o name`` object each (atomic).

    Coordinates in metres with 10 µm resolution (``%.5f``); :meth:`Scene.load` reads
    the objects back as separately labelled parts.
    """
    from .record import atomic_write

    def write(tmp):
        lines, base = [f"# {line}" for line in comment.splitlines()], 1
        for name, mesh in named_meshes:
            lines.append(f"o {name}")
            lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in np.asarray(mesh.vertices)]
            lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in np.asarray(mesh.faces)]
            base += len(mesh.vertices)
        with open(tmp, "w") as fh:
            fh.write("\n".join(lines) + "\n")

    atomic_write(path, write, suffix=".obj")


def _meshes_from_file(path: str):
    """(name, Trimesh) pairs of a mesh file, scene-graph transforms applied."""
    if not os.path.exists(path):
        raise SceneError(f"{path}: mesh file not found")
    if os.path.isdir(path):
        raise SceneError(f"{path}: is a directory, not a mesh file")
    try:
        extra = {"split_objects": True, "group_material": False} if path.lower().endswith(".obj") else {}
        loaded = trimesh.load(path, process=False, **extra)
    except Exception as exc:  # trimesh raises many types for unreadable files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise SceneError(f"{path}: cannot read mesh ({msg})") from None
    if isinstance(loaded, trimesh.Trimesh):
        return [(os.path.splitext(os.path.basename(path))[0], loaded)]
    if isinstance(loaded, trimesh.Scene):
        out = []
        for node in loaded.graph.nodes_geometry:
            transform, geom_name = loaded.graph[node]
            geom = loaded.geometry[geom_name]
            if not isinstance(geom, trimesh.Trimesh):
                continue
            mesh = geom.copy()
            mesh.apply_transform(transform)
            out.append((str(node), mesh))
        if not out:
            raise SceneError(f"{path}: mesh has no faces")
        return sorted(out, key=lambda item: item[0])  # loaders differ in order; sort for determinism
    raise SceneError(f"{path}: mesh has no faces (got {type(loaded).__name__})")


class Scene:
    """A set of labelled meshes with one :class:`Material` each.

    Build with :meth:`add` (chainable) or :meth:`load`. Labels must be unique.
    """

    def __init__(self):
        self._objects: list[SceneObject] = []
        self._compiled: CompiledScene | None = None

    @classmethod
    def load(cls, path, material: Material | None = None, materials: dict | None = None) -> "Scene":
        """A scene from one mesh file; each object of a multi-object file keeps its name as label
        (objects are added in sorted label order).

        Parameters
        ----------
        path : str or PathLike
            OBJ, PLY, STL, GLB/GLTF or OFF file, in metres, z up.
        material : Material, optional
            Material of objects not named in ``materials`` (default μ = −27 dB).
        materials : dict of str to Material, optional
            Material per object label.
        """
        scene = cls()
        scene.add(path, material=material, materials=materials)
        return scene

    def add(self, mesh_or_path, material: Material | None = None, label: str | None = None,
            materials: dict | None = None, seafloor: bool | None = None) -> "Scene":
        """Add a mesh (a ``trimesh.Trimesh``) or every object of a mesh file.

        Parameters
        ----------
        mesh_or_path : trimesh.Trimesh or str or PathLike
            The geometry, world metres.
        material : Material, optional
            Its material; default :class:`Material` ().
        label : str, optional
            Its label. For a file with several objects the labels become
            ``label/name``; without ``label`` each object is labelled by its name.
        materials : dict of str to Material, optional
            Per-object materials by (final) label, for multi-object files.
        seafloor : bool, optional
            Whether this is seafloor (for ground-truth labels: seafloor hidden
            behind other surfaces is shadow, everything else is an object). By
            default an object is seafloor when its label is ``"seafloor"`` or
            starts with ``"seafloor/"``.

        Returns
        -------
        Scene
            ``self``, for chaining.
        """
        if material is not None and not isinstance(material, Material):
            raise SceneError(f"material must be a sonar_embree.Material, got {type(material).__name__}")
        material = material or Material()
        materials = dict(materials or {})
        if isinstance(mesh_or_path, (str, os.PathLike)):
            path = os.fspath(mesh_or_path)
            parts = _meshes_from_file(path)
            items = []
            for name, mesh in parts:
                if label is None:
                    lab = name
                elif len(parts) == 1:
                    lab = label
                else:
                    lab = f"{label}/{name}"
                items.append((lab, mesh, f"{path} (object {name!r})" if len(parts) > 1 else path))
        elif isinstance(mesh_or_path, trimesh.Trimesh):
            lab = label if label is not None else f"object{len(self._objects)}"
            items = [(lab, mesh_or_path, f"mesh {lab!r}")]
        else:
            raise SceneError(f"Scene.add expects a trimesh.Trimesh or a file path, got {type(mesh_or_path).__name__}")
        unknown = set(materials) - {lab for lab, _, _ in items}
        if unknown:
            raise SceneError(f"materials name unknown object {sorted(unknown)[0]!r}")
        new = []
        taken = set(self.labels)
        for lab, mesh, source in items:
            if lab in taken:
                raise SceneError(f"{source}: label {lab!r} is already in the scene")
            taken.add(lab)
            v, f = _validate(mesh.vertices, mesh.faces, source)
            floor = (lab == "seafloor" or lab.startswith("seafloor/")) if seafloor is None else bool(seafloor)
            new.append(SceneObject(lab, v, f, materials.get(lab, material), floor))
        self._objects.extend(new)
        self._compiled = None
        return self

    @property
    def objects(self) -> tuple:
        return tuple(self._objects)

    @property
    def labels(self) -> tuple:
        return tuple(o.label for o in self._objects)

    @property
    def n_faces(self) -> int:
        return int(sum(o.faces.shape[0] for o in self._objects))

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) world min and max corner (m)."""
        if not self._objects:
            raise SceneError("scene is empty: add a mesh or a seafloor first")
        lo = np.min([o.vertices.min(axis=0) for o in self._objects], axis=0)
        hi = np.max([o.vertices.max(axis=0) for o in self._objects], axis=0)
        return np.array([lo, hi])

    def compiled(self) -> CompiledScene:
        """Flat float64 local-frame arrays of the whole scene (cached until the next :meth:`add`)."""
        if self._compiled is None:
            b = self.bounds
            origin = np.round(0.5 * (b[0] + b[1]))
            verts, faces, obj = [], [], []
            offset = 0
            for i, o in enumerate(self._objects):
                verts.append(o.vertices - origin)
                faces.append(o.faces + offset)
                obj.append(np.full(o.faces.shape[0], i, dtype=np.int32))
                offset += o.vertices.shape[0]
            v = np.concatenate(verts)
            f = np.concatenate(faces).astype(np.int32)
            tri = v[f]
            n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            n /= np.linalg.norm(n, axis=1)[:, None]
            self._compiled = CompiledScene(origin, v, f, n, np.concatenate(obj), self.labels,
                                           np.array([o.material.mu for o in self._objects]),
                                           np.array([o.seafloor for o in self._objects], dtype=bool))
        return self._compiled
