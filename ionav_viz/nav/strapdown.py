"""Strapdown mechanisation and the error-state Kalman filter behind ``gins`` (:mod:`ionav_viz.nav.gins`).

Frames and conventions
    Navigation frame ``n``: east-north-up, the tangent frame of an origin, fixed to the Earth
    (positions in metres, :func:`ionav_viz.core.geo.enu_of_geodetic`). In an Earth-fixed frame the
    mechanisation needs no transport rate: the Earth's rotation ``Omega`` turns the frame, and
    gravity (:func:`ionav_viz.core.geo.gravity_enu_mps2`) points to the Earth's centre wherever the
    vehicle is. Body frame ``b``: the drive model's x forward, y left, z up (REP 103). Attitude:
    the quaternion ``q`` of ``C_b^n`` (w, x, y, z).

Nominal state (20): ``p`` (3, m), ``v`` (3, m/s, in ``n``), ``q`` (4), gyro bias ``b_g`` (3,
rad/s), accelerometer bias ``b_a`` (3, m/s^2), the vehicle speed's scale ``k`` (its reading over
the true forward speed), the residual mount yaw and pitch ``psi_m``, ``theta_m`` (rad: how far the
vehicle's forward axis lies from the IMU's x axis after the reader's mount correction; signed as
:mod:`ionav_viz.core.rotation` has it: yaw positive where the IMU's x points left of the vehicle's
forward axis, pitch positive where it points below it) and the
gyro z scale error ``s_g`` (the gyro reads ``(1 + s_g)`` times the true rate about z).

Mechanisation, per IMU sample step ``dt`` with the trapezoid mean of the two samples' rate and
specific force (a log's samples are 10 Hz bin means: the increments of the interval)::

    omega = (w_m - b_g) with its z component / (1 + s_g)       f = f_m - b_a
    C+ = exp(-[Omega x] dt) C exp([omega x] dt)
    v+ = v + (C exp-integral(omega, dt) f - 2 Omega x v + g(p)) dt       p+ = p + (v + v+) dt / 2

with the exact integral of a constant rotation over the step (no sculling error in a steady turn).

Error state (19), estimated minus true, attitude as ``C_hat = (I - [phi x]) C`` (Shin 2005,
as KF-GINS): ``dp, dv, phi, db_g, db_a, dk, dpsi_m, dtheta_m, ds_g``. Its dynamics::

    dp' = dv      dv' = [f^n x] phi - C db_a      phi' = C db_g + C e_z omega_z ds_g

(the Earth-rate terms, 1e-4 of these over a drive's seconds, are left out), biases and the other
states are random walks. The covariance is propagated once per 1-second window with the
transition matrix's series to third order in the window's mean ``f^n`` and ``C`` (block-sparse
products: the pass must run at millions of samples a second), and the measurements come once per
window boundary, as scalar updates, their corrections fed back into the nominal state:

* GNSS position (the receiver's sigma; height at twice it; a component 5 sigma off the
  prediction is a jump and is left out, GNSS_GATE), and GNSS horizontal velocity from 1 m/s
  (below it the course is held);
* non-holonomic constraint: the vehicle frame's lateral and vertical velocity are zero, with
  noise for slip and road roughness; the residual mount angles turn body into vehicle frame;
* odometer: the vehicle speed reads ``k`` times the forward velocity;
* zero velocity where the IMU says the vehicle stands (:mod:`ionav_viz.nav.stillness`) and the
  filter's velocity agrees (a chi-square gate, ZUPT_GATE): velocity zero, and the mean gyro over
  the last second (the window's samples, at any rate) is its bias plus the Earth's rate (ZARU).

Noise values are :class:`GinsNoise`; the sensors' white noise is measured on the drive itself.

What follows KF-GINS (i2Nav-WHU, ``src/kf-gins/gi_engine.cpp``) and where it differs: the same
phi-angle error model and F blocks (``insPropagation``: ``F_v,phi = [(C f) x]``, ``F_v,ba = C``,
``F_phi,bg = -C``: its bias errors are true minus estimated, ours estimated minus true, hence our
signs; its position, velocity and attitude errors are ours, ``stateFeedback``), the GNSS update
with the receiver's standard deviations as R (``gnssUpdate``) and the feedback of the error state
into the nominal one after each update. KF-GINS propagates ``Phi = I + F dt`` per IMU sample with
Gauss-Markov biases (``corrtime``, hours) and a lever arm; we propagate once per window (a third-
order series, for speed), take the biases as random walks (the same over an outage's seconds) and
have no lever arm (logs rarely carry it; its error is the arm times the attitude error, centimetres).
KF-GINS has no vehicle constraints. Its sibling OB_GINS (i2Nav-WHU, a sliding-window
optimiser over 30 s of pre-integrated IMU) adds them as we do: the odometer and the non-holonomic
constraint are one measurement of the vehicle-frame velocity ``(v_odo, 0, 0)`` with a standard
deviation per axis (``odometer.std``, 0.05 m/s; ``preintegration_odo.cc``), the IMU turned into
the vehicle frame by mounting angles (``bodyangle``, fixed there, estimated residuals here) and the
odometer's scale error estimated as a state (``sodo``, a random walk of ``srw`` ppm). It integrates
the odometer's distance between epochs; we take the velocity at each window boundary. pyins
(nmayorov, ``filters.run_feedback_filter``) propagates the covariance over batches of increments
(``time_step``, "should not exceed 1 second") from the batch's mean state and rates, the
trade-off we make with our 1 s windows, and takes odometry or NHC as a ``BodyVelocity``
measurement, as above. Neither has a zero-velocity detector: ours is :mod:`ionav_viz.nav.stillness`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..core import rotation

#: A GNSS position component further than this many variances (a chi-square, 1 degree of freedom:
#: 5 sigma) from the filter's prediction is a jump, not a fix (receivers jump by metres when they
#: come back after losing the sky), and is not used.
GNSS_GATE = 25.0
#: After this many boundaries in a row whose fix was left out, the next is used whatever it says.
GNSS_REJECTS_MAX = 5
#: A zero-velocity update is used only when the filter's velocity is within this chi-square
#: (3 degrees of freedom, p = 0.001) of zero: the detector can be wrong, the update must not be.
ZUPT_GATE = 16.27
# nominal state layout
PX, VX, QW, BGX, BAX, KO, PSIM, THM, SG = 0, 3, 6, 10, 13, 16, 17, 18, 19
N_NOMINAL = 20
# error state layout
DP, DV, PHI, DBG, DBA, DK, DPSIM, DTHM, DSG = 0, 3, 6, 9, 12, 15, 16, 17, 18
N_ERR = 19


@dataclass(frozen=True)
class GinsNoise:
    """The filter's noise (1 sigma; random walks per sqrt(s)).

    ``*_white_floor``: lower bounds on the sensors' white noise measured on the drive (per 10 Hz
    sample). Constraint noise follows KF-GINS/OB_GINS practice: a few cm/s to 0.1 m/s.
    """

    accel_white_floor_mps2: float = 0.02
    gyro_white_floor_radps: float = np.deg2rad(0.01)
    gyro_bias_walk_radps: float = np.deg2rad(0.002)
    accel_bias_walk_mps2: float = 0.005
    scale_walk: float = 1e-5
    mount_walk_rad: float = 1e-5
    gyro_scale_walk: float = 1e-5
    gnss_position_m: float = 1.0
    gnss_velocity_mps: float = 0.3
    #: where the speed and course are fitted to the fixes (no receiver velocity; Drive.speed_fitted)
    gnss_fitted_velocity_mps: float = 2.0
    nhc_lateral_mps: float = 0.1
    nhc_vertical_mps: float = 0.1
    odometer_mps: float = 0.1
    zupt_mps: float = 0.02
    init_velocity_mps: float = 0.5
    init_level_rad: float = np.deg2rad(2.0)
    init_heading_rad: float = np.deg2rad(15.0)
    init_gyro_bias_radps: float = np.deg2rad(0.5)
    init_accel_bias_mps2: float = 0.3
    init_scale: float = 0.05
    init_mount_rad: float = np.deg2rad(2.0)
    init_gyro_scale: float = 0.02

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Random-walk densities per error state (variance per second, (19,)) for the states
        that are not driven by the sensors' white noise, and the initial standard deviations (19,)."""
        walk = np.zeros(N_ERR)
        walk[DBG:DBG + 3] = self.gyro_bias_walk_radps**2
        walk[DBA:DBA + 3] = self.accel_bias_walk_mps2**2
        walk[DK] = self.scale_walk**2
        walk[DPSIM] = walk[DTHM] = self.mount_walk_rad**2
        walk[DSG] = self.gyro_scale_walk**2
        init = np.zeros(N_ERR)
        init[DP:DP + 3] = self.gnss_position_m
        init[DV:DV + 3] = self.init_velocity_mps
        init[PHI:PHI + 2] = self.init_level_rad
        init[PHI + 2] = self.init_heading_rad
        init[DBG:DBG + 3] = self.init_gyro_bias_radps
        init[DBA:DBA + 3] = self.init_accel_bias_mps2
        init[DK] = self.init_scale
        init[DPSIM] = init[DTHM] = self.init_mount_rad
        init[DSG] = self.init_gyro_scale
        return walk, init


