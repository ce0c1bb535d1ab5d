"""``ionav-viz replay``: one drive, GNSS outages, every estimator side by side, written to a ``.rrd``."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Optional

import typer

from ..viz.live import DEFAULT_CONNECT_URL, DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT
from . import common as c
from .app import app, log, options_named

if TYPE_CHECKING:
    from ..api.options import ReadOptions, RunOptions

#: The --help panel of the options that show the recording.
VIEWING = "Viewing it (viewer, browser)"

@app.command()
@c.with_source_options
@c.with_estimator_options
@c.with_placement_options
def replay(
    drive_specs: Optional[list[str]] = typer.Argument(None, metavar="DRIVE...",
                                                      help="A file or folder (IO-VNBD CSV, MCAP, ROS 1 .bag, ROS 2 "
                                                           "bag, KITTI raw), bundled scenario name or IO-VNBD run "
                                                           "name; several (a folder of drives, a glob, @list.txt): one "
                                                           "recording each, in parallel, into the folder -o."),
    outage: Optional[str] = c.OutageOrPlanOpt,
    plan: Optional[Path] = c.PlanOpt,
    external: Optional[list[str]] = c.ExternalOpt,
    export: Optional[Path] = c.ExportOpt,
    output: Optional[Path] = typer.Option(None, "-o", "--output",
                                          help="The .rrd file to write (default: recordings/<drive>.rrd in the current "
                                               "directory, made when missing; with --span "
                                               "recordings/<drive>-0s-60s.rrd or <drive>-60s-end.rrd; an existing file "
                                               "is replaced)."),
    open_viewer: bool = typer.Option(False, "--open", rich_help_panel=VIEWING,
                                     help="Open the Rerun viewer on the recording afterwards (needs a display)."),
    connect: Optional[str] = typer.Option(None, "--connect", rich_help_panel=VIEWING, metavar="[URL]",
                                          help="Also stream the recording to a running Rerun viewer (default "
                                               f"{DEFAULT_CONNECT_URL}, where 'rerun' listens)."),
    serve_web: bool = typer.Option(False, "--serve-web", rich_help_panel=VIEWING,
                                   help="Serve the recording to a browser (Rerun's web viewer) and print its address; "
                                        "runs until Ctrl-C."),
    grpc_port: int = typer.Option(DEFAULT_GRPC_PORT, "--grpc-port", rich_help_panel=VIEWING,
                                  help="--serve-web: the port of the recording's gRPC server."),
    web_port: int = typer.Option(DEFAULT_WEB_PORT, "--web-port", rich_help_panel=VIEWING,
                                 help="--serve-web: the port of the web viewer."),
    bind: str = typer.Option("127.0.0.1", "--bind", rich_help_panel=VIEWING, metavar="ADDRESS",
                      help="--serve-web: the address to listen on (default: this machine only; 0.0.0.0 opens the "
                           "recording to every network the machine is on)."),
    quiet: bool = c.QuietOpt,
    placement: c.PlacementArgs = None,  # --every, --at, --random, --seed, --on (c.with_placement_options)
    # RunOptions: --estimators, --estimator, --model, --no-idnn, --bias-from, --threshold (c.with_estimator_options)
    run: RunOptions | None = None,
    # ReadOptions: --data-root, --yaw-sign, log topics and stamps, --gnss-limit (c.with_source_options)
    read: ReadOptions | None = None,
    screenshot_dir: Optional[Path] = typer.Option(None, "--screenshot",
                                                  help="Also render review images (every view, at the worst outage) "
                                                       "into this directory."),
    workers: Optional[int] = c.WorkersOpt,
    cluster: Optional[str] = c.ClusterOpt,
    fail_fast: bool = c.FailFastOpt,
    fleet_rrd: Optional[Path] = c.FleetRrdOpt,
    runs: Optional[list[str]] = c.RunsOpt,
) -> None:
    """Replay a drive with GNSS outages, run the estimators side by side, and write a .rrd for review."""
    from .. import api
    from . import fleet

    drive_specs = list(drive_specs or [])
    if len(drive_specs) > 1 or fleet_rrd is not None or fleet.is_fleet_run(drive_specs, workers, cluster, fail_fast,
                                                                           # one recording per drive (cli/fleet.py)
                                                                           False, runs):
        refused = {"--plan": plan, "--external": external, "--export": export, "--open": open_viewer,
                   "--connect": connect, "--serve-web": serve_web, "--screenshot": screenshot_dir,
                   "--outage LENGTH,LENGTH": outage is not None and "," in outage}
        fleet.replay_fleet(drive_specs, output, outage, placement, run, read, workers=workers, cluster=cluster,
                           fail_fast=fail_fast, quiet=quiet, refused=refused, fleet_rrd=fleet_rrd, runs=runs)
        return
    if not drive_specs:
        raise typer.BadParameter("give a drive (or many, or --runs)", param_hint="DRIVE...")
    drive_spec = drive_specs[0]

    if outage is not None and "," in outage:
        for given, option in ((plan, "--plan"), (external, "--external"), (open_viewer or None, "--open"),
                              (connect, "--connect"), (serve_web or None, "--serve-web"),
                              (screenshot_dir, "--screenshot")):
            if given:
                raise typer.BadParameter(f"several outage lengths write one recording each, without {option}",
                                         param_hint="--outage")
        lengths = c.durations_of(outage, "--outage")
        with c.progress(quiet) as bar, options_named(outage_s=f"--outage {outage}", placement=placement.option):
            results = api.replay(api.Experiment(drive_spec, lengths, placement.placement, run=run, read=read),
                                 output=output, export=export, progress=c.progress_callback(bar, "writing"))
        if not quiet:
            from ..analysis.report import length_rows
            from ..analysis.tables import render_lengths

            reports = {r.report.results[0].outage_s: r.report for r in results}
            print(render_lengths(length_rows(reports), width=c.terminal_width(sys.stderr)), end="", file=sys.stderr)
        for r in results:
            print(r.path)
        return
    outage_s, chosen = c.outage_and_placement(outage, plan, placement)
    if screenshot_dir is not None:  # checked before any work, as the other outputs are
        from ..api.options import input_paths
        from ..core.fileio import check_output_folder, refuse_output_onto_input, refuse_output_onto_output

        with options_named(screenshot="--screenshot", output="-o", export="--export"):
            check_output_folder(screenshot_dir, param="screenshot")
            refuse_output_onto_output(output, screenshot_dir, param="screenshot", folder_is="the screenshot folder")
            refuse_output_onto_input(screenshot_dir,
                                     input_paths(drive_spec, read, run=run, plan=chosen,
                                                 external=c.externals_of(external)), param="screenshot")
    if open_viewer:
        _check_display()
    serving = None
    if serve_web:
        with options_named(grpc_port="--grpc-port", web_port="--web-port", bind="--bind"):
            serving = api.WebServing(grpc_port, web_port, bind)  # checked before any work
        if serving.public:
            log.warning("--bind %s: the served recording (the drive's positions) is reachable from every network this "
                        "machine is on", bind)
    with c.progress(quiet) as bar, options_named(outage_s=f"--outage {outage or '10s'}",
                                                 placement="--plan" if plan else placement.option):
        result = api.replay(api.Experiment(drive_spec, outage_s, chosen, run=run, read=read,
                                           external=c.externals_of(external)),
                            output=output, connect=connect, export=export, progress=c.progress_callback(bar, "writing"))
    if not quiet:
        print(result.report.to_text(c.terminal_width(sys.stderr)), end="", file=sys.stderr)
    print(result.path)
    if screenshot_dir is not None:
        from ..viz.blueprints import VIEWS, shown_views
        from ..viz.recording_info import read_recording_info

        # every view the recording has data for (the filter health only where an estimator reports one)
        has_health = "health" in shown_views(read_recording_info(result.path))
        views = [v for v in VIEWS if v != "health" or has_health]
        api.screenshot([result.path], screenshot_dir, api.Shots(times=["worst"], views=views), progress=print)
    if connect is not None and not quiet:
        print(f"streamed to the viewer at {connect}", file=sys.stderr)
    if open_viewer:
        _open_viewer(result.path)
    if serving is not None:
        _serve(api.serve_web(result, serving))


def _serve(server) -> None:
    """Print where to look and keep the servers up until Ctrl-C or SIGTERM (exit 130 / 143); the
    server process is stopped on the way out."""
    import time

    with server:
        print(f"serving the recording: open {server.web_url} in a browser (gRPC: {server.grpc_url}); Ctrl-C to stop",
              flush=True)
        while True:
            time.sleep(3600)


def _check_display() -> None:
    import os

    from ..core.errors import ToolFailure

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ToolFailure("--open: no display here (DISPLAY and WAYLAND_DISPLAY are unset); use --serve-web "
                          "to view the recording in a browser, or 'ionav-viz screenshot' for images")


def _open_viewer(path: Path) -> None:
    import shutil
    import subprocess

    from ..core.errors import ToolFailure

    exe = shutil.which("rerun")
    if exe is None:
        raise ToolFailure(f"--open: the 'rerun' viewer command is not on PATH; open {path} with the Rerun "
                          "viewer yourself")
    subprocess.Popen([exe, str(path)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


__all__ = ["log", "replay"]
