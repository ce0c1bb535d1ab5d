"""How late a receiver's speed is against the IMU, and what that lag makes of its velocity.

The reader estimates it on every log with a measured IMU and its own receiver speed
(:func:`speed_lag_of`, kept in :class:`ionav_viz.core.imu.ImuCharacter` and said in its line), and
``gins`` weighs the receiver's velocity for it. A phone's location service reports a speed smoothed
over the last second or two: on seven real
iPhone logs (docs/real-imu-logs.md) the receiver's speed changes 0.5-1.0 s after the IMU's forward
acceleration says the car's did (1.5 s on a car data logger's), where a GNSS chip's Doppler speed is
of its epoch (the simulated receivers, the dash device: under 0.2 s). A filter that takes such a
speed as the car's present one, at a receiver's 0.3 m/s, is pulled after it in every acceleration
and puts the difference into its biases and attitude.

Estimate (:func:`estimate_speed_lag`): at speed, the rate of change of the receiver's speed (on the
drive's grid, where it is interpolated between fixes: the mean acceleration over each fix interval)
against the IMU's forward specific force, both smoothed over 1 s alike; the lag that best lines them
up (normalised cross-correlation, 0 to :data:`MAX_LAG_S` in 50 ms steps, a parabola through the
peak). Only a lag of the receiver behind the IMU is searched: a receiver early against the IMU is
the IMU's clock (:mod:`ionav_viz.sources.imu.clock`). It is *resolved* when the peak correlation is
clear (:data:`LAG_MIN_PEAK`) over enough driving (:data:`MIN_DRIVING_S`), and used when above
:data:`USE_ABOVE_S`.

What the lag does to the velocity (:func:`lag_velocity_error_mps`): it is off by the lag times the
car's horizontal acceleration, the forward one from the IMU less its offset from the receiver's
speed rate over the last :data:`OFFSET_WINDOW_S` (bias, grade: what the lag does not change), the
lateral one the speed times the yaw rate. ``gins`` widens its velocity updates by it
(:class:`ionav_viz.nav.strapdown.FilterInputs` ``vel_var``): on the real logs that did as much as
moving the velocity forward by it (the same mean over 34 cells, 0.67 of the INS DR's error), and it
leaves the measurement as the receiver gave it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .drive import Drive
from .gnss_quality import GnssFault
from .moving import moving_mean

#: Lags searched (s): a location service's smoothing, not an unsynchronised clock.
MAX_LAG_S = 2.0
#: The search's step (s) before the parabola refines it.
LAG_STEP_S = 0.05
#: Samples at least this fast (m/s) count.
LAG_MIN_SPEED_MPS = 5.0
#: Both signals are smoothed over this (s) before they are compared (a 1 Hz receiver's interval).
LAG_SMOOTH_S = 1.0
#: Resolved: a peak correlation of at least this over at least this much driving at speed (s).
LAG_MIN_PEAK = 0.5
MIN_DRIVING_S = 60.0
#: Lags under this (s) are left alone: at 1 m/s² they are under 0.2 m/s, within a receiver's noise.
USE_ABOVE_S = 0.2
#: The fix faults that break a speed's time series (a gap, a frozen or jumping receiver); a coarse
#: fix's speed (few satellites, a poor reported accuracy: a phone's 6-8 m) still shows when it changed.
SPEED_FAULTS = (GnssFault.NO_FIX | GnssFault.NEAR_ZERO | GnssFault.FROZEN | GnssFault.JUMP
                | GnssFault.SPEED_STEP)
#: The forward accelerometer's offset from the receiver's speed rate is its mean over this (s, trailing).
OFFSET_WINDOW_S = 30.0


@dataclass(frozen=True)
class SpeedLag:
    """The estimate: ``lag_s`` (the receiver's speed behind the IMU), the peak correlation, the
    driving it used (s) and whether it is ``resolved`` (else ``reason``)."""

    lag_s: float
    peak: float
    driving_s: float
    resolved: bool
    reason: str = ""

    @property
    def used(self) -> bool:
        """Whether ``gins`` weighs the receiver's velocity for it (resolved, and above :data:`USE_ABOVE_S`)."""
        return self.resolved and self.lag_s > USE_ABOVE_S

    def describe(self) -> str:
        """The estimate in words: ``0.98 s behind the IMU (correlation 0.77)``, or why there is none."""
        if not self.resolved:
            return f"not resolved ({self.reason})"
        return (f"{self.lag_s:.2f} s behind the IMU (correlation {self.peak:.2f})"
                + ("" if self.used else f", under {USE_ABOVE_S:g} s: left alone"))


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    """:func:`ionav_viz.core.moving.moving_mean` of one signal, as a 1D array."""
    return moving_mean(x, n)[:, 0]


def speed_lag_of(drive: Drive) -> SpeedLag:
    """:func:`estimate_speed_lag` on a drive as its receiver saw it (:meth:`Drive.as_received`:
    its speed, the IMU's ``accel_x_mps2``); a speed fitted to the fixes is the positions', of their
    epochs: not estimated."""
    if drive.velocity_fitted:
        return SpeedLag(0.0, 0.0, 0.0, False, "the speed is fitted to the fixes")
    if "accel_x_mps2" not in drive.columns:
        return SpeedLag(0.0, 0.0, 0.0, False, "no forward accelerometer")
    return estimate_speed_lag(drive.t_s, drive.speed_mps, drive.columns["accel_x_mps2"],
                              (drive.gnss_fault & SPEED_FAULTS) == 0)


def estimate_speed_lag(t_s: np.ndarray, speed_mps: np.ndarray, accel_fwd_mps2: np.ndarray,
                       usable: np.ndarray | None = None) -> SpeedLag:
    """How late the receiver's speed ``speed_mps`` (on the drive's grid ``t_s``, s) is against the
    IMU's forward specific force ``accel_fwd_mps2`` (m/s², the vehicle frame's x); ``usable``: the
    samples whose fix is trusted (default all)."""
    t = np.asarray(t_s, dtype=float)
    if len(t) < 10:
        return SpeedLag(0.0, 0.0, 0.0, False, "too short")
    dt = float(np.median(np.diff(t)))
    n = max(int(round(LAG_SMOOTH_S / dt)), 1)
    speed, accel_in = np.asarray(speed_mps, dtype=float), np.asarray(accel_fwd_mps2, dtype=float)
    finite = np.isfinite(speed) & np.isfinite(accel_in)
    rate = _smooth(np.gradient(np.where(finite, speed, 0.0), t), n)
    accel = _smooth(np.where(finite, accel_in, 0.0), n)
    # samples whose smoothing reached a gap are left out
    ok = (np.where(finite, speed, 0.0) >= LAG_MIN_SPEED_MPS) & (_smooth((~finite).astype(float), n + 2) == 0)
    if usable is not None:
        ok &= np.asarray(usable, dtype=bool)
    driving_s = float(ok.sum() * dt)
    if driving_s < MIN_DRIVING_S:
        return SpeedLag(0.0, 0.0, driving_s, False,
                        f"too little driving at speed ({driving_s:.0f} s; {MIN_DRIVING_S:.0f} needed)")
    steps = np.arange(0, int(round(MAX_LAG_S / LAG_STEP_S)) + 1)
    corr = np.full(len(steps), -np.inf)
    for k, step in enumerate(steps):
        shift = int(round(step * LAG_STEP_S / dt))  # the IMU's sample `shift` earlier lines up with the receiver's now
        if shift >= len(t) - 10:
            break
        a, r, m = accel[: len(t) - shift], rate[shift:], ok[shift:] & ok[: len(t) - shift]
        if m.sum() < 10:
            continue
        a, r = a[m] - a[m].mean(), r[m] - r[m].mean()
        den = float(np.sqrt((a * a).sum() * (r * r).sum()))
        value = float((a * r).sum() / den) if den > 0 else -np.inf
        corr[k] = value if np.isfinite(value) else -np.inf
    best = int(np.argmax(corr))
    lag = float(best * LAG_STEP_S)
    if 0 < best < len(steps) - 1 and np.isfinite(corr[best - 1]) and np.isfinite(corr[best + 1]):
        y0, y1, y2 = corr[best - 1], corr[best], corr[best + 1]
        den = y0 - 2.0 * y1 + y2
        if den < 0:
            lag += LAG_STEP_S * 0.5 * (y0 - y2) / den
    peak = float(corr[best])
    if peak < LAG_MIN_PEAK:
        return SpeedLag(float(lag), peak, driving_s, False,
                        f"the receiver's speed and the IMU agree poorly (correlation {peak:.2f})")
    return SpeedLag(float(lag), peak, driving_s, True)


def lag_velocity_error_mps(t_s: np.ndarray, speed_mps: np.ndarray, accel_fwd_mps2: np.ndarray,
                           yaw_rate_radps: np.ndarray,
                           lag_s: float) -> np.ndarray:
    """How far (m/s) a receiver velocity ``lag_s`` late is from the car's, per sample of the grid
    ``t_s``: the lag times the car's horizontal acceleration (see the module docstring;
    ``yaw_rate_radps`` counter-clockwise positive, its sign immaterial here)."""
    t = np.asarray(t_s, dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.1
    n = max(int(round(LAG_SMOOTH_S / dt)), 1)
    speed = np.asarray(speed_mps, dtype=float)
    rate = _smooth(np.gradient(speed, t), n)
    accel = _smooth(np.asarray(accel_fwd_mps2, dtype=float), n)
    # the offset over the trailing window: the receiver's rate lags, but over 30 s it averages alike
    w = max(int(round(OFFSET_WINDOW_S / dt)), 1)
    c = np.concatenate([[0.0], np.cumsum(np.nan_to_num(accel - rate))])
    i = np.arange(len(t))
    lo = np.maximum(i + 1 - w, 0)
    forward = accel - (c[i + 1] - c[lo]) / (i + 1 - lo)
    lateral = speed * _smooth(np.asarray(yaw_rate_radps, dtype=float), n)
    error = lag_s * np.hypot(forward, lateral)
    return np.where(np.isfinite(error), error, 0.0)  # a gap in a column: nothing known to add
