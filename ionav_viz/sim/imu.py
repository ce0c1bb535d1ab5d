"""Drives with a full 6-axis IMU, a GNSS receiver and a reference truth, as a car's logger records
them: the evidence for the 3D GNSS/INS (:mod:`ionav_viz.nav.gins`), written as MCAP logs.

Vehicle (truth, 100 Hz, from :func:`~ionav_viz.sim.simulate.plan_truth`'s speed and curvature)
    A car with no side slip on a 3D road: yaw from the curvature, pitch from a road grade and roll
    from a road camber (both smooth random functions of distance). The attitude is
    ``C_b^n = Rz(alpha) Ry(-pitch) Rx(roll)`` (body x forward, y left, z up; n east-north-up, a
    tangent frame fixed to the Earth at a random origin in England; ``alpha`` counter-clockwise
    from east), the velocity ``v C_b^n e_x``. The IMU senses the body rates plus the Earth's
    rotation, and the specific force ``f = a + 2 Omega x v - g(p)`` with normal gravity pointing
    to the Earth's centre wherever the car is (:func:`ionav_viz.core.geo.gravity_enu_mps2`), so
    the log is physically consistent in 3D: grade and camber put gravity into the forward and
    lateral axes exactly as on a road.

IMU grades (:data:`IMU_GRADES`, per ``../shared/SENSORS.md``)
    ``mems``: a roof or dashboard MEMS IMU at 100 Hz (gyro turn-on bias 50 deg/h per axis and
    angle random walk 0.24 deg/sqrt(h), velocity random walk 0.24 m/s/sqrt(h): SENSORS.md's consumer
    MEMS, KF-GINS's configuration for one; accelerometer bias 0.05 m/s^2; scale errors 0.3 %;
    engine and road vibration as measured: gyro 0.06 deg/s standing, 0.15 driving; accelerometer
    0.13 m/s^2 standing, growing with speed to 0.3), mounted about 2 degrees off the car in yaw and
    under 1 degree in pitch and roll (what a fit leaves of a configured roof mount), an automotive
    receiver at 10 Hz (about 1.4 m median error, as SENSORS.md's u-blox, wandering with a 30 s
    correlation time) and the CAN vehicle speed (1-3 % off through the wheel radius, 1 km/h steps,
    50 ms late).
    ``phone``: a phone in a dashboard holder at 10 Hz, single readings (gyro bias 0.3 deg/s per
    axis, up to the 0.7 SENSORS.md saw; accelerometer bias 0.15 m/s^2; 1 % scale errors; random
    walks 0.8 deg/sqrt(h) and 0.3 m/s/sqrt(h), a phone IMU's noise densities of about
    0.014 deg/s/sqrt(Hz) and 100-300 ug/sqrt(Hz); standing as quiet as real phones are, 0.06 deg/s
    and 0.03 m/s^2 per sample, with a slow sway of 0.06 deg/s; driving, the holder's vibration and
    wobble: gyro 0.5 deg/s and a 2 deg/s wobble, accelerometer to 0.45 m/s^2), turned 8 degrees
    in yaw and 1 in pitch on its holder and tilting on it with the car's acceleration, its clock
    steady to 10 us with a sample lost now and then, and its GPS at 1 Hz (about 3 m median error,
    reporting 8 m), no vehicle speed. Each number against the public real logs it comes from: the
    comment above :data:`IMU_GRADES` and ``docs/real-imu-logs.md``.
    ``roof``: a roof MEMS IMU with an RTK receiver at 4 Hz: the mems grade, standing as quiet as
    the sensor (0.03 deg/s, 0.02 m/s^2 per sample) and driving through the engine's and the road's
    vibration (0.57 deg/s, 0.17 m/s^2), as a real roof log measures.
    ``dash``: a dash device on the windshield (comma2k19's EON): a phone-class IMU at 104 Hz,
    averaged by the reader, wobbling 0.5 deg/s on pitch and roll, a u-blox at 10 Hz, no vehicle
    speed.
    Biases are a turn-on value plus a first-order Gauss-Markov wander (``bias_tau_s``).

Noise: two parts, because they integrate differently
    SENSORS.md's noise table is the spread of 10 Hz samples on real cars, and most of it is
    vibration: the engine and the road shaking the sensor, a real motion that stays within
    centimetres (and hundredths of a degree). Its integral is that motion, not a random walk, so it
    is simulated as the rate of change of a bounded Gauss-Markov motion (:func:`vibration`, 50 ms
    correlation) whose 10 Hz samples spread as the table says (the successive-difference spread
    over sqrt(2), as the table and :func:`ionav_viz.nav.gins.sensor_noise` measure).
    The sensor's own white noise is its datasheet random walk (``*_random_walk``), tens of times
    smaller per sample; it is what integrates. Drawn as white noise at the table's level, a MEMS
    gyro would walk at 2.9 deg/sqrt(h), twelve times SENSORS.md's 0.24.

Output is identical for a given scenario, seed, duration and grade.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numba import njit

from ..core.drive import IMU_COLUMNS, Drive
from ..core.errors import InputError
from ..core.fileio import check_output_file
from ..core.geo import earth_rate_enu_radps, geodetic_of_enu, gravity_enu_mps2, normal_gravity_mps2
from ..core.rotation import dcm_of_euler_series
from ..core.units import wrap_360
from ..sources.imu.mount import rotation_deg
from ..sources.iovnbd import HEADER
from ..sources.mcap_writer import TRUTH_TOPIC, write_mcap
from .simulate import (
    SIMULATED_SCENARIOS,
    TRUTH_RATE_HZ,
    SensorModel,
    can_speeds,
    gauss_markov,
    grade_profile,
    plan_truth,
)


@dataclass(frozen=True)
class ImuGrade:
    """The sensors of one kind of logger (see the module docstring): biases and vibration as 1
    sigma at 10 Hz, the white noise as random walks (deg/sqrt(h), m/s/sqrt(h))."""

    name: str
    imu_rate_hz: float
    gnss_rate_hz: float
    gyro_bias_dps: float
    gyro_instability_dps: float
    gyro_scale: float
    gyro_vibration_still_dps: float
    gyro_vibration_driving_dps: float
    gyro_random_walk_dps_rthr: float
    accel_bias_mps2: float
    accel_instability_mps2: float
    accel_scale: float
    accel_vibration_still_mps2: float
    accel_vibration_per_mps: float
    accel_vibration_max_mps2: float
    accel_random_walk_mps_rthr: float
    bias_tau_s: float
    mount_deg: tuple[float, float, float]
    mount_spread_deg: float
    gnss_wander_m: float
    gnss_tau_s: float
    gnss_white_m: float
    gnss_reported_sigma_m: float
    gnss_speed_noise_mps: float
    clock_jitter_s: float
    missing_sample_prob: float
    vehicle_speed: bool
    grade_rms: float = 0.03
    camber_rms: float = 0.015
    #: each sample one instantaneous reading (a phone's sensor event) instead of the mean over its
    #: interval: what the car and the holder shake faster than half the rate aliases into it
    single_readings: bool = False
    #: the holder's wobble while driving: its pitch and roll rates' spread (deg/s, 1 sigma, a share
    #: of it on yaw and standing below), a resonance near ``holder_wobble_hz``
    holder_wobble_dps: float = 0.0
    holder_wobble_hz: float = 8.0
    #: the wobble's share on the yaw rate and, standing, its share of ``holder_wobble_dps``
    holder_wobble_yaw_share: float = 1.0 / 3.0
    holder_wobble_still_share: float = 0.2
    #: the IMU's stamps minus the receiver's for one instant (s; positive: the IMU is stamped late)
    clock_offset_s: float = 0.0
    #: the receiver's speed is the car's this long ago (s): a phone's location service smooths it
    #: (0.5-1.0 s on six of the seven real iPhone logs, 1.6 s on a car data logger's,
    #: docs/real-imu-logs.md), where a GNSS chip's Doppler speed is of its epoch. Its course and
    #: positions are left of their epoch (on the real logs the course lags the gyro by 0.1-0.4 s, far
    #: less than the speed; the steps between fixes are too noisy to show a lag)
    gnss_speed_lag_s: float = 0.0
    #: the receiver losing the sky (no fix at all, as a phone's own receiver in a city): losses at
    #: this rate (per 10 minutes, Poisson), each ``gnss_loss_s`` long (s, log-uniform between the two)
    gnss_losses_per_10min: float = 0.0
    gnss_loss_s: tuple[float, float] = (2.0, 20.0)
    #: a loose holder: the sensor tilts on it by this much per m/s^2 of horizontal specific force
    #: (deg; pitch with the forward, roll with the lateral), settling with ``holder_flex_tau_s``
    holder_flex_deg_per_mps2: float = 0.0
    holder_flex_tau_s: float = 0.3
    #: a slow sway of the sensor's rates on all axes (deg/s, 1 sigma; a Gauss-Markov rate of
    #: correlation ``gyro_sway_tau_s``): what makes a real phone's standing gyro spread more over a
    #: second than its successive samples say (its Allan deviation at 1 s)
    gyro_sway_dps: float = 0.0
    gyro_sway_tau_s: float = 1.0


IMU_GRADES = {
    "mems": ImuGrade("mems", 100.0, 10.0, gyro_bias_dps=50.0 / 3600.0, gyro_instability_dps=0.005, gyro_scale=0.003,
                     gyro_vibration_still_dps=0.06, gyro_vibration_driving_dps=0.15, gyro_random_walk_dps_rthr=0.24,
                     accel_bias_mps2=0.05, accel_instability_mps2=0.01, accel_scale=0.003,
                     accel_vibration_still_mps2=0.13, accel_vibration_per_mps=0.008, accel_vibration_max_mps2=0.3,
                     accel_random_walk_mps_rthr=0.24, bias_tau_s=600.0, mount_deg=(0.5, -0.7, 2.2),
                     mount_spread_deg=0.3, gnss_wander_m=1.2, gnss_tau_s=30.0, gnss_white_m=0.1,
                     gnss_reported_sigma_m=1.5, gnss_speed_noise_mps=0.05, clock_jitter_s=0.0005,
                     missing_sample_prob=0.0, vehicle_speed=True),
    # The phone and the dash device as public real logs show them, measured the same way on both
    # sides by benchmarks/imu_character.py (docs/real-imu-logs.md; the real logs: cloudpose_iphonex_ds1
    # an iPhone X in a dash holder at 10 Hz, cmu_* iPhones polled at 5 Hz, meszdav_* iPhones lying flat
    # at 100 Hz, comma2k19_example1 a comma EON on the windshield at 104 Hz). Per 10 Hz sample:
    #   gyro standing 0.06-0.07 deg/s (cmu, cloudpose), Allan deviation at 1 s 0.028-0.045 (cmu_03_26_trip1,
    #   cloudpose); accelerometer standing 0.02-0.04 m/s^2 (cmu_04_02_trip1, cloudpose): far below
    #   SENSORS.md's 10 Hz table (0.05-0.14 deg/s, 0.13-0.28 m/s^2, engine vibration through a car's
    #   own sensors), which the mems grade follows; SENSORS.md's consumer section (a phone 0.10 deg/s
    #   standing, 1.03 driving: "only standstill stretches measure the sensor") is what the phone follows;
    #   holder wobble (pitch and roll rates) standing 0.06-0.17, driving 1.6-2.7 deg/s (holders:
    #   cloudpose, cmu), 0.5-1.8 (flat, windshield); driving noise gyro 0.60-4.5 deg/s, accelerometer
    #   0.38-0.60 m/s^2 (holders); sample periods within 0.01-0.06 ms of each other and under
    #   0.03 % of them doubled (all logs; SENSORS.md: 0.099-0.101 s, "occasional" doubled periods).
    #   The receiver's speed 0.5-1.0 s behind the IMU's forward acceleration on six of the seven
    #   meszdav iPhone logs (0.48, 0.48, 0.63, 0.73, 0.98, 1.02 s; the seventh 0.0), 1.6 s on
    #   cloudpose's car logger (core.gnss_lag, docs/real-imu-logs.md): 0.7 s, their median.
    #   The phones' own receivers (meszdav, cmu; benchmarks/imu_character.py --max-sigma-m 13) start
    #   cold for 0-14 s (median 8 s) and then lose the sky 0-9.0 times per 10 min (median 2.8) for
    #   2-53 s (their medians 3-10 s): 2.8 losses per 10 min of 2-30 s (log-uniform: median 7.7 s).
    #   A real cold start gives fixes the quality check does not trust (wandering, 16-65 m reported),
    #   not none, so it is not drawn here (tests/test_consumer_imu.py builds one). How the fixes come
    #   back (SENSORS.md: jumping by metres before settling) is not measured: as good as before.
    #   Not resolved on any real log, so kept as assumptions: the holder's tilt under acceleration
    #   (0.4 deg per m/s^2), the clock offset (40 ms, SENSORS.md's "under 0.1 s"), the biases.
    #   Left as it was: the roads' grade (3 % rms). The forward accelerometer's offset from the GNSS
    #   acceleration wanders by 0.36-0.44 m/s^2 within 10 s on the phones in holders (hilly Austin
    #   and Pittsburgh; 0.56 on the dash device's hilly highway, 0.08-0.30 on the flat phones in
    #   Hungary), 0.11-0.32 on the simulated phone drives: grade in 6 % rms closes that, but the logs
    #   cannot tell grade from a holder's tilt or bias wander, and the INS DR then errs by 26 % of the
    #   distance after 10 s against the real phone's 18.6 % (docs/real-imu-logs.md).
    "phone": ImuGrade("phone", 10.0, 1.0, gyro_bias_dps=0.3, gyro_instability_dps=0.02, gyro_scale=0.01,
                      gyro_vibration_still_dps=0.025, gyro_vibration_driving_dps=0.5, gyro_random_walk_dps_rthr=0.8,
                      accel_bias_mps2=0.15, accel_instability_mps2=0.02, accel_scale=0.01,
                      accel_vibration_still_mps2=0.03, accel_vibration_per_mps=0.05, accel_vibration_max_mps2=0.45,
                      accel_random_walk_mps_rthr=0.3, bias_tau_s=300.0, mount_deg=(0.5, 1.0, 8.0), mount_spread_deg=1.0,
                      gnss_wander_m=2.5, gnss_tau_s=60.0, gnss_white_m=0.5, gnss_reported_sigma_m=8.0,
                      gnss_speed_noise_mps=0.3, clock_jitter_s=1e-5, missing_sample_prob=0.0003, vehicle_speed=False,
                      single_readings=True, holder_wobble_dps=2.0, holder_wobble_hz=8.0, holder_wobble_still_share=0.04,
                      clock_offset_s=0.04, holder_flex_deg_per_mps2=0.4, gyro_sway_dps=0.06, gyro_sway_tau_s=1.0,
                      gnss_speed_lag_s=0.7, gnss_losses_per_10min=2.8, gnss_loss_s=(2.0, 30.0)),
    # comma2k19_example1 (60 s, no stand): 104 Hz averaged by the reader, gyro 0.07-0.10 deg/s and
    # accelerometer 0.15 m/s^2 per 10 Hz sample driving, wobble 0.5 deg/s (pitch and roll; little on
    # yaw), offset wander 0.56 m/s^2 in 10 s (0.3-0.4 simulated, the roads' grade left at 3 %), its
    # mount roll 0.7, pitch 3.8, yaw -0.8 deg, a u-blox at 10 Hz. A phone-class IMU (the EON is a
    # phone): biases, random walks and standing noise the phone's.
    "dash": ImuGrade("dash", 104.0, 10.0, gyro_bias_dps=0.3, gyro_instability_dps=0.02, gyro_scale=0.01,
                     gyro_vibration_still_dps=0.05, gyro_vibration_driving_dps=0.05, gyro_random_walk_dps_rthr=0.8,
                     accel_bias_mps2=0.15, accel_instability_mps2=0.02, accel_scale=0.01,
                     accel_vibration_still_mps2=0.03, accel_vibration_per_mps=0.005, accel_vibration_max_mps2=0.2,
                     accel_random_walk_mps_rthr=0.3, bias_tau_s=300.0, mount_deg=(0.7, 3.8, -0.8), mount_spread_deg=1.0,
                     gnss_wander_m=1.2, gnss_tau_s=30.0, gnss_white_m=0.1, gnss_reported_sigma_m=1.5,
                     gnss_speed_noise_mps=0.05, clock_jitter_s=1e-5, missing_sample_prob=0.0, vehicle_speed=False,
                     holder_wobble_dps=1.0, holder_wobble_hz=8.0, holder_wobble_yaw_share=0.1),
}
# A roof MEMS IMU with an RTK receiver, as issue 59's held-out roof log measures (its statistics
# only; the log is not public): per 10 Hz sample, standing accelerometer 0.02 m/s^2 and gyro
# 0.0005 rad/s (0.03 deg/s), the sensor's own noise; driving 0.17 m/s^2 and 0.010 rad/s (0.57 deg/s),
# the engine's and the road's vibration, 8 and 21 times that. RTK at 4 Hz (SENSORS.md: cm). The
# rest is the mems grade's. What it is for: a filter that weighs its mechanisation by the standstill
# noise trusts it through the vibration (the regression of issue 59, 2.2 -> 4.4 % after 10 s there).
IMU_GRADES["roof"] = replace(IMU_GRADES["mems"], name="roof", gnss_rate_hz=4.0, gyro_vibration_still_dps=0.03,
                             gyro_vibration_driving_dps=0.57, accel_vibration_still_mps2=0.02,
                             accel_vibration_per_mps=0.012, accel_vibration_max_mps2=0.17, gnss_wander_m=0.02,
                             gnss_white_m=0.01, gnss_reported_sigma_m=0.03, gnss_speed_noise_mps=0.02)

#: Where the simulated logs carry the reference truth (a NavSatFix, read with ``--truth-topic``).
SIM_TRUTH_TOPIC = TRUTH_TOPIC


@dataclass
class Motion3d:
    """Exact 3D motion at ``TRUTH_RATE_HZ``: time (s), position (m, east-north-up tangent frame),
    velocity (m/s, same frame), attitude ``C_b^n`` (n, 3, 3), and the ideal IMU in the body frame:
    specific force (m/s^2) and angular rate against inertial space (rad/s)."""

    t_s: np.ndarray
    position_m: np.ndarray
    velocity_mps: np.ndarray
    attitude: np.ndarray
    specific_force_mps2: np.ndarray
    angular_rate_radps: np.ndarray
    speed_mps: np.ndarray
    origin: tuple[float, float, float]


def _cumtrapz(x: np.ndarray, dt: float) -> np.ndarray:
    return np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(0.5 * (x[1:] + x[:-1]) * dt, axis=0)])


def motion_3d(scenario: str, seed: int, duration_s: float, grade_rms: float, camber_rms: float) -> Motion3d:
    """The exact motion of a scenario's drive in 3D (see the module docstring)."""
    truth = plan_truth(scenario, seed, duration_s)
    rng = np.random.default_rng([seed, 5000 + SIMULATED_SCENARIOS.index(scenario)])
    dt = 1.0 / TRUTH_RATE_HZ
    t, v, a = truth.t_s, truth.speed_mps, truth.accel_mps2
    distance = _cumtrapz(v, dt)
    alpha = rng.uniform(-np.pi, np.pi) + _cumtrapz(v * truth.curvature_1pm, dt)
    # pitch in the package's sense (core/rotation.py: positive nose-down), so a climb is negative
    pitch = -np.arctan(grade_profile(rng, distance, grade_rms))
    roll = np.arctan(grade_profile(rng, distance, camber_rms))
    origin = (float(rng.uniform(52.0, 53.0)), float(rng.uniform(-2.2, -0.7)), float(rng.uniform(50.0, 150.0)))
    C = dcm_of_euler_series(roll, pitch, alpha)
    # body rates of C = Rz(alpha) Ry(pitch) Rx(roll) (the Euler-angle kinematics)
    da, db, dr = np.gradient(alpha, dt), np.gradient(pitch, dt), np.gradient(roll, dt)
    sb, cb, sr, cr = np.sin(pitch), np.cos(pitch), np.sin(roll), np.cos(roll)
    w_nb = np.column_stack([dr - sb * da, cr * db + sr * cb * da, -sr * db + cr * cb * da])
    velocity = v[:, None] * C[:, :, 0]
    position = _cumtrapz(velocity, dt)
    accel_n = np.einsum("nij,nj->ni", C, np.column_stack([a, v * w_nb[:, 2], -v * w_nb[:, 1]]))
    omega_ie = earth_rate_enu_radps(origin[0])
    gravity = gravity_enu_mps2(position, normal_gravity_mps2(origin[0], origin[2]))
    f_n = accel_n + 2.0 * np.cross(omega_ie, velocity) - gravity
    f_b = np.einsum("nji,nj->ni", C, f_n)
    w_ib = w_nb + np.einsum("nji,j->ni", C, omega_ie)
    return Motion3d(t, position, velocity, C, f_b, w_ib, v, origin)


