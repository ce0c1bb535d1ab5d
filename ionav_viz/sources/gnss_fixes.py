"""A log's GNSS fixes and receiver velocity on the drive's grid: one fix per stamp, the receiver's
speed and course interpolated (course held when slow), gaps in the fixes found, and, where the
receiver gives no velocity, position, speed and course fitted to the fixes themselves
(:func:`fit_fixes`). Used by :mod:`.resample`, which binds every stream into a drive."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.geo import radii_of_curvature_m
from ..core.grid import MIN_COURSE_SPEED_MPS, hold_course_when_slow
from ..core.units import wrap_360

log = logging.getLogger("ionav_viz")

#: A pause between fixes longer than this (s) and than 1.5 of the receiver's usual interval is a gap.
MAX_GNSS_GAP_S = 1.0


def first_per_stamp(path: Path, fixes: np.ndarray) -> np.ndarray:
    """Fixes in time order, keeping the first (as recorded) of fixes sharing one stamp."""
    order = np.argsort(fixes[:, 0], kind="stable")
    fixes = fixes[order]
    first = np.concatenate([[True], np.diff(fixes[:, 0]) > 0])
    if not first.all():
        same_place = (np.diff(fixes[:, 1]) == 0) & (np.diff(fixes[:, 2]) == 0)
        repeats = int((~first[1:] & same_place).sum())
        log.warning("%s: %d GNSS fix(es) share a time stamp with an earlier one (%d of them the same position); "
                    "kept the first of each stamp (a receiver publishing twice, or stamping whole seconds?)",
                    path, int((~first).sum()), repeats)
    return fixes[first]


def receiver_velocity(t: np.ndarray, speed: np.ndarray | None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The receiver's speed (m/s) and course (deg) on the times ``t``, each None where the log has
    none (the course held at a standstill)."""
    v = course = None
    if speed is not None and len(speed) >= 2:
        s_t, s_v, s_course = speed.T
        v = np.interp(t, s_t, s_v)
        has_course = np.isfinite(s_course)
        if has_course.any():
            # a receiver's course at a standstill is atan2(0, 0): the course at speed is held instead,
            # fix by fix before interpolating (a row between a standing and a moving fix would mix them)
            held = hold_course_when_slow(s_course[has_course], s_v[has_course], MIN_COURSE_SPEED_MPS, s_t[has_course])
            unwrapped = np.rad2deg(np.unwrap(np.deg2rad(held)))
            course = hold_course_when_slow(wrap_360(np.interp(t, s_t[has_course], unwrapped)), v, MIN_COURSE_SPEED_MPS,
                                           t)
    return v, course


#: Below this speed (m/s) a course from fixes is noise (the fixes' scatter, not the car's motion,
#: sets its direction), so the last course at speed is held; a receiver's Doppler course is good
#: down to MIN_COURSE_SPEED_MPS.
FIX_COURSE_MIN_SPEED_MPS = 2.0

#: Shortest half-width (s) of the local fit that gives speed and course from fixes: the fix noise is
#: averaged over at least 2 s of track, never divided by the time between two fixes.
MIN_HALF_BASELINE_S = 1.0


def fit_fixes(t: np.ndarray, g_t: np.ndarray, g_lat: np.ndarray, g_lon: np.ndarray) -> FixFit:
    """Position, speed (m/s) and course (deg from north, clockwise) at times ``t`` from GNSS fixes alone.

    A parabola in time fitted by least squares to the fixes within ``t - h .. t + h`` (``h`` the
    larger of MIN_HALF_BASELINE_S and 1.5 median fix intervals), evaluated and differentiated at
    ``t``: exact for a constant acceleration whatever the spacing of the fixes, unbiased for a
    constant turn rate, and the noise of the fixes averaged over every fix in the window, whatever
    the rate (1-20 Hz), jitter or duplicates. Degrees become metres with the WGS84 radii of
    curvature at the window's first fix. ``g_t`` must be strictly increasing.

    At a standstill the parabola's speed is the magnitude of the fix noise's slope (a Rayleigh
    variable, ~0.2 m/s for 0.15 m of noise at 10 Hz), which would hide the stillness the bias
    estimate needs. So below ~1.5 m/s the speed blends towards the smaller of it and a straight
    line fitted over SLOW_BASELINE_FACTOR times the baseline (well under 0.1 m/s when still); the
    smaller, because the long line lags when the car stops, and blended, so the speed stays
    continuous (its derivative is the events' acceleration).

    Within ``h`` of the first and last fix, and of a gap in the fixes longer than ``h``, the window
    is one-sided and the parabola's slope there several times noisier: a parabola over ``4 h`` of
    fixes gives the velocity instead.
    """
    gap = float(np.median(np.diff(g_t))) if len(g_t) > 1 else 0.0
    h = max(MIN_HALF_BASELINE_S, 1.5 * gap)
    lat, lon, ve, vn = _local_fit(t, g_t, g_lat, g_lon, h, degree=2)
    # within h of the record's ends, and of a gap wider than h, the window is one-sided, and a
    # parabola's slope at its end has 3.6 times the noise of a centred one (three fixes): one over
    # 4 h of fixes has about the centre's (seven 1 Hz fixes: 0.68 against 0.71 sigma) and stays
    # exact for a constant acceleration
    edge = _near_run_ends(t, g_t, h)
    if edge.any():
        _, _, ve[edge], vn[edge] = _local_fit(t[edge], g_t, g_lat, g_lon, 4.0 * h, degree=2)
    speed = np.hypot(ve, vn)
    _, _, slow_ve, slow_vn = _local_fit(t, g_t, g_lat, g_lon, SLOW_BASELINE_FACTOR * h, degree=1)
    still = np.minimum(speed, np.hypot(slow_ve, slow_vn))
    w = np.clip((speed - SLOW_BLEND_MPS[0]) / (SLOW_BLEND_MPS[1] - SLOW_BLEND_MPS[0]), 0.0, 1.0)
    return FixFit(lat, lon, w * speed + (1.0 - w) * still, wrap_360(np.degrees(np.arctan2(ve, vn))))


