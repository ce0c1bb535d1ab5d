"""The IDNN on a vehicle's own data: fine-tune the shipped model on 5 minutes of one car, test on its other drives.

Per simulated car (cars of the simulator's "held-out" fleet, whose sensor and vehicle errors lie
outside every range of the shipped model's training drives, and one car beyond even those):

* five fine-tuning drives, one per scenario (seeds ``SEED``-``SEED+4``), of which only the first
  minute each is used (``--span 0s:60s``): 5 minutes in all, as
  ``ionav-viz train DRIVES --span 0s:60s --from-model shipped -o MODEL``;
* five test drives of the same car, one per scenario, other seeds, ``--minutes`` long each, never
  seen in training (``ionav-viz evaluate DRIVES --model MODEL --outage 10s``, with ``--strict``:
  the leakage check would refuse an outage in training data);

and compares the displacement CRSE (mean over the tiled outages of the five test drives) of the
INS DR, the shipped IDNN and the fine-tuned IDNN at 10 s and 30 s outages. The fine-tuning time is
the wall time of training on this machine (``nice -n 10``, one torch thread).

Run: ``nice -n 10 python benchmarks/own_vehicle.py``; ``--write docs/results-own-vehicle.md``
writes the Markdown page instead of printing the table.
"""

from __future__ import annotations

import argparse
import datetime
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _cli import add_debug, output_file, run
from results_table import command_line, machine, replace_section, wrap, write_atomically

import ionav_viz as iv
from ionav_viz.dataset.catalog import SCENARIOS
from ionav_viz.sim.simulate import fleet_sensors, write_simulated_drive

#: The cars the table reports (held-out fleet seeds; the last one made worse, beyond the fleet).
REPORTED_CARS = (870, 871, 872, 873)
#: The cars fine-tuning's settings were chosen on (``--cars 880,881,882,883``), never the reported ones.
TUNING_CARS = (880, 881, 882, 883)


def cars(seeds: tuple[int, ...] = REPORTED_CARS) -> list[tuple[str, object]]:
    """(label, sensors) of each car tried: held-out cars ``seeds[:-1]``, and ``seeds[-1]`` with errors beyond the fleet's."""
    last = seeds[-1]
    beyond = replace(fleet_sensors("held-out", last), accel_offset_mps2=0.55, gyro_bias_dps=-1.0, gyro_scale_error=0.05,
                     gyro_latency_s=0.2)
    return [(f"held-out car {s}", fleet_sensors("held-out", s)) for s in seeds[:-1]] + [(f"beyond held-out (car {last}, errors x1.4)", beyond)]


def crse(report_json: str) -> dict[str, float]:
    summary = json.loads(report_json)["summary"]
    return {name: stats["crse_m"]["mean"] for name, stats in summary.items() if isinstance(stats, dict) and "crse_m" in stats}


def drift(report_json: str, name: str) -> dict[str, list[float]]:
    """Position error against seconds since the outage began (mean, 10 and 90 %) of one estimator."""
    return json.loads(report_json)["drift"][name]


def measure(folder: Path, label: str, sensors: object, index: int, minutes: float, seed: int, span: str = "0s:60s") -> dict:
    tune = [write_simulated_drive(folder / f"V-car{index}-tune-{sc}.csv", sc, seed + i, 120.0, sensors) for i, sc in enumerate(SCENARIOS)]
    test = [write_simulated_drive(folder / f"V-car{index}-test-{sc}.csv", sc, seed + 50 + i, 60.0 * minutes, sensors)
            for i, sc in enumerate(SCENARIOS)]
    model = folder / f"model-car{index}"
    start = time.perf_counter()
    cpu0 = time.process_time()
    iv.train(model, [str(p) for p in tune], iv.TrainingOptions(from_model="shipped"), read=iv.ReadOptions(span=span),
             command="benchmarks/own_vehicle.py")
    wall_s, cpu_s = time.perf_counter() - start, time.process_time() - cpu0
    row = {"car": label, "tune_wall_s": wall_s, "tune_cpu_s": cpu_s}
    for outage in (10, 30):
        tuned_json = iv.evaluate([str(p) for p in test], outage, estimators=["ins", "idnn"], run=iv.RunOptions(model=str(model), strict=True)).to_json()
        shipped_json = iv.evaluate([str(p) for p in test], outage, estimators=["idnn"], run=iv.RunOptions(strict=True)).to_json()
        tuned, shipped = crse(tuned_json), crse(shipped_json)
        row[outage] = {"ins": tuned["ins"], "shipped": shipped["idnn"], "tuned": tuned["idnn"]}
        if outage == 30:
            row["drift"] = {"ins": drift(tuned_json, "ins"), "shipped": drift(shipped_json, "idnn"), "tuned": drift(tuned_json, "idnn")}
    return row


