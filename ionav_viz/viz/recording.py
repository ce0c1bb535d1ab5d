"""Writing a replay's results to a Rerun ``.rrd`` recording (the logging layer).

It consumes only results (:class:`ionav_viz.analysis.evaluate.DriveResult`, a summary text and
detected events) and sends
every series as whole columns with ``send_columns``; static layers are logged once.

Timelines: ``time`` (seconds since the first sample of the drive) and ``time_of_day`` (UTC
time of day, as a duration since midnight).

Entity paths and state labels come from :mod:`ionav_viz.viz.entities` (``docs/recording.md`` lists
them for users); the layout from :mod:`ionav_viz.viz.blueprints`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..analysis.evaluate import DriveResult
from ..analysis.metrics import cumulative_errors
from ..core.errors import ToolFailure
from ..core.fileio import utf8_alias
from ..core.geo import local_en_m
from ..core.gnss_quality import GnssFault, fault_names
from ..core.grid import WINDOW_S
from ..core.runs import run_ranges
from . import columns
from . import entities as ent
from .blueprints import blueprint, plot_range, ruler_end_s
from .columns import with_breaks
from .geometry import map_zoom, screen_xy
from .health import log_health
from .layers import (
    END_DOT_PT,
    END_ORDER,
    TRACK_ORDER,
    TRUTH_DOT_PT,
    TRUTH_END_ORDER,
    Layers,
    log_drift,
    log_events,
    log_grid,
    log_outage_frames,
    log_real_outages,
    log_state_lane,
    track_radii_pt,
)
from .style import (
    BAD_GNSS_COLOR,
    GNSS_COLOR,
    GNSS_LABEL,
    GYRO_COLOR,
    GYRO_LABEL,
    RECEIVER_COLOR,
    REFERENCE_LABEL,
    color_word,
    estimator_colors,
    faded,
    stacking,
)
from .uncertainty import log_uncertainty, log_uncertainty_styles

APP_ID = "ionav-viz"
#: Longest wait (s) for Rerun's file sink to write what was logged: a healthy disk writes a 12 h
#: drive's recording in about a second, and a failed writer makes the flush raise at once.
FLUSH_TIMEOUT_S = 600.0


def _times(t_s: np.ndarray, start_tod_s: float):
    import rerun as rr

    t_s = np.asarray(t_s, dtype=np.float64)
    return [rr.TimeColumn("time", duration=t_s), rr.TimeColumn("time_of_day", duration=start_tod_s + t_s)]


def _outage_times(t0_s: np.ndarray, t_win: np.ndarray) -> np.ndarray:
    """Row times of the per-outage growing tracks: just after each start, then each window's end."""
    return np.concatenate([t0_s[:, None] + ent.OUTAGE_EPS_S, t_win], axis=1).ravel()


def recording_id(result: DriveResult) -> str:
    """The recording's id: the same drive and outage length replayed again is the same recording."""
    return f"{result.drive.name}-{result.outage_s:g}s"


def write_recording(result: DriveResult, summary_md: str, path: Path, progress=None,
                    target: Path | None = None, events: list | None = None, report_json: str | None = None,
                    overview_md: str | None = None) -> dict[str, int]:
    """Log ``result`` to the ``.rrd`` file ``path`` (with ``report_json``, the run's report, at
    ``report``, and ``overview_md``, the summary's head, at ``overview``).

    Returns row counts per entity (for messages and tests). The recording is streamed to ``path``
    as it is logged. The caller makes the write atomic: ``path`` is then a temporary file and
    ``target`` the name used in error messages.
    """
    import rerun as rr

    rec = rr.RecordingStream(APP_ID, recording_id=recording_id(result))
    with streamed_to(rec, path, target):
        rows = log_result(rec, result, summary_md, progress, events)
        if overview_md is not None:
            rec.log(ent.OVERVIEW, rr.TextDocument(overview_md, media_type=rr.MediaType.MARKDOWN), static=True)
            rows[ent.OVERVIEW] = 1
        if report_json is not None:
            rec.log(ent.REPORT, rr.TextDocument(report_json, media_type=rr.MediaType.TEXT), static=True)
            rows[ent.REPORT] = 1
    return rows


