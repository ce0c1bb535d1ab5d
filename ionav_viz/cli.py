"""The ``ionav-viz`` command line: parses options and wires sources, navigation and outputs.

Heavy libraries (numpy, torch, pyproj, rerun) are imported inside the commands so that
``ionav-viz --help`` answers at once. Every known input problem is an
:class:`~ionav_viz.errors.InputError`, printed by :func:`main` as one line with exit code 2
(a traceback only with ``--debug``); Ctrl-C exits with 130.
"""

from __future__ import annotations

import json
import logging
import math
import re
import sys
from pathlib import Path
from typing import Any, Optional

import typer

from .errors import InputError, ToolFailure

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Replay drives, inject GNSS outages, and compare INS dead reckoning with the IDNN in Rerun.",
)
log = logging.getLogger("ionav_viz")

_DURATION = re.compile(r"^\s*(?:(\d+(?:\.\d+)?)h)?\s*(?:(\d+(?:\.\d+)?)m(?!s))?\s*(?:(\d+(?:\.\d+)?)s)?\s*(?:(\d+(?:\.\d+)?)ms)?\s*$")


def parse_duration_s(text: str, option: str = "duration") -> float:
    """``'10s'``, ``'500ms'``, ``'1m'``, ``'1m30s'``, ``'2h'`` or a plain number of seconds -> seconds."""
    value = str(text).strip().lower()
    try:
        seconds = float(value)
    except ValueError:
        match = _DURATION.match(value)
        if not value or not match or not any(match.groups()):
            raise typer.BadParameter(f"{text!r} is not a duration; use e.g. 10s, 500ms, 1m", param_hint=option) from None
        h, m, s, ms = (float(g) if g else 0.0 for g in match.groups())
        seconds = h * 3600 + m * 60 + s + ms / 1000
    if not math.isfinite(seconds) or seconds <= 0:
        raise typer.BadParameter(f"{text!r} must be a positive duration", param_hint=option)
    return seconds


class _StderrHandler(logging.Handler):
    def emit(self, record: logging.LogRecord) -> None:
        prefix = "warning: " if record.levelno >= logging.WARNING else ""
        print(prefix + record.getMessage(), file=sys.stderr)


def _setup_logging(verbose: bool = False) -> None:
    import os

    # Rerun's native logger writes to stderr; our own one-line errors say what failed.
    if not verbose and "--debug" not in sys.argv:
        os.environ.setdefault("RUST_LOG", "off")
    log.handlers[:] = [_StderrHandler()]
    log.setLevel(logging.INFO if verbose else logging.WARNING)
    log.propagate = False


def _print_version(value: bool) -> None:
    if value:
        from . import __version__

        print(f"ionav-viz {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    debug: bool = typer.Option(False, "--debug", help="Show full tracebacks on errors."),
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Say more about what is read and assumed."),
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True, help="Print the version and exit."),
) -> None:
    _setup_logging(verbose)


DataRoot = typer.Option(None, "--data-root", help="IO-VNBD checkout to find run names in (default: $IONAV_DATA).", show_default=False)
YawSign = typer.Option("auto", "--yaw-sign", help="Sign of the CSV yaw-rate column: auto (checked against the GNSS heading), cw or ccw positive.")
ImuTopic = typer.Option(None, "--imu-topic", help="MCAP: the IMU topic (default: the one sensor_msgs/msg/Imu channel).", show_default=False)
GnssTopic = typer.Option(None, "--gnss-topic", help="MCAP: the GNSS topic (default: the one NavSatFix or LocationFix channel).", show_default=False)
SpeedTopic = typer.Option(None, "--speed-topic", help="MCAP: a TwistStamped or Odometry topic for speed (optional).", show_default=False)
Stamps = typer.Option("header", "--stamps", help="MCAP: time stamps from message headers (header) or the recorder's log time (log).")


OutageOpt = typer.Option("10s", "--outage", help="Length of each GNSS outage (whole seconds).")
ModelOpt = typer.Option(None, "--model", help="IDNN model directory (default: the shipped model).", show_default=False)
NoIdnnOpt = typer.Option(False, "--no-idnn", help="INS only, no IDNN.")
BiasFromOpt = typer.Option(None, "--bias-from", help="Stationary drive for sensor biases (default: the drive's own stationary stretches).", show_default=False)
Thresholds = typer.Option(None, "--threshold", help="Override an event-detector threshold, e.g. hard_brake_g=0.4 (repeatable; see 'ionav-viz events --help').", show_default=False)


def _thresholds(pairs: Optional[list[str]]):
    from .events import EventThresholds

    return EventThresholds().with_overrides(list(pairs or []))


def _event_types(text: str) -> tuple[str, ...]:
    from .events import EVENT_TYPES

    kinds = tuple(k.strip() for k in text.split(",") if k.strip())
    unknown = [k for k in kinds if k not in EVENT_TYPES]
    if unknown or not kinds:
        raise typer.BadParameter(f"unknown event type(s) {', '.join(unknown) or text!r}; choose from {', '.join(EVENT_TYPES)}", param_hint="--on")
    return kinds


def _mcap_options(imu_topic, gnss_topic, speed_topic, stamps):
    from .sources import McapOptions

    if stamps not in ("header", "log"):
        raise typer.BadParameter(f"{stamps!r}: choose header or log", param_hint="--stamps")
    return McapOptions(imu_topic, gnss_topic, speed_topic, stamps)


