"""Soak run: 100 replays in a loop, watching memory, leftover processes and temporary files.

    python benchmarks/soak_replay.py                     # 100 `ionav-viz replay` processes
    python benchmarks/soak_replay.py --in-process        # 100 replays inside this process

Default: each replay is a fresh ``ionav-viz replay`` process, as users and scripts run it; the
peak resident memory of every run (from ``wait4``) must stay flat, and afterwards no process
of ours may remain and no temporary file may be left in the output directory or the system
temporary directory. ``--in-process`` calls the same function as the command 100 times in
this process and prints the resident memory every 10 runs: rerun-sdk 0.41 keeps about 1.6 MB
per 20,000 logged rows of every closed RecordingStream (an upstream leak, see the README), so
a long-lived library user grows while the command line does not.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _cli import add_debug, check_logs, run


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def our_processes() -> set[int]:
    """Processes running ionav-viz or a rerun viewer."""
    found = set()
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            text = cmdline.read_bytes().replace(b"\x00", b" ").decode(errors="replace")
        except OSError:
            continue
        if ("ionav_viz" in text or "ionav-viz" in text or "rerun --headless" in text) and "soak_replay" not in text:
            found.add(int(cmdline.parent.name))
    return found


def temp_entries() -> set[str]:
    return {p.name for p in Path(tempfile.gettempdir()).iterdir()}


def soak_cli(runs: int, drive: str, out: Path) -> None:
    peaks = []
    start = time.perf_counter()
    for i in range(1, runs + 1):
        proc = subprocess.Popen([sys.executable, "-m", "ionav_viz.cli", "replay", drive, "-o", str(out), "-q"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise SystemExit(f"run {i} failed: {proc.stderr.read().decode()}")
        proc.stderr.close()
        peaks.append(usage.ru_maxrss / 1024.0)
        if i % 10 == 0 or i == 1:
            print(f"run {i:4d}: peak RSS {peaks[-1]:7.1f} MB, {(time.perf_counter() - start) / i:.2f} s per replay", flush=True)
    first, last = sum(peaks[:10]) / 10, sum(peaks[-10:]) / 10
    print(f"peak RSS, mean of the first 10 runs {first:.1f} MB, of the last 10 {last:.1f} MB ({last - first:+.1f} MB)")


def soak_in_process(runs: int, drive: str, out: Path) -> None:
    import ionav_viz

    samples = []
    for i in range(1, runs + 1):
        ionav_viz.replay(drive, 10.0, output=out)
        if i % 10 == 0 or i == 1:
            samples.append((i, rss_mb()))
            print(f"run {i:4d}: RSS {samples[-1][1]:7.1f} MB", flush=True)
    print(f"RSS growth from run {samples[1][0]} to run {samples[-1][0]}: {samples[-1][1] - samples[1][1]:+.1f} MB")


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter))
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--drive", default="roundabout", help="a bundled scenario or a log's file or folder")
    parser.add_argument("--in-process", action="store_true", help="replay inside this process instead of one process per run")
    args = parser.parse_args()
    check_logs([args.drive], "--drive")

    processes_before, temp_before = our_processes(), temp_entries()
    with tempfile.TemporaryDirectory(prefix="soak-") as out_dir:
        out = Path(out_dir) / "soak.rrd"
        (soak_in_process if args.in_process else soak_cli)(args.runs, args.drive, out)
        leftovers = sorted(p.name for p in Path(out_dir).iterdir() if p.name != "soak.rrd")
    time.sleep(0.5)
    print(f"processes left: {sorted(our_processes() - processes_before) or 'none'}")
    print(f"temporary files left in the output directory: {leftovers or 'none'}")
    new_temp = sorted(temp_entries() - temp_before)
    print(f"new entries in {tempfile.gettempdir()}: {new_temp or 'none'}")


if __name__ == "__main__":
    run(main)
