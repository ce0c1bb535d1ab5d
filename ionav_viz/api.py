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
    iv.screenshot([result.path], "shots/", times=["worst"], views=["local"])
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .analysis.evaluate import DriveResult, evaluate_drive
from .analysis.events import EVENT_TYPES, GNSS_OUTAGE, MANOEUVRE_TYPES, Event, EventThresholds, detect_events
from .analysis.report import Report, run_summary_markdown
from .core.drive import Drive
from .core.errors import InputError
from .core.fileio import check_output_file
from .core.gnss_quality import GnssLimits
from .core.timing import stage
from .dataset.catalog import PAPER_TEST_RUNS, SCENARIOS, run_key
from .nav.bias import SensorBias, resolve_bias
from .nav.outages import AroundEvents, Placement, Tile, around, excluded_by_truth, outage_windows
from .nav.protocol import Estimator, applies
from .nav.registry import BUILTIN
from .nav.registry import resolve as resolve_estimators
from .nav.windows import make_windows
from .sources.load import LogOptions
from .sources.load import load_drive as _load_drive
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


def load_drive(
    spec: DriveLike,
    data_root: str | Path | None = None,
    *,
    yaw_sign: str = "auto",
    mcap: LogOptions | None = None,
    gnss_limits: GnssLimits | None = None,
) -> Drive:
    """Read a drive: a path (IO-VNBD ``V-*.csv``, ``.mcap``, ROS 1 ``.bag``, a ROS 2 bag folder or its
    ``metadata.yaml``, a KITTI raw drive folder), a bundled scenario name
    (``"roundabout"``, ``"stationary"``) or an IO-VNBD run name (``"V-Vw8"``) under ``data_root``
    (default ``$IONAV_DATA``, else the per-user data directory ``fetch`` fills).

    ``yaw_sign``: sign of the yaw rate (the CSV column, the MCAP gyro's z), ``"auto"`` (the
    source's convention, checked against the GNSS course), ``"cw"`` or ``"ccw"``; ``mcap``: topics,
    time stamps and IMU axes (``imu_axes``) for MCAP logs and ROS bags (a :class:`LogOptions`); ``gnss_limits``: thresholds of the GNSS quality checks
    that mark untrustworthy fixes (default :class:`GnssLimits`). A :class:`Drive` is returned as
    is.
    """
    if isinstance(spec, Drive):
        return spec
    if yaw_sign not in ("auto", "cw", "ccw"):
        raise InputError(f"yaw sign {yaw_sign!r} is not auto, cw or ccw", param="yaw_sign")
    with stage(f"read {spec}") as s:
        drive = _load_drive(str(spec), _data_root(data_root), yaw_sign, mcap, gnss_limits)
        s.detail = f"{drive.name}, {len(drive)} samples, {drive.duration_s:.1f} s"
    return drive


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


def _estimators_for(drives: Sequence[Drive], estimators: Sequence[str | Estimator] | None, plugins: Sequence[str | Estimator],
                    without: Sequence[str], model: Any) -> list[Estimator]:
    """The estimators that apply to every one of ``drives`` (one report compares them all on the
    same outages). A default one left out is said at ``-v`` (by its ``applies``); one the caller
    named (in ``estimators`` or ``plugins``), with a warning; none left is an error."""
    chosen = resolve_estimators(estimators, plugins=plugins, without=without, model=model)
    defaults = set(BUILTIN) if estimators is None else set()
    kept = []
    for est in chosen:
        missing = [d.name for d in drives if not applies(est, d)]
        if not missing:
            kept.append(est)
        elif est.name not in defaults:
            log.warning("%s left out: it does not apply to %s", est.label, ", ".join(missing))
    if not kept:
        raise InputError(f"none of the chosen estimators ({', '.join(e.name for e in chosen)}) applies to {', '.join(d.name for d in drives)}",
                         "choose others with --estimators (ins always applies)", param="estimators")
    return kept


def _bias_for(bias_from: DriveLike | SensorBias | None, data_root: Any, load_kw: dict) -> Callable[[Drive], SensorBias]:
    """``drive -> biases``: a given :class:`SensorBias`, a stationary drive's (read once), or each drive's own."""
    if isinstance(bias_from, SensorBias):
        return lambda drive: bias_from
    stationary = load_drive(bias_from, data_root, **load_kw) if bias_from is not None else None
    return lambda drive: resolve_bias(drive, stationary)


