"""The layers that frame each outage and mark events in a recording: the outage inspector, the
outage's truth and scale bars, the drive's grid, the tracks through the log's own GNSS losses, and
the detected events (:func:`ionav_viz.viz.recording.log_result` logs the rest)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..analysis.evaluate import DriveResult
from ..core.geo import local_en_m
from . import columns
from . import entities as ent
from .geometry import grid_strips, nice_step, padded_bounds, scale_bar, scale_bar_clear_of, scale_label, screen_xy
from .style import (
    EVENT_COLOR,
    EVENT_STATE_COLORS,
    GNSS_COLOR,
    GRID_COLOR,
    OUTAGE_MARK_COLOR,
    SCALE_COLOR,
    STATE_COLORS,
    faded,
    stacking,
)

#: Draw orders of the 2D views' marks: an estimator's mark adds its place in the stack of the
#: outage (:func:`~ionav_viz.viz.style.stacking`, in [0, 1)) to its kind's: tracks, then the truth's
#: end (a wide dot: a ring around an estimate's end on it), then the estimates' ends.
TRACK_ORDER, TRUTH_END_ORDER, END_ORDER = 30.0, 35.0, 40.0
#: Sizes (ui points) of the estimates' end dots and of the truth's, a ring around theirs.
END_DOT_PT, TRUTH_DOT_PT = 5.0, 8.5
#: The current outage's tracks (radius, ui points): the best estimate's, and what each one below it
#: in the stack adds, so that tracks along one line show as nested bands, each a rim of its colour.
TRACK_PT, RIM_PT = 2.0, 1.0
#: The current outage's truth, underneath: wider than five stacked tracks.
TRUTH_TRACK_PT = 6.5
#: The inspector's scale bar: this share of its frame's height above the frame's bottom, so that its
#: label (below it) is not cut at the view's edge where the frame fills the view's height (the
#: web page's inspector is 366 px high at 1280x720: 0.05 left 18 px, "20 m" cut in half).
INSPECT_SCALE_ABOVE = 0.09


def track_radii_pt(stack: np.ndarray, n_estimators: int) -> np.ndarray:
    """Radii (ui points, as Rerun takes them: negative) of tracks at places ``stack`` in the draw
    order (:func:`~ionav_viz.viz.style.stacking`: 0 the worst, underneath): the best :data:`TRACK_PT`,
    each one below it :data:`RIM_PT` wider, so a track wholly under others still shows its rim."""
    below = (n_estimators - 1) - np.rint(np.asarray(stack, dtype=float) * n_estimators)
    return -(TRACK_PT + RIM_PT * below)


def real_stacking(result: DriveResult) -> dict[str, np.ndarray]:
    """Each estimator's place in the draw order of each of the log's own GNSS losses
    (:func:`~ionav_viz.viz.style.stacking` of its final errors there)."""
    return stacking({e.name: np.array([b.final_error_m.get(e.name, np.nan) for b in result.bridged])
                     for e in result.estimators})

#: Seconds of GNSS track before and after an outage drawn faintly around it on the map.
CONTEXT_S = 3.0




@dataclass
class Layers:
    """What every layer of one recording is logged with: the stream and its ``send`` (columns on the
    time lines, row counts kept), and the drive's local frame (origin at the first usable fix)."""

    rec: Any
    send: Callable[[str, np.ndarray, Any], None]
    lat0: float
    lon0: float
    truth_ll: np.ndarray  # every sample's fix (lat, lon)
    truth_xy: np.ndarray  # the same in the local view's screen frame (m)
    usable: np.ndarray  # samples whose fix is worth drawing (:func:`usable_fixes`)

    def xy(self, lat_deg: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
        """Positions in the local view's screen frame (m)."""
        return screen_xy(*local_en_m(lat_deg, lon_deg, self.lat0, self.lon0))


def state_color(state: str) -> tuple[int, int, int]:
    """A state lane's colour (:data:`~ionav_viz.viz.style.STATE_COLORS`): never an estimator's; one
    per kind of state (every span's value of it alike, :func:`~ionav_viz.viz.entities.base_state`)."""
    state = ent.base_state(state)
    if (n := ent.parse_outage_state(state)) is not None:
        return STATE_COLORS["outage" if n % 2 else "outage alt"]
    if ent.parse_real_outage_state(state) is not None:
        return STATE_COLORS["real outage"]
    if state.startswith("receiver "):
        return STATE_COLORS["receiver"]
    if state.startswith("bad: "):
        return STATE_COLORS["bad"]
    if state in (ent.GNSS_AVAILABLE_STATE, ent.GOOD_TRUTH_STATE, ent.NO_EVENT_STATE):
        return STATE_COLORS[{ent.GNSS_AVAILABLE_STATE: "GNSS", ent.GOOD_TRUTH_STATE: "good",
                             ent.NO_EVENT_STATE: "none"}[state]]
    return EVENT_STATE_COLORS.get(state.rpartition(" #")[0], EVENT_COLOR)


def log_state_lane(rec, send, entity: str, states: list[str], t_s: np.ndarray, end_s: float,
                   ruler_s: float | None = None) -> None:
    """The state lane ``entity``: ``states``, each from its time of ``t_s`` on (the last until
    ``end_s``, where an empty state ends it), sent as state changes, and each value's colour
    (:func:`state_color`, one per kind) and label, static. With ``ruler_s`` after ``end_s``, a second
    empty state there: the recording's last time, where the state timeline's ruler ends
    (:func:`~ionav_viz.viz.blueprints.ruler_end_s`). A state that several spans share gets a value per span
    (:func:`~ionav_viz.viz.entities.span_state`): the viewer gives a value one label, and each span's
    label is the longest of :func:`~ionav_viz.viz.entities.state_labels` that fits that span in the
    lane's default view (:func:`~ionav_viz.viz.blueprints.state_label_fits`; one short ``bad`` span
    made every ``bad`` span's label blank), else one whole wherever the viewer draws it
    (:func:`~ionav_viz.viz.blueprints.state_label_whole_anywhere`: ``28``, which the hover shows)."""
    import pyarrow as pa
    import rerun as rr

    from .blueprints import state_label_fits, state_label_whole_anywhere

    t = np.asarray(t_s, dtype=np.float64)
    ends = np.append(t[1:], max(float(end_s), float(t[-1]) if len(t) else 0.0))
    shared = _shared(states)
    values = [ent.span_state(s, a, b) if s in shared else s for s, a, b in zip(states, t, ends)]
    shortest: dict[str, float] = {}  # a value's shortest span (two spans' values alike when rounded: the shorter's)
    for value, span in zip(values, ends - t):
        shortest[value] = min(shortest.get(value, np.inf), float(span))
    names = list(shortest)
    labels = [ent.state_label(v, lambda label, v=v: state_label_fits(label, shortest[v], end_s),
                              state_label_whole_anywhere) for v in names]
    rec.log(entity, rr.StateConfiguration(values=names, labels=labels,
                                          colors=[state_color(v) for v in names]), static=True)
    # empty states (nulls: a gap in the lane) end the last span at the drive's end, not open-ended past it
    ends_s = [float(ends[-1])] if len(t) else []
    if ruler_s is not None and ends_s and ruler_s > ends_s[0]:
        ends_s.append(float(ruler_s))
    times_s, values = with_merge_breaks(t, values)
    send(entity, np.append(times_s, ends_s),
         rr.StateChange.columns(state=pa.array(values + [None] * len(ends_s), pa.utf8())))


#: How long before a span's end the empty state that keeps it apart from the next one starts (s):
#: :func:`with_merge_breaks`.
MERGE_BREAK_S = 1e-3


def with_merge_breaks(t_s: np.ndarray, values: list) -> tuple[np.ndarray, list]:
    """State changes ``values`` at times ``t_s`` (s, ascending), each span ended
    :data:`MERGE_BREAK_S` before the next one starts by an empty state (None). Rerun 0.41's state
    timeline folds runs of consecutive spans under 4 px into one grey block labelled "N states", cut
    where the block is narrower than that label ("13 sta" of sharp-cornering's manoeuvres at
    1024x576); an empty state ends such a run, so each span is drawn alone, in its own colour, and
    labelled only where its label fits. The breaks are far under a pixel at any zoom the drive's
    length allows, and a span shorter than 4 breaks keeps its end."""
    t = np.asarray(t_s, dtype=np.float64)
    if len(t) < 2:
        return t, list(values)
    gap = np.diff(t)
    breaks = gap > 4 * MERGE_BREAK_S
    out_t = np.concatenate([t, t[1:][breaks] - MERGE_BREAK_S])
    out_v = list(values) + [None] * int(breaks.sum())
    order = np.argsort(out_t, kind="stable")
    return out_t[order], [out_v[k] for k in order]


def _shared(states: list[str]) -> set[str]:
    """The states that occur more than once in ``states``."""
    from collections import Counter

    return {s for s, n in Counter(states).items() if n > 1}


def log_outage_frames(layers: Layers, result: DriveResult, tracks_xy: dict[str, np.ndarray]) -> None:
    """What frames each outage: its GNSS track (wide, on top of the faint whole drive), the outage
    inspector (everything in metres from the fix at the outage start, with a grid and a scale bar)
    and the outage start markers."""
    import rerun as rr

    rec, send, truth_xy, truth_ll, usable = layers.rec, layers.send, layers.truth_xy, layers.truth_ll, layers.usable
    drive, w, starts, n_win = result.drive, result.windows, result.starts, result.n_windows
    t0 = w.t0_s[starts]
    t_rows = t0 + ent.OUTAGE_EPS_S
    n = len(starts)
    last = starts + n_win - 1
    start_ll = np.stack([w.lat0_deg[starts], w.lon0_deg[starts]], axis=-1)
    end_ll = np.stack([w.lat1_deg[last], w.lon1_deg[last]], axis=-1)
    start_xy = layers.xy(start_ll[:, 0], start_ll[:, 1])
    end_xy = layers.xy(end_ll[:, 0], end_ll[:, 1])
    ti = np.flatnonzero(usable)
    # the fixes inside the outage, between its start and end on the windows' grid (what metrics score)
    a = np.searchsorted(drive.t_s[ti], t0, side="right")
    b = np.searchsorted(drive.t_s[ti], t0 + n_win, side="left")
    ca = np.searchsorted(drive.t_s[ti], t0 - CONTEXT_S, side="left")
    cb = np.searchsorted(drive.t_s[ti], t0 + n_win + CONTEXT_S, side="right")
    truth = [np.concatenate([start_xy[k : k + 1], truth_xy[ti[i:j]], end_xy[k : k + 1]])
             for k, (i, j) in enumerate(zip(a, b))]
    truth_geo = [np.concatenate([start_ll[k : k + 1], truth_ll[ti[i:j]], end_ll[k : k + 1]])
                 for k, (i, j) in enumerate(zip(a, b))]
    wide = rr.Radius.ui_points(TRUTH_TRACK_PT)
    send(ent.outage_truth(ent.LOCAL), t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged(truth)), colors=np.tile(GNSS_COLOR, (n, 1)),
        radii=np.full(n, wide), draw_order=np.full(n, 12.0)))
    send(ent.outage_truth(ent.MAP), t_rows, rr.GeoLineStrings.columns(
        line_strings=columns.geo_line_strings(*columns.ragged(truth_geo)), colors=np.tile(GNSS_COLOR, (n, 1)),
        radii=np.full(n, wide)))
    send(ent.MAP_CONTEXT, t_rows, rr.GeoLineStrings.columns(
        line_strings=columns.geo_line_strings(*columns.ragged([truth_ll[ti[i:j]] for i, j in zip(ca, cb)])),
        colors=np.tile(faded(GNSS_COLOR), (n, 1)), radii=np.full(n, rr.Radius.ui_points(2.0))))
    send(ent.outage_truth(ent.INSPECT), t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged([tr - s for tr, s in zip(truth, start_xy)])),
        colors=np.tile(GNSS_COLOR, (n, 1)), radii=np.full(n, wide), draw_order=np.full(n, 12.0)))

    # Each outage's frame: its truth and every estimate, padded; a grid and a scale bar to match.
    bounds = []
    for i in range(n):
        pts = np.concatenate([truth[i], *(t[i] for t in tracks_xy.values()), start_xy[i : i + 1]])
        bounds.append(padded_bounds(pts - start_xy[i]))
    steps = [nice_step(max(bx[1] - bx[0], bx[3] - bx[2])) for bx in bounds]
    grids = [grid_strips(bx, st) for bx, st in zip(bounds, steps)]
    send(ent.INSPECT_GRID, t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged([g for grid in grids for g in grid])),
        colors=np.tile(GRID_COLOR, (sum(map(len, grids)), 1)),
        radii=np.full(sum(map(len, grids)), rr.Radius.ui_points(0.8)),
        draw_order=np.full(sum(map(len, grids)), 1.0)).partition([len(g) for g in grids]))
    send(ent.INSPECT_SCALE, t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged([scale_bar(bx, st, INSPECT_SCALE_ABOVE)
                                                       for bx, st in zip(bounds, steps)])),
        labels=[scale_label(st) for st in steps],
        colors=np.tile(SCALE_COLOR, (n, 1)), radii=np.full(n, rr.Radius.ui_points(2.0)), draw_order=np.full(n, 50.0)))
    local_bounds = [(bx[0] + s[0], bx[1] + s[0], bx[2] + s[1], bx[3] + s[1]) for bx, s in zip(bounds, start_xy)]
    send(ent.LOCAL_SCALE, t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged([scale_bar(bx, st) for bx, st in zip(local_bounds, steps)])),
        labels=[scale_label(st) for st in steps], colors=np.tile(SCALE_COLOR, (n, 1)),
        radii=np.full(n, rr.Radius.ui_points(2.0)), draw_order=np.full(n, 50.0)))
    rec.log(ent.INSPECT_START,
            rr.Points2D([[0.0, 0.0]], colors=[OUTAGE_MARK_COLOR], radii=rr.Radius.ui_points(5.0), draw_order=45),
            static=True)
    rec.log(ent.LOCAL_OUTAGES, rr.Points2D(start_xy, labels=[f"outage {i + 1}" for i in range(n)], show_labels=False,
                                         colors=[OUTAGE_MARK_COLOR], radii=rr.Radius.ui_points(3.0), draw_order=25),
            static=True)


