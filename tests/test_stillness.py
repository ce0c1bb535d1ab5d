"""Standing still: the IMU's stillness detector, and no estimator driving backwards through a stop.

Real urban drives stand 20-30 % of the time, often inside an outage (SENSORS.md); a speed
integrated through zero ran the INS DR and the IDNN backwards at -4 m/s on a real roof-IMU log.
"""

from __future__ import annotations

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.nav.bias import resolve_bias
from ionav_viz.nav.ins import InsEstimator
from ionav_viz.nav.protocol import EstimatorInputs, applies
from ionav_viz.nav.registry import BUILTIN, builtin
from ionav_viz.nav.stillness import drive_still, still_samples
from ionav_viz.nav.windows import make_windows
from ionav_viz.sim.simulate import plan_truth, write_simulated_drive

SEED, MINUTES = 3, 10


@pytest.fixture(scope="module")
def stopping(tmp_path_factory):
    """A hard-brake drive (stops of 2-5 s) in the IO-VNBD format, and its true speed at each sample."""
    path = write_simulated_drive(tmp_path_factory.mktemp("stops") / "V-stops.csv", "hard-brake", SEED, 60.0 * MINUTES)
    drive = iv.load_drive(path)
    truth = plan_truth("hard-brake", SEED, 60.0 * MINUTES)
    return drive, np.interp(drive.t_s, truth.t_s, truth.speed_mps)


def test_the_detector_finds_the_stops_and_never_a_moving_car(stopping):
    drive, speed = stopping
    still = drive_still(drive)
    standing, moving = speed < 0.01, speed > 0.5
    assert standing.mean() > 0.05  # the drive does stop
    assert still[standing].mean() > 0.8, still[standing].mean()
    assert not still[moving].any()


def test_a_steady_turn_as_quiet_as_a_stop_is_not_still():
    """The worst case for a variance detector: a turn whose IMU shakes no more than the standing
    car's. The gyro's mean gives it away."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 60.0, 0.1)
    standing = t < 10.0
    gyro = np.where(standing, 0.0, 0.1) + np.deg2rad(0.3) + rng.normal(0.0, np.deg2rad(0.08), len(t))  # 0.3 deg/s bias
    accel = rng.normal(0.0, 0.15, len(t)) - 0.12
    still = still_samples(t, accel, gyro, reference_still=standing)
    assert still[(t > 1.0) & (t < 9.0)].all()
    assert not still[t > 11.0].any()


def test_without_a_calibrated_standstill_nothing_is_still():
    t = np.arange(0.0, 30.0, 0.1)
    quiet = np.zeros(len(t))
    assert not still_samples(t, quiet, quiet).any()
    assert not still_samples(t, quiet, quiet, reference_still=t < 2.0).any()  # 2 s: too little to measure the levels


def _plain_double_integration(inputs, bias):
    """The paper's INS as it was: the bias-corrected acceleration integrated twice, through zero."""
    acc = inputs.accel_mps2 - bias.accel_mps2
    n, w, k = acc.shape
    dv = (0.5 * (acc[..., 1:] + acc[..., :-1]) / inputs.rate_hz).reshape(n, w * (k - 1))
    v = np.concatenate([inputs.speed0_mps[:, None], inputs.speed0_mps[:, None] + np.cumsum(dv, axis=1)], axis=1)
    return (0.5 * (v[:, 1:] + v[:, :-1]) / inputs.rate_hz).reshape(n, w, k - 1).sum(axis=-1)


def test_a_stop_inside_an_outage_never_drives_an_estimator_backwards(stopping):
    drive, speed = stopping
    windows = make_windows(drive)
    n = 30
    # 30 s outages, not overlapping, each with a stop of the true motion inside
    starts, last = [], -n
    for k in range(1, len(windows) - n):
        inside = np.interp(windows.t0_s[k] + np.arange(n * 10) / 10, drive.t_s, speed)
        if k >= last + n and (inside < 0.01).any() and inside[0] > 2.0:
            starts.append(k)
            last = k
    assert len(starts) >= 5
    bias = resolve_bias(drive)
    inputs = EstimatorInputs(drive, windows, np.array(starts), n, bias)
    for name in BUILTIN:  # every built-in that runs on this drive (gins needs six axes: tests/test_gins.py)
        est = builtin(name)
        if not applies(est, drive):
            continue
        disp = est.estimate(inputs).disp_m
        assert (disp >= 0).all(), (name, disp.min())
    # the INS DR with the stops is closer to the distance driven than integrated through them
    ins = InsEstimator().estimate(inputs).disp_m
    plain = _plain_double_integration(inputs, bias)
    gnss = windows.gnss_disp_m[inputs.window_index]
    assert (plain < 0).any()  # the old integration did drive backwards here
    crse_now, crse_plain = np.abs(ins - gnss).sum(axis=1).mean(), np.abs(plain - gnss).sum(axis=1).mean()
    assert crse_now < 0.9 * crse_plain, (crse_now, crse_plain)  # measured: 34.3 against 42.3 m