def _check_event_types(types: Sequence[str]) -> None:
    unknown = [t for t in types if t not in EVENT_TYPES]
    if unknown or not types:
        raise InputError(f"unknown event type(s) {', '.join(unknown) or '(none)'}", f"choose from {', '.join(EVENT_TYPES)}")


def _gnss_gaps(placement: Placement, events: list[Event] | None) -> list[tuple[float, float]]:
    """The log's own GNSS outages to bridge: ``(last good fix s, first good fix s)`` of each
    ``gnss-outage`` event, when the placement asks for them."""
    if not isinstance(placement, AroundEvents) or GNSS_OUTAGE not in placement.types:
        return []
    return [(e.t0_s, e.t1_s) for e in events or [] if e.type == GNSS_OUTAGE]


def _starts(drive: Drive, windows, placement: Placement, outage_s: float, events: list[Event] | None) -> tuple[np.ndarray, str, int]:
    """Outage starts, the placement's description, and how many outages bad GNSS truth excluded."""
    n = outage_windows(outage_s)
    if isinstance(placement, AroundEvents):
        _check_event_types(placement.types)
        if GNSS_OUTAGE in placement.types:  # bridged separately (_gnss_gaps): no synthetic outage on them
            rest = tuple(t for t in placement.types if t != GNSS_OUTAGE)
            gaps = _gnss_gaps(placement, events)
            if not rest:
                if not gaps:
                    raise InputError(f"{drive.source}: no GNSS outage of 2 s or more in this drive", f"see 'ionav-viz events {drive.source}'")
                return np.zeros(0, dtype=int), f"every estimator through the log's own {len(gaps)} GNSS outage(s), from the last good fix", 0
            starts, description, excluded = _starts(drive, windows, AroundEvents(rest), outage_s, events)
            return starts, f"{description}; and the log's own {len(gaps)} GNSS outage(s)", excluded
        targets = placement.targets(events or [])
        spans = [(e.t0_s, e.t1_s) for e in targets]
        starts, used = around(windows, spans, n)
        excluded = excluded_by_truth(windows, n, lambda w: around(w, spans, n)[0])
        if len(used) < len(targets):
            log.warning("%s: %d of %d %s event(s) got no outage (overlapping another, too near a gap or an end, or on bad GNSS truth)",
                        drive.name, len(targets) - len(used), len(targets), "/".join(placement.types))
        if len(starts) == 0:
            raise InputError(f"{drive.source}: no {' or '.join(placement.types)} event with room for a {outage_s:g} s outage",
                             f"see 'ionav-viz events {drive.source}'")
        return starts, placement.describe(outage_s, len(used), len(targets)), excluded
    starts = placement.starts(windows, n, events or ())
    return starts, placement.describe(outage_s), excluded_by_truth(windows, n, lambda w: placement.starts(w, n, events or ()))


