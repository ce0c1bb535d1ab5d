"""Writing a replay's results to a Rerun ``.rrd`` recording (the logging layer).

It consumes only results (:class:`ionav_viz.analysis.evaluate.DriveResult`, a summary text and
detected events) and sends
every series as whole columns with ``send_columns``; static layers are logged once.

Timelines: ``time`` (seconds since the first sample of the drive) and ``time_of_day`` (UTC
time of day, as a duration since midnight).

Entity paths (docs/recording.md lists them for users):

==============================================  ==============================================
``map/gnss``                                    GNSS ground-truth track (static, lat/lon), broken
                                                where the fixes are not trustworthy truth
``map/gnss_bad``                                stretches of untrustworthy fixes with a usable
                                                position (frozen, no fix, few satellites, poor
                                                accuracy), thin and grey; fixes at (0, 0) or
                                                jumping are not drawn at all
``map/gnss/position``                           current GNSS position (per sample with a usable
                                                position)
``map/<estimator>/live``                        the current outage's estimated track, growing
                                                each second (lat/lon); <estimator> is each
                                                estimator's name (``ins``, ``idnn``, plug-ins)
``map/<estimator>/all``                         all outages' estimated tracks (static overview)
``local/...``                                   the same in a local east-north frame (metres,
                                                origin at the first fix; x east, y = -north so
                                                north is up in Rerun's y-down 2D view), for
                                                offline review without map tiles
``local/outages``                               outage start points, named in the hover text (static)
``{local,map}/gnss/outage``                     the current outage's GNSS track, wide (per outage)
``map/gnss/context``                            the GNSS track 3 s either side of it, faint
``local/grid``, ``local/grid/scale``            static grid and labelled scale bar over the drive
``local/scale``                                 the current outage's scale bar (framed screenshots)
``inspect/{gnss,<est>}``                        outage inspector: the current outage in metres from
                                                the fix at its start (screen frame as ``local``)
``inspect/<est>/position``                      each estimate's current position in it (a dot)
``inspect/{grid,scale,start}``                  its grid, labelled scale bar and origin
``gnss/available``                              1 with GNSS, 0 during an outage (per window)
``gnss/state``                                  "GNSS" or "outage N" (state timeline)
``gnss/quality``                                "good" or the reasons the fixes are not
                                                trustworthy truth (state timeline, per sample)
``signals/accel_long_mps2``                     longitudinal acceleration (per sample)
``signals/yaw_rate_radps/{gyro,gnss,<est>}``   yaw rates, counter-clockwise positive
``signals/displacement_m/{gnss,<est>}``         displacement per second (per window)
``signals/speed_mps``                           GNSS speed (per sample)
``errors/{crse_m,cae_m,yaw_crse_radps,``        cumulative errors inside each outage, per
``position_error_m}/<est>``                     estimator (per window, reset at each outage)
``events/state``                                detected manoeuvres ("hard-brake #3"), state timeline
``map/events``, ``local/events``                manoeuvre positions, named in the hover text
``summary``                                     Markdown: metrics table and run parameters
==============================================  ==============================================
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..analysis.evaluate import DriveResult
from ..analysis.metrics import cumulative_errors
from ..core.errors import ToolFailure
from ..core.geo import local_en_m
from ..core.gnss_quality import GnssFault, fault_names
from ..nav.protocol import short_label
from .geometry import grid_strips, nice_step, padded_bounds, scale_bar, scale_label
from .style import BAD_GNSS_COLOR, EVENT_COLOR, GNSS_COLOR, GNSS_LABEL, GRID_COLOR, GYRO_COLOR, GYRO_LABEL, OUTAGE_MARK_COLOR, SCALE_COLOR, estimator_colors

APP_ID = "ionav-viz"


def screen_xy(east: np.ndarray, north: np.ndarray) -> np.ndarray:
    """Local frame -> Rerun 2D view coordinates (y grows downwards on screen)."""
    return np.stack([east, -north], axis=-1)


def map_zoom(lat_deg: np.ndarray, lon_deg: np.ndarray, view_px: float) -> float:
    """Web-map zoom level at which the track's extent fills about ``view_px`` pixels.

    Web Mercator: metres per pixel = 156543.03 * cos(lat) / 2^zoom (checked on a rendered map view).
    """
    lat0 = float(np.mean(lat_deg))
    east, north = local_en_m(lat_deg, lon_deg, lat0, float(np.mean(lon_deg)))
    extent_m = max(float(np.ptp(east)), float(np.ptp(north)), 50.0)
    zoom = np.log2(156543.03 * np.cos(np.radians(lat0)) * view_px / extent_m)
    return float(np.clip(zoom, 3.0, 19.0))


INSPECTOR_NAME = "Current outage: m from its start fix, north up"
#: The local view shows the whole drive's scale bar; framed on an outage (screenshots), that outage's.
LOCAL_CONTENTS = ["+ $origin/**", "- /local/scale"]
LOCAL_FRAMED_CONTENTS = ["+ $origin/**", "- /local/grid/scale"]


def blueprint(labels: list[str], zoom: float = 16.0):
    """The default review layout: the outage inspector above the whole-drive local and map views,
    the signals, the errors and the summary."""
    import rerun.blueprint as rrb

    tracks = rrb.Vertical(
        rrb.Spatial2DView(origin="inspect", name=INSPECTOR_NAME),
        rrb.Horizontal(
            rrb.Spatial2DView(origin="local", contents=LOCAL_CONTENTS, name="Drive: east-north (m)"),
            rrb.MapView(origin="map", name="Map", zoom=zoom),
        ),
        row_shares=[3, 2],
    )
    # Legends where the lines are first met (and the yaw rate's gyro); more would cover the data.
    hidden = rrb.PlotLegend(visible=False)
    signals = rrb.Vertical(
        rrb.StateTimelineView(origin="/", contents=["gnss/state", "gnss/quality", "events/state"],
                              name="GNSS, outages, manoeuvres"),
        rrb.TimeSeriesView(origin="signals/displacement_m", name="Displacement per second (m)"),
        rrb.TimeSeriesView(origin="signals/yaw_rate_radps", name="Yaw rate (rad/s, CCW +; gyro grey)", plot_legend=hidden),
        rrb.TimeSeriesView(origin="signals/accel_long_mps2", name="Longitudinal acceleration (m/s²)", plot_legend=hidden),
        row_shares=[2.8, 3, 3, 2],
    )
    errors = rrb.Vertical(
        rrb.TimeSeriesView(origin="errors/position_error_m", name="2D position error (m)"),
        rrb.Tabs(
            rrb.TimeSeriesView(origin="errors/crse_m", name="Displacement CRSE (m)", plot_legend=hidden),
            rrb.TimeSeriesView(origin="errors/cae_m", name="Displacement CAE (m)", plot_legend=hidden),
        ),
        rrb.TimeSeriesView(origin="errors/yaw_crse_radps", name="Orientation-rate CRSE (rad/s)", plot_legend=hidden),
        rrb.TextDocumentView(origin="summary", name="Summary"),
        row_shares=[3, 3, 2.5, 3.5],
    )
    return rrb.Blueprint(rrb.Horizontal(tracks, signals, errors, column_shares=[4, 3, 3]), collapse_panels=True)


def _times(t_s: np.ndarray, start_tod_s: float):
    import rerun as rr

    t_s = np.asarray(t_s, dtype=np.float64)
    return [rr.TimeColumn("time", duration=t_s), rr.TimeColumn("time_of_day", duration=start_tod_s + t_s)]


def with_breaks(t_s: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-outage series (seq, win) flattened, with a NaN half a second after every outage that the
    next one does not follow at once, so plots break the line instead of bridging the GNSS stretch."""
    t, v = t_s.ravel(), np.asarray(values, dtype=np.float64).ravel()
    if t_s.shape[0] < 2:
        return t, v
    gaps = np.flatnonzero(t_s[1:, 0] - t_s[:-1, -1] > 1.0 + 1e-6)  # outage i is followed by GNSS
    at = (gaps + 1) * t_s.shape[1]
    return np.insert(t, at, t_s[gaps, -1] + 0.5), np.insert(v, at, np.nan)


