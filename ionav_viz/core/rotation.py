"""Rotations: quaternions, direction cosine matrices, the skew matrix and Euler angles, in one place.

Conventions (one for the whole package):

* Frames are right-handed; the body frame is REP 103's (x forward, y left, z up), the navigation
  frame east-north-up.
* A quaternion is ``(w, x, y, z)``, Hamilton's product, and stands for the rotation matrix
  ``C = dcm_of_quat(q)`` that takes a vector's coordinates in the rotated frame into the reference
  frame (``v_ref = C v_rot``; e.g. ``C_b^n`` for the attitude, ``body = M imu`` for a mount).
* Euler angles are z-y-x: ``C = Rz(yaw) Ry(pitch) Rx(roll)``, each a right-handed rotation about
  the named axis (REP 103: "by the right hand rule"). With y to the left that makes **pitch
  positive nose-down**: ``Ry(pitch)`` takes x forward to ``(cos pitch, 0, -sin pitch)``. Roll is
  positive right side down (y turned up), yaw positive counter-clockwise seen from above.
  Whoever shows a pitch in another sense converts where it is shown (none does today: the
  ``--imu-mount`` angles and ``gins``'s mount residuals are in this one).

The scalar functions (:func:`quat_mul`, :func:`quat_of_rotvec`, :func:`dcm_of_quat`,
:func:`skew`) are plain Python on NumPy arrays that numba can compile: the navigation kernels
compile them with ``njit`` (:mod:`ionav_viz.nav.strapdown`), so this module imports no numba and a
reader that needs a rotation does not pay for it.
"""

from __future__ import annotations

import math

import numpy as np


def quat_mul(a, b):
    """The Hamilton product ``a b`` of quaternions (w, x, y, z)."""
    return np.array([a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                     a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                     a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                     a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]])


def quat_of_rotvec(r):
    """The unit quaternion of the rotation vector ``r`` (rad: the axis times the angle)."""
    angle = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    if angle < 1e-12:
        return np.array([1.0, 0.5 * r[0], 0.5 * r[1], 0.5 * r[2]])
    s = math.sin(0.5 * angle) / angle
    return np.array([math.cos(0.5 * angle), s * r[0], s * r[1], s * r[2]])


def dcm_of_quat(q):
    """The rotation matrix (3 x 3) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def skew(a):
    """The cross-product matrix ``[a x]`` (3 x 3): ``skew(a) @ b == cross(a, b)``."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def dcm_of_euler(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (rad; the module's convention: pitch positive nose-down)."""
    rx = np.array([[1, 0, 0], [0, math.cos(roll), -math.sin(roll)], [0, math.sin(roll), math.cos(roll)]])
    ry = np.array([[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0], [-math.sin(pitch), 0, math.cos(pitch)]])
    rz = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])
    return rz @ ry @ rx


def dcm_of_euler_series(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """:func:`dcm_of_euler` of each sample of three equally long arrays (rad): ``(n, 3, 3)``."""
    return axis_rotations(2, yaw) @ axis_rotations(1, pitch) @ axis_rotations(0, roll)


def axis_rotations(axis: int, angle: np.ndarray) -> np.ndarray:
    """Right-handed rotation matrices ``(n, 3, 3)`` about a frame axis (0 x, 1 y, 2 z) by each
    ``angle`` (rad): ``Rx``, ``Ry`` and ``Rz`` of :func:`dcm_of_euler`."""
    c, s = np.cos(angle), np.sin(angle)
    m = np.zeros((len(angle), 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[:, axis, axis] = 1.0
    m[:, i, i] = c
    m[:, j, j] = c
    m[:, i, j] = -s
    m[:, j, i] = s
    return m


def euler_of_dcm(matrix: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in rad of a rotation ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``: the inverse of
    :func:`dcm_of_euler` (pitch within +-90 degrees)."""
    pitch = -math.asin(float(np.clip(matrix[2, 0], -1.0, 1.0)))
    roll = math.atan2(matrix[2, 1], matrix[2, 2])
    yaw = math.atan2(matrix[1, 0], matrix[0, 0])
    return roll, pitch, yaw


def quat_of_euler(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """The quaternion (w, x, y, z) of ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (rad), as the product of the
    three axis quaternions."""
    qz = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    qy = np.array([np.cos(pitch / 2), 0.0, np.sin(pitch / 2), 0.0])
    qx = np.array([np.cos(roll / 2), np.sin(roll / 2), 0.0, 0.0])
    return quat_mul(quat_mul(qz, qy), qx)
