"""Benchmark: reading a large ROS bag with a camera topic: time, and peak memory against the same bag without it.

    python benchmarks/bench_rosbag.py                       # ROS 1, ROS 2 SQLite and ROS 2 MCAP, >= 1 GB each
    python benchmarks/bench_rosbag.py --formats ros1 --size-gb 2
    python benchmarks/bench_rosbag.py --formats ros1 --rate-hz 100   # every topic at 100 Hz: the decoding rate

Each bag holds the bundled hard-brake drive (600 s: IMU, NavSatFix and GNSS velocity at 10 Hz,
written with rosbags' own writers) plus a 640x480 rgb8 ``sensor_msgs/msg/Image`` topic at the rate
that brings the bag to ``--size-gb``. Each bag is read by ``ionav_viz.load_drive`` in a fresh
interpreter, which reports its wall time and peak resident memory (``ru_maxrss``); the same drive
without the image topic is the baseline. Memory bounded by the output, not the bag, means the two
peaks are close whatever the bag's size. Run as root, the page cache is emptied before each read
(a cold read from the disk; else the bag may still be in memory from being written, and the
line says "warm"). Bags go to a temporary directory, removed at the end.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

IMAGE_SIZE = (480, 640)  # rows, columns; rgb8
READ = """
import json, resource, sys, time
t0 = time.perf_counter()
import ionav_viz as iv
t1 = time.perf_counter()
drive = iv.load_drive(sys.argv[1])
t2 = time.perf_counter()
print(json.dumps({"samples": len(drive), "import_s": t1 - t0, "read_s": t2 - t1,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def _size_bytes(path: Path) -> int:
    return path.stat().st_size if path.is_file() else sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def _write(fmt: str, drive, path: Path, image_every: int) -> Path:
    from tests import bag_fixtures as bf

    if fmt == "ros1":
        return bf.write_ros1(drive, path.with_suffix(".bag"), compression=None, image_every=image_every, image_size=IMAGE_SIZE)
    storage = "sqlite3" if fmt == "ros2-sqlite" else "mcap"
    return bf.write_ros2(drive, path, storage=storage, image_every=image_every, image_size=IMAGE_SIZE)


def _drop_caches() -> bool:
    """Empty the page cache (root on Linux), so the bag is read from the disk, not from memory."""
    try:
        subprocess.run(["sync"], check=True)
        Path("/proc/sys/vm/drop_caches").write_text("3\n")
    except (OSError, subprocess.CalledProcessError):
        return False
    return True


def _read(path: Path) -> dict:
    cold = _drop_caches()
    proc = subprocess.run([sys.executable, "-c", READ, str(path)], capture_output=True, text=True, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1]) | {"cache": "cold" if cold else "warm"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--formats", default="ros1,ros2-sqlite,ros2-mcap")
    parser.add_argument("--size-gb", type=float, default=1.05)
    parser.add_argument("--rate-hz", type=float, default=10.0, help="message rate of the IMU, fix and velocity topics (the drive interpolated)")
    args = parser.parse_args()
    import numpy as np

    import ionav_viz as iv
    from ionav_viz.core.drive import Drive

    drive = iv.load_drive("hard-brake")
    if args.rate_hz != drive.rate_hz:
        t = np.arange(0.0, drive.t_s[-1], 1.0 / args.rate_hz)
        columns = ("lat_deg", "lon_deg", "speed_mps", "heading_deg", "accel_long_mps2", "yaw_rate_radps")
        drive = Drive(drive.name, drive.source, args.rate_hz, drive.start_time_of_day_s,
                      {"t_s": t} | {c: np.interp(t, drive.t_s, drive.columns[c]) for c in columns})
    image_bytes = IMAGE_SIZE[0] * IMAGE_SIZE[1] * 3
    every = max(1, int(len(drive) * image_bytes / (args.size_gb * 1e9)))
    work = Path(tempfile.mkdtemp(prefix="bench-rosbag-"))
    try:
        for fmt in args.formats.split(","):
            base = _write(fmt, drive, work / f"{fmt}-base", 0)
            t = time.perf_counter()
            big = _write(fmt, drive, work / f"{fmt}-big", every)
            wrote_s = time.perf_counter() - t
            a, b = _read(base), _read(big)
            assert a["samples"] == b["samples"]
            print(f"{fmt:12s} {_size_bytes(big) / 1e9:.2f} GB (one 640x480 image every {every / drive.rate_hz:.1f} s; written in {wrote_s:.0f} s): "
                  f"read ({b['cache']} cache) {b['read_s']:.2f} s, peak RSS {b['peak_rss_mb']:.0f} MB; without the images "
                  f"{_size_bytes(base) / 1e6:.1f} MB: read {a['read_s']:.2f} s, peak RSS {a['peak_rss_mb']:.0f} MB; "
                  f"{3 * len(drive) / b['read_s']:,.0f} messages/s decoded")
            shutil.rmtree(big) if big.is_dir() else big.unlink()
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
