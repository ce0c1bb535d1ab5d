"""Fine-tuning's guard against overfitting: a time-ordered validation tail, and which weights each network keeps."""

from __future__ import annotations

import hashlib
import json
import logging

import numpy as np
import pytest
import torch

from ionav_viz.learning.training import FitSettings, TrainingSet, fit_network
from tests.conftest import REPO

pytestmark = pytest.mark.xdist_group("fine_tune")

DRIVE = REPO / "ionav_viz" / "data" / "samples" / "V-sim-roundabout.csv"


class Gain(torch.nn.Module):
    """y = w * x, one weight, starting at ``w0``."""

    def __init__(self, w0: float) -> None:
        super().__init__()
        self.w = torch.nn.Parameter(torch.tensor(float(w0)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.w * x[:, 0]


X = np.linspace(0.1, 1.0, 40)[:, None]


def _fit(w0: float, train_gain: float, val_gain: float, keep: str, epochs: int = 30, anchor: float = 0.0) -> tuple[float, dict]:
    net, selection = Gain(w0), {}
    fit_network(net, X, train_gain * X[:, 0], FitSettings(lr=0.05, epochs=epochs, batch=8, seed=0, keep=keep, anchor=anchor),
                label="t", validation=(X, val_gain * X[:, 0]), selection=selection)
    return float(net.w.detach()), selection


def test_the_start_is_kept_when_training_only_moves_away_from_the_validation_data():
    # starts exact on validation (w = 1), trained towards w = 3: every epoch is worse on validation
    w, sel = _fit(1.0, 3.0, 1.0, "last-or-start")
    assert w == 1.0 and sel["kept_epoch"] == 0 and sel["validation_loss_kept"] == 0.0
    w_best, sel_best = _fit(1.0, 3.0, 1.0, "best")
    assert w_best == 1.0 and sel_best["kept_epoch"] == 0


def test_the_last_epoch_is_kept_when_it_beats_the_start():
    # starts at w = 0, trained and validated towards w = 1
    w, sel = _fit(0.0, 1.0, 1.0, "last-or-start")
    assert w == pytest.approx(1.0, abs=0.05) and sel["kept_epoch"] == sel["epochs"] == 30
    w_last, sel_last = _fit(0.0, 1.0, 1.0, "last")
    assert w_last == w and "kept_epoch" in sel_last  # measured, nothing restored


def test_best_keeps_the_epoch_nearest_the_validation_data():
    # trained from 0 towards 2, validated at 1: the weights pass 1 on the way; the best epoch's lie nearer it than the last
    w_best, sel = _fit(0.0, 2.0, 1.0, "best")
    w_last, _ = _fit(0.0, 2.0, 1.0, "last")
    assert 0 < sel["kept_epoch"] < 30 and abs(w_best - 1.0) < abs(w_last - 1.0)
    assert sel["validation_loss_kept"] == pytest.approx(np.mean(np.abs(w_best * X[:, 0] - X[:, 0])), rel=1e-5)


def test_anchor_pulls_towards_the_start():
    free, _ = _fit(0.0, 1.0, 1.0, "last")
    held, _ = _fit(0.0, 1.0, 1.0, "last", anchor=100.0)
    assert 0.0 <= held < free


def test_time_split_holds_out_the_tail_of_each_drive():
    # two drives of 60 s and 30 s, windows starting every second; the last 20 %: from 48 s and from 24 s
    t = np.concatenate([np.arange(60.0), np.arange(30.0)])
    length = np.concatenate([np.full(60, 60.0), np.full(30, 30.0)])
    zeros = np.zeros(90)
    data = TrainingSet(zeros[:, None], zeros, zeros, zeros[:, None], zeros, t, length)
    train, val = data.time_split(0.2)
    # training windows end by the cut; validation windows and the window before each lie after it
    assert t[train & (length == 60)].max() == 47 and t[val & (length == 60)].min() == 49
    assert t[train & (length == 30)].max() == 23 and t[val & (length == 30)].min() == 25
    assert not (train & val).any() and (~train & ~val).sum() == 2


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_fine_tuning_that_only_harms_keeps_the_parents_weights_and_says_so(tmp_path, caplog):
    import ionav_viz as iv
    from ionav_viz.api.training import fine_tune_settings
    from ionav_viz.learning.idnn import default_model_dir

    # a learning rate 2,500 times the parent's wrecks both networks in the first steps
    config = fine_tune_settings("shipped", epochs_disp=2, epochs_yaw=2)
    config.lr_disp = config.lr_yaw = 10.0
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        iv.train(tmp_path / "m", [str(DRIVE)], iv.TrainingOptions(config, "shipped"), read=iv.ReadOptions(span="0s:120s"))
    meta = json.loads((tmp_path / "m" / "metadata.json").read_text())
    shipped = default_model_dir()
    for name in ("displacement", "yaw_rate"):
        sel = meta["epoch_selection"][name]
        assert sel["kept"] == "parent" and sel["layers"] is None
        # every layer tried, then the first layer alone: both worse than the parent
        assert [t["layers"] for t in sel["tried"]] == ["all", "first"]
        assert all(t["validation_loss_fine_tuned"] > sel["validation_loss_parent"] for t in sel["tried"])
    weights = ("displacement.safetensors", "yaw_rate.safetensors")  # the uncertainty is fitted again
    assert all(_sha(tmp_path / "m" / f) == _sha(shipped / f) for f in weights)
    lines = [r.getMessage() for r in caplog.records if "did not beat the parent" in r.getMessage()]
    assert len(lines) == 2 and all("\n" not in line and "(first layer)" in line for line in lines)
    assert meta["validation"]["note"].startswith("one-window predictions with the last 20% of each drive (by time) left out")
    assert meta["epoch_selection"]["validation"].startswith("the last 20% of each drive (by time) left out: the displacement CRSE (m, mean) of 5 s outages")
    assert [(f["left_out"], f["layers"]) for f in meta["epoch_selection"]["folds"]] == [([0.8, 1.0], "all"), ([0.8, 1.0], "first")]
    assert meta["config"]["tune_layers"] == "all,first"


def test_without_validation_folds_the_tail_trained_fit_is_kept(tmp_path):
    import dataclasses

    import ionav_viz as iv
    from ionav_viz.api.training import fine_tune_settings

    config = dataclasses.replace(fine_tune_settings("shipped", epochs_disp=2, epochs_yaw=2), validation_folds=0)
    config.lr_disp = config.lr_yaw = 10.0
    iv.train(tmp_path / "m", [str(DRIVE)], iv.TrainingOptions(config, "shipped"), read=iv.ReadOptions(span="0s:120s"))
    meta = json.loads((tmp_path / "m" / "metadata.json").read_text())
    for name in ("displacement", "yaw_rate"):
        assert meta["epoch_selection"][name]["kept"] == "parent"
        assert meta["epoch_selection"][name]["validation_loss_last"] > meta["epoch_selection"][name]["validation_loss_start"]
    assert meta["validation"]["note"].startswith("one-window predictions on the last 20% of each drive")
    assert meta["epoch_selection"]["displacement"]["validation"].startswith("displacement CRSE (m, mean) of 5 s outages")


def test_a_fine_tuned_model_records_which_weights_it_kept(tmp_path):
    import ionav_viz as iv
    from ionav_viz.api.training import fine_tune_settings

    model = iv.train(tmp_path / "m", [str(DRIVE)], iv.TrainingOptions(fine_tune_settings("shipped", epochs_disp=2, epochs_yaw=2), "shipped"),
                     read=iv.ReadOptions(span="0s:120s"))
    sel = model.metadata["epoch_selection"]
    assert model.config.validation_folds == 1 and model.config.validation_tail == pytest.approx(0.2)
    for name in ("displacement", "yaw_rate"):
        # the first try that beat the parent is kept: every layer, else the first layer alone, else the parent
        beat = [t["layers"] for t in sel[name]["tried"] if t["validation_loss_fine_tuned"] < sel[name]["validation_loss_parent"]]
        assert [t["layers"] for t in sel[name]["tried"]] == ["all", "first"][: 1 if beat[:1] == ["all"] else 2]
        assert sel[name]["layers"] == (beat[0] if beat else None)
        assert sel[name]["kept"] == {"all": "fine-tuned on every window", "first": "first layer fine-tuned on every window"}.get(sel[name]["layers"], "parent")
    # the model kept was fitted on every window, the tail too
    assert model.metadata["training"]["n_validation"] == 0


def test_block_split_leaves_out_a_stretch_of_time_of_each_drive():
    # two drives of 60 s and 30 s, windows starting every second; the block from 40 % to 60 %: 24-36 s and 12-18 s
    t = np.concatenate([np.arange(60.0), np.arange(30.0)])
    length = np.concatenate([np.full(60, 60.0), np.full(30, 30.0)])
    zeros = np.zeros(90)
    data = TrainingSet(zeros[:, None], zeros, zeros, zeros[:, None], zeros, t, length)
    outside, inside = data.block_split(0.4, 0.6)
    long, short = length == 60, length == 30
    # inside: the window and the one before it in the block; outside: neither touches it
    assert set(t[inside & long]) == set(range(25, 36)) and set(t[inside & short]) == set(range(13, 18))
    assert set(t[~outside & long]) == set(range(24, 37)) and set(t[~outside & short]) == set(range(12, 19))
    assert not (outside & inside).any()
    # the whole drive as the block: nothing outside it
    assert not data.block_split(0.0, 1.0)[0].any()


def test_outage_cases_lie_in_their_block_after_the_warm_up():
    from ionav_viz.api.training import parent_model
    from ionav_viz.learning.training import outage_cases
    from ionav_viz.nav.bias import resolve_bias
    from ionav_viz.sources.load import ReadOptions, load_drive

    drive = load_drive(str(DRIVE), ReadOptions(span="0s:120s"))
    config = parent_model("shipped").config
    t0 = float(drive.t_s[0])
    for block, warm_up, first in (((0.5, 0.75), 30.0, 60.0), ((0.0, 0.25), 0.0, 0.0), ((0.0, 0.5), 40.0, 40.0)):
        cases = outage_cases([(drive, resolve_bias(drive, None))], config, 5, warm_up_s=warm_up, block=block)
        assert cases
        for w, starts, *_ in cases:
            # the window before each outage starts in the block, after the warm-up; the last window ends in the block
            assert (w.t0_s[starts - 1] - t0 >= first - 1e-6).all()
            assert (w.t0_s[starts + 4] + 1.0 - t0 <= 120.0 * block[1] + 1e-6).all()


def _cross_validated(tmp_path, lr: float | None = None):
    import dataclasses

    import ionav_viz as iv
    from ionav_viz.api.training import fine_tune_settings

    config = dataclasses.replace(fine_tune_settings("shipped", epochs_disp=2, epochs_yaw=2), validation_folds=4)
    if lr is not None:
        config.lr_disp = config.lr_yaw = lr
    model = iv.train(tmp_path / "m", [str(DRIVE)], iv.TrainingOptions(config, "shipped"), read=iv.ReadOptions(span="0s:120s"))
    return model, json.loads((tmp_path / "m" / "metadata.json").read_text())


def test_cross_validated_fine_tuning_that_only_harms_keeps_the_parents_weights_and_says_so(tmp_path, caplog):
    from ionav_viz.learning.idnn import default_model_dir

    # a learning rate 2,500 times the parent's wrecks both networks in the first steps, in every fold
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        _, meta = _cross_validated(tmp_path, lr=10.0)
    sel = meta["epoch_selection"]
    for name in ("displacement", "yaw_rate"):
        assert sel[name]["kept"] == "parent" and sel[name]["validation_loss_fine_tuned"] > sel[name]["validation_loss_parent"]
    weights = ("displacement.safetensors", "yaw_rate.safetensors")
    assert all(_sha(tmp_path / "m" / f) == _sha(default_model_dir() / f) for f in weights)
    lines = [r.getMessage() for r in caplog.records if "did not beat the parent on time it did not see" in r.getMessage()]
    assert len(lines) == 2 and all("\n" not in line for line in lines)
    # four 30 s blocks: outages only in those after the 30 s warm-up; every block scores the orientation rate
    for layers in ("all", "first"):  # every layer, then the first alone: each try left out every block
        folds = [f for f in sel["folds"] if f["layers"] == layers]
        assert [f["left_out"] for f in folds] == [[0.0, 0.25], [0.25, 0.5], [0.5, 0.75], [0.75, 1.0]]
        assert folds[0]["n_outages"] == 0 and all(f["n_outages"] > 0 for f in folds[1:])
    assert len(sel["folds"]) == 8 and all(f["n_windows"] > 0 for f in sel["folds"])
    assert meta["config"]["validation_folds"] == 4


def test_cross_validated_fine_tuning_keeps_what_beat_the_parent_trained_on_every_window(tmp_path):
    model, meta = _cross_validated(tmp_path)
    sel = meta["epoch_selection"]
    for name in ("displacement", "yaw_rate"):
        beat = [t["layers"] for t in sel[name]["tried"] if t["validation_loss_fine_tuned"] < sel[name]["validation_loss_parent"]]
        assert sel[name]["layers"] == (beat[0] if beat else None)
        assert sel[name]["kept"] == {"all": "fine-tuned on every window", "first": "first layer fine-tuned on every window"}.get(sel[name]["layers"], "parent")
        assert sel[name]["n_validation"] > 0
    # the final fit saw every window: none held out
    assert meta["training"]["n_validation"] == 0 and meta["validation"]["note"].startswith("one-window predictions with each of 4 blocks of each drive (by time) left out in turn")
    assert meta["validation"]["disp_mae_m"] > 0 and model.config.validation_folds == 4


def test_fine_tuning_the_first_layer_leaves_the_other_layers_as_they_were():
    from ionav_viz.learning.idnn import build_net

    torch.manual_seed(0)
    net = build_net("idnn", 4, 8, 0.0, True, None)
    start = {k: v.clone() for k, v in net.state_dict().items()}
    rng = np.random.default_rng(0)
    x = rng.normal(size=(64, 5))
    fit_network(net, x, x.sum(axis=1), FitSettings(lr=0.01, epochs=3, batch=16, seed=0, layers="first"))
    moved = {k for k, v in net.state_dict().items() if not torch.equal(v, start[k])}
    assert moved == {"body.0.weight", "body.0.bias"}


def test_first_layer_fine_tuning_changes_only_the_first_layer_of_a_kept_network(tmp_path):
    import dataclasses

    import ionav_viz as iv
    from ionav_viz.api.training import fine_tune_settings
    from ionav_viz.learning.idnn import default_model_dir, load_model

    config = dataclasses.replace(fine_tune_settings("shipped", epochs_disp=2, epochs_yaw=2), tune_layers="first")
    model = iv.train(tmp_path / "m", [str(DRIVE)], iv.TrainingOptions(config, "shipped"), read=iv.ReadOptions(span="0s:120s"))
    tuned, shipped = load_model(tmp_path / "m"), load_model(default_model_dir())
    for name, attr in (("displacement", "disp_net"), ("yaw_rate", "yaw_net")):
        sel = model.metadata["epoch_selection"][name]
        assert "tried" not in sel  # one try only
        a, b = getattr(tuned, attr).state_dict(), getattr(shipped, attr).state_dict()
        moved = {k for k in a if not torch.equal(a[k], b[k])}
        assert moved == (set() if sel["kept"] == "parent" else {"body.0.weight", "body.0.bias"})
        assert sel["kept"] in ("parent", "first layer fine-tuned on every window")
