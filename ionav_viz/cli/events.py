"""``ionav-viz events``: detected manoeuvres, and the detectors' measured quality."""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional

import typer
from typer.core import TyperCommand

from . import common as c
from .app import app, options_named

if TYPE_CHECKING:
    from ..api.options import ReadOptions


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
    drives: Optional[list[str]] = typer.Argument(None,
                                                 help="Drives: files or folders (IO-VNBD CSV, MCAP, ROS 1 .bag, ROS 2 "
                                                      "bag, KITTI raw), bundled scenario names or IO-VNBD run names."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON for scripts."),
    types: Optional[str] = typer.Option(None, "--type",
                                        help="Only these event types, comma-separated: hard-brake, roundabout, "
                                             "sharp-cornering, left-right, quick-accel, cruise, gnss-outage."),
    quality: bool = typer.Option(False, "--quality",
                                 help="Measure each detector's recall and precision on the bundled synthetic drives, "
                                      "where the simulator knows every manoeuvre."),
    thresholds: Optional[list[str]] = c.Thresholds,
    # ReadOptions: --data-root, --yaw-sign, log topics and stamps, --gnss-limit (c.with_source_options)
    read: ReadOptions | None = None,
) -> None:
    """Find hard brakes, roundabouts, sharp/left-right turns, acceleration swings, cruising and the log's GNSS losses.

    Definitions: docs/method.md ('Manoeuvres') and the docstring of ionav_viz/analysis/events.py;
    every --threshold NAME=VALUE, with its default and range, is listed below.
    """
    from .. import api
    from ..analysis.events import EventThresholds, current_type_names
    from ..core.json_out import dumps_json

    th = EventThresholds().with_overrides(list(thresholds or []))
    kinds = current_type_names(c.split_list(types)) if types else None
    if quality:
        if drives:  # were read by no one: the quality is measured on the bundled drives, where every manoeuvre is known
            raise typer.BadParameter("--quality measures the detectors on the bundled synthetic drives, not on "
                                     f"{' '.join(drives)}",
                                     param_hint="DRIVES")
        given = c.source_args(read)
        if given:  # read by no one either: the bundled drives are read whole and as they are, every manoeuvre known
            raise typer.BadParameter(f"--quality measures the detectors on the bundled synthetic drives whole, "
                                     f"as they are; it does not take {' '.join(given)} "
                                     "(leave it out, or find events on your drive with it)", param_hint=given[0])
        rows = api.detector_quality(th, kinds)
        if as_json:
            from ..dataset.samples import SAMPLES

            print(dumps_json({"drives": [s.file for s in SAMPLES], "detectors": {
                k: {"known": q.known, "recalled": q.recalled, "found": q.found, "precise": q.precise,
                    "recall": q.recall, "precision": q.precision}
                for k, q in rows.items()}}))
            return
        w = max(len("event"), *(len(k) for k in rows))  # sharp-cornering is wider than 13
        print(f"{'event':<{w}} {'known':>5} {'found':>5}  {'recall':>7}  {'precision':>9}   (bundled synthetic drives)")
        for k, q in rows.items():
            rec = f"{100 * q.recall:.0f} %" if q.recall is not None else "-"
            prec = f"{100 * q.precision:.0f} %" if q.precision is not None else "-"
            print(f"{k:<{w}} {q.known:>5} {q.found:>5}  {rec:>7}  {prec:>9}")
        return
    if not drives:
        raise typer.BadParameter("give at least one drive (or --quality)", param_hint="DRIVES")
    with options_named(placement="--type"):
        found = api.find_events(drives, kinds, thresholds=th, read=read)
    if as_json:
        print(dumps_json({name: [e.to_dict() for e in evs] for name, evs in found.items()}))
        return
    for name, evs in found.items():
        print(f"{name}: {len(evs)} event(s)")
        for e in evs:
            # a count: 115, not 115.00
            values = ", ".join(f"{k} {v}" if isinstance(v, int) else f"{k} {v:.2f}" for k, v in e.values.items())
            print(f"  {e.type:<15} {e.t0_s:8.1f} - {e.t1_s:8.1f} s   {values}")
