"""Bathymetry from a DEM (issue: real surveys; docs/physics.md §15): GeoTIFF and XYZ grids in a CRS.

The GeoTIFF is written here with rasterio directly, north-up with a known transform; a Gaussian mound's top sits
on one pixel centre, so a half-pixel or a flipped-row mistake moves it by metres (and its height by 0.17 m).
"""
import re

import numpy as np
import pytest
import rasterio
import trimesh
from rasterio.transform import Affine

import sonar_embree as se

CRS, PIXEL, X0, Y0 = "EPSG:32632", 1.0, 532000.0, 6017100.0      # upper-left corner of the raster
NX, NY, FLOOR, APEX, SIGMA = 80, 60, -60.0, -48.0, 3.0
I_APEX, J_APEX = 17, 41                                            # row (from the north), column of the apex
NODATA = -9999.0


def _apex_xy():
    return X0 + (J_APEX + 0.5) * PIXEL, Y0 - (I_APEX + 0.5) * PIXEL  # pixel centre, north-up


def _heights():
    x = X0 + (np.arange(NX) + 0.5) * PIXEL
    y = Y0 - (np.arange(NY) + 0.5) * PIXEL
    xa, ya = _apex_xy()
    rho = np.hypot(x[None, :] - xa, y[:, None] - ya)
    z = FLOOR + (APEX - FLOOR) * np.exp(-0.5 * (rho / SIGMA) ** 2)
    z[50:, :10] = NODATA                                           # a hole in the south-west corner
    return z


def _write_dem(path, crs=CRS, transform=None):
    with rasterio.open(path, "w", driver="GTiff", width=NX, height=NY, count=1, dtype="float32", crs=crs,
                       transform=transform or Affine(PIXEL, 0.0, X0, 0.0, -PIXEL, Y0), nodata=NODATA) as dst:
        dst.write(_heights().astype(np.float32), 1)
    return path


def test_dem_vertices_sit_on_pixel_centres_north_up_with_holes_and_crs(tmp_path):
    mesh = se.seafloor.from_dem(_write_dem(tmp_path / "dem.tif"))
    assert mesh.metadata["crs"] == CRS
    v = mesh.vertices
    top = v[np.argmax(v[:, 2])]
    np.testing.assert_allclose(top, (*_apex_xy(), APEX), atol=1e-6)
    hole = (v[:, 0] < X0 + 10 * PIXEL) & (v[:, 1] < Y0 - 50 * PIXEL)
    assert not hole.any() and v.shape[0] == NX * NY - 10 * 10      # nodata pixels are no vertex
    assert np.all(mesh.face_normals[:, 2] > 0) and abs(v[:, 2].min() - FLOOR) < 1e-6
    assert se.Scene().add(mesh, label="seafloor").crs == CRS


def test_xyz_grid_gives_the_same_floor(tmp_path):
    z = _heights()
    x = X0 + (np.arange(NX) + 0.5) * PIXEL
    y = Y0 - (np.arange(NY) + 0.5) * PIXEL
    keep = z != NODATA
    pts = np.column_stack([np.broadcast_to(x, z.shape)[keep], np.broadcast_to(y[:, None], z.shape)[keep], z[keep]])
    pts = pts[np.random.default_rng(1).permutation(len(pts))]       # any order
    path = tmp_path / "dem.xyz"
    path.write_text("easting northing depth\n" + "\n".join(f"{a:.3f},{b:.3f},{c:.4f}" for a, b, c in pts))
    xyz = se.seafloor.from_xyz(path, crs=32632)
    dem = se.seafloor.from_dem(_write_dem(tmp_path / "dem.tif"))
    assert xyz.metadata["crs"] == CRS
    a, b = (np.unique(np.round(m.vertices, 3), axis=0) for m in (xyz, dem))
    np.testing.assert_allclose(a, b, atol=1e-3)
    assert len(xyz.faces) == len(dem.faces)