#: Per-outage layers are logged just after the outage's start, so at the start time itself (the end
#: of the previous outage, when outages follow each other) the previous outage is still shown.
OUTAGE_EPS_S = 1e-3
#: Seconds of GNSS track before and after an outage drawn faintly around it on the map.
CONTEXT_S = 3.0


def faded(color: tuple[int, int, int], keep: float = 0.45) -> tuple[int, int, int]:
    """``color`` mixed into the viewer's dark background: the faint overview layers."""
    return tuple(int(round(keep * c + (1 - keep) * 18)) for c in color)  # type: ignore[return-value]


def _outage_times(t0_s: np.ndarray, t_win: np.ndarray) -> np.ndarray:
    """Row times of the per-outage growing tracks: just after each start, then each window's end."""
    return np.concatenate([t0_s[:, None] + OUTAGE_EPS_S, t_win], axis=1).ravel()


def _outage_strips(points: np.ndarray) -> list[np.ndarray]:
    """(seq, win+1, 2) -> per outage the start point alone (clears the previous outage's track),
    then the strip of points 0..win+1 at each window's end (rows as :func:`_outage_times`)."""
    return [points[s, : w + 1] for s in range(points.shape[0]) for w in range(points.shape[1])]


def recording_id(result: DriveResult) -> str:
    """The recording's id: the same drive and outage length replayed again is the same recording."""
    return f"{result.drive.name}-{result.outage_s:g}s"


