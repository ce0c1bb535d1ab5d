"""INS dead reckoning during GNSS outages, as Section 2.1 of the paper describes.

* Sensor biases: the mean longitudinal accelerometer and gyro readings while standing still
  (:func:`estimate_bias`), from a stationary drive or from the stationary stretches of the
  drive itself (the paper uses 20 minutes of stationary data). They absorb the mount tilt too.
* Velocity is initialised from the GNSS speed at the outage start, then the bias-corrected
  longitudinal acceleration is integrated twice (trapezoid rule on the 10 Hz samples,
  continuous across windows) to a displacement per 1-second window.
* The bias-corrected yaw rate, averaged over each window, is the INS orientation rate; it is
  integrated from the GNSS course at the outage start to the heading.
* The 2D track is rebuilt from the last fix (:func:`ionav_viz.track.rebuild_track`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .drive import Drive
from .track import Track, rebuild_track
from .windows import Windows


@dataclass(frozen=True)
class SensorBias:
    """Constant sensor biases (accelerometer m/s^2, gyro rad/s) and where they came from."""

    accel_mps2: float
    gyro_radps: float
    source: str
    still_s: float

    @classmethod
    def none(cls) -> "SensorBias":
        return cls(0.0, 0.0, "none (no stationary data)", 0.0)


@dataclass
class Estimate:
    """One estimator's output for every outage sequence: arrays (n_sequences, n_windows[+1])."""

    disp_m: np.ndarray
    yaw_rate_radps: np.ndarray
    track: Track


def stationary_mask(drive: Drive, max_speed_mps: float = 0.3, edge_s: float = 1.0) -> np.ndarray:
    """Samples where the car stands still, at least ``edge_s`` away from moving samples.

    Standing still: GNSS speed below ``max_speed_mps`` (above the receiver's speed noise). Only
    the GNSS speed is used, so every source of the same drive (CSV, MCAP) gives the same biases.
    """
    moving = drive.speed_mps > max_speed_mps
    t_moving = drive.t_s[moving]
    if t_moving.size == 0:
        return np.ones(len(drive), dtype=bool)
    # distance in time to the nearest moving sample
    pos = np.searchsorted(t_moving, drive.t_s)
    before = np.abs(drive.t_s - t_moving[np.clip(pos - 1, 0, t_moving.size - 1)])
    after = np.abs(t_moving[np.clip(pos, 0, t_moving.size - 1)] - drive.t_s)
    return ~moving & (np.minimum(before, after) > edge_s)


def estimate_bias(drive: Drive, min_still_s: float = 3.0) -> SensorBias | None:
    """Biases from the stationary samples of ``drive``; None if it stands still < ``min_still_s``."""
    still = stationary_mask(drive)
    dt = np.median(np.diff(drive.t_s)) if len(drive) > 1 else 0.0
    still_s = float(still.sum() * dt)
    if still_s < min_still_s:
        return None
    return SensorBias(
        accel_mps2=float(drive.accel_long_mps2[still].mean()),
        gyro_radps=float(drive.yaw_rate_radps[still].mean()),
        source=f"stationary samples of {drive.name}",
        still_s=still_s,
    )


def trapezoid_mean(x: np.ndarray) -> np.ndarray:
    """Mean over the last axis of samples on a uniform grid including both ends."""
    return 0.5 * (x[..., 1:] + x[..., :-1]).mean(axis=-1)


def dead_reckon(windows: Windows, starts: np.ndarray, n_windows: int, bias: SensorBias) -> Estimate:
    """INS estimates for outages of ``n_windows`` starting at the windows ``starts``."""
    idx = np.asarray(starts)[:, None] + np.arange(n_windows)[None, :]
    h = 1.0 / windows.rate_hz
    acc = windows.accel_mps2[idx] - bias.accel_mps2  # (seq, win, steps+1)
    gyr = windows.gyro_radps[idx] - bias.gyro_radps
    n_seq, steps = len(idx), windows.steps
    dv = (0.5 * (acc[..., 1:] + acc[..., :-1]) * h).reshape(n_seq, n_windows * steps)
    v0 = windows.speed0_mps[starts][:, None]
    v_end = v0 + np.cumsum(dv, axis=1)
    v_start = np.concatenate([v0, v_end[:, :-1]], axis=1)
    disp = (0.5 * (v_start + v_end) * h).reshape(n_seq, n_windows, steps).sum(axis=-1)
    yaw = trapezoid_mean(gyr)
    track = rebuild_track(windows.lat0_deg[starts], windows.lon0_deg[starts], windows.heading0_deg[starts], disp, yaw)
    return Estimate(disp, yaw, track)
