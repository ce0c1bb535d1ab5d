"""A GNSS-aided INS on the planar vehicle model: the filter behind the ``ekf`` estimator
(:mod:`ionav_viz.nav.ekf`) and the sensor calibration the IDNN's inputs are corrected with.

The paper's INS restarts blind at every outage with the biases of a standstill. A filter running
over the drive while GNSS is good also learns the accelerometer offset (bias, mount tilt and the
slowly changing road grade) and the gyro bias as they are *at the outage*, and starts each
outage from its own speed estimate instead of one noisy GNSS speed.

State (8), on a local east-north plane (m) around the drive's first fix::

    x = [e, n, v, psi, b_a, b_g, k, s]

``e, n`` position (m), ``v`` speed along the course (m/s), ``psi`` course (rad, clockwise from
north, as GNSS gives it), ``b_a`` accelerometer offset (m/s^2), ``b_g`` gyro bias (rad/s, on the
counter-clockwise yaw rate), ``k`` the vehicle-speed scale (the drive's vehicle speed, converted
with the nominal wheel radius, over the true speed), ``s`` the gyro's scale error (the gyro
reads ``(1 + s)`` times the true yaw rate, plus ``b_g``; learnt from the GNSS course in turns).

Propagation, once per 1-second window from its 11 inertial samples (trapezoid integrals over the
window: ``F = int f dt``, ``G = int int f dt dt``, ``W = int omega dt``)::

    v'   = v + F - b_a T                 psi' = psi - turn,  turn = (W - b_g T) / (1 + s)
    d    = v T + G - b_a T^2 / 2         (distance along the window)
    e'   = e + d sin(psi_mid)            n' = n + d cos(psi_mid),  psi_mid = psi - turn / 2

with its Jacobian for the covariance, and process noise from the sensors' white noise and the
offsets' random walks (:class:`EkfNoise`).

Measurements at each window boundary where GNSS is good (the fix ends or starts a window with
good truth): position (sigma :attr:`EkfNoise.gnss_position_m`, or the receiver's own when the drive has
``gnss_sigma_m``), speed, and course while faster than 3 m/s (its noise grows as 1/speed). Where
the drive has a vehicle speed (:func:`ionav_viz.nav.vehicle_speed.vehicle_speed`) it is a measurement
``z = k v`` too, at every boundary, GNSS or not.

Each outage starts from the filter's state at its first window (it has seen GNSS only before
it) and is propagated through the outage without GNSS, still updated with the vehicle speed
where there is one. Per window it reports the distance ``d`` and the yaw rate ``(W - b_g T) / T``.

The offset the filter has learnt at an outage start is its slow part (bias and tilt: its mean
over the last OFFSET_MEMORY_S) plus road grade, and road grade does not last: through the outage
the grade part fades over GRADE_LENGTH_M of road.

Noise values were chosen on the simulator's bundled test drives only (never on the real
dataset), starting from its error model (``ionav_viz/sim/simulate.py``): sensor white noise as
documented, the GNSS wander taken as white with its full standard deviation, the GNSS speed at
0.05 m/s, and an offset random walk of 0.1 m/s^2/sqrt(s) loose enough to follow the road grade
(what they give: docs/method.md, `python benchmarks/ekf_tuning.py`).

The filter's loops are compiled with numba (``cache=True``: the first run on a machine compiles
them and stores the result in ``__pycache__``; `python benchmarks/bench_replay.py` times a pass).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from ..core import jit
from ..core.drive import Drive
from ..core.geo import local_en_m
from ..core.gnss_quality import position_sigma_m
from ..core.grid import GRID_RATE_HZ, WINDOW_S
from . import kalman
from .vehicle_speed import speed_in_mps, vehicle_speed
from .windows import Windows

jit.watch(__name__)  # say a first run's compilation (core/jit.py)

E, N, V, PSI, BA, BG, K, S = range(8)
N_STATES = 8
#: The GNSS course is a measurement only above this speed (m/s; its noise grows as 1/speed). Not the
#: grid's course hold (:data:`ionav_viz.core.grid.MIN_COURSE_SPEED_MPS`), a meaning of its own.
FILTER_COURSE_MIN_SPEED_MPS = 3.0
#: The accelerometer offset's slow part (bias, mount tilt) is its mean over about this long (s);
#: the rest is road grade, which an outage does not keep: it fades over GRADE_LENGTH_M of road.
OFFSET_MEMORY_S = 120.0
GRADE_LENGTH_M = 150.0


@dataclass(frozen=True)
class EkfNoise:
    """Noise of the filter (1 sigma; random walks per sqrt(s)); see the module docstring."""

    accel_white_mps2: float = 0.3
    gyro_white_radps: float = np.deg2rad(0.25)
    #: the offset wanders as the road's grade changes (0.1-0.5 m/s^2 of gravity for tens of seconds,
    #: SENSORS.md); 0.2 was chosen with scale_walk and turn_scale_sd for honesty (95 % of outage ends
    #: inside the 95 % ellipse) on the simulated training fleet, never on the sets results.md reports
    accel_offset_walk_mps2: float = 0.2
    gyro_bias_walk_radps: float = np.deg2rad(0.005)
    #: the rolling radius changes with speed, load and slip (1-3 %, SENSORS.md)
    scale_walk: float = 2e-3
    gyro_scale_walk: float = 1e-5
    gnss_position_m: float = 1.0
    gnss_speed_mps: float = 0.05
    gnss_course_rad_at_10mps: float = np.deg2rad(0.5)
    #: the same where the speed and course are fitted to the fixes (no receiver velocity;
    #: Drive.speed_fitted): measured on 1 Hz phone logs and 1-20 Hz fix-only logs (docs/method.md)
    gnss_fitted_speed_mps: float = 0.5
    gnss_fitted_course_rad_at_10mps: float = np.deg2rad(2.0)
    vehicle_speed_mps: float = 0.15
    #: heading noise per radian turned in a window (gyro scale and latency the scale state does not
    #: follow): the course's process noise gains (this * turn)^2
    turn_scale_sd: float = 0.1
    still_speed_mps: float = 0.05
    init_position_m: float = 1.0
    init_speed_mps: float = 0.2
    init_course_rad: float = np.deg2rad(2.0)
    init_accel_offset_mps2: float = 0.3
    init_gyro_bias_radps: float = np.deg2rad(0.5)
    init_scale: float = 0.05
    init_gyro_scale: float = 0.03


@dataclass
class Increments:
    """Per window: ``F``, ``G``, ``W`` (see the module docstring) and its length ``T`` (s)."""

    F: np.ndarray
    G: np.ndarray
    W: np.ndarray
    T: float


def increments(windows: Windows) -> Increments:
    """Trapezoid integrals of each window's 11 accelerometer and gyro samples."""
    h = 1.0 / windows.rate_hz
    acc, gyr = windows.accel_mps2, windows.gyro_radps
    dv = 0.5 * (acc[:, 1:] + acc[:, :-1]) * h  # per step
    # speed gained since the window start
    v_rel = np.concatenate([np.zeros((len(acc), 1)), np.cumsum(dv, axis=1)], axis=1)
    G = (0.5 * (v_rel[:, 1:] + v_rel[:, :-1]) * h).sum(axis=1)
    W = (0.5 * (gyr[:, 1:] + gyr[:, :-1]) * h).sum(axis=1)
    return Increments(dv.sum(axis=1), G, W, h * (acc.shape[1] - 1))