def log_grid(rec, xy: np.ndarray) -> None:
    """A static grid and scale bar over the whole drive in the local view."""
    import rerun as rr

    bounds = padded_bounds(xy, margin=0.02)
    step = nice_step(max(bounds[1] - bounds[0], bounds[3] - bounds[2]), lines=8)
    # the whole drive's view is small in the review layout (200 px at 1024x576): room for the label below the bar;
    # the bounds hug the drive, so the bar goes to a corner the track leaves free (else below it)
    bar, bounds = scale_bar_clear_of(bounds, step, xy, above=0.09)
    grid = grid_strips(bounds, step)
    rec.log(ent.LOCAL_GRID, rr.LineStrips2D(grid, colors=[GRID_COLOR], radii=rr.Radius.ui_points(0.8), draw_order=1),
            static=True)
    rec.log(ent.LOCAL_GRID_SCALE, rr.LineStrips2D([bar], labels=[scale_label(step)], colors=[SCALE_COLOR],
                                                radii=rr.Radius.ui_points(2.0), draw_order=50), static=True)


def log_real_outages(layers: Layers, result: DriveResult, colors: dict, labels: dict) -> None:
    """The log's own GNSS outages: each estimator's track through them (wide, on top), the first
    good fix after each (the truth that scores them) and each final error on the error timeline;
    from each loss's start on, what frames it (:func:`_log_current_real_outage`) and the inspector
    (:func:`_log_real_outages_inspected`)."""
    import rerun as rr

    rec, send = layers.rec, layers.send
    bridged = result.bridged
    end_ll = np.array([[b.end_lat_deg, b.end_lon_deg] for b in bridged])
    rec.log(ent.end_fixes(ent.MAP),
            rr.GeoPoints(lat_lon=end_ll, colors=[OUTAGE_MARK_COLOR], radii=rr.Radius.ui_points(6.0)), static=True)
    rec.log(ent.end_fixes(ent.LOCAL), rr.Points2D(layers.xy(end_ll[:, 0], end_ll[:, 1]), colors=[OUTAGE_MARK_COLOR],
                                                  radii=rr.Radius.ui_points(5.0), draw_order=40), static=True)
    t1 = np.array([b.t1_s for b in bridged])
    # every estimator's track through each loss, on the map and in the local frame (one projection per estimator)
    tracks_ll, tracks_xy = {}, {}
    stack = real_stacking(result)
    for est in result.estimators:
        name, color = est.name, colors[est.name]
        ll = [np.stack([b.tracks[name].lat_deg[0], b.tracks[name].lon_deg[0]], axis=-1) for b in bridged]
        tracks_ll[name], tracks_xy[name] = ll, np.split(layers.xy(*np.concatenate(ll).T),
                                                        np.cumsum([len(x) for x in ll])[:-1])
        rec.log(ent.real_outage_tracks(ent.MAP, name),
                rr.GeoLineStrings(lat_lon=ll, colors=[color], radii=rr.Radius.ui_points(3.0)), static=True)
        rec.log(ent.real_outage_tracks(ent.LOCAL, name), rr.LineStrips2D(
            tracks_xy[name], colors=[color], draw_order=TRACK_ORDER + float(np.mean(stack[name])),
            radii=track_radii_pt(stack[name], len(result.estimators))), static=True)
        entity = ent.real_outage_errors(name)
        rec.log(entity, rr.SeriesPoints(colors=[color], names=[f"{labels[name]} (real outages)"], marker_sizes=[6.0]),
                static=True)
        send(entity, t1, rr.Scalars.columns(scalars=[b.final_error_m[name] for b in bridged]))
        # its displacement and yaw rate through each loss in the signals' plots (a break before and after each)
        parts = [b.window_signals(name) for b in bridged]
        t_s = np.concatenate([np.concatenate([[t[0] - 0.5], t, [t[-1] + 0.5]]) for t, _, _ in parts])
        for series, k in ((ent.displacement(name), 1), (ent.yaw_rate(name), 2)):
            values = np.concatenate([np.concatenate([[np.nan], p[k], [np.nan]]) for p in parts])
            send(series, t_s, rr.Scalars.columns(scalars=values))
    t_rows = np.array([b.t0_s for b in bridged]) + ent.OUTAGE_EPS_S
    _log_current_real_outage(layers, result, colors, tracks_ll, tracks_xy, t_rows)
    _log_real_outages_inspected(layers, result, colors, tracks_xy, t_rows)


