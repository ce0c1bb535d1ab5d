"""The measured-results page (docs/results.md): every built-in estimator on 10, 30 and 60 s GNSS
outages, on the bundled test drives, on held-out drives from cars outside the training fleet, and
on simulated 6-axis logs of the kinds users record.

    python benchmarks/results_table.py                          # prints the Markdown
    python benchmarks/results_table.py --write docs/results.md  # writes the complete page
    python benchmarks/results_table.py [--model DIR] [--minutes 10] [--seed-base 800] [--lengths 10,30,60]

Held-out drives: one per scenario, ``--minutes`` long, seed ``--seed-base`` + scenario index, its
sensor and vehicle errors drawn from the simulator's "held-out" fleet (every parameter outside the
range the training drives were drawn from; ``ionav_viz.sim.simulate.FLEETS``). The same drive is
``ionav-viz simulate SCENARIO --fleet held-out --seed SEED --duration 10m -o FILE``.

6-axis logs (:mod:`ionav_viz.sim.imu`, written as MCAP and read back like a user's log, the mount
estimated and applied, scored against the reference on ``/truth/fix``): a phone at 10 Hz in
town (IMU only), a roof MEMS IMU at 100 Hz on hilly roads (grade 6 % rms; IMU only: its CAN speed
left out), the same car on the motorway with its CAN speed, and a dash device on the motorway (IMU
only; the phone and dash grades measured against public real logs: docs/real-imu-logs.md).
``ionav-viz simulate SCENARIO --imu phone --seed SEED --duration 10m -o FILE.mcap`` writes one (the
hilly set uses a steeper grade than the CLI's).

Outages tile each drive. Each cell is a mean over the outages of a set of drives: the final position
error as a percentage of the distance driven in the outage, and the displacement CRSE (m).
``--write FILE`` writes a complete Markdown page atomically: under a temporary name beside FILE,
renamed when complete. ``--real-logs``, ``--model`` and ``--write`` are checked before any
measurement: a missing or malformed file is one line naming it (and the entry and field), exit
code 2 (``--debug``: the traceback).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import logging
import os
import re
import sys
import tempfile
import textwrap
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from _cli import add_debug, check_model, lengths_s, named, output_file, read_json, run

import ionav_viz as iv
from ionav_viz.dataset.catalog import SCENARIOS
from ionav_viz.experiment.outages import GNSS_OUTAGE
from ionav_viz.sim.imu import IMU_GRADES, SIM_TRUTH_TOPIC, write_imu_log
from ionav_viz.sim.simulate import fleet_sensors, write_simulated_drive

#: The 6-axis sets: (key, title, grade, steeper grade or None, IMU only, scenarios, first seed).
IMU_SETS = (
    ("phone-urban", "phone IMU 10 Hz, urban", "phone", None, True, ("roundabout", "sharp-cornering", "hard-brake"), 900),
    ("mems-hills", "roof MEMS IMU 100 Hz, hills", "mems", 0.06, True, ("quick-accel", "roundabout", "hard-brake"), 910),
    ("highway-can", "highway, with CAN speed", "mems", None, False, ("motorway", "motorway"), 920),
    ("dash-highway", "dash device IMU 104 Hz, highway", "dash", None, True, ("motorway", "motorway"), 940),
)
ESTIMATORS = ("ins", "idnn", "odo", "ekf", "gins")


def held_out_drives(directory: Path, minutes: float, seed_base: int) -> dict[str, Path]:
    return {sc: write_simulated_drive(directory / f"V-heldout-{sc}.csv", sc, seed_base + i, 60.0 * minutes, fleet_sensors("held-out", seed_base + i))
            for i, sc in enumerate(SCENARIOS)}


def imu_logs(directory: Path, minutes: float, sets: list[str] | None = None) -> dict[str, list[Path]]:
    out = {}
    for key, _, grade, steep, _, scenarios, seed in IMU_SETS:
        if sets is not None and key not in sets:
            continue
        g = IMU_GRADES[grade] if steep is None else replace(IMU_GRADES[grade], grade_rms=steep)
        out[key] = [write_imu_log(directory / f"{key}-{i}.mcap", sc, seed + i, 60.0 * minutes, g) for i, sc in enumerate(scenarios)]
    return out


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


#: docs/results.md's "Your own vehicle" section lies between these lines: benchmarks/own_vehicle.py
#: writes it (:func:`replace_section`), and this script keeps it when it writes the page again.
OWN_VEHICLE_BEGIN = "<!-- section written by benchmarks/own_vehicle.py --write: run it again, do not edit by hand -->"
OWN_VEHICLE_END = "<!-- end of the section written by benchmarks/own_vehicle.py -->"


def kept_section(path: Path, begin: str = OWN_VEHICLE_BEGIN, end: str = OWN_VEHICLE_END) -> str:
    """The section of ``path`` from the ``begin`` line to the ``end`` line (both included), "" when none."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError:
        return ""
    a, b = text.find(begin), text.find(end)
    return text[a : b + len(end)] + "\n" if 0 <= a < b else ""


