"""The recording's review layout, and how each screenshot changes it: which view, framed where,
with which titles. The layout's column shares have one home here, for the blueprint and for the
title widths."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..core.errors import InputError
from ..nav.protocol import short_label
from ..nav.registry import BASELINE
from . import entities as ent
from .geometry import map_zoom, padded_bounds
from .recording_info import OutageInfo, RecordingInfo
from .style import color_word

#: Views a screenshot shows: the whole review layout, or one view (maximised) or column of plots.
VIEWS = ("all", "outage", "map", "local", "signals", "errors", "health")
_ORIGINS = {"outage": ent.INSPECT, "map": ent.MAP, "local": ent.LOCAL, "signals": ent.DISPLACEMENTS, "errors": ent.error_group("position_error_m"),
            "health": ent.HEALTH}
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


INSPECTOR_NAME = "Current outage: m from its start fix, north up"
#: The local view shows the whole drive's scale bar; framed on an outage (screenshots), that outage's.
LOCAL_CONTENTS = ["+ $origin/**", f"- /{ent.LOCAL_SCALE}"]
LOCAL_FRAMED_CONTENTS = ["+ $origin/**", f"- /{ent.LOCAL_GRID_SCALE}"]


def blueprint(labels: list[str], zoom: float = 16.0):
    """The default review layout: the outage inspector above the whole-drive local and map views,
    the signals, the errors and the summary."""
    import rerun.blueprint as rrb

    tracks = rrb.Vertical(
        rrb.Spatial2DView(origin=ent.INSPECT, name=INSPECTOR_NAME),
        rrb.Horizontal(
            rrb.Spatial2DView(origin=ent.LOCAL, contents=LOCAL_CONTENTS, name="Drive: east-north (m)"),
            rrb.MapView(origin=ent.MAP, name="Map", zoom=zoom),
        ),
        row_shares=[3, 2],
    )
    # Legends where the lines are first met (and the yaw rate's gyro); more would cover the data.
    hidden = rrb.PlotLegend(visible=False)
    signals = rrb.Vertical(
        rrb.StateTimelineView(origin="/", contents=[ent.GNSS_STATE, ent.GNSS_QUALITY, ent.EVENTS_STATE],
                              name="GNSS, outages, manoeuvres"),
        rrb.TimeSeriesView(origin=ent.DISPLACEMENTS, name="Displacement per second (m)"),
        rrb.TimeSeriesView(origin=ent.YAW_RATES, name="Yaw rate (rad/s, CCW +; gyro grey)", plot_legend=hidden),
        rrb.TimeSeriesView(origin=ent.ACCEL, name="Longitudinal acceleration (m/s²)", plot_legend=hidden),
        row_shares=[2.8, 3, 3, 2],
    )
    errors = rrb.Vertical(
        rrb.Tabs(
            rrb.TimeSeriesView(origin=ent.error_group("position_error_m"), name="2D position error (m)"),
            rrb.Spatial2DView(origin=ent.DRIFT, name="Drift: error (m) by s into the outage; mean, 10-90 %, current"),
            rrb.TimeSeriesView(origin=ent.HEALTH, name="Filter health: NIS, 10 s mean (1 = consistent; x gated out)"),
            active_tab=0,
        ),
        rrb.Tabs(
            rrb.TimeSeriesView(origin=ent.error_group("crse_m"), name="Displacement CRSE (m)", plot_legend=hidden),
            rrb.TimeSeriesView(origin=ent.error_group("cae_m"), name="Displacement CAE (m)", plot_legend=hidden),
        ),
        rrb.TimeSeriesView(origin=ent.error_group("yaw_crse_radps"), name="Orientation-rate CRSE (rad/s)", plot_legend=hidden),
        rrb.Tabs(rrb.TextDocumentView(origin=ent.OVERVIEW, name="Summary"), rrb.TextDocumentView(origin=ent.SUMMARY, name="Details"),
                 active_tab=0),
        row_shares=list(ERROR_COLUMN_SHARES),
    )
    return rrb.Blueprint(rrb.Horizontal(tracks, signals, errors, column_shares=list(COLUMN_SHARES)), collapse_panels=True)


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
    entities = [ent.outage_truth(ent.MAP), ent.MAP_CONTEXT, *(ent.live_track(ent.MAP, name) for name in info.estimators)]
    return Framing(zoom, bounds, entities)


#: The error column's rows: position error, CRSE/CAE, orientation-rate CRSE, the summary tabs; in
#: screenshots of the whole layout the summary gets more, so that it is never cut.
ERROR_COLUMN_SHARES = (3, 3, 2.5, 3.5)
SCREENSHOT_ERROR_SHARES = (2.3, 2.3, 1.9, 5.5)
#: Seconds of the drive a screenshot's time plots show: centred on the shot's time, kept inside the drive.
PLOT_WINDOW_S = 60.0
#: The viewer's panels a screenshot hides (only the views are drawn: no menu, badges or timeline).
HIDDEN_PANELS = {"/top_panel": "PanelBlueprint", "/blueprint_panel": "PanelBlueprint", "/selection_panel": "PanelBlueprint",
                 "/time_panel": "TimePanelBlueprint"}


def plot_window(t_s: float, end_s: float, width_s: float = PLOT_WINDOW_S) -> tuple[float, float]:
    """The time plots' x range (s) for a shot at ``t_s`` of a drive ending at ``end_s``: ``width_s``
    centred on ``t_s``, shifted to lie inside ``[0, end_s]`` (the whole drive when it is shorter)."""
    if end_s <= width_s:
        return 0.0, max(end_s, 1.0)
    start = min(max(t_s - width_s / 2, 0.0), end_s - width_s)
    return start, start + width_s


def focus_blueprint(blueprint: dict[str, Any], view: str, titles: dict[str, str], frame: Framing | None = None,
                    t_s: float | None = None, end_s: float | None = None, map_tiles: bool = True) -> dict[str, Any]:
    """The recording's blueprint showing only ``view``, with view titles from ``titles`` (by
    origin) and the map and local views framed as ``frame`` says; the viewer's panels hidden;
    with ``t_s`` and ``end_s``, the time plots showing :func:`plot_window`; without
    ``map_tiles`` (they cannot load: offline), the map view left out and the local view in its place."""
    frame = frame or Framing()
    bp = {k: {a: dict(f) for a, f in v.items()} for k, v in blueprint.items()}
    for key, archetype in HIDDEN_PANELS.items():
        bp[key] = {archetype: {**bp.get(key, {}).get(archetype, {}), "state": "Hidden"}}
    views = {k: v["ViewBlueprint"] for k, v in bp.items() if "ViewBlueprint" in v}
    if t_s is not None and end_s is not None:
        x0, x1 = plot_window(t_s, end_s)
        for key, vb in views.items():
            if vb.get("class_identifier") == "TimeSeries":
                bp[key + "/TimeAxis"] = {"TimeAxis": {"view_range": {"start": {"Absolute": int(round(x0 * 1e9))},
                                                                     "end": {"Absolute": int(round(x1 * 1e9))}}}}
    if not map_tiles:
        if view == "map":
            view = "local"
        map_key = next((k for k, vb in views.items() if vb.get("space_origin") == ent.MAP), None)
        if map_key is not None:
            ref = map_key.lstrip("/")
            for value in bp.values():
                container = value.get("ContainerBlueprint")
                if container and ref in [c.lstrip("/") for c in container.get("contents", [])]:
                    keep = [c for c in container["contents"] if c.lstrip("/") != ref]
                    container["contents"] = keep
                    container.pop("col_shares", None)
                    container.pop("row_shares", None)
            _drop(bp, map_key)
            views.pop(map_key)
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
    if view in ("all", "errors"):  # the layouts that show the summary: room for all of it
        summary_key = next((k for k, vb in views.items() if vb.get("space_origin") == ent.OVERVIEW), None)
        for value in bp.values():
            container = value.get("ContainerBlueprint", {})
            tabs = [c.lstrip("/") for c in container.get("contents", [])]
            if summary_key is not None and container.get("row_shares") and len(container["row_shares"]) == len(SCREENSHOT_ERROR_SHARES) \
                    and any(_holds(bp, "/" + c, summary_key) for c in tabs):
                container["row_shares"] = list(SCREENSHOT_ERROR_SHARES)
    if view == "all":
        return bp
    target = _ORIGINS[view]
    view_key = next((k for k, vb in views.items() if vb.get("space_origin") == target), None)
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


def _holds(bp: dict[str, Any], key: str, view_key: str) -> bool:
    """Whether the container or view ``key`` is ``view_key`` or holds it."""
    if key.lstrip("/") == view_key.lstrip("/"):
        return True
    return any(_holds(bp, "/" + c.lstrip("/"), view_key) for c in bp.get(key, {}).get("ContainerBlueprint", {}).get("contents", []))


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
    outage; shortened to fit each view's width (the maximised view has the whole image)."""
    ests = sorted(info.estimators.items(), key=lambda kv: (kv[0] != BASELINE, kv[1][0]))  # as the plot legends
    legend = ", ".join(["GNSS green"] + [f"{short_label(label)} {color_word(rgb)}" for _, (label, rgb) in ests])
    o = shot.outage
    state = info.state_at(shot.t_s)
    when = f"t = {shot.t_s:.1f} s" + (f", {state}" if state else ", GNSS available")
    if o is not None:
        errs = [(short_label(label), name, o.final_error_m.get(name, float("nan"))) for name, (label, _rgb) in ests]
        long_err = ", ".join(f"{lab} ({color_word(info.estimators[n][1])}) {e:.1f} m" for lab, n, e in errs)
        mid_err = ", ".join(f"{lab} {e:.1f} m" for lab, _n, e in errs)
        short_err = ", ".join(f"{n} {e:.1f}" for _lab, n, e in errs)
        head = f"outage {o.number} ({o.span})"
        focus = [f"{head}, final error: {long_err}", f"{head}, final error: {mid_err}", f"{head}, final error (m): {short_err}",
                 f"#{o.number} {o.span}, final: {short_err} m", f"outage {o.number}, final (m): {short_err}"]
    else:
        focus = [when]
    full = width_px if shot.view != "all" else None
    def w(origin: str) -> float:
        return full or width_px * column_fraction(origin)
    inspected = o or _outage_before(info, shot.t_s)
    inspect_head = f"outage {inspected.number} ({inspected.span})" if inspected else "no outage yet"
    titles = {
        ent.INSPECT: _fit([f"{info.drive}: {f}; m from the start fix, north up" for f in focus] + focus, w(ent.INSPECT)) if o else
        _fit([f"{info.drive}: {inspect_head}, t = {shot.t_s:.1f} s; m from its start fix, north up",
              f"{inspect_head}, t = {shot.t_s:.1f} s; m from its start fix", inspect_head], w(ent.INSPECT)),
        ent.MAP: _fit(([f"{info.drive}: map, {when} ({legend})"] if o is None else []) + [f"{info.drive}: map, {f}" for f in focus]
                    + ["Map" + (f", outage {o.number}" if o else "")], w(ent.MAP)),
        ent.LOCAL: _fit([f"{info.drive}: local east-north (m), north up, {f}" for f in focus]
                      + [f"{info.drive}: east-north (m), {f}" for f in focus] + ["Drive: east-north (m)"], w(ent.LOCAL)),
        "/": _fit([f"{info.drive}, {when}", f"{info.drive}, t = {shot.t_s:.1f} s", f"t = {shot.t_s:.1f} s"], w("/")),
        ent.DISPLACEMENTS: _fit([f"{info.drive}: displacement per second (m), {when}", "Displacement per second (m)"], w(ent.DISPLACEMENTS)),
        ent.error_group("position_error_m"): _fit([f"{info.drive}: 2D position error (m), {when}", "2D position error (m)"],
                                                  w(ent.error_group("position_error_m"))),
    }
    return titles


def _outage_before(info: RecordingInfo, t_s: float) -> OutageInfo | None:
    """The outage the inspector shows at ``t_s``: the one under way, else the last one before."""
    started = [o for o in info.outages if o.start_s + ent.OUTAGE_EPS_S <= t_s + 1e-9]
    return started[-1] if started else None


