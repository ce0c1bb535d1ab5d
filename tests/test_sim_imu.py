"""The 6-axis simulator (:mod:`ionav_viz.sim.imu`) is honest to ../shared/SENSORS.md and its logs
read back like a user's: the mount found, the reference scoring, ``gins`` running on them."""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.drive import IMU_COLUMNS
from ionav_viz.core.geo import wgs84
from ionav_viz.nav.windows import make_windows
from ionav_viz.sim.imu import SIM_TRUTH_TOPIC, imu_drive, write_imu_log
from ionav_viz.sources.imu.mount import parse_mount, rotation_angle_deg

from .conftest import run_cli


def _ten_hz(t, x):
    """Means of 0.1 s bins (as the message-log reader makes them), per column."""
    k = np.floor(t / 0.1).astype(int)
    n = np.bincount(k)
    keep = n > 0
    return np.column_stack([np.bincount(k, x[:, j])[keep] / n[keep] for j in range(x.shape[1])])


def _white(x):
    """White noise per sample: the robust spread of successive differences over sqrt(2)."""
    d = np.diff(x, axis=0)
    return 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0) / np.sqrt(2)


# SENSORS.md, per 10 Hz sample: (standing, driving) ranges of the accelerometer (m/s^2) and gyro (deg/s) noise
ACCEL_STANDING, ACCEL_DRIVING = (0.13, 0.28), (0.14, 0.45)
GYRO_STANDING, GYRO_DRIVING = (0.05, 0.14), (0.1, 0.75)
# A phone's own accelerometer standing, measured on the public real phone logs (docs/real-imu-logs.md:
# cmu_04_02_trip1 0.02, cloudpose_iphonex_ds1 and cmu_03_26_trip1 0.04 m/s^2): SENSORS.md's standing
# range is engine vibration through a car's own sensors; its consumer section says only standstill
# measures a phone's
PHONE_ACCEL_STANDING = (0.02, 0.04)


@pytest.mark.parametrize("grade", ["mems", "phone"])
def test_the_simulated_imus_noise_and_biases_are_what_real_cars_show(grade):
    log = imu_drive("hard-brake", 3, 240.0, grade)
    d = log.drive
    t = d.t_s
    imu = np.column_stack([d.columns[c] for c in IMU_COLUMNS])
    bins = _ten_hz(t, np.column_stack([imu, d.speed_mps]))
    standing, driving = bins[:, 6] < 0.01, bins[:, 6] > 5.0
    assert standing.sum() > 50 and driving.sum() > 500
    # noise on the forward axis and the yaw gyro, as SENSORS.md measured them (with 15 % slack)
    accel_still, accel_moving = _white(bins[standing][:, [0]])[0], _white(bins[driving][:, [0]])[0]
    gyro_still, gyro_moving = np.rad2deg(_white(bins[standing][:, [5]])[0]), np.rad2deg(_white(bins[driving][:, [5]])[0])
    accel_standing = ACCEL_STANDING if grade == "mems" else PHONE_ACCEL_STANDING
    assert accel_standing[0] * 0.85 < accel_still < accel_standing[1] * 1.15, accel_still
    assert ACCEL_DRIVING[0] * 0.85 < accel_moving < ACCEL_DRIVING[1] * 1.15, accel_moving
    assert GYRO_STANDING[0] * 0.85 < gyro_still < GYRO_STANDING[1] * 1.15, gyro_still
    assert GYRO_DRIVING[0] * 0.85 < gyro_moving < GYRO_DRIVING[1] * 1.15, gyro_moving
    # a yaw-rate bias between a calibrated IMU's 0 and a phone's 0.7 deg/s
    assert abs(np.rad2deg(log.gyro_bias_radps[2])) < 0.7 + 0.3 * (grade == "phone")
    # the mount: a few degrees off the car, as dashboards and roofs leave it
    assert 1.0 < rotation_angle_deg(log.mount) < 10.5
    # the receiver wanders by about a metre (u-blox, median 1.4 m) or a few (a phone)
    fix = log.fix
    _, _, err = wgs84().inv(d.columns["gnss_lon_deg"][fix], d.columns["gnss_lat_deg"][fix], d.lon_deg[fix], d.lat_deg[fix])
    low, high = (0.7, 2.5) if grade == "mems" else (1.5, 6.0)
    assert low < np.median(err) < high, np.median(err)
    assert np.median(np.diff(t[fix])) == pytest.approx(0.1 if grade == "mems" else 1.0, abs=0.01)


