"""One typed experiment: the drives, the outages (lengths and placement), how the estimators run
and the drives are read, and where the work runs. :func:`ionav_viz.evaluate` and
:func:`ionav_viz.replay` consume it; their variants (several outage lengths, by manoeuvre, a
fleet, a scenario's test drives) are values of its fields, not functions of their own."""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict

from ..core.drive import Drive
from ..core.errors import InputError
from ..dataset.catalog import SCENARIOS
from ..experiment.outages import Placement
from ..experiment.plan_file import FromPlan
from ..nav.protocol import Estimator
from ..sources.load import LogOptions, ReadOptions
from .engine import Engine
from .options import (
    DriveLike,
    RunOptions,
    check_event_types,
    check_externals,
    check_placement,
    lengths_of,
    options_of,
    windows_of,
)

#: What ``drives`` takes, for its errors.
DRIVES_HINT = "give a drive, a folder, a glob or '@list.txt' (a str or Path), or a list of them"


@dataclass(frozen=True)
class FleetOptions:
    """How a fleet run (an :class:`Experiment` with an ``engine``) reports and what else it writes.

    Attributes:
        fail_fast: the first drive that fails raises its :class:`InputError` (the work not started
            is cancelled) instead of being reported.
        fleet_rrd: where to write the fleet's overview recording
            (:func:`~ionav_viz.api.fleet.write_fleet_recording`) when some drive was evaluated;
            checked with the run's other outputs before any work.
        replay_options: the options that replay a drive the same way, for the report's commands.
    """

    fail_fast: bool = False
    fleet_rrd: str | Path | None = None
    replay_options: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.replay_options, str):
            raise InputError(f"replay_options={self.replay_options!r} is not a string",
                             "give the options as one string, e.g. '--outage 10s'", param="replay_options")


