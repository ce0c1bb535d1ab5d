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
  filter's velocity agrees (a chi-square gate, ZUPT_GATE): velocity zero, the mean gyro over
  the last second (the window's samples, at any rate) is its bias plus the Earth's rate (ZARU),
  and the mean specific force's forward and lateral components are gravity's reaction through the
  attitude plus the accelerometer's bias (the level: standing, the accelerometer measures roll and
  pitch with the bias directly, where the ZUPT sees them only through the velocity they integrate
  to; at the stop after hard braking the ZUPT alone left the filter's forward offset 0.2 m/s² off
  what the standing accelerometer read, and the outage that began there ran on it).

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
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from ..core import jit, rotation
from ..core.geo import EARTH_MEAN_RADIUS_M, earth_rate_enu_radps, normal_gravity_mps2
from . import kalman

jit.watch(__name__)  # say a first run's compilation (core/jit.py)

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

#: The measurement slots of the filter's update log (:class:`ionav_viz.nav.kalman.UpdateLog`), in
#: their units: GNSS position (m), GNSS velocity (m/s), ZUPT (m/s), ZARU (rad/s), NHC (m/s), odometer (m/s),
#: level (m/s^2).
#: The last slot is no measurement but the safeguard: a re-initialisation from GNSS (its
#: "innovation" the horizontal distance from the filter's position to the fix, m).
GINS_MEASUREMENTS = ("gnss_east", "gnss_north", "gnss_up", "gnss_velocity_east", "gnss_velocity_north", "zupt_east",
                     "zupt_north", "zupt_up", "zaru_x", "zaru_y", "zaru_z", "nhc_lateral", "nhc_vertical", "odometer",
                     "level_x", "level_y", "reinitialised")
(SLOT_GNSS_POS, SLOT_GNSS_VEL, SLOT_ZUPT, SLOT_ZARU, SLOT_NHC_LAT, SLOT_NHC_VERT, SLOT_ODOMETER, SLOT_LEVEL,
 SLOT_REINIT) = 0, 3, 5, 8, 11, 12, 13, 14, 16


class Earth(NamedTuple):
    """The Earth at the drive's origin: its rate in ``n`` (rad/s, (3,)), gravity's magnitude (m/s^2)
    and the radius gravity points from (m)."""

    omega_ie: np.ndarray
    g0: float
    radius: float


def earth_at(lat_deg: float, height_m: float = 0.0) -> Earth:
    return Earth(np.ascontiguousarray(earth_rate_enu_radps(lat_deg), dtype=float),
                 float(normal_gravity_mps2(lat_deg, height_m)), float(EARTH_MEAN_RADIUS_M))


class FilterInputs(NamedTuple):
    """What the filter runs on. IMU samples: ``t`` (s, (n,)), ``acc`` (body specific force, m/s^2,
    (n, 3)), ``gyr`` (body rate, rad/s, (n, 3)). Per window boundary (nb,): ``b_sample`` (its
    sample), ``b_start`` (it starts a segment), ``gnss_ok`` (a usable fix), ``gnss_pos`` (ENU m,
    (nb, 3)), ``gnss_sigma`` (m), ``gnss_vel`` (east, north m/s, (nb, 2)), ``vel_ok`` (use the
    velocity), ``odo`` (vehicle speed m/s, NaN: none), ``still`` (the IMU shows the car standing);
    ``fix_step``: 1 where the fix goes on from the one before it as the speed says (no jump: when it
    disagrees with the filter, the filter is the one that is off), -1 where it jumps, 0 where it
    cannot tell (the first fix after a gap); ``has_height``: the fixes' heights are measurements;
    ``vel_var``: per boundary, variance (m²/s²) the GNSS velocity has beyond the model's (a lagging
    receiver's in an acceleration: :mod:`ionav_viz.core.gnss_lag`)."""

    t: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    b_sample: np.ndarray
    b_start: np.ndarray
    gnss_ok: np.ndarray
    gnss_pos: np.ndarray
    gnss_sigma: np.ndarray
    gnss_vel: np.ndarray
    vel_ok: np.ndarray
    odo: np.ndarray
    still: np.ndarray
    fix_step: np.ndarray
    has_height: bool
    vel_var: np.ndarray


class FilterNoise(NamedTuple):
    """The filter's noise as it uses it: the white noise densities of velocity and attitude
    (variance per second), the random walks per error state ``walk`` ((19,), variance per second)
    and each measurement's variance (unit squared; ``r_zaru`` per gyro sample)."""

    q_white_v: float
    q_white_phi: float
    walk: np.ndarray
    r_vel: float
    r_lat: float
    r_vert: float
    r_odo: float
    r_zupt: float
    r_zaru: float
    r_level: float


