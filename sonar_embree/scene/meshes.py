"""Scenes: labelled meshes with materials, held in float64 around a local origin.

trimesh is the only mesh reader. Geometry keeps its world coordinates in float64;
:meth:`Scene.compiled` subtracts a local origin so UTM-sized coordinates keep full
precision when they later reach Embree in float32 (docs/physics.md §8). A
simulation puts that origin where its rays are (:func:`survey_origin`: the
trajectory's centre on a 1 km grid), so geometry far from the survey (a stray box
at 10⁸ m) cannot cost the survey precision.
"""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..config import Material
from ..errors import SceneError
from ..validation import check_bool
from ..laws.maps import BackscatterMap, MapTable
from ..laws.texture import TextureTable
from .heightfield import is_heightfield, object_bounds
from .tolerance import TOLERANCE, MeshTolerance  # noqa: F401  (MeshTolerance: documented here too)
from ..io.files import atomic_write
from .seafloor import sediment_classes

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf", ".off")
#: Grid of the survey-centred local origins, m: surveys within it share one compiled scene and BVH,
#: and float32 keeps ~0.1 mm within a few km of the origin.
ORIGIN_GRID_M = 1000.0
#: Compiled scenes (each with its BVH) kept per scene, by origin.
COMPILED_CACHE = 2


def survey_origin(positions_m) -> np.ndarray:
    """The local origin for rays from ``positions_m`` (n, 3): their bounding-box centre on the
    :data:`ORIGIN_GRID_M` grid (z on a 1 m grid)."""
    p = np.asarray(positions_m, dtype=np.float64)
    c = 0.5 * (p.min(axis=0) + p.max(axis=0))
    return np.array([np.round(c[0] / ORIGIN_GRID_M) * ORIGIN_GRID_M,
                     np.round(c[1] / ORIGIN_GRID_M) * ORIGIN_GRID_M, np.round(c[2])])


@dataclass(frozen=True)
class SceneObject:
    """One labelled mesh of a scene: float64 world vertices (v, 3), int faces (f, 3)."""

    label: str
    vertices: np.ndarray
    faces: np.ndarray
    material: Material
    seafloor: bool = False
    backscatter_map: BackscatterMap | None = None
    uv: np.ndarray | None = None