#: Correlation time (s) of the simulated vibration's motion: engine and road shake at several Hz.
VIBRATION_TAU_S = 0.05
#: The sample interval (s) of SENSORS.md's noise table.
TABLE_INTERVAL_S = 0.1


def vibration(rng: np.random.Generator, t_s: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Vibration on three axes at sample times ``t_s`` (s): the rate of change of a bounded motion,
    so that its integral is that motion (centimetres, hundredths of a degree), never a random walk.

    The motion is a Gauss-Markov process (:data:`VIBRATION_TAU_S`) scaled so that the 0.1 s means
    of its rate spread by ``sigma`` (per sample, the signal's unit) as SENSORS.md measures noise:
    the successive differences of those means over sqrt(2). A 0.1 s mean of the rate is the
    motion's change over 0.1 s divided by 0.1 s, and for a Gauss-Markov motion of correlation
    ``rho`` over 0.1 s that spread is ``std * sqrt((1 - rho)(3 - rho)) / 0.1``.
    """
    n = len(t_s)
    dt = float(np.mean(np.diff(t_s))) if n > 1 else TABLE_INTERVAL_S
    rho = math.exp(-TABLE_INTERVAL_S / VIBRATION_TAU_S)
    scale = np.asarray(sigma, dtype=float) * TABLE_INTERVAL_S / math.sqrt((1.0 - rho) * (3.0 - rho))
    motion = (np.column_stack([gauss_markov(rng, n, dt, 1.0, VIBRATION_TAU_S) for _ in range(3)])
              * np.broadcast_to(scale, (n,))[:, None])
    rate = np.zeros_like(motion)
    rate[1:] = np.diff(motion, axis=0) / np.diff(t_s)[:, None]
    return rate


@njit(cache=True)
def _first_order(target, alpha):  # pragma: no cover - compiled
    """A first-order lag following ``target`` ``(n, k)`` with per-sample gains ``alpha`` (n,), from zero."""
    out = np.zeros_like(target)
    for i in range(1, target.shape[0]):
        for k in range(target.shape[1]):
            out[i, k] = out[i - 1, k] + alpha[i] * (target[i, k] - out[i - 1, k])
    return out


def flexed_holder(t_s: np.ndarray, f_b: np.ndarray, w_b: np.ndarray, mount: np.ndarray, deg_per_mps2: float,
                  tau_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The sensor's specific force and rate (its axes) on a holder that tilts with the car's
    horizontal specific force ``f_b`` (body frame, m/s^2): pitch ``deg_per_mps2`` per m/s^2 forward,
    roll the same per m/s^2 lateral, each settling with time constant ``tau_s`` (a spring and a
    damper). The tilt turns the mount (``body = mount @ flex @ sensor``) and its rate adds to the
    body's (the sensor turns with the holder)."""
    k = math.radians(deg_per_mps2)
    # roll, pitch (nose-down positive) towards what the force pushes
    target = np.column_stack([-k * f_b[:, 1], k * f_b[:, 0]])
    alpha = 1.0 - np.exp(-np.diff(t_s, prepend=t_s[0]) / tau_s)
    tilt = _first_order(np.ascontiguousarray(target), alpha)
    roll, pitch = tilt[:, 0], tilt[:, 1]
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    # flex = Ry(pitch) @ Rx(roll), per sample; body = mount @ flex @ sensor, so sensor = flex^T mount^T body
    flex = np.zeros((len(t_s), 3, 3))
    flex[:, 0, 0], flex[:, 0, 1], flex[:, 0, 2] = cp, sp * sr, sp * cr
    flex[:, 1, 1], flex[:, 1, 2] = cr, -sr
    flex[:, 2, 0], flex[:, 2, 1], flex[:, 2, 2] = -sp, cp * sr, cp * cr
    # small angles: about the holder's x, y
    rate = np.column_stack([np.gradient(roll, t_s), np.gradient(pitch, t_s), np.zeros(len(t_s))])
    f_m, w_m = f_b @ mount, w_b @ mount  # in the unflexed sensor axes
    f_s = np.einsum("nji,nj->ni", flex, f_m)
    w_s = np.einsum("nji,nj->ni", flex, w_m) + rate
    return f_s, w_s


#: The wobble is drawn on this fine a time line (Hz) and read at the sample times: instantaneous.
WOBBLE_RATE_HZ = 400.0


def holder_wobble(rng: np.random.Generator, t_s: np.ndarray, sigma_radps: np.ndarray, freq_hz: float,
                  yaw_share: float = 1.0 / 3.0) -> np.ndarray:
    """A holder's wobble on three axes (rad/s), read instantaneously at the sample times ``t_s``:
    the rate of a lightly damped resonance (white noise shaped by a second-order response, damping
    0.2, at ``freq_hz``) drawn at :data:`WOBBLE_RATE_HZ`, scaled per sample to ``sigma_radps`` ((n,) on
    pitch and roll; ``yaw_share`` of it on yaw). Sampled below twice ``freq_hz`` it aliases: successive
    samples are nearly independent, as a phone's are on a dashboard holder."""
    if len(t_s) < 2:
        return np.zeros((len(t_s), 3))
    h = 1.0 / WOBBLE_RATE_HZ
    n = int(math.ceil((t_s[-1] - t_s[0]) / h)) + 2
    # white noise shaped by the resonance's response |1 / (1 - (f/f0)^2 + 2 i zeta f/f0)| (numpy's FFT: no filter loop)
    f = np.fft.rfftfreq(n, h) / freq_hz
    response = 1.0 / np.abs(1.0 - f * f + 2j * 0.2 * f)
    fine = np.fft.irfft(np.fft.rfft(rng.normal(0.0, 1.0, (n, 3)), axis=0) * response[:, None], n, axis=0)
    fine /= fine.std(axis=0)
    idx = np.clip(np.rint((t_s - t_s[0]) / h).astype(np.int64), 0, n - 1)
    return fine[idx] * np.asarray(sigma_radps)[:, None] * np.array([1.0, 1.0, yaw_share])


@dataclass
class ImuLog:
    """A simulated log: the drive at the IMU's rate (the reference truth as its positions, the
    receiver's fixes in the receiver columns, the IMU in its own mounted axes), the rows that carry
    a GNSS fix, and the errors drawn for it: the mount (``body = mount @ sensor``), the turn-on
    biases (sensor axes; gyro rad/s, accelerometer m/s^2) and scale errors."""

    drive: Drive
    fix: np.ndarray
    mount: np.ndarray
    gyro_bias_radps: np.ndarray
    accel_bias_mps2: np.ndarray
    gyro_scale: np.ndarray
    accel_scale: np.ndarray


def imu_drive(scenario: str, seed: int = 0, duration_s: float = 300.0, grade: str | ImuGrade = "mems") -> ImuLog:
    """A simulated log of ``grade`` (a name of :data:`IMU_GRADES`, or a grade of one's own): what
    :func:`write_imu_log` writes."""
    if isinstance(grade, str) and grade not in IMU_GRADES:
        raise InputError(f"unknown IMU grade {grade!r}", f"choose one of {', '.join(IMU_GRADES)}", param="imu")
    g = IMU_GRADES[grade] if isinstance(grade, str) else grade
    m = motion_3d(scenario, seed, duration_s, g.grade_rms, g.camber_rms)
    rng = np.random.default_rng([seed, 6000 + SIMULATED_SCENARIOS.index(scenario), int(g.imu_rate_hz)])

    # IMU sample times: the IMU's own clock, jittered, a few samples lost
    n = int(round(duration_s * g.imu_rate_hz)) + 1
    t = np.arange(n) / g.imu_rate_hz
    t[1:-1] += rng.uniform(-g.clock_jitter_s, g.clock_jitter_s, n - 2)
    keep = rng.random(n) >= g.missing_sample_prob
    keep[[0, -1]] = True
    keep[:: int(round(g.imu_rate_hz / g.gnss_rate_hz))] = True  # the receiver's epochs stay (its own clock)
    t = t[keep]
    n = len(t)

    def at(x: np.ndarray) -> np.ndarray:
        return (np.column_stack([np.interp(t, m.t_s, x[:, k]) for k in range(x.shape[1])]) if x.ndim == 2
                else np.interp(t, m.t_s, x))

    speed = at(m.speed_mps)
    mount = rotation_deg(*(np.array(g.mount_deg) + rng.normal(0.0, g.mount_spread_deg, 3)))

    def sensed(x: np.ndarray) -> np.ndarray:
        """What the IMU stamped ``t`` sensed: at ``t - clock_offset_s`` on the receiver's time line."""
        return np.column_stack([np.interp(t - g.clock_offset_s, m.t_s, x[:, k]) for k in range(x.shape[1])])

    f_b, w_b = sensed(m.specific_force_mps2), sensed(m.angular_rate_radps)
    if g.holder_flex_deg_per_mps2 > 0:  # a loose holder: the mount tilts with the car's accelerations
        f_s, w_s = flexed_holder(t, f_b, w_b, mount, g.holder_flex_deg_per_mps2, g.holder_flex_tau_s)
    else:
        f_s, w_s = f_b @ mount, w_b @ mount  # sensor = mount^T body
    dt_mean = 1.0 / g.imu_rate_hz

    def wander(instability: float) -> np.ndarray:
        return np.column_stack([gauss_markov(rng, n, dt_mean, instability, g.bias_tau_s) for _ in range(3)])

    # the road's vibration starts with the wheels rolling (a ramp to 0.1 m/s, so its motion has no jump)
    moving = np.clip(speed / 0.1, 0.0, 1.0)
    gyro_vib = np.deg2rad(g.gyro_vibration_still_dps
                          + moving * (g.gyro_vibration_driving_dps - g.gyro_vibration_still_dps))
    accel_vib = np.minimum(g.accel_vibration_still_mps2 + g.accel_vibration_per_mps * speed,
                           max(g.accel_vibration_max_mps2, g.accel_vibration_still_mps2))
    white = math.sqrt(g.imu_rate_hz) / 60.0  # a random walk per sqrt(h) -> 1 sigma per sample
    gyro_white, accel_white = np.deg2rad(g.gyro_random_walk_dps_rthr) * white, g.accel_random_walk_mps_rthr * white
    gyro_bias, gyro_scale = np.deg2rad(rng.normal(0.0, g.gyro_bias_dps, 3)), rng.normal(0.0, g.gyro_scale, 3)
    gyro = ((1.0 + gyro_scale) * w_s + gyro_bias + np.deg2rad(wander(g.gyro_instability_dps))
            + vibration(rng, t, gyro_vib) + rng.normal(0.0, gyro_white, (n, 3)))
    if g.holder_wobble_dps > 0:
        wobble_sd = np.deg2rad(g.holder_wobble_dps
                               * (g.holder_wobble_still_share + (1.0 - g.holder_wobble_still_share) * moving))
        gyro += holder_wobble(np.random.default_rng([seed, 8000 + SIMULATED_SCENARIOS.index(scenario)]), t, wobble_sd,
                              g.holder_wobble_hz, g.holder_wobble_yaw_share)
    if g.gyro_sway_dps > 0:
        sway_rng = np.random.default_rng([seed, 9000 + SIMULATED_SCENARIOS.index(scenario)])
        gyro += np.deg2rad(np.column_stack([gauss_markov(sway_rng, n, dt_mean, g.gyro_sway_dps, g.gyro_sway_tau_s)
                                            for _ in range(3)]))
    accel_bias, accel_scale = rng.normal(0.0, g.accel_bias_mps2, 3), rng.normal(0.0, g.accel_scale, 3)
    accel = ((1.0 + accel_scale) * f_s + accel_bias + wander(g.accel_instability_mps2) + vibration(rng, t, accel_vib)
             + rng.normal(0.0, accel_white, (n, 3)))

    # the reference truth (exact) and the receiver (wandering), at every row; fixes at its epochs
    position = at(m.position_m)
    lat, lon, _ = geodetic_of_enu(position, *m.origin)
    wander = np.column_stack([gauss_markov(rng, n, dt_mean, g.gnss_wander_m, g.gnss_tau_s) for _ in range(3)])
    noisy = position + wander * np.array([1.0, 1.0, 2.0]) + rng.normal(0.0, g.gnss_white_m, (n, 3))
    g_lat, g_lon, g_height = geodetic_of_enu(noisy, *m.origin)
    vel = at(m.velocity_mps)
    rx_vel = vel[:, :2]
    if g.gnss_speed_lag_s > 0:  # the receiver's speed is the car's a while ago, along the course of now
        late = np.hypot(*(np.interp(t - g.gnss_speed_lag_s, m.t_s, m.velocity_mps[:, k]) for k in range(2)))
        rx_vel = rx_vel * (late / np.maximum(np.hypot(vel[:, 0], vel[:, 1]), 1e-9))[:, None]
    v_e = rx_vel[:, 0] + rng.normal(0.0, g.gnss_speed_noise_mps, n)
    v_n = rx_vel[:, 1] + rng.normal(0.0, g.gnss_speed_noise_mps, n)
    g_speed = np.hypot(v_e, v_n)
    g_course = wrap_360(np.degrees(np.arctan2(v_e, v_n)))
    course = wrap_360(np.degrees(np.arctan2(vel[:, 0], vel[:, 1])))
    fix = np.zeros(n, dtype=bool)
    epochs = np.round(t * g.gnss_rate_hz)
    fix[np.concatenate([[True], np.diff(epochs) > 0])] = True  # the first row at or after each receiver epoch
    fix &= ~receiver_losses(np.random.default_rng([seed, 10000 + SIMULATED_SCENARIOS.index(scenario)]), t, g)

    columns = {"t_s": t, "lat_deg": lat, "lon_deg": lon, "speed_mps": np.hypot(vel[:, 0], vel[:, 1]),
               "heading_deg": course, "accel_long_mps2": accel[:, 0], "yaw_rate_radps": gyro[:, 2],
               "height_m": g_height, "gnss_sigma_m": np.full(n, g.gnss_reported_sigma_m), "gnss_lat_deg": g_lat,
               "gnss_lon_deg": g_lon, "gnss_speed_mps": g_speed, "gnss_heading_deg": g_course}
    columns |= dict(zip(IMU_COLUMNS, np.column_stack([accel, gyro]).T, strict=True))
    if g.vehicle_speed:
        can = can_speeds(np.random.default_rng([seed, 7000 + SIMULATED_SCENARIOS.index(scenario)]), t,
                         plan_truth(scenario, seed, duration_s), SensorModel(), 0.75, 0.3)
        columns["speed_can_mps"] = can[HEADER[15]] / 3.6  # the indicated speed, km/h
    name = f"sim-{g.name}-{scenario}-{seed}"
    drive = Drive(name, name, g.imu_rate_hz, 0.0, columns, start_stamp_s=1_700_000_000.0 + 86400.0 * seed)
    return ImuLog(drive, fix, mount, gyro_bias, accel_bias, gyro_scale, accel_scale)


def receiver_losses(rng: np.random.Generator, t_s: np.ndarray, g: ImuGrade) -> np.ndarray:
    """Where the receiver of grade ``g`` gives no fix (True), at the times ``t_s`` (s): its losses
    (see :class:`ImuGrade`), drawn from ``rng``."""
    lost = np.zeros(len(t_s), dtype=bool)
    span_s = float(t_s[-1] - t_s[0])
    if g.gnss_losses_per_10min <= 0.0 or span_s <= 0.0:
        return lost
    n = rng.poisson(g.gnss_losses_per_10min * span_s / 600.0)
    starts = t_s[0] + rng.uniform(0.0, span_s, n)
    lengths = np.exp(rng.uniform(*np.log(g.gnss_loss_s), n))
    for a, length in zip(starts, lengths, strict=True):
        lost |= (t_s >= a) & (t_s < a + length)
    return lost


def write_imu_log(path: str | Path, scenario: str, seed: int = 0, duration_s: float = 300.0,
                  grade: str | ImuGrade = "mems") -> Path:
    """Simulate a log of ``grade`` and write it as a ROS 2 MCAP (atomically): ``/imu/data`` at the
    IMU's rate (its own mounted axes), ``/gps/fix`` and ``/gps/vel`` at the receiver's epochs, the
    reference truth on :data:`SIM_TRUTH_TOPIC`, and ``/wheel/odom`` where the grade has a vehicle
    speed. Read it with ``--truth-topic /truth/fix``."""
    path = check_output_file(Path(path))
    if path.suffix.lower() != ".mcap":
        raise InputError(f"{path}: a simulated IMU log is an MCAP file", "choose a name like drive.mcap",
                         param="output")
    log = imu_drive(scenario, seed, duration_s, grade)
    speed = log.drive.columns.get("speed_can_mps")
    write_mcap(log.drive, path, speed, ("speed_can_mps",) if speed is not None else (), omit_gnss=~log.fix)
    return path