class FilterSwitches(NamedTuple):
    """Which updates run: GNSS, the NHC, the odometer, ZUPT/ZARU; and ``level_held``: the reduced
    mechanisation (roll and pitch held, not integrated from the x and y rates) for IMUs whose samples
    cannot carry a 3D attitude (single readings at a low rate)."""

    gnss: bool
    nhc: bool
    odometer: bool
    zupt: bool
    level_held: bool = False


class FilterOutputs(NamedTuple):
    """Where :func:`run_filter` writes, per boundary: the state ``xs`` (nb, 20) and covariance ``Ps``
    (nb, 19, 19) after its updates and the update ``log`` (each with 0 rows: kept nowhere), the
    position ``pos`` (ENU m, (nb, 3)) and its east/north covariance ``pos_cov`` (m^2, (nb, 2, 2)),
    the turn (rad) and distance (m) since the first boundary, and the process noise's scale ``q_scale``."""

    xs: np.ndarray
    Ps: np.ndarray
    pos: np.ndarray
    turn: np.ndarray
    dist: np.ndarray
    log: kalman.UpdateLog
    pos_cov: np.ndarray
    q_scale: np.ndarray


def filter_outputs(nb: int, keep_states: bool) -> FilterOutputs:
    """Outputs for ``nb`` boundaries, with the states and the update log or without."""
    rows = nb if keep_states else 0
    return FilterOutputs(np.zeros((rows, N_NOMINAL)), np.zeros((rows, N_ERR, N_ERR)), np.zeros((nb, 3)), np.zeros(nb),
                         np.zeros(nb), kalman.update_log(rows, len(GINS_MEASUREMENTS)), np.zeros((nb, 2, 2)),
                         np.ones(nb))


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
    #: a CAN speed's 1 km/h steps (0.28 m/s), its lag and the scale's drift: 0.3 m/s. Chosen for
    #: honesty on simulated MEMS logs with CAN speed (seeds 940-942, not the results' sets): the 95 %
    #: ellipse held 48 and 69 % of the final errors after 10 and 30 s at 0.1 m/s, 81 and 94 % at 0.3,
    #: the errors the same (1.67 / 1.68 % and 0.62 / 0.61 % of the distance)
    odometer_mps: float = 0.3
    zupt_mps: float = 0.02
    #: the level update's noise (0: none): a standing car's mean specific force over a second holds,
    #: beyond the sensor's averaged noise, the car settling on its springs after a stop and the
    #: engine's shake through a holder, a few cm/s^2; 0.05 m/s^2 is 0.3 deg of roll or pitch
    level_mps2: float = 0.05
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
def _mechanise(x, acc0, acc1, gyr0, gyr1, dt, earth, level_held, out):  # pragma: no cover - compiled
    """One step of ``dt`` (s) in place on the nominal state ``x`` (:class:`Earth` ``earth``);
    returns the horizontal distance (m) and writes the step's mean specific force in ``n`` (m/s^2)
    and corrected z rate (rad/s) into ``out`` (4,). ``level_held``: the reduced mechanisation, roll
    and pitch not integrated (the x and y rates taken as zero; the filter's updates still correct
    them). Scalar code: allocates nothing per sample."""
    omega_ie, g0, radius = earth.omega_ie, earth.g0, earth.radius
    wx = 0.0 if level_held else 0.5 * (gyr0[0] + gyr1[0]) - x[BGX]
    wy = 0.0 if level_held else 0.5 * (gyr0[1] + gyr1[1]) - x[BGX + 1]
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
    nx, ny, nz = (nx - 0.5 * dt * (oy * nz - oz * ny), ny - 0.5 * dt * (oz * nx - ox * nz),
                  nz - 0.5 * dt * (ox * ny - oy * nx))
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


# ---------------------------------------------------------------------------------------------
# The measurements, one function each. Each writes its row of H over the error state into the
# scratch ``H = (cols, h)`` (its nonzeros) and returns ``(dz, r, nnz)``: the prediction from the
# nominal state minus the measurement (the error state's measurement, ``dz = H dx + noise``), its
# variance and the number of nonzeros. :func:`_apply` folds one in. Counts and slots are passed as
# np.int64, not as the constants they are: numba compiles a function once per constant it is given.


