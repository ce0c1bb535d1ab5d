"""The IMU characterised, in order, for the readers (:mod:`ionav_viz.sources.resample`): its mount
on the car (:mod:`.mount`) and the check of its axes (:mod:`.axes`), the nature of its samples,
its clock against the receiver's (:mod:`.clock`) and how much its holder wobbles; the result is
the :class:`ionav_viz.core.imu.ImuCharacter` the drive carries and the reports show.

What the user says (:class:`ImuSettings`) wins over what the log suggests; what cannot be told from
a log is said, with the option that decides it.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...core.errors import InputError
from ...core.imu import AVERAGED, SAMPLE_KINDS, SINGLE, ImuCharacter
from .axes import YAW_REVERSED, check_imu_frame
from .clock import ClockOffset, estimate_clock_offset, should_apply
from .mount import MAX_SILENT_DEG, MIN_APPLIED_DEG, angles_deg, estimate_mount, format_mount, nearest_axes

log = logging.getLogger("ionav_viz")

#: The IMU's axes in the body frame, as messages name them.
IMU_AXIS_NAMES = ("accel x", "accel y", "accel z", "gyro x", "gyro y", "gyro z")
#: With at least this many readings in each of the drive's samples, the reader's mean is the
#: interval's increment whatever each reading was (50 Hz and up on the 10 Hz grid).
READER_AVERAGES_FROM = 5.0
#: The holder's wobble is measured on samples faster than this (m/s).
WOBBLE_SPEED_MPS = 3.0


@dataclass(frozen=True)
class ImuSettings:
    """What the user said of the IMU: the axis ``mapping`` already applied (for hints), the yaw sign
    (``auto``, ``cw``, ``ccw``), the ``mount`` (a rotation, ``"auto"`` or None: estimated, applied
    when small), the clock ``time_offset`` (``"auto"``, seconds, or None: estimated, applied when
    clear) and the sample kind ``samples`` (``"single"``, ``"averaged"`` or None: from the rate)."""

    mapping: np.ndarray
    yaw_sign: str = "auto"
    mount: np.ndarray | str | None = None
    time_offset: float | str | None = None
    samples: str | None = None


def parse_time_offset(text: str | None) -> float | str | None:
    """``--imu-time-offset``: ``auto``, or seconds (``0.3``, ``-0.25s``, ``300ms``)."""
    if text is None:
        return None
    value = str(text).strip().lower()
    if value == "auto":
        return value
    scale = 1e-3 if value.endswith("ms") else 1.0
    number = value.removesuffix("ms").removesuffix("s")
    try:
        seconds = float(number) * scale
    except ValueError:
        seconds = math.nan
    if not math.isfinite(seconds) or abs(seconds) > 10.0:
        raise InputError(f"IMU time offset {text!r} is not auto or a number of seconds within 10 s",
                         "give auto, or e.g. 0.3 (the IMU's stamps 0.3 s late against the receiver's), -0.25s or 300ms",
                         param="imu_time_offset")
    return seconds


def check_samples(text: str | None) -> str | None:
    """``--imu-samples``: ``single``, ``averaged`` or None."""
    if text is None or text in SAMPLE_KINDS:
        return text
    raise InputError(f"IMU sample kind {text!r} is not single or averaged",
                     "give single (each sample one instantaneous reading, as phones log them) or averaged (a mean or "
                     "increment over its interval)",
                     param="imu_samples")


def sample_kind(readings_per_sample: float, given: str | None) -> tuple[str, str]:
    """The samples' nature and how it is known (see :class:`~ionav_viz.core.imu.ImuCharacter`)."""
    if readings_per_sample >= READER_AVERAGES_FROM:
        return AVERAGED, "reader"
    if given is not None:
        return given, "given"
    # a message holds a value, not how it was made: at a low rate, an instantaneous reading (a phone's
    # sensor event) is the common case, and the one a 3D mechanisation must not trust
    return SINGLE, "assumed"


def wobble_dps(body: np.ndarray, speed_mps: np.ndarray) -> float:
    """The pitch and roll rates' successive-sample spread while driving (deg/s per sample, robust)."""
    moving = (speed_mps[1:] > WOBBLE_SPEED_MPS) & (speed_mps[:-1] > WOBBLE_SPEED_MPS)
    if moving.sum() < 20:
        return math.nan
    d = np.diff(body[:, 3:5], axis=0)[moving]
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return float(np.degrees(np.mean(1.4826 * mad / math.sqrt(2.0))))


