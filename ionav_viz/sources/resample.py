"""Putting sensor streams on the drive's 10 Hz grid: IMU samples, GNSS fixes and speeds -> one Drive.

Every log reader (MCAP, ROS 1 and ROS 2 bags, KITTI OXTS folders) collects its streams in the
log's own units and rates, then calls :func:`assemble_drive`:

* IMU samples ``(t, accel x, y, z, gyro x, y, z)`` (s, m/s^2, rad/s; REP 103 body frame once
  mapped) are folded into per-bin sums as they arrive (:class:`ImuBins`), bins of 0.1 s centred on
  each grid time, so memory grows with the output, not the log;
* GNSS fixes ``(t, lat, lon, altitude, sigma)`` (s, deg, deg, m, m) are linearly interpolated to the
  grid times; grid times with IMU samples inside a GNSS gap (longer than 1 s and than 1.5 of the
  receiver's usual interval: a tunnel) are kept with ``gnss_fix`` 0, so the GNSS quality marks
  them no-fix: never scored, but the inertial data through the gap is there;
* speeds ``(t, speed, course)`` (s, m/s, deg clockwise from north or NaN) from the receiver or the
  navigation solution (its course held below 1 m/s, where a velocity's direction is noise, and
  at a standstill ``atan2(0, 0)``); without them, speed and course come from the fixes by a local parabola
  fitted over at least 2 s of track (:func:`fit_fixes`), and the positions are that fit's.

A log whose IMU and GNSS share their stamps at no more than the grid rate (as ``ionav-viz
convert`` writes them) is kept at its own stamps, so converting a CSV and reading it back changes
nothing. Stamps more than an hour away from the rest of their stream are dropped with one warning
(:func:`drop_strays`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..core.drive import IMU_COLUMNS, RECEIVER_COLUMNS, Drive
from ..core.errors import InputError
from ..core.grid import GRID_RATE_HZ, SAME_INSTANT_S, hold_course_when_slow
from .gnss_fixes import FIX_COURSE_MIN_SPEED_MPS, covered, fit_fixes, receiver_velocity
from .imu.character import ImuSettings, character, clock_offset, orient
from .plausibility import first_implausible

log = logging.getLogger("ionav_viz")


#: IMU samples gathered before each :meth:`ImuBins.prepare` (checked and turned to the body frame at once).
IMU_BLOCK_SAMPLES = 65536


class ImuBins:
    """Per-bin sums of IMU samples on a grid of ``dt`` (bins centred on grid times), streamed.

    Sums are kept sparse (occupied bins only), so a stray stamp far from the others (a boot-time
    stamp among UNIX stamps) costs one entry, not an array spanning the distance. Samples arrive
    as the log has them, ``(t, accel x, y, z, gyro x, y, z)``; ``prepare`` turns each buffered
    block into body-frame samples (checking their values) with numpy, not per message.
    """

    def __init__(self, dt: float, keep_samples: bool, prepare: Callable[[np.ndarray], np.ndarray]) -> None:
        self.dt = dt
        self.prepare = prepare
        self.origin: float | None = None
        self.parts: list[tuple[np.ndarray, np.ndarray]] = []  # (bins, [value sums..., count])
        self.rows: list[tuple[float, ...]] = []  # samples added one by one, not yet in ``buffer``
        self.buffer: list[np.ndarray] = []  # blocks of samples waiting for the next flush
        self.buffered = 0  # samples in ``rows`` and ``buffer``
        # A log that may be single-rate (as many IMU as GNSS messages) also keeps its samples:
        # then they are as many as the output rows.
        self.samples: list[np.ndarray] | None = [] if keep_samples else None
        # each axis's smallest and largest value: one that never changes is no measurement
        self.low, self.high = np.full(6, np.inf), np.full(6, -np.inf)

    def add(self, sample: tuple[float, ...]) -> None:
        self.rows.append(sample)
        self.buffered += 1
        if self.buffered >= IMU_BLOCK_SAMPLES:
            self.flush()

    def add_many(self, samples: np.ndarray) -> None:
        """Add samples ``(n, 7)`` as :meth:`add` one by one would: the same blocks reach ``prepare``."""
        while len(samples):
            take = IMU_BLOCK_SAMPLES - self.buffered
            self._park()
            self.buffer.append(samples[:take])
            self.buffered += len(self.buffer[-1])
            samples = samples[take:]
            if self.buffered >= IMU_BLOCK_SAMPLES:
                self.flush()

    def _park(self) -> None:
        if self.rows:
            self.buffer.append(np.asarray(self.rows))
            self.rows.clear()

    def flush(self) -> None:
        self._park()
        if not self.buffer:
            return
        block = np.concatenate(self.buffer)
        self.buffer.clear()
        self.buffered = 0
        self.add_block(block)

    def add_block(self, block: np.ndarray) -> None:
        """Add samples already gathered in an array ``(n, 7)``, as the log has them."""
        if not len(block):
            return
        data = self.prepare(block)
        self.low = np.minimum(self.low, data[:, 1:].min(axis=0))
        self.high = np.maximum(self.high, data[:, 1:].max(axis=0))
        if self.samples is not None:
            self.samples.append(data)
        if self.origin is None:
            self.origin = float(data[0, 0])
        bins = np.rint((data[:, 0] - self.origin) / self.dt).astype(np.int64)
        self.parts.append(_sum_by_bin(bins, np.column_stack([data[:, 1:], np.ones(len(data))])))
        if len(self.parts) > 64:
            self.parts = [_sum_by_bin(np.concatenate([b for b, _ in self.parts]),
                                      np.concatenate([v for _, v in self.parts]))]

    def means(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Grid times (s) of non-empty bins, the mean values per bin (n, 6), samples per bin."""
        self.flush()
        if not self.parts:
            return np.zeros(0), np.zeros((0, 6)), np.zeros(0)
        bins, sums = _sum_by_bin(np.concatenate([b for b, _ in self.parts]), np.concatenate([v for _, v in self.parts]))
        return self.origin + bins * self.dt, sums[:, :-1] / sums[:, -1:], sums[:, -1]

    def constant_axes(self) -> np.ndarray:
        """Per axis (accel x, y, z, gyro x, y, z), whether every sample read the same value: not a
        measurement (a placeholder a converter or driver wrote for an axis it does not have)."""
        self.flush()
        return self.low == self.high

    def kept_samples(self) -> np.ndarray | None:
        """The body-frame samples in time order, when they were kept (else None)."""
        self.flush()
        if not self.samples:
            return None
        data = np.concatenate(self.samples)
        return data[np.argsort(data[:, 0], kind="stable")]


