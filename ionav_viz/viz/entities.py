"""The recording's entity paths and state labels: built here, parsed back here, nowhere else.

A recording is a contract between the writer (:mod:`ionav_viz.viz.recording`), the screenshot
code that reads it back (:mod:`ionav_viz.viz.recording_info`), the blueprints that show it, and
the users who open it (``docs/recording.md`` lists :data:`PATTERNS`; a test keeps them equal).

Paths are written without a leading ``/``; Rerun reads them back with one (:func:`parse`
accepts both). ``view`` is ``"map"`` (lat/lon) or ``"local"`` (east-north metres); ``est`` an
estimator's name; ``source`` of a signal is ``"gyro"``, ``"gnss"`` or an estimator's name.
"""

from __future__ import annotations

import re

MAP, LOCAL, INSPECT = "map", "local", "inspect"
VIEWS_2D = (MAP, LOCAL)
#: The cumulative error series of each estimator inside each outage (``errors/<metric>/<est>``).
ERROR_METRICS = ("crse_m", "cae_m", "yaw_crse_radps", "position_error_m")

#: Per-outage rows are logged this long (s) after the outage's start, so at the start time itself
#: (the end of the previous outage, when outages follow each other) the previous one is still shown.
OUTAGE_EPS_S = 1e-3

GNSS_STATE = "gnss/state"
GNSS_QUALITY = "gnss/quality"
GNSS_AVAILABLE = "gnss/available"
EVENTS_STATE = "events/state"
SUMMARY = "summary"
#: The summary's head (means and the worst outages), the review layout's first text tab: it fits a screenshot.
OVERVIEW = "overview"
#: The run's report as ``evaluate --json`` prints it (plain text), for ``ionav-viz figures``.
REPORT = "report"
#: Markdown: which colour is which line, above the signals in the viewer (the plots show no legend).
KEY = "key"
ACCEL = "signals/accel_long_mps2"
SPEED = "signals/speed_mps"
YAW_RATES = "signals/yaw_rate_radps"
DISPLACEMENTS = "signals/displacement_m"
ERRORS = "errors"
MAP_CONTEXT = "map/gnss/context"
LOCAL_GRID = "local/grid"
LOCAL_GRID_SCALE = "local/grid/scale"
LOCAL_SCALE = "local/scale"
LOCAL_OUTAGES = "local/outages"
#: The drift view: position error against seconds since the outage began (its grid and tick labels).
DRIFT = "drift"
DRIFT_AXES = "drift/grid"
DRIFT_TICKS = "drift/labels"
INSPECT_GRID = "inspect/grid"
INSPECT_SCALE = "inspect/scale"
INSPECT_START = "inspect/start"
#: The filters' health: per estimator that reports one and per measurement kind, its normalised
#: innovations squared over the drive (``health/<est>/nis/<kind>``) and the updates its gate left out.
HEALTH = "health"
HEALTH_EXPECTED = "health/expected"


def truth(view: str) -> str:
    """The GNSS track (static), broken where the fixes are not trustworthy truth."""
    return f"{view}/gnss"


def truth_bad(view: str) -> str:
    return f"{view}/gnss_bad"


def receiver(view: str) -> str:
    """The receiver's own fixes (static), where the truth is a separate reference."""
    return f"{view}/gnss_receiver"


def truth_position(view: str) -> str:
    return f"{view}/gnss/position"


def outage_truth(view: str) -> str:
    """The current outage's GNSS track (``view`` may be ``inspect``: ``inspect/gnss``)."""
    return f"{INSPECT}/gnss" if view == INSPECT else f"{view}/gnss/outage"


def live_track(view: str, est: str) -> str:
    """The current outage's estimated track, growing each second (``inspect/<est>`` in the inspector)."""
    return f"{INSPECT}/{est}" if view == INSPECT else f"{view}/{est}/live"


#: How sure each estimator is: its 95 % ellipse in the views and the sigma-vs-error plot.
UNCERTAINTY = "uncertainty"


