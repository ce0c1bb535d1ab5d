"""The paper's 1-second windows, built from a :class:`~ionav_viz.core.drive.Drive`.

Resampling (how gaps are handled)
    Inertial signals and GNSS are first put on a uniform grid of ``rate_hz`` (10 Hz) points,
    starting at the first sample of each *segment*, by linear interpolation in time (inertial
    samples of a faster log, e.g. 20 Hz, are averaged per grid bin instead). A missing sample
    (a 0.2 s period) is thereby bridged. A gap longer than ``max_gap_s``
    (default 1 s) splits the drive into segments: no window spans such a gap, and no outage
    sequence spans two segments.

Window ``w`` of a segment covers grid points ``10w .. 10w+10`` (both boundaries included),
i.e. ``[t0, t0 + 1 s]``. Per window:

* ``gnss_disp_m``: geodesic distance between the GNSS fixes at the two boundaries (WGS84,
  pyproj ``Geod.inv``, Vincenty-class accuracy), the paper's x_GPS.
* ``gnss_yaw_rate_radps``: counter-clockwise turn rate from the GNSS course change across the
  window, wrap-around safe. The course is meaningless when (nearly) standing still: below
  ``min_course_speed_mps`` (1 m/s) the last course seen at speed is held, so a standing car
  has a zero GNSS yaw rate.
* ``accel_mps2`` / ``gyro_radps``: the 11 inertial samples on the window's grid points
  (the INS integrates them with the trapezoid rule; the IDNN takes the last 10, the samples
  of the window's 10 time steps).
* ``truth_fault``: the GNSS fault bits (:mod:`ionav_viz.core.gnss_quality`) of every sample the
  window touches (its boundaries are interpolated from); a window with any is not a ground-truth
  window: no outage covers it or starts right after it, and it is never scored.
* ``receiver_fault``: where the drive has a reference beside its receiver
  (:attr:`Drive.has_reference <ionav_viz.core.drive.Drive.has_reference>`), the same bits of the
  receiver's fixes, the GNSS the estimators are given. An outage starts from the receiver's state at
  its start: no outage starts right after a window whose receiver fixes are faulty (inside a loss
  of the receiver there is no fix to start from, only one interpolated across the loss).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..core.drive import Drive
from ..core.geo import wgs84
from ..core.grid import GRID_RATE_HZ, MIN_COURSE_SPEED_MPS, WINDOW_S, hold_course_when_slow, stamp_tolerance_s
from ..core.units import wrap_360

__all__ = ["Windows", "faults_between", "hold_course_when_slow", "imu_on_grid", "make_windows", "segments"]


@dataclass
class Windows:
    """All 1-second windows of a drive, as arrays with one row per window.

    ``segment`` numbers the gap-free stretch a window belongs to; windows of one segment are
    consecutive in time. Boundary quantities have a ``0`` (start) and ``1`` (end) suffix.
    """

    rate_hz: float
    t0_s: np.ndarray
    segment: np.ndarray
    lat0_deg: np.ndarray
    lon0_deg: np.ndarray
    lat1_deg: np.ndarray
    lon1_deg: np.ndarray
    heading0_deg: np.ndarray
    heading1_deg: np.ndarray
    speed0_mps: np.ndarray
    gnss_disp_m: np.ndarray
    gnss_yaw_rate_radps: np.ndarray
    accel_mps2: np.ndarray  # (n, steps + 1)
    gyro_radps: np.ndarray  # (n, steps + 1)
    truth_fault: np.ndarray = field(default=None)  # type: ignore[assignment]  # (n,) uint16, 0 = good truth
    # (n,) uint16, 0 = its receiver fixes are good (the next window may start an outage)
    receiver_fault: np.ndarray = field(default=None)  # type: ignore[assignment]
    #: the first window an outage may start at: the filters' warm-up (:meth:`after_warm_up`)
    first_start: int = 0

    def __post_init__(self) -> None:
        if self.truth_fault is None:
            self.truth_fault = np.zeros(len(self.t0_s), dtype=np.uint16)
        if self.receiver_fault is None:
            self.receiver_fault = np.zeros(len(self.t0_s), dtype=np.uint16)

    def __len__(self) -> int:
        return len(self.t0_s)

    @property
    def truth_ok(self) -> np.ndarray:
        """Whether each window's boundary fixes are trustworthy ground truth."""
        return self.truth_fault == 0

    @property
    def receiver_ok(self) -> np.ndarray:
        """Whether each window's boundary fixes of the receiver (the estimators' GNSS) are good."""
        return self.receiver_fault == 0

    def ignoring_receiver(self) -> Windows:
        """The same windows without a receiver's faults: for work on the truth's own GNSS (training)."""
        return replace(self, receiver_fault=np.zeros(len(self), dtype=np.uint16))

    def ignoring_truth(self) -> Windows:
        """The same windows with every one taken as good truth and good receiver fixes (to count
        what bad truth and the receiver's losses excluded)."""
        good = np.zeros(len(self), dtype=np.uint16)
        return replace(self, truth_fault=good, receiver_fault=good)

    def after_warm_up(self, warm_up_s: float) -> Windows:
        """The same windows, outages placed only after ``warm_up_s`` of windows with good GNSS: the
        filters have had that long with GNSS (every estimator gets the same outages). Counted in
        good windows, not from the drive's first: phones start cold, and on real phone logs the first
        9-15 s of fixes were untrustworthy, so 30 s of drive gave the filters 15-21 s of GNSS."""
        if warm_up_s <= 0 or not len(self):
            return replace(self, first_start=0)
        good = self.truth_ok & self.receiver_ok  # beside a reference, the filters had only the receiver's fixes
        good_before = np.concatenate([[0], np.cumsum(good)])[:-1] * WINDOW_S  # GNSS time before each window
        first = int(np.searchsorted(good_before, warm_up_s - 1e-6))
        # never that much good GNSS: the drive's time, so that what is wrong is said (the GNSS, not the length)
        if first >= len(self):
            first = int(np.searchsorted(self.t0_s, self.t0_s[0] + warm_up_s - 1e-6))
        return replace(self, first_start=first)

    def boundary_fixes(self, starts: np.ndarray, n_windows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fixes' latitude, longitude (deg) and course (deg, clockwise from north) at every
        window boundary of the ``n_windows``-window sequences starting at windows ``starts``, the
        start first: each ``(len(starts), n_windows + 1)``, as the estimators' tracks."""
        starts = np.asarray(starts, dtype=int)
        idx = starts[:, None] + np.arange(n_windows)[None, :]
        return tuple(np.concatenate([at0[starts][:, None], at1[idx]], axis=1)  # type: ignore[return-value]
                     for at0, at1 in ((self.lat0_deg, self.lat1_deg), (self.lon0_deg, self.lon1_deg),
                                      (self.heading0_deg, self.heading1_deg)))

    @property
    def steps(self) -> int:
        """Samples per window (10 at 10 Hz)."""
        return self.accel_mps2.shape[1] - 1


def imu_on_grid(t_s: np.ndarray, x: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Inertial samples on the grid: interpolated, or averaged per grid bin when the log is
    faster than the grid (e.g. 20 Hz onto 10 Hz), so extra samples lower the noise instead of
    being skipped."""
    out = np.interp(grid, t_s, x)
    h = grid[1] - grid[0] if len(grid) > 1 else 0.0
    if len(t_s) < 2 or h <= 0 or np.median(np.diff(t_s)) >= 0.75 * h:
        return out
    idx = np.rint((t_s - grid[0]) / h).astype(np.int64)
    inside = (idx >= 0) & (idx < len(grid))
    sums = np.bincount(idx[inside], weights=x[inside], minlength=len(grid))
    counts = np.bincount(idx[inside], minlength=len(grid))
    has = counts > 0
    out[has] = sums[has] / counts[has]
    return out


def faults_between(t_s: np.ndarray, fault: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """GNSS fault bits of every sample an interpolation over ``[t0, t1]`` touches (the samples
    inside, and the ones just outside that the boundaries are interpolated from)."""
    lo = np.clip(np.searchsorted(t_s, t0, side="right") - 1, 0, len(t_s) - 1)
    hi = np.clip(np.searchsorted(t_s, t1, side="left"), 0, len(t_s) - 1)
    out = np.zeros(len(t0), dtype=np.uint16)
    bits = int(np.bitwise_or.reduce(fault)) if len(fault) else 0
    b = 1
    while b <= bits:
        if bits & b:
            count = np.concatenate([[0], np.cumsum((fault & b) != 0)])
            out[count[hi + 1] - count[lo] > 0] |= np.uint16(b)
        b <<= 1
    return out


def segments(t_s: np.ndarray, max_gap_s: float) -> list[tuple[int, int]]:
    """Index ranges ``[i0, i1)`` of the stretches without a time gap longer than ``max_gap_s``."""
    cuts = np.flatnonzero(np.diff(t_s) > max_gap_s) + 1
    bounds = np.concatenate([[0], cuts, [len(t_s)]])
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def _on_step(t_s: float, rate_hz: float, tolerance_s: float) -> float:
    """``t_s`` (s), or the grid step (a multiple of ``1 / rate_hz``) within ``tolerance_s`` of it."""
    step = round(t_s * rate_hz) / rate_hz
    return step if abs(step - t_s) <= tolerance_s else t_s


def make_windows(
    drive: Drive,
    rate_hz: float = GRID_RATE_HZ,
    max_gap_s: float = 1.0,
    min_course_speed_mps: float = MIN_COURSE_SPEED_MPS,
    offset_s: float = 0.0,
) -> Windows:
    """Cut ``drive`` into 1-second windows (see module docstring).

    ``offset_s`` shifts every segment's grid start (training uses the offsets 0, 0.1, ... 0.9 s
    to see each second of a drive at every phase).
    """
    steps = int(round(rate_hz * WINDOW_S))
    tolerance = stamp_tolerance_s(drive.rate_hz)
    heading = hold_course_when_slow(drive.heading_deg, drive.speed_mps, min_course_speed_mps, drive.t_s)
    heading_unwrapped = np.rad2deg(np.unwrap(np.deg2rad(heading)))
    parts: dict[str, list[np.ndarray]] = {k: []
                                          for k in ("t", "seg", "lat", "lon", "hdg", "spd", "acc", "gyr", "bad", "rx")}
    receiver_fault = drive.receiver_fault if drive.has_reference and drive.receiver_fault is not None else None
    n_windows = []
    for seg_id, (i0, i1) in enumerate(segments(drive.t_s, max_gap_s)):
        t = drive.t_s[i0:i1]
        # a first stamp a millisecond off the grid's step (IO-VNBD: 99.999 s for 100 s) starts the grid
        # on the step, as the whole drive's grid has it; a last one as far short of a window's end ends it
        t_first = _on_step(t[0], rate_hz, tolerance)
        n_win = int(np.floor((t[-1] - t_first - offset_s + tolerance) * rate_hz)) // steps
        if n_win < 1:
            continue
        grid = t_first + offset_s + np.arange(n_win * steps + 1) / rate_hz

        def on_grid(x: np.ndarray, grid=grid, t=t, i0=i0, i1=i1) -> np.ndarray:
            return np.interp(grid, t, x[i0:i1])

        parts["t"].append(grid[:-1:steps])
        parts["seg"].append(np.full(n_win, seg_id))
        parts["lat"].append(on_grid(drive.lat_deg)[::steps])
        parts["lon"].append(on_grid(drive.lon_deg)[::steps])
        parts["hdg"].append(on_grid(heading_unwrapped)[::steps])
        parts["spd"].append(on_grid(drive.speed_mps)[::steps])
        parts["bad"].append(faults_between(t, drive.gnss_fault[i0:i1], grid[:-1:steps], grid[steps::steps]))
        if receiver_fault is not None:
            parts["rx"].append(faults_between(t, receiver_fault[i0:i1], grid[:-1:steps], grid[steps::steps]))
        acc = imu_on_grid(t, drive.accel_long_mps2[i0:i1], grid)
        gyr = imu_on_grid(t, drive.yaw_rate_radps[i0:i1], grid)
        # Window w uses grid points steps*w .. steps*w + steps (shared boundary points).
        idx = steps * np.arange(n_win)[:, None] + np.arange(steps + 1)[None, :]
        parts["acc"].append(acc[idx])
        parts["gyr"].append(gyr[idx])
        n_windows.append(n_win)

    if not n_windows:
        empty = np.zeros(0)
        return Windows(rate_hz, empty, empty.astype(int), empty, empty, empty, empty, empty, empty, empty,
                       empty, empty, np.zeros((0, steps + 1)), np.zeros((0, steps + 1)))

    def starts_ends(key: str) -> tuple[np.ndarray, np.ndarray]:
        # per segment, boundary arrays have n_win + 1 entries
        return (np.concatenate([b[:-1] for b in parts[key]]), np.concatenate([b[1:] for b in parts[key]]))

    lat0, lat1 = starts_ends("lat")
    lon0, lon1 = starts_ends("lon")
    hdg0, hdg1 = starts_ends("hdg")
    spd0, _ = starts_ends("spd")
    _, _, disp = wgs84().inv(lon0, lat0, lon1, lat1)
    # d(heading)/dt is clockwise; the drive model's yaw rate is counter-clockwise positive.
    gnss_yaw = -np.deg2rad(hdg1 - hdg0) / WINDOW_S
    return Windows(
        rate_hz=rate_hz,
        t0_s=np.concatenate(parts["t"]),
        segment=np.concatenate(parts["seg"]),
        lat0_deg=lat0,
        lon0_deg=lon0,
        lat1_deg=lat1,
        lon1_deg=lon1,
        heading0_deg=wrap_360(hdg0),
        heading1_deg=wrap_360(hdg1),
        speed0_mps=spd0,
        gnss_disp_m=np.asarray(disp, dtype=np.float64),
        gnss_yaw_rate_radps=gnss_yaw,
        accel_mps2=np.concatenate(parts["acc"]),
        gyro_radps=np.concatenate(parts["gyr"]),
        truth_fault=np.concatenate(parts["bad"]),
        receiver_fault=np.concatenate(parts["rx"]) if parts["rx"] else None,
    )


def segment_ranges(windows: Windows) -> list[tuple[int, int]]:
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
    # and none before the warm-up's end (Windows.after_warm_up)
    return [(max(int(a) + 1, windows.first_start), int(b)) for a, b in zip(starts, ends)
            if max(int(a) + 1, windows.first_start) < b]


def starts_ok(windows: Windows) -> np.ndarray:
    """Per window, whether the receiver gives an outage starting there a fix to start from."""
    return np.concatenate([[False], windows.receiver_ok[:-1]]) if len(windows) else np.zeros(0, dtype=bool)


def valid_start(windows: Windows, start: int, n: int) -> bool:
    """Whether an ``n``-window outage can start at window ``start``."""
    return bool(starts_ok(windows)[start]) and any(a <= start and start + n <= b
                                                    for a, b in segment_ranges(windows)) \
        if 0 <= start < len(windows) else False
