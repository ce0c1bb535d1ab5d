"""How far a learned covariance holds on this drive: the estimator's own NEES on the GNSS before each outage.

A learned variance (the IDNN's, :class:`~ionav_viz.nav.idnn.Uncertainty`) is fitted on its training
drives; on a drive unlike them (another IMU, a shaking phone holder) it is overconfident, and its
inputs cannot tell it so. Before an outage the drive still has GNSS: the estimator is run on
pseudo-outages of the outage's length tiled over the drive, and its normalised estimation error
squared there (its 2D position error against the fixes, over its covariance, which already holds the
fixes' own error) says by how much its covariance understates its error on this drive. Each outage's
covariance is scaled by the mean NEES per degree of freedom of the pseudo-outages that ended at or
before its start: only the past, as a vehicle would have it. The scale is never below 1 (the
estimator is never made surer than it was trained to be) and is shrunk toward 1 with the weight of
:data:`PRIOR_OUTAGES` pseudo-outages, so the first outages of a drive, with little history, move little.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.covariance import nees_en
from .track import boundary_errors_en_m, rebuild_track
from .windows import Windows

#: The weight of the prior scale 1, in pseudo-outages.
PRIOR_OUTAGES = 3.0


@dataclass(frozen=True)
class PseudoOutages:
    """Stretches of ``n_windows`` windows with good GNSS truth throughout, tiled over the drive:
    ``starts`` (window index of each first window) and ``ends`` (index of the window after each)."""

    starts: np.ndarray
    ends: np.ndarray
    n_windows: int


def pseudo_outages(windows: Windows, n_windows: int) -> PseudoOutages:
    """Tiles of ``n_windows`` windows from the second window on, each inside one gap-free segment
    with good truth in every window and in the window before (its GNSS displacement starts the
    estimator)."""
    n = len(windows.t0_s)
    starts = np.arange(1, n - n_windows + 1, n_windows)
    if not len(starts):
        return PseudoOutages(starts, starts, n_windows)
    idx = starts[:, None] + np.arange(-1, n_windows)[None, :]
    good = (windows.truth_fault[idx] == 0).all(axis=1) & (windows.segment[idx] == windows.segment[idx[:, :1]]).all(axis=1)
    starts = starts[good]
    return PseudoOutages(starts, starts + n_windows, n_windows)


def nees_per_dof(windows: Windows, starts: np.ndarray, disp_m: np.ndarray, yaw_rate_radps: np.ndarray,
                 cov_m2: np.ndarray) -> np.ndarray:
    """Per pseudo-outage, the mean over its window boundaries (the start left out) of the NEES per
    degree of freedom of the track rebuilt from ``disp_m``/``yaw_rate_radps`` (each ``(m, n)``)
    against the fixes, with the covariance ``cov_m2`` ``(m, n + 1, 2, 2)`` (east/north, m^2)."""
    if not len(starts):
        return np.zeros(0)
    track = rebuild_track(windows.lat0_deg[starts], windows.lon0_deg[starts], windows.heading0_deg[starts], disp_m, yaw_rate_radps)
    error = boundary_errors_en_m(windows, starts, disp_m.shape[1], track.lat_deg, track.lon_deg)[:, 1:]
    return nees_en(error, cov_m2[:, 1:]).mean(axis=1) / 2.0


def history_scale(pseudo_ends: np.ndarray, pseudo_nees: np.ndarray, outage_starts: np.ndarray) -> np.ndarray:
    """Per outage, the covariance's scale (see the module docstring) from the pseudo-outages that
    ended (``pseudo_ends``, window index after their last) at or before its start."""
    total, count = past_sums(pseudo_ends, pseudo_nees, outage_starts)
    return np.maximum((PRIOR_OUTAGES + total) / (PRIOR_OUTAGES + count), 1.0)


def past_sums(pseudo_ends: np.ndarray, values: np.ndarray, outage_starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per outage, the sum of ``values`` (along their last axis, one per pseudo-outage) over the
    pseudo-outages that ended (``pseudo_ends``, window index after their last) at or before its
    start, and how many those are: only the past, as a vehicle would have it."""
    order = np.argsort(pseudo_ends, kind="stable")
    count = np.searchsorted(pseudo_ends[order], np.asarray(outage_starts), side="right")
    v = np.asarray(values)[..., order]
    total = np.concatenate([np.zeros(v.shape[:-1] + (1,)), np.cumsum(v, axis=-1)], axis=-1)[..., count]
    return total, count
