"""``ekf``: a GNSS-aided INS on the planar vehicle model, the baseline a practitioner would run.

The paper's INS restarts blind at every outage with the biases of a standstill. A filter running
over the drive while GNSS is good also learns the accelerometer offset (bias, mount tilt and the
slowly changing road grade) and the gyro bias as they are *at the outage*, and starts each
outage from its own speed estimate instead of one noisy GNSS speed.

State (7), on a local east-north plane (m) around the drive's first fix::

    x = [e, n, v, psi, b_a, b_g, k]

``e, n`` position (m), ``v`` speed along the course (m/s), ``psi`` course (rad, clockwise from
north, as GNSS gives it), ``b_a`` accelerometer offset (m/s^2), ``b_g`` gyro bias (rad/s, on the
counter-clockwise yaw rate), ``k`` the vehicle-speed scale (the drive's vehicle speed, converted
with the nominal wheel radius, over the true speed).

Propagation, once per 1-second window from its 11 inertial samples (trapezoid integrals over the
window: ``F = int f dt``, ``G = int int f dt dt``, ``W = int omega dt``)::

    v'   = v + F - b_a T                 psi' = psi - (W - b_g T)
    d    = v T + G - b_a T^2 / 2         (distance along the window)
    e'   = e + d sin(psi_mid)            n' = n + d cos(psi_mid),  psi_mid = psi - (W - b_g T) / 2

with its Jacobian for the covariance, and process noise from the sensors' white noise and the
offsets' random walks (:class:`EkfNoise`).

Measurements at each window boundary where GNSS is good (the windows on both sides have good
truth): position (sigma :attr:`EkfNoise.gnss_position_m`, or the receiver's own when the drive has
``gnss_sigma_m``), speed, and course while faster than 3 m/s (its noise grows as 1/speed). Where
the drive has a vehicle speed (:func:`ionav_viz.nav.odometry.vehicle_speed`) it is a measurement
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
0.05 m/s, and an offset random walk of 0.1 m/s^2/sqrt(s) loose enough to follow the road grade.
Measured on those drives with the vehicle speed left out (`python benchmarks/ekf_tuning.py`):
displacement CRSE 0.24-0.96 of the INS DR's, the motorway (grade changing within an outage at
26 m/s) the closest.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.drive import Drive
from ..core.geo import local_en_m
from .odometry import NOMINAL_RADIUS_M, vehicle_speed

if TYPE_CHECKING:
    from .estimators import Estimate, EstimatorInputs
    from .windows import Windows

E, N, V, PSI, BA, BG, K = range(7)
N_STATES = 7
MIN_COURSE_SPEED_MPS = 3.0
#: The accelerometer offset's slow part (bias, mount tilt) is its mean over about this long (s);
#: the rest is road grade, which an outage does not keep: it fades over GRADE_LENGTH_M of road.
OFFSET_MEMORY_S = 120.0
GRADE_LENGTH_M = 150.0


@dataclass(frozen=True)
class EkfNoise:
    """Noise of the filter (1 sigma; random walks per sqrt(s)); see the module docstring."""

    accel_white_mps2: float = 0.3
    gyro_white_radps: float = np.deg2rad(0.25)
    accel_offset_walk_mps2: float = 0.1
    gyro_bias_walk_radps: float = np.deg2rad(0.005)
    scale_walk: float = 1e-4
    gnss_position_m: float = 1.0
    gnss_speed_mps: float = 0.05
    gnss_course_rad_at_10mps: float = np.deg2rad(0.5)
    vehicle_speed_mps: float = 0.15
    init_position_m: float = 1.0
    init_speed_mps: float = 0.2
    init_course_rad: float = np.deg2rad(2.0)
    init_accel_offset_mps2: float = 0.3
    init_gyro_bias_radps: float = np.deg2rad(0.5)
    init_scale: float = 0.05


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
    v_rel = np.concatenate([np.zeros((len(acc), 1)), np.cumsum(dv, axis=1)], axis=1)  # speed gained since the window start
    G = (0.5 * (v_rel[:, 1:] + v_rel[:, :-1]) * h).sum(axis=1)
    W = (0.5 * (gyr[:, 1:] + gyr[:, :-1]) * h).sum(axis=1)
    return Increments(dv.sum(axis=1), G, W, h * (acc.shape[1] - 1))


def propagate(x: np.ndarray, P: np.ndarray, F: np.ndarray, G: np.ndarray, W: np.ndarray, T: float,
              noise: EkfNoise) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One window for a batch of filters (``x`` (m, 7), ``P`` (m, 7, 7)): the new state and
    covariance, the distance along the window (m) and its mean yaw rate (rad/s, CCW +)."""
    v, psi, ba, bg = x[:, V], x[:, PSI], x[:, BA], x[:, BG]
    turn = W - bg * T  # counter-clockwise, rad
    mid = psi - 0.5 * turn
    d = v * T + G - 0.5 * ba * T * T
    s, c = np.sin(mid), np.cos(mid)
    out = x.copy()
    out[:, E] += d * s
    out[:, N] += d * c
    out[:, V] = v + F - ba * T
    out[:, PSI] = psi - turn
    J = np.broadcast_to(np.eye(N_STATES), P.shape).copy()
    # d(e, n) / d(v, psi, b_a, b_g); psi_mid depends on psi and (through the turn) on b_g
    for row, a, b in ((E, s, c), (N, c, -s)):
        J[:, row, V] = T * a
        J[:, row, PSI] = d * b
        J[:, row, BA] = -0.5 * T * T * a
        J[:, row, BG] = d * b * 0.5 * T
    J[:, V, BA] = -T
    J[:, PSI, BG] = T
    q = np.zeros(N_STATES)
    q[E] = q[N] = 0.01 * T
    q[V] = noise.accel_white_mps2**2 * T / 10.0  # white noise per 0.1 s sample, summed over the window
    q[PSI] = noise.gyro_white_radps**2 * T / 10.0
    q[BA] = noise.accel_offset_walk_mps2**2 * T
    q[BG] = noise.gyro_bias_walk_radps**2 * T
    q[K] = noise.scale_walk**2 * T
    P_new = J @ P @ J.transpose(0, 2, 1) + np.diag(q)
    return out, P_new, d, turn / T


