"""Standing still: the IMU's stillness detector, and no estimator driving backwards through a stop.

Real urban drives stand 20-30 % of the time, often inside an outage (SENSORS.md); a speed
integrated through zero ran the INS DR and the IDNN backwards at -4 m/s on a real roof-IMU log.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz import Estimate, EstimatorInputs
from ionav_viz.nav.ins import dead_reckon
from ionav_viz.nav.stillness import drive_still, still_samples
from ionav_viz.sim.imu import SIM_TRUTH_TOPIC, write_imu_log
from ionav_viz.sim.simulate import plan_truth, write_simulated_drive

SEED, MINUTES = 3, 10
#: The built-ins that run on IO-VNBD's two channels (``gins`` needs six measured axes and has its own
#: gated zero-velocity updates: tests/test_gins.py).
TWO_CHANNEL = ("ins", "idnn", "odo", "ekf")


@pytest.fixture(scope="module")
def stopping(tmp_path_factory):
    """A hard-brake drive (stops of 2-5 s) in the IO-VNBD format, and its true speed at each sample."""
    path = write_simulated_drive(tmp_path_factory.mktemp("stops") / "V-stops.csv", "hard-brake", SEED, 60.0 * MINUTES)
    drive = iv.load_drive(path)
    truth = plan_truth("hard-brake", SEED, 60.0 * MINUTES)
    return drive, np.interp(drive.t_s, truth.t_s, truth.speed_mps)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def test_the_detector_finds_the_stops_and_never_a_moving_car(stopping):
    drive, speed = stopping
    still = drive_still(drive)
    standing, moving = speed < 0.01, speed > 0.5
    assert standing.mean() > 0.05  # the drive does stop
    stops = [(a, b) for a, b in _runs(standing)[1:] if b - a >= 10]  # after the first stand (the calibration), >= 1 s
    assert len(stops) >= 5
    assert all(still[a:b].any() for a, b in stops)  # every stop is found
    # the centred 1 s window reaches the moving samples within 0.5 s of a stop's ends; further in,
    # each spread exceeds 1.6 times its standing median with a chance of about 1 % (2.5 standard
    # errors of a 10-sample spread), so at least 90 % of those samples are still
    gap = np.abs(np.arange(len(speed))[:, None] - np.flatnonzero(~standing)[None, :]).min(axis=1)
    inner = np.zeros_like(standing)
    for a, b in stops:
        inner[a:b] = gap[a:b] > 6
    assert still[inner].mean() > 0.9, still[inner].mean()
    assert not still[moving].any()  # a false "still" would stop a moving car: none at all


@pytest.mark.parametrize("scenario", ["sharp-cornering", "roundabout"])
def test_a_drive_that_never_stops_is_never_still_once_moving(tmp_path, scenario):
    path = write_simulated_drive(tmp_path / f"V-{scenario}.csv", scenario, SEED, 300.0)
    drive = iv.load_drive(path)
    truth = plan_truth(scenario, SEED, 300.0)
    speed = np.interp(drive.t_s, truth.t_s, truth.speed_mps)
    started = np.flatnonzero(speed > 0.05)[0]
    assert speed[started:].min() > 0.05  # the drive never stops again
    still = drive_still(drive)
    assert still[:started].mean() > 0.8  # its first stand calibrates the detector and is found
    assert not still[started:].any()


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


def _crawl_then_drive(standing_gyro_dps: float) -> iv.Drive:
    """Two minutes at 10 Hz: 20 s where a phone's receiver reports 0.6-0.9 m/s (its standing
    scatter, or a crawl), then 10 m/s; the gyro shakes 0.5 deg/s driving and ``standing_gyro_dps``
    in the first 20 s."""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 120.0, 0.1)
    first = t < 20.0
    speed = np.where(first, 0.75 + 0.15 * np.sin(t), 10.0)
    gyro = rng.normal(0.0, np.deg2rad(np.where(first, standing_gyro_dps, 0.5)))
    accel = rng.normal(0.0, np.where(first, 0.25, 0.45))
    cols = {"t_s": t, "lat_deg": np.full_like(t, 52.0), "lon_deg": np.full_like(t, -1.5), "speed_mps": speed,
            "heading_deg": np.zeros_like(t), "accel_long_mps2": accel, "yaw_rate_radps": gyro}
    return iv.Drive("V-crawl", "test", 10.0, 0.0, cols)


def test_a_stand_the_receivers_speed_scatter_hides_is_found_where_the_imu_confirms_it():
    """A phone's receiver scatters a standing car's speed to 0.8 m/s, above the 0.5 m/s that says
    "standing" for certain. Where the gyro there is four times quieter than driving (a phone on a
    standing car: SENSORS.md), the stand calibrates the detector; where it shakes as much as
    driving (a crawl in a jam), nothing is still."""
    standing = drive_still(_crawl_then_drive(0.12))
    t = np.arange(0.0, 120.0, 0.1)
    assert standing[(t > 1.0) & (t < 19.0)].mean() > 0.9
    assert not standing[t > 21.0].any()
    assert not drive_still(_crawl_then_drive(0.5)).any()


@pytest.mark.parametrize("seed", [5, 6, 7])
def test_a_phone_log_whose_receiver_hides_its_only_stand_still_gets_zero_velocity(tmp_path, seed):
    """Simulated phone logs (sharp-cornering, seeds chosen where the receiver's 3 s mean speed
    stays above 0.5 m/s for all but 0-2 s of the start's 6 s stand): the stand is found from the IMU,
    and no moving sample is still."""
    path = write_imu_log(tmp_path / "phone.mcap", "sharp-cornering", seed, 60.0, "phone")
    drive = iv.load_drive(path, iv.ReadOptions(log=iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, vehicle_speed_topic="none", imu_mount="auto")))
    still = drive_still(drive.as_received())
    standing, moving = drive.speed_mps < 0.01, drive.speed_mps > 0.5
    assert standing.sum() > 50
    assert still[standing].mean() > 0.8, still[standing].mean()
    assert not still[moving].any()


def _plain_double_integration(inputs: EstimatorInputs) -> np.ndarray:
    """The paper's INS as it was: the bias-corrected acceleration integrated twice, through zero."""
    acc = inputs.accel_mps2 - inputs.bias.accel_mps2
    n, w, k = acc.shape
    dv = (0.5 * (acc[..., 1:] + acc[..., :-1]) / inputs.rate_hz).reshape(n, w * (k - 1))
    v = np.concatenate([inputs.speed0_mps[:, None], inputs.speed0_mps[:, None] + np.cumsum(dv, axis=1)], axis=1)
    return (0.5 * (v[:, 1:] + v[:, :-1]) / inputs.rate_hz).reshape(n, w, k - 1).sum(axis=-1)


class PlainIns:
    """The INS DR without stillness or a floor at zero speed, as a plug-in estimator."""

    name = "plain"
    label = "INS DR through stops"

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        g = inputs.gyro_radps - inputs.bias.gyro_radps
        return Estimate(_plain_double_integration(inputs), (0.5 * (g[..., 1:] + g[..., :-1])).mean(axis=-1))


class FlooredIns:
    """The INS DR with its speed floored at zero but no zero-velocity updates (no stillness)."""

    name = "floored"
    label = "INS DR without ZUPT"

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        return Estimate(*dead_reckon(inputs.accel_mps2, inputs.gyro_radps, inputs.speed0_mps, inputs.bias, inputs.rate_hz))


def test_a_stop_inside_an_outage_never_drives_an_estimator_backwards(stopping):
    drive, speed = stopping
    n = 30
    # 30 s outages, not overlapping, each starting at speed with a stop of the true motion inside
    t = drive.t_s - drive.t_s[0]
    times, last = [], -np.inf
    for t0 in np.arange(10.0, t[-1] - n - 2.0):
        inside = np.interp(t0 + np.arange(n * 10) / 10, t, speed)
        if t0 >= last + n + 1 and (inside < 0.01).any() and inside[0] > 2.0:
            times.append(float(t0))
            last = t0
    assert len(times) >= 5
    report = iv.evaluate(drive, float(n), iv.At(tuple(times)), [*TWO_CHANNEL, PlainIns(), FlooredIns()])
    res = report.results[0]
    assert len(res.starts) == len(times)
    assert report.estimators == [*TWO_CHANNEL, "plain", "floored"]
    for name in TWO_CHANNEL:
        disp = res.estimates[name].disp_m
        assert disp.shape == (len(times), n)
        assert (disp >= 0).all(), (name, disp.min())
    # the drive needed it: integrated through the stops, the INS DR did drive backwards
    assert (res.estimates["plain"].disp_m < 0).any()
    # and a floor at zero with the zero-velocity updates brought it closer to the truth, in
    # displacement and at the outage's end; the updates on their own too (the floor stops the
    # backwards drive; a ZUPT also takes a forward speed error out at each stop)
    for metric in ("crse_m", "final_position_error_m"):
        now, plain, floored = (report.metric(name, metric).mean() for name in ("ins", "plain", "floored"))
        assert now < 0.9 * plain, (metric, now, plain)
        assert now < floored, (metric, now, floored)


def test_odometry_counts_signed_wheel_speeds_as_distance(stopping):
    """Wheel speeds are magnitudes: a log that signs them (negative while reversing, or a sensor
    mounted the other way) still gives distances, and the same ones."""
    drive, _ = stopping
    signed = replace(drive, columns={k: -v if k.startswith("wheel_speed") else v for k, v in drive.columns.items()})
    got = [iv.evaluate(d, 30.0, iv.Random(5, seed=1), ["odo"]).results[0].estimates["odo"].disp_m for d in (drive, signed)]
    assert (got[1] >= 0).all()
    np.testing.assert_allclose(got[1], got[0])
