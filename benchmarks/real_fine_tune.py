"""Fine-tuning the shipped IDNN on a real car's own drive (issue 62): on each public real log of the
test suite's corpus (``tests/data/real/``, read as ``corpus.json`` says), the shipped model is
fine-tuned on the first half of the log, as a user runs it::

    ionav-viz train LOG --span 0s:T --from-model shipped -o MODEL      # T: half the log, whole seconds

and the INS DR, the shipped model (the parent) and the fine-tuned model are scored on the same
10 s outages in the second half, IMU only: outages tiled back to back from T + 1 s on (the whole log
is read, so the filters have had the first half's GNSS before them, as before any real outage; the
window before the first outage lies after T, so no outage touches the training data). The metric is
the displacement CRSE (m, the paper's Eq. 20) per outage::

    python benchmarks/real_fine_tune.py                       # every corpus log
    python benchmarks/real_fine_tune.py --only roof_mems_rtk --json OUT.json
    python benchmarks/real_fine_tune.py --write-docs docs/real-imu-logs.md   # the page's fine-tuning section
    python benchmarks/real_fine_tune.py --set tune_layers=all # a fine-tuning setting changed (choosing them)

Prints per log the three means, the fine-tuned model minus the INS DR and minus its parent (mean
and 95 % interval of a paired bootstrap over the outages), what fine-tuning kept and how long it took
(wall and CPU time of ``iv.train``, in this process). Issue 62's criterion, per log: the fine-tuned
mean below the INS DR's, and the fine-tuned minus parent interval not wholly above zero. Nothing is
written but ``--json`` and ``--write-docs``; the models go to a temporary folder, removed after.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import math
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _cli import add_debug, output_file, run

import ionav_viz as iv
from ionav_viz.analysis.evaluate import paired_bootstrap_means
from ionav_viz.core.errors import InputError
from ionav_viz.core.fileio import atomic_write_bytes
from ionav_viz.core.gnss_quality import GnssLimits
from ionav_viz.learning.idnn import IdnnEstimator

CORPUS_DIR = Path(__file__).resolve().parent.parent / "tests" / "data" / "real"
CORPUS_FILE = CORPUS_DIR / "corpus.json"
START, END = "<!-- fine-tune:start -->", "<!-- fine-tune:end -->"
OUTAGE_S = 10.0


def read_options(entry: dict, span: str | None = None) -> iv.ReadOptions:
    """How the corpus reads a log (``corpus.json``'s entry), IMU only, over ``span``."""
    log = dict(entry.get("log", {}))
    truth = log.pop("truth_topic", None)
    options = iv.LogOptions(imu_mount="auto", vehicle_speed_topic="none", truth_topic=truth, **log)
    limits = (
        GnssLimits()
        if entry.get("max_sigma_m") is None
        else dataclasses.replace(GnssLimits(), max_sigma_m=entry["max_sigma_m"])
    )
    return iv.ReadOptions(log=options, gnss_limits=limits, span=span)


def interval(baseline: np.ndarray, candidate: np.ndarray) -> list[float] | None:
    """Candidate minus baseline: ``[mean, low, high]`` (m), the 95 % interval of a paired bootstrap
    over the outages (:func:`ionav_viz.analysis.evaluate.paired_bootstrap_means`); None below two outages."""
    if len(baseline) < 2:
        return None
    mb, mc = paired_bootstrap_means(baseline, candidate)
    lo, hi = np.percentile(mc - mb, [2.5, 97.5])
    return [float(np.mean(candidate - baseline)), float(lo), float(hi)]


def crse_per_outage(report: dict, name: str) -> tuple[list[float], np.ndarray]:
    """The outages' start times and ``name``'s displacement CRSE (m) on each, from an evaluate report."""
    starts = [s["start_s"] for s in report["sequences"]]
    return starts, np.array([s[name]["crse_m"] for s in report["sequences"]], dtype=float)


def kept_of(meta: dict) -> str:
    """What fine-tuning kept of each network (the metadata's epoch selection)."""
    selection = meta.get("epoch_selection", {})
    kept = [f"{name}: {selection[name].get('kept', '?')}" for name in ("displacement", "yaw_rate") if name in selection]
    if "ins_blend" in selection:
        kept.append(f"INS DR's share of the displacement {100 * selection['ins_blend']['kept']:.0f} %")
    return "; ".join(kept)


def measure(name: str, entry: dict, config_overrides: dict, folder: Path, fraction: float) -> dict:
    """Fine-tune on the first ``fraction`` of one corpus log, score on the rest."""
    path = CORPUS_DIR / entry["file"]
    drive = iv.load_drive(str(path), read_options(entry))
    length_s = float(drive.t_s[-1] - drive.t_s[0])
    split_s = float(math.floor(length_s * fraction))
    config = iv.fine_tune_settings("shipped")
    if config_overrides:
        config = dataclasses.replace(config, **config_overrides)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    model = iv.train(
        folder / name,
        [str(path)],
        iv.TrainingOptions(config, "shipped"),
        read=read_options(entry, f"0s:{split_s:g}s"),
        command=f"benchmarks/real_fine_tune.py ({name})",
    )
    wall_s, cpu_s = time.perf_counter() - wall0, time.process_time() - cpu0
    run_opts = {"warm_up_s": split_s + 1.0}  # the window before the first outage starts after the training span
    read = read_options(entry)
    parent = iv.evaluate(
        [str(path)], OUTAGE_S, estimators=["ins", "idnn"], read=read, run=iv.RunOptions(**run_opts)
    ).to_dict()
    network = iv.evaluate(
        [str(path)], OUTAGE_S, estimators=[IdnnEstimator(arbiter=False)], read=read, run=iv.RunOptions(**run_opts)
    ).to_dict()
    tuned = iv.evaluate(
        [str(path)],
        OUTAGE_S,
        estimators=["idnn"],
        read=read,
        run=iv.RunOptions(model=str(folder / name), strict=True, **run_opts),
    ).to_dict()
    starts, ins = crse_per_outage(parent, "ins")
    _, shipped = crse_per_outage(parent, "idnn")
    _, alone = crse_per_outage(network, "idnn")
    tuned_starts, fine = crse_per_outage(tuned, "idnn")
    if tuned_starts != starts:
        raise RuntimeError(f"{name}: the two evaluations placed different outages")
    return {
        "log": name,
        "grade": entry["grade"],
        "length_s": round(length_s, 1),
        "split_s": split_s,
        "outages": len(starts),
        "start_s": starts,
        "crse_m": {"ins": ins.tolist(), "parent": shipped.tolist(), "parent_network": alone.tolist(),
                   "fine_tuned": fine.tolist()},
        "mean_m": {"ins": float(ins.mean()), "parent": float(shipped.mean()), "parent_network": float(alone.mean()),
                   "fine_tuned": float(fine.mean())}
        if len(starts)
        else {},
        "fine_tuned_minus_ins_m": interval(ins, fine),
        "fine_tuned_minus_parent_m": interval(shipped, fine),
        "kept": kept_of(model.metadata),
        "fine_tune_wall_s": round(wall_s, 1),
        "fine_tune_cpu_s": round(cpu_s, 1),
        "n_examples": model.metadata["training"]["n_examples"],
        "ins_blend": model.metadata["epoch_selection"].get("ins_blend"),
        "ellipse": {"parent": ellipse(parent), "fine_tuned": ellipse(tuned)},
    }


def ellipse(report: dict) -> dict | None:
    """The IDNN's 95 % ellipse on an evaluate report's outages: the share of final errors inside it
    (%), the ANEES (1 when honest) and the outages counted; None without a covariance."""
    c = report["summary"]["idnn"].get("consistency")
    return None if c is None else {"coverage_95": c["coverage_95"], "anees": c["anees"], "n_outages": c["n_outages"]}


def ellipse_cell(e: dict | None) -> str:
    """``inside % / ANEES`` of :func:`ellipse`, or a dash."""
    return "–" if e is None else f"{e['coverage_95']:.0f} % / {e['anees']:.2f}"


def verdict(result: dict) -> str:
    """Issue 62's criterion on one log: below the INS DR (mean) and not above the parent beyond the spread."""
    if not result["outages"]:
        return "no outage"
    below_ins = result["mean_m"]["fine_tuned"] < result["mean_m"]["ins"]
    gap = result["fine_tuned_minus_parent_m"]
    above_parent = gap is not None and gap[1] > 0
    return (
        "holds"
        if below_ins and not above_parent
        else ", ".join(([] if below_ins else ["not below the INS DR"]) + (["above its parent"] if above_parent else []))
    )


def _gap(gap: list[float] | None) -> str:
    return "–" if gap is None else f"{gap[0]:+.2f} [{gap[1]:+.2f}, {gap[2]:+.2f}]"


HEADER = (
    "| log | split (s) | outages | INS DR (m) | parent's network alone (m) | parent (m) | fine-tuned (m) "
    "| fine-tuned - INS DR (m) | fine-tuned - parent (m) | criterion | fine-tuned: inside its 95 % ellipse / ANEES "
    "| fine-tuning kept | fine-tuning wall / CPU (s) |"
)
RULE = "|---|---|---|---|---|---|---|---|---|---|---|---|---|"


def row(r: dict) -> str:
    m = r["mean_m"]
    means = " | ".join(f"{m[k]:.2f}" if m else "–" for k in ("ins", "parent_network", "parent", "fine_tuned"))
    gaps = f"{_gap(r['fine_tuned_minus_ins_m'])} | {_gap(r['fine_tuned_minus_parent_m'])}"
    return (
        f"| {r['log']} | {r['split_s']:g} of {r['length_s']:g} | {r['outages']} | {means} | {gaps} | {verdict(r)} | "
        f"{ellipse_cell(r['ellipse']['fine_tuned'])} | {r['kept']} | {r['fine_tune_wall_s']} / {r['fine_tune_cpu_s']} |"
    )


def markdown(results: list[dict], argv: list[str]) -> str:
    command = " ".join(["python benchmarks/real_fine_tune.py", *argv])
    lines = [
        f"Measured by `{command}` on {datetime.date.today().isoformat()} ({os.cpu_count()} cores, "
        f"{platform.machine()}, trained on the CPU, Python {platform.python_version()}, ionav-viz {iv.__version__}); "
        "do not edit by hand. Displacement CRSE per 10 s outage, mean over the outages of the second half; "
        "differences: mean [95 % interval, paired bootstrap over the outages]. The parent is the shipped model "
        "with its history arbiter (the IDNN's default); its network alone, without it. The ellipse: the share of "
        "the outages' final errors inside the fine-tuned model's 95 % ellipse (95 % when honest) and its ANEES "
        "(1 when honest; outputs.md).",
        "",
        HEADER,
        RULE,
    ]
    return "\n".join(lines + [row(r) for r in results]) + "\n"


def check_page(page: Path) -> str:
    try:
        text = page.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(
            f"{page}: cannot be read ({exc.__class__.__name__})",
            "give the docs page to regenerate",
            param="--write-docs",
        ) from None
    if START not in text or END not in text:
        raise InputError(
            f"{page}: no '{START}' ... '{END}' lines to write the fine-tuning section between",
            "add the two lines where the section belongs",
            param="--write-docs",
        )
    return text


def overrides(items: list[str]) -> dict:
    """``--set NAME=VALUE`` as fine-tuning config fields, each value of its field's type."""
    fields = {
        f.name: type(getattr(iv.fine_tune_settings("shipped"), f.name)) for f in dataclasses.fields(iv.ModelConfig)
    }
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or key not in fields:
            raise InputError(
                f"--set {item}: not NAME=VALUE with a ModelConfig field",
                f"choose from {', '.join(sorted(fields))}",
                param="--set",
            )
        kind = fields[key]
        try:
            out[key] = (value.lower() in ("1", "true", "yes")) if kind is bool else kind(value)
        except ValueError:
            raise InputError(f"--set {item}: {value!r} is not a {kind.__name__}", param="--set") from None
    return out


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--only", help="only these logs of the corpus, comma-separated")
    parser.add_argument("--json", type=Path, help="also write every number (per outage too) as JSON here")
    parser.add_argument("--write-docs", type=Path, metavar="PAGE", help="regenerate the page's fine-tuning section")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a fine-tuning setting (ModelConfig field) changed",
    )
    parser.add_argument(
        "--fraction", type=float, default=0.5, help="the share of each log fine-tuned on (default: the first half)"
    )
    args = parser.parse_args()
    corpus = json.loads(CORPUS_FILE.read_text())
    names = sorted(corpus["logs"]) if not args.only else [n.strip() for n in args.only.split(",")]
    unknown = [n for n in names if n not in corpus["logs"]]
    if unknown:
        raise InputError(
            f"--only: {', '.join(unknown)} not in {CORPUS_FILE}",
            f"choose from {', '.join(sorted(corpus['logs']))}",
            param="--only",
        )
    if not 0.1 <= args.fraction <= 0.9:
        raise InputError(f"--fraction {args.fraction:g} out of range", "give 0.1 to 0.9", param="--fraction")
    output_file(args.json, "--json")
    if args.write_docs:
        check_page(args.write_docs)
    config_overrides = overrides(args.set)
    dataclasses.replace(iv.fine_tune_settings("shipped"), **config_overrides).validate()  # before any work
    print(HEADER)
    print(RULE, flush=True)
    results = []
    with tempfile.TemporaryDirectory(prefix="real-fine-tune-") as tmp:
        for name in names:
            result = measure(name, corpus["logs"][name], config_overrides, Path(tmp), args.fraction)
            results.append(result)
            print(row(result), flush=True)
    if args.json:
        atomic_write_bytes(args.json, json.dumps(results, indent=1).encode())
    if args.write_docs:
        head, rest = check_page(args.write_docs).split(START, 1)
        atomic_write_bytes(
            args.write_docs,
            (head + START + "\n" + markdown(results, sys.argv[1:]) + END + rest.split(END, 1)[1]).encode(),
        )
    print(f"\n{sys.version.split()[0]}, ionav-viz {iv.__version__}", file=sys.stderr)


if __name__ == "__main__":
    run(main)