def noise_arrays(noise: EkfNoise, T: float) -> tuple[np.ndarray, np.ndarray]:
    """The process noise per window (diagonal, (8,)) and the initial standard deviations (8,)."""
    q = np.zeros(N_STATES)
    q[E] = q[N] = 0.01 * T
    # white noise on each grid sample (variance sigma^2 step^2), summed over the T / step samples of a window
    q[V] = noise.accel_white_mps2**2 * T / GRID_RATE_HZ
    q[PSI] = noise.gyro_white_radps**2 * T / GRID_RATE_HZ
    q[BA] = noise.accel_offset_walk_mps2**2 * T
    q[BG] = noise.gyro_bias_walk_radps**2 * T
    q[K] = noise.scale_walk**2 * T
    q[S] = noise.gyro_scale_walk**2 * T
    init = np.array([noise.init_position_m, noise.init_position_m, noise.init_speed_mps, noise.init_course_rad,
                     noise.init_accel_offset_mps2, noise.init_gyro_bias_radps, noise.init_scale, noise.init_gyro_scale])
    return q, init


class PlanarInputs(NamedTuple):
    """What the filter runs on, per window boundary (n_windows + 1): GNSS position ``e``, ``n``
    (local m), ``speed`` (m/s), ``course`` (rad, clockwise from north), ``good`` (a usable fix),
    ``sigma`` (m); per window (n_windows): ``segment``, the vehicle speed at its end ``vehicle``
    (m/s, NaN: none) and its increments ``F``, ``G``, ``W`` over ``T`` s (:class:`Increments`)."""

    segment: np.ndarray
    e: np.ndarray
    n: np.ndarray
    speed: np.ndarray
    course: np.ndarray
    good: np.ndarray
    sigma: np.ndarray
    vehicle: np.ndarray
    F: np.ndarray
    G: np.ndarray
    W: np.ndarray
    T: float


