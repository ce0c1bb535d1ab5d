"""Benchmark: fine-tuning the shipped IDNN on 5 minutes of a drive, as a user runs it.

    python benchmarks/bench_fine_tune.py                  # both drives below
    python benchmarks/bench_fine_tune.py --only simulated
    python benchmarks/bench_fine_tune.py --device cuda    # on a GPU

Times ``ionav-viz train DRIVE --from-model shipped -o MODEL`` as a whole process (the imports,
reading the drive, both networks' fits, the validation that decides between parent and child, the
uncertainty's fit, writing the model) on:

* a generated 5-minute drive: ``ionav-viz simulate roundabout --duration 5m --seed 7 --fleet
  held-out`` (a car whose sensor errors lie outside the shipped model's training ranges);
* the first 300 s of the corpus's roof log (``tests/data/real/roof_mems_rtk_gnss_imu_drive0708.mcap
  --span 0s:300s --imu-mount auto --vehicle-speed-topic none``: a 100 Hz MEMS IMU with RTK).

Prints each run's wall time and CPU time (the process's user + system time), the training's
optimiser steps, and what fine-tuning kept. Target on our 2-core machine: at most 60 s wall each.
One run each: on a shared machine the CPU time is the steadier figure (the wall time waits on
whatever else runs).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _cli import add_debug, run

REPO = Path(__file__).resolve().parent.parent
ROOF_LOG = REPO / "tests" / "data" / "real" / "roof_mems_rtk_gnss_imu_drive0708.mcap"
#: The drives timed (``--only`` chooses one).
CASES = ("simulated", "roof")
TARGET_S = 60.0


def timed(argv: list[str]) -> tuple[float, float]:
    """Run ``argv`` as a process: its wall time (s) and CPU time (s, user + system)."""
    before = os.times()
    start = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True, check=False)
    wall_s = time.perf_counter() - start
    after = os.times()
    cpu_s = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}): {proc.stderr.strip().splitlines()[-1:]}")
    return wall_s, cpu_s


def kept(model_dir: Path) -> str:
    """What fine-tuning kept of each network (the metadata's epoch selection)."""
    selection = json.loads((model_dir / "metadata.json").read_text())["epoch_selection"]
    return ", ".join(f"{name}: {selection[name].get('kept', '?')}" for name in ("displacement", "yaw_rate") if name in selection)


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--only", choices=CASES, help="time this drive only")
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda", "auto"), help="train's --device (default cpu)")
    args = parser.parse_args()
    cli = [sys.executable, "-m", "ionav_viz.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        drives = {}
        if args.only in (None, "simulated"):
            csv = folder / "V-sim-5min.csv"
            subprocess.run([*cli, "simulate", "roundabout", "--duration", "5m", "--seed", "7", "--fleet", "held-out", "-o", str(csv), "-q"],
                           check=True, capture_output=True)
            drives["simulated"] = ("generated 5-minute drive (roundabout, held-out car, seed 7)", [str(csv)])
        if args.only in (None, "roof"):
            drives["roof"] = ("roof log, first 300 s", [str(ROOF_LOG), "--span", "0s:300s", "--imu-mount", "auto", "--vehicle-speed-topic", "none"])
        print(f"fine-tuning the shipped IDNN on 5 minutes of a drive (--device {args.device}); target: <= {TARGET_S:g} s wall each")
        for name, (what, drive_args) in drives.items():
            out = folder / f"model-{name}"
            argv = [*cli, "train", *drive_args, "--from-model", "shipped", "--device", args.device, "-q", "-o", str(out)]
            wall_s, cpu_s = timed(argv)
            meta = json.loads((out / "metadata.json").read_text())
            print(f"{what}: {wall_s:.1f} s wall, {cpu_s:.1f} s CPU; {meta['training']['n_examples']} training examples; kept {kept(out)}")


if __name__ == "__main__":
    run(main)
