"""A fleet in one command: many drives evaluated each on its own, on every core or on a Dask
cluster, one bad drive never sinking the others (:func:`evaluate_fleet`), from drives given as
files, folders, globs or ``@list.txt`` files (:func:`expand_drives`), with a dry run that lists
them with sizes and a time estimate (:func:`plan_fleet`)."""

from __future__ import annotations

import contextlib
import glob
import logging
import os
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..analysis.fleet import DriveFailure, DriveTable, FleetReport, drive_table
from ..core.durations import Span
from ..core.errors import InputError
from ..core.fileio import read_bytes_bounded
from ..experiment.outages import GNSS_OUTAGE, Placement
from ..nav.bias import SensorBias, resolve_bias
from ..sources.load import ReadOptions
from .engine import Engine, WorkerLost, default_workers, run_each
from .experiment import Experiment, FleetOptions
from .options import Progress, RunOptions, load_stationary, placement_of, windows_of
from .replay import default_stem

log = logging.getLogger("ionav_viz")

#: The exit code of ``evaluate`` when some drives failed and the others' results were printed.
EXIT_SOME_FAILED = 3
#: The file types a folder of drives is searched for (one drive each; ROS 2 and KITTI folders are
#: drives themselves).
DRIVE_SUFFIXES = (".csv", ".mcap", ".bag")
#: The largest ``@list.txt`` read (16 MiB: 200,000 drives of 80-byte paths): anything larger is not one.
MAX_LIST_BYTES = 16 << 20
#: The time estimate of a dry run: a start (imports, the workers' start), then per drive a fixed
#: part and a part per MB of file, measured on our 2-core machine with simulated IO-VNBD CSV drives
#: and every built-in estimator (about 5.7 MB per hour of drive; benchmarks/bench_fleet.py).
ESTIMATE_START_S = 3.0
ESTIMATE_S_PER_DRIVE = 0.05
ESTIMATE_S_PER_MB = 0.12


@dataclass(frozen=True)
class FleetDrive:
    """One drive of a fleet: as given (``spec``: what a worker reads and the report names), and
    its file's size in bytes (None: a name not resolved here, or a folder)."""

    spec: str
    size_bytes: int | None = None


def expand_drives(specs: Sequence[str | Path] | str | Path, runs: Sequence[str] | str = ()) -> list[FleetDrive]:
    """The drives ``specs`` name, in order, each once: a file or a drive folder (ROS 2 bag, KITTI
    raw) as it is; a folder of drives: its ``.csv``, ``.mcap`` and ``.bag`` files, sorted; a glob
    (``logs/*.csv``, ``logs/**/*.mcap``): its matches, sorted, ``**`` not descending into symbolic
    links to folders (as bash's globstar; a link loop cannot make it endless); ``@list.txt``: the
    drives listed in it, one a line (``#`` comments and blank lines ignored; relative paths from the
    list's folder; a regular file of at most :data:`MAX_LIST_BYTES`, each list read once); anything
    else (a bundled sample or IO-VNBD run name) as it is. ``specs`` may be one of these alone. Paths
    are de-duplicated by the file they reach (its device and inode: a symbolic or hard link and its
    file are one drive). A list that cannot be read, is a pipe or a device, or a glob that matches
    nothing is an :class:`InputError`.
    ``runs``: IO-VNBD run selections (``all``, a group, a driver:
    :func:`ionav_viz.api.datasets.runs_selected`), their runs after the drives given, by name (each
    read under the data root), with the size the manifest gives."""
    specs, runs = _drive_specs(specs, runs)
    out: dict[Any, FleetDrive] = {}
    lists_read: set[Any] = set()
    for spec in specs:
        for path in _expand_one(str(spec), depth=0, lists_read=lists_read):
            key = _identity(path)
            if key not in out:
                out[key] = FleetDrive(path, _size_of(path))
    if runs:
        from ..dataset.catalog import run_key
        from .datasets import runs_selected

        given = {run_key(d.spec) for d in out.values() if not Path(d.spec).expanduser().exists()}  # runs named already
        for name, size in runs_selected(runs):
            if run_key(name) not in given:
                out[name] = FleetDrive(name, size)
    return list(out.values())