@contextlib.contextmanager
def streamed_to(rec, path: Path, target: Path | None = None) -> Iterator[None]:
    """``rec`` streamed to the ``.rrd`` file ``path`` while the block logs to it, flushed and
    checked after (``target``: the name for messages when ``path`` is a temporary file). Rerun's
    file sink streams chunks to disk as they are batched: a recording never sits whole in memory
    (a 12 h drive's is 180 MB). A write that fails (disk full, file size limit) ends its writer
    thread, and the flush then raises instead of waiting: a :class:`ToolFailure` in one line."""
    try:
        with utf8_alias(path) as writable:
            rec.save(writable)
        yield
        rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
    except RuntimeError as exc:  # the file sink's failures (Rerun's bindings raise RuntimeError)
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ToolFailure(f"{target or path}: write failed ({first}); is the disk full?") from None
    finally:
        rec.disconnect()
    _check_written(path, target or path)


def review_blueprint(labels: list[str], lat_deg: np.ndarray, lon_deg: np.ndarray, y_ranges: dict | None = None,
                     shown: frozenset[str] | None = None, end_s: float | None = None):
    """The review layout for estimators ``labels``, its map zoomed to the track (``lat_deg``,
    ``lon_deg``: the usable GNSS fixes), its time plots' y axes set to ``y_ranges`` when given,
    with the optional views ``shown``, its time views framed for a drive ending at ``end_s``
    (:func:`~ionav_viz.viz.blueprints.blueprint`)."""
    return blueprint(labels, map_zoom(lat_deg, lon_deg, 350), y_ranges, shown, end_s)


def y_ranges(result: DriveResult) -> dict[str, tuple[float, float]]:
    """Each time plot's data range over the whole drive (:func:`~ionav_viz.viz.blueprints.plot_range`
    without padding: a flat line still gets ticks; the blueprint widens it to labelled ticks): the
    signals, and the errors of the synthetic outages (the position error's with the log's own
    losses' final errors). The web page's plots show the whole drive, so its worst outage sets the
    error plots' range, as the viewer's own fit would (screenshots set every plot's range to what
    they show)."""
    from ..analysis.metrics import cumulative_errors

    drive, w = result.drive, result.windows
    ok = w.truth_ok
    data = {
        ent.DISPLACEMENTS: [w.gnss_disp_m[ok], *(e.disp_m for e in result.estimates.values())],
        ent.YAW_RATES: [drive.yaw_rate_radps, w.gnss_yaw_rate_radps[ok],
                        *(e.yaw_rate_radps for e in result.estimates.values())],
        ent.ACCEL: [drive.accel_long_mps2],
    }
    if len(result.starts):
        for est in result.estimates.values():
            for metric, values in cumulative_errors(w, result.starts, result.n_windows, est).items():
                data.setdefault(ent.error_group(metric), []).append(values)
    if result.bridged:
        data.setdefault(ent.error_group("position_error_m"), []).append(
            [v for b in result.bridged for v in b.final_error_m.values()])
    out = {}
    for origin, parts in data.items():
        values = np.concatenate([np.asarray(v, dtype=np.float64).ravel() for v in parts])
        values = values[np.isfinite(values)]
        out[origin] = plot_range(origin, *((float(values.min()), float(values.max())) if len(values) else (0.0, 0.0)),
                                 pad=False)
    return out


