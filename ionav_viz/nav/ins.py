"""INS dead reckoning during GNSS outages, as Section 2.1 of the paper describes (the baseline).

* Sensor biases (:mod:`ionav_viz.nav.bias`) are subtracted from the accelerometer and gyro.
* Velocity is initialised from the GNSS speed at the outage start, then the bias-corrected
  longitudinal acceleration is integrated twice (trapezoid rule on the 10 Hz samples,
  continuous across windows) to a displacement per 1-second window.
* The bias-corrected yaw rate, averaged over each window, is the INS orientation rate.

The library rebuilds the 2D track from the last fix (:func:`ionav_viz.nav.track.rebuild_track`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .bias import SensorBias
from .integrals import trapezoid_mean
from .protocol import Estimate, EstimatorInputs


def dead_reckon(accel_mps2: np.ndarray, gyro_radps: np.ndarray, speed0_mps: np.ndarray, bias: SensorBias,
                rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Displacement (m) and yaw rate (rad/s, CCW +) per window, from inertial samples.

    ``accel_mps2``/``gyro_radps``: (n_outages, n_windows, steps + 1) samples as measured, on a grid
    of ``rate_hz``, each window including both ends; ``speed0_mps``: (n_outages,) GNSS speed at the
    start of each outage. Returns two arrays of shape (n_outages, n_windows).
    """
    h = 1.0 / rate_hz
    acc = accel_mps2 - bias.accel_mps2
    gyr = gyro_radps - bias.gyro_radps
    n_seq, n_windows, steps = acc.shape[0], acc.shape[1], acc.shape[2] - 1
    dv = (0.5 * (acc[..., 1:] + acc[..., :-1]) * h).reshape(n_seq, n_windows * steps)
    v0 = np.asarray(speed0_mps, dtype=np.float64)[:, None]
    v_end = v0 + np.cumsum(dv, axis=1)
    v_start = np.concatenate([v0, v_end[:, :-1]], axis=1)
    disp = (0.5 * (v_start + v_end) * h).reshape(n_seq, n_windows, steps).sum(axis=-1)
    return disp, trapezoid_mean(gyr)


class InsEstimator:
    """The paper's INS dead reckoning, restarted from the GNSS speed at every outage."""

    name = "ins"
    label = "INS DR"
    color = (230, 60, 50)

    def available(self) -> bool:
        return True

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        disp, yaw = dead_reckon(inputs.accel_mps2, inputs.gyro_radps, inputs.speed0_mps, inputs.bias, inputs.rate_hz)
        return Estimate(disp, yaw)

    def describe(self) -> dict[str, Any]:
        return {}
