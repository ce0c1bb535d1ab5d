"""How far an estimator's covariance holds on this drive: its own NEES on the GNSS before each outage.

A learned variance (the IDNN's, :class:`~ionav_viz.learning.idnn.Uncertainty`) is fitted on its training
drives, a filter's (``ekf``) follows a noise model written for a car's IMU; on a drive unlike those
(another IMU, a shaking phone holder) either is overconfident, and its inputs cannot tell it so.
Before an outage the drive still has GNSS: the estimator is run on
pseudo-outages of the outage's length tiled over the drive, and its normalised estimation error
squared there (its 2D position error against the fixes, over its covariance) says by how much its
covariance understates its error on this drive; the fixes' own noise is in the error, not in the
covariance, so on a receiver of metres (a phone's) the scale comes out a little wider than the
reference would ask (:func:`covariance_scale`). Each outage's
covariance is scaled by the geometric mean of the NEES per degree of freedom of the pseudo-outages
that ended at or before its start (:func:`history_scale`): only the past, as a vehicle would have
it; a mean of logs, so that one pseudo-outage across a jump of the fixes does not set it. The scale
is never below 1 (the estimator is never made surer than it was trained to be) and is shrunk toward
1 with the weight of :data:`PRIOR_OUTAGES` pseudo-outages, so the first outages of a drive, with
little history, move little.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..core.covariance import growth_en, nees_en
from .track import boundary_errors_en_m, rebuild_track
from .windows import Windows

#: The weight of the prior scale 1, in pseudo-outages.
PRIOR_OUTAGES = 3.0
#: The shorter horizon (windows) whose pseudo-outages speak for a longer outage that has fewer than
#: :data:`ENOUGH` of its own length behind it (an arbiter's choice: which estimate holds on a drive
#: shows after 10 s already, and a 2-minute drive has a dozen of those).
SHORT_WINDOWS = 10
#: The pseudo-outages of an outage's own length it takes to be judged on them: under the prior
#: (:data:`PRIOR_OUTAGES`), fewer than 4 can hardly move a choice.
ENOUGH = 4


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
    good = ((windows.truth_fault[idx] == 0).all(axis=1)
            & (windows.segment[idx] == windows.segment[idx[:, :1]]).all(axis=1))
    starts = starts[good]
    return PseudoOutages(starts, starts + n_windows, n_windows)


def nees_per_dof(windows: Windows, starts: np.ndarray, disp_m: np.ndarray, yaw_rate_radps: np.ndarray,
                 cov_m2: np.ndarray) -> np.ndarray:
    """Per pseudo-outage, the mean over its window boundaries (the start left out) of the NEES per
    degree of freedom of the track rebuilt from ``disp_m``/``yaw_rate_radps`` (each ``(m, n)``)
    against the fixes, with the covariance ``cov_m2`` ``(m, n + 1, 2, 2)`` (east/north, m^2)."""
    if not len(starts):
        return np.zeros(0)
    track = rebuild_track(windows.lat0_deg[starts], windows.lon0_deg[starts], windows.heading0_deg[starts], disp_m,
                          yaw_rate_radps)
    error = boundary_errors_en_m(windows, starts, disp_m.shape[1], track.lat_deg, track.lon_deg)[:, 1:]
    return nees_en(error, cov_m2[:, 1:]).mean(axis=1) / 2.0


def pseudo_starts_before(windows: Windows, n_windows: int, outage_starts: np.ndarray) -> np.ndarray:
    """The first windows of the pseudo-outages of ``n_windows`` (:func:`pseudo_outages`) that end
    before the last of ``outage_starts``: the only ones any outage can learn from (none without outages)."""
    starts = pseudo_outages(windows, n_windows).starts
    if not len(outage_starts):
        return starts[:0]
    return starts[starts + n_windows <= np.max(outage_starts)]


def covariance_scale(windows: Windows, n_windows: int, outage_starts: np.ndarray,
                     run: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]) -> tuple[np.ndarray, str]:
    """Per outage of ``n_windows`` windows at ``outage_starts``, the scale of an estimator's position
    covariance (:func:`history_scale`) from its NEES on pseudo-outages over the GNSS before it, and a
    sentence saying what was found ("" when no pseudo-outage fits). ``run(starts)`` runs the
    estimator on pseudo-outages starting at windows ``starts``: displacement (m) and yaw rate (rad/s)
    per window ``(m, n)`` and the position covariance ``(m, n + 1, 2, 2)`` (east/north, m^2). Only
    those that end before the last outage starts are run.

    From the drive's first window on, though the state that starts the first ones (a filter's, a
    calibration from it) has not settled: tried from 30 s on instead, the IDNN's first outages on
    a simulated phone drive lost the only history they had (ANEES after 10 s 2.8 -> 11.0; its
    outages at 30-50 s NEES 65-153)."""
    outage_starts = np.asarray(outage_starts, dtype=int)
    starts = pseudo_starts_before(windows, n_windows, outage_starts)
    if not len(starts):
        return np.ones(len(outage_starts)), ""
    disp, yaw, cov = run(starts)
    nees = nees_per_dof(windows, starts, disp, yaw, cov)
    scale = history_scale(starts + n_windows, nees, outage_starts)
    return scale, (f"x{float(np.median(scale)):.2f} median, x{float(scale.max()):.2f} at most, from its NEES per "
                   f"degree of freedom {float(nees.mean()):.2f} on {len(nees)} pseudo-outages over the GNSS")


def history_scale(pseudo_ends: np.ndarray, pseudo_nees: np.ndarray, outage_starts: np.ndarray) -> np.ndarray:
    """Per outage, the covariance's scale from the mean NEES per degree of freedom of each
    pseudo-outage that ended (``pseudo_ends``, window index after their last) at or before its
    start: :func:`log_scale`, never below 1. Its correction for the log of one NEES (an exponential
    variable) widens a little for a mean over a pseudo-outage's boundaries, which spreads less."""
    return np.maximum(log_scale(pseudo_ends, pseudo_nees, outage_starts), 1.0)


