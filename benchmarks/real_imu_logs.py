"""Every estimator on real 6-axis logs, in the shape of issue 41's table: final position error as a
share of the distance driven (mean over tiled outages), IMU only, per log and outage length.

Give your local copies of the logs (MCAP, ROS bags: what ``ionav-viz evaluate`` reads); nothing
is downloaded and no data is committed. Where the logs came from and their measured statistics
are in ``docs/real-imu-logs.md``; that page's table was made with this script::

    python benchmarks/real_imu_logs.py LOG.mcap... [--truth-topic /truth/fix] [--max-sigma-m 13] [--json OUT] [--debug]

Logs with a reference trajectory (``--truth-topic``) are scored against it; the others against
their receiver's fixes (then ``--max-sigma-m`` lets a phone's 5-10 m fixes count as truth).

A missing log or output folder stops the script before any work (one line, exit code 2); a log its
reader cannot read gets a row saying why, the other logs are measured (and written to ``--json``),
and the script ends with that log's error and exit code 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _cli import add_debug, check_logs, lengths_s, output_file, raise_if_unreadable, run

import ionav_viz as iv
from ionav_viz.analysis.evaluate import paired_bootstrap_means
from ionav_viz.core.fileio import atomic_write_bytes
from ionav_viz.core.gnss_quality import GnssLimits

ESTIMATORS = ("ins", "idnn", "ekf", "gins")


def measure(path: Path, lengths: list[float], truth_topic: str | None, max_sigma_m: float | None, extra: dict | None = None,
            warm_up_s: float = 30.0) -> dict:
    """Per outage length: each estimator's mean final error (% of distance), the outage count, and
    the run's warnings."""
    log = iv.LogOptions(imu_mount="auto", vehicle_speed_topic="none", truth_topic=truth_topic, **(extra or {}))
    limits = GnssLimits() if max_sigma_m is None else replace(GnssLimits(), max_sigma_m=max_sigma_m)
    read = iv.ReadOptions(log=log, gnss_limits=limits)
    out: dict = {"log": path.name, "lengths": {}}
    run = iv.RunOptions(warm_up_s=warm_up_s)
    for length in lengths:
        try:
            d = iv.evaluate([str(path)], length, estimators=list(ESTIMATORS), read=read, run=run).to_dict()
        except iv.InputError as exc:  # e.g. no outage of that length fits the log
            raise_if_unreadable([path], read)  # not when the log itself cannot be read: its reader's error
            out["lengths"][f"{length:g}"] = {"outages": 0, "why": str(exc)}
            continue
        cell = {"outages": d["n_sequences"]}
        per_outage = outage_pcts_of(d, [est["name"] for est in d["estimators"]])
        for est in d["estimators"]:
            name = est["name"]
            pct = per_outage[name][np.isfinite(per_outage[name])]
            cell[name] = float(np.mean(pct)) if len(pct) else None
            if est.get("info", {}).get("arbiter"):  # what gins's history arbiter chose, per length
                out.setdefault("arbiter", {})[f"{length:g}"] = est["info"]["arbiter"]
        if "gins" in per_outage and "ins" in per_outage:
            cell["gins_minus_ins_points"] = gap_points(per_outage["ins"], per_outage["gins"])
        out["lengths"][f"{length:g}"] = cell
        out["warnings"] = d.get("warnings", [])
        out["filter_health"] = d.get("filter_health", {})
        out["imu"] = d["drives"][0].get("imu_text", "")
    return out


def outage_pcts_of(report: dict, names: list[str]) -> dict[str, np.ndarray]:
    """Per estimator of ``names``, its final error (% of distance) on each outage of ``report`` (an
    ``evaluate --json`` object), NaN where it is not scored."""
    return {name: np.array([s[name]["final_error_pct"] if isinstance(s.get(name), dict) and s[name]["final_error_pct"] is not None
                            else np.nan for s in report["sequences"]], dtype=float) for name in names}