@dataclass(frozen=True)
class Experiment:
    """GNSS outages on drives, every estimator scored on the same ones: what :func:`ionav_viz.evaluate`
    scores and :func:`ionav_viz.replay` records. Checked when made (one-line :class:`InputError`
    naming the field); nothing is read until it runs, but for the plan file.

    Attributes:
        drives: drives or what names them (a path, a bundled scenario or IO-VNBD run name, a
            :class:`~ionav_viz.core.drive.Drive`), or one alone; with an ``engine`` also folders,
            globs and ``@list.txt`` files (:func:`~ionav_viz.api.fleet.expand_drives`). Kept as a tuple.
        outage_s: the length of each outage (whole seconds; None: 10 s, or a plan's); several
            lengths (a sequence, kept sorted as a tuple): every length on the same drives and
            placement, one result each.
        placement: where outages go (default :class:`~ionav_viz.experiment.outages.Tile`, the
            paper's consecutive outages).
        run: which estimators run with what model, biases, thresholds and warm-up (:class:`RunOptions`).
        read: how drives are read (:class:`ReadOptions`).
        engine: run the drives as a fleet, each on its own, on this engine (worker processes or a
            Dask cluster); None: one after another in this process, one report.
        plan: an outage plan file (``NAME.outages.json`` of :func:`~ionav_viz.api.outage_log.outage_log`):
            exactly its outages, on its one drive (instead of ``placement``; the length is the plan's).
        external: estimates made outside ionav-viz on the plan's outaged log, ``{name: trajectory}``
            (a ``.csv``, a ``.tum`` or ``LOG:TOPIC``), scored like the built-ins; they need ``plan``.
        truth: a message log's reference topic, the truth every score is measured against (a
            shortcut for ``read.log.truth_topic``).
        by_event: one outage centred on each detected event, one report per manoeuvre type: True
            for every manoeuvre type, or the types (``gnss-outage``: the log's own losses).
        scenario: a scenario's test drives instead of ``drives`` (``"all"``: every scenario's;
            :func:`~ionav_viz.api.evaluate.scenario_drives`), one result per scenario.
        runs: IO-VNBD run selections added to a fleet's drives (``all``, a group, a driver).
    """

    drives: Sequence[DriveLike] | DriveLike | None = ()
    outage_s: float | Sequence[float] | None = None
    placement: Placement | None = None
    run: RunOptions = field(default_factory=RunOptions)
    read: ReadOptions = field(default_factory=ReadOptions)
    engine: Engine | None = None
    plan: str | Path | None = None
    external: Mapping[str, str | Path] | None = None
    truth: str | None = None
    by_event: bool | Sequence[str] = False
    scenario: str | None = None
    runs: Sequence[str] = ()

    def __post_init__(self) -> None:
        if self.run is None:
            object.__setattr__(self, "run", RunOptions())
        if self.read is None:
            object.__setattr__(self, "read", ReadOptions())
        options_of(self.run, None, self.read, None, self.truth)  # run=, read= and truth= checked
        if isinstance(self.runs, str):
            object.__setattr__(self, "runs", (self.runs,))
        object.__setattr__(self, "drives", self._drives())
        check_placement(self.placement, self.plan)
        if self.placement is not None and self.placement.event_types:
            check_event_types(self.placement.event_types)
        if isinstance(self.outage_s, Iterable) and not isinstance(self.outage_s, (str, bytes)):
            object.__setattr__(self, "outage_s", tuple(lengths_of(self.outage_s, self.placement)))
        elif self.outage_s is not None and not self.on_a_plan:
            windows_of(self.outage_s)
        check_externals(self.external, self.on_a_plan)
        if self.engine is not None and not isinstance(self.engine, Engine):
            raise InputError(f"engine={self.engine!r} is not an Engine",
                             "give engine=iv.Engine(workers=4) or iv.Engine(cluster='local'), or leave it out",
                             param="engine")
        self._check_by_event()
        self._check_together()

    def _drives(self) -> tuple[DriveLike, ...]:
        """``drives`` as a tuple: one drive, path or name alone is one drive (not its characters)."""
        drives = self.drives
        if drives is None and (self.runs or self.scenario is not None):
            drives = ()
        if isinstance(drives, (Drive, str, os.PathLike)):
            drives = (drives,)
        if drives is None or isinstance(drives, bytes) or not isinstance(drives, Iterable):
            raise InputError(f"drives={drives!r}: not a drive or a list of drives", DRIVES_HINT, param="drives")
        drives = tuple(drives)
        for i, item in enumerate(drives):
            if not isinstance(item, (Drive, str, os.PathLike)):
                raise InputError(f"drives[{i}]={item!r}: not a drive's path or name", DRIVES_HINT, param="drives")
        if self.scenario is not None:
            if drives:
                raise InputError("drives and a scenario given", "give drives or scenario=, not both", param="scenario")
            if self.scenario != "all" and self.scenario not in SCENARIOS:
                raise InputError(f"unknown scenario {self.scenario!r}", f"choose {', '.join(SCENARIOS)} or all",
                                 param="scenario")
        elif not drives and not self.runs:
            raise InputError("no drive to evaluate", "give at least one drive")
        return drives

    def _check_by_event(self) -> None:
        if self.by_event is False:
            return
        if self.by_event is not True:
            if isinstance(self.by_event, (str, bytes)) or not isinstance(self.by_event, Iterable):
                raise InputError(f"by_event={self.by_event!r}: not True or a list of event types",
                                 "e.g. by_event=['hard-brake', 'roundabout'], or by_event=True for every manoeuvre",
                                 param="by_event")
            object.__setattr__(self, "by_event", tuple(self.by_event))
            if self.by_event:
                check_event_types(self.by_event)
        for given, what in ((self.on_a_plan, "a plan places the plan's"),
                            (self.placement is not None, "placement= places them otherwise")):
            if given:
                raise InputError(f"by_event places one outage on each event; {what}",
                                 "leave out by_event or the other", param="by_event")

    def _check_together(self) -> None:
        """Variants that do not go together, each refused naming one of them."""
        lengths = isinstance(self.outage_s, tuple)
        fleet = self.engine is not None
        refused = (
            (lengths and self.by_event is not False, "several outage lengths do not go with by_event", "outage_s"),
            (lengths and self.on_a_plan, "several outage lengths do not go with a plan (its length is its "
                                                "own)", "outage_s"),
            (lengths and self.scenario is not None, "several outage lengths do not go with a scenario", "outage_s"),
            (fleet and lengths, "a fleet (engine=) takes one outage length", "outage_s"),
            (fleet and self.on_a_plan, "a fleet (engine=) does not take a plan (made for one drive)", "plan"),
            (fleet and self.by_event is not False, "a fleet (engine=) does not take by_event yet", "by_event"),
            (fleet and self.scenario is not None, "a fleet (engine=) does not take a scenario yet", "scenario"),
            (not fleet and bool(self.runs), "runs= selects IO-VNBD runs for a fleet", "runs"),
            (self.on_a_plan and len(self.drives) > 1,
             f"a plan is made for one drive, and {len(self.drives)} are given", "plan"),
        )
        for bad, message, param in refused:
            if bad:
                hint = ("give engine=iv.Engine(...) too" if param == "runs"
                        else "evaluate the plan's drive alone" if param == "plan" and not fleet
                        else "give them in separate experiments")
                raise InputError(message, hint, param=param)

    @property
    def on_a_plan(self) -> bool:
        """Whether the outages are a plan file's (``plan``, or a :class:`FromPlan` placement)."""
        return self.plan is not None or isinstance(self.placement, FromPlan)

    @property
    def lengths_s(self) -> tuple[float, ...] | None:
        """The outage lengths when several were given (increasing), else None."""
        return self.outage_s if isinstance(self.outage_s, tuple) else None

    def options(self) -> tuple[RunOptions, ReadOptions]:
        """The run and read options, ``truth`` folded into ``read.log.truth_topic``."""
        return options_of(self.run, None, self.read, None, self.truth)


