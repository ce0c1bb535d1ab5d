"""The same drive as a CSV with the logger's course and speed, and as a ROS 2 MCAP with fixes only.

Issue 16: course, speed and positions from noisy fixes (1-20 Hz, jitter, duplicates, 0.15 m of
white noise on top of the simulator's wander) must give the same verdict as the logger's own
course and Doppler speed: per-window GNSS yaw rate, the INS and IDNN mean displacement CRSE,
the standstill biases and the manoeuvres found.
"""

from __future__ import annotations

import logging
from collections import Counter

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.analysis.events import EVENT_TYPES, detect_events
from ionav_viz.core.grid import hold_course_when_slow
from ionav_viz.nav.bias import estimate_bias
from ionav_viz.nav.windows import make_windows

from .mcap_fixtures import write_fix_only

# the module's generated fixtures are built once, on one worker (pytest-xdist's --dist loadgroup)
pytestmark = pytest.mark.xdist_group("fix_pairs")

SCENARIOS = ("V-sim-roundabout", "V-sim-hard-brake", "V-sim-motorway")
RATES_HZ = (1, 5, 10, 20)


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    """{scenario: (csv drive, csv report, {rate: mcap drive})}, every MCAP with its own noise seed."""
    logger = logging.getLogger("ionav_viz")
    level = logger.level
    logger.setLevel(logging.ERROR)  # the duplicated fixes' warning, for this module's tests only
    out = {}
    folder = tmp_path_factory.mktemp("pairs")
    for scenario in SCENARIOS:
        csv = iv.load_drive(scenario)
        mcaps = {hz: iv.load_drive(write_fix_only(csv, folder / f"{scenario}-{hz}.mcap", hz, seed=hz)) for hz in RATES_HZ}
        out[scenario] = (csv, iv.evaluate([csv], 10.0), mcaps)
    yield out
    logger.setLevel(level)


def _logger_yaw_rate(csv, t0_s):
    """The CSV's per-window GNSS yaw rate (rad/s, counter-clockwise) from the logger's course, at
    windows starting at ``t0_s`` (s from the CSV's start): computed here, not by make_windows."""
    course = np.rad2deg(np.unwrap(np.deg2rad(hold_course_when_slow(csv.heading_deg, csv.speed_mps))))
    return -np.deg2rad(np.interp(t0_s + 1.0, csv.t_s, course) - np.interp(t0_s, csv.t_s, course))


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_window_yaw_rate_from_fixes_agrees_with_the_loggers_course(pairs, scenario):
    csv, _, mcaps = pairs[scenario]
    for hz, mcap in mcaps.items():
        w = make_windows(mcap)
        t0 = w.t0_s + (mcap.start_time_of_day_s - csv.start_time_of_day_s)
        inside = (t0 >= 0) & (t0 + 1.0 <= csv.t_s[-1])
        rms = np.sqrt(np.mean((w.gnss_yaw_rate_radps[inside] - _logger_yaw_rate(csv, t0[inside])) ** 2))
        # measured 0.011-0.047 rad/s; a course from consecutive fixes gives ~1 rad/s here
        assert rms < 0.06, f"{scenario} at {hz} Hz: per-window yaw-rate RMS {rms:.3f} rad/s"


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_mean_displacement_crse_agrees_within_10_percent(pairs, scenario):
    _, csv_report, mcaps = pairs[scenario]
    for hz, mcap in mcaps.items():
        report = iv.evaluate([mcap], 10.0)
        for name in ("ins", "idnn") if hz >= 5 else ("ins",):
            ref, got = (r.summary[name]["crse_m"]["mean"] for r in (csv_report, report))
            # At 1 Hz a 1-second window's displacement rests on two fixes: their 0.15 m of white
            # noise cannot be averaged away (0.2 m per window, +3 % on the INS's 8 m).
            tolerance = 0.10 if hz >= 5 else 0.25
            assert abs(got - ref) <= tolerance * ref, f"{scenario} at {hz} Hz, {name}: CRSE {got:.2f} m vs {ref:.2f} m from the CSV"
        if hz < 5:
            # The IDNN's calibration comes from a filter on the fixes' speed, which a 1 Hz fit
            # smooths (up to +56 % on the hard-brake drive, measured): it must still beat the INS.
            s = report.summary
            assert s["idnn"]["crse_m"]["mean"] < s["ins"]["crse_m"]["mean"], f"{scenario} at {hz} Hz"


def test_a_standstill_is_found_from_fixes_alone(pairs):
    csv, _, mcaps = pairs["V-sim-roundabout"]  # stands still for ~6 s at the start
    ref = estimate_bias(csv)
    for hz, mcap in mcaps.items():
        bias = estimate_bias(mcap)
        assert bias is not None, f"{hz} Hz: no standstill found"
        assert abs(bias.accel_mps2 - ref.accel_mps2) < 0.03 and abs(bias.gyro_radps - ref.gyro_radps) < 0.002


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_event_counts_agree(pairs, scenario):
    csv, _, mcaps = pairs[scenario]
    ref = Counter(e.type for e in detect_events(csv))
    for hz, mcap in mcaps.items():
        got = Counter(e.type for e in detect_events(mcap))
        for kind in EVENT_TYPES:
            # within 20 %, and one event either way where 20 % is less than one
            assert abs(got[kind] - ref[kind]) <= max(1, 0.2 * ref[kind]), f"{scenario} at {hz} Hz: {kind} {got[kind]} vs {ref[kind]}"
