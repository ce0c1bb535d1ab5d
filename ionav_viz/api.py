"""The public Python API: load drives, evaluate estimators on GNSS outages, replay to ``.rrd``, render screenshots.

Every function here is what one CLI command does, without the shell: arguments are Python values
(seconds as floats, paths, placement objects, estimator names or objects), results are
dataclasses, and problems are :class:`~ionav_viz.core.errors.InputError` (bad input) or
:class:`~ionav_viz.core.errors.ToolFailure` (the environment: disk, renderer, network).

    import ionav_viz as iv

    drive = iv.load_drive("roundabout")                  # a bundled scenario, a path or a run name
    report = iv.evaluate([drive], outage_s=10.0)          # the paper's consecutive outages
    print(report.to_text())
    result = iv.replay(drive, placement=iv.Every(30.0), output="roundabout.rrd")
    iv.screenshot([result.path], "shots/", iv.Shots(times=["worst"], views=["local"]))
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from .analysis.evaluate import DriveResult, evaluate_drive
from .analysis.events import EVENT_TYPES, MANOEUVRE_TYPES, Event, EventThresholds, detect_events
from .analysis.report import Report, run_summary_markdown
from .core.drive import Drive
from .core.errors import InputError
from .core.fileio import check_output_file
from .core.timing import stage
from .dataset.catalog import PAPER_TEST_RUNS, SCENARIOS, run_key
from .nav.bias import SensorBias, resolve_bias
from .nav.outages import GNSS_OUTAGE, AroundEvents, OutagePlan, Placement, Tile, outage_windows
from .nav.protocol import Estimator, applies
from .nav.registry import BUILTIN
from .nav.registry import resolve as resolve_estimators
from .nav.windows import Windows, make_windows
from .sources.load import LogOptions, ReadOptions, load_drive, with_deprecated_log
from .sources.resolve import data_root as _data_root

log = logging.getLogger("ionav_viz")

#: ``progress(label, done, total)``: called as long work advances (e.g. to drive a progress bar).
Progress = Callable[[str, int, int], None]
DriveLike = Drive | str | Path
#: Where :func:`replay` writes ``<drive>.rrd`` by default, relative to the current directory.
RECORDINGS_DIR = "recordings"


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
        return (f"ReplayResult({str(self.path)!r}\n  drive: {self.result.drive.name}, {len(self.outages)} outage(s): {self.placement}\n"
                f"  {self.report.summary_line()}\n)")


class ScenarioDrives(dict):
    """Test drives by scenario (a ``dict``), with ``source``: one line saying where they come from."""

    source: str = ""


def scenario_drives(scenario: str, data_root: str | Path | None = None) -> ScenarioDrives:
    """The test drives of a scenario (``"all"``: of every scenario), by scenario: the paper's runs
    where all of a scenario's runs are under the data root, else the bundled synthetic drive.
    ``.source`` says which, in one line."""
    from .dataset.samples import by_scenario, sample_path
    from .sources.resolve import index_data_root

    if scenario != "all" and scenario not in SCENARIOS:
        raise InputError(f"unknown scenario {scenario!r}", f"choose {', '.join(SCENARIOS)} or all", param="scenario")
    names = SCENARIOS if scenario == "all" else (scenario,)
    root = _data_root(data_root)
    present = index_data_root(root.resolve()) if root is not None else {}
    out = ScenarioDrives()
    paper, bundled = [], []
    for s in names:
        if root is not None and all(run_key(r) in present for r in PAPER_TEST_RUNS[s]):
            out[s] = list(PAPER_TEST_RUNS[s])
            paper.append(s)
        else:
            out[s] = [str(sample_path(sample)) for sample in by_scenario(s)]
            bundled.append(s)
    parts = []
    if paper:
        parts.append(f"{', '.join(paper)}: the paper's IO-VNBD test runs under {root}")
    if bundled:
        why = f"the paper's runs are not all under {root}; 'ionav-viz fetch --scenario NAME' gets them" if root else "no IO-VNBD data root"
        parts.append(f"{', '.join(bundled)}: the bundled synthetic test drives ({why})")
    out.source = "; ".join(parts)
    return out


@dataclass(frozen=True)
class RunOptions:
    """How the estimators run, the same for every API function and command.

    Attributes:
        estimators: names (``"ins"``, ``"idnn"``, entry-point names, ``"module:NAME"``,
            ``"path/to/file.py:NAME"``) or estimator objects; None: every built-in that applies
            (the IDNN when a model exists, odometry where the drive has a vehicle speed).
        plugins: estimators added to those (``--estimator``).
        without: built-ins left out of the default set (``("idnn",)`` is ``--no-idnn``).
        model: the IDNN's model (an ``IdnnModel`` or its directory); default the shipped one.
        bias_from: a stationary drive (or ready :class:`SensorBias`) for the sensor biases;
            default each drive's own stationary stretches.
        thresholds: the event detectors' thresholds (default :class:`EventThresholds`).
    """

    estimators: Sequence[str | Estimator] | None = None
    plugins: Sequence[str | Estimator] = ()
    without: Sequence[str] = ()
    model: Any = None
    bias_from: DriveLike | SensorBias | None = None
    thresholds: EventThresholds = field(default_factory=EventThresholds)

    def chosen(self) -> list[Estimator]:
        """The estimators, resolved (plug-ins loaded) and checked: before any drive is read."""
        return resolve_estimators(self.estimators, plugins=self.plugins, without=self.without, model=self.model)

    def applying_to(self, drives: Sequence[Drive]) -> list[Estimator]:
        """The estimators that apply to every one of ``drives`` (one report compares them all on
        the same outages). A default one left out is said at ``-v`` (by its ``applies``); one the
        caller named (in ``estimators`` or ``plugins``), with a warning; none left is an error."""
        defaults = set(BUILTIN) if self.estimators is None else set()
        kept = []
        for est in self.chosen():
            missing = [d.name for d in drives if not applies(est, d)]
            if not missing:
                kept.append(est)
            elif est.name not in defaults:
                log.warning("%s left out: it does not apply to %s", est.label, ", ".join(missing))
        if not kept:
            raise InputError(f"none of the chosen estimators ({', '.join(e.name for e in self.chosen())}) applies to {', '.join(d.name for d in drives)}",
                             "choose others with --estimators (ins always applies)", param="estimators")
        return kept

    def bias_of(self, read: ReadOptions) -> Callable[[Drive], SensorBias]:
        """``drive -> biases``: a given :class:`SensorBias`, a stationary drive's (read once), or each drive's own."""
        if isinstance(self.bias_from, SensorBias):
            fixed = self.bias_from
            return lambda drive: fixed
        stationary = load_drive(self.bias_from, read) if self.bias_from is not None else None
        return lambda drive: resolve_bias(drive, stationary)


def _options(run: RunOptions | None, estimators: Sequence[str | Estimator] | None, read: ReadOptions | None,
             mcap: LogOptions | None) -> tuple[RunOptions, ReadOptions]:
    """The run and read options of a call: ``estimators`` is a shortcut for ``run.estimators``."""
    run = run if run is not None else RunOptions()
    if estimators is not None:
        if run.estimators is not None:
            raise InputError("estimators given twice (as estimators= and in run=)", "give them once", param="estimators")
        run = replace(run, estimators=estimators)
    return run, with_deprecated_log(read, mcap)


def _check_event_types(types: Sequence[str]) -> None:
    unknown = [t for t in types if t not in EVENT_TYPES]
    if unknown or not types:
        raise InputError(f"unknown event type(s) {', '.join(unknown) or '(none)'}", f"choose from {', '.join(EVENT_TYPES)}", param="placement")


def _plan(drive: Drive, windows: Windows, placement: Placement, n_windows: int, run: RunOptions,
          events: list[Event] | None = None) -> tuple[OutagePlan, list[Event]]:
    """The placement's plan for one drive, with the events it was planned on (detected when the
    placement needs them and they were not given)."""
    if events is None and placement.event_types:
        events = detect_events(drive, run.thresholds)
    return placement.plan(windows, n_windows, events or [], drive.source), events or []


def _windows_of(outage_s: float) -> int:
    """The one place seconds become windows: the outage length (whole seconds) as windows."""
    return outage_windows(outage_s)


def evaluate(
    drives: Sequence[DriveLike] | DriveLike,
    outage_s: float = 10.0,
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    run: RunOptions | None = None,
    read: ReadOptions | None = None,
    progress: Progress | None = None,
    mcap: LogOptions | None = None,
) -> Report:
    """Every estimator on the same GNSS outages of each drive, scored with the paper's metrics.

    Args:
        drives: drives or what names them (see :func:`load_drive`).
        outage_s: length of each outage, whole seconds.
        placement: where outages go (default :class:`Tile`, the paper's consecutive outages).
            A drive too short for one tiled outage is skipped with a warning.
        estimators: a shortcut for ``run.estimators``.
        run: which estimators run with what model, biases and event thresholds (:class:`RunOptions`).
        read: how drives are read (:class:`ReadOptions`); outages go only where every window has
            good GNSS truth, and the report counts what was excluded.
        mcap: deprecated, ``read.log``.

    Returns:
        a :class:`Report`; ``report.to_json()`` is what ``ionav-viz evaluate --json`` prints.
    """
    items = [drives] if isinstance(drives, (Drive, str, Path)) else list(drives)
    if not items:
        raise InputError("no drive to evaluate", "give at least one drive")
    placement = placement or Tile()
    n = _windows_of(outage_s)  # checked before any drive is read
    run, read = _options(run, estimators, read, mcap)
    if placement.event_types:
        _check_event_types(placement.event_types)
    run.chosen()
    bias_of = run.bias_of(read)
    loaded = [load_drive(item, read) for item in items]
    ests = run.applying_to(loaded)
    results = []
    for i, drive in enumerate(loaded):
        if progress:
            progress(drive.name, i, len(items))
        windows = make_windows(drive)
        plan, _ = _plan(drive, windows, placement, n, run)
        if plan.too_short:
            log.warning("%s: too short for a single %g s outage%s; skipped", drive.name, n, " on good GNSS truth" if plan.excluded else "")
            continue
        results.append(evaluate_drive(drive, n, ests, bias=bias_of(drive), starts=plan.starts, windows=windows,
                                      excluded_outages=plan.excluded, gnss_gaps=plan.gnss_gaps))
    if progress:
        progress("done", len(items), len(items))
    if not results:
        raise InputError(f"no {n:g} s outage fits in {', '.join(_name(d) for d in items)}", "use shorter outages", param="outage_s")
    return Report(results)


def evaluate_by_event(
    drives: Sequence[DriveLike],
    outage_s: float = 10.0,
    types: Sequence[str] | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    *,
    run: RunOptions | None = None,
    read: ReadOptions | None = None,
    mcap: LogOptions | None = None,
) -> dict[str, Report]:
    """One report per manoeuvre type: an outage centred on each detected event, across ``drives``
    (``types`` default: every manoeuvre type; ``gnss-outage``: the log's own losses, bridged).
    The other arguments as for :func:`evaluate`."""
    kinds = tuple(types) if types else MANOEUVRE_TYPES
    _check_event_types(kinds)
    n = _windows_of(outage_s)
    run, read = _options(run, estimators, read, mcap)
    run.chosen()
    bias_of = run.bias_of(read)
    per_type: dict[str, list[DriveResult]] = {k: [] for k in kinds}
    loaded = [load_drive(item, read) for item in drives]
    ests = run.applying_to(loaded)
    for drive in loaded:
        windows = make_windows(drive)
        bias = bias_of(drive)
        found = detect_events(drive, run.thresholds, kinds)
        for kind in kinds:
            if kind != GNSS_OUTAGE and not any(e.type == kind for e in found):
                continue
            try:
                plan, _ = _plan(drive, windows, AroundEvents((kind,)), n, run, found)
            except InputError:  # no room for an outage on this drive's events of that type, or no loss
                continue
            per_type[kind].append(evaluate_drive(drive, n, ests, bias=bias, starts=plan.starts, windows=windows,
                                                 excluded_outages=plan.excluded, gnss_gaps=plan.gnss_gaps))
    reports = {kind: Report(results, kind) for kind, results in per_type.items() if results}
    if not reports:
        raise InputError(f"no {', '.join(kinds)} event with room for a {n:g} s outage in {', '.join(_name(d) for d in drives)}",
                         "see 'ionav-viz events DRIVE'")
    return reports


def _name(item: DriveLike) -> str:
    return item.name if isinstance(item, Drive) else str(item)


def replay(
    drive: DriveLike,
    outage_s: float = 10.0,
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    output: str | Path | None = None,
    *,
    run: RunOptions | None = None,
    read: ReadOptions | None = None,
    progress: Progress | None = None,
    connect: str | None = None,
    mcap: LogOptions | None = None,
) -> ReplayResult:
    """Replay ``drive`` with GNSS outages, run the estimators side by side and write a ``.rrd``.

    Args:
        drive, outage_s, placement, estimators, run, read: as for :func:`evaluate`
            (:class:`AroundEvents` places an outage on each detected manoeuvre of its types).
        output: the ``.rrd`` to write (default ``recordings/<drive>.rrd`` in the current
            directory, the folder made when missing); an existing file is replaced atomically,
            nothing is left behind on failure.
        progress: called as the recording is built.
        connect: also stream the recording to the Rerun viewer at this gRPC address (e.g.
            ``rerun+http://127.0.0.1:9876/proxy``, where a plain ``rerun`` listens); checked
            before any work.

    Returns:
        a :class:`ReplayResult` with the written path, the report and the outages.
    """
    from .core.fileio import atomic_path
    from .viz import live
    from .viz.recording import write_recording

    if connect is not None:
        live.check_listening(connect)
    out = Path(output) if output is not None else None
    if out is not None and out.suffix.lower() != ".rrd":
        raise InputError(f"{out}: a recording must end in .rrd", "choose a name like drive.rrd", param="output")
    placement = placement or Tile()
    n = _windows_of(outage_s)
    run, read = _options(run, estimators, read, mcap)
    if placement.event_types:
        _check_event_types(placement.event_types)
    run.chosen()
    d = load_drive(drive, read)
    with stage("windows") as s:
        windows = make_windows(d)
        s.detail = f"{len(windows)} of 1 s"
    with stage("manoeuvres") as s:
        events = detect_events(d, run.thresholds)
        s.detail = f"{len(events)} detected"
    plan, _ = _plan(d, windows, placement, n, run, events)
    if len(plan.starts) == 0 and not plan.gnss_gaps:
        raise InputError(f"{d.source}: drive too short ({d.duration_s:.1f} s) for a {n:g} s outage", "use shorter outages", param="outage_s")
    default = out is None
    out = check_output_file(Path(RECORDINGS_DIR, f"{d.name}.rrd") if default else out, create_parent=default)  # before the work
    chosen = run.applying_to([d])
    result = evaluate_drive(d, n, chosen, bias=run.bias_of(read)(d), starts=plan.starts, windows=windows, excluded_outages=plan.excluded,
                            gnss_gaps=plan.gnss_gaps)
    report = Report([result])
    summary = _summary_markdown(result, report, plan.description)
    total = 5 + len(result.estimates)
    done = [0]

    def advance(label: str) -> None:
        done[0] += 1
        if progress:
            progress(f"{out.name}: {label}", done[0], total)

    with stage(f"write {out}") as s, atomic_path(out, create_parent=default) as tmp:
        rows = write_recording(result, summary, tmp, progress=advance, target=out, events=events)
        s.detail = f"{len(rows)} entities, {sum(rows.values())} rows"
    if connect is not None:
        with stage(f"stream to {connect}"):
            live.connect(result, summary, connect, events=events)
    outages = [Outage(i + 1, float(windows.t0_s[k]), float(windows.t0_s[k] + n), int(k)) for i, k in enumerate(plan.starts)]
    return ReplayResult(out, report, outages, plan.description, result, events)



def find_events(drives: Sequence[DriveLike] | DriveLike, types: Sequence[str] | None = None, *, thresholds: EventThresholds | None = None,
                read: ReadOptions | None = None) -> dict[str, list[Event]]:
    """The detected events of each drive (by drive name), of ``types`` (default every type), in
    time order; overlapping detections of one type are one event (``ionav-viz events``)."""
    kinds = tuple(types) if types else EVENT_TYPES
    _check_event_types(kinds)
    items = [drives] if isinstance(drives, (Drive, str, Path)) else list(drives)
    if not items:
        raise InputError("no drive to look at", "give at least one drive")
    found = {}
    for item in items:
        drive = load_drive(item, read)
        found[drive.name] = detect_events(drive, thresholds or EventThresholds(), kinds)
    return found


@dataclass(frozen=True)
class DetectorQuality:
    """One detector's measured quality: known manoeuvres, recalled ones, detections, precise ones."""

    known: int
    recalled: int
    found: int
    precise: int

    @property
    def recall(self) -> float | None:
        return self.recalled / self.known if self.known else None

    @property
    def precision(self) -> float | None:
        return self.precise / self.found if self.found else None


def detector_quality(thresholds: EventThresholds | None = None, types: Sequence[str] | None = None) -> dict[str, DetectorQuality]:
    """Each detector's recall and precision on the bundled synthetic drives, where the simulator
    knows every manoeuvre it drove (``ionav-viz events --quality``)."""
    from .analysis.events import score
    from .dataset.samples import SAMPLES, sample_path
    from .sim.simulate import simulated_manoeuvres

    kinds = tuple(types) if types else EVENT_TYPES
    _check_event_types(kinds)
    totals = {k: [0, 0, 0, 0] for k in EVENT_TYPES}
    for sample in SAMPLES:
        drive = load_drive(sample_path(sample))  # with the GNSS quality marks, as every command reads
        truth = simulated_manoeuvres(sample.scenario, sample.seed, sample.duration_s, sample.gnss_losses)
        for kind, sc in score(truth, detect_events(drive, thresholds or EventThresholds()), drive.duration_s).items():
            for i, v in enumerate((sc.n_truth, sc.recalled, sc.n_found, sc.precise)):
                totals[kind][i] += v
    return {k: DetectorQuality(*t) for k, t in totals.items() if k in kinds}


class TrainingDrives(list):
    """Training drives (a ``list``), with ``description``: what they are, kept in the model's metadata."""

    description: str = "user-given drives"


def training_drives(paper: bool = False, data_root: str | Path | None = None) -> TrainingDrives:
    """The bundled synthetic training drives, or with ``paper`` the paper's IO-VNBD training runs
    (Table 1) under the data root."""
    from .dataset.catalog import PAPER_TRAIN_RUNS
    from .dataset.samples import SAMPLES, sample_path

    if paper:
        if _data_root(data_root) is None:
            raise InputError("training on the paper's runs needs the IO-VNBD data", "pass --data-root DIR or set IONAV_DATA", param="data_root")
        drives = TrainingDrives(PAPER_TRAIN_RUNS)
        drives.description = "the paper's IO-VNBD training runs (Table 1)"
        return drives
    drives = TrainingDrives(str(sample_path(s)) for s in SAMPLES if s.role == "train")
    drives.description = "the bundled synthetic training drives (ionav_viz/data/samples/V-sim-*-train-*.csv), not real data"
    return drives


def train(
    output: str | Path,
    drives: Sequence[DriveLike] | None = None,
    config: Any = None,
    *,
    bias_from: DriveLike | None = None,
    read: ReadOptions | None = None,
    force: bool = False,
    progress: Progress | None = None,
    command: str = "ionav_viz.train",
) -> Any:
    """Train the IDNN's two networks and write them with their metadata to ``output`` (a model
    directory; an existing one is replaced only with ``force``, atomically).

    ``drives``: default the bundled synthetic training drives (:func:`training_drives`, which
    also gives the paper's runs);
    ``config``: an ``ionav_viz.nav.idnn.ModelConfig`` (default the shipped model's settings);
    ``bias_from``: a stationary drive for the sensor biases (default each drive's own);
    ``command``: how it was trained, kept in the metadata. Returns the trained ``IdnnModel``.
    """
    from .nav.idnn import ModelConfig, check_model_dir, save_model
    from .nav.training import train_models

    read = read if read is not None else ReadOptions()
    config = config if config is not None else ModelConfig()
    config.validate()
    out = check_model_dir(Path(output), overwrite=force)  # before any work
    specs = training_drives() if drives is None else drives
    description = getattr(specs, "description", TrainingDrives.description)
    stationary = load_drive(bias_from, read) if bias_from is not None else None
    loaded = [(d, resolve_bias(d, stationary)) for d in (load_drive(spec, read) for spec in specs)]
    model = train_models(loaded, config, progress=progress, description=description)
    model.metadata["training"]["command"] = command
    save_model(model, out, overwrite=force)
    return model


def replay_scenario(scenario: str, folder: str | Path, outage_s: float = 10.0, placement: Placement | None = None, *,
                    run: RunOptions | None = None, read: ReadOptions | None = None) -> list[Path]:
    """Replay every test drive of ``scenario`` (``"all"``: of every scenario; see
    :func:`scenario_drives`) into ``folder`` as ``<scenario>-<drive>.rrd``; returns the paths."""
    read = read if read is not None else ReadOptions()
    groups = scenario_drives(scenario, read.data_root)
    log.info("drives: %s", groups.source)
    return [replay(spec, outage_s, placement, output=Path(folder) / f"{group}-{Path(spec).stem}.rrd", run=run, read=read).path
            for group, specs in groups.items() for spec in specs]

def _summary_markdown(result: DriveResult, report: Report, description: str) -> str:
    """The recording's summary document: the run, the worst outages and the paper's table."""
    return run_summary_markdown(result, report, description) + "\n" + report.to_markdown()


def serve_web(replayed: ReplayResult, grpc_port: int | None = None, web_port: int | None = None):
    """Serve a replay's recording to browsers from this process (Rerun's gRPC server and web
    viewer, on ports ``viz.live.DEFAULT_GRPC_PORT`` and ``DEFAULT_WEB_PORT`` unless given);
    returns a :class:`ionav_viz.viz.live.WebServer` whose ``web_url`` to open. The servers stop
    when the process ends."""
    from .viz import live

    grpc_port = live.DEFAULT_GRPC_PORT if grpc_port is None else grpc_port
    web_port = live.DEFAULT_WEB_PORT if web_port is None else web_port
    return live.serve_web(replayed.result, _summary_markdown(replayed.result, replayed.report, replayed.placement),
                          replayed.events, grpc_port=grpc_port, web_port=web_port)


@dataclass(frozen=True)
class Shots:
    """What :func:`screenshot` renders of each recording: every view at every time and outage.

    Attributes:
        times: seconds (float), ``"35s"``, ``"worst"`` or ``"end"``. ``"worst"`` is the end of the
            outage with the largest final position error of ``worst_of`` (default the INS DR), and
            frames that outage.
        views: ``all``, ``outage`` (the outage inspector), ``map``, ``local``, ``signals``, ``errors``.
        size: image width and height in pixels.
        outages: outage numbers (1-based, as the replay lists them): each is shown at its end, framed.
        worst_of: the estimator whose final error picks ``"worst"``.
    """

    times: Sequence[str | float] = ("end",)
    views: Sequence[str] = ("all",)
    size: tuple[int, int] = (1600, 900)
    outages: Sequence[int] = ()
    worst_of: str = "ins"


def screenshot(
    recordings: Sequence[str | Path] | str | Path,
    output: str | Path,
    shots: Shots | None = None,
    *,
    timeout_s: float = 120.0,
    progress: Callable[[Path], None] | None = None,
) -> list[Path]:
    """Render PNG screenshots of recordings with a private headless Rerun viewer.

    Args:
        recordings: ``.rrd`` files written by :func:`replay`.
        output: a ``.png`` for one image, else a directory (or a ``.png`` whose stem prefixes the names).
        shots: which views at which times and outages, and the image size (default :class:`Shots`:
            the whole review layout at the end, 1600x900).
        timeout_s: longest wait for the viewer to start or load a recording.
        progress: called with each image's path as it is written.

    Returns:
        the written PNG paths. Needs a Vulkan renderer (Mesa's lavapipe on machines without a GPU).
    """
    from .viz.screenshot import check_size, render

    paths = [Path(recordings)] if isinstance(recordings, (str, Path)) else [Path(r) for r in recordings]
    if not paths:
        raise InputError("no recording to render", "give at least one .rrd made by replay")
    for rec in paths:
        if not rec.is_file():
            raise InputError(f"{rec}: no such recording", "make one with 'ionav-viz replay DRIVE'")
    shots = shots if shots is not None else Shots()
    width, height = check_size(*(int(x) for x in shots.size))
    out = Path(output)
    single = out.suffix.lower() == ".png" and len(paths) == 1 and (len(shots.times) + len(shots.outages)) * len(shots.views) == 1
    if single:
        check_output_file(out)
    elif out.suffix.lower() != ".png" and out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory", "several images go into a directory: name one", param="output")
    folder = out if out.suffix.lower() != ".png" else out.parent
    existing = next((p for p in [folder, *folder.parents] if p.exists()), Path("."))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{out}: cannot write in {existing} (permission denied)", "choose a writable output directory", param="output")
    spec = [f"{t:g}s" if isinstance(t, (int, float)) else str(t) for t in shots.times]
    return render(paths, Path(output), spec, list(shots.views), (width, height), timeout_s=timeout_s, progress=progress,
                  outages=[int(n) for n in shots.outages], worst_of=shots.worst_of)
