"""Run the estimators on the same outages of a drive and score them all the same way.

:func:`evaluate_drive` is the one pure entry point that ``evaluate``, ``replay`` and the Python
API use: it cuts the drive into windows, places the outages (the paper's tiling by default),
runs every estimator on them (:func:`ionav_viz.nav.protocol.solve` checks the output and
rebuilds the track) and computes the paper's metrics per outage. The result is a
:class:`DriveResult`; :mod:`ionav_viz.analysis.report` turns results into reports.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.drive import Drive
from ..core.gnss_quality import count_by_fault
from ..core.grid import WINDOW_S
from ..core.timing import stage
from ..experiment.outages import OutagePlan, excluded_by_truth, tile
from ..experiment.registry import BASELINE
from ..experiment.registry import resolve as resolve_estimators
from ..nav.bias import SensorBias, resolve_bias
from ..nav.protocol import Estimator, EstimatorInputs, Solution, color_of, describe, solve
from ..nav.windows import Windows, make_windows
from .bridging import BridgedOutage, bridge_gnss_outages
from .metrics import METRICS, sequence_metrics, truth_for

__all__ = ["METRICS", "DriveResult", "OutageTruth", "clustered_improvement_ci95_pct", "evaluate_drive",
           "improvement_ci95_pct", "improvement_pct", "paired_bootstrap_means", "resolve_bias"]


@dataclass(frozen=True)
class OutageTruth:
    """The GNSS truth of each outage's windows: displacement (m) and yaw rate (rad/s, counter-
    clockwise positive), shape (n_outages, n_windows)."""

    disp_m: np.ndarray
    yaw_rate_radps: np.ndarray


@dataclass(repr=False)
class DriveResult:
    """Everything computed for one drive: windows, outages, and per estimator its solution and metrics.

    Attributes:
        drive, windows: the drive and its 1-second windows.
        n_windows: windows (seconds) per outage; ``starts``: first window index of each outage.
        bias: the sensor biases every estimator was given.
        estimators: the estimators, in report order.
        estimates: per estimator name, its :class:`~ionav_viz.nav.protocol.Solution` (per-window
            displacement and yaw rate, and the rebuilt track).
        metrics: per estimator name, each of :data:`METRICS` as an array (n_outages,).
        excluded_outages: how many outages the placement would have put on bad GNSS truth, or
            right after a window where a receiver beside a reference had no fix to trust.
        bridged: the log's own GNSS losses every estimator was run through (``--on gnss-outage``),
            scored at the first good fix after each; ``unbridged``: how many losses could not be, per reason.
        placement: where the outages went, in words (the placement's plan, with its warm-up).
    """

    drive: Drive
    windows: Windows
    n_windows: int
    starts: np.ndarray
    bias: SensorBias
    estimators: list[Estimator]
    estimates: dict[str, Solution]
    metrics: dict[str, dict[str, np.ndarray]]
    excluded_outages: int = 0
    bridged: list[BridgedOutage] = field(default_factory=list)
    unbridged: dict[str, int] = field(default_factory=dict)
    placement: str = ""

    def __repr__(self) -> str:
        ests = ", ".join(e.name for e in self.estimators)
        bridged = f", {len(self.bridged)} real GNSS outage(s) bridged" if self.bridged else ""
        return (f"DriveResult(drive={self.drive.name!r}, {len(self.starts)} outage(s) of {self.outage_s:g} s{bridged}, "
                f"estimators: {ests})")

    @property
    def truth(self) -> OutageTruth:
        """The GNSS truth every estimate of each outage is scored against."""
        disp, yaw = truth_for(self.windows, self.starts, self.n_windows)
        return OutageTruth(disp, yaw)

    def truth_exclusions(self) -> dict[str, Any]:
        """What the GNSS quality checks excluded: ``windows`` (all), ``excluded_windows`` (bad
        truth), ``excluded_by_reason`` (windows per fault name), ``receiver_lost_windows`` (beside
        a reference: windows where the estimators' receiver had no fix to trust, right after which
        no outage starts) and ``excluded_outages`` (not placed for either)."""
        fault = self.windows.truth_fault
        bad = fault != 0
        return {"windows": len(fault), "excluded_windows": int(bad.sum()),
                "excluded_by_reason": count_by_fault(fault[bad]),
                "receiver_lost_windows": int(np.count_nonzero(self.windows.receiver_fault)),
                "excluded_outages": int(self.excluded_outages)}

    @property
    def outage_s(self) -> float:
        """Outage length (s)."""
        return float(self.n_windows * WINDOW_S)

    @property
    def gnss_distance_m(self) -> np.ndarray:
        """GNSS distance travelled during each outage (m)."""
        disp, _ = truth_for(self.windows, self.starts, self.n_windows)
        return disp.sum(axis=1)

    @property
    def outage_t0_s(self) -> np.ndarray:
        """Start time of each outage (s since the drive's first sample)."""
        return self.windows.t0_s[self.starts]

    @property
    def in_training(self) -> np.ndarray | None:
        """Per outage, whether it lies in data the IDNN's model (or its parent) was trained on (the
        same file by sha256, overlapping time; :func:`ionav_viz.learning.idnn.outages_in_training`), or
        None when no IDNN ran: its scores there flatter the model."""
        from ..learning.idnn import IdnnEstimator, outages_in_training

        models = [e.model for e in self.estimators if isinstance(e, IdnnEstimator)]
        if not models:
            return None
        hit = np.zeros(len(self.starts), dtype=bool)
        for model in models:
            hit |= outages_in_training(model, self.drive, self.windows, self.starts, self.n_windows)
        return hit

    def estimator_info(self) -> list[dict[str, Any]]:
        """Name, label, its own colour (RGB, when it has one) and description of every estimator (for reports)."""
        return [{"name": e.name, "label": e.label, **({"color": list(color)} if (color := color_of(e)) else {}),
                 **({"info": info} if (info := describe(e)) else {})} for e in self.estimators]


def evaluate_drive(
    drive: Drive,
    n_windows: int,
    estimators: Sequence[str | Estimator],
    *,
    bias: SensorBias | None = None,
    plan: OutagePlan | None = None,
    windows: Windows | None = None,
) -> DriveResult:
    """Every one of ``estimators`` on the ``n_windows``-second outages of ``plan`` (default: the
    paper's tiling) of ``drive``.

    ``estimators``: names or objects (see :func:`ionav_viz.experiment.registry.resolve`). ``bias``:
    default from the drive's own stationary stretches. ``plan``: the outages' first windows, how
    many outages the caller's placement lost to bad GNSS truth (counted here for the default
    tiling), the log's own GNSS losses ``(last good fix s, first good fix s)`` to bridge as well
    (:mod:`ionav_viz.analysis.bridging`) and the placement in words.
    """
    n = int(n_windows)
    windows = windows if windows is not None else make_windows(drive)
    if plan is None:
        plan = OutagePlan(tile(windows, n), "", excluded_by_truth(windows, n, lambda w: tile(w, n)))
    starts = np.asarray(plan.starts, dtype=int)
    excluded_outages, gnss_gaps, placement = plan.excluded, plan.gnss_gaps, plan.description
    bias = bias if bias is not None else resolve_bias(drive)
    chosen = resolve_estimators(list(estimators))
    # estimators get the receiver's GNSS; they are scored against the truth (a reference, if any)
    received = drive.as_received()
    inputs = EstimatorInputs(received, windows if received is drive else make_windows(received), starts, n, bias)
    solutions = {}
    for est in chosen:
        with stage(f"{est.label} on {drive.name}") as s:
            solutions[est.name] = solve(est, inputs)
            s.detail = f"{len(starts)} outages of {n} s"
    metrics = {name: sequence_metrics(windows, starts, n, sol) for name, sol in solutions.items()}
    result = DriveResult(drive, windows, n, starts, bias, list(chosen), solutions, metrics, excluded_outages or 0,
                         placement=placement)
    if gnss_gaps:
        with stage(f"bridge {len(gnss_gaps)} GNSS outage(s) of {drive.name}"):
            result.bridged, result.unbridged = bridge_gnss_outages(drive, windows, gnss_gaps, chosen, bias)
    return result


def improvement_pct(baseline: float, candidate: float) -> float:
    """How much lower ``candidate`` is than ``baseline``, in percent of the baseline."""
    if not np.isfinite(baseline) or baseline == 0:
        return float("nan")
    return 100.0 * (baseline - candidate) / baseline


#: Resamples of :func:`improvement_ci95_pct`'s bootstrap: the 2.5 and 97.5 percentiles of 2000
#: move by about 0.1 of the interval's width from one seed to another.
BOOTSTRAP_RESAMPLES = 2000

#: Above this many outages :func:`improvement_ci95_pct` takes the normal approximation (the
#: bootstrap's cost grows with the outages): with this many they agree within 0.1 point on
#: light-tailed errors, within 0.7-1.7 where 2 % of the outages err 50 times as much (the bootstrap's
#: own sampling noise there is about 0.5).
BOOTSTRAP_MAX_OUTAGES = 5000


def paired_bootstrap_means(baseline: np.ndarray, candidate: np.ndarray, resamples: int = BOOTSTRAP_RESAMPLES,
                           seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The two means over ``resamples`` resamples (with replacement) of the outages where both are
    defined, the same outages for both: shape ``(resamples,)`` each (empty when no outage has both).
    Seeded, so a report reads the same on every run."""
    b, c = np.asarray(baseline, dtype=np.float64), np.asarray(candidate, dtype=np.float64)
    both = np.isfinite(b) & np.isfinite(c)
    b, c = b[both], c[both]
    if not len(b):
        return np.zeros(0), np.zeros(0)
    rng = np.random.default_rng(seed)
    mb, mc = np.empty(resamples), np.empty(resamples)
    step = max(1, 4_000_000 // len(b))  # resamples per chunk: a fleet's outages stay within tens of MB
    for i in range(0, resamples, step):
        idx = rng.integers(0, len(b), (min(step, resamples - i), len(b)))
        # take: 3x fancy indexing's speed
        mb[i:i + len(idx)], mc[i:i + len(idx)] = np.take(b, idx).mean(axis=1), np.take(c, idx).mean(axis=1)
    return mb, mc


def improvement_ci95_pct(baseline: np.ndarray, candidate: np.ndarray) -> tuple[float, float]:
    """A 95 % interval of :func:`improvement_pct` of the candidate's mean over the baseline's, from a
    paired percentile bootstrap over the outages (per outage values, each array ``(n,)``; outages
    where either is NaN left out; above :data:`BOOTSTRAP_MAX_OUTAGES`, the normal approximation).
    The outages are resampled as if independent: consecutive outages of one drive share its road
    and sensors, so the interval is, if anything, too narrow. NaN when fewer than 2 outages have both."""
    b, c = np.asarray(baseline, dtype=np.float64), np.asarray(candidate, dtype=np.float64)
    both = np.isfinite(b) & np.isfinite(c)
    if int(both.sum()) < 2:
        return float("nan"), float("nan")
    if int(both.sum()) > BOOTSTRAP_MAX_OUTAGES:
        return _improvement_ci95_normal(b[both], c[both])
    mb, mc = paired_bootstrap_means(b, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _ci95(100.0 * (mb - mc) / mb)


def _ci95(resampled: np.ndarray) -> tuple[float, float]:
    """The 2.5 and 97.5 percentiles of a bootstrap's resampled statistic (its undefined draws, a
    zero baseline, left out); NaN when none is defined."""
    v = resampled[np.isfinite(resampled)]
    if not len(v):
        return float("nan"), float("nan")
    lo, hi = np.percentile(v, [2.5, 97.5])
    return float(lo), float(hi)


def _improvement_ci95_normal(b: np.ndarray, c: np.ndarray) -> tuple[float, float]:
    """The delta method's 95 % interval of ``100 (1 - mean(c) / mean(b))``: the ratio's variance
    is ``var(c - r b) / (n mean(b)^2)``."""
    mean_b = float(b.mean())
    if mean_b == 0.0:
        return float("nan"), float("nan")
    r = float(c.mean()) / mean_b
    sd = float(np.std(c - r * b, ddof=1)) / (np.sqrt(len(b)) * abs(mean_b))
    return float(100.0 * (1.0 - r - 1.96 * sd)), float(100.0 * (1.0 - r + 1.96 * sd))


#: Below this many drives a fleet's interval is at least the outages' (:func:`clustered_improvement_ci95_pct`).
FEW_DRIVES = 10


def clustered_improvement_ci95_pct(baseline: Sequence[np.ndarray],
                                   candidate: Sequence[np.ndarray]) -> tuple[float, float]:
    """:func:`improvement_ci95_pct` over a fleet, its drives resampled rather than its outages: one
    array per drive each (per outage values; outages where either is NaN left out), each resample
    a draw of whole drives with replacement, its improvement that of the drawn outages' means. A
    drive's outages share its road, car and sensors, so the drives are the independent units. With
    few drives (under :data:`FEW_DRIVES`) their resamples are few (two drives: three) and the
    interval is only the spread of the drives' own ratios (none when they agree, however much their
    outages vary): there it spans at least the outages' interval. With fewer than two drives scored,
    the outages' interval."""
    sums_b, sums_c, both_b, both_c = [], [], [], []
    for b, c in zip(baseline, candidate):
        b, c = np.asarray(b, dtype=np.float64), np.asarray(c, dtype=np.float64)
        ok = np.isfinite(b) & np.isfinite(c)
        if ok.any():
            sums_b.append(float(b[ok].sum()))
            sums_c.append(float(c[ok].sum()))
            both_b.append(b[ok])
            both_c.append(c[ok])
    # the outages' interval is needed (and, over many outages, costly: not computed otherwise)
    if len(sums_b) < FEW_DRIVES:
        outages = improvement_ci95_pct(np.concatenate(both_b) if both_b else np.zeros(0),
                                       np.concatenate(both_c) if both_c else np.zeros(0))
        if len(sums_b) < 2:
            return outages
    sb, sc = np.array(sums_b), np.array(sums_c)
    idx = np.random.default_rng(0).integers(0, len(sb), (BOOTSTRAP_RESAMPLES, len(sb)))
    with np.errstate(divide="ignore", invalid="ignore"):
        lo, hi = _ci95(100.0 * (1.0 - sc[idx].sum(axis=1) / sb[idx].sum(axis=1)))
    if len(sb) < FEW_DRIVES and all(np.isfinite(outages)) and np.isfinite(lo):
        lo, hi = min(lo, outages[0]), max(hi, outages[1])
    return lo, hi


def is_baseline(name: str) -> bool:
    """Whether ``name`` is the paper's INS DR, the baseline of every improvement."""
    return name == BASELINE
