"""The measured-results tables (docs/results.md): every built-in estimator per scenario, on the
bundled test drives and on held-out drives from cars outside the training fleet.

    python benchmarks/results_table.py                          # prints the Markdown
    python benchmarks/results_table.py --write docs/results.md  # writes the complete page
    python benchmarks/results_table.py [--model DIR] [--minutes 10] [--seed-base 800]

Held-out drives: one per scenario, ``--minutes`` long, seed ``--seed-base`` + scenario index, its
sensor and vehicle errors drawn from the simulator's "held-out" fleet (every parameter outside the
range the training drives were drawn from; ``ionav_viz.sim.simulate.FLEETS``). The same drive is
``ionav-viz simulate SCENARIO --fleet held-out --seed SEED --duration 10m -o FILE``.

One table per metric, with 10 s outages tiling each drive: each estimator's mean displacement CRSE
(m), mean orientation-rate CRSE (rad/s), mean final position error (m) and mean final error as a
percentage of the distance driven in the outage. ``--write FILE`` writes a complete Markdown page
(heading, the command and machine, the tables, the columns explained), atomically: under a
temporary name beside FILE, renamed when complete.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import logging
import os
import re
import sys
import tempfile
import textwrap
from pathlib import Path

import ionav_viz as iv
from ionav_viz.dataset.catalog import SCENARIOS
from ionav_viz.sim.simulate import fleet_sensors, write_simulated_drive

#: (summary key, decimals, table heading)
METRICS = (
    ("crse_m", 2, "Displacement CRSE (m)"),
    ("yaw_crse_radps", 4, "Orientation-rate CRSE (rad/s)"),
    ("final_position_error_m", 2, "Final position error (m)"),
    ("final_error_pct", 1, "Final position error (% of the distance driven)"),
)


def held_out_drives(directory: Path, minutes: float, seed_base: int) -> dict[str, Path]:
    return {sc: write_simulated_drive(directory / f"V-heldout-{sc}.csv", sc, seed_base + i, 60.0 * minutes, fleet_sensors("held-out", seed_base + i))
            for i, sc in enumerate(SCENARIOS)}


def machine() -> str:
    """'2-core, 24 GiB' for this machine (the cores this process may use, the physical memory)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    mem_gib = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    return f"{cores}-core, {mem_gib:.0f} GiB"


