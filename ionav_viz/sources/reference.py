"""A reference trajectory given in a local world frame (``nav_msgs/Odometry``, ``PoseStamped``),
placed on the earth.

Post-processed solutions and localisation stacks often publish their trajectory as poses in a
local frame (``map``, ``odom``, ``enu``) rather than as NavSatFix. ionav-viz scores against
latitude and longitude, so such a frame needs its origin (``--truth-origin``):

* ``LAT,LON`` or ``LAT,LON,YAW``: the frame's origin in WGS84 degrees; its x axis points ``YAW``
  degrees counter-clockwise from east (default 0: x east, y north, REP 103's ENU). Positions are
  metres on the local east-north plane about the origin (:func:`~ionav_viz.core.geo.local_en_m`).
* ``auto``: the frame's origin and rotation fitted to the receiver's fixes (a rigid 2D least-squares
  fit, Kabsch/Umeyama without scale, over the fixes inside the reference's time span). The fitted
  origin, rotation and the RMS distance of the fixes from the placed reference are reported; the
  reference inherits the receiver's mean offset, nothing else of its noise. It needs a reference
  that moves (:data:`MIN_EXTENT_M`), or the rotation is not observable.

Only the horizontal position is used (z is ignored).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from ..core.geo import geodetic_of_en_m, local_en_m

#: ``auto`` needs a reference spanning at least this (m) on both the fit's axes together, and this many fixes.
MIN_EXTENT_M = 20.0
MIN_FIXES = 10
#: A local frame's positions beyond this (m) from its origin are an error (a frame in the wrong units, UTM given as
#local).
MAX_LOCAL_M = 2_000_000.0


@dataclass(frozen=True)
class FrameOrigin:
    """Where a local frame lies on the earth: ``lat_deg``/``lon_deg`` of its origin and the angle of
    its x axis counter-clockwise from east (``yaw_deg``)."""

    lat_deg: float
    lon_deg: float
    yaw_deg: float = 0.0


def parse_origin(text: str) -> FrameOrigin | str:
    """``"auto"`` or ``"LAT,LON[,YAW]"`` (degrees) -> ``"auto"`` or a :class:`FrameOrigin`; an error naming
    ``truth_origin``."""
    text = text.strip()
    if text == "auto":
        return "auto"
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if (len(values) not in (2, 3) or not all(math.isfinite(v) for v in values) or abs(values[0]) > 90
            or abs(values[1]) > 180):
        raise InputError(f"truth origin {text!r} is not auto or LAT,LON[,YAW] in degrees",
                         "e.g. 52.4089,-1.5104 (x east, y north) or auto", param="truth_origin")
    return FrameOrigin(*values)


def place_reference(local: np.ndarray, origin: FrameOrigin | str | None, fixes: np.ndarray,
                    where: str) -> tuple[np.ndarray, str]:
    """Reference positions ``(t s, x m, y m)`` in a local frame -> ``(t s, lat deg, lon deg)``.

    ``fixes``: the receiver's ``(t s, lat deg, lon deg, ...)``, for ``"auto"``. ``where`` names the
    topic in errors. Returns the positions and a sentence saying how they were placed.
    """
    t, x, y = local[:, 0], local[:, 1], local[:, 2]
    if origin is None:
        raise InputError(f"{where}: the reference is in a local frame (metres), which needs its place on the earth",
                         "give the frame's origin as LAT,LON[,YAW] (x east, y north by default) or auto "
                         "(fitted to the receiver's fixes)", param="truth_origin")
    if not (np.isfinite(x).all() and np.isfinite(y).all()) or max(np.abs(x).max(), np.abs(y).max()) > MAX_LOCAL_M:
        bad = int(np.argmax(~np.isfinite(x) | ~np.isfinite(y) | (np.abs(x) > MAX_LOCAL_M) | (np.abs(y) > MAX_LOCAL_M)))
        raise InputError(f"{where}: reference position {float(x[bad])!r}, {float(y[bad])!r} m at {t[bad]:.3f} s is not "
                         f"within {MAX_LOCAL_M / 1000:.0f} km of its frame's origin",
                         "give a reference in a local metric frame (map, odom, enu)")
    if origin == "auto":
        origin, rms_m, n = fit_origin(t, x, y, fixes, where)
        how = (f"placed on the receiver's fixes (--truth-origin auto): origin {origin.lat_deg:.7f}, "
               f"{origin.lon_deg:.7f}, x axis {origin.yaw_deg:+.2f} deg from east; the fixes lie {rms_m:.2f} m RMS "
               f"from it over {n} fixes")
    else:
        how = (f"its frame's origin {origin.lat_deg:.7f}, {origin.lon_deg:.7f}, "
               f"x axis {origin.yaw_deg:+.2f} deg from east")
    c, s = math.cos(math.radians(origin.yaw_deg)), math.sin(math.radians(origin.yaw_deg))
    lat, lon = geodetic_of_en_m(c * x - s * y, s * x + c * y, origin.lat_deg, origin.lon_deg)
    return np.column_stack([t, lat, lon]), how


def fit_origin(t: np.ndarray, x: np.ndarray, y: np.ndarray, fixes: np.ndarray,
               where: str) -> tuple[FrameOrigin, float, int]:
    """The frame whose rotation and origin best put the reference on the receiver's fixes: the
    fixes inside the reference's span, the reference interpolated at their stamps, and the rigid
    least-squares fit (no scale). Returns the origin, the RMS residual (m) and the fixes used."""
    inside = (fixes[:, 0] >= t[0]) & (fixes[:, 0] <= t[-1])
    f_t, f_lat, f_lon = fixes[inside, 0], fixes[inside, 1], fixes[inside, 2]
    if len(f_t) < MIN_FIXES:
        raise InputError(f"{where}: only {len(f_t)} receiver fixes lie within the reference's time span; placing it "
                         f"automatically needs {MIN_FIXES}",
                         "give the frame's origin as LAT,LON[,YAW]", param="truth_origin")
    lat0, lon0 = float(f_lat[0]), float(f_lon[0])
    east, north = local_en_m(f_lat, f_lon, lat0, lon0)
    a = np.column_stack([np.interp(f_t, t, x), np.interp(f_t, t, y)])
    b = np.column_stack([east, north])
    a_mean, b_mean = a.mean(axis=0), b.mean(axis=0)
    ac, bc = a - a_mean, b - b_mean
    if np.sqrt((ac**2).sum(axis=1).mean()) < MIN_EXTENT_M / 2:
        raise InputError(f"{where}: the reference moves too little for its origin to be placed automatically "
                         f"(under {MIN_EXTENT_M:.0f} m across)", "give the frame's origin as LAT,LON[,YAW]",
                         param="truth_origin")
    yaw = math.atan2(float((ac[:, 0] * bc[:, 1] - ac[:, 1] * bc[:, 0]).sum()), float((ac * bc).sum()))
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    shift = b_mean - rot @ a_mean  # where the frame's origin lies, in metres about the first fix
    rms = float(np.sqrt((((a @ rot.T) + shift - b) ** 2).sum(axis=1).mean()))
    lat, lon = geodetic_of_en_m(np.array([shift[0]]), np.array([shift[1]]), lat0, lon0)
    return FrameOrigin(float(lat[0]), float(lon[0]), math.degrees(yaw)), rms, len(f_t)