def _log_current_real_outage(layers: Layers, result: DriveResult, colors: dict, tracks_ll: dict[str, list[np.ndarray]],
                             tracks_xy: dict[str, list[np.ndarray]], t_rows: np.ndarray) -> None:
    """:data:`~ionav_viz.viz.entities.REAL_OUTAGE_CURRENT` (rows ``t_rows``, each loss's start): the
    good fixes :data:`CONTEXT_S` before and after it (faint) and every estimator's track through it
    (``tracks_ll``, per estimator one (lat, lon) array per loss); the local view's scale bar for it,
    as a synthetic outage's (:func:`log_outage_frames`), from the tracks in the local frame ``tracks_xy``."""
    import rerun as rr

    bridged, t = result.bridged, result.drive.t_s
    ti = np.flatnonzero(layers.usable)
    rows, rgb, bars, steps = [], [], [], []
    for i, b in enumerate(bridged):
        before = ti[(t[ti] >= b.gap_t0_s - CONTEXT_S) & (t[ti] <= b.gap_t0_s)]
        after = ti[(t[ti] >= b.gap_t1_s) & (t[ti] <= b.gap_t1_s + CONTEXT_S)]
        rows.append([layers.truth_ll[before], layers.truth_ll[after],
                     *(tracks_ll[e.name][i] for e in result.estimators)])
        rgb += [faded(GNSS_COLOR), faded(GNSS_COLOR)] + [colors[e.name] for e in result.estimators]
        end = layers.xy(np.array([b.end_lat_deg]), np.array([b.end_lon_deg]))
        bounds = padded_bounds(np.concatenate([*(tracks_xy[e.name][i] for e in result.estimators), end]))
        steps.append(nice_step(max(bounds[1] - bounds[0], bounds[3] - bounds[2])))
        bars.append(scale_bar(bounds, steps[-1]))
    flat = [s for strips in rows for s in strips]
    n, m = len(flat), len(bridged)
    layers.send(ent.REAL_OUTAGE_CURRENT, t_rows, rr.GeoLineStrings.columns(
        line_strings=columns.geo_line_strings(*columns.ragged(flat)), colors=np.asarray(rgb),
        radii=np.full(n, rr.Radius.ui_points(3.0))).partition([len(strips) for strips in rows]))
    layers.send(ent.LOCAL_SCALE, t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged(bars)), labels=[scale_label(st) for st in steps],
        colors=np.tile(SCALE_COLOR, (m, 1)), radii=np.full(m, rr.Radius.ui_points(2.0)), draw_order=np.full(m, 50.0)))