def command_line() -> str:
    """The command as run, with the script's path relative to the repository."""
    script = Path(sys.argv[0]).resolve()
    with contextlib.suppress(ValueError):
        script = script.relative_to(Path(__file__).resolve().parent.parent)
    return " ".join(["python", str(script), *sys.argv[1:]])


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` under a temporary name beside it and rename it when complete."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def measure(model: str | None, minutes: float, seed_base: int) -> tuple[dict[str, str], list[tuple[str, str, dict]]]:
    """Estimator labels by name, and (scenario, test set, report dict) per drive."""
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        sets = {"bundled": {sc: sc for sc in SCENARIOS},
                "held-out": {sc: str(p) for sc, p in held_out_drives(Path(tmp), minutes, seed_base).items()}}
        for scenario in SCENARIOS:
            for name, drives in sets.items():
                runs.append((scenario, name, iv.evaluate([drives[scenario]], 10.0, run=iv.RunOptions(model=model)).to_dict()))
    labels = {e["name"]: e["label"] for e in runs[0][2]["estimators"]}
    return labels, runs


def tables(labels: dict[str, str], runs: list[tuple[str, str, dict]]) -> str:
    out = []
    for key, decimals, heading in METRICS:
        out += [f"## {heading}", "", "| Scenario | Drives | Outages | " + " | ".join(labels.values()) + " |",
                "|---|---|---:|" + "---:|" * len(labels)]
        for scenario, test_set, rep in runs:
            s = rep["summary"]
            cells = [f"{s[e][key]['mean']:.{decimals}f}" for e in labels]
            out.append(f"| {scenario} | {test_set} | {rep['n_sequences']} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def comparisons(labels: dict[str, str], runs: list[tuple[str, str, dict]]) -> str:
    """What the tables say, counted from them (no number here is typed by hand)."""
    n = len(runs)
    lines = []
    if "ins" in labels and "idnn" in labels:
        disp = sum(r["summary"]["idnn"]["crse_m"]["mean"] < r["summary"]["ins"]["crse_m"]["mean"] for _, _, r in runs)
        yaw = sum(r["summary"]["idnn"]["yaw_crse_radps"]["mean"] < r["summary"]["ins"]["yaw_crse_radps"]["mean"] for _, _, r in runs)
        lines.append(f"- The {labels['idnn']}'s mean displacement CRSE is lower than the {labels['ins']}'s on {disp} of {n} drives, "
                     f"its mean orientation-rate CRSE on {yaw} of {n}.")
    best: dict[str, int] = {}
    for _, _, r in runs:
        name = min(labels, key=lambda e: r["summary"][e]["crse_m"]["mean"])
        best[name] = best.get(name, 0) + 1
    ranked = ", ".join(f"{labels[e]} on {k}" for e, k in sorted(best.items(), key=lambda x: -x[1]))
    lines.append(f"- Lowest mean displacement CRSE: {ranked} of {n} drives.")
    return "\n".join(lines)


def wrap(markdown: str, width: int = 100) -> str:
    """Prose paragraphs and bullets wrapped at ``width`` columns; headings and tables as they are."""
    out = []
    markdown = re.sub(r"(\d) (GiB|MB|s|m)\b", "\\1\u00a0\\2", markdown.strip("\n"))  # a number stays with its unit
    for block in markdown.split("\n\n"):
        if block.startswith(("#", "|")):
            out.append(block)
            continue
        items = re.split(r"\n(?=- )", block)
        out.append("\n".join(textwrap.fill(item, width, subsequent_indent="  " if item.startswith("- ") else "",
                                            break_long_words=False, break_on_hyphens=False) for item in items))
    return "\n\n".join(out).replace("\u00a0", " ") + "\n"


def page(labels: dict[str, str], runs: list[tuple[str, str, dict]], minutes: float, seed_base: int, model: str | None) -> str:
    day = datetime.datetime.now(datetime.UTC).date().isoformat()
    model_text = f"the IDNN model in `{model}`" if model else "the shipped IDNN model"
    return wrap("\n".join([
        "# Measured results",
        "",
        f"Written by `{command_line()}` on a {machine()} machine ({day}, ionav-viz {iv.__version__}, "
        f"{model_text}); do not edit by hand, run the command again.",
        "",
        "Every built-in estimator on 10 s GNSS outages tiling each drive (the paper's protocol), on two "
        "sets of synthetic drives: **bundled**, the bundled test drive of each scenario "
        "(`ionav-viz evaluate SCENARIO`), and **held-out**, one drive per scenario from a car of the "
        "simulator's held-out fleet, whose sensor and vehicle errors all lie outside the ranges of the "
        f"training drives (`ionav-viz simulate SCENARIO --fleet held-out --seed SEED --duration {minutes:g}m -o FILE.csv`, "
        f"seeds {seed_base}-{seed_base + len(SCENARIOS) - 1} in the scenario order below). Each cell is the mean "
        "over the drive's outages.",
        "",
        comparisons(labels, runs),
        "",
        tables(labels, runs),
        "Columns:",
        "",
        "- **Drives**: `bundled` or `held-out`, as above; **Outages**: the outages scored on that drive.",
        "- **Displacement CRSE (m)**: per outage, the sum over its 1 s windows of the absolute error of "
        "the distance travelled in the window, against GNSS.",
        "- **Orientation-rate CRSE (rad/s)**: the same for the mean yaw rate of each window.",
        "- **Final position error (m)**: the 2D distance between the estimated and the GNSS position at "
        "the end of the outage.",
        "- **Final position error (% of the distance driven)**: that error over the GNSS distance driven "
        "in the outage (outages under 10 m driven are left out of this mean).",
        "- Estimators: " + ", ".join(f"{label} (`{name}`)" for name, label in labels.items()) + "; "
        "described in [method.md](method.md).",
        "",
    ]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", help="IDNN model directory (default: the shipped one)")
    parser.add_argument("--minutes", type=float, default=10.0, help="length of each held-out drive")
    parser.add_argument("--seed-base", type=int, default=800, help="seed of the first held-out drive")
    parser.add_argument("--write", metavar="FILE", type=Path, help="write the complete Markdown page to FILE (atomically) instead of printing the tables")
    args = parser.parse_args()
    if args.write is not None and not args.write.parent.is_dir():
        parser.error(f"--write: folder {args.write.parent} does not exist")
    logging.getLogger("ionav_viz").setLevel(logging.ERROR)
    labels, runs = measure(args.model, args.minutes, args.seed_base)
    if args.write is None:
        print(comparisons(labels, runs) + "\n\n" + tables(labels, runs), end="")
    else:
        write_atomically(args.write, page(labels, runs, args.minutes, args.seed_base, args.model))
        print(args.write)


if __name__ == "__main__":
    main()
