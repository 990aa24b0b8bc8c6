"""Mosaics a surveyor can read (issue 35, item 5): normalised values, receiver codes, GeoTIFF bands with units,
nodata and overviews (read back with rasterio), and a quick-look PNG."""
import numpy as np
import pytest
import rasterio

import sonar_embree as se

E0, N0 = 500_000.0, 6_000_000.0


def _line(sonar, n=40, speckle=False):
    """A line over a flat Lambertian floor 10 m below, in UTM 31N, with labels."""
    scene = se.Scene().add(se.seafloor.flat((200, 200), z_m=-30.0, center_m=(E0, N0)), label="seafloor")
    traj = se.Trajectory.line((E0 - 4, N0, -20.0), (E0 + 4, N0, -20.0), n)
    traj = se.Trajectory(traj.positions_m, traj.heading_deg, times_s=traj.times_s, crs=32631)
    return se.simulate(scene, traj, sonar, labels=True, speckle=speckle, seed=2)


def test_a_flat_floors_normalised_mosaic_is_uniform_across_range():
    """One sediment, a flat floor: the raw mosaic falls by more than 15 dB from near to far range (spreading,
    absorption, the beam and the law); divided line by line by its mean at each slant range (values='normalised')
    every pixel outside the nadir gap is within 1 dB of 1, with or without speckle averaged over the pixel."""
    rec = _line(se.Sonar(max_range_m=30.0))
    raw = se.mosaic.mosaic(rec, pixel_m=0.5)
    db = 10 * np.log10(raw.intensity[np.isfinite(raw.intensity) & (raw.intensity > 0)])
    assert db.max() - db.min() > 15.0
    flat = se.mosaic.mosaic(rec, pixel_m=0.5, values="normalised")
    v = flat.intensity[np.isfinite(flat.intensity)]
    assert v.size > 500 and np.abs(10 * np.log10(v)).max() < 1.0
    assert (flat.values, flat.units) == ("normalised", "1")
    speckled = se.mosaic.mosaic(_line(se.Sonar(max_range_m=30.0), speckle=True), pixel_m=2.0, values="normalised")
    well = speckled.count >= 200                                       # pixels averaging ≥ 200 speckled samples
    assert well.sum() > 20 and np.abs(10 * np.log10(speckled.intensity[well])).max() < 1.0


def test_mosaic_geotiff_has_units_nodata_overviews_and_a_quick_look(tmp_path):
    """The GeoTIFF as rasterio reads it: the CRS, two bands described and with units (µPa² with a source level,
    m), NaN nodata where no sample, average overviews; the receiver's codes can be mosaicked instead; the PNG is
    grey + alpha, transparent where no sample."""
    import imageio.v3 as iio

    rx = se.Receiver(gain=se.TVG(k=30.0, g0_db=20.0))
    rec = _line(se.Sonar(max_range_m=30.0, source_level_db=210.0, receiver=rx))
    grid = se.mosaic.mosaic(rec, pixel_m=0.05)
    grid.to_geotiff(tmp_path / "m.tif")
    with rasterio.open(tmp_path / "m.tif") as src:
        assert src.crs.to_epsg() == 32631 and src.descriptions == ("intensity", "height_m")
        assert src.units == ("uPa^2", "m") and np.isnan(src.nodata)
        assert src.overviews(1) and src.overviews(1)[0] == 2
        assert src.bounds.left >= E0 - 100 and src.bounds.right <= E0 + 100
        band = src.read(1)
        assert np.isnan(band).any() and np.isfinite(band).any()             # the nadir gap and the swaths
    codes = se.mosaic.mosaic(rec, pixel_m=0.05, values="codes")
    finite = codes.intensity[np.isfinite(codes.intensity)]
    assert finite.max() <= 2 ** 16 - 1 and finite.max() > 1 and codes.units == "1"
    with pytest.raises(se.ConfigError, match="values='codes' needs"):
        se.mosaic.mosaic(_line(se.Sonar(max_range_m=30.0)), values="codes")
    with pytest.raises(se.ConfigError, match="values must be one of"):
        se.mosaic.mosaic(rec, values="gain")
    grid.save_png(tmp_path / "m.png")
    img = iio.imread(tmp_path / "m.png")
    assert img.shape == grid.intensity.shape + (2,)
    np.testing.assert_array_equal(img[..., 1] == 0, np.isnan(grid.intensity))


def test_a_streamed_lines_store_mosaics_normalised(tmp_path):
    """A streamed store is normalised as the in-memory record is (two passes over its blocks)."""
    sonar = se.Sonar(max_range_m=30.0)
    rec = _line(sonar, n=24)
    scene = se.Scene().add(se.seafloor.flat((200, 200), z_m=-30.0, center_m=(E0, N0)), label="seafloor")
    se.stream.render_line(scene, rec.trajectory, tmp_path / "l.zarr", sonar, block_pings=8, labels=True,
                          speckle=False)
    a = se.mosaic.mosaic(rec, pixel_m=0.5, values="normalised")
    b = se.mosaic.mosaic(str(tmp_path / "l.zarr"), pixel_m=0.5, values="normalised")
    np.testing.assert_allclose(b.intensity, a.intensity, rtol=1e-9, equal_nan=True)
