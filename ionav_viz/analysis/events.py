"""Finding the paper's challenging manoeuvres (Section 2) in any drive.

All detectors work on the drive resampled to a uniform 10 Hz grid (never across a gap longer
than 1 s), on two smoothed signals:

* longitudinal acceleration ``a`` (m/s^2): the derivative of the GNSS (Doppler) speed, smoothed
  over ``accel_smooth_s`` (0.5 s). The GNSS speed is used rather than the accelerometer because
  it carries no mount offset and no road-grade gravity;
* yaw rate ``r`` (rad/s, counter-clockwise positive): the gyro minus its standstill bias (as the
  INS estimates it, when the drive stands still for 3 s or more), smoothed over ``yaw_smooth_s`` (1 s).

A *turning segment* is a maximal stretch where ``|r| >= turn_rate_radps`` (3 deg/s) with one
sign; its heading change is the integral of ``r`` and its radius the distance travelled divided
by the heading change. Definitions (thresholds in :class:`EventThresholds`, all overridable):

``hard-brake``
    ``a <= -0.45 g`` (the paper's definition, after [19]); the event spans the surrounding
    deceleration below ``-brake_onset_g`` (0.1 g). Values: peak deceleration (g), speed before and
    after (m/s).
``roundabout``
    A turning segment through at least ``roundabout_min_turn_deg`` (115 deg) of heading at a
    radius of 8-60 m: most of the way round a roundabout (first exits included: a UK roundabout's
    circulating turn plus its opposite entry and exit flares). The event spans the segment and
    any turning segment of the other sign within 3 s on either side (the flares).
    Values: heading change (deg), radius (m). U-turns at that radius count too.
``sharp-cornering``
    A turning segment of 70-115 deg within 8 s at a radius of at most 30 m, outside a roundabout.
    Values: heading change, radius, duration.
``left-right``
    Successive left and right turns: at least two consecutive turning segments of alternating
    sign, each turning at least 20 deg, less than ``left_right_gap_s`` (2 s) apart, outside a
    roundabout. Values: number of turns, largest heading change.
``quick-accel``
    A quick change in acceleration: two consecutive acceleration peaks of opposite sign, each at
    least ``quick_accel_peak_mps2`` (1.2 m/s^2), at most ``quick_accel_window_s`` (4 s) apart.
    The event spans the two peaks. Values: the two peaks (m/s^2) and the jerk between them (m/s^3).
``gnss-outage``
    A real loss of GNSS in the log: a stretch of samples whose GNSS is bad or missing
    (:mod:`ionav_viz.core.gnss_quality`: no fix, frozen, at (0, 0), ...) lasting at least
    ``gnss_outage_min_s`` (2 s) from the last good fix to the first good fix after it; the event
    spans those two fixes. Values: length (s), bad samples. The other detectors see nothing inside
    bad GNSS (their speed is the GNSS speed). Beside a reference (``--truth-topic``) it is the
    receiver's loss, the GNSS the estimators are given: bridged, it is scored against the reference.
``cruise``
    Straight-line cruising, the motorway reference: speed at least 15 m/s, ``|a| <= 0.5 m/s^2``
    (``a`` further smoothed over ``cruise_smooth_s``, 3 s: steady on average, so the speed noise of
    a fix-only log does not cut a cruise into pieces), ``|r| <= 0.02 rad/s``, for at least 10 s.
    Values: mean speed (m/s).
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field

import numpy as np

from ..core.drive import Drive
from ..core.grid import GRID_RATE_HZ
from ..core.overrides import check_ranges, with_overrides
from ..core.runs import run_ranges
from ..core.units import G_MPS2
from ..experiment.outages import GNSS_OUTAGE  # a real loss of GNSS in the log, not a manoeuvre

log = logging.getLogger("ionav_viz")

MANOEUVRE_TYPES = ("hard-brake", "roundabout", "sharp-cornering", "left-right", "quick-accel", "cruise")
EVENT_TYPES = (*MANOEUVRE_TYPES, GNSS_OUTAGE)
#: Names event types had before, each with its name now (the scenario's and the event's are one).
RENAMED_TYPES = {"sharp-corner": "sharp-cornering"}


def current_type_names(types: tuple[str, ...]) -> tuple[str, ...]:
    """``types`` with each old name (:data:`RENAMED_TYPES`) replaced by its name now, said once as
    deprecated."""
    old = [t for t in types if t in RENAMED_TYPES]
    for name in old:
        log.warning("event type %s is %s now", name, RENAMED_TYPES[name])
    return tuple(RENAMED_TYPES.get(t, t) for t in types)


#: Plausible range of each threshold (values outside are refused before any work; smoothing
#: windows are bounded so the filters stay small). Units are in the names.
THRESHOLD_LIMITS = {
    "accel_smooth_s": (0.1, 10.0), "yaw_smooth_s": (0.1, 10.0), "hard_brake_g": (0.05, 2.0),
    "brake_onset_g": (0.0, 2.0), "turn_rate_radps": (0.001, 2.0), "roundabout_min_turn_deg": (0.0, 1080.0),
    "roundabout_radius_m": (1.0, 1000.0), "flare_gap_s": (0.0, 60.0), "sharp_min_turn_deg": (0.0, 360.0),
    "sharp_max_s": (0.5, 120.0), "sharp_max_radius_m": (1.0, 1000.0), "left_right_min_turn_deg": (0.0, 360.0),
    "left_right_gap_s": (0.0, 60.0), "quick_accel_peak_mps2": (0.05, 20.0), "quick_accel_window_s": (0.5, 60.0),
    "cruise_min_speed_mps": (0.0, 100.0), "cruise_max_accel_mps2": (0.0, 20.0), "cruise_max_yaw_radps": (0.0, 2.0),
    "cruise_min_s": (1.0, 3600.0), "cruise_smooth_s": (0.1, 30.0), "gnss_outage_min_s": (0.1, 3600.0),
}  # fmt: skip


@dataclass(frozen=True)
class EventThresholds:
    """Every threshold of the detectors (see the module docstring)."""

    accel_smooth_s: float = 0.5
    yaw_smooth_s: float = 1.0
    hard_brake_g: float = 0.45
    brake_onset_g: float = 0.1
    turn_rate_radps: float = 0.0524  # 3 deg/s
    roundabout_min_turn_deg: float = 115.0
    roundabout_radius_m: tuple[float, float] = (8.0, 60.0)
    flare_gap_s: float = 3.0
    sharp_min_turn_deg: float = 70.0
    sharp_max_s: float = 8.0
    sharp_max_radius_m: float = 30.0
    left_right_min_turn_deg: float = 20.0
    left_right_gap_s: float = 2.0
    quick_accel_peak_mps2: float = 1.2
    quick_accel_window_s: float = 4.0
    cruise_min_speed_mps: float = 15.0
    cruise_max_accel_mps2: float = 0.5
    cruise_max_yaw_radps: float = 0.02
    cruise_min_s: float = 10.0
    cruise_smooth_s: float = 3.0
    gnss_outage_min_s: float = 2.0

    def __post_init__(self) -> None:
        check_ranges(self, THRESHOLD_LIMITS, "threshold", "thresholds")

    def with_overrides(self, pairs: list[str]) -> EventThresholds:
        """``['hard_brake_g=0.4', ...]`` -> a copy with those thresholds changed."""
        return with_overrides(self, pairs, THRESHOLD_LIMITS, "threshold", "thresholds")


@dataclass
class Event:
    """A detected manoeuvre: type, interval (s from the start of the drive) and measured values."""

    type: str
    t0_s: float
    t1_s: float
    values: dict[str, float | int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # plain floats (not numpy scalars), times to the microsecond: the 10 Hz grid's sums carry
        # rounding noise (28.700000000000003) that says nothing; a count (turns, bad samples) a plain int
        self.t0_s = round(float(self.t0_s), 6)
        self.t1_s = round(float(self.t1_s), 6)
        self.values = {k: int(v) if isinstance(v, (int, np.integer)) and not isinstance(v, bool) else float(v)
                       for k, v in self.values.items()}

    def to_dict(self) -> dict:
        return {"type": self.type, "start_s": round(self.t0_s, 3), "end_s": round(self.t1_s, 3),
                # counts stay whole
                **{k: v if isinstance(v, int) else round(float(v), 3) for k, v in self.values.items()}}


@dataclass
class Signals:
    """Uniform 10 Hz signals of a drive; ``valid`` is False in gaps."""

    t_s: np.ndarray
    speed_mps: np.ndarray
    accel_mps2: np.ndarray
    yaw_rate_radps: np.ndarray
    valid: np.ndarray


def _smooth(x: np.ndarray, seconds: float, rate_hz: float) -> np.ndarray:
    n = max(1, int(round(seconds * rate_hz)))
    if n == 1:
        return x.copy()
    kernel = np.ones(n) / n
    padded = np.concatenate([np.full(n // 2, x[0]), x, np.full(n - 1 - n // 2, x[-1])])
    return np.convolve(padded, kernel, mode="valid")


def signals_of(drive: Drive, th: EventThresholds) -> Signals:
    """The drive on a 10 Hz grid with smoothed acceleration (from GNSS speed) and yaw rate."""
    from ..nav.bias import estimate_bias

    t = drive.t_s
    grid = np.arange(0.0, t[-1] + 1e-9, 1.0 / GRID_RATE_HZ)
    grid = grid[grid >= t[0] - 1e-9]  # a --span's drive starts later on its own clock: nothing before it is seen
    k = np.clip(np.searchsorted(t, grid), 1, len(t) - 1)
    good = drive.gnss_ok
    valid = ((t[k] - t[k - 1]) <= 1.0) & good[k] & good[k - 1]  # nothing is seen inside bad GNSS
    speed = np.interp(grid, t[good], drive.speed_mps[good]) if good.sum() >= 2 else np.interp(grid, t, drive.speed_mps)
    still = estimate_bias(drive)  # the same standstill biases the INS uses
    bias = still.gyro_radps if still is not None else 0.0
    return smoothed_signals(grid, speed, np.interp(grid, t, drive.yaw_rate_radps) - bias, valid, th)


def smoothed_signals(t_s: np.ndarray, speed_mps: np.ndarray, yaw_rate_radps: np.ndarray, valid: np.ndarray,
                     th: EventThresholds) -> Signals:
    """Signals on a 10 Hz grid: acceleration from the smoothed speed, smoothed yaw rate."""
    yaw = _smooth(yaw_rate_radps, th.yaw_smooth_s, GRID_RATE_HZ)
    accel = _smooth(np.gradient(_smooth(speed_mps, th.accel_smooth_s, GRID_RATE_HZ), t_s), th.accel_smooth_s,
                    GRID_RATE_HZ)
    return Signals(t_s, speed_mps, accel, yaw, valid)


def detect_hard_brakes(s: Signals, th: EventThresholds) -> list[Event]:
    out = []
    braking = (s.accel_mps2 <= -th.brake_onset_g * G_MPS2) & s.valid
    for i0, i1 in run_ranges(braking):
        peak = float(s.accel_mps2[i0:i1].min())
        if peak <= -th.hard_brake_g * G_MPS2:
            out.append(Event("hard-brake", s.t_s[i0], s.t_s[i1 - 1], {
                "peak_decel_g": -peak / G_MPS2, "speed_before_mps": s.speed_mps[i0],
                "speed_after_mps": s.speed_mps[i1 - 1]}))
    return out


@dataclass
class _Turn:
    i0: int
    i1: int
    sign: int
    turn_deg: float
    radius_m: float
    t0: float
    t1: float


def turning_segments(s: Signals, th: EventThresholds) -> list[_Turn]:
    """Maximal one-signed stretches of turning faster than ``turn_rate_radps``."""
    dt = 1.0 / GRID_RATE_HZ
    turns = []
    for sign in (1, -1):
        for i0, i1 in run_ranges((sign * s.yaw_rate_radps >= th.turn_rate_radps) & s.valid):
            heading = float(np.sum(s.yaw_rate_radps[i0:i1]) * dt)
            dist = float(np.sum(s.speed_mps[i0:i1]) * dt)
            radius = dist / abs(heading) if heading else np.inf
            turns.append(_Turn(i0, i1, sign, float(np.degrees(abs(heading))), radius, s.t_s[i0], s.t_s[i1 - 1]))
    return sorted(turns, key=lambda x: x.i0)


def detect_turn_events(s: Signals, th: EventThresholds) -> list[Event]:
    """Roundabouts, sharp corners and successive left-right turns, from the turning segments."""
    turns = turning_segments(s, th)
    out: list[Event] = []
    r_lo, r_hi = th.roundabout_radius_m
    t0s, t1s = np.array([tr.t0 for tr in turns], dtype=float), np.array([tr.t1 for tr in turns], dtype=float)
    signs = np.array([tr.sign for tr in turns])
    round_spans = []
    for tr in turns:
        if tr.turn_deg >= th.roundabout_min_turn_deg and r_lo <= tr.radius_m <= r_hi:
            # entry and exit flares: the other way, just before and after
            flare = (signs != tr.sign) & (((tr.t0 - t1s >= 0) & (tr.t0 - t1s <= th.flare_gap_s))
                                          | ((t0s - tr.t1 >= 0) & (t0s - tr.t1 <= th.flare_gap_s)))
            t0, t1 = (min(tr.t0, float(t0s[flare].min(initial=np.inf))),
                      max(tr.t1, float(t1s[flare].max(initial=-np.inf))))
            round_spans.append((t0, t1))
            out.append(Event("roundabout", t0, t1, {"turn_deg": tr.turn_deg, "radius_m": tr.radius_m}))
    spans = np.array(round_spans, dtype=float).reshape(-1, 2)
    # the turns that overlap no roundabout's span
    inside = (((t0s[:, None] <= spans[None, :, 1]) & (t1s[:, None] >= spans[None, :, 0])).any(axis=1)
              if len(turns) else np.zeros(0, bool))
    outside = [tr for tr, within in zip(turns, inside) if not within]

    for tr in outside:
        if (th.sharp_min_turn_deg <= tr.turn_deg < th.roundabout_min_turn_deg and tr.t1 - tr.t0 <= th.sharp_max_s
                and tr.radius_m <= th.sharp_max_radius_m):
            out.append(Event("sharp-cornering", tr.t0, tr.t1,
                             {"turn_deg": tr.turn_deg, "radius_m": tr.radius_m, "duration_s": tr.t1 - tr.t0}))

    big = [tr for tr in outside if tr.turn_deg >= th.left_right_min_turn_deg]
    series: list[_Turn] = []
    for tr in big + [None]:
        if tr is not None and series and tr.sign != series[-1].sign and tr.t0 - series[-1].t1 <= th.left_right_gap_s:
            series.append(tr)
            continue
        if len(series) >= 2:
            out.append(Event("left-right", series[0].t0, series[-1].t1,
                             {"turns": len(series), "max_turn_deg": max(x.turn_deg for x in series)}))
        series = [tr] if tr is not None else []
    return out


def detect_quick_accel(s: Signals, th: EventThresholds) -> list[Event]:
    """Consecutive acceleration peaks of opposite sign, both large, close in time."""
    a = s.accel_mps2
    peaks = []
    for sign in (1, -1):
        for i0, i1 in run_ranges((sign * a >= th.quick_accel_peak_mps2) & s.valid):
            i = i0 + int(np.argmax(sign * a[i0:i1]))
            peaks.append((i, sign))
    peaks.sort()
    out = []
    for (i, si), (j, sj) in zip(peaks[:-1], peaks[1:]):
        dt = s.t_s[j] - s.t_s[i]
        if si != sj and dt <= th.quick_accel_window_s and s.valid[i:j + 1].all():
            out.append(Event("quick-accel", s.t_s[i], s.t_s[j], {
                "first_peak_mps2": a[i], "second_peak_mps2": a[j], "jerk_mps3": (a[j] - a[i]) / max(dt, 1e-9)}))
    return out


def detect_cruise(s: Signals, th: EventThresholds) -> list[Event]:
    steady = _smooth(s.accel_mps2, th.cruise_smooth_s, GRID_RATE_HZ)  # a moment's noise does not end a cruise
    calm = ((s.speed_mps >= th.cruise_min_speed_mps) & (np.abs(steady) <= th.cruise_max_accel_mps2)
            & (np.abs(s.yaw_rate_radps) <= th.cruise_max_yaw_radps) & s.valid)
    out = []
    for i0, i1 in run_ranges(calm):
        if s.t_s[i1 - 1] - s.t_s[i0] >= th.cruise_min_s:
            out.append(Event("cruise", s.t_s[i0], s.t_s[i1 - 1], {"mean_speed_mps": float(s.speed_mps[i0:i1].mean())}))
    return out


def detect_gnss_outages(drive: Drive, th: EventThresholds) -> list[Event]:
    """Stretches of bad GNSS lasting ``gnss_outage_min_s`` or more, from the last good fix before
    to the first good fix after (a stretch reaching an end of the drive has no such fix: left out).
    Beside a reference, the receiver's fixes (:meth:`~ionav_viz.core.drive.Drive.as_received`)."""
    bad = ~drive.as_received().gnss_ok
    out = []
    for i0, i1 in run_ranges(bad):
        if i0 == 0 or i1 >= len(drive):
            continue
        t0, t1 = float(drive.t_s[i0 - 1]), float(drive.t_s[i1])
        if t1 - t0 >= th.gnss_outage_min_s:
            out.append(Event(GNSS_OUTAGE, t0, t1, {"length_s": t1 - t0, "bad_samples": int(i1 - i0)}))
    return out


