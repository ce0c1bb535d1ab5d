"""The API's names of the release before :class:`~.experiment.Experiment`, kept one release: each
warns (``DeprecationWarning``, naming its replacement) and returns what it returned, through
:func:`~.run.evaluate` or :func:`~.run.replay`."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypedDict, Unpack

from ..analysis.fleet import FleetReport
from ..analysis.report import EventReports, Report
from ..core.errors import InputError
from ..experiment.outages import Placement
from ..nav.protocol import Estimator
from ..sources.load import ReadOptions
from .engine import Engine, default_workers
from .experiment import Experiment, ExperimentKeywords, FleetOptions, deprecated
from .fleet import check_callables
from .options import DriveLike, Progress, RunOptions
from .replay import ReplayResult
from .run import evaluate, replay


def evaluate_lengths(
    drives: Sequence[DriveLike] | DriveLike,
    lengths_s: Sequence[float],
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    progress: Progress | None = None,
    **keywords: Unpack[ExperimentKeywords],
) -> dict[float, Report]:
    """Deprecated: ``evaluate(drives, [length, ...])`` (several outage lengths), which this calls."""
    deprecated("evaluate_lengths", "evaluate(drives, [length, ...])")
    return evaluate(drives, list(lengths_s), placement, estimators, progress=progress, **keywords)


def evaluate_by_event(
    drives: Sequence[DriveLike],
    outage_s: float | None = None,
    types: Sequence[str] | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    **keywords: Unpack[ExperimentKeywords],
) -> EventReports:
    """Deprecated: ``evaluate(drives, outage_s, by_event=types or True)``, which this calls."""
    deprecated("evaluate_by_event", "evaluate(drives, outage_s, by_event=[type, ...])")
    return evaluate(drives, outage_s, None, estimators, by_event=tuple(types) if types else True, **keywords)


def replay_lengths(
    drive: DriveLike,
    lengths_s: Sequence[float],
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    output: str | Path | None = None,
    *,
    progress: Progress | None = None,
    **keywords: Unpack[ExperimentKeywords],
) -> list[ReplayResult]:
    """Deprecated: ``replay(drive, [length, ...])`` (several outage lengths), which this calls;
    ``analysis.report.by_length`` of their reports gives the error against outage length."""
    deprecated("replay_lengths", "replay(drive, [length, ...])")
    return replay(drive, list(lengths_s), placement, estimators, output, progress=progress, **keywords)


def replay_scenario(scenario: str, folder: str | Path, outage_s: float = 10.0, placement: Placement | None = None, *,
                    run: RunOptions | None = None, read: ReadOptions | None = None) -> list[Path]:
    """Deprecated: ``replay(Experiment(scenario=scenario, ...), output=folder)``, which this calls."""
    deprecated("replay_scenario", "replay(Experiment(scenario=...), output=FOLDER)")
    return replay(Experiment(scenario=scenario, outage_s=outage_s, placement=placement, run=run, read=read),
                  output=folder)


class FleetKeywords(TypedDict, total=False):
    """The keyword arguments of the deprecated :func:`evaluate_fleet` and :func:`replay_fleet`."""

    run: RunOptions | None
    read: ReadOptions | None
    fail_fast: bool
    replay_options: str
    runs: Sequence[str]
    fleet_rrd: str | Path | None
    progress: Progress | None


def evaluate_fleet(
    drives: Sequence[str | Path] | str | Path,
    outage_s: float | None = None,
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    workers: int | None = None,
    cluster: str | None = None,
    progress: Progress | None = None,
    **keywords: Unpack[FleetKeywords],
) -> FleetReport:
    """Deprecated: ``evaluate(drives, ..., engine=Engine(workers, cluster), fleet=FleetOptions(...))``
    (:func:`run_fleet`), which this calls; ``workers`` default every core."""
    deprecated("evaluate_fleet", "evaluate(drives, ..., engine=iv.Engine(workers, cluster))")
    return evaluate(drives, outage_s, placement, estimators, progress=progress,
                    **_fleet_keywords(workers, cluster, progress, keywords))


def replay_fleet(
    drives: Sequence[str | Path] | str | Path,
    folder: str | Path = "recordings",
    outage_s: float | None = None,
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    workers: int | None = None,
    cluster: str | None = None,
    **keywords: Unpack[FleetKeywords],
) -> FleetReport:
    """Deprecated: ``replay(drives, ..., output=folder, engine=Engine(workers, cluster))``
    (:func:`run_fleet`), which this calls; ``progress`` may be among the keywords."""
    deprecated("replay_fleet", "replay(drives, ..., output=FOLDER, engine=iv.Engine(workers, cluster))")
    progress = keywords.pop("progress", None)
    check_callables(progress, keywords.get("replay_options", ""))
    if not isinstance(folder, (str, os.PathLike)):
        raise InputError(f"folder={folder!r} is not a folder's path",
                         "give the folder the recordings go into, e.g. 'recordings'", param="output")
    return replay(drives, outage_s, placement, estimators, folder, progress=progress,
                  **_fleet_keywords(workers, cluster, progress, keywords))


def _fleet_keywords(workers: int | None, cluster: str | None, progress: Progress | None,
                    keywords: dict[str, Any]) -> dict[str, Any]:
    """The deprecated fleet functions' arguments as :func:`ionav_viz.evaluate`'s: checked in the
    order those functions checked them (the callables, then the engine)."""
    unknown = sorted(set(keywords) - set(FleetKeywords.__annotations__))
    if unknown:
        raise TypeError(f"got an unexpected keyword argument {unknown[0]!r}")
    check_callables(progress, keywords.get("replay_options", ""))
    fleet = FleetOptions(keywords.pop("fail_fast", False), keywords.pop("fleet_rrd", None),
                         keywords.pop("replay_options", ""))
    engine = Engine(workers if workers is not None else default_workers(), cluster)
    return {**keywords, "engine": engine, "fleet": fleet}