# ---------------------------------------------------------------------------------------------
# the rotation helpers of :mod:`ionav_viz.core.rotation`, compiled

_quat_mul = njit(cache=True)(rotation.quat_mul)
_quat_of_rotvec = njit(cache=True)(rotation.quat_of_rotvec)
_dcm = njit(cache=True)(rotation.dcm_of_quat)
_skew = njit(cache=True)(rotation.skew)


@njit(cache=True)
def _mechanise(x, acc0, acc1, gyr0, gyr1, dt, omega_ie, g0, radius, out):  # pragma: no cover - compiled
    """One step of ``dt`` (s) in place on the nominal state ``x``; returns the horizontal distance
    (m) and writes the step's mean specific force in ``n`` (m/s^2) and corrected z rate (rad/s) into
    ``out`` (4,). Scalar code: the pass over a drive allocates nothing per sample."""
    wx = 0.5 * (gyr0[0] + gyr1[0]) - x[BGX]
    wy = 0.5 * (gyr0[1] + gyr1[1]) - x[BGX + 1]
    wz = (0.5 * (gyr0[2] + gyr1[2]) - x[BGX + 2]) / (1.0 + x[SG])
    fx = 0.5 * (acc0[0] + acc1[0]) - x[BAX]
    fy = 0.5 * (acc0[1] + acc1[1]) - x[BAX + 1]
    fz = 0.5 * (acc0[2] + acc1[2]) - x[BAX + 2]
    # the specific force of a steady rotation, integrated over the step (body frame)
    cx, cy, cz = wy * fz - wz * fy, wz * fx - wx * fz, wx * fy - wy * fx  # w x f
    ccx, ccy, ccz = wy * cz - wz * cy, wz * cx - wx * cz, wx * cy - wy * cx  # w x (w x f)
    a2 = wx * wx + wy * wy + wz * wz
    th = math.sqrt(a2) * dt
    if th < 1e-4:
        c1, c2 = 0.5 * dt * dt, dt**3 / 6.0
    else:
        c1, c2 = (1.0 - math.cos(th)) / a2, (dt - math.sin(th) / math.sqrt(a2)) / a2
    bx, by, bz = dt * fx + c1 * cx + c2 * ccx, dt * fy + c1 * cy + c2 * ccy, dt * fz + c1 * cz + c2 * ccz
    qw, qx, qy, qz = x[QW], x[QW + 1], x[QW + 2], x[QW + 3]
    # dv_n = C(q) dv_b
    nx = (1 - 2 * (qy * qy + qz * qz)) * bx + 2 * (qx * qy - qw * qz) * by + 2 * (qx * qz + qw * qy) * bz
    ny = 2 * (qx * qy + qw * qz) * bx + (1 - 2 * (qx * qx + qz * qz)) * by + 2 * (qy * qz - qw * qx) * bz
    nz = 2 * (qx * qz - qw * qy) * bx + 2 * (qy * qz + qw * qx) * by + (1 - 2 * (qx * qx + qy * qy)) * bz
    ox, oy, oz = omega_ie[0], omega_ie[1], omega_ie[2]
    # the frame turns with the Earth during the step: the middle of it
    nx, ny, nz = nx - 0.5 * dt * (oy * nz - oz * ny), ny - 0.5 * dt * (oz * nx - ox * nz), nz - 0.5 * dt * (ox * ny - oy * nx)
    vx, vy, vz = x[VX], x[VX + 1], x[VX + 2]
    # gravity towards the Earth's centre, and the Coriolis acceleration
    rx, ry, rz = x[PX], x[PX + 1], x[PX + 2] + radius
    rn = math.sqrt(rx * rx + ry * ry + rz * rz)
    gx, gy, gz = -g0 * rx / rn, -g0 * ry / rn, -g0 * rz / rn
    kx, ky, kz = 2 * (oy * vz - oz * vy), 2 * (oz * vx - ox * vz), 2 * (ox * vy - oy * vx)
    ux, uy, uz = vx + nx + (gx - kx) * dt, vy + ny + (gy - ky) * dt, vz + nz + (gz - kz) * dt
    x[PX] += 0.5 * (vx + ux) * dt
    x[PX + 1] += 0.5 * (vy + uy) * dt
    x[PX + 2] += 0.5 * (vz + uz) * dt
    x[VX], x[VX + 1], x[VX + 2] = ux, uy, uz
    # q <- q_earth(-Omega dt) q q_body(w dt)
    h = 0.5 * th
    s = 0.5 * dt if th < 1e-12 else math.sin(h) / math.sqrt(a2)
    pw, px, py, pz = math.cos(h), s * wx, s * wy, s * wz
    aw = qw * pw - qx * px - qy * py - qz * pz
    ax = qw * px + qx * pw + qy * pz - qz * py
    ay = qw * py - qx * pz + qy * pw + qz * px
    az = qw * pz + qx * py - qy * px + qz * pw
    ew, ex, ey, ez = 1.0, -0.5 * dt * ox, -0.5 * dt * oy, -0.5 * dt * oz
    qw = ew * aw - ex * ax - ey * ay - ez * az
    qx = ew * ax + ex * aw + ey * az - ez * ay
    qy = ew * ay - ex * az + ey * aw + ez * ax
    qz = ew * az + ex * ay - ey * ax + ez * aw
    qn = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    x[QW], x[QW + 1], x[QW + 2], x[QW + 3] = qw / qn, qx / qn, qy / qn, qz / qn
    out[0], out[1], out[2], out[3] = nx / dt, ny / dt, nz / dt, wz
    return 0.5 * (math.sqrt(vx * vx + vy * vy) + math.sqrt(ux * ux + uy * uy)) * dt