def key_markdown(result: DriveResult, colors: dict, labels: dict[str, str], manoeuvres: bool = False) -> str:
    """Which colour is which line, in words (the viewer's ``key`` above the signals; its plots
    show no legend): the truth, each estimator (the baseline first), the sensors and, where an
    estimator gives a covariance, its 95 % ellipses (drawn in synthetic outages only: a run through
    the log's own GNSS losses alone has none), and the drive views' dots: the ``manoeuvres`` where
    there are some, the outage starts."""
    from ..experiment.registry import BASELINE

    names = sorted(result.estimates, key=lambda n: (n != BASELINE, labels[n]))
    items = [f"{labels[n]} {color_word(colors[n])}" for n in ("gnss", *names)] + [f"{GYRO_LABEL}, accelerometer grey"]
    if result.drive.has_reference:  # the receiver's own fixes beside the reference (the truth)
        items.append("receiver fixes pale green dots")
    if len(result.starts) and any(getattr(e, "pos_cov_m2", None) is not None for e in result.estimates.values()):
        items.append("outlines: 95 % ellipses")
    starts = ["outage starts"] * bool(len(result.starts)) + ["first fixes after real losses"] * bool(result.bridged)
    dots = ["manoeuvres pale yellow"] * manoeuvres + [f"{' and '.join(starts)} grey"] * bool(starts)
    if dots:
        items.append("dots: " + ", ".join(dots))
    return " · ".join(items) + "\n"


def log_result(rec, result: DriveResult, summary_md: str, progress=None, events: list | None = None) -> dict[str, int]:
    """Log everything about ``result`` to the recording stream ``rec`` (any sink: memory, a viewer,
    a server). Returns row counts per entity."""
    import rerun as rr

    drive = result.drive
    tod = drive.start_time_of_day_s
    usable = usable_fixes(drive.gnss_fault)
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
    layers = Layers(rec, send, lat0, lon0, truth_ll, truth_xy, usable)

    colors = {**estimator_colors(result.estimators), "gnss": GNSS_COLOR, "gyro": GYRO_COLOR}
    labels = {**{e.name: e.label for e in result.estimators},
              "gnss": REFERENCE_LABEL if drive.has_reference else GNSS_LABEL, "gyro": GYRO_LABEL}
    _log_series_styles(rec, list(result.estimates), colors, labels)
    rec.log(ent.KEY,
            rr.TextDocument(key_markdown(result, colors, labels, bool(events)), media_type=rr.MediaType.MARKDOWN),
            static=True)
    rows[ent.KEY] = 1
    _log_static_layers(layers, drive, summary_md)
    step("static layers")
    _log_signals(layers, drive)
    step("signals")
    t_end, idx = _log_outage_states(rec, send, result)
    step("outages")
    if events:
        log_events(layers, events, drive)

    starts = result.starts
    if len(starts):
        # every estimate's tracks in the local frame, (seq, win+1, 2): projected once
        tracks_xy = {name: screen_xy(*local_en_m(e.track.lat_deg, e.track.lon_deg, lat0, lon0))
                     for name, e in result.estimates.items()}
        log_outage_frames(layers, result, tracks_xy)
        t_win = t_end[idx].ravel()
        t_rows = _outage_times(result.windows.t0_s[starts], t_win.reshape(len(starts), result.n_windows))
        log_uncertainty_styles(rec, result, colors, labels)
        stack = outage_stacking(result)
        for name, est in result.estimates.items():
            _log_estimate(layers, result, name, est, colors[name], tracks_xy[name], t_rows, t_end[idx], stack[name])
            log_uncertainty(layers, result, name, est, colors[name], tracks_xy[name], t_rows, t_end[idx])
            step(name)
        _log_truth_position(layers, result, t_rows)
        log_drift(layers, result, colors, t_rows)
    if result.bridged:
        log_real_outages(layers, result, colors, labels)
        step("real GNSS outages")
    health = log_health(layers, result, labels)
    # sent last: the layout shows only the views that got data (no empty CRSE plots in a run through real losses alone)
    synthetic = len(starts) > 0
    shown = {ent.DRIFT: synthetic, ent.error_group("crse_m"): synthetic, ent.HEALTH: health,
             ent.UNCERTAINTY: synthetic and any(e.pos_cov_m2 is not None for e in result.estimates.values())}
    rec.send_blueprint(review_blueprint([e.label for e in result.estimators], drive.lat_deg[usable],
                                        drive.lon_deg[usable], y_ranges(result),
                                        frozenset(k for k, v in shown.items() if v), float(drive.t_s[-1])))
    return rows


