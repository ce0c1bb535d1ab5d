"""What several commands share: option declarations (once), option parsing, progress bars.

Heavy libraries are imported inside functions so that ``ionav-viz --help`` answers at once.
"""

from __future__ import annotations

import functools
import inspect
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import typer

if TYPE_CHECKING:
    from ..api.options import ReadOptions, RunOptions
    from ..experiment.outages import Placement
    from ..experiment.plan_file import FromPlan

# --- options shared by several commands -----------------------------------------------------
DataRoot = typer.Option(None, "--data-root",
                        help="Where IO-VNBD run names are found (default: $IONAV_DATA, else the per-user data "
                             "directory that fetch fills; 'ionav-viz list' names it).", show_default=False)
YawSign = typer.Option("auto", "--yaw-sign",
                       help="Sign of the yaw rate: auto (the source's convention, checked against the GNSS heading), "
                            "cw or ccw positive.")
ImuAxes = typer.Option(None, "--imu-axes",
                       help="MCAP/ROS bags: map the log's IMU axes to the body frame (x forward, y left, z up), e.g. "
                            "x=-y,y=x,z=z.", show_default=False)
TruthTopic = typer.Option(None, "--truth-topic",
                          help="MCAP/ROS bags: a reference trajectory to score against (NavSatFix, or "
                               "Odometry/PoseStamped with --truth-origin); estimators get only the GNSS topic.",
                          show_default=False)
TruthOrigin = typer.Option(None, "--truth-origin",
                           help="Where a local-frame reference lies: LAT,LON[,YAW] (its origin; x axis YAW deg from "
                                "east) or auto (fitted to the GNSS fixes).", show_default=False)
ImuMount = typer.Option(None, "--imu-mount",
                        help="MCAP/ROS bags: the IMU's mount, after --imu-axes: auto (estimated from the log), "
                             "roll=2,pitch=-7,yaw=5 (degrees) or quat=w,x,y,z.", show_default=False)
ImuTopic = typer.Option(None, "--imu-topic",
                        help="MCAP/ROS bags: the IMU topic (default: the one sensor_msgs/msg/Imu topic).",
                        show_default=False)
GnssTopic = typer.Option(None, "--gnss-topic",
                         help="MCAP/ROS bags: the GNSS topic (default: the one NavSatFix or LocationFix topic).",
                         show_default=False)
GnssVelocityTopic = typer.Option(None, "--gnss-velocity-topic", "--speed-topic",
                                 help="MCAP/ROS bags: the receiver's velocity (TwistStamped, world frame): GNSS "
                                      "speed and course (default: the one such topic), or 'none' (from the fixes).",
                                 show_default=False)
VehicleSpeedTopic = typer.Option(None, "--vehicle-speed-topic",
                                 help="MCAP/ROS bags: the vehicle's speed (wheel or CAN odometry: Odometry, or "
                                      "TwistStamped in a body frame; default: the one such topic), or 'none'.",
                                 show_default=False)
ImuTimeOffset = typer.Option(None, "--imu-time-offset",
                             help="MCAP/ROS bags: the IMU's stamps minus the receiver's, seconds (e.g. 0.3) or auto "
                                  "(estimated; refused when unresolved). Default: applied when clearly off.",
                             show_default=False)
ImuSamples = typer.Option(None, "--imu-samples",
                          help="MCAP/ROS bags: what an IMU sample below 50 Hz is: single (one instantaneous reading, "
                               "as phones log; the default) or averaged (a mean over its interval).",
                          show_default=False)
WarmUp = typer.Option("30s", "--warm-up",
                      help="GNSS time the filters get before the first outage (e.g. 30s, 0s); every estimator gets the "
                           "same outages.")
Stamps = typer.Option("header", "--stamps",
                      help="MCAP/ROS bags: time stamps from message headers (header) or the recorder's "
                           "receive time (log).")
OutageOpt = typer.Option("10s", "--outage", help="Length of each GNSS outage (whole seconds).")
PlanOpt = typer.Option(None, "--plan",
                       help="Exactly the outages of a plan file (NAME.outages.json, written by outage-log) instead of "
                            "--every/--at/--random/--on.", show_default=False)


