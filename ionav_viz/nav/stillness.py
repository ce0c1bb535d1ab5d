"""Standing still, as the IMU itself shows it: the zero-velocity detector behind the built-ins'
zero-velocity updates (:attr:`~ionav_viz.nav.protocol.EstimatorInputs.still`) and ``gins``'s ZUPTs.

A car standing with its engine running shakes its IMU less than a moving one (SENSORS.md, per
10 Hz sample: the accelerometer 0.13-0.28 m/s^2 standing, 0.14-0.45 driving; the gyro 0.05-0.14
deg/s standing, 0.1-0.75 driving), and does not turn. The detector compares, over a centred
window of STILL_WINDOW_S,

* the spread of the accelerometer (standard deviation; with three axes, the root mean square
  of theirs),
* the spread of the gyro,
* and how far the gyro's mean lies from its standing value (the bias; a steady turn is never still),

with the levels this drive's IMU shows while the GNSS says the car stands (``reference_still``,
:func:`standing_reference`): a sample is still when both spreads are under
STILL_MARGIN times their standing medians and the mean rate is within the standing mean's own
noise. The margin: a 1 s window of 10 samples estimates a standard deviation to about 24 % (one
axis; 14 % with three), so 1.6 times the median is about 2.5 of its standard errors above it
(4 with three), while moving the gyro spread is 2.5-4 times the standing one (the table above). Still stretches
shorter than MIN_STANDING_S are dropped.

A false "still" while moving is far worse than a missed stop (a zero-velocity update would
stop the car on the road), so a drive that never stands still under good GNSS, where the levels
cannot be measured, gets no still samples at all: the detector is only used where it was
calibrated on the drive itself. No fixed default would do: the table's standing and driving
ranges overlap (an accelerometer shaking 0.2 m/s^2 stands on one car and drives on another), and
the turn check needs the gyro's standing mean, its bias (up to 0.7 deg/s on a phone).

The calibration is a property of the sensor, measured on the drive: the median spreads and the
gyro's mean over every sample the GNSS says stands, outages included. What the GNSS says there
is never scored (the scores are positions and displacements, not where the car stood), and one
stop's samples move a median over the drive's stands little; each sample's decision is then the
IMU's own.

Measured on simulated drives against their true speed (`python benchmarks/stillness_rates.py`,
5 seeds x 10 min of every paper scenario, the nominal and a held-out car, and the 6-axis
``mems``/``phone`` logs of the hard-brake scenario; the first stand of each drive calibrates and
is not scored): in each group every one of the 61 later stops of 1 s or more is found (the
hard-brake drives'; the other scenarios stand only at their start), with 84 % (10 Hz
two-channel) to 91 % (100 Hz six-axis) of their samples (the centred window blurs
each stop's ends); no sample faster than 0.5 m/s is called still on the two-channel and phone
drives, and at most 0.11 % of those faster than 0.05 m/s (the last crawl into a stop), under 1 m of
true motion per hour of driving. On the MEMS logs, whose vibration is a bounded motion (the 6-axis
simulator), 0.04 % of the samples faster than 0.5 m/s are (one gentle pull-away at 1-2 m/s read
as standing for a second: 11 samples, 2.7 m of motion lost per hour).
"""

from __future__ import annotations

import numpy as np

from ..core.drive import Drive, measured_imu
from ..core.moving import as_columns, moving_mean
from ..core.runs import keep_runs, true_runs
from .bias import stationary_mask
from .windows import Windows

#: Length of the centred window of the statistics (s), and its fewest samples (a slower log's
#: window is longer): fewer than 10 samples estimate a spread too loosely for STILL_MARGIN
#: (measured: a 5 Hz log's 5-sample windows called 0.5 % of its moving samples still).
STILL_WINDOW_S = 1.0
MIN_WINDOW_SAMPLES = 10
#: A spread counts as standing below this factor of the standing median (see the module docstring).
STILL_MARGIN = 1.6
#: Still stretches shorter than this are dropped (s).
MIN_STANDING_S = 1.0
#: The standing levels need at least this much standing under good GNSS (s).
MIN_REFERENCE_S = 3.0
#: The gyro's mean may lie this far from its standing value at least (rad/s): 0.1 deg/s.
MIN_RATE_TOLERANCE_RADPS = np.deg2rad(0.1)


def moving_spread(x: np.ndarray, n: int) -> np.ndarray:
    """Centred moving standard deviation over ``n`` samples, the root mean square over the columns (n,)."""
    x = as_columns(x)
    mean = moving_mean(x, n)
    var = np.maximum(moving_mean(x * x, n) - mean * mean, 0.0)
    return np.sqrt(var.mean(axis=1))


def _drop_short(mask: np.ndarray, min_len: int) -> np.ndarray:
    """``mask`` without its runs of True shorter than ``min_len`` samples."""
    if min_len <= 1:
        return mask
    starts, ends = true_runs(mask)
    return keep_runs(mask, ends - starts >= min_len)


