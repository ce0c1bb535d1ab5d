"""Detected events and the detectors' measured quality (``ionav-viz events``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..analysis.events import EVENT_TYPES, Event, EventThresholds, detect_events
from ..core.drive import Drive, drive_labels
from ..core.errors import InputError
from ..sources.load import ReadOptions, load_drive, load_drives
from .options import DriveLike, check_event_types


def find_events(drives: Sequence[DriveLike] | DriveLike, types: Sequence[str] | None = None, *,
                thresholds: EventThresholds | None = None, read: ReadOptions | None = None) -> dict[str, list[Event]]:
    """The detected events of each drive (by drive name; by its file where two drives share a
    name), of ``types`` (default every type), in time order; overlapping detections of one type
    are one event (``ionav-viz events``)."""
    kinds = _kinds(types)
    items = [drives] if isinstance(drives, (Drive, str, Path)) else list(drives)
    if not items:
        raise InputError("no drive to look at", "give at least one drive")
    drives_read = load_drives(items, read)  # a warning each drive repeats is said once
    return {label: detect_events(drive, thresholds or EventThresholds(), kinds)
            for label, drive in zip(drive_labels(drives_read), drives_read)}


def _kinds(types: Sequence[str] | None) -> tuple[str, ...]:
    """The event types asked for (default every type), checked: a lone string was taken letter by
    letter ("unknown event type(s) r, o, u, n, d, ...")."""
    if isinstance(types, (str, bytes)):
        raise InputError(f"types={types!r} is not a sequence of event types", f"give a list, e.g. types=[{types!r}]",
                         param="types")
    kinds = tuple(types) if types else EVENT_TYPES
    check_event_types(kinds)
    return kinds


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


def detector_quality(thresholds: EventThresholds | None = None,
                     types: Sequence[str] | None = None) -> dict[str, DetectorQuality]:
    """Each detector's recall and precision on the bundled synthetic drives, where the simulator
    knows every manoeuvre it drove (``ionav-viz events --quality``)."""
    from ..analysis.events import score
    from ..dataset.samples import SAMPLES, sample_path
    from ..sim.simulate import simulated_manoeuvres

    kinds = _kinds(types)
    totals = {k: [0, 0, 0, 0] for k in EVENT_TYPES}
    for sample in SAMPLES:
        drive = load_drive(sample_path(sample))  # with the GNSS quality marks, as every command reads
        truth = simulated_manoeuvres(sample.scenario, sample.seed, sample.duration_s, sample.gnss_losses)
        for kind, sc in score(truth, detect_events(drive, thresholds or EventThresholds()), drive.duration_s).items():
            for i, v in enumerate((sc.n_truth, sc.recalled, sc.n_found, sc.precise)):
                totals[kind][i] += v
    return {k: DetectorQuality(*t) for k, t in totals.items() if k in kinds}

