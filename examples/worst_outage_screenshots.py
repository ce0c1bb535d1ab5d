"""Batch review: a screenshot of the worst outage of every bundled scenario, from Python.

For each scenario's bundled 10-minute test drive, replay it with the paper's consecutive 10 s
outages, find the outage with the largest final position error of the INS DR, and render the
local east-north view at the end of that outage with a headless Rerun viewer.

    python examples/worst_outage_screenshots.py shots/

Needs a Vulkan renderer (on a machine without a GPU: apt-get install mesa-vulkan-drivers).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import ionav_viz as iv
from ionav_viz.dataset.catalog import SCENARIOS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("output", type=Path, help="directory for the PNGs")
    parser.add_argument("--view", default="local", help="all, map, local, signals or errors")
    parser.add_argument("--size", default="1280x720", help="WIDTHxHEIGHT")
    args = parser.parse_args()
    width, height = (int(x) for x in args.size.split("x"))
    args.output.mkdir(parents=True, exist_ok=True)

    with tempfile.TemporaryDirectory(prefix="worst-") as tmp:
        for scenario in SCENARIOS:
            result = iv.replay(scenario, outage_s=10.0, output=Path(tmp) / f"{scenario}.rrd")
            final_error_m = result.report.metric("ins", "final_position_error_m")
            worst = result.outages[int(final_error_m.argmax())]
            others = ", ".join(f"{e} {result.report.metric(e, 'final_position_error_m')[worst.number - 1]:.1f} m"
                               for e in result.report.estimators if e != "ins")
            [png] = iv.screenshot([result.path], args.output / f"{scenario}-worst.png", times=[worst.end_s],
                                  views=[args.view], size=(width, height))
            print(f"{scenario}: outage {worst.number} ({worst.start_s:.0f}-{worst.end_s:.0f} s), "
                  f"INS DR final error {final_error_m.max():.1f} m, {others} -> {png}")


if __name__ == "__main__":
    main()
