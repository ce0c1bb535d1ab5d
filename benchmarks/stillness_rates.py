"""How often the IMU's stillness detector (:mod:`ionav_viz.nav.stillness`) finds a standing car,
and how often it calls a moving one still, on simulated drives whose true speed is known.

    python benchmarks/stillness_rates.py [--seeds 5] [--minutes 10]

Drives: every paper scenario of the simulator (IO-VNBD's two channels at 10 Hz; its nominal car
and a held-out fleet car, noisier), and the simulated 6-axis logs (``mems`` at 100 Hz, ``phone`` at
10 Hz, read back from their MCAP) of the hard-brake scenario. Each drive is read as a user's
would be and the detector calibrated on it as the estimators have it (:func:`drive_still`), then
compared with the simulator's true speed at each sample. Prints per group:

* standing: samples whose true speed is under 0.01 m/s after the drive's first start, and the
  share detected still (hit rate; the first stand of each drive calibrates the detector, so it is
  left out);
* stops: those standstills lasting 1 s or more, and how many have a still sample;
* false alarms: samples detected still while the true speed is over 0.05 m/s and over 0.5 m/s
  (their share of such samples), and the true distance driven over them (what a wrong zero-velocity
  update would lose, m per hour of driving).
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import ionav_viz as iv
from ionav_viz.core.runs import run_ranges
from ionav_viz.dataset.catalog import SCENARIOS
from ionav_viz.nav.stillness import drive_still
from ionav_viz.sim.imu import SIM_TRUTH_TOPIC, imu_drive, write_imu_log
from ionav_viz.sim.simulate import fleet_sensors, plan_truth, write_simulated_drive

STANDING_MPS, CREEPING_MPS, MOVING_MPS, MIN_STOP_S = 0.01, 0.05, 0.5, 1.0


class Tally:
    """Counts over the drives of one group."""

    def __init__(self) -> None:
        self.standing = self.standing_hit = self.stops = self.stops_hit = 0
        self.creeping = self.creeping_false = self.moving = self.moving_false = 0
        self.false_m = self.hours = 0.0

    def add(self, t_s: np.ndarray, speed_mps: np.ndarray, still: np.ndarray) -> None:
        dt = np.gradient(t_s)
        standing = speed_mps < STANDING_MPS
        for a, b in run_ranges(standing)[1:]:  # the first stand calibrates the detector: not scored
            self.standing += b - a
            self.standing_hit += int(still[a:b].sum())
            if t_s[b - 1] - t_s[a] >= MIN_STOP_S:
                self.stops += 1
                self.stops_hit += int(still[a:b].any())
        creeping, moving = speed_mps > CREEPING_MPS, speed_mps > MOVING_MPS
        self.creeping += int(creeping.sum())
        self.creeping_false += int((still & creeping).sum())
        self.moving += int(moving.sum())
        self.moving_false += int((still & moving).sum())
        self.false_m += float((speed_mps * dt)[still & ~standing].sum())
        self.hours += float(dt[~standing].sum()) / 3600.0

    def line(self, name: str) -> str:
        def pct(a: int, b: int) -> str:
            return f"{100.0 * a / b:6.2f} %" if b else "     -  "

        return (f"{name:44s} {pct(self.standing_hit, self.standing)} of {self.standing:7d}  {self.stops_hit:4d}/{self.stops:<4d}"
                f"  {pct(self.creeping_false, self.creeping)} ({self.creeping_false:5d})  {pct(self.moving_false, self.moving)}"
                f" ({self.moving_false:4d})  {self.false_m / max(self.hours, 1e-9):8.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--minutes", type=float, default=10.0)
    args = parser.parse_args()
    logging.getLogger("ionav_viz").setLevel(logging.ERROR)
    duration_s = 60.0 * args.minutes
    print(f"{args.seeds} seeds x {args.minutes:g} min per scenario and car")
    print(f"{'drives':44s} {'standing detected':>20s}  {'stops':>9s}  {'false > 0.05 m/s':>19s}  {'false > 0.5 m/s':>17s}  {'m/h lost':>8s}")
    with tempfile.TemporaryDirectory() as tmp:
        for car in ("nominal", "held-out"):
            total = Tally()
            for scenario in SCENARIOS:
                tally = Tally()
                for seed in range(args.seeds):
                    sensors = None if car == "nominal" else fleet_sensors("held-out", seed)
                    path = write_simulated_drive(Path(tmp) / f"V-{car}-{scenario}-{seed}.csv", scenario, seed, duration_s, sensors)
                    drive = iv.load_drive(path)
                    truth = plan_truth(scenario, seed, duration_s)
                    speed = np.interp(drive.t_s, truth.t_s, truth.speed_mps)
                    still = drive_still(drive)
                    tally.add(drive.t_s, speed, still)
                    total.add(drive.t_s, speed, still)
                print(tally.line(f"10 Hz 2-axis, {car} car, {scenario}"))
            print(total.line(f"10 Hz 2-axis, {car} car, all"))
        for grade in ("mems", "phone"):
            tally = Tally()
            for seed in range(args.seeds):
                path = write_imu_log(Path(tmp) / f"{grade}-{seed}.mcap", "hard-brake", seed, duration_s, grade)
                drive = iv.load_drive(path, iv.ReadOptions(log=iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC)))
                log = imu_drive("hard-brake", seed, duration_s, grade).drive
                speed = np.interp(drive.t_s, log.t_s, log.columns["speed_mps"])
                tally.add(drive.t_s, speed, drive_still(drive))
            print(tally.line(f"6-axis {grade}, hard-brake"))


if __name__ == "__main__":
    main()
