"""Running an :class:`~.experiment.Experiment`: :func:`evaluate` scores it, :func:`replay` records
it. Each takes an experiment, or today's arguments that make one, and hands it to its one
consumer: one outage length, several, by manoeuvre type, a scenario's test drives, or a fleet on
an engine."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Unpack

from ..analysis.fleet import FleetReport
from ..analysis.report import EventReports, Report
from ..core.errors import InputError
from ..experiment.outages import Placement
from ..nav.protocol import Estimator
from .evaluate import evaluate_each_length, evaluate_events, evaluate_single, scenario_groups
from .experiment import Experiment, ExperimentKeywords, experiment_of
from .fleet import run_fleet
from .options import DriveLike, Progress
from .replay import RECORDINGS_DIR, ReplayResult, replay_each_length, replay_scenario_drives, replay_single


def evaluate(
    drives: Experiment | Sequence[DriveLike] | DriveLike,
    outage_s: float | Sequence[float] | None = None,
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    progress: Progress | None = None,
    **keywords: Unpack[ExperimentKeywords],
) -> Report | dict[float, Report] | EventReports | FleetReport | dict[str, Report]:
    """Every estimator on the same GNSS outages of each drive, scored with the paper's metrics.

    Args:
        drives: an :class:`~ionav_viz.api.experiment.Experiment`, or its drives (what names them,
            see :func:`load_drive`) with the experiment's other fields as the arguments that follow.
        outage_s: length of each outage, whole seconds; several lengths (a sequence): each on the
            same drives and placement.
        placement: where outages go (default :class:`Tile`, the paper's consecutive outages).
            A drive too short for one tiled outage is skipped with a warning.
        estimators: a shortcut for ``run.estimators``.
        progress: ``progress(label, done, total)`` as the drives are done.
        keywords: the :class:`Experiment`'s other fields (``run``, ``read``, ``engine``, ``plan``,
            ``external``, ``truth``, ``by_event``, ``scenario``, ``runs``; ``mcap``: deprecated,
            ``read.log``), and what the call writes: ``export``, a folder to write the per-outage
            table, evo's TUM tracks and GeoJSON/GPX tracks into (:mod:`ionav_viz.analysis.exports`;
            with several lengths ``EXPORT/<length>s`` each, with a scenario ``EXPORT/<scenario>``),
            and ``fleet`` (:class:`FleetOptions`) with an ``engine``.

    Returns:
        a :class:`Report` (``report.to_json()`` is what ``ionav-viz evaluate --json`` prints); with
        several outage lengths ``{length: report}`` in increasing length (a length no drive has room
        for is left out with a warning when another fits; when none fits, the shortest one's error,
        and nothing is written); with ``by_event`` an
        :class:`~ionav_viz.analysis.report.EventReports` (one report per manoeuvre type with an
        outage, and each type's count of events); with a ``scenario`` ``{scenario: report}``; with an
        ``engine`` a :class:`~ionav_viz.analysis.fleet.FleetReport` (:func:`~ionav_viz.api.fleet.run_fleet`:
        each drive on its own, a drive that fails reported, not fatal).
    """
    exp, outputs = experiment_of("evaluate", drives, outage_s, placement, estimators, keywords)
    export = outputs.get("export")
    fleet = outputs.get("fleet")
    if exp.engine is not None:
        if export is not None:
            raise InputError("a fleet (engine=) does not take export yet", "export one drive at a time",
                             param="export")
        return run_fleet(exp, None, progress, fleet)
    if fleet is not None:
        raise InputError("fleet= options are a fleet's", "give engine=iv.Engine(...) too", param="fleet")
    if exp.by_event is not False:
        if export is not None:
            raise InputError("by_event does not take export", "export the drives' own outages", param="export")
        if exp.scenario is not None:
            exp = replace(exp, drives=[s for specs in scenario_groups(exp).values() for s in specs], scenario=None)
        return evaluate_events(exp)
    if exp.scenario is not None:
        return {group: replace(evaluate_single(replace(exp, drives=specs, scenario=None), progress,
                                               None if export is None else Path(export) / group), title=group)
                for group, specs in scenario_groups(exp).items()}
    if exp.lengths_s is not None:
        return evaluate_each_length(exp, progress, export)
    return evaluate_single(exp, progress, export)



def replay(
    drive: Experiment | DriveLike | Sequence[DriveLike],
    outage_s: float | Sequence[float] | None = None,
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    output: str | Path | None = None,
    *,
    progress: Progress | None = None,
    connect: str | None = None,
    **keywords: Unpack[ExperimentKeywords],
) -> ReplayResult | list[ReplayResult] | list[Path] | FleetReport:
    """Replay ``drive`` with GNSS outages, run the estimators side by side and write a ``.rrd``.

    Args:
        drive, outage_s, placement, estimators, keywords: as for :func:`evaluate` (an
            :class:`~ionav_viz.api.experiment.Experiment`, or its one drive and its other fields;
            :class:`AroundEvents` places an outage on each detected manoeuvre of its types); not
            ``by_event``.
        output: the ``.rrd`` to write (default ``recordings/<drive>.rrd`` in the current
            directory, the folder made when missing; with ``read.span``, ``<drive>-0s-60s.rrd`` or
            ``<drive>-60s-end.rrd``: :func:`default_stem`); an existing file is replaced atomically,
            nothing is left behind on failure. With several outage lengths ``OUTPUT-<length>s.rrd``
            (default ``recordings/<drive>-<length>s.rrd``); with a ``scenario`` or an ``engine`` the
            folder the recordings go into (default ``recordings``).
        progress: called as the recording is built.
        connect: also stream the recording to the Rerun viewer at this gRPC address (e.g.
            ``rerun+http://127.0.0.1:9876/proxy``, where a plain ``rerun`` listens); checked
            before any work; one drive, one outage length.

    Returns:
        a :class:`ReplayResult` with the written path, the report and the outages; with several
        outage lengths one per length, increasing (a length the drive has no room for is left out
        with a warning when another fits; when none fits, the shortest one's error, and nothing is
        written); with a ``scenario`` the recordings' paths, ``<scenario>-<drive>.rrd`` each; with an
        ``engine`` the fleet's :class:`~ionav_viz.analysis.fleet.FleetReport`, each row with its
        ``recording`` (:func:`~ionav_viz.api.fleet.run_fleet`).
    """
    exp, outputs = experiment_of("replay", drive, outage_s, placement, estimators, keywords)
    export = outputs.get("export")
    fleet = outputs.get("fleet")
    many = exp.engine is not None or exp.scenario is not None
    for given, name in ((connect, "connect"), (export, "export")):
        if given is not None and (many or (name == "connect" and exp.lengths_s is not None)):
            raise InputError(f"{name}= goes with one drive's replay", f"replay one drive to {name} it", param=name)
    if exp.by_event is not False:
        raise InputError("replay records a drive's outages; by_event is evaluate's",
                         "place an outage on each event with placement=iv.AroundEvents([...])", param="by_event")
    if exp.engine is not None:
        return run_fleet(exp, RECORDINGS_DIR if output is None else output, progress, fleet)
    if fleet is not None:
        raise InputError("fleet= options are a fleet's", "give engine=iv.Engine(...) too", param="fleet")
    if exp.scenario is not None:
        return replay_scenario_drives(exp, RECORDINGS_DIR if output is None else output)
    if len(exp.drives) != 1:
        raise InputError(f"replay records one drive, and {len(exp.drives)} are given",
                         "give engine=iv.Engine(...) to replay many, one recording each", param="drives")
    if exp.lengths_s is not None:
        return replay_each_length(exp, output, progress, export)
    return replay_single(exp, output, progress, connect, export)
