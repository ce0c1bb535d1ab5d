"""Fine-tuning's guard against overfitting: a time-ordered validation tail, and which weights each network keeps."""

from __future__ import annotations

import hashlib
import json
import logging

import numpy as np
import pytest
import torch

from ionav_viz.nav.training import FitSettings, TrainingSet, fit_network
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
    from ionav_viz.nav.idnn import default_model_dir

    # a learning rate 2,500 times the parent's wrecks both networks in the first steps
    config = fine_tune_settings("shipped", epochs_disp=2, epochs_yaw=2)
    config.lr_disp = config.lr_yaw = 10.0
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        iv.train(tmp_path / "m", [str(DRIVE)], config, read=iv.ReadOptions(span="0s:120s"), from_model="shipped")
    meta = json.loads((tmp_path / "m" / "metadata.json").read_text())
    shipped = default_model_dir()
    for name in ("displacement", "yaw_rate"):
        assert meta["epoch_selection"][name]["kept"] == "parent"
        assert meta["epoch_selection"][name]["validation_loss_last"] > meta["epoch_selection"][name]["validation_loss_start"]
    weights = ("displacement.safetensors", "yaw_rate.safetensors")  # the uncertainty is fitted again
    assert all(_sha(tmp_path / "m" / f) == _sha(shipped / f) for f in weights)
    lines = [r.getMessage() for r in caplog.records if "did not beat the parent" in r.getMessage()]
    assert len(lines) == 2 and all("\n" not in line for line in lines)
    assert meta["validation"]["note"].startswith("one-window predictions on the last 20% of each drive")
    assert meta["epoch_selection"]["displacement"]["validation"].startswith("displacement CRSE (m, mean) of 5 s outages")


def test_a_fine_tuned_model_records_which_weights_it_kept(tmp_path):
    import ionav_viz as iv
    from ionav_viz.api.training import fine_tune_settings

    model = iv.train(tmp_path / "m", [str(DRIVE)], fine_tune_settings("shipped", epochs_disp=2, epochs_yaw=2),
                     read=iv.ReadOptions(span="0s:120s"), from_model="shipped")
    sel = model.metadata["epoch_selection"]
    assert model.config.keep == "last-or-start" and model.config.validation_tail == pytest.approx(0.2)
    for name in ("displacement", "yaw_rate"):
        assert sel[name]["kept"] in ("parent", "epoch 2 of 2")
        assert sel[name]["validation_loss_kept"] == min(sel[name]["validation_loss_start"], sel[name]["validation_loss_last"])
