"""Reports: the per-outage metrics and their summaries across drives, as JSON, text or Markdown.

A :class:`Report` is what ``ionav-viz evaluate`` prints for one group of drives (one scenario,
one manoeuvre type, or the drives given); :meth:`Report.to_json` is exactly ``evaluate --json``.
Groups of reports (``--scenario all``, ``--by-event``) print as ``{"scenarios": {...}}`` or
``{"by_event": {...}}`` (:func:`reports_to_json`) and as one overview table
(:func:`render_overview`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ..core import run_config
from ..core.drive import drive_labels
from ..core.errors import InputError
from ..core.json_out import dumps_json
from . import tables
from .consistency import consistency
from .document import Block, Document, Heading, Items, Paragraphs, Table, aligned, to_markdown, to_text
from .drift import final_error_percentiles, report_drift
from .evaluate import DriveResult, improvement_ci95_pct, improvement_pct, is_baseline
from .health import pooled_health, summarise_health
from .metrics import METRICS, summarise
from .rows import (
    IMPROVEMENT_METRICS,
    BridgedRow,
    DomainNote,
    DriftRow,
    DriveEntry,
    EstimatorRow,
    GnssOutages,
    GnssTruth,
    Improvement,
    LengthRow,
    Spread,
    WorstRow,
)
from .schema import tagged

#: How many of the worst outages reports list.
WORST_COUNT = 3


@dataclass(repr=False)
class Report:
    """Metrics of every estimator on the outages of one or more drives.

    Attributes:
        results: one :class:`~ionav_viz.analysis.evaluate.DriveResult` per drive.
        title: the group's name (a scenario or manoeuvre type), or None.
        warnings: what the run warned about while reading the drives and running the estimators
            (one line each), so that a report read later says it too.
        config: the configuration of the command that made it, as an experiment file holds it
            (default: the running command's, :mod:`ionav_viz.core.run_config`; None from a script).
    """

    results: list[DriveResult]
    title: str | None = None
    warnings: list[str] = field(default_factory=list)
    config: dict[str, Any] | None = field(default_factory=run_config.current)
    _dict: dict[str, Any] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if not self.results:
            raise InputError("a report needs at least one evaluated drive")
        names = [e.name for e in self.results[0].estimators]
        for res in self.results[1:]:
            if [e.name for e in res.estimators] != names:
                raise ValueError("every drive of a report must be evaluated with the same estimators")

    def __repr__(self) -> str:
        drives = ", ".join(r.drive.name for r in self.results)
        title = f"{self.title!r}, " if self.title else ""
        return (f"Report({title}{len(self.results)} drive(s): {drives}; {self.n_outages} outage(s); "
                f"{self.summary_line()})")

    def summary_line(self) -> str:
        """Each estimator's mean final position error, in one line (``"mean final error: INS DR 8.17 m, ..."``)."""
        means = []
        for name, label in self.labels.items():
            errors = self.metric(name, "final_position_error_m")
            finite = errors[np.isfinite(errors)]
            means.append(f"{label} {float(finite.mean()):.2f} m" if len(finite) else f"{label} -")
        return "mean final error: " + ", ".join(means) if self.n_outages else "no synthetic outage"

    @property
    def estimators(self) -> list[str]:
        """Estimator names in report order."""
        return [e.name for e in self.results[0].estimators]

    @property
    def labels(self) -> dict[str, str]:
        return {e.name: e.label for e in self.results[0].estimators}

    @property
    def n_outages(self) -> int:
        """Synthetic outages over all drives (the JSON's ``n_sequences``, the paper's word)."""
        return int(sum(len(r.starts) for r in self.results))

    def metric(self, estimator: str, metric: str) -> np.ndarray:
        """One metric of one estimator for every outage of every drive, shape (n_sequences,); an
        estimator the report does not hold or a metric not of :data:`METRICS` is an InputError
        naming the choices (a bare ``KeyError: 'idnn'`` otherwise)."""
        if estimator not in self.estimators:
            raise InputError(f"no estimator {estimator!r} in this report",
                             f"choose from {', '.join(self.estimators) or '(none)'}", param="estimator")
        if metric not in METRICS:
            raise InputError(f"unknown metric {metric!r}", f"choose from {', '.join(METRICS)}", param="metric")
        return np.concatenate([r.metrics[estimator][metric] for r in self.results])

    @cached_property
    def drive_labels(self) -> list[str]:
        """Each result's drive as the report names it: its name, or its file where two drives of the
        report share a name (``a/V-x.csv`` and ``b/V-x.csv``; :func:`ionav_viz.core.drive.drive_labels`)."""
        return drive_labels([r.drive for r in self.results])

    @cached_property
    def estimator_rows(self) -> list[EstimatorRow]:
        """Per estimator, in report order: each metric's :class:`Spread` across the outages."""
        return [EstimatorRow(est, label, **{m: Spread(**summarise(self.metric(est, m))) for m in METRICS})
                for est, label in self.labels.items()]

    @cached_property
    def summary(self) -> dict[str, dict[str, dict[str, float]]]:
        """Per estimator and metric: ``max``, ``min``, ``mean``, ``std`` across outages (:attr:`estimator_rows`)."""
        return {r.name: {m: asdict(getattr(r, m)) for m in METRICS} for r in self.estimator_rows}

    @cached_property
    def improvement_pct(self) -> dict[str, Improvement[float]]:
        """Per estimator other than the INS DR: how much lower its mean metrics are than the INS's (%;
        ``improvement_pct["idnn"]["crse_m"]``); none without the INS DR."""
        base = next((n for n in self.estimators if is_baseline(n)), None)
        return {} if base is None else {
            est: Improvement(*(improvement_pct(self.summary[base][m]["mean"], self.summary[est][m]["mean"])
                               for m in IMPROVEMENT_METRICS))
            for est in self.estimators if est != base}

    @cached_property
    def improvement_ci95_pct(self) -> dict[str, Improvement[list[float]]]:
        """:attr:`improvement_pct`'s 95 % intervals, ``[low, high]`` per estimator and metric: a paired
        bootstrap over the outages (:func:`~ionav_viz.analysis.evaluate.improvement_ci95_pct`)."""
        base = next((n for n in self.estimators if is_baseline(n)), None)
        return {} if base is None else {
            est: Improvement(*(list(improvement_ci95_pct(self.metric(base, m), self.metric(est, m)))
                               for m in IMPROVEMENT_METRICS))
            for est in self.estimators if est != base}

    @property
    def worst_of(self) -> str:
        """The estimator whose final position error ranks the worst outages: the INS DR if it ran."""
        return next((n for n in self.estimators if is_baseline(n)), self.estimators[0])

    def worst_rows(self, count: int = WORST_COUNT, estimator: str | None = None) -> list[WorstRow]:
        """The ``count`` outages with the largest final position error of ``estimator`` (default
        :attr:`worst_of`), worst first."""
        est = estimator or self.worst_of
        ranked = [(float(err), r, label, i) for r, label in zip(self.results, self.drive_labels)
                  for i, err in enumerate(r.metrics[est]["final_position_error_m"]) if np.isfinite(err)]
        ranked.sort(key=lambda x: -x[0])
        return [WorstRow(label, i + 1, round(float(r.outage_t0_s[i]), 3),
                         round(float(r.outage_t0_s[i] + r.n_windows), 3),
                         {e: float(r.metrics[e]["final_position_error_m"][i]) for e in self.estimators})
                for _err, r, label, i in ranked[:count]]

    def worst_outages(self, count: int = WORST_COUNT, estimator: str | None = None) -> list[dict[str, Any]]:
        """:meth:`worst_rows` as the JSON's ``worst`` entries: ``drive``, ``number``, ``start_s``,
        ``end_s`` and ``final_error_m`` per estimator."""
        return [asdict(w) for w in self.worst_rows(count, estimator)]

    @cached_property
    def drift_rows(self) -> list[DriftRow]:
        """Per estimator, in report order, its drift curve and final-error percentiles; none without outages."""
        if not self.n_outages:
            return []
        drift = report_drift(self.results, self.estimators)
        final = {est: final_error_percentiles(self.metric(est, "final_position_error_m")) for est in self.estimators}
        return [DriftRow(est, label, **drift[est], **{f"final_{k}_m": v for k, v in final[est].items()})
                for est, label in self.labels.items()]

    @cached_property
    def bridged_rows(self) -> list[BridgedRow]:
        """The log's own GNSS losses the estimators bridged, drive by drive."""
        return [BridgedRow(label, **b.to_dict())
                for r, label in zip(self.results, self.drive_labels) for b in r.bridged]

    @cached_property
    def gnss_outages(self) -> GnssOutages | None:
        """The log's own GNSS losses, bridged or not; None where the drives had none."""
        results = self.results
        if not any(r.bridged or r.unbridged for r in results):
            return None
        bridged = [b for r in results for b in r.bridged]
        return GnssOutages(self.bridged_rows, sum(sum(r.unbridged.values()) for r in results),
                           _summed_counts([r.unbridged for r in results]),
                           {e: Spread(**summarise(np.array([b.final_error_m[e] for b in bridged])))
                            for e in self.estimators})

    @cached_property
    def distance_m(self) -> Spread:
        """The GNSS distance driven during each outage, across the outages (m; the JSON leaves out its ``std``)."""
        return Spread(**summarise(np.concatenate([r.gnss_distance_m for r in self.results])))

    @property
    def drive(self) -> str:
        """The drives' names joined by ``+`` (the JSON's ``drive``)."""
        return "+".join(r.drive.name for r in self.results)

    @cached_property
    def drive_entries(self) -> list[DriveEntry]:
        """Each drive: its name in the report, source, GNSS truth, placement, IMU and filter health."""
        return [DriveEntry(label, r.drive.source, GnssTruth(**r.truth_exclusions()), r.placement or "",
                           *((r.drive.imu.to_dict(), r.drive.imu.describe()) if r.drive.imu is not None else ()),
                           filter_health=_drive_health(r))
                for r, label in zip(self.results, self.drive_labels)]

    @cached_property
    def gnss_truth(self) -> GnssTruth:
        """What the GNSS quality checks excluded, summed over the drives."""
        parts = [d.gnss_truth for d in self.drive_entries]
        return GnssTruth(sum(p.windows for p in parts), sum(p.excluded_windows for p in parts),
                         _summed_counts([p.excluded_by_reason for p in parts]),
                         sum(p.receiver_lost_windows for p in parts), sum(p.excluded_outages for p in parts))

    @cached_property
    def filter_health(self) -> dict[str, dict[str, Any]]:
        """Per estimator that reports one, its filters' health over the drives (:func:`~.health.pooled_health`)."""
        health = {est: pooled_health([d.filter_health[est] for d in self.drive_entries if est in d.filter_health])
                  for est in self.estimators}
        return {est: h for est, h in health.items() if h}

    @cached_property
    def estimator_info(self) -> list[dict[str, Any]]:
        """Name, label, colour and the estimator's own description (``info``) of each estimator."""
        return self.results[0].estimator_info()

    @cached_property
    def arbiter_notes(self) -> dict[str, str]:
        """Per estimator that chose per outage from its pseudo-outages over the GNSS before it (a
        history arbiter: ``gins``'s propagation, :func:`ionav_viz.nav.gins.arbitrate`; the IDNN's share
        of the INS DR's displacement, :class:`ionav_viz.learning.idnn.IdnnEstimator`): what it chose
        and why, as its own description's ``arbiter`` says of the last drive it ran on."""
        return {e["name"]: note for e in self.estimator_info if (note := e.get("info", {}).get("arbiter"))}

    @cached_property
    def domain_notes(self) -> list[DomainNote]:
        """Each estimator's drives whose inputs lie outside its model's training (its ``info.domain``)."""
        return [DomainNote(e["name"], drive, list(n["outside"]), n["sigma_scale_median"], n["sigma_scale_max"])
                for e in self.estimator_info for drive, n in (e.get("info", {}).get("domain") or {}).items()]

    def outage_tracks(self, drive: str, number: int) -> dict[str, Any]:
        """One outage's tracks at its window boundaries: ``drive``, ``number``, ``start_s``, and
        per estimator and ``truth`` the ``east_m`` and ``north_m`` of each boundary, metres on the
        local plane about the truth at the outage's start (for figures with a scale bar)."""
        from ..core.geo import local_en_m

        res = next((r for r, label in zip(self.results, self.drive_labels) if label == drive), None)
        if res is None:
            raise InputError(f"no evaluated drive is named {drive!r}", hint="one of: " + ", ".join(self.drive_labels),
                             param="drive")
        if not 1 <= number <= len(res.starts):
            raise InputError(f"drive {drive} has no outage {number}",
                             hint=f"outages are numbered 1 to {len(res.starts)}", param="number")
        i = number - 1
        lat, lon, _ = res.windows.boundary_fixes(res.starts[i : i + 1], res.n_windows)
        lat0, lon0 = float(lat[0, 0]), float(lon[0, 0])
        lines = {"truth": (lat[0], lon[0])}
        lines |= {e: (res.estimates[e].track.lat_deg[i], res.estimates[e].track.lon_deg[i]) for e in self.estimators}
        out: dict[str, Any] = {"drive": drive, "number": number,
                               "start_s": round(float(res.windows.t0_s[res.starts[i]]), 3)}
        for name, (lat, lon) in lines.items():
            east, north = local_en_m(lat, lon, lat0, lon0)
            out[name] = {"east_m": np.round(east, 4).tolist(), "north_m": np.round(north, 4).tolist()}
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``evaluate --json`` object, kind ``report`` of docs/report-schema.md (every key there).
        NaN is kept here; :meth:`to_json` writes it as null (:mod:`ionav_viz.core.json_out`)."""
        if self._dict is not None:
            return self._dict
        results, estimators = self.results, self.estimators
        sequences = []
        for res, label in zip(results, self.drive_labels):
            dist = res.gnss_distance_m
            trained = res.in_training
            for i, k in enumerate(res.starts):
                entry: dict[str, Any] = {
                    "drive": label,
                    "start_s": round(float(res.windows.t0_s[k]), 3),
                    "gnss_distance_m": float(dist[i]),
                }
                if trained is not None:
                    entry["in_training"] = bool(trained[i])
                for est in estimators:
                    entry[est] = {m: float(res.metrics[est][m][i]) for m in METRICS}
                sequences.append(entry)
        out: dict[str, Any] = tagged("report", {
            "drive": self.drive,
            "drives": [d.to_dict() for d in self.drive_entries],
            "outage_s": results[0].outage_s,
            "n_sequences": len(sequences),
            "sequences": sequences,
            "summary": self._summary_with_consistency(),
            "distance_m": {k: v for k, v in asdict(self.distance_m).items() if k != "std"},
            "bias": [
                {"drive": label, "accel_mps2": r.bias.accel_mps2, "gyro_radps": r.bias.gyro_radps,
                 "source": r.bias.source}
                for r, label in zip(results, self.drive_labels)
            ],
            "estimators": self.estimator_info,
            "gnss_truth": asdict(self.gnss_truth),
        })
        if self.improvement_pct:
            out["improvement_pct"] = {e: i.to_dict() for e, i in self.improvement_pct.items()}
            out["improvement_ci95_pct"] = {e: i.to_dict() for e, i in self.improvement_ci95_pct.items()}
        if self.drift_rows:
            out["drift"] = {d.name: {"t_s": d.t_s, "mean_m": d.mean_m, "p10_m": d.p10_m, "p90_m": d.p90_m}
                            for d in self.drift_rows}
            out["final_error_percentiles"] = {d.name: {"p50": d.final_p50_m, "p90": d.final_p90_m, "p95": d.final_p95_m,
                                                       "max": d.final_max_m} for d in self.drift_rows}
        out["worst_of"] = self.worst_of
        out["worst"] = self.worst_outages()
        if out["worst"]:
            out["worst_tracks"] = self.outage_tracks(out["worst"][0]["drive"], out["worst"][0]["number"])
        if self.gnss_outages is not None:
            out["gnss_outages"] = asdict(self.gnss_outages)
        idnn = next((e for e in out["estimators"] if e["name"] == "idnn"), None)
        if idnn is not None:
            out["model"] = idnn.get("info", {})
        out["truth"] = "reference" if any(r.drive.has_reference for r in results) else "gnss"
        if self.filter_health:
            out["filter_health"] = self.filter_health
        out["warnings"] = list(self.warnings)
        if self.config is not None:
            out["config"] = dict(self.config)
        self._dict = out
        return out

    @cached_property
    def consistency(self) -> dict[str, dict[str, Any]]:
        """Per estimator that gives a position covariance: how honest it is (:mod:`.consistency`)."""
        out = {}
        for est in self.estimators:
            c = consistency(self.results, est)
            if c is not None:
                out[est] = c
        return out

    def _summary_with_consistency(self) -> dict[str, Any]:
        return {est: ({**stats, "consistency": self.consistency[est]} if est in self.consistency else stats)
                for est, stats in self.summary.items()}

    def to_json(self, indent: int | None = 2) -> str:
        """Exactly what ``ionav-viz evaluate --json`` prints for one group (NaN as null)."""
        return dumps_json(self.to_dict(), indent=indent)

    def document(self) -> Document:
        """The report as a document (:mod:`.document`), what :meth:`to_text` and :meth:`to_markdown` lay
        out: the paper's table, the log's own GNSS outages where it bridged some, a line each on the
        improvements, the GNSS truth, the drives, the estimators' uncertainty, health and choices,
        then the drift and the worst outages: from the typed values the JSON is built from
        (:attr:`estimator_rows`, :attr:`gnss_outages`, :attr:`drift_rows`, :meth:`worst_rows`,
        :attr:`improvement_pct`, :attr:`gnss_truth`, :attr:`drive_entries`, ...), never from the JSON."""
        labels, n, real = self.labels, self.n_outages, self.gnss_outages
        blocks: list[Block] = []
        if n or real is None:
            header, rows = tables.estimator_table(self.estimator_rows, self.distance_m, n)
            blocks += [Heading(tables.title_of(self.drive, self.results[0].outage_s, self.title)),
                       Table(header, rows, 2, strong_first=True)]
        if real is not None:
            header, rows = tables.bridged_table(real.bridged, labels, len({b.drive for b in real.bridged}) > 1)
            blocks += [Heading(f"{self.drive}: the log's own GNSS outages",
                               note="(truth: the first good fix after each)"),
                       Table(header, rows, 1), Paragraphs([tables.bridged_line(real, labels)])]
        blocks.append(Paragraphs(self.lines()))
        if self.drift_rows:
            header, rows = tables.drift_table(self.drift_rows)
            blocks += [Heading(tables.DRIFT_TITLE, lead_in=True), Table(header, rows, 1)]
        worst = self.worst_rows()
        if worst:
            several = len({w.drive for w in worst}) > 1 or "+" in self.drive
            header, rows = tables.worst_table(worst, labels, several)
            blocks += [Heading(f"Worst outages by {labels[self.worst_of]} final position error", lead_in=True),
                       Table(header, rows, 3 if several else 2)]
        return Document(blocks, spaced=False)

    def lines(self) -> list[str]:
        """The lines under the report's tables, from its typed values: the improvements where it has
        synthetic outages, the GNSS truth, the drives, the estimators' uncertainty, health and choices."""
        from .consistency import consistency_line
        from .health import health_line

        labels = self.labels
        said = (tables.improvement_lines(labels, self.improvement_pct, self.improvement_ci95_pct)
                if self.n_outages else [])
        said += [tables.truth_line(self.gnss_truth), *tables.drive_lines(self.drive_entries)]
        said += [consistency_line(labels[est], c) for est, c in self.consistency.items()]
        said += [health_line(labels[est], summary) for est, summary in self.filter_health.items()]
        if len(self.results) == 1:  # an estimator describes the last drive it ran on: several leave it to each's own
            said += [f"{labels[e]} arbiter: {note}" for e, note in self.arbiter_notes.items()]
        return said + [f"{labels[n.estimator]} out of its training domain on {n.drive}: {tables.domain_detail(n)}"
                       for n in self.domain_notes]

    def to_text(self, width: int | None = None) -> str:
        """The paper's table layout (Tables 8-12) as plain text; ``width``: fit tables and lines
        into that many columns (wrapped headers, then blocks of columns), None: no limit."""
        return to_text(self.document(), width)

    def to_markdown(self) -> str:
        """The same table as Markdown."""
        return to_markdown(self.document())


def _drive_health(result: DriveResult) -> dict[str, Any]:
    """Each estimator's filter health on one drive (:mod:`.health`), for those that report one."""
    return {name: summarise_health(sol.health) for name, sol in result.estimates.items() if sol.health is not None}


def _summed_counts(parts: list[dict[str, int]]) -> dict[str, int]:
    """Counts per name, summed over ``parts`` (names in the order first met)."""
    total: dict[str, int] = {}
    for part in parts:
        for name, n in part.items():
            total[name] = total.get(name, 0) + n
    return total


def combined(reports: Mapping[Any, Report]) -> Report:
    """One report over every drive of several groups (the total of an overview)."""
    return Report([r for rep in reports.values() for r in rep.results], "total")


def overview_reports(reports: Mapping[Any, Report], by_group: bool = False) -> dict[str, Report]:
    """The rows of an overview: one per drive (named ``group: drive`` in named groups), or one per
    group with ``by_group`` (manoeuvre types share drives), then ``total`` over every outage."""
    rows: dict[str, Report] = {}
    for group, rep in reports.items():
        if by_group:
            rows[str(group)] = rep
            continue
        # two drives of one name: by their files
        for res, label in zip(rep.results, drive_labels([r.drive for r in rep.results])):
            rows[f"{group}: {label}" if group else label] = Report([res], res.drive.name)
    rows["total"] = combined(reports)
    return rows


def overview_rows(reports: Mapping[Any, Report], label: str = "Scenario") -> tuple[list[str], list[list[str]]]:
    """One row per scenario (or drive group): mean CRSE and final position error per estimator,
    the INS DR first, each other estimator with its improvement over the INS DR (Δ %)."""
    labels = next(iter(reports.values())).labels
    names = [n for n in labels if n == "ins"] + [n for n in labels if n != "ins"]
    blocks = (("Disp. CRSE μ", "crse_m", "m", 2, "crse_pct"),
              ("Yaw CRSE μ", "yaw_crse_radps", "rad/s", 3, "yaw_crse_pct"),
              ("Final pos. err. μ", "final_position_error_m", "m", 2, None),
              ("Final err. μ", "final_error_pct", "% of distance", 1, None))
    header = [label, "Sequences"]
    for title, _metric, unit, _d, delta in blocks:
        for i, est in enumerate(names):
            header.append(f"{title} {labels[est]} ({unit})" if i == 0 else f"{labels[est]} ({unit})")
            if delta and est != "ins" and "ins" in names:
                header.append("Δ %")
    rows = []
    for group, rep in reports.items():
        means, imp = {r.name: r for r in rep.estimator_rows}, rep.improvement_pct
        row = [str(group or rep.drive), str(rep.n_outages)]
        for _title, metric, _unit, d, delta in blocks:
            for est in names:
                row.append(tables._fmt(getattr(means[est], metric).mean, d) if est in means else "-")
                if delta and est != "ins" and "ins" in names:
                    row.append(tables._fmt(getattr(imp[est], delta), 1) if est in imp else "-")
        rows.append(row)
    return header, rows


def render_overview(reports: Mapping[Any, Report], markdown: bool, label: str = "Scenario",
                    width: int | None = None) -> str:
    """The overview table; Δ % is an estimator's improvement over the INS DR (positive = better).

    As text wider than ``width`` it is transposed: one column per group, one row per metric and
    estimator (and split into blocks of groups if that is still too wide)."""
    header, rows = overview_rows(reports, label)
    if markdown:
        return to_markdown(Document([Table(header, rows)]))
    widths = [max(len(r[j]) for r in [header] + rows) for j in range(len(header))]
    lines = ["  ".join(c.rjust(w) if j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths)))
             for r in [header] + rows]
    if width is not None and max(map(len, lines)) > width:
        lines = aligned(*overview_transposed(reports, label), 2, width)
    return "\n".join(lines) + "\n"


