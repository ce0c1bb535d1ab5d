"""The IMU's clock against the receiver's: the offset between their stamps, estimated from the log.

Convention: ``offset_s`` is the IMU's stamp minus the receiver's for the same instant (positive:
the IMU is stamped late). The reader corrects it by moving the IMU's samples to ``t - offset_s``
on the receiver's time line before the fixes are put on them.

Estimate (:func:`estimate_clock_offset`): at speed, the car's yaw rate is seen twice, by the
levelled gyro's vertical axis and by the rate of the GNSS course. Both smoothed over 1 s alike, the
lag that best lines them up (normalised cross-correlation over ``-MAX_OFFSET_S .. +MAX_OFFSET_S`` in
5 ms steps, refined by a parabola through the peak) is the offset. Its uncertainty comes from the
spread of the same estimate over independent blocks of driving (batch means, :data:`BLOCK_S`): a
turn or two per block decides it, so a drive with few turns reports a wide one. It is *resolved*
when the peak correlation is clear (:data:`MIN_PEAK`), there was enough turning
(:data:`MIN_TURN_RAD`) and the uncertainty is under :data:`MAX_SIGMA_S`.

Applied (:func:`should_apply`) when resolved and larger than :data:`APPLY_ABOVE_S` and three of its
sigmas. The lag found is the clock's *plus the receiver's course's own lag* behind its epoch (a
course from successive positions, a smoothing filter), which the log cannot tell apart: a real roof
RTK log, its stated logging delay already applied, gives -0.067 +- 0.016 s, and moving its IMU by it
raised ``gins``'s error after 10 s from 2.3 to 2.9 % of the distance (tests/data/real). So only an
offset clearly beyond what a course lags by is taken for a clock; below it the error left is small
(a turn of 20 deg/s misread by 0.1 s is a 2 degree heading error for the length of the turn, which
the filters' GNSS updates take out), while 0.3 s (issue 41's log) doubles a filter's error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Offsets searched (s) either way: more is a log whose clocks were never synchronised.
MAX_OFFSET_S = 1.0
#: The lag search's step (s) before the parabola refines it.
STEP_S = 0.005
#: Samples faster than this (m/s) count: slower, a GNSS course's rate is noise.
COURSE_RATE_MIN_SPEED_MPS = 4.0
#: Both signals are smoothed over this (s) before they are compared.
SMOOTH_S = 1.0
#: Independent blocks of driving (s) for the uncertainty.
BLOCK_S = 60.0
#: A resolved estimate needs a peak correlation of at least this, this much turning (the integral
#: of |yaw rate| over the samples used, rad: a few full turns) and an uncertainty below this (s).
MIN_PEAK = 0.6
MIN_TURN_RAD = 6.0
MAX_SIGMA_S = 0.05
#: Offsets under this (s; and under three of their sigmas) are left alone: a receiver's course can
#: lag by that much (see the module docstring).
APPLY_ABOVE_S = 0.1


@dataclass(frozen=True)
class ClockOffset:
    """The estimate: ``offset_s`` (IMU stamp minus receiver stamp), ``sigma_s``, the peak
    correlation, the turning it saw (rad), and whether it is ``resolved`` (else ``reason``)."""

    offset_s: float
    sigma_s: float
    peak: float
    turn_rad: float
    resolved: bool
    reason: str = ""


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    if n <= 1:
        return x
    kernel = np.ones(n) / n
    return np.convolve(x, kernel, mode="same")


def _course_rate_ccw_radps(t_s: np.ndarray, course_deg: np.ndarray) -> np.ndarray:
    """The GNSS course's rate, counter-clockwise (rad/s): course is clockwise from north."""
    unwrapped = np.unwrap(np.deg2rad(course_deg))
    return -np.gradient(unwrapped, t_s)