def _sum_by_bin(bins: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted unique bins and the column sums of ``values`` per bin."""
    unique, inverse = np.unique(bins, return_inverse=True)
    sums = np.zeros((len(unique), values.shape[1]))
    np.add.at(sums, inverse, values)
    return unique, sums


#: Stamps separated from the bulk of a topic's stamps by more than this (s) are strays (a clock
#: not yet synchronised, a boot-time stamp) and are dropped; a recording paused for less is kept.
MAX_STAMP_JUMP_S = 3600.0


def _main_span(t: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Mask of the stamps in the largest group of ``t`` without a jump over MAX_STAMP_JUMP_S.

    ``t`` must be sorted; ``weights`` count samples per stamp (default one each).
    """
    if len(t) == 0:
        return np.zeros(0, dtype=bool)
    group = np.concatenate([[0], np.cumsum(np.diff(t) > MAX_STAMP_JUMP_S)])
    size = np.bincount(group, weights=weights)
    return group == int(np.argmax(size))


def drop_strays(path: Path, what: str, t: np.ndarray, weights: np.ndarray | None = None,
                origin_s: float = 0.0) -> np.ndarray:
    """Mask of ``t`` (sorted; s after ``origin_s``) to keep, warning once about stray stamps."""
    keep = _main_span(t, weights)
    if not keep.all():
        n = int((weights[~keep] if weights is not None else (~keep)).sum())
        log.warning("%s: dropped %d %s sample(s) stamped more than %g s away from the rest of the log "
                    "(e.g. %.3f s against %.3f-%.3f s): a clock not yet synchronised?",
                    path, n, what, MAX_STAMP_JUMP_S, origin_s + float(t[~keep][0]), origin_s + float(t[keep][0]),
                    origin_s + float(t[keep][-1]))
    return keep


@dataclass(frozen=True)
class LogStreams:
    """A log's streams as its reader collected them, times in s after ``origin_s`` (a whole second
    since 1970, so that float64 keeps the stamps' nanoseconds).

    ``gnss``: fixes ``(t s, lat deg, lon deg, altitude m, sigma m or NaN)``, sorted, one per stamp;
    ``speed``: ``(t s, speed m/s, course deg or NaN)`` sorted, or None; ``vehicle_speed``:
    ``(t s, speed m/s)`` sorted, the vehicle's own speed (wheel or CAN odometry), or None: the
    drive's ``speed_can_mps``, interpolated onto the grid; ``reference``: ``(t s, lat deg, lon deg)``
    sorted, a reference trajectory: then it is the drive's position, speed and course (the truth),
    fitted like fixes, and the receiver's go into :data:`~ionav_viz.core.drive.RECEIVER_COLUMNS`;
    ``fix_columns``: more per-fix drive columns (e.g. ``n_satellites``), each held from the last fix
    at every grid time.
    """

    imu: ImuBins
    gnss: np.ndarray
    speed: np.ndarray | None = None
    origin_s: float = 0.0
    vehicle_speed: np.ndarray | None = None
    reference: np.ndarray | None = None
    fix_columns: dict[str, np.ndarray] | None = None


def assemble_drive(path: Path, name: str, streams: LogStreams, settings: ImuSettings) -> Drive:
    """The drive on the grid from a log's streams (see the module docstring and :class:`LogStreams`),
    the IMU characterised (:mod:`.imu.character`: mount and axes, sample kind, clock offset) as
    ``settings`` (what the user said) allow; the drive carries what was found (``Drive.imu``).

    A clock offset to apply moves the IMU's samples to the receiver's time line, and the fixes are
    put on them there: the grid is built again from the streams, the IMU turned as before."""
    grid = _on_grid(path, streams)
    v, course, lat, lon, fitted = _receiver_on(grid, streams)
    body = grid.body
    if settings.yaw_sign == "cw":  # a clockwise yaw axis is a z-down IMU (x forward, y left: FRD): y and z turn over
        body = body * np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])
    wheels = _vehicle_speed_on(grid.t_s, streams)
    oriented = orient(path, grid.t_s, body, v, course, settings, wheels, grid.measured)
    shift, found = clock_offset(path, grid.t_s, oriented.body, v, course, settings, one_clock=_shares_stamps(streams))
    if shift != 0.0:
        grid = _on_grid(path, streams, shift)
        v, course, lat, lon, fitted = _receiver_on(grid, streams)
        body = grid.body * np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0]) if settings.yaw_sign == "cw" else grid.body
        oriented = replace(oriented, body=oriented.turn(body))
    imu = character(grid.native_rate_hz, grid.readings_per_sample, oriented, shift, found, settings, v)
    t, body = grid.t_s, oriented.body
    columns = {"t_s": t - float(t[0]), "lat_deg": lat, "lon_deg": lon, "speed_mps": v, "heading_deg": course,
               "accel_long_mps2": body[:, 0], "yaw_rate_radps": body[:, 5]}
    columns |= dict(zip(IMU_COLUMNS, body.T, strict=True))  # the full IMU, body frame
    if streams.reference is not None:
        reference = streams.reference
        truth = fit_fixes(t, reference[:, 0], reference[:, 1], reference[:, 2])
        columns |= dict(zip(RECEIVER_COLUMNS, (lat, lon, v, course), strict=True))
        columns |= {"lat_deg": truth.lat_deg, "lon_deg": truth.lon_deg, "speed_mps": truth.speed_mps,
                    "heading_deg": hold_course_when_slow(truth.course_deg, truth.speed_mps, FIX_COURSE_MIN_SPEED_MPS,
                                                         t)}
    columns |= _fix_quality_columns(grid, fitted, streams)
    origin_s = streams.origin_s
    start_of_day = (origin_s % 86400.0 + float(t[0])) % 86400.0
    return Drive(name=name, source=str(path), rate_hz=round(1.0 / float(np.median(np.diff(t))), 1),
                 start_time_of_day_s=start_of_day, columns=columns, start_stamp_s=origin_s + float(t[0]), imu=imu)