def _log_series_styles(rec, estimators: list[str], colors: dict, labels: dict[str, str]) -> None:
    """Each time series' colour, name and width, logged once as static."""
    import rerun as rr

    for est in ["gyro", "gnss", *estimators]:
        rec.log(ent.yaw_rate(est), rr.SeriesLines(colors=[colors[est]], names=[labels[est]], widths=[1.5]), static=True)
    for est in ["gnss", *estimators]:
        rec.log(ent.displacement(est), rr.SeriesLines(colors=[colors[est]], names=[labels[est]], widths=[1.5]),
                static=True)
    for est in estimators:
        for metric in ent.ERROR_METRICS:
            rec.log(ent.error_series(metric, est),
                    rr.SeriesLines(colors=[colors[est]], names=[labels[est]], widths=[2.0]), static=True)
    rec.log(ent.ACCEL, rr.SeriesLines(colors=[GYRO_COLOR], names=["accelerometer"]), static=True)
    rec.log(ent.SPEED, rr.SeriesLines(colors=[GNSS_COLOR], names=["GNSS speed"]), static=True)
    rec.log(ent.GNSS_AVAILABLE, rr.SeriesLines(colors=[GNSS_COLOR], names=["GNSS available"]), static=True)


def _log_static_layers(layers: Layers, drive, summary_md: str) -> None:
    """The whole drive's truth (its bad stretches apart), the grid, the receiver's fixes beside a
    reference, and the summary: static, once."""
    import rerun as rr

    rec, truth_ll, truth_xy, usable = layers.rec, layers.truth_ll, layers.truth_xy, layers.usable
    good_runs, bad_runs = truth_runs(drive.gnss_ok, usable)
    # The truth is drawn wide underneath, the overview layers thin, the growing tracks wide on top.
    # The whole drive's truth is faint: the current outage's (``*/gnss/outage``) is drawn wide on top.
    rec.log(ent.truth(ent.MAP), rr.GeoLineStrings(lat_lon=[truth_ll[a:b] for a, b in good_runs],
                                                  colors=[faded(GNSS_COLOR, 0.6)], radii=rr.Radius.ui_points(2.5)),
            static=True)
    rec.log(ent.truth(ent.LOCAL), rr.LineStrips2D([truth_xy[a:b] for a, b in good_runs],
                                                  colors=[faded(GNSS_COLOR, 0.6)], radii=rr.Radius.ui_points(2.5),
                                                  draw_order=10), static=True)
    log_grid(rec, truth_xy[usable])
    if bad_runs:
        rec.log(ent.truth_bad(ent.MAP), rr.GeoLineStrings(lat_lon=[truth_ll[a:b] for a, b in bad_runs],
                                                          colors=[BAD_GNSS_COLOR], radii=rr.Radius.ui_points(1.5)),
                static=True)
        rec.log(ent.truth_bad(ent.LOCAL), rr.LineStrips2D([truth_xy[a:b] for a, b in bad_runs], colors=[BAD_GNSS_COLOR],
                                                  radii=rr.Radius.ui_points(1.5), draw_order=11), static=True)
    if drive.has_reference:  # the receiver's fixes the estimators were given, as small dots beside the truth
        rx_ll = np.column_stack([drive.columns["gnss_lat_deg"], drive.columns["gnss_lon_deg"]])
        rx_east, rx_north = local_en_m(rx_ll[:, 0], rx_ll[:, 1], layers.lat0, layers.lon0)
        rec.log(ent.receiver(ent.MAP),
                rr.GeoPoints(lat_lon=rx_ll[usable], colors=[RECEIVER_COLOR], radii=rr.Radius.ui_points(1.5)),
                static=True)
        rec.log(ent.receiver(ent.LOCAL), rr.Points2D(screen_xy(rx_east, rx_north)[usable], colors=[RECEIVER_COLOR],
                                                     radii=rr.Radius.ui_points(1.5), draw_order=9), static=True)
    rec.log(ent.SUMMARY, rr.TextDocument(summary_md, media_type=rr.MediaType.MARKDOWN), static=True)