# ---------------------------------------------------------------------------------------------
# the error-state filter (compiled)


# Plain loops for the 3 x 3 products: numba's ``@`` needs SciPy's BLAS, which is not a dependency.


@njit(cache=True)
def _mul3(A, B):  # pragma: no cover - compiled
    out = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]
    return out


@njit(cache=True)
def _tmul3(A, v):  # pragma: no cover - compiled
    """``A^T v`` for a 3 x 3 ``A`` and a 3-vector ``v``."""
    return np.array([A[0, 0] * v[0] + A[1, 0] * v[1] + A[2, 0] * v[2], A[0, 1] * v[0] + A[1, 1] * v[1] + A[2, 1] * v[2],
                     A[0, 2] * v[0] + A[1, 2] * v[1] + A[2, 2] * v[2]])


@njit(cache=True)
def _body_velocity_jacobian(C, v):  # pragma: no cover - compiled
    """``-C^T [v x]``: how the body-frame velocity ``C^T v`` moves with the attitude error ``phi``."""
    X = _skew(v)
    M = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            M[i, j] = -(C[0, i] * X[0, j] + C[1, i] * X[1, j] + C[2, i] * X[2, j])
    return M


@njit(cache=True)
def _transition(C, fn, wz, T, D):  # pragma: no cover - compiled
    """``Phi - I`` for a window of ``T`` s into ``D`` (every entry it has is written; the rest stay
    zero): the series of ``exp(F T)`` to third order, whose only blocks are these (rows dp, dv,
    phi; columns dv, phi, db_g, db_a, ds_g)."""
    Fx = _skew(fn)
    FxC = _mul3(Fx, C)
    cz = C[:, 2] * wz
    Fxcz = np.cross(fn, cz)
    for i in range(3):
        D[DP + i, DV + i] = T
        D[DP + i, DSG] = T**3 / 6.0 * Fxcz[i]
        D[DV + i, DSG] = 0.5 * T * T * Fxcz[i]
        D[PHI + i, DSG] = T * cz[i]
        for j in range(3):
            D[DP + i, PHI + j] = 0.5 * T * T * Fx[i, j]
            D[DP + i, DBA + j] = -0.5 * T * T * C[i, j]
            D[DP + i, DBG + j] = T**3 / 6.0 * FxC[i, j]
            D[DV + i, PHI + j] = T * Fx[i, j]
            D[DV + i, DBA + j] = -T * C[i, j]
            D[DV + i, DBG + j] = 0.5 * T * T * FxC[i, j]
            D[PHI + i, DBG + j] = T * C[i, j]