def _json_safe(obj: Any) -> Any:
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    return obj


@app.command()
def simulate(
    scenario: Optional[str] = typer.Argument(None, help="motorway, roundabout, quick-accel, hard-brake, sharp-cornering or stationary."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="The V-*.csv file to write."),
    seed: int = typer.Option(0, "--seed", help="Random seed; the same seed gives the same bytes."),
    duration: str = typer.Option("120s", "--duration", help="Length of the drive, e.g. 120s or 5m."),
    ideal: bool = typer.Option(False, "--ideal", help="Perfect sensors and flat roads (for checks)."),
    bundled: Optional[Path] = typer.Option(None, "--bundled", help="Regenerate every bundled sample into this directory instead."),
) -> None:
    """Write a synthetic drive in the exact IO-VNBD V-*.csv format."""
    from .samples import SAMPLES
    from .simulate import SCENARIOS, SensorModel, write_simulated_drive

    if bundled is not None:
        bundled.mkdir(parents=True, exist_ok=True)
        for sample in SAMPLES:
            write_simulated_drive(bundled / sample.file, sample.scenario, sample.seed, sample.duration_s)
            print(bundled / sample.file)
        return
    if scenario is None or output is None:
        raise typer.BadParameter("give a SCENARIO and -o FILE.csv (or --bundled DIR)")
    if scenario not in SCENARIOS:
        raise typer.BadParameter(f"unknown scenario {scenario!r}; choose one of {', '.join(SCENARIOS)}", param_hint="SCENARIO")
    seconds = parse_duration_s(duration, "--duration")
    path = write_simulated_drive(output, scenario, seed, seconds, SensorModel.ideal() if ideal else None)
    print(path)


def _load_model(model: Optional[Path], no_idnn: bool):
    if no_idnn:
        return None
    from .idnn import default_model_dir, load_model

    directory = model if model is not None else default_model_dir()
    if model is None and not (directory / "metadata.json").is_file():
        log.warning("no shipped IDNN model at %s; evaluating INS only (train one with 'ionav-viz train')", directory)
        return None
    return load_model(directory)


def _scenario_specs(scenario: str, root: Optional[Path]) -> dict[str, list[str]]:
    from .catalog import PAPER_TEST_RUNS, SCENARIOS
    from .samples import by_scenario

    names = SCENARIOS if scenario == "all" else (scenario,)
    if scenario != "all" and scenario not in SCENARIOS:
        raise typer.BadParameter(f"unknown scenario {scenario!r}; choose {', '.join(SCENARIOS)} or all", param_hint="--scenario")
    if root is not None:
        return {s: list(PAPER_TEST_RUNS[s]) for s in names}
    return {s: [sample.file for sample in by_scenario(s)] for s in names}


@app.command()
def evaluate(
    drives: Optional[list[str]] = typer.Argument(None, help="Drives: file paths, bundled scenario names or IO-VNBD run names."),
    outage: str = OutageOpt,
    scenario: Optional[str] = typer.Option(None, "--scenario", help="Evaluate a scenario's test drives: the paper's runs with a data root, else the bundled ones; 'all' for every scenario."),
    as_json: bool = typer.Option(False, "--json", help="Print the results as JSON."),
    markdown: bool = typer.Option(False, "--markdown", help="Print the tables as Markdown."),
    overview: bool = typer.Option(False, "--overview", help="One line per scenario (means and improvement) instead of full tables."),
    by_event: bool = typer.Option(False, "--by-event", help="Tables per manoeuvre type: one outage centred on each detected event, across all the drives."),
    on: Optional[str] = typer.Option(None, "--on", help="With --by-event: only these event types (default: all)."),
    thresholds: Optional[list[str]] = Thresholds,
    model: Optional[Path] = ModelOpt,
    no_idnn: bool = NoIdnnOpt,
    bias_from: Optional[str] = BiasFromOpt,
    data_root_opt: Optional[Path] = DataRoot,
    yaw_sign: str = YawSign,
    imu_topic: Optional[str] = ImuTopic,
    gnss_topic: Optional[str] = GnssTopic,
    speed_topic: Optional[str] = SpeedTopic,
    stamps: str = Stamps,
) -> None:
    """Evaluate INS dead reckoning (and the IDNN) on consecutive GNSS outages, as the paper does."""
    from .evaluate import evaluate_drive, report, resolve_bias
    from .resolve import data_root
    from .sources import load_drive
    from .tables import render_markdown, render_overview, render_text

    outage_s = parse_duration_s(outage, "--outage")
    root = data_root(data_root_opt)
    mcap = _mcap_options(imu_topic, gnss_topic, speed_topic, stamps)
    if scenario is not None and drives:
        raise typer.BadParameter("give drives or --scenario, not both")
    groups = _scenario_specs(scenario, root) if scenario else {None: list(drives or [])}
    if not any(groups.values()):
        raise typer.BadParameter("give at least one drive (or --scenario)", param_hint="DRIVES")
    idnn = _load_model(model, no_idnn)
    stationary = load_drive(bias_from, root, yaw_sign, mcap) if bias_from else None

    reports: dict[Any, dict] = {}
    if by_event:
        reports = _reports_by_event([s for specs in groups.values() for s in specs], outage_s, on, thresholds, root,
                                    yaw_sign, mcap, stationary, idnn)
    for group, specs in ({} if by_event else groups).items():
        results = []
        for spec in specs:
            drive = load_drive(spec, root, yaw_sign, mcap)
            bias = resolve_bias(drive, stationary)
            res = evaluate_drive(drive, outage_s, bias=bias, model=idnn)
            if len(res.starts) == 0:
                log.warning("%s: too short for a single %g s outage; skipped", drive.name, outage_s)
                continue
            results.append(res)
        if not results:
            raise InputError(f"no {outage_s:g} s outage fits in {', '.join(specs)}", "use a shorter --outage")
        reports[group] = report(results)

    if as_json:
        out = reports[None] if None in reports else {"by_event" if by_event else "scenarios": reports}
        print(json.dumps(_json_safe(out), indent=2))
        return
    if overview:
        print(render_overview(reports, markdown, "Manoeuvre" if by_event else "Scenario"), end="")
        return
    render = render_markdown if markdown else render_text
    print("\n".join(render(rep, group) for group, rep in reports.items()), end="")


