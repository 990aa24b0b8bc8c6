"""Scenes (formats, labels, materials, local origin) and trajectories (conventions, constructors)."""
import numpy as np
import pytest
import trimesh

import sonar_embree as se
from sonar_embree.runs.demo import write_anchor_mine_obj


def test_multi_object_obj_keeps_one_label_per_object(tmp_path):
    path = tmp_path / "mine.obj"
    write_anchor_mine_obj(path)
    scene = se.Scene.load(path, materials={"mine": se.Material(backscatter_db=-10)})
    assert scene.labels == ("float_high", "float_low", "mine", "sinker")  # sorted
    mats = {o.label: o.material.backscatter_db for o in scene.objects}
    assert mats["mine"] == -10 and mats["sinker"] == -27
    c = scene.compiled()
    assert c.face_object.max() == 3 and c.mu[scene.labels.index("mine")] == pytest.approx(0.1)


@pytest.mark.parametrize("ext", ["stl", "ply", "glb", "obj"])
def test_formats_load_with_same_geometry(tmp_path, ext):
    mesh = trimesh.creation.box(extents=(1, 2, 3))
    path = tmp_path / f"box.{ext}"
    mesh.export(path)  # trimesh writes the coordinates as they are, also into GLB (y up by its specification)
    scene = se.Scene.load(path, up_axis="z")
    np.testing.assert_allclose(scene.bounds, [[-0.5, -1, -1.5], [0.5, 1, 1.5]], atol=1e-6)
    assert scene.n_faces == 12


def test_duplicate_label_and_unknown_material_rejected():
    scene = se.Scene().add(se.seafloor.flat((10, 10)), label="floor")
    with pytest.raises(se.SceneError, match="'floor'"):
        scene.add(se.seafloor.flat((10, 10)), label="floor")
    with pytest.raises(se.SceneError, match="'nothing'"):
        scene.add(se.seafloor.flat((10, 10)), label="b", materials={"nothing": se.Material()})


def test_local_origin_keeps_float64_precision():
    mesh = se.seafloor.flat((10, 10), center_m=(512_000.3, 5_412_000.7), z_m=-20.0)
    c = se.Scene().add(mesh, label="f").compiled()
    np.testing.assert_array_equal(c.origin_m, [512_000.0, 5_412_001.0, -20.0])
    assert np.abs(c.vertices).max() < 6
    np.testing.assert_allclose(c.face_normals, [[0, 0, 1]] * 2)


def test_seafloors_are_upward_and_deterministic():
    for mesh in (se.seafloor.flat((20, 10)), se.seafloor.perlin((20, 10), 1.0, relief_m=0.5, seed=3),
                 se.seafloor.ripples((8, 6), 0.1, wavelength_m=0.8, height_m=0.1)):
        assert np.all(mesh.face_normals[:, 2] > 0)
    a = se.seafloor.perlin((20, 10), 1.0, relief_m=0.5, seed=3)
    b = se.seafloor.perlin((20, 10), 1.0, relief_m=0.5, seed=3)
    c = se.seafloor.perlin((20, 10), 1.0, relief_m=0.5, seed=4)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert not np.array_equal(a.vertices, c.vertices)
    assert np.ptp(a.vertices[:, 2]) == pytest.approx(0.5)
    assert se.seafloor.flat((400, 200)).bounds.tolist() == [[-200, -100, 0], [200, 100, 0]]


