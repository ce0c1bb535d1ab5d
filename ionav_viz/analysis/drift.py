"""How position error grows through an outage (the drift curve every GNSS-outage paper shows), and
the distribution of final errors.

The position error of an estimator at ``k`` seconds into an outage is the geodesic distance
between its track at the ``k``-th window boundary and the truth there (the GNSS, or the reference,
at the end of window ``k``; at ``k = 0`` the truth at the outage's start). Over all outages of a
report, per second since the outage began: the mean and the 10th and 90th percentiles.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..core.geo import wgs84

#: The percentiles of the final position error a report gives (``final_error_percentiles``).
FINAL_PERCENTILES = (50, 90, 95)


def boundary_errors_m(result: Any, estimator: str) -> np.ndarray:
    """Position error (m) of ``estimator`` at every window boundary of every outage of one
    :class:`~ionav_viz.analysis.evaluate.DriveResult`, shape ``(n_outages, n_windows + 1)``."""
    track = result.estimates[estimator].track
    if len(result.starts) == 0:
        return np.zeros((0, result.n_windows + 1))
    truth_lat, truth_lon, _ = result.windows.boundary_fixes(result.starts, result.n_windows)
    _, _, dist = wgs84().inv(track.lon_deg.ravel(), track.lat_deg.ravel(), truth_lon.ravel(), truth_lat.ravel())
    return np.asarray(dist, dtype=float).reshape(truth_lat.shape)


def drift_curve(errors_m: np.ndarray) -> dict[str, list[float]]:
    """``t_s`` (seconds since the outage began) with the ``mean_m``, ``p10_m`` and ``p90_m`` of
    the position error over outages, from ``(n_outages, n_windows + 1)`` errors."""
    n_b = errors_m.shape[1]
    if errors_m.shape[0] == 0:
        nan = [float("nan")] * n_b
        return {"t_s": [float(k) for k in range(n_b)], "mean_m": nan, "p10_m": nan, "p90_m": nan}
    p10, p90 = np.percentile(errors_m, [10, 90], axis=0)
    return {"t_s": [float(k) for k in range(n_b)], "mean_m": errors_m.mean(axis=0).tolist(), "p10_m": p10.tolist(),
            "p90_m": p90.tolist()}


def final_error_percentiles(final_m: np.ndarray) -> dict[str, float]:
    """``p50``, ``p90``, ``p95`` and ``max`` of final position errors (m), over the defined ones."""
    v = np.asarray(final_m, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {**{f"p{p}": float("nan") for p in FINAL_PERCENTILES}, "max": float("nan")}
    return {**{f"p{p}": float(np.percentile(v, p)) for p in FINAL_PERCENTILES}, "max": float(v.max())}


def report_drift(results: Sequence[Any], estimators: Sequence[str]) -> dict[str, dict[str, list[float]]]:
    """Per estimator, the drift curve over every outage of ``results`` (same outage length)."""
    return {est: drift_curve(np.concatenate([boundary_errors_m(r, est) for r in results])) for est in estimators}


def error_cdf(final_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The empirical CDF of final errors: sorted errors (m) and the share of outages at or below each."""
    v = np.sort(np.asarray(final_m, dtype=float)[np.isfinite(final_m)])
    return v, np.arange(1, len(v) + 1) / max(len(v), 1)