#: What the API's ``drives`` takes, for its errors.
_DRIVES_HINT = "give a drive, a folder, a glob or '@list.txt' (a str or Path), or a list of them"


def _drive_specs(specs: Any, runs: Any) -> tuple[list[str | Path], list[str]]:
    """``drives`` and ``runs`` of a fleet call as lists, checked: one str or Path is one drive,
    folder, glob or list (not its characters, each a "drive"); anything else but a sequence of them
    is an :class:`InputError` naming the argument."""
    runs = [runs] if isinstance(runs, str) else [] if runs is None else runs
    if isinstance(runs, bytes) or not isinstance(runs, Iterable) or not all(isinstance(r, str) for r in runs):
        raise InputError(f"runs={runs!r}: not IO-VNBD run selections", "give a list of names, e.g. runs=['Vta']",
                         param="runs")
    runs = list(runs)
    if specs is None and runs:
        return [], runs
    if isinstance(specs, (str, os.PathLike)):
        return [specs], runs
    if isinstance(specs, bytes) or not isinstance(specs, Iterable):
        raise InputError(f"drives={specs!r}: not a drive or a list of drives", _DRIVES_HINT, param="drives")
    specs = list(specs)
    for i, spec in enumerate(specs):
        if not isinstance(spec, (str, os.PathLike)):
            raise InputError(f"drives[{i}]={spec!r}: not a drive's path or name", _DRIVES_HINT, param="drives")
    return specs, runs


def _expand_one(spec: str, depth: int, lists_read: set[Any]) -> list[str]:
    if spec.startswith("@"):
        return _from_list(Path(spec[1:]), depth, lists_read)
    path = Path(spec).expanduser()
    if path.is_dir() and _is_folder_of_drives(path):
        return sorted(str(p) for p in path.iterdir() if p.is_file() and p.suffix.lower() in DRIVE_SUFFIXES)
    if not path.exists() and glob.has_magic(spec):
        found = sorted(set(_glob(os.path.expanduser(spec))))
        if not found:
            raise InputError(f"{spec}: no file matches",
                             "check the pattern (quote it so the shell leaves it to ionav-viz)")
        # a folder of drives among them: its drives
        return [p for match in found for p in _expand_one(match, depth, lists_read)]
    return [spec]


def _glob(pattern: str) -> Iterator[str]:
    """``glob.glob(pattern, recursive=True)``, but a ``**`` component does not descend into symbolic
    links to folders (as bash's globstar, and pathlib): a link loop (``logs/a -> .``) made the glob
    follow it 40 levels deep, and two of them made it endless. A folder named before the ``**``
    (``linked/**/*.csv``) is followed."""
    parts = pattern.split(os.sep)
    if "**" not in parts:
        yield from glob.iglob(pattern)
        return
    k = parts.index("**")
    head, rest = (os.sep.join(parts[:k]) if parts[:k] != [""] else os.sep), os.sep.join(parts[k + 1:])
    for base in glob.iglob(head) if glob.has_magic(head) else [head]:
        top = base or os.curdir
        if not os.path.isdir(top):
            continue
        for folder, subfolders, files in os.walk(top):  # a link to a folder is listed, never entered
            subfolders[:] = [d for d in subfolders if not d.startswith(".")]  # hidden ones left out, as by glob's '**'
            rel = os.path.relpath(folder, top)
            here = base if rel == os.curdir else os.path.join(base, rel)
            if rest:
                yield from _glob(os.path.join(glob.escape(here), rest) if here else rest)
            else:
                yield from (os.path.join(here, name) for name in (*subfolders, *files) if not name.startswith("."))