def replace_section(path: Path, section: str, begin: str = OWN_VEHICLE_BEGIN, end: str = OWN_VEHICLE_END) -> None:
    """Put ``section`` (Markdown, without the marker lines) between ``begin`` and ``end`` in ``path``,
    replacing what lay there, or at the end of the file when it has none (atomically)."""
    text = Path(path).read_text(encoding="utf-8")
    block = f"{begin}\n\n{section.strip()}\n\n{end}\n"
    a, b = text.find(begin), text.find(end)
    if 0 <= a < b:
        text = text[:a] + block + text[b + len(end):].lstrip("\n")
    else:
        text = text.rstrip("\n") + "\n\n" + block
    write_atomically(Path(path), text)


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


@dataclass
class Cell:
    """Per estimator, the outages' final errors (% of distance) and displacement CRSEs (m) of a set."""

    pct: dict[str, list[float]]
    crse: dict[str, list[float]]
    outages: int = 0
    #: per drive of the set, each estimator's mean displacement CRSE (m)
    drive_crse: list[dict[str, float]] = field(default_factory=list)
    #: per estimator that gives a covariance, its consistency over the set (analysis.consistency)
    consistency: dict[str, dict] = field(default_factory=dict)

    def add(self, rep: dict) -> None:
        names = [e["name"] for e in rep["estimators"]]
        by_drive: dict[str, dict[str, list[float]]] = {}
        for seq in rep["sequences"]:
            for name in names:
                m = seq.get(name)
                if not isinstance(m, dict):
                    continue
                pct = m.get("final_error_pct")
                if pct is not None and np.isfinite(pct):  # none for outages under 10 m driven
                    self.pct.setdefault(name, []).append(pct)
                self.crse.setdefault(name, []).append(m["crse_m"])
                by_drive.setdefault(seq["drive"], {}).setdefault(name, []).append(m["crse_m"])
        self.outages += len(rep["sequences"])
        self.consistency.update({n: rep["summary"][n]["consistency"] for n in names if "consistency" in rep["summary"].get(n, {})})
        self.drive_crse += [{"drive": name} | {n: float(np.mean(v)) for n, v in d.items()} for name, d in by_drive.items()]

    def mean(self, name: str, key: str) -> float | None:
        values = (self.pct if key == "pct" else self.crse).get(name)
        return float(np.mean(values)) if values else None


def measure(model: str | None, minutes: float, seed_base: int, lengths: list[float],
            sets: list[str] | None = None) -> tuple[dict[str, str], dict[tuple[str, float], Cell], dict | None]:
    """Estimator labels by name, per (set, outage length) the pooled outages (of ``sets`` only,
    keys of :func:`set_titles`, when given), and the phone set through its receiver's own losses
    (:func:`receiver_losses`; None without the phone set)."""
    cells: dict[tuple[str, float], Cell] = {}
    labels: dict[str, str] = {}
    losses = None
    run = iv.RunOptions(model=model)

    def add(key: str, drives: list, read: iv.ReadOptions | None = None) -> None:
        for length, rep in iv.evaluate(drives, list(lengths), estimators=list(ESTIMATORS), run=run, read=read).items():
            d = rep.to_dict()
            labels.update({e["name"]: e["label"] for e in d["estimators"]})
            cells.setdefault((key, length), Cell({}, {})).add(d)

    with tempfile.TemporaryDirectory() as tmp:
        if sets is None or "bundled" in sets:
            add("bundled", list(SCENARIOS))
        if sets is None or "held-out" in sets:
            add("held-out", [str(p) for p in held_out_drives(Path(tmp), minutes, seed_base).values()])
        logs = imu_logs(Path(tmp), minutes, sets)
        for key, _, _, _, imu_only, _, _ in IMU_SETS:
            if key not in logs:
                continue
            log_options = iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, vehicle_speed_topic="none" if imu_only else None, imu_mount="auto")
            add(key, [str(p) for p in logs[key]], iv.ReadOptions(log=log_options))
            if key == "phone-urban":
                losses = receiver_losses([str(p) for p in logs[key]], run, iv.ReadOptions(log=log_options))
    return {n: labels[n] for n in ESTIMATORS if n in labels}, cells, losses


