"""The values every API function shares: how estimators run (:class:`RunOptions`), and the
checks on the arguments they take, each in one place."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, get_args

import numpy as np

from ..analysis.events import EVENT_TYPES, EventThresholds
from ..core.drive import Drive
from ..core.errors import InputError
from ..experiment.outages import outage_windows
from ..experiment.registry import BUILTIN
from ..experiment.registry import resolve as resolve_estimators
from ..nav.bias import SensorBias, resolve_bias
from ..nav.protocol import Estimator, applies
from ..sources.load import LogOptions, ReadOptions, load_drive, with_deprecated_log

if TYPE_CHECKING:
    from ..experiment.outages import Placement
    from ..experiment.plan_file import FromPlan

log = logging.getLogger("ionav_viz")

#: ``progress(label, done, total)``: called as long work advances (e.g. to drive a progress bar).
Progress = Callable[[str, int, int], None]
DriveLike = Drive | str | Path


#: GNSS time before the first outage (s): see RunOptions.warm_up_s.
DEFAULT_WARM_UP_S = 30.0


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
        warm_up_s: GNSS time every estimator gets before the first outage (s): placements that
            choose where outages go (tiled, every, random, on manoeuvres) leave it free at the
            drive's start; outages at given times or from a plan are where they are said to be.
            30 s: the filters' position and velocity settle within it on the logs measured
            (``docs/method.md``, "Warm-up").
        strict: refuse, instead of warning, when an outage lies in data the IDNN's model was
            trained on (the same file by sha256, overlapping time; :mod:`ionav_viz.learning.provenance`).
    """

    estimators: Sequence[str | Estimator] | None = None
    plugins: Sequence[str | Estimator] = ()
    without: Sequence[str] = ()
    model: Any = None
    bias_from: DriveLike | SensorBias | None = None
    thresholds: EventThresholds = field(default_factory=EventThresholds)
    warm_up_s: float = DEFAULT_WARM_UP_S
    strict: bool = False

    def __post_init__(self) -> None:
        for name in ("estimators", "plugins", "without"):  # estimators="ins" was "unknown estimator 'i'"
            value = getattr(self, name)
            if isinstance(value, (str, bytes)) or (value is not None and not isinstance(value, Iterable)):  # 5 too
                raise InputError(f"{name}={value!r} is not a sequence of estimators",
                                 f"give a list, e.g. {name}=['ins']", param=name)
        if not (isinstance(self.warm_up_s, (int, float)) and math.isfinite(self.warm_up_s)
                and 0 <= self.warm_up_s <= 3600):
            raise InputError(f"warm-up {self.warm_up_s!r} is not 0-3600 seconds",
                             "give e.g. 30s, or 0s for outages from the drive's start", param="warm_up")

    def chosen(self) -> list[Estimator]:
        """The estimators, resolved (plug-ins loaded) and checked: before any drive is read."""
        from ..learning.idnn import IdnnEstimator

        chosen = resolve_estimators(self.estimators, plugins=self.plugins, without=self.without, model=self.model)
        for est in chosen:
            if isinstance(est, IdnnEstimator) and self.strict:
                est.strict = True
        return chosen

    def applying_to(self, drives: Sequence[Drive]) -> list[Estimator]:
        """The estimators that apply to every one of ``drives`` (one report compares them all on
        the same outages). A default one left out is said at ``-v`` (by its ``applies``); one the
        caller named (in ``estimators`` or ``plugins``), with a warning; none left is an error."""
        defaults = set(BUILTIN) if self.estimators is None else set()
        chosen = self.chosen()
        kept = []
        for est in chosen:
            missing = [d.name for d in drives if not applies(est, d)]
            if not missing:
                kept.append(est)
            elif est.name not in defaults:
                need = getattr(est, "requires", "")
                log.warning("%s left out: it does not apply to %s%s", est.label, ", ".join(missing),
                            f" (it needs {need})" if need else "")
        if not kept:
            raise InputError(f"none of the chosen estimators ({', '.join(e.name for e in chosen)}) applies to "
                             f"{', '.join(d.name for d in drives)}",
                             "choose others (ins always applies)", param="estimators")
        return kept

    def bias_of(self, read: ReadOptions) -> Callable[[Drive], SensorBias]:
        """``drive -> biases``: a given :class:`SensorBias`, a stationary drive's (read once), or each drive's own."""
        if isinstance(self.bias_from, SensorBias):
            fixed = self.bias_from
            return lambda drive: fixed
        stationary = load_stationary(self.bias_from, read)
        return lambda drive: resolve_bias(drive, stationary)