@dataclass(frozen=True)
class Oriented:
    """The IMU's samples in the body frame and how they were turned: the ``mount`` matrix applied
    (None: none) and whether the yaw axis was turned over (``flipped``), to turn samples again."""

    body: np.ndarray
    mount: np.ndarray | None
    flipped: bool
    mount_deg: tuple[float, float, float] | None
    mount_sigma_deg: tuple[float, float, float] | None

    def turn(self, body: np.ndarray) -> np.ndarray:
        """Other samples of the same IMU turned the same way."""
        out = body
        if self.mount is not None:
            out = body.copy()
            out[:, :3], out[:, 3:] = body[:, :3] @ self.mount.T, body[:, 3:] @ self.mount.T
        return out * np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0]) if self.flipped else out


def orient(path: Path, t: np.ndarray, body: np.ndarray, speed_mps: np.ndarray, course_deg: np.ndarray,
           settings: ImuSettings, vehicle_speed_mps: np.ndarray | None, measured: np.ndarray) -> Oriented:
    """The mount (:func:`_mounted`) and the frame check (:func:`_frame_reversed`)."""
    matrix, estimate = _mounted(path, t, body, speed_mps, course_deg, settings, vehicle_speed_mps, measured)
    mounted = body if matrix is None else Oriented(body, matrix, False, None, None).turn(body)
    flipped = _frame_reversed(path, t, mounted, speed_mps, course_deg, settings, measured)
    shown = matrix if matrix is not None else (estimate.matrix if estimate is not None else None)
    sigma = (tuple(float(s) for s in estimate.sigma_deg)
             if estimate is not None and hasattr(estimate, "sigma_deg") else None)
    out = Oriented(body, matrix, flipped, angles_deg(shown) if shown is not None else None,
                   sigma)  # type: ignore[arg-type]
    return Oriented(out.turn(body), matrix, flipped, out.mount_deg, sigma)


def clock_offset(path: Path, t: np.ndarray, body: np.ndarray, speed_mps: np.ndarray, course_deg: np.ndarray,
                 settings: ImuSettings, one_clock: bool = False) -> tuple[float, ClockOffset | None]:
    """The offset to move the IMU's samples by (s; 0: none) and the estimate behind it (None when given).

    ``one_clock``: IMU and GNSS share every stamp (one logger's rows, as ``convert`` writes an
    IO-VNBD drive): an offset found there is the receiver's own lag, not a clock's, and is applied
    only when asked for (``auto`` or seconds)."""
    if isinstance(settings.time_offset, float):
        return settings.time_offset, None
    found = estimate_clock_offset(t, body[:, 5], speed_mps, course_deg)
    if settings.time_offset == "auto" and not found.resolved:
        raise InputError(f"{path}: the IMU's clock offset against the receiver cannot be resolved: {found.reason}",
                         "give it in seconds (the IMU's stamps minus the receiver's, e.g. 0.3), or leave "
                         "the option out",
                         param="imu_time_offset")
    if one_clock and settings.time_offset is None:
        if found.resolved and should_apply(found):
            log.info("%s: IMU and GNSS share their stamps (one clock): the %+.3f s found between them is not applied "
                     "(--imu-time-offset %.3f applies it)", path, found.offset_s, found.offset_s)
        return 0.0, found
    if found.resolved and should_apply(found):
        log.warning("%s: the IMU's stamps are %+.3f s (± %.3f) off the receiver's: moved them (the IMU time offset "
                    "%.3f gives it exactly)", path, found.offset_s, found.sigma_s, found.offset_s)
        return found.offset_s, found
    if not found.resolved:
        log.info("%s: the IMU's clock offset against the receiver is not resolved (%s); none applied", path,
                 found.reason)
    else:
        log.info("%s: the IMU's stamps are %+.3f s (± %.3f) off the receiver's course, within what a course lags by: "
                 "none applied (--imu-time-offset %.3f applies it)", path, found.offset_s, found.sigma_s,
                 found.offset_s)
    return 0.0, found


def character(rate_hz: float, readings: float, oriented: Oriented, applied_offset_s: float, offset: ClockOffset | None,
              settings: ImuSettings, speed_mps: np.ndarray) -> ImuCharacter:
    """The :class:`~ionav_viz.core.imu.ImuCharacter` of what was found and applied."""
    kind, source = sample_kind(readings, settings.samples)
    if offset is None:  # given
        clock = dict(clock_offset_s=applied_offset_s, clock_offset_sigma_s=0.0, clock_offset_applied=True,
                     clock_offset_note="given")
    else:
        clock = dict(clock_offset_s=offset.offset_s,
                     clock_offset_sigma_s=offset.sigma_s if offset.resolved else math.inf,
                     clock_offset_applied=applied_offset_s != 0.0,
                     clock_offset_note="estimated" if offset.resolved else offset.reason)
    return ImuCharacter(native_rate_hz=round(rate_hz, 1), readings_per_sample=round(readings, 1), sample_kind=kind,
                        sample_kind_source=source, mount_deg=oriented.mount_deg,
                        mount_sigma_deg=oriented.mount_sigma_deg, mount_applied=oriented.mount is not None,
                        wobble_dps=wobble_dps(oriented.body, speed_mps), **clock)


