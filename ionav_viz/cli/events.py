"""``ionav-viz events``: detected manoeuvres, and the detectors' measured quality."""

from __future__ import annotations

import json
from typing import Optional

import typer
from typer.core import TyperCommand

from . import common as c
from .app import app


class _EventsCommand(TyperCommand):
    """``events --help`` ends with every detector threshold, its default and range (read from
    :class:`~ionav_viz.analysis.events.EventThresholds` only when help is shown)."""

    def format_help(self, ctx, formatter):
        from ..analysis.events import threshold_help

        self.epilog = threshold_help()
        return super().format_help(ctx, formatter)


@app.command(cls=_EventsCommand)
@c.with_source_options
def events(
    drives: Optional[list[str]] = typer.Argument(None, help="Drives: files or folders (IO-VNBD CSV, MCAP, ROS 1 .bag, ROS 2 bag, KITTI raw), bundled scenario names or IO-VNBD run names."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON for scripts."),
    types: Optional[str] = typer.Option(None, "--type", help="Only these event types, comma-separated."),
    quality: bool = typer.Option(False, "--quality", help="Measure each detector's recall and precision on the bundled synthetic drives, where the simulator knows every manoeuvre."),
    thresholds: Optional[list[str]] = c.Thresholds,
    source: c.SourceArgs = None,  # --data-root, --yaw-sign, MCAP topics and stamps (c.with_source_options)
) -> None:
    """Find hard brakes, roundabouts, sharp corners, left-right turns, quick acceleration changes and cruising.

    Definitions: docs/method.md ('Manoeuvres') and the docstring of ionav_viz/analysis/events.py;
    every --threshold NAME=VALUE, with its default and range, is listed below.
    """
    from ..analysis.events import EVENT_TYPES, detect_events, score
    from ..dataset.samples import SAMPLES, sample_path
    from ..sim.simulate import simulated_manoeuvres
    from ..sources.load import load_drive
    from ..sources.resolve import data_root

    th = c.thresholds(thresholds)
    kinds = c.event_types(types) if types else EVENT_TYPES
    if quality:
        totals: dict[str, list[int]] = {k: [0, 0, 0, 0] for k in EVENT_TYPES}
        for sample in SAMPLES:
            drive = load_drive(str(sample_path(sample)))  # with the GNSS quality marks, as every command reads
            truth = simulated_manoeuvres(sample.scenario, sample.seed, sample.duration_s, sample.gnss_losses)
            for kind, sc in score(truth, detect_events(drive, th), drive.duration_s).items():
                for i, v in enumerate((sc.n_truth, sc.recalled, sc.n_found, sc.precise)):
                    totals[kind][i] += v
        rows = {k: {"known": t[0], "recalled": t[1], "found": t[2], "precise": t[3],
                    "recall": t[1] / t[0] if t[0] else None, "precision": t[3] / t[2] if t[2] else None}
                for k, t in totals.items() if k in kinds}
        if as_json:
            print(json.dumps({"drives": [s.file for s in SAMPLES], "detectors": rows}, indent=2))
            return
        print(f"{'event':<13} {'known':>5} {'found':>5}  {'recall':>7}  {'precision':>9}   (bundled synthetic drives)")
        for k, r in rows.items():
            rec = f"{100 * r['recall']:.0f} %" if r["recall"] is not None else "-"
            prec = f"{100 * r['precision']:.0f} %" if r["precision"] is not None else "-"
            print(f"{k:<13} {r['known']:>5} {r['found']:>5}  {rec:>7}  {prec:>9}")
        return
    if not drives:
        raise typer.BadParameter("give at least one drive (or --quality)", param_hint="DRIVES")
    root = data_root(source.data_root)
    yaw_sign, mcap = source.yaw_sign, source.mcap
    found = {}
    for spec in drives:
        drive = load_drive(spec, root, yaw_sign, mcap, source.gnss_limits)
        found[drive.name] = [e for e in detect_events(drive, th) if e.type in kinds]
    if as_json:
        print(json.dumps({name: [e.to_dict() for e in evs] for name, evs in found.items()}, indent=2))
        return
    for name, evs in found.items():
        print(f"{name}: {len(evs)} event(s)")
        for e in evs:
            values = ", ".join(f"{k} {v:.2f}" for k, v in e.values.items())
            print(f"  {e.type:<13} {e.t0_s:8.1f} - {e.t1_s:8.1f} s   {values}")