def _log_signals(layers: Layers, drive) -> None:
    """Per-sample series: the truth's current position, the GNSS quality, the sensors and the speed."""
    import rerun as rr

    send, usable = layers.send, layers.usable
    t = drive.t_s
    tu, nu = t[usable], int(usable.sum())
    send(ent.truth_position(ent.MAP), tu, rr.GeoPoints.columns(positions=layers.truth_ll[usable],
                                                               colors=np.tile(GNSS_COLOR, (nu, 1)),
                                                               radii=np.full(nu, -6.0)))
    send(ent.truth_position(ent.LOCAL), tu, rr.Points2D.columns(positions=layers.truth_xy[usable],
                                                                colors=np.tile(GNSS_COLOR, (nu, 1)),
                                                                radii=np.full(nu, -TRUTH_DOT_PT),
                                                                draw_order=np.full(nu, TRUTH_END_ORDER)))
    quality = _quality_states(drive.gnss_fault)
    change = np.concatenate([[True], quality[1:] != quality[:-1]])
    log_state_lane(layers.rec, send, ent.GNSS_QUALITY, [str(q) for q in quality[change]], t[change], float(t[-1]),
                   ruler_end_s(float(t[-1])))
    send(ent.ACCEL, t, rr.Scalars.columns(scalars=drive.accel_long_mps2))
    send(ent.yaw_rate("gyro"), t, rr.Scalars.columns(scalars=drive.yaw_rate_radps))
    send(ent.SPEED, t, rr.Scalars.columns(scalars=drive.speed_mps))


def _log_outage_states(rec, send, result: DriveResult) -> tuple[np.ndarray, np.ndarray]:
    """Per window: the GNSS truth's displacement and yaw rate, GNSS availability and the outage
    state (and, beside a reference, where the receiver lost the sky outside the outages). Returns
    each window's end time and the outage windows' indices (outage, window)."""
    import rerun as rr

    w, starts, n_win = result.windows, result.starts, result.n_windows
    t_end = w.t0_s + WINDOW_S
    # windows without trustworthy truth are not drawn (NaN breaks the line: no spike to (0, 0))
    ok = w.truth_ok
    send(ent.displacement("gnss"), t_end, rr.Scalars.columns(scalars=np.where(ok, w.gnss_disp_m, np.nan)))
    send(ent.yaw_rate("gnss"), t_end, rr.Scalars.columns(scalars=np.where(ok, w.gnss_yaw_rate_radps, np.nan)))
    available = np.ones(len(w))
    idx = starts[:, None] + np.arange(n_win)[None, :]
    available[idx.ravel()] = 0.0
    for b in result.bridged:  # the log's own GNSS losses, bridged: no GNSS there either
        available[b.start : b.start + b.n_windows] = 0.0
    t_state = np.concatenate([w.t0_s, [t_end[-1]]]) if len(w) else np.zeros(0)
    send(ent.GNSS_AVAILABLE, t_state,
         rr.Scalars.columns(scalars=np.concatenate([available, [available[-1]]]) if len(w) else available))
    states = np.full(len(w), ent.GNSS_AVAILABLE_STATE, dtype=object)
    for mask in np.unique(w.receiver_fault[w.receiver_fault != 0]):  # beside a reference: the estimators' GNSS lost
        states[w.receiver_fault == mask] = ent.receiver_lost_state(fault_names(int(mask)))
    for i, k in enumerate(starts):
        states[k : k + n_win] = ent.outage_state(i + 1, w.t0_s[k], w.t0_s[k] + n_win)
    for b in result.bridged:
        states[b.start : b.start + b.n_windows] = ent.real_outage_state(b.number, b.gap_t0_s, b.gap_t1_s)
    change = np.concatenate([[True], states[1:] != states[:-1]]) if len(w) else np.zeros(0, bool)
    log_state_lane(rec, send, ent.GNSS_STATE, [str(s) for s in states[change]], w.t0_s[change],
                   float(t_end[-1]) if len(w) else 0.0, ruler_end_s(float(result.drive.t_s[-1])))
    return t_end, idx