def _best_lag(t: np.ndarray, gyro: np.ndarray, rate: np.ndarray, use: np.ndarray,
              lags: np.ndarray) -> tuple[float, float]:
    """The lag (s) maximising the correlation of ``gyro(t + lag)`` with ``rate(t)`` over ``use``, refined by a parabola;
    and that peak."""
    r = rate[use] - rate[use].mean()
    scores = np.empty(len(lags))
    for i, lag in enumerate(lags):
        g = np.interp(t[use] + lag, t, gyro)
        g = g - g.mean()
        denom = math.sqrt(float((g * g).sum() * (r * r).sum()))
        scores[i] = float((g * r).sum()) / denom if denom > 0 else 0.0
    k = int(np.argmax(scores))
    lag = float(lags[k])
    if 0 < k < len(lags) - 1:
        a, b, c = scores[k - 1], scores[k], scores[k + 1]
        curve = a - 2 * b + c
        if curve < 0:
            lag += 0.5 * (a - c) / curve * (lags[1] - lags[0])
    return lag, float(scores[k])


def estimate_clock_offset(t_s: np.ndarray, gyro_z_radps: np.ndarray, speed_mps: np.ndarray,
                          course_deg: np.ndarray) -> ClockOffset:
    """The IMU's clock offset from the body-frame vertical rate ``gyro_z_radps`` (counter-clockwise,
    the IMU levelled by its mount) and the receiver's speed and course, all on the times ``t_s``
    (the IMU's stamps); see the module docstring."""
    t = np.asarray(t_s, dtype=float)
    if len(t) < 10:
        return ClockOffset(0.0, math.inf, 0.0, 0.0, False, "too short")
    dt = float(np.median(np.diff(t)))
    n = max(1, int(round(SMOOTH_S / dt)))
    gyro = _smooth(np.asarray(gyro_z_radps, dtype=float), n)
    rate = _smooth(_course_rate_ccw_radps(t, np.asarray(course_deg, dtype=float)), n)
    margin = int(math.ceil(MAX_OFFSET_S / dt)) + n
    use = np.asarray(speed_mps) > COURSE_RATE_MIN_SPEED_MPS
    use[:margin], use[-margin:] = False, False
    turn = float(np.abs(rate[use]).sum() * dt)
    if use.sum() < 10 * n or turn < MIN_TURN_RAD:
        return ClockOffset(0.0, math.inf, 0.0, turn, False,
                           f"too little turning at speed ({math.degrees(turn):.0f} deg; "
                                                             f"{math.degrees(MIN_TURN_RAD):.0f} needed)")
    lags = np.arange(-MAX_OFFSET_S, MAX_OFFSET_S + STEP_S / 2, STEP_S)
    offset, peak = _best_lag(t, gyro, rate, use, lags)
    # batch means: the same estimate per block of driving, near the whole's (a block has few turns)
    near = lags[np.abs(lags - offset) <= 0.3]
    blocks = []
    block = max(int(BLOCK_S / dt), 1)
    for a in range(0, len(t), block):
        part = np.zeros(len(t), dtype=bool)
        part[a:a + block] = use[a:a + block]
        if part.sum() >= 5 * n and float(np.abs(rate[part]).sum() * dt) >= MIN_TURN_RAD / 6:
            blocks.append(_best_lag(t, gyro, rate, part, near)[0])
    sigma = float(np.std(blocks, ddof=1) / math.sqrt(len(blocks))) if len(blocks) >= 3 else math.inf
    if peak < MIN_PEAK:
        return ClockOffset(offset, sigma, peak, turn, False,
                           f"gyro and GNSS course agree poorly (correlation {peak:.2f})")
    if not sigma <= MAX_SIGMA_S:
        why = ("too few stretches of turning to check it"
               if not math.isfinite(sigma) else f"its uncertainty is {1000 * sigma:.0f} ms")
        return ClockOffset(offset, sigma, peak, turn, False, why)
    return ClockOffset(offset, sigma, peak, turn, True)


def should_apply(found: ClockOffset) -> bool:
    """Whether a resolved estimate is worth applying (see the module docstring)."""
    return found.resolved and abs(found.offset_s) > max(APPLY_ABOVE_S, 3.0 * found.sigma_s)
