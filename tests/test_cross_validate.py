"""ionav-viz cross-validate: K folds by drive or by time blocks, each model tested on data it never saw."""

from __future__ import annotations

import json

import pytest

from tests.conftest import REPO, run_cli
from tests.test_report_schema import documented_keys

pytestmark = pytest.mark.xdist_group("cross_validate")

SAMPLES = REPO / "ionav_viz" / "data" / "samples"
TINY = ("--epochs-disp", "1", "--epochs-yaw", "1", "-q")


def documented_keys_of_folds() -> set[str]:
    """The fold keys docs/report-schema.md names in the ``folds`` row."""
    import re

    row = next(line for line in (REPO / "docs" / "report-schema.md").read_text().splitlines() if line.startswith("| `folds` |"))
    return set(re.findall(r"`([a-z_0-9]+)`", row.split("|")[2]))


def test_folds_by_time_blocks_of_one_drive_are_disjoint_and_reported():
    proc = run_cli("cross-validate", "roundabout", "--folds", "3", "--span", "0s:150s", *TINY, "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["by"] == "time" and result["device"] == "cpu" and len(result["folds"]) == 3
    assert result["schema"] == "ionav-viz/cross-validation/1" and set(result) <= documented_keys("cross-validation")
    assert set(result["folds"][0]) <= documented_keys_of_folds()
    tests = [f["test"][0] for f in result["folds"]]
    assert tests == ["V-sim-roundabout 0-50s", "V-sim-roundabout 50-100s", "V-sim-roundabout 100-150s"]
    for fold in result["folds"]:
        assert fold["test"][0] not in fold["train"] and len(fold["train"]) == 2 and fold["n_outages"] > 0
    spread = result["summary"]["idnn_crse_m"]
    assert spread["min"] <= spread["mean"] <= spread["max"] and spread["sd"] >= 0
    # the summary's improvement is that of the mean CRSEs (as the text's mean row shows it), each from the folds
    ins = sum(f["crse_m"]["ins"] for f in result["folds"]) / 3
    idnn = sum(f["crse_m"]["idnn"] for f in result["folds"]) / 3
    assert result["summary"]["idnn_improvement_pct"] == pytest.approx(100 * (ins - idnn) / ins)
    assert result["summary"]["idnn_improvement_pct_by_fold"]["max"] == max(f["improvement_pct"] for f in result["folds"])
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
                                              (["roundabout", "--span", "0s:60s", "--folds", "3"], "too short for 3 time blocks"),
                                              # 36 s blocks: fold 1 was trained, then its test failed on a --warm-up the command has not
                                              (["roundabout", "--span", "0s:180s", "--folds", "5"], "too short for 5 time blocks of 40 s or more")])
def test_bad_folds_are_one_line(args, words):
    proc = run_cli("cross-validate", *args, *TINY)
    assert proc.returncode == 2 and words in proc.stderr and "Traceback" not in proc.stderr


def test_the_mean_rows_improvement_is_that_of_its_own_columns():
    """The mean row printed the mean of the folds' percentages (-75 % here) beside mean CRSEs whose
    improvement is +25 %: the row now agrees with its columns; the folds' spread is said apart."""
    from ionav_viz.api import CrossValidation
    from ionav_viz.api.cross_validate import Fold

    folds = [Fold(0, ["b"], ["a"], 10, {"ins": 2.0, "idnn": 6.0}, -200.0, 1.0),  # 2 -> 6 m: -200 %
             Fold(1, ["a"], ["b"], 12, {"ins": 18.0, "idnn": 9.0}, 50.0, 1.0)]  # 18 -> 9 m: +50 %
    result = CrossValidation(folds, "drive", 10.0, "cpu", "from random weights")
    mean_row = next(line for line in result.to_text().splitlines() if line.startswith("mean"))
    assert mean_row.split() == ["mean", "22", "10.00", "7.50", "+25.0%"]  # (10 - 7.5) / 10
    assert "IDNN vs INS DR sd 176.8 points (min -200.0 %, max +50.0 %)" in result.to_text()  # sqrt(2) x 125
    summary = json.loads(result.to_json())["summary"]
    assert summary["idnn_improvement_pct"] == pytest.approx(25.0)
    assert summary["idnn_improvement_pct_by_fold"] == pytest.approx({"mean": -75.0, "sd": 125 * 2**0.5, "min": -200.0, "max": 50.0})