def detect_events(drive: Drive, thresholds: EventThresholds | None = None,
                  types: tuple[str, ...] = EVENT_TYPES) -> list[Event]:
    """Every manoeuvre of the requested ``types`` in ``drive``, in time order."""
    th = thresholds or EventThresholds()
    if len(drive) < 2:
        return []
    if drive.t_s[-1] - drive.t_s[0] < 2.0 / GRID_RATE_HZ:  # fewer than two steps of the 10 Hz grid: no manoeuvre to see
        return merge_overlapping([e for e in detect_gnss_outages(drive, th) if e.type in types])
    s = signals_of(drive, th)
    found = (detect_hard_brakes(s, th) + detect_turn_events(s, th) + detect_quick_accel(s, th) + detect_cruise(s, th)
             + detect_gnss_outages(drive, th))
    return merge_overlapping([e for e in found if e.type in types])


def merge_overlapping(events: list[Event]) -> list[Event]:
    """Events in time order, overlapping detections of one type merged into one event spanning
    them all, with the values of the longest (of equal spans, the one whose first value, e.g. the
    turn, is largest): a roundabout's circulating turn and its exit flare both turn far enough to
    be found as roundabouts, each spanning the other."""
    merged: list[list[Event]] = []
    for e in sorted(events, key=lambda e: (e.type, e.t0_s)):
        if merged and merged[-1][0].type == e.type and e.t0_s <= max(x.t1_s for x in merged[-1]):
            merged[-1].append(e)
        else:
            merged.append([e])
    out = []
    for group in merged:
        longest = max(group, key=lambda e: (round(e.t1_s - e.t0_s, 6), abs(next(iter(e.values.values()), 0.0))))
        out.append(Event(longest.type, min(e.t0_s for e in group), max(e.t1_s for e in group), dict(longest.values)))
    return sorted(out, key=lambda e: (e.t0_s, e.type))