class PlanarModel(NamedTuple):
    """The filter's noise as it uses it: process noise per window ``q`` (8,), initial standard
    deviations ``init_sd`` (8,), the variances of the GNSS speed, the vehicle speed and a standstill's
    zero speed ((m/s)^2), the GNSS course's sigma at 10 m/s (rad), the offset's slow part's
    smoothing per window ``alpha`` and the road length a grade fades over (m)."""

    q: np.ndarray
    init_sd: np.ndarray
    r_speed: float
    r_vehicle: float
    r_still: float
    course_sd_at_10mps: float
    alpha: float
    grade_length_m: float
    turn_sd: float


#: The measurement slots of the forward pass's update log (:class:`ionav_viz.nav.kalman.UpdateLog`,
#: a row per window: GNSS at its start, the vehicle speed at its end), in their units (m, m/s, rad, m/s).
PLANAR_MEASUREMENTS = ("gnss_east", "gnss_north", "gnss_speed", "gnss_course", "vehicle_speed")
SLOT_VEHICLE = 4


# The filter runs one small state per window, which numpy cannot batch along the drive: the
# loops below are compiled by numba (cached on disk after the first run), about 50x faster
# than the same numpy code per window (benchmarks/bench_replay.py).


@njit(cache=True)
def _propagate(x, P, F, G, W, T, q, J, turn_sd=0.0):  # pragma: no cover - compiled
    """One window, in place: the state ``x`` (8,) and covariance ``P`` (8, 8); returns the
    distance along the window (m) and its mean yaw rate (rad/s, CCW +). ``J`` is scratch;
    ``turn_sd``: the course's noise per radian turned (:attr:`EkfNoise.turn_scale_sd`)."""
    v, psi, ba, bg, gain = x[V], x[PSI], x[BA], x[BG], 1.0 + x[S]
    turn = (W - bg * T) / gain  # counter-clockwise, rad
    mid = psi - 0.5 * turn
    d = v * T + G - 0.5 * ba * T * T
    s, c = np.sin(mid), np.cos(mid)
    dturn_dbg, dturn_ds = -T / gain, -turn / gain
    x[E] += d * s
    x[N] += d * c
    x[V] = v + F - ba * T
    x[PSI] = psi - turn
    J[:, :] = 0.0
    for i in range(N_STATES):
        J[i, i] = 1.0
    # d(e, n) / d(v, psi, b_a, b_g, s); psi_mid depends on psi and (through the turn) on b_g and s
    J[E, V], J[E, PSI], J[E, BA] = T * s, d * c, -0.5 * T * T * s
    J[N, V], J[N, PSI], J[N, BA] = T * c, -d * s, -0.5 * T * T * c
    J[E, BG], J[E, S] = -0.5 * d * c * dturn_dbg, -0.5 * d * c * dturn_ds
    J[N, BG], J[N, S] = 0.5 * d * s * dturn_dbg, 0.5 * d * s * dturn_ds
    J[V, BA] = -T
    J[PSI, BG], J[PSI, S] = -dturn_dbg, -dturn_ds
    _congruence(J, P, q)
    P[PSI, PSI] += (turn_sd * turn) ** 2
    return d, turn / T