def test_every_folds_output_is_checked_before_any_training(tmp_path):
    """-o with fold-3 taken trained and wrote fold-1 and fold-2, then failed on fold-3 with a hint at
    a --force cross-validate has not; a file as -o was "FILE does not exist". Both are refused before
    any training now, nothing written."""
    out = tmp_path / "folds"
    (out / "fold-3").mkdir(parents=True)
    drives = [str(SAMPLES / f"V-sim-roundabout-train-{i}.csv") for i in (1, 2, 3)]
    proc = run_cli("cross-validate", *drives, "--folds", "3", "--span", "0s:80s", *TINY, "-o", str(out))
    assert proc.returncode == 2 and "fold-3: exists already" in proc.stderr and "--force" not in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["fold-3"]
    a_file = tmp_path / "models.txt"
    a_file.write_text("")
    proc = run_cli("cross-validate", *drives, "--folds", "3", "--span", "0s:80s", *TINY, "-o", str(a_file))
    assert proc.returncode == 2 and "models.txt: is not a directory" in proc.stderr and "Traceback" not in proc.stderr


def test_a_cross_validation_stopped_midway_leaves_no_folds_behind(tmp_path):
    """Stopped (Ctrl-C, SIGTERM) or failed after fold 1 was written, cross-validate left fold-1 in
    the output folder, and the same command run again was refused on it; the folds this run wrote
    are removed now, the folder as it was."""
    import ionav_viz as iv

    out = tmp_path / "folds"
    out.mkdir()
    (out / "notes.txt").write_text("mine")

    def progress(label, done, total):
        if label.startswith("fold 2/"):
            raise KeyboardInterrupt

    drives = [str(SAMPLES / f"V-sim-roundabout-train-{i}.csv") for i in (1, 2, 3)]
    from ionav_viz.learning.idnn import ModelConfig

    with pytest.raises(KeyboardInterrupt):
        iv.cross_validate(drives, 3, config=ModelConfig(epochs_disp=1, epochs_yaw=1), read=iv.ReadOptions(span="0s:80s"), output=out, progress=progress)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_folds_tested_on_the_parents_training_drives_are_refused_for_what_they_are():
    """--from-model shipped on the shipped model's own training drives stopped with "--strict: ...
    data the IDNN model (in memory) was trained on (hint: ... leave out --strict)": cross-validate
    has no --strict. The refusal names the fold, the parent and --from-model now."""
    drives = [str(SAMPLES / f"V-sim-roundabout-train-{i}.csv") for i in (1, 2)]
    proc = run_cli("cross-validate", *drives, "--folds", "2", "--span", "0s:80s", "--from-model", "shipped", *TINY)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    error = proc.stderr.strip().splitlines()[-1]
    # 0s:80s after the 30 s warm-up: 30-40 ... 70-80 s (the span's last sample is stamped 79.999 s, on its end)
    assert error.startswith("error: --from-model: fold 1: V-sim-roundabout-train-1: 5 of 5 outages lie in data fold 1's model"), error
    assert "--strict" not in error and "(in memory)" not in error and "leave out --from-model" in error


def test_a_drive_too_short_to_test_on_is_refused_before_any_training():
    """By drive, a 35 s drive was trained on in the other folds, then its own fold failed on
    '--warm-up: ... use a shorter warm-up' (cross-validate has no --warm-up); said first now."""
    drives = [str(SAMPLES / f"V-sim-roundabout-train-{i}.csv") for i in (1, 2, 3)]
    proc = run_cli("cross-validate", *drives, "--folds", "3", "--span", "0s:35s", *TINY)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert "V-sim-roundabout-train-1.csv: 35 s is too short to test on" in proc.stderr and "--warm-up" not in proc.stderr


def test_a_warning_every_fold_repeats_is_said_once():
    """Each fold trained and tested on the same drive's blocks, and warned again each time: 'no
    stationary stretch' 4 times and 'IDNN uncertainty not fitted' twice for 2 folds of the motorway."""
    proc = run_cli("cross-validate", "motorway", "--folds", "2", "--span", "0s:100s", "--epochs-disp", "1", "--epochs-yaw", "1")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("no stationary stretch of 3 s") == 1, proc.stderr
    assert proc.stderr.count("IDNN uncertainty not fitted") == 1, proc.stderr