@njit(cache=True)
def _propagate_covariance(P, D, q_diag, q_pv, A, B):  # pragma: no cover - compiled
    """``P <- Phi P Phi^T + Q`` in place, ``Phi = I + D`` with D's sparse structure: only the rows of
    dp, dv and phi (< 9) have entries, in the columns dv .. db_a (3 .. 14) and ds_g (``A``, ``B``: scratch)."""
    A[:, :] = P  # A = Phi P
    for i in range(9):
        for j in range(N_ERR):
            acc = D[i, DSG] * P[DSG, j]
            for c in range(DV, DBA + 3):
                acc += D[i, c] * P[c, j]
            A[i, j] += acc
    B[:, :] = A  # B = A Phi^T: only its columns < 9 change
    for i in range(N_ERR):
        for j in range(9):
            acc = A[i, DSG] * D[j, DSG]
            for c in range(DV, DBA + 3):
                acc += A[i, c] * D[j, c]
            B[i, j] += acc
    for i in range(N_ERR):
        for j in range(i + 1):
            P[i, j] = P[j, i] = 0.5 * (B[i, j] + B[j, i])
        P[i, i] += q_diag[i]
    for i in range(3):
        P[DP + i, DV + i] += q_pv
        P[DV + i, DP + i] += q_pv


