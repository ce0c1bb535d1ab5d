"""The experiment's one chain, per drive: its windows, the outage plan, then every estimator scored
on the plan's outages. :func:`plan_drive` and :func:`score` are the only place it is written;
``evaluate``, ``replay``, fleets, ``outage-log`` and the manoeuvre tables are its consumers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

from ..analysis.evaluate import DriveResult, evaluate_drive
from ..analysis.events import Event, detect_events
from ..core.drive import Drive
from ..experiment.outages import At, OutagePlan, Placement, Planned
from ..nav.bias import SensorBias
from ..nav.protocol import Estimator
from ..nav.windows import Windows, make_windows
from .options import RunOptions


@dataclass(frozen=True)
class DrivePlan:
    """One drive cut into 1 s windows with its outages planned: what :func:`score` runs on.

    Attributes:
        drive: the drive.
        n_windows: the outage length (whole seconds, one window a second).
        windows: its 1 s windows (:func:`~ionav_viz.nav.windows.make_windows`).
        plan: where the outages go (first windows, those lost to bad GNSS, the log's own losses).
        events: the manoeuvres the plan was made on (detected when the placement needs them).
    """

    drive: Drive
    n_windows: int
    windows: Windows
    plan: OutagePlan
    events: list[Event] = field(default_factory=list)


def plan_outages(drive: Drive, windows: Windows, placement: Placement, n_windows: int, run: RunOptions,
                 events: list[Event] | None = None) -> tuple[OutagePlan, list[Event]]:
    """The placement's plan for one drive, with the events it was planned on (detected when the
    placement needs them and they were not given). Placements that choose where outages go leave
    ``run.warm_up_s`` free at the drive's start; outages at given times or from a plan are where
    they are said to be."""
    from ..experiment.plan_file import FromPlan

    if isinstance(placement, FromPlan):
        placement = placement.for_drive(drive)
    if events is None and placement.event_types:
        events = detect_events(drive, run.thresholds)
    explicit = isinstance(placement, (At, Planned))  # the outages are where the caller said
    warm_up = 0.0 if explicit else float(run.warm_up_s)
    plan = placement.plan(windows.after_warm_up(warm_up), n_windows, events or [], drive.source)
    if warm_up > 0 and len(plan.starts):
        plan = replace(plan, description=f"{plan.description}, after a {warm_up:g} s warm-up")
    return plan, events or []


def plan_drive(drive: Drive, placement: Placement, n_windows: int, run: RunOptions, events: list[Event] | None = None,
               windows: Windows | None = None) -> DrivePlan:
    """``drive``'s windows (made here unless given) and its outage plan (:func:`plan_outages`)."""
    windows = windows if windows is not None else make_windows(drive)
    plan, found = plan_outages(drive, windows, placement, n_windows, run, events)
    return DrivePlan(drive, n_windows, windows, plan, found)


def score(planned: DrivePlan, estimators: Sequence[Estimator], bias: SensorBias | None) -> DriveResult:
    """Every one of ``estimators`` on the planned outages of the drive, scored with the paper's
    metrics (:func:`~ionav_viz.analysis.evaluate.evaluate_drive`); ``bias``: the sensor biases
    (None: from the drive's own stationary stretches)."""
    return evaluate_drive(planned.drive, planned.n_windows, estimators, bias=bias, plan=planned.plan,
                          windows=planned.windows)