def evaluate(
    drives: Sequence[DriveLike] | DriveLike,
    outage_s: float = 10.0,
    placement: Placement | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    model: Any = None,
    *,
    plugins: Sequence[str | Estimator] = (),
    without: Sequence[str] = (),
    bias_from: DriveLike | SensorBias | None = None,
    data_root: str | Path | None = None,
    thresholds: EventThresholds | None = None,
    title: str | None = None,
    yaw_sign: str = "auto",
    mcap: LogOptions | None = None,
    gnss_limits: GnssLimits | None = None,
    progress: Progress | None = None,
) -> Report:
    """Every estimator on the same GNSS outages of each drive, scored with the paper's metrics.

    Args:
        drives: drives or what names them (see :func:`load_drive`).
        outage_s: length of each outage, whole seconds.
        placement: where outages go (default :class:`Tile`, the paper's consecutive outages).
            A drive too short for one outage is skipped with a warning.
        estimators: names (``"ins"``, ``"idnn"``, entry-point names, ``"module:NAME"``) or
            estimator objects; default every built-in that applies (the IDNN when a model exists).
        model: the IDNN's model (an ``IdnnModel`` or its directory); default the shipped one.
        plugins: estimators added to ``estimators`` (or to the default ones), as ``--estimator``:
            ``"module:NAME"``, ``"path/to/file.py:NAME"`` or objects.
        without: built-in names left out of the default estimators (``("idnn",)`` is ``--no-idnn``).
        bias_from: a stationary drive (or ready :class:`SensorBias`) for the sensor biases;
            default each drive's own stationary stretches.
        thresholds: event-detector thresholds (for :class:`AroundEvents`).
        title: the report's group name (a scenario), shown in its tables.
        gnss_limits: thresholds of the GNSS quality checks (see :func:`load_drive`); outages
            go only where every window has good truth, and the report counts what was excluded.

    Returns:
        a :class:`Report`; ``report.to_json()`` is what ``ionav-viz evaluate --json`` prints.
    """
    items = [drives] if isinstance(drives, (Drive, str, Path)) else list(drives)
    if not items:
        raise InputError("no drive to evaluate", "give at least one drive")
    placement = placement or Tile()
    outage_windows(outage_s)  # checked before any drive is read
    resolve_estimators(estimators, plugins=plugins, without=without, model=model)  # checked before any drive is read
    load_kw = {"yaw_sign": yaw_sign, "mcap": mcap, "gnss_limits": gnss_limits}
    bias_of = _bias_for(bias_from, data_root, load_kw)
    loaded = [load_drive(item, data_root, **load_kw) for item in items]
    ests = _estimators_for(loaded, estimators, plugins, without, model)
    results = []
    for i, drive in enumerate(loaded):
        if progress:
            progress(drive.name, i, len(items))
        windows = make_windows(drive)
        events = detect_events(drive, thresholds or EventThresholds()) if isinstance(placement, AroundEvents) else None
        starts, _, excluded = _starts(drive, windows, placement, outage_s, events)
        gaps = _gnss_gaps(placement, events)
        if isinstance(placement, Tile) and len(starts) == 0:
            log.warning("%s: too short for a single %g s outage%s; skipped", drive.name, outage_s,
                        " on good GNSS truth" if excluded else "")
            continue
        bias = bias_of(drive)
        results.append(evaluate_drive(drive, outage_s, bias=bias, estimators=ests, starts=starts, windows=windows,
                                      excluded_outages=excluded, gnss_gaps=gaps))
    if progress:
        progress("done", len(items), len(items))
    if not results:
        raise InputError(f"no {outage_s:g} s outage fits in {', '.join(_name(d) for d in items)}", "use shorter outages", param="outage_s")
    return Report(results, title)