@njit(cache=True)
def _subtract_outer(P, PH, S):  # pragma: no cover - compiled
    """``P <- P - PH PH^T / S`` row by row (contiguous; the product is symmetric, and the next
    propagation symmetrises what rounding leaves)."""
    n = P.shape[0]
    for i in range(n):
        k = PH[i] / S
        for j in range(n):
            P[i, j] -= k * PH[j]


@njit(cache=True)
def _scalar_update(P, dx, H, cols, dz, r):  # pragma: no cover - compiled
    """A scalar measurement ``dz = H dx + noise`` (variance ``r``; H's nonzeros at ``cols``) folded
    into the error estimate ``dx`` and covariance ``P`` in place (the standard form, kept symmetric)."""
    n = P.shape[0]
    PH = np.zeros(n)
    for i in range(n):
        acc = 0.0
        for k in range(len(cols)):
            acc += P[i, cols[k]] * H[k]
        PH[i] = acc
    S = r
    pred = 0.0
    for k in range(len(cols)):
        S += H[k] * PH[cols[k]]
        pred += H[k] * dx[cols[k]]
    if S <= 0.0:
        return
    innov = dz - pred
    for i in range(n):
        dx[i] += PH[i] / S * innov
    _subtract_outer(P, PH, S)


@njit(cache=True)
def _unit_update(P, dx, col, dz, r, gate=np.inf):  # pragma: no cover - compiled
    """:func:`_scalar_update` for ``dz = dx[col] + noise`` (a state measured directly); a
    measurement whose innovation is more than ``sqrt(gate)`` of its standard deviations away is
    not used. Returns whether it was."""
    n = P.shape[0]
    S = P[col, col] + r
    if S <= 0.0:
        return False
    innov = dz - dx[col]
    if innov * innov > gate * S:
        return False
    PH = P[:, col].copy()
    for i in range(n):
        dx[i] += PH[i] / S * innov
    _subtract_outer(P, PH, S)
    return True


@njit(cache=True)
def _correct(x, dx):  # pragma: no cover - compiled
    """Feed the estimated errors back into the nominal state (``dx`` estimated minus true)."""
    for i in range(3):
        x[PX + i] -= dx[DP + i]
        x[VX + i] -= dx[DV + i]
        x[BGX + i] -= dx[DBG + i]
        x[BAX + i] -= dx[DBA + i]
    x[KO] -= dx[DK]
    x[PSIM] -= dx[DPSIM]
    x[THM] -= dx[DTHM]
    x[SG] -= dx[DSG]
    # C = (I + [phi x]) C_hat: the quaternion of the small rotation phi, on the left
    q = _quat_mul(_quat_of_rotvec(dx[PHI:PHI + 3]), x[QW:QW + 4].copy())
    x[QW:QW + 4] = q / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    dx[:] = 0.0


