"""Estimator plug-ins for the tests: a working one and broken ones (each fails in one way)."""

import numpy as np

from ionav_viz import Estimate, EstimatorInputs


class ConstantSpeed:
    """Keeps the GNSS speed of the outage start, drives straight (zero yaw rate)."""

    name = "const"
    label = "Constant speed"

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        disp = np.repeat(inputs.speed0_mps[:, None], inputs.n_windows, axis=1) * 1.0  # m per 1 s window
        return Estimate(disp_m=disp, yaw_rate_radps=np.zeros_like(disp))


def make_constant_speed():
    """A no-argument factory works as well as a class."""
    return ConstantSpeed()


class WrongShape(ConstantSpeed):
    name = "wrong-shape"

    def estimate(self, inputs):
        est = super().estimate(inputs)
        return Estimate(est.disp_m[:, :-1], est.yaw_rate_radps)


class NaNOutput(ConstantSpeed):
    name = "nan-out"

    def estimate(self, inputs):
        est = super().estimate(inputs)
        disp = est.disp_m.copy()
        disp[1, 3] = np.nan
        return Estimate(disp, est.yaw_rate_radps)


class Raises(ConstantSpeed):
    name = "raises"

    def estimate(self, inputs):
        raise ZeroDivisionError("division by zero in my filter")


class WritesInputs(ConstantSpeed):
    """Tries to change what every estimator sees: the drive's GNSS track and its own inputs."""

    name = "writes"

    def estimate(self, inputs):
        inputs.drive.columns["lat_deg"][:] = 0.0
        return super().estimate(inputs)


class ComplexOutput(ConstantSpeed):
    name = "complex"

    def estimate(self, inputs):
        est = super().estimate(inputs)
        return Estimate(est.disp_m + 1j, est.yaw_rate_radps)


class HugeOutput(ConstantSpeed):
    name = "huge"

    def estimate(self, inputs):
        est = super().estimate(inputs)
        disp = est.disp_m.copy()
        disp[2, 5] = 1e200
        return Estimate(disp, est.yaw_rate_radps)


class AppliesRaises(ConstantSpeed):
    name = "applies-raises"

    def applies(self, drive):
        raise KeyError("speed_can_mps")


class AvailableRaises(ConstantSpeed):
    name = "available-raises"

    def available(self):
        raise RuntimeError("no licence")


class DescribesAList(ConstantSpeed):
    name = "describes-list"

    def describe(self):
        return ["not", "a", "dict"]


class HintRaises(ConstantSpeed):
    """Refuses the drive with a hint of two lines, as a plug-in may write one."""

    name = "hint-raises"

    def estimate(self, inputs):
        from ionav_viz import InputError

        raise InputError("my filter needs a calibration", "calibrate it:\n   run my-calibrate  first")
