"""The IMU's mount: the rotation from the IMU's axes to the vehicle body frame, estimated from the
log itself, given by the user, and applied at the reader.

Convention: ``body = M @ imu`` for every specific-force and angular-rate vector, ``M`` a rotation
(REP 103 body frame: x forward, y left, z up). The same matrix as ``--imu-axes`` (a signed
permutation); a mount is any rotation. It is reported as the IMU's attitude in the body frame, in
degrees, z-y-x: ``M = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (the package's one convention,
:mod:`ionav_viz.core.rotation`). So yaw +5 means the IMU's x axis points 5
degrees to the left of forward, pitch +7 that it points 7 degrees down, roll +2 that its y axis is
turned 2 degrees up (right-handed rotations about the body axes).

Estimate (:func:`estimate_mount`), from grid samples of the IMU and the GNSS speed and course:

* **up** (roll and pitch): the mean specific force over the whole drive, where the car's
  accelerations average out, is gravity: the rotation that takes it onto +z, the shortest one;
  then three times again from the mean with the estimated motion (below, turned into the IMU's
  axes) taken out;
* **yaw**: in that levelled frame, the horizontal specific force ``h`` (east of the IMU's x, say)
  follows the body's ``b = (dv/dt, v * omega)`` (forward: the speed's derivative, the wheels' speed
  where the log has one, else the GNSS's; left: speed times the turn rate, counter-clockwise, from
  the levelled gyro's vertical axis, which the yaw does not change, else the GNSS course's rate)
  turned by the yaw: ``h = exp(-i yaw) b`` as
  complex numbers, so ``yaw = -arg(sum((h - mean h) * conj(b - mean b)))`` (least squares; the
  means take out accelerometer bias and gravity left by a road's grade), over samples above 0.5 m/s
  (a slow robot counts too), both smoothed over 1 s alike;
* **uncertainty**: yaw's standard deviation from the residuals, from their sums over 30 s blocks
  (batch means: a road's camber tilts gravity into ``h`` for tens of seconds, so neighbouring
  seconds are not independent), never below ``sigma / sqrt(2 * sum |b|^2)`` of independent seconds;
  roll's and pitch's the same from the residual's lateral and forward components over gravity
  (never below 0.2 degrees), so a short drive says it knows less.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core.errors import InputError
from ...core.rotation import dcm_of_euler, dcm_of_quat, euler_of_dcm, skew
from ...core.units import G_MPS2

#: A mount further than this from the body frame (degrees, the rotation's angle) is "clearly not
#: in the body frame": the run stops and shows the estimate instead of guessing.
MAX_SILENT_DEG = 10.0
#: A mount closer than this (degrees) is left alone: gravity cannot tell so small a tilt from an
#: accelerometer bias (0.1 m/s^2 is 0.6 deg) or the road's grade where the car stood.
MIN_APPLIED_DEG = 2.0
#: Yaw uses samples above this speed (m/s), and needs this much horizontal excitation
#: (sum of |b|^2 over samples, (m/s^2)^2) to say anything.
MOVING_MPS = 0.5
MIN_EXCITATION = 20.0
#: The yaw's uncertainty counts blocks of this many seconds as independent (a road's camber and
#: grade leave errors correlated over tens of seconds; see ``_estimate``).
YAW_BLOCK_S = 30.0
#: Gravity must read between these (m/s^2) for the up axis to be trusted.
GRAVITY_RANGE_MPS2 = (0.7 * G_MPS2, 1.3 * G_MPS2)


def rotation_deg(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``M = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (degrees; :func:`ionav_viz.core.rotation.dcm_of_euler`)."""
    return dcm_of_euler(*np.radians([roll, pitch, yaw]))


