"""Two or more runs of the same outages side by side (``ionav-viz compare``): two models, two filter
settings, a plug-in before and after a change.

A run is a report's JSON (``evaluate --json``: one drive or several, several ``--outage`` lengths,
``--scenario all`` or ``--by-event`` groups, a fleet's ``evaluate --workers N --json``, or the
report a recording of ``replay`` carries), read into a :class:`Run`: per outage its key (group,
drive, start, length) and every estimator's :data:`~ionav_viz.analysis.metrics.METRICS`. The runs
are paired outage by outage (the first run, the baseline, in its order): runs whose outages differ,
or whose same outage covers a different truth distance (another drive's data under the same name),
are refused, naming the first outage that differs.

For each estimator, metric and run (:class:`Comparison`):

* the statistics of the metric over the run's outages, as evo's ``evo_res`` tabulates its runs:
  ``n`` (outages where defined), ``mean``, ``median``, ``std`` (population, as the reports'), ``min``,
  ``max``, ``rmse`` (the root mean square) and ``sse`` (the sum of squares);
* the change of each later run against the baseline: the mean over the outages both define of
  ``run - baseline``, with a paired Student t 95 % interval (``mean(d) +- t(0.975, n-1) sd(d) /
  sqrt(n)``, ``sd`` with n - 1), its share of the baseline's mean (not for the signed CAE), how many
  outages went lower and higher, and a verdict (the interval below zero: ``lower``; above:
  ``higher``; every outage equal: ``unchanged``; else ``no clear change``). The outages are taken
  as independent: consecutive outages of one drive share its road and sensors, so the interval is,
  if anything, too narrow (the reports' improvement intervals say the same);
* the outages that changed most in the first shown metric (by the size of the change).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.json_out import dumps_json, is_finite_number
from .document import Block, Document, Heading, Paragraphs, Table, to_markdown, to_text
from .metrics import METRICS
from .schema import schema_of, tagged

#: What each metric is called in tables and figures, with its unit.
METRIC_LABELS = {
    "crse_m": "displacement CRSE (m)",
    "cae_m": "displacement CAE (m)",
    "aeps_m": "displacement AEPS (m)",
    "yaw_crse_radps": "orientation-rate CRSE (rad/s)",
    "yaw_cae_radps": "orientation-rate CAE (rad/s)",
    "yaw_aeps_radps": "orientation-rate AEPS (rad/s)",
    "final_position_error_m": "final position error (m)",
    "final_error_pct": "final error (% of distance)",
}
#: Metrics with a sign (over- or under-predicting): no change in percent of their mean.
SIGNED_METRICS = ("cae_m", "yaw_cae_radps")
#: The metrics tabulated unless asked otherwise: the paper's CRSE and CAE of the displacement.
DEFAULT_METRICS = ("crse_m", "cae_m")
#: How many of the outages that changed most are listed per estimator and run.
TOP_COUNT = 5
#: The statistics of a metric over a run's outages (evo_res's, and the count).
STATISTICS = ("n", "mean", "median", "std", "min", "max", "rmse", "sse")
#: What the interval is: said in every output.
INTERVAL_METHOD = "paired Student t over the outages"
#: Numbers a run may hold (metres, seconds): beyond this none comes from a drive.
MAX_VALUE = 1e9
#: Two runs' truth distances of one outage agree within this (m): the same drive data.
DISTANCE_TOLERANCE_M = 1e-6
HINT = (
    "compare runs of the same drives and outages: the same drives, --outage, placement "
    "(--every/--at/--random/--seed/--on/--plan), --warm-up and --span"
)
RUN_HINT = (
    "give the output of 'ionav-viz evaluate ... --json' (one drive or several, several --outage lengths, "
    "--scenario or --by-event groups, a fleet's) or a recording written by 'ionav-viz replay'"
)


@dataclass(frozen=True)
class OutageKey:
    """Which outage: the report's group (scenario or manoeuvre type; ``""`` for none), the drive,
    its start (s into the drive) and its length (s)."""

    group: str
    drive: str
    start_s: float
    outage_s: float

    def describe(self) -> str:
        group = f"{self.group}: " if self.group else ""
        return f"{group}{self.drive} at {self.start_s:g} s ({self.outage_s:g} s)"


@dataclass
class Run:
    """One run's outages and metrics.

    Attributes:
        label: the run's name in every output.
        source: where it was read from (the file as given), for messages.
        kind: ``report``, ``lengths``, ``scenarios``, ``by_event``, ``fleet``.
        outages: each outage's key, in the report's order.
        numbers: each outage's number within its drive (1-based, as recordings and reports number them).
        distances_m: the truth distance of each outage (the report's ``gnss_distance_m``; NaN when absent).
        estimators: name -> ``{"label": ..., "color": [r, g, b]}`` (colour only where the report gives one).
        values: estimator -> metric -> per-outage values (NaN: undefined, or the estimator did not
            run on that outage's drive).
    """

    label: str
    source: str
    kind: str
    outages: list[OutageKey]
    numbers: list[int]
    distances_m: np.ndarray
    estimators: dict[str, dict[str, Any]]
    values: dict[str, dict[str, np.ndarray]]


def run_from_report(rep: Any, label: str, source: str) -> Run:
    """A :class:`Run` from a report's JSON (parsed; null for NaN), checked field by field: one
    :class:`InputError` naming ``source`` and the field otherwise."""

    def fail(where: str, why: str) -> None:
        raise InputError(f"{source}: {where}: {why}" if where else f"{source}: {why}", RUN_HINT, param="runs")

    if not isinstance(rep, dict):
        fail("", f"a JSON {_kind(rep)}, not a report (an object)")
    if schema_of(rep, source, "runs", RUN_HINT) == "comparison":
        fail("", "a comparison (compare --json), not a run's report")
    if isinstance(rep.get("folds"), list) and "drive" not in rep:
        fail("", "a cross-validation report (cross-validate --json), with no outages to pair")
    parts: list[tuple[str, str, Any, Any]] = []  # (group, where, report, its outage length)
    if "drives_evaluated" in rep and "pooled" in rep:
        kind = "fleet"
        parts.append(("", "", rep, rep.get("outage_s")))
    elif isinstance(rep.get("lengths"), dict):
        kind = "lengths"
        for key, sub in rep["lengths"].items():
            parts.append(("", f"lengths.{key}.", sub, sub.get("outage_s") if isinstance(sub, dict) else None))
    elif isinstance(rep.get("scenarios"), dict) or isinstance(rep.get("by_event"), dict):
        kind = "scenarios" if isinstance(rep.get("scenarios"), dict) else "by_event"
        for key, sub in rep[kind].items():
            parts.append((str(key), f"{kind}.{key}.", sub, sub.get("outage_s") if isinstance(sub, dict) else None))
    else:
        kind = "report"
        parts.append(("", "", rep, rep.get("outage_s")))
    if not parts:
        fail(kind, "holds no report")
    estimators: dict[str, dict[str, Any]] = {}
    rows: list[tuple[OutageKey, Any, dict[str, Any]]] = []
    for group, where, sub, outage_s in parts:
        if not isinstance(sub, dict):
            fail(where.rstrip("."), f"is a JSON {_kind(sub)}, not a report")
        if not is_finite_number(outage_s) or not 0 < outage_s <= MAX_VALUE:
            fail(f"{where}outage_s", f"{outage_s!r} is not an outage length in seconds")
        names = _estimators(sub.get("estimators"), f"{where}estimators", fail, estimators)
        sequences = sub.get("sequences")
        if not isinstance(sequences, list):
            fail(f"{where}sequences", "missing, or not a list of outages")
        for i, seq in enumerate(sequences):
            at = f"{where}sequences[{i}]"
            if not isinstance(seq, dict):
                fail(at, f"is a JSON {_kind(seq)}, not an outage")
            drive = seq.get("drive", sub.get("drive"))
            if not isinstance(drive, str) or not drive.strip():
                fail(f"{at}.drive", f"{drive!r} is not a drive's name")
            start = seq.get("start_s")
            if not is_finite_number(start) or abs(start) > MAX_VALUE:
                fail(f"{at}.start_s", f"{start!r} is not a time in seconds")
            distance = seq.get("gnss_distance_m")
            if distance is not None and (not is_finite_number(distance) or abs(distance) > MAX_VALUE):
                fail(f"{at}.gnss_distance_m", f"{distance!r} is not a distance in metres")
            metrics: dict[str, Any] = {}
            for name in names:
                if name not in seq:  # a fleet's estimator that did not run on this drive
                    continue
                obj = seq[name]
                if not isinstance(obj, dict):
                    fail(f"{at}.{name}", f"is a JSON {_kind(obj)}, not the estimator's metrics")
                for metric in METRICS:
                    if metric not in obj:
                        fail(f"{at}.{name}.{metric}", "missing (a report made by an earlier ionav-viz?)")
                    value = obj[metric]
                    if value is not None and (not is_finite_number(value) or abs(value) > MAX_VALUE):
                        fail(f"{at}.{name}.{metric}", f"{value!r} is not a number")
                metrics[name] = obj
            rows.append((OutageKey(group, drive, round(float(start), 3), float(outage_s)), distance, metrics))
    if not rows:
        fail(
            "sequences",
            "no synthetic outages to compare (a run through the log's own GNSS losses alone, --on gnss-outage?)",
        )
    counts: dict[tuple[str, str, float], int] = {}
    numbers = []
    for key, _d, _m in rows:
        k = (key.group, key.drive, key.outage_s)
        counts[k] = counts.get(k, 0) + 1
        numbers.append(counts[k])
    values = {
        name: {m: np.array([_num(r[2][name][m]) if name in r[2] else math.nan for r in rows]) for m in METRICS}
        for name in estimators
    }
    return Run(
        label, source, kind, [r[0] for r in rows], numbers, np.array([_num(r[1]) for r in rows]), estimators, values
    )


def _estimators(value: Any, where: str, fail: Any, into: dict[str, dict[str, Any]]) -> list[str]:
    """The estimator names of one report (checked), added to ``into`` (name -> label, colour)."""
    if not isinstance(value, list) or not value:
        fail(where, "is not a list of estimators")
    names = []
    for i, e in enumerate(value):
        if not isinstance(e, dict):
            fail(f"{where}[{i}]", f"is a JSON {_kind(e)}, not an object")
        for key in ("name", "label"):
            if not isinstance(e.get(key), str) or not e[key].strip():
                fail(f"{where}[{i}].{key}", f"{e.get(key)!r} is not a name (a non-empty string)")
        color = e.get("color")
        if color is not None and not (
            isinstance(color, list)
            and len(color) == 3
            and all(isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 255 for c in color)
        ):
            fail(f"{where}[{i}].color", f"{color!r} is not an RGB triple of 0-255 integers")
        if e["name"] in names:
            fail(f"{where}[{i}].name", f"{e['name']!r} is listed twice")
        names.append(e["name"])
        into.setdefault(e["name"], {"label": e["label"], **({"color": list(color)} if color is not None else {})})
    return names


def _num(value: Any) -> float:
    return math.nan if value is None else float(value)


def _kind(value: Any) -> str:
    return {dict: "object", list: "array", str: "string", bool: "boolean", type(None): "null"}.get(
        type(value), "number"
    )


def t_quantile_975(dof: int) -> float:
    """Student's t distribution's 97.5th percentile for ``dof`` degrees of freedom (the half-width
    of a two-sided 95 % interval in standard errors): the exact series of Abramowitz and Stegun
    26.7.3-4 for the two-sided probability, inverted by bisection, up to 1000 degrees of freedom;
    beyond, the normal quantile with Hill's three correction terms (error below 1e-10)."""
    if dof < 1:
        raise ValueError("at least one degree of freedom")
    z = 1.959963984540054
    if dof > 1000:
        g1 = (z**3 + z) / 4
        g2 = (5 * z**5 + 16 * z**3 + 3 * z) / 96
        g3 = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384
        return z + g1 / dof + g2 / dof**2 + g3 / dof**3
    lo, hi = 0.0, math.pi / 2  # theta = atan(t / sqrt(dof))
    for _ in range(200):
        mid = (lo + hi) / 2
        if _two_sided(mid, dof) < 0.95:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-15:
            break
    return math.sqrt(dof) * math.tan((lo + hi) / 2)


def _two_sided(theta: float, dof: int) -> float:
    """P(|T| < t) for Student's t with ``dof`` degrees of freedom, ``t = sqrt(dof) tan(theta)``."""
    s, c = math.sin(theta), math.cos(theta)
    if dof % 2:  # odd: (2/pi) (theta + sin cos (1 + 2/3 cos^2 + 2.4/(3.5) cos^4 + ...))
        term, total = 1.0, 1.0 if dof > 1 else 0.0
        for k in range(1, (dof - 1) // 2):
            term *= (2 * k) / (2 * k + 1) * c * c
            total += term
        return 2 / math.pi * (theta + s * c * total)
    term, total = 1.0, 1.0  # even: sin (1 + 1/2 cos^2 + 1.3/(2.4) cos^4 + ...)
    for k in range(1, dof // 2):
        term *= (2 * k - 1) / (2 * k) * c * c
        total += term
    return s * total


def statistics(values: np.ndarray) -> dict[str, float]:
    """:data:`STATISTICS` of one metric over the outages where it is defined (all NaN, ``n`` 0, when none)."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if not len(v):
        return {"n": 0, **{k: math.nan for k in STATISTICS[1:]}}
    return {
        "n": len(v),
        "mean": float(v.mean()),
        "median": float(np.median(v)),
        "std": float(v.std()),
        "min": float(v.min()),
        "max": float(v.max()),
        "rmse": float(np.sqrt(np.mean(v**2))),
        "sse": float(np.sum(v**2)),
    }


def paired_change(baseline: np.ndarray, run: np.ndarray, signed: bool = False) -> dict[str, Any]:
    """The change of ``run`` against ``baseline`` (per outage values, the same outages, NaN where
    undefined) over the outages both define: ``n``, both means, ``change`` (the mean of ``run -
    baseline``), ``ci95`` (``[low, high]``, the paired Student t interval; NaN below 2 outages),
    ``change_pct`` (of the baseline's mean; NaN for a ``signed`` metric or a zero mean), ``lower``,
    ``higher`` and ``equal`` (outages), and the ``verdict``."""
    a, b = np.asarray(baseline, dtype=np.float64), np.asarray(run, dtype=np.float64)
    both = np.isfinite(a) & np.isfinite(b)
    a, b = a[both], b[both]
    n = len(a)
    d = b - a
    change = float(d.mean()) if n else math.nan
    lo = hi = math.nan
    if n >= 2:
        half = t_quantile_975(n - 1) * float(d.std(ddof=1)) / math.sqrt(n)
        lo, hi = change - half, change + half
    mean_a = float(a.mean()) if n else math.nan
    pct = 100.0 * change / mean_a if n and not signed and mean_a != 0 else math.nan
    if n and not d.any():
        verdict = "unchanged"
    elif n < 2:
        verdict = "too few outages"
    elif hi < 0:
        verdict = "lower"
    elif lo > 0:
        verdict = "higher"
    else:
        verdict = "no clear change"
    return {
        "n": n,
        "baseline_mean": mean_a,
        "run_mean": float(b.mean()) if n else math.nan,
        "change": change,
        "ci95": [lo, hi],
        "change_pct": pct,
        "lower": int((d < 0).sum()),
        "higher": int((d > 0).sum()),
        "equal": int((d == 0).sum()),
        "verdict": verdict,
    }


def paired(runs: Sequence[Run]) -> list[Run]:
    """The runs with every later one's outages put in the first's order (the k-th outage of a key
    paired with the k-th of the same key); an :class:`InputError` naming both files and the first
    outage that differs (or covers another truth distance) otherwise."""
    first = runs[0]
    out = [first]
    for run in runs[1:]:
        where: dict[OutageKey, list[int]] = {}
        for i, key in enumerate(run.outages):
            where.setdefault(key, []).append(i)
        order = []
        for k, key in enumerate(first.outages):
            if not where.get(key):
                raise InputError(
                    f"{first.source} and {run.source} hold different outages "
                    f"({len(first.outages)} and {len(run.outages)}): "
                    f"outage {k + 1} of {first.label}, {key.describe()}, is not in {run.label}"
                    + (f" (its outage {k + 1}: {run.outages[k].describe()})" if k < len(run.outages) else ""),
                    HINT,
                    param="runs",
                )
            order.append(where[key].pop(0))
        extra = sorted(i for left in where.values() for i in left)
        if extra:
            raise InputError(
                f"{first.source} and {run.source} hold different outages "
                f"({len(first.outages)} and {len(run.outages)}): "
                f"outage {extra[0] + 1} of {run.label}, {run.outages[extra[0]].describe()}, is not in {first.label}",
                HINT,
                param="runs",
            )
        idx = np.array(order, dtype=int)
        dist = run.distances_m[idx]
        for k, (da, db) in enumerate(zip(first.distances_m, dist)):
            if np.isfinite(da) and np.isfinite(db) and abs(da - db) > DISTANCE_TOLERANCE_M + 1e-9 * abs(da):
                raise InputError(
                    f"{first.source} and {run.source}: outage {k + 1}, {first.outages[k].describe()}, "
                    f"covers {da:.3f} m of "
                    f"truth in {first.label} and {db:.3f} m in {run.label}: not the same drive data",
                    HINT,
                    param="runs",
                )
        out.append(
            Run(
                run.label,
                run.source,
                run.kind,
                list(first.outages),
                list(first.numbers),
                dist,
                run.estimators,
                {e: {m: v[idx] for m, v in per.items()} for e, per in run.values.items()},
            )
        )
    return out


@dataclass(repr=False)
class Comparison:
    """Runs of the same outages side by side (see the module's docstring): built by
    :func:`compare_runs`, written by :meth:`to_json`, :meth:`to_text` and :meth:`to_markdown`.

    Attributes:
        runs: the runs, paired (every run's outages in the first's order); the first is the baseline.
        metrics: the metrics the tables and the figure show (the JSON holds every one of
            :data:`~ionav_viz.analysis.metrics.METRICS`); the first ranks the outages that changed most.
        top: how many of those are listed per estimator and run.
    """

    runs: list[Run]
    metrics: tuple[str, ...] = DEFAULT_METRICS
    top: int = TOP_COUNT
    _dict: dict[str, Any] | None = field(default=None, init=False, repr=False)

    def __repr__(self) -> str:
        return (
            f"Comparison({', '.join(r.label for r in self.runs)}; {self.n_outages} outage(s); "
            f"estimators {', '.join(self.estimators)})"
        )

    @property
    def baseline(self) -> Run:
        return self.runs[0]

    @property
    def n_outages(self) -> int:
        return len(self.baseline.outages)

    @cached_property
    def estimators(self) -> dict[str, dict[str, Any]]:
        """Every estimator of any run (name -> label, colour), in the order first met."""
        out: dict[str, dict[str, Any]] = {}
        for run in self.runs:
            for name, info in run.estimators.items():
                out.setdefault(name, info)
        return out

    @cached_property
    def stats(self) -> dict[str, dict[str, dict[str, dict[str, float]]]]:
        """estimator -> metric -> run label -> :func:`statistics` (runs without the estimator left out)."""
        return {
            e: {m: {r.label: statistics(r.values[e][m]) for r in self.runs if e in r.values} for m in METRICS}
            for e in self.estimators
        }

    @cached_property
    def changes(self) -> dict[str, dict[str, dict[str, dict[str, Any]]]]:
        """estimator -> metric -> later run's label -> :func:`paired_change` against the baseline
        (estimators the baseline and that run both have)."""
        base = self.baseline
        return {
            e: {
                m: {
                    r.label: paired_change(base.values[e][m], r.values[e][m], m in SIGNED_METRICS)
                    for r in self.runs[1:]
                    if e in r.values
                }
                for m in METRICS
            }
            for e in self.estimators
            if e in base.values and any(e in r.values for r in self.runs[1:])
        }

    def most_changed(
        self, estimator: str, run: str, metric: str | None = None, count: int | None = None
    ) -> list[dict[str, Any]]:
        """The ``count`` (default :attr:`top`) outages where ``metric`` (default the first shown)
        of ``estimator`` changed most from the baseline to ``run`` (by the change's size, largest
        first; outages that did not change are not listed): ``group`` (where the report had
        groups), ``drive``, ``number``, ``start_s``, ``outage_s``, ``baseline``, ``run`` and ``change``."""
        metric = metric or self.metrics[0]
        other = next(r for r in self.runs if r.label == run)
        a, b = self.baseline.values[estimator][metric], other.values[estimator][metric]
        d = b - a
        idx = np.flatnonzero(np.isfinite(d) & (d != 0))  # an outage that did not change is not listed
        ranked = idx[np.argsort(-np.abs(d[idx]), kind="stable")][: self.top if count is None else count]
        out = []
        for i in ranked:
            key = self.baseline.outages[i]
            out.append(
                {
                    **({"group": key.group} if key.group else {}),
                    "drive": key.drive,
                    "number": self.baseline.numbers[i],
                    "start_s": key.start_s,
                    "outage_s": key.outage_s,
                    "baseline": float(a[i]),
                    "run": float(b[i]),
                    "change": float(d[i]),
                }
            )
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``compare --json`` object, kind ``comparison`` of docs/report-schema.md (every key there).
        NaN is kept here; :meth:`to_json` writes it as null."""
        if self._dict is not None:
            return self._dict
        base = self.baseline
        keys = base.outages
        out: dict[str, Any] = tagged("comparison", {
            "runs": [{"label": r.label, "file": r.source, "kind": r.kind} for r in self.runs],
            "baseline": base.label,
            "n_outages": self.n_outages,
            "drives": list(dict.fromkeys(k.drive for k in keys)),
            "outage_s": sorted({k.outage_s for k in keys}),
            **({"groups": list(dict.fromkeys(k.group for k in keys))} if any(k.group for k in keys) else {}),
            "interval": {"method": INTERVAL_METHOD, "level": 0.95},
            "metrics": list(self.metrics),
            "estimators": [
                {"name": e, **info, "runs": [r.label for r in self.runs if e in r.values]}
                for e, info in self.estimators.items()
            ],
            "stats": self.stats,
            "changes": self.changes,
            "most_changed": {
                e: {r: self.most_changed(e, r) for r in per[self.metrics[0]]} for e, per in self.changes.items()
            },
        })
        self._dict = out
        return out

    def to_json(self, indent: int | None = 2) -> str:
        """Exactly what ``ionav-viz compare --json`` prints (NaN as null)."""
        return dumps_json(self.to_dict(), indent=indent)

    def to_text(self, width: int | None = None) -> str:
        """The tables as plain text; ``width``: fit them into that many columns (None: no limit)."""
        return to_text(self.document(), width)

    def to_markdown(self) -> str:
        """The tables as Markdown."""
        return to_markdown(self.document())

    def document(self) -> Document:
        """The comparison as a document (:mod:`.document`): the runs; per metric each run's
        statistics and each later run's change against the baseline; the outages that changed most."""
        base = self.baseline.label
        labels = {e: info["label"] for e, info in self.estimators.items()}
        lengths = ", ".join(f"{x:g}" for x in sorted({k.outage_s for k in self.baseline.outages}))
        drives = list(dict.fromkeys(k.drive for k in self.baseline.outages))
        shown = ", ".join(drives[:4]) + (f" and {len(drives) - 4} more" if len(drives) > 4 else "")

        def table(header: list[str], rows: list[list[str]], left: int) -> Table:
            # as Markdown each row whole (a key the text leaves blank under the row above is repeated)
            return Table(header, rows, left, repeat_keys=True)

        blocks: list[Block] = [
            Heading(f"{len(self.runs)} runs on the same {self.n_outages} outages of {lengths} s ({shown}); "
                    f"changes against {base}, {INTERVAL_METHOD}, 95 %"),
            table(["Run", "file", "kind of report"], [[r.label, r.source, r.kind] for r in self.runs], 3),
        ]
        for metric in self.metrics:
            decimals = _decimals(metric)
            rows = [
                [
                    labels[e] if j == 0 else "",
                    label,
                    *(str(st["n"]) if k == "n" else _fmt(st[k], decimals) for k in STATISTICS),
                ]
                for e, per in self.stats.items()
                for j, (label, st) in enumerate(per[metric].items())
            ]
            name = METRIC_LABELS[metric]
            blocks += [Heading(f"{name[:1].upper()}{name[1:]} over each run's outages"),
                       table(["Estimator", "Run", *STATISTICS], rows, 2)]
            rows = []
            for e, per in self.changes.items():
                for j, (label, ch) in enumerate(per[metric].items()):
                    rows.append(
                        [
                            labels[e] if j == 0 else "",
                            label,
                            _fmt(ch["baseline_mean"], decimals),
                            _fmt(ch["run_mean"], decimals),
                            _fmt(ch["change"], decimals, sign=True),
                            _interval(ch["ci95"], decimals),
                            "-"
                            if not math.isfinite(ch["change_pct"])
                            else f"{round(ch['change_pct'], 1) + 0.0:+.1f} %",
                            f"{ch['lower']}/{ch['higher']}",
                            ch["verdict"],
                        ]
                    )
            if rows:
                header = ["Estimator", "Run", f"{base} mean", "run mean", "change", "95 % interval", "change %",
                          "outages lower/higher", "verdict"]
                blocks += [Heading(f"Change of the mean against {base} ({METRIC_LABELS[metric]})"),
                           table(header, rows, 2)]
        only = [e for e in self.estimators if e not in self.changes]
        if only:
            blocks.append(Paragraphs([
                f"Not compared (in one run only, or not in {base}): "
                + ", ".join(f"{labels[e]} ({', '.join(r.label for r in self.runs if e in r.values)})" for e in only)
            ]))
        metric = self.metrics[0]
        decimals = _decimals(metric)
        rows = []
        for e, per in self.changes.items():
            for label in per[metric]:
                for k, o in enumerate(self.most_changed(e, label)):
                    drive = f"{o['group']}: {o['drive']}" if "group" in o else o["drive"]
                    rows.append(
                        [
                            labels[e] if k == 0 else "",
                            label if k == 0 else "",
                            drive,
                            str(o["number"]),
                            f"{o['start_s']:g}",
                            f"{o['outage_s']:g}",
                            _fmt(o["baseline"], decimals),
                            _fmt(o["run"], decimals),
                            _fmt(o["change"], decimals, sign=True),
                        ]
                    )
        if rows:
            blocks += [Heading(f"The {self.top} outages that changed most ({METRIC_LABELS[metric]})"),
                       table(["Estimator", "Run", "Drive", "#", "start s", "length s", base, "run", "change"], rows, 3)]
        blocks.append(Paragraphs([
            "Outages are taken as independent: those of one drive share its road and sensors, so the intervals are, "
            "if anything, too narrow."
        ]))
        return Document(blocks, spaced=True, hang=None)


def _decimals(metric: str) -> int:
    return 3 if metric.startswith("yaw_") else 1 if metric == "final_error_pct" else 2


def _fmt(x: float, decimals: int, sign: bool = False) -> str:
    """A cell: ``-`` where undefined; never ``-0.00``."""
    if x is None or not math.isfinite(x):
        return "-"
    return f"{round(x, decimals) + 0.0:{'+' if sign else ''}.{decimals}f}"


def _interval(ci: list[float], decimals: int) -> str:
    lo, hi = ci
    return (
        "-"
        if not (math.isfinite(lo) and math.isfinite(hi))
        else f"[{_fmt(lo, decimals, True)}, {_fmt(hi, decimals, True)}]"
    )


def compare_runs(runs: Sequence[Run], metrics: Sequence[str] = DEFAULT_METRICS, top: int = TOP_COUNT) -> Comparison:
    """Pair ``runs`` (:func:`paired`; the first is the baseline) and compare them. At least two
    runs with distinct labels; ``metrics`` of :data:`~ionav_viz.analysis.metrics.METRICS`; ``top`` at
    least 1. Every problem is an :class:`InputError` naming what it is about."""
    if len(runs) < 2:
        raise InputError(
            f"{len(runs)} run(s) given: a comparison needs two or more",
            "give two or more reports (A.json B.json ...)",
            param="runs",
        )
    seen: dict[str, str] = {}
    for run in runs:
        if run.label in seen:
            raise InputError(
                f"two runs are labelled {run.label!r} ({seen[run.label]} and {run.source})",
                "give each its own --label",
                param="labels",
            )
        seen[run.label] = run.source
    check_metrics(metrics)
    if isinstance(top, bool) or not isinstance(top, int) or top < 1:
        raise InputError(f"top {top!r}: not a count of outages (1 or more)", "e.g. 5", param="top")
    return Comparison(paired(runs), tuple(metrics), top)


def check_metrics(metrics: Sequence[str]) -> None:
    """That ``metrics`` names one or more of :data:`~ionav_viz.analysis.metrics.METRICS`, each once."""
    if isinstance(metrics, str) or not metrics:
        raise InputError(
            f"metrics {metrics!r}: give a list of one or more metric names",
            f"choose from {', '.join(METRICS)}",
            param="metrics",
        )
    for m in metrics:
        if m not in METRICS:
            raise InputError(f"unknown metric {m!r}", f"choose from {', '.join(METRICS)}", param="metrics")
    if len(set(metrics)) != len(metrics):
        raise InputError(f"metrics {', '.join(metrics)}: one is given twice", "name each metric once", param="metrics")