def write_recording(result: DriveResult, summary_md: str, path: Path, progress=None,
                    target: Path | None = None, events: list | None = None) -> dict[str, int]:
    """Log ``result`` to the ``.rrd`` file ``path``.

    Returns row counts per entity (for messages and tests). The recording is built in memory and
    written in one go. The caller makes the write atomic: ``path`` is then a temporary file and
    ``target`` the name used in error messages.
    """
    import rerun as rr

    rec = rr.RecordingStream(APP_ID, recording_id=recording_id(result))
    # Logged into memory and written by Python: a full disk then fails as a plain OSError, where
    # Rerun's file sink can block forever once its writer thread has died.
    memory = rec.memory_recording()
    rows = log_result(rec, result, summary_md, progress, events)
    data = memory.drain_as_bytes()
    rec.disconnect()
    with open(path, "wb") as f:  # OSError (disk full) reaches the caller's atomic write
        f.write(data)
    _check_written(path, target or path)
    return rows


def log_result(rec, result: DriveResult, summary_md: str, progress=None, events: list | None = None) -> dict[str, int]:
    """Log everything about ``result`` to the recording stream ``rec`` (any sink: memory, a viewer,
    a server). Returns row counts per entity."""
    import rerun as rr

    drive, w, starts = result.drive, result.windows, result.starts
    n_win = result.n_windows
    tod = drive.start_time_of_day_s
    usable = usable_fixes(drive.gnss_fault)
    zoom = map_zoom(drive.lat_deg[usable], drive.lon_deg[usable], 350)
    rec.send_blueprint(blueprint([short_label(e.label) for e in result.estimators], zoom))
    rec.send_recording_name(drive.name)
    rows: dict[str, int] = {}

    def send(entity: str, t_s: np.ndarray, columns) -> None:
        rec.send_columns(entity, indexes=_times(t_s, tod), columns=columns)
        rows[entity] = len(t_s)

    def step(label: str) -> None:
        if progress:
            progress(label)

    first = int(np.argmax(usable))
    lat0, lon0 = float(drive.lat_deg[first]), float(drive.lon_deg[first])
    east, north = local_en_m(drive.lat_deg, drive.lon_deg, lat0, lon0)
    truth_ll = np.stack([drive.lat_deg, drive.lon_deg], axis=-1)
    truth_xy = screen_xy(east, north)
    good_runs, bad_runs = truth_runs(drive.gnss_ok, usable)

    # Styling and static layers, once.
    estimators = list(result.estimates)
    colors = {**estimator_colors(result.estimators), "gnss": GNSS_COLOR, "gyro": GYRO_COLOR}
    labels = {**{e.name: e.label for e in result.estimators}, "gnss": GNSS_LABEL, "gyro": GYRO_LABEL}
    for est in ["gyro", "gnss", *estimators]:
        rec.log(f"signals/yaw_rate_radps/{est}", rr.SeriesLines(colors=[colors[est]], names=[labels[est]], widths=[1.5]), static=True)
    for est in ["gnss", *estimators]:
        rec.log(f"signals/displacement_m/{est}", rr.SeriesLines(colors=[colors[est]], names=[labels[est]], widths=[1.5]), static=True)
    for est in estimators:
        for group in ("crse_m", "cae_m", "yaw_crse_radps", "position_error_m"):
            rec.log(f"errors/{group}/{est}", rr.SeriesLines(colors=[colors[est]], names=[labels[est]], widths=[2.0]), static=True)
    rec.log("signals/accel_long_mps2", rr.SeriesLines(colors=[GYRO_COLOR], names=["accelerometer"]), static=True)
    rec.log("signals/speed_mps", rr.SeriesLines(colors=[GNSS_COLOR], names=["GNSS speed"]), static=True)
    rec.log("gnss/available", rr.SeriesLines(colors=[GNSS_COLOR], names=["GNSS available"]), static=True)
    # The truth is drawn wide underneath, the overview layers thin, the growing tracks wide on top.
    # The whole drive's truth is faint: the current outage's (``*/gnss/outage``) is drawn wide on top.
    rec.log("map/gnss", rr.GeoLineStrings(lat_lon=[truth_ll[a:b] for a, b in good_runs], colors=[faded(GNSS_COLOR, 0.6)],
                                           radii=rr.Radius.ui_points(2.5)), static=True)
    rec.log("local/gnss", rr.LineStrips2D([truth_xy[a:b] for a, b in good_runs], colors=[faded(GNSS_COLOR, 0.6)],
                                          radii=rr.Radius.ui_points(2.5), draw_order=10), static=True)
    _log_grid(rec, truth_xy[usable])
    if bad_runs:
        rec.log("map/gnss_bad", rr.GeoLineStrings(lat_lon=[truth_ll[a:b] for a, b in bad_runs], colors=[BAD_GNSS_COLOR],
                                                  radii=rr.Radius.ui_points(1.5)), static=True)
        rec.log("local/gnss_bad", rr.LineStrips2D([truth_xy[a:b] for a, b in bad_runs], colors=[BAD_GNSS_COLOR],
                                                  radii=rr.Radius.ui_points(1.5), draw_order=11), static=True)
    rec.log("summary", rr.TextDocument(summary_md, media_type=rr.MediaType.MARKDOWN), static=True)
    step("static layers")

    # Per-sample series.
    t = drive.t_s
    tu, nu = t[usable], int(usable.sum())
    send("map/gnss/position", tu, rr.GeoPoints.columns(positions=truth_ll[usable], colors=np.tile(GNSS_COLOR, (nu, 1)), radii=np.full(nu, -6.0)))
    send("local/gnss/position", tu, rr.Points2D.columns(positions=truth_xy[usable], colors=np.tile(GNSS_COLOR, (nu, 1)), radii=np.full(nu, -6.0)))
    quality = _quality_states(drive.gnss_fault)
    change = np.concatenate([[True], quality[1:] != quality[:-1]])
    send("gnss/quality", t[change], rr.StateChange.columns(state=[str(q) for q in quality[change]]))
    send("signals/accel_long_mps2", t, rr.Scalars.columns(scalars=drive.accel_long_mps2))
    send("signals/yaw_rate_radps/gyro", t, rr.Scalars.columns(scalars=drive.yaw_rate_radps))
    send("signals/speed_mps", t, rr.Scalars.columns(scalars=drive.speed_mps))
    step("signals")

    # Per-window GNSS truth and outage state.
    t_end = w.t0_s + 1.0
    # windows without trustworthy truth are not drawn (NaN breaks the line: no spike to (0, 0))
    ok = w.truth_ok
    send("signals/displacement_m/gnss", t_end, rr.Scalars.columns(scalars=np.where(ok, w.gnss_disp_m, np.nan)))
    send("signals/yaw_rate_radps/gnss", t_end, rr.Scalars.columns(scalars=np.where(ok, w.gnss_yaw_rate_radps, np.nan)))
    available = np.ones(len(w))
    idx = starts[:, None] + np.arange(n_win)[None, :]
    available[idx.ravel()] = 0.0
    t_state = np.concatenate([w.t0_s, [t_end[-1]]]) if len(w) else np.zeros(0)
    send("gnss/available", t_state, rr.Scalars.columns(scalars=np.concatenate([available, [available[-1]]]) if len(w) else available))
    for b in result.bridged:
        available[b.start : b.start + b.n_windows] = 0.0
    states = np.full(len(w), "GNSS", dtype=object)
    for i, k in enumerate(starts):
        states[k : k + n_win] = f"outage {i + 1} ({w.t0_s[k]:.0f}-{w.t0_s[k] + n_win:.0f} s)"
    for b in result.bridged:
        states[b.start : b.start + b.n_windows] = f"real GNSS outage {b.number} ({b.gap_t0_s:.1f}-{b.gap_t1_s:.1f} s)"
    change = np.concatenate([[True], states[1:] != states[:-1]]) if len(w) else np.zeros(0, bool)
    send("gnss/state", w.t0_s[change], rr.StateChange.columns(state=[str(s) for s in states[change]]))
    step("outages")
    if events:
        _log_events(rec, events, drive, usable, lat0, lon0, send)

    if len(starts):
        # every estimate's tracks in the local frame, (seq, win+1, 2): projected once
        tracks_xy = {name: screen_xy(*local_en_m(e.track.lat_deg, e.track.lon_deg, lat0, lon0)) for name, e in result.estimates.items()}
        _log_outages(rec, result, truth_xy, truth_ll, tracks_xy, usable, lat0, lon0, send)
        t_win = t_end[idx].ravel()
        t_rows = _outage_times(w.t0_s[starts], t_win.reshape(len(starts), n_win))
        for name, est in result.estimates.items():
            color = colors[name]
            ll = np.stack([est.track.lat_deg, est.track.lon_deg], axis=-1)  # (seq, win+1, 2)
            xy = tracks_xy[name]
            n_rows = len(t_rows)
            thin, wide = rr.Radius.ui_points(1.2), rr.Radius.ui_points(3.0)
            send(f"map/{name}/live", t_rows, rr.GeoLineStrings.columns(
                line_strings=_outage_strips(ll), colors=np.tile(color, (n_rows, 1)), radii=np.full(n_rows, wide)))
            send(f"local/{name}/live", t_rows, rr.LineStrips2D.columns(
                strips=_outage_strips(xy), colors=np.tile(color, (n_rows, 1)), radii=np.full(n_rows, wide),
                draw_order=np.full(n_rows, 30.0)))
            rel = xy - xy[:, :1]
            send(f"inspect/{name}", t_rows, rr.LineStrips2D.columns(
                strips=_outage_strips(rel), colors=np.tile(color, (n_rows, 1)), radii=np.full(n_rows, wide),
                draw_order=np.full(n_rows, 30.0)))
            # the estimate's current position: visible where tracks along the same road cover each other
            send(f"inspect/{name}/position", t_rows, rr.Points2D.columns(
                positions=rel.reshape(-1, 2), colors=np.tile(color, (n_rows, 1)), radii=np.full(n_rows, rr.Radius.ui_points(6.0)),
                draw_order=np.full(n_rows, 40.0)))
            faint = faded(color)
            rec.log(f"map/{name}/all", rr.GeoLineStrings(lat_lon=list(ll), colors=[faint], radii=thin), static=True)
            rec.log(f"local/{name}/all", rr.LineStrips2D(list(xy), colors=[faint], radii=thin, draw_order=20), static=True)
            series = {f"signals/displacement_m/{name}": est.disp_m, f"signals/yaw_rate_radps/{name}": est.yaw_rate_radps}
            series.update({f"errors/{m}/{name}": v for m, v in cumulative_errors(w, starts, n_win, est).items()})
            for entity, values in series.items():
                t_plot, v_plot = with_breaks(t_end[idx], values)
                send(entity, t_plot, rr.Scalars.columns(scalars=v_plot))
            step(name)
    if result.bridged:
        _log_bridged(rec, result, colors, labels, lat0, lon0, send)
        step("real GNSS outages")
    return rows


