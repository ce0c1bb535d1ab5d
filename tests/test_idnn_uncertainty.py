"""The IDNN's uncertainty: fitted, stored beside the networks, propagated to the estimate's position
covariance; a model without one (every older model) loads and estimates none."""

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from ionav_viz.core.errors import InputError
from ionav_viz.dataset.samples import samples_dir
from ionav_viz.learning.idnn import UNCERTAINTY_FILE, IdnnEstimator, Uncertainty, load_model, save_model
from ionav_viz.learning.training import CHI2_2_95, OutageRuns, fit_uncertainty, nees
from ionav_viz.nav.bias import SensorBias
from ionav_viz.nav.protocol import EstimatorInputs, solve
from ionav_viz.nav.windows import make_windows
from ionav_viz.sources.iovnbd import read_iovnbd

from .conftest import run_cli

#: The repository's shipped model (not the installed package data: this checkout's).
SHIPPED = Path(__file__).resolve().parent.parent / "models" / "idnn"
#: The shipped networks' checksums before the uncertainty was added: they must not change.
SHIPPED_WEIGHTS = {"displacement.safetensors": "697d38c7cbe4c591fe1374f7b1708f0211cda3da7ea06b71ab494723144f9062",
                   "yaw_rate.safetensors": "6bf1c4271a0c0fd58eb176267c247f9f96586821e39552faaf18a64751bf8a6f"}


@pytest.fixture(scope="module")
def shipped():
    return load_model(SHIPPED)


@pytest.fixture(scope="module")
def outages():
    """30 s outages of the bundled roundabout test drive, as evaluate gives them."""
    drive = read_iovnbd(samples_dir() / "V-sim-roundabout.csv")
    windows = make_windows(drive)
    return EstimatorInputs(drive, windows, np.arange(31, len(windows) - 30, 30), 30, SensorBias(0.0, 0.0, "test", 0.0))


@pytest.fixture()
def older(tmp_path):
    """The shipped model as it was before it had an uncertainty: metadata without the entry, no file."""
    target = tmp_path / "older"
    shutil.copytree(SHIPPED, target)
    (target / UNCERTAINTY_FILE).unlink()
    meta = json.loads((target / "metadata.json").read_text())
    del meta["uncertainty"]
    (target / "metadata.json").write_text(json.dumps(meta))
    return target


def test_the_shipped_model_carries_an_uncertainty_and_its_networks_are_unchanged(shipped):
    assert isinstance(shipped.uncertainty, Uncertainty)
    for name, digest in SHIPPED_WEIGHTS.items():
        assert hashlib.sha256((SHIPPED / name).read_bytes()).hexdigest() == digest
        assert shipped.metadata["weights_sha256"][name] == digest
    info = shipped.metadata["uncertainty"]
    assert info["file"] == UNCERTAINTY_FILE and info["sha256"] == hashlib.sha256((SHIPPED / UNCERTAINTY_FILE).read_bytes()).hexdigest()


def test_the_estimate_has_a_position_covariance_that_grows_through_the_outage(shipped, outages):
    sol = solve(IdnnEstimator(shipped), outages)  # solve checks it: shape, finite, symmetric, PSD
    cov = sol.pos_cov_m2
    assert cov.shape == (outages.n_outages, 31, 2, 2)
    np.testing.assert_array_equal(cov[:, 0], 0.0)  # the start fix
    trace = np.trace(cov, axis1=-2, axis2=-1)
    assert np.all(np.diff(trace[:, 1:], axis=1) > 0)
    sd_30 = np.sqrt(trace[:, -1])
    assert np.all((sd_30 > 1.0) & (sd_30 < 500.0))  # metres after 30 s: neither nothing nor everything


def test_an_older_model_without_uncertainty_still_works_and_estimates_no_covariance(older, shipped, outages):
    model = load_model(older)
    assert model.uncertainty is None
    sol = solve(IdnnEstimator(older), outages)
    assert sol.pos_cov_m2 is None
    np.testing.assert_array_equal(sol.disp_m, solve(IdnnEstimator(shipped), outages).disp_m)  # the same networks


def test_save_and_load_round_trip_the_uncertainty(tmp_path, shipped):
    save_model(shipped, tmp_path / "copy")
    again = load_model(tmp_path / "copy")
    np.testing.assert_array_equal(again.uncertainty.disp_coef, shipped.uncertainty.disp_coef)
    np.testing.assert_array_equal(again.uncertainty.yaw_coef, shipped.uncertainty.yaw_coef)
    assert again.uncertainty.fix_var_m2 == shipped.uncertainty.fix_var_m2
    for name in SHIPPED_WEIGHTS:
        assert (tmp_path / "copy" / name).read_bytes() == (SHIPPED / name).read_bytes()