def ellipse(view: str, est: str) -> str:
    """The estimate's 95 % position ellipse at its current position (``map``, ``local``, ``inspect``)."""
    return f"{INSPECT}/{est}/ellipse" if view == INSPECT else f"{view}/{est}/ellipse"


def uncertainty_error(est: str) -> str:
    """The estimate's position error (m) at each second of the outage, beside its ellipse's radius."""
    return f"{UNCERTAINTY}/{est}/error"


def uncertainty_radius(est: str) -> str:
    """The largest radius (m) of the estimate's 95 % ellipse at each second of the outage."""
    return f"{UNCERTAINTY}/{est}/radius95"


def kind_slug(kind: str) -> str:
    """A measurement kind's path segment: ``"GNSS position"`` -> ``gnss_position``."""
    return re.sub(r"[^a-z0-9]+", "_", kind.lower()).strip("_") or "other"


def health_nis(est: str, kind: str) -> str:
    """An estimator's normalised innovation squared of one kind of measurement, per boundary (its 10 s mean)."""
    return f"{HEALTH}/{est}/nis/{kind_slug(kind)}"


def health_gated(est: str, kind: str) -> str:
    """The boundaries where the estimator's gate left that kind of measurement out (points)."""
    return f"{HEALTH}/{est}/gated/{kind_slug(kind)}"


def all_tracks(view: str, est: str) -> str:
    return f"{view}/{est}/all"


def real_outage_tracks(view: str, est: str) -> str:
    return f"{view}/{est}/real_outages"


def drift_mean(est: str) -> str:
    """The estimator's mean position error over the outages, against seconds since their start."""
    return f"{DRIFT}/{est}/mean"


def drift_band(est: str) -> str:
    """Its 10th and 90th percentiles (two thin lines)."""
    return f"{DRIFT}/{est}/band"


def drift_current(est: str) -> str:
    """The current outage's position error, growing each second."""
    return f"{DRIFT}/{est}/current"


def inspect_position(est: str) -> str:
    return f"{INSPECT}/{est}/position"


def local_position(est: str) -> str:
    """The estimate's current position in the local view (its end point once the outage is over), a dot."""
    return f"{LOCAL}/{est}/position"


#: The truth's position in the inspector at the same instants as the estimates' (``inspect/<est>/position``).
INSPECT_TRUTH_POSITION = f"{INSPECT}/gnss/position"


def end_fixes(view: str) -> str:
    return f"{view}/gnss_outages/end_fix"


#: The map's current real GNSS outage: from each real loss's start on, its estimated tracks and the
#: fixes just around it (what a screenshot framed on it shows on the map, so the map centres there).
REAL_OUTAGE_CURRENT = "map/gnss_outages/current"


def event_points(view: str) -> str:
    return f"{view}/events"


def yaw_rate(source: str) -> str:
    return f"{YAW_RATES}/{source}"


def displacement(source: str) -> str:
    return f"{DISPLACEMENTS}/{source}"


def error_group(metric: str) -> str:
    """The folder of one metric's series (a plot's origin)."""
    return f"{ERRORS}/{metric}"


def error_series(metric: str, est: str) -> str:
    return f"{error_group(metric)}/{est}"


def real_outage_errors(est: str) -> str:
    return f"{ERRORS}/position_error_m/real_outages/{est}"


def parse_error_series(path: str) -> tuple[str, str] | None:
    """``errors/<metric>/<est>`` (with or without the leading ``/``) -> (metric, est), else None."""
    parts = path.strip("/").split("/")
    return (parts[1], parts[2]) if len(parts) == 3 and parts[0] == ERRORS and parts[1] in ERROR_METRICS else None


def is_outage_frame(path: str) -> bool:
    """Whether ``path`` is drawn per outage in the map or local view and so frames it: the outage's
    truth, every growing estimated track, the outage's scale bar."""
    parts = path.strip("/").split("/")
    return parts[0] in VIEWS_2D and (parts[1:] in (["gnss", "outage"], ["scale"]) or
                                     (len(parts) == 3 and parts[2] == "live"))


