"""The filters' one update and their measurements, each against an independent computation, and
the health every update leaves in the reports and the recording.

* The shared Joseph-form update (:mod:`ionav_viz.nav.kalman`) against the textbook matrices in
  numpy; a gated measurement leaves state and covariance as they were.
* Each of ``gins``'s measurement functions: its row of H against central finite differences of
  its prediction over the error state (the nonlinear model, as ``test_jacobians`` does for the
  transition), its value against the quantity computed from the state directly.
* A receiver that jumps: the gate's rejections reach the JSON, the text report and the recording.
"""

from __future__ import annotations

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.drive import Drive
from ionav_viz.core.rotation import dcm_of_quat
from ionav_viz.nav import kalman
from ionav_viz.nav import strapdown as sd

from .test_gins import _drive
from .test_jacobians import ERR_STEP, _nominal, _perturbed
from .test_replay import read_rrd


def _spd(n: int, seed: int) -> np.ndarray:
    a = np.random.default_rng(seed).normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


@pytest.mark.parametrize("cols", [[2], [0, 3, 5], list(range(8))])
def test_the_joseph_update_is_the_textbook_one(cols):
    """x + K nu and (I - K H) P (I - K H)^T + K r K^T, K = P H^T / S, computed densely in numpy."""
    n = 8
    P = _spd(n, 1)
    x = np.arange(n, dtype=float)
    H = np.zeros(n)
    H[cols] = np.linspace(0.5, 1.5, len(cols))
    nu, r = 0.7, 0.3
    S = H @ P @ H + r
    K = P @ H / S
    A = np.eye(n) - np.outer(K, H)
    want_P = A @ P @ A.T + r * np.outer(K, K)
    want_x = x + K * nu
    S_got, used = kalman.update(P, x, H, nu, r)
    assert used and S_got == pytest.approx(S, rel=1e-12)
    np.testing.assert_allclose(x, want_x, rtol=1e-12)
    np.testing.assert_allclose(P, want_P, rtol=1e-10, atol=1e-12)
    assert np.array_equal(P, P.T)


def test_a_gated_measurement_changes_nothing():
    """An innovation beyond the gate (NIS 100 against 25) leaves the state and covariance alone."""
    P = _spd(5, 2)
    x = np.ones(5)
    P0, x0 = P.copy(), x.copy()
    H = np.array([0.0, 1.0, 0.0, 0.0, 0.0])
    S = P[1, 1] + 1.0
    _, used = kalman.update(P, x, H, 10.0 * np.sqrt(S), 1.0, gate=25.0)
    assert not used
    assert np.array_equal(P, P0) and np.array_equal(x, x0)


def _prediction(name: str, **given):
    return lambda x: sd.measurement_model(name, x, **given)[0]


POS = np.array([118.0, -41.0, 2.5])
VEL = np.array([8.7, 4.2])
GYRO_MEAN = np.deg2rad([0.04, -0.07, 0.12])
OMEGA = np.array([0.0, 4.5e-5, 5.7e-5])
FORCE = np.array([0.41, -0.17, 9.79])  # a standing car's mean specific force, nose up on a grade (m/s^2)
MEASUREMENTS = {
    "GNSS east": ("gnss_position", {"pos": POS, "axis": 0}),
    "GNSS north": ("gnss_position", {"pos": POS, "axis": 1}),
    "GNSS up": ("gnss_position", {"pos": POS, "axis": 2}),
    "GNSS velocity east": ("gnss_velocity", {"vel": VEL, "axis": 0}),
    "GNSS velocity north": ("gnss_velocity", {"vel": VEL, "axis": 1}),
    **{f"ZUPT {a}": ("zupt", {"axis": i}) for i, a in enumerate("enu")},
    **{f"ZARU {a}": ("zaru", {"axis": i, "gyro_mean": GYRO_MEAN, "omega_ie": OMEGA}) for i, a in enumerate("xyz")},
    "NHC lateral": ("nhc_lateral", {}),
    "NHC vertical": ("nhc_vertical", {}),
    "odometer": ("odometer", {"speed_mps": 9.5}),
    **{f"level {a}": ("level", {"axis": i, "specific_force": FORCE}) for i, a in enumerate("xy")},
}


