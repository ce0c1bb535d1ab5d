"""Constant sensor biases from stationary data (Section 2.1 of the paper).

The mean longitudinal accelerometer and gyro readings while standing still are the biases
(:func:`estimate_bias`); they absorb the mount tilt too. The paper takes them from 20 minutes of
stationary data; ionav-viz takes them from a stationary drive if given (``--bias-from``), else
from the stationary stretches of the drive itself (:func:`resolve_bias`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError

log = logging.getLogger("ionav_viz")


@dataclass(frozen=True)
class SensorBias:
    """Constant sensor biases (accelerometer m/s^2, gyro rad/s) and where they came from."""

    accel_mps2: float
    gyro_radps: float
    source: str
    still_s: float

    @classmethod
    def none(cls) -> SensorBias:
        return cls(0.0, 0.0, "none (no stationary data)", 0.0)


def stationary_mask(drive: Drive, max_speed_mps: float = 0.3, edge_s: float = 1.0,
                    speed_mps: np.ndarray | None = None) -> np.ndarray:
    """Samples where the car stands still, at least ``edge_s`` away from moving samples.

    Standing still: GNSS speed below ``max_speed_mps`` (above the receiver's speed noise). Only
    the GNSS speed is used, so every source of the same drive (CSV, MCAP) gives the same biases.
    A sample without trustworthy GNSS counts as moving: a logger that writes zeros in a tunnel
    would otherwise make a car at speed look parked. ``speed_mps``: another speed per sample to
    judge by (e.g. the GNSS speed smoothed), instead of ``drive.speed_mps``.
    """
    speed = drive.speed_mps if speed_mps is None else speed_mps
    moving = (speed > max_speed_mps) | ~drive.gnss_ok
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



def resolve_bias(drive: Drive, stationary: Drive | None = None) -> SensorBias:
    """Biases from ``stationary`` if given, else from the drive's own stationary stretches, else none."""
    if stationary is not None:
        bias = estimate_bias(stationary)
        if bias is None:
            raise InputError(
                f"{stationary.source}: stands still for less than 3 s",
                "biases need a stationary recording (e.g. the bundled 'stationary' drive)",
                param="bias_from",
            )
        return bias
    bias = estimate_bias(drive)
    if bias is None:
        log.warning(
            "%s: no stationary stretch of 3 s to estimate sensor biases; INS runs uncorrected "
            "(give a stationary drive for the biases: --bias-from, or bias_from= in Python)",
            drive.name,
        )
        return SensorBias.none()
    return bias