def _from_list(path: Path, depth: int, lists_read: set[Any]) -> list[str]:
    if depth > 4:
        raise InputError(f"@{path}: lists of drives nested more than 4 deep", "list the drives themselves")
    hint = "give a UTF-8 text file, one drive per line"
    if not path.exists() and not path.is_symlink():
        raise InputError(f"@{path}: no such list of drives", "give @FILE with one drive per line") from None
    key = _identity(str(path))
    if key in lists_read:  # listed again (or including itself): its drives are in already
        return []
    try:
        data = read_bytes_bounded(path, param="drives", max_bytes=MAX_LIST_BYTES, hint=hint, what="a list of drives")
        text = data.decode("utf-8")
    except InputError as exc:  # a pipe, a device, a socket, too large: said as the list it is
        raise InputError(f"@{exc.message}", exc.hint, param="drives") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"@{path}: not UTF-8 text (byte {exc.start})", hint, param="drives") from None
    lists_read.add(key)
    out: list[str] = []
    for line in text.splitlines():
        item = line.split("#", 1)[0].strip()
        if not item:
            continue
        if item.startswith("@"):
            out += _expand_one("@" + str(path.parent / Path(item[1:]).expanduser()), depth + 1, lists_read)
            continue
        candidate = path.parent / Path(item).expanduser()  # an absolute path stays as it is
        is_path = candidate.exists() or glob.has_magic(item) or "/" in item or os.sep in item
        out += _expand_one(str(candidate) if is_path else item, depth + 1, lists_read)  # else a sample or run name
    return out


def _is_folder_of_drives(path: Path) -> bool:
    """A folder that is not one drive (no ROS 2 metadata, no KITTI oxts/) but holds drive files."""
    from ..sources.kitti import oxts_folder

    if (path / "metadata.yaml").is_file() or oxts_folder(path) is not None:
        return False
    try:
        return any(p.is_file() and p.suffix.lower() in DRIVE_SUFFIXES for p in path.iterdir())
    except OSError:
        return False


def _identity(spec: str) -> Any:
    """What tells two drives apart: the file a path reaches (device and inode, so that a symbolic
    or a hard link and its file are one), else the name as given."""
    try:
        info = os.stat(Path(spec).expanduser())
    except (OSError, ValueError):
        return spec
    return (info.st_dev, info.st_ino)


def _size_of(spec: str) -> int | None:
    path = Path(spec).expanduser()
    try:
        if path.is_file():
            return path.stat().st_size
        if path.is_dir():
            return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    except OSError:
        return None
    return None


@dataclass(frozen=True)
class _Job:
    """What every worker needs besides the drive: small and picklable."""

    n_windows: int
    placement: Placement
    run: RunOptions
    read: ReadOptions
    #: the running command's configuration, for the reports and recordings workers write (other processes)
    config: dict[str, Any] | None = None


def evaluate_one(spec: str, job: _Job, recording: str | None = None,
                 path: str | None = None) -> DriveTable | DriveFailure:
    """Evaluate one drive (in whichever process runs it), and with ``recording`` replay it into
    that ``.rrd``: its compact table, or why it failed in one line. ``path``: where the worker reads
    it (the absolute path of ``spec``, for workers in other folders). The drive's arrays are
    released when this returns."""
    from ..core import run_config
    from ..core.warnings_log import collecting_warnings
    from ..sources.load import load_drive
    from .pipeline import plan_drive, score

    began = time.perf_counter()
    with _quiet_log(), collecting_warnings() as warned, run_config.running(job.config):
        try:
            drive = load_drive(path or spec, job.read)
            try:
                planned = plan_drive(drive, job.placement, job.n_windows, job.run)
            except InputError as exc:
                if tuple(job.placement.event_types) != (GNSS_OUTAGE,):
                    raise
                # through the logs' own losses: a drive without one has nothing to bridge, it has not failed
                return DriveFailure(spec, f"skipped: {exc.message}", time.perf_counter() - began, skipped=True)
            plan = planned.plan
            if plan.too_short:
                why = ("no outage fits where the GNSS truth and the receiver's fixes are good"
                       if plan.excluded else "too short for a single outage")
                return DriveFailure(spec, f"skipped: {why} ({drive.duration_s:.0f} s)", time.perf_counter() - began,
                                    skipped=True)
            if recording is not None:
                from .replay import replay_single

                with _one_torch_thread(load=_torch_idnn(job.run.applying_to([drive]))):
                    result = replay_single(Experiment(drive, job.n_windows, job.placement, run=job.run, read=job.read),
                                           recording, None, None, None).result
            else:
                ests = job.run.applying_to([drive])
                with _one_torch_thread(load=_torch_idnn(ests)):
                    result = score(planned, ests, job.run.bias_of(job.read)(drive))
            return drive_table(spec, result, list(warned), time.perf_counter() - began, recording, job.run.thresholds)
        except Exception as exc:  # any drive's failure is its own: reported, the fleet goes on
            return DriveFailure(spec, _one_line(exc).removeprefix(f"{path or spec}: ").removeprefix(f"{spec}: "),
                                time.perf_counter() - began,
                                # as the reason's one line has it
                                hint=" ".join((exc.hint or "").split()) if isinstance(exc, InputError) else "")