@njit(cache=True)
def gnss_position(x, pos, sigma, axis, H):  # pragma: no cover - compiled
    """A GNSS position component (``axis`` 0 east, 1 north, 2 up; m), sigma ``sigma`` (twice it up)."""
    kalman.unit_row(H, DP + axis)
    s = sigma if axis < 2 else 2.0 * sigma
    return x[PX + axis] - pos[axis], s * s, np.int64(1)


@njit(cache=True)
def gnss_velocity(x, vel, axis, r, H):  # pragma: no cover - compiled
    """A GNSS horizontal velocity component (``axis`` 0 east, 1 north; m/s), variance ``r``."""
    kalman.unit_row(H, DV + axis)
    return x[VX + axis] - vel[axis], r, np.int64(1)


@njit(cache=True)
def zupt(x, axis, r, H):  # pragma: no cover - compiled
    """Zero velocity: the navigation-frame velocity component ``axis`` is 0 m/s."""
    kalman.unit_row(H, DV + axis)
    return x[VX + axis], r, np.int64(1)


@njit(cache=True)
def zaru(x, C, omega_ie, gyro_mean, axis, r, H):  # pragma: no cover - compiled
    """Zero angular rate: standing, the mean gyro reading about body ``axis`` (rad/s) is its bias
    plus the Earth's rate (``C``: ``C_b^n``)."""
    kalman.unit_row(H, DBG + axis)
    earth_b = C[0, axis] * omega_ie[0] + C[1, axis] * omega_ie[1] + C[2, axis] * omega_ie[2]
    return x[BGX + axis] + earth_b - gyro_mean[axis], r, np.int64(1)


@njit(cache=True)
def level(x, C, f_mean, axis, r, H):  # pragma: no cover - compiled
    """Standing: the mean specific force over the last window along body ``axis`` (0 x, 1 y; m/s^2)
    is gravity's reaction seen through the attitude plus the accelerometer's bias, ``(C^T (0, 0, g))[axis]
    + b_a[axis]`` (``g``: the mean specific force's magnitude). Its attitude row is
    :func:`_body_velocity_jacobian`'s ``-C^T [u x]`` for ``u = (0, 0, g)``, written out."""
    g = math.sqrt(f_mean[0] ** 2 + f_mean[1] ** 2 + f_mean[2] ** 2)
    cols, h = H
    cols[0], h[0] = PHI, -g * C[1, axis]
    cols[1], h[1] = PHI + 1, g * C[0, axis]
    cols[2], h[2] = DBA + axis, 1.0
    return C[2, axis] * g + x[BAX + axis] - f_mean[axis], r, np.int64(3)


@njit(cache=True)
def _body_velocity_row(C, M, row, scale, extra_col, extra_h, H):  # pragma: no cover - compiled
    """The row of H (7 nonzeros) of ``scale * (C^T v)[row] + extra_h * state[extra_col]`` (``M =
    -C^T [v x]``: the body-frame velocity's attitude Jacobian)."""
    cols, h = H
    for j in range(3):
        cols[j] = DV + j
        h[j] = scale * C[j, row]
        cols[3 + j] = PHI + j
        h[3 + j] = scale * M[row, j]
    cols[6] = extra_col
    h[6] = extra_h


@njit(cache=True)
def nhc_lateral(x, C, M, vb, r, H):  # pragma: no cover - compiled
    """The vehicle frame's lateral velocity ``vb_y + psi_m vb_x`` is 0 m/s (``vb = C^T v``, ``M``
    its attitude Jacobian)."""
    _body_velocity_row(C, M, 1, 1.0, DPSIM, vb[0], H)
    return vb[1] + x[PSIM] * vb[0], r, np.int64(7)


@njit(cache=True)
def nhc_vertical(x, C, M, vb, r, H):  # pragma: no cover - compiled
    """The vehicle frame's vertical velocity ``vb_z - theta_m vb_x`` is 0 m/s."""
    _body_velocity_row(C, M, 2, 1.0, DTHM, -vb[0], H)
    return vb[2] - x[THM] * vb[0], r, np.int64(7)


@njit(cache=True)
def odometer(x, C, M, vb, speed_mps, r, H):  # pragma: no cover - compiled
    """The vehicle speed reads ``k`` times the forward velocity ``vb_x`` (m/s)."""
    _body_velocity_row(C, M, 0, x[KO], DK, vb[0], H)
    return x[KO] * vb[0] - speed_mps, r, np.int64(7)


