"""The recording's own layout as a browser shows it (``replay --serve-web``, issue 63): read back from
the ``.rrd`` a replay writes (its blueprint and its state lanes), no viewer needed. On the page the
layout is made for (1280x720) the web viewer cut view titles at their view's edge ("Drive:
east-north (", the tabs "Drift: error (m" and "Displaceme"), hid the third state lane (the
outages) below the timeline's edge, cut the summary's table, and cut state labels at their span's
end ("bra" of a 3 s hard brake)."""

import uuid

import numpy as np
import pytest

from ionav_viz.viz import entities as ent
from ionav_viz.viz.blueprints import (
    NARROWEST_PX,
    STATE_LABEL_PAD_PX,
    STATE_LABEL_PX_PER_CHAR,
    TAB_BAR_ICONS_PX,
    TAB_EXTRA_PX,
    TITLE_ICONS_PX,
    TITLE_PX_PER_CHAR,
    WEB_CHROME_PX,
    WEB_PAGE_PX,
    column_fraction,
    state_view_s,
    summary_px,
)

from .conftest import run_cli

pytestmark = pytest.mark.xdist_group("web_layout")

#: Container kinds as the viewer stores them.
TABS, HORIZONTAL, VERTICAL = 1, 2, 3
#: What the state timeline needs for its three lanes (title bar, time axis, and each lane's name
#: above its bar; pixels, measured on the served page at 1280x720).
THREE_LANES_PX = 170


def _stores(path):
    from rerun.chunk import RrdReader

    reader = RrdReader(str(path))
    [recording] = reader.recordings()
    [layout] = reader.blueprints()
    return reader, recording, layout


def _components(chunk) -> dict:
    batch = chunk.to_record_batch()
    return {n.split(":")[-1]: batch.column(n).to_pylist()[-1] for n in batch.schema.names if ":" in n}