def outage_stacking(result: DriveResult) -> dict[str, np.ndarray]:
    """Each estimator's place in the draw order of each synthetic outage (:func:`~ionav_viz.viz.style.stacking`
    of its final position errors): the outage's worst estimate drawn underneath, its best on top."""
    from ..analysis.drift import boundary_errors_m

    return stacking({name: boundary_errors_m(result, name)[:, -1] for name in result.estimates})




def _log_estimate(layers: Layers, result: DriveResult, name: str, est, color, xy: np.ndarray, t_rows: np.ndarray,
                  t_windows: np.ndarray, stack: np.ndarray) -> None:
    """One estimator's tracks over the outages (growing, on the map, the local view and the
    inspector; all of them faint), its current position, and its series per window (``t_windows``:
    the end time of each outage window, (outage, window)); ``stack``: its place in each outage's
    draw order (:func:`outage_stacking`)."""
    import rerun as rr

    rec, send = layers.rec, layers.send
    ll = np.stack([est.track.lat_deg, est.track.lon_deg], axis=-1)  # (seq, win+1, 2)
    n_rows = len(t_rows)
    order = np.repeat(stack, xy.shape[1])  # per row: each outage's rows (its start, then each window's end)
    thin, wide = rr.Radius.ui_points(1.2), rr.Radius.ui_points(3.0)
    # per outage the start point alone (clears the previous outage's track), then the
    # strip of points 0..k at each window's end (rows as :func:`_outage_times`)
    send(ent.live_track(ent.MAP, name), t_rows, rr.GeoLineStrings.columns(
        line_strings=columns.geo_line_strings(*columns.growing(ll)), colors=np.tile(color, (n_rows, 1)),
        radii=np.full(n_rows, wide)))
    # stacked by the outage's errors: the worst underneath and widest, so that each track shows a rim of its colour
    radii = track_radii_pt(order, len(result.estimates))
    send(ent.live_track(ent.LOCAL, name), t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.growing(xy)), colors=np.tile(color, (n_rows, 1)), radii=radii,
        draw_order=TRACK_ORDER + order))
    rel = xy - xy[:, :1]
    send(ent.live_track(ent.INSPECT, name), t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.growing(rel)), colors=np.tile(color, (n_rows, 1)), radii=radii,
        draw_order=TRACK_ORDER + order))
    # the estimate's current position: visible where tracks along the same road cover each other
    for entity, points in ((ent.inspect_position(name), rel), (ent.local_position(name), xy)):
        send(entity, t_rows, rr.Points2D.columns(
            positions=points.reshape(-1, 2), colors=np.tile(color, (n_rows, 1)),
            radii=np.full(n_rows, rr.Radius.ui_points(END_DOT_PT)), draw_order=END_ORDER + order))
    faint = faded(color)
    rec.log(ent.all_tracks(ent.MAP, name),
            rr.GeoLineStrings(lat_lon=columns.geo_line_strings(*columns.stacked(ll)), colors=[faint], radii=thin),
            static=True)
    rec.log(ent.all_tracks(ent.LOCAL, name), rr.LineStrips2D(columns.line_strips_2d(*columns.stacked(xy)),
                                                             colors=[faint], radii=thin,
                                                             draw_order=20 + float(np.mean(stack))), static=True)
    w, starts, n_win = result.windows, result.starts, result.n_windows
    series = {ent.displacement(name): est.disp_m, ent.yaw_rate(name): est.yaw_rate_radps}
    series.update({ent.error_series(m, name): v for m, v in cumulative_errors(w, starts, n_win, est).items()})
    for entity, values in series.items():
        t_plot, v_plot = with_breaks(t_windows, values)
        send(entity, t_plot, rr.Scalars.columns(scalars=v_plot))


