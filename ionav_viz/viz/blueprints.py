"""The recording's review layout, and how each screenshot changes it: which view, framed where,
with which titles. The layout's column shares have one home here, for the blueprint and for the
title widths."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..experiment.registry import BASELINE
from . import entities as ent
from .geometry import map_zoom, padded_bounds
from .recording_info import OutageInfo, RecordingInfo
from .style import color_word

#: Views a screenshot shows: the whole review layout, or one view (maximised) or column of plots.
VIEWS = ("all", "outage", "map", "local", "signals", "errors", "health")
_ORIGINS = {"outage": ent.INSPECT, "map": ent.MAP, "local": ent.LOCAL, "signals": ent.DISPLACEMENTS,
            "errors": ent.error_group("position_error_m"), "health": ent.HEALTH}
#: The review layout's three columns and their shares: tracks (the inspector above the local view
#: and the map, side by side), signals, errors.
COLUMN_SHARES = (4, 3, 3)
#: Which column each view's title sits in, and what share of it the view has across.
_COLUMN_OF = {ent.INSPECT: (0, 1.0), ent.LOCAL: (0, 0.5), ent.MAP: (0, 0.5), "/": (1, 1.0), ent.DISPLACEMENTS: (1, 1.0),
              ent.error_group("position_error_m"): (2, 1.0)}


def column_fraction(origin: str) -> float:
    """The fraction of the image's width a view of the review layout has."""
    column, share = _COLUMN_OF.get(origin, (1, 1.0))
    return COLUMN_SHARES[column] / sum(COLUMN_SHARES) * share


#: The page (pixels, width x height) the recording's own layout is made for in a browser (Rerun's
#: web viewer, ``replay --serve-web``), the least it is made for: every view and tab title shows in
#: full there (the viewer cuts a title at its view's edge, "Drive: east-north ("), the state
#: timeline keeps its three lanes, the summary its table. Wider and taller pages only add room.
WEB_PAGE_PX = (1280, 720)
#: What the web viewer's page keeps above and below the views: its top bar and the collapsed time panel.
WEB_CHROME_PX = 66
#: The narrowest image whose state labels must fit their spans: screenshots are made for 1024x576
#: and larger, the web page for :data:`WEB_PAGE_PX`.
NARROWEST_PX = 1024
#: A state label's width in its lane: pixels per character and the padding around it (measured on renders).
STATE_LABEL_PX_PER_CHAR, STATE_LABEL_PAD_PX = 7.0, 8.0
#: The state timeline opens on the whole drive, with these shares of the drive's length as room
#: before its start and after its end: no span crosses the view's edge (the viewer draws a label from
#: where its span enters the view and cuts it where the span ends: "cr" of "cruise"), and the time
#: plots' first and last tick labels, centred on their ticks, are whole.
STATE_VIEW_PAD_BEFORE, STATE_VIEW_PAD_AFTER = 0.05, 0.05


def state_view_s(end_s: float) -> tuple[float, float]:
    """The state timeline's and the web page's time plots' default time range (s) for a drive ending
    at ``end_s`` (its times start at 0): the whole drive and its time ruler (:func:`ruler_end_s`),
    with :data:`STATE_VIEW_PAD_BEFORE` and :data:`STATE_VIEW_PAD_AFTER` of the drive as room."""
    length_s = max(float(end_s), 1.0)
    return -STATE_VIEW_PAD_BEFORE * length_s, ruler_end_s(end_s) + STATE_VIEW_PAD_AFTER * length_s


#: The state timeline's time ruler (Rerun 0.41, measured on renders and read in its ruler code): it
#: spans the recording's data on the ``time`` timeline, :data:`RULER_EDGE_PX` more each way (its torn
#: edges), whatever the view's range, and cuts there a tick label that runs past it (the "+" of a
#: "+10m" at a drive's end at 600 s). Ticks are :data:`RULER_STEPS_S` apart; the finest step at least
#: 4 px apart is drawn, with two coarser ones, and a step's ticks are labelled where they are more
#: than :data:`RULER_LABEL_MIN_PX` apart; a label starts :data:`RULER_LABEL_GAP_PX` right of its tick,
#: :data:`RULER_CHAR_PX` a character or less ("+10m": 27 px).
RULER_EDGE_PX, RULER_LABEL_MIN_PX, RULER_LABEL_GAP_PX, RULER_CHAR_PX = 10.0, 60.0, 4.0, 7.0
#: Half the width of the time cursor's head on the ruler (px, measured on the served page): the web
#: page opens with the cursor at the recording's last time, and a label under it reads "+10" of "+10m".
CURSOR_HALF_PX = 7.0
RULER_STEPS_S = (0.001, 0.01, 0.1, 1.0, 10.0, 60.0, 600.0, 3600.0, 43200.0, 86400.0, 864000.0, 8640000.0)
#: The state timeline's widths (px) its ruler's labels must be whole at: the review layout's signals
#: column and the signals view alone, in images and pages from :data:`NARROWEST_PX` to 1920 px wide.
RULER_WIDTHS_PX = tuple(f * w for w in range(1024, 1921, 16) for f in (3 / 10, 1.0))
#: The state timeline's widths (px) on the web page, which opens with the time cursor at the
#: recording's last time: its signals column in pages from :data:`WEB_PAGE_PX` to 1920 px wide.
PAGE_RULER_WIDTHS_PX = tuple(3 / 10 * w for w in range(WEB_PAGE_PX[0], 1921, 16))


def ruler_label(t_s: float) -> str:
    """A tick label of the state timeline's ruler as the viewer writes it (``+10m``, ``+1h 10m``)."""
    total = int(round(t_s))
    hours, rest = divmod(total, 3600)
    minutes, seconds = divmod(rest, 60)
    parts = [f"{v}{u}" for v, u in ((hours, "h"), (minutes, "m"), (seconds, "s")) if v]
    return "+" + (" ".join(parts) or "0s")


def ruler_cuts_a_label(last_s: float, view: tuple[float, float], width_px: float, cursor: bool = False) -> bool:
    """Whether the ruler of data ending at ``last_s``, in a state timeline ``width_px`` wide showing
    ``view`` (s), cuts the label of its last labelled tick at its end (or the view's); with
    ``cursor``, also whether it runs that label under the time cursor at ``last_s`` (where the web
    page opens)."""
    px_per_s = width_px / (view[1] - view[0])
    small = next((s for s in RULER_STEPS_S if s * px_per_s >= 4.0), RULER_STEPS_S[-1])
    drawn = RULER_STEPS_S[RULER_STEPS_S.index(small):][:3]
    labelled = [s for s in drawn if s * px_per_s > RULER_LABEL_MIN_PX]
    if not labelled:
        return False
    edge_s = min(last_s + RULER_EDGE_PX / px_per_s, view[1])
    tick_s = math.floor(edge_s / labelled[0] + 1e-9) * labelled[0]
    label_px = RULER_LABEL_GAP_PX + len(ruler_label(tick_s)) * RULER_CHAR_PX
    cursor_s = CURSOR_HALF_PX / px_per_s
    under_cursor = tick_s - cursor_s <= last_s < tick_s + label_px / px_per_s + cursor_s
    return tick_s >= 0 and (tick_s + label_px / px_per_s > edge_s or (cursor and under_cursor))


@functools.lru_cache(maxsize=64)  # pure, and asked again for every state label of a recording
def ruler_end_s(end_s: float) -> float:
    """Where the state lanes of a drive ending at ``end_s`` log their last (empty) change: the
    recording's last time on the ``time`` timeline, so that the state timeline's ruler ends where
    no tick's label runs past it at any of :data:`RULER_WIDTHS_PX` (its label whole). ``end_s``
    itself where that holds there, else the first time after it (at most 25 % of the drive) that
    does; the lanes end at ``end_s`` either way. Where such a time also keeps the last label clear of
    the web page's opening time cursor (:data:`PAGE_RULER_WIDTHS_PX`), the first such."""
    end_s = float(end_s)
    length_s = max(end_s, 1.0)
    step_s = max(0.1, length_s / 2000)
    whole = []
    for i in range(int(0.25 * length_s / step_s) + 1):
        last_s = end_s + i * step_s
        view = (-STATE_VIEW_PAD_BEFORE * length_s, last_s + STATE_VIEW_PAD_AFTER * length_s)
        if not any(ruler_cuts_a_label(last_s, view, w) for w in RULER_WIDTHS_PX):
            if not any(ruler_cuts_a_label(last_s, view, w, cursor=True) for w in PAGE_RULER_WIDTHS_PX):
                return last_s
            whole.append(last_s)
    return whole[0] if whole else end_s


