"""Evaluating estimators on GNSS outages: :func:`evaluate`, :func:`evaluate_by_event`, and the
scenarios' test drives."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from ..analysis.evaluate import DriveResult
from ..analysis.events import MANOEUVRE_TYPES, detect_events
from ..analysis.report import EventReports, Report
from ..core.drive import Drive
from ..core.errors import InputError
from ..core.fileio import check_output_folder
from ..core.warnings_log import collecting_warnings
from ..dataset.catalog import PAPER_TEST_RUNS, SCENARIOS, run_key
from ..experiment.outages import GNSS_OUTAGE, AroundEvents, Placement
from ..experiment.plan_file import FromPlan
from ..nav.protocol import Estimator
from ..nav.windows import make_windows
from ..sources.load import LogOptions, ReadOptions, load_drives
from ..sources.resolve import data_root as _data_root
from .options import (
    DriveLike,
    Progress,
    RunOptions,
    check_event_types,
    each_length,
    input_paths,
    lengths_of,
    log,
    name_of,
    no_outage_fits,
    options_of,
    placement_of,
    refuse_export_onto_inputs,
    too_short,
    windows_of,
    with_externals,
)
from .pipeline import plan_drive, score


class ScenarioDrives(dict):
    """Test drives by scenario (a ``dict``), with ``source``: one line saying where they come from."""

    source: str = ""


def scenario_drives(scenario: str, data_root: str | Path | None = None) -> ScenarioDrives:
    """The test drives of a scenario (``"all"``: of every scenario), by scenario: the paper's runs
    where all of a scenario's runs are under the data root, else the bundled synthetic drive.
    ``.source`` says which, in one line."""
    from ..dataset.samples import by_scenario, sample_path
    from ..sources.resolve import index_data_root

    if scenario != "all" and scenario not in SCENARIOS:
        raise InputError(f"unknown scenario {scenario!r}", f"choose {', '.join(SCENARIOS)} or all", param="scenario")
    names = SCENARIOS if scenario == "all" else (scenario,)
    root = _data_root(data_root)
    present = index_data_root(root.resolve()) if root is not None else {}
    out = ScenarioDrives()
    paper, bundled = [], []
    for s in names:
        if root is not None and all(run_key(r) in present for r in PAPER_TEST_RUNS[s]):
            out[s] = list(PAPER_TEST_RUNS[s])
            paper.append(s)
        else:
            out[s] = [str(sample_path(sample)) for sample in by_scenario(s)]
            bundled.append(s)
    parts = []
    if paper:
        parts.append(f"{', '.join(paper)}: the paper's IO-VNBD test runs under {root}")
    if bundled:
        why = (f"the paper's runs are not all under {root}; 'ionav-viz fetch --scenario NAME' gets them"
               if root else "no IO-VNBD data root")
        parts.append(f"{', '.join(bundled)}: the bundled synthetic test drives ({why})")
    out.source = "; ".join(parts)
    return out



def evaluate(
    drives: Sequence[DriveLike] | DriveLike,
    outage_s: float | None = None,
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    run: RunOptions | None = None,
    read: ReadOptions | None = None,
    progress: Progress | None = None,
    mcap: LogOptions | None = None,
    truth: str | None = None,
    plan: str | Path | None = None,
    external: Mapping[str, str | Path] | None = None,
    export: str | Path | None = None,
) -> Report:
    """Every estimator on the same GNSS outages of each drive, scored with the paper's metrics.

    Args:
        drives: drives or what names them (see :func:`load_drive`).
        outage_s: length of each outage, whole seconds.
        placement: where outages go (default :class:`Tile`, the paper's consecutive outages).
            A drive too short for one tiled outage is skipped with a warning.
        estimators: a shortcut for ``run.estimators``.
        run: which estimators run with what model, biases and event thresholds (:class:`RunOptions`).
        read: how drives are read (:class:`ReadOptions`); outages go only where every window has
            good GNSS truth, and the report counts what was excluded.
        mcap: deprecated, ``read.log``.
        plan: an outage plan file (``OUT.outages.json`` of :func:`outage_log`): exactly its outages
            (instead of ``placement``; the outage length is the plan's).
        external: estimates made outside ionav-viz on the plan's outaged log, ``{name: trajectory}``
            (a ``.csv``, a ``.tum`` or ``LOG:TOPIC``, :mod:`ionav_viz.sources.trajectory`), scored
            like the built-ins; they need ``plan``.
        export: a folder to write the per-outage table, evo's TUM tracks and GeoJSON/GPX tracks
            into (:mod:`ionav_viz.analysis.exports`).
        truth: a message log's reference topic, the truth every score is measured against
            (a shortcut for ``read.log.truth_topic``; see :class:`LogOptions`).

    Returns:
        a :class:`Report`; ``report.to_json()`` is what ``ionav-viz evaluate --json`` prints.
    """
    items = [drives] if isinstance(drives, (Drive, str, Path)) else list(drives)
    if not items:
        raise InputError("no drive to evaluate", "give at least one drive")
    placement = placement_of(placement, plan)
    n = windows_of(outage_s, placement)  # checked before any drive is read
    if isinstance(placement, FromPlan) and len(items) != 1:
        raise InputError(f"a plan is made for one drive, and {len(items)} are given", "evaluate the plan's drive alone",
                         param="plan")
    run, read = options_of(run, estimators, read, mcap, truth)
    run = with_externals(run, external, placement)
    if export is not None:
        check_output_folder(Path(export), param="export")
        refuse_export_onto_inputs(export, input_paths(items, read, run=run, plan=placement, external=external))
    if placement.event_types:
        check_event_types(placement.event_types)
    run.chosen()
    with collecting_warnings() as warned:
        results = _evaluate_each(items, n, placement, run, read, progress)
    report = Report(results, warnings=warned)
    if export is not None:
        write_exports(results, export)
    return report


def write_exports(results: Sequence[DriveResult], export: str | Path) -> None:
    """``export=``: :func:`~ionav_viz.analysis.exports.export_results`, the tracks in the colours
    the recording draws them (:mod:`ionav_viz.viz.style`)."""
    from ..analysis.exports import export_results
    from ..viz.style import GNSS_COLOR, estimator_colors

    estimators = list({est.name: est for res in results for est in res.estimators}.values())
    export_results(list(results), export, colors=estimator_colors(estimators), truth_color=GNSS_COLOR)


def _evaluate_each(items: list[DriveLike], n: int, placement: Placement, run: RunOptions, read: ReadOptions,
                   progress: Progress | None) -> list[DriveResult]:
    bias_of = run.bias_of(read)
    loaded = load_drives(items, read)
    ests = run.applying_to(loaded)
    results = []
    for i, drive in enumerate(loaded):
        if progress:
            progress(drive.name, i, len(items))
        planned = plan_drive(drive, placement, n, run)
        plan = planned.plan
        if plan.too_short:
            if plan.excluded:
                log.warning("%s: no %g s outage fits where the GNSS truth and the receiver's fixes are good; skipped",
                            drive.name, n)
            elif len(loaded) > 1:  # one drive alone: the error says it
                short = too_short(drive, n, run, read)
                log.warning("%s; skipped (%s)", short.message, short.hint)
            continue
        results.append(score(planned, ests, bias_of(drive)))
    if progress:
        progress("done", len(items), len(items))
    if not results:
        if len(loaded) == 1 and not plan.excluded:
            raise too_short(loaded[0], n, run, read)
        raise no_outage_fits(loaded, n, ", ".join(name_of(d) for d in items))
    return results


def evaluate_lengths(
    drives: Sequence[DriveLike] | DriveLike,
    lengths_s: Sequence[float],
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    run: RunOptions | None = None,
    read: ReadOptions | None = None,
    progress: Progress | None = None,
    truth: str | None = None,
    export: str | Path | None = None,
) -> dict[float, Report]:
    """:func:`evaluate` for each outage length of ``lengths_s`` on the same drives and placement:
    ``{length: report}`` in increasing length (``analysis.report.by_length`` compares them), and with
    ``export`` one folder ``EXPORT/<length>s`` each (as :func:`~ionav_viz.api.replay.replay_lengths`
    writes them). A length no drive has room for is left out with a warning (nothing exported for
    it) when another fits; when none fits, the shortest one's error, and nothing is written."""
    lengths = lengths_of(lengths_s, placement)
    _, read = options_of(None, None, read, None, truth)  # the reference topic read with the drives, once
    items = [drives] if isinstance(drives, (Drive, str, Path)) else list(drives)
    if export is not None:  # checked before any work, as evaluate checks it
        check_output_folder(Path(export), param="export")
        refuse_export_onto_inputs(export, input_paths(items, read, run=run, plan=placement))
    loaded = load_drives(items, read)  # read once, used for every length
    return dict(each_length(lengths,
                            lambda length: evaluate(loaded, length, placement, estimators, run=run, read=read,
                                                    progress=progress,
                                                    export=None if export is None else Path(export) / f"{length:g}s")))


def evaluate_by_event(
    drives: Sequence[DriveLike],
    outage_s: float | None = None,
    types: Sequence[str] | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    run: RunOptions | None = None,
    read: ReadOptions | None = None,
    mcap: LogOptions | None = None,
    truth: str | None = None,
) -> EventReports:
    """One report per manoeuvre type: an outage centred on each detected event, across ``drives``
    (``types`` default: every manoeuvre type; ``gnss-outage``: the log's own losses, bridged).
    A type with no event, or none with room for an outage, has no report; the result's ``events``
    counts each type's events (:class:`~ionav_viz.analysis.report.EventReports`). The other
    arguments as for :func:`evaluate`."""
    kinds = tuple(types) if types else MANOEUVRE_TYPES
    check_event_types(kinds)
    n = windows_of(outage_s)
    run, read = options_of(run, estimators, read, mcap, truth)
    run.chosen()
    with collecting_warnings() as warned:
        per_type, counts = _evaluate_by_event_each(drives, n, kinds, run, read)
    reports = EventReports({kind: Report(results, kind, warnings=warned) for kind, results in per_type.items()
                            if results}, counts, n)
    if not reports:
        raise InputError(f"no {', '.join(kinds)} event with room for a {n:g} s outage in "
                         f"{', '.join(name_of(d) for d in drives)}",
                         "see 'ionav-viz events DRIVE'")
    return reports


def _evaluate_by_event_each(drives: Sequence[DriveLike], n: int, kinds: tuple[str, ...], run: RunOptions,
                            read: ReadOptions) -> tuple[dict[str, list[DriveResult]], dict[str, int]]:
    """Each type's drive results and how many events of it were found across the drives."""
    bias_of = run.bias_of(read)
    per_type: dict[str, list[DriveResult]] = {k: [] for k in kinds}
    counts = dict.fromkeys(kinds, 0)
    loaded = load_drives(drives, read)
    ests = run.applying_to(loaded)
    for drive in loaded:
        windows = make_windows(drive)
        bias = bias_of(drive)
        found = detect_events(drive, run.thresholds, kinds)
        for kind in kinds:
            counts[kind] += sum(e.type == kind for e in found)
            if kind != GNSS_OUTAGE and not any(e.type == kind for e in found):
                continue
            try:
                planned = plan_drive(drive, AroundEvents((kind,)), n, run, found, windows)
            except InputError:  # no room for an outage on this drive's events of that type, or no loss
                continue
            per_type[kind].append(score(planned, ests, bias))
    return per_type, counts

