"""Named unit conversions; readers apply them once, at the boundary."""

import math

G_MPS2 = 9.80665
KMH_TO_MPS = 1.0 / 3.6
DEG_TO_RAD = math.pi / 180.0


def wrap_360(angle_deg):
    """Angles (deg) into [0, 360): ``np.mod`` alone gives 360.0 for a tiny negative angle."""
    import numpy as np

    wrapped = np.mod(angle_deg, 360.0)
    return np.where(wrapped >= 360.0, 0.0, wrapped)
