"""The common time grid of every drive, and the GNSS course convention at low speed.

Every source is resampled to one 10 Hz grid (the IO-VNBD rate); the paper's estimators work in
1-second windows of that grid (10 time steps each). These constants have this one home.
"""

from __future__ import annotations

import numpy as np

from .runs import keep_runs, true_runs

#: Rate (Hz) of the grid that inertial signals and GNSS are put on (the IO-VNBD rate).
GRID_RATE_HZ = 10.0
#: One time step of the grid (s).
GRID_STEP_S = 1.0 / GRID_RATE_HZ
#: Length (s) of one estimator window: the estimators predict once per window (the paper's 1 s).
WINDOW_S = 1.0
#: How far (s) a sample's stamp may lie from a time it stands for: IO-VNBD stamps are whole
#: milliseconds with a millisecond of jitter (the 100 s sample of a 10 Hz drive is stamped 99.999 s),
#: so a span's end or a window's grid point within this of a sample is on it. Capped at a quarter of
#: the sampling period (:func:`stamp_tolerance_s`): a sample is never mistaken for its neighbour.
STAMP_TOLERANCE_S = 0.005


#: Stamps this close (s) are one instant: far below any sample period (a 1 kHz IMU's is 1 ms) and far
#: above the rounding of stamps in seconds, so a clock offset or a rounding this small moves no sample
#: across a bound (``--imu-time-offset 1e-9`` gives the results of none).
SAME_INSTANT_S = 1e-6


def stamp_tolerance_s(rate_hz: float) -> float:
    """:data:`STAMP_TOLERANCE_S`, at most a quarter of a sample period at ``rate_hz`` (Hz)."""
    return min(STAMP_TOLERANCE_S, 0.25 / rate_hz) if rate_hz > 0 else STAMP_TOLERANCE_S


#: Below this GNSS speed (m/s) the course over ground is noise: the last course at speed is held.
MIN_COURSE_SPEED_MPS = 1.0
#: A stretch above that speed counts only when it lasts this long (s): a standing receiver's speed
#: noise crosses it for a second or so (:func:`hold_course_when_slow`).
MIN_COURSE_RUN_S = 2.0


def hold_course_when_slow(heading_deg: np.ndarray, speed_mps: np.ndarray, min_speed_mps: float = MIN_COURSE_SPEED_MPS,
                          t_s: np.ndarray | None = None, min_run_s: float = MIN_COURSE_RUN_S) -> np.ndarray:
    """Replace the course at speeds below ``min_speed_mps`` by the last course seen at speed.

    Before the first fast sample the first fast course is used; a drive that never moves keeps
    its logged course. With sample times ``t_s`` (s), a stretch at speed shorter than
    ``min_run_s`` does not count as at speed: a standing receiver's speed noise crosses the
    threshold now and then (a phone's, 0.3 m/s per axis, for a fix or two), and its course
    then is noise that would be held, or given to the drive's start, as the course. A drive with
    no stretch that long keeps its short ones.
    """
    fast = np.asarray(speed_mps) >= min_speed_mps
    if t_s is not None and min_run_s > 0 and fast.any():
        first, end = true_runs(fast)
        t = np.asarray(t_s, dtype=float)
        long_enough = t[end - 1] - t[first] >= min_run_s
        if long_enough.any():  # else the short stretches are all the course there is
            fast = keep_runs(fast, long_enough)
    if fast.all() or not fast.any():
        return heading_deg.copy()
    idx = np.where(fast, np.arange(len(fast)), 0)
    np.maximum.accumulate(idx, out=idx)
    idx[: int(np.argmax(fast))] = int(np.argmax(fast))
    return heading_deg[idx]
