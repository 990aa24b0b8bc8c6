"""Coordinate reference systems: the only module that imports pyproj (docs/physics.md §15).

The world frame of a georeferenced scene or trajectory is a projected CRS in metres (x east, y north,
z up; e.g. a UTM zone, EPSG 326zz north / 327zz south), held in float64 around a local origin as for any
scene. Latitude and longitude (WGS 84, EPSG:4326, degrees) go in and out through pyproj's transformations,
always in (longitude, latitude) = (x, y) order.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..errors import ConfigError

#: Geographic coordinates in and out: WGS 84 longitude/latitude, degrees.
LONLAT = "EPSG:4326"


@functools.lru_cache(maxsize=64)
def _crs(value: int | str):
    import pyproj

    try:
        return pyproj.CRS.from_user_input(value)
    except pyproj.exceptions.CRSError as exc:
        raise ConfigError(f"unknown CRS {value!r} ({exc})") from None


def crs_name(value) -> str:
    """The canonical name of a projected CRS in metres ("EPSG:32632" for 32632, "epsg:32632", a WKT or PROJ string
    of a known code); a geographic CRS or one in other units is refused (the world frame is in metres)."""
    if isinstance(value, (bool, float)) or value is None:
        raise ConfigError(f"CRS must be an EPSG code or a CRS string, got {value!r}")
    crs = _crs(int(value) if isinstance(value, (int, np.integer)) else str(value))
    if not crs.is_projected:
        raise ConfigError(f"CRS {value!r} is not projected: the world frame needs one in metres (e.g. a UTM zone)")
    units = {a.unit_name for a in crs.axis_info[:2]}
    if units != {"metre"}:
        raise ConfigError(f"CRS {value!r} is in {', '.join(sorted(units))}, not metres")
    code = crs.to_epsg()
    return f"EPSG:{code}" if code is not None else crs.to_wkt()


@functools.lru_cache(maxsize=64)
def _transformer(src: str, dst: str):
    import pyproj

    return pyproj.Transformer.from_crs(_crs(src), _crs(dst), always_xy=True)


def from_lonlat(crs, lon_deg, lat_deg):
    """Project WGS 84 longitude and latitude (degrees, any matching shapes) into ``crs``: (x, y) in metres."""
    lon, lat = np.asarray(lon_deg, dtype=np.float64), np.asarray(lat_deg, dtype=np.float64)
    if np.any(np.abs(lat) > 90.0) or np.any(np.abs(lon) > 360.0):
        bad = float(lat.flat[np.argmax(np.abs(lat))]) if np.any(np.abs(lat) > 90.0) else float(
            lon.flat[np.argmax(np.abs(lon))])
        raise ConfigError(f"latitude/longitude {bad:g} out of range (degrees expected; are these metres?)")
    return _transformer(LONLAT, crs_name(crs)).transform(lon, lat)


def to_lonlat(crs, x_m, y_m):
    """Unproject world (x, y) in metres of ``crs`` to WGS 84 (longitude, latitude) in degrees."""
    return _transformer(crs_name(crs), LONLAT).transform(np.asarray(x_m, dtype=np.float64),
                                                          np.asarray(y_m, dtype=np.float64))


#: The step along a heading used to turn it between grid and true north, m (short against the map's curvature).
HEADING_STEP_M = 1.0


def true_heading_deg(crs, x_m, y_m, grid_heading_deg):
    """Grid headings (clockwise from the projected CRS's grid north, degrees) at world points (x, y) of ``crs``
    as true headings (clockwise from true north on WGS 84, degrees, [0, 360)): the forward azimuth from each point
    to a point :data:`HEADING_STEP_M` along it. The difference is the meridian convergence (some 1° at 54° N a
    zone's half-width from its central meridian, 2.6° at its edge at 60° N); XTF headings are true headings."""
    import pyproj

    x, y = np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64)
    h = np.radians(np.asarray(grid_heading_deg, dtype=np.float64))
    lon0, lat0 = to_lonlat(crs, x, y)
    lon1, lat1 = to_lonlat(crs, x + HEADING_STEP_M * np.sin(h), y + HEADING_STEP_M * np.cos(h))
    az = pyproj.Geod(ellps="WGS84").inv(lon0, lat0, lon1, lat1)[0]
    return np.mod(az, 360.0)


def grid_heading_deg(crs, x_m, y_m, true_heading_deg_):
    """The inverse of :func:`true_heading_deg`: true headings at world points (x, y) of ``crs`` as grid headings
    (degrees, [0, 360)) — an XTF file's SensorHeading in the frame its positions are projected into."""
    import pyproj

    x, y = np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64)
    lon0, lat0 = to_lonlat(crs, x, y)
    az = np.broadcast_to(np.asarray(true_heading_deg_, dtype=np.float64), np.shape(lon0))
    lon1, lat1, _ = pyproj.Geod(ellps="WGS84").fwd(lon0, lat0, az, np.full(np.shape(lon0), HEADING_STEP_M))
    x1, y1 = from_lonlat(crs, lon1, lat1)
    return np.mod(np.degrees(np.arctan2(np.asarray(x1) - x, np.asarray(y1) - y)), 360.0)


def utm_crs(lon_deg: float, lat_deg: float) -> str:
    """The WGS 84 UTM zone holding a point: "EPSG:326zz" north of the equator, "EPSG:327zz" south (plain 6° zones,
    without the Norway and Svalbard exceptions)."""
    if not abs(lat_deg) <= 84.0:
        raise ConfigError(f"latitude {lat_deg:g} lies outside UTM (|lat| ≤ 84°)")
    zone = int(math.floor(((lon_deg + 180.0) % 360.0) / 6.0)) + 1
    return f"EPSG:{(32600 if lat_deg >= 0 else 32700) + min(zone, 60)}"


def crs_wkt(value) -> str:
    """The WKT (2019) of a CRS, as CF's ``crs_wkt`` attribute holds it."""
    return _crs(crs_name(value)).to_wkt()