ExportOpt = typer.Option(None, "--export",
                         help="Also write outages.csv, evo's TUM tracks per outage and GeoJSON/GPX tracks into "
                              "this folder.", show_default=False)
ExternalOpt = typer.Option(None, "--external",
                           help="NAME=TRAJECTORY: an estimate made outside ionav-viz on the plan's outaged log (.csv, "
                                ".tum or LOG:TOPIC), scored like the built-ins (repeatable; needs --plan).",
                           show_default=False)


def externals_of(values: Optional[list[str]]) -> dict[str, str]:
    """``["rl=rl.csv", ...]`` -> ``{"rl": "rl.csv"}`` (the library checks names and files)."""
    out: dict[str, str] = {}
    for value in values or []:
        name, sep, spec = value.partition("=")
        if not sep or not name.strip() or not spec.strip():
            raise typer.BadParameter(f"{value!r}: give NAME=TRAJECTORY, e.g. rl=rl.csv", param_hint="--external")
        if name.strip() in out:
            raise typer.BadParameter(f"{name.strip()!r} given twice", param_hint="--external")
        out[name.strip()] = spec.strip()
    return out


#: ``--outage`` of the commands that also take ``--plan`` (not given: 10 s, or the plan's length).
OutageOrPlanOpt = typer.Option(None, "--outage",
                               help="Length of each GNSS outage (whole seconds; default 10s, or the plan's).",
                               show_default=False)


def outage_and_placement(outage: Optional[str], plan: Optional[Path],
                         placement: PlacementArgs) -> tuple[Optional[float], Placement | FromPlan]:
    """The outage length and placement of a command with ``--plan``: with a plan, its length unless
    --outage is given (the library checks they agree) and its outages (no other placement)."""
    length = duration_s(outage, "--outage") if outage is not None else None
    if plan is None:
        return length, placement.placement
    if placement.option != "--outage":
        raise typer.BadParameter(f"give --plan or {placement.option.split()[0]}, not both", param_hint="--plan")
    from ..experiment.plan_file import FromPlan

    return length, FromPlan(plan)
ModelOpt = typer.Option(None, "--model", help="IDNN model directory (default: the shipped model).", show_default=False)
NoIdnnOpt = typer.Option(False, "--no-idnn", help="Without the IDNN (same as leaving idnn out of --estimators).")
EstimatorsOpt = typer.Option(None, "--estimators",
                             help="Which estimators run, comma-separated: ins, idnn, odo, ekf, gins, "
                                  "installed plug-ins or --external names (default: every built-in that applies).",
                             show_default=False)
EstimatorOpt = typer.Option(None, "--estimator",
                            help="Add your own estimator MODULE:NAME (a class or no-argument factory; repeatable). See "
                                 "'Your own estimator' in the README.", show_default=False)
EpochsDispOpt = typer.Option(None, "--epochs-disp",
                             help="Epochs of the displacement model (default: Table 5's 40; 100 with --from-model).",
                             show_default=False)
EpochsYawOpt = typer.Option(None, "--epochs-yaw",
                            help="Epochs of the orientation-rate model (default: Table 5's 60; 100 with --from-model).",
                            show_default=False)
TrainSeedOpt = typer.Option(0, "--seed", help="Random seed of the training (deterministic on the CPU).")
BiasFromOpt = typer.Option(None, "--bias-from",
                           help="Stationary drive for sensor biases (default: the drive's own stationary stretches).",
                           show_default=False)
Thresholds = typer.Option(None, "--threshold",
                          help="Override an event-detector threshold, e.g. hard_brake_g=0.4 (repeatable; see "
                               "'ionav-viz events --help').", show_default=False)
GnssLimitOpt = typer.Option(None, "--gnss-limit",
                            help="Override a GNSS quality threshold, e.g. jump_margin_m=5 (repeatable; names, "
                                 "defaults: 'GNSS quality' in docs/method.md).", show_default=False)
