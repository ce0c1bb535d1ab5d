"""Fine-tuning on a real car's own drive (issue 62, points 1 and 5): on each public real log of
``tests/data/real/``, the shipped IDNN fine-tuned on the first half of the log (``train --span 0s:T
--from-model shipped``) scores, on 10 s outages tiled over the second half (IMU only), a mean
displacement CRSE below the INS DR's and not above its parent's beyond the outages' spread (the 95 %
interval of a paired bootstrap over the outages wholly above zero). As ``benchmarks/real_fine_tune.py``
measures it, with fewer epochs (the choices fine-tuning makes are the same kind)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.analysis.evaluate import paired_bootstrap_means
from ionav_viz.core.gnss_quality import GnssLimits
from ionav_viz.learning.idnn import IdnnEstimator

pytestmark = pytest.mark.xdist_group("real_fine_tune")

CORPUS_DIR = Path(__file__).parent / "data" / "real"
CORPUS = json.loads((CORPUS_DIR / "corpus.json").read_text())
EPOCHS = 20


def read_options(entry: dict, span: str | None = None) -> iv.ReadOptions:
    """The corpus entry's read options (IMU only, the mount estimated), over ``span``."""
    log = dict(entry.get("log", {}))
    options = iv.LogOptions(imu_mount="auto", vehicle_speed_topic="none", **log)
    limits = (
        GnssLimits()
        if entry.get("max_sigma_m") is None
        else dataclasses.replace(GnssLimits(), max_sigma_m=entry["max_sigma_m"])
    )
    return iv.ReadOptions(log=options, gnss_limits=limits, span=span)


def crse(report: iv.Report, name: str) -> tuple[list[float], np.ndarray]:
    sequences = report.to_dict()["sequences"]
    return [s["start_s"] for s in sequences], np.array([s[name]["crse_m"] for s in sequences])