def overview_transposed(reports: Mapping[Any, Report], label: str = "Scenario") -> tuple[list[str], list[list[str]]]:
    """The overview with one column per group: rows are (metric, estimator) and each candidate's
    improvement over the INS DR (``Δ %``) under it."""
    header, rows = overview_rows(reports, label)
    labels = next(iter(reports.values())).labels
    # "motorway: V-sim-motorway" -> its group
    out_header = ["Metric", "Estimator", *(r[0].split(": ")[0] for r in rows)]
    out_rows = [["Sequences", "", *(r[1] for r in rows)]]
    metric = ""
    for j in range(2, len(header)):
        name = header[j]
        est = next((lab for lab in labels.values() if name.startswith(f"{lab} (") or f" {lab} (" in name), "")
        if name == "Δ %":
            out_rows.append(["", f"{out_rows[-1][1]} Δ %", *(r[j] for r in rows)])
            continue
        title = name[: name.index(est)].strip() if est and not name.startswith(est) else ""
        unit = name[name.rindex("(") :].replace("% of distance", "% of dist.")
        if title:
            metric = f"{title} {unit}"
        out_rows.append([metric if title else "", est, *(r[j] for r in rows)])
    return out_header, out_rows


class EventReports(dict):
    """Reports by manoeuvre type (a ``dict``: ``evaluate --by-event``), in the order the types were
    asked for; a type that got no outage has no report. ``events``: how many events of each type
    asked for were found across the drives, 0 included; ``outage_s``: the outages' length."""

    def __init__(self, reports: Mapping[str, Report], events: Mapping[str, int], outage_s: float) -> None:
        super().__init__(reports)
        self.events, self.outage_s = dict(events), float(outage_s)

    def without_outage_lines(self) -> list[str]:
        """One line per type asked for that got no outage: ``quick-accel: 0 events``, or
        ``roundabout: 2 events, none with room for a 10 s outage``."""
        return [f"{kind}: 0 events" if not n else
                f"{kind}: {n} event{'s' if n != 1 else ''}, none with room for a {self.outage_s:g} s outage"
                for kind, n in self.events.items() if kind not in self]


