"""Evaluating estimators on GNSS outages in this process: an :class:`~.experiment.Experiment` at
one outage length, at several, by manoeuvre type, and the scenarios' test drives
(:func:`ionav_viz.evaluate` chooses among them)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from ..analysis.evaluate import DriveResult
from ..analysis.events import MANOEUVRE_TYPES, detect_events
from ..analysis.report import EventReports, Report
from ..core.errors import InputError
from ..core.fileio import check_output_folder
from ..core.warnings_log import collecting_warnings
from ..dataset.catalog import PAPER_TEST_RUNS, SCENARIOS, run_key
from ..experiment.outages import GNSS_OUTAGE, AroundEvents, Placement
from ..nav.windows import make_windows
from ..sources.load import ReadOptions, load_drives
from ..sources.resolve import data_root as _data_root
from .experiment import Experiment
from .options import (
    DriveLike,
    Progress,
    RunOptions,
    check_event_types,
    each_length,
    input_paths,
    log,
    name_of,
    no_outage_fits,
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



def scenario_groups(exp: Experiment) -> ScenarioDrives:
    """``exp.scenario``'s test drives by scenario, where they come from logged."""
    groups = scenario_drives(exp.scenario, exp.read.data_root)
    log.info("drives: %s", groups.source)
    return groups


def evaluate_single(exp: Experiment, progress: Progress | None, export: str | Path | None) -> Report:
    """One outage length: every drive of ``exp`` in this process, one report."""
    items = list(exp.drives)
    placement = placement_of(exp.placement, exp.plan)
    n = windows_of(exp.outage_s, placement)  # checked before any drive is read
    run, read = exp.options()
    run = with_externals(run, exp.external, placement)
    if export is not None:
        check_output_folder(Path(export), param="export")
        refuse_export_onto_inputs(export, input_paths(items, read, run=run, plan=placement, external=exp.external))
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


def evaluate_each_length(exp: Experiment, progress: Progress | None, export: str | Path | None) -> dict[float, Report]:
    """Each of ``exp``'s outage lengths on the same drives, read once: ``{length: report}``."""
    _, read = exp.options()  # the reference topic read with the drives, once
    items = list(exp.drives)
    if export is not None:  # checked before any work, as evaluate checks it
        check_output_folder(Path(export), param="export")
        refuse_export_onto_inputs(export, input_paths(items, read, run=exp.run, plan=exp.placement))
    loaded = load_drives(items, read)  # read once, used for every length
    return dict(each_length(exp.lengths_s,
                            lambda length: evaluate_single(replace(exp, drives=loaded, outage_s=length), progress,
                                                           None if export is None else Path(export) / f"{length:g}s")))


def evaluate_events(exp: Experiment) -> EventReports:
    """One report per manoeuvre type of ``exp.by_event`` (True: every manoeuvre type)."""
    kinds = exp.by_event if isinstance(exp.by_event, tuple) and exp.by_event else MANOEUVRE_TYPES
    check_event_types(kinds)
    n = windows_of(exp.outage_s)
    run, read = exp.options()
    run.chosen()
    drives = list(exp.drives)
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

