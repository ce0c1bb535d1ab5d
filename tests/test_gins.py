"""The 3D GNSS/INS ``gins``: its mechanisation against an analytic trajectory, the simulator's 3D
physics against the mechanisation, bias and scale recovery, and what NHC and ZUPT each earn.

Golden values come from closed-form motion (a steady climbing turn) or from the values injected
into the sensors, never from the filter's own output.
"""

from __future__ import annotations

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.drive import IMU_COLUMNS, Drive
from ionav_viz.core.geo import earth_rate_enu_radps, geodetic_of_enu, gravity_enu_mps2, normal_gravity_mps2
from ionav_viz.core.units import wrap_360
from ionav_viz.experiment.outages import tile
from ionav_viz.nav.bias import SensorBias
from ionav_viz.nav.gins import GinsEstimator
from ionav_viz.nav.protocol import EstimatorInputs
from ionav_viz.nav.strapdown import BAX, BGX, KO, N_NOMINAL, QW, SG, VX, propagate
from ionav_viz.nav.windows import make_windows
from ionav_viz.sim.imu import motion_3d

LAT0 = 52.0


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(b):
    c, s = np.cos(b), np.sin(b)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _quat(C):
    """(w, x, y, z) of a rotation matrix (its trace is positive for the attitudes used here)."""
    w = 0.5 * np.sqrt(1.0 + np.trace(C))
    return np.array([w, (C[2, 1] - C[1, 2]) / (4 * w), (C[0, 2] - C[2, 0]) / (4 * w), (C[1, 0] - C[0, 1]) / (4 * w)])


@pytest.mark.parametrize("rate_hz", [10.0, 100.0])
def test_a_climbing_turn_is_followed_within_a_decimetre_for_60_s(rate_hz):
    """A car turning left at 0.1 rad/s at 15 m/s while climbing at 3 degrees: its exact IMU
    (Earth rate, Coriolis and gravity towards the Earth's centre included) mechanised from the
    true start lands within 0.1 m of the helix after 60 s (900 m)."""
    v, r, climb, a0 = 15.0, 0.1, np.deg2rad(3.0), 0.3
    t = np.arange(0.0, 60.0 + 1e-9, 1.0 / rate_hz)
    alpha = a0 + r * t  # counter-clockwise from east
    radius = v * np.cos(climb) / r
    p = np.column_stack([radius * (np.sin(alpha) - np.sin(a0)), -radius * (np.cos(alpha) - np.cos(a0)), v * np.sin(climb) * t])
    vel = v * np.column_stack([np.cos(climb) * np.cos(alpha), np.cos(climb) * np.sin(alpha), np.full_like(t, np.sin(climb))])
    acc = v * np.cos(climb) * r * np.column_stack([-np.sin(alpha), np.cos(alpha), np.zeros_like(t)])
    C = np.array([_rz(a) @ _ry(-climb) for a in alpha])  # body x along the velocity, pitched up by the climb
    omega = earth_rate_enu_radps(LAT0)
    f_n = acc + 2.0 * np.cross(omega, vel) - gravity_enu_mps2(p, normal_gravity_mps2(LAT0))
    f_b = np.einsum("nji,nj->ni", C, f_n)
    w_b = np.einsum("nji,j->ni", C, np.array([0.0, 0.0, r]) + omega)
    x0 = np.zeros(N_NOMINAL)
    x0[VX:VX + 3] = vel[0]
    x0[QW:QW + 4] = _quat(C[0])
    out = propagate(t, f_b, w_b, x0, LAT0)
    assert np.linalg.norm(out[-1, :3] - p[-1]) < 0.1
    # and it is the turn that was followed: half a lap and more, not a straight line
    assert np.linalg.norm(p[-1, :2]) < 2 * radius


def test_the_simulators_3d_imu_drives_the_mechanisation_along_its_own_track():
    """The simulator's ideal IMU (grade, camber, turns, stops) mechanised from its true start stays
    within 0.5 m of its true track over 60 s of a roundabout drive: its 3D physics are consistent."""
    m = motion_3d("roundabout", 5, 60.0, grade_rms=0.03, camber_rms=0.015)
    x0 = np.zeros(N_NOMINAL)
    x0[VX:VX + 3] = m.velocity_mps[0]
    x0[QW:QW + 4] = _quat(m.attitude[0])
    out = propagate(m.t_s, m.specific_force_mps2, m.angular_rate_radps, x0, m.origin[0], m.origin[2])
    travelled = np.sum(np.linalg.norm(np.diff(m.position_m, axis=0), axis=1))
    assert travelled > 300
    assert np.linalg.norm(out[-1, :3] - m.position_m[-1]) < 0.5