def _receiver_on(grid: _Grid, streams: LogStreams) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """The receiver's speed (m/s) and course (deg) on the grid, and the positions (deg): the
    receiver's velocity where it has one, else fitted to the fixes (with smoothed positions: the
    per-window displacement of raw fixes would carry their white noise twice); and whether fitted."""
    t, lat, lon = grid.t_s, grid.lat_deg, grid.lon_deg
    g_t, g_lat, g_lon = streams.gnss[:, 0], streams.gnss[:, 1], streams.gnss[:, 2]
    v, course = receiver_velocity(t, streams.speed)
    fitted = v is None or course is None
    if fitted:
        fit = fit_fixes(t, g_t, g_lat, g_lon)
        v = fit.speed_mps if v is None else v
        course = (hold_course_when_slow(fit.course_deg, fit.speed_mps, FIX_COURSE_MIN_SPEED_MPS, t)
                  if course is None else course)
        lat, lon = fit.lat_deg, fit.lon_deg
    return v, course, lat, lon, fitted


def _vehicle_speed_on(t: np.ndarray, streams: LogStreams) -> np.ndarray | None:
    vehicle_speed = streams.vehicle_speed
    return (np.interp(t, vehicle_speed[:, 0], vehicle_speed[:, 1])
            if vehicle_speed is not None and len(vehicle_speed) >= 2 else None)


