"""Does the simulator predict the ranking on real consumer IMUs (issue 41 point 6)? ``gins`` as
shipped (its mechanisation chosen from the samples: roll and pitch held on single readings), ``gins``
forced to the full 3D mechanisation (without the history arbiter, which could hand it another propagation), and the INS DR, on your local copies of real logs and on the
simulator's phone and dash sets (benchmarks/results_table.py's drives): final position error as a
share of the distance driven, mean over the outages tiled after the 30 s warm-up, IMU only::

    python benchmarks/sim_vs_real.py [LOG.mcap...] [--truth-topic T] [--gnss-topic T] [--max-sigma-m 13] [--simulated [--scored-on-fixes] [--per-drive]] [--minutes 10] [--debug]

Read each real log with the options benchmarks/real_imu_logs.py takes for it (one kind per run).
The simulated sets are scored against their reference trajectory; with ``--scored-on-fixes``
against their receiver's fixes, as the real logs without a reference are (``--max-sigma-m 13``):
the same measurement on both.

A missing log stops it before any work, a log its reader cannot read when it is reached: one line
naming the file, exit code 2 (``--debug``: the traceback).
"""

from __future__ import annotations

import argparse
import logging
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from _cli import add_debug, check_logs, raise_if_unreadable, run
from real_imu_logs import gap_points, outage_pcts_of

import ionav_viz as iv
from ionav_viz.core.gnss_quality import GnssLimits
from ionav_viz.nav.gins import GinsEstimator
from ionav_viz.sim.imu import IMU_GRADES, SIM_TRUTH_TOPIC, write_imu_log
from ionav_viz.sources.mcap_writer import TOPICS

SIM_GNSS_TOPIC = TOPICS["fix"]

#: (title, grade, scenarios, first seed): results_table.py's phone and dash sets
SETS = (("simulated phone IMU 10 Hz, urban", "phone", ("roundabout", "sharp-cornering", "hard-brake"), 900),
        ("simulated dash device IMU 104 Hz, highway", "dash", ("motorway", "motorway"), 940))


def outage_pcts(paths: list[str], estimators: list, length: float, read: iv.ReadOptions) -> dict[str, np.ndarray]:
    """Each estimator's final error (% of distance) on each of the drives' outages of ``length`` s,
    from one evaluation (NaN where not scored; empty arrays: no outage of that length fits)."""
    names = [e if isinstance(e, str) else e.name for e in estimators]
    try:
        rep = iv.evaluate(paths, length, estimators=list(estimators), read=read).to_dict()
    except iv.InputError:  # no outage of that length fits
        raise_if_unreadable(paths, read)  # not when a log cannot be read at all: its reader's error
        return {name: np.zeros(0) for name in names}
    return outage_pcts_of(rep, names)


def mean_pcts(paths: list[str], estimators: list, length: float, read: iv.ReadOptions) -> dict[str, float | None]:
    """Each estimator's mean final error (% of distance) over the drives' outages of ``length`` s,
    from one evaluation (None: no outage of that length fits, or none scored)."""
    out: dict[str, float | None] = {}
    for name, pct in outage_pcts(paths, estimators, length, read).items():
        pct = pct[np.isfinite(pct)]
        out[name] = float(np.mean(pct)) if len(pct) else None
    return out


def mean_pct(paths: list[str], estimator, name: str, length: float, read: iv.ReadOptions) -> float | None:
    return mean_pcts(paths, [estimator], length, read)[name]


def row(title: str, paths: list[str], read: iv.ReadOptions) -> str:
    cells = []
    for estimator, name in ((GinsEstimator(), "gins"), (GinsEstimator(mechanisation="3d", arbiter=False), "gins"), ("ins", "ins")):
        values = [mean_pct(paths, estimator, name, length, read) for length in (10.0, 30.0)]
        cells.append(" / ".join("–" if v is None else f"{v:.1f}" for v in values))
    return f"| {title} | " + " | ".join(cells) + " |"


