"""ionav-viz cross-validate: K folds by drive or by time blocks, each model tested on data it never saw."""

from __future__ import annotations

import json

import pytest

from tests.conftest import REPO, run_cli

pytestmark = pytest.mark.xdist_group("cross_validate")

SAMPLES = REPO / "ionav_viz" / "data" / "samples"
TINY = ("--epochs-disp", "1", "--epochs-yaw", "1", "-q")


def test_folds_by_time_blocks_of_one_drive_are_disjoint_and_reported():
    proc = run_cli("cross-validate", "roundabout", "--folds", "3", "--span", "0s:150s", *TINY, "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["by"] == "time" and result["device"] == "cpu" and len(result["folds"]) == 3
    tests = [f["test"][0] for f in result["folds"]]
    assert tests == ["V-sim-roundabout 0-50s", "V-sim-roundabout 50-100s", "V-sim-roundabout 100-150s"]
    for fold in result["folds"]:
        assert fold["test"][0] not in fold["train"] and len(fold["train"]) == 2 and fold["n_outages"] > 0
    spread = result["summary"]["idnn_crse_m"]
    assert spread["min"] <= spread["mean"] <= spread["max"] and spread["sd"] >= 0
    again = json.loads(run_cli("cross-validate", "roundabout", "--folds", "3", "--span", "0s:150s", *TINY, "--json").stdout)
    assert [f["crse_m"] for f in again["folds"]] == [f["crse_m"] for f in result["folds"]]  # seeded: the same models


def test_folds_by_drive_and_the_device_is_said():
    drives = [str(SAMPLES / f"V-sim-roundabout-train-{i}.csv") for i in (1, 2, 3)]
    proc = run_cli("cross-validate", *drives, "--folds", "3", "--span", "0s:80s", "--epochs-disp", "1", "--epochs-yaw", "1")
    assert proc.returncode == 0, proc.stderr
    assert "training on the CPU (torch sees no GPU)" in proc.stderr
    assert "3-fold cross-validation by drive" in proc.stdout and "spread over folds" in proc.stdout
    assert proc.stdout.count("V-sim-roundabout-train-") == 3  # each drive tested once


@pytest.mark.parametrize(("args", "words"), [(["roundabout", "--folds", "1"], "--folds: 1 folds: need at least 2"),
                                              (["roundabout", "motorway", "--folds", "3"], "--folds: 2 drives for 3 folds"),
                                              (["roundabout", "--span", "0s:60s", "--folds", "3"], "too short for 3 time blocks")])
def test_bad_folds_are_one_line(args, words):
    proc = run_cli("cross-validate", *args, *TINY)
    assert proc.returncode == 2 and words in proc.stderr and "Traceback" not in proc.stderr