def _log_outages(rec, result: DriveResult, truth_xy: np.ndarray, truth_ll: np.ndarray, tracks_xy: dict[str, np.ndarray],
                 usable: np.ndarray, lat0: float, lon0: float, send) -> None:
    """What frames each outage: its GNSS track (wide, on top of the faint whole drive), the outage
    inspector (everything in metres from the fix at the outage start, with a grid and a scale bar)
    and the outage start markers."""
    import rerun as rr

    drive, w, starts, n_win = result.drive, result.windows, result.starts, result.n_windows
    t0 = w.t0_s[starts]
    t_rows = t0 + OUTAGE_EPS_S
    n = len(starts)
    last = starts + n_win - 1
    start_ll = np.stack([w.lat0_deg[starts], w.lon0_deg[starts]], axis=-1)
    end_ll = np.stack([w.lat1_deg[last], w.lon1_deg[last]], axis=-1)
    start_xy = screen_xy(*local_en_m(start_ll[:, 0], start_ll[:, 1], lat0, lon0))
    end_xy = screen_xy(*local_en_m(end_ll[:, 0], end_ll[:, 1], lat0, lon0))
    ti = np.flatnonzero(usable)
    # the fixes inside the outage, between its start and end on the windows' grid (what metrics score)
    a = np.searchsorted(drive.t_s[ti], t0, side="right")
    b = np.searchsorted(drive.t_s[ti], t0 + n_win, side="left")
    ca = np.searchsorted(drive.t_s[ti], t0 - CONTEXT_S, side="left")
    cb = np.searchsorted(drive.t_s[ti], t0 + n_win + CONTEXT_S, side="right")
    truth = [np.concatenate([start_xy[k : k + 1], truth_xy[ti[i:j]], end_xy[k : k + 1]]) for k, (i, j) in enumerate(zip(a, b))]
    truth_geo = [np.concatenate([start_ll[k : k + 1], truth_ll[ti[i:j]], end_ll[k : k + 1]]) for k, (i, j) in enumerate(zip(a, b))]
    wide = rr.Radius.ui_points(4.5)
    send("local/gnss/outage", t_rows, rr.LineStrips2D.columns(
        strips=truth, colors=np.tile(GNSS_COLOR, (n, 1)), radii=np.full(n, wide), draw_order=np.full(n, 12.0)))
    send("map/gnss/outage", t_rows, rr.GeoLineStrings.columns(
        line_strings=truth_geo, colors=np.tile(GNSS_COLOR, (n, 1)), radii=np.full(n, wide)))
    send("map/gnss/context", t_rows, rr.GeoLineStrings.columns(
        line_strings=[truth_ll[ti[i:j]] for i, j in zip(ca, cb)], colors=np.tile(faded(GNSS_COLOR), (n, 1)),
        radii=np.full(n, rr.Radius.ui_points(2.0))))
    send("inspect/gnss", t_rows, rr.LineStrips2D.columns(
        strips=[tr - s for tr, s in zip(truth, start_xy)], colors=np.tile(GNSS_COLOR, (n, 1)), radii=np.full(n, wide),
        draw_order=np.full(n, 12.0)))

    # Each outage's frame: its truth and every estimate, padded; a grid and a scale bar to match.
    bounds = []
    for i in range(n):
        pts = np.concatenate([truth[i], *(t[i] for t in tracks_xy.values()), start_xy[i : i + 1]])
        bounds.append(padded_bounds(pts - start_xy[i]))
    steps = [nice_step(max(bx[1] - bx[0], bx[3] - bx[2])) for bx in bounds]
    grids = [grid_strips(bx, st) for bx, st in zip(bounds, steps)]
    send("inspect/grid", t_rows, rr.LineStrips2D.columns(
        strips=[g for grid in grids for g in grid], colors=np.tile(GRID_COLOR, (sum(map(len, grids)), 1)),
        radii=np.full(sum(map(len, grids)), rr.Radius.ui_points(0.8)), draw_order=np.full(sum(map(len, grids)), 1.0)).partition(
            [len(g) for g in grids]))
    send("inspect/scale", t_rows, rr.LineStrips2D.columns(
        strips=[scale_bar(bx, st) for bx, st in zip(bounds, steps)], labels=[scale_label(st) for st in steps],
        colors=np.tile(SCALE_COLOR, (n, 1)), radii=np.full(n, rr.Radius.ui_points(2.0)), draw_order=np.full(n, 50.0)))
    local_bounds = [(bx[0] + s[0], bx[1] + s[0], bx[2] + s[1], bx[3] + s[1]) for bx, s in zip(bounds, start_xy)]
    send("local/scale", t_rows, rr.LineStrips2D.columns(
        strips=[scale_bar(bx, st) for bx, st in zip(local_bounds, steps)], labels=[scale_label(st) for st in steps],
        colors=np.tile(SCALE_COLOR, (n, 1)), radii=np.full(n, rr.Radius.ui_points(2.0)), draw_order=np.full(n, 50.0)))
    rec.log("inspect/start", rr.Points2D([[0.0, 0.0]], colors=[OUTAGE_MARK_COLOR], radii=rr.Radius.ui_points(5.0), draw_order=45),
            static=True)
    rec.log("local/outages", rr.Points2D(start_xy, labels=[f"outage {i + 1}" for i in range(n)], show_labels=False,
                                         colors=[OUTAGE_MARK_COLOR], radii=rr.Radius.ui_points(3.0), draw_order=25), static=True)