@njit(cache=True)
def _congruence(J, P, q):  # pragma: no cover - compiled
    """``P <- J P J^T + diag(q)`` in place."""
    JP = np.empty((N_STATES, N_STATES))
    _product(J, P, JP)
    _product(JP, J.T, P)
    for i in range(N_STATES):
        P[i, i] += q[i]


@njit(cache=True)
def _product(A, B, out):  # pragma: no cover - compiled
    """``out <- A @ B`` (``out`` neither ``A`` nor ``B``) with plain loops: numba's matrix product
    needs SciPy's BLAS and compiles slowly."""
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            acc = 0.0
            for m in range(A.shape[1]):
                acc += A[i, m] * B[m, j]
            out[i, j] = acc


# The measurements, one function each: each writes its row of H into the scratch ``H = (cols,
# h)`` (its nonzeros) and returns ``(innovation, r, nnz)``: measured minus predicted, its variance
# and the number of nonzeros; :func:`_apply` folds one in with the shared update. Counts, columns
# and slots go as np.int64, not as the constants they are: numba compiles once per constant given.


@njit(cache=True)
def gnss_state(x, col, z, r, H):  # pragma: no cover - compiled
    """A GNSS measurement of a state directly: east or north (m), speed (m/s), or the course (rad,
    its innovation wrapped to [-pi, pi))."""
    kalman.unit_row(H, col)
    innovation = z - x[col]
    if col == PSI:
        innovation = (innovation + np.pi) % (2 * np.pi) - np.pi
    return innovation, r, np.int64(1)


@njit(cache=True)
def vehicle_speed_meas(x, z, r, H):  # pragma: no cover - compiled
    """The vehicle speed ``z = k v`` (m/s)."""
    cols, h = H
    cols[0], h[0] = V, x[K]
    cols[1], h[1] = K, x[V]
    return z - x[K] * x[V], r, np.int64(2)


@njit(cache=True)
def standstill(x, r, H):  # pragma: no cover - compiled
    """Standing: the speed is 0 m/s."""
    kalman.unit_row(H, V)
    return -x[V], r, np.int64(1)


@njit(cache=True)
def _apply(P, x, H, meas, log, row, slot):  # pragma: no cover - compiled
    """Fold ``meas = (innovation, r, nnz)`` with row ``H`` into ``x``, ``P`` (the shared Joseph-form
    update; no gate) and keep it in ``log`` at ``(row, slot)``."""
    innovation, r, nnz = meas
    S, used = kalman.scalar_update(P, x, H[0], H[1], nnz, innovation, r, np.inf)
    kalman.record(log, row, slot, innovation, S, used)


@njit(cache=True)
def _restart(x, P, inp, model, k, accel_offset, gyro_bias):  # pragma: no cover - compiled
    """A segment starts at window ``k``: the state from its fix and the starting biases, with the
    initial covariance; after a gap, what was learnt about the sensors is kept."""
    prior_x, prior_P = x.copy(), P.copy()
    x[:] = (inp.e[k], inp.n[k], inp.speed[k], inp.course[k], accel_offset, gyro_bias, 1.0, 0.0)
    P[:, :] = 0.0
    for i in range(N_STATES):
        P[i, i] = model.init_sd[i] ** 2
    if k > 0:
        x[BA:] = prior_x[BA:]
        P[BA:, BA:] = prior_P[BA:, BA:]