def reports_to_json(reports: Mapping[str, Report], key: str = "scenarios", indent: int | None = 2) -> str:
    """Several groups as one JSON object ``{key: {group: report}, "worst": [...]}`` (``evaluate
    --scenario all --json``); ``worst`` ranks the outages of every group together. Reports by
    manoeuvre type (:class:`EventReports`) add ``events``: how many of each type asked for were
    found, 0 included (a type with none, or none with room for an outage, has no report)."""
    total = combined(reports)
    events = {"events": reports.events} if isinstance(reports, EventReports) else {}
    return dumps_json(tagged(key, {key: {g: r.to_dict() for g, r in reports.items()}, **events,
                                   "worst_of": total.worst_of, "worst": total.worst_outages()}), indent=indent)


def length_rows(reports: Mapping[float, Report]) -> list[LengthRow]:
    """Error against outage length (``evaluate --outage 10s,30s,60s``): a :class:`LengthRow` per
    estimator, in report order, over each length's outages."""
    reps = [reports[x] for x in sorted(reports)]

    def means(est: str, metric: str) -> list[float]:
        return [r.summary[est][metric]["mean"] if r.n_outages else float("nan") for r in reps]

    return [LengthRow(est, label, [float(x) for x in sorted(reports)], [r.n_outages for r in reps],
                      means(est, "final_position_error_m"), means(est, "final_error_pct"), means(est, "crse_m"),
                      [final_error_percentiles(r.metric(est, "final_position_error_m"))["p90"] for r in reps])
            for est, label in reps[0].labels.items()]