def load_stationary(bias_from: DriveLike | None, read: ReadOptions | None) -> Drive | None:
    """The stationary drive ``bias_from`` for the sensor biases (None: none given); a file it cannot
    be read from is said as ``bias_from``'s (--bias-from), not as one of the drives'."""
    if bias_from is None:
        return None
    try:
        return load_drive(bias_from, read)
    except InputError as exc:
        if exc.param is None:
            exc.param = "bias_from"
        raise


def options_of(run: RunOptions | None, estimators: Sequence[str | Estimator] | None, read: ReadOptions | None,
             mcap: LogOptions | None, truth: str | None = None) -> tuple[RunOptions, ReadOptions]:
    """The run and read options of a call: ``estimators`` is a shortcut for ``run.estimators``,
    ``truth`` for ``read.log.truth_topic``."""
    if run is not None and not isinstance(run, RunOptions):  # run="x" was an AttributeError naming no argument
        raise InputError(f"run={run!r} is not a RunOptions", "give run=iv.RunOptions(...), or leave it out",
                         param="run")
    run = run if run is not None else RunOptions()
    if estimators is not None:
        if run.estimators is not None:
            raise InputError("estimators given twice (as estimators= and in run=)", "give them once",
                             param="estimators")
        run = replace(run, estimators=estimators)
    read = with_deprecated_log(read, mcap)
    if truth is not None:
        if not isinstance(truth, str) or not truth:
            raise InputError(f"truth={truth!r} is not a topic name",
                             "give the reference's topic, e.g. truth='/reference/fix'", param="truth")
        if read.log.truth_topic not in (None, truth):
            raise InputError("the reference given twice (as truth= and in read.log.truth_topic)", "give it once",
                             param="truth")
        read = replace(read, log=replace(read.log, truth_topic=truth))
    return run, read



def check_event_types(types: Sequence[str]) -> None:
    from ..analysis.events import RENAMED_TYPES

    unknown = [t for t in types if t not in EVENT_TYPES]
    if unknown or not types:
        renamed = "; ".join(f"{t} is {RENAMED_TYPES[t]} now" for t in unknown if t in RENAMED_TYPES)
        raise InputError(f"unknown event type(s) {', '.join(unknown) or '(none)'}",
                         renamed or f"choose from {', '.join(EVENT_TYPES)}", param="placement")



def placement_of(placement: Placement | FromPlan | None, plan: str | Path | None) -> Placement | FromPlan:
    """The placement of a call: ``plan`` (a plan file) or ``placement``, default :class:`Tile`."""
    from ..experiment.outages import Tile
    from ..experiment.plan_file import FromPlan

    check_placement(placement, plan)
    if plan is not None:
        return FromPlan(plan)
    return placement or Tile()


def check_placement(placement: object, plan: str | Path | None) -> None:
    """``placement`` a placement (or None), and not given beside a plan file; reads nothing."""
    from ..experiment.outages import Placement
    from ..experiment.plan_file import FromPlan

    if plan is not None and placement is not None:
        raise InputError("outages given twice (a plan and a placement)", "give a plan or a placement, not both",
                         param="plan")
    if placement is not None and not isinstance(placement, (*get_args(Placement), FromPlan)):  # 5 was an AttributeError
        raise InputError(f"placement={placement!r} is not a placement",
                         "give iv.Tile(), iv.Every(30.0), iv.At([...]), iv.Random(n), iv.AroundEvents([...]) "
                         "or a plan (plan=FILE), or leave it out", param="placement")


