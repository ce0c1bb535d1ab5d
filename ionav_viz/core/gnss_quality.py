"""GNSS quality per sample: which fixes are trustworthy ground truth, and why not.

Every number ionav-viz reports is a difference from the GNSS track, so a bad fix must never be
scored. Each sample of a drive carries a fault mask (:attr:`Drive.gnss_fault`, 0 = good); the
bits say why (:class:`GnssFault`). They come from what the source says (satellite count,
reported accuracy) and from consistency with the drive's own speed, in :func:`assess_gnss`,
with thresholds in one place (:class:`GnssLimits`, every one overridable: ``--gnss-limit
jump_margin_m=5`` on the command line, ``gnss_limits=GnssLimits(jump_margin_m=5)`` in Python).

Fixes a reader cannot use at all (``status < 0``, a non-finite position) are dropped by the
reader, leaving a gap; fixes sharing a time stamp keep the first; out-of-order fixes are sorted
by stamp (MCAP) or refused (CSV, where time going backwards means two logs joined).

Checks, per sample ``i`` (positions compared in a local flat frame, fine for the metres
between consecutive samples):

* ``no-fix``: satellite count 0 (IO-VNBD's logger keeps its last numbers during a loss), or no
  fix at all at that time (an MCAP log whose IMU goes on through a gap between fixes, or between
  the receiver's velocity messages while its fixes go on).
* ``few-satellites``: satellite count below ``min_satellites``.
* ``poor-accuracy``: reported horizontal standard deviation above ``max_sigma_m``.
* ``near-zero``: latitude and longitude both within ``near_zero_deg`` of 0 (a receiver's
  "no position" written as (0, 0)).
* ``frozen``: the position does not change for at least ``frozen_min_s`` while the car moved: the
  mean of the GNSS speed (and, where the drive has it, the vehicle speed) over the run is at least
  ``moving_mps``, or the car was moving that fast just before the run and the accelerometer does not
  brake it below that within the run (a receiver holding its speed at 0, or a fix-only log whose
  speed comes from the frozen positions). A receiver holding its last fix. The run's first sample
  (the last real fix) stays good.
* ``jump``: between two otherwise good samples the position moves further than the speed can
  explain: ``d > jump_speed_factor * max(v_i, v_i+1) * dt + jump_margin_m``. A single sample
  jumping away and back is flagged alone; a step (the track jumps once, e.g. when the receiver
  settles after a loss) flags both samples around it.
* ``speed-step``: from one sample not already known bad to another ``speed_step_span_s`` later, the
  speed changes by more than the accelerometer's longitudinal specific force integrated over the
  same time, give or take ``speed_step_mps`` (a phone's location service reporting 1.5 m/s for a
  second of a drive at 9 m/s). Every sample of such a stretch is flagged: the glitch and the
  samples interpolated to and from it. Only where the drive has a measured longitudinal
  acceleration; 5 m/s in 1 s is twice what a hard brake leaves unexplained on a receiver that
  smooths its speed by a second (a phone's, measured on the corpus logs).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from .geo import steps_en_m
from .overrides import check_ranges, with_overrides
from .runs import true_runs


class GnssFault(enum.IntFlag):
    """Why a GNSS sample is not trustworthy truth (bits of :attr:`Drive.gnss_fault`)."""

    NO_FIX = 1
    FEW_SATELLITES = 2
    POOR_ACCURACY = 4
    NEAR_ZERO = 8
    FROZEN = 16
    JUMP = 32
    SPEED_STEP = 64


#: Each fault bit's name in reports, JSON and the recording.
FAULT_NAMES = {
    GnssFault.NO_FIX: "no-fix",
    GnssFault.FEW_SATELLITES: "few-satellites",
    GnssFault.POOR_ACCURACY: "poor-accuracy",
    GnssFault.NEAR_ZERO: "near-zero",
    GnssFault.FROZEN: "frozen",
    GnssFault.JUMP: "jump",
    GnssFault.SPEED_STEP: "speed-step",
}


@dataclass(frozen=True)
class GnssLimits:
    """Thresholds of the GNSS quality checks (see the module docstring for what each does)."""

    min_satellites: int = 4
    max_sigma_m: float = 5.0
    near_zero_deg: float = 0.01
    frozen_min_s: float = 0.5
    moving_mps: float = 1.0
    jump_speed_factor: float = 1.5
    jump_margin_m: float = 3.0
    speed_step_mps: float = 5.0
    speed_step_span_s: float = 1.0

    def __post_init__(self) -> None:
        check_ranges(self, _LIMIT_RANGES, "GNSS limit", "gnss_limits")

    def with_overrides(self, pairs: list[str]) -> GnssLimits:
        """``['jump_margin_m=5', ...]`` -> a copy with those limits changed, each checked against its range."""
        return with_overrides(self, pairs, _LIMIT_RANGES, "GNSS limit", "gnss_limits")


_LIMIT_RANGES = {
    "min_satellites": (0, 64), "max_sigma_m": (0.001, 1e4), "near_zero_deg": (0.0, 10.0), "frozen_min_s": (0.05, 60.0),
    "moving_mps": (0.0, 50.0), "jump_speed_factor": (1.0, 10.0), "jump_margin_m": (0.0, 1e4),
    "speed_step_mps": (0.1, 1e3), "speed_step_span_s": (0.05, 60.0),
}


def fault_names(mask: int) -> list[str]:
    """Names of the bits set in ``mask``."""
    return [name for bit, name in FAULT_NAMES.items() if mask & bit]


def count_by_fault(masks: np.ndarray) -> dict[str, int]:
    """How many of ``masks`` have each fault bit (only faults that occur)."""
    masks = np.asarray(masks, dtype=np.int64)
    counts = {name: int(np.count_nonzero(masks & bit)) for bit, name in FAULT_NAMES.items()}
    return {name: n for name, n in counts.items() if n}


#: The filters' GNSS position sigma (m) is the receiver's reported accuracy, never below this (the
#: planar ``ekf`` and ``gins`` alike; an RTK receiver's centimetres are not taken at their word).
GNSS_SIGMA_FLOOR_M = 0.3


def position_sigma_m(t_s: np.ndarray, drive_t_s: np.ndarray, reported_m: np.ndarray | None,
                     default_m: float) -> np.ndarray:
    """The GNSS position sigma (m) at times ``t_s`` for a filter: the receiver's reported accuracy
    (``reported_m`` per drive sample at ``drive_t_s``, the drive's ``gnss_sigma_m``) interpolated,
    never below GNSS_SIGMA_FLOOR_M; ``default_m`` everywhere when the drive has none."""
    if reported_m is None:
        return np.full(len(t_s), default_m)
    return np.maximum(np.interp(t_s, drive_t_s, reported_m), GNSS_SIGMA_FLOOR_M)


@dataclass(frozen=True)
class ReceiverQuality:
    """What the source says of each fix, per sample (each optional; None: the source does not say).

    Attributes:
        n_satellites: satellites used (0: no fix).
        sigma_m: reported horizontal standard deviation (m).
        has_fix: 0 where the source had no fix at that time.
    """

    n_satellites: np.ndarray | None = None
    sigma_m: np.ndarray | None = None
    has_fix: np.ndarray | None = None


def assess_gnss(t_s: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray, speed_mps: np.ndarray,
                receiver: ReceiverQuality | None = None, vehicle_speed_mps: np.ndarray | None = None,
                limits: GnssLimits = GnssLimits(), accel_mps2: np.ndarray | None = None) -> np.ndarray:
    """Fault mask (uint16, 0 = good) of each sample; see the module docstring for the checks.
    ``receiver`` (what the source says of each fix) and ``accel_mps2`` (longitudinal specific
    force (m/s^2), for the frozen and speed-step checks) are optional."""
    receiver = receiver if receiver is not None else ReceiverQuality()
    n_satellites, sigma_m, has_fix = receiver.n_satellites, receiver.sigma_m, receiver.has_fix
    n = len(t_s)
    fault = np.zeros(n, dtype=np.uint16)
    if has_fix is not None:
        fault[has_fix <= 0] |= np.uint16(GnssFault.NO_FIX)
    if n_satellites is not None:
        fault[n_satellites <= 0] |= np.uint16(GnssFault.NO_FIX)
        fault[(n_satellites > 0) & (n_satellites < limits.min_satellites)] |= np.uint16(GnssFault.FEW_SATELLITES)
    if sigma_m is not None:
        fault[sigma_m > limits.max_sigma_m] |= np.uint16(GnssFault.POOR_ACCURACY)
    fault[(np.abs(lat_deg) < limits.near_zero_deg)
          & (np.abs(lon_deg) < limits.near_zero_deg)] |= np.uint16(GnssFault.NEAR_ZERO)
    if n < 2:
        return fault

    dt = np.diff(t_s)
    east, north = steps_en_m(lat_deg, lon_deg)
    step_m = np.hypot(north, east)
    speed = speed_mps if vehicle_speed_mps is None else np.maximum(speed_mps, vehicle_speed_mps)
    fault |= _frozen(t_s, step_m, speed, limits, accel_mps2)

    # Jumps, only between samples not already known bad.
    good = fault == 0
    expected = limits.jump_speed_factor * np.maximum(speed[1:], speed[:-1]) * dt + limits.jump_margin_m
    jump = (step_m > expected) & good[1:] & good[:-1]
    spike = np.zeros(n, dtype=bool)
    spike[1:-1] = jump[:-1] & jump[1:]
    step = jump & ~spike[:-1] & ~spike[1:]
    flagged = spike.copy()
    flagged[:-1] |= step
    flagged[1:] |= step
    fault[flagged] |= np.uint16(GnssFault.JUMP)
    if accel_mps2 is not None and np.ptp(accel_mps2) > 0:  # a constant is no accelerometer
        fault[_speed_steps(t_s, speed_mps, accel_mps2, fault == 0, limits)] |= np.uint16(GnssFault.SPEED_STEP)
    return fault




def _frozen(t_s: np.ndarray, step_m: np.ndarray, speed: np.ndarray, limits: GnssLimits,
            accel_mps2: np.ndarray | None = None) -> np.ndarray:
    """FROZEN on samples repeating the previous position for >= frozen_min_s while moving."""
    fault = np.zeros(len(t_s), dtype=np.uint16)
    same = step_m < 1e-3
    if not same.any():
        return fault
    # runs of repeated positions: samples first+1 .. last repeat sample first
    first, last = true_runs(same)
    speed_sum = np.concatenate([[0.0], np.cumsum(speed)])
    mean_speed = (speed_sum[last + 1] - speed_sum[first + 1]) / (last - first)
    moving = mean_speed >= limits.moving_mps
    if accel_mps2 is not None:
        # moving just before the run, and the accelerometer never brakes it below moving_mps:
        # the slowest speed within the run is v_before + min(integral of a) over the run
        before = np.clip(np.searchsorted(t_s, t_s[first] - 1.0), 0, len(t_s) - 1)
        dv = np.concatenate([[0.0], np.cumsum(0.5 * (accel_mps2[1:] + accel_mps2[:-1]) * np.diff(t_s)), [np.inf]])
        lowest = np.minimum.reduceat(dv, np.column_stack([first, last + 1]).ravel())[::2] - dv[first]
        moving |= (speed[before] >= limits.moving_mps) & (speed[before] + lowest >= limits.moving_mps)
    held = (t_s[last] - t_s[first] >= limits.frozen_min_s) & moving
    run_of = np.cumsum(np.bincount(first[held] + 1, minlength=len(t_s) + 1)
                       - np.bincount(last[held] + 1, minlength=len(t_s) + 1))
    fault[run_of[: len(t_s)] > 0] = np.uint16(GnssFault.FROZEN)
    return fault


def _speed_steps(t_s: np.ndarray, speed_mps: np.ndarray, accel_mps2: np.ndarray, good: np.ndarray,
                 limits: GnssLimits) -> np.ndarray:
    """Whether each sample lies in a stretch of ``speed_step_span_s`` from one ``good`` sample to
    another over which the speed changes by more than ``speed_step_mps`` beyond the integrated
    longitudinal specific force (both ends included; a receiver's speed of 0 in a loss, already
    flagged, is no step from the fixes around it). A gap in the samples longer than the span is
    never inside a stretch."""
    dv_imu = np.concatenate([[0.0], np.cumsum(0.5 * (accel_mps2[1:] + accel_mps2[:-1]) * np.diff(t_s))])
    end = np.arange(len(t_s))
    start = np.searchsorted(t_s, t_s - limits.speed_step_span_s)
    unexplained = (speed_mps[end] - speed_mps[start]) - (dv_imu[end] - dv_imu[start])
    bad = (np.abs(unexplained) > limits.speed_step_mps) & good[start] & good[end]
    # every sample from start to end of each bad stretch: +1 at its start, -1 after its end
    edges = np.bincount(start[bad], minlength=len(t_s) + 1) - np.bincount(end[bad] + 1, minlength=len(t_s) + 1)
    cover = np.cumsum(edges)
    return cover[: len(t_s)] > 0
