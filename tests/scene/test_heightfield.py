"""Which meshes are height fields over their xy rectangle (sonar_embree.scene.heightfield): a sufficient test,
so every mesh that is not one, or that it cannot prove is one, must come out False."""
import numpy as np
import pytest
import trimesh

import sonar_embree as se
from sonar_embree.scene.heightfield import is_heightfield, object_bounds
from sonar_embree.scene.meshes import heightfield_objects


def _check(mesh) -> bool:
    return is_heightfield(np.asarray(mesh.vertices), np.asarray(mesh.faces))


@pytest.mark.parametrize("mesh", [se.seafloor.flat((40.0, 20.0)),
                                  se.seafloor.perlin((20.0, 30.0), resolution_m=0.5, relief_m=2.0),
                                  se.seafloor.ripples((10.0, 10.0), resolution_m=0.1)], ids=["flat", "perlin", "ripples"])
def test_grids_of_heights_are_height_fields(mesh):
    assert _check(mesh)


def _grid(n=6, z=None):
    z = np.zeros((n, n)) if z is None else z
    return se.seafloor.from_heights(z, spacing_m=1.0)


def test_meshes_that_are_not_or_not_provably_height_fields():
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    down = _grid()
    down.faces = down.faces[:, ::-1]                                  # facing down
    stacked = trimesh.util.concatenate([_grid(), _grid(z=np.ones((6, 6)))])   # two sheets: covers twice
    holed = _grid()
    holed.faces = np.delete(np.asarray(holed.faces), [12, 37], axis=0)   # a hole: inner edges without a reverse
    patched = trimesh.util.concatenate([holed, trimesh.Trimesh(                # the hole's area laid twice elsewhere:
        np.asarray(_grid().vertices)[np.asarray(_grid().faces)[[12, 37]].ravel()] + [1.0, 1.0, 0.5],
        np.arange(6).reshape(2, 3), process=False)])                    # area right, edges inside: caught there
    turned = _grid(z=np.random.default_rng(0).uniform(0, 1, (6, 6)))
    turned.apply_transform(trimesh.transformations.rotation_matrix(0.3, [0, 0, 1]))   # not over its rectangle
    folded = _grid()
    v = np.asarray(folded.vertices).copy()
    v[v[:, 0] == 3.0, 0] = 4.5                                        # a column pushed past the next: overlap
    folded = trimesh.Trimesh(v, folded.faces, process=False)
    for name, mesh in dict(box=box, down=down, stacked=stacked, holed=holed, patched=patched, turned=turned,
                            folded=folded).items():
        assert not _check(mesh), name


def test_compiled_scene_knows_its_height_fields_and_boxes():
    plate = trimesh.creation.box((2.0, 2.0, 1.0))
    plate.apply_translation((0.0, 5.0, 3.0))
    scene = se.Scene().add(se.seafloor.perlin((20.0, 20.0), resolution_m=1.0, relief_m=0.5), label="seafloor")
    scene.add(plate, label="box")
    c = scene.compiled(np.zeros(3))
    assert heightfield_objects(c).tolist() == [True, False]
    np.testing.assert_allclose(c.object_bounds[1], [[-1.0, 4.0, 2.5], [1.0, 6.0, 3.5]])
    lo, hi = c.object_bounds[0]
    assert lo[0] == -10.0 and hi[1] == 10.0 and hi[2] - lo[2] <= 1.0
    empty = object_bounds(c.vertices, c.faces[:0], c.face_object[:0], 1)
    assert np.all(np.isinf(empty))


def test_object_bounds_match_a_loop_over_objects():
    """object_bounds (one sorted pass) against each object's own min and max, objects interleaved and one empty
    (objects share no vertices, as in a compiled scene)."""
    rng = np.random.default_rng(3)
    vertices = rng.normal(size=(300, 3)) * [10.0, 5.0, 1.0]
    vertex_object = rng.choice([0, 1, 3], 300)                          # interleaved; object 2 has nothing
    face_object = rng.choice([0, 1, 3], 200).astype(np.int32)
    faces = np.array([rng.choice(np.flatnonzero(vertex_object == o), 3) for o in face_object])
    got = object_bounds(vertices, faces, face_object, 4)
    for o in range(4):
        v = vertices[np.unique(faces[face_object == o])]
        want = np.array([v.min(axis=0), v.max(axis=0)]) if len(v) else np.array([[np.inf] * 3, [-np.inf] * 3])
        np.testing.assert_array_equal(got[o], want)