def with_externals(run: RunOptions, external: Mapping[str, str | Path] | None,
                   placement: Placement | FromPlan) -> RunOptions:
    """``run`` with the external estimates (``{name: trajectory}``, see :mod:`ionav_viz.nav.external`)
    added to its plug-ins; they need the plan of the outaged log they were made on."""
    from ..experiment.plan_file import FromPlan
    from ..nav.external import External
    from ..nav.protocol import validate
    from ..sources.trajectory import read_trajectory

    if not external:
        return run
    check_externals(external, isinstance(placement, FromPlan))
    built = []
    for name, spec in external.items():
        if str(name) in BUILTIN:  # an external 'ins' became the baseline every improvement is measured against
            raise InputError(f"--external {name}: {name!r} is a built-in estimator's name",
                             f"name the trajectory otherwise, e.g. my-{name}={spec}", param="external")
        est = External(str(name), read_trajectory(spec))
        validate(est, f"--external {name}")
        built.append(est)
    names = {est.name for est in built} - set(BUILTIN)
    estimators = run.estimators
    if estimators is not None:  # --estimators ins,mine with --external mine=...: 'mine' is the external, run once
        estimators = [e for e in estimators if not (isinstance(e, str) and e.strip() in names)]
    return replace(run, estimators=estimators, plugins=tuple(run.plugins) + tuple(built))


def check_externals(external: object, on_a_plan: bool) -> None:
    """``external`` (when given) a mapping of names to trajectories, scored on a plan's outages
    (``on_a_plan``); reads nothing."""
    if not external:
        return
    if not hasattr(external, "items"):
        raise InputError(f"external={external!r} is not a mapping of names to trajectories",
                         "e.g. external={'rl': 'rl.csv'}", param="external")
    if not on_a_plan:
        raise InputError("an external estimate is scored on the outages of the log it ran on",
                         "score it on that log's plan (its NAME.outages.json)", param="external")


def input_paths(drives: Sequence[DriveLike] | DriveLike | None, read: ReadOptions | None = None, *,
                run: RunOptions | None = None, plan: str | Path | Placement | FromPlan | None = None,
                external: Mapping[str, str | Path] | None = None) -> list[Path]:
    """The files and folders a call reads: its drives (resolved as :func:`load_drive` resolves them),
    a plan file, external trajectories, a bias drive, a model directory and plug-in files; for
    :func:`~ionav_viz.core.fileio.refuse_output_onto_input` before any work. A name that does not
    resolve is left out (its reader says why later)."""
    from ..experiment.plan_file import FromPlan
    from ..sources.load import with_deprecated_log
    from ..sources.resolve import data_root, resolve_drive

    read = with_deprecated_log(read, None)  # read="x" is refused naming it, as load_drive refuses it
    items = [drives] if isinstance(drives, (Drive, str, Path)) else list(drives or [])
    if run is not None and isinstance(run.bias_from, (Drive, str, Path)):
        items.append(run.bias_from)
    out: list[Path] = []
    for item in items:
        if isinstance(item, Drive):
            # a drive built in memory names a file it may not have come from
            if item.source and Path(item.source).exists():
                out.append(Path(item.source))
            continue
        try:
            out.append(resolve_drive(str(item), data_root(read.data_root)))
        except InputError:
            continue
    if isinstance(plan, FromPlan):
        plan = plan.path
    if isinstance(plan, (str, Path)):
        out.append(Path(plan))
    for spec in (external.values() if hasattr(external, "values") else []):
        text = str(spec)
        out.append(Path(text) if Path(text).exists() or ":" not in text else Path(text.rsplit(":", 1)[0]))
    if run is not None:
        if isinstance(run.model, (str, Path)):
            out.append(Path(run.model))
        for spec in [*(run.estimators or []), *run.plugins]:
            if isinstance(spec, str) and ".py:" in spec:
                out.append(Path(spec.rsplit(":", 1)[0]).expanduser())
    return out