SpanOpt = typer.Option(None, "--span",
                       help="Only this stretch of each drive, START:END on the drive's own time, e.g. 0s:330s or 330s: "
                            "(outages and training windows stay inside it).", show_default=False)
StrictOpt = typer.Option(False, "--strict",
                         help="Refuse, instead of warning, when an outage lies in data the IDNN's model was trained on "
                              "(same file by sha256, overlapping time).")
ManifestOpt = typer.Option(None, "--manifest",
                           help="A manifest TSV (path, sha256, size_bytes) to use instead of the packaged one "
                                "(mirrors, tests).", show_default=False)


#: The options that say how drives are found and read: (parameter, typer option, type).
_SOURCE_OPTIONS = (
    ("data_root_opt", DataRoot, Optional[Path]), ("yaw_sign", YawSign, str), ("imu_topic", ImuTopic, Optional[str]),
    ("gnss_topic", GnssTopic, Optional[str]), ("gnss_velocity_topic", GnssVelocityTopic, Optional[str]),
    ("vehicle_speed_topic", VehicleSpeedTopic, Optional[str]), ("truth_topic", TruthTopic, Optional[str]),
    ("truth_origin", TruthOrigin, Optional[str]), ("stamps", Stamps, str),
    ("imu_axes", ImuAxes, Optional[str]), ("imu_mount", ImuMount, Optional[str]),
    ("imu_time_offset", ImuTimeOffset, Optional[str]), ("imu_samples", ImuSamples, Optional[str]),
    ("gnss_limit", GnssLimitOpt, Optional[list[str]]), ("span", SpanOpt, Optional[str]),
)


def _with_options(command: Callable[..., Any], options: tuple, argument: str,
                  build: Callable[[dict[str, Any]], Any]) -> Callable[..., Any]:
    """Add ``options`` ((parameter, typer option, type), ...) to ``command``'s signature, where typer
    reads them, and pass them to it built into one value, as the parameter ``argument``."""
    signature = inspect.signature(command)
    params = [p for name, p in signature.parameters.items() if name != argument]
    params += [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=option, annotation=kind)
               for name, option, kind in options]

    @functools.wraps(command)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        kwargs[argument] = build({name: kwargs.pop(name) for name, _, _ in options})
        return command(*args, **kwargs)

    wrapper.__signature__ = signature.replace(parameters=params)  # type: ignore[attr-defined]
    wrapper.__annotations__ = ({k: v for k, v in command.__annotations__.items() if k != argument}
                               | {n: t for n, _, t in options})
    return wrapper