def fine_tuned_on_first_half(log: str, folder: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    """INS DR, parent and fine-tuned displacement CRSE (m) per 10 s outage of the log's second half,
    the parent's network alone (without its history arbiter), and the fine-tuned model's metadata."""
    entry = CORPUS["logs"][log]
    path = str(CORPUS_DIR / entry["file"])
    drive = iv.load_drive(path, read_options(entry))
    split_s = float(math.floor(float(drive.t_s[-1] - drive.t_s[0]) / 2))
    config = iv.fine_tune_settings("shipped", epochs_disp=EPOCHS, epochs_yaw=EPOCHS)
    model = iv.train(folder / "m", [path], iv.TrainingOptions(config, "shipped"), read=read_options(entry, f"0s:{split_s:g}s"))
    run = {"warm_up_s": split_s + 1.0}  # the window before the first outage lies after the training span
    parent = iv.evaluate([drive], 10, estimators=["ins", "idnn"], run=iv.RunOptions(**run))
    tuned = iv.evaluate(
        [drive], 10, estimators=["idnn"], run=iv.RunOptions(model=str(folder / "m"), strict=True, **run)
    )
    network = iv.evaluate([drive], 10, estimators=[IdnnEstimator(arbiter=False)], run=iv.RunOptions(**run))
    starts, ins = crse(parent, "ins")
    tuned_starts, fine = crse(tuned, "idnn")
    assert tuned_starts == starts and len(starts) >= 2
    metadata = {**model.metadata, "second_half": tuned.to_dict()["summary"]["idnn"]}
    return ins, crse(parent, "idnn")[1], fine, crse(network, "idnn")[1], metadata


def above_beyond_spread(baseline: np.ndarray, candidate: np.ndarray) -> bool:
    """Whether the candidate's mean is above the baseline's beyond the outages' spread: the 95 %
    interval of the paired bootstrap of the difference lies wholly above zero."""
    mb, mc = paired_bootstrap_means(baseline, candidate)
    return bool(np.percentile(mc - mb, 2.5) > 0)


@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    """:func:`fine_tuned_on_first_half` of a log, worked out once for the module."""
    done: dict[str, tuple] = {}

    def of(log: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        if log not in done:
            done[log] = fine_tuned_on_first_half(log, tmp_path_factory.mktemp(log))
        return done[log]

    return of


LOGS = sorted(CORPUS["logs"])
#: 29 s to fine-tune on: no validation outage fits after the 30 s warm-up, so the parent is kept,
#: and the parent is above the INS DR on the second half's 2 outages (docs/real-imu-logs.md).
SHORT = {"dash_comma2k19"}
#: The second phone drive, held out of every choice made on the first (added 2026-11-29): issue 62 points 1
#: and 3 fail there (docs/real-imu-logs.md, "The held-out phone drive").
HELD_OUT_PHONE = "phone_flat_meszdav_q2"
HELD_OUT_MISSES = {
    "criterion": "held-out phone: fine-tuned 14.27 m against the INS DR's 10.15 m on the second half (issue 62 point 1)",
    "ellipse": "held-out phone: 67 % of 12 second-half outages inside the 95 % ellipse, ANEES 3.5 (issue 62 point 3)",
}


def expected(log: str, check: str):
    """``log`` as a parameter, an expected failure (strict) where this check fails on it, said why."""
    if log in SHORT and check == "criterion":
        return pytest.param(log, marks=pytest.mark.xfail(strict=True, reason="29 s of drive validates nothing"))
    if log == HELD_OUT_PHONE:
        return pytest.param(log, marks=pytest.mark.xfail(strict=True, reason=HELD_OUT_MISSES[check]))
    return log


@pytest.mark.parametrize("log", [expected(log, "criterion") for log in LOGS])
def test_fine_tuned_on_the_first_half_beats_the_ins_dr_and_never_its_parent_on_the_second(log, tuned):
    ins, parent, fine, _, _ = tuned(log)
    assert fine.mean() < ins.mean(), f"{log}: fine-tuned {fine.mean():.2f} m, INS DR {ins.mean():.2f} m"
    assert not above_beyond_spread(parent, fine), f"{log}: fine-tuned {fine.mean():.2f} m, parent {parent.mean():.2f} m"


def test_the_phone_takes_the_ins_drs_displacement_where_its_first_half_shows_it_better(tuned):
    """On the phone log the shipped model's network loses to the INS DR on the second half (13.5 against
    11.6 m; with its history arbiter 11.4 m); its first half says so too, and fine-tuning blends the
    INS DR's displacement in."""
    ins, _, _, network, meta = tuned("phone_flat_meszdav")
    record = meta["epoch_selection"]["ins_blend"]
    assert (
        network.mean() > ins.mean() and 0 < record["kept"] < 1 and meta["hyperparameters"]["ins_blend"] == record["kept"]
    )
    assert record["last_block_m"][f"{record['kept']:g}"] <= record["last_block_m"]["0"]


def test_a_model_taking_all_of_the_ins_drs_displacement_is_the_ins_dr(tmp_path):
    from ionav_viz.learning.idnn import default_model_dir, load_model, save_model

    entry = CORPUS["logs"]["roof_mems_rtk"]
    drive = iv.load_drive(str(CORPUS_DIR / entry["file"]), read_options(entry, "0s:120s"))
    model = load_model(default_model_dir())
    model.config = dataclasses.replace(model.config, ins_blend=1.0)
    save_model(model, tmp_path / "m")
    report = iv.evaluate([drive], 10, estimators=["ins", "idnn"], run=iv.RunOptions(model=str(tmp_path / "m")))
    assert np.array_equal(crse(report, "idnn")[1], crse(report, "ins")[1])
    info = {e["name"]: e.get("info", {}) for e in report.to_dict()["estimators"]}
    assert info["idnn"]["ins_blend"] == 1.0  # the report says what the model's displacement is
    assert json.loads((tmp_path / "m" / "metadata.json").read_text())["config"]["ins_blend"] == 1.0


def test_where_the_parent_beats_the_ins_dr_on_the_first_half_no_share_is_taken(tuned):
    """The roof log: the INS DR loses to the parent on the first half's outages; the model stays the network."""
    *_, meta = tuned("roof_mems_rtk")
    record = meta["epoch_selection"]["ins_blend"]
    assert (
        record["kept"] == 0
        and record["mean_m"]["1"] > record["mean_m"]["0"]
        and meta["hyperparameters"]["ins_blend"] == 0
    )
    assert len(record["n_outages"]) == 5 and sum(record["n_outages"]) > 0


@pytest.mark.parametrize("log", [expected(log, "ellipse") for log in LOGS])
def test_every_fine_tuned_model_has_an_uncertainty_and_its_ellipse_holds_the_second_half(log, tuned):
    """Issue 62 point 3 on the corpus: fine-tuned on half a log (too short to fit an uncertainty of
    its own), the model keeps its parent's (the phone's and the dash's had none: no covariance at
    all); on the logs with 10 or more outages in the second half its 95 % ellipse holds 80-99 % of
    the outages' final position errors (the robot's own fit held 3 of 6 at 30 s), or all of them
    where an honest ellipse holds all n one time in four or more (0.95^n >= 0.25: n <= 27), and it
    is not underconfident by more than a factor of two (ANEES at least 0.5: the phone's was 0.14,
    its ellipse 52 m across 10 s against 13 m of error, when the metric took a whole fix's 8 m for
    the noise of the difference of two fixes 10 s apart, 3.0 m there)."""
    *_, meta = tuned(log)
    assert meta["uncertainty"]["inherited"].startswith("the parent's"), meta.get("uncertainty")
    consistency = meta["second_half"]["consistency"]
    n = consistency["n_outages"]
    if n >= 10:
        assert 80.0 <= consistency["coverage_95"] <= 99.0 or (consistency["coverage_95"] == 100.0 and 0.95**n >= 0.25), consistency
        assert consistency["anees"] >= 0.5, consistency
    # the truth's own noise counted: the phone's fixes 1-10 s apart, under the 8 m its receiver reports (RTK: the floor)
    truth = consistency["by_second"]["truth_sigma_m"]
    if log == "phone_flat_meszdav":
        assert 0.3 < truth[0] < truth[-1] < 5.0, truth
    elif log == "roof_mems_rtk":
        assert truth == pytest.approx([0.3] * 10), truth