@njit(cache=True)
def _forward_kernel(inp, model, accel_offset, gyro_bias, log):  # pragma: no cover - compiled
    """The pass over the drive: at each window start its fix (position, speed, and the course when
    faster than FILTER_COURSE_MIN_SPEED_MPS), then the window's propagation and the vehicle speed at
    its end. Each segment's state starts (again) at its first usable fix. Returns the states and
    covariances at the window starts (after their fix) and the offset's slow part there."""
    nw = len(inp.segment)
    xs, Ps, slow = np.zeros((nw, N_STATES)), np.zeros((nw, N_STATES, N_STATES)), np.zeros(nw)
    x, P = np.zeros(N_STATES), np.zeros((N_STATES, N_STATES))
    J = np.zeros((N_STATES, N_STATES))
    H = (np.zeros(2, dtype=np.int64), np.zeros(2))
    mean = accel_offset
    started = False  # whether this segment has had a usable fix: its state starts at the first
    for k in range(nw):
        # a phone's first seconds hold a stale position and course: a state started from them and
        # corrected at the first usable fix (a course 156 deg off, at 2 deg) learns a gyro bias of 11 deg/s
        if k == 0 or inp.segment[k] != inp.segment[k - 1] or (not started and inp.good[k]):
            _restart(x, P, inp, model, k, accel_offset, gyro_bias)
            started = bool(inp.good[k])
        elif inp.good[k]:
            r_pos = inp.sigma[k] ** 2
            _apply(P, x, H, gnss_state(x, np.int64(E), inp.e[k], r_pos, H), log, k, np.int64(E))
            _apply(P, x, H, gnss_state(x, np.int64(N), inp.n[k], r_pos, H), log, k, np.int64(N))
            _apply(P, x, H, gnss_state(x, np.int64(V), inp.speed[k], model.r_speed, H), log, k, np.int64(V))
            if inp.speed[k] > FILTER_COURSE_MIN_SPEED_MPS:  # the course only when moving: its noise grows as 1/speed
                r_course = (model.course_sd_at_10mps * 10.0 / max(inp.speed[k], 1.0)) ** 2
                _apply(P, x, H, gnss_state(x, np.int64(PSI), inp.course[k], r_course, H), log, k, np.int64(PSI))
        xs[k], Ps[k] = x, P
        mean += model.alpha * (x[BA] - mean)
        slow[k] = mean
        _propagate(x, P, inp.F[k], inp.G[k], inp.W[k], inp.T, model.q, J, model.turn_sd)
        if np.isfinite(inp.vehicle[k]):
            _apply(P, x, H, vehicle_speed_meas(x, inp.vehicle[k], model.r_vehicle, H), log, k, np.int64(SLOT_VEHICLE))
    return xs, Ps, slow


