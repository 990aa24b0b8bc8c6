"""DEMs larger than memory: tiles meshed as the pings need them (docs/physics.md §17).

The raster is cut into square tiles of ``tile_px`` pixel cells; tile (i, j) meshes the cells between pixel
rows i·T … (i+1)·T and columns j·T … (j+1)·T (the boundary pixels are shared, so the tiles' triangles are
exactly those of :func:`~sonar_embree.seafloor.from_dem` on the whole raster, without cracks). For a set of
sonar positions, :meth:`TiledDEM.scene_around` builds a scene of the tiles within reach of them; tiles and
the last scenes (with their compiled BVHs) are kept in small caches, so memory follows the swath and a
streamed line (:func:`~sonar_embree.survey.stream.render_line`) rebuilds a BVH only when its pings reach new tiles.
"""
from __future__ import annotations

import os
from collections import OrderedDict

import numpy as np

from ..config import Material
from ..errors import ConfigError
from .meshes import Scene
from .seafloor import declared_nodata, grid_mesh


class TiledDEM:
    """A DEM raster meshed tile by tile.

    Parameters
    ----------
    path : str or PathLike
        A GeoTIFF (or any raster GDAL reads) in a projected CRS, metres; nodata pixels are holes.
    tile_px : int
        Tile size in pixel cells.
    material : Material, optional
        The seafloor's material.
    cache_tiles : int
        Tile meshes kept in memory.
    band : int
        The raster band holding the heights (from 1).
    nodata : float, optional
        A height meaning "no data" beyond the raster's own (a common sentinel held but not declared is refused
        when its tile is read, see :func:`~sonar_embree.seafloor.declared_nodata`).
    """

    def __init__(self, path, tile_px: int = 256, material: Material | None = None, cache_tiles: int = 64,
                 band: int = 1, nodata: float | None = None):
        from ..io.geotiff import raster_info

        for name, value, low in (("tile_px", tile_px, 2), ("cache_tiles", cache_tiles, 1), ("band", band, 1)):
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
                raise ConfigError(f"TiledDEM: {name} must be an integer >= {low}, got {value!r}")
        if nodata is not None and (isinstance(nodata, bool) or not isinstance(nodata, (int, float, np.number))):
            raise ConfigError(f"TiledDEM: nodata must be a number, got {nodata!r}")
        self.nodata = nodata
        self.info = raster_info(path, band)
        self.path, self.tile_px, self.band = self.info.path, int(tile_px), band
        self.material = material or Material()
        self.crs = None
        if self.info.crs is not None:
            from ..io.geo import crs_name

            try:
                self.crs = crs_name(self.info.crs)
            except ConfigError as exc:
                raise ConfigError(f"{self.path}: {exc}") from None
        self._tiles: OrderedDict = OrderedDict()
        self._scenes: OrderedDict = OrderedDict()
        self._cache_tiles = int(cache_tiles)

    @property
    def n_tiles(self) -> tuple:
        """(rows, columns) of tiles."""
        ny, nx = self.info.shape
        return (-(-(ny - 1) // self.tile_px), -(-(nx - 1) // self.tile_px))

    def fingerprint(self) -> str:
        """What identifies the DEM for a resumed stream: its path, size, modification time and tiling."""
        st = os.stat(self.path)
        return f"{os.path.abspath(self.path)}:{st.st_size}:{st.st_mtime_ns}:{self.tile_px}:{self.band}:" \
               f"{self.material!r}:{self.nodata!r}"

    def tiles_around(self, positions_m, reach_m: float) -> tuple:
        """The (i, j) of the tiles holding a pixel centre within ``reach_m`` (horizontally, by the bounding box)
        of any of ``positions_m`` (n, 3)."""
        p = np.asarray(positions_m, dtype=np.float64)
        lo, hi = p[:, :2].min(axis=0) - reach_m, p[:, :2].max(axis=0) + reach_m
        x, y = self.info.x_m, self.info.y_m
        cols = np.flatnonzero((x >= lo[0]) & (x <= hi[0]))
        rows = np.flatnonzero((y >= lo[1]) & (y <= hi[1]))
        if cols.size == 0 or rows.size == 0:
            return ()
        t, (ti, tj) = self.tile_px, self.n_tiles
        i_range = range(max(0, (rows[0] - 1) // t), min(ti, rows[-1] // t + 1))
        j_range = range(max(0, (cols[0] - 1) // t), min(tj, cols[-1] // t + 1))
        return tuple((i, j) for i in i_range for j in j_range)

    def _tile(self, i: int, j: int):
        """The mesh of tile (i, j), or None when it has no cell with heights at all its corners."""
        from ..io.geotiff import read_window

        key = (i, j)
        if key in self._tiles:
            self._tiles.move_to_end(key)
            return self._tiles[key]
        ny, nx = self.info.shape
        rows = slice(i * self.tile_px, min((i + 1) * self.tile_px + 1, ny))
        cols = slice(j * self.tile_px, min((j + 1) * self.tile_px + 1, nx))
        z = declared_nodata(read_window(self.info, rows, cols, self.band), self.nodata, f"{self.path} tile {key}")
        try:
            mesh = grid_mesh(self.info.x_m[cols], self.info.y_m[rows], z, where=f"{self.path} tile {key}")
        except ConfigError:
            mesh = None                                             # all nodata
        self._tiles[key] = mesh
        while len(self._tiles) > self._cache_tiles:
            self._tiles.popitem(last=False)
        return mesh

    @property
    def pixel_m(self) -> float:
        """The raster's larger pixel side, m."""
        steps = [abs(float(a[1] - a[0])) for a in (self.info.x_m, self.info.y_m) if a.size > 1]
        return max(steps, default=0.0)

    def scene_around(self, positions_m, reach_m: float, empty_ok: bool = False):
        """A :class:`~sonar_embree.Scene` of the tiles within ``reach_m`` of ``positions_m`` (one object,
        "seafloor"), kept for the next call with the same tiles (its BVH with it). Where no tile there has data:
        an error, or None when ``empty_ok``."""
        keys = self.tiles_around(positions_m, reach_m)
        if keys in self._scenes:
            self._scenes.move_to_end(keys)
            return self._scenes[keys]
        meshes = [m for m in (self._tile(i, j) for i, j in keys) if m is not None]
        if not meshes and empty_ok:
            return None
        if not meshes:
            raise ConfigError(f"{self.path}: no DEM data within {reach_m:g} m of the pings "
                              f"(x {np.min(positions_m, axis=0)[0]:.1f}…, y {np.min(positions_m, axis=0)[1]:.1f}…)")
        scene = Scene().add(_joined(meshes, self.crs), material=self.material, label="seafloor")
        self._scenes[keys] = scene
        while len(self._scenes) > 2:
            self._scenes.popitem(last=False)[1].release()          # its BVHs freed now, not at the next gc
        return scene


def _joined(meshes, crs):
    """One trimesh of several (vertices stacked, faces offset); the CRS in its metadata."""
    import trimesh

    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    mesh = trimesh.Trimesh(np.concatenate([m.vertices for m in meshes]),
                           np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]), process=False)
    mesh.metadata["crs"] = crs
    return mesh