def with_source_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Give a command the shared drive-reading options (declared once, in :data:`_SOURCE_OPTIONS`);
    the command receives them as one ``read: ReadOptions`` argument (checked by the library)."""
    def build(v: dict[str, Any]) -> ReadOptions:
        from ..core.gnss_quality import GnssLimits
        from ..sources.load import LogOptions, ReadOptions

        log = LogOptions(v["imu_topic"], v["gnss_topic"], v["gnss_velocity_topic"], v["stamps"], v["imu_axes"],
                         vehicle_speed_topic=v["vehicle_speed_topic"], imu_mount=v["imu_mount"],
                         truth_topic=v["truth_topic"], truth_origin=v["truth_origin"],
                         imu_time_offset=v["imu_time_offset"], imu_samples=v["imu_samples"])
        return ReadOptions(v["data_root_opt"], v["yaw_sign"], log,
                           GnssLimits().with_overrides(list(v["gnss_limit"] or [])), span=v["span"])

    return _with_options(command, _SOURCE_OPTIONS, "read", build)


def source_args(read: ReadOptions) -> list[str]:
    """The source options ``read`` (a ReadOptions built by :func:`with_source_options`) holds, as
    command-line arguments, those at their defaults left out: what a printed next command needs to
    read the drive as this one did."""
    from dataclasses import fields

    from ..core.gnss_quality import GnssLimits

    values = {"data_root_opt": read.data_root, "yaw_sign": read.yaw_sign,
              "span": None if read.span is None else str(read.span),
              "gnss_limit": [f"{f.name}={getattr(read.gnss_limits, f.name):.12g}" for f in fields(GnssLimits)
                             if getattr(read.gnss_limits, f.name) != getattr(GnssLimits(), f.name)] or None}
    args: list[str] = []
    for name, option, _ in _SOURCE_OPTIONS:
        value = values[name] if name in values else getattr(read.log, name)
        if value is not None and value != option.default:
            args += [x for v in (value if isinstance(value, list) else [value])
                     for x in (option.param_decls[0], str(v))]
    return args


_ESTIMATOR_OPTIONS = (
    ("estimator_names", EstimatorsOpt, Optional[str]), ("plugins", EstimatorOpt, Optional[list[str]]),
    ("model", ModelOpt, Optional[Path]), ("no_idnn", NoIdnnOpt, bool), ("bias_from", BiasFromOpt, Optional[str]),
    ("thresholds", Thresholds, Optional[list[str]]), ("warm_up", WarmUp, str), ("strict", StrictOpt, bool),
)


def with_estimator_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Give a command ``--estimators``, ``--estimator``, ``--model``, ``--no-idnn``, ``--bias-from``,
    ``--threshold`` and ``--strict`` (declared once, in :data:`_ESTIMATOR_OPTIONS`), as one ``run: RunOptions``
    argument."""
    def build(v: dict[str, Any]) -> RunOptions:
        from dataclasses import replace

        run = run_options(v["estimator_names"], v["plugins"], v["no_idnn"], v["model"], v["bias_from"], v["thresholds"],
                          v["warm_up"])
        return replace(run, strict=v["strict"])

    return _with_options(command, _ESTIMATOR_OPTIONS, "run", build)


def run_options(names: Optional[str], plugins: Optional[list[str]], no_idnn: bool = False, model: Optional[Path] = None,
                bias_from: Optional[str] = None, threshold_pairs: Optional[list[str]] = None,
                warm_up: str = "30s") -> RunOptions:
    """The :class:`~ionav_viz.api.RunOptions` the estimator options say (the library checks them)."""
    from ..analysis.events import EventThresholds
    from ..api import RunOptions

    chosen: Optional[list[str]] = None
    if names is not None:
        chosen = [n.strip() for n in names.split(",") if n.strip()]
        if not chosen:
            raise typer.BadParameter(f"{names!r}: name at least one estimator, e.g. ins,idnn",
                                     param_hint="--estimators")
        if no_idnn:
            chosen = [n for n in chosen if n != "idnn"]
            if not chosen and not plugins:
                raise typer.BadParameter("--no-idnn leaves no estimator", param_hint="--estimators")
    without = ("idnn",) if no_idnn and chosen is None else ()
    return RunOptions(chosen, tuple(plugins or ()), without, model, bias_from,
                      EventThresholds().with_overrides(list(threshold_pairs or [])),
                      warm_up_s=duration_s(warm_up, "--warm-up", allow_zero=True))


#: The options that place outages, shared by every command that places them.
EveryOpt = typer.Option(None, "--every", help="Start an outage every PERIOD (GNSS available in between), e.g. 30s.",
                        show_default=False)
AtOpt = typer.Option(None, "--at", help="Start outages at these times, e.g. 12s,40s.", show_default=False)
RandomOpt = typer.Option(None, "--random", help="Draw N non-overlapping outages at random (with --seed).",
                         show_default=False)
SeedOpt = typer.Option(0, "--seed", help="Seed for --random.")
OnOpt = typer.Option(None, "--on",
                     help="One outage centred on each detected event of these types, e.g. hard-brake,roundabout; "
                          "gnss-outage: the log's own losses (see 'ionav-viz events').", show_default=False)

_PLACEMENT_OPTIONS = (
    ("every", EveryOpt, Optional[str]), ("at", AtOpt, Optional[str]), ("random_count", RandomOpt, Optional[int]),
    ("seed", SeedOpt, int), ("on", OnOpt, Optional[str]),
)


@dataclass(frozen=True)
class PlacementArgs:
    """The outage placement the options chose, and the option that chose it (for messages)."""

    placement: Placement
    option: str
    on: Optional[tuple[str, ...]]  # the --on event types, if given


