"""The README's measured-results table: every built-in estimator per scenario, on the bundled
test drives and on held-out drives from cars outside the training fleet.

    python benchmarks/results_table.py [--model DIR] [--minutes 10] [--seed-base 800]

Held-out drives: one per scenario, ``--minutes`` long, seed ``--seed-base`` + scenario index, its
sensor and vehicle errors drawn from the simulator's "held-out" fleet (every parameter outside the
range the training drives were drawn from; ``ionav_viz.sim.simulate.FLEETS``). The same drive is
``ionav-viz simulate SCENARIO --fleet held-out --seed SEED --duration 10m -o FILE``.

Prints one Markdown table: per scenario and test set, each estimator's mean displacement CRSE (m),
mean orientation-rate CRSE (rad/s), mean final position error (m) and mean final error as a
percentage of the distance driven in the outage; 10 s outages.
"""

from __future__ import annotations

import argparse
import logging
import tempfile
from pathlib import Path

import ionav_viz as iv
from ionav_viz.dataset.catalog import SCENARIOS
from ionav_viz.sim.simulate import fleet_sensors, write_simulated_drive

COLUMNS = (("crse_m", 2), ("yaw_crse_radps", 4), ("final_position_error_m", 2), ("final_error_pct", 1))


def held_out_drives(directory: Path, minutes: float, seed_base: int) -> dict[str, Path]:
    return {sc: write_simulated_drive(directory / f"V-heldout-{sc}.csv", sc, seed_base + i, 60.0 * minutes, fleet_sensors("held-out", seed_base + i))
            for i, sc in enumerate(SCENARIOS)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", help="IDNN model directory (default: the shipped one)")
    parser.add_argument("--minutes", type=float, default=10.0, help="length of each held-out drive")
    parser.add_argument("--seed-base", type=int, default=800, help="seed of the first held-out drive")
    args = parser.parse_args()
    logging.getLogger("ionav_viz").setLevel(logging.ERROR)
    with tempfile.TemporaryDirectory() as tmp:
        sets = {"bundled": {sc: sc for sc in SCENARIOS},
                "held-out": {sc: str(p) for sc, p in held_out_drives(Path(tmp), args.minutes, args.seed_base).items()}}
        rows, labels = [], None
        for scenario in SCENARIOS:
            for name, drives in sets.items():
                rep = iv.evaluate([drives[scenario]], 10.0, model=args.model).to_dict()
                labels = labels or {e["name"]: e["label"] for e in rep["estimators"]}
                s = rep["summary"]
                cells = [" / ".join(f"{s[e][key]['mean']:.{d}f}" for e in labels) for key, d in COLUMNS]
                rows.append(f"| {scenario} | {name} | {rep['n_sequences']} | " + " | ".join(cells) + " |")
    order = " / ".join(labels.values())
    print(f"Each cell: {order}; means over the outages.\n")
    print("| Scenario | Drives | Outages | Disp. CRSE (m) | Yaw CRSE (rad/s) | Final error (m) | Final error (% of distance) |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