def _torch_idnn(estimators: list) -> bool:
    """Whether an IDNN among ``estimators`` runs in torch (a recurrent model; the feed-forward ones
    run in numpy, :class:`ionav_viz.learning.idnn.NumpyFeedForward`)."""
    from ..learning.idnn import FEED_FORWARD_ARCHS

    return any(e.name == "idnn" and getattr(getattr(e, "model", None), "config", None) is not None
               and e.model.config.arch not in FEED_FORWARD_ARCHS for e in estimators)


class _one_torch_thread:
    """torch on one thread while a drive is evaluated, in this process as in a worker: a sum split
    over another number of threads may round differently, and the fleet's numbers must not depend
    on where a drive ran. Where torch is loaded already, or ``load`` (the IDNN may run: it will
    load it); the previous setting is restored after."""

    def __init__(self, load: bool = True) -> None:
        self.load = load

    def __enter__(self) -> None:
        import sys

        self.torch = sys.modules.get("torch")
        if self.torch is None and self.load:
            import importlib.util

            if importlib.util.find_spec("torch") is None:
                return
            import torch

            self.torch = torch
        if self.torch is None:
            return
        self.saved = self.torch.get_num_threads()
        self.torch.set_num_threads(1)

    def __exit__(self, *exc: Any) -> None:
        if self.torch is not None:
            self.torch.set_num_threads(self.saved)


def _run_item(item: tuple[str, _Job, str | None, str | None]) -> DriveTable | DriveFailure:
    return evaluate_one(*item)


def _absolute(spec: str) -> str | None:
    """Where a worker reads ``spec``, whatever its working folder: the absolute path of a path
    that exists here, else None (a name, read as it is)."""
    local = Path(spec).expanduser()
    return str(local.absolute()) if local.exists() else None


def _one_line(exc: BaseException) -> str:
    from ..core.errors import plain_text

    text = " ".join(plain_text(str(exc)).split())
    return text if isinstance(exc, InputError) else f"{type(exc).__name__}: {text or 'no message'}"


class _quiet_log:
    """While one drive is evaluated, ionav-viz's warnings go to its report, not to stderr (a
    worker's stderr interleaves with the others'); restored after."""

    def __enter__(self) -> None:
        import logging

        self.logger = logging.getLogger("ionav_viz")
        self.saved = self.logger.handlers[:], self.logger.propagate
        self.logger.handlers[:] = [logging.NullHandler()]
        self.logger.propagate = False

    def __exit__(self, *exc: Any) -> None:
        self.logger.handlers[:], self.logger.propagate = self.saved