def angles_deg(matrix: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees of a rotation ``M = Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
    roll, pitch, yaw = euler_of_dcm(matrix)
    return math.degrees(roll), math.degrees(pitch), math.degrees(yaw)


def rotation_angle_deg(matrix: np.ndarray) -> float:
    """How far a rotation turns, whatever the axis (degrees)."""
    return math.degrees(math.acos(float(np.clip((np.trace(matrix) - 1.0) / 2.0, -1.0, 1.0))))


def nearest_axes(matrix: np.ndarray, within_deg: float = 5.0) -> str | None:
    """The ``--imu-axes`` signed permutation within ``within_deg`` of a rotation, else None."""
    from .axes import format_imu_axes

    perm = np.zeros((3, 3))
    for row in range(3):
        k = int(np.argmax(np.abs(matrix[row])))
        perm[row, k] = np.sign(matrix[row, k])
    if sorted(np.argmax(np.abs(perm), axis=1)) != [0, 1, 2] or np.linalg.det(perm) < 0:
        return None
    return format_imu_axes(perm) if rotation_angle_deg(perm.T @ matrix) <= within_deg else None


def format_mount(matrix: np.ndarray) -> str:
    """``roll=2.0,pitch=-7.0,yaw=5.0``: what ``--imu-mount`` takes back."""
    roll, pitch, yaw = (_tenths(a) for a in angles_deg(matrix))
    return f"roll={roll:.1f},pitch={pitch:.1f},yaw={yaw:.1f}"


def _tenths(deg: float) -> float:
    """``deg`` rounded to 0.1 with no negative zero: -0.04 deg read 'roll -0.0' and 'roll=-0.0'."""
    return round(deg, 1) + 0.0


def parse_mount(text: str) -> np.ndarray | str:
    """``--imu-mount``: ``"auto"`` (returned as is), ``"roll=R,pitch=P,yaw=Y"`` (degrees, any of
    them; the others 0) or ``"quat=w,x,y,z"`` (a unit quaternion of the rotation body <- IMU)."""
    hint = "give --imu-mount auto, roll=2,pitch=-7,yaw=5 (degrees) or quat=w,x,y,z"
    text = text.strip().lower()
    if text == "auto":
        return text
    if text.startswith("quat="):
        try:
            w, x, y, z = (float(v) for v in text[5:].split(","))
        except ValueError:
            raise InputError(f"imu mount {text!r}: a quaternion is quat=w,x,y,z", hint, param="imu_mount") from None
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        if not math.isfinite(norm) or abs(norm - 1.0) > 1e-3:
            raise InputError(f"imu mount {text!r}: not a unit quaternion (norm {norm:.4g})", hint, param="imu_mount")
        return dcm_of_quat((w / norm, x / norm, y / norm, z / norm))
    angles = {"roll": 0.0, "pitch": 0.0, "yaw": 0.0}
    for part in (p.strip() for p in text.split(",")):
        name, sep, value = part.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not sep or name.strip() not in angles or not math.isfinite(number) or abs(number) > 360:
            raise InputError(f"imu mount {text!r}: {part!r} is not roll=, pitch= or yaw= degrees", hint,
                             param="imu_mount")
        angles[name.strip()] = number
    return rotation_deg(angles["roll"], angles["pitch"], angles["yaw"])


@dataclass(frozen=True)
class MountEstimate:
    """A mount estimated from a log: ``matrix`` (``body = matrix @ imu``), its angles and their
    standard deviations (degrees; NaN: not estimated), and how up and yaw were found."""

    matrix: np.ndarray
    sigma_deg: tuple[float, float, float]  # roll, pitch, yaw
    up_from: str
    yaw_known: bool

    @property
    def angles_deg(self) -> tuple[float, float, float]:
        return angles_deg(self.matrix)

    @property
    def angle_deg(self) -> float:
        return rotation_angle_deg(self.matrix)

    def describe(self) -> str:
        roll, pitch, yaw = (_tenths(a) for a in self.angles_deg)
        s_roll, s_pitch, s_yaw = self.sigma_deg
        yaw_text = f"yaw {yaw:+.1f} ± {s_yaw:.1f}" if self.yaw_known else "yaw unknown (too little motion)"
        return (f"roll {roll:+.1f} ± {s_roll:.1f}, pitch {pitch:+.1f} ± {s_pitch:.1f}, {yaw_text} deg "
                f"(up from {self.up_from})")


def _onto_z(u: np.ndarray) -> np.ndarray:
    """The shortest rotation taking the unit vector ``u`` onto +z."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(u, z)
    s, c = float(np.linalg.norm(axis)), float(u @ z)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])  # upside down: half a turn about x
    k = axis / s
    kx = skew(k)
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    return np.convolve(x, np.ones(n) / n, mode="same") if len(x) >= n else x


#: Roll and pitch are never said surer than this (degrees): an accelerometer bias of 0.03 m/s^2.
MIN_LEVEL_SIGMA_DEG = 0.2


def estimate_mount(t_s: np.ndarray, accel_xyz: np.ndarray, speed_mps: np.ndarray, course_deg: np.ndarray,
                   gyro_xyz: np.ndarray | None = None,
                   vehicle_speed_mps: np.ndarray | None = None) -> MountEstimate | None:
    """The mount from grid samples (``accel_xyz`` ``(n, 3)`` m/s^2 in the IMU's axes; GNSS speed,
    course clockwise from north), or None when gravity cannot be told (see the module docstring).

    ``gyro_xyz`` ``(n, 3)`` rad/s in the IMU's axes: the turn rate is the levelled gyro's vertical
    axis (whatever the yaw), not the GNSS course's rate, which a slow vehicle's fixes make noise;
    ``vehicle_speed_mps``: the speed (and its rate) from the wheels instead of the GNSS. Roll and
    pitch come from gravity minus the GNSS-derived acceleration, their uncertainties from the
    residuals' sums over 30 s blocks (batch means: honest on a short drive, where one grade or one
    manoeuvre can lean them). The road's grade is not taken out: from a receiver's height (metres of
    wander over tens of seconds) it made the pitch worse on simulated 2 min drives (errors 0.12-0.66
    degrees without it, 0.69-0.96 with it) and on a real 60 s dash log (3.8 to 4.2 degrees).
    """
    if len(t_s) < 3:
        return None
    mean_f = accel_xyz.mean(axis=0)
    g = float(np.linalg.norm(mean_f))
    if not GRAVITY_RANGE_MPS2[0] <= g <= GRAVITY_RANGE_MPS2[1]:
        return None
    dt = float(np.median(np.diff(t_s)))
    n_smooth = max(1, int(round(1.0 / dt)))
    speed = speed_mps if vehicle_speed_mps is None else vehicle_speed_mps
    accel_fwd = _smooth(np.gradient(speed, t_s), n_smooth)
    if gyro_xyz is not None:
        turn_ccw = (gyro_xyz @ _onto_z(mean_f / g).T)[:, 2]
    else:
        turn_ccw = -np.gradient(np.unwrap(np.radians(course_deg)), t_s)
    accel_left = _smooth(speed, n_smooth) * _smooth(turn_ccw, n_smooth)
    motion = np.column_stack([accel_fwd, accel_left, np.zeros(len(t_s))])  # the body's own acceleration
    up_from = "the mean over the drive"
    speed_mps = speed
    estimate = _estimate(accel_xyz, mean_f, motion, speed_mps, n_smooth)
    for _ in range(3):  # up again, from the mean with the motion (turned into the IMU's axes) taken out
        mean_f = (accel_xyz - motion @ estimate[0]).mean(axis=0)
        estimate = _estimate(accel_xyz, mean_f, motion, speed_mps, n_smooth)
    matrix, s_yaw, yaw_known = estimate
    s_roll, s_pitch = _level_sigmas_deg(accel_xyz, motion, matrix, g, n_smooth)
    return MountEstimate(matrix, (s_roll, s_pitch, s_yaw), up_from, yaw_known)


def _level_sigmas_deg(accel_xyz: np.ndarray, motion: np.ndarray, matrix: np.ndarray, g: float,
                      n_smooth: int) -> tuple[float, float]:
    """Roll and pitch uncertainties (degrees): the error of the mean residual's lateral and forward
    components (what is left of the body-frame specific force less the motion and gravity), from its
    sums over YAW_BLOCK_S blocks (batch means), over gravity; never below MIN_LEVEL_SIGMA_DEG."""
    residual = accel_xyz @ matrix.T - motion - np.array([0.0, 0.0, g])
    n = len(residual)
    block = np.arange(n) // max(1, n_smooth * int(YAW_BLOCK_S))
    out = []
    for axis in (1, 0):  # roll tilts gravity into y, pitch into x
        r = residual[:, axis] - residual[:, axis].mean()
        sums = np.bincount(block, weights=r)
        spread = math.sqrt(float(np.sum(sums**2))) / n
        # with few blocks the spread of the means says little: take at least one block's own scatter over its length
        if block[-1] < 2:
            spread = max(spread, float(np.std(residual[:, axis])) / math.sqrt(max(n / max(n_smooth, 1) / 10.0, 1.0)))
        out.append(max(math.degrees(math.atan2(spread, g)), MIN_LEVEL_SIGMA_DEG))
    return out[0], out[1]


def _estimate(accel_xyz: np.ndarray, mean_f: np.ndarray, motion: np.ndarray, speed_mps: np.ndarray,
              n_smooth: int) -> tuple[np.ndarray, float, bool]:
    """(matrix, yaw sigma deg, yaw known) for the up direction ``mean_f``."""
    g = float(np.linalg.norm(mean_f))
    level = _onto_z(mean_f / g)
    h = accel_xyz @ level.T  # levelled: horizontal components in h[:, :2]
    moving = speed_mps > MOVING_MPS
    hc = _smooth(h[:, 0], n_smooth) + 1j * _smooth(h[:, 1], n_smooth)
    b = motion[:, 0] + 1j * motion[:, 1]
    hc, b = hc[moving], b[moving]
    block = np.flatnonzero(moving) // (n_smooth * int(YAW_BLOCK_S))
    yaw_known = len(b) > 10
    excitation = 0.0
    if yaw_known:
        hc, b = hc - hc.mean(), b - b.mean()
        excitation = float(np.sum(np.abs(b) ** 2))
        yaw_known = excitation >= MIN_EXCITATION
    if yaw_known:
        yaw = -float(np.angle(np.sum(hc * np.conj(b))))
        residual = hc - np.exp(-1j * yaw) * b
        sigma = float(np.sqrt(np.mean(np.abs(residual) ** 2) / 2.0))
        # samples smoothed over 1 s are not independent: count one per second
        s_white = sigma / math.sqrt(2.0 * excitation / n_smooth)
        # nor are the seconds: a road's camber and grade tilt gravity into h for tens of seconds.
        # The yaw's error is -Im(exp(i yaw) sum(residual conj(b))) / excitation; its variance from
        # the sums over YAW_BLOCK_S blocks (batch means), never below the independent seconds'.
        terms = np.imag(np.exp(1j * yaw) * residual * np.conj(b))
        s_blocks = math.sqrt(float(np.sum(np.bincount(block, weights=terms) ** 2))) / excitation
        s_yaw = math.degrees(max(s_white, s_blocks))
    else:
        yaw, s_yaw = 0.0, math.nan
    rz = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    return rz @ level, s_yaw, yaw_known