@dataclass(frozen=True)
class _Grid:
    """A log's IMU and fixes on the drive's sample times."""

    t_s: np.ndarray
    body: np.ndarray  # (n, 6): accelerations and turn rates, unmeasured axes at their constant value
    measured: np.ndarray  # (6,): the axes that read more than one value over the log
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    alt_m: np.ndarray
    sigma_m: np.ndarray
    has_fix: np.ndarray  # False in a GNSS gap the IMU goes on through
    native_rate_hz: float  # the IMU's readings per second
    readings_per_sample: float  # readings the reader averaged into each sample (median)


def _on_grid(path: Path, streams: LogStreams, imu_shift_s: float = 0.0) -> _Grid:
    """The IMU's samples as they are when IMU and GNSS share their stamps at the grid rate, else its
    means per grid step, within the fixes' span (fixes interpolated onto them). ``imu_shift_s``: the
    IMU's clock offset (its stamps minus the receiver's): its samples are put at ``t - imu_shift_s``.

    A sample within :data:`~ionav_viz.core.grid.SAME_INSTANT_S` of the fixes' span is in it: a shift
    far below the sample period (``--imu-time-offset 1e-9``) moves no sample in or out, so the drive
    starts on the same sample and its windows and outages are those of no shift."""
    imu = streams.imu
    g_t, g_lat, g_lon, g_alt, g_sigma = streams.gnss.T
    tolerance_s = SAME_INSTANT_S
    samples = imu.kept_samples()
    if _shares_stamps(streams):  # IMU and GNSS share their stamps at the grid rate: the samples stay as they are
        t, body = samples[:, 0] - imu_shift_s, samples[:, 1:]
        lat, lon, alt, sigma = g_lat, g_lon, g_alt, g_sigma
        has_fix = np.ones(len(t), dtype=bool)
        if imu_shift_s != 0.0:  # moved off the fixes' stamps: the fixes are interpolated onto them
            keep = (t >= g_t[0] - tolerance_s) & (t <= g_t[-1] + tolerance_s)
            t, body = t[keep], body[keep]
            has_fix = covered(t, g_t, tolerance_s)
            lat, lon, alt, sigma = (np.interp(t, g_t, x) for x in (g_lat, g_lon, g_alt, g_sigma))
        readings = 1.0
    else:
        t, body, count = imu.means()
        t = t - imu_shift_s
        keep = (drop_strays(path, "IMU", t, count, origin_s=streams.origin_s) & (t >= g_t[0] - tolerance_s)
                & (t <= g_t[-1] + tolerance_s))
        t, body = t[keep], body[keep]
        if imu_shift_s == 0.0 and len(t) >= 2:
            _warn_imu_short_of_fixes(path, t, g_t)
        readings = float(np.median(count[keep])) if keep.any() else 1.0
        has_fix = covered(t, g_t, tolerance_s)  # the IMU goes on through a GNSS gap: no-fix samples, not a gap
        lat, lon, alt, sigma = (np.interp(t, g_t, x) for x in (g_lat, g_lon, g_alt, g_sigma))
    if len(t) < 2:
        raise InputError(f"{path}: IMU and GNSS do not overlap in time",
                         "check the topics and the choice of stamps (header or log)", param="stamps")
    # an axis that reads one value over the whole log is not measured (a two-channel log written as
    # sensor_msgs/Imu: zeros and a constant gravity): no mount is estimated from it, no axis check
    # uses it, and it keeps its exact value (a mean per bin could round it), so that
    # core.drive.measured_imu does not count it either
    measured = ~imu.constant_axes()
    body = body.copy()
    body[:, ~measured] = imu.low[~measured]
    step = float(np.median(np.diff(t)))
    return _Grid(t, body, measured, lat, lon, alt, sigma, has_fix, readings / step if step > 0 else 0.0, readings)


