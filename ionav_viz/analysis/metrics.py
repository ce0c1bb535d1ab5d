"""The paper's error metrics (Section 3.2), per outage sequence, and their summaries.

The prediction error of a window is ``e = truth - estimate`` (the paper's Eq. 14), for the
displacement (m) and for the orientation rate (rad/s). Over the N windows of one outage:

* CRSE = sum |e|         (cumulative root squared error, Eq. 20: sqrt(e^2) = |e|)
* CAE  = sum e           (cumulative error with its sign, Eq. 21: negative = over-predicting)
* AEPS = CRSE / N        (average error per second, Eq. 22)

Beyond the paper, ``final_position_error_m`` is the geodesic distance between the estimated
and the GNSS position at the end of the outage, and ``final_error_pct`` that error as a
percentage of the distance the car drove in the outage (the GNSS displacements summed; the
drift measure of odometry benchmarks), undefined (NaN) where it drove less than
:data:`MIN_PCT_DISTANCE_M`. Summaries across sequences give max, min, mean and the population
standard deviation (Eq. 24, divided by N_s), over the sequences where the metric is defined.
"""

from __future__ import annotations

import numpy as np

from ..core.geo import wgs84
from ..nav.protocol import Solution
from ..nav.windows import Windows

METRICS = (
    "crse_m",
    "cae_m",
    "aeps_m",
    "yaw_crse_radps",
    "yaw_cae_radps",
    "yaw_aeps_radps",
    "final_position_error_m",
    "final_error_pct",
)

#: Below this distance driven in an outage (m), an error as a percentage of it means nothing.
MIN_PCT_DISTANCE_M = 10.0


def crse(err: np.ndarray) -> np.ndarray:
    """Cumulative root squared error over the last axis."""
    return np.abs(err).sum(axis=-1)


def cae(err: np.ndarray) -> np.ndarray:
    """Cumulative (signed) error over the last axis."""
    return np.asarray(err).sum(axis=-1)


def aeps(err: np.ndarray) -> np.ndarray:
    """Average error per second: CRSE divided by the number of windows."""
    return crse(err) / np.shape(err)[-1]


def truth_for(windows: Windows, starts: np.ndarray, n_windows: int) -> tuple[np.ndarray, np.ndarray]:
    """GNSS displacement (m) and yaw rate (rad/s) of every window of every outage: (seq, win)."""
    idx = np.asarray(starts)[:, None] + np.arange(n_windows)[None, :]
    return windows.gnss_disp_m[idx], windows.gnss_yaw_rate_radps[idx]


def sequence_metrics(windows: Windows, starts: np.ndarray, n_windows: int, est: Solution) -> dict[str, np.ndarray]:
    """All :data:`METRICS` for each sequence: arrays of shape (n_sequences,)."""
    disp_true, yaw_true = truth_for(windows, starts, n_windows)
    e_disp = disp_true - est.disp_m
    e_yaw = yaw_true - est.yaw_rate_radps
    last = np.asarray(starts) + n_windows - 1
    if len(last):
        _, _, final = wgs84().inv(
            est.track.lon_deg[:, -1], est.track.lat_deg[:, -1], windows.lon1_deg[last], windows.lat1_deg[last]
        )
    else:
        final = np.zeros(0)
    return {
        "crse_m": crse(e_disp),
        "cae_m": cae(e_disp),
        "aeps_m": aeps(e_disp),
        "yaw_crse_radps": crse(e_yaw),
        "yaw_cae_radps": cae(e_yaw),
        "yaw_aeps_radps": aeps(e_yaw),
        "final_position_error_m": np.asarray(final, dtype=np.float64),
        "final_error_pct": final_error_pct(np.asarray(final, dtype=np.float64), disp_true.sum(axis=1)),
    }


def final_error_pct(final_m: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
    """Final position error (m) as a percentage of the distance driven (m); NaN below
    :data:`MIN_PCT_DISTANCE_M`."""
    driven = np.asarray(distance_m, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(driven >= MIN_PCT_DISTANCE_M, 100.0 * np.asarray(final_m) / driven, np.nan)


def cumulative_errors(windows: Windows, starts: np.ndarray, n_windows: int, est: Solution) -> dict[str, np.ndarray]:
    """How the error builds up inside each outage: arrays (seq, win), value after each window.

    Running displacement CRSE and CAE (m), running orientation-rate CRSE (rad/s), and the 2D
    position error (m) at the end of each window (geodesic distance to the GNSS fix).
    """
    disp_true, yaw_true = truth_for(windows, starts, n_windows)
    e_disp = disp_true - est.disp_m
    e_yaw = yaw_true - est.yaw_rate_radps
    idx = np.asarray(starts)[:, None] + np.arange(n_windows)[None, :]
    if idx.size:
        _, _, pos = wgs84().inv(est.track.lon_deg[:, 1:], est.track.lat_deg[:, 1:], windows.lon1_deg[idx],
                                windows.lat1_deg[idx])
    else:
        pos = np.zeros(idx.shape)
    return {
        "crse_m": np.cumsum(np.abs(e_disp), axis=1),
        "cae_m": np.cumsum(e_disp, axis=1),
        "yaw_crse_radps": np.cumsum(np.abs(e_yaw), axis=1),
        "position_error_m": np.asarray(pos, dtype=np.float64).reshape(idx.shape),
    }


def summarise(values: np.ndarray) -> dict[str, float]:
    """max, min, mean and population std of one metric across the sequences where it is defined
    (not NaN); all NaN when there is none."""
    v = np.asarray(values, dtype=np.float64)
    v = v[~np.isnan(v)]
    if v.size == 0:
        return {"max": float("nan"), "min": float("nan"), "mean": float("nan"), "std": float("nan")}
    return {"max": float(v.max()), "min": float(v.min()), "mean": float(v.mean()), "std": float(v.std())}
