"""Synthetic drives in the exact IO-VNBD ``V-*.csv`` format, from a vehicle model and a sensor error model.

The real dataset cannot be downloaded on every machine, so tests and bundled samples use
drives generated here. They are written through the same header, units, decimals, CRLF
line ends and 10 Hz timing as the real files, so :func:`ionav_viz.iovnbd.read_iovnbd`
cannot tell them apart.

Vehicle model (truth, integrated at 100 Hz)
    A planar point vehicle with no side slip. A plan of manoeuvres gives speed v(t) and path
    curvature kappa(t) (1/m, left positive). Speed changes follow half-sine acceleration pulses
    (peak accel = pi * dv / (2 T)); curvature ramps in and out of turns over cosine ramps (a
    clothoid-like transition). Yaw rate r = v * kappa (counter-clockwise positive), heading is
    the integral of -r (compass, clockwise), positions are integrated in a local east-north frame
    around a random origin in England and projected to WGS84 with pyproj (azimuthal equidistant).
    Road grade is a smooth random function of distance (sum of sinusoids, ~2 % rms).

Scenarios mirror the paper's: ``motorway`` (80-100 km/h, gentle curves, lane changes),
``roundabout`` (UK roundabouts, driven clockwise, radii 12-40 m, left entry and exit flares),
``quick-accel`` (speeding up and slowing down in turn by 2-5 m/s at 0.18-0.29 g, between 38 and 74 km/h), ``hard-brake``
(braking at 0.5-0.76 g, often to a stop), ``sharp-cornering`` (90-degree junction turns at
8-15 m radius and successive left-right zig-zags), and ``stationary`` (engine idling, for
sensor-bias calibration). Every drive but the motorway one starts with the car standing still
for 5-8 s; the motorway drive starts from a standstill on a slip road.

Sensor error model (:class:`SensorModel`, defaults from measured real logs, see SENSORS.md)
    accelerometer (longitudinal, reported in g like CAN):
        f = a + g*sin(grade) + offset + bias_walk + white noise, quantised to 0.01 g.
        offset = -0.12 m/s^2 for the simulated car (mount tilt + bias) +- 0.03 per drive;
        bias random walk 0.002 m/s^2/sqrt(s); white noise 0.15 m/s^2 standing,
        growing 0.012 m/s^2 per m/s of speed up to 0.45 m/s^2.
    gyroscope (yaw rate, written clockwise positive in deg/s, 0.01 deg/s resolution):
        r_meas = (1 + scale) * r(t - latency) + bias + bias_walk + white noise;
        scale +1.5 %, latency 0.1 s (CAN), bias 0.25 deg/s +- 0.05 per drive,
        bias random walk 0.002 deg/s/sqrt(s), noise 0.08 deg/s standing, 0.25 deg/s driving.
    GNSS (VBOX-class, 10 Hz): position error is a first-order Gauss-Markov wander per axis
        (sigma 0.5 m, tau 20 s) plus 2 cm white noise; speed noise 0.15 km/h; course noise
        0.3 deg at 10 m/s, growing as 1/speed; the course holds its last value below 1 m/s.
    timing: sample periods jitter by +-1 ms and ~0.2 % of samples are missing (0.2 s periods).
    wheel speeds (rad/s, CAN) and indicated speed (see SENSORS.md):
        omega = v_wheel / r_eff, the effective rolling radius off the nominal 0.3 m by 1-3 % (either
        way, per drive); v_wheel = v (1 -+ curvature * half track) for the inner and outer wheels,
        minus ABS slip under hard braking (up to 15 % below -4 m/s^2, cycling at 3 Hz) and, on the
        driven front wheels, plus wheelspin under hard acceleration (up to 6 % above 2.5 m/s^2);
        quantised to 0.05 rad/s and 0 below 0.5 m/s; 50 ms CAN latency. Indicated speed: 3 % over
        the true speed (as speedometers read), rounded to 1 km/h, with the same latency.
    fleets (:data:`FLEETS`, :func:`fleet_sensors`): the defaults above are one car; the bundled
        training drives come from a "training" fleet of cars whose offsets, biases, gyro scale
        and latency, noise, road grade and wheel radius vary per drive, and "held-out" cars lie
        outside all of those ranges.
    GNSS losses (``gnss_losses``, off by default): tunnel-like stretches of 3-15 s while driving,
        satellites 0, the last fix (position, speed, course, height) repeated or zeros written,
        alternately; the CAN bus and the IMU go on (see :func:`gnss_loss_spans`).

Output is byte-identical for a given scenario, seed and duration.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..analysis.events import EventThresholds
from ..core.errors import InputError
from ..core.fileio import check_output_file
from ..core.grid import GRID_RATE_HZ
from ..core.units import G_MPS2
from ..dataset.catalog import SCENARIOS as PAPER_SCENARIOS
from ..sources.iovnbd import HEADER, write_iovnbd

log = logging.getLogger("ionav_viz")

#: The paper's hard-brake threshold (Section 2), as the event detector has it by default.
HARD_BRAKE_G = EventThresholds().hard_brake_g

SIMULATED_SCENARIOS = (*PAPER_SCENARIOS, "stationary")  # the paper's five, and a standing car for biases
TRUTH_RATE_HZ = 100.0
OUTPUT_RATE_HZ = GRID_RATE_HZ  # IO-VNBD's rate


@dataclass(frozen=True)
class SensorModel:
    """Sensor error parameters (see module docstring). ``SensorModel.ideal()`` has none."""

    accel_offset_mps2: float = -0.12
    accel_offset_spread_mps2: float = 0.03
    accel_bias_walk_mps2_per_sqrt_s: float = 0.002
    accel_noise_still_mps2: float = 0.15
    accel_noise_per_mps: float = 0.012
    accel_noise_max_mps2: float = 0.45
    accel_quantum_g: float = 0.01
    gyro_bias_dps: float = 0.25
    gyro_bias_spread_dps: float = 0.05
    gyro_bias_walk_dps_per_sqrt_s: float = 0.002
    gyro_noise_still_dps: float = 0.08
    gyro_noise_driving_dps: float = 0.25
    gyro_scale_error: float = 0.015
    gyro_latency_s: float = 0.1
    gnss_wander_m: float = 0.5
    gnss_wander_tau_s: float = 20.0
    gnss_white_m: float = 0.02
    gnss_speed_noise_kmh: float = 0.15
    gnss_heading_noise_deg_at_10mps: float = 0.3
    grade_rms: float = 0.02
    clock_jitter_s: float = 0.001
    missing_sample_prob: float = 0.002
    wheel_radius_error_min: float = 0.01
    wheel_radius_error_max: float = 0.03
    wheel_quantum_radps: float = 0.05
    wheel_min_speed_mps: float = 0.5
    brake_slip: float = 0.15
    wheelspin: float = 0.06
    can_latency_s: float = 0.05
    can_speed_overread: float = 0.03
    can_speed_quantum_kmh: float = 1.0

    @classmethod
    def ideal(cls) -> SensorModel:
        """Perfect sensors and flat roads: for tests with exact expectations."""
        return cls(**{f: 0.0 for f in cls.__dataclass_fields__})


@dataclass
class Truth:
    """Ground truth at ``TRUTH_RATE_HZ``: time (s), speed (m/s), accel (m/s^2), curvature (1/m),
    and the manoeuvres the plan put in: (type, start s, end s)."""

    t_s: np.ndarray
    speed_mps: np.ndarray
    accel_mps2: np.ndarray
    curvature_1pm: np.ndarray
    manoeuvres: list[tuple[str, float, float]]


class _Plan:
    """Builds speed and curvature profiles piece by piece at 100 Hz."""

    def __init__(self) -> None:
        self.dt = 1.0 / TRUTH_RATE_HZ
        self.v: list[np.ndarray] = []
        self.a: list[np.ndarray] = []
        self.k: list[np.ndarray] = []
        self.speed = 0.0
        self.duration_s = 0.0
        self.manoeuvres: list[tuple[str, float, float]] = []

    def mark(self, kind: str, start_s: float) -> None:
        """Record that the pieces since ``start_s`` form one manoeuvre of ``kind``."""
        self.manoeuvres.append((kind, start_s, self.duration_s))

    def _append(self, v: np.ndarray, a: np.ndarray, k: np.ndarray) -> None:
        self.v.append(v)
        self.a.append(a)
        self.k.append(k)
        self.duration_s += len(v) * self.dt
        self.speed = float(v[-1]) if len(v) else self.speed

    def _n(self, seconds: float) -> int:
        return max(1, int(round(seconds / self.dt)))

    def hold(self, seconds: float) -> None:
        """Keep speed, drive straight (or stand still at speed 0)."""
        n = self._n(seconds)
        self._append(np.full(n, self.speed), np.zeros(n), np.zeros(n))

    def speed_to(self, target_mps: float, peak_accel_mps2: float) -> None:
        """Change speed with a half-sine acceleration pulse of the given peak magnitude."""
        dv = target_mps - self.speed
        if abs(dv) < 1e-6:
            return
        seconds = math.pi * abs(dv) / (2.0 * peak_accel_mps2)
        start = self.duration_s
        n = self._n(seconds)
        tau = (np.arange(n) + 1) * self.dt
        big_t = n * self.dt
        v = self.speed + dv * 0.5 * (1.0 - np.cos(np.pi * tau / big_t))
        a = dv * math.pi / (2.0 * big_t) * np.sin(np.pi * tau / big_t)
        self._append(v, a, np.zeros(n))
        self.speed = target_mps
        if dv < 0 and peak_accel_mps2 >= HARD_BRAKE_G * G_MPS2:
            self.mark("hard-brake", start)

    def turn(self, angle_deg: float, radius_m: float, ramp_s: float = 1.0) -> None:
        """Turn by ``angle_deg`` (left positive) on ``radius_m`` at the current speed."""
        if self.speed <= 0.5:
            raise ValueError("turn needs speed")
        kappa = math.copysign(1.0 / radius_m, angle_deg)
        total_s = math.radians(abs(angle_deg)) * radius_m / self.speed
        ramp_s = min(ramp_s, total_s / 2.0)
        # the two cosine ramps together turn as much as ramp_s at full curvature
        n_ramp, n_hold = self._n(ramp_s), max(0, int(round((total_s - ramp_s) / self.dt)))
        up = kappa * 0.5 * (1.0 - np.cos(np.pi * (np.arange(n_ramp) + 0.5) / n_ramp))
        k = np.concatenate([up, np.full(n_hold, kappa), up[::-1]])
        self._append(np.full(len(k), self.speed), np.zeros(len(k)), k)

    def truth(self, duration_s: float) -> Truth:
        n = int(round(duration_s * TRUTH_RATE_HZ)) + 1
        v = np.concatenate([[0.0]] + self.v)  # every plan starts standing still
        a = np.concatenate([[0.0]] + self.a)
        k = np.concatenate([[0.0]] + self.k)
        if len(v) < n:
            raise ValueError("plan shorter than the requested duration")
        end = (n - 1) * self.dt
        kept = [(kind, t0, min(t1, end)) for kind, t0, t1 in self.manoeuvres if t0 < end]
        return Truth(np.arange(n) * self.dt, np.maximum(v[:n], 0.0), a[:n], k[:n], kept)


def _plan_motorway(p: _Plan, rng: np.random.Generator, duration_s: float) -> None:
    p.hold(rng.uniform(5, 8))
    p.speed_to(rng.uniform(9, 12), 1.5)
    p.turn(rng.uniform(-40, 40), rng.uniform(150, 300))  # slip road
    p.speed_to(rng.uniform(24, 27), 1.6)
    while p.duration_s < duration_s:
        p.hold(rng.uniform(4, 14))
        kind = rng.integers(0, 3)
        if kind == 0:
            p.turn(rng.choice([-1, 1]) * rng.uniform(5, 20), rng.uniform(800, 2000))
        elif kind == 1:  # lane change
            side = rng.choice([-1, 1])
            p.turn(side * rng.uniform(3, 5), 300.0)
            p.hold(rng.uniform(0.5, 1.5))
            p.turn(-side * rng.uniform(3, 5), 300.0)
        else:
            p.speed_to(rng.uniform(22.5, 27.5), rng.uniform(0.3, 0.7))


def _plan_roundabout(p: _Plan, rng: np.random.Generator, duration_s: float) -> None:
    p.hold(rng.uniform(5, 8))
    p.speed_to(rng.uniform(12, 15), 1.8)
    while p.duration_s < duration_s:
        p.hold(rng.uniform(4, 10))
        radius = rng.uniform(12, 40)
        v_circ = float(np.clip(math.sqrt(2.5 * radius), 4.5, 10.0))
        p.speed_to(v_circ, rng.uniform(1.5, 3.0))
        flare = rng.uniform(15, 30)
        start = p.duration_s
        p.turn(flare, 15.0, ramp_s=0.6)  # UK: enter turning left
        p.turn(-(rng.choice([90, 180, 270]) + 2 * flare), radius)  # circulate clockwise
        p.turn(flare, 15.0, ramp_s=0.6)
        p.mark("roundabout", start)
        p.speed_to(rng.uniform(11, 16), rng.uniform(1.2, 2.2))


def _plan_quick_accel(p: _Plan, rng: np.random.Generator, duration_s: float) -> None:
    p.hold(rng.uniform(5, 8))
    p.speed_to(rng.uniform(12, 15), 2.0)
    sign = 1.0
    while p.duration_s < duration_s:  # speed up and slow down in turn, between 38 and 74 km/h
        target = float(np.clip(p.speed + sign * rng.uniform(2.0, 5.0), 10.5, 20.5))
        p.speed_to(target, rng.uniform(1.8, 2.8))
        sign = -sign
        p.hold(rng.uniform(0.3, 1.5))
        if rng.random() < 0.2:
            p.turn(rng.choice([-1, 1]) * rng.uniform(10, 30), rng.uniform(200, 500))


def _plan_hard_brake(p: _Plan, rng: np.random.Generator, duration_s: float) -> None:
    p.hold(rng.uniform(5, 8))
    while p.duration_s < duration_s:
        p.speed_to(rng.uniform(14, 24), rng.uniform(1.5, 2.5))
        p.hold(rng.uniform(4, 10))
        stop = rng.random() < 0.6
        p.speed_to(0.0 if stop else rng.uniform(2, 8), rng.uniform(5.0, 7.5))
        if stop:
            p.hold(rng.uniform(2, 5))
        elif rng.random() < 0.5:
            start = p.duration_s
            p.turn(rng.choice([-1, 1]) * 90, rng.uniform(10, 15))
            p.mark("sharp-cornering", start)


def _plan_sharp_cornering(p: _Plan, rng: np.random.Generator, duration_s: float) -> None:
    p.hold(rng.uniform(5, 8))
    p.speed_to(rng.uniform(8, 11), 1.5)
    while p.duration_s < duration_s:
        p.hold(rng.uniform(2, 6))
        if rng.random() < 0.5:  # junction
            p.speed_to(rng.uniform(4, 6), rng.uniform(1.5, 3.0))
            start = p.duration_s
            p.turn(rng.choice([-1, 1]) * rng.uniform(80, 100), rng.uniform(8, 15), ramp_s=0.8)
            p.mark("sharp-cornering", start)
            p.speed_to(rng.uniform(8, 12.5), rng.uniform(1.5, 2.5))
        else:  # successive left-right turns
            side = rng.choice([-1, 1])
            start = p.duration_s
            for _ in range(int(rng.integers(2, 5))):
                p.turn(side * rng.uniform(30, 60), rng.uniform(15, 25), ramp_s=0.8)
                side = -side
            p.mark("left-right", start)


def _plan_stationary(p: _Plan, rng: np.random.Generator, duration_s: float) -> None:
    p.hold(duration_s + 1.0)


_PLANS = {
    "motorway": _plan_motorway,
    "roundabout": _plan_roundabout,
    "quick-accel": _plan_quick_accel,
    "hard-brake": _plan_hard_brake,
    "sharp-cornering": _plan_sharp_cornering,
    "stationary": _plan_stationary,
}


#: Longest drive the simulator makes (s). Measured peak memory of `ionav-viz simulate`: 0.17 GB for
#: 1 h, 0.27 GB for 2 h (about 0.1 GB per hour, so roughly 1.3 GB for 12 h, extrapolated); 12 h is
#: longer than any IO-VNBD run.
MAX_DURATION_S = 12 * 3600.0


def plan_truth(scenario: str, seed: int, duration_s: float) -> Truth:
    """The ground-truth motion of a scenario (100 Hz)."""
    if scenario not in _PLANS:
        raise InputError(f"unknown scenario {scenario!r}", f"choose one of {', '.join(SIMULATED_SCENARIOS)}")
    if not duration_s > 0:
        raise InputError(f"duration must be positive, got {duration_s} s", param="duration_s")
    if duration_s > MAX_DURATION_S:
        raise InputError(f"duration {duration_s / 3600:g} h is longer than the {MAX_DURATION_S / 3600:g} h the "
                         "simulator allows",
                         "simulate several shorter drives", param="duration_s")
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise InputError(f"seed {seed!r} must be a whole number >= 0", param="seed")
    rng = np.random.default_rng([seed, SIMULATED_SCENARIOS.index(scenario)])
    plan = _Plan()
    _PLANS[scenario](plan, rng, duration_s + 1.0)
    return plan.truth(duration_s)


def simulated_manoeuvres(scenario: str, seed: int, duration_s: float,
                         gnss_losses: int = 0) -> list[tuple[str, float, float]]:
    """Where the simulator put each manoeuvre: (type, start s, end s), times as in the CSV.

    ``gnss-outage``: the GNSS losses of a drive simulated with ``gnss_losses``.

    ``hard-brake``, ``roundabout``, ``sharp-cornering`` and ``left-right`` come from the plan's
    pieces (those the end of the drive cut off are left out). ``quick-accel`` and ``cruise`` are
    properties of the motion rather than pieces, so they are found on the exact, noise-free truth
    (true speed and yaw rate at 10 Hz: no sensor errors, no road grade) by their definitions in
    :mod:`ionav_viz.events`.
    """
    from ..analysis.events import detect_cruise, detect_quick_accel, smoothed_signals

    truth = plan_truth(scenario, seed, duration_s)
    step = int(round(TRUTH_RATE_HZ / OUTPUT_RATE_HZ))
    t = truth.t_s[::step]
    th = EventThresholds()
    clean = smoothed_signals(t, truth.speed_mps[::step], (truth.speed_mps * truth.curvature_1pm)[::step],
                             np.ones(len(t), dtype=bool), th)
    derived = [(e.type, e.t0_s, e.t1_s) for e in detect_quick_accel(clean, th) + detect_cruise(clean, th)]
    end = truth.t_s[-1]
    planned = [m for m in truth.manoeuvres if m[2] < end - 1e-9]  # drop manoeuvres the drive's end cut off
    losses = [("gnss-outage", a, b) for a, b, _ in gnss_loss_spans(scenario, seed, duration_s, gnss_losses)]
    return sorted(planned + derived + losses, key=lambda m: (m[1], m[0]))


def gauss_markov(rng: np.random.Generator, n: int, dt: float, sigma: float, tau: float) -> np.ndarray:
    """First-order Gauss-Markov process (stationary std ``sigma``, correlation time ``tau``)."""
    out = np.zeros(n)
    if sigma == 0.0 or n == 0:
        return out
    phi = math.exp(-dt / tau)
    drive = rng.normal(0.0, sigma * math.sqrt(1 - phi * phi), n)
    x = rng.normal(0.0, sigma)
    for i in range(n):  # each step depends on the last
        x = phi * x + drive[i]
        out[i] = x
    return out


def grade_profile(rng: np.random.Generator, distance_m: np.ndarray, rms: float) -> np.ndarray:
    """Smooth random road grade (rise/run) along the path: a sum of sinusoids in distance."""
    if rms == 0.0:
        return np.zeros_like(distance_m)
    wavelengths = rng.uniform(150.0, 1500.0, 6)
    phases = rng.uniform(0, 2 * np.pi, 6)
    g = sum(np.sin(2 * np.pi * distance_m / w + ph) for w, ph in zip(wavelengths, phases))
    return g * rms / math.sqrt(6 / 2)


#: Tunnel-like GNSS losses (``gnss_losses``): lengths (s), the speed (m/s) the car drives when
#: one begins, and the time kept clear at the ends of the drive and between losses (s).
LOSS_LENGTH_S = (3.0, 15.0)
LOSS_MIN_SPEED_MPS = 5.0
LOSS_CLEAR_S = 20.0


def gnss_loss_room(duration_s: float) -> int:
    """The most GNSS losses a drive of ``duration_s`` can hold: each at least LOSS_LENGTH_S[0] long,
    LOSS_CLEAR_S from the drive's ends and from each other."""
    return max(0, int((duration_s - LOSS_CLEAR_S) // (LOSS_LENGTH_S[0] + LOSS_CLEAR_S)))


def gnss_loss_spans(scenario: str, seed: int, duration_s: float, count: int) -> list[tuple[float, float, str]]:
    """Where a drive of ``simulate_rows(..., gnss_losses=count)`` loses GNSS: ``(start s, end s,
    kind)``, sorted. Kinds alternate between ``frozen`` (the logger repeats its last fix, speed and
    course) and ``absent`` (it writes zeros); the satellite count is 0 in both. Losses begin
    while driving and stay LOSS_CLEAR_S away from each other and from the ends of the drive; fewer
    than ``count`` when the drive has no room for more."""
    if count < 0:
        raise InputError(f"{count} GNSS losses: give 0 or more", param="gnss_losses")
    if count == 0:
        return []
    truth = plan_truth(scenario, seed, duration_s)
    # its own stream: the rest of the drive is unchanged
    rng = np.random.default_rng([seed, 2000 + SIMULATED_SCENARIOS.index(scenario)])
    spans: list[tuple[float, float, str]] = []
    # --gnss-loss 1000000 drew 50 M times (a hang) for the few that fit
    for _ in range(50 * min(count, max(1, gnss_loss_room(duration_s)))):
        if len(spans) == count:
            break
        length = float(np.round(rng.uniform(*LOSS_LENGTH_S), 1))
        t0 = (float(np.round(rng.uniform(LOSS_CLEAR_S, duration_s - LOSS_CLEAR_S - length), 1))
              if duration_s > 2 * LOSS_CLEAR_S + length else -1.0)
        if t0 < 0 or np.interp(t0, truth.t_s, truth.speed_mps) < LOSS_MIN_SPEED_MPS:
            continue
        if all(t0 >= b + LOSS_CLEAR_S or t0 + length + LOSS_CLEAR_S <= a for a, b, _ in spans):
            spans.append((t0, t0 + length, ""))
    spans.sort()
    return [(a, b, ("frozen", "absent")[i % 2]) for i, (a, b, _) in enumerate(spans)]


def simulate_rows(
    scenario: str, seed: int = 0, duration_s: float = 120.0, sensors: SensorModel | None = None, gnss_losses: int = 0
) -> dict[str, np.ndarray]:
    """Raw IO-VNBD columns (file units, keyed by header name) of a synthetic drive, with
    ``gnss_losses`` tunnel-like GNSS losses (:func:`gnss_loss_spans`).

    One generator draws every random number in a fixed order (the truth's start heading and grade,
    the sample times, the accelerometer, the gyro, the GNSS, then the housekeeping channels): the
    helpers below are called in that order."""
    sensors = sensors if sensors is not None else SensorModel()
    truth = plan_truth(scenario, seed, duration_s)
    rng = np.random.default_rng([seed, 1000 + SIMULATED_SCENARIOS.index(scenario)])
    track = _integrate_truth(truth, rng, sensors)
    t = _sample_times(rng, duration_s, sensors)
    n = len(t)

    def at(x: np.ndarray, times: np.ndarray = t) -> np.ndarray:
        return np.interp(times, truth.t_s, x)

    v_s, a_s, g_s = at(truth.speed_mps), at(truth.accel_mps2), at(track.grade)
    moving = v_s > 0.05
    accel_g = _accelerometer_g(rng, sensors, v_s, a_s, g_s)
    r_meas_dps = _gyro_dps(rng, sensors, at(track.yaw_rate_radps, t - sensors.gyro_latency_s), moving)
    lat, lon, speed_kmh, course = _gnss_columns(rng, sensors, at(track.east_m), at(track.north_m),
                                                at(np.unwrap(track.heading_rad)), v_s)

    # CAN and housekeeping channels.
    k_s = at(truth.curvature_1pm)
    gear = np.select([v_s < 0.3, v_s < 4, v_s < 8, v_s < 12.5, v_s < 17], [0, 1, 2, 3, 4], 5)
    brake_psi = np.clip((-a_s - 0.5) * 150.0, 0.0, None)
    # "same" is max(n, 30) long: a drive under 3 s never stands
    standing = np.convolve(~moving, np.ones(30), "same")[:n] >= 30
    half_track_m, wheel_radius_m = 0.75, 0.3
    rows = {
        HEADER[0]: np.clip(np.round(11 + np.cumsum(rng.integers(-1, 2, n)) * 0.05), 6, 16),
        HEADER[1]: rng.uniform(7, 17) * 3600.0 + t,
        HEADER[2]: lat,
        HEADER[3]: lon,
        HEADER[4]: speed_kmh,
        HEADER[5]: course,
        HEADER[6]: 120.0 + at(track.elevation_m) + np.cumsum(rng.normal(0, 0.02, n)),
        HEADER[7]: v_s * np.sin(np.arctan(g_s)) * 3.6,
        HEADER[8]: np.concatenate([[0.1], np.diff(t)]),
        HEADER[9]: np.degrees(np.arctan(2.5 * k_s)) * 15.0,
        **can_speeds(np.random.default_rng([seed, 3000 + SIMULATED_SCENARIOS.index(scenario)]), t, truth, sensors,
                     half_track_m, wheel_radius_m),
        HEADER[14]: -r_meas_dps,
        HEADER[16]: accel_g,
        HEADER[17]: (v_s * v_s * k_s + rng.normal(0, 1, n) * 0.1 * (sensors.accel_noise_still_mps2 > 0)) / G_MPS2,
        HEADER[18]: standing.astype(float),
        HEADER[19]: gear,
        HEADER[20]: gear,
        HEADER[21]: np.where(gear == 0, 800.0, 800.0 + v_s * 3.6 * np.array([0, 90, 55, 40, 32, 27])[gear]),
        HEADER[22]: 90.0 + np.round(np.sin(t / 300.0) * 2),
        HEADER[23]: np.zeros(n),
        HEADER[24]: brake_psi,
        HEADER[25]: (brake_psi > 0).astype(float),
        HEADER[26]: 14.2 + rng.normal(0, 0.02, n),
        HEADER[27]: np.full(n, round(rng.uniform(4, 20))),
        HEADER[28]: np.clip(a_s * 30 + v_s * 0.8, 0, 100) * moving,
    }
    spans = gnss_loss_spans(scenario, seed, duration_s, gnss_losses)
    if len(spans) < gnss_losses:
        log.warning("%s drive of %g s: wrote %d of the %d GNSS losses asked for (each %g-%g s, begun at %g "
                    "m/s or more, %g s from the drive's ends and each other: room for at most %d, placed at random); a "
                    "longer drive (--duration) fits more",
                    scenario, duration_s, len(spans), gnss_losses, *LOSS_LENGTH_S, LOSS_MIN_SPEED_MPS, LOSS_CLEAR_S,
                    gnss_loss_room(duration_s))
    for t0, t1, kind in spans:
        _lose_gnss(rows, t, t0, t1, kind)
    return rows


@dataclass(frozen=True)
class _TruthTrack:
    """The truth integrated at 100 Hz (trapezoid), on :class:`Truth`'s times."""

    yaw_rate_radps: np.ndarray  # counter-clockwise positive
    heading_rad: np.ndarray  # compass: clockwise from north
    east_m: np.ndarray
    north_m: np.ndarray
    grade: np.ndarray  # rise over run
    elevation_m: np.ndarray


def _integrate_truth(truth: Truth, rng: np.random.Generator, sensors: SensorModel) -> _TruthTrack:
    """Heading, position and elevation from the truth's speed and curvature (the start heading and
    the road's grade drawn from ``rng``)."""
    dt = 1.0 / TRUTH_RATE_HZ
    v, k = truth.speed_mps, truth.curvature_1pm
    yaw_rate = v * k
    start_heading = rng.uniform(0, 2 * np.pi)
    heading = start_heading - np.concatenate([[0.0], np.cumsum(0.5 * (yaw_rate[1:] + yaw_rate[:-1]) * dt)])
    distance = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
    ve, vn = v * np.sin(heading), v * np.cos(heading)
    east = np.concatenate([[0.0], np.cumsum(0.5 * (ve[1:] + ve[:-1]) * dt)])
    north = np.concatenate([[0.0], np.cumsum(0.5 * (vn[1:] + vn[:-1]) * dt)])
    grade = grade_profile(rng, distance, sensors.grade_rms)
    elevation = np.concatenate([[0.0], np.cumsum(0.5 * (grade[1:] + grade[:-1]) * np.diff(distance))])
    return _TruthTrack(yaw_rate, heading, east, north, grade, elevation)


def _sample_times(rng: np.random.Generator, duration_s: float, sensors: SensorModel) -> np.ndarray:
    """Sample times at 10 Hz with clock jitter and a few missing samples (the first and last kept)."""
    n_out = int(round(duration_s * OUTPUT_RATE_HZ)) + 1
    t = np.arange(n_out) / OUTPUT_RATE_HZ
    t[1:-1] += rng.uniform(-sensors.clock_jitter_s, sensors.clock_jitter_s, n_out - 2)
    keep = rng.random(n_out) >= sensors.missing_sample_prob
    keep[[0, -1]] = True
    return t[keep]


def _accelerometer_g(rng: np.random.Generator, sensors: SensorModel, v_s: np.ndarray, a_s: np.ndarray,
                     g_s: np.ndarray) -> np.ndarray:
    """The longitudinal accelerometer (g) at the sample times: acceleration and gravity along the
    grade, offset, bias walk, speed-dependent noise, quantisation."""
    n = len(v_s)
    accel_offset = sensors.accel_offset_mps2 + rng.normal(0, 1) * sensors.accel_offset_spread_mps2
    accel_walk = np.cumsum(rng.normal(0, sensors.accel_bias_walk_mps2_per_sqrt_s * math.sqrt(0.1), n))
    accel_sigma = np.minimum(sensors.accel_noise_still_mps2 + sensors.accel_noise_per_mps * v_s,
                             max(sensors.accel_noise_max_mps2, sensors.accel_noise_still_mps2))
    f = a_s + G_MPS2 * np.sin(np.arctan(g_s)) + accel_offset + accel_walk + rng.normal(0, 1, n) * accel_sigma
    accel_g = f / G_MPS2
    if sensors.accel_quantum_g > 0:
        accel_g = np.round(accel_g / sensors.accel_quantum_g) * sensors.accel_quantum_g
    return accel_g


def _gyro_dps(rng: np.random.Generator, sensors: SensorModel, yaw_rate_late_radps: np.ndarray,
              moving: np.ndarray) -> np.ndarray:
    """The yaw-rate gyro (deg/s, counter-clockwise positive; the file column is clockwise positive)
    from the true yaw rate at the sample times less its latency: scale error, bias, bias walk, noise."""
    n = len(moving)
    gyro_bias = sensors.gyro_bias_dps + rng.normal(0, 1) * sensors.gyro_bias_spread_dps
    gyro_walk = np.cumsum(rng.normal(0, sensors.gyro_bias_walk_dps_per_sqrt_s * math.sqrt(0.1), n))
    gyro_sigma = np.where(moving, sensors.gyro_noise_driving_dps, sensors.gyro_noise_still_dps)
    return ((1 + sensors.gyro_scale_error) * np.degrees(yaw_rate_late_radps) + gyro_bias + gyro_walk
            + rng.normal(0, 1, n) * gyro_sigma)


def _gnss_columns(rng: np.random.Generator, sensors: SensorModel, east_m: np.ndarray, north_m: np.ndarray,
                  heading_rad_unwrapped: np.ndarray,
                  v_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The receiver's latitude, longitude (deg), speed (km/h) and course (deg) from the true track at
    the sample times: wandering and white position error about a random origin (latitude 52-53, longitude -2.2 to -0.7),
    speed and course noise, the course held while (nearly) standing."""
    from pyproj import Transformer

    n = len(v_s)
    moving = v_s > 0.05
    e_err = gauss_markov(rng, n, 0.1, sensors.gnss_wander_m, sensors.gnss_wander_tau_s or 1.0)
    n_err = gauss_markov(rng, n, 0.1, sensors.gnss_wander_m, sensors.gnss_wander_tau_s or 1.0)
    e_meas = east_m + e_err + rng.normal(0, 1, n) * sensors.gnss_white_m
    n_meas = north_m + n_err + rng.normal(0, 1, n) * sensors.gnss_white_m
    lat0 = rng.uniform(52.0, 53.0)
    lon0 = rng.uniform(-2.2, -0.7)
    to_wgs84 = Transformer.from_crs(f"+proj=aeqd +lat_0={lat0} +lon_0={lon0} +datum=WGS84", "EPSG:4326", always_xy=True)
    lon, lat = to_wgs84.transform(e_meas, n_meas)
    speed_kmh = np.maximum(v_s * 3.6 + rng.normal(0, 1, n) * sensors.gnss_speed_noise_kmh, 0.0)
    speed_kmh[~moving] = np.abs(rng.normal(0, 1, (~moving).sum())) * sensors.gnss_speed_noise_kmh
    course = np.degrees(heading_rad_unwrapped)
    course += rng.normal(0, 1, n) * sensors.gnss_heading_noise_deg_at_10mps * 10.0 / np.maximum(v_s, 1.0)
    slow = v_s < 1.0
    if slow.any():  # the receiver holds its last course while (nearly) standing still
        idx = np.where(slow, 0, np.arange(n))
        np.maximum.accumulate(idx, out=idx)
        first_fast = int(np.argmax(~slow)) if (~slow).any() else 0
        idx[: first_fast] = first_fast
        course = course[idx]
    return lat, lon, speed_kmh, np.mod(course, 360.0)


def can_speeds(rng: np.random.Generator, t: np.ndarray, truth: Truth, sensors: SensorModel, half_track_m: float,
                    nominal_radius_m: float) -> dict[str, np.ndarray]:
    """The four wheel speeds (rad/s, front left, front right, rear left, rear right) and the
    indicated speed (km/h) as the CAN bus reports them (see the module docstring). Drawn from
    their own random stream, so the other columns do not depend on them."""
    error = rng.uniform(sensors.wheel_radius_error_min, sensors.wheel_radius_error_max) * rng.choice([-1.0, 1.0])
    r_eff = nominal_radius_m * (1.0 + error)
    late = t - sensors.can_latency_s
    v, a, k = (np.interp(late, truth.t_s, x) for x in (truth.speed_mps, truth.accel_mps2, truth.curvature_1pm))
    slip = np.clip((-a - 4.0) / 3.0, 0.0, 1.0) * sensors.brake_slip * (0.6 + 0.4 * np.sin(2 * np.pi * 3.0 * late))
    spin = np.clip((a - 2.5) / 1.5, 0.0, 1.0) * sensors.wheelspin

    def wheel(side: float, driven: bool) -> np.ndarray:
        v_wheel = v * (1.0 + side * k * half_track_m) * (1.0 - slip) * (1.0 + (spin if driven else 0.0))
        omega = v_wheel / r_eff
        if sensors.wheel_quantum_radps > 0:
            omega = np.round(omega / sensors.wheel_quantum_radps) * sensors.wheel_quantum_radps
        return np.where(v_wheel < sensors.wheel_min_speed_mps, 0.0, omega)

    indicated = v * 3.6 * (1.0 + sensors.can_speed_overread)
    if sensors.can_speed_quantum_kmh > 0:
        indicated = np.round(indicated / sensors.can_speed_quantum_kmh) * sensors.can_speed_quantum_kmh
    # left wheels are on the inside of a left (counter-clockwise, k > 0) turn
    return {HEADER[10]: wheel(-1.0, True), HEADER[11]: wheel(1.0, True), HEADER[12]: wheel(-1.0, False),
            HEADER[13]: wheel(1.0, False), HEADER[15]: indicated}


def _lose_gnss(rows: dict[str, np.ndarray], t: np.ndarray, t0: float, t1: float, kind: str) -> None:
    """Write a GNSS loss over ``t0 <= t < t1`` as the VBOX logger does: no satellites, and the last
    fix repeated (``frozen``) or zeros (``absent``) in the GNSS columns. CAN and IMU go on."""
    lost = (t >= t0) & (t < t1)
    if not lost.any():
        return
    last = max(int(np.argmax(lost)) - 1, 0)
    rows[HEADER[0]][lost] = 0
    for column in (HEADER[2], HEADER[3], HEADER[4], HEADER[5], HEADER[6], HEADER[7]):
        rows[column][lost] = rows[column][last] if kind == "frozen" else 0.0


#: Decimals each column is written with (the real files use a similar resolution).
DECIMALS = dict(
    zip(
        HEADER,
        (0, 3, 8, 8, 2, 2, 2, 2, 3, 1, 2, 2, 2, 2, 3, 1, 3, 3, 0, 0, 0, 0, 0, 0, 1, 0, 2, 0, 1),
    )
)


def write_simulated_drive(
    path: str | Path, scenario: str, seed: int = 0, duration_s: float = 120.0, sensors: SensorModel | None = None,
    gnss_losses: int = 0, *, package_ok: bool = False,
) -> Path:
    """Simulate a drive and write it as an IO-VNBD ``V-*.csv`` (atomically). Returns the path.
    ``package_ok``: it may be written inside the installed package (the bundled samples, regenerated)."""
    path = check_output_file(Path(path), package_ok=package_ok)
    rows = simulate_rows(scenario, seed, duration_s, sensors, gnss_losses)
    write_iovnbd(path, rows, DECIMALS)
    return path


#: Fleets of simulated cars: per drive each parameter is drawn uniformly from its range (magnitude
#: and, where marked signed, a random sign). The training fleet varies every sensor and vehicle
#: error the IDNN could otherwise learn as a constant of one car; the held-out fleet lies outside
#: every training range, to test whether a model transfers to a car it has never seen. The noise
#: factor multiplies the accelerometer and gyro white noise.
FLEETS: dict[str, dict[str, tuple[float, float, bool]]] = {
    "training": {
        "accel_offset_mps2": (0.0, 0.25, True),
        "gyro_bias_dps": (0.0, 0.4, True),
        "gyro_scale_error": (0.0, 0.02, True),
        "gyro_latency_s": (0.0, 0.1, False),
        "noise_factor": (0.7, 1.3, False),
        "grade_rms": (0.01, 0.03, False),
        "wheel_radius_error": (0.01, 0.03, False),
    },
    "held-out": {
        "accel_offset_mps2": (0.25, 0.4, True),
        "gyro_bias_dps": (0.4, 0.7, True),
        "gyro_scale_error": (0.02, 0.035, True),
        "gyro_latency_s": (0.1, 0.15, False),
        "noise_factor": (1.3, 1.6, False),
        "grade_rms": (0.03, 0.04, False),
        "wheel_radius_error": (0.03, 0.045, False),
    },
}


def fleet_sensors(fleet: str, seed: int) -> SensorModel:
    """The sensors of one car of ``fleet`` (:data:`FLEETS`), drawn from their own random stream."""
    if fleet not in FLEETS:
        raise InputError(f"unknown fleet {fleet!r}", f"choose one of {', '.join(FLEETS)}")
    rng = np.random.default_rng([seed, 4000])
    draw = {name: rng.uniform(lo, hi) * (rng.choice([-1.0, 1.0]) if signed else 1.0)
            for name, (lo, hi, signed) in FLEETS[fleet].items()}
    base = SensorModel()
    noise = draw.pop("noise_factor")
    radius = abs(draw.pop("wheel_radius_error"))
    return replace(base, **draw, accel_offset_spread_mps2=0.0, gyro_bias_spread_dps=0.0,
                   accel_noise_still_mps2=base.accel_noise_still_mps2 * noise,
                   accel_noise_per_mps=base.accel_noise_per_mps * noise,
                   accel_noise_max_mps2=base.accel_noise_max_mps2 * noise,
                   gyro_noise_still_dps=base.gyro_noise_still_dps * noise,
                   gyro_noise_driving_dps=base.gyro_noise_driving_dps * noise, wheel_radius_error_min=radius,
                   wheel_radius_error_max=radius)


def ideal_sensors_with(**changes: float) -> SensorModel:
    """Perfect sensors with a few chosen errors switched on (for tests)."""
    return replace(SensorModel.ideal(), **changes)