# --- state labels -------------------------------------------------------------------------

GNSS_AVAILABLE_STATE = "GNSS"
GOOD_TRUTH_STATE = "good"
NO_EVENT_STATE = "none"
_OUTAGE = re.compile(r"^outage (\d+) \(")
_REAL_OUTAGE = re.compile(r"^real GNSS outage (\d+) \(")


def outage_state(number: int, t0_s: float, t1_s: float) -> str:
    """``gnss/state`` during synthetic outage ``number`` (from 1)."""
    return f"outage {number} ({t0_s:.0f}-{t1_s:.0f} s)"


def real_outage_state(number: int, t0_s: float, t1_s: float) -> str:
    """``gnss/state`` during the log's own GNSS loss ``number``, from its last to its first good fix."""
    return f"real GNSS outage {number} ({t0_s:.1f}-{t1_s:.1f} s)"


def parse_outage_state(label: str) -> int | None:
    """The synthetic outage's number of a ``gnss/state`` label, else None (GNSS, real losses)."""
    found = _OUTAGE.match(label)
    return int(found.group(1)) if found else None


def parse_real_outage_state(label: str) -> int | None:
    """The real GNSS outage's number of a ``gnss/state`` label (:func:`real_outage_state`), else None."""
    found = _REAL_OUTAGE.match(label)
    return int(found.group(1)) if found else None


def is_outage_state(label: str) -> bool:
    """Whether a ``gnss/state`` label is an outage, synthetic or real."""
    return label != GNSS_AVAILABLE_STATE and "outage" in label


def bad_truth_state(fault_names: list[str]) -> str:
    """``gnss/quality`` of a sample whose fix is not trustworthy truth."""
    return "bad: " + ", ".join(fault_names)


def receiver_lost_state(fault_names: list[str]) -> str:
    """``gnss/state`` of a window where the receiver beside a reference (the estimators' GNSS) has
    no fix to trust, outside the outages: ``receiver lost: no-fix`` (a loss of the sky),
    ``receiver untrusted: poor-accuracy, jump`` (fixes there, none trustworthy)."""
    return ("receiver lost: " if fault_names == ["no-fix"] else "receiver untrusted: ") + ", ".join(fault_names)


def event_state(event_type: str, number: int) -> str:
    """``events/state`` during a detected event (``hard-brake #3``), also its name in hover texts."""
    return f"{event_type} #{number}"


#: The manoeuvre lane's short names of event types (its full state, ``hard-brake #3``, in the hover text).
EVENT_SHORT = {"hard-brake": "brake", "quick-accel": "accel", "roundabout": "round", "sharp-cornering": "corner",
               "left-right": "L-R", "cruise": "cruise", "gnss-outage": "no GNSS"}


_SPAN = re.compile(r"^(.*), (\d+\.\d)-(\d+\.\d) s$")


def span_state(state: str, t0_s: float, t1_s: float) -> str:
    """The value of one span of a state that several spans of a lane share (``GNSS``, ``good``,
    ``bad: frozen``, ``none``): the state and its times, ``GNSS, 40.0-70.0 s``. The viewer gives each
    value one label, so each span needs its own value for a label sized to that span."""
    return f"{state}, {t0_s:.1f}-{t1_s:.1f} s"


def base_state(value: str) -> str:
    """The state of a lane's value (:func:`span_state`'s times taken off; any other value is its
    own state, as in recordings made before spans had their own values)."""
    found = _SPAN.match(value)
    return found.group(1) if found else value


