"""``ionav-viz replay``: one drive, GNSS outages, every estimator side by side, written to a ``.rrd``."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from ..viz.live import DEFAULT_CONNECT_URL
from . import common as c
from .app import app, log, name_options


def placement_of(every: Optional[str], at: Optional[str], random_count: Optional[int], seed: int, on: Optional[str]):
    """The outage placement the options choose (at most one of them), and the option that chose it."""
    from ..nav.outages import AroundEvents, At, Every, Random, Tile

    chosen = [o for o, v in (("--every", every), ("--at", at), ("--random", random_count), ("--on", on)) if v is not None]
    if len(chosen) > 1:
        raise typer.BadParameter(f"choose one outage placement, not {' and '.join(chosen)}")
    if on is not None:
        return AroundEvents(c.event_types(on)), f"--on {on}"
    if every is not None:
        return Every(c.whole_seconds(every, "--every", "outage period")), f"--every {every}"
    if at is not None:
        return At(tuple(_parse_times(at))), f"--at {at}"
    if random_count is not None:
        return Random(random_count, seed), f"--random {random_count}"
    return Tile(), "--outage"


def _parse_times(text: str) -> list[float]:
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if not parts:
        raise typer.BadParameter(f"{text!r}: give start times like 12s,40s", param_hint="--at")
    return [0.0 if p in ("0", "0s") else c.duration_s(p, "--at") for p in parts]


@app.command()
@c.with_source_options
@c.with_estimator_options
def replay(
    drive_spec: str = typer.Argument(..., metavar="DRIVE", help="A file or folder (IO-VNBD CSV, MCAP, ROS 1 .bag, ROS 2 bag, KITTI raw), bundled scenario name or IO-VNBD run name."),
    outage: str = c.OutageOpt,
    every: Optional[str] = typer.Option(None, "--every", help="Start an outage every PERIOD (GNSS available in between), e.g. 30s."),
    at: Optional[str] = typer.Option(None, "--at", help="Start outages at these times, e.g. 12s,40s."),
    random_count: Optional[int] = typer.Option(None, "--random", help="Draw N non-overlapping outages at random."),
    seed: int = typer.Option(0, "--seed", help="Seed for --random."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="The .rrd file to write (default: recordings/<drive>.rrd in the current directory, made when missing; an existing file is replaced)."),
    open_viewer: bool = typer.Option(False, "--open", help="Open the Rerun viewer on the recording afterwards (needs a display)."),
    connect: Optional[str] = typer.Option(None, "--connect", metavar="[URL]", help=f"Also stream the recording to a running Rerun viewer (default {DEFAULT_CONNECT_URL}, where 'rerun' listens)."),
    serve_web: bool = typer.Option(False, "--serve-web", help="Serve the recording to a browser (Rerun's web viewer) and print its address; runs until Ctrl-C."),
    grpc_port: int = typer.Option(9876, "--grpc-port", help="--serve-web: the port of the recording's gRPC server."),
    web_port: int = typer.Option(9090, "--web-port", help="--serve-web: the port of the web viewer."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar and no summary."),
    run: c.EstimatorArgs = None,  # --estimators, --estimator, --model, --no-idnn, --bias-from (c.with_estimator_options)
    source: c.SourceArgs = None,  # --data-root, --yaw-sign, MCAP topics and stamps (c.with_source_options)
    screenshot_dir: Optional[Path] = typer.Option(None, "--screenshot", help="Also render review images (every view, at the worst outage) into this directory."),
    on: Optional[str] = typer.Option(None, "--on", help="One outage centred on each detected event of these types, e.g. hard-brake,roundabout (see 'ionav-viz events')."),
    thresholds: Optional[list[str]] = c.Thresholds,
) -> None:
    """Replay a drive with GNSS outages, run the estimators side by side, and write a .rrd for review."""
    from .. import api

    outage_s = c.whole_seconds(outage, "--outage")
    placement, option = placement_of(every, at, random_count, seed, on)
    name_options(outage_s=f"--outage {outage}", placement=option)
    if output is not None and output.suffix.lower() != ".rrd":
        raise typer.BadParameter(f"{output}: the output must end in .rrd", param_hint="-o")
    if open_viewer:
        _check_display()
    with c.progress(quiet) as bar:
        result = api.replay(drive_spec, outage_s, placement, output=output, thresholds=c.thresholds(thresholds),
                            **run.api_kwargs(), **source.api_kwargs(), connect=connect,
                            progress=c.progress_callback(bar, "writing"))
    if not quiet:
        print(result.report.to_text(), end="", file=sys.stderr)
    print(result.path)
    if screenshot_dir is not None:
        from ..viz.screenshot import VIEWS

        api.screenshot([result.path], screenshot_dir, ["worst"], list(VIEWS), (1600, 900), progress=print)
    if connect is not None and not quiet:
        print(f"streamed to the viewer at {connect}", file=sys.stderr)
    if open_viewer:
        _open_viewer(result.path)
    if serve_web:
        _serve(api.serve_web(result, grpc_port=grpc_port, web_port=web_port))


def _serve(server) -> None:
    """Print where to look and keep the servers up until Ctrl-C or SIGTERM (exit 130 / 143)."""
    import time

    print(f"serving the recording: open {server.web_url} in a browser (gRPC: {server.grpc_url}); Ctrl-C to stop", flush=True)
    while True:
        time.sleep(3600)


def _check_display() -> None:
    import os

    from ..core.errors import ToolFailure

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ToolFailure("--open: no display here (DISPLAY and WAYLAND_DISPLAY are unset); use --serve-web to view the "
                          "recording in a browser, or 'ionav-viz screenshot' for images")


def _open_viewer(path: Path) -> None:
    import shutil
    import subprocess

    from ..core.errors import ToolFailure

    exe = shutil.which("rerun")
    if exe is None:
        raise ToolFailure(f"--open: the 'rerun' viewer command is not on PATH; open {path} with the Rerun viewer yourself")
    subprocess.Popen([exe, str(path)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


__all__ = ["log", "placement_of", "replay"]
