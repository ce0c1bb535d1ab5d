"""Is an estimator's uncertainty honest? Its position covariance through each outage
(:attr:`ionav_viz.nav.protocol.Estimate.pos_cov_m2`) against the errors it actually made.

Per window boundary of every outage (the start fix left out), the normalised estimation error
squared ``NEES = e^T (P + R) e`` (``e``: the estimate's east/north error against the truth, m;
``P``: the estimator's covariance; ``R``: the truth's own noise, ``sigma^2 I``, zero beside a
reference trajectory). Where the truth is the receiver's fixes, the error at a boundary ``h`` s into
an outage holds the noise of the *difference* of two fixes ``h`` s apart (the outage starts at a
fix), not of one fix: a receiver's error wanders slowly, so the difference is metres smaller than
the sigma it reports (the real phone log: 0.85 m at 1 s and 3.0 m at 10 s, against 8 m
reported). ``sigma`` is that difference's noise as the drive's own fixes show it
(:func:`fix_difference_sigma_m`), at least :data:`~ionav_viz.core.gnss_quality.GNSS_SIGMA_FLOOR_M`
and never above the receiver's reported sigma, which stands where the drive cannot measure it.
A consistent estimator's NEES averages 2
(two degrees of freedom); we report it halved (ANEES per degree of freedom, 1 when honest, as
OpenVINS's ``ov_eval``), with the chi-square 95 % band for that many samples (Wilson-Hilferty's
approximation), although the boundaries of one outage are not independent, so the band is narrower
than the truth of the matter. ``coverage_95``: the share of outages whose final error lies inside
the 95 % ellipse (NEES at most 5.99; 95 % when honest). ``error_over_sigma``: at 10, 30 and 60 s
into the outages, the rms error over the rms of the covariance's radius (``sqrt(trace P)``): 1 when
honest, above it overconfident; ``by_second``: both rms values at every second into the outages
(the calibration figure's points; the sigma with the truth's noise in it), and the rms of the truth's
noise counted there (``truth_sigma_m``, 1 sigma per axis).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.covariance import nees_en
from ..core.geo import local_en_m
from ..core.gnss_quality import GNSS_SIGMA_FLOOR_M
from ..nav.kalman import CHI2_2_95
from ..nav.track import boundary_errors_en_m

#: Seconds into the outages where the error/sigma ratio is reported.
RATIO_AT_S = (10, 30, 60)


def chi2_quantile(p: float, dof: float) -> float:
    """The ``p`` quantile of a chi-square of ``dof`` degrees of freedom (Wilson-Hilferty: within
    1 % from 10 degrees of freedom up)."""
    # the standard normal quantile, by Acklam's rational approximation's central and tail pieces
    z = _normal_quantile(p)
    h = 2.0 / (9.0 * dof)
    return dof * (1.0 - h + z * math.sqrt(h)) ** 3


def _normal_quantile(p: float) -> float:
    a = (-3.969683028665376e01, 2.209460984245205e02, -2.759285104469687e02, 1.383577518672690e02,
         -3.066479806614716e01, 2.506628277459239e00)
    b = (-5.447609879822406e01, 1.615858368580409e02, -1.556989798598866e02, 6.680131188771972e01,
         -1.328068155288572e01)
    c = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e00, -2.549732539343734e00,
         4.374664141464968e00, 2.938163982698783e00)
    d = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e00, 3.754408661907416e00)
    if p < 0.02425:
        q = math.sqrt(-2 * math.log(p))
        return ((((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5])
                / ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1))
    if p > 1 - 0.02425:
        return -_normal_quantile(1 - p)
    q = p - 0.5
    r = q * q
    return ((((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q
            / (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1))


def boundary_errors_m(result, name: str) -> np.ndarray:
    """The estimate's east/north error (m) against the truth at every window boundary of every
    outage, ``(n_outages, n_windows + 1, 2)``."""
    track = result.estimates[name].track
    return boundary_errors_en_m(result.windows, np.asarray(result.starts), result.n_windows, track.lat_deg,
                                track.lon_deg)


def truth_sigma_m(result) -> float:
    """The truth's own noise (m, 1 sigma per axis) as the receiver reports it: zero beside a
    reference, else the median of its reported sigma, at least the floor."""
    drive = result.drive
    if drive.has_reference:
        return 0.0
    reported = drive.columns.get("gnss_sigma_m")
    sigma = (float(np.nanmedian(reported))
             if reported is not None and np.isfinite(reported).any() else GNSS_SIGMA_FLOOR_M)
    return max(sigma, GNSS_SIGMA_FLOOR_M)


#: Fewest pairs of fixes at a lag that measure the noise of their difference there.
MIN_PAIRS = 30
#: The most the course may change between two fixes for their chord to be the distance driven (deg).
STRAIGHT_DEG = 5.0
#: The least distance (m) between two fixes whose chord is measured: standing, a course is noise.
MOVING_M = 1.0


def fix_difference_sigma_m(drive, n_lags: int) -> np.ndarray | None:
    """The noise (m, 1 sigma per axis) of the difference of two of ``drive``'s GNSS fixes 1, 2, ...,
    ``n_lags`` s apart, measured on the drive itself ``(n_lags,)``, NaN at a lag with fewer than
    :data:`MIN_PAIRS` pairs; None where it cannot be measured: beside a reference (the truth is not
    the fixes), or where the receiver's speed is fitted to the fixes (not independent of them).

    On a 1 s grid of trustworthy fixes, while the course changed under :data:`STRAIGHT_DEG` and the
    vehicle moved over :data:`MOVING_M`, the straight-line distance between two fixes and the
    receiver's own speed integrated between them differ by the two fixes' noise along the track (a
    Doppler speed's error integrates to far less over seconds); per lag the robust spread of that
    difference (1.4826 times its median absolute deviation, so that a jump of the fixes does not set
    it)."""
    if drive.has_reference or drive.velocity_fitted:
        return None
    ok = drive.gnss_ok
    t = drive.t_s[ok]
    if len(t) < 2:
        return np.full(n_lags, np.nan)
    grid = np.arange(t[0], t[-1], 1.0)
    after = np.clip(np.searchsorted(t, grid), 1, len(t) - 1)
    lost = np.minimum(grid - t[after - 1], t[after] - grid) > 1.0  # no trustworthy fix within 1 s
    lost_before = np.concatenate([[0], np.cumsum(lost)])
    east, north = local_en_m(np.interp(grid, t, drive.lat_deg[ok]), np.interp(grid, t, drive.lon_deg[ok]),
                             float(drive.lat_deg[ok][0]), float(drive.lon_deg[ok][0]))
    speed = drive.speed_mps[ok]
    driven = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])
    arc = np.interp(grid, t, driven)
    course = np.interp(grid, t, np.unwrap(np.radians(drive.heading_deg[ok])))
    out = np.full(n_lags, np.nan)
    for h in range(1, min(n_lags, len(grid) - 1) + 1):
        chord = np.hypot(east[h:] - east[:-h], north[h:] - north[:-h])
        along = arc[h:] - arc[:-h]
        keep = ((np.abs(course[h:] - course[:-h]) < np.radians(STRAIGHT_DEG)) & (along > MOVING_M)
                & (lost_before[h + 1:] == lost_before[:-h - 1]))  # no lost fix from one to the other
        if keep.sum() >= MIN_PAIRS:
            d = (chord - along)[keep]
            out[h - 1] = 1.4826 * float(np.median(np.abs(d - np.median(d))))
    return out


def truth_noise_m(result, n_lags: int) -> np.ndarray:
    """The truth's own noise (m, 1 sigma per axis) at the boundaries 1..``n_lags`` s into an outage,
    ``(n_lags,)``: zero beside a reference; else the noise of the difference of the start's fix and
    that boundary's (:func:`fix_difference_sigma_m`), at least
    :data:`~ionav_viz.core.gnss_quality.GNSS_SIGMA_FLOOR_M`, never above the receiver's reported
    sigma (:func:`truth_sigma_m`), which stands where the drive does not measure it."""
    reported = truth_sigma_m(result)
    measured = fix_difference_sigma_m(result.drive, n_lags)
    if measured is None or reported == 0.0:
        return np.full(n_lags, reported)
    return np.clip(np.where(np.isfinite(measured), measured, reported), GNSS_SIGMA_FLOOR_M, reported)


def outage_nees(result, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Per outage and boundary (the start left out): NEES (2 dof), the squared error (m^2) and the
    covariance's trace (m^2); None when the estimator has no covariance."""
    cov = result.estimates[name].pos_cov_m2
    if cov is None or not len(result.starts):
        return None
    e = boundary_errors_m(result, name)[:, 1:]
    P = cov[:, 1:] + (truth_noise_m(result, e.shape[1]) ** 2)[:, None, None] * np.eye(2)
    ex, ey = e[..., 0], e[..., 1]
    return nees_en(e, P), ex * ex + ey * ey, P[..., 0, 0] + P[..., 1, 1]


def outage_consistency(result, name: str) -> dict[str, np.ndarray] | None:
    """The compact per-outage values :func:`pooled_consistency` needs (what a fleet's per-drive
    table keeps, :class:`ionav_viz.analysis.fleet.DriveTable`), or None without a covariance:
    ``nees_mean`` (each outage's NEES averaged over its boundaries, the start left out),
    ``final_nees`` and, at each second ``t`` of :data:`RATIO_AT_S` the outage reaches, the squared
    error ``sq_error_m2_<t>`` and the covariance's trace ``trace_m2_<t>``."""
    part = outage_nees(result, name)
    return None if part is None else _compact(part)


def _compact(part: tuple[np.ndarray, np.ndarray, np.ndarray]) -> dict[str, np.ndarray]:
    nees, sq, tr = part
    out = {"nees_mean": nees.mean(axis=1), "final_nees": nees[:, -1].copy()}
    for t in RATIO_AT_S:
        if t <= nees.shape[1]:
            out[f"sq_error_m2_{t}"], out[f"trace_m2_{t}"] = sq[:, t - 1].copy(), tr[:, t - 1].copy()
    return out


def pooled_consistency(parts: list[dict[str, np.ndarray]], n_windows: int) -> dict[str, Any] | None:
    """ANEES with its band and verdict, ``coverage_95``, ``error_over_sigma``, ``n_samples`` and
    ``n_outages`` over the outages of ``parts`` (:func:`outage_consistency` of each drive, outages
    of ``n_windows`` s), or None when there is none: the one place these are computed, for one
    report's drives and for a fleet's tables alike."""
    parts = [p for p in parts if len(p["nees_mean"])]
    if not parts:
        return None
    nees_mean = np.concatenate([p["nees_mean"] for p in parts])
    final = np.concatenate([p["final_nees"] for p in parts])
    anees = float(nees_mean.mean() / 2.0)  # every outage has n_windows boundaries: the mean of the means is the mean
    n_samples = len(nees_mean) * int(n_windows)
    dof = 2 * n_samples
    band = [chi2_quantile(0.025, dof) / dof, chi2_quantile(0.975, dof) / dof]
    ratio = {}
    for t in RATIO_AT_S:
        if all(f"sq_error_m2_{t}" in p for p in parts):
            sq = np.concatenate([p[f"sq_error_m2_{t}"] for p in parts])
            tr = np.concatenate([p[f"trace_m2_{t}"] for p in parts])
            ratio[str(t)] = float(math.sqrt(sq.mean() / max(tr.mean(), 1e-12)))
    verdict = ("consistent" if band[0] <= anees <= band[1]
               else ("overconfident" if anees > band[1] else "underconfident"))
    return {"anees": anees, "anees_band": band, "coverage_95": float(100.0 * np.mean(final <= CHI2_2_95)),
            "error_over_sigma": ratio, "n_samples": n_samples, "n_outages": len(final), "verdict": verdict}


def consistency(results: list, name: str) -> dict[str, Any] | None:
    """The consistency of estimator ``name`` over the outages of ``results`` (see the module
    docstring; :func:`pooled_consistency` of each drive's :func:`outage_consistency`, with
    ``by_second``), or None when it gives no covariance."""
    parts = [x for x in (outage_nees(r, name) for r in results) if x is not None]
    if not parts:
        return None
    n_win = parts[0][0].shape[1]
    out = pooled_consistency([_compact(p) for p in parts], n_win)
    if out is None:
        return None
    sq = np.concatenate([p[1] for p in parts])  # (outages, n_win)
    tr = np.concatenate([p[2] for p in parts])
    truth = np.concatenate([np.tile(truth_noise_m(r, n_win) ** 2, (len(r.starts), 1)) for r in results
                            if r.estimates[name].pos_cov_m2 is not None and len(r.starts)])
    out["by_second"] = {"t_s": [float(t) for t in range(1, n_win + 1)],
                        "rms_error_m": [float(v) for v in np.sqrt(sq.mean(axis=0))],
                        "rms_sigma_m": [float(v) for v in np.sqrt(tr.mean(axis=0))],
                        "truth_sigma_m": [float(v) for v in np.sqrt(truth.mean(axis=0))]}
    return out


def consistency_line(label: str, c: dict[str, Any]) -> str:
    """One line of the text report: the outages counted with the share inside (all of 2 outages
    inside says little, all of 200 much); the rms error/sigma only at the seconds of
    :data:`RATIO_AT_S` the outages reach (none in outages under 10 s)."""
    ratios = ", ".join(f"{t} s {v:.2f}" for t, v in c["error_over_sigma"].items())
    lo, hi = c["anees_band"]
    n = int(c["n_outages"])
    inside = round(c["coverage_95"] * n / 100.0)
    return (f"{label} uncertainty: ANEES {c['anees']:.2f} (1 when honest; 95 % band {lo:.2f}-{hi:.2f}: "
            f"{c['verdict']}), final errors inside the 95 % ellipse on {inside} of {n} outages, "
            f"{c['coverage_95']:.0f} % (95 % when honest)" + (f", rms error/sigma {ratios}" if ratios else ""))
