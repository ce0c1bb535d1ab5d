"""One colour-blind-safe palette for the tracks, another scheme for everything coloured by kind
(issue 63: the health view reused the estimators' colours for measurement kinds, an external
estimator got pink beside the INS DR's red and the odometry's purple, the GNSS-quality lane drew
"good" in salmon red)."""

from types import SimpleNamespace

from ionav_viz.learning.idnn import IdnnEstimator
from ionav_viz.nav.ekf import EkfEstimator
from ionav_viz.nav.gins import GinsEstimator
from ionav_viz.nav.ins import InsEstimator
from ionav_viz.nav.odometry import OdometryEstimator
from ionav_viz.viz import entities as ent
from ionav_viz.viz.health import GATED_COLOR, SERIES_COLORS
from ionav_viz.viz.layers import state_color
from ionav_viz.viz.style import (
    BUILT_IN_COLORS,
    EVENT_COLOR,
    GNSS_COLOR,
    OKABE_ITO,
    SCALE_COLOR,
    STATE_COLORS,
    TOL_MUTED,
    estimator_colors,
)


def test_the_tracks_take_okabe_ito_and_nothing_else_does():
    """The truth and every built-in estimator: a distinct Okabe-Ito colour (black left out: unseen
    on the dark theme); a plug-in without a colour gets the one left, yellow, not pink; the
    health lines, their gated marks, the state lanes and the manoeuvre dots take none of them."""
    classes = {"ins": InsEstimator, "idnn": IdnnEstimator, "odo": OdometryEstimator, "ekf": EkfEstimator, "gins": GinsEstimator}
    builtins = {name: tuple(cls.color) for name, cls in classes.items()}
    assert builtins == BUILT_IN_COLORS
    tracks = [GNSS_COLOR, *builtins.values()]
    assert len(set(tracks)) == len(tracks) and set(tracks) <= set(OKABE_ITO.values()) - {OKABE_ITO["black"]}
    ests = [*(SimpleNamespace(name=n, color=c) for n, c in builtins.items()), SimpleNamespace(name="external", color=None)]
    assert estimator_colors(ests)["external"] == OKABE_ITO["yellow"]
    by_kind = [*SERIES_COLORS, GATED_COLOR, *STATE_COLORS.values(), EVENT_COLOR]
    assert not set(by_kind) & set(OKABE_ITO.values())
    assert set(SERIES_COLORS) | {GATED_COLOR} <= set(TOL_MUTED.values())


def test_state_lanes_good_is_no_red_and_labels_fit_a_short_lane():
    """'good' truth and GNSS available are grey, a fault rose; each lane shows a short label (the
    viewer cuts a label at its lane's end: 'outage 55 (5' in a 10 s lane)."""
    good, bad = state_color(ent.GOOD_TRUTH_STATE), state_color(ent.bad_truth_state(["frozen", "jump"]))
    assert good[0] == good[1] == good[2] and bad == TOL_MUTED["rose"]
    assert state_color(ent.outage_state(3, 20, 30)) != state_color(ent.outage_state(4, 30, 40))  # consecutive outages told apart
    labels = {ent.outage_state(55, 540, 550): "#55", ent.real_outage_state(2, 118.2, 133.0): "real #2",
              ent.bad_truth_state(["no-fix", "frozen"]): "bad", ent.event_state("roundabout", 19): "round",
              ent.event_state("hard-brake", 3): "brake", ent.GNSS_AVAILABLE_STATE: "GNSS", ent.GOOD_TRUTH_STATE: "good"}
    assert {s: ent.state_label(s) for s in labels} == labels
    assert all(len(label) <= 7 for label in labels.values())


def test_scale_bars_read_on_a_dark_and_a_light_background():
    """The scale bars were white (220): lost on the web viewer's light theme. Mid grey contrasts
    with both backgrounds (at least 60 levels from each)."""
    dark, light = 13, 248
    assert all(abs(c - dark) >= 60 and abs(c - light) >= 60 for c in SCALE_COLOR)


def test_each_span_of_a_state_has_the_label_that_fits_it():
    """The viewer gives a state value one label: with one value for every "bad" span, one short
    bad span made the label of every bad span blank. Each span of a shared state now has its own
    value (its times), so a long bad span reads "bad" beside a short one's "!", every span
    in its kind's one colour, and the state read back is the state."""
    import numpy as np

    from ionav_viz.viz.layers import log_state_lane

    logged, sent = {}, {}
    rec = SimpleNamespace(log=lambda entity, arch, static: logged.update(
        {entity: {b.component_descriptor().component.split(":")[-1]: b.as_arrow_array().to_pylist()
                  for b in arch.as_component_batches()}}))
    bad = ent.bad_truth_state(["frozen"])
    states = [ent.GOOD_TRUTH_STATE, bad, ent.GOOD_TRUTH_STATE, bad, ent.GOOD_TRUTH_STATE]
    times_s = np.array([0.0, 100.0, 101.0, 300.0, 500.0])  # a 1 s bad span, then a 200 s one, on a 600 s drive
    log_state_lane(rec, lambda entity, t, cols: sent.update({entity: [
        v for b in cols for v in b.as_arrow_array().to_pylist()]}), ent.GNSS_QUALITY, states, times_s, 600.0)
    config = logged[ent.GNSS_QUALITY]
    label = dict(zip(config["values"], config["labels"]))
    color = dict(zip(config["values"], config["colors"]))
    values = [v[0] if isinstance(v, list) else v for v in sent[ent.GNSS_QUALITY]]
    assert values[-1] is None  # an empty state ends the lane at the drive's end
    values = [v for v in values[:-1] if v is not None]  # and one between spans (layers.with_merge_breaks)
    assert len(set(values)) == 5 and [ent.base_state(v) for v in values] == states
    assert [label[v] for v in values[1::2]] == ["!", "bad"]  # the short span's label whole wherever drawn, the long one's in full
    assert len({color[v] for v in values[1::2]}) == 1 and len({color[v] for v in values[::2]}) == 1
    assert values[1] == "bad: frozen, 100.0-101.0 s"


def _contrast(a: int, b: int) -> float:
    """WCAG's contrast ratio of two greys (0-255)."""
    def lum(v: int) -> float:
        c = v / 255
        return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4
    hi, lo = sorted((lum(a), lum(b)), reverse=True)
    return (hi + 0.05) / (lo + 0.05)


def test_scale_labels_contrast_on_both_themes_label_boxes():
    """Rerun draws a label in its entity's colour on a box of the theme's: (239, 239, 239) on the
    light theme, (28, 28, 28) on the dark one (measured on the served page). The scale bars' grey
    (145) gave "20 m" 2.7:1 on the light box; the grey now is the one that reads best on both, at
    least 3.8:1 on each (the most one colour can have on both boxes)."""
    light_box, dark_box = 239, 28
    assert all(c == SCALE_COLOR[0] for c in SCALE_COLOR)
    grey = SCALE_COLOR[0]
    assert min(_contrast(grey, light_box), _contrast(grey, dark_box)) >= 3.8
    best = max(range(256), key=lambda v: min(_contrast(v, light_box), _contrast(v, dark_box)))
    assert abs(grey - best) <= 3, best