def _log_real_outages_inspected(layers: Layers, result: DriveResult, colors: dict,
                                tracks_xy: dict[str, list[np.ndarray]], t_rows: np.ndarray) -> None:
    """The outage inspector from each real loss's start (rows ``t_rows``) on, as for a synthetic
    outage (:func:`log_outage_frames`): in metres from its start fix (where the tracks ``tracks_xy``
    start), the good fixes :data:`CONTEXT_S` before it and from the first good fix after it, every
    estimator's whole track through it, a grid and a scale bar; a synthetic outage's current
    positions and ellipses cleared."""
    import rerun as rr

    bridged, t, send = result.bridged, result.drive.t_s, layers.send
    ti = np.flatnonzero(layers.usable)
    m = len(bridged)
    truth, tracks, grids, bars, steps = [], {e.name: [] for e in result.estimators}, [], [], []
    for i, b in enumerate(bridged):
        start = tracks_xy[result.estimators[0].name][i][0]  # every track starts on the start fix
        # the fixes up to the start fix and on from the end fix (the outage runs from and to window boundaries)
        before = ti[(t[ti] >= b.t0_s - CONTEXT_S) & (t[ti] < b.t0_s)]
        after = ti[(t[ti] > b.t1_s) & (t[ti] <= b.t1_s + CONTEXT_S)]
        end = layers.xy(np.array([b.end_lat_deg]), np.array([b.end_lon_deg]))
        truth.append([np.concatenate([layers.truth_xy[before] - start, np.zeros((1, 2))]),
                      np.concatenate([end, layers.truth_xy[after]]) - start])
        for e in result.estimators:
            tracks[e.name].append(tracks_xy[e.name][i] - start)
        bounds = padded_bounds(np.concatenate([*truth[-1], *(tr[-1] for tr in tracks.values()), np.zeros((1, 2))]))
        steps.append(nice_step(max(bounds[1] - bounds[0], bounds[3] - bounds[2])))
        grids.append(grid_strips(bounds, steps[-1]))
        bars.append(scale_bar(bounds, steps[-1], INSPECT_SCALE_ABOVE))
    wide = rr.Radius.ui_points(TRUTH_TRACK_PT)
    send(ent.outage_truth(ent.INSPECT), t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged([s for pair in truth for s in pair])),
        colors=np.tile(GNSS_COLOR, (2 * m, 1)), radii=np.full(2 * m, wide),
        draw_order=np.full(2 * m, 12.0)).partition(np.full(m, 2)))
    stack = real_stacking(result)
    for e in result.estimators:
        color = np.tile(colors[e.name], (m, 1))
        send(ent.live_track(ent.INSPECT, e.name), t_rows, rr.LineStrips2D.columns(
            strips=columns.line_strips_2d(*columns.ragged(tracks[e.name])), colors=color,
            radii=track_radii_pt(stack[e.name], len(result.estimators)), draw_order=TRACK_ORDER + stack[e.name]))
        # each estimate's end, a dot: where tracks along one road cover each other, how far each went
        ends = np.array([tr[-1] for tr in tracks[e.name]])
        send(ent.inspect_position(e.name), t_rows, rr.Points2D.columns(
            positions=ends, colors=color, radii=np.full(m, rr.Radius.ui_points(END_DOT_PT)),
            draw_order=END_ORDER + stack[e.name]))
        send(ent.local_position(e.name), t_rows, rr.Points2D.columns(
            positions=np.array([tracks_xy[e.name][i][-1] for i in range(m)]), colors=color,
            radii=np.full(m, rr.Radius.ui_points(END_DOT_PT)), draw_order=END_ORDER + stack[e.name]))
        # a synthetic outage's ellipse, drawn before: emptied
        if len(result.starts) and result.estimates[e.name].pos_cov_m2 is not None:
            send(ent.ellipse(ent.INSPECT, e.name), t_rows, rr.LineStrips2D.columns(
                strips=columns.line_strips_2d(np.zeros((0, 2)), np.zeros(1, dtype=int))
            ).partition(np.zeros(m, dtype=int)))
    # the truth's end (the first good fix after the loss), a wide dot under the estimates' ends
    send(ent.INSPECT_TRUTH_POSITION, t_rows, rr.Points2D.columns(
        positions=np.array([pair[1][0] for pair in truth]), colors=np.tile(GNSS_COLOR, (m, 1)),
        radii=np.full(m, rr.Radius.ui_points(TRUTH_DOT_PT)), draw_order=np.full(m, TRUTH_END_ORDER)))
    count = sum(map(len, grids))
    send(ent.INSPECT_GRID, t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged([g for grid in grids for g in grid])),
        colors=np.tile(GRID_COLOR, (count, 1)), radii=np.full(count, rr.Radius.ui_points(0.8)),
        draw_order=np.full(count, 1.0)).partition([len(g) for g in grids]))
    send(ent.INSPECT_SCALE, t_rows, rr.LineStrips2D.columns(
        strips=columns.line_strips_2d(*columns.ragged(bars)), labels=[scale_label(st) for st in steps],
        colors=np.tile(SCALE_COLOR, (m, 1)), radii=np.full(m, rr.Radius.ui_points(2.0)), draw_order=np.full(m, 50.0)))
    layers.rec.log(ent.INSPECT_START,
                   rr.Points2D([[0.0, 0.0]], colors=[OUTAGE_MARK_COLOR], radii=rr.Radius.ui_points(5.0), draw_order=45),
                   static=True)


