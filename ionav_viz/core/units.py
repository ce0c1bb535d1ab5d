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


#: Time units a stamp may have been written in by mistake, as (factor to seconds, name).
_STAMP_UNITS = ((1e-3, "milliseconds"), (1e-6, "microseconds"), (1e-9, "nanoseconds"))


def stamp_unit_hint(stamps_s, first_s: float, last_s: float) -> str | None:
    """Why stamps (s as read) may miss a clock spanning ``first_s``..``last_s`` (s): written in
    milliseconds, microseconds or nanoseconds (scaled to seconds, they fall on that clock), or
    counted from the first sample instead of on the clock. A sentence for a hint, or None."""
    import numpy as np

    t = np.asarray(stamps_s, dtype=float)
    t = t[np.isfinite(t)]
    if not len(t):
        return None
    lo, hi = float(t.min()), float(t.max())
    span = max(last_s - first_s, 1.0)
    margin = max(10.0, 0.1 * span)

    def on_clock(a: float, b: float) -> bool:
        return a <= last_s + margin and b >= first_s - margin and (b - a) <= 10 * span + margin

    if on_clock(lo, hi):
        return None
    for factor, name in _STAMP_UNITS:
        if on_clock(lo * factor, hi * factor):
            return (f"its stamps look like {name} ({lo:.15g}-{hi:.15g}; divided by {1 / factor:.0f} they fall on the "
                    "log's clock): write seconds")
    if first_s > span + margin and -margin <= lo and hi <= span + margin:
        return (f"its stamps look like seconds since the drive's start ({lo:.15g}-{hi:.15g}); the log's clock runs "
                f"{first_s:.15g}-{last_s:.15g} s: add the drive's first stamp")
    return None
