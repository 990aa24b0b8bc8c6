"""The scene: meshes and their materials in a local frame (:mod:`.meshes`), procedural and measured floors
(:mod:`.seafloor`), DEMs larger than memory (:mod:`.tiles`) and the paper's shipwreck (:mod:`.shipwreck`)."""
from .meshes import (COMPILED_CACHE, MESH_SUFFIXES, ORIGIN_GRID_M, CompiledScene, Scene, SceneObject, load_mesh,
                     survey_origin, write_obj)
from . import features, seafloor, shipwreck  # noqa: E402  (they build on .meshes)
from .tiles import TiledDEM  # noqa: E402

__all__ = ["COMPILED_CACHE", "CompiledScene", "MESH_SUFFIXES", "ORIGIN_GRID_M", "Scene", "SceneObject", "load_mesh",
           "seafloor", "shipwreck", "survey_origin", "TiledDEM", "write_obj"]