def by_length(reports: Mapping[float, Report]) -> dict[str, Any]:
    """:func:`length_rows` as the JSON's ``by_length``, by estimator (:meth:`LengthRow.to_dict`)."""
    return {r.name: r.to_dict() for r in length_rows(reports)}


def lengths_to_json(reports: Mapping[float, Report], indent: int | None = 2) -> str:
    """Several outage lengths as one JSON object: ``lengths`` (each length's report, keyed by its
    seconds) and ``by_length`` (:func:`by_length`)."""
    return dumps_json(tagged("lengths", {"lengths": {f"{k:g}": r.to_dict() for k, r in sorted(reports.items())},
                                         "by_length": by_length(reports)}), indent=indent)


def _bridged_loss_blocks(result: DriveResult, label: Mapping[str, str], ests: list[str], worst: int) -> list[Block]:
    """On the log's own GNSS losses the estimators bridged (``--on gnss-outage``): each estimator's
    mean final error over them and the ``worst`` worst of them (by the first estimator's error,
    the INS DR where it ran); nothing without any."""
    bridged = result.bridged
    if not bridged:
        return []
    mean = {e: float(np.mean([b.final_error_m[e] for b in bridged])) for e in ests}
    by = ests[0]
    lines = [f"**Real GNSS outages**: {len(bridged)} ({sum(b.gap_s for b in bridged):.0f} s without GNSS), "
             f"final error from the last good fix, mean m: " + ", ".join(f"{label[e]} {mean[e]:.1f}" for e in ests)]
    lines += [f"{'**Worst real**' if worst == 1 else '-'} #{b.number} ({b.gap_t0_s:.0f}-{b.gap_t1_s:.0f} s, m): "
              + ", ".join(f"{label[e]} {b.final_error_m[e]:.1f}" for e in ests)
              for b in sorted(bridged, key=lambda b: -b.final_error_m[by])[:worst]]
    return [Paragraphs(lines)]