def state_label_fits(label: str, span_s: float, end_s: float) -> bool:
    """Whether the state label ``label`` shows whole in a span of ``span_s`` seconds of its lane in
    its default view (:func:`state_view_s` of a drive ending at ``end_s``, across the signals column)
    of the narrowest image (:data:`NARROWEST_PX`): the viewer cuts a label at its span's end ("bra"
    of a 3 s brake)."""
    t0_s, t1_s = state_view_s(end_s)
    px_per_s = NARROWEST_PX * column_fraction("/") / (t1_s - t0_s)
    return len(label) * STATE_LABEL_PX_PER_CHAR + STATE_LABEL_PAD_PX <= span_s * px_per_s


#: The viewer draws a state label only in a span more than this many pixels wide (and cuts it at the
#: span's end); two characters are whole from 18 px on ("28" ends 17 px into its span, measured on
#: renders: in a span of 17 px it loses its last pixel column).
STATE_TEXT_MIN_PX, STATE_WHOLE_ANYWHERE_CHARS = 16.0, 2


def state_label_whole_anywhere(label: str) -> bool:
    """Whether the state label ``label`` is whole in any span the viewer draws a label in, at any
    zoom (absent in a narrower one): two characters or fewer."""
    return len(label) <= STATE_WHOLE_ANYWHERE_CHARS


INSPECTOR_NAME = "Current outage: m from its start fix, north up"
#: The local view shows the whole drive's scale bar; framed on an outage (screenshots), that outage's.
LOCAL_CONTENTS = ["+ $origin/**", f"- /{ent.LOCAL_SCALE}"]
LOCAL_FRAMED_CONTENTS = ["+ $origin/**", f"- /{ent.LOCAL_GRID_SCALE}"]


#: The key's ellipse: an outline in a neutral light grey, as each estimator draws its own in its colour.
ELLIPSE_KEY_COLOR = (200, 200, 200)

#: The local view's name in the recording (what its dots are is in the key:
#: :func:`~ionav_viz.viz.recording.key_markdown`).
LOCAL_NAME = "Drive: east-north (m)"
#: Views of the review layout that only some recordings have data for (:func:`blueprint`'s ``shown``).
OPTIONAL_VIEWS = (ent.DRIFT, ent.UNCERTAINTY, ent.HEALTH, ent.error_group("crse_m"))
def shown_views(info: RecordingInfo) -> frozenset[str]:
    """Which of :data:`OPTIONAL_VIEWS` the recording ``info`` has data for."""
    synthetic = bool(info.outages)
    shown = {ent.DRIFT: synthetic, ent.error_group("crse_m"): synthetic, ent.HEALTH: bool(info.health),
             ent.UNCERTAINTY: synthetic and info.ellipses}
    return frozenset(k for k, v in shown.items() if v)


#: The timeline the viewer opens on: seconds into the drive (the recording also has ``time_of_day``).
DEFAULT_TIMELINE = "time"
#: Tab titles, longest first: a screenshot takes the longest variant that fits its column (tabs
#: share one bar, so each gets a share of it).
TAB_TITLES = {
    ent.error_group("position_error_m"): ("2D position error (m)", "Position error (m)", "Error (m)"),
    ent.DRIFT: ("Drift: error (m) by s into the outage", "Drift (m by s)", "Drift"),
    ent.UNCERTAINTY: ("Sigma vs error: 95 % radius (thin) and error (m)", "95 % radius vs error", "Sigma"),
    ent.HEALTH: ("Filter health: NIS, 10 s mean (1 = consistent)", "Filter NIS", "NIS"),
    ent.error_group("crse_m"): ("Displacement CRSE (m)", "Disp. CRSE (m)", "CRSE (m)"),
    ent.error_group("cae_m"): ("Displacement CAE (m)", "Disp. CAE (m)", "CAE (m)"),
    ent.OVERVIEW: ("Summary",),
    ent.SUMMARY: ("Details",),
}
#: Every time plot's y-axis name (unit included).
PLOT_NAMES = {
    ent.DISPLACEMENTS: "Displacement per second (m)",
    ent.YAW_RATES: "Yaw rate (rad/s, CCW +)",
    ent.ACCEL: "Longitudinal acceleration (m/s²)",
    ent.error_group("position_error_m"): TAB_TITLES[ent.error_group("position_error_m")][0],
    ent.error_group("crse_m"): TAB_TITLES[ent.error_group("crse_m")][0],
    ent.error_group("cae_m"): TAB_TITLES[ent.error_group("cae_m")][0],
    ent.error_group("yaw_crse_radps"): "Orientation-rate CRSE (rad/s)",
}


def data_range(lo: float, hi: float, min_span: float, pad: bool = True, signed: bool = False) -> tuple[float, float]:
    """The y range a time plot of the recording shows for data from ``lo`` to ``hi``: widened to
    ``min_span`` (a flat line is drawn in the middle of a readable range, with ticks; a magnitude's
    range starts at zero unless ``signed``) and by 5 %
    each way. Screenshots round it to ticks for their plots' heights (:func:`axis_range`)."""
    lo, hi = (float(lo), float(hi)) if np.isfinite(lo) and np.isfinite(hi) else (0.0, 0.0)
    if hi - lo < min_span:
        mid = (lo + hi) / 2
        lo, hi = ((0.0, min_span)
                  if not signed and lo >= 0 and mid - min_span / 2 < 0 else (mid - min_span / 2, mid + min_span / 2))
    margin = 0.05 * (hi - lo) if pad else 0.0
    return (lo if lo == 0 else lo - margin), hi + margin


#: The least y span of each time plot (its unit): a flat line still gets three labelled ticks.
MIN_Y_SPAN = {ent.DISPLACEMENTS: 1.0, ent.YAW_RATES: 0.1, ent.ACCEL: 1.0, ent.error_group("position_error_m"): 1.0,
              ent.error_group("crse_m"): 1.0, ent.error_group("cae_m"): 1.0, ent.error_group("yaw_crse_radps"): 0.01}
#: The plots of signed values (the others are magnitudes, drawn from zero).
SIGNED_PLOTS = (ent.YAW_RATES, ent.ACCEL, ent.error_group("cae_m"))


def plot_range(origin: str, lo: float, hi: float, pad: bool = True) -> tuple[float, float]:
    """:func:`data_range` of the time plot ``origin`` for data from ``lo`` to ``hi``: from zero for
    magnitudes, at least :data:`MIN_Y_SPAN`; without ``pad``, not widened by 5 % (screenshots
    round to ticks and add their own margin)."""
    signed = origin in SIGNED_PLOTS
    return data_range(lo if signed else min(lo, 0.0), hi, MIN_Y_SPAN[origin], pad, signed)


#: Pixels between two labelled ticks of a time plot's y axis: the plots label a tick a power of ten
#: apart only with about this much room (fewer pixels: only the coarser ticks get labels; at 23 px
#: they are drawn at about half the brightness of the others, 120 of 255, and read well).
TICK_PX = 23
#: Pixels between labelled ticks at which the plots still label them, fainter (measured on renders of
#: a 69 px plot: "0.1" and "0.2" read at 20 px, not drawn at 18): :func:`axis_range` goes down to it
#: where :data:`TICK_PX` would leave the data in less than :data:`SQUASHED_SHARE` of the plot.
FAINT_TICK_PX = 20
SQUASHED_SHARE = 0.5
#: Pixels above the top tick and below the bottom one: half a label's height, so that it is not cut.
LABEL_MARGIN_PX = 7
#: Pixels between the data and the plot's edge where no label needs the room.
DATA_MARGIN_PX = 3


