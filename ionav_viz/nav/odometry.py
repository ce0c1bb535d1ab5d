"""Vehicle-speed odometry (``odo``): distance from the car's own speed, heading from the gyro.

A car with a CAN bus measures its speed far better than an accelerometer integrated twice; this
is the baseline a practitioner would set beside the paper's INS (the same authors' WhONet uses
the wheel speeds too).

* Speed: the mean of the rear wheel speeds (rad/s; the undriven wheels of a front-wheel-drive
  car, like IO-VNBD's Fiesta, slip least), else the indicated CAN speed (m/s), as a magnitude.
  Each window's distance is its trapezoid mean on the window's 10 Hz grid times 1 s, times a
  **scale** (positive): never negative, and zero where the wheels stand, so a stop inside an
  outage needs no stillness detector here.
* Scale (the effective rolling radius in m for wheel speeds, a unitless factor for the indicated
  speed): calibrated while GNSS is good, per outage, as the GNSS distance over the wheels'
  distance in the good-truth windows of the CALIBRATION_S seconds before its start (only windows
  where the car moves more than MIN_CALIBRATION_STEP_M count). The effective radius is 1-3 % off
  any nominal value and changes with tyre pressure, load and wear, so a fixed one would not do.
  With less than MIN_CALIBRATION_M of such driving before an outage, the nominal values are used
  (NOMINAL_RADIUS_M, or 1 for a speed).
* Yaw rate: the gyro minus its standstill bias, averaged per window (as the INS).

The drive must have a usable vehicle speed: a column that is missing, not finite, all zero or
constant is not one (:func:`ionav_viz.nav.vehicle_speed.vehicle_speed`). The estimator then does not apply (it is left
out of the default set, said once at ``-v``) and choosing it explicitly is an error.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from .integrals import trapezoid_mean
from .protocol import Estimate, EstimatorInputs
from .track import systematic_track_covariance, track_covariance
from .vehicle_speed import nominal_mps_per_unit, vehicle_speed, why_no_vehicle_speed
from .windows import Windows

log = logging.getLogger("ionav_viz")

CALIBRATION_S = 120.0
MIN_CALIBRATION_STEP_M = 1.0
MIN_CALIBRATION_M = 100.0

def window_distance(windows: Windows, drive: Drive, values: np.ndarray) -> np.ndarray:
    """Trapezoid mean of ``values`` (per sample) over each window's 10 Hz grid, times 1 s."""
    steps = int(round(windows.rate_hz))
    grid = windows.t0_s[:, None] + np.arange(steps + 1)[None, :] / windows.rate_hz
    return trapezoid_mean(np.interp(grid, drive.t_s, values))


def calibrated_scale(windows: Windows, raw: np.ndarray, starts: np.ndarray, nominal: float) -> np.ndarray:
    """Per outage start, the GNSS distance over the raw distance in the good-truth, moving
    windows of the CALIBRATION_S seconds before it (``nominal`` with too little of them)."""
    use = windows.truth_ok & (windows.gnss_disp_m > MIN_CALIBRATION_STEP_M) & (raw > 0)
    gnss = np.concatenate([[0.0], np.cumsum(np.where(use, windows.gnss_disp_m, 0.0))])
    wheel = np.concatenate([[0.0], np.cumsum(np.where(use, raw, 0.0))])
    first = np.searchsorted(windows.t0_s, windows.t0_s[starts] - CALIBRATION_S)
    g, w = gnss[starts] - gnss[first], wheel[starts] - wheel[first]
    return np.where(g >= MIN_CALIBRATION_M, g / np.where(w > 0, w, 1.0), nominal)


#: How sure odometry is (1 sigma): its scale calibrated on GNSS (the fixes' error over the
#: calibration's 100 m or more, and a tyre's change within minutes) or nominal (1-3 % off any
#: nominal value: 3 %); the gyro's standstill bias (what a standstill of a few seconds leaves,
#: 0.02 deg/s) and its white noise per 1 s window (0.05 deg/s); the GNSS course at the start
#: (0.5 deg at 10 m/s, growing as 1/speed, as the planar filter takes it).
ODO_SCALE_SIGMA_CALIBRATED = 0.005
ODO_SCALE_SIGMA_NOMINAL = 0.03
ODO_GYRO_BIAS_SIGMA_RADPS = np.deg2rad(0.02)
ODO_GYRO_WHITE_RADPS = np.deg2rad(0.05)
COURSE_SIGMA_RAD_AT_10MPS = np.deg2rad(0.5)


def odometry_covariance(inputs: EstimatorInputs, disp_m: np.ndarray, yaw_rate_radps: np.ndarray,
                        calibrated: np.ndarray) -> np.ndarray:
    """Odometry's east/north position covariance (m^2) at every window boundary: its scale's and the
    gyro bias's errors, which hold through an outage, the gyro's white noise per window and the GNSS
    course at the start (the constants above)."""
    scale_sigma = np.where(calibrated, ODO_SCALE_SIGMA_CALIBRATED, ODO_SCALE_SIGMA_NOMINAL)
    course_sigma = COURSE_SIGMA_RAD_AT_10MPS * 10.0 / np.maximum(np.asarray(inputs.speed0_mps, dtype=float), 1.0)
    return (track_covariance(inputs.course0_deg, disp_m, yaw_rate_radps, 0.0, ODO_GYRO_WHITE_RADPS**2, course_sigma**2)
            + systematic_track_covariance(inputs.course0_deg, disp_m, yaw_rate_radps, scale_sigma,
                                          ODO_GYRO_BIAS_SIGMA_RADPS))


class OdometryEstimator:
    """Distance from the wheel speeds (or indicated speed), yaw rate from the bias-corrected gyro."""

    name = "odo"
    label = "Odometry"
    color = (204, 121, 167)  # Okabe-Ito reddish purple ("pink")
    requires = "a vehicle speed: wheel speeds, CAN speed or wheel odometry"

    def __init__(self) -> None:
        self._last: dict[str, Any] = {}

    def available(self) -> bool:
        return True

    def applies(self, drive: Drive) -> bool:
        if vehicle_speed(drive) is not None:
            return True
        log.info("%s: odometry left out: %s", drive.name, why_no_vehicle_speed(drive))
        return False

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        found = vehicle_speed(inputs.drive)
        if found is None:
            raise InputError(f"{inputs.drive.source}: odometry needs a vehicle speed, and "
                             f"{why_no_vehicle_speed(inputs.drive)}",
                             "leave odo out of the estimators for this drive", param="estimators")
        values, unit, source = found
        # a distance, never negative: the speed's magnitude (a log's signed wheel speeds or odometry
        # count reversing as distance too, as the reader does for a body twist)
        raw = window_distance(inputs.windows, inputs.drive, np.abs(values))
        nominal = nominal_mps_per_unit(unit)
        scale = calibrated_scale(inputs.windows, raw, inputs.starts, nominal)
        disp = raw[inputs.window_index] * scale[:, None]
        yaw = trapezoid_mean(inputs.gyro_radps - inputs.bias.gyro_radps)
        self._last = {"speed": f"{source} ({unit})", "scale": f"{'radius' if unit == 'rad/s' else 'factor'} "
                      f"{np.median(scale) if len(scale) else nominal:.4f}{' m' if unit == 'rad/s' else ''} (median, "
                      "from GNSS before each outage)"}
        return Estimate(disp, yaw, pos_cov_m2=odometry_covariance(inputs, disp, yaw, scale != nominal))

    def describe(self) -> dict[str, Any]:
        return dict(self._last)
