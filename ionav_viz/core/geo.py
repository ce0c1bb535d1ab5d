"""Geodesy on WGS84: geodesics between positions, and positions on a local east-north plane."""

from __future__ import annotations

import threading
from functools import cache, lru_cache
from typing import Any

import numpy as np


@cache
def wgs84() -> Any:
    """The WGS84 ellipsoid's geodesics (a ``pyproj.Geod``: ``inv`` for distance and azimuths,
    ``fwd`` to move along a geodesic); pyproj imported on first use."""
    from pyproj import Geod

    return Geod(ellps="WGS84")


def _aeqd(lat0_deg: float, lon0_deg: float) -> Any:
    """The transformer from WGS84 longitude, latitude to the azimuthal equidistant plane at the origin."""
    return _aeqd_of_thread(float(lat0_deg), float(lon0_deg), threading.get_ident())


@lru_cache(maxsize=64)  # making one costs ~10 ms; a pyproj Transformer is not to be shared across threads
def _aeqd_of_thread(lat0_deg: float, lon0_deg: float, thread: int) -> Any:
    from pyproj import Transformer

    return Transformer.from_crs("EPSG:4326", f"+proj=aeqd +lat_0={lat0_deg} +lon_0={lon0_deg} +datum=WGS84",
                                always_xy=True)


def local_en_m(lat_deg: np.ndarray, lon_deg: np.ndarray, lat0_deg: float,
               lon0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """East and north (m) of positions relative to an origin (azimuthal equidistant projection:
    true distances from the origin, and local scale within 1e-4 over 100 km)."""
    to_local = _aeqd(lat0_deg, lon0_deg)
    east, north = to_local.transform(np.asarray(lon_deg), np.asarray(lat_deg))
    return np.asarray(east), np.asarray(north)


def geodetic_of_en_m(east_m: np.ndarray, north_m: np.ndarray, lat0_deg: float,
                     lon0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Latitude and longitude (deg) of east and north offsets (m) from an origin: the inverse of
    :func:`local_en_m` (the same azimuthal equidistant projection)."""
    to_local = _aeqd(lat0_deg, lon0_deg)
    lon, lat = to_local.transform(np.asarray(east_m, dtype=float), np.asarray(north_m, dtype=float),
                                  direction="INVERSE")
    return np.asarray(lat), np.asarray(lon)


#: WGS84 Earth rotation rate (rad/s).
EARTH_RATE_RADPS = 7.292115e-5
#: WGS84 semi-major axis (m) and first eccentricity squared.
WGS84_A_M, WGS84_E2 = 6_378_137.0, 6.694379990141317e-3


def radii_of_curvature_m(lat_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The WGS84 radii of curvature (m) at ``lat_deg``: meridian (north-south) and prime vertical
    (east-west; a parallel's radius is it times the latitude's cosine)."""
    sin2 = np.sin(np.radians(lat_deg)) ** 2
    return WGS84_A_M * (1 - WGS84_E2) / (1 - WGS84_E2 * sin2) ** 1.5, WGS84_A_M / np.sqrt(1 - WGS84_E2 * sin2)


def normal_gravity_mps2(lat_deg: float, height_m: float = 0.0) -> float:
    """Magnitude of normal gravity (m/s^2) on WGS84 at ``lat_deg``: Somigliana's formula with the
    free-air height term (as KF-GINS's ``Earth::gravity``)."""
    s2 = np.sin(np.deg2rad(lat_deg)) ** 2
    g0 = 9.7803253359 * (1.0 + 0.00193185265241 * s2) / np.sqrt(1.0 - 0.00669437999013 * s2)
    return float(g0 - 3.086e-6 * height_m)


def earth_rate_enu_radps(lat_deg: float) -> np.ndarray:
    """The Earth's rotation in a local east-north-up frame at ``lat_deg`` (rad/s, (3,))."""
    lat = np.deg2rad(lat_deg)
    return EARTH_RATE_RADPS * np.array([0.0, np.cos(lat), np.sin(lat)])


def enu_of_geodetic(lat_deg: np.ndarray, lon_deg: np.ndarray, height_m: np.ndarray, lat0_deg: float, lon0_deg: float,
                    height0_m: float) -> np.ndarray:
    """Cartesian east-north-up coordinates (m, (n, 3)) of WGS84 positions in the tangent frame at an
    origin: an Earth-fixed frame, so straight lines in it are straight and up tilts away from the origin."""
    from pyproj import Transformer

    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    x, y, z = to_ecef.transform(np.asarray(lon_deg, dtype=float), np.asarray(lat_deg, dtype=float),
                                np.asarray(height_m, dtype=float))
    x0, y0, z0 = to_ecef.transform(lon0_deg, lat0_deg, height0_m)
    return (np.column_stack([x - x0, y - y0, z - z0])) @ _ecef_to_enu(lat0_deg, lon0_deg).T


def geodetic_of_enu(enu_m: np.ndarray, lat0_deg: float, lon0_deg: float,
                    height0_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Latitude, longitude (deg) and height (m) of tangent-frame positions: the inverse of :func:`enu_of_geodetic`."""
    from pyproj import Transformer

    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    x0, y0, z0 = to_ecef.transform(lon0_deg, lat0_deg, height0_m)
    ecef = np.asarray(enu_m, dtype=float).reshape(-1, 3) @ _ecef_to_enu(lat0_deg, lon0_deg) + np.array([x0, y0, z0])
    lon, lat, h = to_ecef.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2], direction="INVERSE")
    return np.asarray(lat), np.asarray(lon), np.asarray(h)


def _ecef_to_enu(lat0_deg: float, lon0_deg: float) -> np.ndarray:
    """Rotation from ECEF to the east-north-up frame at the origin (rows: east, north, up)."""
    lat, lon = np.deg2rad(lat0_deg), np.deg2rad(lon0_deg)
    return np.array([[-np.sin(lon), np.cos(lon), 0.0],
                     [-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)],
                     [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)]])


#: The Earth's mean radius (m): where "down" points from a tangent-frame position (a sphere's
#: centre; within 0.2 degrees of the ellipsoid's normal, and only its change over a drive matters).
EARTH_MEAN_RADIUS_M = 6_371_000.0
#: Metres per degree of latitude on a sphere of the mean Earth radius (6,371,008.8 m): for local
#: steps and distance checks (of longitude too, times the latitude's cosine), not for positions.
M_PER_DEG = 6_371_008.8 * np.pi / 180.0


def steps_en_m(lat_deg: np.ndarray, lon_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """East and north (m) of each step between consecutive fixes (``len - 1`` of each), on a
    sphere of the mean radius at the step's mean latitude: for step lengths and speeds, not positions."""
    north = np.diff(lat_deg) * M_PER_DEG
    east = np.diff(lon_deg) * M_PER_DEG * np.cos(np.deg2rad(0.5 * (lat_deg[1:] + lat_deg[:-1])))
    return east, north


def gravity_enu_mps2(enu_m: np.ndarray, gravity_mps2: float) -> np.ndarray:
    """Gravity (m/s^2, (n, 3)) at tangent-frame positions (m, (n, 3)): ``gravity_mps2`` towards the
    Earth's centre, which lies EARTH_MEAN_RADIUS_M below the origin; at the origin ``(0, 0, -g)``."""
    r = np.asarray(enu_m, dtype=float) + np.array([0.0, 0.0, EARTH_MEAN_RADIUS_M])
    return -gravity_mps2 * r / np.linalg.norm(r, axis=-1, keepdims=True)