@njit(cache=True)
def _apply(P, dx, H, meas, gate, log, row, slot):  # pragma: no cover - compiled
    """Fold the measurement ``meas = (dz, r, nnz)`` with row ``H`` into ``dx``, ``P`` (the shared
    Joseph-form update), gated at ``gate`` (NIS), and keep it in ``log`` at ``(row, slot)`` (the
    innovation as measured minus predicted). Returns whether it was used, the innovation (predicted
    minus measured, against ``dx`` before the update) and its variance ``S``."""
    cols, h = H
    dz, r, nnz = meas
    nu = dz
    for k in range(nnz):
        nu -= h[k] * dx[cols[k]]
    S, used = kalman.scalar_update(P, dx, cols, h, nnz, nu, r, gate)
    kalman.record(log, row, slot, -nu, S, used)
    return used, nu, S


@njit(cache=True)
def standing_nis(x, P, r_zupt):  # pragma: no cover - compiled
    """How far the filter's velocity is from zero, as a chi-square of 3 degrees of freedom."""
    nis = 0.0
    for i in range(3):
        nis += x[VX + i] ** 2 / (P[DV + i, DV + i] + r_zupt)
    return nis


# ---------------------------------------------------------------------------------------------
# the filter's pass


@njit(cache=True)
def _restart_segment(x, P, P0, inputs, b):  # pragma: no cover - compiled
    """A new segment at boundary ``b`` (after a gap in the log): position and velocity from GNSS
    again, their covariance the initial one, what was learnt about the sensors kept."""
    for i in range(3):
        x[PX + i] = inputs.gnss_pos[b, i] if (i < 2 or inputs.has_height) else x[PX + i]
    x[VX] = inputs.gnss_vel[b, 0]
    x[VX + 1] = inputs.gnss_vel[b, 1]
    x[VX + 2] = 0.0
    for i in range(6):
        for k in range(N_ERR):
            P[i, k] = P[k, i] = 0.0
    for i in range(6):
        P[i, i] = P0[i, i]


#: The heading error from which a re-initialisation sets the heading from the GNSS course
#: (:func:`_heading_from_course`): beyond it the filter's small-angle error model cannot bring the
#: heading back; below it the filter's heading (the gyro's, with the mount's yaw residual) is better
#: than one course from a phone's fixes.
HEADING_REALIGN_RAD = math.radians(30.0)


@njit(cache=True)
def _heading_from_course(x, v_east, v_north, r_vel):  # pragma: no cover - compiled
    """Turn the attitude about the vertical (roll and pitch kept) so that the vehicle's forward
    axis (the body x axis turned by the mount's yaw residual, as the NHC has it) points along the
    horizontal velocity ``(v_east, v_north)`` (m/s, variance ``r_vel`` m^2/s^2 per axis), where the
    two differ by more than :data:`HEADING_REALIGN_RAD` and by more than three sigmas of the course."""
    C = _dcm(x[QW:QW + 4])
    c, s = math.cos(x[PSIM]), -math.sin(x[PSIM])
    now = math.atan2(C[1, 0] * c + C[1, 1] * s, C[0, 0] * c + C[0, 1] * s)
    turn = math.atan2(v_north, v_east) - now
    turn = math.atan2(math.sin(turn), math.cos(turn))
    course_sigma = math.atan2(math.sqrt(r_vel), math.hypot(v_east, v_north))
    if abs(turn) < max(HEADING_REALIGN_RAD, 3.0 * course_sigma):
        return
    q = _quat_mul(_quat_of_rotvec(np.array([0.0, 0.0, turn])), x[QW:QW + 4].copy())
    x[QW:QW + 4] = q / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


@njit(cache=True)
def _reinitialise(x, P, P0, inputs, r_vel, b, log):  # pragma: no cover - compiled
    """The safeguard: the filter disagrees with a fix that agrees with the fixes before it, so the
    filter is the one that is off: its position and velocity from GNSS again, with their initial
    covariance and the heading's (a velocity that was wrong had turned it), the rest kept. At speed
    the heading is set from the GNSS course too, as the alignment does (:func:`_heading_from_course`):
    the covariance alone cannot bring back a heading tens of degrees off, which a phone's GNSS gap
    leaves where its course comes back turned against the gyro."""
    offset = math.sqrt((x[PX] - inputs.gnss_pos[b, 0]) ** 2 + (x[PX + 1] - inputs.gnss_pos[b, 1]) ** 2)
    _restart_segment(x, P, P0, inputs, b)
    if inputs.vel_ok[b]:
        _heading_from_course(x, inputs.gnss_vel[b, 0], inputs.gnss_vel[b, 1], r_vel)
    for k in range(N_ERR):
        P[PHI + 2, k] = P[k, PHI + 2] = 0.0
    P[PHI + 2, PHI + 2] = P0[PHI + 2, PHI + 2]
    kalman.record(log, b, np.int64(SLOT_REINIT), offset, 1.0, True)


