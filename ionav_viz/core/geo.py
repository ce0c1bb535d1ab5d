"""Geodesy on WGS84: geodesics between positions, and positions on a local east-north plane."""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np


@cache
def wgs84() -> Any:
    """The WGS84 ellipsoid's geodesics (a ``pyproj.Geod``: ``inv`` for distance and azimuths,
    ``fwd`` to move along a geodesic); pyproj imported on first use."""
    from pyproj import Geod

    return Geod(ellps="WGS84")


def local_en_m(lat_deg: np.ndarray, lon_deg: np.ndarray, lat0_deg: float, lon0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """East and north (m) of positions relative to an origin (azimuthal equidistant projection:
    true distances from the origin, and local scale within 1e-4 over 100 km)."""
    from pyproj import Transformer

    to_local = Transformer.from_crs("EPSG:4326", f"+proj=aeqd +lat_0={lat0_deg} +lon_0={lon0_deg} +datum=WGS84", always_xy=True)
    east, north = to_local.transform(np.asarray(lon_deg), np.asarray(lat_deg))
    return np.asarray(east), np.asarray(north)


def geodetic_of_en_m(east_m: np.ndarray, north_m: np.ndarray, lat0_deg: float, lon0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Latitude and longitude (deg) of east and north offsets (m) from an origin: the inverse of
    :func:`local_en_m` (the same azimuthal equidistant projection)."""
    from pyproj import Transformer

    to_local = Transformer.from_crs("EPSG:4326", f"+proj=aeqd +lat_0={lat0_deg} +lon_0={lon0_deg} +datum=WGS84", always_xy=True)
    lon, lat = to_local.transform(np.asarray(east_m, dtype=float), np.asarray(north_m, dtype=float), direction="INVERSE")
    return np.asarray(lat), np.asarray(lon)