class ExperimentKeywords(TypedDict, total=False):
    """The keyword arguments :func:`ionav_viz.evaluate` and :func:`ionav_viz.replay` take beside
    the drives, outage length, placement and estimators: the other fields of an
    :class:`Experiment` (given without one), what the call writes, and ``mcap`` (deprecated:
    ``read=ReadOptions(log=...)``)."""

    run: RunOptions | None
    read: ReadOptions | None
    engine: Engine | None
    plan: str | Path | None
    external: Mapping[str, str | Path] | None
    truth: str | None
    by_event: bool | Sequence[str]
    scenario: str | None
    runs: Sequence[str]
    mcap: LogOptions | None
    export: str | Path | None
    fleet: FleetOptions | None


#: The keywords of :class:`ExperimentKeywords` that are not the experiment's: what a call writes.
OUTPUT_KEYWORDS = ("export", "fleet")


def experiment_of(function: str, drives: Experiment | Sequence[DriveLike] | DriveLike | None,
                  outage_s: float | Sequence[float] | None, placement: Placement | None,
                  estimators: Sequence[str | Estimator] | None,
                  keywords: Mapping[str, object]) -> tuple[Experiment, dict[str, object]]:
    """The :class:`Experiment` of an ``evaluate`` or ``replay`` call (``function``: its name, for
    errors), given whole or as today's arguments, and the call's outputs (``export``, ``fleet``)."""
    unknown = sorted(set(keywords) - set(ExperimentKeywords.__annotations__))
    if unknown:
        raise TypeError(f"{function}() got an unexpected keyword argument {unknown[0]!r}")
    outputs = {k: keywords[k] for k in OUTPUT_KEYWORDS if keywords.get(k) is not None}
    fields = {k: v for k, v in keywords.items() if k not in OUTPUT_KEYWORDS}
    if isinstance(drives, Experiment):
        given = [name for name, value in (("outage_s", outage_s), ("placement", placement), ("estimators", estimators),
                                          *fields.items()) if value is not None]
        if given:
            raise InputError(f"{given[0]}= given beside an Experiment",
                             "give it in the Experiment (dataclasses.replace(experiment, ...))", param=given[0])
        return drives, outputs
    mcap = fields.pop("mcap", None)
    if mcap is not None or estimators is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # said below, pointing at the caller
            run, read = options_of(fields.pop("run", None), estimators, fields.pop("read", None), mcap)
        if mcap is not None:
            warnings.warn("mcap= is deprecated: pass read=ReadOptions(log=LogOptions(...))", DeprecationWarning,
                          stacklevel=3)
        fields.update(run=run, read=read)
    fields = {k: v for k, v in fields.items() if v is not None}
    return Experiment(drives, outage_s, placement, **fields), outputs  # type: ignore[arg-type]


def deprecated(old: str, new: str) -> None:
    """The one-release warning of an old API name, pointing at its caller's line."""
    warnings.warn(f"{old} is deprecated: use {new}", DeprecationWarning, stacklevel=3)
