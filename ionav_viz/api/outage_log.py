"""``outage_log``: a drive's log with the GNSS removed inside the outages ``replay``/``evaluate``
would place, and the plan that scores an estimate made on it (:mod:`ionav_viz.experiment.plan_file`)."""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, is_dataclass
from pathlib import Path

from ..core.errors import InputError
from ..core.fileio import atomic_path, check_output_file, refuse_output_onto_input
from ..core.signals import hold_signals
from ..core.timing import stage
from ..experiment.outages import Placement
from ..experiment.plan_file import FromPlan, PlanFile, checksum
from ..nav.windows import make_windows
from ..sources.load import ReadOptions, load_drive, open_message_log, source_kind
from .options import (
    DriveLike,
    RunOptions,
    check_event_types,
    input_paths,
    no_outage_fits,
    options_of,
    placement_of,
    too_short,
    windows_of,
)
from .pipeline import plan_outages
from .simulation import vehicle_speed_for_log


@dataclass(frozen=True)
class OutageLogResult:
    """What :func:`outage_log` wrote: the outaged log, its plan file and the plan."""

    path: Path
    plan_path: Path
    plan: PlanFile
    removed: int

    def __repr__(self) -> str:
        return (f"OutageLogResult({str(self.path)!r}, plan {str(self.plan_path)!r}: {len(self.plan.start_stamps_s)} "
                f"outage(s) of {self.plan.outage_s:g} s, {self.removed} GNSS message(s) removed)")


def plan_path_of(output: Path) -> Path:
    """``drive.mcap`` -> ``drive.outages.json`` beside it."""
    return output.with_name(output.stem + ".outages.json")


def outage_log(
    drive: DriveLike,
    output: str | Path,
    outage_s: float | None = None,
    placement: Placement | None = None,
    *,
    run: RunOptions | None = None,
    read: ReadOptions | None = None,
) -> OutageLogResult:
    """Write ``drive``'s log with its GNSS removed inside each outage, and the plan beside it.

    The outages are exactly those :func:`evaluate` and :func:`replay` place with the same
    ``outage_s``, ``placement`` (and seed) and ``read`` options. ``output``'s suffix chooses the
    format (:mod:`ionav_viz.sources.outage_writer`: ``.mcap`` from any source, every other topic of
    an MCAP source kept byte for byte; ``.csv`` from an IO-VNBD file, the logger's no-fix rows).
    The plan goes to ``OUTPUT`` with ``.outages.json`` for its suffix: give it to
    ``evaluate(..., plan=...)`` with the same drive to score an estimate made on the outaged log.
    Both files are written atomically, or neither.
    """
    from ..sources.message_log import select_channels
    from ..sources.outage_writer import write_outage_log

    out = Path(output)
    if out.name in ("", ".", ".."):  # '.', '..', '/': an existing folder, and no name to derive the plan's from
        raise InputError(f"{out}: exists; an outage log is a new file (.mcap, .bag, .csv) or a new folder "
                         "(a ROS 2 bag)",
                         "name a new one, e.g. -o cut.mcap", param="output")
    plan_file = plan_path_of(out)
    if out.suffix:
        check_output_file(out)
    check_output_file(plan_file)
    if not isinstance(drive, (str, Path)):
        raise InputError(f"outage_log needs the drive's file, not a {type(drive).__name__}", "give its path or name",
                         param="drive")
    sources = input_paths(drive, read)
    refuse_output_onto_input(out, sources)  # an outaged log written over its source would lose it
    refuse_output_onto_input(plan_file, sources)
    if isinstance(placement, FromPlan):
        raise InputError("outage_log places outages itself", "give a placement (Tile, Every, At, Random, AroundEvents)",
                         param="placement")
    placement = placement_of(placement, None)
    n = windows_of(outage_s, placement)
    run, read = options_of(run, None, read, None)
    if placement.event_types:
        check_event_types(placement.event_types)
    d = load_drive(drive, read)
    source = Path(d.source)
    kind = source_kind(source)
    with stage("windows"):
        windows = make_windows(d)
    plan, _ = plan_outages(d, windows, placement, n, run)
    if plan.gnss_gaps and not len(plan.starts):
        raise InputError(f"{d.name}: the gnss-outage placement bridges the log's own GNSS losses; there is "
                         "nothing to remove",
                         "place synthetic outages (every, at, random or on a manoeuvre)", param="placement")
    if not len(plan.starts):
        if plan.excluded:
            raise no_outage_fits([d], n, d.source)
        raise too_short(d, n, run, read)
    start_s = windows.t0_s[plan.starts]
    stamps = [float(s) for s in d.stamp_s(start_s)]
    outages = [(a, a + n) for a in stamps]
    gnss_topics: tuple[str, ...] = ()
    if kind in ("mcap", "ros1", "ros2"):
        sel = select_channels(open_message_log(source, kind), read.log.imu_topic, read.log.gnss_topic,
                              read.log.gnss_velocity_topic, read.log.vehicle_speed_topic,
                              truth_topic=read.log.truth_topic)
        gnss_topics = tuple(c.topic for c in (sel.gnss, sel.gnss_velocity) if c is not None)
    clock = ("IO-VNBD time since the start of the day (s)" if kind == "iovnbd"
             else f"UNIX time (s), the messages' {'log times' if read.log.stamps == 'log' else 'header stamps'}")
    options = {"type": type(placement).__name__, **(asdict(placement) if is_dataclass(placement) else {})}
    # Both files or neither: the log is written first (atomically), then the plan; if the plan
    # fails (a full disk, a signal), the new log goes and the previous file at OUT, kept aside
    # under a hard link while they are written, comes back.
    release = hold_signals()  # no signal between making the link and the cleanup that removes it
    previous: Path | None = None
    written = None
    try:
        previous = _link_aside(out)
        release()
        with stage(f"write {out.name}"):
            written = write_outage_log(d, source, kind, outages, out, gnss_topics, read.log.stamps,
                                       vehicle_speed_for_log(d.as_received()))
        result = PlanFile(str(source), checksum(source), d.name, float(n), plan.description, options, tuple(stamps),
                          tuple(float(s) for s in start_s), clock, written.removed_topics)
        with atomic_path(plan_file) as tmp:
            tmp.write_text(result.to_json(), encoding="utf-8")
    except BaseException:
        release()
        if written is not None:
            if out.is_dir():
                import shutil

                shutil.rmtree(out, ignore_errors=True)
            else:
                out.unlink(missing_ok=True)
            if previous is not None:
                os.replace(previous, out)
        raise
    finally:
        if previous is not None:
            previous.unlink(missing_ok=True)
    return OutageLogResult(out, plan_file, result, written.removed)


def _link_aside(path: Path) -> Path | None:
    """A hidden hard link beside ``path`` to the regular file there (None: no file, or the file
    system makes no hard links)."""
    import secrets

    if not path.is_file():
        return None
    aside = path.with_name(f".{path.name}.previous.{secrets.token_hex(6)}")
    try:
        os.link(path, aside, follow_symlinks=False)  # a link at OUT comes back as the link
    except OSError:
        return None
    return aside