def axis_range(lo: float, hi: float, plot_px: float, faint: bool = False) -> tuple[float, float]:
    """A y range over ``lo``..``hi`` for a plot ``plot_px`` high, with at least three labelled
    ticks: the plots tick a power of ten apart and label ticks at least :data:`TICK_PX` apart, so
    the step is the finest power of ten that is labelled, and the range is widened to three ticks
    of it when the data spans fewer. Three labels come first: where only a coarse step is labelled,
    the data fills less of the plot (the screenshot layout gives the plots the height that keeps
    this rare, :func:`shot_rows`). A plot too small for three labels at any step (under about
    2.3 :data:`TICK_PX`) keeps the data's own range. A margin of 6 % each way keeps the outer
    labels drawn (at least :data:`LABEL_MARGIN_PX`, beyond the data and beyond the outermost
    labelled ticks). With ``faint`` (the web page's plots, which open on the whole drive), where
    that leaves the data in less than :data:`SQUASHED_SHARE` of the plot (0.27 rad/s under ticks of 1
    in a plot 69 px high: the data in its bottom tenth), a finer step
    labelled at :data:`FAINT_TICK_PX` or more is taken when it gives three labelled ticks (0, 0.1,
    0.2), the data :data:`DATA_MARGIN_PX` inside the edges and the outer labels
    :data:`LABEL_MARGIN_PX` inside."""

    def framed(a: float, b: float) -> tuple[float, float]:
        m = max(0.06, LABEL_MARGIN_PX / max(plot_px - 2 * LABEL_MARGIN_PX, 1.0)) * (b - a)
        return a - m, b + m

    def clear(r0: float, r1: float, step: float) -> tuple[float, float]:
        # a tick the margin takes in (just beyond the data) would sit at the edge, its label cut: push the
        # edge out to half a label beyond the outermost ticks (a few rounds: the push changes the scale)
        for _ in range(4):
            m = LABEL_MARGIN_PX * (r1 - r0) / plot_px
            r0, r1 = min(r0, math.ceil(r0 / step - 1e-9) * step - m), max(r1, math.floor(r1 / step + 1e-9) * step + m)
        return r0, r1

    def reach(step: float) -> tuple[float, float]:
        first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
        if last - first >= 2:
            return lo, hi
        # fewer than three ticks inside: reach out to them
        if lo >= 0:
            return min(lo, first * step), max(hi, (first + 2) * step)
        if hi <= 0:
            return min(lo, (last - 2) * step), max(hi, last * step)
        return min(lo, -step), max(hi, step)

    def tight(a: float, b: float, step: float) -> tuple[float, float]:
        # the data DATA_MARGIN_PX inside each edge, and the outermost ticks inside LABEL_MARGIN_PX: a tick just
        # beyond the data is left outside rather than pushing the edge out (a few rounds: the scale moves)
        r0, r1 = framed(a, b)
        for _ in range(6):
            per_px = (r1 - r0) / plot_px
            top, bottom = b + DATA_MARGIN_PX * per_px, a - DATA_MARGIN_PX * per_px
            t_top, t_bottom = math.floor(top / step + 1e-9) * step, math.ceil(bottom / step - 1e-9) * step
            r0, r1 = min(bottom, t_bottom - LABEL_MARGIN_PX * per_px), max(top, t_top + LABEL_MARGIN_PX * per_px)
        return r0, r1

    k0 = math.floor(math.log10(max(hi - lo, 1e-12))) - 1
    chosen = None
    for k in range(k0, k0 + 4):  # from a tenth of the data's span to ten times it: coarser gains nothing
        step = 10.0 ** k
        r0, r1 = clear(*framed(*reach(step)), step)
        if plot_px * step / (r1 - r0) >= TICK_PX:
            chosen = (k, (r0, r1))
            break
    if chosen is None:
        return framed(lo, hi)
    k, (r0, r1) = chosen
    # the data squashed: finer ticks, fainter, if they are labelled at all (not in screenshots: their plots are high
    # enough for TICK_PX, and wider y labels there showed the tick before the first's label at the column's edge)
    if faint and hi - lo < SQUASHED_SHARE * (r1 - r0):
        for finer in range(k0, k):
            step = 10.0 ** finer
            t0, t1 = tight(*reach(step), step)
            labelled = math.floor(t1 / step + 1e-9) - math.ceil(t0 / step - 1e-9) + 1
            if plot_px * step / (t1 - t0) >= FAINT_TICK_PX and labelled >= 3:
                return t0, t1
    return r0, r1


#: Above the views, the band the viewer keeps for its hidden top panel (screenshots draw the colour
#: key there); each view's title bar, and a time plot's time-axis labels (pixels, measured on renders).
TOP_BAND_PX, TITLE_BAR_PX, TIME_LABELS_PX = 36, 26, 20


#: A screenshot's rows, in pixels of its views (below the key band): the state timeline keeps its
#: three lanes, the summary its table and worst outage (a line more per estimator); the time plots
#: share the rest of their column, each a drawing area at least :data:`MIN_PLOT_PX` high where it can.
TIMELINE_PX = 166
MIN_PLOT_PX = 110


def summary_px(n_estimators: int, warned: bool = False) -> float:
    """The summary tab's height in a screenshot: title, heading, table, the worst outage on two
    lines and, when ``warned``, the line that points to the warnings (measured on renders)."""
    return 170.0 + 23.0 * n_estimators + (22.0 if warned else 0.0)


@dataclass(frozen=True)
class ShotRows:
    """The rows (pixels) of a screenshot's signals and errors columns."""

    signals: tuple[float, ...]  # the state timeline, displacement, yaw rate, acceleration (unless dropped)
    errors: tuple[float, ...]  # position error, CRSE/CAE, the orientation-rate CRSE (unless dropped), the summary
    yaw_crse: bool  # whether the orientation-rate CRSE is drawn
    accel: bool = True  # whether the acceleration is drawn
    crse: bool = True  # whether the CRSE and CAE are drawn


def shot_rows(size: tuple[int, int], n_estimators: int = 4, warned: bool = False, synthetic: bool = True) -> ShotRows:
    """The rows of a screenshot of ``size`` with ``n_estimators`` (:func:`summary_px`): in a small
    image each column keeps the plots that are :data:`MIN_PLOT_PX` high, the first ones, rather than
    draw them too low for three labelled y ticks over the data (a 1024x576 image's displacement, 0-30
    m in plots 79 px high, had ticks of 100; its position errors, 0-52 m in 89 px, too): the signals
    column leaves out its acceleration, the error column its orientation-rate CRSE, then its CRSE and
    CAE (the summary's table keeps their means); without ``synthetic`` outages (a run through the
    log's own losses alone) the error column has the position error alone above the summary."""
    views = size[1] - TOP_BAND_PX
    timeline = min(TIMELINE_PX, 0.31 * views)
    accel = (views - timeline) / 3 - TITLE_BAR_PX - TIME_LABELS_PX >= MIN_PLOT_PX
    signals = (timeline,) + ((views - timeline) / (3 if accel else 2),) * (3 if accel else 2)
    summary = min(summary_px(n_estimators, warned), 0.5 * views)
    if not synthetic:
        return ShotRows(signals, (views - summary, summary), False, accel)
    plots = next(k for k in (3, 2, 1) if (views - summary) / k - TITLE_BAR_PX - TIME_LABELS_PX >= MIN_PLOT_PX or k == 1)
    err = (views - summary) / plots
    return ShotRows(signals, (err,) * plots + (summary,), plots == 3, accel, plots >= 2)


