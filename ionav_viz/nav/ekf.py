"""``ekf``: a GNSS-aided INS on the planar vehicle model, the baseline a practitioner would run.

The filter, its equations and noise values are :mod:`ionav_viz.nav.planar_filter`: it runs over
the drive with GNSS, and each outage goes on from its state at the outage start without GNSS,
with a zero-speed update where the IMU shows the car standing (:mod:`ionav_viz.nav.stillness`)
and its speed never below zero. Its position covariance through an outage is the filter's, widened
where the filter's own past on this drive says it is too sure: its NEES on pseudo-outages over the
GNSS before each outage (:mod:`ionav_viz.nav.history_check`, as the IDNN's learned one; on the
simulated phones its noise model, written for a car's IMU, left it 3-5 times too sure).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..core.covariance import scale_growth
from . import history_check
from .planar_filter import BA, BG, PLANAR_MEASUREMENTS, EkfNoise, forward_pass, increments, measurements
from .protocol import Estimate, EstimatorInputs, FilterHealth

#: The kind of each of the filter's measurement slots (:data:`ionav_viz.nav.planar_filter.PLANAR_MEASUREMENTS`).
PLANAR_MEASUREMENT_KINDS = ("GNSS position", "GNSS position", "GNSS speed", "GNSS course", "vehicle speed")


class EkfEstimator:
    """A GNSS-aided INS (see the module docstring)."""

    name = "ekf"
    label = "GNSS-aided INS"
    color = (86, 180, 233)  # Okabe-Ito sky blue

    def __init__(self, noise: EkfNoise | None = None) -> None:
        self.noise = noise or EkfNoise()
        self._last: dict[str, Any] = {}
        self._scale_note = ""

    def available(self) -> bool:
        return True

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        w = inputs.windows
        noise = self.noise
        if inputs.drive.velocity_fitted:  # no receiver velocity: the fixes' fit is noisier
            noise = replace(noise, gnss_speed_mps=max(noise.gnss_speed_mps, noise.gnss_fitted_speed_mps),
                            gnss_course_rad_at_10mps=max(noise.gnss_course_rad_at_10mps,
                                                         noise.gnss_fitted_course_rad_at_10mps))
        meas, inc = measurements(inputs.drive, w, noise), increments(w)
        fp = forward_pass(w, meas, inc, inputs.bias.accel_mps2, inputs.bias.gyro_radps, noise, keep_log=True)
        xs = fp.xs
        # each window's last grid point: where its state ends
        disp, yaw, cov = fp.outages(inputs.starts, inputs.n_windows, inputs.still[..., -1])
        cov = scale_growth(cov, self._history_scale(fp, inputs))
        if len(inputs.starts):
            start = xs[inputs.starts]
            self._last = {"accel_offset_mps2": f"{np.median(start[:, BA]):+.3f} (median at the outage starts)",
                          "gyro_bias_radps": f"{np.median(start[:, BG]):+.5f}",
                          "vehicle_speed": "used" if np.isfinite(meas.vehicle).any() else "none"}
        health = FilterHealth(w.t0_s, PLANAR_MEASUREMENTS, PLANAR_MEASUREMENT_KINDS, fp.log.innovation, fp.log.variance,
                              fp.log.status)
        return Estimate(np.maximum(disp, 0.0), yaw, health=health, pos_cov_m2=0.5 * (cov + np.swapaxes(cov, -1, -2)))

    def _history_scale(self, fp, inputs: EstimatorInputs) -> np.ndarray:
        """Per outage, the scale of what the filter's covariance grows by through it, both ways: its
        NEES on pseudo-outages over the GNSS before it (:func:`ionav_viz.nav.history_check.growth_scale`).
        A filter's noise model can be wider than the drive asks as well as narrower (a roof MEMS IMU
        of tests/data/real: 100 % of its final errors inside the 95 % ellipse with the scale only widening)."""
        n = inputs.n_windows

        def run(starts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            disp, yaw, cov = fp.outages(starts, n, inputs.still_grid[starts[:, None] + np.arange(n)[None, :]][..., -1])
            # as the estimate: solve rebuilds its track so
            return np.maximum(disp, 0.0), yaw, 0.5 * (cov + np.swapaxes(cov, -1, -2))

        scale, self._scale_note = history_check.growth_scale(inputs.windows, n, inputs.starts, run)
        return scale

    def describe(self) -> dict[str, Any]:
        return dict(self._last) | ({"uncertainty_scale": self._scale_note} if self._scale_note else {})
