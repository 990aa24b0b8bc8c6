"""The scene: meshes and their materials in a local frame (:mod:`.meshes`), procedural floors
(:mod:`.seafloor`) and the paper's shipwreck (:mod:`.shipwreck`)."""
from .meshes import (COMPILED_CACHE, MESH_SUFFIXES, ORIGIN_GRID_M, CompiledScene, Scene, SceneObject, load_mesh,
                     survey_origin, write_obj)
from . import seafloor, shipwreck  # noqa: E402  (they build on .meshes)

__all__ = ["COMPILED_CACHE", "CompiledScene", "MESH_SUFFIXES", "ORIGIN_GRID_M", "Scene", "SceneObject", "load_mesh",
           "seafloor", "shipwreck", "survey_origin", "write_obj"]