def evaluate_by_event(
    drives: Sequence[DriveLike],
    outage_s: float = 10.0,
    types: Sequence[str] | None = None,
    estimators: Sequence[str | Estimator] | None = None,
    model: Any = None,
    *,
    plugins: Sequence[str | Estimator] = (),
    without: Sequence[str] = (),
    bias_from: DriveLike | SensorBias | None = None,
    data_root: str | Path | None = None,
    thresholds: EventThresholds | None = None,
    yaw_sign: str = "auto",
    mcap: LogOptions | None = None,
    gnss_limits: GnssLimits | None = None,
) -> dict[str, Report]:
    """One report per manoeuvre type: an outage centred on each detected event, across ``drives``."""
    kinds = tuple(types) if types else MANOEUVRE_TYPES
    _check_event_types(kinds)
    n = outage_windows(outage_s)
    resolve_estimators(estimators, plugins=plugins, without=without, model=model)  # checked before any drive is read
    load_kw = {"yaw_sign": yaw_sign, "mcap": mcap, "gnss_limits": gnss_limits}
    bias_of = _bias_for(bias_from, data_root, load_kw)
    th = thresholds or EventThresholds()
    per_type: dict[str, list[DriveResult]] = {k: [] for k in kinds}
    loaded = [load_drive(item, data_root, **load_kw) for item in drives]
    ests = _estimators_for(loaded, estimators, plugins, without, model)
    for drive in loaded:
        windows = make_windows(drive)
        bias = bias_of(drive)
        found = detect_events(drive, th, kinds)
        for kind in kinds:
            if kind == GNSS_OUTAGE:  # the log's own losses: bridged, scored at the first good fix after
                gaps = _gnss_gaps(AroundEvents((kind,)), found)
                if gaps:
                    per_type[kind].append(evaluate_drive(drive, outage_s, bias=bias, estimators=ests, starts=np.zeros(0, dtype=int),
                                                         windows=windows, gnss_gaps=gaps))
                continue
            starts = AroundEvents((kind,)).starts(windows, n, found)
            excluded = excluded_by_truth(windows, n, lambda w, kind=kind, found=found: AroundEvents((kind,)).starts(w, n, found))
            if len(starts):
                per_type[kind].append(evaluate_drive(drive, outage_s, bias=bias, estimators=ests, starts=starts, windows=windows,
                                                     excluded_outages=excluded))
    reports = {kind: Report(results, kind) for kind, results in per_type.items() if results}
    if not reports:
        raise InputError(f"no {', '.join(kinds)} event with room for a {outage_s:g} s outage in {', '.join(_name(d) for d in drives)}",
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
    model: Any = None,
    plugins: Sequence[str | Estimator] = (),
    without: Sequence[str] = (),
    bias_from: DriveLike | SensorBias | None = None,
    data_root: str | Path | None = None,
    thresholds: EventThresholds | None = None,
    yaw_sign: str = "auto",
    mcap: LogOptions | None = None,
    gnss_limits: GnssLimits | None = None,
    progress: Progress | None = None,
    connect: str | None = None,
) -> ReplayResult:
    """Replay ``drive`` with GNSS outages, run the estimators side by side and write a ``.rrd``.

    Args:
        drive, outage_s, placement, estimators, model, bias_from, thresholds: as for :func:`evaluate`
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
        raise InputError(f"{out}: a recording must end in .rrd", "choose a name like drive.rrd")
    placement = placement or Tile()
    load_kw = {"yaw_sign": yaw_sign, "mcap": mcap, "gnss_limits": gnss_limits}
    d = load_drive(drive, data_root, **load_kw)
    with stage("windows") as s:
        windows = make_windows(d)
        s.detail = f"{len(windows)} of 1 s"
    with stage("manoeuvres") as s:
        events = detect_events(d, thresholds or EventThresholds())
        s.detail = f"{len(events)} detected"
    starts, description, excluded = _starts(d, windows, placement, outage_s, events)
    gaps = _gnss_gaps(placement, events)
    if len(starts) == 0 and not gaps:
        raise InputError(f"{d.source}: drive too short ({d.duration_s:.1f} s) for a {outage_s:g} s outage", "use shorter outages", param="outage_s")
    default = out is None
    out = check_output_file(Path(RECORDINGS_DIR, f"{d.name}.rrd") if default else out, create_parent=default)  # before the work
    chosen = _estimators_for([d], estimators, plugins, without, model)
    bias = _bias_for(bias_from, data_root, load_kw)(d)
    result = evaluate_drive(d, outage_s, bias=bias, estimators=chosen, starts=starts, windows=windows, excluded_outages=excluded,
                            gnss_gaps=gaps)
    report = Report([result])
    summary = _summary_markdown(result, report, description)
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
    n = result.n_windows
    outages = [Outage(i + 1, float(windows.t0_s[k]), float(windows.t0_s[k] + n), int(k)) for i, k in enumerate(starts)]
    return ReplayResult(out, report, outages, description, result, events)


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


def screenshot(
    recordings: Sequence[str | Path] | str | Path,
    output: str | Path,
    times: Sequence[str | float] = ("end",),
    views: Sequence[str] = ("all",),
    size: tuple[int, int] = (1600, 900),
    *,
    timeout_s: float = 120.0,
    progress: Callable[[Path], None] | None = None,
    outages: Sequence[int] = (),
    worst_of: str = "ins",
) -> list[Path]:
    """Render PNG screenshots of recordings with a private headless Rerun viewer.

    Args:
        recordings: ``.rrd`` files written by :func:`replay`.
        output: a ``.png`` for one image, else a directory (or a ``.png`` whose stem prefixes the names).
        times: seconds (float), ``"35s"``, ``"worst"`` or ``"end"``. ``"worst"`` is the end of the
            outage with the largest final position error of ``worst_of`` (default the INS DR), and
            frames that outage.
        views: ``all``, ``outage`` (the outage inspector), ``map``, ``local``, ``signals``, ``errors``.
        size: image width and height in pixels.
        outages: outage numbers (1-based, as the replay lists them): each is shown at its end, framed.
        worst_of: the estimator whose final error picks ``"worst"``.

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
    width, height = check_size(*(int(x) for x in size))
    out = Path(output)
    single = out.suffix.lower() == ".png" and len(paths) == 1 and (len(times) + len(outages)) * len(views) == 1
    if single:
        check_output_file(out)
    elif out.suffix.lower() != ".png" and out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory", "several images go into a directory: name one", param="output")
    folder = out if out.suffix.lower() != ".png" else out.parent
    existing = next((p for p in [folder, *folder.parents] if p.exists()), Path("."))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{out}: cannot write in {existing} (permission denied)", "choose a writable output directory", param="output")
    spec = [f"{t:g}s" if isinstance(t, (int, float)) else str(t) for t in times]
    return render(paths, Path(output), spec, list(views), (width, height), timeout_s=timeout_s, progress=progress,
                  outages=[int(n) for n in outages], worst_of=worst_of)
