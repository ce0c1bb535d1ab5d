"""Bridging the log's own GNSS losses (``replay --on gnss-outage``): the real test of an estimator.

A synthetic outage has truth in every window; a real one (a tunnel, a bridge, an urban canyon: the
``gnss-outage`` events of :mod:`ionav_viz.analysis.events`) has none inside. Every estimator is run
through each loss from the last good fix (:func:`ionav_viz.experiment.outages.bridging` places the
outage on the 1-second windows), and the only truth there is, the first good fix after the
loss, scores it: the geodesic distance between the estimator's position and that fix at the end
of the outage (``final_error_m``). The paper's per-window metrics (CRSE, CAE, AEPS) do not exist
for a real loss and are not computed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.drive import Drive
from ..core.geo import wgs84
from ..core.grid import WINDOW_S
from ..experiment.outages import bridge_each, placed_of, reasons_of
from ..nav.bias import SensorBias
from ..nav.protocol import Estimator, EstimatorInputs, solve
from ..nav.track import Track
from ..nav.windows import Windows, make_windows


@dataclass
class BridgedOutage:
    """One real GNSS loss, bridged by every estimator.

    Times are seconds since the drive's first sample. ``gap_t0_s``/``gap_t1_s``: the last good
    fix before the loss and the first good fix after it; ``t0_s``/``t1_s``: the outage run on the
    windows (from the window boundary at or before the last good fix, ``n_windows`` seconds long).
    ``end_lat_deg``/``end_lon_deg``: the truth at ``t1_s``; ``span_m``: straight-line distance from
    the start fix to it. ``final_error_m`` and ``tracks`` per estimator name.
    """

    number: int
    gap_t0_s: float
    gap_t1_s: float
    t0_s: float
    t1_s: float
    start: int
    n_windows: int
    end_lat_deg: float
    end_lon_deg: float
    span_m: float
    final_error_m: dict[str, float] = field(default_factory=dict)
    tracks: dict[str, Track] = field(default_factory=dict)

    @property
    def gap_s(self) -> float:
        return self.gap_t1_s - self.gap_t0_s

    def window_signals(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the estimator ``name`` gave through this loss, per window: the windows' end times
        (s), the displacement (m, the geodesic between its track's positions) and the yaw rate (rad/s,
        counter-clockwise positive, from its course: clockwise from north), as its track was built."""
        track = self.tracks[name]
        lat, lon, course = track.lat_deg[0], track.lon_deg[0], track.heading_deg[0]
        _, _, disp = wgs84().inv(lon[:-1], lat[:-1], lon[1:], lat[1:])
        yaw = -np.deg2rad((np.diff(course) + 180.0) % 360.0 - 180.0) / WINDOW_S
        return self.t0_s + WINDOW_S * np.arange(1, len(course)), np.asarray(disp, dtype=float), yaw

    def to_dict(self) -> dict[str, Any]:
        return {"number": self.number, "gap_start_s": round(self.gap_t0_s, 2), "gap_end_s": round(self.gap_t1_s, 2),
                "gap_s": round(self.gap_s, 2), "outage_start_s": round(self.t0_s, 2), "outage_s": self.n_windows,
                "span_m": round(self.span_m, 2),
                "final_error_m": {k: round(v, 3) for k, v in self.final_error_m.items()}}


def bridge_gnss_outages(drive: Drive, windows: Windows, gaps: Sequence[tuple[float, float]],
                        estimators: Sequence[Estimator],
                        bias: SensorBias) -> tuple[list[BridgedOutage], dict[str, int]]:
    """Every estimator through each GNSS gap ``(last good fix s, first good fix s)``; returns the
    bridged outages and how many gaps could not be bridged, per reason
    (:func:`~ionav_viz.experiment.outages.unbridged`). The estimators are given the receiver's fixes
    (:meth:`~ionav_viz.core.drive.Drive.as_received`) and scored against ``windows``, the truth (a
    reference where the drive has one)."""
    geod = wgs84()
    received = drive.as_received()
    given = windows if received is drive else make_windows(received)
    each = bridge_each(windows, gaps)  # one pass: what is bridged, and why the rest is not
    placed = placed_of(each)
    out: list[BridgedOutage] = []
    for number, (i, k, n) in enumerate(placed, start=1):
        end = k + n
        _, _, span = geod.inv(windows.lon0_deg[k], windows.lat0_deg[k], windows.lon0_deg[end], windows.lat0_deg[end])
        out.append(BridgedOutage(number, float(gaps[i][0]), float(gaps[i][1]), float(windows.t0_s[k]),
                                 float(windows.t0_s[end]), k, n, float(windows.lat0_deg[end]),
                                 float(windows.lon0_deg[end]), float(span)))
    for n in sorted({b.n_windows for b in out}):  # one batch per outage length
        group = [b for b in out if b.n_windows == n]
        inputs = EstimatorInputs(received, given, np.asarray([b.start for b in group], dtype=int), n, bias)
        for est in estimators:
            track = solve(est, inputs).track
            _, _, err = geod.inv(track.lon_deg[:, -1], track.lat_deg[:, -1], [b.end_lon_deg for b in group],
                                 [b.end_lat_deg for b in group])
            for j, b in enumerate(group):
                b.final_error_m[est.name] = float(np.atleast_1d(err)[j])
                b.tracks[est.name] = Track(track.lat_deg[j : j + 1], track.lon_deg[j : j + 1],
                                           track.heading_deg[j : j + 1])
    return out, reasons_of(each)
