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
