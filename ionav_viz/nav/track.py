"""Rebuilding a 2D track from per-window displacement and yaw rate (the paper's Eq. 19).

Starting from the last GNSS fix and course, each 1-second window moves the position along
the geodesic (pyproj ``Geod.fwd``, WGS84) by the window's displacement, in the direction of the
course at the middle of the window; the course turns by -yaw_rate * 1 s over the window
(course clockwise, yaw rate counter-clockwise positive).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.geo import radii_of_curvature_m, wgs84
from ..core.grid import WINDOW_S
from .windows import Windows


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


#: Below this distance in a window (m) a track's own direction is noise: its course is held.
MIN_COURSE_DISTANCE_M = 0.05


def windows_of_track(lat_deg: np.ndarray, lon_deg: np.ndarray,
                     heading0_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-window distance (m) and yaw rate (rad/s, counter-clockwise) of positions at window
    boundaries ``(n_sequences, n_windows + 1)``: what :func:`rebuild_track` takes, from a track.

    Distance is the geodesic between consecutive boundaries. A window's yaw rate is the change of
    the track's direction of travel from the window before (from ``heading0_deg``, the course at
    the start, for the first), over the window's length: exact for a steady turn, a two-window
    mean of a rebuilt track's turns; a window under :data:`MIN_COURSE_DISTANCE_M` keeps the
    direction before it (standing still, a track's direction is its noise).
    """
    geod = wgs84()
    lat, lon = np.asarray(lat_deg, dtype=float), np.asarray(lon_deg, dtype=float)
    n_seq, n_b = lat.shape
    if n_seq == 0:
        return np.zeros((0, n_b - 1)), np.zeros((0, n_b - 1))
    az, _, dist = geod.inv(lon[:, :-1], lat[:, :-1], lon[:, 1:], lat[:, 1:])
    dist, az = np.asarray(dist).reshape(n_seq, -1), np.asarray(az).reshape(n_seq, -1)
    yaw = np.zeros_like(dist)
    direction = np.asarray(heading0_deg, dtype=float).copy()
    for w in range(dist.shape[1]):
        moved = dist[:, w] >= MIN_COURSE_DISTANCE_M
        turn = np.where(moved, (az[:, w] - direction + 180.0) % 360.0 - 180.0, 0.0)
        yaw[:, w] = -np.deg2rad(turn) / WINDOW_S
        direction = direction + turn
    return dist, yaw


def track_covariance(heading0_deg: np.ndarray, disp_m: np.ndarray, yaw_rate_radps: np.ndarray, var_disp_m2: np.ndarray,
                     var_yaw_radps2: np.ndarray, var_heading0_rad2: np.ndarray | float = 0.0) -> np.ndarray:
    """The east/north covariance (m^2) of a rebuilt track at every window boundary, shape
    ``(n_sequences, n_windows + 1, 2, 2)`` (zero at the start fix), linearised about the track
    :func:`rebuild_track` makes (flat-Earth steps: metres, not geodesics).

    Each window's distance and yaw rate errors are independent, of variances ``var_disp_m2`` and
    ``var_yaw_radps2`` (arrays as ``disp_m``); the course at the start has ``var_heading0_rad2``.
    Position ``p_k = sum_{j<k} d_j u(psi_j)``, ``u(psi) = (sin psi, cos psi)`` (course clockwise),
    ``psi_j = psi_0 - T (sum_{i<j} w_i + w_j / 2)``: a distance error moves along ``u_j``, a course
    error ``dpsi`` moves every later step by ``d_j u'(psi_j) dpsi`` (:class:`TrackCovariance`)."""
    return TrackCovariance(heading0_deg, disp_m, yaw_rate_radps)(var_disp_m2, var_yaw_radps2, var_heading0_rad2)