def with_placement_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Give a command ``--every``, ``--at``, ``--random``, ``--seed`` and ``--on`` (declared once, in
    :data:`_PLACEMENT_OPTIONS`), as one ``placement: PlacementArgs`` argument."""
    def build(v: dict[str, Any]) -> PlacementArgs:
        return placement_of(v["every"], v["at"], v["random_count"], v["seed"], v["on"])

    return _with_options(command, _PLACEMENT_OPTIONS, "placement", build)


def placement_of(every: Optional[str], at: Optional[str], random_count: Optional[int], seed: int,
                 on: Optional[str]) -> PlacementArgs:
    """The outage placement the options choose (at most one of them; the library checks its values)."""
    from ..experiment.outages import AroundEvents, At, Every, Random, Tile
    from .app import options_named

    chosen = [o for o, v in (("--every", every), ("--at", at), ("--random", random_count), ("--on", on))
              if v is not None]
    if len(chosen) > 1:
        raise typer.BadParameter(f"choose one outage placement, not {' and '.join(chosen)}")
    option = {"--every": f"--every {every}", "--at": f"--at {at}", "--random": f"--random {random_count}",
              "--on": f"--on {on}"}.get(chosen[0] if chosen else "", "--outage")
    with options_named(placement=option):  # the library checks the values; its errors name the option
        if on is not None:
            from ..analysis.events import current_type_names

            kinds = current_type_names(split_list(on))
            if not kinds:
                raise typer.BadParameter(f"{on!r}: name event types like hard-brake,roundabout", param_hint="--on")
            return PlacementArgs(AroundEvents(kinds), option, kinds)
        if every is not None:
            return PlacementArgs(Every(duration_s(every, "--every")), option, None)
        if at is not None:
            return PlacementArgs(At(tuple(_start_times(at))), option, None)
        if random_count is not None:
            return PlacementArgs(Random(random_count, seed), option, None)
        return PlacementArgs(Tile(), option, None)


def _start_times(text: str) -> list[float]:
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if not parts:
        raise typer.BadParameter(f"{text!r}: give start times like 12s,40s", param_hint="--at")
    return [0.0 if p in ("0", "0s") else duration_s(p, "--at") for p in parts]


QuietOpt = typer.Option(False, "--quiet", "-q", help="No progress bar and no summary on stderr.")

#: The options of a fleet run (many drives, each evaluated on its own; see api/fleet.py).
WorkersOpt = typer.Option(None, "--workers",
                          help="Run the drives in this many processes, each drive on its own (default, and at most: "
                               "every core this process may use); one bad drive is reported, not fatal (exit code 3).",
                          show_default=False)
ClusterOpt = typer.Option(None, "--cluster", metavar="ADDRESS",
                          help="Run the drives on a Dask cluster: its scheduler (tcp://HOST:8786) or 'local' "
                               "(needs ionav-viz[cluster]; the workers read the drives from the same paths).",
                          show_default=False)
FailFastOpt = typer.Option(False, "--fail-fast",
                           help="Many drives: stop at the first drive that fails, with its error (exit code 2).")
RunsOpt = typer.Option(None, "--runs", show_default=False,
                       help="IO-VNBD runs as drives of a fleet: all, a group (Vta, Vtb, Vw, Vf, ...) or a driver (A-E, "
                            "'driver E'); comma-separated or repeated; read under --data-root (see 'ionav-viz list').")
FleetRrdOpt = typer.Option(None, "--fleet-rrd", show_default=False,
                           help="Also write the fleet's overview recording (a table of the drives with each one's "
                                "worst outage and replay command, bar charts per estimator) to this .rrd; makes "
                                "evaluate a fleet run.")
DryRunOpt = typer.Option(False, "--dry-run",
                         help="List the drives that would be evaluated, with sizes and a time estimate; read nothing.")


def duration_s(text: str, option: str, allow_zero: bool = False) -> float:
    """A duration option -> seconds (``allow_zero``: 0 too); a bad one is a usage error naming the option."""
    from ..core.durations import NotADuration, parse_duration_s
    from ..core.errors import InputError

    try:
        return parse_duration_s(text, option, allow_zero)
    except InputError as exc:
        why = "is not a duration; use e.g. 10s, 500ms, 1m" if isinstance(exc, NotADuration) else \
            ("must be 0 or a positive duration" if allow_zero else "must be a positive duration")
        raise typer.BadParameter(f"{text!r} {why}", param_hint=option) from None


def durations_of(text: str, option: str) -> list[float]:
    """``"10s,30s,60s"`` -> seconds, each checked like one duration."""
    return [duration_s(part, option) for part in split_list(text)]


def split_list(text: str) -> tuple[str, ...]:
    """``"a, b,"`` -> ``("a", "b")``: a comma-separated option (the library checks the names)."""
    return tuple(k.strip() for k in text.split(",") if k.strip())


#: The width text tables fit when ``COLUMNS`` is unset and the output is no terminal (a pipe, a
#: file, a CI log): a 5-estimator report or a scenario overview was about 430 characters wide.
PIPED_WIDTH = 120


def terminal_width(stream=None) -> int:
    """The width text tables must fit: ``COLUMNS`` when set, else the terminal's when ``stream``
    (default stdout) is one, else :data:`PIPED_WIDTH` (``--json`` and ``--markdown`` have no width)."""
    import os
    import shutil

    columns = os.environ.get("COLUMNS", "")
    if columns.strip().isdigit() and int(columns) > 0:
        return max(int(columns), 40)
    stream = stream or sys.stdout
    if stream.isatty():
        return max(shutil.get_terminal_size().columns, 40)
    return PIPED_WIDTH


#: Said above the progress bar when the first run after an install compiles the filters (core/jit.py).
COMPILE_NOTICE = "compiling the filters for this machine, once after an install or an update: about 25 s"


def progress(quiet: bool):
    """A rich progress bar on stderr, or a no-op when quiet or not a terminal. While it shows, a first
    run's compilation of the filters is said above it (:data:`COMPILE_NOTICE`), once."""
    from contextlib import contextmanager, nullcontext

    if quiet or not sys.stderr.isatty():
        return nullcontext(None)
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from ..core import jit

    bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                   TimeElapsedColumn(), console=Console(stderr=True), transient=True)

    @contextmanager
    def showing():
        with bar:
            jit.on_first_compile(lambda: bar.console.print(COMPILE_NOTICE, highlight=False, markup=False))
            try:
                yield bar
            finally:
                jit.on_first_compile(None)

    return showing()