def log_events(layers: Layers, events: list, drive) -> None:
    """Detected manoeuvres: a state timeline, and labelled points on the map and local view."""
    import rerun as rr

    from .blueprints import ruler_end_s

    rec, send, usable = layers.rec, layers.send, layers.usable
    times, states = [], []
    for i, e in enumerate(sorted(events, key=lambda e: e.t0_s)):
        if times and e.t0_s < times[-1]:  # overlapping events: the timeline shows the later one
            times.pop()
            states.pop()
        times += [e.t0_s, e.t1_s]
        states += [ent.event_state(e.type, i + 1), ent.NO_EVENT_STATE]
    order = np.argsort(times, kind="stable")
    log_state_lane(rec, send, ent.EVENTS_STATE, [states[k] for k in order], np.asarray(times)[order],
                   float(drive.t_s[-1]), ruler_end_s(float(drive.t_s[-1])))
    mid = np.array([0.5 * (e.t0_s + e.t1_s) for e in events])
    # a loss's middle lies between its good fixes (``usable``), not at (0, 0)
    lat = np.interp(mid, drive.t_s[usable], drive.lat_deg[usable])
    lon = np.interp(mid, drive.t_s[usable], drive.lon_deg[usable])
    labels = [ent.event_state(e.type, i + 1) for i, e in enumerate(events)]
    # names in the hover text and on the timeline only: permanent labels would cover the tracks
    rec.log(ent.event_points(ent.MAP),
            rr.GeoPoints(lat_lon=np.stack([lat, lon], axis=-1), colors=[EVENT_COLOR], radii=rr.Radius.ui_points(3.5)),
            static=True)
    rec.log(ent.event_points(ent.LOCAL), rr.Points2D(layers.xy(lat, lon), labels=labels, show_labels=False,
                                        colors=[EVENT_COLOR], radii=rr.Radius.ui_points(3.5), draw_order=25),
            static=True)


