"""Where GNSS outages go: outage sequences as runs of consecutive 1-second windows.

An outage of ``n`` seconds starting at window ``k`` blanks GNSS over windows ``k .. k+n-1``;
the estimators start from the GNSS fix at the start of window ``k``. Every sequence lies in
one gap-free segment, and window ``k-1`` must exist in that segment too: the IDNN's first
window is fed the GNSS displacement of the second before the outage (the paper's Figure 2).
So the first window of each segment never starts an outage. The same holds for bad GNSS truth
(:attr:`Windows.truth_ok`): every window of an outage, and the one before it, must have good
truth, so a stretch of bad fixes splits a segment as a gap does. Where the estimators' receiver is
not the truth (a reference beside it), the window before the start must also have good receiver
fixes (:attr:`Windows.receiver_ok`): inside a loss of the receiver there is no fix to start from, and
an outage is not placed there (a placement that walks the drive moves on to the first start after
the loss).

Placements are values (:class:`Tile`, :class:`Every`, :class:`At`, :class:`Random`, :class:`Planned`,
:class:`AroundEvents`), each planning its own outages (``plan(windows, n_windows, events, source)
-> OutagePlan``: starts, description, what bad truth excluded, GNSS losses to bridge), over these
functions (all return sorted start indices into :class:`~ionav_viz.nav.windows.Windows`):

* :func:`tile` -- the paper's protocol: consecutive, back-to-back outages from the start of each
  segment to its end (a last partial outage is dropped).
* :func:`every` -- an outage every ``period`` seconds, with GNSS available in between.
* :func:`at` -- outages starting at given times (the window whose start is nearest).
* :func:`random` -- ``count`` non-overlapping outages drawn with a seed.
* :func:`around` -- one outage around each of a list of time intervals (detected manoeuvres):
  the outage is centred on the interval, so the manoeuvre lies inside it when it is shorter
  than the outage (a longer one starts 1 s into the outage); an outage that would overlap the
  one before it, or not fit in the drive, is skipped.
"""

from __future__ import annotations

import logging
import numbers
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..core.errors import InputError
from ..core.gnss_quality import fault_names
from ..core.grid import WINDOW_S
from ..nav.windows import Windows, segment_ranges, starts_ok, valid_start

log = logging.getLogger("ionav_viz")


def outage_windows(outage_s: float, what: str = "outage length", param: str = "outage_s") -> int:
    """Outage length (s) -> number of 1-second windows; must be a positive whole number."""
    if isinstance(outage_s, bool) or not isinstance(outage_s, numbers.Real):
        raise InputError(f"{what} {outage_s!r} is not a number of seconds", "give seconds as a number, e.g. 10.0",
                         param=param)
    if not np.isfinite(outage_s) or outage_s <= 0 or abs(outage_s - round(outage_s)) > 1e-9:
        raise InputError(
            f"{what} {outage_s:g} s is not a positive whole number of seconds",
            "the estimators predict once per 1 s window; use whole seconds, e.g. 10 s",
            param=param,
        )
    return int(round(outage_s))


def truth_faults_near(windows: Windows, start: int, n: int) -> int:
    """Fault bits of the windows an ``n``-window outage at ``start`` needs good (start-1 .. start+n-1)."""
    return int(np.bitwise_or.reduce(windows.truth_fault[max(start - 1, 0) : start + n])) if len(windows) else 0


def receiver_faults_before(windows: Windows, start: int) -> int:
    """Fault bits of the receiver's fixes the estimators would start an outage at ``start`` from
    (the window before it)."""
    return int(windows.receiver_fault[start - 1]) if 1 <= start <= len(windows) else 0


def excluded_by_truth(windows: Windows, n: int, place: Callable[[Windows], np.ndarray]) -> int:
    """How many outages ``place`` would have put where the GNSS truth is bad or the receiver had no
    fix at their start."""
    if windows.truth_ok.all() and windows.receiver_ok.all():
        return 0
    try:
        starts = place(windows.ignoring_truth())
    except InputError:
        return 0
    return sum(1 for k in starts if truth_faults_near(windows, int(k), n) or receiver_faults_before(windows, int(k)))