def _near_run_ends(t: np.ndarray, g_t: np.ndarray, h: float) -> np.ndarray:
    """Whether each time lies within ``h`` of either end of its run of fixes (runs split where the
    fixes are more than ``h`` apart: a window of ``t +- h`` there holds fixes on one side only)."""
    brk = np.flatnonzero(np.diff(g_t) > h)
    first, last = np.r_[g_t[0], g_t[brk + 1]], np.r_[g_t[brk], g_t[-1]]
    run = np.clip(np.searchsorted(first, t, side="right") - 1, 0, len(first) - 1)
    return (t < first[run] + h) | (t > last[run] - h)


@dataclass(frozen=True)
class FixFit:
    """What :func:`fit_fixes` gives per grid time: smoothed position (deg), speed (m/s), course (deg)."""

    lat_deg: np.ndarray
    lon_deg: np.ndarray
    speed_mps: np.ndarray
    course_deg: np.ndarray


#: How much longer the straight-line fit is where the car is slow, and the speeds (m/s) between
#: which the fixes' speed blends from it to the parabola's (see fit_fixes).
SLOW_BASELINE_FACTOR = 2.5
SLOW_BLEND_MPS = (0.5, 1.5)


def _local_fit(t: np.ndarray, g_t: np.ndarray, g_lat: np.ndarray, g_lon: np.ndarray, h: float,
               degree: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Latitude, longitude (deg) and east, north velocity (m/s) at ``t`` from a polynomial of
    ``degree`` (1 or 2) in time fitted to the fixes within ``t +- h``."""
    lat, lon, ve, vn = (np.zeros(len(t)) for _ in range(4))
    need = degree + 1
    max_fixes = int(np.max(np.searchsorted(g_t, g_t + 2 * h, side="right") - np.arange(len(g_t)))) + need
    block = max(1, 2_000_000 // max_fixes)  # bounds the (grid x fixes) arrays
    for a in range(0, len(t), block):
        tb = t[a : a + block]
        at = np.searchsorted(g_t, tb)
        # the fixes within h, and at least the last at or before t and the first at or after it
        # (across a wider gap: the chord; a fix at t is its own, not one across the gap before it)
        lo = np.minimum(np.searchsorted(g_t, tb - h, side="left"),
                        np.clip(np.searchsorted(g_t, tb, side="right") - 1, 0, None))
        hi = np.maximum(np.searchsorted(g_t, tb + h, side="right"), np.minimum(at + 1, len(g_t)))
        lo = np.maximum(np.minimum(lo, hi - need), 0)  # enough fixes for the polynomial, at the ends too
        hi = np.minimum(np.maximum(hi, lo + need), len(g_t))
        idx = lo[:, None] + np.arange(max_fixes)[None, :]
        use = idx < hi[:, None]
        idx = np.minimum(idx, len(g_t) - 1)
        dt = np.where(use, g_t[idx] - tb[:, None], 0.0)
        terms = [use * 1.0, dt, 0.5 * dt * dt][:need]  # value, rate, acceleration at t
        design = np.stack(terms, axis=-1)
        normal = design.transpose(0, 2, 1) @ design
        normal[:, -1, -1] += 1e-9  # fewer fixes than terms (two fixes): the chord
        for position, rate, values in ((lat, vn, g_lat), (lon, ve, g_lon)):
            y = np.where(use, values[idx] - values[lo][:, None], 0.0)
            coef = np.linalg.solve(normal, (design.transpose(0, 2, 1) @ y[:, :, None]))
            position[a : a + block] = values[lo] + coef[:, 0, 0]
            rate[a : a + block] = coef[:, 1, 0]  # deg/s
        meridian_m, prime_vertical_m = radii_of_curvature_m(g_lat[lo])
        vn[a : a + block] *= np.radians(meridian_m)
        ve[a : a + block] *= np.radians(prime_vertical_m) * np.cos(np.radians(g_lat[lo]))
    return lat, lon, ve, vn


def covered(t: np.ndarray, g_t: np.ndarray, tolerance_s: float = 0.0) -> np.ndarray:
    """Grid times inside the GNSS record (or within ``tolerance_s`` of its ends) and not inside a
    GNSS gap: a gap is longer than MAX_GNSS_GAP_S and than 1.5 of the receiver's usual intervals (a
    jittered 1 Hz receiver's 1.004 s between fixes is its rate, not a gap)."""
    inside = (t >= g_t[0] - tolerance_s) & (t <= g_t[-1] + tolerance_s)
    k = np.clip(np.searchsorted(g_t, t), 1, len(g_t) - 1)
    gap = g_t[k] - g_t[k - 1]
    usual = float(np.median(np.diff(g_t))) if len(g_t) > 1 else 0.0
    return inside & (gap <= max(MAX_GNSS_GAP_S, 1.5 * usual))