def test_pass_over_the_mound_gives_its_altitude_and_first_return(tmp_path):
    """A line east over the top: the ping above it measures the altitude to the top, and its record's first
    echo (the nearest point: the top is curved more tightly, σ²/h = 0.75 m, than the 8 m range) lies at
    2·altitude/c, within one sample."""
    scene = se.Scene().add(se.seafloor.from_dem(_write_dem(tmp_path / "dem.tif")), label="seafloor")
    xa, ya = _apex_xy()
    z = -40.0
    line = se.Trajectory.line((xa - 4.0, ya, z), (xa + 4.0, ya, z), 5).stop_and_hop()
    rec = se.simulate(scene, line, se.Sonar(max_range_m=40.0))
    assert rec.attrs["crs"] == CRS and rec.trajectory.crs == CRS    # the trajectory takes the scene's CRS
    dt = rec.time_s[1] - rec.time_s[0]
    c = rec.acquisition.sound_speed_m_s
    altitude = z - APEX
    assert abs(rec.altitude_m[2] - altitude) < c * dt / 2
    for side in (rec.port[2], rec.starboard[2]):
        first = rec.time_s[np.flatnonzero(side > 0)[0]]
        assert abs(first - 2 * altitude / c) <= dt * (1 + 1e-9)
    flank = FLOOR + (APEX - FLOOR) * np.exp(-0.5 * (4.0 / SIGMA) ** 2)     # 4 m west, on the flank
    assert abs(rec.altitude_m[0] - (z - flank)) < 0.05                    # (between pixel centres)


def test_dem_errors_name_the_file(tmp_path):
    with pytest.raises(se.ConfigError, match="nope.tif: cannot read raster"):
        se.seafloor.from_dem(tmp_path / "nope.tif")
    rotated = Affine(PIXEL, 0.2, X0, 0.2, -PIXEL, Y0)
    with pytest.raises(se.ConfigError, match="rot.tif: rotated or sheared"):
        se.seafloor.from_dem(_write_dem(tmp_path / "rot.tif", transform=rotated))
    with pytest.raises(se.ConfigError, match="geo.tif: CRS .* not projected"):
        se.seafloor.from_dem(_write_dem(tmp_path / "geo.tif", crs="EPSG:4326"))
    ragged = tmp_path / "ragged.xyz"
    ragged.write_text("0 0 1\n1 0 1\n2.5 0 1\n0 1 1\n1 1 1\n2.5 1 1\n")
    with pytest.raises(se.ConfigError, match="ragged.xyz: .*not on a regular grid in x"):
        se.seafloor.from_xyz(ragged)
    scene = se.Scene().add(se.seafloor.from_dem(_write_dem(tmp_path / "dem.tif")), label="seafloor")
    line = se.Trajectory(np.array([[X0 + 40.0, Y0 - 30.0, -40.0]]), crs="EPSG:25832")
    with pytest.raises(se.ConfigError, match="CRS EPSG:25832 differs from the scene's EPSG:32632"):
        se.simulate(scene, line)