def _means_table(report: Report, label: Mapping[str, str], header: list[str]) -> list[Block]:
    """Each estimator's mean final error (m), displacement CRSE (m) and yaw CRSE (rad/s), under
    ``header``; nothing without synthetic outages."""
    rows = [[label[r.name], f"{r.final_position_error_m.mean:.2f}", f"{r.crse_m.mean:.2f}",
             f"{r.yaw_crse_radps.mean:.3f}"] for r in report.estimator_rows]
    return [Table(header, rows)] if report.n_outages else []


def overview_markdown(result: DriveResult, report: Report) -> str:
    """The summary's head as Markdown, short enough for a screenshot's summary tab (the
    recording's ``overview``): the run in a line, each estimator's means, the worst outage. The
    units sit beside the column names, not in brackets: the table fits a 1024-pixel image's
    summary column."""
    ests = report.estimators
    label = {e.name: e.label for e in result.estimators}
    head = f": {report.n_outages} outage(s) of {result.outage_s:g} s" if report.n_outages else ""
    # only the log's own losses: no table of synthetic outages to fill with nothing
    blocks: list[Block] = [Paragraphs([f"**{result.drive.name}**{head}"]),
                           *_means_table(report, label, ["mean", "final m", "CRSE m", "yaw rad/s"]),
                           # the worst real one where there is room: the screenshot's summary tab holds one worst line
                           *_bridged_loss_blocks(result, label, ests, worst=0 if report.n_outages else 1)]
    said = [f"**Worst** #{w.number} ({w.start_s:.0f}-{w.end_s:.0f} s, m): "
            + ", ".join(f"{label[e]} {w.final_error_m[e]:.1f}" for e in ests) for w in report.worst_rows(1)]
    if report.warnings:  # the Details tab beside this one lists them, with the run's parameters
        said.append(f"**{len(report.warnings)} warning(s)**: see Details.")
    return to_markdown(Document([*blocks, Paragraphs(said)]))