def _mounted(path: Path, t: np.ndarray, body: np.ndarray, speed_mps: np.ndarray, course_deg: np.ndarray,
             settings: ImuSettings, vehicle_speed_mps: np.ndarray | None, measured: np.ndarray):
    """The mount to apply (None: none) and the estimate (None when given or not estimated).

    Given a rotation: applied. Otherwise estimated: with ``"auto"`` applied and reported; without,
    below :data:`~.mount.MIN_APPLIED_DEG` left alone (gravity cannot tell so small a tilt from an
    accelerometer bias or a road's grade), up to :data:`~.mount.MAX_SILENT_DEG` applied and
    reported, beyond it a stop showing the estimate and the options.

    A mount turns whole vectors, so with an axis not measured none is estimated (said at ``-v``; a
    warning with ``"auto"``) and a given rotation other than a signed permutation of the axes is refused.
    """
    imu_mount = settings.mount
    unmeasured = [name for name, ok in zip(IMU_AXIS_NAMES, measured, strict=True) if not ok]
    if isinstance(imu_mount, np.ndarray):
        if unmeasured and not np.array_equal(np.abs(imu_mount), np.abs(imu_mount).round()):
            raise InputError(f"{path}: the IMU's {', '.join(unmeasured)} read one value over the whole log "
                             "(not measured), so its vectors cannot be turned by a mount",
                             "leave the mount out (the IMU axes map whole axes)", param="imu_mount")
        return imu_mount, None
    if unmeasured:
        (log.warning if imu_mount == "auto" else log.info)(
            "%s: the IMU's mount is not estimated: its %s read one value over the whole log (not measured); "
            "its axes are used as they are", path, ", ".join(unmeasured))
        return None, None
    found = estimate_mount(t, body[:, :3], speed_mps, course_deg, gyro_xyz=body[:, 3:6],
                           vehicle_speed_mps=vehicle_speed_mps)
    if found is None:
        log.warning("%s: the IMU's mount cannot be estimated (gravity does not read 7-13 m/s^2 on average); "
                    "its axes are used as they are", path)
        return None, None
    angle = found.angle_deg
    if imu_mount != "auto" and angle > MAX_SILENT_DEG:
        permutation = nearest_axes(found.matrix @ settings.mapping)
        axes = (f", or map the IMU axes with --imu-axes {permutation} (the nearest exact permutation)"
                if permutation else "")
        raise InputError(f"{path}: the IMU is not in the body frame (REP 103: x forward, y left, z up): its mount "
                         f"is estimated as {found.describe()}, {angle:.0f} deg from it",
                         "apply this estimate with --imu-mount auto, or give it as --imu-mount "
                         f"{format_mount(found.matrix)}{axes}",
                         param="imu_mount")
    if imu_mount != "auto" and angle < MIN_APPLIED_DEG:
        return None, found
    log.warning("%s: applied the IMU mount estimated from the log: %s (%.1f deg from the body frame; "
                "--imu-mount %s gives it exactly)", path, found.describe(), angle, format_mount(found.matrix))
    return found.matrix, found


def _frame_reversed(path: Path, t: np.ndarray, body: np.ndarray, speed_mps: np.ndarray, course_deg: np.ndarray,
                    settings: ImuSettings, measured: np.ndarray) -> bool:
    """Check the IMU's frame (:func:`.axes.check_imu_frame`, on the ``measured`` axes), warn
    once, and say whether the yaw rate must be flipped (only with the yaw sign ``auto``)."""
    check_yaw_sign = settings.yaw_sign == "auto"
    found = check_imu_frame(t, body[:, :3], body[:, 3:], speed_mps, course_deg, settings.mapping, measured=measured)
    problems = [p for p in found.problems if check_yaw_sign or not p.startswith(YAW_REVERSED)]
    if problems:
        fix = f"; map the axes with --imu-axes {found.suggestion}" if found.suggestion else ""
        force = "; force the sign with --yaw-sign cw|ccw" if found.yaw_reversed and check_yaw_sign else ""
        log.warning("%s: the IMU is not in the body frame ionav-viz expects (REP 103: x forward, z up): %s%s%s",
                    path, "; ".join(problems), fix, force)
    return found.yaw_reversed and check_yaw_sign
