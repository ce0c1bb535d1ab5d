"""An estimate made outside ionav-viz, scored like a built-in (``--external NAME=PATH``).

The external program ran on the outaged log (``ionav-viz outage-log``) and wrote its trajectory
(:mod:`ionav_viz.sources.trajectory`). Per outage, its positions at the window boundaries are
interpolated from that trajectory on the log's own clock (:meth:`~ionav_viz.core.drive.Drive.stamp_s`),
from its poses up to the outage's end only (the end extrapolated from the last two when no pose falls
on it: nothing written after the GNSS came back counts); a trajectory whose poses begin only after an
outage's start (an estimator that writes inside the gaps) begins at the outage's start fix, the last
fix the outaged log keeps and the estimators' start state;
per-window distance and yaw rate come from those positions (:func:`.track.windows_of_track`), and
its final position error from its own position at the outage's end. A trajectory that does not
cover an outage is an error naming it (and, when its stamps look like milliseconds or another unit,
saying so); one that equals the removed GNSS fixes inside the outages
(it ran on the original log, or is the GNSS itself) is reported. A trajectory that carries its
east/north covariance (:attr:`~ionav_viz.sources.trajectory.Trajectory.cov_en_m2`) gives the
estimate's :attr:`~ionav_viz.nav.protocol.Estimate.pos_cov_m2`, each entry linear in time between
poses like the positions (a mix of positive semi-definite matrices is one), held after the last
pose, and the next pose's at a start fix the trajectory was begun at.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.geo import geodetic_of_en_m, wgs84
from ..core.units import stamp_unit_hint
from ..sources.trajectory import Trajectory
from .protocol import Estimate, EstimatorError, EstimatorInputs
from .track import windows_of_track

log = logging.getLogger("ionav_viz")

#: The trajectory must have a pose within this (s) of every boundary, before and after it.
MAX_GAP_S = 2.0
#: Positions within this (m) of the removed fixes at most of an outage's boundaries: it saw them.
LEAK_M = 0.01
#: The pose nearest an outage's start may lie at most this far (m) from the start fix the estimator
#: was given; farther, its positions are in other units or on another origin.
MAX_START_OFFSET_M = 1000.0


#: A day (s): an IO-VNBD log's clock, the time of day, starts again at 0 after midnight.
DAY_S = 86400.0


def _past_midnight(drive: Any, t: np.ndarray, *columns: Any) -> tuple[Any, ...]:
    """The order of the trajectory's poses, its stamps ``t`` (sorted) and its ``columns`` on the drive's clock. An
    IO-VNBD drive's clock is the time of day run on past 86,400 s when the drive crosses midnight (as its
    plan's stamps are), while a trajectory written on the outaged log's own stamps starts the new
    day at 0: its poses after midnight were sorted before the drive's start. They are moved on by
    a day and the poses sorted again; on any other clock, or before midnight, nothing changes."""
    same = np.arange(len(t))
    if not len(drive) or not len(t):
        return (same, t, *columns)
    first, last = float(drive.stamp_s(drive.t_s[0])), float(drive.stamp_s(drive.t_s[-1]))
    if not first < DAY_S < last:  # not a time of day run past midnight (UNIX stamps are 1e9 s and more)
        return (same, t, *columns)
    wrapped = (t < first - MAX_GAP_S) & (t <= last - DAY_S + MAX_GAP_S)
    if not wrapped.any():
        return (same, t, *columns)
    t = np.where(wrapped, t + DAY_S, t)
    order = np.argsort(t, kind="stable")
    return (order, t[order], *(None if c is None else np.asarray(c)[order] for c in columns))


@dataclass
class External:
    """An external trajectory as an estimator (``name``, ``label`` as the report shows it)."""

    name: str
    trajectory: Trajectory
    label: str = ""
    needs = ()

    def __post_init__(self) -> None:
        self.label = self.label or f"{self.name} (external)"

    def describe(self) -> dict:
        return {"external": self.trajectory.source}

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        drive, traj, n = inputs.drive, self.trajectory, inputs.n_windows
        offsets = np.arange(n + 1, dtype=float)
        when = np.asarray(drive.stamp_s(inputs.t0_s[:, None] + offsets[None, :]), dtype=float)
        if traj.local:
            lat_all, lon_all = geodetic_of_en_m(traj.east_m, traj.north_m, *drive.local_origin_deg)
        else:
            lat_all, lon_all = traj.lat_deg, traj.lon_deg
        order, t, lat_all, lon_all, cov_all = _past_midnight(drive, traj.stamps_s, lat_all, lon_all, traj.cov_en_m2)
        lon_all = np.rad2deg(np.unwrap(np.deg2rad(lon_all)))
        lat, lon = np.empty_like(when), np.empty_like(when)
        cov = None if cov_all is None else np.empty((*when.shape, 2, 2))
        nearest = np.zeros(len(when), dtype=int)  # per outage, the pose nearest its start
        for i, row in enumerate(when):
            # only poses up to the outage's end: nothing the estimator wrote after the GNSS came back
            upto = int(np.searchsorted(t, row[-1] + 1e-6, side="right"))
            nearest[i] = _nearest(t[:upto], row[0])
            t_i, lat_i, lon_i, cov_i = _from_start_fix(row[0], t[:upto], lat_all[:upto], lon_all[:upto],
                                                       None if cov is None else cov_all[:upto],
                                                       float(inputs.lat0_deg[i]), float(inputs.lon0_deg[i]))
            if not _covers(t_i, row):
                first = float(drive.stamp_s(drive.t_s[0]))
                units = stamp_unit_hint(t, first, float(drive.stamp_s(drive.t_s[-1])))
                raise EstimatorError(
                    f"external {self.name!r} ({traj.source}): its trajectory does not cover outage {i + 1} "
                    f"(stamps {row[0]:.3f}-{row[-1]:.3f} s; it spans {t[0]:.3f}-{t[-1]:.3f} s, poses at most "
                    f"{MAX_GAP_S:g} s apart needed)",
                    units or
                    "run the estimator over the whole outaged log, and write stamps on its clock (see 'An estimator "
                    "outside ionav-viz')")
            lat[i], lon[i] = (_interpolated(row, t_i, v) for v in (lat_i, lon_i))
            if cov is not None:
                cov[i] = _interpolated_cov(row, t_i, cov_i)
        lon = (lon + 180.0) % 360.0 - 180.0
        self._check_start(inputs, nearest, lat_all, lon_all, order)
        self._report_leaks(inputs, when, lat, lon)
        disp, yaw = windows_of_track(lat, lon, inputs.course0_deg)
        return Estimate(disp, yaw, lat_deg=lat, lon_deg=lon, pos_cov_m2=cov)

    def _check_start(self, inputs: EstimatorInputs, nearest: np.ndarray, lat_all: np.ndarray, lon_all: np.ndarray,
                     order: np.ndarray) -> None:
        """Refuse a trajectory whose pose nearest an outage's start lies more than
        :data:`MAX_START_OFFSET_M` from the start fix it was given: positions in other units
        (radians, kilometres), latitude and longitude swapped, or another local origin; the hint
        names the likely one."""
        if not len(nearest):
            return
        geod = wgs84()
        _, _, dist = geod.inv(lon_all[nearest], lat_all[nearest], inputs.lon0_deg, inputs.lat0_deg)
        dist = np.asarray(dist, dtype=float)
        if not (dist > MAX_START_OFFSET_M).any():
            return
        i = int(np.argmax(dist > MAX_START_OFFSET_M))
        j, traj = int(order[nearest[i]]), self.trajectory  # the pose as the file has it
        lat0, lon0 = float(inputs.lat0_deg[i]), float(inputs.lon0_deg[i])
        if traj.local:
            e, n = float(traj.east_m[j]), float(traj.north_m[j])
            origin = inputs.drive.local_origin_deg
            candidates = [("kilometres", *geodetic_of_en_m(e * 1e3, n * 1e3, *origin)),
                          ("x north and y east", *geodetic_of_en_m(n, e, *origin)),
                          ("latitude and longitude in degrees", e, n)]
        else:
            a, b = float(traj.lat_deg[j]), float(traj.lon_deg[j])
            candidates = [("radians", np.degrees(a), np.degrees(b)), ("longitude first, then latitude", b, a)]
        likely = next((label for label, la, lo in candidates if abs(float(la)) <= 90
                       and geod.inv(float(lo), float(la), lon0, lat0)[2] <= MAX_START_OFFSET_M), None)
        what = ("time_s,east_m,north_m (metres about the drive's first fix)"
                if traj.local else "time_s,lat_deg,lon_deg (WGS84 degrees)")
        raise EstimatorError(
            f"external {self.name!r} ({traj.source}): at outage {i + 1}'s start its pose lies {dist[i] / 1000:.4g} km "
            f"from the start fix it was given ({lat0:.6f}, {lon0:.6f}); at most {MAX_START_OFFSET_M / 1000:g} km "
            "is an estimate",
            (f"its positions look like {likely}: " if likely else "") + f"write {what}")

    def _report_leaks(self, inputs: EstimatorInputs, when: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> None:
        """Warn when inside the outages the trajectory sits on the GNSS fixes that were removed."""
        drive, n = inputs.drive, inputs.n_windows
        if n < 2:
            return
        stamps = np.asarray(drive.stamp_s(drive.t_s), dtype=float)
        inner = when[:, 1:-1]
        g_lat, g_lon = np.interp(inner, stamps, drive.lat_deg), np.interp(inner, stamps, drive.lon_deg)
        _, _, dist = wgs84().inv(lon[:, 1:-1].ravel(), lat[:, 1:-1].ravel(), g_lon.ravel(), g_lat.ravel())
        on_fixes = (np.asarray(dist).reshape(inner.shape) < LEAK_M).mean(axis=1) > 0.5
        if on_fixes.any():
            log.warning("external %s: inside %d of %d outage(s) its positions are the GNSS fixes the outaged log lacks "
                        "(within %g m): it ran on the original log, or is the GNSS itself; its scores are "
                        "not an outage's",
                        self.name, int(on_fixes.sum()), len(on_fixes), LEAK_M)


def _covers(t: np.ndarray, at: np.ndarray) -> bool:
    """Whether poses at ``t`` (sorted) give every boundary ``at``: a pose on it, or one within
    :data:`MAX_GAP_S` before and after it; at least two poses."""
    if len(t) < 2:
        return False
    k = np.searchsorted(t, at)
    before = np.where(k > 0, at - t[np.maximum(k - 1, 0)], np.inf)
    on = (k < len(t)) & np.isclose(t[np.minimum(k, len(t) - 1)], at, rtol=0.0, atol=1e-6)
    after = np.where(k < len(t), t[np.minimum(k, len(t) - 1)] - at, 0.0)
    return bool(np.all(on | ((before <= MAX_GAP_S) & (after <= MAX_GAP_S))))


def _from_start_fix(start: float, t: np.ndarray, lat: np.ndarray, lon: np.ndarray, cov: np.ndarray | None, lat0: float,
                    lon0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """The poses (stamps, latitudes, longitudes and, unless None, covariances ``(n, 2, 2)`` in m^2),
    begun at the outage's start fix (``lat0``, ``lon0``: the estimators' start state, the last fix
    the outaged log keeps; its covariance the next pose's) when the trajectory has none within
    :data:`MAX_GAP_S` at or before ``start`` but one within it after: an estimator that writes poses
    only inside the gaps starts from that fix. Otherwise the poses as they are."""
    k = int(np.searchsorted(t, start + 1e-6, side="right"))  # poses at or before the start
    if (k > 0 and start - t[k - 1] <= MAX_GAP_S) or k >= len(t) or t[k] - start > MAX_GAP_S:
        return t, lat, lon, cov
    lon0 += 360.0 * round((lon[k] - lon0) / 360.0)  # on the trajectory's unwrapped longitudes
    cov = None if cov is None else np.insert(cov, k, cov[k], axis=0)
    return np.insert(t, k, start), np.insert(lat, k, lat0), np.insert(lon, k, lon0), cov


def _interpolated(at: np.ndarray, t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear in time between poses; after the last one, extrapolated from the last two."""
    out = np.interp(at, t, values)
    late = at > t[-1]
    if late.any():
        rate = (values[-1] - values[-2]) / (t[-1] - t[-2])
        out[late] = values[-1] + rate * (at[late] - t[-1])
    return out


def _interpolated_cov(at: np.ndarray, t: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Covariances ``(n, 2, 2)`` at ``at``: each entry linear in time between poses, the last one
    held after the last pose (extrapolating a covariance could make it indefinite)."""
    flat = cov.reshape(len(t), 4)
    return np.stack([np.interp(at, t, flat[:, j]) for j in range(4)], axis=-1).reshape(len(at), 2, 2)


def _nearest(t: np.ndarray, at: float) -> int:
    """Index of the stamp of ``t`` (sorted) nearest ``at``, the earlier on a tie; 0 when empty."""
    k = int(np.searchsorted(t, at))
    candidates = [c for c in (k - 1, k) if 0 <= c < len(t)]
    return min(candidates, key=lambda c: (abs(t[c] - at), c)) if candidates else 0