def test_mosaic_places_the_mound_where_it_is_and_truth_resamples_the_dem(tmp_path):
    """Two lines east, 18 m south and 18 m north of the mound, with labels; the mosaic GeoTIFF (read back with
    rasterio) has the DEM's CRS and a 1 m north-up transform; the placed seafloor heights peak at the top's
    pixel (within one pixel), the brightest echoes lie on the mound's flanks facing the lines, and the truth
    GeoTIFF is the DEM at the pixel centres (the mosaic grid is the raster's)."""
    dem = _write_dem(tmp_path / "dem.tif")
    scene = se.Scene().add(se.seafloor.from_dem(dem), label="seafloor")
    xa, ya = _apex_xy()
    recs = [se.simulate(scene, se.Trajectory.line((xa - 12.0, ya + dy, -48.0), (xa + 12.0, ya + dy, -48.0), 25),
                        se.Sonar(max_range_m=40.0), labels=True) for dy in (-18.0, 18.0)]
    x, y = se.mosaic.sample_positions(recs[0])                       # port north of the southern line
    assert x.shape == (2,) + recs[0].port.shape and np.nanmin(y[0]) >= ya - 18.0 >= np.nanmax(y[1])
    assert np.nanmax(y[0]) > ya - 18.0 + 20.0 > ya - 18.0 - 20.0 > np.nanmin(y[1])   # 20 m out on each side
    grid = se.mosaic.mosaic(recs, pixel_m=PIXEL, bounds_m=(X0, Y0 - NY * PIXEL, X0 + NX * PIXEL, Y0))
    grid.to_geotiff(tmp_path / "mosaic.tif")
    se.mosaic.write_truth(tmp_path / "truth.tif", scene, grid)
    with rasterio.open(tmp_path / "mosaic.tif") as src:
        assert src.crs.to_epsg() == 32632 and src.count == 2 and src.descriptions == ("intensity", "height_m")
        assert tuple(src.transform)[:6] == (PIXEL, 0.0, X0, 0.0, -PIXEL, Y0)
        intensity, height = src.read(1), src.read(2)
        apex_row, apex_col = src.index(xa, ya)
    assert (apex_row, apex_col) == (I_APEX, J_APEX)
    peak = np.unravel_index(np.nanargmax(height), height.shape)
    assert abs(peak[0] - I_APEX) <= 1 and abs(peak[1] - J_APEX) <= 1, (peak, height[I_APEX, J_APEX])
    yy, xx = np.mgrid[0:NY, 0:NX]
    rho = np.hypot(xx - J_APEX, yy - I_APEX) * PIXEL
    bright = np.argsort(np.nan_to_num(intensity, nan=-1.0), axis=None)[-20:]     # the 20 brightest pixels
    assert np.all(rho.ravel()[bright] < 3 * SIGMA)                              # on the mound
    with rasterio.open(tmp_path / "truth.tif") as src:
        z = src.read(1)
        assert src.crs.to_epsg() == 32632 and tuple(src.transform)[:6] == (PIXEL, 0.0, X0, 0.0, -PIXEL, Y0)
    dem_z = _heights()
    valid = (dem_z != NODATA) & np.isfinite(z)
    np.testing.assert_allclose(z[valid], dem_z[valid], atol=1e-3)    # vertices sit on the pixel centres


def test_mosaic_of_streamed_stores_equals_the_in_memory_one(tmp_path):
    """Lines streamed to Zarr with labels mosaic (read a block of pings at a time) as their in-memory records."""
    scene = se.Scene().add(se.seafloor.from_dem(_write_dem(tmp_path / "dem.tif")), label="seafloor")
    xa, ya = _apex_xy()
    lines = [se.Trajectory.line((xa - 6.0, ya + dy, -48.0), (xa + 6.0, ya + dy, -48.0), 9) for dy in (-15.0, 15.0)]
    sonar = se.Sonar(max_range_m=30.0)
    recs = [se.simulate(scene, ln, sonar, labels=True, start_time="2026-05-01T12:00:00Z") for ln in lines]
    stores = [se.stream.render_line(scene, ln, tmp_path / f"l{k}.zarr", sonar, block_pings=4, labels=True,
                                    start_time="2026-05-01T12:00:00Z") for k, ln in enumerate(lines)]
    a, b = se.mosaic.mosaic(recs, pixel_m=1.0), se.mosaic.mosaic(stores, pixel_m=1.0)
    assert (a.x0_m, a.y0_m, a.count.shape, a.crs) == (b.x0_m, b.y0_m, b.count.shape, b.crs) and a.crs == CRS
    np.testing.assert_array_equal(a.count, b.count)
    np.testing.assert_allclose(a.intensity, b.intensity, rtol=1e-12)
    np.testing.assert_allclose(a.height_m, b.height_m, rtol=1e-12)
    with pytest.raises(se.ConfigError, match="no ground truth"):
        se.mosaic.mosaic([se.simulate(scene, lines[0], sonar)])