def figure(rows: list[dict], path: Path) -> None:
    """The 30 s drift curves (mean position error, 10-90 % band) of each car: INS DR, shipped and fine-tuned IDNN."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    fig, axes = plt.subplots(1, len(rows), figsize=(3.2 * len(rows), 3.0), sharey=True, constrained_layout=True)
    styles = {"ins": ("INS DR", "0.45"), "shipped": ("shipped IDNN (before)", "tab:orange"), "tuned": ("fine-tuned IDNN (after)", "tab:blue")}
    for ax, row in zip(axes, rows):
        for key, (label, color) in styles.items():
            d = row["drift"][key]
            ax.plot(d["t_s"], d["mean_m"], color=color, label=label)
            ax.fill_between(d["t_s"], d["p10_m"], d["p90_m"], color=color, alpha=0.15, linewidth=0)
        if all(np.isclose(row[o]["tuned"], row[o]["shipped"]) for o in (10, 30)):  # the blue line hides the orange: say why
            ax.text(0.04, 0.96, "fine-tuned hides shipped: validation\nkept the shipped displacement network", transform=ax.transAxes,
                    ha="left", va="top", fontsize=7, color="tab:blue")
        ax.set_title(row["car"], fontsize=8)
        ax.set_xlabel("s since the outage began")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("position error (m)")
    axes[0].legend(fontsize=7, loc="upper left")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def gain(base: float, new: float) -> float:
    return 100.0 * (base - new) / base


def table(rows: list[dict]) -> list[str]:
    out = ["| Car | Outage | INS DR (m) | shipped IDNN (m) | fine-tuned IDNN (m) | fine-tuned vs INS DR | fine-tuned vs shipped | "
           "shipped vs INS DR | fine-tuning time |",
           "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for row in rows:
        for outage in (10, 30):
            c = row[outage]
            out.append(f"| {row['car']} | {outage} s | {c['ins']:.2f} | {c['shipped']:.2f} | {c['tuned']:.2f} | {gain(c['ins'], c['tuned']):+.0f} % | "
                       f"{gain(c['shipped'], c['tuned']):+.0f} % | {gain(c['ins'], c['shipped']):+.0f} % | {row['tune_wall_s']:.0f} s |")
    for outage in (10, 30):
        mean = sum(gain(r[outage]["ins"], r[outage]["tuned"]) for r in rows) / len(rows)
        mean_shipped = sum(gain(r[outage]["ins"], r[outage]["shipped"]) for r in rows) / len(rows)
        out.append(f"| **mean of the cars' gains** | {outage} s | | | | **{mean:+.0f} %** | | {mean_shipped:+.0f} % | |")
    return out


def page(rows: list[dict], minutes: float) -> str:
    day = datetime.datetime.now(datetime.UTC).date().isoformat()
    return wrap("\n".join([
        "# The IDNN on your own vehicle",
        "",
        f"Written by `{command_line()}` on a {machine()} machine ({day}, ionav-viz {iv.__version__}), "
        "one torch thread at `nice -n 10`; do not edit by hand, run the command again.",
        "",
        "Each car is simulated with sensor and vehicle errors outside every range of the shipped model's "
        "training drives (the simulator's held-out fleet, and one car beyond it). The shipped model is "
        "fine-tuned on 5 minutes of the car (the first minute of one drive per scenario: "
        "`ionav-viz train DRIVES --span 0s:60s --from-model shipped -o MODEL`), then tested on five other "
        f"drives of the same car ({minutes:g} minutes each, one per scenario, never seen in training; "
        "`ionav-viz evaluate DRIVES --model MODEL --outage 10s --strict`). Cells: displacement CRSE, mean "
        "over the tiled outages of the five test drives; gains: how much lower (positive = better).",
        "",
        "\n".join(table(rows)),
        "",
        "Fine-tuning time: wall time of `train --from-model shipped` on the 5 minutes (calibrating "
        "inputs with the GNSS-aided INS, then 100 epochs of each network on the first 80 % of each drive's minute, "
        "pulled towards the parent's weights; the last 20 % validates, and a network whose fine-tuned weights do not beat "
        "the parent's there is fine-tuned again with its first layer alone trained, and keeps the parent's weights when that does "
        "not beat them either; one that does is fine-tuned again (those layers) on the whole minute: "
        "`fine_tune_config` in `ionav_viz/learning/training.py`; the time is longer where the first layer is tried). "
        "A fine-tuned IDNN equal to the shipped one (+0 %) is a car whose displacement network kept the parent's weights "
        "(the displacement CRSE depends on that network only).",
        "",
        "Position error against seconds since the outage began, 30 s outages of the test drives (mean, "
        "10-90 % band), before (shipped model) and after fine-tuning:",
        "",
        "![drift before and after fine-tuning](figure-own-vehicle.png)",
    ]))


def results_section(rows: list[dict], minutes: float, detail: str) -> str:
    """docs/results.md's "Your own vehicle" section: the table, the command, a link to the detail page."""
    day = datetime.datetime.now(datetime.UTC).date().isoformat()
    return wrap("\n".join([
        "## Your own vehicle",
        "",
        f"Written by `{command_line()}` ({day}, ionav-viz {iv.__version__}), with the page "
        f"[{detail}]({detail}) (how the cars are made, the drift curves before and after). On each simulated car, "
        "outside the shipped model's training ranges, the shipped IDNN is fine-tuned on 5 minutes of the car "
        "(`ionav-viz train DRIVES --span 0s:60s --from-model shipped -o MODEL`) and tested on five other drives of the car "
        f"({minutes:g} minutes each, never seen in training; `ionav-viz evaluate DRIVES --model MODEL --outage 10s --strict`). "
        "Cells: displacement CRSE, mean over the outages of the test drives; gains: how much lower (positive = better).",
        "",
        "\n".join(table(rows)),
    ]))