def test_a_simulated_log_reads_back_as_a_users_log_and_gins_runs_on_it(tmp_path):
    path = tmp_path / "drive.mcap"
    proc = run_cli("simulate", "roundabout", "--imu", "mems", "--seed", "4", "--duration", "300s", "-o", str(path))
    assert proc.returncode == 0, proc.stderr
    proc = run_cli("evaluate", str(path), "--truth-topic", SIM_TRUTH_TOPIC, "--imu-mount", "auto", "--estimators", "ins,ekf,gins", "--json")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert rep["truth"] == "reference"
    assert "applied the IMU mount estimated from the log" in proc.stderr
    gins, ins = rep["summary"]["gins"], rep["summary"]["ins"]
    assert gins["final_error_pct"]["mean"] < ins["final_error_pct"]["mean"]
    # the mount the reader found is the one drawn for the log, within the 2 degrees the reader's
    # estimate reaches on such logs (measured 0.2-1.8 degrees over six 300 s drives; gins estimates the rest)
    found = parse_mount(re.search(r"--imu-mount (\S+) gives it exactly", proc.stderr).group(1))
    log = imu_drive("roundabout", 4, 300.0, "mems")
    assert rotation_angle_deg(log.mount) > 2.0
    assert rotation_angle_deg(found.T @ log.mount) < 2.0, (found, log.mount)
    drive = iv.load_drive(path, iv.ReadOptions(log=iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC)))
    assert len(drive) == pytest.approx(3001, abs=2)  # 10 Hz bins of the 100 Hz IMU


def test_a_phone_standing_at_the_start_gets_the_course_it_drives_off_on(tmp_path):
    """A standing phone's 1 Hz fixes carry speed noise and random courses. The course the
    estimators start from before the car moves is the one it drives off on, not a standing fix's
    course nor a mix of the two (held fix by fix before interpolation; 2 s at speed needed).
    Measured on seeds 0-5: 14, 23, 2, 42, 20 and 9 degrees off before, 3-13 after."""
    read = iv.ReadOptions(log=iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, imu_mount="auto"))
    errors = []
    for seed in range(6):
        path = write_imu_log(tmp_path / f"{seed}.mcap", "hard-brake", seed, 60.0, "phone")
        drive = iv.load_drive(path, read)
        truth, received = make_windows(drive), make_windows(drive.as_received())
        assert drive.speed_mps[:40].max() < 0.05  # the car stands for the first seconds
        errors.append(abs((received.heading0_deg[0] - truth.heading0_deg[0] + 180.0) % 360.0 - 180.0))
    assert np.mean(errors) < 10.0 and max(errors) < 20.0, errors


def test_simulate_imu_refuses_what_it_cannot_carry(tmp_path):
    proc = run_cli("simulate", "roundabout", "--imu", "gyro", "-o", str(tmp_path / "x.mcap"))
    assert proc.returncode == 2 and "unknown IMU grade 'gyro'" in proc.stderr and "Traceback" not in proc.stderr
    proc = run_cli("simulate", "roundabout", "--imu", "mems", "-o", str(tmp_path / "x.csv"))
    assert proc.returncode == 2 and "MCAP" in proc.stderr
    proc = run_cli("simulate", "roundabout", "--imu", "mems", "--fleet", "held-out", "-o", str(tmp_path / "x.mcap"))
    assert proc.returncode == 2 and "--imu" in proc.stderr
    assert not list(tmp_path.iterdir())


def test_a_log_without_the_receivers_velocity_is_read_as_such_and_the_filters_weigh_it(tmp_path):
    """Many phone logs carry fixes and no velocity topic (``--gnss-velocity-topic none`` reads one
    that way). The speed and course fitted to 1 Hz fixes are the positions again, smoothed, not a
    Doppler measurement: the drive says so (``speed_fitted``) and both filters weigh them as the
    fit's noise (it lags in hard braking). Measured on nine 10 min phone drives (seeds 930-938,
    hard-brake, roundabout and sharp-cornering in turn, 10 s outages after the 30 s warm-up): ekf
    26.0 -> 15.4 % of distance (better on 9 of 9); with the phone grade measured against real phones
    (issue 41, docs/real-imu-logs.md) 28.3 -> 18.5 % (9 of 9), this 5 min drive 22.2 -> 18.7 %.
    For gins on the phone grade (single readings, reduced mechanisation, a holder that tilts) the weighting no longer earns its place reliably
    (7 of 9 before the holder's tilt was simulated; worse on the hard-brake drive after): checked
    here for the ekf only, gins only reads the flag (noted for re-tuning)."""
    from ionav_viz.core.drive import Drive

    log = iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, vehicle_speed_topic="none", imu_mount="auto", gnss_velocity_topic="none")
    for scenario, seed, estimator in (("roundabout", 931, "ekf"),):
        path = write_imu_log(tmp_path / f"{scenario}.mcap", scenario, seed, 300.0, "phone")
        drive = iv.load_drive(path, iv.ReadOptions(log=log))
        assert drive.speed_fitted.all()
        assert not iv.load_drive(path, iv.ReadOptions(log=replace(log, gnss_velocity_topic=None))).speed_fitted.any()
        unflagged = Drive(drive.name, drive.source, drive.rate_hz, drive.start_time_of_day_s,
                          {k: v for k, v in drive.columns.items() if k != "gnss_speed_fitted"}, gnss_fault=drive.gnss_fault,
                          receiver_fault=drive.receiver_fault, start_stamp_s=drive.start_stamp_s, imu=drive.imu)
        flagged_pct, unflagged_pct = (iv.evaluate([d], 10.0, estimators=[estimator]).summary[estimator]["final_error_pct"]["mean"]
                                      for d in (drive, unflagged))
        assert flagged_pct < 0.9 * unflagged_pct, (estimator, flagged_pct, unflagged_pct)
    proc = run_cli("evaluate", str(path), "--truth-topic", SIM_TRUTH_TOPIC, "--imu-mount", "auto", "--gnss-velocity-topic", "none",
                   "--estimators", "gins", "--json")
    assert proc.returncode == 0, proc.stderr
    # written out again, such a drive has no velocity topic: read back, its speed is still the fit's
    from ionav_viz.sources.mcap_writer import write_mcap

    written = write_mcap(drive, tmp_path / "again.mcap")
    assert "/gps/vel" not in written.topics and "gnss_speed_fitted" not in written.left_out
    again = iv.load_drive(tmp_path / "again.mcap", iv.ReadOptions(log=replace(log, gnss_velocity_topic=None)))
    assert again.speed_fitted.all()


