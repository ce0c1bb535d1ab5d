"""The filters' health in the recording: per estimator that reports one (:class:`ionav_viz.nav.
protocol.FilterHealth`) and per kind of measurement, its normalised innovation squared (NIS) over
the drive as a 10 s running mean, a line at 1 (what a consistent filter averages) and a mark where
the filter's gate left a measurement out. Consumes only results."""

from __future__ import annotations

import numpy as np

from ..analysis.evaluate import DriveResult
from ..nav.protocol import SAFEGUARD_KINDS
from . import entities as ent
from .style import TOL_MUTED

#: The running mean's length (s): single NIS values scatter over two decades (a chi-square).
NIS_MEAN_S = 10.0
#: Colours of the series, one each, in order (estimators, then the kinds each lists): Paul Tol's
#: muted scheme, never the estimators' own (a measurement kind is no estimator); the gated marks its rose.
SERIES_COLORS = tuple(TOL_MUTED[n] for n in ("sand", "purple", "teal", "olive", "cyan", "wine", "dark green", "indigo"))
GATED_COLOR = TOL_MUTED["rose"]


def running_mean(t_s: np.ndarray, values: np.ndarray, length_s: float) -> np.ndarray:
    """The mean of the finite ``values`` over the last ``length_s`` seconds at each time (NaN where none)."""
    ok = np.isfinite(values)
    csum = np.concatenate([[0.0], np.cumsum(np.where(ok, values, 0.0))])
    ccount = np.concatenate([[0], np.cumsum(ok)])
    first = np.searchsorted(t_s, t_s - length_s, side="right")
    last = np.arange(1, len(t_s) + 1)
    n = ccount[last] - ccount[first]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, (csum[last] - csum[first]) / np.maximum(n, 1), np.nan)


def log_health(layers, result: DriveResult, labels: dict[str, str]) -> bool:
    """Every filter's health (see the module docstring), static styles and per-boundary series;
    whether there was any to log."""
    import rerun as rr

    rec, send = layers.rec, layers.send
    logged = False
    n_series = 0
    for name, sol in result.estimates.items():
        health = sol.health
        if health is None or not len(health.t_s):
            continue
        nis, status = health.nis(), np.asarray(health.status)
        t = np.asarray(health.t_s, dtype=float)
        for kind in dict.fromkeys(health.kinds):
            if kind in SAFEGUARD_KINDS:  # acts, not a measurement: no NIS to draw (the summary counts them)
                continue
            cols = [j for j, k in enumerate(health.kinds) if k == kind]
            used = (status[:, cols] == 1) & np.isfinite(nis[:, cols])
            if not used.any():
                continue
            count = used.sum(axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                per_row = np.where(count > 0, np.where(used, nis[:, cols], 0.0).sum(axis=1) / count, np.nan)
            color = SERIES_COLORS[n_series % len(SERIES_COLORS)]
            n_series += 1
            mean = running_mean(t, per_row, NIS_MEAN_S)
            keep = np.isfinite(mean)
            rec.log(ent.health_nis(name, kind),
                    rr.SeriesLines(colors=[color], names=[f"{labels.get(name, name)}: {kind}"], widths=[1.5]),
                    static=True)
            send(ent.health_nis(name, kind), t[keep], rr.Scalars.columns(scalars=mean[keep]))
            gated = (status[:, cols] == 2).any(axis=1)
            if gated.any():
                rec.log(ent.health_gated(name, kind),
                        rr.SeriesPoints(colors=[GATED_COLOR], names=[f"{labels.get(name, name)}: {kind} gated out"],
                                        markers=["cross"], marker_sizes=[4.0]), static=True)
                level = np.where(np.isfinite(mean[gated]), mean[gated], 1.0)
                send(ent.health_gated(name, kind), t[gated], rr.Scalars.columns(scalars=level))
            logged = True
    if logged:
        rec.log(ent.HEALTH_EXPECTED, rr.SeriesLines(colors=[(90, 90, 90)], names=["1: consistent"], widths=[1.0]),
                static=True)
        t_all = result.drive.t_s
        send(ent.HEALTH_EXPECTED, np.array([t_all[0], t_all[-1]]), rr.Scalars.columns(scalars=np.ones(2)))
    return logged
