"""The fleet report: many drives evaluated one by one (in any order, on any worker), compared from
their small per-outage tables, never from the drives themselves.

A :class:`DriveTable` is everything the report needs of one evaluated drive: per outage its start,
GNSS distance and every estimator's metrics, and per drive its length, distance, biases, GNSS truth
exclusions and warnings (a few kB for a long drive). A :class:`DriveFailure` is a drive that could
not be evaluated, with its one-line reason; a :class:`DriveRow` one drive's row of the
report (its mean errors and improvements). A :class:`FleetReport` pools the tables in input
order, so its numbers are the same whichever worker computed which drive; as JSON, text and
Markdown it gives per-drive rows, the pooled summary per estimator, the worst drives and outages
with the command that replays each, and the failures.
"""

from __future__ import annotations

import math
import shlex
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..core import run_config
from ..core.fileio import safe_stem
from ..core.json_out import dumps_json
from ..nav.protocol import color_of
from .consistency import RATIO_AT_S
from .document import Block, Code, Document, Heading, Items, Paragraphs, Table, to_markdown, to_text
from .drift import final_error_percentiles
from .evaluate import DriveResult, clustered_improvement_ci95_pct, improvement_pct, is_baseline
from .metrics import METRICS, summarise
from .rows import IMPROVEMENT_METRICS, BridgedRow, EstimatorRow, GnssTruth, Improvement, Spread, WorstRow
from .schema import tagged

#: How many drives and outages the fleet report ranks as the worst.
FLEET_WORST_COUNT = 5


@dataclass
class DriveTable:
    """One evaluated drive, compactly: what the fleet report is made of.

    Attributes:
        spec: the drive as it was given (a path, a bundled or run name): what replays it.
        name, source: the drive's name and the file it was read from.
        duration_s, distance_m: the drive's length in time and its GNSS (truth) distance
            (:attr:`~ionav_viz.core.drive.Drive.distance_m`).
        outage_s: the length of each outage.
        estimators: name and label of each estimator that ran, in report order.
        start_s, gnss_distance_m: per outage, its start (s since the drive's first sample) and
            the GNSS distance travelled during it (m).
        metrics: per estimator, each of :data:`METRICS` per outage.
        bias: the sensor biases the estimators were given (``accel_mps2``, ``gyro_radps``, ``source``).
        gnss_truth: what the GNSS quality checks excluded (:class:`~ionav_viz.analysis.rows.GnssTruth`).
        truth: ``gnss`` or ``reference``.
        warnings: what was warned while this drive was read and evaluated (one line each).
        elapsed_s: wall time of this drive on its worker (not part of the results).
        recording: the ``.rrd`` the drive was replayed into, if it was.
        placement: where its outages went (with the warm-up); imu: what the reader found of a log's
            IMU (rate, sample kind, clock offset, mount; ``ImuCharacter.to_dict`` and ``text``), or None.
        manoeuvre: per outage, its manoeuvre type (:func:`ionav_viz.analysis.events.outage_manoeuvres`).
        in_training: per outage, whether it lies in data the IDNN's model was trained on (as the
            single-drive report's ``in_training``; None when no IDNN ran).
        error_at_s: per estimator, per second ``"t"`` of :func:`length_points` before the outage's
            end, the position error (m) of each outage that far into it (the end's is
            ``final_position_error_m``).
        consistency: per estimator that gives a covariance, its compact per-outage values
            (:func:`ionav_viz.analysis.consistency.outage_consistency`).
        real_outages: the log's own GNSS losses, bridged (``--on gnss-outage``), each a
            :class:`~ionav_viz.analysis.rows.BridgedRow` of this drive.
    """

    spec: str
    name: str
    source: str
    duration_s: float
    distance_m: float
    outage_s: float
    estimators: list[dict[str, str]]
    start_s: np.ndarray
    gnss_distance_m: np.ndarray
    metrics: dict[str, dict[str, np.ndarray]]
    bias: dict[str, Any]
    gnss_truth: GnssTruth
    truth: str = "gnss"
    warnings: list[str] = field(default_factory=list)
    elapsed_s: float = 0.0
    recording: str | None = None
    placement: str = ""
    imu: dict[str, Any] | None = None
    manoeuvre: list[str] = field(default_factory=list)
    error_at_s: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    consistency: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    #: per outage, whether it lies in data the IDNN's model was trained on (None: no IDNN ran)
    in_training: np.ndarray | None = None
    real_outages: list[BridgedRow] = field(default_factory=list)

    @property
    def n_outages(self) -> int:
        return len(self.start_s)

    def mean_final_error_m(self, estimator: str) -> float:
        """Mean final position error of ``estimator`` over this drive's outages (NaN: did not run)."""
        if estimator not in self.metrics:
            return float("nan")
        return summarise(self.metrics[estimator]["final_position_error_m"])["mean"]


