"""``ionav-viz screenshot``: PNG review images of recordings, rendered by a headless Rerun viewer."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Optional

import typer

from . import common as c
from .app import app, log, options_named


@app.command()
@c.with_placement_options
def screenshot(
    recordings: Optional[list[Path]] = typer.Argument(None, metavar="[REC.rrd]...",
                                                      help="Recordings made by 'ionav-viz replay'."),
    output: Path = typer.Option(..., "-o", "--output",
                                help="OUT.png for one image, else a directory (or OUT.png whose name is used "
                                     "as a prefix)."),
    times: Optional[list[str]] = typer.Option(None, "--time",
                                              help="Times to show: e.g. 35s, 'end' (default) or 'worst' (the end of "
                                                   "the outage with the largest final position error of --worst-of, "
                                                   "framed). Repeatable."),
    outage_numbers: Optional[list[str]] = typer.Option(None, "--outage-number",
                                                       help="Outage numbers (as replay lists them; in a replay "
                                                            "through the log's own GNSS losses alone, its real "
                                                            "losses): each framed and shown at its end. Repeatable."),
    outage: Optional[list[str]] = typer.Option(None, "--outage",
                                               help="Outage length of --scenario replays, e.g. 10s (default). A bare "
                                                    "number N is --outage-number N (deprecated).", show_default=False),
    worst_of: str = typer.Option("ins", "--worst-of",
                                 help="The estimator whose final error picks --time worst (default: the "
                                      "paper's INS DR)."),
    views: Optional[list[str]] = typer.Option(None, "--view",
                                              help="all (default), outage (the outage inspector), map, local, signals, "
                                                   "errors or health (the filters' health). Repeatable."),
    size: str = typer.Option("1600x900", "--size", help="Image size WIDTHxHEIGHT in pixels."),
    scenario: Optional[str] = typer.Option(None, "--scenario",
                                           help="Replay and render a scenario's test drives ('all' for every "
                                                "scenario): bundled ones, or the paper's runs with a data root."),
    outage_length: Optional[str] = typer.Option(None, "--outage-length", help="Deprecated: --outage.", hidden=True),
    estimator_names: Optional[str] = c.EstimatorsOpt,
    plugins: Optional[list[str]] = c.EstimatorOpt,
    timeout: str = typer.Option("120s", "--timeout", help="Longest wait for the viewer to start or load a recording."),
    data_root_opt: Optional[Path] = c.DataRoot,
    quiet: bool = typer.Option(False, "--quiet", "-q",
                               help="Do not print the path of each image, nor where --scenario drives come from."),
    # --every, --at, --random, --seed, --on for --scenario replays (c.with_placement_options)
    placement: c.PlacementArgs = None,
) -> None:
    """Render PNG screenshots of recordings with a headless Rerun viewer (no display or GPU needed).

    Prints the path of every image written (unless -q).
    """
    from .. import api
    from ..sources.load import ReadOptions
    from ..viz.screenshot import parse_size

    width_height = parse_size(size)
    timeout_s = c.duration_s(timeout, "--timeout")
    if scenario is not None and recordings:
        raise typer.BadParameter("give recordings or --scenario, not both")
    if scenario is None and not recordings:
        raise typer.BadParameter("give at least one REC.rrd (or --scenario)", param_hint="REC.rrd")
    if scenario is None and (estimator_names is not None or plugins):
        raise typer.BadParameter("--estimators and --estimator choose what --scenario replays run",
                                 param_hint="--scenario")
    if scenario is None and placement.option != "--outage":
        raise typer.BadParameter(f"{placement.option.split()[0]} places the outages of --scenario replays",
                                 param_hint="--scenario")
    length, numbers = _outage_length_and_numbers(outage or [], outage_length, outage_numbers or [])
    if scenario is None and (outage_length is not None or any(not o.strip().isdigit() for o in outage or [])):
        raise typer.BadParameter("the outage length is for --scenario replays (a recording has its own); to frame "
                                 "outage N give --outage-number N",
                                 param_hint="--outage")
    times = list(times or ([] if numbers else ["worst"] if scenario else ["end"]))
    views = list(views or ["all"])
    names = options_named(outage_s="--outage", outages="--outage-number", worst_of="--worst-of",
                          placement=placement.option)
    with tempfile.TemporaryDirectory(prefix="ionav-shots-") as tmp, names:
        rrds = list(recordings or [])
        if scenario is not None:
            read = ReadOptions(data_root=data_root_opt)
            if not quiet:
                print(f"drives: {api.scenario_drives(scenario, read.data_root).source}", file=sys.stderr)
            rrds = api.replay(api.Experiment(scenario=scenario, outage_s=length, placement=placement.placement,
                                             run=c.run_options(estimator_names, plugins), read=read), output=tmp)
        api.screenshot(rrds, output, api.Shots(times, views, width_height, numbers, worst_of), timeout_s=timeout_s,
                       progress=None if quiet else print)


def _outage_length_and_numbers(outage: list[str], outage_length: Optional[str],
                               numbers: list[str]) -> tuple[float, list[int]]:
    """``--outage`` is a length here as on every other command; a bare number there is an outage
    number (its meaning before 0.2, said once as deprecated), as is ``--outage-length`` for the length."""
    lengths = [o for o in outage if not o.strip().isdigit()]
    old_numbers = [o for o in outage if o.strip().isdigit()]
    if old_numbers:
        log.warning("--outage %s: outage numbers are --outage-number now (--outage is the outage length, "
                    "as for replay)", old_numbers[0])
    if outage_length is not None:
        log.warning("--outage-length is --outage now")
        lengths.append(outage_length)
    if len(lengths) > 1:
        raise typer.BadParameter("one outage length for --scenario replays", param_hint="--outage")
    length = c.duration_s(lengths[0], "--outage") if lengths else 10.0
    return length, [_outage_number(n) for n in [*old_numbers, *numbers]]


def _outage_number(text: str) -> int:
    if not text.strip().isdigit() or int(text) < 1:
        hint = "; the outage length of --scenario replays is --outage" if text.strip().endswith("s") else ""
        raise typer.BadParameter(f"{text!r}: give an outage number (1, 2, ...) as replay lists them{hint}",
                                 param_hint="--outage-number")
    return int(text)
