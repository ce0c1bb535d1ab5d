import numpy as np
import pytest

from ionav_viz.analysis.evaluate import evaluate_drive
from ionav_viz.analysis.metrics import truth_for
from ionav_viz.nav.bias import SensorBias, estimate_bias
from ionav_viz.sim.simulate import ideal_sensors_with, write_simulated_drive
from ionav_viz.sources.iovnbd import read_iovnbd


@pytest.mark.parametrize("scenario", ["motorway", "quick-accel"])
def test_noise_free_ins_matches_gnss_displacement_within_1cm(tmp_path, scenario):
    from ionav_viz.sim.simulate import SensorModel

    path = write_simulated_drive(tmp_path / "V-x.csv", scenario, seed=3, duration_s=120, sensors=SensorModel.ideal())
    res = evaluate_drive(read_iovnbd(path), 10, ["ins"], bias=SensorBias.none())
    disp, yaw = truth_for(res.windows, res.starts, 10)
    assert res.starts.size >= 10
    assert np.abs(disp - res.estimates["ins"].disp_m).max() < 0.01
    assert np.abs(yaw - res.estimates["ins"].yaw_rate_radps).max() < 1e-3


def test_uncorrected_accelerometer_bias_drifts_as_half_b_t_squared(tmp_path):
    b = 0.1  # m/s^2
    path = write_simulated_drive(tmp_path / "V-b.csv", "motorway", seed=3, duration_s=120, sensors=ideal_sensors_with(accel_offset_mps2=b))
    res = evaluate_drive(read_iovnbd(path), 10, ["ins"], bias=SensorBias.none())
    # displacement over-estimated by 1/2 b t^2 after t = 10 s: e = truth - estimate = -5 m
    np.testing.assert_allclose(res.metrics["ins"]["cae_m"], -0.5 * b * 10.0**2, atol=0.15)
    disp, _ = truth_for(res.windows, res.starts, 10)
    err_per_window = (res.estimates["ins"].disp_m - disp).mean(axis=0)
    # window w (1-based) adds b/2 * (w^2 - (w-1)^2) = b (2w - 1) / 2
    np.testing.assert_allclose(err_per_window, b * (2 * np.arange(1, 11) - 1) / 2, atol=0.02)


def test_bias_estimated_from_stationary_drive_removes_the_drift(tmp_path):
    sensors = ideal_sensors_with(accel_offset_mps2=0.1, gyro_bias_dps=0.5)
    still = read_iovnbd(write_simulated_drive(tmp_path / "V-s.csv", "stationary", seed=1, duration_s=60, sensors=sensors))
    bias = estimate_bias(still)
    assert bias.accel_mps2 == pytest.approx(0.1, abs=0.005)
    assert bias.gyro_radps == pytest.approx(np.radians(0.5), abs=1e-4)  # counter-clockwise positive
    drive = read_iovnbd(write_simulated_drive(tmp_path / "V-m.csv", "motorway", seed=3, duration_s=120, sensors=sensors))
    res = evaluate_drive(drive, 10, ["ins"], bias=bias)
    assert np.abs(res.metrics["ins"]["cae_m"]).max() < 0.3
