"""Regenerate the images the README and docs show, and the numbers they show.

    python docs/make_images.py           # docs/review-roundabout.png, docs/figure-drift.png, docs/images.json
    python docs/make_images.py --check   # exit 1 when docs/images.json's numbers are not the current code's

Both images come from one replay of the bundled roundabout drive (tiled 10 s outages, every
built-in estimator): the hero image is the review layout at the worst outage of the INS DR
(``ionav-viz screenshot --time worst``), the drift figure is ``ionav-viz figures``' drift.png.
``docs/images.json`` records the numbers the images show (the worst outage, each estimator's
final error there and its mean final error and displacement CRSE over the drive's outages, the
drift curve's mean at the outages' end), so that ``tests/test_docs.py`` can check them against a
fresh evaluation without rendering anything. Rendering needs the lavapipe Vulkan driver.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

DOCS = Path(__file__).resolve().parent
NUMBERS = DOCS / "images.json"
DRIVE, OUTAGE_S = "roundabout", 10.0


def shown_numbers(report: dict) -> dict:
    """What the images show, from a report (``evaluate --json`` of the drive), rounded as shown."""
    summary = report["summary"]
    names = [e["name"] for e in report["estimators"]]
    sequences = report["sequences"]
    worst = max(range(len(sequences)), key=lambda i: sequences[i]["ins"]["final_position_error_m"])
    return {
        "drive": report["drive"],
        "outages": len(sequences),
        "worst_outage": worst + 1,
        "worst_final_error_m": {n: round(sequences[worst][n]["final_position_error_m"], 1) for n in names},
        "mean_final_error_m": {n: round(summary[n]["final_position_error_m"]["mean"], 2) for n in names},
        "mean_crse_m": {n: round(summary[n]["crse_m"]["mean"], 2) for n in names},
        "drift_mean_at_end_m": {n: round(report["drift"][n]["mean_m"][-1], 2) for n in names},
    }


def current_numbers() -> dict:
    import ionav_viz as iv

    return shown_numbers(json.loads(iv.evaluate(DRIVE, OUTAGE_S).to_json()))


def regenerate() -> dict:
    import ionav_viz as iv

    with tempfile.TemporaryDirectory(prefix="ionav-docs-") as tmp:
        folder = Path(tmp)
        replayed = iv.replay(DRIVE, OUTAGE_S, output=folder / "roundabout.rrd")
        [hero] = iv.screenshot(replayed.path, folder / "hero.png",
                               iv.Shots(times=("worst",), views=("all",), size=(1600, 900)))
        shutil.copyfile(hero, DOCS / "review-roundabout.png")
        iv.figures(replayed.path, folder / "figures")
        shutil.copyfile(folder / "figures" / "drift.png", DOCS / "figure-drift.png")
        numbers = shown_numbers(json.loads(replayed.report.to_json()))
    NUMBERS.write_text(json.dumps(numbers, indent=2) + "\n")
    return numbers


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--check", action="store_true", help="compare docs/images.json with the current code's numbers")
    args = parser.parse_args()
    if args.check:
        recorded, now = json.loads(NUMBERS.read_text()), current_numbers()
        if recorded != now:
            print(f"docs/images.json is out of date: run 'python docs/make_images.py'\n  recorded {recorded}\n"
                  f"  now      {now}", file=sys.stderr)
            return 1
        print("docs/images.json matches the current code")
        return 0
    print(json.dumps(regenerate(), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
