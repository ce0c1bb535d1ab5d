"""train --from-model: fine-tuning, what the model records, and the checks that use it (input match, leakage)."""

from __future__ import annotations

import csv
import hashlib
import json

import pytest

from tests.conftest import REPO, run_cli

pytestmark = pytest.mark.xdist_group("fine_tune")

DRIVE = REPO / "ionav_viz" / "data" / "samples" / "V-sim-roundabout.csv"


def _error_lines(stderr: str) -> list[str]:
    """The error lines (warnings may come before); exactly one, and no traceback."""
    assert "Traceback" not in stderr
    lines = [line for line in stderr.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and stderr.endswith(lines[0] + "\n")
    return lines


@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    model = tmp_path_factory.mktemp("tuned") / "model"
    proc = run_cli("train", str(DRIVE), "--span", "0s:120s", "--from-model", "shipped", "--epochs-disp", "1", "--epochs-yaw", "1",
                   "-q", "-o", str(model))
    assert proc.returncode == 0, proc.stderr
    assert "fine-tuned from shipped" in proc.stderr
    (model.parent / "stderr.txt").write_text(proc.stderr)
    return model


def test_the_summary_says_what_its_counts_are(tuned):
    """'1481 windows' for 150 s read as 1 s windows; '21 outages of 60 s' in 150 s did not say they
    overlap. The counts say what they count: the examples are 1 s windows starting every 0.1 s, and
    the uncertainty's outages start every 3 s after a 30 s warm-up: the span's last sample is
    stamped 119.999 s, on the 120 s end (1 ms clock jitter), 120 whole windows, so the last 60 s
    outage starts at 60 s: 30, 33, ..., 60, 11 of them."""
    stderr = (tuned.parent / "stderr.txt").read_text()
    n = json.loads((tuned / "metadata.json").read_text())["training"]["n_examples"]
    assert f"trained idnn on 1 drive(s), {n} training examples (1 s windows every 0.1 s); trainable parameters" in stderr
    assert 1000 < n <= 1200  # about 10 a second over 120 s, less the validation tail
    # 11 outages of 60 s, one every 3 s: 11 * 3 / 60 = 0.55 outages' worth of independent time
    assert ("uncertainty: the parent's: the fine-tuning drives hold 11 overlapping outages of 60 s (one every 3 s), "
            "about 0.6 independent, fewer than 30 to fit its own") in stderr


def test_a_fine_tuned_model_too_short_to_fit_an_uncertainty_keeps_its_parents(tuned):
    """Fine-tuned on 120 s, the model had no uncertainty at all (no covariance, nothing for the
    review's ellipses or the out-of-domain widening to act on); on the corpus's robot log a fit on
    the first half's 3 minutes held the second half's 30 s errors in its 95 % ellipse on 3 of 6
    outages. It keeps the shipped model's, the same parameters and the same file's bytes."""
    from ionav_viz.learning.idnn import UNCERTAINTY_FILE, default_model_dir, load_model

    meta = json.loads((tuned / "metadata.json").read_text())
    shipped = json.loads((default_model_dir() / "metadata.json").read_text())
    assert meta["uncertainty"]["parameters"] == shipped["uncertainty"]["parameters"]
    assert meta["uncertainty"]["inherited"].startswith("the parent's")
    assert (tuned / UNCERTAINTY_FILE).read_bytes() == (default_model_dir() / UNCERTAINTY_FILE).read_bytes()
    assert load_model(tuned).uncertainty is not None and "uncertainty_skipped" not in meta


def test_fine_tuned_model_records_parent_span_checksum_and_imu(tuned):
    from ionav_viz.learning.idnn import default_model_dir

    meta = json.loads((tuned / "metadata.json").read_text())
    shipped = json.loads((default_model_dir() / "metadata.json").read_text())
    record = meta["training"]["drives"][0]
    assert record["sha256"] == hashlib.sha256(DRIVE.read_bytes()).hexdigest() and record["size_bytes"] == DRIVE.stat().st_size
    assert record["span_s"] == pytest.approx([0.0, 120.0], abs=0.01)  # the first and last sample inside (1 ms clock jitter)
    assert meta["input"] == {"channels": ["accel_long_mps2", "yaw_rate_radps"], "grid_rate_hz": 10.0, "imu_kind": "2-channel", "imu_rate_hz": 10.0}
    assert meta["parent"]["directory"] == "shipped" and meta["parent"]["weights_sha256"] == shipped["weights_sha256"]
    assert meta["normalisation"] == shipped["normalisation"]  # the parent's input normalisation is kept
    assert meta["config"]["lr_schedule"] == "cosine" and meta["config"]["lr_disp"] == shipped["config"]["lr_disp"] / 2


def test_outages_in_training_data_are_listed_and_refused_with_strict(tuned):
    proc = run_cli("evaluate", str(DRIVE), "--span", "0s:200s", "--warm-up", "0s", "--model", str(tuned), "--estimators", "ins,idnn", "--json")
    assert proc.returncode == 0, proc.stderr
    warned = [w for w in json.loads(proc.stdout)["warnings"] if "was trained on" in w]
    # outages 1-11 .. 111-121 s touch the trained 0-120 s (the window before each included); 121-131 s does not
    assert len(warned) == 1 and "12 of 19 outages" in warned[0] and "111-121 s" in warned[0] and "121-131 s" not in warned[0]
    held_out = run_cli("evaluate", str(DRIVE), "--span", "120s:", "--model", str(tuned), "--estimators", "ins,idnn", "--strict")
    assert held_out.returncode == 0 and "was trained on" not in held_out.stderr
    strict = run_cli("evaluate", str(DRIVE), "--span", "0s:200s", "--model", str(tuned), "--estimators", "ins,idnn", "--strict")
    assert strict.returncode == 2 and _error_lines(strict.stderr)[0].startswith("error: --strict:")


def test_each_outage_says_whether_it_lies_in_training_data(tuned, tmp_path):
    proc = run_cli("evaluate", str(DRIVE), "--span", "0s:200s", "--warm-up", "0s", "--model", str(tuned), "--estimators", "ins,idnn", "--json",
                   "--export", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    sequences = json.loads(proc.stdout)["sequences"]
    flagged = {s["start_s"]: s["in_training"] for s in sequences}
    # trained on 0-120 s: the 111-121 s outage (its window before from 110 s) is inside, 121-131 s is not (it only touches 120 s)
    assert flagged[111.0] is True and flagged[121.0] is False and flagged[1.0] is True
    assert sum(flagged.values()) == 12 and len(flagged) == 19
    rows = list(csv.DictReader((tmp_path / "out" / "outages.csv").open()))
    by_start = {(r["start_s"], r["estimator"]): r["in_training"] for r in rows}
    assert by_start[("111.000", "idnn")] == by_start[("111.000", "ins")] == "1"
    assert by_start[("121.000", "idnn")] == by_start[("121.000", "ins")] == "0"


def test_without_the_idnn_no_outage_is_said_to_be_in_training(tmp_path):
    proc = run_cli("evaluate", str(DRIVE), "--span", "0s:60s", "--estimators", "ins", "--json", "--export", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    assert all("in_training" not in s for s in json.loads(proc.stdout)["sequences"])
    assert {r["in_training"] for r in csv.DictReader((tmp_path / "out" / "outages.csv").open())} == {""}


def test_a_model_of_another_imu_rate_is_refused_in_one_line(tuned, tmp_path):
    import shutil

    other = tmp_path / "other"
    shutil.copytree(tuned, other)
    meta = json.loads((other / "metadata.json").read_text())
    meta["input"]["imu_rate_hz"] = 100.0
    (other / "metadata.json").write_text(json.dumps(meta))
    proc = run_cli("evaluate", str(DRIVE), "--span", "120s:", "--model", str(other), "--estimators", "ins,idnn")
    (error,) = _error_lines(proc.stderr)
    assert proc.returncode == 2 and "samples at 10 Hz" in error and "100 Hz" in error
    again = run_cli("train", str(DRIVE), "--from-model", str(other), "--epochs-disp", "1", "--epochs-yaw", "1", "-q", "-o", str(tmp_path / "m"))
    assert again.returncode == 2 and "100 Hz" in again.stderr and "Traceback" not in again.stderr


@pytest.mark.parametrize(("args", "words"), [(["--from-model", "no/such/model"], "--from-model"),
                                              (["--from-model", "shipped", "--arch", "lstm"], "--arch with --from-model"),
                                              # was taken and silently ignored (the parent's 0.1 m trained, and recorded)
                                              (["--from-model", "shipped", "--feedback-noise", "0.5"], "--feedback-noise with --from-model"),
                                              # the drive was dropped silently for the paper's runs
                                              (["--paper-train"], "--paper-train trains on the paper's runs, and 1 drive(s) were given too")])
def test_bad_fine_tuning_options_are_one_line(tmp_path, args, words):
    proc = run_cli("train", str(DRIVE), "--span", "0s:60s", *args, "-q", "-o", str(tmp_path / "m"))
    assert proc.returncode == 2 and words in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "m").exists()
