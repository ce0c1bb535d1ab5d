"""Where GNSS outages go: outage sequences as runs of consecutive 1-second windows.

An outage of ``n`` seconds starting at window ``k`` blanks GNSS over windows ``k .. k+n-1``;
the estimators start from the GNSS fix at the start of window ``k``. Every sequence lies in
one gap-free segment, and window ``k-1`` must exist in that segment too: the IDNN's first
window is fed the GNSS displacement of the second before the outage (the paper's Figure 2).
So the first window of each segment never starts an outage. The same holds for bad GNSS truth
(:attr:`Windows.truth_ok`): every window of an outage, and the one before it, must have good
truth, so a stretch of bad fixes splits a segment as a gap does.

Placements are values (:class:`Tile`, :class:`Every`, :class:`At`, :class:`Random`,
:class:`AroundEvents`), each with ``starts(windows, n, events)`` and ``describe(outage_s)``, over
these functions (all return sorted start indices into :class:`~ionav_viz.nav.windows.Windows`):

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

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.gnss_quality import fault_names
from .windows import Windows


def outage_windows(outage_s: float, what: str = "outage length", param: str = "outage_s") -> int:
    """Outage length (s) -> number of 1-second windows; must be a positive whole number."""
    if not np.isfinite(outage_s) or outage_s <= 0 or abs(outage_s - round(outage_s)) > 1e-9:
        raise InputError(
            f"{what} {outage_s:g} s is not a positive whole number of seconds",
            "the estimators predict once per 1 s window; use whole seconds, e.g. 10 s",
            param=param,
        )
    return int(round(outage_s))


def _segment_ranges(windows: Windows) -> list[tuple[int, int]]:
    """Per run of consecutive good-truth windows of one segment, the range ``[first possible
    start, end)`` of window indices (the run's first window only feeds the IDNN's first input)."""
    seg = windows.segment
    if len(seg) == 0:
        return []
    ok = windows.truth_ok
    # a run breaks where the segment changes or the truth turns bad
    key = np.where(ok, seg, -1)
    starts = np.flatnonzero(ok & np.concatenate([[True], key[1:] != key[:-1]]))
    ends = np.flatnonzero(ok & np.concatenate([key[1:] != key[:-1], [True]])) + 1
    return [(int(a) + 1, int(b)) for a, b in zip(starts, ends)]


def truth_faults_near(windows: Windows, start: int, n: int) -> int:
    """Fault bits of the windows an ``n``-window outage at ``start`` needs good (start-1 .. start+n-1)."""
    return int(np.bitwise_or.reduce(windows.truth_fault[max(start - 1, 0) : start + n])) if len(windows) else 0


def excluded_by_truth(windows: Windows, n: int, place: Callable[[Windows], np.ndarray]) -> int:
    """How many outages ``place`` would have put where the GNSS truth is bad."""
    if windows.truth_ok.all():
        return 0
    try:
        starts = place(windows.ignoring_truth())
    except InputError:
        return 0
    return sum(1 for k in starts if truth_faults_near(windows, int(k), n))


def valid_start(windows: Windows, start: int, n: int) -> bool:
    """Whether an ``n``-window outage can start at window ``start``."""
    return any(a <= start and start + n <= b for a, b in _segment_ranges(windows))


def tile(windows: Windows, n: int) -> np.ndarray:
    """Back-to-back outages of ``n`` windows covering each segment (the paper's protocol)."""
    return every(windows, n, n)


def every(windows: Windows, n: int, period: int) -> np.ndarray:
    """An ``n``-window outage every ``period`` windows (``period >= n``)."""
    if period < n:
        raise InputError(f"outage period {period} s is shorter than the outage ({n} s)", "choose a period at least as long as the outage", param="placement")
    starts = [np.arange(a, b - n + 1, period) for a, b in _segment_ranges(windows)]
    return np.concatenate(starts).astype(int) if starts else np.zeros(0, dtype=int)


def at(windows: Windows, times_s: list[float], n: int) -> np.ndarray:
    """Outages starting at the windows nearest to ``times_s`` (s from the start of the drive)."""
    starts = []
    for t in sorted(times_s):
        k = int(np.argmin(np.abs(windows.t0_s - t))) if len(windows) else -1
        faults = truth_faults_near(windows, k, n) if k >= 0 and abs(windows.t0_s[k] - t) <= 1.0 else 0
        if faults and valid_start(windows.ignoring_truth(), k, n):
            raise InputError(
                f"start time {t:g} s: the GNSS truth of that {n} s outage is not trustworthy ({', '.join(fault_names(faults))})",
                "choose a time where the fixes are good (the recording's gnss/quality timeline shows them)",
                param="placement",
            )
        if k < 0 or not valid_start(windows, k, n) or abs(windows.t0_s[k] - t) > 1.0:
            raise InputError(
                f"start time {t:g} s: no {n} s outage fits there",
                f"choose start times between 1 s and {max(0.0, windows.t0_s[-1] + 1 - n) if len(windows) else 0:g} s, away from gaps in the log",
                param="placement",
            )
        if starts and k < starts[-1] + n:
            raise InputError(f"start time {t:g} s overlaps the outage before it", f"space the times at least {n} s apart", param="placement")
        starts.append(k)
    return np.asarray(starts, dtype=int)


def random(windows: Windows, n: int, count: int, seed: int) -> np.ndarray:
    """``count`` non-overlapping ``n``-window outages drawn uniformly (seeded)."""
    if count < 1:
        raise InputError(f"{count} random outages: need at least one", param="placement")
    if seed < 0:
        raise InputError(f"random seed {seed} is negative", "use a seed >= 0", param="placement")
    rng = np.random.default_rng(seed)
    candidates = np.concatenate([np.arange(a, b - n + 1) for a, b in _segment_ranges(windows)] or [np.zeros(0, int)])
    chosen: list[int] = []
    for k in rng.permutation(candidates):
        if all(abs(int(k) - c) >= n for c in chosen):
            chosen.append(int(k))
            if len(chosen) == count:
                break
    if len(chosen) < count:
        raise InputError(f"{count} random outages: only {len(chosen)} non-overlapping {n} s outages fit in this drive", param="placement")
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
            if 0 <= candidate < len(windows) and valid_start(windows, candidate, n) and (not starts or candidate >= starts[-1] + n):
                starts.append(candidate)
                used.append(i)
                break
    return np.asarray(starts, dtype=int), used


# --- placements as values: what the API and the CLI pass around ----------------------------


@dataclass(frozen=True)
class Tile:
    """The paper's protocol: consecutive, back-to-back outages covering each segment."""

    def starts(self, windows: Windows, n: int, events: Sequence[Any] = ()) -> np.ndarray:
        return tile(windows, n)

    def describe(self, outage_s: float) -> str:
        return f"consecutive {outage_s:g} s outages (the paper's protocol)"


@dataclass(frozen=True)
class Every:
    """An outage every ``period_s`` seconds (whole seconds, at least the outage length)."""

    period_s: float

    def starts(self, windows: Windows, n: int, events: Sequence[Any] = ()) -> np.ndarray:
        return every(windows, n, outage_windows(self.period_s, "outage period", "placement"))

    def describe(self, outage_s: float) -> str:
        return f"a {outage_s:g} s outage every {self.period_s:g} s"


@dataclass(frozen=True)
class At:
    """Outages starting at the given times (s since the drive's first sample)."""

    times_s: tuple[float, ...]

    def starts(self, windows: Windows, n: int, events: Sequence[Any] = ()) -> np.ndarray:
        return at(windows, list(self.times_s), n)

    def describe(self, outage_s: float) -> str:
        return f"{outage_s:g} s outages at {', '.join(f'{x:g} s' for x in self.times_s)}"


@dataclass(frozen=True)
class Random:
    """``count`` non-overlapping outages drawn uniformly with ``seed``."""

    count: int
    seed: int = 0

    def starts(self, windows: Windows, n: int, events: Sequence[Any] = ()) -> np.ndarray:
        return random(windows, n, self.count, self.seed)

    def describe(self, outage_s: float) -> str:
        return f"{self.count} random {outage_s:g} s outages (seed {self.seed})"


@dataclass(frozen=True)
class AroundEvents:
    """One outage centred on each detected manoeuvre of the given types (see ``ionav-viz events``).

    The caller detects the events (:func:`ionav_viz.analysis.events.detect_events`) and passes
    them to :meth:`starts`; ``used``/``targets`` then say how many got an outage.
    """

    types: tuple[str, ...]

    def targets(self, events: Sequence[Any]) -> list[Any]:
        return [e for e in events if e.type in self.types]

    def starts(self, windows: Windows, n: int, events: Sequence[Any] = ()) -> np.ndarray:
        starts, _ = around(windows, [(e.t0_s, e.t1_s) for e in self.targets(events)], n)
        return starts

    def describe(self, outage_s: float, used: int | None = None, targets: int | None = None) -> str:
        counts = f" ({used} of {targets})" if used is not None else ""
        return f"one {outage_s:g} s outage centred on each {', '.join(self.types)} event{counts}"


Placement = Tile | Every | At | Random | AroundEvents


def bridging(windows: Windows, gaps: Sequence[tuple[float, float]], max_extra: int = 3) -> list[tuple[int, int, int]]:
    """Outages through the log's own GNSS gaps: for each gap ``(last good fix s, first good fix s)``,
    ``(gap index, start window, windows)`` of the outage that starts at the window boundary at or
    before the last good fix (the window before it has good truth, for the IDNN's first input)
    and ends at the first boundary at or after the first good fix whose next window has good truth
    (its start is the only truth there is). Gaps without such windows in one gap-free segment
    (a data gap, an end of the drive) get none."""
    out = []
    t0 = windows.t0_s
    for i, (last_good, first_good) in enumerate(gaps):
        k = int(np.searchsorted(t0, last_good + 1e-6, side="right")) - 1
        while k >= 2 and not windows.truth_ok[k - 1] and t0[k] > last_good - max_extra:
            k -= 1  # the window before touches the loss (its end is interpolated from a bad sample)
        if k < 1 or not windows.truth_ok[k - 1] or windows.segment[k - 1] != windows.segment[k]:
            continue
        shortest = max(1, int(np.ceil(first_good - t0[k] - 1e-6)))
        for n in range(shortest, shortest + max_extra + 1):
            end = k + n
            if end >= len(windows) or windows.segment[end] != windows.segment[k]:
                break
            if windows.truth_ok[end]:
                out.append((i, k, n))
                break
    return out