def still_samples(t_s: np.ndarray, accel_mps2: np.ndarray, gyro_radps: np.ndarray,
                  reference_still: np.ndarray | None = None) -> np.ndarray:
    """Whether the vehicle stands still at each sample (see the module docstring).

    ``accel_mps2``/``gyro_radps``: as measured (gravity and biases in), shape ``(n,)`` (one axis,
    e.g. IO-VNBD's longitudinal accelerometer and yaw gyro) or ``(n, 3)``; ``reference_still``:
    samples known to stand (the GNSS speed says so), where the standing levels are measured.
    Without MIN_REFERENCE_S of them nothing is still.
    """
    n = len(t_s)
    if n < 3 or reference_still is None:
        return np.zeros(n, dtype=bool)
    dt = float(np.median(np.diff(t_s)))
    ref = np.asarray(reference_still, dtype=bool)
    if ref.sum() * dt < MIN_REFERENCE_S:
        return np.zeros(n, dtype=bool)
    w = max(MIN_WINDOW_SAMPLES, int(round(STILL_WINDOW_S / dt)))
    acc, gyr = as_columns(accel_mps2), as_columns(gyro_radps)
    spread_a, spread_g = moving_spread(acc, w), moving_spread(gyr, w)
    level_a, level_g = float(np.median(spread_a[ref])), float(np.median(spread_g[ref]))
    bias = np.median(gyr[ref], axis=0)
    offset = np.sqrt(((moving_mean(gyr, w) - bias) ** 2).mean(axis=1))
    tolerance = max(4.0 * level_g / np.sqrt(w), MIN_RATE_TOLERANCE_RADPS)
    still = (spread_a < STILL_MARGIN * level_a) & (spread_g < STILL_MARGIN * level_g) & (offset < tolerance)
    return _drop_short(still, int(round(MIN_STANDING_S / dt)))


#: The GNSS speed that says where the car stands is its mean over this long (s), below
#: REFERENCE_MAX_SPEED_MPS: a phone's receiver scatters its speed by a few tenths of a m/s at a
#: standstill (0.3 m/s per axis puts the mean of its magnitude at 0.38 m/s).
REFERENCE_MEAN_S = 3.0
REFERENCE_MAX_SPEED_MPS = 0.5
#: Where that finds under MIN_REFERENCE_S (a phone's 3 s mean crosses 0.5 m/s on a short stand:
#: three of nine simulated phone drives, seven of nine when the speed is fitted to the fixes), the
#: stretches below LOOSE_REFERENCE_MAX_SPEED_MPS are the reference if the IMU agrees the car stands
#: there: the gyro's median spread under REFERENCE_QUIET_RATIO times its median where the GNSS
#: speed is above CLEARLY_MOVING_MPS. Standing shakes the gyro 2.5-4 times less than driving (the
#: module docstring); a crawl in a jam shakes like driving and fails the check.
LOOSE_REFERENCE_MAX_SPEED_MPS = 1.0
REFERENCE_QUIET_RATIO = 0.6
CLEARLY_MOVING_MPS = 3.0


def _sensors(drive: Drive) -> tuple[np.ndarray, np.ndarray]:
    """The accelerometer and gyro the detector reads: the full IMU where the drive has one, else
    the longitudinal accelerometer and the yaw gyro."""
    imu = measured_imu(drive)
    return imu if imu is not None else (drive.accel_long_mps2, drive.yaw_rate_radps)


def standing_reference(drive: Drive) -> np.ndarray:
    """Where the GNSS says the car stands (:func:`ionav_viz.nav.bias.stationary_mask` on the GNSS
    speed's moving mean over REFERENCE_MEAN_S, below REFERENCE_MAX_SPEED_MPS; below
    LOOSE_REFERENCE_MAX_SPEED_MPS where the gyro confirms it, when that finds too little): where
    the detector's levels are measured."""
    n = len(drive)
    if n < 3:
        return np.zeros(n, dtype=bool)
    dt = float(np.median(np.diff(drive.t_s)))
    smooth = moving_mean(drive.speed_mps, max(1, int(round(REFERENCE_MEAN_S / dt))))[:, 0]
    ref = stationary_mask(drive, REFERENCE_MAX_SPEED_MPS, speed_mps=smooth)
    if ref.sum() * dt >= MIN_REFERENCE_S:
        return ref
    slow = stationary_mask(drive, LOOSE_REFERENCE_MAX_SPEED_MPS, speed_mps=smooth)
    moving = drive.gnss_ok & (smooth > CLEARLY_MOVING_MPS)
    if slow.sum() * dt < MIN_REFERENCE_S or not moving.any():
        return ref
    spread = moving_spread(_sensors(drive)[1], max(MIN_WINDOW_SAMPLES, int(round(STILL_WINDOW_S / dt))))
    return slow if np.median(spread[slow]) < REFERENCE_QUIET_RATIO * np.median(spread[moving]) else ref


def drive_still(drive: Drive) -> np.ndarray:
    """:func:`still_samples` of a drive: on its full IMU where it has one, else on the longitudinal
    accelerometer and the yaw gyro, calibrated where the GNSS says the car stands (:func:`standing_reference`)."""
    return still_samples(drive.t_s, *_sensors(drive), standing_reference(drive))


def still_on_grid(drive: Drive, windows: Windows) -> np.ndarray:
    """Whether the car stands at each window's grid points, shape ``(n_windows, steps + 1)`` like
    :attr:`Windows.accel_mps2` (the nearest sample's :func:`drive_still`)."""
    steps = windows.steps
    if len(windows) == 0 or len(drive) == 0:
        return np.zeros((len(windows), steps + 1), dtype=bool)
    still = drive_still(drive)
    grid = windows.t0_s[:, None] + np.arange(steps + 1)[None, :] / windows.rate_hz
    i = np.clip(np.searchsorted(drive.t_s, grid), 1, len(drive) - 1)
    nearest = np.where(np.abs(drive.t_s[i - 1] - grid) <= np.abs(drive.t_s[i] - grid), i - 1, i)
    return still[nearest]
