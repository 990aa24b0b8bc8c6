"""The paper's scenes as shipped examples: assets equal their generators, configs load, and a curved
pass bends a straight feature exactly as the geometry says it must."""
import glob
import os

import numpy as np
import pytest

import sonar_embree as se
from conftest import box, flat_scene
from sonar_embree import demo, shipwreck
from sonar_embree.signal.labels import OBJECT
from sonar_embree.runs.runconfig import load_run_config
from sonar_embree.scene import load_mesh

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CONFIGS = sorted(glob.glob(os.path.join(ROOT, "sonar_embree", "assets", "configs", "*.toml")))


def _triangles(mesh):
    return np.asarray(mesh.vertices)[np.asarray(mesh.faces)]


def test_shipped_meshes_equal_their_generators():
    """scripts/make_assets.py wrote them; a changed generator without a re-run fails here."""
    wreck = load_mesh(os.path.join(ROOT, "sonar_embree", "assets", "scenes", "wreck.obj"))
    np.testing.assert_allclose(_triangles(wreck), _triangles(shipwreck.wreck()), atol=6e-6)  # %.5f in the OBJ
    mine = se.Scene.load(os.path.join(ROOT, "sonar_embree", "assets", "scenes", "anchor_mine.obj"))
    parts = {label: mesh for label, mesh, _ in demo.anchor_mine_objects()}
    assert set(mine.labels) == set(parts)
    for obj in mine.objects:
        np.testing.assert_allclose(obj.vertices[obj.faces], _triangles(parts[obj.label]), atol=6e-6)
    moored = se.Scene.load(se.assets.path("moored_mine.obj"))
    for obj in moored.objects:
        want = _triangles(parts[obj.label]) + np.array([0.0, demo.MINE_GROUND_RANGE_M, 0.0])
        np.testing.assert_allclose(obj.vertices[obj.faces], want, atol=6e-6)


def test_every_scene_has_a_straight_and_a_curved_example():
    names = {os.path.basename(p)[:-5] for p in CONFIGS}
    assert {"anchor_mine", "anchor_mine_curved", "shipwreck_perlin_straight", "shipwreck_perlin_curved",
            "shipwreck_ripples_straight", "shipwreck_ripples_curved"} <= names


@pytest.fixture(scope="module")
def library_floors():
    return {}


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: os.path.basename(p))
def test_example_configs_load_and_match_the_library(path, library_floors):
    cfg = load_run_config(path)
    heading = cfg.trajectory.heading_deg
    curved = "curved" in os.path.basename(path)
    assert (np.ptp(heading) > 10.0) if curved else (np.ptp(heading) == 0.0)
    if "shipwreck" not in path:
        return
    floor = "ripples" if "ripples" in path else "perlin"
    expected = (shipwreck.curved_pass if curved else shipwreck.straight_pass)(**shipwreck.PAPER_PASS)
    np.testing.assert_allclose(cfg.trajectory.positions_m, expected.positions_m, atol=1e-9)
    np.testing.assert_allclose(cfg.trajectory.heading_deg, expected.heading_deg, atol=1e-9)
    np.testing.assert_allclose(cfg.trajectory.times_s, expected.times_s, atol=1e-9)
    assert cfg.sonar.max_range_m == shipwreck.PAPER_MAX_RANGE_M
    if floor not in library_floors:
        library_floors[floor] = shipwreck.shipwreck_scene(floor=floor)
    lib = {o.label: o for o in library_floors[floor].objects}
    got = {o.label: o for o in cfg.scene.objects}
    assert set(got) == {"seafloor", "wreck"}
    for label in got:
        assert got[label].material == lib[label].material
        np.testing.assert_allclose(got[label].vertices[got[label].faces], lib[label].vertices[lib[label].faces],
                                   atol=6e-6)


RAIL_Y_M, RAIL_W_M, RAIL_H_M, ALT_M = -20.0, 0.5, 0.5, 10.0


@pytest.fixture(scope="module")
def rail_scene():
    """A straight 0.5 m × 0.5 m rail, 140 m long along x, 20 m to starboard of the straight pass."""
    return flat_scene().add(box((140.0, RAIL_W_M, RAIL_H_M), (0.0, RAIL_Y_M, RAIL_H_M / 2)), label="rail")


