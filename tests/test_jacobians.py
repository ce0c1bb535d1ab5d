"""The filters' linearisations against their nonlinear models, by finite differences (as pyins's
tests check its error propagation against the nonlinear result).

* ``gins`` (:mod:`ionav_viz.nav.strapdown`): the error state's transition matrix over a window
  against the real mechanisation run twice, from a nominal state and from one with each error state
  perturbed (central differences: ``(err(+e) - err(-e)) / 2e`` is ``Phi``'s column to second order);
  the NHC's and odometer's rows of H against the vehicle-frame velocity computed from the state.
* ``ekf`` (:mod:`ionav_viz.nav.planar_filter`): the window's Jacobian against its own propagation,
  and the vehicle speed's H.
"""

from __future__ import annotations

import numpy as np
import pytest

from ionav_viz.core.rotation import dcm_of_euler, dcm_of_quat, quat_mul, quat_of_euler, quat_of_rotvec
from ionav_viz.nav import planar_filter as pf
from ionav_viz.nav import strapdown as sd

LAT0 = 52.0
# error states: their names (for messages) and the finite-difference step of each
ERR_NAMES = ["dp_e", "dp_n", "dp_u", "dv_e", "dv_n", "dv_u", "phi_e", "phi_n", "phi_u", "dbg_x", "dbg_y", "dbg_z",
             "dba_x", "dba_y", "dba_z", "dk", "dpsi_m", "dtheta_m", "ds_g"]
ERR_STEP = np.array([0.1] * 3 + [0.01] * 3 + [1e-3] * 3 + [1e-4] * 3 + [1e-2] * 3 + [1e-3] * 4)


def _nominal() -> np.ndarray:
    """A car on a slope, turning and braking, with biases and scale errors of a MEMS IMU."""
    x = np.zeros(sd.N_NOMINAL)
    x[sd.PX:sd.PX + 3] = (120.0, -40.0, 3.0)
    x[sd.VX:sd.VX + 3] = (9.0, 4.0, 0.3)
    x[sd.QW:sd.QW + 4] = quat_of_euler(0.03, -0.05, 0.42)
    x[sd.BGX:sd.BGX + 3] = np.deg2rad([0.05, -0.08, 0.1])
    x[sd.BAX:sd.BAX + 3] = (0.05, -0.03, 0.08)
    x[sd.KO], x[sd.PSIM], x[sd.THM], x[sd.SG] = 1.02, 0.0, 0.0, 0.01
    return x