# Measured by benchmarks/imu_character.py on the public real logs of phones in dash holders
# (docs/real-imu-logs.md; the data is not in the repository). The yaw gyro's standing noise per
# 10 Hz sample (deg/s; successive-sample spread over sqrt 2 where the stillness detector says
# standing): cmu_04_02_trip1 0.056, cmu_03_26_trip1 0.062, cloudpose_iphonex_ds1 0.067.
REAL_PHONE_GYRO_STANDING_DPS = (0.056, 0.067)
# The holder's wobble while driving (the reader's pitch- and roll-rate spread, deg/s):
# cloudpose_iphonex_ds1 1.65, cmu_03_26_trip1 2.01, cmu_04_02_trip1 2.44, cmu_03_26_trip2 2.74.
REAL_PHONE_WOBBLE_DPS = (1.65, 2.74)


def test_the_simulated_phone_stands_and_wobbles_as_real_phones_do(tmp_path):
    """Issue 41 point 6: the phone grade's log, written and read back like a user's, measured the
    way the real logs were (the stillness detector's stands, the reader's wobble), not from the
    grade's parameters, lies in the range the real phones span."""
    from ionav_viz.nav.stillness import drive_still

    path = write_imu_log(tmp_path / "phone.mcap", "hard-brake", 902, 300.0, "phone")
    drive = iv.load_drive(path, iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", truth_topic=SIM_TRUTH_TOPIC, vehicle_speed_topic="none")))
    still = drive_still(drive)
    both = still[1:] & still[:-1]
    assert both.sum() > 150  # its stands: over 15 s
    d = np.diff(drive.columns["gyro_z_radps"])[both]
    standing = np.rad2deg(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))
    low, high = REAL_PHONE_GYRO_STANDING_DPS
    assert low <= standing <= high, standing
    low, high = REAL_PHONE_WOBBLE_DPS
    assert low <= drive.imu.wobble_dps <= high, drive.imu.wobble_dps


def test_a_phone_receiver_loses_the_sky_as_the_real_phones_did(tmp_path):
    """The phone grade's receiver loses every fix 2.8 times per 10 minutes for 2-30 s (log-uniform:
    median sqrt(2 x 30) = 7.7 s), as the real phones' own receivers did (docs/real-imu-logs.md);
    a written log reads back with those stretches untrusted, and nothing else is lost."""
    from ionav_viz.sim.imu import IMU_GRADES, receiver_losses
    from ionav_viz.sim.simulate import SIMULATED_SCENARIOS

    t = np.arange(0.0, 100 * 3600.0, 1.0)
    lost = receiver_losses(np.random.default_rng(3), t, IMU_GRADES["phone"])
    edges = np.diff(np.concatenate([[0], lost.astype(int), [0]]))
    lengths = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)  # s, at 1 Hz
    # overlapping (or, at 1 Hz, touching) losses merge: stretches of a Poisson process of rate lam
    # with mean length E[L] come at lam exp(-lam (E[L] + 1 s)); log-uniform E[L] = (30 - 2) / ln 15
    lam, mean_length_s = 2.8 / 600.0, 28.0 / np.log(15.0)
    expected = lam * len(t) * np.exp(-lam * (mean_length_s + 1.0))
    assert abs(len(lengths) - expected) < 4.0 * np.sqrt(expected), (len(lengths), expected)
    assert lengths.min() >= 1 and np.median(lengths) == pytest.approx(7.7, abs=1.0)
    assert not receiver_losses(np.random.default_rng(3), t, IMU_GRADES["mems"]).any()

    path = write_imu_log(tmp_path / "p.mcap", "roundabout", 900, 600.0, "phone")
    drive = iv.load_drive(path, iv.ReadOptions(log=iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, imu_mount="auto", vehicle_speed_topic="none")))
    want = receiver_losses(np.random.default_rng([900, 10000 + SIMULATED_SCENARIOS.index("roundabout")]), drive.t_s, IMU_GRADES["phone"])
    assert want.any()
    untrusted = drive.receiver_fault != 0
    assert untrusted[want].mean() > 0.9  # each loss is a stretch without a trusted fix
    assert untrusted[~want].mean() < 0.02  # and little else is
