"""``ionav-viz evaluate``: the paper's tables for every estimator on consecutive GNSS outages."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Optional

import typer

from ..core.errors import InputError
from . import common as c
from .app import app, options_named

if TYPE_CHECKING:
    from ..api.options import ReadOptions, RunOptions


@app.command()
@c.with_source_options
@c.with_estimator_options
@c.with_placement_options
def evaluate(
    drives: Optional[list[str]] = typer.Argument(None,
                                                 help="Drives: files or folders (IO-VNBD CSV, MCAP, ROS 1 .bag, ROS 2 "
                                                      "bag, KITTI raw), bundled scenario names or IO-VNBD run names."),
    outage: Optional[str] = c.OutageOrPlanOpt,
    plan: Optional[Path] = c.PlanOpt,
    external: Optional[list[str]] = c.ExternalOpt,
    export: Optional[Path] = c.ExportOpt,
    scenario: Optional[str] = typer.Option(None, "--scenario",
                                           help="Evaluate a scenario's test drives: the paper's runs with a data root, "
                                                "else the bundled ones; 'all' for every scenario."),
    as_json: bool = typer.Option(False, "--json", help="Print the results as JSON."),
    markdown: bool = typer.Option(False, "--markdown", help="Print the tables as Markdown."),
    overview: bool = typer.Option(False, "--overview",
                                  help="One line per scenario (means and improvement) instead of full tables."),
    by_event: bool = typer.Option(False, "--by-event",
                                  help="Tables per manoeuvre type: one outage centred on each detected event, across "
                                       "all the drives (--on: the types to tabulate)."),
    quiet: bool = c.QuietOpt,
    workers: Optional[int] = c.WorkersOpt,
    cluster: Optional[str] = c.ClusterOpt,
    fail_fast: bool = c.FailFastOpt,
    dry_run: bool = c.DryRunOpt,
    fleet_rrd: Optional[Path] = c.FleetRrdOpt,
    runs: Optional[list[str]] = c.RunsOpt,
    placement: c.PlacementArgs = None,  # --every, --at, --random, --seed, --on (c.with_placement_options)
    # RunOptions: --estimators, --estimator, --model, --no-idnn, --bias-from, --threshold (c.with_estimator_options)
    run: RunOptions | None = None,
    # ReadOptions: --data-root, --yaw-sign, log topics and stamps, --gnss-limit (c.with_source_options)
    read: ReadOptions | None = None,
) -> None:
    """Evaluate INS dead reckoning, the IDNN (and your estimators) on consecutive GNSS outages, as the paper does."""
    from .. import api
    from ..analysis.report import overview_reports, render_overview, reports_to_json

    if as_json and markdown:
        raise InputError("--json and --markdown: two output formats asked for", "give one of them")
    from . import fleet

    # many drives, each on its own (cli/fleet.py)
    if fleet_rrd is not None or fleet.is_fleet_run(drives, workers, cluster, fail_fast, dry_run, runs):
        refused = {"--scenario": scenario, "--plan": plan, "--external": external, "--export": export,
                   "--by-event": by_event, "--overview": overview, "--outage LENGTH,LENGTH": outage is not None and
                   "," in outage}
        fleet.evaluate_fleet(drives, outage, placement, run, read, workers=workers, cluster=cluster,
                             fail_fast=fail_fast, dry_run=dry_run, as_json=as_json, markdown=markdown, quiet=quiet,
                             refused=refused, fleet_rrd=fleet_rrd, runs=runs)
        return
    if outage is not None and "," in outage:
        for given, option in ((scenario, "--scenario"), (plan, "--plan"), (by_event or None, "--by-event"),
                              (overview or None, "--overview"), (external or None, "--external")):
            if given:
                raise typer.BadParameter(f"{outage}: several outage lengths do not go with {option}: give one length "
                                         f"with it, or leave {option} out",
                                         param_hint="--outage")
        _evaluate_lengths(outage, drives, placement, run, read, as_json, markdown, quiet, export)
        return
    outage_s, chosen = c.outage_and_placement(outage, plan, placement)
    if scenario is not None and drives:
        raise typer.BadParameter("give drives or --scenario, not both")
    if by_event and plan is not None:
        raise typer.BadParameter("--by-event places one outage on each event; --plan places the plan's",
                                 param_hint="--by-event")
    if by_event and export is not None:  # it was ignored without a word
        raise typer.BadParameter("--by-event writes no per-outage files; --export writes a run's",
                                 param_hint="--export")
    if by_event and placement.on is None and placement.option != "--outage":
        raise typer.BadParameter(f"--by-event places one outage on each event; {placement.option.split()[0]} places "
                                 "them otherwise", param_hint="--by-event")
    groups = api.scenario_drives(scenario, read.data_root) if scenario else {None: list(drives or [])}
    if scenario and not quiet:
        print(f"drives: {groups.source}", file=sys.stderr)
    if not any(groups.values()):
        raise typer.BadParameter("give at least one drive (or --scenario)", param_hint="DRIVES")
    with c.progress(quiet) as bar, options_named(outage_s=f"--outage {outage or '10s'}",
                                                 placement="--plan" if plan else placement.option):
        if by_event:
            reports = api.evaluate(api.Experiment([s for specs in groups.values() for s in specs], outage_s,
                                                  run=run, read=read,
                                                  by_event=tuple(placement.on) if placement.on else True))
        else:
            reports = {group: replace(api.evaluate(api.Experiment(specs, outage_s, chosen, run=run, read=read,
                                                                  external=c.externals_of(external)),
                                                   export=None if export is None
                                                   else (export / group if group else export),
                                                   progress=c.progress_callback(bar, "evaluating")), title=group)
                       for group, specs in groups.items()}

    if as_json:
        if None in reports:
            print(reports[None].to_json())
        else:
            print(reports_to_json(reports, "by_event" if by_event else "scenarios"))
        return
    # a type asked for that got no outage: one line, as its report's title would be (its count is in the JSON)
    none_here = ("".join(f"\n**{line}**\n" if markdown else f"\n{line}\n" for line in reports.without_outage_lines())
                 if by_event else "")
    if overview:
        rows = overview_reports(reports, by_event)
        print(render_overview(rows, markdown, "Manoeuvre" if by_event else "Drive", c.terminal_width()) + none_here,
              end="")
        return
    print("\n".join(rep.to_markdown() if markdown else rep.to_text(c.terminal_width())
                    for rep in reports.values()) + none_here, end="")


def _evaluate_lengths(outage: str, drives: Optional[list[str]], placement: c.PlacementArgs, run: RunOptions,
                      read: ReadOptions, as_json: bool, markdown: bool, quiet: bool, export: Optional[Path]) -> None:
    """``--outage 10s,30s,60s``: each length's report, then the error against outage length (the
    options it cannot take are refused by the caller); ``--export DIR`` writes ``DIR/<length>s``."""
    from .. import api
    from ..analysis.report import length_rows, lengths_to_json
    from ..analysis.tables import render_lengths

    if not drives:
        raise typer.BadParameter("give at least one drive", param_hint="DRIVES")
    lengths = c.durations_of(outage, "--outage")
    with c.progress(quiet) as bar, options_named(outage_s=f"--outage {outage}", placement=placement.option):
        reports = api.evaluate(api.Experiment(drives, lengths, placement.placement, run=run, read=read),
                               progress=c.progress_callback(bar, "evaluating"), export=export)
    if as_json:
        print(lengths_to_json(reports))
        return
    width = c.terminal_width()
    parts = [rep.to_markdown() if markdown else rep.to_text(width) for rep in reports.values()]
    parts.append(render_lengths(length_rows(reports), markdown, width))
    print("\n".join(parts), end="")
