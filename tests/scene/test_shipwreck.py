"""The procedural shipwreck scene: a closed hull of the paper's size, deterministic, sunk into its floor."""
import numpy as np
import pytest

import sonar_embree as se
from sonar_embree import shipwreck


def test_hull_is_closed_outward_and_patrol_boat_sized():
    h = shipwreck.hull()
    assert h.is_watertight
    edges = h.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    assert len(np.unique(edges, axis=0)) == len(edges)  # each directed edge once: consistent winding
    assert h.volume > 0                                 # normals point out
    ext = h.bounds[1] - h.bounds[0]
    assert ext[0] == pytest.approx(shipwreck.HULL_LENGTH_M, rel=0.01)
    assert ext[1] == pytest.approx(shipwreck.HULL_BEAM_M, rel=0.01)


def test_scene_is_deterministic_sunk_and_about_two_million_triangles_by_default():
    a = shipwreck.shipwreck_scene(resolution_m=2.0).compiled()
    b = shipwreck.shipwreck_scene(resolution_m=2.0).compiled()
    np.testing.assert_array_equal(a.vertices, b.vertices)
    wreck = a.vertices[np.unique(a.faces[a.face_object == a.labels.index("wreck")])] + a.origin_m
    assert wreck[:, 2].min() < -1.0 < 0.0 < wreck[:, 2].max()
    cells = round(203.0 / 0.2)
    assert 2 * cells ** 2 > 2.0e6  # the default 0.2 m floor: ~2 M triangles (not built here)
    with pytest.raises(se.ConfigError, match="floor"):
        shipwreck.shipwreck_scene(floor="sand")
    r = shipwreck.shipwreck_scene(floor="ripples", size_m=40.0, resolution_m=0.2).compiled()
    assert "wreck" in r.labels and "seafloor" in r.labels
