"""A drive's vehicle speed (wheel speeds or the indicated CAN speed), as odometry and the GNSS-aided
filter use it: which columns, in which unit, and whether they are usable."""

from __future__ import annotations

import numpy as np

from ..core.drive import Drive

#: The nominal effective rolling radius (m) that turns wheel speeds (rad/s) into a speed; real
#: ones are 1-3 % off it, so odometry and the filter calibrate the scale against GNSS.
NOMINAL_RADIUS_M = 0.3

#: Where a drive's vehicle speed comes from, in order of preference: (columns averaged, unit).
SOURCES = (
    (("wheel_speed_rl_radps", "wheel_speed_rr_radps"), "rad/s"),
    (("speed_can_mps",), "m/s"),
)


def vehicle_speed(drive: Drive) -> tuple[np.ndarray, str, str] | None:
    """The drive's usable vehicle speed: (values per sample, unit, description), or None."""
    for columns, unit in SOURCES:
        if not all(c in drive.columns for c in columns):
            continue
        values = np.mean([drive.columns[c] for c in columns], axis=0)
        if np.isfinite(values).all() and np.any(values != 0) and np.ptp(values) > 0:
            return values, unit, " and ".join(columns)
    return None


def nominal_mps_per_unit(unit: str) -> float:
    """How many m/s one of ``unit`` is, nominally: a wheel speed (``"rad/s"``) at
    NOMINAL_RADIUS_M, a speed (``"m/s"``) as it is."""
    return NOMINAL_RADIUS_M if unit == "rad/s" else 1.0


def speed_in_mps(values: np.ndarray, unit: str) -> np.ndarray:
    """:func:`vehicle_speed`'s values in m/s (wheel speeds at the nominal radius: odometry and the
    filters calibrate the scale against GNSS)."""
    return values * nominal_mps_per_unit(unit)


def why_no_vehicle_speed(drive: Drive) -> str:
    """Why :func:`vehicle_speed` found none, for messages."""
    present = [c for cols, _ in SOURCES for c in cols if c in drive.columns]
    if not present:
        return "no wheel speeds or vehicle speed"
    return (f"its {', '.join(present)} {'is' if len(present) == 1 else 'are'} not usable "
            "(non-finite, all zero or constant)")