def _triangles(mesh):
    tri = np.round(mesh.vertices[mesh.faces], 6)
    return {tuple(map(tuple, t)) for t in tri}


def test_tiles_hold_exactly_the_whole_dem_s_triangles(tmp_path):
    dem = _write_dem(tmp_path / "dem.tif")
    tiled = se.TiledDEM(dem, tile_px=16)
    assert tiled.crs == CRS and tiled.n_tiles == (4, 5)
    every = tiled.tiles_around(np.array([[X0 + 40.0, Y0 - 30.0, -48.0]]), 100.0)
    assert len(every) == 20
    union = set()
    for i, j in every:
        mesh = tiled._tile(i, j)
        if mesh is not None:
            union |= _triangles(mesh)
    assert union == _triangles(se.seafloor.from_dem(dem))            # no triangle lost or added at the seams
    xa, ya = _apex_xy()
    near = tiled.tiles_around(np.array([[xa, ya, -48.0]]), 5.0)     # only the tiles within reach
    assert 1 <= len(near) <= 4 and (I_APEX // 16, J_APEX // 16) in near
    with pytest.raises(se.ConfigError, match="no DEM data within"):
        tiled.scene_around(np.array([[X0 - 500.0, Y0, -48.0]]), 10.0)


def test_tiled_dem_renders_as_the_whole_dem(tmp_path):
    """A line over the mound from a TiledDEM (small tiles: its blocks need different ones) gives the record of
    the whole DEM's mesh bit for bit, streamed or not (every triangle within reach is there, in the same frame)."""
    dem = _write_dem(tmp_path / "dem.tif")
    xa, ya = _apex_xy()
    line = se.Trajectory.line((xa - 20.0, ya - 6.0, -48.0), (xa + 20.0, ya - 6.0, -48.0), 12)
    sonar = se.Sonar(max_range_m=20.0)
    whole = se.simulate(se.Scene().add(se.seafloor.from_dem(dem), label="seafloor"), line, sonar,
                        start_time="2026-05-01T12:00:00Z")
    tiled = se.simulate(se.TiledDEM(dem, tile_px=8), line, sonar, start_time="2026-05-01T12:00:00Z")
    np.testing.assert_array_equal(tiled.starboard, whole.starboard)
    np.testing.assert_array_equal(tiled.port, whole.port)
    se.stream.render_line(se.TiledDEM(dem, tile_px=8), line, tmp_path / "t.zarr", sonar, block_pings=3,
                          start_time="2026-05-01T12:00:00Z")
    import xarray as xr

    ds = xr.open_zarr(tmp_path / "t.zarr")
    np.testing.assert_array_equal(ds["starboard"].values, whole.starboard)
    assert whole.starboard.max() > 0


# --- issue 33: outliers, undeclared nodata, broken files: one line each, nothing dropped silently ----------
def _write_values(path, z, nodata=None):
    with rasterio.open(path, "w", driver="GTiff", width=z.shape[1], height=z.shape[0], count=1, dtype="float32",
                       crs=CRS, transform=Affine(PIXEL, 0.0, X0, 0.0, -PIXEL, Y0), nodata=nodata) as dst:
        dst.write(z.astype(np.float32), 1)
    return path


@pytest.mark.parametrize("spike_m", [1e6, 3e6])
def test_one_outlier_pixel_is_named_not_half_the_mesh_dropped(tmp_path, spike_m):
    """Finding 4: one DEM pixel at 10⁶ m used to drop 16 % of the triangles silently (the degenerate test was
    relative to the mesh's extent); now it is refused, naming its vertex and height."""
    z = np.where(_heights() == NODATA, FLOOR, _heights())
    good = se.seafloor.from_dem(_write_values(tmp_path / "good.tif", z))
    assert len(good.faces) == 2 * (NX - 1) * (NY - 1)               # every cell of a clean DEM kept
    z[30, 20] = spike_m
    with pytest.raises(se.ConfigError, match=r"spike.tif: pixel \(row 30, column 20\) holds " + re.escape(f"{spike_m:.6g}") + " m, "
                                             r".* from the median height, beyond any relief"):
        se.seafloor.from_dem(_write_values(tmp_path / "spike.tif", z))
    with pytest.raises(se.ConfigError, match=r"spike.tif tile \(1, 1\): pixel \(row 14, column 4\) holds"):
        se.TiledDEM(tmp_path / "spike.tif", tile_px=16).scene_around(np.array([[X0 + 20.0, Y0 - 30.0, -40.0]]), 5.0)
    # a mesh (not a raster) with the same spike: the scene names the vertex
    mesh = trimesh.Trimesh(good.vertices.copy(), good.faces, process=False)
    k = int(np.argmin(np.hypot(mesh.vertices[:, 0] - X0 - 20.5, mesh.vertices[:, 1] - Y0 + 30.5)))
    mesh.vertices[k, 2] = spike_m
    with pytest.raises(se.SceneError, match=rf"mesh 'seafloor': vertex {k} at \(.*, " + re.escape(f"{spike_m:.6g}") + r"\) m lies "):
        se.Scene().add(mesh, label="seafloor")


def test_a_vertex_at_1e30_is_named_and_tiny_triangles_far_away_are_kept():
    """Finding 4: the checks are absolute in metres: a 1e30 vertex is refused by name; a 1 cm triangle stays a
    triangle however far another vertex of the mesh lies (the old relative test dropped it)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.01, 0, 0], [0, 0.01, 0], [0, 0, 1e30]], dtype=float)
    with pytest.raises(se.SceneError, match=r"mesh 'x': vertex 5 at \(0, 0, 1e\+30\) m lies beyond 1e\+09 m"):
        se.Scene().add(trimesh.Trimesh(v, [[0, 1, 2], [0, 3, 4], [0, 1, 5]], process=False), label="x")
    far = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [5e5, 0, 0], [5e5, 1, 0], [5e5 + 1, 0, 0]], dtype=float)
    scene = se.Scene().add(trimesh.Trimesh(far, [[0, 1, 2], [3, 5, 4]], process=False), label="x")
    assert scene.n_faces == 2


def test_undeclared_nodata_is_refused_and_declared_it_is_a_hole(tmp_path):
    """Finding 4: −9999 that the raster does not declare used to be meshed as a 10 km pit."""
    z = _heights()
    with pytest.raises(se.ConfigError, match=r"raw.tif: 100 pixel\(s\) hold exactly -9999, a common nodata value "
                                             r"the raster does not declare; pass nodata=-9999"):
        se.seafloor.from_dem(_write_values(tmp_path / "raw.tif", z))
    declared = se.seafloor.from_dem(_write_dem(tmp_path / "dem.tif"))
    given = se.seafloor.from_dem(tmp_path / "raw.tif", nodata=-9999)
    assert len(given.faces) == len(declared.faces) < 2 * (NX - 1) * (NY - 1)
    tiled = se.TiledDEM(tmp_path / "raw.tif", tile_px=16)
    with pytest.raises(se.ConfigError, match=r"raw.tif tile \(3, 0\): 100 pixel\(s\) hold exactly -9999"):
        tiled.scene_around(np.array([[X0 + 5.0, Y0 - 55.0, -40.0]]), 5.0)


def test_broken_rasters_and_bad_tiling_arguments_give_one_line(tmp_path):
    """Finding 12: a truncated GeoTIFF (its pixels unreadable) and TiledDEM's arguments: one-line errors."""
    data = _write_dem(tmp_path / "dem.tif").read_bytes()
    cut = tmp_path / "cut.tif"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(se.ConfigError, match="cut.tif: cannot read raster"):
        se.seafloor.from_dem(cut)
    with pytest.raises(se.ConfigError, match="cut.tif: cannot read raster"):
        se.TiledDEM(cut, tile_px=16).scene_around(np.array([[X0 + 40.0, Y0 - 55.0, -40.0]]), 5.0)
    for kw, what in ((dict(band="1"), "band must be an integer >= 1, got '1'"),
                     (dict(cache_tiles="x"), "cache_tiles must be an integer"),
                     (dict(cache_tiles=None), "cache_tiles must be an integer"),
                     (dict(cache_tiles=-1), "cache_tiles must be an integer >= 1, got -1"),
                     (dict(nodata="none"), "nodata must be a number")):
        with pytest.raises(se.ConfigError, match=what):
            se.TiledDEM(tmp_path / "dem.tif", **kw)
    with pytest.raises(se.ConfigError, match="dem.tif: band must be an integer"):
        se.seafloor.from_dem(tmp_path / "dem.tif", band="1")


def test_write_truth_refuses_other_crs_and_takes_a_tiled_dem(tmp_path):
    """Finding 8: a scene in EPSG:32633 under a grid in EPSG:32632 gave a truth.tif labelled 32632; a TiledDEM
    raised AttributeError. Now the CRSs must agree, and a TiledDEM (strip by strip) gives the whole DEM's truth."""
    dem = _write_dem(tmp_path / "dem.tif")
    grid = se.mosaic.Mosaic(np.zeros((NY, NX)), np.zeros((NY, NX)), np.zeros((NY, NX), dtype=np.int64), X0, Y0,
                            PIXEL, CRS)
    other = se.Scene().add(se.seafloor.from_dem(_write_dem(tmp_path / "utm33.tif", crs="EPSG:32633")),
                           label="seafloor")
    with pytest.raises(se.ConfigError, match="write_truth: the scene is in EPSG:32633, the mosaic grid in "
                                             "EPSG:32632"):
        se.mosaic.write_truth(tmp_path / "bad.tif", other, grid)
    assert not (tmp_path / "bad.tif").exists()
    whole = se.Scene().add(se.seafloor.from_dem(dem), label="seafloor")
    a = se.mosaic.write_truth(tmp_path / "a.tif", whole, grid)
    import sonar_embree.survey.mosaic as mosaic_module

    old = mosaic_module.TRUTH_STRIP_ROWS
    mosaic_module.TRUTH_STRIP_ROWS = 7                                 # several strips over 60 rows
    try:
        b = se.mosaic.write_truth(tmp_path / "b.tif", se.TiledDEM(dem, tile_px=16), grid)
    finally:
        mosaic_module.TRUTH_STRIP_ROWS = old
    dem_z = _heights()
    valid = (dem_z != NODATA) & np.isfinite(a)                         # the raster's edge: centres on its rim
    assert valid.sum() > 0.9 * (dem_z != NODATA).sum()
    np.testing.assert_allclose(b[valid], dem_z[valid], atol=1e-3)     # the DEM itself
    np.testing.assert_array_equal(np.isfinite(a), np.isfinite(b))
    with rasterio.open(tmp_path / "b.tif") as src:
        assert src.crs.to_epsg() == 32632


def test_mosaic_bad_inputs_give_one_line(tmp_path):
    """Finding 12: a generator of records works; None, a missing store, a .tif, NaN bounds, a grid of 1 mm
    pixels over 10⁷ m, and a GeoTIFF into a missing folder each give one line naming the problem."""
    scene = se.Scene().add(se.seafloor.from_dem(_write_dem(tmp_path / "dem.tif")), label="seafloor")
    xa, ya = _apex_xy()
    rec = se.simulate(scene, se.Trajectory.line((xa - 3.0, ya, -48.0), (xa + 3.0, ya, -48.0), 4),
                      se.Sonar(max_range_m=30.0), labels=True)
    a = se.mosaic.mosaic((r for r in [rec]), pixel_m=1.0)
    np.testing.assert_array_equal(a.count, se.mosaic.mosaic([rec], pixel_m=1.0).count)
    for records, bounds, pixel, what in (
            (None, None, 1.0, "mosaic: no records"),
            (str(tmp_path / "missing.zarr"), None, 1.0, "missing.zarr: no such Zarr store"),
            (str(tmp_path / "dem.tif"), None, 1.0, "dem.tif: no such Zarr store"),
            (rec, (0.0, np.nan, 1.0, 2.0), 1.0, "bounds_m must be four finite numbers"),
            (rec, (0.0, 0.0, 1e7, 1e7), 1e-3, r"a grid of 10000000000 x 10000000000 pixels .* use a larger pixel_m"),
            (rec, None, True, "pixel_m must be a positive number of metres")):
        with pytest.raises(se.ConfigError, match=what):
            se.mosaic.mosaic(records, pixel_m=pixel, bounds_m=bounds)
    with pytest.raises(se.ConfigError, match=r"nowhere/m.tif: its folder .*nowhere does not exist"):
        a.to_geotiff(tmp_path / "nowhere" / "m.tif")


def test_a_dem_too_large_to_mesh_whole_is_refused_before_reading(tmp_path, monkeypatch):
    """Finding 10: a 52 M-triangle DEM as one mesh failed with MemoryError after 46 s; its size is known from the
    header (0.4 GB per million triangles), so it is refused at once, pointing at TiledDEM, which renders it."""
    from sonar_embree import checks

    dem = _write_dem(tmp_path / "dem.tif")
    monkeypatch.setattr(checks, "physical_memory_bytes", lambda: 2 ** 20)              # a 1 MiB machine
    with pytest.raises(se.ConfigError, match=r"dem.tif: 80 x 60 pixels make 0.0 M triangles, about 0.0 GiB once "
                                             r"meshed, .* load it as se.TiledDEM\(path\)"):
        se.seafloor.from_dem(dem)
    assert 2 * 79 * 59 * 400 > 0.5 * 2 ** 20                                          # the estimate that refused
    tiles = se.TiledDEM(dem, tile_px=16)
    assert tiles.scene_around(np.array([[X0 + 40.0, Y0 - 20.0, -40.0]]), 5.0).n_faces > 0


def test_an_evicted_tile_scene_frees_its_bvh_at_once(tmp_path):
    """Finding 12 (a tiled stream's memory climbed by ~0.5 GB over 100 000 pings): a caster kept with its compiled
    scene made a reference cycle, so an evicted scene's BVH waited for the garbage collector. Casters now live in
    a run's RunCache (a line's blocks share one), which holds its most recent scenes: with the collector off, the
    first scene's caster is gone once two newer scenes pushed it out of the cache, and its scene is freed too."""
    import gc
    import weakref

    from sonar_embree.propagation.prepared import RunCache, scene_caster
    from sonar_embree.raycast import RayCaster

    tiles, cache = se.TiledDEM(_write_dem(tmp_path / "dem.tif"), tile_px=16), RunCache(scenes=2)
    first = tiles.scene_around(np.array([[X0 + 8.0, Y0 - 20.0, -40.0]]), 4.0)
    ref = weakref.ref(scene_caster(first.compiled(), RayCaster, cache))
    scene_ref = weakref.ref(first.compiled())
    del first
    gc.collect()
    gc.disable()
    try:
        assert ref() is not None                                        # kept while its scene is cached
        for x in (40.0, 72.0):                                          # two other tile sets: the first evicted
            scene_caster(tiles.scene_around(np.array([[X0 + x, Y0 - 20.0, -40.0]]), 4.0).compiled(), RayCaster, cache)
        assert ref() is None and scene_ref() is None
    finally:
        gc.enable()
