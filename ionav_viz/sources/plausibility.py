"""Physical plausibility limits: values no car sensor can produce, checked at every reader's boundary.

One table for every source (IO-VNBD CSV, MCAP and ROS bags, KITTI). A value outside its limits is not noise to average
away but a broken file or a unit mix-up, so the reader refuses the drive with an error naming the
file, the row (CSV) or time (MCAP), the column and the limit. Limits are generous on purpose:
they catch impossible values (1e300 g, a heading of 1e20, a negative speed over ground), not
unusual driving. *Plausible but bad* GNSS (fixes at (0, 0), frozen or jumping fixes, 0 satellites)
is not refused here: that is a per-sample quality question for the GNSS integrity checks.

Limits (inclusive), in drive-model units:

========================  ==================  ==================================================
column                    limits              why
========================  ==================  ==================================================
``lat_deg``               -90 .. 90           WGS84
``lon_deg``               -180 .. 180         WGS84
``speed_mps``             0 .. 100            speed over ground is a magnitude; 360 km/h
``speed_can_mps``         0 .. 100            as above
``velocity_mps``          -100 .. 100         one component of a velocity (KITTI's vn, ve, vf, vl, vu)
``heading_deg``           -360 .. 360         a course, before wrapping to [0, 360)
``height_m``              -1000 .. 10000      ellipsoid/sea-level height of a road
``accel_long_mps2``       -157 .. 157         16 g, the widest full-scale range of vehicle IMUs
``accel_lat_mps2``        -157 .. 157         as above
``yaw_rate_radps``        -34.9 .. 34.9       2000 deg/s, the widest full-scale range of gyros
``accel_{x,y,z}_mps2``    -157 .. 157         16 g, as ``accel_long_mps2``
``gyro_{x,y,z}_radps``    -34.9 .. 34.9       2000 deg/s, as ``yaw_rate_radps``
``steering_angle_deg``    -1800 .. 1800       five turns of the steering wheel
``wheel_speed_*_radps``   -500 .. 500         100 m/s on a 0.2 m wheel
========================  ==================  ==================================================

Every value must also be finite, in every column a reader uses (those without limits too).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..core.errors import InputError
from ..core.units import G_MPS2

_G16_MPS2 = 16 * G_MPS2

#: column -> (lowest, highest) plausible value, in drive-model units.
LIMITS: dict[str, tuple[float, float]] = {
    "lat_deg": (-90.0, 90.0),
    "lon_deg": (-180.0, 180.0),
    "speed_mps": (0.0, 100.0),
    "speed_can_mps": (0.0, 100.0),
    "velocity_mps": (-100.0, 100.0),  # one component of a velocity (KITTI's vn, ve, vf, vl, vu)
    "heading_deg": (-360.0, 360.0),
    "height_m": (-1000.0, 10000.0),
    "accel_long_mps2": (-_G16_MPS2, _G16_MPS2),
    "accel_lat_mps2": (-_G16_MPS2, _G16_MPS2),
    "yaw_rate_radps": (-math.radians(2000.0), math.radians(2000.0)),
    **{f"accel_{a}_mps2": (-_G16_MPS2, _G16_MPS2) for a in "xyz"},
    **{f"gyro_{a}_radps": (-math.radians(2000.0), math.radians(2000.0)) for a in "xyz"},
    "steering_angle_deg": (-1800.0, 1800.0),
    "wheel_speed_fl_radps": (-500.0, 500.0),
    "wheel_speed_fr_radps": (-500.0, 500.0),
    "wheel_speed_rl_radps": (-500.0, 500.0),
    "wheel_speed_rr_radps": (-500.0, 500.0),
}


_UNITS = {"deg": "deg", "mps": "m/s", "mps2": "m/s^2", "radps": "rad/s", "m": "m"}


def first_implausible(column: str, values: np.ndarray) -> int | None:
    """Index of the first value of ``column`` that is not finite or outside its limits, else None."""
    lo, hi = LIMITS.get(column, (-math.inf, math.inf))
    with np.errstate(invalid="ignore"):
        bad = ~(np.isfinite(values) & (values >= lo) & (values <= hi))
    return int(np.argmax(bad)) if bad.any() else None


def implausible(column: str, value: float, file_unit: tuple[float, str] | None = None) -> str | None:
    """Why one value of ``column`` (drive-model units) is implausible, else None: "not a finite
    number" or "VALUE UNIT outside [LO, HI]", shown in ``file_unit`` = (factor to drive-model
    units, unit name) when given, so a message shows the value as the file has it."""
    lo, hi = LIMITS.get(column, (-math.inf, math.inf))
    if not math.isfinite(value):
        return "not a finite number"
    if lo <= value <= hi:
        return None
    factor, unit = file_unit or (1.0, _UNITS.get(column.rsplit("_", 1)[-1], ""))
    return f"{value / factor:.6g} {unit} outside [{lo / factor:.6g}, {hi / factor:.6g}]"


def check_plausible(columns: dict[str, np.ndarray], path: object, where: Callable[[int], str],
                    names: dict[str, str] | None = None,
                    file_units: dict[str, tuple[float, str]] | None = None) -> None:
    """Raise :class:`InputError` for the first implausible value of any column with limits.

    ``where(i)`` says where sample ``i`` is in the file ("row 57", "t = 12.3 s"); ``names`` maps a
    column to the name the file gives it, ``file_units`` to (factor to drive-model units, unit
    name) as for :func:`implausible`.
    """
    for column, values in columns.items():
        i = first_implausible(column, values)
        if i is not None:
            reason = implausible(column, float(values[i]), (file_units or {}).get(column))
            raise InputError(f"{path}: {where(i)}, {(names or {}).get(column, column)}: {reason}",
                             "no car sensor produces that value: fix or delete the sample, or check the column's unit")


#: Factors a speed column may read against the positions' ground speed when a unit is mixed up: (factor, hint).
_SPEED_MIXUPS = ((1 / 3.6, "its values look like m/s where the header says km/h: fix the header's unit or the values"),
                 (3.6, "its values look like km/h where the header says m/s: fix the header's unit or the values"),
                 (0.44704 / (1 / 3.6),
                  "its values look like mph where the header says km/h: fix the header's unit or the values"),
                 (1 / 0.621371,
                  "its values look like km/h where the header says mph: fix the header's unit or the values"),
                 (1000.0, "the time stamps look like milliseconds: write the time in seconds"))
#: A speed column and the positions' ground speed agree within this factor (median over moving seconds).
SPEED_AGREEMENT = 1.6
_MOVING_MPS = 3.0
_MIN_MOVING_S = 20


def check_units_agree(values: dict[str, np.ndarray], t_s: np.ndarray, path: object,
                      names: dict[str, str] | None = None) -> None:
    """Refuse a drive whose columns disagree by a unit's factor: a speed column (``speed_mps``,
    ``speed_can_mps``) against the ground speed the positions give, and the heading against the
    course they give, over the seconds the car moves (medians: GNSS losses and noise do not count).
    Each value passed :func:`check_plausible`, so a unit mix-up within the limits went through
    silently before (speed written in m/s under a km/h header, latitude and longitude in radians,
    the heading in radians). Too few moving seconds: nothing is checked."""
    from ..core.geo import steps_en_m

    names = names or {}
    if not {"lat_deg", "lon_deg"} <= values.keys() or len(t_s) < 3:
        return
    dt = float(np.median(np.diff(t_s)))
    step = max(1, int(round(1.0 / dt))) if dt > 0 else 1
    idx = np.arange(0, len(t_s), step)
    lat, lon, t = values["lat_deg"][idx], values["lon_deg"][idx], t_s[idx]
    d_east, d_north = steps_en_m(lat, lon)
    with np.errstate(divide="ignore", invalid="ignore"):
        ground = np.hypot(d_north, d_east) / np.diff(t)
    moved = (ground > 0) & np.isfinite(ground)  # a frozen fix (a GNSS loss) moves 0
    hint_pos = "the positions look like radians: write latitude and longitude in degrees"
    for column in ("speed_mps", "speed_can_mps"):
        if column not in values:
            continue
        speed = 0.5 * (values[column][idx][1:] + values[column][idx][:-1])
        use = moved & (speed > _MOVING_MPS)
        if use.sum() < _MIN_MOVING_S:
            continue
        ratio = float(np.median(speed[use] / ground[use]))
        if 1 / SPEED_AGREEMENT <= ratio <= SPEED_AGREEMENT:
            continue
        label = names.get(column, column)
        likely = next((why for factor, why in _SPEED_MIXUPS if abs(math.log(ratio / factor)) < math.log(1.15)), None)
        # 57 times, less cos(lat)
        if ratio > 10 and np.nanmax(np.abs(lat)) <= math.pi / 2 and np.nanmax(np.abs(lon)) <= math.pi:
            likely = None
            hint = hint_pos
        else:
            hint = likely or "check the column's unit and the positions'"
        raise InputError(f"{path}: {label} reads {ratio:.3g} times the speed the positions give (median over "
                         f"{int(use.sum())} moving seconds): a unit mixed up", hint)
    if "heading_deg" not in values:
        return
    speed = values.get("speed_mps", np.full(len(t_s), np.inf))[idx][1:]
    use = moved & (ground > _MOVING_MPS) & (speed > _MOVING_MPS)
    if use.sum() < _MIN_MOVING_S:
        return
    course = np.degrees(np.arctan2(d_east, d_north))[use]
    heading = values["heading_deg"][idx][1:][use]

    def off(angle: np.ndarray) -> float:
        return float(np.median(np.abs((angle - course + 180.0) % 360.0 - 180.0)))

    if off(np.degrees(heading)) < 15.0 and off(heading) > max(20.0, 3 * off(np.degrees(heading))):
        raise InputError(f"{path}: {names.get('heading_deg', 'heading_deg')} is off the course the positions give by "
                         f"{off(heading):.0f} deg (median), and within {off(np.degrees(heading)):.0f} deg read as "
                         "radians: a unit mixed up",
                         "write the heading in degrees")
