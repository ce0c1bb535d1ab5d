"""Benchmark: ``ionav-viz replay`` of long simulated motorway drives, end to end after imports.

    python benchmarks/bench_replay.py                     # 3.5 h and 12 h drives, 3 runs each
    python benchmarks/bench_replay.py --hours 3.5 --runs 5
    python benchmarks/bench_replay.py --rowwise-hours 0.25  # also: batched vs per-sample logging

Each drive is ``ionav-viz simulate motorway --duration <hours> --seed 3`` (3.5 h: 126,000 samples,
like IO-VNBD's V-Vw4), replayed with tiled 10 s outages and every built-in estimator, as
``ionav-viz replay`` runs it. Every run is a fresh process (imports excluded from the timing, peak
memory its own), and the figures are the median over the runs: the replay's wall time after
imports, each stage's (reading, windows, manoeuvres, each estimator, writing the recording, the
rest: report and summaries), the writer's rows per second, the ``.rrd``'s size and the process's
peak resident memory (imports included: about 390 MB of it is torch, Rerun and numba).

Targets on our 2-core, 24 GiB machine (issue "Fast and tight again"): the 3.5 h drive in at most
2.5 s with its recording written in at most 1.2 s; the 12 h drive in at most 8 s and 1 GB.
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def one_run(csv: Path, out: Path) -> dict:
    """Replay ``csv`` in this process; the stage timings come from ``-v``'s stage log."""
    import numba  # noqa: F401  (the imports the CLI pays before any work, out of the timing)
    import rerun  # noqa: F401
    import torch  # noqa: F401

    import ionav_viz.learning.idnn
    import ionav_viz.nav.gins
    import ionav_viz.viz.recording  # noqa: F401
    from ionav_viz.api.run import replay

    stages: dict[str, float] = {}
    rows = [0]

    class Stages(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            text = record.getMessage()
            found = re.match(r"(.+?)(?:: (.*))? \((\d+\.\d+) s\)$", text)
            if not found:
                return
            what, detail, seconds = found.groups()
            key = "write" if what.startswith("write ") else "read" if what.startswith("read ") else what.split(" on ")[0]
            stages[key] = stages.get(key, 0.0) + float(seconds)
            if key == "write" and detail:
                rows[0] = int(re.search(r"(\d+) rows", detail).group(1))

    logger = logging.getLogger("ionav_viz")
    logger.addHandler(Stages())
    logger.setLevel(logging.INFO)
    start = time.perf_counter()
    replayed = replay(str(csv), 10.0, output=out)
    total = time.perf_counter() - start
    stages["rest"] = total - sum(stages.values())
    return {"total_s": total, "stages_s": stages, "rows": rows[0], "samples": len(replayed.result.drive),
            "outages": len(replayed.outages), "rrd_mb": out.stat().st_size / 1e6,
            "peak_mb": peak_resident_mb()}


def peak_resident_mb() -> float:
    """This process's peak resident memory (``VmHWM``: since its exec, where ``ru_maxrss`` keeps the
    forking parent's peak)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def simulate(folder: Path, hours: float) -> Path:
    from ionav_viz.sim.simulate import write_simulated_drive

    return write_simulated_drive(folder / f"V-motorway-{hours:g}h.csv", "motorway", seed=3, duration_s=hours * 3600)


def bench(hours: float, runs: int, folder: Path) -> None:
    csv = simulate(folder, hours)
    results = []
    for _ in range(runs):
        proc = subprocess.run([sys.executable, __file__, "--one", str(csv), str(folder / "out.rrd")], capture_output=True, text=True,
                              check=True)
        results.append(json.loads(proc.stdout.splitlines()[-1]))
    med = lambda key: statistics.median(r[key] for r in results)  # noqa: E731
    first = results[0]
    print(f"{hours:g} h motorway drive: {first['samples']:,} samples, {first['outages']} outages of 10 s, median of {runs} runs")
    each = ", ".join(f"{r['total_s']:.2f}" for r in results)
    print(f"  replay after imports: {med('total_s'):.2f} s (runs {each})")
    for key in first["stages_s"]:
        print(f"    {key:<24} {statistics.median(r['stages_s'][key] for r in results):6.2f} s")
    write_s = statistics.median(r["stages_s"]["write"] for r in results)
    print(f"  recording: {first['rows']:,} rows, {med('rrd_mb'):.0f} MB, written at {first['rows'] / write_s / 1e6:.2f} M rows/s")
    print(f"  peak memory of the process: {med('peak_mb'):.0f} MB")
    bench_filter(csv)


def bench_filter(csv: Path) -> None:
    """The ekf filter's pass over the whole drive (GNSS updates at every window), compiled on the
    first call and cached on disk: best of three, measurements included."""
    from ionav_viz.analysis.evaluate import resolve_bias
    from ionav_viz.nav import planar_filter
    from ionav_viz.nav.windows import make_windows
    from ionav_viz.sources.iovnbd import read_iovnbd

    drive = read_iovnbd(csv)
    windows, bias = make_windows(drive), resolve_bias(drive)
    passes = []
    for _ in range(3):
        start = time.perf_counter()
        planar_filter.forward(drive, windows, bias.accel_mps2, bias.gyro_radps)
        passes.append(time.perf_counter() - start)
    print(f"  ekf forward pass over the drive: {min(passes) * 1e3:.0f} ms ({len(drive) / min(passes) / 1e6:.2f} M samples/s)")


def write_recording_rowwise(result, path: Path) -> None:
    """Part of the time-varying content of ``write_recording`` (the per-sample signals and the
    per-window estimates), one ``rr.log`` call per row: what batching is measured against."""
    import rerun as rr

    drive, w = result.drive, result.windows
    rec = rr.RecordingStream("ionav-viz", recording_id="rowwise")
    rec.save(path)
    for i, t in enumerate(drive.t_s):
        rec.set_time("time", duration=float(t))
        rec.log("signals/accel_long_mps2", rr.Scalars(drive.accel_long_mps2[i]))
        rec.log("signals/yaw_rate_radps/gyro", rr.Scalars(drive.yaw_rate_radps[i]))
        rec.log("signals/speed_mps", rr.Scalars(drive.speed_mps[i]))
    for name, est in result.estimates.items():
        for s, k0 in enumerate(result.starts):
            for j in range(result.n_windows):
                rec.set_time("time", duration=float(w.t0_s[k0 + j] + 1.0))
                rec.log(f"signals/displacement_m/{name}", rr.Scalars(est.disp_m[s, j]))
                rec.log(f"signals/yaw_rate_radps/{name}", rr.Scalars(est.yaw_rate_radps[s, j]))
    rec.flush()
    rec.disconnect()


def bench_rowwise(hours: float, folder: Path) -> None:
    import numpy as np
    import rerun as rr

    from ionav_viz.api.run import replay

    replayed = replay(str(simulate(folder, hours)), 10.0, output=folder / "batched.rrd")
    result = replayed.result
    start = time.perf_counter()
    write_recording_rowwise(result, folder / "rowwise.rrd")
    rowwise = time.perf_counter() - start
    start = time.perf_counter()
    rec = rr.RecordingStream("ionav-viz", recording_id="batched")
    rec.save(folder / "batched-part.rrd")
    t = rr.TimeColumn("time", duration=result.drive.t_s)
    for entity, values in (("accel", result.drive.accel_long_mps2), ("gyro", result.drive.yaw_rate_radps), ("speed", result.drive.speed_mps)):
        rec.send_columns(f"signals/{entity}", indexes=[t], columns=rr.Scalars.columns(scalars=values))
    t_win = rr.TimeColumn("time", duration=np.repeat(result.windows.t0_s[result.starts], result.n_windows) + 1.0)
    for name, est in result.estimates.items():
        rec.send_columns(f"signals/displacement_m/{name}", indexes=[t_win], columns=rr.Scalars.columns(scalars=est.disp_m.ravel()))
        rec.send_columns(f"signals/yaw_rate_radps/{name}", indexes=[t_win], columns=rr.Scalars.columns(scalars=est.yaw_rate_radps.ravel()))
    rec.flush()
    rec.disconnect()
    batched = time.perf_counter() - start
    print(f"{hours:g} h drive, the same signals and estimates: send_columns {batched:.2f} s, per-sample rr.log {rowwise:.2f} s "
          f"-> {rowwise / batched:.0f}x faster")


def main() -> None:
    if len(sys.argv) == 4 and sys.argv[1] == "--one":
        print(json.dumps(one_run(Path(sys.argv[2]), Path(sys.argv[3]))))
        return
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hours", type=float, action="append", help="drive length (h); repeat for several (default 3.5 and 12)")
    parser.add_argument("--runs", type=int, default=3, help="replays of each drive, each a fresh process (default 3)")
    parser.add_argument("--rowwise-hours", type=float, default=0.0, help="also compare with per-sample rr.log on a drive this long")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for hours in args.hours or [3.5, 12.0]:
            bench(hours, args.runs, Path(tmp))
        if args.rowwise_hours > 0:
            bench_rowwise(args.rowwise_hours, Path(tmp))


if __name__ == "__main__":
    main()