def _log_grid(rec, xy: np.ndarray) -> None:
    """A static grid and scale bar over the whole drive in the local view."""
    import rerun as rr

    bounds = padded_bounds(xy, margin=0.02)
    step = nice_step(max(bounds[1] - bounds[0], bounds[3] - bounds[2]), lines=8)
    grid = grid_strips(bounds, step)
    rec.log("local/grid", rr.LineStrips2D(grid, colors=[GRID_COLOR], radii=rr.Radius.ui_points(0.8), draw_order=1), static=True)
    rec.log("local/grid/scale", rr.LineStrips2D([scale_bar(bounds, step)], labels=[scale_label(step)], colors=[SCALE_COLOR],
                                                radii=rr.Radius.ui_points(2.0), draw_order=50), static=True)


def _log_bridged(rec, result: DriveResult, colors: dict, labels: dict, lat0: float, lon0: float, send) -> None:
    """The log's own GNSS outages: each estimator's track through them (wide, on top), the first
    good fix after each (the truth that scores them) and each final error on the error timeline."""
    import rerun as rr

    bridged = result.bridged
    end_ll = np.array([[b.end_lat_deg, b.end_lon_deg] for b in bridged])
    rec.log("map/gnss_outages/end_fix", rr.GeoPoints(lat_lon=end_ll, colors=[OUTAGE_MARK_COLOR], radii=rr.Radius.ui_points(6.0)), static=True)
    rec.log("local/gnss_outages/end_fix", rr.Points2D(screen_xy(*local_en_m(end_ll[:, 0], end_ll[:, 1], lat0, lon0)),
                                                      colors=[OUTAGE_MARK_COLOR], radii=rr.Radius.ui_points(5.0), draw_order=40), static=True)
    t1 = np.array([b.t1_s for b in bridged])
    for est in result.estimators:
        name, color = est.name, colors[est.name]
        ll = [np.stack([b.tracks[name].lat_deg[0], b.tracks[name].lon_deg[0]], axis=-1) for b in bridged]
        xy = screen_xy(*local_en_m(*np.concatenate(ll).T, lat0, lon0))  # one projection for every track
        ends = np.cumsum([len(x) for x in ll])[:-1]
        rec.log(f"map/{name}/real_outages", rr.GeoLineStrings(lat_lon=ll, colors=[color], radii=rr.Radius.ui_points(3.0)), static=True)
        rec.log(f"local/{name}/real_outages", rr.LineStrips2D(np.split(xy, ends), colors=[color], radii=rr.Radius.ui_points(3.0),
                                                              draw_order=30), static=True)
        entity = f"errors/position_error_m/real_outages/{name}"
        rec.log(entity, rr.SeriesPoints(colors=[color], names=[f"{labels[name]} (real outages)"], marker_sizes=[6.0]), static=True)
        send(entity, t1, rr.Scalars.columns(scalars=[b.final_error_m[name] for b in bridged]))