@njit(cache=True)
def _propagate_window(x, P, inputs, noise, earth, level_held, q_scale, j, jb, acc):  # pragma: no cover - compiled
    """Mechanise the samples ``j`` to ``jb`` (``level_held``: the reduced mechanisation) and
    propagate ``P`` over them; adds the distance (m) and the turn against the Earth (rad) into ``acc`` (2,)."""
    T = 0.0
    fsum, step = np.zeros(3), np.zeros(4)
    wz = 0.0
    C0 = _dcm(x[QW:QW + 4])
    t, omega_ie = inputs.t, earth.omega_ie
    while j < jb:
        dt = t[j + 1] - t[j]
        acc[0] += _mechanise(x, inputs.acc[j], inputs.acc[j + 1], inputs.gyr[j], inputs.gyr[j + 1], dt, earth,
                             level_held, step)
        acc[1] += (step[3] - omega_ie[2]) * dt  # the turn against the Earth, about the body's z
        for i in range(3):
            fsum[i] += step[i] * dt
        wz += step[3] * dt
        T += dt
        j += 1
    if T > 0.0:
        D, q_diag = np.zeros((N_ERR, N_ERR)), np.zeros(N_ERR)
        Cm = 0.5 * (C0 + _dcm(x[QW:QW + 4]))
        _transition(Cm, fsum / T, wz / T, T, D)
        for i in range(3):
            q_diag[DV + i] = q_scale * noise.q_white_v * T
            q_diag[PHI + i] = q_scale * noise.q_white_phi * T
            q_diag[DP + i] = q_scale * noise.q_white_v * T**3 / 3.0
        for i in range(9, N_ERR):
            q_diag[i] = noise.walk[i] * T
        _propagate_covariance(P, D, q_diag, q_scale * noise.q_white_v * T * T / 2.0, np.zeros((N_ERR, N_ERR)),
                              np.zeros((N_ERR, N_ERR)))


@njit(cache=True)
def _gnss_updates(x, P, dx, inputs, noise, b, gate, H, log, vel_r):  # pragma: no cover - compiled
    """Boundary ``b``'s fix: position (each component gated at ``gate``: a jump is not a fix), then,
    at speed and only where the horizontal position was used, velocity. Returns whether the
    horizontal position was used.

    The velocity's variance is the larger of the model's (``noise.r_vel``) and the one its own
    innovations show (covariance matching, Mohamed and Schwarz 1999: the running mean of the
    squared innovation less the filter's share of its variance, ``H P H'``, over about
    :data:`VEL_R_MEMORY` scalars, kept in ``vel_r[0]``): a phone's receiver reports a speed that
    lags the car by 0.5-1 s (iOS; measured against the IMU on the real logs), not the 0.3 m/s white
    noise a receiver's Doppler has, and held to 0.3 m/s it pulls the filter's velocity, biases and
    pitch after it."""
    used = True
    for axis in range(3 if inputs.has_height else 2):
        ok = _apply(P, dx, H, gnss_position(x, inputs.gnss_pos[b], inputs.gnss_sigma[b], axis, H), gate, log, b,
                    SLOT_GNSS_POS + axis)[0]
        used = used and (ok or axis == 2)
    if inputs.vel_ok[b] and used:
        r_vel = max(noise.r_vel, vel_r[0]) + inputs.vel_var[b]
        for axis in range(2):
            _, nu, S = _apply(P, dx, H, gnss_velocity(x, inputs.gnss_vel[b], axis, r_vel, H), np.inf, log, b,
                              SLOT_GNSS_VEL + axis)
            # the filter's share of S is S - r_vel
            vel_r[0] += (nu * nu - (S - r_vel) - inputs.vel_var[b] - vel_r[0]) / VEL_R_MEMORY
    return used


#: The GNSS velocity's own variance (:func:`_gnss_updates`) is a running mean over about this many
#: scalar innovations (two a fix: 10 s of 1 Hz fixes).
VEL_R_MEMORY = 20.0