def plot_heights_px(size: tuple[int, int], n_estimators: int = 4, warned: bool = False,
                    synthetic: bool = True) -> dict[str, float]:
    """The height in pixels of each time plot's drawing area in a screenshot of ``size`` (the
    review layout and the signals and errors columns share their rows); a plot the image leaves
    out is not there."""
    rows = shot_rows(size, n_estimators, warned, synthetic)
    out = {o: rows.signals[1] for o in (ent.DISPLACEMENTS, ent.YAW_RATES, ent.ACCEL)[: len(rows.signals) - 1]}
    out.update({o: rows.errors[0]
                for o in (ent.error_group("position_error_m"), ent.error_group("crse_m"), ent.error_group("cae_m"))[
                    : 3 if rows.crse else 1]})
    if rows.yaw_crse:
        out[ent.error_group("yaw_crse_radps")] = rows.errors[2]
    return {o: max(px - TITLE_BAR_PX - TIME_LABELS_PX, 20.0) for o, px in out.items()}


def blueprint(labels: list[str], zoom: float = 16.0, y_ranges: dict[str, tuple[float, float]] | None = None,
              shown: frozenset[str] | None = None, end_s: float | None = None):
    """The default review layout: the outage inspector above the whole-drive local and map views,
    the signals, the errors and the summary; time plots with ``y_ranges`` (by origin) when given.
    ``shown``: which of :data:`OPTIONAL_VIEWS` hold data (None: all); the others are left out, so
    that no view opens empty (a run through the log's own losses alone has no CRSE, CAE or drift;
    one without a filter's covariance or health no sigma or NIS tab). Made for the page
    :data:`WEB_PAGE_PX`: titles that show in full there, the rows of :func:`web_signal_rows_px` and
    :func:`web_error_rows_px` (the summary's table a row per estimator of ``labels``). With the
    drive's ``end_s``, the state timeline and the time plots open on the whole drive
    (:func:`state_view_s`). ``y_ranges`` are the data's: each plot's is widened to labelled ticks for its
    height on the page (:func:`axis_range`, :func:`web_plot_px`)."""
    import rerun as rr
    import rerun.blueprint as rrb

    has = (lambda origin: True) if shown is None else (lambda origin: origin in shown)
    n_estimators = len(labels)
    # y ranges with at least three labelled ticks at the plots' heights on the page (the viewer's own fit
    # labelled only "0" of errors from 0 to 9 m in a plot 90 px high)
    heights = web_plot_px(n_estimators, has(ent.error_group("crse_m")))
    ranges = {o: axis_range(*r, heights[o], faint=True) if o in heights else r for o, r in (y_ranges or {}).items()}
    # every time view opens on the whole drive, as the state timeline: nothing scrolls with the time cursor,
    # where the first tick's label was cut at the view's edge ("9m 30s" of "+9m 30s")
    whole = None if end_s is None else rrb.TimeAxis(view_range=rr.TimeRange(
        *(rrb.TimeRangeBoundary.absolute(seconds=t) for t in state_view_s(end_s))))

    # No legend on the time plots: Rerun draws it inside the plot, in a corner, where the curves of
    # a 60 s window pass sooner or later. The key above the signals names every line by its colour
    # (screenshots draw theirs in the band above the views).
    def plot(origin: str, name: str | None = None):
        return rrb.TimeSeriesView(origin=origin, name=name or PLOT_NAMES[origin],
                                  axis_y=rrb.ScalarAxis(range=ranges[origin]) if origin in ranges else None,
                                  axis_x=whole, plot_legend=rrb.PlotLegend(visible=False))

    tracks = rrb.Vertical(
        rrb.Spatial2DView(origin=ent.INSPECT, name=INSPECTOR_NAME),
        rrb.Horizontal(
            rrb.Spatial2DView(origin=ent.LOCAL, contents=LOCAL_CONTENTS, name=LOCAL_NAME),
            rrb.MapView(origin=ent.MAP, name="Map", zoom=zoom),
        ),
        row_shares=[3, 2],
    )
    signals = rrb.Vertical(
        rrb.TextDocumentView(origin=ent.KEY, name="Key", titlebar=False),
        rrb.StateTimelineView(origin="/", contents=[ent.GNSS_STATE, ent.GNSS_QUALITY, ent.EVENTS_STATE],
                              name="GNSS, outages, manoeuvres", time_view=whole),
        plot(ent.DISPLACEMENTS),
        plot(ent.YAW_RATES, f"{PLOT_NAMES[ent.YAW_RATES]}; gyro grey"),
        plot(ent.ACCEL),
        row_shares=list(web_signal_rows_px()),
    )
    # tab titles that all show in their bar on the narrowest page (the viewer cuts the others: "Drift: error (m")
    error_origins = [ent.error_group("position_error_m"),
                     *(o for o in (ent.DRIFT, ent.UNCERTAINTY, ent.HEALTH) if has(o))]
    tab_names = _fit_tabs(tuple(error_origins), WEB_PAGE_PX[0] * column_fraction(ent.error_group("position_error_m")))
    views = {ent.DRIFT: rrb.Spatial2DView, ent.UNCERTAINTY: rrb.TimeSeriesView, ent.HEALTH: rrb.TimeSeriesView}
    error_tabs = [plot(o, tab_names[o]) if o not in views else
                  views[o](origin=o, name=tab_names[o], **({} if o == ent.DRIFT else {"axis_x": whole}))
                  for o in error_origins]
    rows = [rrb.Tabs(*error_tabs, active_tab=0) if len(error_tabs) > 1 else plot(error_origins[0])]
    synthetic = has(ent.error_group("crse_m"))
    if synthetic:  # the CRSE, CAE and orientation-rate CRSE are of synthetic outages
        crse_cae = (ent.error_group("crse_m"), ent.error_group("cae_m"))
        crse_names = _fit_tabs(crse_cae, WEB_PAGE_PX[0] * column_fraction(crse_cae[0]))
        rows += [rrb.Tabs(*(plot(o, crse_names[o]) for o in crse_cae)), plot(ent.error_group("yaw_crse_radps"))]
    rows.append(rrb.Tabs(rrb.TextDocumentView(origin=ent.OVERVIEW, name="Summary"),
                         rrb.TextDocumentView(origin=ent.SUMMARY, name="Details"), active_tab=0))
    shares = list(web_error_rows_px(n_estimators, synthetic))
    errors = rrb.Vertical(*rows, row_shares=shares)
    # the viewer opens on the first timeline it meets, time_of_day (axes at "+17h 30s"): time into the drive instead
    return rrb.Blueprint(rrb.Horizontal(tracks, signals, errors, column_shares=list(COLUMN_SHARES)),
                         rrb.TimePanel(timeline=DEFAULT_TIMELINE, state="collapsed"), collapse_panels=True)


@dataclass
class Shot:
    """One image to render: a view at a time, framed on an outage or not."""

    view: str
    t_s: float
    label: str  # for the file name: 'worst', 'end', 'outage12', '0035.0s'
    outage: OutageInfo | None = None


@dataclass
class Framing:
    """Where the map and local views look for one image: the whole drive, or one outage."""

    map_zoom: float | None = None
    local_bounds: tuple[float, float, float, float] | None = None  # x_min, x_max, y_min, y_max (m)
    map_entities: list[str] = field(default_factory=list)  # the map's contents when framed on an outage


def framing(info: RecordingInfo, outage: OutageInfo | None, size: tuple[int, int], view: str) -> Framing:
    """The whole drive (map zoom from the GNSS track), or ``outage``: its truth and estimated tracks
    with a margin, in the local view's bounds and on the map (only that outage's tracks and the
    GNSS track just around it, so the map centres on them)."""
    width, height = size
    # the map's side in pixels: the whole image maximised, else its tile of the review layout
    map_px = min(width, height) if view == "map" else min(column_fraction(ent.MAP) * width, 0.4 * height * 0.85)
    if outage is None:
        zoom = map_zoom(info.lat_deg, info.lon_deg, 0.8 * map_px) if len(info.lat_deg) else None
        return Framing(zoom)
    zoom = map_zoom(outage.lat_deg, outage.lon_deg, 0.6 * map_px) if len(outage.lat_deg) else None
    bounds = padded_bounds(outage.local_points, margin=0.12) if len(outage.local_points) else None
    if outage.real:  # the log's own loss: its tracks and the fixes around it, drawn from its start on
        return Framing(zoom, bounds, [ent.REAL_OUTAGE_CURRENT])
    entities = [ent.outage_truth(ent.MAP), ent.MAP_CONTEXT,
                *(ent.live_track(ent.MAP, name) for name in info.estimators)]
    return Framing(zoom, bounds, entities)