@pytest.fixture(scope="module")
def hard_brake(tmp_path_factory):
    """hard-brake replayed with every built-in estimator that reports a covariance or health: four
    error tabs (position error, drift, sigma, NIS), the brakes' short spans on the manoeuvre lane."""
    out = tmp_path_factory.mktemp("web") / "hb.rrd"
    proc = run_cli("replay", "hard-brake", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def roundabout(tmp_path_factory):
    """roundabout replayed: its last outage's frame (a bend north) fills the inspector's height."""
    out = tmp_path_factory.mktemp("web") / "rb.rrd"
    proc = run_cli("replay", "roundabout", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    return out


def _layout(path) -> tuple[str, dict[str, dict]]:
    """The layout's root container and every container and view of it (by ``container/<id>``, ``view/<id>``)."""
    reader, _, layout = _stores(path)
    items, root = {}, None
    for chunk in reader.stream(store=layout):
        entity = str(chunk.entity_path).strip("/")
        if entity == "viewport":
            root = "container/" + str(uuid.UUID(bytes=bytes(_components(chunk)["root_container"][0])))
        elif entity.count("/") == 1 and entity.startswith(("container/", "view/")):
            items.setdefault(entity, {}).update(_components(chunk))
    return root, items


def _widths(root: str, items: dict[str, dict], width_px: float, height_px: float) -> dict[str, tuple[float, float, list[str]]]:
    """Each view's (width, height) in pixels on a page of the views' ``width_px`` x ``height_px``,
    and the tabs sharing its bar (itself alone outside a tab bar)."""
    out = {}

    def walk(key: str, w: float, h: float, tabs: list[str]) -> None:
        item = items[key]
        if key.startswith("view/"):
            out[key] = (w, h, tabs or [key])
            return
        contents, kind = item["contents"], item["container_kind"][0]
        if kind == TABS:
            for child in contents:
                walk(child, w, h, list(contents))
            return
        shares = item.get("col_shares" if kind == HORIZONTAL else "row_shares") or [1.0] * len(contents)
        for child, share in zip(contents, shares):
            part = share / sum(shares)
            walk(child, w * part if kind == HORIZONTAL else w, h * part if kind == VERTICAL else h, [])

    walk(root, width_px, height_px, [])
    return out


def test_every_title_shows_whole_on_the_page_the_layout_is_made_for(hard_brake):
    """At 1280x720 every view title fits its view and the tabs of a bar fit it together (the title
    font's measured width per character, the icons beside), the state timeline has room for its
    three lanes and the summary for its table (a row per estimator)."""
    root, items = _layout(hard_brake)
    views = _widths(root, items, WEB_PAGE_PX[0], WEB_PAGE_PX[1] - WEB_CHROME_PX)
    name = {k: v["display_name"][0] for k, v in items.items() if k.startswith("view/")}
    origin = {k: v["space_origin"][0].strip("/") for k, v in items.items() if k.startswith("view/")}
    tabbed = {o for k, (_, _, tabs) in views.items() if len(tabs) > 1 for o in (origin[k],)}
    assert {ent.error_group("position_error_m"), ent.DRIFT, ent.UNCERTAINTY, ent.HEALTH} <= tabbed  # four error tabs
    for key, (width, _height, tabs) in views.items():
        if len(tabs) > 1:
            needed = sum(len(name[t]) * TITLE_PX_PER_CHAR + TAB_EXTRA_PX for t in tabs) + TAB_BAR_ICONS_PX
        else:
            needed = len(name[key]) * TITLE_PX_PER_CHAR + TITLE_ICONS_PX
        assert needed <= width, (origin[key], name[key], [name[t] for t in tabs], round(width))
    height = {origin[k] or items[k]["class_identifier"][0]: h for k, (_, h, _) in views.items()}
    assert height["StateTimeline"] >= THREE_LANES_PX, height["StateTimeline"]
    assert height[ent.OVERVIEW] >= summary_px(4), height[ent.OVERVIEW]  # INS DR, IDNN, odometry, GNSS-aided INS


def _lanes(path, ends: dict | None = None) -> tuple[dict, dict, float]:
    """The state lanes of a recording: each lane's labels by value, its (time, value) changes, and the
    drive's last time (s), the last of its data but the lanes' empty states (their ends, and the
    ruler's end after the drive); those go into ``ends`` by lane, with the recording's last time."""
    reader, recording, _ = _stores(path)
    lanes = (ent.GNSS_STATE, ent.GNSS_QUALITY, ent.EVENTS_STATE)
    labels, changes, end_s, last_s = {}, {lane: [] for lane in lanes}, 0.0, 0.0
    for chunk in reader.stream(store=recording):
        entity = str(chunk.entity_path).strip("/")
        batch = chunk.to_record_batch()
        t_s = batch.column("time").cast("int64").to_numpy() / 1e9 if "time" in batch.schema.names else np.zeros(0)
        if len(t_s):
            last_s = max(last_s, float(t_s.max()))
        if entity not in lanes:
            end_s = max([end_s, *t_s])
            continue
        if chunk.is_static:
            found = _components(chunk)
            labels[entity] = dict(zip(found["values"], found["labels"]))
        else:
            column = next(n for n in batch.schema.names if n.endswith(":state"))
            for t, v in zip(t_s, batch.column(column).to_pylist()):
                if v[0] is None:
                    (ends if ends is not None else {}).setdefault(entity, []).append(float(t))
                else:
                    changes[entity].append((t, v[0]))
                    end_s = max(end_s, float(t))
    if ends is not None:
        ends["recording"] = last_s
    return labels, changes, end_s


def test_every_state_label_fits_its_span(hard_brake):
    """Each span's label fits that span in the state timeline's default view (the whole drive, with
    the room :func:`state_view_s` leaves, across the signals column of the narrowest image, 1024 px),
    or is whole wherever the viewer draws it (two characters: it draws none in a span of 16 px or
    less); else the span shows its colour and no label. Issue 63: the viewer's hover text shows the
    label, not the value, so the outages' spans, too short for "#28" at the whole-drive zoom, were
    blank there and in the hover; they are now "28" (drawn where the span is 18 px or wider, as in
    the signals view of a 1600 px image, and named in the hover), the brakes "3". Each span has its
    own value, so that a short span of a state no longer blanks the label of a long one (the viewer
    labels a value, not a span)."""
    labels, changes, end_s = _lanes(hard_brake)
    t0_s, t1_s = state_view_s(end_s)
    px_per_s = NARROWEST_PX * column_fraction("/") / (t1_s - t0_s)
    seen = set()
    for lane, rows in changes.items():
        rows = sorted(rows)
        ends = [t for t, _ in rows[1:]] + [end_s]
        assert len({v for _, v in rows}) == len(rows), lane  # a value per span
        for (t0, state), t1 in zip(rows, ends):
            label = labels[lane][state]
            assert label != "", (lane, state)  # an empty label falls back to the whole state, cut
            fits = len(label) * STATE_LABEL_PX_PER_CHAR + STATE_LABEL_PAD_PX <= (t1 - t0) * px_per_s
            assert fits or not label.strip() or len(label) <= 2, (lane, state, label, t1 - t0)
            seen.add((ent.base_state(state).rpartition(" #")[0] or ent.base_state(state), label))
            if (n := ent.parse_outage_state(ent.base_state(state))) is not None:
                assert label in (f"#{n}", f"{n}"), (state, label)  # never blank: the hover shows the label
    assert ("hard-brake", "3") in seen and ("good", "good") in seen
    assert any(state.startswith("outage ") and label.isdigit() for state, label in seen), sorted(seen)


def test_the_state_timeline_opens_on_the_whole_drive(hard_brake):
    """The state timeline's default range holds the whole drive with room on either side: no span
    crosses its edges, where the viewer drew a label from the span's visible start and cut it at
    the span's end ("cr" of "cruise"); the time axis is seconds into the drive."""
    _root, items = _layout(hard_brake)
    _, _, end_s = _lanes(hard_brake)
    reader, _, layout = _stores(hard_brake)
    [timeline] = [k for k, v in items.items() if v.get("class_identifier", [""])[0] == "StateTimeline"]
    ranges = [_components(c)["view_range"] for c in reader.stream(store=layout)
              if str(c.entity_path).strip("/").startswith(timeline + "/") and "TimeAxis" in str(c.entity_path)]
    assert ranges, "no time axis on the state timeline"
    [[view]] = ranges
    start_s, stop_s = view["start"] / 1e9, view["end"] / 1e9  # absolute times (ns)
    assert start_s < 0 and stop_s > end_s and (stop_s - end_s) >= 0.05 * end_s, (start_s, stop_s, end_s)


#: Pixels below the inspector's scale bar its label takes (the label's box under the bar; measured on
#: the served page, where 18 px cut "20 m" in half).
SCALE_LABEL_PX = 24


def test_the_inspectors_scale_label_is_inside_its_view(roundabout):
    """In every outage the inspector's scale bar lies high enough in its frame that its label, below
    it, is inside the view on the page the layout is made for (the viewer fits the frame, its grid,
    to the view and centres it): roundabout's outage 57, whose frame fills the view's height, had
    17 px below its bar, "20 m" cut in half."""
    from ionav_viz.viz.blueprints import TITLE_BAR_PX

    root, items = _layout(roundabout)
    [(width_px, height_px)] = [(w, h - TITLE_BAR_PX) for k, (w, h, _) in _widths(root, items, WEB_PAGE_PX[0], WEB_PAGE_PX[1] - WEB_CHROME_PX).items()
                               if items[k]["space_origin"][0].strip("/") == ent.INSPECT]
    reader, recording, _ = _stores(roundabout)
    strips = {}
    for chunk in reader.stream(store=recording):
        entity = str(chunk.entity_path).strip("/")
        if entity in (ent.INSPECT_GRID, ent.INSPECT_SCALE) and not chunk.is_static:
            batch = chunk.to_record_batch()
            column = next(n for n in batch.schema.names if n.endswith(":strips"))
            times = batch.column("time").cast("int64").to_pylist()
            strips.setdefault(entity, {}).update(zip(times, batch.column(column).to_pylist()))
    rooms = []
    for t, grid in strips[ent.INSPECT_GRID].items():
        xy = np.array([p for line in grid for p in line], dtype=float)
        (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)  # screen y grows downwards: the bottom is y1
        px_per_m = min(width_px / (x1 - x0), height_px / (y1 - y0))
        view_bottom = (y0 + y1) / 2 + height_px / px_per_m / 2
        [bar] = strips[ent.INSPECT_SCALE][t]
        rooms.append((view_bottom - bar[0][1]) * px_per_m)
    assert len(rooms) == 57 and min(rooms) >= SCALE_LABEL_PX, sorted(rooms)[:5]


def test_every_time_plot_opens_on_the_whole_drive_with_labelled_y_ticks(hard_brake):
    """On the page the layout is made for, every time plot opens on the whole drive, as the state
    timeline (nothing scrolls with the time cursor, which cut the first tick's label at the view's
    edge: "9m 30s"), and its y range has at least two labelled ticks at its height (the viewer
    labels ticks a power of ten apart, and only :data:`FAINT_TICK_PX` or more apart: its own fit of
    an error plot 90 px high labelled only "0" of errors up to 9 m)."""
    import math

    from ionav_viz.viz.blueprints import FAINT_TICK_PX, web_plot_px

    _root, items = _layout(hard_brake)
    _, _, end_s = _lanes(hard_brake)
    reader, _, layout = _stores(hard_brake)
    props = {}
    for chunk in reader.stream(store=layout):
        path = str(chunk.entity_path).strip("/").split("/")
        if len(path) == 3 and path[0] == "view":
            props.setdefault(f"view/{path[1]}", {}).update(_components(chunk))
    heights = web_plot_px(4)
    plots = {items[k]["space_origin"][0].strip("/"): k for k, v in items.items()
             if v.get("class_identifier", [""])[0] == "TimeSeries"}
    assert set(heights) <= set(plots) | {ent.UNCERTAINTY, ent.HEALTH}, set(heights) - set(plots)
    for origin, key in plots.items():
        view = props[key]["view_range"][0]
        assert (view["start"] / 1e9, view["end"] / 1e9) == pytest.approx(state_view_s(end_s)), origin
        if origin not in heights:  # sigma and NIS tabs: the viewer's own fit
            continue
        lo, hi = props[key]["range"][0]
        labelled = max(sum(1 for _ in range(math.ceil(lo / 10.0 ** k), math.floor(hi / 10.0 ** k) + 1))
                       for k in range(-4, 4) if heights[origin] * 10.0 ** k / (hi - lo) >= FAINT_TICK_PX)
        assert labelled >= 2, (origin, lo, hi, heights[origin])


def test_small_values_fill_their_plot_on_the_page():
    """On the page, the orientation-rate CRSE plot (69 px of plot) of the roundabout drive (0 to
    0.271 rad/s) was labelled 0, 1 and 2: the three-labels rule at 23 px a tick took ticks of 1,
    and the data lay in the bottom tenth. It now has ticks of 0.1 (0, 0.1, 0.2, labelled 20 px or
    more apart, as the viewer still draws them), the data filling most of the plot, the outer labels
    whole; where a coarse step leaves the data room enough, nothing changes, nor in screenshots."""
    import math

    from ionav_viz.viz.blueprints import (
        FAINT_TICK_PX,
        LABEL_MARGIN_PX,
        TICK_PX,
        axis_range,
        plot_range,
        web_plot_px,
    )

    px = web_plot_px(4)[ent.error_group("yaw_crse_radps")]
    assert 60 < px < 80  # the page's smallest error plot
    lo, hi = plot_range(ent.error_group("yaw_crse_radps"), 2.4e-5, 0.271, pad=False)
    a, b = axis_range(lo, hi, px, faint=True)
    assert a <= lo and b >= hi and (hi - lo) / (b - a) > 0.8, (a, b)
    step = 0.1
    assert FAINT_TICK_PX <= px * step / (b - a) < TICK_PX
    ticks = np.arange(math.ceil(a / step), math.floor(b / step) + 1) * step
    assert len(ticks) == 3 and min(ticks[0] - a, b - ticks[-1]) * px / (b - a) >= LABEL_MARGIN_PX - 0.01
    # screenshots keep ticks labelled 23 px apart (their plots are made high enough for them)
    assert axis_range(lo, hi, px) == pytest.approx((-0.253, 2.253), abs=1e-3)
    # errors up to 29 m in the page's 92 px plots: ticks of 10 at 23 px or more, as before
    a, b = axis_range(0.0, 29.18, web_plot_px(4)[ent.error_group("position_error_m")])
    assert (a, b) == pytest.approx((-2.68, 32.68), abs=1e-2)


def test_the_lanes_end_at_the_drive_and_the_ruler_where_its_last_label_is_whole(hard_brake):
    """Rerun's state timeline draws its time ruler over the recording's data, from its first to its
    last time on the ``time`` timeline, whatever the view's range, and cuts a tick label that runs
    past it: a drive ending at 600 s showed a lone "+" of "+10m" at the ruler's end, in screenshots
    and on the page. Each lane now ends at the drive's end with an empty state (no span drawn
    open-ended past it), and a second empty state sets the recording's last time to the ruler's
    end (:func:`ruler_end_s`), where its last label is whole at every width the layout is made for;
    the state timeline and the time plots open on the drive and the ruler (:func:`state_view_s`)."""
    from ionav_viz.viz.blueprints import PAGE_RULER_WIDTHS_PX, RULER_WIDTHS_PX, ruler_cuts_a_label, ruler_end_s

    ends: dict = {}
    _, changes, end_s = _lanes(hard_brake, ends)
    assert end_s == pytest.approx(600.0, abs=0.2)
    ruler_s = ruler_end_s(end_s)
    assert ends["recording"] == pytest.approx(ruler_s) and end_s + 1.0 < ruler_s < 1.15 * end_s
    for lane in (ent.GNSS_STATE, ent.GNSS_QUALITY, ent.EVENTS_STATE):
        assert max(t for t, _ in changes[lane]) < ends[lane][-2] <= end_s + 1e-6 and ends[lane][-1] == pytest.approx(ruler_s)
    view = state_view_s(end_s)
    assert view[1] > ruler_s
    assert not any(ruler_cuts_a_label(ruler_s, view, w) for w in RULER_WIDTHS_PX)
    assert all(ruler_cuts_a_label(end_s, (view[0], end_s + 0.05 * end_s), w) for w in (0.3 * 1024, 0.3 * 1600, 0.3 * 1280))
    # the page opens with the time cursor at the recording's last time: clear of "+10m" there (27 px from its tick at
    # 600 s, the cursor's head 7 px each side), as it was not at 651 s, the end chosen before for the label alone
    assert not any(ruler_cuts_a_label(ruler_s, view, w, cursor=True) for w in PAGE_RULER_WIDTHS_PX)
    old = (view[0], 651.0 + 0.05 * end_s)
    assert not ruler_cuts_a_label(651.0, old, 0.3 * 1280) and ruler_cuts_a_label(651.0, old, 0.3 * 1280, cursor=True)


def test_no_two_spans_of_a_lane_touch(hard_brake):
    """Rerun 0.41's state timeline folds a run of consecutive spans each under 4 px into one grey
    block labelled "N states", and cuts that label where the block is narrower ("13 sta" of
    sharp-cornering's manoeuvres at 1024x576); an empty state ends such a run. Every span of every
    lane now ends 1 ms before the next one starts (an empty state there: far under a pixel), so no
    two spans are consecutive and the viewer draws each alone, in its own colour."""
    ends: dict = {}
    _, changes, _ = _lanes(hard_brake, ends)
    for lane in (ent.GNSS_STATE, ent.GNSS_QUALITY, ent.EVENTS_STATE):
        rows = sorted([(t, v) for t, v in changes[lane]] + [(t, None) for t in ends[lane]], key=lambda r: r[0])
        assert len(changes[lane]) >= 1
        assert all(a[1] is None or b[1] is None for a, b in zip(rows, rows[1:])), lane
        starts = np.array([t for t, _ in changes[lane]])
        breaks = np.array(ends[lane][:-2])  # the last two: the lane's end at the drive's, the ruler's
        assert len(breaks) == len(starts) - 1
        assert np.allclose(starts[1:] - breaks, 1e-3, atol=1e-6), lane
