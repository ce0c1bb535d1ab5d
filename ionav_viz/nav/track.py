"""Rebuilding a 2D track from per-window displacement and yaw rate (the paper's Eq. 19).

Starting from the last GNSS fix and course, each 1-second window moves the position along
the geodesic (pyproj ``Geod.fwd``, WGS84) by the window's displacement, in the direction of the
course at the middle of the window; the course turns by -yaw_rate * 1 s over the window
(course clockwise, yaw rate counter-clockwise positive).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.geo import wgs84
from ..core.grid import WINDOW_S


@dataclass
class Track:
    """Positions and courses at window boundaries: arrays of shape (n_sequences, n_windows + 1)."""

    lat_deg: np.ndarray
    lon_deg: np.ndarray
    heading_deg: np.ndarray


def rebuild_track(
    lat0_deg: np.ndarray,
    lon0_deg: np.ndarray,
    heading0_deg: np.ndarray,
    disp_m: np.ndarray,
    yaw_rate_radps: np.ndarray,
) -> Track:
    """Dead-reckon all sequences at once; loops over the (few) windows, vectorised over sequences."""
    geod = wgs84()
    n_seq, n_win = disp_m.shape
    lat = np.empty((n_seq, n_win + 1))
    lon = np.empty((n_seq, n_win + 1))
    hdg = np.empty((n_seq, n_win + 1))
    lat[:, 0], lon[:, 0], hdg[:, 0] = lat0_deg, lon0_deg, heading0_deg
    turn_deg = -np.rad2deg(yaw_rate_radps) * WINDOW_S
    for w in range(n_win):
        mid = hdg[:, w] + 0.5 * turn_deg[:, w]
        if n_seq:
            lon[:, w + 1], lat[:, w + 1], _ = geod.fwd(lon[:, w], lat[:, w], mid, disp_m[:, w])
        hdg[:, w + 1] = hdg[:, w] + turn_deg[:, w]
    return Track(lat, lon, np.mod(hdg, 360.0))
