"""How much `gins`'s IMU-only results depend on the drives drawn: the 3D GNSS/INS, the planar ekf
and the INS DR on simulated 6-axis logs of seeds other than docs/results.md's.

    python benchmarks/gins_seeds.py                       # phone, seeds 930-938, 10 and 30 s outages
    python benchmarks/gins_seeds.py --grade mems --first-seed 940 --drives 9
    python benchmarks/gins_seeds.py --without-velocity    # the receiver's velocity left out: speed and course fitted to the fixes

Each drive is ``--minutes`` long, written as MCAP by the 6-axis simulator (the scenarios roundabout,
sharp-cornering and hard-brake in turn) and read back like a user's log (``--truth-topic
/truth/fix --imu-mount auto``, no vehicle speed); outages tile it. Prints, per estimator and outage
length, the final position error as a percentage of the distance driven: the mean over all the
outages, and each drive's mean. Same as ``ionav-viz simulate SCENARIO --imu GRADE --seed SEED
--duration 10m -o FILE.mcap`` then ``ionav-viz evaluate FILE.mcap ... --outage 10s,30s``.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from _cli import add_debug, lengths_s, run

import ionav_viz as iv
from ionav_viz.sim.imu import IMU_GRADES, SIM_TRUTH_TOPIC, write_imu_log

SCENARIOS = ("roundabout", "sharp-cornering", "hard-brake")
ESTIMATORS = ("ins", "ekf", "gins")


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--grade", choices=sorted(IMU_GRADES), default="phone")
    parser.add_argument("--first-seed", type=int, default=930)
    parser.add_argument("--drives", type=int, default=9)
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--lengths", default="10,30", help="outage lengths (s), comma-separated")
    parser.add_argument("--without-velocity", action="store_true", help="read the logs with --gnss-velocity-topic none (a log of fixes only)")
    args = parser.parse_args()
    lengths = lengths_s(args.lengths)
    seeds = range(args.first_seed, args.first_seed + args.drives)
    log = iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, vehicle_speed_topic="none", imu_mount="auto",
                        gnss_velocity_topic="none" if args.without_velocity else None)
    with tempfile.TemporaryDirectory() as tmp:
        paths = [str(write_imu_log(Path(tmp) / f"{args.grade}-{s}.mcap", SCENARIOS[i % 3], s, 60.0 * args.minutes, args.grade))
                 for i, s in enumerate(seeds)]
        reports = iv.evaluate(paths, list(lengths), estimators=list(ESTIMATORS), read=iv.ReadOptions(log=log))
    fixes_only = ", fixes only (no receiver velocity)" if args.without_velocity else ""
    print(f"{args.grade}{fixes_only}, seeds {seeds[0]}-{seeds[-1]}, {args.minutes:g} min each: final error, % of distance driven")
    for length, rep in reports.items():
        per: dict[str, dict[str, list[float]]] = {}
        for seq in rep.to_dict()["sequences"]:
            for name in ESTIMATORS:
                pct = seq[name].get("final_error_pct")
                if pct is not None and np.isfinite(pct):  # none below 10 m driven
                    per.setdefault(name, {}).setdefault(seq["drive"], []).append(pct)
        for name, drives in per.items():
            pooled = np.concatenate([np.asarray(v) for v in drives.values()])
            each = " ".join(f"{np.mean(v):5.1f}" for v in drives.values())
            print(f"  {length:3.0f} s  {name:5s} mean {pooled.mean():5.2f}   per drive {each}")


if __name__ == "__main__":
    run(main)