GYRO_BIAS_DPS = np.array([0.20, -0.15, 0.30])
ACCEL_BIAS_MPS2 = np.array([0.12, -0.08, 0.10])
ODOMETER_SCALE = 1.025
GYRO_Z_SCALE = 0.02


def _drive(scenario, seed, duration_s, *, gnss_sigma_m=0.5, noise=True, odometer=True, gyro_bias_dps=GYRO_BIAS_DPS,
           accel_bias_mps2=ACCEL_BIAS_MPS2, gyro_z_scale=GYRO_Z_SCALE):
    """A 10 Hz drive from the simulator's exact 3D motion with the injected sensor errors, GNSS fixes
    at 1 Hz (white, ``gnss_sigma_m``) and an odometer reading ``ODOMETER_SCALE`` times the speed."""
    m = motion_3d(scenario, seed, duration_s, grade_rms=0.03, camber_rms=0.015)
    rng = np.random.default_rng(seed)
    step = 10  # 100 Hz truth -> 10 Hz samples, each the mean of its bin as a logger's reader makes them
    n = (len(m.t_s) - 1) // step
    def bins(x):
        return x[: n * step].reshape(n, step, -1).mean(axis=1) if x.ndim == 2 else x[: n * step].reshape(n, step).mean(axis=1)
    t = m.t_s[: n * step : step] + 0.5 * step / 100.0 - 0.005
    f, w = bins(m.specific_force_mps2), bins(m.angular_rate_radps)
    w[:, 2] *= 1.0 + gyro_z_scale
    # white noise as a car shakes its IMU (SENSORS.md, 10 Hz): less standing than driving
    speed_bins = bins(m.speed_mps)
    gyro_sd = np.deg2rad(np.where(speed_bins > 0.05, 0.15, 0.06))[:, None]
    accel_sd = (0.13 + 0.008 * speed_bins)[:, None]
    gyro = w + np.deg2rad(gyro_bias_dps) + (rng.normal(0, 1.0, w.shape) * gyro_sd if noise else 0.0)
    accel = f + accel_bias_mps2 + (rng.normal(0, 1.0, f.shape) * accel_sd if noise else 0.0)
    pos = np.column_stack([np.interp(t, m.t_s, m.position_m[:, k]) for k in range(3)])
    vel = np.column_stack([np.interp(t, m.t_s, m.velocity_mps[:, k]) for k in range(3)])
    lat, lon, _ = geodetic_of_enu(pos, *m.origin)
    fix = np.round(t * 10) % 10 == 0
    noisy = pos + rng.normal(0, gnss_sigma_m, pos.shape)
    glat, glon, gh = geodetic_of_enu(noisy, *m.origin)
    # between fixes the receiver's position is held (the windows read it at whole seconds only)
    idx = np.maximum.accumulate(np.where(fix, np.arange(n), 0))
    speed = np.hypot(vel[:, 0], vel[:, 1])
    columns = {"t_s": t - t[0], "lat_deg": lat, "lon_deg": lon, "speed_mps": speed,
               "heading_deg": wrap_360(np.degrees(np.arctan2(vel[:, 0], vel[:, 1]))), "accel_long_mps2": accel[:, 0],
               "yaw_rate_radps": gyro[:, 2], "height_m": gh[idx], "gnss_sigma_m": np.full(n, gnss_sigma_m),
               "gnss_lat_deg": glat[idx], "gnss_lon_deg": glon[idx], "gnss_speed_mps": speed, "gnss_heading_deg": wrap_360(np.degrees(np.arctan2(vel[:, 0], vel[:, 1])))}
    columns |= dict(zip(IMU_COLUMNS, np.column_stack([accel, gyro]).T, strict=True))
    if odometer:
        columns["speed_can_mps"] = ODOMETER_SCALE * np.linalg.norm(vel, axis=1)
    return Drive(f"gins-{scenario}-{seed}", "test", 10.0, 0.0, columns)


def test_injected_biases_and_scales_are_recovered():
    """After 10 minutes of driving with GNSS the filter's biases are within 0.03 deg/s and
    0.03 m/s^2 of the injected ones, the odometer scale within 0.3 % and the gyro z scale within 0.5 %."""
    drive = _drive("sharp-cornering", 11, 600.0)
    received = drive.as_received()
    run = GinsEstimator().run(received, make_windows(received))
    end = run.xs[-60:].mean(axis=0)  # the last minute
    assert np.abs(np.rad2deg(end[BGX:BGX + 3]) - GYRO_BIAS_DPS).max() < 0.03, np.rad2deg(end[BGX:BGX + 3])
    assert np.abs(end[BAX:BAX + 3] - ACCEL_BIAS_MPS2).max() < 0.03, end[BAX:BAX + 3]
    assert abs(end[KO] - ODOMETER_SCALE) < 0.003, end[KO]
    assert abs(end[SG] - GYRO_Z_SCALE) < 0.005, end[SG]
    # the filter had to learn them: it started from zero biases and a unit scale
    assert run.xs[0, KO] == 1.0 and not run.xs[0, BGX:BAX + 3].any()


