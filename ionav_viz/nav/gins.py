"""``gins``: a 3D GNSS/INS with vehicle constraints, for drives with a full 6-axis IMU.

The practitioner's baseline: the error-state filter of :mod:`ionav_viz.nav.strapdown` runs over
the drive with GNSS (position, and velocity at speed), non-holonomic constraints, the odometer
where the drive has a vehicle speed, and zero-velocity updates where the IMU shows the vehicle
standing (:mod:`ionav_viz.nav.stillness`). Each outage starts from the filter's state at its
first window boundary (it has seen GNSS only before it) and runs on without GNSS, still
constrained, to its end. Per 1-second window it reports the horizontal distance travelled (the
integral of the horizontal speed, never negative), the mean yaw rate (counter-clockwise: the
corrected gyro's, so that the updates' corrections of the heading are not counted as turns), and its
own positions at the window boundaries, which the metrics use.

Initial alignment, at the drive's first window boundary with a usable fix (:func:`alignment_boundary`): level (roll and
pitch) from the mean specific force over the second after it, heading from the GNSS course at speed (the windows hold
the first course at speed through a standstill at the start), velocity from the GNSS speed and
course (15 degrees of sigma: a course at walking pace is worth little), biases zero with sigmas wide enough for a phone
(0.5 deg/s, 0.3 m/s^2). The sensors' white noise (the filter's random walks) is measured on the whole drive, driving
included (:func:`sensor_noise`): the robust spread of successive differences of each axis, the grade's
floors as a prior.

The mechanisation is the data's (``mechanisation="auto"``): where the drive's IMU samples are single
readings at a low rate (a phone's sensor events, :class:`ionav_viz.core.imu.ImuCharacter`), their x
and y rates alias what the holder shakes, and integrating roll and pitch from them leaks gravity into
the velocity within seconds; then roll and pitch are held (the reduced mechanisation: yaw rate and specific
force with the constraints), corrected by the updates only, and the report says so.

The safeguards (:func:`ionav_viz.nav.strapdown.run_filter`): the process noise is scaled up while
the GNSS position's running NIS stays above 3 (the filter meets more than its model says; at most
30 times, carried into each outage); a fix the gate leaves out while it
agrees with the fixes before it re-initialises position and velocity from GNSS instead of locking the
fixes out, and the heading from the GNSS course where the two are more than 30 degrees and three
of the course's sigmas apart (a phone's GNSS gap can end with the course turned against the gyro); a stop the IMU shows
for two boundaries is taken even when the filter's velocity disagrees, unless a fix at speed says the car moves. Each
re-initialisation is in the filter's health (:class:`ionav_viz.nav.protocol.FilterHealth`), and so in the report.

Drives with only the paper's two channels (IO-VNBD) are the planar ``ekf``'s: ``gins`` does not
apply to them. The measurements behind these choices: docs/gins-design.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.covariance import growth_en, nees_en, scale_growth
from ..core.drive import Drive, measured_imu
from ..core.errors import InputError
from ..core.geo import enu_of_geodetic, geodetic_of_enu
from ..core.gnss_lag import lag_velocity_error_mps
from ..core.gnss_quality import position_sigma_m
from ..core.grid import MIN_COURSE_SPEED_MPS, WINDOW_S
from ..core.rotation import quat_of_euler
from . import history_check
from .ins import dead_reckon
from .kalman import UpdateLog
from .protocol import REINITIALISED, Estimate, EstimatorInputs, FilterHealth
from .stillness import drive_still
from .strapdown import (
    BAX,
    BGX,
    GINS_MEASUREMENTS,
    KO,
    N_NOMINAL,
    PSIM,
    PX,
    QW,
    SG,
    THM,
    VX,
    Earth,
    FilterInputs,
    FilterNoise,
    FilterSwitches,
    GinsNoise,
    earth_at,
    filter_outputs,
    run_filter,
)
from .track import rebuild_track
from .vehicle_speed import speed_in_mps, vehicle_speed
from .windows import Windows

#: GNSS velocity updates the filter from this speed (m/s): below it the windows hold the course
#: (:data:`ionav_viz.core.grid.MIN_COURSE_SPEED_MPS`), so east and north would point the held way.
GNSS_VELOCITY_MIN_SPEED_MPS = MIN_COURSE_SPEED_MPS


def sensor_noise(acc: np.ndarray, gyr: np.ndarray, noise: GinsNoise) -> tuple[float, float, str]:
    """The white noise per sample (accelerometer m/s^2, gyro rad/s) the filter propagates with, and
    where it was measured: the successive-sample spread over the whole drive, driving included,
    never below the floors of ``noise`` (the grade's prior).

    The whole drive, not its stands: what the engine and the road shake into each sample while
    driving is noise to a filter that integrates through it, whatever the IMU's kind of samples.
    A standstill measures the sensor alone, which can lie an order of magnitude below the driving
    spread (a roof MEMS IMU: 0.02 against 0.17 m/s^2), and weighing the mechanisation by it makes
    the filter overconfident in it (docs/real-imu-logs.md, issue 59)."""
    d_acc, d_gyr = np.diff(acc, axis=0), np.diff(gyr, axis=0)
    sigma_a = max(_spread(d_acc), noise.accel_white_floor_mps2)
    sigma_g = max(_spread(d_gyr), noise.gyro_white_floor_radps)
    return sigma_a, sigma_g, "measured on the whole drive"


def _spread(d: np.ndarray, most: int = 20_000) -> float:
    """The white noise per sample from successive differences ``d`` (n, 3): 1.4826 MAD over sqrt(2),
    the median over the axes."""
    if not len(d):
        return 0.0
    d = d[:: max(1, len(d) // most)]
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return float(np.median(1.4826 * mad / np.sqrt(2.0)))


@dataclass
class Boundaries:
    """The drive's window boundaries, in time order: every window's start and each segment's
    last end. ``of_window[k]``: the boundary where window ``k`` starts (its end is the next)."""

    t_s: np.ndarray
    sample: np.ndarray
    segment_start: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    speed_mps: np.ndarray
    course_deg: np.ndarray
    gnss_ok: np.ndarray
    of_window: np.ndarray


def boundaries(drive: Drive, windows: Windows) -> Boundaries:
    """Window boundaries with the GNSS there (the windows' own interpolated fixes)."""
    n = len(windows)
    last = np.ones(n, dtype=bool)
    last[:-1] = windows.segment[1:] != windows.segment[:-1]
    first = np.ones(n, dtype=bool)
    first[1:] = last[:-1]
    ends_through = np.cumsum(last)
    start_at = np.arange(n) + ends_through - last  # each window's start, after the ends of earlier segments
    end_at = start_at[last] + 1  # a segment's last end, right after its last window's start
    nb = n + int(last.sum())
    t, lat, lon, course, speed = (np.zeros(nb) for _ in range(5))
    good, seg_start = np.zeros(nb, dtype=bool), np.zeros(nb, dtype=bool)
    t[start_at], t[end_at] = windows.t0_s, windows.t0_s[last] + WINDOW_S
    lat[start_at], lat[end_at] = windows.lat0_deg, windows.lat1_deg[last]
    lon[start_at], lon[end_at] = windows.lon0_deg, windows.lon1_deg[last]
    course[start_at], course[end_at] = windows.heading0_deg, windows.heading1_deg[last]
    speed[start_at], speed[end_at] = windows.speed0_mps, np.interp(t[end_at], drive.t_s, drive.speed_mps)
    ok = windows.truth_ok
    prev_ok = np.concatenate([[False], ok[:-1]]) & ~first
    # a boundary's fix is usable when it starts or ends a window with good GNSS
    good[start_at], good[end_at] = ok | prev_ok, ok[last]
    seg_start[start_at] = first
    sample = np.clip(np.searchsorted(drive.t_s, t - 1e-6), 0, len(drive) - 1)
    return Boundaries(t, sample, seg_start, lat, lon, speed, course, good, start_at)


#: A fix agrees with the one before it when the step between them is within this of what the
#: speed says (m, plus the fixes' sigmas and a share of the step): as the GNSS jump check has it
#: (:class:`ionav_viz.core.gnss_quality.GnssLimits`: ``jump_margin_m``, ``jump_speed_factor``).
FIX_STEP_MARGIN_M = 3.0
FIX_STEP_SHARE = 0.5


def alignment_boundary(b: Boundaries) -> int:
    """Where the filter is aligned: the drive's first boundary with a usable fix in its first segment
    (0 when the drive starts with one or has none there). The alignment's covariance (position at
    the fix's sigma, 0.5 m/s, 15 deg of heading) is a promise only a fix the GNSS check trusts can
    keep: phones start cold, with seconds of fixes reported tens of metres off and a speed and course
    held from before; aligned on those, the filter runs free through them and the first good fix's
    correction goes into the biases (docs/gins-design.md, "Alignment")."""
    first_segment_end = int(np.argmax(b.segment_start[1:])) + 1 if b.segment_start[1:].any() else len(b.t_s)
    good = np.flatnonzero(b.gnss_ok[:first_segment_end])
    return int(good[0]) if len(good) else 0


def fix_steps(b: Boundaries, pos_m: np.ndarray, sigma_m: np.ndarray) -> np.ndarray:
    """Per boundary, how its fix follows the one before (int8): 1 when both are good and the step
    between them is what the speed says (no jump: the fixes can be believed over the filter,
    :func:`~.strapdown.run_filter`'s safeguard), -1 when it is not (a jump), 0 when it cannot be
    told (the first good fix after a gap or a segment's start)."""
    out = np.zeros(len(b.t_s), dtype=np.int8)
    if len(out) < 2:
        return out
    step = np.hypot(*np.diff(pos_m[:, :2], axis=0).T)
    expected = 0.5 * (b.speed_mps[1:] + b.speed_mps[:-1]) * np.diff(b.t_s)
    margin = FIX_STEP_MARGIN_M + 2.0 * (sigma_m[1:] + sigma_m[:-1]) + FIX_STEP_SHARE * expected
    both = b.gnss_ok[1:] & b.gnss_ok[:-1] & ~b.segment_start[1:]
    out[1:] = np.where(both, np.where(np.abs(step - expected) <= margin, 1, -1), 0)
    return out


def _level_attitude(accel_mean: np.ndarray, heading_deg: float) -> np.ndarray:
    """The quaternion (w, x, y, z) of ``C_b^n`` from the mean specific force (level) and the course
    (yaw); angles as :mod:`ionav_viz.core.rotation` has them (pitch positive nose-down)."""
    fx, fy, fz = accel_mean
    roll = np.arctan2(fy, fz)
    pitch = -np.arctan2(fx, np.hypot(fy, fz))  # a nose up reads gravity's reaction forward: fx > 0
    yaw = np.pi / 2 - np.deg2rad(heading_deg)
    return quat_of_euler(roll, pitch, yaw)


@dataclass
class GinsRun:
    """The filter's pass over a drive: boundaries, the state after each (``(nb, 20)``) and its
    covariance (``(nb, 19, 19)``), and what the outages need to run on."""

    bounds: Boundaries
    xs: np.ndarray
    Ps: np.ndarray
    inputs: FilterInputs
    noise: FilterNoise
    earth: Earth
    switches: FilterSwitches
    origin: tuple[float, float, float]
    still: np.ndarray
    log: UpdateLog
    q_scale: np.ndarray  # the process noise's scale the consistency test set at each boundary


#: ``GinsEstimator(mechanisation=...)``: from the IMU's samples, the full 3D strapdown, or roll and pitch held.
MECHANISATIONS = ("auto", "3d", "reduced")


class GinsEstimator:
    """The 3D GNSS/INS (see the module docstring)."""

    name = "gins"
    label = "GNSS/INS 3D"
    color = (230, 159, 0)  # Okabe-Ito orange
    requires = "all six IMU axes, measured: a message log's or KITTI's IMU"

    def __init__(self, noise: GinsNoise | None = None, *, nhc: bool = True, zupt: bool = True, odometer: bool = True,
                 mechanisation: str = "auto", arbiter: bool = True, speed_lag: bool = True) -> None:
        """``mechanisation``: ``"3d"``, ``"reduced"`` (roll and pitch held: yaw rate and specific
        force with the constraints) or ``"auto"``: reduced where the drive's IMU samples are single
        readings at a low rate (:attr:`ionav_viz.core.imu.ImuCharacter.single_readings`). ``arbiter``:
        per outage, the propagation whose past pseudo-outages on this drive ended nearest the fixes
        (:func:`arbitrate`); without it, the mechanisation's own on every outage. ``speed_lag``: where the
        reader found the receiver's speed late against the IMU (``drive.imu.speed_lag_s``,
        :mod:`ionav_viz.core.gnss_lag`), widen the velocity updates by what that lag makes of it in an
        acceleration; without it, the receiver's velocity is taken as of its epoch."""
        self.noise = noise or GinsNoise()
        if mechanisation not in MECHANISATIONS:
            raise InputError(f"gins mechanisation {mechanisation!r} is not one of {', '.join(MECHANISATIONS)}",
                             "choose auto (from the IMU's samples), 3d or reduced", param="mechanisation")
        self.nhc, self.zupt, self.odometer = nhc, zupt, odometer
        self.mechanisation = mechanisation
        self.arbiter = bool(arbiter)
        self.speed_lag = bool(speed_lag)
        self._last: dict[str, Any] = {}

    def available(self) -> bool:
        return True

    def applies(self, drive: Drive) -> bool:
        return measured_imu(drive) is not None

    def run(self, drive: Drive, windows: Windows) -> GinsRun:
        """The forward pass over the drive with GNSS (see the module docstring)."""
        b = boundaries(drive, windows)
        imu = measured_imu(drive)
        if imu is None:
            raise ValueError(f"drive {drive.name}: gins needs all six IMU axes, measured")
        acc, gyr = (np.ascontiguousarray(x) for x in imu)
        height = drive.columns.get("height_m")
        has_height = height is not None and bool(np.isfinite(height).all())
        h = np.interp(b.t_s, drive.t_s, height) if has_height else np.zeros(len(b.t_s))
        origin = (float(b.lat_deg[0]), float(b.lon_deg[0]), float(h[0]))
        pos = np.ascontiguousarray(enu_of_geodetic(b.lat_deg, b.lon_deg, h, *origin))
        sigma = position_sigma_m(b.t_s, drive.t_s, drive.columns.get("gnss_sigma_m"), self.noise.gnss_position_m)
        course = np.deg2rad(b.course_deg)
        vel = np.ascontiguousarray(np.column_stack([b.speed_mps * np.sin(course), b.speed_mps * np.cos(course)]))
        lag_s, lag_text = self._speed_lag(drive)
        vel_var = np.zeros(len(b.t_s))
        if lag_s > 0.0:  # a location service's smoothed speed: its velocity updates widened by what the lag makes of it
            vel_var = lag_velocity_error_mps(drive.t_s, drive.columns["speed_mps"], acc[:, 0], gyr[:, 2],
                                             lag_s)[b.sample] ** 2
        vel_ok = b.gnss_ok & (b.speed_mps > GNSS_VELOCITY_MIN_SPEED_MPS)
        odo = np.full(len(b.t_s), np.nan)
        found = vehicle_speed(drive)
        if found is not None:
            values, unit, _ = found
            odo = np.interp(b.t_s, drive.t_s, speed_in_mps(values, unit))
        still_s = drive_still(drive)
        # a boundary is still when every sample within half a second of it is
        k = np.searchsorted(drive.t_s, b.t_s - 0.5), np.searchsorted(drive.t_s, b.t_s + 0.5, side="right")
        moving_count = np.concatenate([[0], np.cumsum(~still_s)])
        still = (moving_count[k[1]] - moving_count[k[0]] == 0) & (k[1] > k[0])

        dt = float(np.median(np.diff(drive.t_s))) if len(drive) > 1 else 0.1
        reduced = self.mechanisation == "reduced" or (self.mechanisation == "auto" and drive.imu is not None and
                                                      drive.imu.single_readings)
        sigma_a, sigma_g, noise_from = sensor_noise(acc, gyr, self.noise)
        walk, init = self.noise.arrays()
        n = self.noise
        # no receiver velocity: the one fitted to the fixes lags in braking (the positions again, smoothed)
        r_vel = (n.gnss_fitted_velocity_mps if drive.velocity_fitted else n.gnss_velocity_mps) ** 2
        # a copy: a read-only time array (an MCAP log's) is another type to numba, and another compilation
        inputs = FilterInputs(np.array(drive.t_s, dtype=float), acc, gyr, b.sample.astype(np.int64),
                              b.segment_start.astype(bool), b.gnss_ok.astype(bool), pos,
                              np.ascontiguousarray(sigma, dtype=float), vel, vel_ok.astype(bool), odo,
                              still.astype(bool), fix_steps(b, pos, sigma), bool(has_height),
                              np.ascontiguousarray(vel_var, dtype=float))
        noise = FilterNoise(sigma_a**2 * dt, sigma_g**2 * dt, walk, r_vel, n.nhc_lateral_mps**2, n.nhc_vertical_mps**2,
                            n.odometer_mps**2, n.zupt_mps**2, sigma_g**2, n.level_mps2**2)
        earth = earth_at(origin[0], origin[2])
        switches = FilterSwitches(True, bool(self.nhc), bool(self.odometer and found is not None), bool(self.zupt),
                                  reduced)

        nb = len(b.t_s)
        out = filter_outputs(nb, keep_states=True)
        aligned = alignment_boundary(b)
        if aligned > 0:
            # no usable fix before it: the boundaries before run free from an alignment on the unusable
            # fixes (as the drive's start always was; only an outage placed there uses them)
            run_filter(inputs, noise, earth, switches, *self._aligned(0, pos, vel, sigma, acc, b, dt, init), 0,
                       aligned - 1, out, 1.0)
        run_filter(inputs, noise, earth, switches, *self._aligned(aligned, pos, vel, sigma, acc, b, dt, init), aligned,
                   nb - 1, out, 1.0)
        xs = out.xs
        self._last = {"mechanisation": _mechanisation_text(reduced, drive), "gnss_speed_lag": lag_text,
                      "imu_white_noise": f"accel {sigma_a:.3f} m/s^2, gyro {np.rad2deg(sigma_g):.3f} deg/s per sample "
                                         f"({noise_from})",
                      "gyro_bias_dps": _median_text(np.rad2deg(xs[:, BGX:BGX + 3])),
                      "accel_bias_mps2": _median_text(xs[:, BAX:BAX + 3]),
                      "mount_residual_deg": f"yaw {np.rad2deg(np.median(xs[:, PSIM])):+.2f}, pitch "
                                            f"{np.rad2deg(np.median(xs[:, THM])):+.2f}",
                      "gyro_z_scale_error": f"{np.median(xs[:, SG]):+.4f}",
                      "vehicle_speed": f"used, scale {np.median(xs[:, KO]):.4f}" if switches.odometer else "none",
                      "still_s": f"{float(still_s.sum() * dt):.0f} s of the drive detected standing",
                      "process_noise_scale": f"x{float(np.max(out.q_scale)):.1f} at most, above x1 over "
                                             f"{100.0 * float(np.mean(out.q_scale > 1.0)):.0f} % of the drive (the "
                                             "consistency test: the GNSS position's running NIS)"}
        return GinsRun(b, xs, out.Ps, inputs, noise, earth, switches, origin, still, out.log, out.q_scale.copy())

    def _speed_lag(self, drive: Drive) -> tuple[float, str]:
        """How late the receiver's speed is against the IMU, as the reader found it
        (``ImuCharacter.speed_lag_s``; 0: not weighed), and the report's words on it."""
        imu = drive.imu
        if not self.speed_lag:
            return 0.0, "not weighed (turned off)"
        if imu is None or not imu.speed_lag_note:
            return 0.0, "not estimated (the drive carries no IMU character)"
        if not imu.speed_lag_used:
            return 0.0, imu.speed_lag_note
        return imu.speed_lag_s, f"{imu.speed_lag_note}; velocity updates widened by the lag times the acceleration"

    @staticmethod
    def _aligned(k: int, pos: np.ndarray, vel: np.ndarray, sigma: np.ndarray, acc: np.ndarray, b: Boundaries, dt: float,
                 init: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The initial state and covariance at boundary ``k`` (see the module docstring)."""
        x0 = np.zeros(N_NOMINAL)
        x0[PX:PX + 3] = pos[k]
        x0[VX:VX + 2] = vel[k]
        j0 = b.sample[k]
        x0[QW:QW + 4] = _level_attitude(acc[j0:j0 + max(int(round(1.0 / dt)), 1)].mean(axis=0), float(b.course_deg[k]))
        x0[KO] = 1.0
        P0 = np.diag(init**2)
        P0[0, 0] = P0[1, 1] = sigma[k] ** 2
        P0[2, 2] = (2.0 * sigma[k]) ** 2
        return x0, P0

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        drive, n = inputs.drive, int(inputs.n_windows)
        m = inputs.n_outages
        if m == 0:
            return Estimate(np.zeros((0, n)), np.zeros((0, n)))
        r = self.run(drive, inputs.windows)
        blind = r.switches._replace(gnss=False)
        b0s = r.bounds.of_window[np.asarray(inputs.starts)].astype(int)
        positions, cov, disp, yaw = _propagate(r, blind, b0s, n)
        if self.arbiter:
            choice, note, cov_scale = arbitrate(r, inputs, blind)
            self._last["arbiter"] = note
            self._last["covariance_scale"] = (f"x{float(np.median(cov_scale)):.2f} median "
                                              f"({float(cov_scale.min()):.2f}-{float(cov_scale.max()):.2f}) on its "
                                              "growth through the outage, from the final NEES on the same "
                                              "pseudo-outages")
            held = np.flatnonzero(choice == REDUCED)
            if len(held):
                p2, c2, d2, y2 = _propagate(r, blind._replace(level_held=True), b0s[held], n)
                positions[held], cov[held], disp[held], yaw[held] = p2, c2, d2, y2
            planar = np.flatnonzero(choice == PLANAR_DR)
            cov = scale_growth(cov, cov_scale)  # after the reduced propagation's outages took their own
        else:
            planar = np.zeros(0, dtype=int)
        lat, lon, _ = geodetic_of_enu(positions.reshape(-1, 3), *r.origin)
        lat, lon = lat.reshape(m, n + 1), lon.reshape(m, n + 1)
        if len(planar):  # the INS DR's own propagation from the same start (its output, on these outages)
            d, y, track = _planar_dr(inputs, inputs.starts[planar], n)
            disp[planar], yaw[planar], lat[planar], lon[planar] = d, y, track.lat_deg, track.lon_deg
        # the filter's own position covariance through the outage (no GNSS), symmetrised; on the planar
        # DR's outages the filter's (the DR has none of its own)
        cov = 0.5 * (cov + np.swapaxes(cov, -1, -2))
        return Estimate(np.maximum(disp, 0.0), yaw, lat, lon, health=health_of(r), pos_cov_m2=cov)

    def describe(self) -> dict[str, Any]:
        return dict(self._last)


def _propagate(r: GinsRun, sw: FilterSwitches, b0s: np.ndarray,
               n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The filter run on without GNSS (switches ``sw``) for ``n`` windows from each boundary of
    ``b0s``, from the pass's state there: positions (ENU m, ``(m, n + 1, 3)``), their east/north
    covariance ``(m, n + 1, 2, 2)``, the distance and the mean yaw rate per window ``(m, n)``."""
    m = len(b0s)
    out = filter_outputs(len(r.bounds.t_s), keep_states=False)
    positions, cov = np.zeros((m, n + 1, 3)), np.zeros((m, n + 1, 2, 2))
    disp, yaw = np.zeros((m, n)), np.zeros((m, n))
    for o, b0 in enumerate(b0s):
        b0 = int(b0)
        run_filter(r.inputs, r.noise, r.earth, sw, r.xs[b0], r.Ps[b0], b0, b0 + n, out, float(r.q_scale[b0]))
        span = slice(b0, b0 + n + 1)
        positions[o] = out.pos[span]
        cov[o] = out.pos_cov[span]
        disp[o] = np.diff(out.dist[span])
        yaw[o] = np.diff(out.turn[span]) / np.diff(r.bounds.t_s[span])
    return positions, cov, disp, yaw


def _planar_dr(inputs: EstimatorInputs, starts: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, Any]:
    """The INS DR's propagation (:func:`ionav_viz.nav.ins.dead_reckon`) for ``n`` windows from each
    window of ``starts``, restarted from the GNSS speed and course there: distance and yaw rate per
    window ``(m, n)`` and the rebuilt track."""
    w = inputs.windows
    idx = starts[:, None] + np.arange(n)[None, :]
    d, y = dead_reckon(w.accel_mps2[idx], w.gyro_radps[idx], w.speed0_mps[starts], inputs.bias, w.rate_hz,
                       inputs.still_grid[idx])
    return d, y, rebuild_track(w.lat0_deg[starts], w.lon0_deg[starts], w.heading0_deg[starts], d, y)


#: The arbiter's candidates (:func:`arbitrate`): the mechanisation's own propagation (the default),
#: the reduced one (roll and pitch held; a candidate where the default is 3D), the planar DR.
DEFAULT, REDUCED, PLANAR_DR = 0, 1, 2
#: The prior the arbiter shrinks each alternative's record toward: it ends this many times as far
#: from the fixes as the default does, with the weight of :data:`ARBITER_PRIOR_OUTAGES`
#: pseudo-outages. On the simulated phone and dash sets the INS DR errs 2.2-6 times as far as
#: ``gins`` (docs/real-imu-logs.md): 2 is the cautious end, so an alternative is taken only when this
#: drive's own past says clearly otherwise (docs/gins-design.md, "The arbiter's prior").
ARBITER_PRIOR_RATIO = 2.0
#: The prior's weight in pseudo-outages, as :data:`ionav_viz.nav.history_check.PRIOR_OUTAGES`: with
#: ``k`` past pseudo-outages an alternative must have ended on average ``1 - 3 / k`` as far from the
#: fixes as the default (none before 4, 25 % nearer after 12, 10 % after 30).
ARBITER_PRIOR_OUTAGES = history_check.PRIOR_OUTAGES
_CANDIDATE_TEXT = {DEFAULT: "", REDUCED: "reduced (roll and pitch held)",
                   PLANAR_DR: "planar DR (the INS DR's propagation)"}


#: The shorter horizon (windows) whose pseudo-outages speak for a longer outage that has fewer than
#: :data:`ARBITER_ENOUGH` of its own length behind it (:func:`arbitrate`).
ARBITER_SHORT_WINDOWS = history_check.SHORT_WINDOWS
#: The pseudo-outages of an outage's own length it takes to be judged on them: under the prior
#: (:data:`ARBITER_PRIOR_OUTAGES` at :data:`ARBITER_PRIOR_RATIO`), fewer than 4 can never switch.
ARBITER_ENOUGH = history_check.ENOUGH


def arbitrate(r: GinsRun, inputs: EstimatorInputs, blind: FilterSwitches) -> tuple[np.ndarray, str, np.ndarray]:
    """Per outage, which propagation ``gins`` uses (:data:`DEFAULT`, :data:`REDUCED`,
    :data:`PLANAR_DR`), the report's sentence on it, and the scale of what its position covariance
    grows by through the outage, from the same pseudo-outages of the outage's own length (1 where
    none lies behind it).

    Each candidate is run on pseudo-outages of the outage's length tiled over the drive's GNSS
    (:func:`ionav_viz.nav.history_check.pseudo_outages`, from the filter's alignment on: the first ones
    see a filter less converged than later, which the prior's caution answers) from the same start as
    the default (the pass's state there; the planar DR from the GNSS speed and course, as the INS DR
    restarts). Each pseudo-outage's final horizontal distance from the fix scores it. An outage gets
    the candidate with the least mean of the pseudo-outages that ended at or before its start (only
    the past), each alternative's mean shrunk toward :data:`ARBITER_PRIOR_RATIO` times the default's
    with the weight of :data:`ARBITER_PRIOR_OUTAGES`. An outage longer than
    :data:`ARBITER_SHORT_WINDOWS` with fewer than :data:`ARBITER_ENOUGH` pseudo-outages of its own
    length behind it (a drive of a few minutes, a 30 or 60 s outage) is judged on the
    :data:`ARBITER_SHORT_WINDOWS` s ones instead: which propagation holds on this drive shows after
    10 s already, and a 2-minute drive has a dozen of those."""
    n, m = int(inputs.n_windows), inputs.n_outages
    names = (DEFAULT, PLANAR_DR) if r.switches.level_held else (DEFAULT, REDUCED, PLANAR_DR)
    own = "reduced" if r.switches.level_held else "3D"
    record = _record(r, inputs, blind, n, names)
    short = _record(r, inputs, blind, ARBITER_SHORT_WINDOWS, names) if n > ARBITER_SHORT_WINDOWS else None
    if record is None and short is None:
        return (np.full(m, DEFAULT),
                f"{own} on all {m} outages (no pseudo-outage of {n} s over the GNSS before them to compare with)",
                np.ones(m))
    if record is None:  # not one of its own length: the short ones speak for every outage
        record = (np.full(m, DEFAULT), np.zeros((3, m)), np.zeros(m, dtype=int), np.zeros((3, 0)), np.ones(m))
    choice, sums, count, err, cov_scale = record
    horizon = np.full(m, n)
    if short is not None:
        use = count < ARBITER_ENOUGH
        choice, sums = np.where(use, short[0], choice), np.where(use, short[1], sums)
        horizon[use] = ARBITER_SHORT_WINDOWS
    parts = [f"{own} on {int(np.sum(choice == DEFAULT))} outages"]
    for c in names[1:]:
        on = choice == c
        if on.any():
            nearer = 1.0 - np.sum(sums[c][on]) / max(float(np.sum(sums[DEFAULT][on])), 1e-9)
            parts.append(f"{_CANDIDATE_TEXT[c]} on {int(on.sum())} (its past pseudo-outages ended {100.0 * nearer:.0f} "
                         "% nearer the fixes)")
    means = ", ".join(f"{'default' if c == DEFAULT else _CANDIDATE_TEXT[c].split(' (')[0]} {float(err[c].mean()):.1f} m"
                      for c in names) \
        if err.shape[1] else "none of this length"
    shorter = int(np.sum(horizon < n))
    return choice, (f"{', '.join(parts)}; chosen per outage from the {n} s pseudo-outages over the GNSS before it "
                    f"({err.shape[1]} on the drive; mean final distance from the fix: {means})"
                    + (f"; {shorter} outages with fewer than {ARBITER_ENOUGH} behind them judged on the "
                       f"{ARBITER_SHORT_WINDOWS} s ones" if shorter else "")), cov_scale


def _record(r: GinsRun, inputs: EstimatorInputs, blind: FilterSwitches, n: int,
            names: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """:func:`arbitrate`'s choice per outage from the pseudo-outages of ``n`` windows: the choice,
    each candidate's summed final distance (m) over the pseudo-outages behind each outage ``(3, m)``,
    their count per outage, every pseudo-outage's distance ``(3, k)``, and per outage the scale of
    the default propagation's covariance growth its past pseudo-outages call for
    (:func:`ionav_viz.nav.history_check.log_scale`); None where none fits."""
    w = inputs.windows
    pseudo = history_check.pseudo_outages(w, n)
    # from the filter's alignment on (before it the pass ran free from fixes the GNSS check distrusts)
    starts = pseudo.starts[r.bounds.of_window[pseudo.starts] >= alignment_boundary(r.bounds)]
    if not len(starts):
        return None
    ends = starts + n
    b0s = r.bounds.of_window[starts].astype(int)
    h0 = r.origin[2]
    fix = enu_of_geodetic(w.lat1_deg[ends - 1], w.lon1_deg[ends - 1], np.full(len(ends), h0), *r.origin)[:, :2]
    err = np.zeros((3, len(starts)))
    pos, cov = _propagate(r, blind, b0s, n)[:2]
    err[DEFAULT] = np.hypot(*(pos[:, -1, :2] - fix).T)
    # what the covariance grew by against how far the track drifted from the fixes: the start's own
    # uncertainty is the fixes' (a receiver's slow wander the filter follows), which the fixes at the
    # end share and so cannot measure
    nees = nees_en(pos[:, -1, :2] - fix, growth_en(cov)[:, -1]) / 2.0
    if REDUCED in names:
        err[REDUCED] = np.hypot(*(_propagate(r, blind._replace(level_held=True), b0s, n)[0][:, -1, :2] - fix).T)
    track = _planar_dr(inputs, starts, n)[2]
    dr = enu_of_geodetic(track.lat_deg[:, -1], track.lon_deg[:, -1], np.full(len(ends), h0), *r.origin)[:, :2]
    err[PLANAR_DR] = np.hypot(*(dr - fix).T)
    # a candidate left out never wins (its record infinite)
    ranked = np.where(np.isin(np.arange(3), names)[:, None], err, np.inf)
    choice, sums, count = history_check.past_choice(ends, ranked, inputs.starts, np.array([1.0, ARBITER_PRIOR_RATIO,
                                                                                            ARBITER_PRIOR_RATIO]))
    sums = np.where(np.isfinite(sums), sums, 0.0)
    return choice, sums, count, err, history_check.log_scale(ends, nees, inputs.starts)


#: The kind of each of the filter's measurement slots (:data:`ionav_viz.nav.strapdown.GINS_MEASUREMENTS`).
GINS_MEASUREMENT_KINDS = (("GNSS position",) * 3 + ("GNSS velocity",) * 2 + ("ZUPT",) * 3 + ("ZARU",) * 3 + ("NHC",) * 2
                          + ("odometer", "level", "level", REINITIALISED))


def health_of(r: GinsRun) -> FilterHealth:
    """The pass's update log as the estimate's :class:`~ionav_viz.nav.protocol.FilterHealth`."""
    return FilterHealth(r.bounds.t_s, GINS_MEASUREMENTS, GINS_MEASUREMENT_KINDS, r.log.innovation, r.log.variance,
                        r.log.status)


def _mechanisation_text(reduced: bool, drive: Drive) -> str:
    if not reduced:
        return "3D strapdown"
    why = f"the IMU's samples are single readings at {drive.imu.native_rate_hz:g} Hz" \
        if drive.imu is not None and drive.imu.single_readings else "asked for"
    return f"reduced: roll and pitch held, not integrated ({why}: their x and y rates alias what the holder shakes)"


def _median_text(values: np.ndarray) -> str:
    med = np.median(values, axis=0)
    return "x {:+.3f}, y {:+.3f}, z {:+.3f} (median over the drive)".format(*med)
