"""``ionav-viz screenshot``: PNG review images of recordings, rendered by a headless Rerun viewer."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Optional

import typer

from ..core.errors import InputError
from . import common as c
from .app import app, name_options


@app.command()
def screenshot(
    recordings: Optional[list[Path]] = typer.Argument(None, metavar="[REC.rrd]...", help="Recordings made by 'ionav-viz replay'."),
    output: Path = typer.Option(..., "-o", "--output", help="OUT.png for one image, else a directory (or OUT.png whose name is used as a prefix)."),
    times: Optional[list[str]] = typer.Option(None, "--time", help="Times to show: e.g. 35s, 'worst' (end of the outage with the largest INS error) or 'end' (default). Repeatable."),
    views: Optional[list[str]] = typer.Option(None, "--view", help="all (default), map, local, signals or errors. Repeatable."),
    size: str = typer.Option("1600x900", "--size", help="Image size WIDTHxHEIGHT in pixels."),
    scenario: Optional[str] = typer.Option(None, "--scenario", help="Replay and render a scenario's test drives ('all' for every scenario): bundled ones, or the paper's runs with a data root."),
    outage: str = typer.Option("10s", "--outage", help="Outage length for --scenario replays."),
    estimator_names: Optional[str] = c.EstimatorsOpt,
    plugins: Optional[list[str]] = c.EstimatorOpt,
    timeout: str = typer.Option("120s", "--timeout", help="Longest wait for the viewer to start or load a recording."),
    data_root_opt: Optional[Path] = c.DataRoot,
) -> None:
    """Render PNG screenshots of recordings with a headless Rerun viewer (no display or GPU needed).

    Prints the path of every image written.
    """
    from .. import api
    from ..viz.screenshot import parse_size

    name_options(outage_s="--outage")
    width_height = parse_size(size)
    timeout_s = c.duration_s(timeout, "--timeout")
    if scenario is not None and recordings:
        raise typer.BadParameter("give recordings or --scenario, not both")
    if scenario is None and not recordings:
        raise typer.BadParameter("give at least one REC.rrd (or --scenario)", param_hint="REC.rrd")
    if scenario is None and (estimator_names is not None or plugins):
        raise typer.BadParameter("--estimators and --estimator choose what --scenario replays run", param_hint="--scenario")
    times = list(times or (["worst"] if scenario else ["end"]))
    views = list(views or ["all"])
    for rec in recordings or []:
        if not rec.is_file():
            raise InputError(f"{rec}: no such recording", "make one with 'ionav-viz replay DRIVE'")
    with tempfile.TemporaryDirectory(prefix="ionav-shots-") as tmp:
        rrds = list(recordings or [])
        if scenario is not None:
            outage_s = c.whole_seconds(outage, "--outage")
            ests = c.estimators(estimator_names, plugins, False, None)
            groups = api.scenario_drives(scenario, data_root_opt)
            print(f"drives: {groups.source}", file=sys.stderr)
            for group, specs in groups.items():
                for spec in specs:
                    rrd = Path(tmp) / f"{group}-{Path(spec).stem}.rrd"
                    rrds.append(api.replay(spec, outage_s, estimators=ests, output=rrd, data_root=data_root_opt).path)
        api.screenshot(rrds, output, times, views, width_height, timeout_s=timeout_s, progress=print)
