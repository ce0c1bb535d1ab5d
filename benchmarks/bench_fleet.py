"""Benchmark: a fleet of simulated drives evaluated serially, on ``--workers N`` processes and
(``--dask``) on a local Dask cluster: throughput in drive-hours per second and peak memory.

    python benchmarks/bench_fleet.py                        # 40 drives of 30 min (20 h), serial vs 2 workers
    python benchmarks/bench_fleet.py --drives 40 --minutes 30 --workers 2 --dask
    python benchmarks/bench_fleet.py --folder /tmp/fleet    # keep (and reuse) the simulated drives
    python benchmarks/bench_fleet.py --runs 3               # the modes in turn, 3 times: medians (min-max)
    python benchmarks/bench_fleet.py --cli --drives 48 --minutes 45 --runs 5   # the whole command, as a user runs it

With ``--cli`` the whole ``ionav-viz evaluate FOLDER --workers N -q`` process is timed against
``--workers 1`` (start-up, imports, the report's text included), the two in turn ``--runs`` times;
the ratio is taken pair by pair and its median printed with its spread, so that a change of the
machine's load during the call touches both sides of each pair alike.

The fleet: ``--drives`` IO-VNBD CSV drives of ``--minutes`` each from ``ionav-viz simulate``,
scenarios in turn (motorway, roundabout, quick-accel, hard-brake, sharp-cornering), seed = the
drive's number, sensor errors of the 'training' fleet; tiled 10 s outages, every built-in
estimator that applies (the IDNN, so torch, in every worker).

Each mode runs in a fresh process (``--child``), timed from the call of
``ionav_viz.evaluate`` on an engine to its return: reading, estimators, the workers' start
(the forkserver's imports, each worker's first load of numba's compiled filters) and pooling
included. The timed runs are not watched: memory comes from one more run of each mode, sampled
every 0.1 s over the child and all its descendants (``peak_total_MB``: the largest sum of their
resident sets; ``peak_process_MB``: the largest single process). Sampling a process tree ten times
a second costs CPU, which on two busy cores comes out of the workers' time and not the serial
run's, so it would bias the speed-up. Every run's results (the report's JSON without its timings)
must hash the same: the parallel runs are checked against the serial one, bit for bit. With
``--runs N`` the modes run in turn N times and the wall times are medians (min-max).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from _cli import add_debug, output_folder, run

SCENARIOS = ("motorway", "roundabout", "quick-accel", "hard-brake", "sharp-cornering")


def make_fleet(folder: Path, drives: int, minutes: float) -> list[Path]:
    """``drives`` simulated drives of ``minutes`` in ``folder`` (kept when already there)."""
    import ionav_viz as iv

    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for i in range(drives):
        path = folder / f"V-fleet{i:03d}-{minutes:g}min.csv"
        if not path.exists():
            iv.simulate(SCENARIOS[i % len(SCENARIOS)], path, seed=i, duration_s=minutes * 60.0, fleet="training")
        out.append(path)
    return out


def child(folder: Path, pattern: str, workers: int, cluster: str | None) -> None:
    """One mode, in this process: print its figures as one JSON line."""
    import ionav_viz as iv

    began = time.perf_counter()
    report = iv.evaluate([str(folder / pattern)], 10, engine=iv.Engine(workers, cluster))
    wall_s = time.perf_counter() - began
    results = report.to_dict()
    results.pop("timing")
    print(json.dumps({"wall_s": wall_s, "drive_hours": results["duration_s"] / 3600.0, "drives": results["drives_evaluated"],
                      "failed": results["drives_failed"], "outages": results["n_outages"],
                      "results_sha256": hashlib.sha256(json.dumps(results).encode()).hexdigest()}))


def run_mode(args: list[str], sample_memory: bool = False) -> dict:
    """Run one mode in a child process; with ``sample_memory``, sample its process tree's memory
    (and leave the wall time out: the sampling takes CPU from the run)."""
    proc = subprocess.Popen([sys.executable, __file__, "--child", *args], stdout=subprocess.PIPE, text=True)

    def figures_of(out: str) -> dict:
        if proc.returncode != 0:
            raise SystemExit(f"bench_fleet: {' '.join(args)} exited with {proc.returncode}")
        return json.loads(out.strip().splitlines()[-1])

    if not sample_memory:
        return figures_of(proc.communicate()[0])
    import psutil

    peak_total, peak_one = 0, 0
    stop = threading.Event()

    def sample() -> None:
        nonlocal peak_total, peak_one
        root = psutil.Process(proc.pid)
        while not stop.is_set():
            try:
                rss = [p.memory_info().rss for p in [root, *root.children(recursive=True)]]
            except psutil.Error:
                rss = []
            if rss:
                peak_total, peak_one = max(peak_total, sum(rss)), max(peak_one, max(rss))
            time.sleep(0.1)

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    out, _ = proc.communicate()
    stop.set()
    thread.join()
    return figures_of(out) | {"peak_total_MB": peak_total / 1e6, "peak_process_MB": peak_one / 1e6}


def cli_pairs(drives: str, workers: int, runs: int) -> None:
    """Time ``ionav-viz evaluate DRIVES --workers N -q`` against ``--workers 1``, whole processes,
    in turn (one warm-up pair first, not counted); print medians (min-max) and the paired ratio."""
    import shutil

    exe = shutil.which("ionav-viz") or sys.exit("bench_fleet: ionav-viz is not on PATH (install the package)")

    def wall(n: int) -> float:
        began = time.perf_counter()
        subprocess.run([exe, "evaluate", drives, "--workers", str(n), "-q"], stdout=subprocess.DEVNULL, check=True)
        return time.perf_counter() - began

    wall(workers), wall(1)  # warm-up: the file cache, compiled bytecode
    pairs = [(wall(workers), wall(1)) for _ in range(runs)]
    ratios = [a / b for a, b in pairs]

    def figure(values: list[float], digits: int) -> str:
        return f"{statistics.median(values):.{digits}f} ({min(values):.{digits}f}-{max(values):.{digits}f})"

    print(f"ionav-viz evaluate {drives} -q, {runs} pair(s) in turn; medians (min-max)")
    print(f"  --workers {workers}: {figure([a for a, _ in pairs], 1)} s")
    print(f"  --workers 1: {figure([b for _, b in pairs], 1)} s")
    print(f"  ratio, pair by pair: {figure(ratios, 2)}")


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--drives", type=int, default=40)
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--dask", action="store_true", help="also a local Dask cluster of --workers workers (needs ionav-viz[cluster])")
    parser.add_argument("--folder", type=Path, help="where the simulated drives go (kept; default a temporary folder)")
    parser.add_argument("--runs", type=int, default=1, help="run the modes in turn this many times; the figures are medians (min-max)")
    parser.add_argument("--cli", action="store_true", help="time the whole command (--workers N against --workers 1, in turn) instead of the call")
    parser.add_argument("--child", nargs=4, metavar=("FOLDER", "PATTERN", "WORKERS", "CLUSTER"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        folder, pattern, workers, cluster = args.child
        child(Path(folder), pattern, int(workers), None if cluster == "-" else cluster)
        return
    output_folder(args.folder, "--folder")
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.folder or Path(tmp)
        make_fleet(folder, args.drives, args.minutes)
        pattern = f"V-fleet*-{args.minutes:g}min.csv"
        if args.cli:
            cli_pairs(str(folder / pattern), args.workers, max(1, args.runs))
            return
        modes = {"serial": ["1", "-"], f"--workers {args.workers}": [str(args.workers), "-"]}
        if args.dask:
            modes[f"--cluster local ({args.workers} workers)"] = [str(args.workers), "local"]
        runs: dict[str, list[dict]] = {name: [] for name in modes}
        for _ in range(args.runs):  # in turn, so that a change of the machine's load touches every mode alike
            for name, mode in modes.items():
                runs[name].append(run_mode([str(folder), pattern, *mode]))
        memory = {name: run_mode([str(folder), pattern, *mode], sample_memory=True) for name, mode in modes.items()}
    serial = runs["serial"][0]
    print(f"fleet: {serial['drives']} drives, {serial['drive_hours']:.1f} drive-hours, {serial['outages']} outages of 10 s; "
          f"{args.runs} run(s) of each mode in turn" + ("; medians (min-max)" if args.runs > 1 else ""))
    print(f"{'mode':<30}{'wall s':>18}{'drive-h/s':>11}{'speed-up':>10}{'peak total MB':>15}{'peak process MB':>17}  results")
    serial_wall = statistics.median(r["wall_s"] for r in runs["serial"])
    for name, rs in runs.items():
        walls = [r["wall_s"] for r in rs]
        wall = statistics.median(walls)
        spread = f" ({min(walls):.1f}-{max(walls):.1f})" if len(walls) > 1 else ""
        same = "same as serial" if all(r["results_sha256"] == serial["results_sha256"] for r in [*rs, memory[name]]) else "DIFFERENT from serial"
        print(f"{name:<30}{f'{wall:.1f}{spread}':>18}{rs[0]['drive_hours'] / wall:>11.2f}{serial_wall / wall:>9.2f}x"
              f"{memory[name]['peak_total_MB']:>15.0f}{memory[name]['peak_process_MB']:>17.0f}  {same}")


if __name__ == "__main__":
    run(main)
