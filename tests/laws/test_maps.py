"""Backscatter maps (docs/physics.md §10): per face, per vertex, image through UV; against the geometry and a twin."""
import numpy as np
import pytest

import sonar_embree as se
from sonar_embree.laws.maps import BackscatterMap, MapTable, map_weights

H, TAU, FS = 10.0, 100e-6, 20e3
SQUARE, TEXELS = 2.5, 100          # 2.5 m squares of 100 texels: 2.5 cm texels, under one sample (3.75 cm)
X0, X1, Y0, Y1 = -5.0, 5.0, -45.0, 5.0


def _checker_obj(tmp_path):
    """A flat quad with UVs (u along x, v along y, as Blender writes them) and a ±6 dB checkerboard PNG."""
    import imageio.v3 as iio

    (tmp_path / "floor.obj").write_text(
        f"o floor\nv {X0} {Y0} 0\nv {X1} {Y0} 0\nv {X1} {Y1} 0\nv {X0} {Y1} 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    cols, rows = int((X1 - X0) / SQUARE) * TEXELS, int((Y1 - Y0) / SQUARE) * TEXELS
    x = X0 + (np.arange(cols) + 0.5) * SQUARE / TEXELS
    y = Y1 - (np.arange(rows) + 0.5) * SQUARE / TEXELS           # image row 0 is the top: v = 1
    i, j = np.floor((x - X0) / SQUARE).astype(int), np.floor((y - Y0) / SQUARE).astype(int)
    white = (i[None, :] + j[:, None]) % 2 == 0
    iio.imwrite(tmp_path / "checker.png", np.where(white, 255, 0).astype(np.uint8))
    return tmp_path / "floor.obj", tmp_path / "checker.png"


def _record(scene):
    sonar = se.Sonar(max_range_m=40.0, sample_rate_hz=FS)
    traj = se.Trajectory.line((1.2, 0.0, H), (1.3, 0.0, H), 3).stop_and_hop()    # over the column x ∈ [0, 2.5] (i = 2)
    return se.simulate(scene, traj, sonar, se.Pulse.cw(duration_s=TAU, taper=0.0), start_time="2000-01-01")


def test_checkerboard_texture_edges_and_contrast(tmp_path):
    obj, png = _checker_obj(tmp_path)
    bmap = BackscatterMap.image(png, db_range=(-6.0, 6.0))
    textured = _record(se.Scene().add(obj, label="seafloor", backscatter_map=bmap))
    plain = _record(se.Scene().add(obj, label="seafloor"))
    r = textured.slant_range_m
    with np.errstate(invalid="ignore"):   # 0/0 in the water column
        ratio = textured.starboard.mean(axis=0) / plain.starboard.mean(axis=0)
    ext = 1500.0 * TAU / 2
    # each sample integrates slant ranges [R − cτ/2, R]; ground range ρ = −y of the starboard floor
    rho_lo = np.sqrt(np.clip((r - ext) ** 2 - H ** 2, 0, None))
    rho_hi = np.sqrt(np.clip(r ** 2 - H ** 2, 0, None))
    j = np.floor((-rho_hi - Y0) / SQUARE).astype(int)
    want_db = np.where((2 + j) % 2 == 0, 6.0, -6.0)
    edge = SQUARE * np.round(rho_hi / SQUARE)
    interior = (rho_lo > SQUARE) & (rho_hi < 38.0) & (np.floor(rho_lo / SQUARE) == np.floor(rho_hi / SQUARE)) \
        & (np.abs(rho_lo - edge) > 0.05) & (np.abs(rho_hi - edge) > 0.05)
    assert interior.sum() > 300
    err = 10 * np.log10(ratio[interior]) - want_db[interior]
    assert np.max(np.abs(err)) < 0.3, np.max(np.abs(err))
    # edges: the ratio crosses the middle of its two plateaus where the pulse straddles the edge,
    # R = R_edge + cτ/4 (a quarter of the pulse's extent past the edge's slant range)
    mid = 0.5 * (10 ** 0.6 + 10 ** -0.6)
    n_edges = 0
    for k in range(2, 16):
        r_edge = np.hypot(H, k * SQUARE)
        want = np.interp(r_edge + ext / 2, r, np.arange(r.size))
        a = int(want) - 6
        seg = ratio[a:a + 13] - mid
        cross = np.flatnonzero(np.sign(seg[:-1]) != np.sign(seg[1:]))
        assert cross.size == 1, (k, seg)
        c = cross[0]
        got = a + c + seg[c] / (seg[c] - seg[c + 1])
        assert abs(got - want) < 2.0, (k, got, want)
        n_edges += 1
    assert n_edges == 14


def _naive_map(prim, points, vertices, faces, corner_db, face_tex, corner_uv, images):
    """Twin of map_weights: barycentric weights by areas, bilinear wrapped texel lookup, as factors."""
    out = np.ones(prim.size)
    for n, t in enumerate(prim):
        if t < 0:
            continue
        a, b, c = vertices[faces[t]]
        area = np.linalg.norm(np.cross(b - a, c - a))
        p = points[n]
        w = np.array([np.linalg.norm(np.cross(b - p, c - p)), np.linalg.norm(np.cross(c - p, a - p)),
                      np.linalg.norm(np.cross(a - p, b - p))]) / area
        db = w @ corner_db[t]
        if face_tex[t] >= 0:
            img = images[face_tex[t]]
            h, wd = img.shape
            u, v = w @ corner_uv[t]
            x, y = u * wd - 0.5, (1 - v) * h - 0.5
            x0, y0 = np.floor(x), np.floor(y)
            fx, fy = x - x0, y - y0
            c0, r0 = int(x0) % wd, int(y0) % h
            c1, r1 = (c0 + 1) % wd, (r0 + 1) % h
            db += (img[r0, c0] * (1 - fx) * (1 - fy) + img[r0, c1] * fx * (1 - fy) + img[r1, c0] * (1 - fx) * fy
                   + img[r1, c1] * fx * fy)
        out[n] = 10 ** (db / 10)
    return out


def test_map_kernel_matches_its_twin(rng):
    """Three objects: per-face, per-vertex and an image with UVs beyond [0, 1] (wrapped)."""
    import trimesh

    meshes = [trimesh.creation.icosphere(subdivisions=1), trimesh.creation.box(), trimesh.creation.icosphere(1)]
    maps = [BackscatterMap.per_face(rng.uniform(-10, 10, len(meshes[0].faces))),
            BackscatterMap.per_vertex(rng.uniform(-10, 10, len(meshes[1].vertices))),
            BackscatterMap.image(rng.uniform(-5, 5, (7, 11)), uv=rng.uniform(-2, 3, (len(meshes[2].vertices), 2)))]
    scene = se.Scene()
    for k, (m, bm) in enumerate(zip(meshes, maps)):
        m.apply_translation([3.0 * k, 0, 0])
        scene.add(m, label=f"o{k}", backscatter_map=bm)
    c = scene.compiled()
    table = MapTable.build(scene.objects)
    n = 3000
    prim = rng.integers(-1, c.faces.shape[0], n).astype(np.int32)
    bary = rng.dirichlet([1, 1, 1], n)
    points = np.einsum("nk,nkj->nj", bary, c.vertices[c.faces[np.maximum(prim, 0)]])
    weight = rng.uniform(0.5, 1.0, n)
    got = weight.copy()
    map_weights(prim, points, c.vertices, c.faces, table.corner_db, table.face_tex, table.corner_uv, table.tex,
                table.tex_off, table.tex_h, table.tex_w, got)
    want = weight * _naive_map(prim, points, c.vertices, c.faces, table.corner_db, table.face_tex, table.corner_uv,
                               [maps[2].values_db])
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert np.all(got[prim < 0] == weight[prim < 0]) and np.ptp(got / weight) > 5


def test_per_face_map_follows_kept_faces_and_errors():
    import trimesh

    mesh = se.seafloor.flat(size_m=(10, 10))
    with pytest.raises(se.SceneError, match="per-face map needs 2 values, got 3"):
        se.Scene().add(mesh, label="seafloor", backscatter_map=BackscatterMap.per_face([0, 1, 2]))
    with pytest.raises(se.SceneError, match="image map needs UV coordinates"):
        se.Scene().add(trimesh.Trimesh(mesh.vertices, mesh.faces), label="seafloor",
                       backscatter_map=BackscatterMap.image(np.zeros((2, 2))))
    with pytest.raises(se.ConfigError, match="give dB, not linear"):
        BackscatterMap.per_vertex([0.0, 1e3])
    with pytest.raises(se.ConfigError, match="db_range"):
        BackscatterMap.image("x.png")
    # a degenerate face is dropped with its map value
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3], [1, 3, 2]])
    obj = se.Scene().add(trimesh.Trimesh(v, f, process=False), label="x",
                         backscatter_map=BackscatterMap.per_face([1.0, 2.0, 3.0])).objects[0]
    np.testing.assert_array_equal(obj.backscatter_map.values_db, [1.0, 3.0])


def test_a_scene_without_maps_or_texture_pays_nothing():
    c = se.Scene().add(se.seafloor.flat(), label="seafloor").compiled()
    assert c.maps is None and c.textures is None and not c.needs_points