def tile(windows: Windows, n: int) -> np.ndarray:
    """Back-to-back outages of ``n`` windows covering each segment (the paper's protocol)."""
    return every(windows, n, n)


def every(windows: Windows, n: int, period: int) -> np.ndarray:
    """An ``n``-window outage every ``period`` windows (``period >= n``; equal: tiled)."""
    if period < n:
        raise InputError(f"outage period {period} s is shorter than the outage ({n} s)",
                         "choose a period at least as long as the outage", param="placement")
    ok = starts_ok(windows)
    starts: list[int] = []
    for a, b in segment_ranges(windows):
        k = a
        while k + n <= b:
            if ok[k]:
                starts.append(k)
                k += period
            else:  # the receiver has no fix here: the next start after its loss
                k += 1
    return np.asarray(starts, dtype=int)


def at(windows: Windows, times_s: list[float], n: int) -> np.ndarray:
    """Outages starting at the windows nearest to ``times_s`` (s from the start of the drive)."""
    starts = []
    for t in sorted(times_s):
        k = int(np.argmin(np.abs(windows.t0_s - t))) if len(windows) else -1
        near = k >= 0 and abs(windows.t0_s[k] - t) <= 1.0
        faults = truth_faults_near(windows, k, n) if near else 0
        if faults and valid_start(windows.ignoring_truth(), k, n):
            raise InputError(
                f"start time {t:g} s: the GNSS truth of that {n} s outage is not trustworthy "
                f"({', '.join(fault_names(faults))})",
                "choose a time where the fixes are good (the recording's gnss/quality timeline shows them)",
                param="placement",
            )
        lost = receiver_faults_before(windows, k) if near else 0
        if lost and valid_start(windows.ignoring_truth(), k, n):
            raise InputError(
                f"start time {t:g} s: the receiver has no trustworthy fix to start that outage from "
                f"({', '.join(fault_names(lost))})",
                "choose a time where the receiver has fixes (the recording's gnss/state timeline shows where "
                "it lost them)",
                param="placement",
            )
        if k < 0 or not valid_start(windows, k, n) or abs(windows.t0_s[k] - t) > 1.0:
            raise InputError(
                f"start time {t:g} s: no {n} s outage fits there",
                "choose start times between 1 s and "
                f"{max(0.0, windows.t0_s[-1] + WINDOW_S - n) if len(windows) else 0:g} s, away from gaps in the log",
                param="placement",
            )
        if starts and k < starts[-1] + n:
            raise InputError(f"start time {t:g} s overlaps the outage before it",
                             f"space the times at least {n} s apart", param="placement")
        starts.append(k)
    return np.asarray(starts, dtype=int)


def random(windows: Windows, n: int, count: int, seed: int) -> np.ndarray:
    """``count`` non-overlapping ``n``-window outages drawn uniformly (seeded; :class:`Random` checks both)."""
    rng = np.random.default_rng(seed)
    candidates = np.concatenate([np.arange(a, b - n + 1) for a, b in segment_ranges(windows)] or [np.zeros(0, int)])
    candidates = candidates[starts_ok(windows)[candidates]]
    chosen: list[int] = []
    for k in rng.permutation(candidates):
        if all(abs(int(k) - c) >= n for c in chosen):
            chosen.append(int(k))
            if len(chosen) == count:
                break
    if len(chosen) < count:
        raise InputError(f"{count} random outages: only {len(chosen)} non-overlapping {n} s outages fit in this drive",
                         param="placement")
    return np.sort(np.asarray(chosen, dtype=int))


def around(windows: Windows, intervals: list[tuple[float, float]], n: int) -> tuple[np.ndarray, list[int]]:
    """Outage starts centred on each interval (s); returns the starts and which intervals got one."""
    starts: list[int] = []
    used: list[int] = []
    for i, (t0, t1) in sorted(enumerate(intervals), key=lambda x: x[1][0]):
        length = t1 - t0
        first = t0 - (n - length) / 2.0 if length <= n - 1.0 else t0 - 1.0
        k = int(np.argmin(np.abs(windows.t0_s - first))) if len(windows) else -1
        for candidate in (k, k + 1, k - 1):
            if (0 <= candidate < len(windows) and valid_start(windows, candidate, n)
                    and (not starts or candidate >= starts[-1] + n)):
                starts.append(candidate)
                used.append(i)
                break
    return np.asarray(starts, dtype=int), used