def refuse_export_onto_inputs(export: str | Path, inputs: Sequence[Path]) -> None:
    """``--export DIR`` writes ``outages.csv``, ``tracks.geojson`` and ``tracks.gpx`` into DIR and
    replaces ``DIR/tum/<drive>`` whole (:mod:`ionav_viz.analysis.exports`): none may be an input,
    and DIR may not lie inside an input folder (other files already in DIR are left alone)."""
    from ..core.fileio import refuse_output_onto_input

    folder = Path(export)
    refuse_output_onto_input(folder, inputs, param="export")
    for name in ("outages.csv", "tracks.geojson", "tracks.gpx"):
        refuse_output_onto_input(folder / name, inputs, param="export")
    refuse_output_onto_input(folder / "tum", inputs, param="export", output_is_folder=True)


def lengths_of(lengths_s: Sequence[float], placement: object = None) -> list[float]:
    """Several outage lengths (s), increasing and distinct, each checked before any work; refused
    with only the log's own GNSS losses as the ``placement``: each loss has its own length."""
    from ..experiment.outages import GNSS_OUTAGE

    lengths = sorted({float(x) for x in lengths_s})
    if not lengths:
        raise InputError("no outage length given", "give one or more, e.g. 10, 30, 60", param="outage_s")
    if len(lengths) > 1 and tuple(getattr(placement, "event_types", ())) == (GNSS_OUTAGE,):
        raise InputError("several outage lengths, but the log's own GNSS outages (gnss-outage) each have "
                         "their own length",
                         "leave out the outage lengths, or place synthetic outages too (e.g. --on "
                         "gnss-outage,hard-brake)",
                         param="outage_s")
    for length in lengths:
        windows_of(length)
    return lengths


#: The outage length when none is given (s).
DEFAULT_OUTAGE_S = 10.0


def windows_of(outage_s: float | None, placement: object = None) -> int:
    """The one place seconds become windows: the outage length (whole seconds; None: a plan file's
    length, else :data:`DEFAULT_OUTAGE_S`) as windows. A plan file's placement fixes the length."""
    from ..experiment.plan_file import FromPlan

    if isinstance(placement, FromPlan):
        planned = placement.file.outage_s
        if outage_s is not None and float(outage_s) != planned:
            raise InputError(f"outage length {outage_s:g} s, and the plan {placement.path} has {planned:g} s outages",
                             "leave the outage length out with a plan", param="outage_s")
        outage_s = planned
    return outage_windows(DEFAULT_OUTAGE_S if outage_s is None else outage_s)



def name_of(item: DriveLike) -> str:
    return item.name if isinstance(item, Drive) else str(item)


#: Above this share of samples with untrustworthy GNSS, "no outage fits" is the receiver's doing,
#: not the outage length's.
POOR_GNSS_SHARE = 0.5


def each_length(lengths: Sequence[float], one: Callable[[float], Any]) -> list[tuple[float, Any]]:
    """``(length, one(length))`` for each outage length, each warning the lengths repeat (of the same
    drives) printed once; a length the drives have no room for (``one`` refuses it on the outage or
    the warm-up, before writing anything) is left out with a warning when another fits; when none
    fits, the first one's error."""
    from ..core.warnings_log import printing_once

    done, refused = [], []
    with printing_once():
        for length in lengths:
            try:
                done.append((length, one(length)))
            except InputError as exc:
                if exc.param not in ("outage_s", "warm_up"):  # not a matter of this length
                    raise
                refused.append(exc)
    if not done:
        raise refused[0]
    for exc in refused:
        log.warning("%s; that length is left out (%s)", exc.message, exc.hint)
    return done