#: The drift view's plot area (its own units: the 2D view keeps one scale on both axes, so seconds
#: and metres are each mapped onto it): width and height.
DRIFT_W, DRIFT_H = 160.0, 100.0


def log_drift(layers: Layers, result: DriveResult, colors: dict, t_rows: np.ndarray) -> None:
    """The drift view (``drift``): position error against seconds since the outage began, per
    estimator its mean over the drive's outages (wide) and 10th and 90th percentiles (thin, faded),
    static; and the current outage's own curve, growing each second as the recording plays (rows
    ``t_rows``, as the live tracks). Axes with labelled ticks."""
    import rerun as rr

    from ..analysis.drift import boundary_errors_m, drift_curve

    rec, send = layers.rec, layers.send
    n_win = result.n_windows
    errors = {name: boundary_errors_m(result, name) for name in result.estimates}
    curves = {name: drift_curve(e) for name, e in errors.items()}
    top = max([max(c["p90_m"]) for c in curves.values()] + [1.0])
    step = nice_step(top * 1.05, lines=4)
    y_max = step * np.ceil(top * 1.05 / step)
    t_step = max(1, int(nice_step(float(n_win), lines=5)))

    def xy(t_s: np.ndarray, err_m: np.ndarray) -> np.ndarray:
        return np.stack([np.asarray(t_s, dtype=float) / n_win * DRIFT_W,
                         -np.asarray(err_m, dtype=float) / y_max * DRIFT_H], axis=-1)

    t_axis = np.arange(n_win + 1, dtype=float)
    ys = np.arange(0.0, y_max + step / 2, step)
    ts = np.arange(0.0, n_win + 0.5, t_step)
    grid = [xy([0, n_win], [y, y]) for y in ys] + [xy([t, t], [0, y_max]) for t in ts]
    rec.log(ent.DRIFT_AXES, rr.LineStrips2D(grid, colors=[GRID_COLOR], radii=rr.Radius.ui_points(0.8), draw_order=1),
            static=True)
    ticks = np.concatenate([xy(ts, np.zeros(len(ts))) + [0.0, 6.0], xy(np.zeros(len(ys)), ys) - [10.0, 0.0]])
    labels = [f"{t:g} s" for t in ts] + [f"{y:g} m" for y in ys]
    rec.log(ent.DRIFT_TICKS, rr.Points2D(ticks, labels=labels, colors=[SCALE_COLOR], radii=rr.Radius.ui_points(0.5),
                                         show_labels=True, draw_order=2), static=True)
    for name, curve in curves.items():
        color = colors[name]
        rec.log(ent.drift_mean(name), rr.LineStrips2D([xy(t_axis, curve["mean_m"])], colors=[color],
                                                      radii=rr.Radius.ui_points(3.5), draw_order=20), static=True)
        rec.log(ent.drift_band(name), rr.LineStrips2D([xy(t_axis, curve["p10_m"]), xy(t_axis, curve["p90_m"])],
                                                      colors=[faded(color, 0.3)], radii=rr.Radius.ui_points(0.6),
                                                      draw_order=10), static=True)
        current = xy(np.broadcast_to(t_axis, errors[name].shape), errors[name])  # (outages, win+1, 2)
        n_rows = len(t_rows)
        send(ent.drift_current(name), t_rows, rr.LineStrips2D.columns(
            strips=columns.line_strips_2d(*columns.growing(current)), colors=np.tile(color, (n_rows, 1)),
            radii=np.full(n_rows, rr.Radius.ui_points(1.6)), draw_order=np.full(n_rows, 30.0)))
