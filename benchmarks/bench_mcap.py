"""Benchmark: writing and reading a ROS 2 MCAP log of a 100 Hz MEMS IMU, in one process.

    python benchmarks/bench_mcap.py                     # a 10-minute log, 3 runs, medians
    python benchmarks/bench_mcap.py --minutes 30 --runs 5

The log is the simulator's (``ionav-viz simulate roundabout --imu mems``): ``/imu/data`` at 100 Hz,
the receiver's ``/gps/fix`` and ``/gps/vel``, ``/wheel/odom`` and the reference on ``/truth/fix``.
Writing is :func:`ionav_viz.sim.imu.write_imu_log` after the drive is simulated (the simulation is
timed apart); reading is :func:`ionav_viz.load_drive` with the truth topic and ``--imu-mount auto``,
as a user reads such a log. The first read of the process is left out of the medians (numba's
kernels load from its cache then). Files go to a temporary directory, removed at the end.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import tempfile
import time
from pathlib import Path

from _cli import add_debug, run

import ionav_viz as iv
from ionav_viz.core.errors import InputError
from ionav_viz.sim.imu import SIM_TRUTH_TOPIC, imu_drive, write_imu_log


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--minutes", type=float, default=10.0, help="the log's length (default 10)")
    parser.add_argument("--runs", type=int, default=3, help="timed runs of each step (default 3)")
    args = parser.parse_args()
    if not 0.5 <= args.minutes <= 120 or not 1 <= args.runs <= 20:
        raise InputError(f"--minutes {args.minutes:g} / --runs {args.runs}: out of range",
                         "give 0.5-120 minutes and 1-20 runs", param="minutes")
    logging.getLogger("ionav_viz").setLevel(logging.ERROR)  # the mount estimate's line, once per read
    duration_s = 60.0 * args.minutes
    read = iv.ReadOptions(log=iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, imu_mount="auto"))
    simulate_s, write_s, read_s = [], [], []
    with tempfile.TemporaryDirectory(prefix="bench-mcap-") as folder:
        path = Path(folder) / "log.mcap"
        for _ in range(args.runs):
            t0 = time.perf_counter()
            imu_drive("roundabout", 1, duration_s, "mems")
            t1 = time.perf_counter()
            write_imu_log(path, "roundabout", 1, duration_s, "mems")  # simulates again, then writes
            simulate_s.append(t1 - t0)
            write_s.append(time.perf_counter() - t1 - (t1 - t0))
        iv.load_drive(path, read)  # numba's kernels load from the cache on the first read
        for _ in range(args.runs):
            t0 = time.perf_counter()
            drive = iv.load_drive(path, read)
            read_s.append(time.perf_counter() - t0)
        size_mb = path.stat().st_size / 1e6
    samples = round(duration_s * 100)
    print(f"{args.minutes:g} min of a 100 Hz MEMS IMU log ({size_mb:.1f} MB, {len(drive)} samples on the 10 Hz grid), "
          f"medians of {args.runs}: simulate {statistics.median(simulate_s):.2f} s, "
          f"write {statistics.median(write_s):.2f} s, read {statistics.median(read_s):.2f} s "
          f"({samples / statistics.median(read_s):,.0f} IMU messages/s)")


if __name__ == "__main__":
    run(main)
