"""Named unit conversions; readers apply them once, at the boundary."""

import math

G_MPS2 = 9.80665
KMH_TO_MPS = 1.0 / 3.6
DEG_TO_RAD = math.pi / 180.0