def _perturbed(x: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """The estimated state whose error (estimated minus true, the module docstring's) from ``x`` is ``dx``."""
    out = x.copy()
    for nominal, error in ((sd.PX, sd.DP), (sd.VX, sd.DV), (sd.BGX, sd.DBG), (sd.BAX, sd.DBA)):
        out[nominal:nominal + 3] += dx[error:error + 3]
    out[sd.KO] += dx[sd.DK]
    out[sd.PSIM] += dx[sd.DPSIM]
    out[sd.THM] += dx[sd.DTHM]
    out[sd.SG] += dx[sd.DSG]
    out[sd.QW:sd.QW + 4] = quat_mul(quat_of_rotvec(-dx[sd.PHI:sd.PHI + 3]), x[sd.QW:sd.QW + 4])  # C_hat = exp(-[phi x]) C
    return out


def _error(estimated: np.ndarray, true: np.ndarray) -> np.ndarray:
    """The error state (19,) of ``estimated`` against ``true`` (attitude: ``C C_hat^T = I + [phi x]``)."""
    dx = np.zeros(sd.N_ERR)
    dx[sd.DP:sd.DP + 3] = estimated[sd.PX:sd.PX + 3] - true[sd.PX:sd.PX + 3]
    dx[sd.DV:sd.DV + 3] = estimated[sd.VX:sd.VX + 3] - true[sd.VX:sd.VX + 3]
    dx[sd.DBG:sd.DBG + 3] = estimated[sd.BGX:sd.BGX + 3] - true[sd.BGX:sd.BGX + 3]
    dx[sd.DBA:sd.DBA + 3] = estimated[sd.BAX:sd.BAX + 3] - true[sd.BAX:sd.BAX + 3]
    dx[sd.DK] = estimated[sd.KO] - true[sd.KO]
    dx[sd.DPSIM] = estimated[sd.PSIM] - true[sd.PSIM]
    dx[sd.DTHM] = estimated[sd.THM] - true[sd.THM]
    dx[sd.DSG] = estimated[sd.SG] - true[sd.SG]
    E = dcm_of_quat(true[sd.QW:sd.QW + 4]) @ dcm_of_quat(estimated[sd.QW:sd.QW + 4]).T
    dx[sd.PHI:sd.PHI + 3] = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    return dx


def _window(rate_hz: float, turn_dps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One second of IMU samples (body frame: braking on a slope, turning at ``turn_dps`` about the
    body's z) and the nominal state, its gyro scale error zero (see the transition test)."""
    x0 = _nominal()
    x0[sd.SG] = 0.0
    t = np.arange(0.0, 1.0 + 0.5 / rate_hz, 1.0 / rate_hz)
    gyr = np.tile(x0[sd.BGX:sd.BGX + 3] + np.deg2rad([0.0, 0.0, turn_dps]), (len(t), 1))
    acc = np.tile([-1.2, 1.8, 9.7], (len(t), 1))
    return t, acc, gyr, x0


def _window_means(x0: np.ndarray, states: np.ndarray, acc: np.ndarray, gyr: np.ndarray, t: np.ndarray):
    """The window's mean attitude, specific force in ``n`` and corrected z rate, as the filter forms them."""
    C = [dcm_of_quat(q) for q in states[:, sd.QW:sd.QW + 4]]
    f_b = acc - x0[sd.BAX:sd.BAX + 3]
    fn = np.mean([0.5 * (C[k] + C[k + 1]) @ (0.5 * (f_b[k] + f_b[k + 1])) for k in range(len(t) - 1)], axis=0)
    wz = (gyr[0, 2] - x0[sd.BGX + 2]) / (1.0 + x0[sd.SG])
    return 0.5 * (C[0] + C[-1]), fn, wz


@pytest.mark.parametrize(("turn_dps", "tolerance"), [(0.0, 0.005), (6.0, 0.03)])
@pytest.mark.parametrize("rate_hz", [10.0, 100.0])
def test_the_transition_matrix_is_the_mechanisation_linearised(rate_hz, turn_dps, tolerance):
    """Each column of ``Phi`` against the real mechanisation's error after one window, within
    ``tolerance`` of the column's largest entry. Without rotation the series is exact (F's chain
    dp <- dv <- phi <- db_g ends at the third power) and what is left is the Earth's rate and
    gravity's change with position, which the filter leaves out (2e-3). In a turn the filter's
    window means of ``C`` and ``f^n`` stand for quantities that turn with the car (2 % at 6 deg/s,
    10 % at 12 deg/s or with 2 deg/s of roll or pitch rate: the trade-off of one propagation per
    window, as pyins's ``time_step``). The nominal gyro scale error is zero: ``Phi`` leaves out its
    ``1 / (1 + s_g)`` in phi's rows for db_g_z (first order in s_g, 1 % at s_g = 0.01)."""
    t, acc, gyr, x0 = _window(rate_hz, turn_dps)
    T = float(t[-1] - t[0])
    states = sd.propagate(t, acc, gyr, x0, LAT0)
    Phi = sd.transition_matrix(*_window_means(x0, states, acc, gyr, t), T)
    numeric = np.zeros((sd.N_ERR, sd.N_ERR))
    for j in range(sd.N_ERR):
        dx = np.zeros(sd.N_ERR)
        dx[j] = ERR_STEP[j]
        plus = _error(sd.propagate(t, acc, gyr, _perturbed(x0, dx), LAT0)[-1], states[-1])
        minus = _error(sd.propagate(t, acc, gyr, _perturbed(x0, -dx), LAT0)[-1], states[-1])
        numeric[:, j] = (plus - minus) / (2.0 * ERR_STEP[j])
    # within tolerance of the column's largest entry of Phi - I (its identity would hide small terms);
    # 1e-5 for gravity's change with position (the columns of dp, 1.5e-6 per metre)
    bad = np.abs(numeric - Phi) > tolerance * np.abs(Phi - np.eye(sd.N_ERR)).max(axis=0) + 1e-5
    where = [f"d{ERR_NAMES[i]}/d{ERR_NAMES[j]}: Phi {Phi[i, j]:+.5g}, numeric {numeric[i, j]:+.5g}" for i, j in zip(*np.nonzero(bad), strict=True)]
    assert not where, where


@pytest.mark.parametrize(("entry", "turn_dps", "factor"), [((sd.DP, sd.DBG + 1), 0.0, 1.3), ((sd.DV + 1, sd.PHI), 0.0, 1.1),
                                                         ((sd.DV, sd.DSG), 6.0, 1.3), ((sd.PHI + 2, sd.DBG + 2), 0.0, -1.0)])
def test_the_transition_check_finds_a_wrong_entry(monkeypatch, entry, turn_dps, factor):
    """The check above fails for a transition matrix with one entry off: the third-order term of
    position from the gyro bias (the smallest kept), velocity from attitude, velocity from the gyro
    scale (in a turn), and the heading from the gyro bias with its sign flipped."""
    real = sd.transition_matrix

    def wrong(*args):
        Phi = real(*args)
        Phi[entry] *= factor
        return Phi

    monkeypatch.setattr(sd, "transition_matrix", wrong)
    with pytest.raises(AssertionError, match=f"d{ERR_NAMES[entry[0]]}/d{ERR_NAMES[entry[1]]}"):
        test_the_transition_matrix_is_the_mechanisation_linearised(10.0, turn_dps, 0.005 if turn_dps == 0 else 0.03)


def _vehicle_velocity(x: np.ndarray) -> np.ndarray:
    """The nonlinear model: the vehicle frame's lateral and vertical velocity and the odometer's
    reading (``k`` times the forward velocity), the IMU's body frame turned by the residual mount
    (yaw ``psi_m``, pitch ``theta_m``: ``vehicle = Rz(psi_m) Ry(theta_m) body``, the package's
    rotation convention)."""
    body = dcm_of_quat(x[sd.QW:sd.QW + 4]).T @ x[sd.VX:sd.VX + 3]
    vehicle = dcm_of_euler(0.0, x[sd.THM], x[sd.PSIM]) @ body
    return np.array([vehicle[1], vehicle[2], x[sd.KO] * body[0]])


def _numeric_h(model, x: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """``d model(x + dx) / d dx`` by central differences over the error state."""
    columns = []
    for j in range(sd.N_ERR):
        dx = np.zeros(sd.N_ERR)
        dx[j] = steps[j]
        columns.append((model(_perturbed(x, dx)) - model(_perturbed(x, -dx))) / (2.0 * steps[j]))
    return np.column_stack(columns)


def test_nhc_and_odometer_rows_are_the_vehicle_velocity_linearised():
    """At a residual mount of zero (where the filter's rows leave out nothing: they drop the
    mount angles' products with the attitude and velocity errors, second order), exact to 1e-6."""
    x = _nominal()
    z, H = sd.vehicle_velocity_model(x)
    np.testing.assert_allclose(z, _vehicle_velocity(x), rtol=0, atol=1e-12)
    numeric = _numeric_h(_vehicle_velocity, x, ERR_STEP * 1e-3)
    for i, name in enumerate(("NHC lateral", "NHC vertical", "odometer")):
        np.testing.assert_allclose(H[i], numeric[i], rtol=1e-6, atol=1e-7, err_msg=name)


def test_nhc_and_odometer_rows_with_a_residual_mount():
    """With the residual mount at a degree, the rows are right to that degree's order (the terms
    the filter leaves out are the mount angles times the others)."""
    x = _nominal()
    x[sd.PSIM], x[sd.THM] = np.deg2rad(1.0), np.deg2rad(-1.0)
    z, H = sd.vehicle_velocity_model(x)
    numeric = _numeric_h(_vehicle_velocity, x, ERR_STEP * 1e-3)
    np.testing.assert_allclose(z, _vehicle_velocity(x), rtol=0, atol=2e-3 * np.linalg.norm(x[sd.VX:sd.VX + 3]))
    np.testing.assert_allclose(H, numeric, rtol=0, atol=0.03 * np.abs(numeric).max())


def test_the_nhc_check_finds_a_wrong_entry(monkeypatch):
    real = sd.vehicle_velocity_model

    def wrong(x):
        z, H = real(x)
        H[0, sd.PHI + 2] *= -1.0  # the lateral velocity's dependence on the heading error, sign flipped
        return z, H

    monkeypatch.setattr(sd, "vehicle_velocity_model", wrong)
    with pytest.raises(AssertionError, match="NHC lateral"):
        test_nhc_and_odometer_rows_are_the_vehicle_velocity_linearised()


# --- the planar filter (ekf) --------------------------------------------------------------------

PLANAR_X = np.array([35.0, -12.0, 14.0, 0.7, 0.04, np.deg2rad(0.3), 1.01, 0.005])  # e, n, v, psi, b_a, b_g, k, s
PLANAR_STEP = np.array([0.1, 0.1, 0.01, 1e-4, 1e-3, 1e-5, 1e-4, 1e-4])


def test_the_planar_window_jacobian_is_its_propagation_linearised():
    F, G, W, T = -1.1, -0.6, np.deg2rad(9.0), 1.0  # braking in a left turn
    _, J, _, _ = pf.propagate_window(PLANAR_X, F, G, W, T)
    numeric = np.zeros_like(J)
    for j in range(pf.N_STATES):
        dx = np.zeros(pf.N_STATES)
        dx[j] = PLANAR_STEP[j]
        numeric[:, j] = (pf.propagate_window(PLANAR_X + dx, F, G, W, T)[0] - pf.propagate_window(PLANAR_X - dx, F, G, W, T)[0]) / (2 * PLANAR_STEP[j])
    np.testing.assert_allclose(J, numeric, rtol=1e-6, atol=1e-7)


def test_the_planar_vehicle_speed_row_is_its_model_linearised():
    z, H = pf.vehicle_speed_model(PLANAR_X)
    assert z == pytest.approx(PLANAR_X[pf.K] * PLANAR_X[pf.V])
    numeric = np.zeros(pf.N_STATES)
    for j in range(pf.N_STATES):
        dx = np.zeros(pf.N_STATES)
        dx[j] = PLANAR_STEP[j]
        numeric[j] = (pf.vehicle_speed_model(PLANAR_X + dx)[0] - pf.vehicle_speed_model(PLANAR_X - dx)[0]) / (2 * PLANAR_STEP[j])
    np.testing.assert_allclose(H, numeric, rtol=1e-6, atol=1e-9)