def gap_points(ins_pct: np.ndarray, gins_pct: np.ndarray) -> list[float] | None:
    """``gins``'s mean final error minus the INS DR's, in points of the distance driven, on the
    outages both scored, with its 95 % interval from a paired bootstrap over those outages
    (:func:`ionav_viz.analysis.evaluate.paired_bootstrap_means`): ``[mean, low, high]``; None
    below two such outages."""
    both = np.isfinite(ins_pct) & np.isfinite(gins_pct)
    if both.sum() < 2:
        return None
    m_ins, m_gins = paired_bootstrap_means(ins_pct, gins_pct)
    lo, hi = np.percentile(m_gins - m_ins, [2.5, 97.5])
    return [float(gins_pct[both].mean() - ins_pct[both].mean()), float(lo), float(hi)]


def gap_row(result: dict, lengths: list[str]) -> str:
    """The second table's row: per length, gins minus the INS DR with its interval, and whether
    gins is above it beyond the outages' spread (the interval above 0)."""
    cells = []
    for length in lengths:
        gap = result["lengths"].get(length, {}).get("gins_minus_ins_points")
        if gap is None:
            cells.append("–")
            continue
        mean, lo, hi = gap
        verdict = "above" if lo > 0 else "below" if hi < 0 else "cannot tell"
        cells.append(f"{mean:+.1f} [{lo:+.1f}, {hi:+.1f}] {verdict}")
    return f"| {result['log']} | " + " | ".join(cells) + " |"


def row(result: dict) -> str:
    cells = result["lengths"]

    def pct(length: str, name: str) -> str:
        value = cells.get(length, {}).get(name)
        return "–" if value is None else f"{value:.1f} %"

    ten = cells.get("10", {})
    others = {k: v for k, v in ten.items() if k in ESTIMATORS and k not in ("gins", "ins") and v is not None}
    best = min(others, key=others.get) if others else None
    best_text = f"{best} {others[best]:.1f} %" if best else "–"
    return (f"| {result['log']} | {pct('10', 'gins')} | {pct('30', 'gins')} | {pct('60', 'gins')} | "
            f"{pct('10', 'ins')} / {pct('30', 'ins')} | {best_text} | {ten.get('outages', 0)} |")


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("logs", nargs="+", type=Path)
    parser.add_argument("--lengths", default="10,30,60", help="outage lengths (s), comma-separated")
    parser.add_argument("--truth-topic", help="a reference trajectory's topic (NavSatFix), when the logs carry one")
    parser.add_argument("--max-sigma-m", type=float, help="GNSS limit max_sigma_m (fixes less accurate are not truth)")
    parser.add_argument("--gnss-topic", help="the receiver's topic, when the logs carry several")
    parser.add_argument("--warm-up", type=float, default=30.0, help="GNSS time before the first outage (s)")
    parser.add_argument("--json", type=Path, help="also write every number as JSON here")
    args = parser.parse_args()
    check_logs(args.logs)
    output_file(args.json, "--json", inputs=args.logs)
    lengths = lengths_s(args.lengths)
    print("| log | `gins` 10 s | 30 s | 60 s | INS DR 10 s / 30 s | best other at 10 s | outages (10 s) |")
    print("|---|---|---|---|---|---|---|")
    results, unread = [], []
    for path in args.logs:
        start = time.perf_counter()
        try:
            result = measure(path, lengths, args.truth_topic, args.max_sigma_m, {"gnss_topic": args.gnss_topic} if args.gnss_topic else None,
                             args.warm_up)
        except iv.InputError as exc:
            print(f"| {path.name} | {exc} |||||", flush=True)
            unread.append(exc)
            continue
        result["seconds"] = round(time.perf_counter() - start, 1)
        results.append(result)
        print(row(result), flush=True)
    if results:
        keys = [f"{length:g}" for length in lengths]
        print("\n`gins` minus the INS DR, points of the distance driven, mean [95 % interval, paired bootstrap over the outages]:\n")
        print("| log | " + " | ".join(f"{k} s" for k in keys) + " |")
        print("|---|" + "---|" * len(keys))
        for result in results:
            print(gap_row(result, keys))
    if args.json:
        atomic_write_bytes(args.json, json.dumps(results, indent=1, default=float).encode())
    if unread:
        first = unread[0]
        raise iv.InputError(first.message if len(unread) == 1 else f"{len(unread)} of {len(args.logs)} logs could not be measured; first {first.message}",
                            first.hint)
    print(f"\n{sys.version.split()[0]}, ionav-viz {iv.__version__}", file=sys.stderr)


if __name__ == "__main__":
    run(main)