def run_fleet(exp: Experiment, folder: str | Path | None, progress: Progress | None,
              fleet: FleetOptions | None = None) -> FleetReport:
    """``exp``'s drives each on its own on ``exp.engine`` (worker processes, default every core, or a
    Dask cluster), pooled in the order the drives were given: the report is the same whatever the
    workers. With ``folder``, each drive is replayed there too (made when missing), one recording
    each, ``<drive>.rrd`` (with ``read.span`` the span too, ``<drive>-0s-60s.rrd``, as
    :func:`ionav_viz.api.replay.default_stem` names it; a name another drive's recording has taken
    gets the first free ``-2``, ``-3``...: :func:`plan_outputs`), each row of the report with its
    ``recording``; on a cluster, ``folder`` must be one every worker can write to.

    ``exp.drives``: paths, folders, globs, ``@list.txt`` files or names (:func:`expand_drives`),
    and ``exp.runs`` IO-VNBD run selections; a worker reads each drive itself, so on a cluster
    every path must be one the workers see; the estimators are chosen per drive (the default ones
    that apply to it). ``progress(label, done, total)`` after each drive; the label says the
    outages scored and the slowest drive so far. ``fleet``: :class:`FleetOptions` (fail fast, the
    overview recording, the replay options the report's commands carry).

    Returns a :class:`FleetReport`; a drive that cannot be read or evaluated is in its ``failures``
    with its one-line reason, a drive too short for one outage in ``skipped``."""
    fleet = fleet if fleet is not None else FleetOptions()
    if not isinstance(fleet, FleetOptions):
        raise InputError(f"fleet={fleet!r} is not a FleetOptions", "give fleet=iv.FleetOptions(...), or leave it out",
                         param="fleet")
    check_callables(progress, fleet.replay_options)
    if folder is not None and not isinstance(folder, (str, os.PathLike)):
        raise InputError(f"folder={folder!r} is not a folder's path",
                         "give the folder the recordings go into, e.g. 'recordings'", param="output")
    engine = exp.engine.start()
    items = expand_drives(list(exp.drives), exp.runs)
    job = _job_of(items, exp)
    if folder is None:
        outputs = plan_outputs(items, fleet_rrd=fleet.fleet_rrd, inputs=fleet_inputs(list(exp.drives), items, job.run))
        report = _run_fleet([(d.spec, job, None, _absolute(d.spec)) for d in items], [d.size_bytes for d in items],
                            job, engine, fleet.fail_fast, progress, fleet.replay_options)
        if outputs.fleet_rrd is not None and report.drives:
            _write_overview(report, outputs.fleet_rrd)
        return report
    out = Path(folder)
    outputs = plan_outputs(items, folder=out, span=job.read.span, fleet_rrd=fleet.fleet_rrd,
                           inputs=fleet_inputs(list(exp.drives), items, job.run))
    for spec, recording in outputs.renamed.items():
        log.warning("%s: recorded as %s, as another output of this run has the drive's name", spec, recording)
    work = [(d.spec, job, recording, _absolute(d.spec)) for d, recording in zip(items, outputs.recordings)]
    made = [level for level in [*reversed(out.parents), out] if not level.exists()]
    out.mkdir(parents=True, exist_ok=True)
    report = None
    try:
        report = _run_fleet(work, [d.size_bytes for d in items], job, engine, fleet.fail_fast, progress,
                            fleet.replay_options)
        if outputs.fleet_rrd is not None and report.drives:
            _write_overview(report, outputs.fleet_rrd)
        return report
    finally:
        # no recording written: the folders made for them go again (if still empty)
        if report is None or not report.drives:
            for level in reversed(made):
                with contextlib.suppress(OSError):
                    level.rmdir()


@dataclass(frozen=True)
class FleetOutputs:
    """Every file a fleet run writes, planned before any work (:func:`plan_outputs`): no two are
    one file and none is one of the run's inputs, whichever worker writes it and when."""

    #: per drive, in the order given: the absolute path of its recording (None: not replayed)
    recordings: list[str | None]
    #: the fleet's overview recording, if asked for
    fleet_rrd: Path | None = None
    #: the drives whose recording is not ``<drive>.rrd``, as another drive's recording (or the
    #: overview) has that name: drive as given -> its recording
    renamed: dict[str, str] = field(default_factory=dict)