@app.command()
def train(
    drives: Optional[list[str]] = typer.Argument(None, help="Training drives (default: the bundled synthetic training drives)."),
    output: Path = typer.Option(Path("models/idnn"), "-o", "--output", help="Model directory to write (weights + metadata.json)."),
    paper_train: bool = typer.Option(False, "--paper-train", help="Train on the paper's Table 1 runs under the data root."),
    arch: str = typer.Option("idnn", "--arch", help="idnn (the paper's), mlp, rnn, gru or lstm (Section 3.3)."),
    steps: int = typer.Option(10, "--steps", help="Time steps (10 Hz samples) of acceleration per displacement input (Table 4; 10 = 1 s, 20 = 2 s)."),
    steps_yaw: int = typer.Option(10, "--steps-yaw", help="Time steps of gyro yaw rate per orientation-rate input (Table 3)."),
    epochs_disp: int = typer.Option(40, "--epochs-disp", help="Epochs of the displacement model (Table 5: 40)."),
    epochs_yaw: int = typer.Option(60, "--epochs-yaw", help="Epochs of the orientation-rate model (Table 5: 60)."),
    feedback_noise: float = typer.Option(0.1, "--feedback-noise", help="Std (m) of the white noise on the fed-back GNSS displacement in training."),
    residual: bool = typer.Option(True, "--residual/--no-residual", help="Kinematic skip terms (see README); --no-residual is the paper's plain net."),
    lr_decay_tail: float = typer.Option(0.3, "--lr-decay-tail", help="Fraction of the training over which the learning rate falls linearly to 0 at the end (0 = constant, as in the paper)."),
    seed: int = typer.Option(0, "--seed", help="Random seed (training is deterministic on the CPU)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    bias_from: Optional[str] = BiasFromOpt,
    data_root_opt: Optional[Path] = DataRoot,
    yaw_sign: str = YawSign,
    imu_topic: Optional[str] = ImuTopic,
    gnss_topic: Optional[str] = GnssTopic,
    speed_topic: Optional[str] = SpeedTopic,
    stamps: str = Stamps,
) -> None:
    """Train the displacement and orientation-rate networks and write them with their metadata."""
    from .catalog import PAPER_TRAIN_RUNS
    from .evaluate import resolve_bias
    from .idnn import ModelConfig, save_model
    from .resolve import data_root
    from .samples import SAMPLES, sample_path
    from .sources import load_drive
    from .training import train_models

    root = data_root(data_root_opt)
    mcap = _mcap_options(imu_topic, gnss_topic, speed_topic, stamps)
    if paper_train:
        if root is None:
            raise InputError("--paper-train needs the IO-VNBD data", "pass --data-root DIR or set IONAV_DATA")
        specs, description = list(PAPER_TRAIN_RUNS), "the paper's IO-VNBD training runs (Table 1)"
    elif drives:
        specs, description = list(drives), "user-given drives"
    else:
        specs = [str(sample_path(s)) for s in SAMPLES if s.role == "train"]
        description = "the bundled synthetic training drives (recordings/samples/V-sim-*-train-*.csv), not real data"
    config = ModelConfig(arch=arch, n_steps_disp=steps, n_steps_yaw=steps_yaw, epochs_disp=epochs_disp,
                         epochs_yaw=epochs_yaw, feedback_noise_m=feedback_noise, residual=residual,
                         lr_decay_tail=lr_decay_tail, seed=seed)
    config.validate()
    if epochs_disp < 1 or epochs_yaw < 1:
        raise typer.BadParameter("epochs must be at least 1")
    stationary = load_drive(bias_from, root, yaw_sign, mcap) if bias_from else None
    loaded = []
    for spec in specs:
        drive = load_drive(spec, root, yaw_sign, mcap)
        loaded.append((drive, resolve_bias(drive, stationary)))

    with _progress(quiet) as bar:
        tasks: dict[str, Any] = {}

        def progress(label: str, done: int, total: int) -> None:
            if bar is None:
                return
            if label not in tasks:
                tasks[label] = bar.add_task(f"training {label}", total=total)
            bar.update(tasks[label], completed=done)

        model = train_models(loaded, config, progress=progress, description=description)
    model.metadata["training"]["command"] = "ionav-viz " + " ".join(sys.argv[1:])
    save_model(model, output)
    val = model.metadata["validation"]
    params = model.metadata["trainable_parameters"]
    print(f"trained {arch} on {len(loaded)} drive(s), {model.metadata['training']['n_examples']} windows; "
          f"trainable parameters: displacement {params['displacement']}, orientation rate {params['yaw_rate']}", file=sys.stderr)
    print(f"validation MAE: displacement {val['disp_mae_m']:.3f} m, orientation rate {val['yaw_rate_mae_radps']:.4f} rad/s", file=sys.stderr)
    print(output)


@app.command()
def architectures(
    steps: int = typer.Option(10, "--steps", help="Time steps per input."),
) -> None:
    """Trainable parameters of each network per hidden width, laid out like the paper's Table 2."""
    from .idnn import ARCHS, build_net, count_parameters

    widths = (8, 16, 32, 64, 128, 192, 256, 320)
    print("hidden units  " + "  ".join(f"{a.upper():>8}" for a in ARCHS) + "   (displacement model, with feedback input)")
    for width in widths:
        counts = [count_parameters(build_net(a, steps, width, 0.1, True)) for a in ARCHS]
        print(f"{width:>12}  " + "  ".join(f"{c:>8,}" for c in counts))


def _parse_times(text: str) -> list[float]:
    try:
        return [parse_duration_s(part, "--at") if part.strip() not in ("0", "0s") else 0.0 for part in text.split(",") if part.strip()]
    except typer.BadParameter:
        raise
    except Exception:
        raise typer.BadParameter(f"{text!r}: give start times like 12s,40s", param_hint="--at") from None


def _progress(quiet: bool):
    """A rich progress bar on stderr, or a no-op when quiet or not a terminal."""
    from contextlib import nullcontext

    if quiet or not sys.stderr.isatty():
        return nullcontext(None)
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                    TimeElapsedColumn(), console=Console(stderr=True), transient=True)


