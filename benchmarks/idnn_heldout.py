"""How robust is "the IDNN beats the INS"? Retrain with other seeds and test on unseen drives.

Trains the networks with the shipped model's hyperparameters (``ionav_viz/data/models/idnn/metadata.json``)
on the bundled training drives for each ``--seeds`` value, and evaluates each model (and the
shipped one) on

* the bundled synthetic test drives (what ``ionav-viz evaluate --scenario all`` reports), and
* held-out drives simulated here (``--minutes`` long each, seed ``--seed-base`` + scenario
  index) from cars of the simulator's "held-out" fleet, whose sensor and vehicle errors lie
  outside every range of the training fleet. The default seeds 800-804 were used neither by the
  bundled drives nor when choosing the hyperparameters.

Prints, per model and test set, the IDNN's improvement over the INS on mean displacement CRSE
and mean orientation-rate CRSE per scenario (positive = IDNN better) and how many of the ten
comparisons the IDNN wins. Run: ``python benchmarks/idnn_heldout.py``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from results_table import held_out_drives  # the same held-out cars as the README's table

from ionav_viz.analysis.evaluate import evaluate_drive, improvement_pct, resolve_bias
from ionav_viz.dataset.catalog import SCENARIOS
from ionav_viz.dataset.samples import SAMPLES, sample_path
from ionav_viz.nav.idnn import ModelConfig, default_model_dir, load_model
from ionav_viz.nav.training import train_models
from ionav_viz.sources.iovnbd import read_iovnbd


def compare(model, drives: dict) -> tuple[list[str], int]:
    cells, wins = [], 0
    for scenario in SCENARIOS:
        result = evaluate_drive(drives[scenario], 10.0, model=model)
        ins, idnn = result.metrics["ins"], result.metrics["idnn"]
        disp = improvement_pct(ins["crse_m"].mean(), idnn["crse_m"].mean())
        yaw = improvement_pct(ins["yaw_crse_radps"].mean(), idnn["yaw_crse_radps"].mean())
        wins += int(disp > 0) + int(yaw > 0)
        cells.append(f"{disp:+6.1f} {yaw:+6.1f}")
    return cells, wins


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="*", default=[1, 2, 3], help="training seeds to retrain with")
    parser.add_argument("--minutes", type=float, default=10.0, help="length of each held-out drive")
    parser.add_argument("--seed-base", type=int, default=800, help="seed of the first held-out drive")
    args = parser.parse_args()

    shipped = load_model(default_model_dir())
    hyper = json.loads((default_model_dir() / "metadata.json").read_text())["config"]
    train = [read_iovnbd(sample_path(s)) for s in SAMPLES if s.role == "train"]
    train = [(d, resolve_bias(d)) for d in train]
    bundled = {s.scenario: read_iovnbd(sample_path(s)) for s in SAMPLES if s.role == "test"}
    with tempfile.TemporaryDirectory() as tmp:
        heldout = {sc: read_iovnbd(path) for sc, path in held_out_drives(Path(tmp), args.minutes, args.seed_base).items()}

    header = "model            test set   " + "  ".join(f"{s[:13]:>13}" for s in SCENARIOS) + "  wins"
    print("IDNN improvement over INS in % (displacement CRSE, orientation-rate CRSE), 10 s outages")
    print(header)
    for seed in [None, *args.seeds]:
        name = "shipped" if seed is None else f"seed {seed}"
        model = shipped if seed is None else train_models(train, ModelConfig(**{**hyper, "seed": seed}))
        for label, drives in (("bundled", bundled), ("held-out", heldout)):
            cells, wins = compare(model, drives)
            print(f"{name:<16} {label:<10} " + "  ".join(cells) + f"  {wins}/10", flush=True)


if __name__ == "__main__":
    main()