def receiver_losses(paths: list[str], run: iv.RunOptions, read: iv.ReadOptions) -> dict | None:
    """A set's logs ``paths`` through their receiver's own losses of the sky (``--on gnss-outage``
    beside the reference: each from the last receiver fix before it, scored against the reference at
    the first after it): the losses (``gap_s``, ``span_m``) and every estimator's final error (m) on
    each; None when the receiver never loses the sky."""
    try:
        rep = iv.evaluate(paths, 10.0, iv.AroundEvents((GNSS_OUTAGE,)), estimators=list(ESTIMATORS), run=run, read=read)
    except iv.InputError:  # no loss on any drive
        return None
    d = rep.to_dict()
    bridged = d.get("gnss_outages", {}).get("bridged", [])
    if not bridged:
        return None
    names = [e["name"] for e in d["estimators"]]
    return {"labels": {e["name"]: e["label"] for e in d["estimators"]}, "gap_s": [b["gap_s"] for b in bridged],
            "span_m": [b["span_m"] for b in bridged], "final_error_m": {n: [b["final_error_m"][n] for b in bridged] for n in names},
            "drives": len(paths)}


def receiver_loss_table(losses: dict) -> str:
    """:func:`receiver_losses` as Markdown: per estimator the mean and largest final error (m) and
    the summed error as a share of the summed straight-line span (the loss's own "distance")."""
    span = float(np.sum(losses["span_m"]))
    rows = ["| estimator | mean final error (m) | largest (m) | summed error / summed span |", "|---|---:|---:|---:|"]
    for name, errs in losses["final_error_m"].items():
        e = np.asarray(errs)
        rows.append(f"| {losses['labels'][name]} | {e.mean():.1f} | {e.max():.1f} | {100.0 * e.sum() / span:.1f} % |")
    return "\n".join(rows)


def set_titles(cells: dict | None = None) -> dict[str, str]:
    """The sets' titles by key (those measured in ``cells`` when given)."""
    titles = {"bundled": "bundled test drives (IO-VNBD format)", "held-out": "held-out fleet (IO-VNBD format)"} | {
        key: title for key, title, *_ in IMU_SETS}
    return titles if cells is None else {k: v for k, v in titles.items() if any(key == k for key, _ in cells)}


def overview(labels: dict[str, str], cells: dict[tuple[str, float], Cell], lengths: list[float]) -> str:
    """The issue's shape: per outage length and set, the best estimator and the others (% of distance)."""
    titles = set_titles(cells)
    out = ["| outage | " + " | ".join(titles.values()) + " |", "|---|" + "---|" * len(titles)]
    for length in lengths:
        row = []
        for key in titles:
            cell = cells[(key, length)]
            ranked = sorted((m, n) for n in labels if (m := cell.mean(n, "pct")) is not None)
            if not ranked:
                row.append("–")
                continue
            best = f"best {ranked[0][0]:.1f} % ({ranked[0][1]})"
            row.append(", ".join([best] + [f"{n} {m:.1f}" for m, n in ranked[1:]]))
        out.append(f"| {length:g} s | " + " | ".join(row) + " |")
    return "\n".join(out)


def tables(labels: dict[str, str], cells: dict[tuple[str, float], Cell], lengths: list[float]) -> str:
    out = []
    titles = set_titles(cells)
    for key, heading, decimals in (("pct", "Final position error (% of the distance driven)", 1), ("crse", "Displacement CRSE (m)", 2)):
        out += [f"## {heading}", "", "| Drives | Outage | Outages | " + " | ".join(labels.values()) + " |",
                "|---|---:|---:|" + "---:|" * len(labels)]
        for s_key, title in titles.items():
            for length in lengths:
                cell = cells[(s_key, length)]
                values = [cell.mean(n, key) for n in labels]
                out.append(f"| {title} | {length:g} s | {cell.outages} | " + " | ".join("–" if v is None else f"{v:.{decimals}f}" for v in values) + " |")
        out.append("")
    return "\n".join(out)