#: The web page's colour key (four lines of the signals column at :data:`WEB_PAGE_PX`) and state
#: timeline (its title, time axis and three lanes; pixels, measured on renders).
WEB_KEY_PX, WEB_TIMELINE_PX = 84.0, 180.0
#: How the time plots of a column share what the key, the timeline or the summary leave: the
#: signals (displacement, yaw rate, acceleration) and the errors (position error, CRSE/CAE,
#: orientation-rate CRSE).
SIGNAL_PLOT_SHARES, ERROR_PLOT_SHARES = (3.0, 3.0, 2.5), (3.0, 3.0, 2.5)


def _split(total_px: float, shares: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(total_px * s / sum(shares) for s in shares)


def web_signal_rows_px() -> tuple[float, ...]:
    """The signals column's rows on the page :data:`WEB_PAGE_PX` (pixels; the blueprint's row shares):
    the key, the state timeline with its three lanes, displacement, yaw rate, acceleration."""
    views = WEB_PAGE_PX[1] - WEB_CHROME_PX
    return (WEB_KEY_PX, WEB_TIMELINE_PX, *_split(views - WEB_KEY_PX - WEB_TIMELINE_PX, SIGNAL_PLOT_SHARES))


def web_error_rows_px(n_estimators: int, synthetic: bool = True) -> tuple[float, ...]:
    """The errors column's rows on the page :data:`WEB_PAGE_PX` (pixels; the blueprint's row shares):
    the position error, and with ``synthetic`` outages the CRSE/CAE and orientation-rate CRSE, then
    the summary with its whole table of ``n_estimators`` (:func:`summary_px`)."""
    views = WEB_PAGE_PX[1] - WEB_CHROME_PX
    summary = min(summary_px(n_estimators), 0.5 * views)
    plots = _split(views - summary, ERROR_PLOT_SHARES) if synthetic else (views - summary,)
    return (*plots, summary)


def web_plot_px(n_estimators: int, synthetic: bool = True) -> dict[str, float]:
    """The height in pixels of each time plot's drawing area on the page :data:`WEB_PAGE_PX` (its row
    of :func:`web_signal_rows_px` or :func:`web_error_rows_px`, less its title bar and time labels)."""
    signals = dict(zip((ent.DISPLACEMENTS, ent.YAW_RATES, ent.ACCEL), web_signal_rows_px()[2:]))
    error_rows = web_error_rows_px(n_estimators, synthetic)[:-1]
    errors = {ent.error_group("position_error_m"): error_rows[0]}
    if synthetic:
        errors.update({ent.error_group("crse_m"): error_rows[1], ent.error_group("cae_m"): error_rows[1],
                       ent.error_group("yaw_crse_radps"): error_rows[2]})
    return {o: px - TITLE_BAR_PX - TIME_LABELS_PX for o, px in {**signals, **errors}.items()}


#: Seconds of the drive a screenshot's time plots show: centred on the shot's time, kept inside the drive.
PLOT_WINDOW_S = 60.0
#: The time plots' tick step (s) at a screenshot's window (the viewer's choice, measured on renders).
PLOT_TICK_S = 10.0
#: Seconds of empty plot after the window's end: the label of a tick at the window's end is centred
#: on it, and was cut in half at the plot's edge.
PLOT_MARGIN_S = 4.0
#: Pixels of plot before the window's first tick: its label, centred on it, cleared the view's left
#: edge by a few pixels less than that ("4m 40s" of "+4m 40s"; half a label, about 25 px, less the
#: narrowest y-axis labels beside it, about 10 px). And pixels of plot the label of the tick before
#: it reaches into, from the plot's start back (the y-axis labels, up to about 35 px beside "-0.1",
#: and half a label: "0s" of "+4m 30s" drawn at the view's edge). Measured on renders.
FIRST_LABEL_PX, PREVIOUS_LABEL_PX = 16.0, 65.0


#: A time plot's y axis, from the view's left edge to the plot's (measured on renders: 24 px beside
#: "20", 36 px beside "-0.5"): a base and a width per character of its widest label; the plot's right
#: edge inset from the view's; half a time label ("+1m 30s" is 49-50 px), centred on its tick; and the
#: pixels between the 10 s ticks above which the viewer labels them.
Y_AXIS_BASE_PX, Y_AXIS_CHAR_PX, PLOT_RIGHT_INSET_PX, TIME_LABEL_HALF_PX, TEN_S_LABELLED_PX = 12.0, 6.0, 2.0, 25.0, 60.0


def y_axis_px(y_range: tuple[float, float], plot_px: float) -> float:
    """The width (px) of a time plot's y axis over ``y_range`` in a plot ``plot_px`` high: the
    labels of its finest labelled power of ten (at least :data:`TICK_PX` apart, as in screenshots), at
    :data:`Y_AXIS_CHAR_PX` a character, plus :data:`Y_AXIS_BASE_PX`."""
    r0, r1 = y_range
    span = max(r1 - r0, 1e-12)
    k = next((k for k in range(-6, 7) if plot_px * 10.0 ** k / span >= TICK_PX), 6)
    ticks = np.arange(math.ceil(r0 / 10.0 ** k - 1e-9), math.floor(r1 / 10.0 ** k + 1e-9) + 1) * 10.0 ** k
    chars = max((len(f"{t:.{max(0, -k)}f}") for t in ticks), default=1)
    return Y_AXIS_BASE_PX + Y_AXIS_CHAR_PX * chars


def time_axis_range_s(x0: float, x1: float, view_px: float, axis_px: float) -> tuple[float, float]:
    """The x range (s) of a time plot showing the window ``x0``..``x1`` (``x0`` on a whole
    :data:`PLOT_TICK_S`) in a view ``view_px`` wide whose y axis is ``axis_px`` wide. The viewer
    centres each time label on its tick and draws it from the view's left edge (under the y axis) to
    its right, cutting it there: where it labels the 10 s ticks, the first tick's label starts a few
    pixels inside the view, the label of the tick before it ends outside ("s" of "+1m 20s" beside
    "-0.5" on a real roof log), and the last tick's ends inside; elsewhere
    :func:`first_label_margin_s` before ``x0`` and :data:`PLOT_MARGIN_S` after ``x1``."""
    plot_px = max(view_px - axis_px - PLOT_RIGHT_INSET_PX, 1.0)
    start, end = x0, x1 + PLOT_MARGIN_S
    if PLOT_TICK_S * plot_px / (end - start) < TEN_S_LABELLED_PX:
        return x0 - first_label_margin_s(x1 - x0 + PLOT_MARGIN_S, view_px), end
    for _ in range(3):  # the margins change the scale: a few rounds
        px_per_s = plot_px / (end - start)
        lowest = max(TIME_LABEL_HALF_PX + 1 - axis_px, 0.0) + 4.0  # the first label whole, with room
        highest = PLOT_TICK_S * px_per_s - axis_px - TIME_LABEL_HALF_PX - 1  # the one before it outside
        start = x0 - max(min(lowest, highest), 0.0) / px_per_s
        last_tick = math.floor(end / PLOT_TICK_S + 1e-9) * PLOT_TICK_S
        if (end - last_tick) * px_per_s + PLOT_RIGHT_INSET_PX < TIME_LABEL_HALF_PX + 1:
            end = last_tick + (TIME_LABEL_HALF_PX + 1) / px_per_s
    return start, end


def first_label_margin_s(window_s: float, plot_px: float) -> float:
    """Seconds of time plot before the first tick of a window ``window_s`` long (:func:`plot_window`,
    its start on a whole :data:`PLOT_TICK_S`) in plots ``plot_px`` wide: :data:`FIRST_LABEL_PX` of
    them, so that the first tick's label is whole, and no more than leaves the tick before it
    :data:`PREVIOUS_LABEL_PX` out of the plot, so that its label is not drawn in part (that wins in
    plots too narrow for both, about 7.5 px a second or less: the review layout's columns up to
    1600 px, where the y-axis labels beside the first tick leave its label room enough)."""
    px_per_s = plot_px / window_s
    return max(0.0, min(FIRST_LABEL_PX / px_per_s, PLOT_TICK_S - PREVIOUS_LABEL_PX / px_per_s))
#: The viewer's panels a screenshot hides (only the views are drawn: no menu, badges or timeline).
HIDDEN_PANELS = {"/top_panel": "PanelBlueprint", "/blueprint_panel": "PanelBlueprint",
                 "/selection_panel": "PanelBlueprint", "/time_panel": "TimePanelBlueprint"}


def without_panels(blueprint: dict[str, Any]) -> dict[str, Any]:
    """A copy of the viewer's ``blueprint`` dict with its panels (:data:`HIDDEN_PANELS`: menu,
    badges, blueprint and selection panels, timeline) hidden: an image holds only the views."""
    bp = {k: {a: dict(f) for a, f in v.items()} for k, v in blueprint.items()}
    for value in bp.values():  # the viewer writes a container of one as "contents": "view/<id>"
        container = value.get("ContainerBlueprint")
        if container and isinstance(container.get("contents"), str):
            container["contents"] = [container["contents"]]
    for key, archetype in HIDDEN_PANELS.items():
        bp[key] = {archetype: {**bp.get(key, {}).get(archetype, {}), "state": "Hidden"}}
    return bp


def plot_window(t_s: float, end_s: float, width_s: float = PLOT_WINDOW_S) -> tuple[float, float]:
    """The time plots' x range (s) for a shot at ``t_s`` of a drive ending at ``end_s``: ``width_s``
    centred on ``t_s``, shifted to lie inside ``[0, end_s]`` (the whole drive when it is shorter),
    its start moved back to a whole :data:`PLOT_TICK_S` (the plots label a tick just before their
    start at their left edge, cut: "m" of "+6m")."""
    if end_s <= width_s:
        return 0.0, max(end_s, 1.0)
    start = min(max(t_s - width_s / 2, 0.0), end_s - width_s)
    return math.floor(start / PLOT_TICK_S + 1e-9) * PLOT_TICK_S, start + width_s


@dataclass(frozen=True)
class ShotLayout:
    """What a screenshot's layout (:func:`focus_blueprint`) depends on beyond its view and framing.

    Attributes:
        t_s, end_s: the shot's time and the recording's end (s); with both, the time plots show
            :func:`plot_window`, :func:`first_label_margin_s` before it and :data:`PLOT_MARGIN_S` after.
        map_tiles: whether map tiles load; without (offline), the map view is left out and the local
            view takes its place.
        size: the image (width, height, px); with ``n_estimators`` and ``warned`` it sets the
            columns' rows (:func:`shot_rows`).
        y_extents: per plot origin, the y range its data spans in the window (m, rad/s, ...).
        shown: of :data:`OPTIONAL_VIEWS`, the ones the recording shows (None: all; a recording made
            before they were left out of its own layout still holds them, empty).
    """

    t_s: float | None = None
    end_s: float | None = None
    map_tiles: bool = True
    size: tuple[int, int] | None = None
    y_extents: dict[str, tuple[float, float]] | None = None
    n_estimators: int = 4
    warned: bool = False
    shown: frozenset[str] | None = None


def focus_blueprint(blueprint: dict[str, Any], view: str, titles: dict[str, str], frame: Framing | None = None,
                    layout: ShotLayout | None = None) -> dict[str, Any]:
    """The recording's blueprint showing only ``view``, with view titles from ``titles`` (by
    origin), the map and local views framed as ``frame`` says, the rest as ``layout`` says
    (:class:`ShotLayout`); the viewer's panels hidden."""
    frame = frame or Framing()
    layout = layout or ShotLayout()
    t_s, end_s, map_tiles, size = layout.t_s, layout.end_s, layout.map_tiles, layout.size
    y_extents, n_estimators, warned, shown = layout.y_extents, layout.n_estimators, layout.warned, layout.shown
    bp = without_panels(blueprint)
    views = {k: v["ViewBlueprint"] for k, v in bp.items() if "ViewBlueprint" in v}
    synthetic = shown is None or ent.error_group("crse_m") in shown
    if shown is not None:
        empty = [o for o in OPTIONAL_VIEWS if o not in shown]
        if not synthetic:
            empty += [ent.error_group("cae_m"), ent.error_group("yaw_crse_radps")]
        for origin in empty:
            _remove(bp, views, _view_key(views, origin))
        _remove_empty_containers(bp)
    heights = plot_heights_px(size, n_estimators, warned, synthetic) if size is not None else {}
    y_extents = y_extents or {}
    for key, vb in views.items():
        if vb.get("class_identifier") != "TimeSeries":
            continue
        origin = vb.get("space_origin", "").strip("/")
        # the image's colour key names every line (screenshot.draw_key): no legend over the curves
        bp[key + "/PlotLegend"] = {"PlotLegend": {**bp.get(key + "/PlotLegend", {}).get("PlotLegend", {}),
                                                  "visible": False}}
        if origin in heights and origin in y_extents:  # ticks for this plot's height, over what it shows
            y = bp.get(key + "/ScalarAxis", {}).get("ScalarAxis", {})
            bp[key + "/ScalarAxis"] = {
                "ScalarAxis": {**y, "range": list(axis_range(*y_extents[origin], heights[origin]))}}
    if t_s is not None and end_s is not None:
        x0, x1 = plot_window(t_s, end_s)
        # the time plots are a column wide in the review layout, else as wide as the image (a column alone, or
        # maximised)
        view_px = (size or (1600, 900))[0] * (column_fraction(ent.DISPLACEMENTS) if view == "all" else 1.0)
        for key, vb in views.items():
            if vb.get("class_identifier") == "TimeSeries":  # room on either side for the first and last ticks' labels
                origin = vb.get("space_origin", "").strip("/")
                axis = (y_axis_px(axis_range(*y_extents[origin], heights[origin]), heights[origin])
                        if origin in heights and origin in y_extents else Y_AXIS_BASE_PX + 3 * Y_AXIS_CHAR_PX)
                start, end = time_axis_range_s(x0, x1, view_px, axis)
                bp[key + "/TimeAxis"] = {"TimeAxis": {"view_range": {
                    "start": {"Absolute": int(round(start * 1e9))}, "end": {"Absolute": int(round(end * 1e9))}}}}
    if not map_tiles:
        if view == "map":
            view = "local"
        _remove(bp, views, _view_key(views, ent.MAP))
    for key, vb in views.items():
        origin = vb.get("space_origin", "")
        if origin in titles:
            vb["display_name"] = titles[origin]
        if origin == ent.MAP and frame.map_zoom is not None:
            bp[key + "/MapZoom"] = {"MapZoom": {"zoom": frame.map_zoom}}
        if origin == ent.MAP and frame.map_entities:
            bp[key + "/ViewContents"] = {"ViewContents": {"query": [f"+ /{e}" for e in frame.map_entities]}}
        if origin == ent.LOCAL and frame.local_bounds is not None and view in ("local", "map"):
            x0, x1, y0, y1 = frame.local_bounds
            bp[key + "/VisualBounds2D"] = {"VisualBounds2D": {"range": {"x_range": [x0, x1], "y_range": [y0, y1]}}}
            bp[key + "/ViewContents"] = {"ViewContents": {"query": LOCAL_FRAMED_CONTENTS}}
    # the image's own colour key (screenshot.draw_key) takes the place of the viewer's key view
    _remove(bp, views, _view_key(views, ent.KEY))
    _single_tabs_where_narrow(bp, views, (size or (1600, 900))[0], view)
    # the columns' rows in screenshots (pixels): the timeline's lanes, the whole summary, and the
    # time plots as high as the rest allows; a small image leaves out what would squeeze them (shot_rows)
    rows = shot_rows(size or (1600, 900), n_estimators, warned, synthetic)
    if not rows.yaw_crse:
        _remove(bp, views, _view_key(views, ent.error_group("yaw_crse_radps")))
    if not rows.accel:
        _remove(bp, views, _view_key(views, ent.ACCEL))
    if not rows.crse:
        for origin in (ent.error_group("crse_m"), ent.error_group("cae_m")):
            _remove(bp, views, _view_key(views, origin))
        _remove_empty_containers(bp)
    for origin, shares in ((ent.OVERVIEW, rows.errors), (ent.DISPLACEMENTS, rows.signals)):
        held = _view_key(views, origin)
        for value in bp.values():
            container = value.get("ContainerBlueprint", {})
            inside = [c.lstrip("/") for c in container.get("contents", [])]
            if (held is not None and container.get("container_kind") == "Vertical" and len(inside) == len(shares)
                    and any(_holds(bp, "/" + c, held) for c in inside)):
                container["row_shares"] = list(shares)
    if view == "all":
        return bp
    target = _ORIGINS[view]
    view_key = _view_key(views, target)
    if view_key is None:
        raise InputError(f"the recording has no {view} view", "replay it again with this version of ionav-viz")
    viewport = bp.setdefault("/viewport", {}).setdefault("ViewportBlueprint", {})
    if view in ("map", "local", "outage", "health"):
        viewport["maximized"] = view_key.rsplit("/", 1)[-1]
    else:  # keep only the column of plots that holds the target view
        # the viewer writes container contents as "view/<id>" or "/view/<id>"
        root_key = "/container/" + viewport["root_container"].rsplit("/", 1)[-1]
        root = bp[root_key]["ContainerBlueprint"]
        column = next("/" + c.lstrip("/") for c in root["contents"] if _holds(bp, "/" + c.lstrip("/"), view_key))
        for other in root["contents"]:
            if "/" + other.lstrip("/") != column:
                _drop(bp, "/" + other.lstrip("/"))
        root["contents"] = [column.lstrip("/")]
        for shares in ("col_shares", "row_shares"):
            root.pop(shares, None)
    return bp


def _single_tabs_where_narrow(bp: dict[str, Any], views: dict[str, Any], width_px: int, view: str) -> None:
    """Where a tab bar is too narrow for even its tabs' shortest titles (their ends would be cut),
    the image keeps only the active tab: it shows one tab anyway, and its title then has the bar."""
    by_stripped = {o.strip("/"): o for o in TAB_TITLES}
    for value in list(bp.values()):
        container = value.get("ContainerBlueprint")
        if not container or container.get("container_kind") != "Tabs" or len(container.get("contents", [])) < 2:
            continue
        keys = ["/" + c.lstrip("/") for c in container["contents"]]
        origins = [bp.get(k, {}).get("ViewBlueprint", {}).get("space_origin", "").strip("/") for k in keys]
        if not all(o in by_stripped for o in origins):
            continue
        width = width_px * (column_fraction(by_stripped[origins[0]]) if view == "all" else 1.0)
        shortest = {by_stripped[o]: TAB_TITLES[by_stripped[o]][-1] for o in origins}
        if sum(len(t) * TITLE_PX_PER_CHAR + TAB_EXTRA_PX for t in shortest.values()) + TAB_BAR_ICONS_PX <= width:
            continue
        active = (container.get("active_tab") or container["contents"][0]).lstrip("/")
        for k in keys:
            if k.lstrip("/") != active:
                _remove(bp, views, k)


def _remove_empty_containers(bp: dict[str, Any]) -> None:
    """Take every container left without contents out of its parent and out of the blueprint."""
    while True:
        empty = [k for k, v in bp.items() if "ContainerBlueprint" in v and not v["ContainerBlueprint"].get("contents")]
        if not empty:
            return
        for key in empty:
            ref = key.lstrip("/")
            for value in bp.values():
                container = value.get("ContainerBlueprint")
                if container and ref in [c.lstrip("/") for c in container.get("contents", [])]:
                    container["contents"] = [c for c in container["contents"] if c.lstrip("/") != ref]
                    container.pop("col_shares", None)
                    container.pop("row_shares", None)
            _drop(bp, key)


def _holds(bp: dict[str, Any], key: str, view_key: str) -> bool:
    """Whether the container or view ``key`` is ``view_key`` or holds it."""
    if key.lstrip("/") == view_key.lstrip("/"):
        return True
    return any(_holds(bp, "/" + c.lstrip("/"), view_key)
               for c in bp.get(key, {}).get("ContainerBlueprint", {}).get("contents", []))


def _view_key(views: dict[str, Any], origin: str) -> str | None:
    """The key of the first of ``views`` (key -> ViewBlueprint) whose space origin is ``origin``
    (slashes at either end aside: the viewer writes ``map``, the timeline's ``/``), or None."""
    return next((k for k, vb in views.items() if vb.get("space_origin", "").strip("/") == origin.strip("/")), None)


def _remove(bp: dict[str, Any], views: dict[str, Any], view_key: str | None) -> None:
    """Take the view ``view_key`` (None: nothing) out of its container, whose shares no longer fit
    its contents (the rows' are set again after), out of ``views`` and out of the blueprint; a tab
    bar whose active tab it was shows its first tab."""
    if view_key is None:
        return
    ref = view_key.lstrip("/")
    for value in bp.values():
        container = value.get("ContainerBlueprint")
        if container and ref in [c.lstrip("/") for c in container.get("contents", [])]:
            container["contents"] = [c for c in container["contents"] if c.lstrip("/") != ref]
            container.pop("col_shares", None)
            container.pop("row_shares", None)
            if (container.get("active_tab") or "").lstrip("/") == ref:
                container["active_tab"] = container["contents"][0] if container["contents"] else None
    _drop(bp, view_key)
    views.pop(view_key, None)


def _drop(bp: dict[str, Any], key: str) -> None:
    """Remove a container or view and everything under it from a blueprint dict."""
    for child in bp.get(key, {}).get("ContainerBlueprint", {}).get("contents", []):
        _drop(bp, "/" + child.lstrip("/"))
    for k in [k for k in bp if k == key or k.startswith(key + "/")]:
        del bp[k]


#: Pixels per character of a view title, and what the title bar's icons take (measured on renders).
TITLE_PX_PER_CHAR = 6.3
TITLE_ICONS_PX = 110


def _fit(variants: list[str], width_px: float) -> str:
    """The first (longest) title variant that fits ``width_px``, else the last."""
    budget = (width_px - TITLE_ICONS_PX) / TITLE_PX_PER_CHAR
    return next((v for v in variants if len(v) <= budget), variants[-1])


def titles_for(info: RecordingInfo, shot: Shot, width_px: int) -> dict[str, str]:
    """View titles that say drive, outage and time, and each estimator's final error on the framed
    outage; shortened to fit each view's width (the maximised view has the whole image). Every
    estimator is named by its one label (as tables, legends and figures name it)."""
    ests = ordered_estimators(info)
    legend = ", ".join([f"{info.truth_label} green"] + [f"{label} {color_word(rgb)}" for _, (label, rgb) in ests])
    o = shot.outage
    state = info.state_at(shot.t_s)
    when = f"t = {shot.t_s:.1f} s" + (f", {state}" if state else ", GNSS available")
    if o is not None:
        errs = [(label, name, o.final_error_m.get(name, float("nan"))) for name, (label, _rgb) in ests]
        long_err = ", ".join(f"{lab} ({color_word(info.estimators[n][1])}) {e:.1f} m" for lab, n, e in errs)
        mid_err = ", ".join(f"{lab} {e:.1f} m" for lab, _n, e in errs)
        short_err = ", ".join(f"{lab} {e:.1f}" for lab, _n, e in errs)
        head = o.head
        focus = [f"{head}, final error: {long_err}", f"{head}, final error: {mid_err}",
                 f"{head}, final error (m): {short_err}",
                 f"{'real ' if o.real else ''}#{o.number} {o.span}, final (m): {short_err}",
                 f"{head}, final errors in the key above"]
        shortest = [head]
    else:
        focus, shortest = [when], []
    full = width_px if shot.view != "all" else None
    def w(origin: str) -> float:
        return full or width_px * column_fraction(origin)
    inspected = o or _outage_before(info, shot.t_s)
    inspect_head = inspected.head if inspected else "no outage yet"
    inspect_titles = [f"{info.drive}: {inspect_head}, t = {shot.t_s:.1f} s; m from its start fix, north up",
                      f"{inspect_head}, t = {shot.t_s:.1f} s; m from its start fix", inspect_head]
    titles = {
        ent.INSPECT: _fit([f"{info.drive}: {f}; m from the start fix, north up" for f in focus] + focus + shortest,
                          w(ent.INSPECT)) if o else
        _fit(inspect_titles, w(ent.INSPECT)),
        ent.MAP: _fit(([f"{info.drive}: map, {when} ({legend})"] if o is None else [])
                      + [f"{info.drive}: map, {f}" for f in focus]
                    + shortest + ["Map" + (f", {o.name}" if o else "")], w(ent.MAP)),
        ent.LOCAL: _fit([f"{info.drive}: local east-north (m), north up, {f}" for f in focus]
                      + [f"{info.drive}: east-north (m), {f}" for f in focus]
                      + ["Drive: east-north (m)", "East-north (m)"], w(ent.LOCAL)),
        "/": _fit([f"{info.drive}, {when}", f"{info.drive}, t = {shot.t_s:.1f} s", f"t = {shot.t_s:.1f} s"], w("/")),
        ent.DISPLACEMENTS: _fit([f"{info.drive}: displacement per second (m), {when}", PLOT_NAMES[ent.DISPLACEMENTS],
                                 "Displacement (m)"],
                                w(ent.DISPLACEMENTS)),
        ent.YAW_RATES: _fit([f"{PLOT_NAMES[ent.YAW_RATES]}; gyro grey", PLOT_NAMES[ent.YAW_RATES], "Yaw rate (rad/s)"],
                            w(ent.YAW_RATES)),
        ent.ACCEL: _fit([f"{PLOT_NAMES[ent.ACCEL]}; accelerometer grey", PLOT_NAMES[ent.ACCEL], "Long. accel. (m/s²)"],
                        w(ent.ACCEL)),
        ent.error_group("yaw_crse_radps"): _fit([PLOT_NAMES[ent.error_group("yaw_crse_radps")],
                                                 "Orientation-rate CRSE (rad/s)", "Yaw-rate CRSE (rad/s)"],
                                                w(ent.error_group("yaw_crse_radps"))),
    }
    for tabs in ((ent.error_group("position_error_m"), ent.DRIFT, ent.UNCERTAINTY, ent.HEALTH),
                 (ent.error_group("crse_m"), ent.error_group("cae_m"))):
        titles.update(_fit_tabs(tabs, w(tabs[0])))
    if o is None and shot.view != "all":  # the time plots of a column: say when
        titles[ent.error_group("position_error_m")] = _fit([f"{info.drive}: 2D position error (m), {when}",
                                                            titles[ent.error_group("position_error_m")]],
                                                           w(ent.error_group("position_error_m")))
    return titles


#: What each tab takes beside its title text (icon and padding, measured on renders), and what the
#: tab bar's own buttons take.
TAB_EXTRA_PX, TAB_BAR_ICONS_PX = 36, 100


def _fit_tabs(origins: tuple[str, ...], width_px: float) -> dict[str, str]:
    """Titles of tabs sharing one bar: the longest level of :data:`TAB_TITLES` at which all fit."""
    levels = max(len(TAB_TITLES[o]) for o in origins)
    for level in range(levels):
        chosen = {o: TAB_TITLES[o][min(level, len(TAB_TITLES[o]) - 1)] for o in origins}
        needed = sum(len(t) * TITLE_PX_PER_CHAR + TAB_EXTRA_PX for t in chosen.values()) + TAB_BAR_ICONS_PX
        if needed <= width_px:
            return chosen
    return chosen


def ordered_estimators(info: RecordingInfo) -> list[tuple[str, tuple[str, tuple[int, int, int]]]]:
    """The recording's estimators as (name, (label, colour)): the baseline first, then by label."""
    return sorted(info.estimators.items(), key=lambda kv: (kv[0] != BASELINE, kv[1][0]))


@dataclass(frozen=True)
class KeyEntry:
    """One item of a screenshot's colour key: a line or a dot of a colour, and what it is."""

    mark: str  # "line", "dot" or "ellipse" (an outline)
    rgb: tuple[int, int, int]
    text: str


def key_for(info: RecordingInfo, shot: Shot, accel: bool = True) -> list[KeyEntry]:
    """The colour key of a screenshot: every track or curve the shot draws, the truth first, with
    each estimator's final error when the shot frames an outage; the overview's markers where the
    shot shows them (the local view and map: manoeuvres and outage starts, and beside a reference
    the receiver's own fixes; the inspector: the outage's start fix); the sensors' grey lines where
    the signals are shown (the gyro's alone without the ``accel`` plot: :func:`shot_rows`); the
    estimators' 95 % position ellipses where the tracks are shown and the recording draws them."""
    from .style import EVENT_COLOR, GNSS_COLOR, GYRO_COLOR, OUTAGE_MARK_COLOR, RECEIVER_COLOR

    view = shot.view
    if view == "health":  # per filter and kind of measurement
        return [KeyEntry("line", rgb, label) for label, rgb in info.health] + [
            KeyEntry("line", (90, 90, 90), "1: a consistent filter's mean NIS; crosses: fixes its gate left out")]
    keys = [] if view == "errors" else [KeyEntry("line", GNSS_COLOR, info.truth_label)]
    for name, (label, rgb) in ordered_estimators(info):
        final = shot.outage.final_error_m.get(name) if shot.outage is not None else None
        keys.append(KeyEntry("line", rgb, f"{label} {final:.1f} m" if final is not None and final == final else label))
    if view in ("all", "signals"):
        keys.append(KeyEntry("line", GYRO_COLOR, "gyro, accelerometer" if accel else "gyro"))
    if view in ("all", "local", "map") and info.receiver:  # beside a reference: the fixes the estimators were given
        keys.append(KeyEntry("dot", RECEIVER_COLOR, "receiver fixes"))
    if view in ("all", "local", "map"):
        marks = (["outage start"] * bool(info.outages or not info.real_outages)
                 + ["first fix after a real loss"] * bool(info.real_outages))
        keys += [KeyEntry("dot", EVENT_COLOR, "manoeuvre"), KeyEntry("dot", OUTAGE_MARK_COLOR, ", ".join(marks))]
    if view == "outage":
        keys.append(KeyEntry("dot", OUTAGE_MARK_COLOR, "start fix"))
    # the estimators' 95 % ellipses (in their colours) around their positions, once an outage has begun;
    # on a whole-drive local or map view they are a few pixels: named only where a view frames an outage
    framed = shot.outage is not None
    shown = framed or (view in ("all", "outage") and _outage_before(info, shot.t_s) is not None)
    if view in ("all", "local", "map", "outage") and info.ellipses and shown:
        keys.append(KeyEntry("ellipse", ELLIPSE_KEY_COLOR, "95 % ellipse"))
    return keys


def _outage_before(info: RecordingInfo, t_s: float) -> OutageInfo | None:
    """The outage the inspector shows at ``t_s``: the one under way, else the last one begun
    before, synthetic or one of the log's own losses."""
    started = [o for o in info.outages + info.real_outages if o.start_s + ent.OUTAGE_EPS_S <= t_s + 1e-9]
    return max(started, key=lambda o: o.start_s) if started else None