def test_attitude_conventions():
    rot = se.Trajectory(np.zeros((3, 3)), heading_deg=[90, 0, 0], pitch_deg=[0, 10, 0],
                        roll_deg=[0, 0, 10]).rotations()
    fwd, stbd, down = rot[0].T
    np.testing.assert_allclose(fwd, [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(stbd, [0, -1, 0], atol=1e-15)   # heading +x: starboard −y
    np.testing.assert_allclose(down, [0, 0, -1], atol=1e-15)
    assert rot[1][:, 0][2] > 0          # pitch up raises the nose
    assert rot[2][:, 1][2] < 0          # roll + puts starboard down
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", rot, rot), np.broadcast_to(np.eye(3), (3, 3, 3)), atol=1e-15)


def test_line_and_waypoints():
    t = se.Trajectory.line((0, 0, 10), (20, 0, 10), 11, speed_m_s=2.0)
    np.testing.assert_allclose(t.heading_deg, 90.0)
    np.testing.assert_allclose(t.times_s, np.arange(11))
    wp = np.array([[0, 0, 10], [20, 5, 10], [40, 0, 10]], float)
    c = se.Trajectory.through_waypoints(wp, 201)
    np.testing.assert_allclose(c.positions_m[[0, -1]], wp[[0, -1]], atol=1e-9)
    assert np.min(np.linalg.norm(c.positions_m - wp[1], axis=1)) < 0.2  # passes the middle waypoint
    steps = np.linalg.norm(np.diff(c.positions_m, axis=0), axis=1)
    assert np.ptp(steps) < 0.01 * steps.mean()                           # evenly spaced in arc length
    assert c.heading_deg[0] < 90 < c.heading_deg[-1]                    # turns right then left: bends


def test_csv_round_trip(tmp_path):
    t = se.Trajectory([[0, 0, 10], [1, 2, 9.5]], heading_deg=[10, 20], pitch_deg=[1, 2], roll_deg=[-3, 4],
                      times_s=[0.0, 0.5])
    t.to_csv(tmp_path / "nav.csv")
    back = se.Trajectory.from_csv(tmp_path / "nav.csv")
    assert back.stop_and_hop() == t                                      # the poses, bit for bit
    np.testing.assert_allclose(back.velocity_m_s, [[2, 4, -1]] * 2)     # and the speed the time stamps give
    moving = se.Trajectory.line((0, 0, 10), (3, 4, 10), 5, speed_m_s=1.5)
    moving.to_csv(tmp_path / "moving.csv")
    assert se.Trajectory.from_csv(tmp_path / "moving.csv") == moving   # velocity columns written and read
    (tmp_path / "bad.csv").write_text("x_m,y_m,z_m,speed\n0,0,0,1\n")
    with pytest.raises(se.ConfigError, match="'speed'"):
        se.Trajectory.from_csv(tmp_path / "bad.csv")


def test_csv_velocity_columns_derivation_and_unit_slip(tmp_path, caplog):
    """Velocity columns are used as given (all three or an error naming the missing ones); without them the
    velocity is d(position)/dt by second-order differences (exact on a parabola, ends too); without times there is
    none; a speed no vehicle flies warns of time stamps not in seconds."""
    t = np.array([0.0, 0.5, 1.5, 2.0, 3.0])
    x = 0.2 * t ** 2 + t                                                  # v = 0.4 t + 1
    rows = "\n".join(f"{a},{b},0,10" for a, b in zip(t, x))
    (tmp_path / "nav.csv").write_text("time_s,x_m,y_m,z_m\n" + rows + "\n")
    v = se.Trajectory.from_csv(tmp_path / "nav.csv").velocity_m_s
    np.testing.assert_allclose(v[:, 0], 0.4 * t + 1, rtol=1e-12)        # second order: exact, ends included
    np.testing.assert_allclose(v[:, 1:], 0.0, atol=1e-12)
    (tmp_path / "still.csv").write_text("x_m,y_m,z_m\n0,0,10\n1,0,10\n")
    assert se.Trajectory.from_csv(tmp_path / "still.csv").velocity_m_s is None
    (tmp_path / "given.csv").write_text("x_m,y_m,z_m,vx_m_s,vy_m_s,vz_m_s\n0,0,10,1,2,0\n1,0,10,1,2,0\n")
    np.testing.assert_array_equal(se.Trajectory.from_csv(tmp_path / "given.csv").velocity_m_s, [[1, 2, 0]] * 2)
    (tmp_path / "part.csv").write_text("x_m,y_m,z_m,vx_m_s\n0,0,10,1\n")
    with pytest.raises(se.ConfigError, match="part.csv: velocity needs all of vx_m_s, vy_m_s, vz_m_s; got only vx_m_s"):
        se.Trajectory.from_csv(tmp_path / "part.csv")
    (tmp_path / "ms.csv").write_text("time_s,x_m,y_m,z_m\n0,0,0,10\n1,100,0,10\n")  # milliseconds, 2 m apart
    with caplog.at_level("WARNING"):
        se.Trajectory.from_csv(tmp_path / "ms.csv")
    assert any("ms.csv: the vehicle moves at up to 100 m/s" in r.getMessage() and "seconds" in r.getMessage()
               for r in caplog.records)
