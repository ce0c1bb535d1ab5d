"""Replaying a drive to a ``.rrd`` recording, a scenario's drives, and serving a recording to browsers."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from ..analysis.evaluate import DriveResult
from ..analysis.events import Event, detect_events
from ..analysis.report import Report, overview_markdown, run_summary_markdown
from ..core.durations import Span
from ..core.errors import InputError
from ..core.fileio import check_output_file, check_output_folder, refuse_output_onto_input, refuse_output_onto_output
from ..core.timing import stage
from ..core.warnings_log import collecting_warnings
from ..experiment.outages import Placement
from ..nav.windows import make_windows
from ..sources.load import ReadOptions, load_drive
from ..viz.live import WebServing
from .evaluate import scenario_drives, write_exports
from .experiment import Experiment
from .options import (
    DriveLike,
    Progress,
    RunOptions,
    each_length,
    input_paths,
    log,
    no_outage_fits,
    placement_of,
    refuse_export_onto_inputs,
    too_short,
    windows_of,
    with_externals,
)
from .pipeline import plan_drive, score

#: Where :func:`replay` writes ``<drive>.rrd`` by default, relative to the current directory.
RECORDINGS_DIR = "recordings"


def default_stem(name: str, span: Span | None) -> str:
    """The default recording's name before ``.rrd``: the drive's name, and with ``--span`` the
    span (``<drive>-0s-60s``, ``<drive>-60s-end``), so that two spans of a drive are two files."""
    if span is None:
        return name
    return f"{name}-{span.start_s:g}s-" + ("end" if span.end_s is None else f"{span.end_s:g}s")


@dataclass(frozen=True)
class Outage:
    """One GNSS outage of a replay: its number (from 1), start and end (s since the drive's start)."""

    number: int
    start_s: float
    end_s: float
    first_window: int


@dataclass(repr=False)
class ReplayResult:
    """What :func:`replay` produced: the written recording, the report and the outages."""

    path: Path
    report: Report
    outages: list[Outage]
    placement: str
    result: DriveResult
    events: list[Event] = field(default_factory=list)

    def __repr__(self) -> str:
        return (f"ReplayResult({str(self.path)!r}\n  drive: {self.result.drive.name}, {len(self.outages)} outage(s): "
                f"{self.placement}\n  {self.report.summary_line()}\n)")



def replay_single(exp: Experiment, output: str | Path | None, progress: Progress | None, connect: str | None,
                export: str | Path | None) -> ReplayResult:
    """One drive at one outage length into one recording."""
    from ..viz import live

    if connect is not None:
        live.check_viewer(connect)
    out = Path(output) if output is not None else None
    if out is not None and out.suffix.lower() != ".rrd":
        raise InputError(f"{out}: a recording must end in .rrd", "choose a name like drive.rrd", param="output")
    drive = exp.drives[0]
    placement = placement_of(exp.placement, exp.plan)
    n = windows_of(exp.outage_s, placement)
    run, read = exp.options()
    run = with_externals(run, exp.external, placement)
    inputs = input_paths(drive, read, run=run, plan=placement, external=exp.external)
    refuse_output_onto_input(out, inputs)
    if export is not None:
        check_output_folder(Path(export), param="export")
        refuse_export_onto_inputs(export, inputs)
        refuse_output_onto_output(out, export, param="export", replaced=["tum"])
    run.chosen()
    with collecting_warnings() as warned:
        replayed = _replay(drive, n, placement, out, run, read, progress, connect, warned, export)
    if export is not None:
        write_exports(replayed.report.results, export)
    return replayed


def _replay(drive: DriveLike, n: int, placement: Placement, out: Path | None, run: RunOptions, read: ReadOptions,
            progress: Progress | None, connect: str | None, warned: list[str],
            export: str | Path | None = None) -> ReplayResult:
    from ..core.fileio import atomic_path
    from ..viz import live
    from ..viz.recording import write_recording

    d = load_drive(drive, read)
    with stage("windows") as s:
        windows = make_windows(d)
        s.detail = f"{len(windows)} of 1 s"
    with stage("manoeuvres") as s:
        events = detect_events(d, run.thresholds)
        s.detail = f"{len(events)} detected"
    planned = plan_drive(d, placement, n, run, events, windows)
    plan = planned.plan
    if len(plan.starts) == 0 and not plan.gnss_gaps:
        if plan.excluded:
            raise no_outage_fits([d], n, d.source)
        raise too_short(d, n, run, read)
    default = out is None
    out = check_output_file(Path(RECORDINGS_DIR, f"{default_stem(d.name, read.span)}.rrd") if default else out,
                            create_parent=default)  # before the work
    refuse_output_onto_output(out, export, param="export", replaced=["tum"])  # the default name is known only now
    chosen = run.applying_to([d])
    result = score(planned, chosen, run.bias_of(read)(d))
    report = Report([result], warnings=warned)  # what was warned so far: reading, planning, estimating
    summary = _summary_markdown(result, report, plan.description)
    total = 5 + len(result.estimates)
    done = [0]

    def advance(label: str) -> None:
        done[0] += 1
        if progress:
            progress(f"{out.name}: {label}", done[0], total)

    with stage(f"write {out}") as s, atomic_path(out, create_parent=default) as tmp:
        rows = write_recording(result, summary, tmp, progress=advance, target=out, events=events,
                               report_json=report.to_json(indent=None), overview_md=overview_markdown(result, report))
        s.detail = f"{len(rows)} entities, {sum(rows.values())} rows"
    if connect is not None:
        with stage(f"stream to {connect}"):
            live.send_recording(out, connect)
    outages = [Outage(i + 1, float(windows.t0_s[k]), float(windows.t0_s[k] + n), int(k))
               for i, k in enumerate(plan.starts)]
    return ReplayResult(out, report, outages, plan.description, result, events)




def replay_each_length(exp: Experiment, output: str | Path | None, progress: Progress | None,
                    export: str | Path | None) -> list[ReplayResult]:
    """Each of ``exp``'s outage lengths on its one drive, read once: one recording per length,
    ``OUTPUT-<length>s.rrd`` (default ``recordings/<drive>-<length>s.rrd``), and with ``export``
    one folder ``EXPORT/<length>s`` each."""
    if output is not None and Path(output).suffix.lower() != ".rrd":
        raise InputError(f"{output}: a recording must end in .rrd", "choose a name like drive.rrd", param="output")
    _, read = exp.options()
    d = load_drive(exp.drives[0], read)  # read once, replayed for every length

    def one(length: float) -> ReplayResult:
        stem = Path(output).stem if output is not None else default_stem(d.name, read.span)
        name = f"{stem}-{length:g}s.rrd"
        target = Path(output).with_name(name) if output is not None else Path(RECORDINGS_DIR, name)
        return replay_single(replace(exp, drives=(d,), outage_s=length), target, progress, None,
                           None if export is None else Path(export) / f"{length:g}s")

    return [result for _, result in each_length(exp.lengths_s, one)]


def replay_scenario_drives(exp: Experiment, folder: str | Path) -> list[Path]:
    """Every test drive of ``exp.scenario`` into ``folder`` as ``<scenario>-<drive>.rrd``; the paths."""
    groups = scenario_drives(exp.scenario, exp.read.data_root)
    log.info("drives: %s", groups.source)
    return [replay_single(replace(exp, drives=(spec,), scenario=None), Path(folder) / f"{group}-{Path(spec).stem}.rrd",
                        None, None, None).path
            for group, specs in groups.items() for spec in specs]


def _summary_markdown(result: DriveResult, report: Report, description: str) -> str:
    """The recording's summary document: the run, the worst outages and the paper's table."""
    return run_summary_markdown(result, report, description) + "\n" + report.to_markdown()


def serve_web(replayed: ReplayResult, serving: WebServing | None = None):
    """Serve a replay's recording to browsers: a :class:`ionav_viz.viz.live.WebServer` to use with
    ``with`` (the servers run inside it), whose ``web_url`` to open. ``serving``: a
    :class:`WebServing` (ports and bind address; default the loopback address and Rerun's ports)."""
    from ..viz import live

    return live.serve_web(replayed.path, serving)