# --- placements as values: what the API and the CLI pass around ----------------------------


@dataclass(frozen=True)
class OutagePlan:
    """Where one drive's outages go, as a placement planned them.

    Attributes:
        starts: first window of each synthetic outage (sorted indices into the windows).
        description: the placement in words, for reports and recordings.
        excluded: how many outages the placement would have put where the GNSS truth is bad, or
            right after a window where a receiver beside a reference had no fix to trust.
        gnss_gaps: the log's own GNSS losses to bridge, ``(last good fix s, first good fix s)``.
        too_short: no outage fits the drive, and the placement skips such a drive (the tiling
            of a report over several drives) instead of failing.
    """

    starts: np.ndarray
    description: str
    excluded: int = 0
    gnss_gaps: tuple[tuple[float, float], ...] = ()
    too_short: bool = False


@dataclass(frozen=True)
class Tile:
    """The paper's protocol: consecutive, back-to-back outages covering each segment."""

    event_types: ClassVar[tuple[str, ...]] = ()  # the events the plan needs detected: none

    def plan(self, windows: Windows, n_windows: int, events: Sequence[Any] = (), source: str = "") -> OutagePlan:
        starts = tile(windows, n_windows)
        return OutagePlan(starts, f"consecutive {n_windows:g} s outages (the paper's protocol)",
                          excluded_by_truth(windows, n_windows, lambda w: tile(w, n_windows)),
                          too_short=len(starts) == 0)


@dataclass(frozen=True)
class Every:
    """An outage every ``period_s`` seconds (whole seconds, longer than the outage: GNSS in between)."""

    period_s: float
    event_types: ClassVar[tuple[str, ...]] = ()  # the events the plan needs detected: none

    def __post_init__(self) -> None:
        outage_windows(self.period_s, "outage period", "placement")

    def plan(self, windows: Windows, n_windows: int, events: Sequence[Any] = (), source: str = "") -> OutagePlan:
        period = outage_windows(self.period_s, "outage period", "placement")
        if period == n_windows:  # the promise of --every is GNSS in between
            raise InputError(f"an outage every {period} s with {n_windows} s outages leaves no GNSS between them",
                             f"give a longer period (e.g. every {n_windows + max(n_windows // 2, 5)} s), or no "
                             "placement to tile the drive with back-to-back outages", param="placement")
        return OutagePlan(every(windows, n_windows, period), f"a {n_windows:g} s outage every {self.period_s:g} s",
                          excluded_by_truth(windows, n_windows, lambda w: every(w, n_windows, period)))


@dataclass(frozen=True)
class At:
    """Outages starting at the given times (s since the drive's first sample)."""

    times_s: tuple[float, ...]
    event_types: ClassVar[tuple[str, ...]] = ()  # the events the plan needs detected: none

    def __post_init__(self) -> None:
        # At(12.0) was "'float' object is not iterable", At(("12",)) a numpy type error, At(()) a report of no outage
        times = self.times_s
        if isinstance(times, (str, bytes)) or not isinstance(times, Iterable) or not (times := tuple(times)):
            raise InputError(f"outage start times {self.times_s!r}: not a sequence of seconds",
                             "give at least one, e.g. At((12.0, 40.0)) or At((12.0,))", param="placement")
        object.__setattr__(self, "times_s", times)  # a tuple, whatever sequence was given
        for t in times:
            if isinstance(t, bool) or not isinstance(t, numbers.Real):
                raise InputError(f"outage start time {t!r} is not a number of seconds",
                                 "give seconds as numbers, e.g. At((12.0, 40.0))", param="placement")

    def plan(self, windows: Windows, n_windows: int, events: Sequence[Any] = (), source: str = "") -> OutagePlan:
        times = list(self.times_s)
        return OutagePlan(at(windows, times, n_windows),
                          f"{n_windows:g} s outages at {', '.join(f'{x:g} s' for x in self.times_s)}",
                          excluded_by_truth(windows, n_windows, lambda w: at(w, times, n_windows)))