def progress_callback(bar, label: str):
    """A ``progress(label, done, total)`` callback that drives one task of ``bar`` (or does nothing)."""
    task: list[Any] = []

    def update(text: str, done: int, total: int) -> None:
        if bar is None:
            return
        if not task:
            task.append(bar.add_task(label, total=total))
        bar.update(task[0], completed=done, total=total, description=text)

    return update


# --- --help: the options most runs need first, the rest in named panels ------------------------------
#: panel -> its options; every other option stays in the first panel ("Options").
HELP_PANELS = {
    "Reading logs (MCAP, ROS bags, data root)": (DataRoot, YawSign, ImuAxes, TruthTopic, TruthOrigin, ImuMount,
                                                 ImuTopic, GnssTopic, GnssVelocityTopic, VehicleSpeedTopic,
                                                 ImuTimeOffset, ImuSamples, Stamps, GnssLimitOpt),
    "Estimators: models, biases, plug-ins": (ModelOpt, NoIdnnOpt, EstimatorOpt, BiasFromOpt, Thresholds, StrictOpt),
    "Where outages go": (PlanOpt, ExternalOpt, EveryOpt, AtOpt, RandomOpt, SeedOpt, OnOpt),
    "Many drives (fleets)": (WorkersOpt, ClusterOpt, FailFastOpt, RunsOpt, FleetRrdOpt, DryRunOpt),
}
for _panel, _options in HELP_PANELS.items():
    for _option in _options:
        _option.rich_help_panel = _panel
