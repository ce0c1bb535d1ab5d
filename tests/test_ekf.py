"""The GNSS-aided INS (issue 17, part 1): it learns the accelerometer offset and grade, and is
never worse than the paper's INS DR on a noise-free drive."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import ionav_viz as iv
from ionav_viz.core.units import G_MPS2
from ionav_viz.nav.planar_filter import BA, BG, S, forward
from ionav_viz.nav.windows import make_windows
from ionav_viz.sim.simulate import ideal_sensors_with, write_simulated_drive
from ionav_viz.sources.iovnbd import HEADER

OFFSET = 0.3  # m/s^2, injected: a pitched mount


@pytest.fixture(scope="module")
def offset_and_grade(tmp_path_factory):
    sensors = ideal_sensors_with(accel_offset_mps2=OFFSET, grade_rms=0.02)
    return write_simulated_drive(tmp_path_factory.mktemp("ekf") / "V-grade.csv", "motorway", 11, 300.0, sensors)


def test_offset_estimate_converges_to_the_injected_offset_plus_grade(offset_and_grade):
    drive = iv.load_drive(str(offset_and_grade))
    windows = make_windows(drive)
    xs, _, slow = forward(drive, windows, 0.0, 0.0)  # told nothing: no standstill biases
    # the truth, independently: the CSV's vertical velocity over its speed is sin(grade)
    raw = pd.read_csv(offset_and_grade, skipinitialspace=True)
    cols = {c.strip(): c for c in raw.columns}
    t = raw[cols[HEADER[1]]].to_numpy() - raw[cols[HEADER[1]]].to_numpy()[0]
    v = raw[cols[HEADER[4]]].to_numpy() / 3.6
    sin_grade = np.divide(raw[cols[HEADER[7]]].to_numpy() / 3.6, v, out=np.zeros_like(v), where=v > 1)
    truth = OFFSET + G_MPS2 * np.interp(windows.t0_s, t, sin_grade)
    later = (windows.t0_s > 60) & (windows.speed0_mps > 5)  # after a minute of driving
    err = xs[later, BA] - truth[later]
    assert abs(np.median(err)) < 0.03 and np.sqrt(np.mean(err**2)) < 0.1, (np.median(err), np.sqrt(np.mean(err**2)))
    assert abs(np.median(slow[later]) - OFFSET) < 0.1


def test_never_worse_than_ins_on_a_noise_free_drive(ideal_drive_csv):
    s = iv.evaluate([str(ideal_drive_csv)], 10.0, estimators=["ins", "ekf"]).to_dict()["summary"]
    for metric in ("crse_m", "final_position_error_m"):
        assert s["ekf"][metric]["mean"] <= s["ins"][metric]["mean"] + 0.1, metric


def test_runs_by_default_and_says_what_it_learnt():
    rep = iv.evaluate(["hard-brake"], 10.0).to_dict()
    names = [e["name"] for e in rep["estimators"]]
    assert names == ["ins", "idnn", "odo", "ekf"]
    info = next(e for e in rep["estimators"] if e["name"] == "ekf")["info"]
    assert info["vehicle_speed"] == "used" and "accel_offset_mps2" in info
    assert rep["summary"]["ekf"]["crse_m"]["mean"] < rep["summary"]["ins"]["crse_m"]["mean"]


def test_learns_an_injected_gyro_scale_error_in_turns(tmp_path):
    # a gyro reading 2.5 % high (and a 0.3 deg/s bias, told nothing): the GNSS course in the
    # roundabouts makes the scale observable; a straight motorway leaves it near its prior 0
    sensors = ideal_sensors_with(gyro_scale_error=0.025, gyro_bias_dps=0.3)
    drive = iv.load_drive(str(write_simulated_drive(tmp_path / "V-scale.csv", "roundabout", 12, 300.0, sensors)))
    windows = make_windows(drive)
    xs, Ps, _ = forward(drive, windows, 0.0, 0.0)
    # resolved: within 0.003 of it, and the filter's sigma below a third of the error it learnt (its
    # heading noise per radian turned, turn_scale_sd, keeps it from claiming more)
    assert abs(xs[-1, S] - 0.025) < 0.003 and np.sqrt(Ps[-1, S, S]) < 0.025 / 3, xs[-1, S]
    assert abs(xs[-1, BG] - np.deg2rad(0.3)) < np.deg2rad(0.05)  # on the counter-clockwise rate, as the simulator adds it


def test_a_phones_stale_first_course_teaches_the_filter_no_gyro_bias():
    """The held-out phone drive of the corpus (tests/data/real) begins with 14 s of unusable fixes
    holding a stale course (6 deg; the car heads 216 deg at the first usable fix). A filter started
    from them corrected its course by 156 deg at a 2 deg sigma and learnt a gyro bias of -0.2 rad/s
    (the gyro against the GNSS yaw rate: 0.001 rad/s), which turned every outage: its yaw-rate CRSE
    was 0.57 rad/s against the gyro's own 0.26. Started at the segment's first usable fix, it is no
    worse than the gyro."""
    import dataclasses
    import json
    from pathlib import Path

    from ionav_viz.core.gnss_quality import GnssLimits

    corpus = Path(__file__).parent / "data" / "real"
    entry = json.loads((corpus / "corpus.json").read_text())["logs"]["phone_flat_meszdav_q2"]
    read = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", vehicle_speed_topic="none"),
                          gnss_limits=dataclasses.replace(GnssLimits(), max_sigma_m=entry["max_sigma_m"]))
    report = iv.evaluate([str(corpus / entry["file"])], 10, estimators=["ins", "ekf"], read=read).to_dict()
    yaw = {name: np.mean([s[name]["yaw_crse_radps"] for s in report["sequences"]]) for name in ("ins", "ekf")}
    assert yaw["ekf"] <= 1.1 * yaw["ins"], yaw