@njit(cache=True)
def _standing_updates(x, P, dx, noise, earth, gm, fm, n_mean, H, log, b):  # pragma: no cover - compiled
    """Standing: ZUPT on each velocity component, ZARU on each gyro axis from the mean of
    ``n_mean`` samples ``gm``, and the level from the mean specific force ``fm``."""
    for axis in range(3):
        _apply(P, dx, H, zupt(x, axis, noise.r_zupt, H), np.inf, log, b, SLOT_ZUPT + axis)
    C = _dcm(x[QW:QW + 4])
    for axis in range(3):
        _apply(P, dx, H, zaru(x, C, earth.omega_ie, gm, axis, noise.r_zaru / n_mean, H), np.inf, log, b,
               SLOT_ZARU + axis)
    if noise.r_level > 0.0:
        for axis in range(2):
            _apply(P, dx, H, level(x, C, fm, axis, noise.r_level, H), np.inf, log, b, SLOT_LEVEL + axis)


@njit(cache=True)
def _moving_updates(x, P, dx, noise, sw, odo_mps, H, log, b):  # pragma: no cover - compiled
    """Moving: the non-holonomic constraint (lateral and vertical) and the odometer (``odo_mps``,
    NaN: none), all linearised at the same nominal state."""
    C = _dcm(x[QW:QW + 4])
    v = x[VX:VX + 3]
    vb, M = _tmul3(C, v), _body_velocity_jacobian(C, v)
    if sw.nhc:
        _apply(P, dx, H, nhc_lateral(x, C, M, vb, noise.r_lat, H), np.inf, log, b, np.int64(SLOT_NHC_LAT))
        _apply(P, dx, H, nhc_vertical(x, C, M, vb, noise.r_vert, H), np.inf, log, b, np.int64(SLOT_NHC_VERT))
    if sw.odometer and not math.isnan(odo_mps):
        _apply(P, dx, H, odometer(x, C, M, vb, odo_mps, noise.r_odo, H), np.inf, log, b, np.int64(SLOT_ODOMETER))


#: The consistency test (run_filter): the running mean of the GNSS position's NIS per scalar over
#: about NIS_MEMORY boundaries; above NIS_HIGH the process noise is scaled up by the ratio (at most
#: Q_SCALE_MAX times), below it eased back towards the model's.
NIS_MEMORY = 10.0
NIS_HIGH = 3.0
Q_SCALE_MAX = 30.0


@njit(cache=True)
def _consistency_step(log, b, nis_mean, q_scale):  # pragma: no cover - compiled
    """The running NIS from boundary ``b``'s horizontal GNSS position updates (used or gated) and
    the process noise's scale it asks for."""
    total, count = 0.0, 0
    for slot in range(SLOT_GNSS_POS, SLOT_GNSS_POS + 2):
        if log.status[b, slot] > 0 and log.variance[b, slot] > 0.0:
            total += log.innovation[b, slot] ** 2 / log.variance[b, slot]
            count += 1
    if count == 0:
        return nis_mean, q_scale
    nis_mean += (total / count - nis_mean) / NIS_MEMORY
    target = min(max(nis_mean / NIS_HIGH, 1.0), Q_SCALE_MAX)
    return nis_mean, target