def test_a_changed_or_missing_uncertainty_file_is_refused(tmp_path):
    target = tmp_path / "m"
    shutil.copytree(SHIPPED, target)
    path = target / UNCERTAINTY_FILE
    raw = bytearray(path.read_bytes())
    raw[-1] ^= 1
    path.write_bytes(bytes(raw))
    with pytest.raises(InputError, match="sha256 differs"):
        load_model(target)
    path.unlink()
    with pytest.raises(InputError, match="cannot read the model's uncertainty"):
        load_model(target)


def test_a_pickle_in_place_of_the_uncertainty_is_refused(tmp_path):
    import pickle

    target = tmp_path / "m"
    shutil.copytree(SHIPPED, target)
    raw = pickle.dumps({"disp_coef": [0.0, 0.0, 0.0]})
    (target / UNCERTAINTY_FILE).write_bytes(raw)
    meta = json.loads((target / "metadata.json").read_text())
    meta["uncertainty"]["sha256"] = hashlib.sha256(raw).hexdigest()
    (target / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="not a valid uncertainty file"):
        load_model(target)


def test_the_fit_recovers_a_known_uncertainty(shipped, outages):
    """Position errors drawn from a known uncertainty's covariance: the fit finds covariances that
    hold 95 % of them in their 95 % ellipse, and about the true size."""
    truth = Uncertainty(np.array([-2.0, 1.5, 0.2]), np.array([-10.0, 0.3, 0.5]), 0.1)
    disp, yaw = shipped.predict(outages.windows, outages.starts, outages.n_windows, outages.bias,
                                None if shipped.config.inputs == "plain" else _calibration(outages))
    reps = 40
    disp, yaw = np.tile(disp, (reps, 1)), np.tile(yaw, (reps, 1))
    course, speed = np.tile(outages.course0_deg, reps), np.tile(outages.speed0_mps, reps)
    cov = truth.position_covariance(course, speed, disp, yaw)[:, 1:]
    rng = np.random.default_rng(5)
    err = np.einsum("nwab,nwb->nwa", np.linalg.cholesky(cov), rng.standard_normal(cov.shape[:-1]))
    runs = OutageRuns(disp, yaw, course, speed, err)
    fitted, info = fit_uncertainty(shipped, [], runs)
    q = nees(fitted, runs)
    assert np.mean(q <= CHI2_2_95) == pytest.approx(0.95, abs=0.02)
    assert np.mean(q) == pytest.approx(2.0, rel=0.1)
    size = np.trace(fitted.position_covariance(course, speed, disp, yaw)[:, -1], axis1=-2, axis2=-1)
    assert np.median(size / np.trace(cov[:, -1], axis1=-2, axis2=-1)) == pytest.approx(1.0, rel=0.2)
    assert info["coverage_95"]["10s"] == pytest.approx(0.95, abs=0.03)


def _calibration(inputs):
    from ionav_viz.nav.planar_filter import calibration

    return calibration(inputs.drive, inputs.windows, inputs.bias.accel_mps2, inputs.bias.gyro_radps)


def test_train_writes_the_uncertainty_or_says_why_not(tmp_path):
    train = [str(samples_dir() / f"V-sim-roundabout-train-{i}.csv") for i in (1, 2)]
    proc = run_cli("train", *train, "-o", str(tmp_path / "m"), "-q", "--epochs-disp", "1", "--epochs-yaw", "1")
    assert proc.returncode == 0, proc.stderr
    assert "uncertainty: the 95 % ellipse holds" in proc.stderr
    model = load_model(tmp_path / "m")
    assert isinstance(model.uncertainty, Uncertainty) and (tmp_path / "m" / UNCERTAINTY_FILE).is_file()


def test_drives_too_short_for_the_fit_leave_a_model_without_uncertainty(tmp_path):
    """One 150 s drive gives too few 60 s outages to fit seven parameters: the model gets none, says
    so in its metadata, and saves and loads without one."""
    from ionav_viz.learning.training import add_uncertainty

    model = load_model(SHIPPED)
    drive = read_iovnbd(samples_dir() / "V-sim-roundabout-train-1.csv")
    add_uncertainty(model, [(drive, SensorBias(0.0, 0.0, "test", 0.0))])
    assert model.uncertainty is None and "no uncertainty fitted" in model.metadata["uncertainty_skipped"]
    save_model(model, tmp_path / "m")
    assert load_model(tmp_path / "m").uncertainty is None and not (tmp_path / "m" / UNCERTAINTY_FILE).exists()
