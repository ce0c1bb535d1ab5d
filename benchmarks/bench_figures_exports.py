"""Benchmark: how long exports (``--export``) and figures (``ionav-viz figures``) take for a long
drive, against the replay that makes the recording they come from.

    python benchmarks/bench_figures_exports.py              # 3.5 h drive (~126,000 samples, like V-Vw4)
    python benchmarks/bench_figures_exports.py --hours 0.5
    python benchmarks/bench_figures_exports.py --dir /dev/shm   # files on a RAM disk

Prints the seconds of the replay (``iv.replay``, every built-in but the IDNN's model load counted
in), of the exports of its report and of the figures drawn from its recording, and their share of
the replay. Target: each a small share (under a third) of the replay.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from _cli import add_debug, existing_folder, run

import ionav_viz as iv
from ionav_viz.analysis.exports import export_results
from ionav_viz.sim.simulate import write_simulated_drive


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--hours", type=float, default=3.5)
    parser.add_argument("--dir", default=None, help="where to write (default: the system's temporary folder); e.g. /dev/shm to leave the disk out")
    args = parser.parse_args()
    existing_folder(args.dir, "--dir")
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        folder = Path(tmp)
        csv = write_simulated_drive(folder / "V-long.csv", "motorway", seed=7, duration_s=args.hours * 3600.0)
        import matplotlib.pyplot  # noqa: F401  (imports and the font cache are not the figures' own time)

        t = time.perf_counter()
        replayed = iv.replay(csv, output=folder / "long.rrd")
        replay_s = time.perf_counter() - t
        t = time.perf_counter()
        files = export_results(replayed.report.results, folder / "export")
        export_s = time.perf_counter() - t
        size_mb = sum(f.stat().st_size for f in files) / 1e6
        t = time.perf_counter()
        figures = iv.figures(replayed.path, folder / "figures")
        figures_s = time.perf_counter() - t
        print(f"{args.hours:g} h drive, {replayed.report.n_outages} outages of 10 s, estimators: {', '.join(replayed.report.estimators)}")
        print(f"replay  {replay_s:7.2f} s")
        print(f"export  {export_s:7.2f} s  ({100 * export_s / replay_s:.0f} % of the replay; {len(files)} files, {size_mb:.1f} MB)")
        print(f"figures {figures_s:7.2f} s  ({100 * figures_s / replay_s:.0f} % of the replay; {len(figures)} files)")


if __name__ == "__main__":
    run(main)