@njit(cache=True)
def run_filter(inputs, noise, earth, sw, x0, P0, b_first, b_last, out, q_scale0):  # pragma: no cover - compiled
    """Run from boundary ``b_first`` to ``b_last`` (inclusive) from the state ``x0, P0`` at
    ``b_first``'s sample, updating at every boundary after the first (:class:`FilterInputs`,
    :class:`FilterNoise`, :class:`Earth`, :class:`FilterSwitches`); writes into ``out``
    (:class:`FilterOutputs`) the state after each boundary's updates (``xs``/``Ps``, when they have
    rows), the update log (when it has rows), and per boundary the position (m), the turn since
    ``b_first`` (rad, counter-clockwise: the corrected gyro integrated, so a window's yaw rate is a
    rate, not the updates' corrections of the heading) and the distance since ``b_first`` (m).
    ``q_scale0``: the process noise's scale at ``b_first`` (1.0 from a filter's start; always given,
    so that every call has one signature and numba compiles the filter once).

    At each boundary, in this order, every update folded into one error estimate and fed back once:

    1. GNSS (with ``sw.gnss`` and a good fix): position, gated at GNSS_GATE, then velocity at speed.
       A fix the gate leaves out that goes on smoothly from the fixes before it (``fix_step`` 1:
       no jump since the last fix the filter took) says the filter is off: the safeguard
       re-initialises position and velocity from it (and the heading from its course, where far
       off: :func:`_heading_from_course`) (:func:`_reinitialise`, logged) instead of
       shutting the fixes out. A jump is left out, and so are the fixes after it until one agrees
       with the filter again; after GNSS_REJECTS_MAX boundaries in a row the next is taken whatever it says.
    2. Standing (the detector says so, ``sw.zupt``): ZUPT, ZARU and the level, *instead of* the NHC and the
       odometer (at rest the zero velocity says what they would, more strongly, and a wheel speed
       of 0 says nothing of its scale). Not where a fix at speed says the car moves; where the
       filter's velocity is further than ZUPT_GATE from zero only after two still boundaries in a
       row (then the filter is off: its velocity variance is widened to take the stop), else logged
       as gated.
    3. Moving: the NHC (``sw.nhc``) and the odometer (``sw.odometer``, where the drive has one).
    """
    x = x0.copy()
    P = P0.copy()
    dx = np.zeros(N_ERR)
    H = (np.zeros(7, dtype=np.int64), np.zeros(7))
    store = out.xs.shape[0] > 0
    walked = np.zeros(2)  # distance (m) and turn (rad) since b_first
    gm = np.zeros(3)
    fm = np.zeros(3)
    rejected, jumped = 0, False
    # the consistency test: a running mean of the GNSS position's NIS per scalar; persistently above
    # NIS_HIGH, the white noise the filter assumes is too small for what it meets: scaled up
    q_scale, nis_mean = q_scale0, 1.0
    vel_r = np.full(1, noise.r_vel)  # the GNSS velocity's variance its innovations show (_gnss_updates)
    j = inputs.b_sample[b_first]
    for b in range(b_first, b_last + 1):
        jb = inputs.b_sample[b]
        if b > b_first and inputs.b_start[b]:
            _restart_segment(x, P, P0, inputs, b)
            j = jb
        elif b > b_first:
            _propagate_window(x, P, inputs, noise, earth, sw.level_held, q_scale, j, jb, walked)
            j = jb
            gnss_here = sw.gnss and inputs.gnss_ok[b]
            if gnss_here:
                if _gnss_updates(x, P, dx, inputs, noise, b, GNSS_GATE if rejected < GNSS_REJECTS_MAX else np.inf, H,
                                 out.log, vel_r):
                    rejected, jumped = 0, False
                elif inputs.fix_step[b] > 0 and not jumped:
                    # the fixes went on smoothly from the last one the filter took, and it disagrees: it is off
                    _correct(x, dx)
                    _reinitialise(x, P, P0, inputs, noise.r_vel, b, out.log)
                    rejected = 0
                else:  # a jump in the fixes (and the fixes after it until they come back to the filter), or a
                    # first fix after a gap, which nothing confirms yet: left out
                    rejected += 1
                    jumped = jumped or inputs.fix_step[b] < 0
                if out.log.status.shape[0] > 0 and not jumped:
                    nis_mean, q_scale = _consistency_step(out.log, b, nis_mean, q_scale)
            standing = sw.zupt and inputs.still[b]
            moving_says_gnss = gnss_here and inputs.vel_ok[b]
            if standing and (moving_says_gnss or standing_nis(x, P, noise.r_zupt) >= ZUPT_GATE):
                if not moving_says_gnss and inputs.still[b - 1]:
                    # still for two boundaries and no fix saying otherwise: the filter's velocity is the one that is off
                    for axis in range(3):
                        P[DV + axis, DV + axis] += x[VX + axis] ** 2
                else:  # the detector is wrong, or the filter is: a ZUPT would not be a small correction
                    standing = False
                    for axis in range(3):
                        kalman.record(out.log, b, SLOT_ZUPT + axis, -x[VX + axis],
                                      P[DV + axis, DV + axis] + noise.r_zupt, False)
            if standing:
                # the mean gyro reading over the last window (WINDOW_S, both ends, at any rate)
                k0 = inputs.b_sample[b - 1]
                gm[:] = 0.0
                fm[:] = 0.0
                for k in range(k0, jb + 1):
                    gm += inputs.gyr[k]
                    fm += inputs.acc[k]
                gm /= jb + 1 - k0
                fm /= jb + 1 - k0
                _standing_updates(x, P, dx, noise, earth, gm, fm, max(jb + 1 - k0, 1), H, out.log, b)
            else:
                _moving_updates(x, P, dx, noise, sw, inputs.odo[b], H, out.log, b)
            _correct(x, dx)
        if store:
            out.xs[b] = x
            out.Ps[b] = P
        out.q_scale[b] = q_scale
        for i in range(3):
            out.pos[b, i] = x[PX + i]
        for i in range(2):
            for k in range(2):
                out.pos_cov[b, i, k] = P[DP + i, DP + k]
        out.dist[b] = walked[0]
        out.turn[b] = walked[1]
    return x, P