def main() -> None:
    import torch

    torch.set_num_threads(1)
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--minutes", type=float, default=5.0, help="length of each test drive")
    parser.add_argument("--tune-span", default="0s:60s", help="the minute of each 2-minute fine-tuning drive trained on")
    parser.add_argument("--write", type=Path, help="write the Markdown page here instead of printing the table")
    parser.add_argument("--cars", default=",".join(map(str, REPORTED_CARS)),
                        help=f"held-out car seeds, the last made worse (choose settings on {','.join(map(str, TUNING_CARS))}, never on the reported ones)")
    args = parser.parse_args()
    seeds = tuple(int(s) for s in args.cars.split(","))
    if args.write and seeds != REPORTED_CARS:
        parser.error("--write reports the cars in REPORTED_CARS only")
    output_file(args.write, "--write")  # before the hour of training: a folder that is not there is one line, exit code 2
    rows = []
    with tempfile.TemporaryDirectory(prefix="own-vehicle-") as tmp:
        for index, (label, sensors) in enumerate(cars(seeds)):
            # the drives' seeds: the reported cars' as ever; the tuning cars drive other roads too
            seed = 1000 + 100 * index + (0 if seeds == REPORTED_CARS else 5000)
            rows.append(measure(Path(tmp), label, sensors, index, args.minutes, seed, args.tune_span))
            print("\n".join(table(rows[-1:])[2:4]), flush=True)
    if args.write:
        figure(rows, args.write.parent / "figure-own-vehicle.png")
        write_atomically(args.write, page(rows, args.minutes))
        results = args.write.parent / "results.md"
        if results.is_file():  # the summary page's section (benchmarks/results_table.py keeps it)
            replace_section(results, results_section(rows, args.minutes, args.write.name))
        print(args.write)
    else:
        print("\n".join(table(rows)))


if __name__ == "__main__":
    run(main)