#: The IMU may start or stop this long inside the fixes' span before it is said (the drive is read
#: only where both are, so the fixes beyond the IMU are silently left out).
IMU_SHORT_S = 2.0


def _warn_imu_short_of_fixes(path: Path, t: np.ndarray, g_t: np.ndarray) -> None:
    """Say when the IMU covers only part of the fixes' span (it started late or stopped early, e.g.
    a driver that crashed): the drive is cut to where both are, shorter than the log looks."""
    late_s, early_s = float(t[0] - g_t[0]), float(g_t[-1] - t[-1])
    if late_s + early_s <= IMU_SHORT_S:
        return
    where = " and ".join(x for x in (f"starts {late_s:.1f} s after the first fix" if late_s > 0.5 else "",
                                     f"stops {early_s:.1f} s before the last fix" if early_s > 0.5 else "") if x)
    log.warning("%s: the IMU covers only %.1f of the %.1f s of GNSS fixes (it %s); the drive is read where both are",
                path, float(t[-1] - t[0]), float(g_t[-1] - g_t[0]), where)


def _shares_stamps(streams: LogStreams) -> bool:
    """Whether the IMU's samples and the fixes share every stamp, at the grid rate or slower."""
    samples, g_t = streams.imu.kept_samples(), streams.gnss[:, 0]
    same = samples is not None and len(samples) == len(g_t) and np.array_equal(samples[:, 0], g_t)
    return bool(same and len(g_t) > 1 and float(np.median(np.diff(g_t))) >= 0.9 / GRID_RATE_HZ)


def _fix_quality_columns(grid: _Grid, fitted: bool, streams: LogStreams) -> dict[str, np.ndarray]:
    """The optional columns: height, the receiver's sigma, the fix flag, whether speed and course
    were fitted, the vehicle's speed and the per-fix columns."""
    t, columns = grid.t_s, {}
    if first_implausible("height_m", grid.alt_m) is None:
        columns["height_m"] = grid.alt_m
    if len(grid.sigma_m) and np.isfinite(grid.sigma_m).all():  # the receiver's own accuracy, when every fix has one
        columns["gnss_sigma_m"] = grid.sigma_m
    has_fix = grid.has_fix
    if streams.speed is not None and len(streams.speed) >= 2:
        # inside a gap of the receiver's velocity (its fixes going on) the speed is a line drawn across
        # the gap: no fix to score or to start an outage from
        has_fix = has_fix & covered(t, streams.speed[:, 0], SAME_INSTANT_S)
    if not has_fix.all():
        columns["gnss_fix"] = has_fix.astype(float)
    if fitted:  # the receiver's speed and course are the positions' (Drive: gnss_speed_fitted)
        columns["gnss_speed_fitted"] = np.ones(len(t))
    vehicle_speed = streams.vehicle_speed
    if vehicle_speed is not None and len(vehicle_speed) >= 2:
        columns["speed_can_mps"] = np.interp(t, vehicle_speed[:, 0], vehicle_speed[:, 1])
    g_t = streams.gnss[:, 0]
    last_fix = np.clip(np.searchsorted(g_t, t, side="right") - 1, 0, len(g_t) - 1)
    for column, values in (streams.fix_columns or {}).items():
        columns[column] = np.asarray(values, dtype=float)[last_fix]
    return columns