def past_sums(pseudo_ends: np.ndarray, values: np.ndarray, outage_starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per outage, the sum of ``values`` (along their last axis, one per pseudo-outage) over the
    pseudo-outages that ended (``pseudo_ends``, window index after their last) at or before its
    start, and how many those are: only the past, as a vehicle would have it."""
    order = np.argsort(pseudo_ends, kind="stable")
    count = np.searchsorted(pseudo_ends[order], np.asarray(outage_starts), side="right")
    v = np.asarray(values)[..., order]
    total = np.concatenate([np.zeros(v.shape[:-1] + (1,)), np.cumsum(v, axis=-1)], axis=-1)[..., count]
    return total, count


#: Euler's constant: minus the mean log of an honest NEES per degree of freedom of 2 dimensions
#: (an exponential variable of mean 1, whose log has mean ``-EULER_GAMMA``).
EULER_GAMMA = 0.5772156649015329


def log_scale(pseudo_ends: np.ndarray, pseudo_nees: np.ndarray, outage_starts: np.ndarray) -> np.ndarray:
    """Per outage, the scale of a covariance that is too wide or too narrow on this drive, from the
    NEES per degree of freedom (2 dimensions) of pseudo-outages that ended (``pseudo_ends``, window
    index after their last) at or before its start: ``exp(mean log NEES + gamma)``, the scale under
    which their NEES would be honest (:data:`EULER_GAMMA`), its log shrunk toward 0 with the weight of
    :data:`PRIOR_OUTAGES`. Both ways, unlike :func:`history_scale`: a filter's model can be wider
    than the drive asks (a good IMU weighed with the road's vibration) as well as narrower. The mean
    of logs, not of the NEES, so that one pseudo-outage with a jump in the fixes does not set it."""
    logs = np.log(np.maximum(np.asarray(pseudo_nees, dtype=float), 1e-12)) + EULER_GAMMA
    total, count = past_sums(np.asarray(pseudo_ends), logs, outage_starts)
    return np.exp(total / (PRIOR_OUTAGES + count))


def growth_scale(windows: Windows, n_windows: int, outage_starts: np.ndarray,
                 run: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]) -> tuple[np.ndarray, str]:
    """Per outage of ``n_windows`` windows at ``outage_starts``, the scale of what a filter's position
    covariance grows by through it (:func:`ionav_viz.core.covariance.scale_growth`), both ways
    (:func:`log_scale`), from the final NEES of that growth on pseudo-outages over the GNSS before it,
    and a sentence saying what was found ("" when no pseudo-outage fits). ``run`` as
    :func:`covariance_scale`'s. The growth, not the whole: the start's covariance is the fixes' own
    (a receiver's slow wander the filter follows), which the fix at a pseudo-outage's end shares and
    so cannot measure."""
    outage_starts = np.asarray(outage_starts, dtype=int)
    starts = pseudo_starts_before(windows, n_windows, outage_starts)
    if not len(starts):
        return np.ones(len(outage_starts)), ""
    disp, yaw, cov = run(starts)
    track = rebuild_track(windows.lat0_deg[starts], windows.lon0_deg[starts], windows.heading0_deg[starts], disp, yaw)
    error = boundary_errors_en_m(windows, starts, n_windows, track.lat_deg, track.lon_deg)[:, -1]
    nees = nees_en(error, growth_en(cov)[:, -1]) / 2.0
    scale = log_scale(starts + n_windows, nees, outage_starts)
    return scale, (f"x{float(np.median(scale)):.2f} median ({float(scale.min()):.2f}-{float(scale.max()):.2f}) "
                   f"on its growth through the outage, from its final NEES on {len(nees)} pseudo-outages over the GNSS")


def past_choice(pseudo_ends: np.ndarray, err: np.ndarray, outage_starts: np.ndarray,
                prior_ratio: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per outage, the candidate whose pseudo-outages that ended (``pseudo_ends``, window index after
    their last) at or before its start erred least on average, from ``err`` ``(c, k)`` (one row per
    candidate, row 0 the default; any error measure, larger worse). Each alternative's mean is shrunk
    toward ``prior_ratio[c]`` times the default's with the weight of :data:`PRIOR_OUTAGES`: an
    alternative is taken only when the drive's own past says clearly otherwise. Returns the choice
    ``(m,)`` (0 where no pseudo-outage lies behind), each candidate's summed error ``(c, m)`` and the
    count of pseudo-outages behind each outage ``(m,)``."""
    sums, count = past_sums(pseudo_ends, err, outage_starts)
    mean_default = sums[0] / np.maximum(count, 1)
    ratio = np.asarray(prior_ratio, dtype=float)[:, None]
    score = (PRIOR_OUTAGES * ratio * mean_default + sums) / (PRIOR_OUTAGES + count)
    score[0] = mean_default
    return np.where(count > 0, np.argmin(score, axis=0), 0), sums, count