def drive_row(title: str, path: str, read: iv.ReadOptions) -> str:
    """``gins`` against the INS DR on one drive at 10, 30 and 60 s (bold: ``gins``'s mean above;
    "beyond the spread": the 95 % interval of the gap, :func:`real_imu_logs.gap_points`, above 0)."""
    cells = []
    for length in (10.0, 30.0, 60.0):
        both = outage_pcts([path], [GinsEstimator(), "ins"], length, read)  # one evaluation: the same outages
        gp, ip = both["gins"], both["ins"]
        if not np.isfinite(gp).any() or not np.isfinite(ip).any():
            cells.append("–")
            continue
        g, n = float(np.nanmean(gp)), float(np.nanmean(ip))
        gap = gap_points(ip, gp)
        beyond = " (beyond the spread)" if gap is not None and gap[1] > 0 else ""
        cells.append(f"**{g:.1f}** / {n:.1f}{beyond}" if g > n else f"{g:.1f} / {n:.1f}")
    return f"| {title} | " + " | ".join(cells) + " |"


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("logs", nargs="*", type=Path)
    parser.add_argument("--truth-topic")
    parser.add_argument("--gnss-topic")
    parser.add_argument("--max-sigma-m", type=float)
    parser.add_argument("--simulated", action="store_true", help="also the simulator's phone and dash sets")
    parser.add_argument("--minutes", type=float, default=10.0, help="length of each simulated drive")
    parser.add_argument("--per-drive", action="store_true",
                        help="gins against the INS DR per drive (each log, each simulated drive) at 10, 30 and 60 s instead of the pooled rows")
    parser.add_argument("--scored-on-fixes", action="store_true",
                        help="score the simulated sets against their receiver's fixes (max sigma 13 m), as the real logs without a reference")
    args = parser.parse_args()
    check_logs(args.logs)
    logging.getLogger("ionav_viz").setLevel(logging.ERROR)
    if args.per_drive:
        print("| drive | `gins` / INS DR 10 s | 30 s | 60 s |\n|---|---|---|---|")
    else:
        print("| log | `gins` 10 s / 30 s | `gins` in 3D 10 s / 30 s | INS DR 10 s / 30 s |\n|---|---|---|---|")
    limits = GnssLimits() if args.max_sigma_m is None else replace(GnssLimits(), max_sigma_m=args.max_sigma_m)
    read = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", vehicle_speed_topic="none", truth_topic=args.truth_topic, gnss_topic=args.gnss_topic),
                          gnss_limits=limits)
    for path in args.logs:
        print(drive_row(path.stem, str(path), read) if args.per_drive else row(path.stem, [str(path)], read), flush=True)
    if args.simulated:
        if args.scored_on_fixes:
            sim_read = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", vehicle_speed_topic="none", gnss_topic=SIM_GNSS_TOPIC),
                                      gnss_limits=replace(GnssLimits(), max_sigma_m=13.0))
        else:
            sim_read = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", vehicle_speed_topic="none", truth_topic=SIM_TRUTH_TOPIC))
        with tempfile.TemporaryDirectory() as tmp:
            for title, grade, scenarios, seed in SETS:
                if grade not in IMU_GRADES:
                    continue
                paths = [str(write_imu_log(Path(tmp) / f"{grade}-{i}.mcap", sc, seed + i, 60.0 * args.minutes, grade)) for i, sc in enumerate(scenarios)]
                if args.per_drive:
                    for i, (path, scenario) in enumerate(zip(paths, scenarios, strict=True)):
                        scored = ", scored on its fixes" if args.scored_on_fixes else ""
                        print(drive_row(f"{title}: {scenario}, seed {seed + i}{scored}", path, sim_read), flush=True)
                    continue
                print(row(title + (", scored on its fixes" if args.scored_on_fixes else ""), paths, sim_read), flush=True)


if __name__ == "__main__":
    run(main)