@dataclass(frozen=True)
class Random:
    """``count`` non-overlapping outages drawn uniformly with ``seed``."""

    count: int
    seed: int = 0
    event_types: ClassVar[tuple[str, ...]] = ()  # the events the plan needs detected: none

    def __post_init__(self) -> None:
        for name, value in (("count", self.count), ("seed", self.seed)):
            if isinstance(value, bool) or not isinstance(value, numbers.Integral):
                raise InputError(f"random outages: {name} {value!r} is not a whole number", param="placement")
        if self.count < 1:
            raise InputError(f"{self.count} random outages: need at least one", param="placement")
        if self.seed < 0:
            raise InputError(f"random seed {self.seed} is negative", "use a seed >= 0", param="placement")

    def plan(self, windows: Windows, n_windows: int, events: Sequence[Any] = (), source: str = "") -> OutagePlan:
        def draw(w: Windows) -> np.ndarray:
            return random(w, n_windows, self.count, self.seed)

        return OutagePlan(draw(windows), f"{self.count} random {n_windows:g} s outages (seed {self.seed})",
                          excluded_by_truth(windows, n_windows, draw))


#: A real loss of GNSS in the log (an event type, :mod:`ionav_viz.analysis.events`): outages
#: bridge it from the last good fix and are scored at the first good fix after it.
GNSS_OUTAGE = "gnss-outage"


@dataclass(frozen=True)
class AroundEvents:
    """One outage centred on each detected event of the given types (see ``ionav-viz events``);
    ``gnss-outage`` bridges the log's own GNSS losses instead.

    The caller detects the events of :attr:`event_types` (:func:`ionav_viz.analysis.events.detect_events`)
    and passes them to :meth:`plan`; every placement has ``event_types`` (the others none).
    """

    types: tuple[str, ...]

    def __post_init__(self) -> None:
        # AroundEvents("hard-brake") was "unknown event type(s) h, a, r, d, ..."; AroundEvents(())
        # (and --on "") "no GNSS outage of 2 s or more in this drive"
        types = self.types
        if (isinstance(types, (str, bytes)) or not isinstance(types, Iterable) or not (types := tuple(types))
                or not all(isinstance(t, str) for t in types)):
            raise InputError(f"event types {self.types!r}: not a sequence of names",
                             "give at least one, e.g. AroundEvents(('hard-brake', 'roundabout'))", param="placement")
        object.__setattr__(self, "types", types)  # a tuple, whatever sequence was given

    @property
    def event_types(self) -> tuple[str, ...]:
        """The events :meth:`plan` needs detected."""
        return self.types

    def plan(self, windows: Windows, n_windows: int, events: Sequence[Any] = (), source: str = "") -> OutagePlan:
        where = f"{source}: " if source else ""
        gaps = tuple((e.t0_s, e.t1_s) for e in events if e.type == GNSS_OUTAGE) if GNSS_OUTAGE in self.types else ()
        kinds = tuple(t for t in self.types if t != GNSS_OUTAGE)
        bridged = f"the log's own {len(gaps)} GNSS outage(s)"
        if not kinds:
            if not gaps:
                raise InputError(f"{where}no GNSS outage of 2 s or more in this drive",
                                 f"see 'ionav-viz events {source}'")
            return OutagePlan(np.zeros(0, dtype=int), f"every estimator through {bridged}, from the last good fix", 0,
                              gaps)
        targets = [e for e in events if e.type in kinds]
        spans = [(e.t0_s, e.t1_s) for e in targets]
        starts, used = around(windows, spans, n_windows)
        if len(used) < len(targets):
            log.warning("%s%d of %d %s event(s) got no outage (overlapping another, too near a gap or an end, on bad "
                        "GNSS truth, or right after the receiver lost the sky)",
                        where, len(targets) - len(used), len(targets), "/".join(kinds))
        if len(starts) == 0:
            raise InputError(f"{where}no {' or '.join(kinds)} event with room for a {n_windows:g} s outage",
                             f"see 'ionav-viz events {source}'")
        description = (f"one {n_windows:g} s outage centred on each {', '.join(kinds)} event "
                       f"({len(used)} of {len(targets)})")
        if gaps:
            description += f"; and {bridged}"
        return OutagePlan(starts, description,
                          excluded_by_truth(windows, n_windows, lambda w: around(w, spans, n_windows)[0]), gaps)


