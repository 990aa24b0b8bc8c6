"""What mesh and raster checking accepts, in absolute metres (docs/physics.md §9)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MeshTolerance:
    """What mesh checking accepts, in absolute metres (one far vertex cannot change what counts as degenerate).

    Attributes
    ----------
    min_area_m2 : float
        Triangles of smaller area are degenerate and dropped (1e-9 m²: a 45 µm square; below the float32
        resolution of Embree's hits a few metres from the local origin).
    max_coordinate_m : float
        A vertex coordinate beyond this is no place on Earth in any projected CRS (their coordinates stay
        within ±2·10⁷ m): a corrupt file or a unit slip, refused.
    max_height_offset_m : float
        A vertex farther above or below its mesh's median height is an outlier (a DEM spike, an undeclared
        nodata value), refused: the Earth's whole relief spans under 20 km.
    """

    min_area_m2: float = 1e-9
    max_coordinate_m: float = 1e9
    max_height_offset_m: float = 20_000.0


#: The tolerances every mesh and DEM is checked against (:mod:`sonar_embree.scene.meshes`, `seafloor`).
TOLERANCE = MeshTolerance()
