"""Logs without a velocity topic: the same simulated drive as a CSV (the logger's course and
Doppler speed) and as a ROS 2 MCAP with NavSatFix only at 1, 5, 10 and 20 Hz (0.15 m white fix
noise, 1e-7 deg rounding, 2 % duplicated fixes, +-4 ms jitter; tests/mcap_fixtures.write_fix_only).

    python benchmarks/fix_pairs.py [SCENARIO ...] [--debug]

Prints per pair: the RMS of the per-window GNSS yaw rate against the logger's course, the INS and
IDNN mean displacement CRSE (CSV -> MCAP), the INS orientation-rate CRSE and the event counts
that differ. The README's table "Logs without a velocity topic" comes from it. A SCENARIO is a
bundled drive's name or an IO-VNBD CSV file; one that is neither stops it before any work (one
line naming it, exit code 2).
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
from _cli import add_debug, check_logs, run

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import ionav_viz as iv
from ionav_viz.analysis.events import detect_events
from ionav_viz.core.grid import hold_course_when_slow
from ionav_viz.nav.windows import make_windows
from tests.mcap_fixtures import write_fix_only

DEFAULT = ("V-sim-motorway", "V-sim-roundabout", "V-sim-quick-accel", "V-sim-hard-brake", "V-sim-sharp-cornering")


def measure(scenarios: list[str]) -> None:
    logging.getLogger("ionav_viz").setLevel(logging.ERROR)
    print(f"{'drive':22s} {'Hz':>3s} {'yaw RMS':>8s} {'INS CRSE m':>18s} {'IDNN CRSE m':>18s} {'INS yaw CRSE':>20s}  events differing")
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in scenarios:
            csv = iv.load_drive(scenario)
            ref = iv.evaluate([csv], 10.0).summary
            ref_events = Counter(e.type for e in detect_events(csv))
            course = np.rad2deg(np.unwrap(np.deg2rad(hold_course_when_slow(csv.heading_deg, csv.speed_mps))))
            for hz in (1, 5, 10, 20):
                mcap = iv.load_drive(write_fix_only(csv, Path(tmp) / f"{scenario}-{hz}.mcap", hz, seed=hz))
                w = make_windows(mcap)
                t0 = w.t0_s + mcap.start_time_of_day_s - csv.start_time_of_day_s
                inside = (t0 >= 0) & (t0 + 1.0 <= csv.t_s[-1])
                truth = -np.deg2rad(np.interp(t0 + 1, csv.t_s, course) - np.interp(t0, csv.t_s, course))
                rms = np.sqrt(np.mean((w.gnss_yaw_rate_radps[inside] - truth[inside]) ** 2))
                got = iv.evaluate([mcap], 10.0).summary
                events = Counter(e.type for e in detect_events(mcap))
                cells = []
                for name, key in (("ins", "crse_m"), ("idnn", "crse_m"), ("ins", "yaw_crse_radps")):
                    a, b = ref[name][key]["mean"], got[name][key]["mean"]
                    cells.append(f"{a:6.3f}->{b:6.3f} {100 * (b - a) / a:+5.1f}%")
                differ = {k: f"{ref_events[k]}->{events[k]}" for k in sorted(set(ref_events) | set(events)) if events[k] != ref_events[k]}
                print(f"{scenario:22s} {hz:3d} {rms:8.4f} {cells[0]:>18s} {cells[1]:>18s} {cells[2]:>20s}  {differ or '-'}", flush=True)


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("scenarios", nargs="*", default=list(DEFAULT), metavar="SCENARIO",
                        help="bundled drives or IO-VNBD CSV files (default: the five bundled test drives)")
    args = parser.parse_args()
    check_logs(args.scenarios)
    measure(args.scenarios)


if __name__ == "__main__":
    run(main)
