"""Bathymetry from an interferometric side-scan record: its soundings and their grid beside the truth
(docs/physics.md §18b).

The soundings are :func:`sonar_embree.signal.interferometry.interferometric_points` (a
:class:`~sonar_embree.signal.interferometry.PointCloud`); :func:`grid` puts them on a north-up
:class:`~sonar_embree.survey.mosaic.Mosaic` (mean height per pixel), the grid that
:func:`~sonar_embree.survey.mosaic.write_truth` writes the scene's truth on.
"""
from __future__ import annotations

from ..signal.interferometry import PointCloud, interferometric_points
from .mosaic import Mosaic


def grid(cloud: PointCloud, pixel_m: float = 0.5, bounds_m=None) -> Mosaic:
    """The soundings' mean height per pixel (``Mosaic.height_m``; ``intensity`` holds the mean coherence, ``count``
    the soundings) over ``bounds_m`` (xmin, ymin, xmax, ymax) or the soundings' extent; ``to_geotiff`` writes it."""
    g = cloud.grid_arrays(pixel_m, bounds_m)
    return Mosaic(g["coherence"], g["height_m"], g["count"], g["x0_m"], g["y0_m"], g["pixel_m"], cloud.crs,
                  "coherence", "1")


__all__ = ["PointCloud", "grid", "interferometric_points"]
