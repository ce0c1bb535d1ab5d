"""How robust is "the IDNN beats the INS"? Retrain with other seeds and test on unseen drives.

Trains the networks with the shipped model's hyperparameters (its ``metadata.json``)
on the bundled training drives for each ``--seeds`` value, and evaluates each model (and the
shipped one) on

* the bundled synthetic test drives (what ``ionav-viz evaluate --scenario all`` reports), and
* held-out drives simulated here (``--minutes`` long each, seed ``--seed-base`` + scenario
  index) from cars of the simulator's "held-out" fleet, whose sensor and vehicle errors lie
  outside every range of the training fleet. The default seeds 800-804 were used neither by the
  bundled drives nor when choosing the hyperparameters.

Prints, per model and test set, the IDNN's improvement over the INS on mean displacement CRSE
and mean orientation-rate CRSE per scenario (positive = IDNN better) and how many of the ten
comparisons the IDNN wins. Run: ``python benchmarks/idnn_heldout.py``;
``--write docs/results-idnn-seeds.md`` writes the complete Markdown page (heading, the command and
machine, the table, the columns explained) atomically instead.
"""

from __future__ import annotations

import argparse
import datetime
import json
import tempfile
from pathlib import Path

from _cli import add_debug, output_file, run
from results_table import (  # the same held-out cars as docs/results.md
    command_line,
    held_out_drives,
    machine,
    wrap,
    write_atomically,
)

import ionav_viz as iv
from ionav_viz.analysis.evaluate import evaluate_drive, improvement_pct, resolve_bias
from ionav_viz.dataset.catalog import SCENARIOS
from ionav_viz.dataset.samples import SAMPLES, sample_path
from ionav_viz.experiment.registry import resolve
from ionav_viz.learning.idnn import ModelConfig, default_model_dir, load_model
from ionav_viz.learning.training import train_models
from ionav_viz.sources.iovnbd import read_iovnbd


def compare(model, drives: dict) -> list[tuple[float, float]]:
    """Per scenario: the IDNN's improvement over the INS in % (displacement CRSE, orientation-rate CRSE)."""
    out = []
    for scenario in SCENARIOS:
        result = evaluate_drive(drives[scenario], 10, resolve(["ins", "idnn"], model=model))
        ins, idnn = result.metrics["ins"], result.metrics["idnn"]
        disp = improvement_pct(ins["crse_m"].mean(), idnn["crse_m"].mean())
        yaw = improvement_pct(ins["yaw_crse_radps"].mean(), idnn["yaw_crse_radps"].mean())
        out.append((disp, yaw))
    return out


def wins(pairs: list[tuple[float, float]]) -> int:
    return sum(int(d > 0) + int(y > 0) for d, y in pairs)


def page(rows: list[tuple[str, str, list[tuple[float, float]]]], seeds: list[int], minutes: float, seed_base: int) -> str:
    day = datetime.datetime.now(datetime.UTC).date().isoformat()
    total = sum(wins(p) for _, _, p in rows)
    n = sum(2 * len(p) for _, _, p in rows)
    table = ["| Model | Test drives | " + " | ".join(SCENARIOS) + " | Wins |", "|---|---|" + "---:|" * (len(SCENARIOS) + 1)]
    for name, test_set, pairs in rows:
        table.append(f"| {name} | {test_set} | " + " | ".join(f"{d:+.1f} / {y:+.1f}" for d, y in pairs)
                     + f" | {wins(pairs)}/{2 * len(pairs)} |")
    return wrap("\n".join([
        "# The IDNN across training seeds",
        "",
        f"Written by `{command_line()}` on a {machine()} machine ({day}, ionav-viz {iv.__version__}); "
        "do not edit by hand, run the command again.",
        "",
        "Does the IDNN's gain over the INS DR depend on the luck of one training run? The shipped model "
        f"and models retrained with seeds {', '.join(map(str, seeds))} (the shipped model's hyperparameters, the "
        "bundled training drives) are each tested with 10 s outages on the bundled test drive of every "
        "scenario and on the held-out drives of [results.md](results.md) (cars outside the training "
        f"fleet, {minutes:g} minutes each, seeds {seed_base}-{seed_base + len(SCENARIOS) - 1}).",
        "",
        f"- The IDNN wins {total} of {n} comparisons.",
        "",
        "\n".join(table),
        "",
        "Columns:",
        "",
        "- **Model**: `shipped`, or retrained with `seed N` (`ionav-viz train --seed N -o DIR`).",
        "- **Test drives**: `bundled` (the bundled test drives) or `held-out` (cars outside the "
        "training fleet).",
        "- **Scenario columns**: the IDNN's improvement over the INS DR in %, displacement CRSE / "
        "orientation-rate CRSE, each from the means over the drive's outages (positive: the IDNN's "
        "error is lower).",
        "- **Wins**: the comparisons of the row in which the IDNN's error is lower.",
        "",
    ]))


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--seeds", type=int, nargs="*", default=[1, 2, 3], help="training seeds to retrain with")
    parser.add_argument("--minutes", type=float, default=10.0, help="length of each held-out drive")
    parser.add_argument("--seed-base", type=int, default=800, help="seed of the first held-out drive")
    parser.add_argument("--write", metavar="FILE", type=Path, help="write the complete Markdown page to FILE (atomically) instead of printing")
    args = parser.parse_args()
    output_file(args.write, "--write")

    shipped = load_model(default_model_dir())
    hyper = json.loads((default_model_dir() / "metadata.json").read_text())["config"]
    train = [read_iovnbd(sample_path(s)) for s in SAMPLES if s.role == "train"]
    train = [(d, resolve_bias(d)) for d in train]
    bundled = {s.scenario: read_iovnbd(sample_path(s)) for s in SAMPLES if s.role == "test"}
    with tempfile.TemporaryDirectory() as tmp:
        heldout = {sc: read_iovnbd(path) for sc, path in held_out_drives(Path(tmp), args.minutes, args.seed_base).items()}

    if args.write is None:
        print("IDNN improvement over INS in % (displacement CRSE, orientation-rate CRSE), 10 s outages")
        print("model            test set   " + "  ".join(f"{s[:13]:>13}" for s in SCENARIOS) + "  wins")
    rows = []
    for seed in [None, *args.seeds]:
        name = "shipped" if seed is None else f"seed {seed}"
        model = shipped if seed is None else train_models(train, ModelConfig(**{**hyper, "seed": seed}))
        for label, drives in (("bundled", bundled), ("held-out", heldout)):
            pairs = compare(model, drives)
            rows.append((name, label, pairs))
            if args.write is None:
                cells = "  ".join(f"{d:+6.1f} {y:+6.1f}" for d, y in pairs)
                print(f"{name:<16} {label:<10} {cells}  {wins(pairs)}/{2 * len(pairs)}", flush=True)
    if args.write is not None:
        write_atomically(args.write, page(rows, args.seeds, args.minutes, args.seed_base))
        print(args.write)


if __name__ == "__main__":
    run(main)