class TrackCovariance:
    """:func:`track_covariance` of one set of rebuilt tracks, for any variances: the track's
    geometry is worked out once (a fit that tries many variances on the same tracks pays it once),
    and each call costs a few cumulative sums, linear in the windows.

    The yaw rate of window ``i`` turns the course of window ``i`` by half a window's turn and of
    every later window by the whole: at boundary ``k > i`` it moves the position by
    ``J_i(k) dw_i``, ``J_i(k) = -T (d_i u'_i / 2 + sum_{i<j<k} d_j u'_j) = -T (a_i + c_k)`` with
    ``c_k = sum_{j<k} d_j u'_j`` and ``a_i = d_i u'_i / 2 - c_{i+1}``, so
    ``sum_{i<k} var_i J_i J_i^T = T^2 (S2_k + S1_k c_k^T + c_k S1_k^T + S0_k c_k c_k^T)`` with the
    cumulative sums ``S0_k = sum_{i<k} var_i``, ``S1_k = sum_{i<k} var_i a_i`` and
    ``S2_k = sum_{i<k} var_i a_i a_i^T``."""

    def __init__(self, heading0_deg: np.ndarray, disp_m: np.ndarray, yaw_rate_radps: np.ndarray) -> None:
        disp = np.asarray(disp_m, dtype=float)
        yaw = np.asarray(yaw_rate_radps, dtype=float)
        n_seq = disp.shape[0]
        self.shape = disp.shape
        turn = -yaw * WINDOW_S  # clockwise course change per window (rad)
        psi0 = np.deg2rad(np.asarray(heading0_deg, dtype=float)).reshape(n_seq, 1)
        before = np.concatenate([np.zeros((n_seq, 1)), np.cumsum(turn, axis=1)[:, :-1]], axis=1)
        psi = psi0 + before + 0.5 * turn  # each window's mid course
        u = np.stack([np.sin(psi), np.cos(psi)], axis=-1)  # (n, w, 2)
        du = np.stack([np.cos(psi), -np.sin(psi)], axis=-1) * disp[..., None]  # d_j u'(psi_j)
        c = np.concatenate([np.zeros((n_seq, 1, 2)), np.cumsum(du, axis=1)], axis=1)  # c_k: sum over j < k of d_j u'_j
        a = 0.5 * du - c[:, 1:]  # a_i
        self.uu = u[..., :, None] * u[..., None, :]  # (n, w, 2, 2)
        self.aa = a[..., :, None] * a[..., None, :]
        self.a, self.c = a, c
        self.cc = c[..., :, None] * c[..., None, :]  # (n, w + 1, 2, 2)

    def __call__(self, var_disp_m2: np.ndarray, var_yaw_radps2: np.ndarray,
                 var_heading0_rad2: np.ndarray | float = 0.0) -> np.ndarray:
        """The covariance (m^2, ``(n_sequences, n_windows + 1, 2, 2)``) for these variances (as
        :func:`track_covariance`)."""
        n_seq, n_win = self.shape
        var_d = np.broadcast_to(np.asarray(var_disp_m2, dtype=float), self.shape)
        var_w = np.broadcast_to(np.asarray(var_yaw_radps2, dtype=float), self.shape)
        v0 = np.broadcast_to(np.asarray(var_heading0_rad2, dtype=float), (n_seq,))
        out = np.zeros((n_seq, n_win + 1, 2, 2))
        # distance errors: sum_{j<k} var_d_j u_j u_j^T
        out[:, 1:] = np.cumsum(var_d[..., None, None] * self.uu, axis=1)
        # the initial course: moves every step so far together
        out += v0[:, None, None, None] * self.cc
        # the yaw rates (the class's docstring)
        s0 = np.cumsum(var_w, axis=1)
        s1 = np.cumsum(var_w[..., None] * self.a, axis=1)
        s2 = np.cumsum(var_w[..., None, None] * self.aa, axis=1)
        c = self.c[:, 1:]
        cross = s1[..., :, None] * c[..., None, :]
        out[:, 1:] += WINDOW_S**2 * (s2 + cross + np.swapaxes(cross, -1, -2) + s0[..., None, None] * self.cc[:, 1:])
        return out


def systematic_track_covariance(heading0_deg: np.ndarray, disp_m: np.ndarray, yaw_rate_radps: np.ndarray,
                                scale_sigma: np.ndarray | float,
                                gyro_bias_sigma_radps: np.ndarray | float) -> np.ndarray:
    """The east/north covariance (m^2, ``(n_sequences, n_windows + 1, 2, 2)``) a rebuilt track gets
    from two errors that hold through an outage: a relative scale error of every distance
    (``scale_sigma``: the position error is that share of the position reached) and a yaw-rate bias
    (``gyro_bias_sigma_radps``: window ``j``'s course is off by ``T (j + 1/2)`` times it), linearised
    as :func:`track_covariance` is."""
    disp = np.asarray(disp_m, dtype=float)
    yaw = np.asarray(yaw_rate_radps, dtype=float)
    n_seq, n_win = disp.shape
    T = WINDOW_S
    turn = -yaw * T
    psi0 = np.deg2rad(np.asarray(heading0_deg, dtype=float)).reshape(n_seq, 1)
    psi = psi0 + np.concatenate([np.zeros((n_seq, 1)), np.cumsum(turn, axis=1)[:, :-1]], axis=1) + 0.5 * turn
    step = np.stack([np.sin(psi), np.cos(psi)], axis=-1) * disp[..., None]
    reached = np.concatenate([np.zeros((n_seq, 1, 2)), np.cumsum(step, axis=1)], axis=1)
    du = np.stack([np.cos(psi), -np.sin(psi)], axis=-1) * disp[..., None]
    lever = -T * (np.arange(n_win) + 0.5)[None, :, None] * du
    bias_dir = np.concatenate([np.zeros((n_seq, 1, 2)), np.cumsum(lever, axis=1)], axis=1)
    s2 = np.broadcast_to(np.asarray(scale_sigma, dtype=float) ** 2, (n_seq,))[:, None, None, None]
    b2 = np.broadcast_to(np.asarray(gyro_bias_sigma_radps, dtype=float) ** 2, (n_seq,))[:, None, None, None]
    return s2 * np.einsum("nka,nkb->nkab", reached, reached) + b2 * np.einsum("nka,nkb->nkab", bias_dir, bias_dir)


def boundary_errors_en_m(windows: Windows, starts: np.ndarray, n_windows: int, lat_deg: np.ndarray,
                         lon_deg: np.ndarray) -> np.ndarray:
    """The east/north error (m) of positions ``lat_deg``/``lon_deg`` ``(m, n_windows + 1)`` (WGS84
    degrees) against the windows' fixes at the boundaries of the sequences starting at windows
    ``starts`` (m,): ``(m, n_windows + 1, 2)``, the first at the start fix; metres along the
    ellipsoid's radii of curvature at the fix."""
    lat_t, lon_t, _ = windows.boundary_fixes(starts, n_windows)
    meridian, prime = radii_of_curvature_m(lat_t)
    north = np.radians(lat_deg - lat_t) * meridian
    east = np.radians(lon_deg - lon_t) * prime * np.cos(np.radians(lat_t))
    return np.stack([east, north], axis=-1)