def _log_truth_position(layers: Layers, result: DriveResult, t_rows: np.ndarray) -> None:
    """The truth's position in the inspector at the rows of the estimates' current positions (each
    outage's start, then each window's end): where the car was when each estimate's dot was, so
    scrubbing inside an outage shows its drift so far (the inspector's truth is the whole outage's)."""
    import rerun as rr

    w, starts, n_win = result.windows, result.starts, result.n_windows
    idx = starts[:, None] + np.arange(n_win)[None, :]
    lat = np.concatenate([w.lat0_deg[idx], w.lat1_deg[idx[:, -1:]]], axis=1)  # (outage, window boundary)
    lon = np.concatenate([w.lon0_deg[idx], w.lon1_deg[idx[:, -1:]]], axis=1)
    xy = layers.xy(lat.ravel(), lon.ravel()).reshape(len(starts), n_win + 1, 2)
    n_rows = len(t_rows)
    layers.send(ent.INSPECT_TRUTH_POSITION, t_rows, rr.Points2D.columns(
        positions=(xy - xy[:, :1]).reshape(-1, 2), colors=np.tile(GNSS_COLOR, (n_rows, 1)),
        radii=np.full(n_rows, rr.Radius.ui_points(TRUTH_DOT_PT)), draw_order=np.full(n_rows, TRUTH_END_ORDER)))


def truth_runs(good: np.ndarray, usable: np.ndarray) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Index ranges ``[a, b)`` of the good stretches and of the bad-but-drawable ones of a track.

    A bad stretch also takes the good samples on either side, so the grey line joins the green.
    Unusable samples (no position) are in neither: the track is broken there.
    """
    n = len(good)
    good_runs = [(a, b) for a, b in run_ranges(good & usable) if b - a >= 2]
    bad_runs = []
    for a, b in run_ranges(~good & usable):
        a = a - 1 if a > 0 and usable[a - 1] else a
        b = b + 1 if b < n and usable[b] else b
        if b - a >= 2:
            bad_runs.append((a, b))
    return good_runs, bad_runs


def _quality_states(fault: np.ndarray) -> np.ndarray:
    """Per sample "good" or the fault names ("bad: frozen, jump")."""
    states = np.full(len(fault), ent.GOOD_TRUTH_STATE, dtype=object)
    for mask in np.unique(fault[fault != 0]):
        states[fault == mask] = ent.bad_truth_state(fault_names(int(mask)))
    return states


def usable_fixes(fault: np.ndarray) -> np.ndarray:
    """Samples whose fix is a position worth drawing (and framing views around): not at (0, 0),
    not a jump. All of them if none is."""
    usable = (fault & np.uint16(GnssFault.NEAR_ZERO | GnssFault.JUMP)) == 0
    return usable if usable.any() else np.ones(len(fault), dtype=bool)



def _check_written(path: Path, target: Path) -> None:
    """Read the file's footer back: a sink that failed silently must not pass as a recording."""
    from .recording_info import rrd_reader

    try:
        with utf8_alias(path) as readable:
            ok = len(rrd_reader(readable).recordings()) == 1
    except Exception as exc:  # the reader's errors are not one class
        raise ToolFailure(f"{target}: the written recording does not read back "
                          f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); is the disk full?"
                          ) from None
    if not ok:
        raise ToolFailure(f"{target}: the written recording holds no recording; is the disk full?")
