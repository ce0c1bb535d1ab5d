"""Training fast and saying so: the feed-forward networks' written-out steps are autograd's, torch's
threads come back as they were, the progress reaches the API and the terminal (a bar) or a pipe
(a line every few seconds), and ``--device`` is checked."""

from __future__ import annotations

import dataclasses
import io
import math

import numpy as np
import pytest
import torch

import ionav_viz as iv
from ionav_viz.cli import train as train_cli
from ionav_viz.learning.idnn import build_net
from ionav_viz.learning.training import EpochStatus, FitSettings, fit_network
from tests.conftest import REPO, run_cli

pytestmark = pytest.mark.xdist_group("fine_tune")

DRIVE = REPO / "ionav_viz" / "data" / "samples" / "V-sim-roundabout.csv"


def _autograd_fit(net, x: np.ndarray, y: np.ndarray, fit: FitSettings) -> None:
    """The training loop as torch writes it: autograd, torch.optim.Adamax, LambdaLR (cosine), L2-SP."""
    gen = torch.Generator().manual_seed(fit.seed)
    xt, yt = torch.from_numpy(x.astype(np.float32)), torch.from_numpy(y.astype(np.float32))
    trained = [p for name, p in net.named_parameters() if fit.layers == "all" or name.startswith("body.0.")]
    opt = torch.optim.Adamax(trained, lr=fit.lr)
    total = fit.epochs * math.ceil(len(xt) / fit.batch)
    schedule = torch.optim.lr_scheduler.LambdaLR(opt, lambda step: 0.5 * (1.0 + math.cos(math.pi * min(step, total) / total)))
    start = [p.detach().clone() for p in net.parameters()]
    n_params = sum(p.numel() for p in start)
    net.train()
    for _ in range(fit.epochs):
        order = torch.randperm(len(xt), generator=gen)
        for i in range(0, len(xt), fit.batch):
            sel = order[i : i + fit.batch]
            xb = xt[sel].clone()
            xb[:, fit.noise_col] += torch.randn(len(sel), generator=gen) * fit.noise_sd
            opt.zero_grad()
            loss = torch.nn.L1Loss()(net(xb), yt[sel])
            pull = fit.anchor * sum(((p - p0) ** 2).sum() for p, p0 in zip(net.parameters(), start)) / n_params
            (loss + pull).backward()
            opt.step()
            schedule.step()


@pytest.mark.parametrize("arch,layers", [("idnn", "all"), ("idnn", "first"), ("mlp", "all")])
def test_the_feed_forward_steps_are_autograds_to_the_bit(arch, layers):
    """fit_network writes the feed-forward networks' gradients and Adamax out (about 4 x faster than
    autograd on these small networks): the same weights, bit for bit, as torch's own loop with the
    same draws (dropout, batch order, feedback noise), the pull to the start and the first-layer
    training included; a last batch of one example included (37 examples in batches of 12)."""
    rng = np.random.default_rng(3)
    x, y = rng.random((37, 11)), rng.random(37)
    fit = FitSettings(lr=0.01, epochs=4, batch=12, seed=5, noise_col=10, noise_sd=0.2, schedule="cosine", anchor=10.0, layers=layers)
    nets = []
    for _ in range(2):
        torch.manual_seed(1)
        nets.append(build_net(arch, 10, 16, 0.1, True, (0.7, 0.1)))
    torch.manual_seed(2)
    fit_network(nets[0], x, y, fit)
    torch.manual_seed(2)
    _autograd_fit(nets[1], x, y, fit)
    ours, theirs = nets[0].state_dict(), nets[1].state_dict()
    assert ours.keys() == theirs.keys()
    for name in ours:
        assert torch.equal(ours[name], theirs[name]), name
    # each weight has its own storage again, as saving needs
    assert len({p.untyped_storage().data_ptr() for p in nets[0].parameters()}) == len(list(nets[0].parameters()))


def test_training_reports_each_epoch_and_gives_torch_its_threads_back(tmp_path):
    before = torch.get_num_threads()
    seen: list[EpochStatus] = []
    calls: list[tuple[str, int, int]] = []
    config = dataclasses.replace(iv.fine_tune_settings("shipped", 2, 2), tune_layers="all")  # one try
    iv.train(tmp_path / "m", [str(DRIVE)], iv.TrainingOptions(config, "shipped", "cpu"), read=iv.ReadOptions(span="0s:120s"),
             on_epoch=seen.append, progress=lambda *a: calls.append(a))
    assert torch.get_num_threads() == before
    # the tail decides (the model fine-tuned on the first 80 %), then every window: both networks, 2 epochs each
    assert [s.label for s in seen] == [f"{net} ({fit})" for fit in ("block 1/1 left out", "every window")
                                       for net in ("displacement", "orientation rate") for _ in range(2)]
    assert [(s.label, s.epoch, s.epochs) for s in seen] == calls
    steps = [s.steps_done for s in seen]
    assert steps == sorted(steps) and steps[-1] == seen[-1].steps_planned
    assert all(s.steps_done <= s.steps_planned and s.left_s >= 0 and math.isfinite(s.loss) for s in seen)
    assert seen[-1].left_s == 0


def test_piped_training_prints_a_line_every_few_seconds(tmp_path, monkeypatch):
    monkeypatch.setattr(train_cli, "PLAIN_PROGRESS_EVERY_S", 0.0)  # every epoch
    proc = run_cli("train", str(DRIVE), "--span", "0s:120s", "--from-model", "shipped", "--epochs-disp", "2", "--epochs-yaw", "2",
                   "-o", str(tmp_path / "m"))
    assert proc.returncode == 0, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.startswith("training: ")]
    assert lines and lines[0].startswith("training: displacement (block 1/1 left out) (all layers), epoch 1/2, loss ")
    assert all(" s elapsed, about " in line and line.endswith(" s left") for line in lines)
    quiet = run_cli("train", str(DRIVE), "--span", "0s:120s", "--from-model", "shipped", "--epochs-disp", "1", "--epochs-yaw", "1",
                    "-q", "-o", str(tmp_path / "q"))
    assert quiet.returncode == 0 and "training: " not in quiet.stderr


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_terminal_gets_a_bar_with_the_epoch_loss_and_time_left():
    stream = _Terminal()
    with train_cli.training_progress(False, stream) as update:
        update(EpochStatus("displacement (every window)", 7, 100, 0.0123, None, 70, 1000, 3.0, 40.0))
    shown = stream.getvalue()
    assert "displacement (every window)" in shown and "epoch 7/100" in shown and "loss 0.0123" in shown
    assert "about 40 s left" in shown
    with train_cli.training_progress(True, stream) as update:
        assert update is None


def test_a_device_torch_cannot_use_is_one_line(tmp_path):
    if torch.cuda.is_available():
        pytest.skip("torch sees a GPU here")
    for device, words in (("cuda", "torch sees no GPU"), ("tpu", "unknown device 'tpu'")):
        proc = run_cli("train", str(DRIVE), "--span", "0s:60s", "--from-model", "shipped", "--device", device, "-q", "-o", str(tmp_path / "m"))
        assert proc.returncode == 2 and proc.stderr.startswith("error: --device: ") and words in proc.stderr
        assert len(proc.stderr.splitlines()) == 1 and not (tmp_path / "m").exists()