#: The manoeuvre label of an outage no detected manoeuvre overlaps (:func:`outage_manoeuvres`).
NO_MANOEUVRE = "none"


def outage_manoeuvres(events: list[Event], t0_s: np.ndarray, length_s: float) -> list[str]:
    """The manoeuvre type of each outage starting at ``t0_s`` (s from the drive's start) and
    lasting ``length_s``: of the ``events`` (:func:`detect_events` with the run's thresholds, as
    ``evaluate --by-event`` finds the events it centres its outages on) the type of the one that
    overlaps the outage longest (ties: in :data:`MANOEUVRE_TYPES` order), :data:`NO_MANOEUVRE`
    when none overlaps it. Real GNSS losses are not manoeuvres and are left out."""
    found = sorted((e for e in events if e.type in MANOEUVRE_TYPES), key=lambda e: MANOEUVRE_TYPES.index(e.type))
    t0 = np.asarray(t0_s, dtype=float)
    if not found:
        return [NO_MANOEUVRE] * len(t0)
    e0, e1 = np.array([e.t0_s for e in found]), np.array([e.t1_s for e in found])
    types = np.array([e.type for e in found] + [NO_MANOEUVRE], dtype=object)
    out: list[str] = []
    for first in range(0, len(t0), 2048):  # (outages x events) overlaps, a block of outages at a time
        a = t0[first:first + 2048, None]
        overlap = np.minimum(e1[None, :], a + length_s) - np.maximum(e0[None, :], a)
        best = np.argmax(overlap, axis=1)  # the first of the longest: in MANOEUVRE_TYPES order
        best[overlap[np.arange(len(a)), best] <= 0.0] = len(found)
        out.extend(types[best].tolist())
    return out