@pytest.mark.parametrize("label", list(MEASUREMENTS))
def test_each_measurement_row_is_its_prediction_linearised(label):
    """Central differences of the prediction over each error state (at a zero residual mount: the
    rows leave out only second-order products) equal the measurement's row of H."""
    name, given = MEASUREMENTS[label]
    x = _nominal()
    _, H = sd.measurement_model(name, x, **given)
    f = _prediction(name, **given)
    steps = ERR_STEP * 1e-3
    numeric = np.zeros(sd.N_ERR)
    for j in range(sd.N_ERR):
        dx = np.zeros(sd.N_ERR)
        dx[j] = steps[j]
        numeric[j] = (f(_perturbed(x, dx)) - f(_perturbed(x, -dx))) / (2.0 * steps[j])
    # ZARU leaves out the Earth rate's turn with the attitude error (7e-5 rad/s times the error)
    atol = 1e-4 if name == "zaru" else 1e-7
    np.testing.assert_allclose(H, numeric, rtol=1e-6, atol=atol, err_msg=label)


def test_each_measurement_predicts_the_quantity_it_measures():
    """The values against the quantities computed from the state by hand (prediction minus measurement)."""
    x = _nominal()
    C = dcm_of_quat(x[sd.QW:sd.QW + 4])
    v = x[sd.VX:sd.VX + 3]
    vb = C.T @ v
    assert sd.measurement_model("gnss_position", x, pos=POS, axis=1)[0] == pytest.approx(x[sd.PX + 1] - POS[1])
    assert sd.measurement_model("gnss_velocity", x, vel=VEL, axis=0)[0] == pytest.approx(x[sd.VX] - VEL[0])
    assert sd.measurement_model("zupt", x, axis=2)[0] == pytest.approx(v[2])
    earth_b = C.T @ OMEGA
    got = sd.measurement_model("zaru", x, axis=1, gyro_mean=GYRO_MEAN, omega_ie=OMEGA)[0]
    assert got == pytest.approx(x[sd.BGX + 1] + earth_b[1] - GYRO_MEAN[1])
    assert sd.measurement_model("nhc_lateral", x)[0] == pytest.approx(vb[1])  # zero residual mount
    assert sd.measurement_model("odometer", x, speed_mps=9.5)[0] == pytest.approx(x[sd.KO] * vb[0] - 9.5)
    # standing, the accelerometer reads gravity's reaction (up, |FORCE|) in the body frame plus its bias
    up_b = C.T @ np.array([0.0, 0.0, np.linalg.norm(FORCE)])
    for axis in (0, 1):
        got = sd.measurement_model("level", x, axis=axis, specific_force=FORCE)[0]
        assert got == pytest.approx(up_b[axis] + x[sd.BAX + axis] - FORCE[axis])


@pytest.fixture(scope="module")
def jumping_drive():
    """A 5 min IMU-only roundabout drive whose receiver is 40 m off for 3 s from 200 s."""
    drive = _drive("roundabout", 14, 300.0, odometer=False)
    cols = dict(drive.columns)
    jump = (cols["t_s"] >= 200.0) & (cols["t_s"] < 203.0)
    cols["gnss_lat_deg"] = np.where(jump, cols["gnss_lat_deg"] + 40.0 / 111_200.0, cols["gnss_lat_deg"])
    return drive, Drive(drive.name, drive.source, drive.rate_hz, 0.0, cols)


def test_gate_rejections_reach_the_report(jumping_drive):
    clean, jumped = jumping_drive
    health = {}
    for key, drive in (("clean", clean), ("jumped", jumped)):
        rep = iv.evaluate(drive, 10.0, estimators=["gins", "ekf"])
        health[key] = rep.to_dict()["filter_health"]
        text = rep.to_text()
    assert health["clean"]["gins"]["GNSS position"]["gated"] == 0
    got = health["jumped"]["gins"]["GNSS position"]
    assert got["gated"] == 3 and got["longest_gated_s"] == 3.0, got  # the boundaries at 200, 201 and 202 s
    assert got["updates"] == health["clean"]["gins"]["GNSS position"]["updates"]
    assert "GNSS/INS 3D health: GNSS position used at" in text and "(3 gated out, longest 3 s)" in text
    # the planar filter has no gate: its innovations at the jump are large instead
    assert health["jumped"]["ekf"]["GNSS position"]["mean_nis"] > 2 * health["clean"]["ekf"]["GNSS position"]["mean_nis"]


def test_gate_rejections_reach_the_recording(jumping_drive, tmp_path):
    _, jumped = jumping_drive
    out = tmp_path / "jump.rrd"
    iv.replay(jumped, 10.0, estimators=["gins"], output=out)
    rows, _ = read_rrd(out)
    gated = rows["/health/gins/gated/gnss_position"]
    assert [round(t) for t, _ in gated] == [200, 201, 202]
    nis = rows["/health/gins/nis/gnss_position"]
    assert len(nis) > 250 and "/health/expected" in rows
