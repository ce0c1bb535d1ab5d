"""``ionav-viz outage-log``: a drive's log with the GNSS removed inside the outages, for an estimator
outside ionav-viz, and the plan that scores what it comes back with (``evaluate --plan``)."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from . import common as c
from .app import app, options_named

if TYPE_CHECKING:
    from ..api.options import ReadOptions


@app.command("outage-log")
@c.with_source_options
@c.with_placement_options
def outage_log(
    drive_spec: str = typer.Argument(..., metavar="DRIVE",
                                     help="A drive: IO-VNBD CSV, MCAP, ROS 1 .bag, ROS 2 bag folder, KITTI raw folder, "
                                          "bundled scenario or run name."),
    output: Path = typer.Option(..., "-o", "--output",
                                help="The outaged log: .mcap, .bag (ROS 1), a new folder (ROS 2 bag) or .csv (an "
                                     "IO-VNBD source); the plan goes beside it as NAME.outages.json."),
    outage: str = c.OutageOpt,
    warm_up: str = c.WarmUp,
    quiet: bool = c.QuietOpt,
    placement: c.PlacementArgs = None,  # --every, --at, --random, --seed, --on (c.with_placement_options)
    read: ReadOptions | None = None,  # ReadOptions (c.with_source_options)
) -> None:
    """Write a drive's log without GNSS in the outages evaluate would place, and the plan to score an estimate on it."""
    from .. import api

    outage_s = c.duration_s(outage, "--outage")
    with options_named(outage_s=f"--outage {outage}", placement=placement.option, warm_up=f"--warm-up {warm_up}"):
        run = api.RunOptions(warm_up_s=c.duration_s(warm_up, "--warm-up", allow_zero=True))
        done = api.outage_log(drive_spec, output, outage_s, placement.placement, run=run, read=read)
    plan = done.plan
    if not quiet:
        print(f"{len(plan.start_stamps_s)} outage(s) of {plan.outage_s:g} s ({plan.placement}); {done.removed} GNSS "
              f"message(s) removed from {', '.join(plan.removed_topics)}", file=sys.stderr)
        evaluate = shlex.join(["ionav-viz", "evaluate", drive_spec, *c.source_args(read), "--plan",
                               str(done.plan_path)])
        print(f"score what your estimator writes on it: {evaluate} --external NAME=TRAJECTORY", file=sys.stderr)
    print(done.path)
    print(done.plan_path)