def length_points(outage_s: float) -> list[int]:
    """The seconds into an outage the fleet report breaks its errors down by: each of 10, 30 and
    60 s (:data:`~ionav_viz.analysis.consistency.RATIO_AT_S`) shorter than the outage, and its end."""
    n = int(round(outage_s))
    return [t for t in RATIO_AT_S if t < n] + [n]


def drive_table(spec: str, result: DriveResult, warnings: list[str] | None = None, elapsed_s: float = 0.0,
                recording: str | None = None, thresholds: Any = None) -> DriveTable:
    """The compact table of one drive's :class:`DriveResult` (its arrays are not kept);
    ``thresholds``: the event detectors' (:class:`~ionav_viz.analysis.events.EventThresholds`),
    which label each outage's manoeuvre."""
    from .consistency import outage_consistency
    from .events import MANOEUVRE_TYPES, detect_events, outage_manoeuvres
    from .metrics import cumulative_errors

    drive = result.drive
    early = [t for t in length_points(result.n_windows) if t < result.n_windows]
    error_at: dict[str, dict[str, np.ndarray]] = {}
    for est, sol in result.estimates.items():
        if early and len(result.starts):
            pos = cumulative_errors(result.windows, result.starts, result.n_windows, sol)["position_error_m"]
            error_at[est] = {str(t): pos[:, t - 1].copy() for t in early}
        else:
            error_at[est] = {str(t): np.zeros(len(result.starts)) for t in early}
    consistent = {est: c for est in result.estimates if (c := outage_consistency(result, est)) is not None}
    events = detect_events(drive, thresholds, MANOEUVRE_TYPES) if len(result.starts) else []
    return DriveTable(
        spec=str(spec), name=drive.name, source=drive.source, duration_s=float(drive.duration_s),
        distance_m=drive.distance_m, outage_s=result.outage_s,
        estimators=[{"name": e.name, "label": e.label, **({"color": list(c)} if (c := color_of(e)) else {})}
                    for e in result.estimators],
        start_s=np.asarray(result.outage_t0_s, dtype=float).copy(),
        gnss_distance_m=np.asarray(result.gnss_distance_m, dtype=float).copy(),
        metrics={est: {m: np.asarray(v, dtype=float).copy() for m, v in per.items()}
                 for est, per in result.metrics.items()},
        bias={"accel_mps2": float(result.bias.accel_mps2), "gyro_radps": float(result.bias.gyro_radps),
              "source": str(result.bias.source)},
        gnss_truth=GnssTruth(**result.truth_exclusions()), truth="reference" if drive.has_reference else "gnss",
        real_outages=[BridgedRow(drive.name, **b.to_dict()) for b in result.bridged],
        warnings=list(warnings or []), elapsed_s=float(elapsed_s), recording=recording, placement=result.placement,
        imu=None if drive.imu is None else {**drive.imu.to_dict(), "text": drive.imu.describe()},
        manoeuvre=outage_manoeuvres(events, result.outage_t0_s, result.outage_s), error_at_s=error_at,
        consistency=consistent,
        in_training=None if (trained := result.in_training) is None else np.asarray(trained, dtype=bool).copy())


@dataclass(frozen=True)
class DriveFailure:
    """A drive that could not be evaluated: as it was given, and why (one line, with its hint).
    ``hint``: the error's own hint, apart (empty when it had none). ``skipped``: it did not fail,
    it had nothing to score (too short for an outage; no loss of its own to bridge)."""

    spec: str
    reason: str
    elapsed_s: float = 0.0
    hint: str = ""
    skipped: bool = False