def too_short(drive: Drive, n_windows: int, run: RunOptions, read: ReadOptions | None = None) -> InputError:
    """Why no ``n_windows`` s outage fits in ``drive`` (neither placed nor excluded for bad GNSS):
    its length, the span it was cut to and the warm-up before the first outage, and what to change;
    the option blamed is the warm-up when the outage alone would fit, else the outage length; the
    hint names only what can help (shorter outages not when not even a 1 s one fits after the
    warm-up)."""
    span = getattr(read, "span", None)
    warm = float(run.warm_up_s)
    what = (f"{drive.source or drive.name}: too short for a {n_windows:g} s outage"
            + (f" after the {warm:g} s warm-up" if warm > 0 else "")
            + f" ({drive.duration_s:.1f} s" + (f" in the span {span}" if span is not None else "") + ")")
    warm_up_blamed = warm > 0 and drive.duration_s >= n_windows + 1  # the outage alone would fit (after its start fix)
    shortest_fits = drive.duration_s >= max(warm, 1.0) + 1  # a 1 s outage after the warm-up: shorter outages can help
    if drive.duration_s < 2.0:  # no outage at all: the shortest needs its start fix's second and its own
        fixes = ["a longer drive (the shortest outage, 1 s, needs 2 s of it)"]
    elif warm_up_blamed:
        fixes = (["shorter outages"] if shortest_fits else []) + ["a shorter warm-up"]
    elif warm > 0 and not shortest_fits:
        fixes = ["shorter outages and a shorter warm-up"]
    else:
        fixes = ["shorter outages"]
    fixes += ["a longer span"] if span is not None else []
    return InputError(what, "use " + ", or ".join(fixes), param="warm_up" if warm_up_blamed else "outage_s")


def no_outage_fits(drives: Sequence[Drive], n_windows: int, where: str) -> InputError:
    """The error for ``where`` (drives or a file) when no outage of ``n_windows`` s fits: when most
    of the GNSS is marked untrustworthy, that says so and why (shorter outages would not help)."""
    from ..core.gnss_quality import count_by_fault

    # beside a reference the receiver's fixes count too: an outage starts from them
    faults = np.concatenate([d.gnss_fault | (d.receiver_fault if d.has_reference and d.receiver_fault is not None
                                             else 0)
                             for d in drives]) if drives else np.zeros(0, dtype=np.uint16)
    bad = float(np.mean(faults != 0)) if len(faults) else 0.0
    if bad >= POOR_GNSS_SHARE:
        counts = sorted(count_by_fault(faults).items(), key=lambda kv: -kv[1])
        reasons = ", ".join(f"{name} {n / len(faults):.0%}" for name, n in counts)
        hint = ("shorter outages will not help: check the receiver's fixes (the recording's GNSS quality view), or "
                "loosen the checks with --gnss-limit (docs/method.md, GNSS quality)")
        sigmas = [d.columns["gnss_sigma_m"] for d in drives if "gnss_sigma_m" in d.columns]
        if counts[0][0] == "poor-accuracy" and sigmas:
            sigma = np.concatenate(sigmas)
            sigma = sigma[np.isfinite(sigma)]
            if len(sigma):  # a phone reports ~8 m: name the limit that scores against fixes that coarse
                hint = (f"shorter outages will not help: the receiver reports {np.median(sigma):.1f} m (median); "
                        f"--gnss-limit max_sigma_m={math.ceil(np.percentile(sigma, 90))} scores against fixes "
                        "that coarse, or --truth-topic names a reference to score against (docs/method.md, "
                        "GNSS quality)")
        return InputError(f"no {n_windows:g} s outage fits on good GNSS truth in {where}: the GNSS is untrustworthy in "
                          f"{bad:.0%} of the samples ({reasons})", hint, param="outage_s")
    return InputError(f"no {n_windows:g} s outage fits in {where}", "use shorter outages", param="outage_s")