def plan_outputs(items: Sequence[FleetDrive], *, folder: str | Path | None = None, span: Span | None = None,
                 fleet_rrd: str | Path | None = None, inputs: Sequence[str | Path] = ()) -> FleetOutputs:
    """The one place that names a fleet run's outputs, before any work: with ``folder`` (replay),
    one recording per drive there, ``<drive>.rrd`` as :func:`ionav_viz.api.replay.default_stem`
    names it (``span``: ``--span``); and the overview recording ``fleet_rrd``.

    Names are decided here, in the order the drives were given, so serial runs, any number of
    workers and a cluster write the same files: a drive whose name is taken already (by an
    earlier drive of that name, compared without case, or by the overview) gets the first of
    ``<drive>-2``, ``<drive>-3``... that no drive and no output has, so ``a/V-x b/V-x c/V-x-2``
    write ``V-x``, ``V-x-3`` and ``V-x-2``. Refused with an :class:`InputError` (``param``
    ``fleet_rrd`` or ``output``): an overview that is not an ``.rrd``, cannot be written, is one of
    the drives' recordings or an input; a recording that is one of ``inputs`` (the drives, list
    files, a model, plug-ins: :func:`fleet_inputs`); a folder inside an input folder."""
    from ..core.fileio import check_output_file, check_output_folder, refuse_output_onto_input

    out = Path(folder) if folder is not None else None
    if out is not None:
        check_output_folder(out, param="output")
        refuse_output_onto_input(out, inputs)  # not inside a drive that is a folder (a ROS 2 bag, a KITTI drive)
    overview = Path(fleet_rrd) if fleet_rrd is not None else None
    overview_name = None
    if overview is not None:
        if overview.suffix.lower() != ".rrd":
            raise InputError(f"{overview}: the fleet's overview is an .rrd file", "give a name ending in .rrd",
                             param="fleet_rrd")
        in_folder = out is not None and (os.path.realpath(overview.parent if str(overview.parent) else ".")
                                         == os.path.realpath(out))
        if not in_folder or out.exists():  # else its folder is made by the run, checked as the recordings' folder
            try:
                check_output_file(overview)
            except InputError as exc:
                exc.param = "fleet_rrd"
                raise
        refuse_output_onto_input(overview, inputs, param="fleet_rrd")
        overview_name = overview.name if in_folder else None
    if out is None:
        return FleetOutputs([None] * len(items), overview)
    stems = [default_stem(_drive_name(d.spec), span) for d in items]
    if overview_name is not None:
        for d, stem in zip(items, stems):
            if f"{stem}.rrd" == overview_name:
                raise InputError(f"{overview}: is the recording of the drive {d.spec}, which the overview "
                                 "would replace",
                                 "give the overview another name (e.g. fleet.rrd) or another folder", param="fleet_rrd")
    reserved = {s.casefold() for s in stems}
    taken = {overview_name.casefold().removesuffix(".rrd")} if overview_name is not None else set()
    recordings, renamed = [], {}
    for d, stem in zip(items, stems):
        name, n = stem, 1
        # another drive's own name: it keeps it
        while name.casefold() in taken or (name != stem and name.casefold() in reserved):
            n += 1
            name = f"{stem}-{n}"
        taken.add(name.casefold())
        recording = str((out / f"{name}.rrd").absolute())
        if name != stem:
            renamed[d.spec] = recording
        recordings.append(recording)
    _refuse_onto_inputs(recordings, inputs)
    return FleetOutputs(recordings, overview, renamed)


def _refuse_onto_inputs(outputs: Sequence[str], inputs: Sequence[str | Path]) -> None:
    """:func:`~ionav_viz.core.fileio.refuse_output_onto_input` for many outputs at once: each input
    resolved and stat'ed once (a fleet has thousands of drives and recordings)."""
    real, ids = {}, {}
    for given in inputs:
        real[os.path.realpath(given)] = given
        with contextlib.suppress(OSError):
            info = os.stat(given)
            ids[(info.st_dev, info.st_ino)] = given
    for output in outputs:
        hit = real.get(os.path.realpath(output))
        if hit is None:
            with contextlib.suppress(OSError):
                info = os.stat(output)
                hit = ids.get((info.st_dev, info.st_ino))
        if hit is not None:
            raise InputError(f"{output}: a drive's recording would replace the input {hit}",
                             "choose another output folder; ionav-viz never writes over its input", param="output")


def fleet_inputs(specs: Sequence[str | Path] | str | Path | None, items: Sequence[FleetDrive],
                 run: RunOptions | None = None) -> list[str]:
    """The files and folders a fleet run reads, for :func:`plan_outputs`: its drives (as
    :func:`expand_drives` found them), the ``@list`` files given (``specs`` as the fleet call took
    them, checked by then), and the run's model, plug-ins and ``--bias-from`` drive."""
    from .options import input_paths

    specs = [] if specs is None else _drive_specs(specs, [])[0]

    paths = [d.spec for d in items if Path(d.spec).expanduser().exists()]
    paths += [str(spec)[1:] for spec in specs if str(spec).startswith("@")]
    paths += [str(p) for p in input_paths([], None, run=run)] if run is not None else []
    return paths