@app.command()
def replay(
    drive_spec: str = typer.Argument(..., metavar="DRIVE", help="A file path, bundled scenario name or IO-VNBD run name."),
    outage: str = OutageOpt,
    every: Optional[str] = typer.Option(None, "--every", help="Start an outage every PERIOD (GNSS available in between), e.g. 30s."),
    at: Optional[str] = typer.Option(None, "--at", help="Start outages at these times, e.g. 12s,40s."),
    random_count: Optional[int] = typer.Option(None, "--random", help="Draw N non-overlapping outages at random."),
    seed: int = typer.Option(0, "--seed", help="Seed for --random."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="The .rrd file to write (default: recordings/<drive>.rrd; an existing file is replaced)."),
    open_viewer: bool = typer.Option(False, "--open", help="Open the Rerun viewer on the recording afterwards."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar and no summary."),
    model: Optional[Path] = ModelOpt,
    no_idnn: bool = NoIdnnOpt,
    bias_from: Optional[str] = BiasFromOpt,
    data_root_opt: Optional[Path] = DataRoot,
    yaw_sign: str = YawSign,
    imu_topic: Optional[str] = ImuTopic,
    gnss_topic: Optional[str] = GnssTopic,
    speed_topic: Optional[str] = SpeedTopic,
    stamps: str = Stamps,
    screenshot_dir: Optional[Path] = typer.Option(None, "--screenshot", help="Also render review images (every view, at the worst outage) into this directory."),
    on: Optional[str] = typer.Option(None, "--on", help="One outage centred on each detected event of these types, e.g. hard-brake,roundabout (see 'ionav-viz events')."),
    thresholds: Optional[list[str]] = Thresholds,
) -> None:
    """Replay a drive with GNSS outages, run INS and IDNN side by side, and write a .rrd for review."""
    mcap = _mcap_options(imu_topic, gnss_topic, speed_topic, stamps)
    out = _replay_drive(drive_spec, outage, every, at, random_count, seed, output, quiet, model, no_idnn, bias_from,
                        data_root_opt, yaw_sign, mcap, on, thresholds)
    print(out)
    if screenshot_dir is not None:
        from .screenshot import VIEWS, render

        render([out], screenshot_dir, ["worst"], list(VIEWS), (1600, 900), progress=print)
    if open_viewer:
        _open_viewer(out)


def _replay_drive(drive_spec: str, outage: str, every: Optional[str], at: Optional[str], random_count: Optional[int],
                  seed: int, output: Optional[Path], quiet: bool, model: Optional[Path], no_idnn: bool,
                  bias_from: Optional[str], data_root_opt: Optional[Path], yaw_sign: str, mcap=None,
                  on: Optional[str] = None, thresholds: Optional[list[str]] = None) -> Path:
    """Everything ``replay`` does up to the written ``.rrd``; returns its path."""
    from . import outages as place
    from .evaluate import evaluate_drive, report, resolve_bias
    from .fileio import atomic_path
    from .resolve import data_root
    from .samples import recordings_dir
    from .sources import load_drive
    from .tables import render_markdown, render_text
    from .events import detect_events
    from .windows import make_windows

    outage_s = parse_duration_s(outage, "--outage")
    chosen = [o for o, v in (("--every", every), ("--at", at), ("--random", random_count), ("--on", on)) if v is not None]
    if len(chosen) > 1:
        raise typer.BadParameter(f"choose one outage placement, not {' and '.join(chosen)}")
    n = place.outage_windows(outage_s)
    root = data_root(data_root_opt)
    if output is not None and output.suffix.lower() != ".rrd":
        raise typer.BadParameter(f"{output}: the output must end in .rrd", param_hint="-o")

    drive = load_drive(drive_spec, root, yaw_sign, mcap)
    windows = make_windows(drive)
    events = detect_events(drive, _thresholds(thresholds))
    if on is not None:
        kinds = _event_types(on)
        targets = [e for e in events if e.type in kinds]
        starts, used = place.around(windows, [(e.t0_s, e.t1_s) for e in targets], n)
        if len(used) < len(targets):
            log.warning("%s: %d of %d %s event(s) got no outage (overlapping another, or too near a gap or an end)",
                        drive.name, len(targets) - len(used), len(targets), "/".join(kinds))
        placement = f"one {outage_s:g} s outage centred on each {', '.join(kinds)} event ({len(used)} of {len(targets)})"
        if len(starts) == 0:
            raise InputError(f"{drive.source}: no {' or '.join(kinds)} event with room for a {outage_s:g} s outage",
                             f"see 'ionav-viz events {drive_spec}'")
    elif every is not None:
        period = parse_duration_s(every, "--every")
        starts = place.every(windows, n, place.outage_windows(period))
        placement = f"a {outage_s:g} s outage every {period:g} s"
    elif at is not None:
        times = _parse_times(at)
        starts = place.at(windows, times, n)
        placement = f"{outage_s:g} s outages at {', '.join(f'{x:g} s' for x in times)}"
    elif random_count is not None:
        starts = place.random(windows, n, random_count, seed)
        placement = f"{random_count} random {outage_s:g} s outages (seed {seed})"
    else:
        starts = place.tile(windows, n)
        placement = f"consecutive {outage_s:g} s outages (the paper's protocol)"
    if len(starts) == 0:
        raise InputError(f"{drive.source}: drive too short ({drive.duration_s:.1f} s) for a {outage_s:g} s outage", "use a shorter --outage")

    idnn = _load_model(model, no_idnn)
    stationary = load_drive(bias_from, root, yaw_sign, mcap) if bias_from else None
    bias = resolve_bias(drive, stationary)
    result = evaluate_drive(drive, outage_s, bias=bias, model=idnn, starts=starts, windows=windows)
    rep = report([result])
    out = output if output is not None else recordings_dir() / f"{drive.name}.rrd"
    summary = summary_markdown(rep, drive, placement, bias, idnn.describe() if idnn else None) + "\n" + render_markdown(rep)

    from .rerun_log import write_recording

    with _progress(quiet) as bar:
        steps = 5 + len(result.estimates)
        task = bar.add_task(f"writing {out.name}", total=steps) if bar else None

        def advance(label: str) -> None:
            if bar is not None:
                bar.update(task, advance=1, description=f"{out.name}: {label}")

        with atomic_path(out) as tmp:
            rows = write_recording(result, summary, tmp, progress=advance, target=out, events=events)
    if not quiet:
        print(render_text(rep), end="", file=sys.stderr)
    log.info("%d entities, %d rows", len(rows), sum(rows.values()))
    return out


@app.command()
def screenshot(
    recordings: Optional[list[Path]] = typer.Argument(None, metavar="[REC.rrd]...", help="Recordings made by 'ionav-viz replay'."),
    output: Path = typer.Option(..., "-o", "--output", help="OUT.png for one image, else a directory (or OUT.png whose name is used as a prefix)."),
    times: Optional[list[str]] = typer.Option(None, "--time", help="Times to show: e.g. 35s, 'worst' (end of the outage with the largest INS error) or 'end' (default). Repeatable."),
    views: Optional[list[str]] = typer.Option(None, "--view", help="all (default), map, local, signals or errors. Repeatable."),
    size: str = typer.Option("1600x900", "--size", help="Image size WIDTHxHEIGHT in pixels."),
    scenario: Optional[str] = typer.Option(None, "--scenario", help="Replay and render a scenario's test drives ('all' for every scenario): bundled ones, or the paper's runs with a data root."),
    outage: str = typer.Option("10s", "--outage", help="Outage length for --scenario replays."),
    timeout: str = typer.Option("120s", "--timeout", help="Longest wait for the viewer to start or load a recording."),
    data_root_opt: Optional[Path] = DataRoot,
) -> None:
    """Render PNG screenshots of recordings with a headless Rerun viewer (no display or GPU needed).

    Prints the path of every image written.
    """
    import tempfile

    from .resolve import data_root
    from .screenshot import parse_size, render

    width_height = parse_size(size)
    timeout_s = parse_duration_s(timeout, "--timeout")
    if scenario is not None and recordings:
        raise typer.BadParameter("give recordings or --scenario, not both")
    if scenario is None and not recordings:
        raise typer.BadParameter("give at least one REC.rrd (or --scenario)", param_hint="REC.rrd")
    times = list(times or (["worst"] if scenario else ["end"]))
    views = list(views or ["all"])
    for rec in recordings or []:
        if not rec.is_file():
            raise InputError(f"{rec}: no such recording", "make one with 'ionav-viz replay DRIVE'")
    with tempfile.TemporaryDirectory(prefix="ionav-shots-") as tmp:
        rrds = list(recordings or [])
        if scenario is not None:
            for group, specs in _scenario_specs(scenario, data_root(data_root_opt)).items():
                for spec in specs:
                    rrd = Path(tmp) / f"{group}-{Path(spec).stem}.rrd"
                    _replay_drive(spec, outage, None, None, None, 0, rrd, True, None, False, None, data_root_opt, "auto")
                    rrds.append(rrd)
        render(rrds, output, times, views, width_height, timeout_s=timeout_s, progress=print)


@app.command()
def convert(
    drive_spec: str = typer.Argument(..., metavar="DRIVE", help="An IO-VNBD CSV (path, bundled scenario or run name)."),
    output: Path = typer.Option(..., "-o", "--output", help="The .mcap file to write (ROS 2 cdr: Imu, NavSatFix, TwistStamped)."),
    data_root_opt: Optional[Path] = DataRoot,
    yaw_sign: str = YawSign,
) -> None:
    """Convert a drive to a ROS 2 MCAP log that opens in Foxglove and 'ros2 bag'."""
    from .mcap_convert import TOPICS, write_mcap
    from .resolve import data_root
    from .sources import load_drive

    if output.suffix.lower() != ".mcap":
        raise typer.BadParameter(f"{output}: the output must end in .mcap", param_hint="-o")
    drive = load_drive(drive_spec, data_root(data_root_opt), yaw_sign)
    n = write_mcap(drive, output)
    print(f"{n} messages on {', '.join(TOPICS.values())} ({len(drive)} samples, {drive.duration_s:.1f} s)", file=sys.stderr)
    print(output)


@app.command()
def info(
    path: Path = typer.Argument(..., metavar="FILE.mcap", help="An MCAP log."),
    imu_topic: Optional[str] = ImuTopic,
    gnss_topic: Optional[str] = GnssTopic,
    speed_topic: Optional[str] = SpeedTopic,
) -> None:
    """List the channels of an MCAP log and which ones ionav-viz would read."""
    from .mcap_source import list_channels, select_channels

    if not path.is_file():
        raise InputError(f"{path}: no such file")
    channels = list_channels(path)
    try:
        sel = select_channels(path, imu_topic, gnss_topic, speed_topic)
        roles = {c.topic: c.role for c in (sel.imu, sel.gnss, sel.speed) if c is not None}
        problem = None
    except InputError as exc:
        roles, problem = {}, str(exc)
    width = max([len(c.topic) for c in channels] + [5])
    print(f"{'topic'.ljust(width)}  {'messages':>9}  encoding  schema  -> use")
    for c in channels:
        print(f"{c.topic.ljust(width)}  {c.count:>9}  {c.encoding:<8}  {c.schema}  -> {roles.get(c.topic, '-')}")
    if problem:
        print(f"cannot replay as is: {problem}", file=sys.stderr)


def _fetch_root(option: Optional[Path]) -> Path:
    """Where fetch writes and list looks: --data-root, $IONAV_DATA, else the per-user data directory."""
    import os

    from .fetch import default_data_root

    value = option or (Path(os.environ["IONAV_DATA"]) if os.environ.get("IONAV_DATA") else None)
    return (value or default_data_root()).expanduser()


def _manifest(option: Optional[Path]):
    from .catalog import manifest, parse_manifest

    if option is None:
        return manifest()
    try:
        return parse_manifest(option.read_text(encoding="utf-8"), str(option))
    except OSError as exc:
        raise InputError(f"{option}: cannot read the manifest ({exc.strerror})") from None


ManifestOpt = typer.Option(None, "--manifest", help="A manifest TSV (path, sha256, size_bytes) to use instead of the packaged one (mirrors, tests).", show_default=False)


@app.command("list")
def list_runs(
    as_json: bool = typer.Option(False, "--json", help="Print JSON for scripts."),
    verify: bool = typer.Option(False, "--verify", help="Check the sha256 of present files not verified before (slow for big files)."),
    data_root_opt: Optional[Path] = typer.Option(None, "--data-root", help="Data root (default: $IONAV_DATA, else the per-user data directory).", show_default=False),
    manifest_opt: Optional[Path] = ManifestOpt,
) -> None:
    """List the IO-VNBD runs: group, driver, role in the paper, size, and whether present locally."""
    from .catalog import paper_role, runs
    from .fetch import VerifiedCache, safe_target

    root = _fetch_root(data_root_opt)
    cache = VerifiedCache(root)
    rows = []
    for run in runs(_manifest(manifest_opt)).values():
        entry = run.vehicle or run.vehicle_sync
        status = cache.status(entry, safe_target(root, entry.path), check=verify) if root.is_dir() else "missing"
        rows.append({
            "name": run.name, "group": run.group, "driver": run.driver, "role": paper_role(run.name) or "",
            "size_bytes": entry.size_bytes, "path": entry.path, "status": status,
        })
    if as_json:
        print(json.dumps({"data_root": str(root), "runs": rows}, indent=2))
        return
    width = max(len(r["name"]) for r in rows) if rows else 4
    print(f"data root: {root}")
    print(f"{'run'.ljust(width)}  group  driver  {'size':>9}  {'local':<8}  role in the paper")
    for r in rows:
        print(f"{r['name'].ljust(width)}  {r['group']:<5}  {r['driver']:<6}  {r['size_bytes'] / 1e6:>7.2f}MB  {r['status']:<8}  {r['role']}")


@app.command()
def fetch(
    names: Optional[list[str]] = typer.Argument(None, help="Run names, e.g. V-Vw8 Vta11."),
    scenario: Optional[str] = typer.Option(None, "--scenario", help="The paper's test runs of a scenario, or all."),
    paper_test: bool = typer.Option(False, "--paper-test", help="All the paper's test runs (Tables 6-7)."),
    paper_train: bool = typer.Option(False, "--paper-train", help="All the paper's training runs (Table 1)."),
    synchronised: bool = typer.Option(False, "--synchronised", help="The synchronised copy instead of the complete (unsynchronised) run."),
    phone: bool = typer.Option(False, "--phone", help="Also the phone's S- file of each run."),
    data_root_opt: Optional[Path] = typer.Option(None, "--data-root", help="Where to put the files (default: $IONAV_DATA, else the per-user data directory).", show_default=False),
    base_url_opt: Optional[str] = typer.Option(None, "--base-url", help="Repository root URL to download from (default: $IONAV_BASE_URL, else the dataset's Git LFS media URL)."),
    timeout: str = typer.Option("30s", "--timeout", help="Give up on a connection that stalls this long."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    manifest_opt: Optional[Path] = ManifestOpt,
) -> None:
    """Download IO-VNBD runs by name into the data root, resuming and verifying size and sha256."""
    from .catalog import PAPER_TEST_RUNS, PAPER_TRAIN_RUNS, run_key, runs
    from .fetch import VerifiedCache, base_url, fetch_file

    catalog = runs(_manifest(manifest_opt))
    wanted = list(names or [])
    if scenario is not None:
        if scenario != "all" and scenario not in PAPER_TEST_RUNS:
            raise typer.BadParameter(f"unknown scenario {scenario!r}; choose {', '.join(PAPER_TEST_RUNS)} or all", param_hint="--scenario")
        wanted += [r for s, rs in PAPER_TEST_RUNS.items() if scenario in ("all", s) for r in rs]
    if paper_test:
        wanted += [r for rs in PAPER_TEST_RUNS.values() for r in rs]
    if paper_train:
        wanted += list(PAPER_TRAIN_RUNS)
    if not wanted:
        raise typer.BadParameter("name runs to fetch, or use --scenario, --paper-test or --paper-train", param_hint="NAMES")
    entries = []
    for name in dict.fromkeys(wanted):
        run = catalog.get(run_key(name))
        if run is None:
            import difflib

            close = difflib.get_close_matches(name, [r.name for r in catalog.values()], n=3)
            raise InputError(f"unknown IO-VNBD run {name!r}", f"did you mean {', '.join(close)}?" if close else "see 'ionav-viz list'")
        files = [run.vehicle_sync if synchronised else run.vehicle or run.vehicle_sync]
        if phone:
            files.append((run.phone_sync if synchronised else run.phone) or run.phone_sync or run.phone)
        for entry in files:
            if entry is None:
                raise InputError(f"{run.name}: the manifest has no {'synchronised ' if synchronised else ''}{'phone ' if phone else ''}file for it")
            entries.append(entry)
    root = _fetch_root(data_root_opt)
    root.mkdir(parents=True, exist_ok=True)
    url = base_url(base_url_opt)
    timeout_s = parse_duration_s(timeout, "--timeout")
    cache = VerifiedCache(root)
    with _progress(quiet) as bar:
        task = bar.add_task("fetching", total=sum(e.size_bytes for e in entries)) if bar else None
        finished = 0
        for entry in entries:
            def progress(e, done: int, before: int = finished) -> None:
                if bar is not None:
                    bar.update(task, completed=before + done, description=e.path.rsplit("/", 1)[-1])

            result = fetch_file(entry, root, url, timeout_s=timeout_s, cache=cache, progress=progress)
            finished += entry.size_bytes
            print(f"{result.action:>10}  {result.path}", file=sys.stderr)
    print(root)


def _reports_by_event(specs: list[str], outage_s: float, on: Optional[str], thresholds, root, yaw_sign, mcap,
                      stationary, idnn) -> dict[str, dict]:
    """One report per manoeuvre type: outages centred on each detected event, across drives."""
    from . import outages as place
    from .evaluate import evaluate_drive, report, resolve_bias
    from .events import EVENT_TYPES, detect_events
    from .sources import load_drive
    from .windows import make_windows

    kinds = _event_types(on) if on else EVENT_TYPES
    th = _thresholds(thresholds)
    n = place.outage_windows(outage_s)
    per_type: dict[str, list] = {k: [] for k in kinds}
    for spec in specs:
        drive = load_drive(spec, root, yaw_sign, mcap)
        windows = make_windows(drive)
        bias = resolve_bias(drive, stationary)
        found = detect_events(drive, th, kinds)
        for kind in kinds:
            starts, _ = place.around(windows, [(e.t0_s, e.t1_s) for e in found if e.type == kind], n)
            if len(starts):
                per_type[kind].append(evaluate_drive(drive, outage_s, bias=bias, model=idnn, starts=starts, windows=windows))
    reports = {kind: report(results) for kind, results in per_type.items() if results}
    if not reports:
        raise InputError(f"no {', '.join(kinds)} event with room for a {outage_s:g} s outage in {', '.join(specs)}",
                         "see 'ionav-viz events DRIVE'")
    return reports


@app.command()
def events(
    drives: Optional[list[str]] = typer.Argument(None, help="Drives: file paths, bundled scenario names or IO-VNBD run names."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON for scripts."),
    types: Optional[str] = typer.Option(None, "--type", help="Only these event types, comma-separated."),
    quality: bool = typer.Option(False, "--quality", help="Measure each detector's recall and precision on the bundled synthetic drives, where the simulator knows every manoeuvre."),
    thresholds: Optional[list[str]] = Thresholds,
    data_root_opt: Optional[Path] = DataRoot,
    yaw_sign: str = YawSign,
    imu_topic: Optional[str] = ImuTopic,
    gnss_topic: Optional[str] = GnssTopic,
    speed_topic: Optional[str] = SpeedTopic,
    stamps: str = Stamps,
) -> None:
    """Find hard brakes, roundabouts, sharp corners, left-right turns, quick acceleration changes and cruising.

    Definitions and thresholds: ionav_viz/events.py and the README ('Manoeuvres').
    """
    from .events import EVENT_TYPES, detect_events, score
    from .resolve import data_root
    from .samples import SAMPLES, sample_path
    from .simulate import simulated_manoeuvres
    from .sources import load_drive

    th = _thresholds(thresholds)
    kinds = _event_types(types) if types else EVENT_TYPES
    if quality:
        from .iovnbd import read_iovnbd

        totals: dict[str, list[int]] = {k: [0, 0, 0, 0] for k in EVENT_TYPES}
        for sample in SAMPLES:
            drive = read_iovnbd(sample_path(sample))
            truth = simulated_manoeuvres(sample.scenario, sample.seed, sample.duration_s)
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
    root = data_root(data_root_opt)
    mcap = _mcap_options(imu_topic, gnss_topic, speed_topic, stamps)
    found = {}
    for spec in drives:
        drive = load_drive(spec, root, yaw_sign, mcap)
        found[drive.name] = [e for e in detect_events(drive, th) if e.type in kinds]
    if as_json:
        print(json.dumps({name: [e.to_dict() for e in evs] for name, evs in found.items()}, indent=2))
        return
    for name, evs in found.items():
        print(f"{name}: {len(evs)} event(s)")
        for e in evs:
            values = ", ".join(f"{k} {v:.2f}" for k, v in e.values.items())
            print(f"  {e.type:<13} {e.t0_s:8.1f} - {e.t1_s:8.1f} s   {values}")


def summary_markdown(rep: dict, drive, placement: str, bias, model_info: dict | None) -> str:
    """The run's parameters as Markdown (the recording's summary document)."""
    lines = [
        f"# {drive.name}: INS and IDNN during GNSS outages",
        "",
        f"- **Source**: `{drive.source}` ({len(drive)} samples, {drive.duration_s:.1f} s, {drive.rate_hz:g} Hz)",
        f"- **Outages**: {placement}; {rep['n_sequences']} outage(s)",
        f"- **Sensor biases**: accelerometer {bias.accel_mps2:+.3f} m/s², gyro {bias.gyro_radps:+.5f} rad/s, from {bias.source}",
    ]
    if model_info:
        trained = ", ".join(d["name"] for d in model_info.get("trained_on", [])) or "unknown"
        lines.append(f"- **IDNN model**: `{model_info['directory']}` ({model_info['arch']}, {model_info['n_steps_disp']} / {model_info['n_steps_yaw']} time steps), trained on {trained}")
        if model_info.get("training_data"):
            lines.append(f"- **Training data**: {model_info['training_data']}")
    else:
        lines.append("- **IDNN model**: none (INS only)")
    lines.append("- **Errors**: e = truth - estimate; CRSE = sum |e|, CAE = sum e, AEPS = CRSE / N")
    return "\n".join(lines) + "\n"


def _open_viewer(path: Path) -> None:
    import shutil
    import subprocess

    exe = shutil.which("rerun")
    if exe is None:
        raise InputError("cannot open the viewer: the 'rerun' command is not on PATH", f"open {path} with the Rerun viewer yourself")
    subprocess.Popen([exe, str(path)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


def main() -> None:
    """Console entry point: one-line errors with exit code 2, 130 on Ctrl-C."""
    debug = "--debug" in sys.argv[1:]
    try:
        code = app(standalone_mode=False)
        # Without standalone mode, typer returns exit codes (130 for Ctrl-C) instead of exiting.
        if isinstance(code, int) and not isinstance(code, bool):
            if code == 130:
                print("interrupted", file=sys.stderr)
            sys.exit(code)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except (KeyboardInterrupt, typer.Abort):
        print("interrupted", file=sys.stderr)
        sys.exit(130)
    except InputError as exc:
        if debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    except ToolFailure as exc:
        if debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(1)
    except Exception as exc:
        # typer's (click's) usage errors: one line too, with the command's --help as the hint
        if hasattr(exc, "format_message") and hasattr(exc, "exit_code") and not debug:
            ctx = getattr(exc, "ctx", None)
            command = ctx.command_path.replace("python -m ionav_viz.cli", "ionav-viz") if ctx is not None else "ionav-viz"
            print(f"error: {exc.format_message()} (hint: see '{command} --help')", file=sys.stderr)
            sys.exit(exc.exit_code)
        raise


if __name__ == "__main__":
    main()
