"""``compare``: runs of the same drives and outages side by side (:mod:`ionav_viz.analysis.compare`)."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..analysis.compare import (
    DEFAULT_METRICS,
    RUN_HINT,
    TOP_COUNT,
    Comparison,
    check_metrics,
    compare_runs,
    run_from_report,
)
from ..core.errors import InputError
from ..core.timing import stage


def compare(
    runs: Sequence[Any],
    *,
    labels: Sequence[str] | None = None,
    metrics: Sequence[str] = DEFAULT_METRICS,
    top: int = TOP_COUNT,
    figure: str | Path | None = None,
) -> Comparison:
    """Compare ``runs`` of the same drives and outages, the first the baseline: each estimator's
    metrics in each run (evo_res's statistics: n, mean, median, std, min, max, rmse, sse), the
    change of each later run's mean with a paired Student t 95 % interval over the outages, and the
    outages that changed most (:class:`~ionav_viz.analysis.compare.Comparison`).

    ``runs``: two or more of: a file written by ``evaluate --json`` (one drive or several, several
    ``--outage`` lengths, ``--scenario``/``--by-event`` groups, a fleet's), a recording (``.rrd``)
    written by ``replay`` (the report it carries), a :class:`~ionav_viz.analysis.report.Report` or
    :class:`~ionav_viz.analysis.fleet.FleetReport`, what :func:`replay` returned, or a report's
    JSON already parsed (a dict). ``labels``: each run's name (default: a file's stem, its suffix or
    folder too where two stems are alike; ``run N`` for an object). ``metrics``: what the
    tables and figure show, of :data:`~ionav_viz.analysis.metrics.METRICS` (the JSON has every
    one); the first ranks the ``top`` outages that changed most. ``figure``: also draw the changes
    with their intervals into this ``.png``, ``.svg`` or ``.pdf``.

    Runs whose outages differ (drive, start or length) or whose same outage covers a different truth
    distance are refused with one :class:`InputError` naming both files and the first outage that
    differs; so are fewer than two runs, labels alike or of another count, and unknown metrics.
    Everything is checked before the figure is drawn; the figure is written under a temporary name
    and renamed when complete."""
    from ..analysis.fleet import FleetReport
    from ..analysis.report import Report
    from .replay import ReplayResult

    runs = list(runs) if not isinstance(runs, (str, os.PathLike, dict)) else [runs]
    if len(runs) < 2:
        raise InputError(
            f"{len(runs)} run given: a comparison needs two or more",
            "give two or more reports (A.json B.json ...)",
            param="runs",
        )
    if labels is not None:
        labels = [labels] if isinstance(labels, str) else list(labels)
        if len(labels) != len(runs):
            raise InputError(
                f"{len(labels)} label(s) for {len(runs)} runs",
                "give one label per run, in the runs' order",
                param="labels",
            )
        for label in labels:
            if not isinstance(label, str) or not label.strip():
                raise InputError(f"label {label!r}: not a name", "give each run a non-empty name", param="labels")
    check_metrics(list(metrics))
    paths = [Path(r) for r in runs if isinstance(r, (str, os.PathLike))]
    if figure is not None:
        from ..core.fileio import refuse_output_onto_input
        from ..viz.compare_figure import check_figure_output

        check_figure_output(figure)
        refuse_output_onto_input(figure, paths, param="figure")
    names = labels or _default_labels(runs)
    read = []
    for run, label in zip(runs, names):
        if isinstance(run, ReplayResult):
            run = run.report
        if isinstance(run, (Report, FleetReport)):
            rep, source = json.loads(run.to_json()), label  # exactly what --json writes
        elif isinstance(run, dict):
            rep, source = run, label
        elif isinstance(run, (str, os.PathLike)):
            rep, source = _read(Path(run)), str(run)
        else:
            raise InputError(
                f"a run of type {type(run).__name__}: not a report or its file",
                "give files written by 'evaluate --json', recordings, or what evaluate or replay returned",
                param="runs",
            )
        read.append(run_from_report(rep, label, source))
    with stage(f"compare {len(read)} runs"):
        result = compare_runs(read, list(metrics), top)
    if figure is not None:
        from ..viz.compare_figure import write_comparison_figure

        with stage("figure of the comparison"):
            write_comparison_figure(result.to_dict(), figure)
    return result


def _read(path: Path) -> Any:
    """A report's JSON from a file written by ``evaluate --json``, or from a recording (``.rrd``)."""
    from ..core.fileio import check_regular_input, parse_json_bounded, read_json_bounded

    check_regular_input(path, "runs", hint=RUN_HINT)
    if path.suffix.lower() == ".rrd":
        from ..viz.recording_info import report_json

        try:
            text = report_json(path)
        except InputError as exc:
            exc.param = "runs"
            raise
        return parse_json_bounded(text, path, param="runs", hint=RUN_HINT, what="a report")
    return read_json_bounded(path, param="runs", hint=RUN_HINT, what="a report")


def _default_labels(runs: list[Any]) -> list[str]:
    """Each file's stem; where two are alike, its name (``run.json`` and ``run.rrd``), else with its
    folder (``a/run`` and ``b/run``), else as given; an object ``run N`` (N from 1), or its report's title."""

    def label_of(run: Any, i: int, depth: int) -> str:
        if isinstance(run, (str, os.PathLike)):
            path = Path(run)
            if depth == 0:
                return path.stem
            if depth == 1:
                return path.name
            if depth == 2:
                return f"{path.parent.name}/{path.stem}" if path.parent.name else path.stem
            return str(path)
        title = getattr(getattr(run, "report", run), "title", None)
        return title if isinstance(title, str) and title.strip() else f"run {i + 1}"

    labels = [label_of(r, i, 0) for i, r in enumerate(runs)]
    for depth in (1, 2, 3):
        alike = {x for x in labels if labels.count(x) > 1}
        if not alike:
            break
        labels = [label_of(r, i, depth) if lab in alike else lab for i, (r, lab) in enumerate(zip(runs, labels))]
    seen: dict[str, int] = {}
    out = []
    for lab in labels:  # the same file given twice
        seen[lab] = seen.get(lab, 0) + 1
        out.append(lab if seen[lab] == 1 else f"{lab} ({seen[lab]})")
    return out