def run_summary_markdown(result: DriveResult, report: Report, placement: str) -> str:
    """A replay's parameters as Markdown (the recording's summary document)."""
    drive, bias = result.drive, result.bias
    names = [e.label for e in result.estimators]
    labels = " and ".join([", ".join(names[:-1]), names[-1]]) if len(names) > 1 else names[0]
    ests = report.estimators
    label = {e.name: e.label for e in result.estimators}
    blocks: list[Block] = [
        Paragraphs([f"**{drive.name}**: {labels}, {report.n_outages} GNSS outage(s) of {result.outage_s:g} s"]),
        *_means_table(report, label, ["mean", "final error (m)", "disp. CRSE (m)", "yaw CRSE (rad/s)"]),
        *_bridged_loss_blocks(result, label, ests, worst=3),
    ]
    worst = report.worst_rows()
    if worst:
        blocks += [Paragraphs([f"**Worst outages** (by {label[report.worst_of]} final error, m):"]),
                   Items([f"#{w.number} ({w.start_s:.0f}-{w.end_s:.0f} s): "
                          + ", ".join(f"{label[e]} {w.final_error_m[e]:.1f}" for e in ests) for w in worst])]
    if report.warnings:
        blocks += [Paragraphs(["**Warnings** (as printed when the run was made):"]), Items(list(report.warnings))]
    lines = [
        f"**Source**: `{drive.source}` ({len(drive)} samples, {drive.duration_s:.1f} s, {drive.rate_hz:g} Hz)",
        f"**Outages**: {placement}; {report.n_outages} outage(s)",
        *([f"**IMU**: {drive.imu.describe()}"] if drive.imu is not None else []),
        f"**{tables.truth_line(report.gnss_truth)}**",
        *(["**Truth**: a reference trajectory beside the receiver; the estimators got only the receiver's fixes "
           "(drawn as dots)"]
          if drive.has_reference else []),
        f"**Sensor biases**: accelerometer {bias.accel_mps2:+.3f} m/s², gyro {bias.gyro_radps:+.5f} rad/s, from "
        f"{bias.source}",
    ]
    info = {e["name"]: e.get("info", {}) for e in result.estimator_info()}
    if "idnn" in info:
        model_info = info["idnn"]
        trained = ", ".join(d["name"] for d in model_info.get("trained_on", [])) or "unknown"
        lines.append(f"**IDNN model**: `{model_info['directory']}` ({model_info['arch']}, "
                     f"{model_info['n_steps_disp']} / {model_info['n_steps_yaw']} time steps), trained on {trained}")
        if model_info.get("training_data"):
            lines.append(f"**Training data**: {model_info['training_data']}")
        if "idnn" in report.arbiter_notes:
            lines.append(f"**IDNN arbiter**: {report.arbiter_notes['idnn']}")
        lines += [f"**IDNN out of its training domain** on {n.drive}: {tables.domain_detail(n)}"
                  for n in report.domain_notes if n.estimator == "idnn"]
    else:
        lines.append("**IDNN model**: none")
    for est in result.estimators:
        if est.name not in ("ins", "idnn"):
            extra = ", ".join(f"{k}: {v}" for k, v in info.get(est.name, {}).items())
            lines.append(f"**{est.label}**: plug-in `{type(est).__module__}.{type(est).__qualname__}`"
                         + (f" ({extra})" if extra else ""))
    lines.append("**Errors**: e = truth - estimate; CRSE = sum |e|, CAE = sum e, AEPS = CRSE / N")
    return to_markdown(Document([*blocks, Items(lines)]))
