"""The common time grid of every drive, and the GNSS course convention at low speed.

Every source is resampled to one 10 Hz grid (the IO-VNBD rate); the paper's estimators work in
1-second windows of that grid (10 time steps each). These constants have this one home.
"""

from __future__ import annotations

import numpy as np

#: Rate (Hz) of the grid that inertial signals and GNSS are put on (the IO-VNBD rate).
GRID_RATE_HZ = 10.0
#: One time step of the grid (s).
GRID_STEP_S = 1.0 / GRID_RATE_HZ
#: Length (s) of one estimator window: the estimators predict once per window (the paper's 1 s).
WINDOW_S = 1.0
#: Below this GNSS speed (m/s) the course over ground is noise: the last course at speed is held.
MIN_COURSE_SPEED_MPS = 1.0


def hold_course_when_slow(heading_deg: np.ndarray, speed_mps: np.ndarray, min_speed_mps: float = MIN_COURSE_SPEED_MPS) -> np.ndarray:
    """Replace the course at speeds below ``min_speed_mps`` by the last course seen at speed.

    Before the first fast sample the first fast course is used; a drive that never moves keeps
    its logged course.
    """
    fast = speed_mps >= min_speed_mps
    if fast.all() or not fast.any():
        return heading_deg.copy()
    idx = np.where(fast, np.arange(len(fast)), 0)
    np.maximum.accumulate(idx, out=idx)
    idx[: int(np.argmax(fast))] = int(np.argmax(fast))
    return heading_deg[idx]