def comparisons(labels: dict[str, str], cells: dict[tuple[str, float], Cell], lengths: list[float]) -> str:
    """What the tables say, counted from them (no number here is typed by hand)."""
    lines = []
    if "idnn" in labels and "ins" in labels:
        for length in lengths:
            drives = [d for (_, ln), c in cells.items() if ln == length for d in c.drive_crse if "idnn" in d]
            worse = [f"{d['drive']} ({d['idnn']:.1f} against {d['ins']:.1f} m)" for d in drives if d["idnn"] > d["ins"]]
            lines.append(f"- {length:g} s outages: the IDNN's mean displacement CRSE is above the INS DR's on {len(worse)} of {len(drives)} drives"
                         + (": " + ", ".join(worse) if worse else "") + ".")
    for key, title, _, _, imu_only, _, _ in IMU_SETS:
        parts = []
        for length in lengths:
            m = cells[(key, length)].mean("gins", "pct") if (key, length) in cells else None
            if m is not None:
                parts.append(f"{m:.1f} % after {length:g} s")
        if parts:
            lines.append(f"- {labels.get('gins', 'gins')} on the {title} logs{' (IMU only)' if imu_only else ''}: " + ", ".join(parts) + ".")
    return "\n".join(lines)


def phone_ratio_sentence(cells: dict, real: list[dict], length: float = 10.0) -> str:
    """"; on the simulated phone set `gins` ends at R of the INS DR's error after 10 s, on these
    real phones at A-B of it", measured: the simulated set's pooled means and each real phone log's
    (a log named after the public phone logs tried, iphone, meszdav or cmu: the dash device is another
    grade); "" without them."""
    cell = cells.get(("phone-urban", length))
    if cell is None:
        return ""
    g, i = cell.mean("gins", "pct"), cell.mean("ins", "pct")
    if g is None or not i:
        return ""
    text = f"; on the simulated phone set `gins` ends at {g / i:.2f} of the INS DR's error after {length:g} s"
    ratios = []
    for r in real:
        c = r.get("lengths", {}).get(f"{length:g}", {})
        if any(k in str(r.get("log", "")) for k in ("iphone", "meszdav", "cmu_")) and c.get("gins") and c.get("ins"):
            ratios.append(c["gins"] / c["ins"])
    if ratios:
        text += f", on these real phones at {min(ratios):.2f}-{max(ratios):.2f} of it"
    return text


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


REAL_LOGS_HINT = "give the file 'python benchmarks/real_imu_logs.py LOG... --json FILE' writes"


def read_real_logs(paths: list[Path]) -> list[dict]:
    """The results in the ``benchmarks/real_imu_logs.py --json`` files ``paths``, in order, checked
    (before any measurement): per file a list of one object per log, its ``log`` name and per
    outage length an object of counts and numbers (null where none), its ``why`` text aside."""
    results = []
    with named("--real-logs"):
        for path in paths:
            data = read_json(path, "--real-logs", what="the results of benchmarks/real_imu_logs.py --json", hint=REAL_LOGS_HINT)
            if not isinstance(data, list) or not data:
                what = "an empty list" if isinstance(data, list) else "a JSON " + {dict: "object", str: "string", bool: "true or false",
                                                                                   type(None): "null"}.get(type(data), "number")
                raise iv.InputError(f"{path}: {what}, not a list of logs' results", REAL_LOGS_HINT)
            for i, result in enumerate(data, 1):
                if not isinstance(result, dict) or not isinstance(result.get("log"), str) or not isinstance(result.get("lengths"), dict):
                    raise iv.InputError(f"{path}: entry {i} is not a log's results (a 'log' name and a 'lengths' object)", REAL_LOGS_HINT)
                for length, cell in result["lengths"].items():
                    where = f"{path}: entry {i} ({result['log']}): lengths[{length!r}]"
                    if not isinstance(cell, dict):
                        raise iv.InputError(f"{where} is {cell!r}, not an object", REAL_LOGS_HINT)
                    for key, value in cell.items():
                        values = value if key == "gins_minus_ins_points" and isinstance(value, list) else [value]
                        if key != "why" and value is not None and any(isinstance(v, bool) or not isinstance(v, (int, float))
                                                                      or not np.isfinite(v) for v in values):
                            raise iv.InputError(f"{where}[{key!r}] is {value!r}, not a number", REAL_LOGS_HINT)
            results += data
    return results