@dataclass(frozen=True)
class Planned:
    """Exactly the outages of a plan file (``--plan``, :mod:`.plan_file`): starts in s since the
    drive's first sample, each on a window boundary (within 1 ms) with room for the outage, else an
    error naming the outage: the plan was made on another drive, or the drive was read differently."""

    times_s: tuple[float, ...]
    description: str
    where: str = "the plan"
    event_types: ClassVar[tuple[str, ...]] = ()  # the events the plan needs detected: none

    def plan(self, windows: Windows, n_windows: int, events: Sequence[Any] = (), source: str = "") -> OutagePlan:
        starts: list[int] = []
        for i, t in enumerate(self.times_s):
            k = int(np.argmin(np.abs(windows.t0_s - t))) if len(windows) else -1
            on_boundary = k >= 0 and abs(windows.t0_s[k] - t) <= 1e-3
            if (on_boundary and (lost := receiver_faults_before(windows, k))
                    and valid_start(windows.ignoring_truth(), k, n_windows)):
                raise InputError(f"{self.where}: outage {i + 1} ({t:.3f} s after the drive's start): the receiver has "
                                 f"no trustworthy fix to start it from ({', '.join(fault_names(lost))})",
                                 "plan outages where the receiver has fixes (outage-log places them so)", param="plan")
            if not on_boundary or not valid_start(windows, k, n_windows):
                raise InputError(f"{self.where}: outage {i + 1} ({t:.3f} s after the drive's start) does not fit this "
                                 "drive's windows",
                                 "give the drive and reading options the plan was made with", param="plan")
            if starts and k < starts[-1] + n_windows:
                raise InputError(f"{self.where}: outage {i + 1} overlaps the one before it",
                                 "write the plan again with outage-log", param="plan")
            starts.append(k)
        return OutagePlan(np.asarray(starts, dtype=int), self.description)


Placement = Tile | Every | At | Random | AroundEvents | Planned


#: A real loss is bridged only when the fixes either side of it lie no further apart than the car
#: could drive in it: at the faster of its speeds there, accelerating at this rate (m/s^2, a car's
#: strong acceleration) all the way, plus :data:`BRIDGE_FIX_SLACK_M` for the two fixes' own errors.
#: A phone's first fix after a loss can land a kilometre off (a real log: 1017 m after 11.9 s, 85 m/s):
#: scored against it, every estimator "erred" by that kilometre.
BRIDGE_MAX_ACCEL_MPS2 = 3.0
BRIDGE_FIX_SLACK_M = 30.0


def reachable(windows: Windows, k: int, end: int) -> bool:
    """Whether the truth at window boundary ``end`` lies within reach of the car from boundary ``k``
    (:data:`BRIDGE_MAX_ACCEL_MPS2`): the straight line between the two fixes against the speeds there."""
    from ..core.geo import steps_en_m

    seconds = float(windows.t0_s[end] - windows.t0_s[k])
    east, north = steps_en_m(np.array([windows.lat0_deg[k], windows.lat0_deg[end]]),
                             np.array([windows.lon0_deg[k], windows.lon0_deg[end]]))
    speed = float(np.nanmax([windows.speed0_mps[k], windows.speed0_mps[end], 0.0]))
    return (float(np.hypot(east[0], north[0]))
            <= (speed + 0.5 * BRIDGE_MAX_ACCEL_MPS2 * seconds) * seconds + BRIDGE_FIX_SLACK_M)