@njit(cache=True)
def _body_velocity_row(C, M, row, scale, extra_col, extra_h, cols, H):  # pragma: no cover - compiled
    """The row of H (its 7 nonzeros ``H`` at ``cols``) of a measurement of ``scale * (C^T v)[row] +
    extra_h * state[extra_col]`` (``M = -C^T [v x]``: the body-frame velocity's attitude Jacobian)."""
    for j in range(3):
        cols[j] = DV + j
        H[j] = scale * C[j, row]
        cols[3 + j] = PHI + j
        H[3 + j] = scale * M[row, j]
    cols[6] = extra_col
    H[6] = extra_h


@njit(cache=True)
def _body_velocity_update(C, vb, M, dx, P, row, scale, dz, r, extra_col, extra_h, cols, H):  # pragma: no cover - compiled
    """A measurement of ``scale * (C^T v)[row] + extra_h * state[extra_col]`` (the body-frame velocity
    ``vb = C^T v``, ``M = -C^T [v x]`` its attitude Jacobian); ``dz``: prediction minus measurement.
    ``cols``/``H``: scratch of 7."""
    _body_velocity_row(C, M, row, scale, extra_col, extra_h, cols, H)
    _scalar_update(P, dx, H, cols, dz, r)


@njit(cache=True)
def _vehicle_velocity_rows(x, vb):  # pragma: no cover - compiled
    """The NHC's two measurements and the odometer's, each ``(body axis, scale, prediction, extra
    state, its H)`` for :func:`_body_velocity_update`: the vehicle frame's lateral ``vb_y + psi_m
    vb_x`` and vertical ``vb_z - theta_m vb_x`` velocity (both measured zero), and the odometer's
    ``k vb_x`` (``vb = C^T v``)."""
    return ((1, 1.0, vb[1] + x[PSIM] * vb[0], DPSIM, vb[0]),
            (2, 1.0, vb[2] - x[THM] * vb[0], DTHM, -vb[0]),
            (0, x[KO], x[KO] * vb[0], DK, vb[0]))


@njit(cache=True)
def _constraints(x, P, dx, nhc, r_lat, r_vert, odo, r_odo, still, r_zupt, gyro_mean, r_zaru, omega_ie):  # pragma: no cover - compiled
    """The vehicle's constraints at a window boundary: NHC, odometer, and ZUPT/ZARU when still."""
    C = _dcm(x[QW:QW + 4])
    # the detector's "still" is checked against the filter's own velocity: a ZUPT more than
    # ZUPT_GATE (chi-square, 3 dof, p = 0.001) away from it is a false detection, not a stop
    gate = 0.0
    for i in range(3):
        gate += x[VX + i] ** 2 / (P[DV + i, DV + i] + r_zupt)
    if still and gate < ZUPT_GATE:
        for i in range(3):
            _unit_update(P, dx, DV + i, x[VX + i], r_zupt)
        earth_b = _tmul3(C, omega_ie)
        for i in range(3):
            _unit_update(P, dx, DBG + i, x[BGX + i] + earth_b[i] - gyro_mean[i], r_zaru)
        return
    v = x[VX:VX + 3]
    vb = _tmul3(C, v)
    M = _body_velocity_jacobian(C, v)
    cols, H = np.empty(7, dtype=np.int64), np.empty(7)
    lat, vert, fwd = _vehicle_velocity_rows(x, vb)
    if nhc:
        # the vehicle frame's lateral and vertical velocity are zero
        _body_velocity_update(C, vb, M, dx, P, lat[0], lat[1], lat[2], r_lat, lat[3], lat[4], cols, H)
        _body_velocity_update(C, vb, M, dx, P, vert[0], vert[1], vert[2], r_vert, vert[3], vert[4], cols, H)
    if not math.isnan(odo):
        # the odometer reads k times the forward velocity
        _body_velocity_update(C, vb, M, dx, P, fwd[0], fwd[1], fwd[2] - odo, r_odo, fwd[3], fwd[4], cols, H)


