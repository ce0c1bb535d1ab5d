"""Is an estimator's uncertainty honest? Its position covariance through each outage
(:attr:`ionav_viz.nav.protocol.Estimate.pos_cov_m2`) against the errors it actually made.

Per window boundary of every outage (the start fix left out), the normalised estimation error
squared ``NEES = e^T (P + R) e`` (``e``: the estimate's east/north error against the truth, m;
``P``: the estimator's covariance; ``R``: the truth's own noise, ``sigma^2 I`` with the receiver's
reported sigma, at least :data:`~ionav_viz.core.gnss_quality.GNSS_SIGMA_FLOOR_M`, where the truth is
the receiver's fixes, zero beside a reference trajectory). A consistent estimator's NEES averages 2
(two degrees of freedom); we report it halved (ANEES per degree of freedom, 1 when honest, as
OpenVINS's ``ov_eval``), with the chi-square 95 % band for that many samples (Wilson-Hilferty's
approximation), although the boundaries of one outage are not independent, so the band is narrower
than the truth of the matter. ``coverage_95``: the share of outages whose final error lies inside
the 95 % ellipse (NEES at most 5.99; 95 % when honest). ``error_over_sigma``: at 10, 30 and 60 s
into the outages, the rms error over the rms of the covariance's radius (``sqrt(trace P)``): 1 when
honest, above it overconfident; ``by_second``: both rms values at every second into the outages
(the calibration figure's points).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.covariance import nees_en
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
    """The truth's own noise (m, 1 sigma per axis): zero beside a reference, else the receiver's."""
    drive = result.drive
    if drive.has_reference:
        return 0.0
    reported = drive.columns.get("gnss_sigma_m")
    sigma = (float(np.nanmedian(reported))
             if reported is not None and np.isfinite(reported).any() else GNSS_SIGMA_FLOOR_M)
    return max(sigma, GNSS_SIGMA_FLOOR_M)


def outage_nees(result, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Per outage and boundary (the start left out): NEES (2 dof), the squared error (m^2) and the
    covariance's trace (m^2); None when the estimator has no covariance."""
    cov = result.estimates[name].pos_cov_m2
    if cov is None or not len(result.starts):
        return None
    e = boundary_errors_m(result, name)[:, 1:]
    P = cov[:, 1:] + truth_sigma_m(result) ** 2 * np.eye(2)
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
    out["by_second"] = {"t_s": [float(t) for t in range(1, n_win + 1)],
                        "rms_error_m": [float(v) for v in np.sqrt(sq.mean(axis=0))],
                        "rms_sigma_m": [float(v) for v in np.sqrt(tr.mean(axis=0))]}
    return out


def consistency_line(label: str, c: dict[str, Any]) -> str:
    """One line of the text report; the rms error/sigma only at the seconds of :data:`RATIO_AT_S`
    the outages reach (none in outages under 10 s)."""
    ratios = ", ".join(f"{t} s {v:.2f}" for t, v in c["error_over_sigma"].items())
    lo, hi = c["anees_band"]
    return (f"{label} uncertainty: ANEES {c['anees']:.2f} (1 when honest; 95 % band {lo:.2f}-{hi:.2f}: "
            f"{c['verdict']}), final errors inside the 95 % ellipse {c['coverage_95']:.0f} % (95 % "
            "when honest)" + (f", rms error/sigma {ratios}" if ratios else ""))