def agreement_lines(real: list[dict], cells: dict) -> list[str]:
    """Per real log with a simulated set of its grade (``simulated_set``), whether the two rank
    ``gins`` against the INS DR alike after 10 s."""
    lines = []
    for r in real:
        key = r.get("simulated_set")
        cell, sim = r["lengths"].get("10", {}), cells.get((key, 10.0))
        if not key or sim is None or cell.get("gins") is None or cell.get("ins") is None:
            continue
        if not sim.pct.get("gins") or not sim.pct.get("ins"):
            continue
        sim_gins, sim_ins = float(np.mean(sim.pct["gins"])), float(np.mean(sim.pct["ins"]))
        agree = (cell["gins"] < cell["ins"]) == (sim_gins < sim_ins)
        lines.append(f"- {r['log']}: `gins` {cell['gins']:.1f} % against the INS DR's {cell['ins']:.1f} % after 10 s; the simulated "
                     f"{set_titles().get(key, key)} set {sim_gins:.1f} against {sim_ins:.1f} %: "
                     + ("they agree." if agree else "**they disagree**."))
    return lines


def corpus_results(lengths: list[float]) -> list[dict]:
    """Every log of the test suite's corpus measured as ``benchmarks/real_corpus.py`` does, each
    with its ``simulated_set``."""
    from real_corpus import CORPUS_FILE, measure_entry

    corpus = json.loads(CORPUS_FILE.read_text())
    return [measure_entry(entry, lengths) | {"log": name, "simulated_set": entry.get("simulated_set")}
            for name, entry in sorted(corpus["logs"].items())]


def fine_tuned_results() -> list[dict]:
    """``benchmarks/real_fine_tune.py``'s measurement on every corpus log: the shipped model
    fine-tuned on the log's first half, scored with its parent and the INS DR on the second."""
    from real_fine_tune import CORPUS_FILE as FINE_TUNE_CORPUS
    from real_fine_tune import measure as fine_tune

    corpus = json.loads(FINE_TUNE_CORPUS.read_text())
    with tempfile.TemporaryDirectory(prefix="results-fine-tune-") as tmp:
        return [fine_tune(name, entry, {}, Path(tmp), 0.5) for name, entry in sorted(corpus["logs"].items())]