@njit(cache=True)
def outage_kernel(forward, inp, model, starts, n_windows, still):  # pragma: no cover - compiled
    """Every outage from the forward pass's state ``forward = (xs, Ps, slow)`` at its start, without
    GNSS. ``still[o, j]``: the car stands at the end of window ``j`` of outage ``o`` (the IMU shows
    it): a zero-speed update there. The speed never goes below zero (a car's filter drives forward).
    Returns the distance (m) and yaw rate (rad/s) per window and the east/north covariance (m^2) at
    every window boundary ``(m, n_windows + 1, 2, 2)``."""
    xs, Ps, slow = forward
    m = len(starts)
    disp, yaw = np.zeros((m, n_windows)), np.zeros((m, n_windows))
    cov = np.zeros((m, n_windows + 1, 2, 2))
    J = np.zeros((N_STATES, N_STATES))
    H = (np.zeros(2, dtype=np.int64), np.zeros(2))
    nowhere = kalman.UpdateLog(np.zeros((0, 1)), np.zeros((0, 1)), np.zeros((0, 1), dtype=np.int8))
    for o in range(m):
        k0 = starts[o]
        x, P = xs[k0].copy(), Ps[k0].copy()
        cov[o, 0] = P[E:N + 1, E:N + 1]
        base = slow[k0]
        grade0 = x[BA] - base
        travelled = 0.0
        for j in range(n_windows):
            k = k0 + j
            # the fast part of the offset is road grade: it fades over grade_length_m of road
            x[BA] = base + grade0 * np.exp(-travelled / model.grade_length_m)
            disp[o, j], yaw[o, j] = _propagate(x, P, inp.F[k], inp.G[k], inp.W[k], inp.T, model.q, J, model.turn_sd)
            travelled += max(disp[o, j], 0.0)
            if np.isfinite(inp.vehicle[k]):
                _apply(P, x, H, vehicle_speed_meas(x, inp.vehicle[k], model.r_vehicle, H), nowhere, 0, 0)
            if still[o, j]:
                _apply(P, x, H, standstill(x, model.r_still, H), nowhere, 0, 0)
            x[V] = max(x[V], 0.0)
            cov[o, j + 1] = P[E:N + 1, E:N + 1]
    return disp, yaw, cov