def _first_return_analytic(traj):
    """Slant range to the rail's near top edge in each ping's zero-azimuth plane (docs/physics.md conventions).

    The plane through the sonar perpendicular to the heading ψ (clockwise from north) meets the
    edge line (x, y_e, H) where (x − px)·sin ψ + (y_e − py)·cos ψ = 0, at horizontal distance
    |y_e − py| / sin ψ; the edge is the nearest point of the rail for a sonar above it.
    """
    p = traj.positions_m
    y_edge = RAIL_Y_M + RAIL_W_M / 2
    horizontal = np.abs(y_edge - p[:, 1]) / np.sin(np.radians(traj.heading_deg))
    return np.hypot(horizontal, p[:, 2] - RAIL_H_M)


@pytest.mark.parametrize("kind", ["straight", "curved"])
def test_curved_pass_bends_a_straight_feature_as_the_geometry_says(rail_scene, kind):
    """The waterfall trace of a straight rail: constant range on the straight pass, the path's
    bend on the curved one (``shipwreck.curved_pass``, the Fig. 9 path), sample for sample."""
    make = shipwreck.straight_pass if kind == "straight" else shipwreck.curved_pass
    traj = make(n_pings=41, altitude_m=ALT_M, ping_rate_hz=1.0, speed_m_s=2.0)  # 80 m, S-bend ±2.5 m
    rec = se.simulate(rail_scene, traj, se.Sonar(max_range_m=30.0), labels=True)
    r = rec.slant_range_m
    dr = r[1] - r[0]
    on_rail = rec.labels.kind[1] == OBJECT  # starboard
    assert on_rail.any(axis=1).all()
    measured = r[np.argmax(on_rail, axis=1)]
    expected = _first_return_analytic(traj)
    np.testing.assert_array_less(np.abs(measured - expected), 2.0 * dr)
    if kind == "straight":
        assert np.ptp(measured) <= dr  # a straight line in the waterfall
    else:
        assert np.ptp(measured) > 4.0  # bent by metres: ±2.5 m of path, seen at ground range ~20 m
        # the bend follows the path's lateral offset: nearer when the path swings towards the rail
        assert np.corrcoef(measured, traj.positions_m[:, 1])[0, 1] > 0.99


BLENDER_OBJ = """# Blender 4.1.1
mtllib scene.mtl
o seafloor
v -30.0 -30.0 0.0
v 30.0 -30.0 0.0
v 30.0 30.0 0.0
v -30.0 30.0 0.0
vn 0.0 0.0 1.0
vt 0.0 0.0
vt 1.0 0.0
vt 1.0 1.0
vt 0.0 1.0
s 0
usemtl Sand
f 1/1/1 2/2/1 3/3/1 4/4/1
o Crate
v -1 -16 0
v 1 -16 0
v 1 -14 0
v -1 -14 0
v -1 -16 1
v 1 -16 1
v 1 -14 1
v -1 -14 1
usemtl Metal
f 5 8 7 6
f 9 10 11 12
f 5 6 10 9
f 6 7 11 10
f 7 8 12 11
f 8 5 9 12
"""


def test_a_blender_style_export_renders_with_per_object_materials(tmp_path):
    """The README's guide: quads, normals, texture coordinates and a missing .mtl load; object names
    become labels ("seafloor" is the floor); ``materials`` sets each object's backscatter."""
    (tmp_path / "scene.obj").write_text(BLENDER_OBJ)
    (tmp_path / "run.toml").write_text("""
[sonar]
max_range_m = 25.0
[trajectory]
kind = "waypoints"
waypoints = [[-2.0, 0.0, 8.0], [0.0, 0.3, 8.0], [2.0, 0.0, 8.0]]
n_pings = 5
[[objects]]
path = "scene.obj"
materials = { seafloor = { backscatter_db = -30.0 }, Crate = { backscatter_db = -12.0 } }
[output]
npz = false
""")
    cfg = load_run_config(tmp_path / "run.toml")
    got = {o.label: (o.faces.shape[0], o.material.backscatter_db, o.seafloor) for o in cfg.scene.objects}
    assert got == {"seafloor": (2, -30.0, True), "Crate": (12, -12.0, False)}
    from sonar_embree.runs.cli import main
    assert main(["render", str(tmp_path / "run.toml"), "-o", str(tmp_path / "out"), "--no-progress"]) == 0
    assert sorted(os.listdir(tmp_path / "out")) == [".sonar-embree-manifest.json", "waterfall.png"]
    (tmp_path / "bad.toml").write_text((tmp_path / "run.toml").read_text().replace("Crate =", "Crates ="))
    with pytest.raises(se.SceneError, match="'Crates'") as exc:
        load_run_config(tmp_path / "bad.toml")
    assert "bad.toml" in str(exc.value)