def check_callables(progress: Any, replay_options: Any) -> None:
    """``progress`` a callable or None and ``replay_options`` a string, before any work (a number
    was a TypeError after the first drive, or a report that printed it as the options)."""
    if progress is not None and not callable(progress):
        raise InputError(f"progress={progress!r} is not callable", "give a function progress(label, done, total)",
                         param="progress")
    if not isinstance(replay_options, str):
        raise InputError(f"replay_options={replay_options!r} is not a string",
                         "give the options as one string, e.g. '--outage 10s'", param="replay_options")


def _drive_name(spec: str) -> str:
    """The name a drive's recording gets: its file's stem (a folder's name, a sample's name)."""
    path = Path(spec)
    return (path.parent.name if path.name == "metadata.yaml" else path.stem) or "drive"


def _job_of(items: list[FleetDrive], exp: Experiment) -> _Job:
    """The run's options, checked once, before any worker starts."""
    if not items:
        raise InputError("no drive to evaluate", "give at least one drive")
    placement = placement_of(exp.placement, None)
    n = windows_of(exp.outage_s, placement)
    run, read = exp.options()
    run.chosen()  # plug-ins and the model are checked here, before any worker starts
    if run.bias_from is not None and not isinstance(run.bias_from, SensorBias):
        # --bias-from too: a file that cannot be read, or does not stand
        stationary = load_stationary(run.bias_from, read)
        resolve_bias(stationary, stationary)  # still, is the run's one error, not every drive's failure
    from ..core import run_config

    return _Job(n, placement, run, read, run_config.current())


def _run_fleet(work: list[tuple[str, _Job, str | None, str | None]], sizes: list[int | None], job: _Job, engine: Engine,
               fail_fast: bool, progress: Progress | None, replay_options: str) -> FleetReport:
    """Run every item on ``engine``, the largest files first (so that no long drive starts last
    while the other workers wait), and pool the results in the order given."""
    began = time.perf_counter()
    done: dict[int, DriveTable | DriveFailure] = {}
    outages, slowest = 0, ("", 0.0)
    order = sorted(range(len(work)), key=lambda i: (-(sizes[i] or 0), i))
    results = run_each(_run_item, [work[i] for i in order], engine)
    try:
        for j, value in results:
            i = order[j]
            if isinstance(value, WorkerLost):
                value = DriveFailure(work[i][0], value.reason)
            done[i] = value
            if fail_fast and isinstance(value, DriveFailure) and not value.skipped:
                reason = value.reason.removesuffix(f" (hint: {value.hint})") if value.hint else value.reason
                other = "leave out --fail-fast to evaluate the other drives and report this one"
                # one hint
                raise InputError(f"{value.spec}: {reason}", f"{value.hint}; or {other}" if value.hint else other)
            if isinstance(value, DriveTable):
                outages += value.n_outages
            if value.elapsed_s > slowest[1]:
                slowest = (Path(value.spec).name, value.elapsed_s)
            if progress:
                progress(f"{len(done)}/{len(work)} drives, {outages} outages scored, slowest {slowest[0]} "
                         f"{slowest[1]:.1f} s",
                         len(done), len(work))
    finally:
        close = getattr(results, "close", None)
        if close is not None:
            close()
    ordered = [done[i] for i in range(len(work))]
    return FleetReport(
        drives=[v for v in ordered if isinstance(v, DriveTable)],
        failures=[v for v in ordered if isinstance(v, DriveFailure) and not v.skipped],
        skipped=[v for v in ordered if isinstance(v, DriveFailure) and v.skipped],
        outage_s=float(job.n_windows), replay_options=replay_options,
        timing={"wall_s": round(time.perf_counter() - began, 3), "engine": engine.describe()})


def _write_overview(report: FleetReport, path: Path) -> None:
    """:func:`write_fleet_recording` as a run's ``fleet_rrd``: its errors name that argument."""
    try:
        write_fleet_recording(report, path)
    except InputError as exc:
        if exc.param == "output":
            exc.param = "fleet_rrd"
        raise