@njit(cache=True)
def _gnss(x, P, dx, pos, sigma, has_height, vel, vel_ok, r_vel, gate):  # pragma: no cover - compiled
    """The GNSS updates of one boundary; returns whether its horizontal position was used."""
    used = True
    for i in range(3 if has_height else 2):
        s = sigma if i < 2 else 2.0 * sigma
        ok = _unit_update(P, dx, DP + i, x[PX + i] - pos[i], s * s, gate)
        used = used and (ok or i == 2)
    if vel_ok and used:
        for i in range(2):
            _unit_update(P, dx, DV + i, x[VX + i] - vel[i], r_vel)
    return used


@njit(cache=True)
def run_filter(t, acc, gyr, b_sample, b_start, gnss_ok, gnss_pos, gnss_sigma, has_height, gnss_vel, vel_ok, odo, still,
               x0, P0, q_white_v, q_white_phi, walk, r_vel, r_lat, r_vert, r_odo, r_zupt, r_zaru, omega_ie, g0, radius,
               use_gnss, use_nhc, use_odo, use_zupt, b_first, b_last, xs, Ps, pos_out, turn_out, dist_out):  # pragma: no cover - compiled
    """Run from boundary ``b_first`` to ``b_last`` (inclusive) from the state ``x0, P0`` at
    ``b_first``'s sample, updating at every boundary after the first; stores the state after each
    boundary's updates (``xs``/``Ps``, when non-empty), and per boundary the position (m), the turn
    since ``b_first`` (rad, counter-clockwise: the corrected gyro integrated, so a window's yaw rate
    is a rate, not the updates' corrections of the heading) and the distance since ``b_first`` (m).

    ``b_start[b]``: boundary ``b`` starts a segment (the state restarts from GNSS there)."""
    x = x0.copy()
    P = P0.copy()
    dx = np.zeros(N_ERR)
    store = xs.shape[0] > 0
    q_diag = np.zeros(N_ERR)
    step, fsum, gm = np.zeros(4), np.zeros(3), np.zeros(3)
    scratch_a, scratch_b, D = np.zeros((N_ERR, N_ERR)), np.zeros((N_ERR, N_ERR)), np.zeros((N_ERR, N_ERR))
    dist = 0.0
    turn = 0.0
    rejected = 0
    j = b_sample[b_first]
    for b in range(b_first, b_last + 1):
        jb = b_sample[b]
        if b > b_first and b_start[b]:  # a new segment: position and velocity from GNSS again
            for i in range(3):
                x[PX + i] = gnss_pos[b, i] if (i < 2 or has_height) else x[PX + i]
            x[VX] = gnss_vel[b, 0]
            x[VX + 1] = gnss_vel[b, 1]
            x[VX + 2] = 0.0
            for i in range(6):
                for k in range(N_ERR):
                    P[i, k] = P[k, i] = 0.0
            for i in range(6):
                P[i, i] = P0[i, i]
            j = jb
        elif b > b_first:
            T = 0.0
            fsum[:] = 0.0
            wz = 0.0
            C0 = _dcm(x[QW:QW + 4])
            while j < jb:
                dt = t[j + 1] - t[j]
                dist += _mechanise(x, acc[j], acc[j + 1], gyr[j], gyr[j + 1], dt, omega_ie, g0, radius, step)
                turn += (step[3] - omega_ie[2]) * dt  # the turn against the Earth, about the body's z
                for i in range(3):
                    fsum[i] += step[i] * dt
                wz += step[3] * dt
                T += dt
                j += 1
            if T > 0.0:
                Cm = 0.5 * (C0 + _dcm(x[QW:QW + 4]))
                _transition(Cm, fsum / T, wz / T, T, D)
                for i in range(3):
                    q_diag[DV + i] = q_white_v * T
                    q_diag[PHI + i] = q_white_phi * T
                    q_diag[DP + i] = q_white_v * T**3 / 3.0
                for i in range(9, N_ERR):
                    q_diag[i] = walk[i] * T
                _propagate_covariance(P, D, q_diag, q_white_v * T * T / 2.0, scratch_a, scratch_b)
            # the mean gyro reading over the last window (its WINDOW_S second at any rate, both ends), for the zero-rate update
            gm[:] = 0.0
            k0 = b_sample[b - 1]
            for k in range(k0, jb + 1):
                gm += gyr[k]
            gm /= jb + 1 - k0
            if use_gnss and gnss_ok[b]:
                # after GNSS_REJECTS_MAX fixes in a row left out, the filter is the one that is off: take the next
                if _gnss(x, P, dx, gnss_pos[b], gnss_sigma[b], has_height, gnss_vel[b], vel_ok[b], r_vel,
                         GNSS_GATE if rejected < GNSS_REJECTS_MAX else np.inf):
                    rejected = 0
                else:
                    rejected += 1
            _constraints(x, P, dx, use_nhc, r_lat, r_vert, odo[b] if use_odo else np.nan, r_odo, use_zupt and still[b], r_zupt, gm,
                         r_zaru / max(jb + 1 - k0, 1), omega_ie)
            _correct(x, dx)
        if store:
            xs[b] = x
            Ps[b] = P
        for i in range(3):
            pos_out[b, i] = x[PX + i]
        turn_out[b] = turn
        dist_out[b] = dist
    return x, P