def propagate_window(x: np.ndarray, F: float, G: float, W: float,
                     T: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """One window of the filter's propagation (see the module docstring) from the state ``x`` (8,):
    the state after it, its Jacobian ``d x' / d x`` (8 x 8) as the covariance is propagated with,
    the distance (m) and the mean yaw rate (rad/s, counter-clockwise)."""
    out, J = np.array(x, dtype=float), np.zeros((N_STATES, N_STATES))
    d, rate = _propagate(out, np.zeros((N_STATES, N_STATES)), float(F), float(G), float(W), float(T),
                         np.zeros(N_STATES), J)
    return out, J, float(d), float(rate)


def vehicle_speed_model(x: np.ndarray) -> tuple[float, np.ndarray]:
    """The vehicle speed as the filter predicts it from the state ``x`` (8,) (``k v``, m/s) and its
    row of H (8,)."""
    H = (np.zeros(2, dtype=np.int64), np.zeros(2))
    innovation, _, nnz = vehicle_speed_meas(np.asarray(x, dtype=float), 0.0, 1.0, H)
    row = np.zeros(N_STATES)
    row[H[0][:nnz]] = H[1][:nnz]
    return float(-innovation), row


@dataclass
class Measurements:
    """GNSS at every window boundary (arrays of n_windows + 1, local metres), and the vehicle
    speed per window end (m/s, NaN where none)."""

    e: np.ndarray
    n: np.ndarray
    speed: np.ndarray
    course: np.ndarray
    good: np.ndarray
    sigma_m: np.ndarray
    vehicle: np.ndarray


def measurements(drive: Drive, windows: Windows, noise: EkfNoise, use_vehicle_speed: bool = True) -> Measurements:
    """What the filter is updated with, at the start of every window and the end of the last
    (the vehicle speed only with ``use_vehicle_speed``)."""
    lat = np.concatenate([windows.lat0_deg, windows.lat1_deg[-1:]])
    lon = np.concatenate([windows.lon0_deg, windows.lon1_deg[-1:]])
    e, n = local_en_m(lat, lon, float(lat[0]), float(lon[0]))
    speed = np.concatenate([windows.speed0_mps, windows.speed0_mps[-1:]])
    course = np.deg2rad(np.concatenate([windows.heading0_deg, windows.heading1_deg[-1:]]))
    ok = windows.truth_ok
    good = np.concatenate([[ok[0]], ok[1:] | ok[:-1], [ok[-1]]])  # the fix ends or starts a good window
    t = np.concatenate([windows.t0_s, windows.t0_s[-1:] + WINDOW_S])
    sigma = position_sigma_m(t, drive.t_s, drive.columns.get("gnss_sigma_m"), noise.gnss_position_m)
    vehicle = np.full(len(windows), np.nan)
    found = vehicle_speed(drive) if use_vehicle_speed else None
    if found is not None:
        values, unit, _ = found
        per_s = speed_in_mps(values, unit)
        steps = int(round(windows.rate_hz))
        vehicle = np.interp(windows.t0_s + steps / windows.rate_hz, drive.t_s, per_s)  # at each window's end
    return Measurements(e, n, speed, course, good, sigma, vehicle)


def forward(drive: Drive, windows: Windows, accel_offset: float, gyro_bias: float,
            noise: EkfNoise = EkfNoise()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The filter over the whole drive: its state and covariance at the start of every window,
    having used the GNSS of earlier boundaries only (shapes (n_windows, 8) and (n_windows, 8, 8)),
    and the offset's slow part there (its mean over the last ~OFFSET_MEMORY_S, (n_windows,))."""
    return forward_states(windows, measurements(drive, windows, noise), increments(windows), accel_offset, gyro_bias,
                          noise)


def planar_inputs(windows: Windows, meas: Measurements, inc: Increments) -> PlanarInputs:
    """The filter's typed inputs (numba-ready) from the windows, measurements and increments: writable
    copies, since a read-only array (a window's segment of an MCAP log) is another type to numba, and
    another compilation of every kernel."""
    f = lambda a: np.array(a, dtype=float)  # noqa: E731
    return PlanarInputs(np.array(windows.segment, dtype=np.int64), f(meas.e), f(meas.n), f(meas.speed),
                        f(meas.course), np.array(meas.good, dtype=np.bool_), f(meas.sigma_m),
                        f(meas.vehicle), f(inc.F), f(inc.G), f(inc.W), float(inc.T))


def planar_model(noise: EkfNoise, T: float) -> PlanarModel:
    """The filter's noise as its kernels use it, for windows of ``T`` s."""
    q, init = noise_arrays(noise, T)
    return PlanarModel(q, init, float(noise.gnss_speed_mps**2), float(noise.vehicle_speed_mps**2),
                       float(noise.still_speed_mps**2), float(noise.gnss_course_rad_at_10mps),
                       float(T / OFFSET_MEMORY_S), float(GRADE_LENGTH_M), float(noise.turn_scale_sd))


@dataclass
class ForwardPass:
    """The filter's pass over a drive: states ``xs`` (n_windows, 8) and covariances ``Ps`` (n_windows,
    8, 8) at the window starts, the offset's slow part there ``slow`` (m/s^2), the update ``log``
    (a row per window, :data:`PLANAR_MEASUREMENTS`), and the inputs and model it ran with."""

    xs: np.ndarray
    Ps: np.ndarray
    slow: np.ndarray
    log: kalman.UpdateLog
    inputs: PlanarInputs
    model: PlanarModel

    def outages(self, starts: np.ndarray, n_windows: int,
                still: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every outage from the state at its start (:func:`outage_kernel`): distance (m) and yaw
        rate (rad/s, counter-clockwise) per window, ``(len(starts), n_windows)``, and the filter's
        east/north position covariance (m^2) at every boundary, ``(len(starts), n_windows + 1, 2, 2)``."""
        # writable copies: a read-only array is another type to numba (another compilation)
        return outage_kernel((self.xs, self.Ps, self.slow), self.inputs, self.model, np.array(starts, dtype=np.int64),
                             int(n_windows), np.array(still, dtype=np.bool_))


def forward_pass(windows: Windows, meas: Measurements, inc: Increments, accel_offset: float, gyro_bias: float,
                 noise: EkfNoise, keep_log: bool = False) -> ForwardPass:
    """The filter over the whole drive from the starting biases ``accel_offset`` (m/s^2) and
    ``gyro_bias`` (rad/s); ``keep_log``: keep every update's innovation (:class:`ForwardPass`)."""
    inputs, model = planar_inputs(windows, meas, inc), planar_model(noise, inc.T)
    log = kalman.update_log(len(windows) if keep_log else 0, len(PLANAR_MEASUREMENTS))
    xs, Ps, slow = _forward_kernel(inputs, model, float(accel_offset), float(gyro_bias), log)
    return ForwardPass(xs, Ps, slow, log, inputs, model)


def forward_states(windows: Windows, meas: Measurements, inc: Increments, accel_offset: float, gyro_bias: float,
                   noise: EkfNoise) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`forward_pass`'s states, covariances and the offset's slow part."""
    fp = forward_pass(windows, meas, inc, accel_offset, gyro_bias, noise)
    return fp.xs, fp.Ps, fp.slow


@dataclass
class SensorCalibration:
    """What the filter knows about the sensors at each window start, having seen GNSS only
    before it (arrays over windows): the accelerometer offset (m/s^2) as its slow part (bias and
    mount tilt) and the road grade there, the gyro bias (rad/s, on the counter-clockwise rate) and
    its scale error.

    A sample ``d`` metres of road later is corrected as the filter propagates an outage: ``f -
    (accel_slow_mps2 + accel_grade_mps2 exp(-d / GRADE_LENGTH_M))`` and ``(omega - gyro_bias_radps)
    / (1 + gyro_scale)``.
    """

    accel_slow_mps2: np.ndarray
    accel_grade_mps2: np.ndarray
    gyro_bias_radps: np.ndarray
    gyro_scale: np.ndarray

    def at(self, idx: np.ndarray) -> SensorCalibration:
        """The calibration at windows ``idx`` (any shape)."""
        return SensorCalibration(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))

    def accel(self, accel_mps2: np.ndarray, distance_m: np.ndarray | float = 0.0) -> np.ndarray:
        """Correct samples ``(..., steps)`` whose leading shape is this calibration's, ``distance_m``
        (same leading shape) of road after the calibration's window."""
        offset = self.accel_slow_mps2 + self.accel_grade_mps2 * np.exp(-np.asarray(distance_m) / GRADE_LENGTH_M)
        return accel_mps2 - offset[..., None]

    def gyro(self, gyro_radps: np.ndarray) -> np.ndarray:
        return (gyro_radps - self.gyro_bias_radps[..., None]) / (1.0 + self.gyro_scale[..., None])


#: The calibration's filter trusts the GNSS speed less (0.3 m/s) and lets the offset wander
#: less (0.05 m/s^2/sqrt(s)) than ``ekf``'s: a speed fitted to fixes (logs without a velocity
#: topic) lags in hard braking, and the IDNN must get the same inputs from such a log as from a
#: receiver's Doppler speed (measured: CRSE within 5 % between a CSV and its 5-10 Hz fix-only MCAP).
#: The scale walk and turn noise stay those the shipped IDNN was trained with (not ``ekf``'s honest
#: outage values): its inputs must not move under it.
CALIBRATION_NOISE = EkfNoise(gnss_speed_mps=0.3, accel_offset_walk_mps2=0.05, scale_walk=1e-4, turn_scale_sd=0.0)


def calibration(drive: Drive, windows: Windows, accel_offset: float, gyro_bias: float,
                noise: EkfNoise = CALIBRATION_NOISE) -> SensorCalibration:
    """The filter's sensor calibration at every window start (see :class:`SensorCalibration`),
    started from the standstill biases ``accel_offset`` (m/s^2) and ``gyro_bias`` (rad/s).

    From the IMU and GNSS alone, even where the drive has a vehicle speed: what calibrates the
    IDNN's inputs then does not depend on whether a log carries wheel speeds (a CSV and its MCAP
    conversion give the same calibration)."""
    meas = measurements(drive, windows, noise, use_vehicle_speed=False)
    xs, _, slow = forward_states(windows, meas, increments(windows), accel_offset, gyro_bias, noise)
    return SensorCalibration(slow, xs[:, BA] - slow, xs[:, BG].copy(), xs[:, S].copy())
