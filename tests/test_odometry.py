"""Vehicle-speed odometry (issue 17, part 2): a calibrated wheel radius, and only where a speed is."""

from __future__ import annotations

import json

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.drive import Drive
from ionav_viz.experiment.outages import tile
from ionav_viz.nav.bias import SensorBias
from ionav_viz.nav.odometry import OdometryEstimator
from ionav_viz.nav.protocol import EstimatorInputs
from ionav_viz.nav.vehicle_speed import vehicle_speed
from ionav_viz.nav.windows import make_windows
from ionav_viz.sim.simulate import ideal_sensors_with, write_simulated_drive

from .conftest import run_cli
from .mcap_fixtures import write_fix_only

RADIUS_ERROR = 0.02  # the effective rolling radius is 2 % off the nominal 0.3 m (either way)


@pytest.fixture(scope="module")
def known_radius(tmp_path_factory):
    sensors = ideal_sensors_with(wheel_radius_error_min=RADIUS_ERROR, wheel_radius_error_max=RADIUS_ERROR)
    path = write_simulated_drive(tmp_path_factory.mktemp("odo") / "V-odo.csv", "roundabout", 5, 300.0, sensors)
    return iv.load_drive(str(path))


def test_calibrated_radius_and_distance_on_a_noise_free_drive(known_radius):
    drive = known_radius
    windows = make_windows(drive)
    starts = tile(windows, 10)
    est = OdometryEstimator()
    out = est.estimate(EstimatorInputs(drive, windows, starts, 10, SensorBias(0.0, 0.0, "none", 0.0)))
    radius = float(est.describe()["scale"].split()[1])
    # omega = v / (0.3 (1 +- 0.02)): the calibrated radius is one of the two, to 0.5 %
    assert min(abs(radius - 0.3 * (1 + RADIUS_ERROR)), abs(radius - 0.3 * (1 - RADIUS_ERROR))) < 0.005 * 0.3, radius
    moving = out.disp_m.sum() > 0
    truth = windows.gnss_disp_m[starts[:, None] + np.arange(10)[None, :]]
    assert moving and abs(out.disp_m.sum() / truth.sum() - 1.0) < 0.005, out.disp_m.sum() / truth.sum()


def test_odometry_runs_by_default_where_the_drive_has_wheel_speeds():
    rep = iv.evaluate(["roundabout"], 10.0).to_dict()
    assert [e["name"] for e in rep["estimators"]] == ["ins", "idnn", "odo", "ekf"]
    # the car's own speed beats twice-integrated acceleration by far on every bundled drive
    assert rep["summary"]["odo"]["crse_m"]["mean"] < 0.5 * rep["summary"]["ins"]["crse_m"]["mean"]


def _drive(**extra):
    t = np.arange(0, 20, 0.1)
    cols = {"t_s": t, "lat_deg": np.full_like(t, 52.0), "lon_deg": np.full_like(t, -1.5), "speed_mps": np.full_like(t, 10.0),
            "heading_deg": np.zeros_like(t), "accel_long_mps2": np.zeros_like(t), "yaw_rate_radps": np.zeros_like(t), **extra}
    return Drive("V-test", "test", 10.0, 0.0, cols)


def test_missing_zero_or_constant_speed_is_not_usable():
    t = np.arange(0, 20, 0.1)
    assert vehicle_speed(_drive()) is None
    assert vehicle_speed(_drive(speed_can_mps=np.zeros_like(t))) is None
    assert vehicle_speed(_drive(speed_can_mps=np.full_like(t, 13.0))) is None
    assert vehicle_speed(_drive(speed_can_mps=np.full_like(t, 13.0), wheel_speed_rl_radps=np.linspace(0, 30, len(t)),
                                wheel_speed_rr_radps=np.linspace(0, 30, len(t))))[1] == "rad/s"
    assert vehicle_speed(_drive(speed_can_mps=np.linspace(0, 13, len(t))))[1] == "m/s"


def test_a_log_without_vehicle_speed_leaves_odometry_out(tmp_path):
    path = write_fix_only(iv.load_drive("roundabout"), tmp_path / "fix-only.mcap", 10)
    rep = iv.evaluate([str(path)], 10.0).to_dict()
    assert "odo" not in [e["name"] for e in rep["estimators"]]
    chosen = run_cli("evaluate", str(path), "--estimators", "ins,odo", "--json")
    assert chosen.returncode == 0 and "Odometry left out: it does not apply to fix-only" in chosen.stderr
    assert [e["name"] for e in json.loads(chosen.stdout)["estimators"]] == ["ins"]
    alone = run_cli("evaluate", str(path), "--estimators", "odo")
    assert alone.returncode == 2 and "none of the chosen estimators (odo) applies" in alone.stderr and "Traceback" not in alone.stderr
    mixed = run_cli("evaluate", "roundabout", str(path), "--json")  # one report: the estimators common to both
    assert mixed.returncode == 0 and [e["name"] for e in json.loads(mixed.stdout)["estimators"]] == ["ins", "idnn", "ekf"]
    verbose = run_cli("-v", "evaluate", str(path), "--json")
    assert verbose.returncode == 0 and "odometry left out" in verbose.stderr
