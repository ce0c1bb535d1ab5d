"""Benchmark: a batch of screenshots rendered by one headless viewer.

    python benchmarks/bench_screenshots.py                 # 12 outages x the 'all' view, 1600x900
    python benchmarks/bench_screenshots.py --images 20 --view local --size 1280x720

Replays the bundled sharp-cornering drive once, then renders one image per outage (framed, at its
end) through ``ionav_viz.screenshot`` and times each image from the previous one's file. Prints
the first image's time (viewer start and recording load included) and the median and worst of
the others. Target on our 2-core machine: every image after the first in at most 1 s at 1600x900.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import ionav_viz as iv


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--images", type=int, default=12)
    parser.add_argument("--view", default="all")
    parser.add_argument("--size", default="1600x900")
    args = parser.parse_args()
    width, height = (int(x) for x in args.size.split("x"))
    with tempfile.TemporaryDirectory(prefix="bench-shots-") as tmp:
        rec = iv.replay("sharp-cornering", outage_s=10.0, output=Path(tmp) / "sharp.rrd").path
        stamps = [time.perf_counter()]
        iv.screenshot([rec], Path(tmp) / "shots", iv.Shots(times=(), views=[args.view], size=(width, height), outages=range(1, args.images + 1)),
                      progress=lambda _p: stamps.append(time.perf_counter()))
        per_image = np.diff(stamps)
    rest = per_image[1:]
    print(f"{len(per_image)} images, view {args.view}, {width}x{height}: first {per_image[0]:.2f} s (viewer start and load), "
          f"then median {np.median(rest):.2f} s, worst {rest.max():.2f} s per image "
          f"({'meets' if rest.max() <= 1.0 else 'misses'} the 1 s target)")


if __name__ == "__main__":
    main()