def _clutter_of(objects) -> tuple:
    """Each object's clutter (or None); empty when no object has any (a scene without clutter pays nothing)."""
    c = tuple(o.material.clutter for o in objects)
    return c if any(x is not None for x in c) else ()


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
        Linear Lambert coefficient per object (NaN for objects of another law).
    laws : tuple
        The scattering law of each object (:func:`sonar_embree.laws.apply_laws` tables them per frequency).
    maps : MapTable or None
        The objects' backscatter maps (:mod:`sonar_embree.laws.maps`), None without any.
    textures : TextureTable or None
        The materials' K textures (:mod:`sonar_embree.laws.texture`), None without any.
    clutter : tuple
        Each object's :class:`~sonar_embree.laws.clutter.Clutter` or None (empty: none anywhere).
    is_seafloor : (n_objects,) bool
        Which objects are seafloor (ground truth: their hidden parts are shadow).
    two_sided : (n_objects,) bool
        Which objects scatter from both sides of their faces.
    """

    origin_m: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    face_normals: np.ndarray
    face_object: np.ndarray
    labels: tuple
    mu: np.ndarray
    is_seafloor: np.ndarray
    two_sided: np.ndarray
    laws: tuple = ()
    maps: object = None
    textures: object = None
    clutter: tuple = ()
    face_two_sided: np.ndarray = field(init=False, repr=False, compare=False)
    bounds_local: np.ndarray = field(init=False, repr=False, compare=False)
    object_bounds: np.ndarray = field(init=False, repr=False, compare=False)
    horizontal_area_share: float = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        """The derived geometry every run reads, made once with the scene (no lazy caches): ``face_two_sided`` (f,)
        bool, triangles of two-sided objects; ``bounds_local`` (2, 3) the vertices' min and max corner, m;
        ``object_bounds`` (n_objects, 2, 3) each object's; ``horizontal_area_share`` the share of the surface area
        whose faces look up or down (|n_z| > 0.7; :func:`sonar_embree.checks.check_scene`)."""
        tri = self.vertices[self.faces]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        derived = dict(face_two_sided=self.two_sided[self.face_object],
                       bounds_local=np.array([self.vertices.min(axis=0), self.vertices.max(axis=0)]),
                       object_bounds=object_bounds(self.vertices, self.faces, self.face_object, len(self.labels)),
                       horizontal_area_share=float(area[np.abs(self.face_normals[:, 2]) > 0.7].sum()
                                                   / max(area.sum(), 1e-300)))
        for name, value in derived.items():
            object.__setattr__(self, name, value)

    @property
    def needs_points(self) -> bool:
        """Whether the surface pass needs the hit points (maps or texture)."""
        return self.maps is not None or self.textures is not None


def heightfield_objects(compiled: CompiledScene) -> np.ndarray:
    """(n_objects,) bool: which objects of ``compiled`` are height fields over their xy rectangle
    (:func:`~sonar_embree.scene.heightfield.is_heightfield`)."""
    return np.array([is_heightfield(compiled.vertices, compiled.faces[compiled.face_object == o])
                     for o in range(len(compiled.labels))], dtype=bool)


def object_slopes(compiled: CompiledScene) -> np.ndarray:
    """(n_objects,) the steepest face of each object: max √(n_x² + n_y²)/n_z (tan of its slope; inf where a face
    is vertical or looks down)."""
    n = compiled.face_normals
    with np.errstate(divide="ignore", invalid="ignore"):
        tan = np.where(n[:, 2] > 0.0, np.hypot(n[:, 0], n[:, 1]) / n[:, 2], np.inf)
    out = np.zeros(len(compiled.labels))
    np.maximum.at(out, compiled.face_object, tan)
    return out


def _outlier(v: np.ndarray, f: np.ndarray, source: str) -> None:
    """Refuse, naming it, the first used vertex beyond the absolute bounds of :data:`TOLERANCE`."""
    used = np.unique(f)
    w = v[used]
    far = np.abs(w).max(axis=1) > TOLERANCE.max_coordinate_m
    z_mid = float(np.median(w[:, 2]))
    high = np.abs(w[:, 2] - z_mid) > TOLERANCE.max_height_offset_m
    if far.any():
        k = int(np.flatnonzero(far)[0])
        why = f"lies beyond {TOLERANCE.max_coordinate_m:g} m of the origin, no place on Earth (a corrupt file?)"
    elif high.any():
        k = int(np.argmax(np.abs(w[:, 2] - z_mid)))
        why = (f"lies {w[k, 2] - z_mid:+.6g} m from the mesh's median height {z_mid:.6g} m, beyond any relief "
               "(a spike or an undeclared nodata value?)")
    else:
        return
    x, y, z = w[k]
    raise SceneError(f"{source}: vertex {int(used[k])} at ({x:.6g}, {y:.6g}, {z:.6g}) m {why}; fix or remove it")


def _validate(vertices, faces, source: str):
    """Check and clean one mesh; return float64 vertices, int faces without degenerate triangles, and which
    of the given faces were kept. The checks are absolute (:data:`TOLERANCE`): an outlier vertex is refused,
    degenerate triangles are dropped and counted in a log line (a warning when they are over 1 % of them)."""
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
    _outlier(v, f, source)
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    good = area > TOLERANCE.min_area_m2
    if not np.any(good):
        raise SceneError(f"{source}: mesh has only degenerate triangles (area under {TOLERANCE.min_area_m2:g} m²; "
                         "a mesh in metres?)")
    dropped = int((~good).sum())
    if dropped:
        (log.warning if dropped > 0.01 * good.size else log.info)(
            "%s: dropped %d of %d triangles as degenerate (area under %g m², first: face %d)", source, dropped,
            good.size, TOLERANCE.min_area_m2, int(np.flatnonzero(~good)[0]))
    return v, f[good].astype(np.int64), good


#: File formats whose axes are fixed by their specification: glTF 2.0 is y up (§3.4 of the spec).
Y_UP_FORMATS = (".glb", ".gltf")
UP_AXES = ("z", "y")


def _up_axis(path: str, up_axis) -> str:
    """The up axis to read ``path`` with: the given one, else y for glTF/GLB and z for the rest."""
    if up_axis is None:
        return "y" if path.lower().endswith(Y_UP_FORMATS) else "z"
    if up_axis not in UP_AXES:
        raise SceneError(f"{path}: up_axis must be one of {list(UP_AXES)}, got {up_axis!r}")
    return up_axis


def _to_z_up(mesh: trimesh.Trimesh, up_axis: str) -> trimesh.Trimesh:
    """``mesh`` with a y-up frame turned to z up: (x, y, z) → (x, −z, y), a +90° turn about x."""
    if up_axis == "z":
        return mesh
    v = np.asarray(mesh.vertices, dtype=np.float64)
    return trimesh.Trimesh(np.column_stack([v[:, 0], -v[:, 2], v[:, 1]]), mesh.faces, process=False)


def load_mesh(path, up_axis: str | None = None) -> trimesh.Trimesh:
    """One mesh file as a single ``trimesh.Trimesh`` (all its objects joined), checked like :meth:`Scene.add`."""
    path = os.fspath(path)
    parts = _meshes_from_file(path, up_axis)
    mesh = parts[0][1] if len(parts) == 1 else trimesh.util.concatenate([m for _, m in parts])
    v, f, _ = _validate(mesh.vertices, mesh.faces, path)
    return trimesh.Trimesh(v, f, process=False)


def write_obj(path, named_meshes, comment: str = "") -> None:
    """Write ``(name, trimesh.Trimesh)`` pairs as one OBJ, one ``o name`` object each (atomic).

    Coordinates in metres with 10 µm resolution (``%.5f``); :meth:`Scene.load` reads
    the objects back as separately labelled parts.
    """
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


_FORMAT_NAMES = {".obj": "OBJ", ".ply": "PLY", ".stl": "STL", ".glb": "GLB", ".gltf": "glTF", ".off": "OFF"}


def _sniff(path: str, head: bytes, size: int) -> None:
    """Raise a one-line :class:`SceneError` when the file's first bytes cannot be its format's."""
    ext = os.path.splitext(path)[1].lower()
    fmt = _FORMAT_NAMES.get(ext)
    if fmt is None:
        raise SceneError(f"{path}: unknown mesh format {ext or '(no extension)'!r} "
                         f"(one of {', '.join(MESH_SUFFIXES)})")
    ok = True
    if ext in (".obj", ".off", ".gltf"):
        ok = b"\0" not in head  # text formats
    elif ext == ".ply":
        ok = head.startswith(b"ply")
    elif ext == ".glb":
        ok = head.startswith(b"glTF")
    elif ext == ".stl":  # ASCII ("solid …") or binary: 80-byte header, count, 50 bytes per triangle
        count = int.from_bytes(head[80:84], "little") if len(head) >= 84 else -1
        ok = (head.lstrip().startswith(b"solid") and b"\0" not in head) or 84 + 50 * count == size
    if not ok or size == 0:
        what = "empty" if size == 0 else f"not a valid {fmt} file"
        raise SceneError(f"{path}: {what} (its contents do not match the {ext} extension)")


def _load_trimesh(path: str):
    """trimesh's loader on ``path``; OBJ text is decoded here (UTF-8, else Latin-1), so a stray byte in
    a comment does not depend on optional charset packages."""
    ext = os.path.splitext(path)[1].lower()
    if ext != ".obj":
        return trimesh.load(path, process=False)
    with open(path, "rb") as fh:
        raw = fh.read()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    import io

    return trimesh.load(io.BytesIO(text.encode("utf-8")), file_type="obj", process=False, split_objects=True,
                        group_material=False, resolver=trimesh.resolvers.FilePathResolver(path))


def _meshes_from_file(path: str, up_axis: str | None = None):
    """(name, Trimesh) pairs of a mesh file, scene-graph transforms applied, turned z up."""
    up = _up_axis(path, up_axis)
    return [(name, _to_z_up(mesh, up)) for name, mesh in _read_meshes(path)]


def _read_meshes(path: str):
    if not os.path.exists(path):
        raise SceneError(f"{path}: mesh file not found")
    if os.path.isdir(path):
        raise SceneError(f"{path}: is a directory, not a mesh file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
        size = os.path.getsize(path)
    except OSError as exc:
        raise SceneError(f"{path}: cannot read mesh ({exc.strerror or exc})") from None
    _sniff(path, head, size)
    try:
        loaded = _load_trimesh(path)
    except Exception as exc:  # trimesh raises many types for unreadable files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise SceneError(f"{path}: cannot read mesh as {_FORMAT_NAMES[os.path.splitext(path)[1].lower()]} "
                         f"({msg})") from None
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


def _object_map(bmap, mesh, kept: np.ndarray, source: str):
    """The map of one mesh, per-face values following the faces kept, and its UVs for an image map."""
    if bmap is None:
        return None, None
    if not isinstance(bmap, BackscatterMap):
        raise SceneError(f"{source}: backscatter_map must be a sonar_embree.BackscatterMap, got {type(bmap).__name__}")
    if bmap.kind == "face":
        if bmap.values_db.shape[0] != kept.size:
            raise SceneError(f"{source}: a per-face map needs {kept.size} values, got {bmap.values_db.shape[0]}")
        return BackscatterMap.per_face(bmap.values_db[kept]), None
    if bmap.kind == "vertex" and bmap.values_db.shape[0] != len(mesh.vertices):
        raise SceneError(f"{source}: a per-vertex map needs {len(mesh.vertices)} values, got {bmap.values_db.shape[0]}")
    if bmap.kind != "image":
        return bmap, None
    uv = bmap.uv if bmap.uv is not None else (mesh.visual.uv if isinstance(mesh.visual, trimesh.visual.TextureVisuals)
                                               else None)
    if uv is None or len(uv) != len(mesh.vertices):
        raise SceneError(f"{source}: an image map needs UV coordinates per vertex (export the mesh with UVs, "
                         "or give BackscatterMap.image(..., uv=...))")
    return bmap, np.asarray(uv, dtype=np.float64)


class Scene:
    """A set of labelled meshes with one :class:`Material` each.

    Build with :meth:`add` (chainable) or :meth:`load`. Labels must be unique.
    """

    def __init__(self):
        self._objects: list[SceneObject] = []
        self._crs: str | None = None
        self._compiled: dict = {}  # origin (x, y, z) -> CompiledScene, the last COMPILED_CACHE

    @classmethod
    def load(cls, path, material: Material | None = None, materials: dict | None = None,
             up_axis: str | None = None) -> "Scene":
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
        up_axis : {"z", "y"}, optional
            The file's up axis; see :meth:`add`.
        """
        scene = cls()
        scene.add(path, material=material, materials=materials, up_axis=up_axis)
        return scene

    def add(self, mesh_or_path, material: Material | None = None, label: str | None = None,
            materials: dict | None = None, seafloor: bool | None = None, up_axis: str | None = None,
            backscatter_map: BackscatterMap | None = None) -> "Scene":
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
        up_axis : {"z", "y"}, optional
            Which axis of a mesh file points up. Default: "y" for GLB/glTF (y up by
            their specification), "z" for OBJ, PLY, STL and OFF, which carry no axis
            convention; "y" turns an export with y up (Blender's default OBJ axes)
            to z up: (x, y, z) → (x, −z, y). Meshes passed as objects are z up.
        backscatter_map : BackscatterMap, optional
            A dB offset on the material's law per face, per vertex or from an image
            through the mesh's UV coordinates (:mod:`sonar_embree.laws.maps`); for
            every object added.

        Returns
        -------
        Scene
            ``self``, for chaining.
        """
        if material is not None and not isinstance(material, Material):
            raise SceneError(f"material must be a sonar_embree.Material, got {type(material).__name__}")
        check_bool("Scene.add", "seafloor", seafloor, none_ok=True)
        material = material or Material()
        materials = dict(materials or {})
        if isinstance(mesh_or_path, (str, os.PathLike)):
            path = os.fspath(mesh_or_path)
            parts = _meshes_from_file(path, up_axis)
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
            if up_axis not in (None, "z"):
                raise SceneError("Scene.add: up_axis applies to mesh files; turn a Trimesh yourself")
            lab = label if label is not None else f"object{len(self._objects)}"
            items = [(lab, mesh_or_path, f"mesh {lab!r}")]
        else:
            raise SceneError(f"Scene.add expects a trimesh.Trimesh or a file path, got {type(mesh_or_path).__name__}")
        unknown = set(materials) - {lab for lab, _, _ in items}
        if unknown:
            raise SceneError(f"materials name unknown object {sorted(unknown)[0]!r}")
        crs = self._crs_of(items)
        new = []
        taken = set(self.labels)
        for lab, mesh, source in items:
            if lab in taken:
                raise SceneError(f"{source}: label {lab!r} is already in the scene")
            taken.add(lab)
            v, f, kept = _validate(mesh.vertices, mesh.faces, source)
            floor = (lab == "seafloor" or lab.startswith("seafloor/")) if seafloor is None else seafloor
            bmap, uv = _object_map(backscatter_map, mesh, kept, source)
            new.append(SceneObject(lab, v, f, materials.get(lab, material), floor, bmap, uv))
        self._objects.extend(new)
        self.release()
        self._crs = crs
        return self

    def _crs_of(self, items) -> str | None:
        """The scene's CRS with meshes ``items`` added: theirs (``mesh.metadata["crs"]``, as
        :func:`~sonar_embree.seafloor.from_dem` sets it) must agree with the scene's."""
        crs = self._crs
        for _, mesh, source in items:
            own = mesh.metadata.get("crs")
            if own is not None and crs is not None and own != crs:
                raise SceneError(f"{source}: its CRS {own} differs from the scene's {crs}")
            crs = own if own is not None else crs
        return crs

    @property
    def crs(self) -> str | None:
        """The projected CRS of the scene's world metres ("EPSG:…"), from the meshes that carry one (a DEM);
        None: local metres."""
        return self._crs

    def add_sediments(self, mesh: trimesh.Trimesh, sediments: dict, patch_m: float = 20.0, seed: int = 0,
                      label: str = "seafloor") -> "Scene":
        """Add a seafloor as patches of sediment classes, one object ``label/<class>`` per class.

        Each class is a separate seafloor object, so the ground truth's ``object_id``
        names the sediment under every seafloor sample (a segmentation mask; see
        :meth:`sonar_embree.Labels.seafloor_class`).

        Parameters
        ----------
        mesh : trimesh.Trimesh
            The floor (e.g. :func:`sonar_embree.seafloor.flat`).
        sediments : dict of str to (Material, law or (that, fraction))
            Class name → its material or law (a preset of :mod:`sonar_embree.laws.sediments`),
            optionally with its share of the floor (default equal shares).
        patch_m, seed
            See :func:`sonar_embree.seafloor.sediment_classes`.
        """
        if not isinstance(sediments, dict) or not sediments:
            raise SceneError("add_sediments needs a dict of class name -> material or sediment")
        names, mats, shares = [], [], []
        for name, spec in sediments.items():
            spec, share = spec if isinstance(spec, tuple) else (spec, 1.0)
            names.append(str(name).replace(" ", "_"))
            mats.append(spec if isinstance(spec, Material) else Material(scattering=spec))
            shares.append(share)
        cls = sediment_classes(mesh, shares, patch_m, seed)
        for k, (name, mat) in enumerate(zip(names, mats)):
            faces = np.flatnonzero(cls == k)
            if faces.size:
                self.add(mesh.submesh([faces], append=True), material=mat, label=f"{label}/{name}", seafloor=True)
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

    def compiled(self, origin_m=None) -> CompiledScene:
        """Flat float64 arrays of the whole scene relative to ``origin_m`` (cached until the next :meth:`add`).

        Parameters
        ----------
        origin_m : (3,) float, optional
            World position of the local origin; default the bounds centre rounded to
            1 m. :func:`~sonar_embree.simulate` passes :func:`survey_origin` of its
            trajectory.
        """
        origin = np.round(0.5 * (self.bounds[0] + self.bounds[1])) if origin_m is None else \
            np.asarray(origin_m, dtype=np.float64).reshape(3)
        key = tuple(float(x) for x in origin)
        if key not in self._compiled:
            while len(self._compiled) >= COMPILED_CACHE:
                self._compiled.pop(next(iter(self._compiled)))
            self._compiled[key] = self._compile(origin)
        return self._compiled[key]

    def release(self) -> None:
        """Drop the compiled scenes (their arrays; nothing else is kept with a scene: casters live in a run's
        :class:`~sonar_embree.propagation.prepared.PreparedRun` or a caller's ``RunCache``)."""
        self._compiled = {}

    def _compile(self, origin: np.ndarray) -> CompiledScene:
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
        return CompiledScene(origin, v, f, n, np.concatenate(obj), self.labels,
                             np.array([o.material.mu for o in self._objects]),
                             np.array([o.seafloor for o in self._objects], dtype=bool),
                             np.array([o.material.two_sided for o in self._objects], dtype=bool),
                             tuple(o.material.scattering for o in self._objects), MapTable.build(self._objects),
                             TextureTable.build([o.material.texture for o in self._objects]),
                             _clutter_of(self._objects))
