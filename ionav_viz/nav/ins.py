"""INS dead reckoning during GNSS outages, as Section 2.1 of the paper describes (the baseline).

* Sensor biases (:mod:`ionav_viz.nav.bias`) are subtracted from the accelerometer and gyro.
* Velocity is initialised from the GNSS speed at the outage start, then the bias-corrected
  longitudinal acceleration is integrated twice (trapezoid rule on the 10 Hz samples,
  continuous across windows) to a displacement per 1-second window.
* The bias-corrected yaw rate, averaged over each window, is the INS orientation rate.

Beyond the paper, two constraints a car obeys (the paper's drives hardly stop inside an outage;
real urban ones stand 20-30 % of the time): the speed never goes below zero (dead reckoning on
the longitudinal axis assumes forward driving; integrated through a stop, a biased accelerometer
drove the car backwards at several m/s), nor above the fastest a car goes (a log whose
accelerometer runs away, as one with 5 Hz held readings did, still gives a car's track), and where the IMU shows the car
standing (:mod:`ionav_viz.nav.stillness`) the speed and the yaw rate are zero (a zero-velocity update).

The library rebuilds the 2D track from the last fix (:func:`ionav_viz.nav.track.rebuild_track`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..sources.plausibility import LIMITS
from .bias import SensorBias
from .integrals import trapezoid_mean
from .protocol import Estimate, EstimatorInputs

#: The speed never goes above the fastest the readers accept of a car (m/s).
MAX_SPEED_MPS = LIMITS["speed_mps"][1]
#: A still step's change of speed in :func:`dead_reckon` (m/s): more than any speed an outage can
#: integrate to, less than the running sum's precision would notice (1e-9 m/s after 600 stops).
STOP_STEP_MPS = 1e4


def dead_reckon(accel_mps2: np.ndarray, gyro_radps: np.ndarray, speed0_mps: np.ndarray, bias: SensorBias,
                rate_hz: float, still: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Displacement (m) and yaw rate (rad/s, CCW +) per window, from inertial samples.

    ``accel_mps2``/``gyro_radps``: (n_outages, n_windows, steps + 1) samples as measured, on a grid
    of ``rate_hz``, each window including both ends; ``speed0_mps``: (n_outages,) GNSS speed at the
    start of each outage; ``still``: the same shape as the samples, True where the car stands (the
    speed and the yaw rate are zero there). The speed never goes below zero. Returns two arrays of
    shape (n_outages, n_windows).
    """
    h = 1.0 / rate_hz
    acc = accel_mps2 - bias.accel_mps2
    gyr = gyro_radps - bias.gyro_radps
    n_seq, n_windows, steps = acc.shape[0], acc.shape[1], acc.shape[2] - 1
    if still is not None:
        gyr = np.where(still, 0.0, gyr)
    dv = (0.5 * (acc[..., 1:] + acc[..., :-1]) * h).reshape(n_seq, n_windows * steps)
    # the end of each step: still when the window's sample there is (a window's last sample is the next one's first)
    stop = np.zeros_like(dv, dtype=bool) if still is None else still[..., 1:].reshape(n_seq, n_windows * steps)
    # v[k+1] = max(v[k] + dv[k], 0), and 0 after a still step. Without the clamp v is the running
    # sum S; with it (Lindley's recursion) v = S - min(0, running min of S). A still step is a
    # step down larger than any speed, so the clamp brings v to zero there.
    dv = np.where(stop, -STOP_STEP_MPS, dv)
    s = np.concatenate([np.asarray(speed0_mps, dtype=np.float64).reshape(n_seq, 1), dv], axis=1).cumsum(axis=1)
    v = s - np.minimum(np.minimum.accumulate(s, axis=1), 0.0)
    # nor above the fastest a car goes: a runaway integral on a broken log is still a car's output
    v = np.minimum(v, MAX_SPEED_MPS)
    disp = (0.5 * (v[:, :-1] + v[:, 1:]) * h).reshape(n_seq, n_windows, steps).sum(axis=-1)
    return disp, trapezoid_mean(gyr)


class InsEstimator:
    """The paper's INS dead reckoning, restarted from the GNSS speed at every outage."""

    name = "ins"
    label = "INS DR"
    color = (213, 94, 0)  # Okabe-Ito vermillion (viz/style.py: the tracks' colour-blind-safe palette)

    def available(self) -> bool:
        return True

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        disp, yaw = dead_reckon(inputs.accel_mps2, inputs.gyro_radps, inputs.speed0_mps, inputs.bias, inputs.rate_hz,
                                inputs.still)
        return Estimate(disp, yaw)

    def describe(self) -> dict[str, Any]:
        return {}