def write_fleet_recording(report: FleetReport, output: str | Path) -> Path:
    """Write the fleet's overview recording (``evaluate --fleet-rrd FILE``,
    :mod:`ionav_viz.viz.fleet`) to ``output``, atomically: a table of the drives with each one's
    worst outage and the command that replays it, and bar charts per estimator. Returns its path."""
    from ..core.fileio import atomic_path
    from ..viz.fleet import write_fleet_recording as write

    if not isinstance(report, FleetReport):
        raise InputError(f"report of type {type(report).__name__}: not a fleet's report",
                         "give what evaluate_fleet or replay_fleet returned", param="report")
    if not isinstance(output, (str, os.PathLike)):
        raise InputError(f"output={output!r} is not a file's path", "give a name ending in .rrd", param="fleet_rrd")
    out = Path(output)
    if out.suffix.lower() != ".rrd":
        raise InputError(f"{out}: the fleet's recording is an .rrd file", "give a name ending in .rrd",
                         param="fleet_rrd")
    with atomic_path(out) as tmp:
        write(report, tmp, target=out)
    return out


@dataclass(frozen=True)
class FleetPlan:
    """What a fleet run would do (``--dry-run``): the drives with their sizes, and the estimate."""

    drives: list[FleetDrive]
    workers: int
    estimate_s: float
    #: per drive that cannot be found (no such file, an unknown name): why, as the run would say it
    missing: dict[str, str] = field(default_factory=dict)

    def to_text(self) -> str:
        """One line per drive (size in MB, or "missing"), then the total and the time estimate."""
        from ..analysis.document import aligned

        rows = [[d.spec,
                 "missing" if d.spec in self.missing else "-" if d.size_bytes is None else f"{d.size_bytes / 1e6:.1f}"]
                for d in self.drives]
        total_mb = sum(d.size_bytes or 0 for d in self.drives) / 1e6
        lines = aligned(["Drive", "MB"], rows, 1)
        lines += ["",
                  f"{len(self.drives)} drive(s), {total_mb:.1f} MB; about {self.estimate_s:.0f} s on "
                  f"{self.workers} worker(s) (a rough estimate from the file sizes)"]
        lines += [f"not found, the run would report it failed: {why}" for why in self.missing.values()]
        return "\n".join(lines) + "\n"

    def to_dict(self) -> dict[str, Any]:
        return {"drives": [{"drive": d.spec, "size_bytes": d.size_bytes,
                            **({"missing": self.missing[d.spec]} if d.spec in self.missing else {})}
                           for d in self.drives], "workers": self.workers, "estimate_s": round(self.estimate_s, 1)}


def plan_fleet(drives: Sequence[str | Path] | str | Path, workers: int | None = None, runs: Sequence[str] = (),
               root: str | Path | None = None, fleet_rrd: str | Path | None = None) -> FleetPlan:
    """The drives :func:`evaluate_fleet` would evaluate, with sizes and a rough time estimate on
    ``workers`` (default every core): nothing is read but the file sizes (an IO-VNBD run's: the
    manifest's). A drive that cannot be found (under ``root``, the data root, for a run name) is
    said missing. ``fleet_rrd`` is checked as the run would check it (:func:`plan_outputs`)."""
    from ..sources.resolve import data_root, resolve_drive

    if root is not None and not isinstance(root, (str, os.PathLike)):
        raise InputError(f"root={root!r} is not a folder's path", "give the data root's folder, or None",
                         param="data_root")
    items = expand_drives(drives, runs)
    if not items:
        raise InputError("no drive to evaluate", "give at least one drive")
    plan_outputs(items, fleet_rrd=fleet_rrd, inputs=fleet_inputs(drives, items))
    n = Engine(workers if workers is not None else default_workers()).pool_size(len(items))
    work_s = sum(ESTIMATE_S_PER_DRIVE + ESTIMATE_S_PER_MB * (d.size_bytes or 0) / 1e6 for d in items)
    missing = {}
    for d in items:
        if d.size_bytes is None:  # a name, or nothing at all
            try:
                resolve_drive(d.spec, data_root(root))
            except InputError as exc:
                missing[d.spec] = str(exc)
    return FleetPlan(items, n, ESTIMATE_START_S + work_s / min(n, len(items)), missing)
