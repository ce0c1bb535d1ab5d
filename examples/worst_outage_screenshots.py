"""Batch review: a screenshot of the worst outage of every bundled scenario, from Python.

For each scenario's bundled 10-minute test drive, replay it with the paper's consecutive 10 s
outages, find the outage with the largest final position error of the INS DR, and render the
local east-north view framed on that outage with a headless Rerun viewer.

    python examples/worst_outage_screenshots.py shots/

Needs a Vulkan renderer (on a machine without a GPU: apt-get install mesa-vulkan-drivers).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import ionav_viz as iv
from ionav_viz.dataset.catalog import SCENARIOS


def worst_line(scenario: str, report: iv.Report, png: Path) -> str:
    """One line of the batch: the scenario's worst outage (by the INS DR's final position error)
    and each estimator's final error there, named as every output names it ("INS DR", "IDNN")."""
    worst = report.worst_outages(1)[0]
    errors = ", ".join(f"{report.labels[name]} {err:.1f} m" for name, err in worst["final_error_m"].items())
    return (f"{scenario}: outage {worst['number']} ({worst['start_s']:.0f}-{worst['end_s']:.0f} s), "
            f"final error {errors} -> {png}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("output", type=Path, help="directory for the PNGs")
    parser.add_argument("--view", default="local", help="all, outage, map, local, signals or errors")
    parser.add_argument("--size", default="1280x720", help="WIDTHxHEIGHT")
    args = parser.parse_args()
    width, height = (int(x) for x in args.size.split("x"))
    args.output.mkdir(parents=True, exist_ok=True)

    with tempfile.TemporaryDirectory(prefix="worst-") as tmp:
        for scenario in SCENARIOS:
            result = iv.replay(scenario, outage_s=10.0, output=Path(tmp) / f"{scenario}.rrd")
            # 'worst' frames the outage worst_line names: its tracks fill the view, its errors are in the title
            [png] = iv.screenshot([result.path], args.output / f"{scenario}-worst.png",
                                  iv.Shots(times=["worst"], views=[args.view], size=(width, height)))
            print(worst_line(scenario, result.report, png))


if __name__ == "__main__":
    main()