def update(x: np.ndarray, P: np.ndarray, H: np.ndarray, z: np.ndarray, h_x: np.ndarray, r: np.ndarray,
           use: np.ndarray, wrap: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Scalar measurement ``z = h(x)`` (linearised ``H`` (m, 7)) with variance ``r`` for the
    filters where ``use`` (m,) is True; angles (``wrap``) use the wrapped innovation."""
    innov = z - h_x
    if wrap:
        innov = (innov + np.pi) % (2 * np.pi) - np.pi
    PHt = np.einsum("mij,mj->mi", P, H)
    S = np.einsum("mi,mi->m", H, PHt) + r
    gain = PHt / S[:, None]
    gain[~use] = 0.0
    x = x + gain * innov[:, None]
    P = P - gain[:, :, None] * PHt[:, None, :]
    return x, 0.5 * (P + P.transpose(0, 2, 1))


def _unit_row(i: int, m: int) -> np.ndarray:
    H = np.zeros((m, N_STATES))
    H[:, i] = 1.0
    return H


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


def measurements(drive: Drive, windows: Windows, noise: EkfNoise) -> Measurements:
    """What the filter is updated with, at the start of every window and the end of the last."""
    lat = np.concatenate([windows.lat0_deg, windows.lat1_deg[-1:]])
    lon = np.concatenate([windows.lon0_deg, windows.lon1_deg[-1:]])
    e, n = local_en_m(lat, lon, float(lat[0]), float(lon[0]))
    speed = np.concatenate([windows.speed0_mps, windows.speed0_mps[-1:]])
    course = np.deg2rad(np.concatenate([windows.heading0_deg, windows.heading1_deg[-1:]]))
    ok = windows.truth_ok
    good = np.concatenate([[ok[0]], ok[1:] & ok[:-1], [ok[-1]]])  # both windows around the boundary
    sigma = np.full(len(lat), noise.gnss_position_m)
    if "gnss_sigma_m" in drive.columns:
        t = np.concatenate([windows.t0_s, windows.t0_s[-1:] + 1.0])
        sigma = np.maximum(np.interp(t, drive.t_s, drive.columns["gnss_sigma_m"]), 0.3)
    vehicle = np.full(len(windows), np.nan)
    found = vehicle_speed(drive)
    if found is not None:
        values, unit, _ = found
        per_s = values * (NOMINAL_RADIUS_M if unit == "rad/s" else 1.0)
        steps = int(round(windows.rate_hz))
        vehicle = np.interp(windows.t0_s + steps / windows.rate_hz, drive.t_s, per_s)  # at each window's end
    return Measurements(e, n, speed, course, good, sigma, vehicle)


def _gnss_update(x, P, meas: Measurements, i: np.ndarray, noise: EkfNoise, use: np.ndarray):
    m = len(x)
    for idx, z, r in ((E, meas.e[i], meas.sigma_m[i] ** 2), (N, meas.n[i], meas.sigma_m[i] ** 2),
                      (V, meas.speed[i], np.full(m, noise.gnss_speed_mps**2))):
        x, P = update(x, P, _unit_row(idx, m), z, x[:, idx], r, use)
    fast = use & (meas.speed[i] > MIN_COURSE_SPEED_MPS)
    r = (noise.gnss_course_rad_at_10mps * 10.0 / np.maximum(meas.speed[i], 1.0)) ** 2
    return update(x, P, _unit_row(PSI, m), meas.course[i], x[:, PSI], r, fast, wrap=True)


def _vehicle_update(x, P, z: np.ndarray, noise: EkfNoise):
    use = np.isfinite(z)
    H = np.zeros((len(x), N_STATES))
    H[:, V], H[:, K] = x[:, K], x[:, V]
    return update(x, P, H, np.where(use, z, 0.0), x[:, K] * x[:, V], np.full(len(x), noise.vehicle_speed_mps**2), use)


def _initial(meas: Measurements, i: int, accel_offset: float, gyro_bias: float, noise: EkfNoise, prior=None):
    x = np.array([meas.e[i], meas.n[i], meas.speed[i], meas.course[i], accel_offset, gyro_bias, 1.0])
    sd = [noise.init_position_m, noise.init_position_m, noise.init_speed_mps, noise.init_course_rad,
          noise.init_accel_offset_mps2, noise.init_gyro_bias_radps, noise.init_scale]
    P = np.diag(np.square(sd))
    if prior is not None:  # after a gap: keep what was learnt about the sensors
        x[BA:], P[BA:, BA:] = prior[0][BA:], prior[1][BA:, BA:]
    return x, P


def forward(drive: Drive, windows: Windows, accel_offset: float, gyro_bias: float, noise: EkfNoise = EkfNoise()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The filter over the whole drive: its state and covariance at the start of every window,
    having used the GNSS of earlier boundaries only (shapes (n_windows, 7) and (n_windows, 7, 7)),
    and the offset's slow part there (its mean over the last ~OFFSET_MEMORY_S, (n_windows,))."""
    return _forward(windows, measurements(drive, windows, noise), increments(windows), accel_offset, gyro_bias, noise)


def _forward(windows: Windows, meas: Measurements, inc: Increments, accel_offset: float, gyro_bias: float,
             noise: EkfNoise) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    nw = len(windows)
    xs, Ps = np.zeros((nw, N_STATES)), np.zeros((nw, N_STATES, N_STATES))
    slow = np.zeros(nw)
    mean = accel_offset
    alpha = inc.T / OFFSET_MEMORY_S
    x = P = None
    for k in range(nw):
        if x is None or windows.segment[k] != windows.segment[k - 1]:
            x, P = _initial(meas, k, accel_offset, gyro_bias, noise, None if x is None else (x[0], P[0]))
            x, P = x[None], P[None]
        else:
            x, P = _gnss_update(x, P, meas, np.array([k]), noise, np.array([bool(meas.good[k])]))
        xs[k], Ps[k] = x[0], P[0]
        mean += alpha * (x[0, BA] - mean)
        slow[k] = mean
        x, P, _, _ = propagate(x, P, inc.F[k : k + 1], inc.G[k : k + 1], inc.W[k : k + 1], inc.T, noise)
        x, P = _vehicle_update(x, P, meas.vehicle[k : k + 1], noise)
    return xs, Ps, slow


class EkfEstimator:
    """A GNSS-aided INS (see the module docstring)."""

    name = "ekf"
    label = "GNSS-aided INS"
    color = (0, 170, 190)

    def __init__(self, noise: EkfNoise | None = None) -> None:
        self.noise = noise or EkfNoise()
        self._last: dict[str, Any] = {}

    def available(self) -> bool:
        return True

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        from .estimators import Estimate

        w = inputs.windows
        meas, inc = measurements(inputs.drive, w, self.noise), increments(w)
        xs, Ps, slow = _forward(w, meas, inc, inputs.bias.accel_mps2, inputs.bias.gyro_radps, self.noise)
        x, P = xs[inputs.starts].copy(), Ps[inputs.starts].copy()
        grade0, base = x[:, BA] - slow[inputs.starts], slow[inputs.starts]
        travelled = np.zeros(inputs.n_outages)
        disp = np.zeros((inputs.n_outages, inputs.n_windows))
        yaw = np.zeros_like(disp)
        for j in range(inputs.n_windows):
            k = inputs.starts + j
            # the fast part of the offset is road grade: it fades over GRADE_LENGTH_M of road
            x[:, BA] = base + grade0 * np.exp(-travelled / GRADE_LENGTH_M)
            x, P, disp[:, j], yaw[:, j] = propagate(x, P, inc.F[k], inc.G[k], inc.W[k], inc.T, self.noise)
            travelled += np.maximum(disp[:, j], 0.0)
            x, P = _vehicle_update(x, P, meas.vehicle[k], self.noise)
        if len(inputs.starts):
            start = xs[inputs.starts]
            self._last = {"accel_offset_mps2": f"{np.median(start[:, BA]):+.3f} (median at the outage starts)",
                          "gyro_bias_radps": f"{np.median(start[:, BG]):+.5f}",
                          "vehicle_speed": "used" if np.isfinite(meas.vehicle).any() else "none"}
        return Estimate(np.maximum(disp, 0.0), yaw)

    def describe(self) -> dict[str, Any]:
        return dict(self._last)