def threshold_help() -> str:
    """Every threshold with its default and the range ``--threshold`` accepts, one per line."""
    lines = ["Thresholds (--threshold NAME=VALUE; default, accepted range):"]
    for name, default in asdict(EventThresholds()).items():
        lo, hi = THRESHOLD_LIMITS[name]
        shown = ",".join(f"{x:g}" for x in default) if isinstance(default, tuple) else f"{default:g}"
        lines.append(f"  {name} = {shown}   ({lo:g} to {hi:g})")
    return "\n".join(lines)


def thresholds_dict(th: EventThresholds) -> dict:
    return asdict(th)


@dataclass
class DetectorScore:
    """Recall and precision of one detector against known manoeuvres."""

    type: str
    n_truth: int
    n_found: int
    recalled: int
    precise: int

    @property
    def recall(self) -> float:
        return self.recalled / self.n_truth if self.n_truth else float("nan")

    @property
    def precision(self) -> float:
        return self.precise / self.n_found if self.n_found else float("nan")


def score(truth: list[tuple[str, float, float]], found: list[Event], end_s: float,
          edge_s: float = 1.0) -> dict[str, DetectorScore]:
    """Match detections to known manoeuvres of the same type by overlapping intervals.

    A known manoeuvre is recalled when a detection overlaps it; a detection is precise when it
    overlaps a known manoeuvre. Neither known manoeuvres nor detections that reach within
    ``edge_s`` of the end of the drive are scored: the end of the drive cuts them off.
    """
    out = {}
    for kind in EVENT_TYPES:
        t = [(a, b) for k, a, b in truth if k == kind and b < end_s - edge_s]
        d = [(e.t0_s, e.t1_s) for e in found if e.type == kind and e.t1_s < end_s - edge_s]
        def hits(x, ys):
            return any(x[0] <= y[1] and y[0] <= x[1] for y in ys)
        out[kind] = DetectorScore(kind, len(t), len(d), sum(hits(x, d) for x in t), sum(hits(x, t) for x in d))
    return out