def fine_tuned_table(results: list[dict]) -> str:
    """The shipped IDNN beside the fine-tuned one per corpus log (:func:`fine_tuned_results`)."""
    from real_fine_tune import ellipse_cell

    lines = ["| log | outages (second half) | INS DR | shipped, its network alone | shipped (with its arbiter) "
             "| fine-tuned on the first half | shipped: inside its 95 % ellipse / ANEES "
             "| fine-tuned: inside its 95 % ellipse / ANEES |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in results:
        m = r["mean_m"]
        cells = [f"{m[k]:.2f}" if m else "–" for k in ("ins", "parent_network", "parent", "fine_tuned")]
        cells += [ellipse_cell(r["ellipse"][k]) for k in ("parent", "fine_tuned")]
        lines.append(f"| {r['log']} | {r['outages']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def real_rows(results: list[dict], lengths: list[float]) -> str:
    """The real logs measured by ``benchmarks/real_imu_logs.py --json`` (on the user's local copies;
    :func:`read_real_logs`), in the overview's shape, for the page's "Real logs" section."""
    lines = ["| outage | " + " | ".join(r["log"].removesuffix(".mcap") for r in results) + " |", "|---|" + "---|" * len(results)]
    for length in lengths:
        cells = []
        for r in results:
            cell = r["lengths"].get(f"{length:g}", {})
            ranked = sorted((v, k) for k, v in cell.items() if k not in ("outages", "why") and isinstance(v, (int, float)))
            cells.append("–" if not ranked else f"best {ranked[0][0]:.1f} % ({ranked[0][1]}), "
                         + ", ".join(f"{k} {v:.1f}" for v, k in ranked[1:]))
        lines.append(f"| {length:g} s | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def consistency_table(labels: dict[str, str], cells: dict[tuple[str, float], Cell], lengths: list[float]) -> str:
    """Per set and length, each estimator's share of final errors inside its 95 % ellipse and its ANEES."""
    titles = set_titles(cells)
    names = [n for n in labels if any(n in c.consistency for c in cells.values())]
    if not names:
        return "No estimator gave a position covariance."
    lines = ["| Drives | Outage | " + " | ".join(f"{labels[n]}: inside 95 % / ANEES" for n in names) + " |",
             "|---|---:|" + "---:|" * len(names)]
    for (key, length), cell in cells.items():
        row = [f"{cell.consistency[n]['coverage_95']:.0f} % / {cell.consistency[n]['anees']:.2f}" if n in cell.consistency else "–" for n in names]
        lines.append(f"| {titles[key]} | {length:g} s | " + " | ".join(row) + " |")
    return "\n".join(lines)


def page(labels: dict[str, str], cells: dict[tuple[str, float], Cell], lengths: list[float], minutes: float, seed_base: int,
         model: str | None, real: list[dict] | None = None, losses: dict | None = None,
         tuned: list[dict] | None = None) -> str:
    day = datetime.datetime.now(datetime.UTC).date().isoformat()
    model_text = f"the IDNN model in `{model}`" if model else "the shipped IDNN model"
    return wrap("\n".join([
        "# Measured results",
        "",
        f"Written by `{command_line()}` on a {machine()} machine ({day}, ionav-viz {iv.__version__}, "
        f"{model_text}); do not edit by hand, run the command again.",
        "",
        "Every built-in estimator on GNSS outages of " + ", ".join(f"{x:g}" for x in lengths) + " s tiling each drive after a 30 s warm-up, on "
        f"synthetic drives of {2 + len(IMU_SETS)} kinds: the **bundled** test drive of each scenario (`ionav-viz evaluate SCENARIO`); "
        "**held-out** drives, one per scenario from a car of the simulator's held-out fleet, whose sensor and vehicle errors "
        f"all lie outside the ranges of the training drives (`ionav-viz simulate SCENARIO --fleet held-out --seed SEED "
        f"--duration {minutes:g}m -o FILE.csv`, seeds {seed_base}-{seed_base + len(SCENARIOS) - 1}); and {len(IMU_SETS)} sets of "
        "**6-axis logs** as users record them, written as MCAP by the 6-axis simulator and read back like a user's log "
        "(`--imu-mount auto`: the IMU's mount estimated and applied; the receiver's fixes given to the estimators, the reference on "
        "`/truth/fix` scoring them): "
        + "; ".join(f"{title} ({', '.join(sc)}, seeds {seed}-{seed + len(sc) - 1}{', IMU only' if imu_only else ''})"
                    for _, title, _, _, imu_only, sc, seed in IMU_SETS)
        + f". Every drive is {minutes:g} minutes long. A cell pools the outages of its set.",
        "",
        "The 3D GNSS/INS (`gins`) needs all six IMU axes: IO-VNBD files carry two, so it does not run on the first two "
        "sets (–); odometry needs a vehicle speed.",
        "",
        *([
            "## Real logs first",
            "",
            "The public real logs of the test suite's corpus ([tests/data/real](../tests/data/real/README.md), measured by "
            "`--corpus`) and any local copies of others (`--real-logs`): IMU only, final position error as a share of the "
            "distance driven, mean over the outages tiled after the warm-up. They are the yardstick; the simulated sets "
            "below are a prediction, which holds where the simulated set of the same IMU grade ranks `gins` against the "
            "INS DR alike:",
            "",
            real_rows(real, lengths),
            "",
            *agreement_lines(real, cells),
            "",
        ] if real else []),
        *([
            "## The IDNN on the real logs, shipped and fine-tuned",
            "",
            "Each corpus log's second half, 10 s outages, IMU only: displacement CRSE (m), mean per outage, of the INS "
            "DR, the shipped IDNN (its network alone, and with its history arbiter, the default) and the shipped IDNN "
            "fine-tuned on the log's first half (`ionav-viz train LOG --span 0s:T --from-model shipped`), as "
            "`benchmarks/real_fine_tune.py` measures it; the intervals and what fine-tuning kept: "
            "[real-imu-logs.md](real-imu-logs.md#fine-tuned-on-the-cars-own-first-half-issue-62). The last two "
            "columns: the share of the outages' final errors inside the model's 95 % ellipse (95 % when honest; "
            "where the truth is the receiver's fixes, the noise of their difference counted: "
            "[outputs.md](outputs.md#how-sure-each-estimator-is)) and its ANEES (1 when honest).",
            "",
            fine_tuned_table(tuned),
            "",
        ] if tuned else []),
        "## Final position error as a share of the distance driven, mean over outages",
        "",
        overview(labels, cells, lengths),
        "",
        comparisons(labels, cells, lengths),
        "",
        tables(labels, cells, lengths),
        "Columns:",
        "",
        "- **Outages**: the outages scored in that set at that length.",
        "- **Final position error (% of the distance driven)**: the 2D distance between the estimated and the true "
        "position at the end of the outage, over the distance driven in it (outages under 10 m driven are left out).",
        "- **Displacement CRSE (m)**: per outage, the sum over its 1 s windows of the absolute error of the distance "
        "travelled in the window.",
        "- Estimators: " + ", ".join(f"{label} (`{name}`)" for name, label in labels.items()) + "; "
        "described in [method.md](method.md) and [estimators.md](estimators.md).",
        "",
        "## How honest each estimator's uncertainty is",
        "",
        "For the estimators that give a position covariance (`analysis/consistency.py`, [outputs.md](outputs.md#how-sure-each-estimator-is)): "
        "the share of outages whose final error lies inside the estimator's 95 % ellipse (95 % when honest) and the average "
        "NEES per degree of freedom (1 when honest; above: overconfident), pooled over each set.",
        "",
        consistency_table(labels, cells, lengths),
        "",
        *([
            "## Through the phone's own receiver losses",
            "",
            f"The phone set's receiver loses the sky as the real phones' did (2.8 times per 10 min for 2-30 s, "
            f"[real-imu-logs.md](real-imu-logs.md)): {len(losses['gap_s'])} losses of {min(losses['gap_s']):.0f}-"
            f"{max(losses['gap_s']):.0f} s (median {np.median(losses['gap_s']):.0f} s) on its {losses['drives']} drives. Every "
            "estimator bridges each from the last receiver fix before it and is scored against the reference at the "
            "first fix after it (`ionav-viz evaluate LOG --truth-topic /truth/fix --on gnss-outage`); the straight-line "
            "span from start to end stands in for the distance driven.",
            "",
            receiver_loss_table(losses),
            "",
        ] if losses else []),
    ]))


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--model", help="IDNN model directory (default: the shipped one)")
    parser.add_argument("--minutes", type=float, default=10.0, help="length of each drive")
    parser.add_argument("--seed-base", type=int, default=800, help="seed of the first held-out drive")
    parser.add_argument("--lengths", default="10,30,60", help="outage lengths (s), comma-separated")
    parser.add_argument("--real-logs", metavar="JSON", type=Path, nargs="*", default=[],
                        help="results of benchmarks/real_imu_logs.py --json on real logs, tabled beside the simulated sets")
    parser.add_argument("--sets", help="only these sets, comma-separated (bundled, held-out, " + ", ".join(k for k, *_ in IMU_SETS)
                        + "); not with --write")
    parser.add_argument("--corpus", action="store_true", help="measure the public real logs of tests/data/real and table them first")
    parser.add_argument("--write", metavar="FILE", type=Path, help="write the complete Markdown page to FILE (atomically) instead of printing the tables")
    args = parser.parse_args()
    sets = args.sets.split(",") if args.sets else None
    if sets is not None and args.write is not None:
        parser.error("--sets: the page needs every set; print the tables instead")
    if sets is not None and (unknown := set(sets) - set(set_titles())):
        parser.error(f"--sets: unknown {', '.join(sorted(unknown))}; choose from {', '.join(set_titles())}")
    output_file(args.write, "--write")
    real = read_real_logs(args.real_logs)
    check_model(args.model)
    lengths = lengths_s(args.lengths)
    logging.getLogger("ionav_viz").setLevel(logging.ERROR)
    labels, cells, losses = measure(args.model, args.minutes, args.seed_base, lengths, sets)
    tuned = None
    if args.corpus:
        real = corpus_results(lengths) + real
        if args.write is not None and args.model is None:
            tuned = fine_tuned_results()
    if args.write is None:
        print(overview(labels, cells, lengths) + "\n\n" + comparisons(labels, cells, lengths) + "\n\n" + tables(labels, cells, lengths)
              + ("\n\n" + receiver_loss_table(losses) if losses else ""), end="")
    else:
        kept = kept_section(args.write)  # the own-vehicle section, written by benchmarks/own_vehicle.py
        write_atomically(args.write, page(labels, cells, lengths, args.minutes, args.seed_base, args.model, real, losses,
                                                  tuned)
                         + ("\n" + kept if kept else ""))
        print(args.write)


if __name__ == "__main__":
    run(main)