def state_labels(state: str) -> tuple[str, ...]:
    """What a state's lane may show, longest first (:func:`state_label` takes the first that fits):
    ``#3`` or ``3`` for outage 3, ``real #2`` or ``r2``, ``bad`` or ``!`` for ``bad: frozen, jump``,
    ``rx lost`` or ``rx``, ``brake`` or ``3`` for ``hard-brake #3``; the last is always a blank (an
    empty label falls back to the state's own value, cut in a short span). The viewer shows the
    label, not the value, in the hover text too; the whole state stays the value (what screenshots
    read back)."""
    blank = " "
    state = base_state(state)
    if (n := parse_outage_state(state)) is not None:
        return f"#{n}", f"{n}", blank
    if (n := parse_real_outage_state(state)) is not None:
        return f"real #{n}", f"r{n}", blank
    if state.startswith("bad: "):
        return "bad", "!", blank
    if state.startswith(("receiver lost", "receiver untrusted")):
        return ("rx lost" if state.startswith("receiver lost") else "rx bad"), "rx", blank
    if state == NO_EVENT_STATE:
        return (blank,)
    kind, sep, number = state.rpartition(" #")
    if sep:
        return EVENT_SHORT.get(kind, kind), number, blank
    return state, blank


def state_label(state: str, fits=lambda label: True, whole_anywhere=lambda label: False) -> str:
    """What a state's lane shows: the longest of :func:`state_labels` that ``fits`` (a test of the
    label's text; the viewer's state timeline cuts a label at its span's end: ``bra`` of a 3 s
    brake), else the longest that is ``whole_anywhere`` (whole in any span the viewer draws a label
    in: ``28`` of outage 28, which the hover text then names), else a blank."""
    labels = state_labels(state)
    return next((label for label in labels if fits(label)), None) or next(
        (label for label in labels if label.strip() and whole_anywhere(label)), " ")


#: Every path a recording can hold, with ``<est>`` for an estimator's name: what
#: ``docs/recording.md`` documents (a test checks both ways).
PATTERNS = (
    truth(MAP), truth(LOCAL), truth_bad(MAP), truth_bad(LOCAL), receiver(MAP), receiver(LOCAL), truth_position(MAP),
    truth_position(LOCAL), *(live_track(v, "<est>") for v in (*VIEWS_2D, INSPECT)),
    *(all_tracks(v, "<est>") for v in VIEWS_2D), *(outage_truth(v) for v in (*VIEWS_2D, INSPECT)), MAP_CONTEXT,
    LOCAL_OUTAGES, LOCAL_GRID, LOCAL_GRID_SCALE, LOCAL_SCALE, inspect_position("<est>"), local_position("<est>"),
    INSPECT_TRUTH_POSITION, INSPECT_GRID, INSPECT_SCALE, INSPECT_START, GNSS_AVAILABLE, GNSS_STATE, GNSS_QUALITY, ACCEL,
    SPEED, *(yaw_rate(s) for s in ("gyro", "gnss", "<est>")), *(displacement(s) for s in ("gnss", "<est>")),
    *(error_series(m, "<est>") for m in ERROR_METRICS),
    *(real_outage_tracks(v, "<est>") for v in VIEWS_2D), *(end_fixes(v) for v in VIEWS_2D), REAL_OUTAGE_CURRENT,
    real_outage_errors("<est>"), EVENTS_STATE, *(event_points(v) for v in VIEWS_2D), SUMMARY, OVERVIEW, REPORT, KEY,
    DRIFT_AXES, DRIFT_TICKS, drift_mean("<est>"), drift_band("<est>"), drift_current("<est>"),
    f"{HEALTH}/<est>/nis/<kind>", f"{HEALTH}/<est>/gated/<kind>", HEALTH_EXPECTED,
    *(ellipse(v, "<est>") for v in (*VIEWS_2D, INSPECT)), uncertainty_error("<est>"), uncertainty_radius("<est>"),
)


def pattern_of(path: str) -> str | None:
    """The entry of :data:`PATTERNS` a written path is an instance of, else None."""
    path = path.strip("/")
    # literal paths before the patterns with a name in them
    for pattern in sorted(PATTERNS, key=lambda p: "<est>" in p):
        regex = (re.escape(pattern).replace(re.escape("<est>"), r"[a-z][a-z0-9_-]*")
                 .replace(re.escape("<kind>"), r"[a-z0-9_]+"))
        if re.fullmatch(regex, path):
            return pattern
    return None