#: Why a GNSS loss of the log could not be bridged (:func:`unbridged`), as the reports say it (after "N with").
NO_FIX_BEFORE = "no trustworthy fix just before it"
DATA_GAP = "a gap in the log's samples in it"
DRIVE_END = "the drive's end in it or right after"
NO_FIX_AFTER = "no trustworthy fix within 3 s after it"
OUT_OF_REACH = "fixes either side further apart than the car could drive in it"


def bridging(windows: Windows, gaps: Sequence[tuple[float, float]], max_extra: int = 3) -> list[tuple[int, int, int]]:
    """Outages through the log's own GNSS gaps: for each gap ``(last good fix s, first good fix s)``,
    ``(gap index, start window, windows)`` of the outage that starts at the window boundary at or
    before the last good fix (the window before it has good truth, for the IDNN's first input)
    and ends at the first boundary at or after the first good fix whose next window has good truth
    (its start is the only truth there is). Beside a reference the window before the start needs
    the receiver's fixes too (the estimators start from them). Gaps without such windows in one
    gap-free segment (a data gap, an end of the drive) get none, and so do gaps whose fixes either
    side lie further apart than the car could drive in them (:func:`reachable`); :func:`unbridged`
    says which and why (:func:`bridge_each` gives both at once)."""
    return placed_of(bridge_each(windows, gaps, max_extra))


def unbridged(windows: Windows, gaps: Sequence[tuple[float, float]], max_extra: int = 3) -> dict[str, int]:
    """How many of ``gaps`` :func:`bridging` leaves out, per reason (:data:`NO_FIX_BEFORE`,
    :data:`DATA_GAP`, :data:`DRIVE_END`, :data:`NO_FIX_AFTER`, :data:`OUT_OF_REACH`)."""
    return reasons_of(bridge_each(windows, gaps, max_extra))


def bridge_each(windows: Windows, gaps: Sequence[tuple[float, float]],
                max_extra: int = 3) -> list[tuple[int, int] | str]:
    """Per gap, :func:`bridging`'s ``(start window, windows)``, or why there is none."""
    start_ok = windows.truth_ok & windows.receiver_ok
    return [_bridge(windows, start_ok, last_good, first_good, max_extra) for last_good, first_good in gaps]


def placed_of(each: Sequence[tuple[int, int] | str]) -> list[tuple[int, int, int]]:
    """``(gap index, start window, windows)`` of the gaps :func:`bridge_each` bridged."""
    return [(i, *got) for i, got in enumerate(each) if isinstance(got, tuple)]


def reasons_of(each: Sequence[tuple[int, int] | str]) -> dict[str, int]:
    """How many gaps :func:`bridge_each` left out, per reason (in the order first met)."""
    reasons = [got for got in each if isinstance(got, str)]
    return {reason: reasons.count(reason) for reason in dict.fromkeys(reasons)}


def _bridge(windows: Windows, start_ok: np.ndarray, last_good: float, first_good: float,
            max_extra: int) -> tuple[int, int] | str:
    """:func:`bridging`'s ``(start window, windows)`` for one gap, or why there is none."""
    t0 = windows.t0_s
    k = int(np.searchsorted(t0, last_good + 1e-6, side="right")) - 1
    while k >= 2 and not start_ok[k - 1] and t0[k] > last_good - max_extra:
        k -= 1  # the window before touches the loss (its end is interpolated from a bad sample)
    if k < 1 or not start_ok[k - 1]:
        return NO_FIX_BEFORE
    if windows.segment[k - 1] != windows.segment[k]:
        return DATA_GAP
    shortest = max(1, int(np.ceil(first_good - t0[k] - 1e-6)))
    for n in range(shortest, shortest + max_extra + 1):
        end = k + n
        if end >= len(windows):
            return DRIVE_END
        if windows.segment[end] != windows.segment[k]:
            return DATA_GAP
        if windows.truth_ok[end]:
            return (k, n) if reachable(windows, k, end) else OUT_OF_REACH
    return NO_FIX_AFTER
