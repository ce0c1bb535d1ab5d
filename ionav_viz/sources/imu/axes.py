"""Is the IMU in the body frame ionav-viz expects? Axis mapping and sanity checks at the reader.

ionav-viz's body frame is REP 103's: x forward, y left, z up. The longitudinal accelerometer is
the specific force along x (gravity reads +9.81 m/s^2 on z at rest), the yaw rate the angular
velocity about z, counter-clockwise (seen from above) positive.

A log's IMU may be mounted otherwise (on its side, upside down, turned on the dashboard).
:func:`parse_imu_axes` reads the user's mapping (``--imu-axes x=-y,y=x,z=z``: body x is the log's
-y, ...) into a matrix; :func:`check_imu_frame` tells from the data whether the axes look right:

* gravity: the mean specific force while standing still (the whole drive if it never stands
  still) should lie along +z;
* yaw axis: the gyro axis whose rate correlates best with the GNSS course change (while turning
  at speed) should be z, with a positive correlation (a negative one on z is the yaw-sign check:
  the rate is flipped, with a warning, as for IO-VNBD files);
* forward axis: the horizontal accelerometer axis that correlates best with the GNSS speed's
  derivative should be +x.

Whatever it finds goes into one warning line naming the axes and the ``--imu-axes`` value that
would fix the mount.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.errors import InputError
from ...core.units import G_MPS2

AXES = "xyz"

#: Correlations (Pearson) that count as clear evidence: an axis "wins" with at least STRONG, and a
#: sign is "reversed" below -STRONG.
STRONG = 0.5
#: Turning faster than this (rad/s) at more than MIN_SPEED_MPS is what the yaw check looks at.
MIN_TURN_RADPS = np.deg2rad(3.0)
MIN_SPEED_MPS = 3.0
#: Samples of turning (or of moving) needed before a check says anything.
MIN_SAMPLES = 50
#: How the yaw-sign finding starts (a reader that was told the sign leaves it out).
YAW_REVERSED = "the gyro's z turns clockwise positive"


def parse_imu_axes(text: str) -> np.ndarray:
    """``"x=-y,y=x,z=z"`` -> the 3x3 matrix ``M`` with ``body = M @ log`` (a signed permutation,
    right-handed). Each body axis must be given once, from a different log axis."""
    hint = "give each body axis once, e.g. --imu-axes x=-y,y=x,z=z (body x is the log's -y ...)"
    matrix = np.zeros((3, 3))
    seen_body, seen_log = set(), set()
    for part in (p.strip() for p in text.split(",")):
        body, sep, source = (s.strip().lower() for s in part.partition("="))
        sign = -1.0 if source.startswith("-") else 1.0
        axis = source.lstrip("+-")
        if not sep or body not in AXES or axis not in AXES or len(source) - len(axis) > 1:
            raise InputError(f"imu axes {text!r}: {part!r} is not AXIS=[-]AXIS", hint, param="imu_axes")
        if body in seen_body or axis in seen_log:
            raise InputError(f"imu axes {text!r}: {body if body in seen_body else axis!r} is used twice", hint,
                             param="imu_axes")
        seen_body.add(body)
        seen_log.add(axis)
        matrix[AXES.index(body), AXES.index(axis)] = sign
    if len(seen_body) != 3:
        raise InputError(f"imu axes {text!r}: {', '.join(a for a in AXES if a not in seen_body)} not given", hint,
                         param="imu_axes")
    if np.linalg.det(matrix) < 0:
        raise InputError(f"imu axes {text!r} mirror the IMU (a left-handed frame)",
                         "flip the sign of one axis: a rigid mount only rotates", param="imu_axes")
    return matrix


def format_imu_axes(matrix: np.ndarray) -> str:
    """The inverse of :func:`parse_imu_axes`."""
    parts = []
    for row, body in zip(matrix, AXES):
        k = int(np.argmax(np.abs(row)))
        parts.append(f"{body}={'-' if row[k] < 0 else ''}{AXES[k]}")
    return ",".join(parts)


def heading_rate_ccw_radps(t_s: np.ndarray, heading_deg: np.ndarray, speed_mps: np.ndarray) -> np.ndarray:
    """Counter-clockwise turn rate implied by the GNSS course (rad/s), NaN below MIN_SPEED_MPS."""
    rate = -np.gradient(np.unwrap(np.deg2rad(heading_deg)), t_s)
    rate[speed_mps < MIN_SPEED_MPS] = np.nan
    return rate


def yaw_correlation(yaw_ccw_radps: np.ndarray, gnss_rate_ccw_radps: np.ndarray) -> float | None:
    """Correlation of a yaw rate with the GNSS turn rate while turning at speed (None: too little turning)."""
    turning = np.isfinite(gnss_rate_ccw_radps) & (np.abs(gnss_rate_ccw_radps) > MIN_TURN_RADPS)
    if turning.sum() < MIN_SAMPLES:
        return None
    return _corr(yaw_ccw_radps[turning], gnss_rate_ccw_radps[turning])


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    if np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])


@dataclass(frozen=True)
class FrameCheck:
    """What :func:`check_imu_frame` found: ``problems`` (empty when the frame looks right), the
    ``--imu-axes`` value that would fix the mount (None if unknown), and whether the yaw rate
    is reversed (z is the yaw axis but turns clockwise positive)."""

    problems: tuple[str, ...]
    suggestion: str | None
    yaw_reversed: bool


def check_imu_frame(t_s: np.ndarray, accel_xyz: np.ndarray, gyro_xyz: np.ndarray, speed_mps: np.ndarray,
                    heading_deg: np.ndarray, mapping: np.ndarray | None = None,
                    measured: np.ndarray | None = None) -> FrameCheck:
    """Check body-frame IMU samples (``(n, 3)`` arrays, m/s^2 and rad/s, on the times ``t_s``)
    against gravity and the GNSS speed and course (see the module docstring). ``mapping`` is the
    ``--imu-axes`` matrix already applied (the suggestion is given in the log's axes). ``measured``:
    per axis (accel x, y, z, gyro x, y, z), whether the log measures it (default all); an axis that
    does not (it reads one value throughout) is no evidence of anything and is left out."""
    problems: list[str] = []
    measured = np.ones(6, dtype=bool) if measured is None else np.asarray(measured, dtype=bool)
    accel_xyz, gyro_xyz = accel_xyz * measured[:3], gyro_xyz * measured[3:]  # a placeholder reads as nothing
    # gravity: the axis of the mean specific force at rest
    still = speed_mps < 0.3
    mean_f = accel_xyz[still].mean(axis=0) if still.sum() >= MIN_SAMPLES else accel_xyz.mean(axis=0)
    g_axis = int(np.argmax(np.abs(mean_f)))
    g_sign = 1.0 if mean_f[g_axis] > 0 else -1.0
    gravity_known = abs(mean_f[g_axis]) > 0.5 * G_MPS2
    if gravity_known and (g_axis, g_sign) != (2, 1.0):
        problems.append(f"gravity reads on {'-' if g_sign < 0 else '+'}{AXES[g_axis]} ({mean_f[g_axis]:+.1f} "
                        "m/s^2), not +z")

    # yaw: the gyro axis that follows the GNSS course
    gnss_rate = heading_rate_ccw_radps(t_s, heading_deg, speed_mps)
    yaw_corr = [yaw_correlation(gyro_xyz[:, k], gnss_rate) for k in range(3)]
    yaw_reversed = False
    yaw_axis = yaw_sign = None
    if yaw_corr[2] is not None:
        best = int(np.argmax(np.abs(yaw_corr)))
        if abs(yaw_corr[best]) >= STRONG:
            yaw_axis, yaw_sign = best, (1.0 if yaw_corr[best] > 0 else -1.0)
            if best != 2:
                problems.append(f"the turn rate is on the gyro's {AXES[best]} axis (correlation {yaw_corr[best]:+.2f} "
                                f"with the GNSS course, z {yaw_corr[2]:+.2f})")
            elif yaw_sign < 0:
                yaw_reversed = True
                problems.append(f"{YAW_REVERSED} (correlation {yaw_corr[2]:+.2f} with the GNSS course): flipped it")

    # forward: the horizontal accelerometer axis that follows the GNSS speed's derivative
    moving = speed_mps > MIN_SPEED_MPS
    fwd_axis = fwd_sign = None
    if moving.sum() >= MIN_SAMPLES and len(t_s) > 2:
        gnss_accel = _smooth(np.gradient(speed_mps, t_s))
        corr = [(_corr(_smooth(accel_xyz[:, k])[moving], gnss_accel[moving]) if k != g_axis or
                 not gravity_known else 0.0) for k in range(3)]
        best = int(np.argmax(np.abs(corr)))
        if abs(corr[best]) >= STRONG:
            fwd_axis, fwd_sign = best, (1.0 if corr[best] > 0 else -1.0)
            if (best, fwd_sign) != (0, 1.0):
                problems.append(f"forward acceleration reads on {'-' if fwd_sign < 0 else '+'}{AXES[best]} "
                                f"(correlation {corr[best]:+.2f} with the GNSS speed), not +x")

    suggestion = None
    up = (g_axis, g_sign) if gravity_known else ((yaw_axis, yaw_sign) if yaw_axis is not None else None)
    if problems and up is not None and fwd_axis is not None and fwd_axis != up[0]:
        matrix = np.zeros((3, 3))
        matrix[0, fwd_axis], matrix[2, up[0]] = fwd_sign, up[1]
        matrix[1] = np.cross(matrix[2], matrix[0])  # y = z x x: right-handed
        suggestion = format_imu_axes(matrix @ (np.eye(3) if mapping is None else mapping))
    return FrameCheck(tuple(problems), suggestion, yaw_reversed)


def _smooth(x: np.ndarray, n: int = 10) -> np.ndarray:
    return np.convolve(x, np.ones(n) / n, mode="same")