def _final_errors(drive, estimator, outage_s):
    rep = iv.evaluate(drive, outage_s, iv.Tile(), estimators=[estimator])
    return rep.summary[estimator.name]["final_position_error_m"]["mean"]


def test_the_vehicle_constraints_earn_their_place_imu_only():
    """Without the odometer, 30 s outages on a cornering drive end at least a third closer with the
    non-holonomic constraint than without it."""
    drive = _drive("sharp-cornering", 12, 600.0, odometer=False)
    with_nhc = _final_errors(drive, GinsEstimator(), 30.0)
    without = _final_errors(drive, GinsEstimator(nhc=False), 30.0)
    assert with_nhc < 0.67 * without, (with_nhc, without)


def test_zero_velocity_updates_hold_the_car_still_through_its_stops():
    """On hard-brake drives, which stop for 2-5 s, often inside an outage, 30 s outages end closer
    with zero-velocity updates than without them, and no window's distance is negative."""
    drive = _drive("hard-brake", 13, 600.0, odometer=False)
    with_zupt = _final_errors(drive, GinsEstimator(), 30.0)
    without = _final_errors(drive, GinsEstimator(zupt=False), 30.0)
    assert with_zupt < 0.8 * without, (with_zupt, without)
    received = drive.as_received()
    windows = make_windows(received)
    inputs = EstimatorInputs(received, windows, tile(windows, 30), 30, SensorBias.none())
    assert inputs.still.any()  # the outages do hold stops
    assert (GinsEstimator().estimate(inputs).disp_m >= 0).all()


def test_gins_does_not_apply_to_a_two_channel_drive(ideal_drive_csv):
    """IO-VNBD carries the longitudinal accelerometer and the yaw gyro only: the 3D filter is left
    out (the planar ekf is its filter) and says why."""
    rep = iv.evaluate(ideal_drive_csv, 10.0, estimators=["ins", "gins"])
    assert "gins" not in rep.summary


def test_a_receiver_that_jumps_does_not_drag_the_filter():
    """Fixes 40 m off for 3 s (a receiver coming back from under a bridge) are left out by the
    filter's 5-sigma gate; the receiver's own quality checks are not in the way (a drive given
    directly, unmarked)."""
    drive = _drive("roundabout", 14, 300.0, odometer=False)
    cols = dict(drive.columns)
    jump = (cols["t_s"] >= 200.0) & (cols["t_s"] < 203.0)
    cols["gnss_lat_deg"] = np.where(jump, cols["gnss_lat_deg"] + 40.0 / 111_200.0, cols["gnss_lat_deg"])
    jumped = Drive(drive.name, drive.source, drive.rate_hz, 0.0, cols).as_received()
    run = GinsEstimator().run(jumped, make_windows(jumped))
    from ionav_viz.core.geo import enu_of_geodetic

    b = run.bounds
    truth = enu_of_geodetic(np.interp(b.t_s, drive.t_s, drive.lat_deg), np.interp(b.t_s, drive.t_s, drive.lon_deg),
                            np.zeros(len(b.t_s)), *run.origin)
    during = (b.t_s >= 200.0) & (b.t_s <= 204.0)
    error = np.hypot(*(run.xs[during, :2] - truth[during, :2]).T)
    assert error.max() < 5.0, error


def test_the_filters_compile_once_whatever_the_drives_arrays():
    """numba compiles a kernel once per argument types (gins's filter about 20 s on a cold cache): a
    read-only array (an MCAP log's time, its windows' segments, a slice of outage starts) beside a
    writable one (a drive built in memory), or a call leaving ``q_scale0`` to its default beside the
    history arbiter's, made three of gins's filter and two of ekf's outage kernel. Both drives,
    outages and pseudo-outages alike, share one signature of each."""
    import json
    from pathlib import Path

    from ionav_viz.nav.planar_filter import outage_kernel
    from ionav_viz.nav.strapdown import run_filter

    corpus = Path(__file__).parent / "data" / "real"
    entry = json.loads((corpus / "corpus.json").read_text())["logs"]["roof_mems_rtk"]
    options = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", **entry.get("log", {})), span="0s:60s")
    for drive in (iv.load_drive(str(corpus / entry["file"]), options), _drive("roundabout", 14, 60.0)):
        report = iv.evaluate([drive], 10, estimators=["gins", "ekf"], run=iv.RunOptions(warm_up_s=20.0))
        assert report.to_dict()["sequences"]
    for kernel in (run_filter, outage_kernel):
        assert len(kernel.signatures) == 1, (kernel.__name__, kernel.signatures)
