"""Bathymetry from a DEM (issue: real surveys; docs/physics.md §15): GeoTIFF and XYZ grids in a CRS.

The GeoTIFF is written here with rasterio directly, north-up with a known transform; a cone's apex sits on
one pixel centre, so a half-pixel or a flipped-row mistake moves it by metres.
"""
import numpy as np
import pytest
import rasterio
from rasterio.transform import Affine

import sonar_embree as se

CRS, PIXEL, X0, Y0 = "EPSG:32632", 1.0, 532000.0, 6017100.0      # upper-left corner of the raster
NX, NY, FLOOR, APEX, SLOPE = 80, 60, -60.0, -35.0, 2.5
I_APEX, J_APEX = 17, 41                                            # row (from the north), column of the apex
NODATA = -9999.0


def _apex_xy():
    return X0 + (J_APEX + 0.5) * PIXEL, Y0 - (I_APEX + 0.5) * PIXEL  # pixel centre, north-up


def _heights():
    x = X0 + (np.arange(NX) + 0.5) * PIXEL
    y = Y0 - (np.arange(NY) + 0.5) * PIXEL
    xa, ya = _apex_xy()
    rho = np.hypot(x[None, :] - xa, y[:, None] - ya)
    z = np.maximum(FLOOR, APEX - SLOPE * rho)
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
    assert np.all(mesh.face_normals[:, 2] > 0) and v[:, 2].min() == FLOOR
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
    """A line east over the apex: the ping above it measures the altitude to the apex, and its record's first
    echo (the nearest point of the cone is its apex) lies at 2·altitude/c, within one sample."""
    scene = se.Scene().add(se.seafloor.from_dem(_write_dem(tmp_path / "dem.tif")), label="seafloor")
    xa, ya = _apex_xy()
    z = -20.0
    line = se.Trajectory.line((xa - 4.0, ya, z), (xa + 4.0, ya, z), 5).stop_and_hop()
    rec = se.simulate(scene, line, se.Sonar(max_range_m=40.0))
    assert rec.attrs["crs"] == CRS and rec.trajectory.crs == CRS    # the trajectory takes the scene's CRS
    dt = rec.time_s[1] - rec.time_s[0]
    c = rec.sonar.sound_speed_m_s
    altitude = z - APEX
    assert abs(rec.altitude_m[2] - altitude) < c * dt / 2
    for side in (rec.port[2], rec.starboard[2]):
        first = rec.time_s[np.flatnonzero(side > 0)[0]]
        assert abs(first - 2 * altitude / c) <= dt * (1 + 1e-9)
    assert abs(rec.altitude_m[0] - (z - (APEX - SLOPE * 4.0))) < c * dt / 2   # 4 m west, on the flank


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
    line = se.Trajectory(np.array([[X0 + 40.0, Y0 - 30.0, -20.0]]), crs="EPSG:25832")
    with pytest.raises(se.ConfigError, match="CRS EPSG:25832 differs from the scene's EPSG:32632"):
        se.simulate(scene, line)