@njit(cache=True)
def _propagate_all(t, acc, gyr, x0, omega_ie, g0, radius):  # pragma: no cover - compiled
    n = len(t)
    out = np.zeros((n, N_NOMINAL))
    step = np.zeros(4)
    x = x0.copy()
    out[0] = x
    for j in range(n - 1):
        _mechanise(x, acc[j], acc[j + 1], gyr[j], gyr[j + 1], t[j + 1] - t[j], omega_ie, g0, radius, step)
        out[j + 1] = x
    return out


def propagate(t_s: np.ndarray, accel_mps2: np.ndarray, gyro_radps: np.ndarray, x0: np.ndarray, lat0_deg: float, height0_m: float = 0.0) -> np.ndarray:
    """The mechanisation alone (no filter): the nominal state (see the module docstring) at every
    sample ``(n, 20)`` from ``x0`` at the first, given body-frame specific force (m/s^2) and angular
    rate (rad/s) samples ``(n, 3)``, in the tangent frame of an origin at ``lat0_deg``, ``height0_m``."""
    from ..core.geo import EARTH_MEAN_RADIUS_M, earth_rate_enu_radps, normal_gravity_mps2

    return _propagate_all(np.ascontiguousarray(t_s, dtype=float), np.ascontiguousarray(accel_mps2, dtype=float),
                          np.ascontiguousarray(gyro_radps, dtype=float), np.asarray(x0, dtype=float), earth_rate_enu_radps(lat0_deg),
                          normal_gravity_mps2(lat0_deg, height0_m), EARTH_MEAN_RADIUS_M)


def transition_matrix(C: np.ndarray, fn_mps2: np.ndarray, wz_radps: float, T_s: float) -> np.ndarray:
    """The error state's transition matrix ``Phi`` (19 x 19) over a window of ``T_s`` s, as the filter
    propagates its covariance: the window's mean attitude ``C`` (``C_b^n``), mean specific force in
    ``n`` (m/s^2) and corrected z rate (rad/s); see the module docstring."""
    D = np.zeros((N_ERR, N_ERR))
    _transition(np.ascontiguousarray(C, dtype=float), np.asarray(fn_mps2, dtype=float), float(wz_radps), float(T_s), D)
    return np.eye(N_ERR) + D


def vehicle_velocity_model(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The NHC's lateral and vertical measurements and the odometer's, as the filter predicts them
    from the nominal state ``x`` (20,) (``(3,)``: vehicle-frame lateral and vertical velocity, m/s;
    ``k`` times the forward velocity) and their rows of H over the error state ``(3, 19)``."""
    x = np.asarray(x, dtype=float)
    C = _dcm(x[QW:QW + 4])
    v = np.ascontiguousarray(x[VX:VX + 3])
    vb, M = _tmul3(C, v), _body_velocity_jacobian(C, v)
    cols, row_h = np.empty(7, dtype=np.int64), np.empty(7)
    z, H = np.zeros(3), np.zeros((3, N_ERR))
    for i, (axis, scale, predicted, extra_col, extra_h) in enumerate(_vehicle_velocity_rows(x, vb)):
        _body_velocity_row(C, M, axis, scale, extra_col, extra_h, cols, row_h)
        z[i] = predicted
        H[i, cols] = row_h
    return z, H