def truth_runs(good: np.ndarray, usable: np.ndarray) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Index ranges ``[a, b)`` of the good stretches and of the bad-but-drawable ones of a track.

    A bad stretch also takes the good samples on either side, so the grey line joins the green.
    Unusable samples (no position) are in neither: the track is broken there.
    """
    def runs(mask: np.ndarray) -> list[tuple[int, int]]:
        edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
        return [(int(a), int(b)) for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)) if b - a >= 1]

    n = len(good)
    good_runs = [(a, b) for a, b in runs(good & usable) if b - a >= 2]
    bad_runs = []
    for a, b in runs(~good & usable):
        a = a - 1 if a > 0 and usable[a - 1] else a
        b = b + 1 if b < n and usable[b] else b
        if b - a >= 2:
            bad_runs.append((a, b))
    return good_runs, bad_runs


def _quality_states(fault: np.ndarray) -> np.ndarray:
    """Per sample "good" or the fault names ("bad: frozen, jump")."""
    states = np.full(len(fault), "good", dtype=object)
    for mask in np.unique(fault[fault != 0]):
        states[fault == mask] = "bad: " + ", ".join(fault_names(int(mask)))
    return states


def usable_fixes(fault: np.ndarray) -> np.ndarray:
    """Samples whose fix is a position worth drawing (and framing views around): not at (0, 0),
    not a jump. All of them if none is."""
    usable = (fault & np.uint16(GnssFault.NEAR_ZERO | GnssFault.JUMP)) == 0
    return usable if usable.any() else np.ones(len(fault), dtype=bool)



def _log_events(rec, events: list, drive, usable: np.ndarray, lat0: float, lon0: float, send) -> None:
    """Detected manoeuvres: a state timeline, and labelled points on the map and local view."""
    import rerun as rr

    times, states = [], []
    for i, e in enumerate(sorted(events, key=lambda e: e.t0_s)):
        if times and e.t0_s < times[-1]:  # overlapping events: the timeline shows the later one
            times.pop()
            states.pop()
        times += [e.t0_s, e.t1_s]
        states += [f"{e.type} #{i + 1}", "none"]
    order = np.argsort(times, kind="stable")
    send("events/state", np.asarray(times)[order], rr.StateChange.columns(state=[states[k] for k in order]))
    mid = np.array([0.5 * (e.t0_s + e.t1_s) for e in events])
    # a loss's middle lies between its good fixes (``usable``), not at (0, 0)
    lat = np.interp(mid, drive.t_s[usable], drive.lat_deg[usable])
    lon = np.interp(mid, drive.t_s[usable], drive.lon_deg[usable])
    labels = [f"{e.type} #{i + 1}" for i, e in enumerate(events)]
    # names in the hover text and on the timeline only: permanent labels would cover the tracks
    rec.log("map/events", rr.GeoPoints(lat_lon=np.stack([lat, lon], axis=-1), colors=[EVENT_COLOR], radii=rr.Radius.ui_points(3.5)),
            static=True)
    rec.log("local/events", rr.Points2D(screen_xy(*local_en_m(lat, lon, lat0, lon0)), labels=labels, show_labels=False,
                                        colors=[EVENT_COLOR], radii=rr.Radius.ui_points(3.5), draw_order=25), static=True)


def _check_written(path: Path, target: Path) -> None:
    """Read the file's footer back: a sink that failed silently must not pass as a recording."""
    from rerun.chunk import RrdReader

    try:
        ok = len(RrdReader(path).recordings()) == 1
    except Exception as exc:  # the reader's errors are not one class
        raise ToolFailure(f"{target}: the written recording does not read back ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); is the disk full?") from None
    if not ok:
        raise ToolFailure(f"{target}: the written recording holds no recording; is the disk full?")