@dataclass(frozen=True)
class DriveRow:
    """One evaluated drive's row of the fleet report.

    Attributes:
        table: the drive's :class:`DriveTable`.
        mean_final_error_m: per estimator that ran on it, the mean final position error over its
            outages (m; NaN without one).
        improvement_pct: per estimator but the INS DR, how much lower that mean is than the INS
            DR's (%); None when the INS DR did not run.
    """

    table: DriveTable
    mean_final_error_m: dict[str, float]
    improvement_pct: dict[str, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The row in the JSON's ``drives``: ``drive``, ``spec``, ``source``, ``duration_s``,
        ``distance_m``, ``outages``, ``mean_final_error_m``, ``improvement_pct`` (with the INS DR),
        ``gnss_truth``, ``bias``, ``truth``, ``warnings``, where known ``placement`` and ``imu`` (the
        drive's mount and clock offset among it), and, when the drive was replayed, its ``recording``."""
        t = self.table
        row: dict[str, Any] = {"drive": t.name, "spec": t.spec, "source": t.source, "duration_s": t.duration_s,
                               "distance_m": t.distance_m, "outages": t.n_outages,
                               "mean_final_error_m": self.mean_final_error_m}
        if self.improvement_pct is not None:
            row["improvement_pct"] = self.improvement_pct
        row |= {"gnss_truth": asdict(t.gnss_truth), "bias": t.bias, "truth": t.truth, "warnings": list(t.warnings),
                **({"placement": t.placement} if t.placement else {}), **({"imu": t.imu} if t.imu else {})}
        if t.recording is not None:
            row["recording"] = t.recording
        return row


@dataclass(frozen=True)
class PooledRow:
    """One estimator pooled over a fleet's outages (a row of the pooled table, the JSON's ``pooled``).

    Attributes:
        drives, outages: how many drives it ran on, and their outages.
        spreads: each metric's spread over those outages.
        final_p50_m, final_p90_m, final_p95_m, final_max_m: the final position error's percentiles.
        improvement_pct: but for the INS DR, how much lower each of
            :data:`~ionav_viz.analysis.rows.IMPROVEMENT_METRICS`' means is than the INS DR's on
            the outages both ran on (%); None for the INS DR or without it.
        improvement_ci95_pct: the same as 95 % intervals ``[low, high]``, the drives resampled.
    """

    drives: int
    outages: int
    spreads: EstimatorRow
    final_p50_m: float
    final_p90_m: float
    final_p95_m: float
    final_max_m: float
    improvement_pct: Improvement[float] | None = None
    improvement_ci95_pct: Improvement[list[float]] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The JSON's ``pooled`` entry: ``drives``, ``outages``, ``summary``, ``final_error_percentiles``
        and, with an improvement, ``improvement_pct`` and ``improvement_ci95_pct``."""
        out: dict[str, Any] = {"drives": self.drives, "outages": self.outages,
                               "summary": {m: asdict(getattr(self.spreads, m)) for m in METRICS},
                               "final_error_percentiles": {"p50": self.final_p50_m, "p90": self.final_p90_m,
                                                           "p95": self.final_p95_m, "max": self.final_max_m}}
        if self.improvement_pct is not None:
            out |= {"improvement_pct": self.improvement_pct.to_dict(),
                    "improvement_ci95_pct": self.improvement_ci95_pct.to_dict()}
        return out


@dataclass(frozen=True)
class BreakdownRow:
    """The outages of one manoeuvre type, or one time into the outages (a row of the breakdowns,
    an entry of the JSON's ``by_manoeuvre`` or ``by_length``): ``key`` (the type, or the seconds),
    ``outages``, per estimator ``mean_error_m`` and, with the INS DR, per other estimator
    ``improvement_pct`` of that mean over the INS DR's on the outages both ran on."""

    key: str
    outages: int
    mean_error_m: dict[str, float]
    improvement_pct: dict[str, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"outages": self.outages, "mean_error_m": self.mean_error_m}
        return out | ({"improvement_pct": self.improvement_pct} if self.improvement_pct is not None else {})


@dataclass(frozen=True)
class WorstDrive:
    """One of a fleet's worst drives (the JSON's ``worst_drives`` entry): its name, how it was given
    (``spec``), per estimator that ran on it the mean final position error (m), and the ``command``
    that replays it with the fleet's outages."""

    drive: str
    spec: str
    mean_final_error_m: dict[str, float]
    command: str


@dataclass(frozen=True)
class WorstOutage(WorstRow):
    """One of a fleet's worst outages (the JSON's ``worst_outages`` entry): a drive report's
    :class:`~ionav_viz.analysis.rows.WorstRow` and the ``command`` that replays its drive and
    renders it (:meth:`FleetReport.open_command`)."""

    command: str


@dataclass(frozen=True)
class RealLossPooled:
    """One estimator over a fleet's own GNSS losses (the JSON's ``real_outages.pooled`` entry): the
    ``drives`` and ``losses`` it bridged, its mean and 90th-percentile final position error, and
    its worst loss (drive, number within it, final error)."""

    drives: int
    losses: int
    mean_final_error_m: float
    p90_final_error_m: float
    worst_drive: str
    worst_number: int
    worst_final_error_m: float

    def to_dict(self) -> dict[str, Any]:
        return {"drives": self.drives, "losses": self.losses, "mean_final_error_m": self.mean_final_error_m,
                "p90_final_error_m": self.p90_final_error_m,
                "worst": {"drive": self.worst_drive, "number": self.worst_number,
                          "final_error_m": self.worst_final_error_m}}


@dataclass(frozen=True)
class RealLossDrive:
    """One drive's own GNSS losses (the JSON's ``real_outages.drives`` entry): how many, their time
    without a fix in all (``gap_s``) and per estimator the mean final position error over them (m)."""

    drive: str
    losses: int
    gap_s: float
    mean_final_error_m: dict[str, float]


@dataclass(frozen=True)
class RealLosses:
    """A fleet's drives' own GNSS losses, bridged (``--on gnss-outage``; the JSON's ``real_outages``,
    :meth:`to_dict`): every loss, per estimator pooled over them, and per drive with losses."""

    losses: list[BridgedRow]
    pooled: dict[str, RealLossPooled]
    drives: list[RealLossDrive]

    @property
    def n(self) -> int:
        return len(self.losses)

    def to_dict(self) -> dict[str, Any]:
        return {"n": self.n, "pooled": {e: p.to_dict() for e, p in self.pooled.items()},
                "drives": [asdict(d) for d in self.drives], "losses": [asdict(b) for b in self.losses]}


@dataclass(repr=False)
class FleetReport:
    """Every drive of a fleet, each evaluated on its own, pooled.

    Attributes:
        drives: the evaluated drives, in the order they were given.
        failures: the drives that could not be evaluated, in the order they were given.
        outage_s: the outage length.
        replay_options: the options that replay a drive with the same outages (``--outage 10s
            --every 30s``), for the commands the report prints.
        timing: how the run went (``wall_s``, ``engine``, per drive ``elapsed_s``): not results,
            and the only part of :meth:`to_dict` that changes with the workers.
        skipped: drives too short for one outage (or with none on good GNSS truth), with why.
    """

    drives: list[DriveTable]
    failures: list[DriveFailure] = field(default_factory=list)
    outage_s: float = 10.0
    replay_options: str = ""
    timing: dict[str, Any] = field(default_factory=dict)
    skipped: list[DriveFailure] = field(default_factory=list)
    #: the configuration of the command that made it (:attr:`ionav_viz.analysis.report.Report.config`)
    config: dict[str, Any] | None = field(default_factory=run_config.current)

    def __repr__(self) -> str:
        return (f"FleetReport({len(self.drives)} drive(s) evaluated, {len(self.failures)} failed, "
                f"{self.n_outages} outage(s))")

    @property
    def n_outages(self) -> int:
        return int(sum(t.n_outages for t in self.drives))

    @property
    def estimators(self) -> list[str]:
        """Every estimator that ran on some drive, in the order they first appear."""
        out: list[str] = []
        for t in self.drives:
            out += [e["name"] for e in t.estimators if e["name"] not in out]
        return out

    @property
    def labels(self) -> dict[str, str]:
        out: dict[str, str] = {}
        for t in self.drives:
            out |= {e["name"]: e["label"] for e in t.estimators if e["name"] not in out}
        return out

    @property
    def colors(self) -> dict[str, list[int]]:
        """The estimators' own colours, where they have one (as their recordings draw them)."""
        out: dict[str, list[int]] = {}
        for t in self.drives:
            out |= {e["name"]: list(e["color"]) for e in t.estimators if e.get("color") and e["name"] not in out}
        return out

    @property
    def baseline(self) -> str | None:
        """The INS DR, when it ran: the estimator improvements are measured against."""
        return next((e for e in self.estimators if is_baseline(e)), None)

    @property
    def worst_of(self) -> str | None:
        """The estimator whose errors rank the worst drives and outages (the INS DR if it ran)."""
        return self.baseline or (self.estimators[0] if self.estimators else None)

    def metric(self, estimator: str, metric: str, drives: list[DriveTable] | None = None) -> np.ndarray:
        """One metric of one estimator over every outage of the drives it ran on, in input order."""
        tables = [t for t in (self.drives if drives is None else drives) if estimator in t.metrics]
        return np.concatenate([t.metrics[estimator][metric] for t in tables]) if tables else np.zeros(0)

    def pooled_rows(self) -> list[PooledRow]:
        """One :class:`PooledRow` per estimator, in the fleet's order: the same numbers as one report
        over all the drives when every drive ran every estimator; the improvement's intervals
        resample the drives (:func:`~ionav_viz.analysis.evaluate.clustered_improvement_ci95_pct`)."""
        out = []
        base = self.baseline
        for est in self.estimators:
            ran = [t for t in self.drives if est in t.metrics]
            spreads = EstimatorRow(est, self.labels[est],
                                   **{m: Spread(**summarise(self.metric(est, m))) for m in METRICS})
            final = final_error_percentiles(self.metric(est, "final_position_error_m"))
            better = ci = None
            if base is not None and est != base:
                both = [t for t in ran if base in t.metrics]
                better = Improvement(*(improvement_pct(summarise(self.metric(base, m, both))["mean"],
                                                       summarise(self.metric(est, m, both))["mean"])
                                       for m in IMPROVEMENT_METRICS))
                ci = Improvement(*(list(clustered_improvement_ci95_pct([t.metrics[base][m] for t in both],
                                                                       [t.metrics[est][m] for t in both]))
                                   for m in IMPROVEMENT_METRICS))
            out.append(PooledRow(len(ran), int(sum(t.n_outages for t in ran)), spreads,
                                 **{f"final_{k}_m": v for k, v in final.items()},
                                 improvement_pct=better, improvement_ci95_pct=ci))
        return out

    def pooled(self) -> dict[str, dict[str, Any]]:
        """:meth:`pooled_rows` as the JSON's ``pooled``, by estimator (:meth:`PooledRow.to_dict`)."""
        return {r.spreads.name: r.to_dict() for r in self.pooled_rows()}

    def _breakdown(self, keys: list[Any], mask_of: Any, value_of: Any) -> list[BreakdownRow]:
        """Per key: ``outages`` and per estimator ``mean_error_m`` over the outages ``mask_of(table,
        key)`` selects (of ``value_of(table, estimator, key)``), and for the others than the INS DR
        ``improvement_pct`` of that mean over the INS DR's on the selected outages both ran on."""
        base = self.baseline
        empty = np.zeros(0)

        def pooled(est: str, key: Any, tables: list[DriveTable]) -> np.ndarray:
            return np.concatenate([value_of(t, est, key)[mask_of(t, key)] for t in tables]) if tables else empty

        out = []
        for key in keys:
            means: dict[str, float] = {}
            better: dict[str, float] | None = None if base is None else {}
            for est in self.estimators:
                ran = [t for t in self.drives if est in t.metrics]
                means[est] = summarise(pooled(est, key, ran))["mean"]
                if better is not None and est != base:
                    both = [t for t in ran if base in t.metrics]
                    better[est] = improvement_pct(summarise(pooled(base, key, both))["mean"],
                                                  summarise(pooled(est, key, both))["mean"])
            out.append(BreakdownRow(str(key), int(sum(mask_of(t, key).sum() for t in self.drives)), means, better))
        return out

    def by_manoeuvre(self) -> dict[str, dict[str, Any]]:
        """:meth:`manoeuvre_rows` as the JSON's ``by_manoeuvre``, by type."""
        return {r.key: r.to_dict() for r in self.manoeuvre_rows()}

    def manoeuvre_rows(self) -> list[BreakdownRow]:
        """Per manoeuvre type the outages were labelled with (:attr:`DriveTable.manoeuvre`; the
        types in :data:`~ionav_viz.analysis.events.MANOEUVRE_TYPES` order, then ``none``):
        ``outages``, per estimator ``mean_error_m`` (the mean final position error) and, but for
        the INS DR, ``improvement_pct`` of it over the INS DR's on those outages."""
        from .events import MANOEUVRE_TYPES, NO_MANOEUVRE

        found = {m for t in self.drives for m in t.manoeuvre}
        keys = [k for k in (*MANOEUVRE_TYPES, NO_MANOEUVRE) if k in found]
        return self._breakdown(keys, lambda t, k: np.asarray(t.manoeuvre, dtype=object) == k,
                               lambda t, e, k: t.metrics[e]["final_position_error_m"])

    def by_length(self) -> dict[str, dict[str, Any]]:
        """:meth:`length_rows` as the JSON's ``by_length``, by seconds."""
        return {r.key: r.to_dict() for r in self.length_rows()}

    def length_rows(self) -> list[BreakdownRow]:
        """Per second ``t`` of :func:`length_points` (10, 30, 60 s into the outages, and their end):
        ``outages``, per estimator ``mean_error_m`` (the mean position error that far into the
        outages: the final error an outage of ``t`` s from the same start would have, for an
        estimator that does not look ahead) and, but for the INS DR, ``improvement_pct`` over it."""
        end = int(round(self.outage_s))

        def value_of(t: DriveTable, est: str, key: int) -> np.ndarray:
            return t.metrics[est]["final_position_error_m"] if key == end else t.error_at_s[est][str(key)]

        return self._breakdown(length_points(self.outage_s), lambda t, k: np.ones(t.n_outages, dtype=bool), value_of)

    def consistency(self) -> dict[str, dict[str, Any]]:
        """Per estimator that gives a position covariance, its consistency pooled over the fleet's
        outages (:func:`ionav_viz.analysis.consistency.pooled_consistency` of the drives' compact
        values): ANEES with its band and verdict, ``coverage_95``, ``error_over_sigma``."""
        from .consistency import pooled_consistency

        out = {}
        for est in self.estimators:
            parts = [t.consistency[est] for t in self.drives if est in t.consistency]
            if parts and (c := pooled_consistency(parts, int(round(self.outage_s)))) is not None:
                out[est] = c
        return out

    def rows(self) -> list[DriveRow]:
        """One :class:`DriveRow` per evaluated drive, in input order."""
        base = self.baseline
        rows = []
        for t in self.drives:
            means = {e: t.mean_final_error_m(e) for e in t.metrics}
            rows.append(DriveRow(
                table=t, mean_final_error_m=means,
                improvement_pct=({e: improvement_pct(means[base], v) for e, v in means.items() if e != base}
                                 if base is not None and base in means else None)))
        return rows

    def drive_rows(self) -> list[dict[str, Any]]:
        """:meth:`rows` as the JSON's ``drives`` (:meth:`DriveRow.to_dict`)."""
        return [r.to_dict() for r in self.rows()]

    @property
    def n_real_outages(self) -> int:
        return int(sum(len(t.real_outages) for t in self.drives))

    def real_losses(self) -> RealLosses:
        """The drives' own GNSS losses bridged (``--on gnss-outage``): every loss; per estimator over
        the fleet its drives, losses, mean and p90 final error and worst loss; per drive with losses
        their count, time without a fix and each estimator's mean final error."""
        losses = [b for t in self.drives for b in t.real_outages]
        pooled: dict[str, RealLossPooled] = {}
        for est in self.estimators:
            mine = [b for b in losses if est in b.final_error_m]
            if not mine:
                continue
            err = np.array([b.final_error_m[est] for b in mine], dtype=float)
            k = int(np.nanargmax(err)) if np.isfinite(err).any() else 0
            pooled[est] = RealLossPooled(len({b.drive for b in mine}), len(mine), summarise(err)["mean"],
                                         final_error_percentiles(err)["p90"], mine[k].drive, mine[k].number,
                                         float(err[k]))
        drives = [RealLossDrive(t.name, len(t.real_outages), float(sum(b.gap_s for b in t.real_outages)),
                                {e: float(np.mean([b.final_error_m[e] for b in t.real_outages]))
                                 for e in self.estimators if e in t.real_outages[0].final_error_m})
                  for t in self.drives if t.real_outages]
        return RealLosses(losses, pooled, drives)

    def real_outages(self) -> dict[str, Any]:
        """:meth:`real_losses` as the JSON's ``real_outages`` (:meth:`RealLosses.to_dict`)."""
        return self.real_losses().to_dict()

    def command(self, spec: str) -> str:
        """The command that replays one drive with the fleet's outages."""
        return " ".join(["ionav-viz replay", shlex.quote(spec),
                         self.replay_options or f"--outage {self.outage_s:g}s"]).strip()

    def open_command(self, table: DriveTable, number: int) -> str:
        """The command that shows outage ``number`` of ``table``'s drive: replay the drive with the
        fleet's outages into ``<drive>.rrd`` (unless the fleet replayed it: its recording), then
        render that outage, framed, by its number (``screenshot --outage-number``: the replay's
        "outage N", or in a fleet through the logs' own losses its real loss N)."""
        stem = safe_stem(table.name)
        rrd = table.recording or f"{stem}.rrd"
        replay = [] if table.recording else [f"{self.command(table.spec)} -o {shlex.quote(rrd)}"]
        png = f"{stem}-outage{number}.png"
        shot = f"ionav-viz screenshot {shlex.quote(rrd)} --outage-number {number} -o {shlex.quote(png)}"
        return " && ".join([*replay, shot])

    def worst_drive_rows(self, count: int = FLEET_WORST_COUNT) -> list[WorstDrive]:
        """The ``count`` drives with the largest mean final error of :attr:`worst_of`, worst first."""
        est = self.worst_of
        ranked = [(t.mean_final_error_m(est), i, t) for i, t in enumerate(self.drives) if est is not None]
        ranked = sorted([r for r in ranked if np.isfinite(r[0])], key=lambda r: (-r[0], r[1]))
        return [WorstDrive(t.name, t.spec, {e: t.mean_final_error_m(e) for e in t.metrics}, self.command(t.spec))
                for _, _, t in ranked[:count]]

    def worst_drives(self, count: int = FLEET_WORST_COUNT) -> list[dict[str, Any]]:
        """:meth:`worst_drive_rows` as the JSON's ``worst_drives``."""
        return [asdict(w) for w in self.worst_drive_rows(count)]

    def worst_outage_rows(self, count: int = FLEET_WORST_COUNT) -> list[WorstOutage]:
        """The ``count`` outages with the largest final error of :attr:`worst_of`, worst first, each
        numbered from 1 within its drive (the recording's "outage N")."""
        est = self.worst_of
        ranked = [(float(err), d, i, t) for d, t in enumerate(self.drives) if est in t.metrics
                  for i, err in enumerate(t.metrics[est]["final_position_error_m"]) if np.isfinite(err)]
        ranked.sort(key=lambda r: (-r[0], r[1], r[2]))
        return [WorstOutage(t.name, i + 1, round(float(t.start_s[i]), 3), round(float(t.start_s[i] + t.outage_s), 3),
                            {e: float(t.metrics[e]["final_position_error_m"][i]) for e in t.metrics},
                            self.open_command(t, i + 1)) for _, _, i, t in ranked[:count]]

    def worst_outages(self, count: int = FLEET_WORST_COUNT) -> list[dict[str, Any]]:
        """:meth:`worst_outage_rows` as the JSON's ``worst_outages``."""
        return [asdict(w) for w in self.worst_outage_rows(count)]

    def to_dict(self) -> dict[str, Any]:
        """The fleet's ``evaluate --json`` object, kind ``fleet`` of docs/report-schema.md (every key
        there); ``timing`` is the only key that changes from run to run. NaN is written as null."""
        sequences = []
        for t in self.drives:
            for i in range(t.n_outages):
                entry: dict[str, Any] = {"drive": t.name, "start_s": round(float(t.start_s[i]), 3),
                                         "gnss_distance_m": float(t.gnss_distance_m[i]),
                                         **({"in_training": bool(t.in_training[i])}
                                            if t.in_training is not None else {}),
                                         **({"manoeuvre": t.manoeuvre[i]} if t.manoeuvre else {})}
                entry |= {e: {m: float(t.metrics[e][m][i]) for m in METRICS} for e in t.metrics}
                sequences.append(entry)
        timing, colors = dict(self.timing), self.colors
        timing["elapsed_s"] = ({t.spec: round(t.elapsed_s, 3) for t in self.drives}
                               | {f.spec: round(f.elapsed_s, 3) for f in self.failures})
        return tagged("fleet", {
            "outage_s": self.outage_s,
            "drives_given": len(self.drives) + len(self.failures) + len(self.skipped),
            "drives_evaluated": len(self.drives), "drives_failed": len(self.failures),
            "drives_skipped": len(self.skipped),
            "n_outages": self.n_outages,
            "duration_s": float(sum(t.duration_s for t in self.drives)),
            "distance_m": float(sum(t.distance_m for t in self.drives)),
            "estimators": [{"name": e, "label": lab, **({"color": colors[e]} if e in colors else {})}
                           for e, lab in self.labels.items()],
            "pooled": self.pooled(),
            "consistency": self.consistency(),
            "by_manoeuvre": self.by_manoeuvre(),
            "by_length": self.by_length(),
            "real_outages": self.real_outages(),
            "drives": self.drive_rows(),
            "worst_of": self.worst_of,
            "worst_drives": self.worst_drives(),
            "worst_outages": self.worst_outages(),
            "failures": [{"drive": f.spec, "reason": f.reason} for f in self.failures],
            "skipped": [{"drive": f.spec, "reason": f.reason} for f in self.skipped],
            "sequences": sequences,
            **({"config": dict(self.config)} if self.config is not None else {}),
            "timing": timing,
        })

    def to_json(self, indent: int | None = 2) -> str:
        """:meth:`to_dict` as JSON (NaN as null)."""
        return dumps_json(self.to_dict(), indent=indent)

    def to_text(self, width: int | None = None) -> str:
        """The report as plain text, its tables fitted into ``width`` columns (None: no limit)."""
        return to_text(self.document(timing=True), width)

    def to_markdown(self) -> str:
        """The report as Markdown (without the run's wall time: the same whatever the workers)."""
        return to_markdown(self.document(timing=False))

    def document(self, timing: bool = True) -> Document:
        """The report as a document (:mod:`.document`): the title, the drives' own GNSS losses, the
        pooled table, the estimators' uncertainty, the breakdowns by manoeuvre and by time into
        the outage, a row per drive, the worst drives and outages with the command that replays
        each, the failed and skipped drives and the warnings; ``timing``: the wall time last."""
        return _document(self, timing)


def _own_losses_section(rep: FleetReport) -> list[Block]:
    """The fleet report's section on the drives' own GNSS losses (:meth:`FleetReport.real_losses`)."""
    real, labels = rep.real_losses(), rep.labels
    gaps = [b.gap_s for b in real.losses]
    rows = [[labels[e], str(p.drives), str(p.losses), _f(p.mean_final_error_m), _f(p.p90_final_error_m),
             f"{_f(p.worst_final_error_m, 1)} ({p.worst_drive} #{p.worst_number})"] for e, p in real.pooled.items()]
    ests = list(real.pooled)
    per_drive = [[d.drive, str(d.losses), f"{d.gap_s:.1f}"]
                 + [_f(d.mean_final_error_m.get(e, float("nan"))) for e in ests] for d in real.drives]
    return [Heading(f"Through the logs' own GNSS losses ({real.n}, {min(gaps):.0f}-{max(gaps):.0f} s "
                    "without a fix; final error from the last good fix to the first after, m)", 2),
            Table(["Estimator", "drives", "losses", "mean final m", "p90 final m", "worst m"], rows, 1, align=True),
            Table(["Drive", "losses", "without fix s"] + [labels[e] for e in ests], per_drive, 1, align=True)]


def _f(x: float, decimals: int = 2) -> str:
    return "-" if not np.isfinite(x) else f"{x:.{decimals}f}"


def _document(rep: FleetReport, timing: bool) -> Document:
    ests, labels, base = rep.estimators, rep.labels, rep.baseline
    hours = sum(t.duration_s for t in rep.drives) / 3600.0
    km = sum(t.distance_m for t in rep.drives) / 1000.0
    given = len(rep.drives) + len(rep.failures) + len(rep.skipped)
    blocks: list[Block] = [Heading(
        f"Fleet: {given} drive(s), {len(rep.drives)} evaluated"
        + (f", {len(rep.failures)} failed" if rep.failures else "")
        + (f", {len(rep.skipped)} skipped" if rep.skipped else "")
        + (f"; {rep.n_outages} outages of {rep.outage_s:g} s" if rep.n_outages or not rep.n_real_outages else "")
        + (f"; {rep.n_real_outages} of the logs' own GNSS losses bridged" if rep.n_real_outages else "")
        + f" over {hours:.2f} h and {km:.1f} km", 1)]
    if rep.n_real_outages:
        blocks += _own_losses_section(rep)
    if rep.drives and (rep.n_outages or not rep.n_real_outages):
        header = (["Estimator", "drives", "outages", "final error m", "p90 final m", "CRSE m", "yaw CRSE rad/s"]
                  + ([f"final vs {labels[base]} %", "95 % interval"] if base else []))
        rows = []
        for p in rep.pooled_rows():
            s = p.spreads
            row = [s.label, str(p.drives), str(p.outages), _f(s.final_position_error_m.mean), _f(p.final_p90_m),
                   _f(s.crse_m.mean), _f(s.yaw_crse_radps.mean, 3)]
            if base:
                row.append(_f(p.improvement_pct.final_position_error_pct, 1) if p.improvement_pct else "")
                lo, hi = (p.improvement_ci95_pct.final_position_error_pct if p.improvement_ci95_pct
                          else (float("nan"), float("nan")))
                row.append(f"{_f(lo, 1)} to {_f(hi, 1)}" if math.isfinite(lo) and math.isfinite(hi) else "")
            rows.append(row)
        blocks += [Heading("Pooled over the fleet (mean over outages)", 2), Table(header, rows, 1, align=True)]
        others = [e for e in ests if e != base]
        consistent = rep.consistency()
        if consistent:
            from .consistency import consistency_line

            blocks += [Heading("How sure each estimator is (pooled over the fleet)", 2),
                       Items([consistency_line(labels[e], c) for e, c in consistent.items()])]
        versus = f"; improvement over {labels[base]}, %" if base else ""
        for title, first, groups in (("By manoeuvre (mean final error, m", "Manoeuvre", rep.manoeuvre_rows()),
                                     ("By time into the outage (mean position error, m", "Into outage",
                                      rep.length_rows())):
            header = ([first, "outages"] + [labels[e] for e in ests]
                      + ([f"{labels[e]} %" for e in others] if base else []))
            rows = []
            for g in groups:
                row = ([g.key if first == "Manoeuvre" else f"{g.key} s", str(g.outages)]
                       + [_f(g.mean_error_m[e]) for e in ests])
                if base:
                    row += [_f((g.improvement_pct or {})[e], 1) for e in others]
                rows.append(row)
            blocks += [Heading(f"{title}{versus})", 2), Table(header, rows, 1, align=True)]
        header = (["Drive", "outages", "h", "km", "bad GNSS %"] + [labels[e] for e in ests]
                  + ([f"{labels[e]} %" for e in others] if base else []) + ["warnings"])
        rows = []
        for r in rep.rows():
            t, means = r.table, r.mean_final_error_m
            windows = t.gnss_truth.windows
            bad_pct = 100.0 * t.gnss_truth.excluded_windows / windows if windows else float("nan")
            row = [t.name, str(t.n_outages), f"{t.duration_s / 3600:.2f}", f"{t.distance_m / 1000:.1f}", _f(bad_pct, 1)]
            row += [_f(means.get(e, float("nan"))) for e in ests]
            if base:
                row += [_f((r.improvement_pct or {}).get(e, float("nan")), 1) for e in others]
            rows.append(row + [str(len(t.warnings))])
        blocks += [Heading(f"Per drive (mean final error, m{versus})", 2), Table(header, rows, 1, align=True)]
        worst_drives = rep.worst_drive_rows()
        if worst_drives:
            blocks += [Heading(f"Worst drives (by {labels[rep.worst_of]} mean final error)", 2),
                       Items([(f"{w.drive}: {_f(w.mean_final_error_m[rep.worst_of])} m; replay: ", Code(w.command))
                              for w in worst_drives], numbered=True)]
        worst = rep.worst_outage_rows()
        if worst:
            blocks += [Heading(f"Worst outages (by {labels[rep.worst_of]} final error)", 2),
                       Items([(f"{w.drive} outage {w.number} ({w.start_s:.0f}-{w.end_s:.0f} s): "
                               + ", ".join(f"{labels[e]} {_f(v, 1)} m" for e, v in w.final_error_m.items())
                               + "; see it: ", Code(w.command)) for w in worst], numbered=True)]
    for title, items in (("Failed drives", rep.failures), ("Skipped drives", rep.skipped)):
        if items:
            blocks += [Heading(f"{title} ({len(items)})", 2), Items([f"{f.spec}: {f.reason}" for f in items])]
    warned = [(t.name, w) for t in rep.drives for w in t.warnings]
    if warned:
        blocks += [Heading(f"Warnings ({len(warned)})", 2),
                   Items([w if w.startswith(name) else f"{name}: {w}" for name, w in warned])]
    if timing and rep.timing.get("wall_s") is not None:
        blocks.append(Paragraphs([f"{rep.timing.get('engine', '')}: {rep.timing['wall_s']:.1f} s wall time"]))
    return Document(blocks, spaced=True, hang=3)