@njit(cache=True)
def _propagate_all(t, acc, gyr, x0, earth):  # pragma: no cover - compiled
    n = len(t)
    out = np.zeros((n, N_NOMINAL))
    step = np.zeros(4)
    x = x0.copy()
    out[0] = x
    for j in range(n - 1):
        _mechanise(x, acc[j], acc[j + 1], gyr[j], gyr[j + 1], t[j + 1] - t[j], earth, False, step)
        out[j + 1] = x
    return out


def propagate(t_s: np.ndarray, accel_mps2: np.ndarray, gyro_radps: np.ndarray, x0: np.ndarray, lat0_deg: float,
              height0_m: float = 0.0) -> np.ndarray:
    """The mechanisation alone (no filter): the nominal state (see the module docstring) at every
    sample ``(n, 20)`` from ``x0`` at the first, given body-frame specific force (m/s^2) and angular
    rate (rad/s) samples ``(n, 3)``, in the tangent frame of an origin at ``lat0_deg``, ``height0_m``."""
    return _propagate_all(np.ascontiguousarray(t_s, dtype=float), np.ascontiguousarray(accel_mps2, dtype=float),
                          np.ascontiguousarray(gyro_radps, dtype=float), np.asarray(x0, dtype=float),
                          earth_at(lat0_deg, height0_m))


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
    z, rows = np.zeros(3), np.zeros((3, N_ERR))
    for i, fn in enumerate((nhc_lateral, nhc_vertical, odometer)):
        H = (np.zeros(7, dtype=np.int64), np.zeros(7))
        args = (x, C, M, vb) + ((0.0,) if fn is odometer else ()) + (1.0, H)
        dz, _, nnz = fn(*args)
        z[i] = dz
        rows[i, H[0][:nnz]] = H[1][:nnz]
    return z, rows


def measurement_model(name: str, x: np.ndarray, **given: Any) -> tuple[float, np.ndarray]:
    """One measurement as the filter predicts it from the nominal state ``x`` (20,): its value
    (prediction minus the measurement ``given``) and its row of H over the error state (19,), for
    tests against the nonlinear model. ``name``: one of :data:`GINS_MEASUREMENTS`' kinds without the
    axis (``gnss_position``, ``gnss_velocity``, ``zupt``, ``zaru``, ``nhc_lateral``,
    ``nhc_vertical``, ``odometer``, ``level``); ``given``: its arguments (``pos``, ``sigma``, ``vel``,
    ``axis``, ``gyro_mean``, ``omega_ie``, ``speed_mps``, ``specific_force``)."""
    x = np.ascontiguousarray(x, dtype=float)
    C = _dcm(x[QW:QW + 4])
    v = np.ascontiguousarray(x[VX:VX + 3])
    vb, M = _tmul3(C, v), _body_velocity_jacobian(C, v)
    H = (np.zeros(7, dtype=np.int64), np.zeros(7))
    axis = int(given.get("axis", 0))
    three = lambda key: np.ascontiguousarray(given.get(key, np.zeros(3)), dtype=float)  # noqa: E731
    calls = {"gnss_position": lambda: gnss_position(x, three("pos"), float(given.get("sigma", 1.0)), axis, H),
             "gnss_velocity": lambda: gnss_velocity(x, three("vel"), axis, 1.0, H),
             "zupt": lambda: zupt(x, axis, 1.0, H),
             "zaru": lambda: zaru(x, C, three("omega_ie"), three("gyro_mean"), axis, 1.0, H),
             "nhc_lateral": lambda: nhc_lateral(x, C, M, vb, 1.0, H),
             "nhc_vertical": lambda: nhc_vertical(x, C, M, vb, 1.0, H),
             "odometer": lambda: odometer(x, C, M, vb, float(given.get("speed_mps", 0.0)), 1.0, H),
             "level": lambda: level(x, C, three("specific_force"), axis, 1.0, H)}
    dz, _, nnz = calls[name]()
    row = np.zeros(N_ERR)
    row[H[0][:nnz]] = H[1][:nnz]
    return float(dz), row
