"""Training the displacement and orientation-rate networks (the paper's Section 3.4, Table 5).

Training examples are 1-second windows of the training drives, taken at ten grid phases
(offsets 0, 0.1, ... 0.9 s) so every second of a drive is seen at every phase. A window is used
when the window before it lies in the same gap-free segment (it supplies the previous GNSS
displacement, the feedback input). Inputs are bias-corrected with each drive's stationary
biases (:func:`ionav_viz.evaluate.resolve_bias`), or calibrated by the GNSS-aided INS
(``inputs="calibrated"``, :func:`training_examples`). A seeded 10 % of the examples is held out for
validation. Loss: mean absolute error; optimiser: Adamax, its learning rate falling linearly to
zero over the last ``lr_decay_tail`` of the steps (beyond the paper: the displacement model's
small constant offset, which the feedback loop integrates, otherwise depends on the last
batches); deterministic on the CPU for a seed.
"""

from __future__ import annotations

import contextlib
import math
import platform
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.covariance import determinant_en, nees_en
from ..core.drive import Drive
from ..core.errors import InputError
from ..core.grid import WINDOW_S
from ..nav.bias import SensorBias
from ..nav.kalman import CHI2_2_95
from ..nav.planar_filter import calibration
from ..nav.track import TrackCovariance
from ..nav.windows import make_windows
from .domain import Domain, domain_of
from .idnn import (
    IdnnModel,
    MinMax,
    ModelConfig,
    Normalisation,
    Uncertainty,
    build_net,
    count_parameters,
    sample_history,
)
from .provenance import check_inputs, drive_record, input_record, seen_drives

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class EpochStatus:
    """An epoch of training done, for a progress display (:func:`train_models`'s ``on_epoch``).

    ``label``: the network and the fit, as the ``progress(label, done, total)`` callback gets it
    (``"displacement (every window)"``); ``epoch`` of ``epochs``; ``loss``: the epoch's mean
    training loss (L1, normalised units); ``validation_loss``: the fit's validation score after
    the epoch, where it has one; ``steps_done`` and ``steps_planned``: optimiser steps of the whole
    training, done and planned so far (fine-tuning plans its first-layer retry when it starts it);
    ``elapsed_s``: since the training began; ``left_s``: the steps planned and not done at the
    pace of the steps so far (the work between fits, such as validation and the uncertainty's fit
    at the end, is not in it)."""

    label: str
    epoch: int
    epochs: int
    loss: float
    validation_loss: float | None
    steps_done: int
    steps_planned: int
    elapsed_s: float
    left_s: float


class TrainingMeter:
    """Counts a training's optimiser steps against its plan and tells ``progress`` (label, epoch,
    epochs) and ``on_epoch`` (:class:`EpochStatus`) after every epoch. :meth:`within` gives the
    meter of a part of the training, whose labels end with its ``suffix``."""

    def __init__(self, progress: Progress | None = None, on_epoch: Callable[[EpochStatus], None] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.progress, self.on_epoch, self.clock = progress, on_epoch, clock
        self.start_s = clock()
        self.steps_done = 0
        self.steps_planned = 0
        self.stepping_s = 0.0

    def within(self, suffix: str) -> _ScopedMeter:
        """This meter (the same counts) for a part of the training: its labels end with ``suffix``."""
        return _ScopedMeter(self, (suffix,))

    def plan(self, steps: int) -> None:
        """``steps`` more optimiser steps to come."""
        self.steps_planned += int(steps)

    def epoch(self, label: str, epoch: int, epochs: int, loss: float, validation_loss: float | None, steps: int,
              seconds: float) -> None:
        """An epoch of ``steps`` optimiser steps, taking ``seconds``, done by the fit ``label``."""
        self.steps_done += int(steps)
        self.steps_planned = max(self.steps_planned, self.steps_done)
        self.stepping_s += seconds
        if self.progress is not None:
            self.progress(label, epoch, epochs)
        if self.on_epoch is not None:
            left_s = self.stepping_s / self.steps_done * (self.steps_planned - self.steps_done)
            self.on_epoch(EpochStatus(label, epoch, epochs, loss, validation_loss, self.steps_done, self.steps_planned,
                                      self.clock() - self.start_s, left_s))


class _ScopedMeter:
    """A :class:`TrainingMeter` seen from a part of the training: the same counts, its labels
    extended by the parts' suffixes (innermost first, as ``"displacement (block 1/1 left out) (all layers)"``)."""

    def __init__(self, meter: TrainingMeter, suffixes: tuple[str, ...]) -> None:
        self.meter, self.suffixes = meter, suffixes

    def within(self, suffix: str) -> _ScopedMeter:
        return _ScopedMeter(self.meter, (suffix, *self.suffixes))

    def plan(self, steps: int) -> None:
        self.meter.plan(steps)

    def epoch(self, label: str, epoch: int, epochs: int, loss: float, validation_loss: float | None, steps: int,
              seconds: float) -> None:
        self.meter.epoch(label + "".join(self.suffixes), epoch, epochs, loss, validation_loss, steps, seconds)


@dataclass
class TrainingSet:
    """Examples: accel (n, n_steps_disp) and gyro (n, n_steps_yaw) histories, previous and current GNSS
    displacement, GNSS yaw rate."""

    accel_mps2: np.ndarray
    prev_disp_m: np.ndarray
    disp_m: np.ndarray
    gyro_radps: np.ndarray
    yaw_rate_radps: np.ndarray
    #: where each example's window starts, seconds from its drive's first sample, and its drive's length (s)
    t_s: np.ndarray | None = None
    drive_s: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.disp_m)

    def time_split(self, tail: float) -> tuple[np.ndarray, np.ndarray]:
        """(train, validation) masks holding out the last ``tail`` of each drive by time: validation
        windows, and the window before each (its feedback input and longer history), lie wholly in the
        tail; training windows end before it (a window across the cut is in neither)."""
        return self.block_split(1.0 - tail, 1.0)

    def block_split(self, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
        """(outside, inside) masks for the block from ``lo`` to ``hi`` (fractions) of each drive by time:
        inside, the window and the window before it lie wholly in the block; outside, neither
        touches it (a window across an edge is in neither)."""
        a, b = lo * self.drive_s, hi * self.drive_s
        inside = (self.t_s - WINDOW_S >= a - 1e-9) & (self.t_s + WINDOW_S <= b + 1e-9)
        return (self.t_s + WINDOW_S <= a + 1e-9) | (self.t_s - WINDOW_S >= b - 1e-9), inside

    def subset(self, mask: np.ndarray) -> TrainingSet:
        return TrainingSet(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))


#: Calibrated inputs: a training window takes the filter's calibration of 0 to this many - 1
#: windows before it, as a window that far into an outage takes the outage start's.
CALIBRATION_LAG_WINDOWS = 10


#: Training examples are windows of WINDOW_S starting every EXAMPLE_STEP_S (the grid's offsets), overlapping.
EXAMPLE_STEP_S = 0.1


def training_examples(drives: list[tuple[Drive, SensorBias]], n_steps_disp: int, n_steps_yaw: int, phases: int = 10,
                      inputs: str = "plain", seed: int = 0) -> TrainingSet:
    """All training windows of ``drives`` (each with its sensor biases) at ``phases`` grid offsets
    EXAMPLE_STEP_S apart.

    ``inputs="plain"`` corrects the samples with the standstill biases (the paper's); ``"calibrated"``
    with the GNSS-aided INS's calibration (:func:`ionav_viz.nav.planar_filter.calibration`) of a window a seeded
    random 0-9 s earlier in the same segment (:data:`CALIBRATION_LAG_WINDOWS`).
    """
    rng = np.random.default_rng([seed, 17])
    parts: list[tuple[np.ndarray, ...]] = []
    for drive, bias in drives:
        for phase in range(phases):
            w = make_windows(drive, offset_s=phase / 10.0)  # EXAMPLE_STEP_S apart
            if len(w) < 2:
                continue
            # the previous window (feedback input, and history beyond 10 steps) is in the same segment,
            # and both have trustworthy GNSS truth (a bad fix is never a training target)
            k = np.arange(1, len(w))
            k = k[(w.segment[k] == w.segment[k - 1]) & w.truth_ok[k] & w.truth_ok[k - 1]]
            accel = sample_history(w.accel_mps2, k, n_steps_disp)
            gyro = sample_history(w.gyro_radps, k, n_steps_yaw)
            if inputs == "calibrated":
                first = np.searchsorted(w.segment, w.segment, side="left")  # each window's segment start
                lagged = np.maximum(k - rng.integers(0, CALIBRATION_LAG_WINDOWS, len(k)), first[k])
                cal = calibration(drive, w, bias.accel_mps2, bias.gyro_radps).at(lagged)
                driven = w.speed0_mps[lagged] * WINDOW_S * (k - lagged)  # as in prediction
                accel, gyro = cal.accel(accel, driven), cal.gyro(gyro)
            else:
                accel, gyro = accel - bias.accel_mps2, gyro - bias.gyro_radps
            t0, length = float(drive.t_s[0]), float(drive.t_s[-1] - drive.t_s[0]) + 1.0 / drive.rate_hz
            parts.append((accel, w.gnss_disp_m[k - 1], w.gnss_disp_m[k], gyro, w.gnss_yaw_rate_radps[k], w.t0_s[k] - t0,
                          np.full(len(k), length)))
    if not parts:
        raise InputError("no training windows: the training drives are too short",
                         "give drives of at least a few seconds")
    return TrainingSet(*(np.concatenate(p) for p in zip(*parts)))


@dataclass(frozen=True)
class FitSettings:
    """How :func:`fit_network` trains one network.

    The learning rate ``lr`` is constant, then falls linearly to zero over the last ``decay_tail``
    fraction of the optimiser steps (0: constant throughout, as in the paper's Keras set-up);
    ``noise_sd``: Gaussian noise added to the (already normalised) input column ``noise_col``.
    """

    lr: float
    epochs: int
    batch: int
    seed: int
    noise_col: int | None = None
    noise_sd: float = 0.0
    decay_tail: float = 0.0
    schedule: str = "tail"  # "cosine": lr * (1 + cos(pi * step / steps)) / 2, for fine-tuning (decay_tail unused)
    device: str = "cpu"
    # with validation data, "best": the weights of the epoch best on it (epoch 0: the start's); "last-or-start": the
    # last epoch's unless the start's are better
    keep: str = "last"
    anchor: float = 0.0  # loss + anchor * mean squared distance of the weights from the starting ones (L2-SP)
    # the parameters trained: "all", or "first": the first layer's only (the others stay as they start)
    layers: str = "all"


def fit_network(net, x: np.ndarray, y: np.ndarray, fit: FitSettings, meter: TrainingMeter | None = None,
                label: str = "", validation: tuple[np.ndarray, np.ndarray] | Callable[[], float] | None = None,
                selection: dict[str, Any] | None = None) -> list[float]:
    """Minimise L1 with Adamax as ``fit`` says; returns the mean loss of each epoch.

    ``validation`` (inputs, targets), or a function of no arguments that scores the network as it
    is: its L1 loss, or that score (dropout off, no input noise), is measured before
    training (epoch 0: the starting weights, a parent's when fine-tuning) and after every epoch; as
    ``fit.keep`` says, the network ends with the weights of the epoch of least validation loss, the
    starting ones unless an epoch beats them (``"best"``), or the last epoch's unless the starting
    ones are better (``"last-or-start"``). ``selection`` (a dict) receives what was kept. ``meter``
    is told of every epoch, as ``label``.

    The feed-forward networks (``idnn``, ``mlp``) take their gradients from :class:`_FeedForwardSteps`,
    which computes what autograd computes, in the same operations, without its bookkeeping (a
    step of these small networks is mostly overhead: about 4 x faster); the recurrent ones from autograd."""
    import torch

    lr, epochs, batch, seed = fit.lr, fit.epochs, fit.batch, fit.seed
    noise_col, noise_sd, decay_tail = fit.noise_col, fit.noise_sd, fit.decay_tail

    gen = torch.Generator().manual_seed(seed)  # on the CPU: the same draws on any device
    device = torch.device(fit.device)
    net.to(device)
    xt, yt = torch.from_numpy(x.astype(np.float32)).to(device), torch.from_numpy(y.astype(np.float32)).to(device)
    steps_per_epoch = (len(xt) + batch - 1) // batch
    total_steps = epochs * steps_per_epoch
    tail_steps = decay_tail * total_steps
    if fit.schedule == "cosine":
        def lr_factor(step: int) -> float:
            return 0.5 * (1.0 + math.cos(math.pi * min(step, total_steps) / total_steps))
    else:
        def lr_factor(step: int) -> float:
            return 1.0 if tail_steps <= 0 else min(1.0, max(0.0, (total_steps - step) / tail_steps))
    trained = [p for name, p in net.named_parameters() if fit.layers == "all" or in_first_layer(name)]
    steps: _FeedForwardSteps | _AutogradSteps = (_FeedForwardSteps(net, trained, fit.anchor)
                                                 if _FeedForwardSteps.fits(net)
                                                 else _AutogradSteps(net, trained, fit.anchor, lr, lr_factor))
    loss_fn = torch.nn.L1Loss()
    history = []
    val_history: list[float] = []
    best_state = None
    if validation is not None and (callable(validation) or len(validation[1])):
        if not callable(validation):
            xv = torch.from_numpy(validation[0].astype(np.float32)).to(device)
            yv = torch.from_numpy(validation[1].astype(np.float32)).to(device)

        def val_loss() -> float:
            net.eval()
            with torch.no_grad():
                value = float(validation()) if callable(validation) else float(loss_fn(net(xv), yv))
            net.train()
            return value

        val_history.append(val_loss())
        if fit.keep != "last":
            best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
    net.train()
    step = 0
    try:
        for epoch in range(epochs):
            epoch_start_s = time.monotonic()
            order = torch.randperm(len(xt), generator=gen)
            losses = torch.empty(steps_per_epoch, device=device)  # read once an epoch: no wait on a GPU every step
            sizes = []
            for i in range(0, len(xt), batch):
                sel = order[i : i + batch].to(device)
                xb = xt[sel]  # a copy: the noise below leaves xt as it is
                if noise_col is not None and noise_sd > 0:
                    xb[:, noise_col] += (torch.randn(len(sel), generator=gen) * noise_sd).to(device)
                losses[len(sizes)] = steps.step(xb, yt[sel], lr * lr_factor(step))
                sizes.append(len(sel))
                step += 1
            total = 0.0
            for value, size in zip(losses.tolist(), sizes):
                total += value * size
            history.append(total / len(xt))
            if val_history:
                val_history.append(val_loss())
                if fit.keep == "best" and val_history[-1] < min(val_history[:-1]):
                    best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
            if meter is not None:
                meter.epoch(label, epoch + 1, epochs, history[-1], val_history[-1] if val_history else None,
                            steps_per_epoch, time.monotonic() - epoch_start_s)
    finally:
        steps.close()
    kept = epochs
    if best_state is not None:
        # argmin: the first of equal losses, the start's on a tie
        kept = (int(np.argmin(val_history))
                if fit.keep == "best" else (0 if val_history[0] <= val_history[-1] else epochs))
        if kept != epochs:
            net.load_state_dict(best_state)
    net.to("cpu")
    net.eval()
    if selection is not None and val_history:
        selection.update({"validation_loss_start": val_history[0], "validation_loss_last": val_history[-1],
                          "validation_loss_kept": val_history[kept],
                          "validation_loss_best_trained": min(val_history[1:]) if len(val_history) > 1 else None,
                          "best_epoch": int(np.argmin(val_history)), "kept_epoch": kept, "epochs": epochs,
                          "keep": fit.keep})
    return history


class _AutogradSteps:
    """Optimiser steps of any network: autograd's gradients, torch's Adamax, the learning rate set
    each step; the loss adds ``anchor`` x the mean squared distance of the weights from the
    starting ones (L2-SP)."""

    def __init__(self, net, trained: list, anchor: float, lr: float, lr_factor: Callable[[int], float]) -> None:
        import torch

        self.net, self.anchor = net, anchor
        self.opt = torch.optim.Adamax(trained, lr=lr)
        self.schedule = torch.optim.lr_scheduler.LambdaLR(self.opt, lr_factor)
        self.start = [p.detach().clone() for p in net.parameters()] if anchor > 0 else []
        self.n_params = sum(p.numel() for p in self.start)
        self.loss_fn = torch.nn.L1Loss()

    def step(self, xb, yb, lr: float):
        """One step on the batch (the learning rate is the schedule's, ``lr`` says the same); returns its L1 loss."""
        self.opt.zero_grad()
        loss = self.loss_fn(self.net(xb), yb)
        objective = loss
        if self.start:
            objective = loss + self.anchor * sum(((p - p0) ** 2).sum()
                                                 for p, p0 in zip(self.net.parameters(), self.start)) / self.n_params
        objective.backward()
        self.opt.step()
        self.schedule.step()
        return loss.detach()

    def close(self) -> None:
        pass


class _FeedForwardSteps:
    """Optimiser steps of :func:`~ionav_viz.learning.idnn.build_net`'s feed-forward networks, their
    gradients written out: the same operations as autograd's backward pass through the
    network (linear, ReLU, dropout, linear, ReLU, dropout, linear, plus the skip term), the L1 loss
    and the L2-SP pull (``anchor``), and the same Adamax update as ``torch.optim.Adamax``, on one
    flat vector of the weights (the network's parameters are views into it while it trains).
    Dropout draws its masks from torch's global generator, as ``nn.Dropout`` does, in the same order."""

    BETA1, BETA2, EPS = 0.9, 0.999, 1e-8

    @staticmethod
    def fits(net) -> bool:
        return hasattr(net, "trunk_input") and hasattr(net, "body")

    def __init__(self, net, trained: list, anchor: float) -> None:
        import torch

        self.net, self.anchor = net, anchor
        params = list(net.parameters())
        self.params = params
        self.flat = torch.cat([p.detach().reshape(-1) for p in params])
        self.grad = torch.zeros_like(self.flat)
        views, grads, offset = [], [], 0
        for p in params:
            views.append(self.flat[offset : offset + p.numel()].view_as(p))
            grads.append(self.grad[offset : offset + p.numel()].view_as(p))
            offset += p.numel()
        for p, v in zip(params, views):
            p.data = v  # the network reads the weights being trained (validation, a kept epoch's copy)
        self.w1, self.b1, self.w2, self.b2, self.w3, self.b3 = views
        self.gw1, self.gb1, self.gw2, self.gb2, self.gw3, self.gb3 = grads
        # the trained weights are a prefix of the flat vector: every layer, or the first layer's two tensors
        ids = {id(p) for p in trained}
        n_trained = 0
        for p in params:
            if id(p) not in ids:
                break
            n_trained += p.numel()
        if sum(p.numel() for p in trained) != n_trained:
            raise ValueError("the trained parameters must lead the network's")
        self.n_trained = n_trained
        self.start = self.flat.clone() if anchor > 0 else None
        if anchor > 0:  # as autograd scales the pull: (1 / n_params) * anchor, in float32
            self.pull = (torch.ones((), device=self.flat.device) / self.flat.numel()) * anchor
        self.exp_avg = torch.zeros(n_trained, device=self.flat.device)
        self.exp_inf = torch.zeros(n_trained, device=self.flat.device)
        self.n_steps = 0
        self.p = float(net.dropout)

    def _mask(self, like):
        import torch

        if self.p <= 0:
            return None
        return torch.empty_like(like).bernoulli_(1 - self.p).div_(1 - self.p)

    def step(self, xb, yb, lr: float):
        import torch

        net = self.net
        skip = net.skip_term(xb)
        x = net.trunk_input(xb)
        z1 = torch.addmm(self.b1, x, self.w1.t())
        a1 = torch.relu(z1)
        m1 = self._mask(a1)
        d1 = a1 * m1 if m1 is not None else a1
        z2 = torch.addmm(self.b2, d1, self.w2.t())
        a2 = torch.relu(z2)
        m2 = self._mask(a2)
        d2 = a2 * m2 if m2 is not None else a2
        out = skip + torch.addmm(self.b3, d2, self.w3.t()).squeeze(-1)
        diff = out - yb
        loss = diff.abs().mean()
        # backward: mean, abs, the last layer, dropout, ReLU, ... as autograd's formulas
        g = (torch.full_like(diff, 1.0) / diff.numel() * diff.sgn()).unsqueeze(-1)
        torch.mm(g.t(), d2, out=self.gw3)
        torch.sum(g, 0, out=self.gb3)
        g = g.mm(self.w3)
        if m2 is not None:
            g = g * m2
        g = torch.ops.aten.threshold_backward(g, a2, 0)
        torch.mm(g.t(), d1, out=self.gw2)
        torch.sum(g, 0, out=self.gb2)
        g = g.mm(self.w2)
        if m1 is not None:
            g = g * m1
        g = torch.ops.aten.threshold_backward(g, a1, 0)
        torch.mm(g.t(), x, out=self.gw1)
        torch.sum(g, 0, out=self.gb1)
        n = self.n_trained
        grad, param = self.grad[:n], self.flat[:n]
        if self.start is not None:
            grad.add_(self.pull * (2.0 * (param - self.start[:n])))
        # Adamax, as torch.optim.Adamax's single-tensor update
        self.n_steps += 1
        self.exp_avg.lerp_(grad, 1 - self.BETA1)
        torch.maximum(self.exp_inf.mul_(self.BETA2), grad.abs().add_(self.EPS), out=self.exp_inf)
        bias_correction = 1 - self.BETA1 ** float(np.float32(self.n_steps))
        param.addcdiv_(self.exp_avg, self.exp_inf, value=-(lr / bias_correction))
        return loss.detach()

    def close(self) -> None:
        """Give each parameter its own storage again (as a network's are when saved)."""
        for p in self.params:
            p.data = p.data.clone()


def in_first_layer(name: str) -> bool:
    """Whether the parameter ``name`` of a :func:`build_net` network is its first layer's (the
    feed-forward nets' first linear layer, the recurrent nets' first cell)."""
    return name.startswith("body.0.") or (name.startswith("rnn.") and name.endswith("_l0"))


def displacement_inputs(norm: Normalisation, s: TrainingSet) -> np.ndarray:
    """The displacement network's normalised inputs for the examples ``s``: each window's
    acceleration history, then the previous window's GNSS displacement (the feedback input)."""
    return np.concatenate([norm.accel.scale(s.accel_mps2), norm.disp.scale(s.prev_disp_m)[:, None]], axis=1)


def train_models(
    drives: list[tuple[Drive, SensorBias]],
    config: ModelConfig,
    progress: Progress | None = None,
    description: str = "",
    parent: IdnnModel | None = None,
    device: str = "cpu",
    on_epoch: Callable[[EpochStatus], None] | None = None,
) -> IdnnModel:
    """Train both networks on ``drives`` with ``config``; returns the model with its metadata.

    ``parent``: fine-tune that model: its weights are the start, its input normalisation and
    architecture are kept (``config`` gives the learning rates, epochs and schedule: see
    :func:`fine_tune_config`). ``device``: where torch trains (``"cuda"`` when it sees a GPU;
    deterministic for a seed on the CPU only). ``progress(label, epoch, epochs)`` and
    ``on_epoch(status)`` (:class:`EpochStatus`: losses, steps done and planned, time) are called
    after every epoch of every fit.

    On the CPU torch works with one thread within the call (restored after): these networks are
    small, and a second thread only waits on the first (on a busy 2-core machine a step took 16 x
    as long with two); the weights are the same either way."""
    meter = TrainingMeter(progress, on_epoch) if progress is not None or on_epoch is not None else None
    with (_torch_scratch(), _seeded_deterministic_torch(config.seed, device == "cpu"),
          _torch_threads(1 if device == "cpu" else None)):
        model = _train(drives, config, meter, description, parent, device)
    model.metadata["domain"] = training_domain(drives, parent).to_dict()
    return model


def training_domain(drives: list[tuple[Drive, SensorBias]], parent: IdnnModel | None = None) -> Domain:
    """The domain of a model trained on ``drives`` (:func:`~ionav_viz.learning.domain.domain_of`), joined
    with a fine-tuned model's ``parent``'s where it has one, said in its note."""
    parent_domain = parent.domain if parent is not None else None
    note = f"the inputs of its {len(drives)} training drive(s)"
    if parent is not None:
        note += (" and its parent's"
                 if parent_domain is not None else " (its parent has no domain record: its inputs are not in it)")
    return domain_of(drives, parent_domain, note)


@contextlib.contextmanager
def _torch_threads(n: int | None) -> Iterator[None]:
    """torch's intra-op threads set to ``n`` within the block (None: left as they are), restored after."""
    import torch

    before = torch.get_num_threads()
    if n is not None:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


#: Fine-tuning from a trained model (:func:`fine_tune_config`): the parent's learning rates divided by
#: this, a cosine decay to zero, these epochs and this batch size.
FINE_TUNE_LR_DIVISOR = 2.0
FINE_TUNE_EPOCHS = 100
FINE_TUNE_BATCH = 64
#: Fine-tuning's validation: the last this fraction of each drive (by time), the weights of the best epoch on it kept.
FINE_TUNE_VALIDATION_TAIL = 0.2
FINE_TUNE_KEEP = "last-or-start"
FINE_TUNE_ANCHOR = 10.0
FINE_TUNE_VALIDATION_OUTAGE_S = 5
#: Fine-tuning's decision, then fit: the tail decides (1 block), the kept networks refitted on every window.
FINE_TUNE_VALIDATION_FOLDS = 1
#: What fine-tuning trains: every layer, and where validation keeps the parent's weights from that, the first
#: layer alone.
FINE_TUNE_LAYERS = "all,first"


def fine_tune_config(parent: ModelConfig, epochs_disp: int | None = None, epochs_yaw: int | None = None,
                     seed: int | None = None) -> ModelConfig:
    """The settings for fine-tuning ``parent`` on a few minutes of one vehicle's drives: the
    parent's architecture, input steps and inputs (its weights and normalisation must fit); learning
    rates the parent's / :data:`FINE_TUNE_LR_DIVISOR` with a cosine decay to zero; batches of
    :data:`FINE_TUNE_BATCH` for ``epochs_disp`` / ``epochs_yaw`` (default :data:`FINE_TUNE_EPOCHS`);
    an L2 pull to the parent's weights (:data:`FINE_TUNE_ANCHOR`); the last
    :data:`FINE_TUNE_VALIDATION_TAIL` of each drive held out to decide, per network, between the
    parent and the fine-tuned weights (every layer, then the first layer alone), the winner refitted
    on all of each drive. The share of the INS DR's displacement blended in (``ins_blend``) is chosen
    apart, on the training span (:data:`FINE_TUNE_INS_BLENDS`). ``seed``: default the parent's. Why each
    choice, and what was tried and not taken: docs/fine-tuning.md."""
    import dataclasses

    return dataclasses.replace(parent, lr_disp=parent.lr_disp / FINE_TUNE_LR_DIVISOR,
                               lr_yaw=parent.lr_yaw / FINE_TUNE_LR_DIVISOR, epochs_disp=epochs_disp or FINE_TUNE_EPOCHS,
                               epochs_yaw=epochs_yaw or FINE_TUNE_EPOCHS, batch_size=FINE_TUNE_BATCH,
                               lr_schedule="cosine", seed=parent.seed if seed is None else seed,
                               validation_tail=FINE_TUNE_VALIDATION_TAIL, keep=FINE_TUNE_KEEP, anchor=FINE_TUNE_ANCHOR,
                               validation_outage_s=FINE_TUNE_VALIDATION_OUTAGE_S,
                               validation_folds=FINE_TUNE_VALIDATION_FOLDS, tune_layers=FINE_TUNE_LAYERS)


@contextlib.contextmanager
def _seeded_deterministic_torch(seed: int, deterministic: bool = True) -> Iterator[None]:
    """torch's global random generator seeded with ``seed`` and (``deterministic``: on the CPU) its
    deterministic algorithms on, within the block only: the caller's generator state and determinism
    setting are restored after. On a GPU they stay as they were: cuBLAS refuses to run under them
    unless the process set ``CUBLAS_WORKSPACE_CONFIG`` before it started."""
    import torch

    # the debug mode is the same switch as use_deterministic_algorithms, without its import of torch's compiler (~2 s)
    mode = torch.get_deterministic_debug_mode()
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        if deterministic:
            torch.set_deterministic_debug_mode("error")
        try:
            yield
        finally:
            torch.set_deterministic_debug_mode(mode)


@contextlib.contextmanager
def _torch_scratch() -> Iterator[None]:
    """torch makes a cache folder (``torchinductor_<user>``) in the temporary directory as training
    starts and never removes it: it goes into a private folder instead, removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="ionav-torch-") as scratch:
        before, tempfile.tempdir = tempfile.tempdir, scratch
        try:
            yield
        finally:
            tempfile.tempdir = before


def fit_steps(config: ModelConfig, n_examples: int) -> int:
    """Optimiser steps of training both networks on ``n_examples`` examples with ``config``."""
    per_epoch = -(-n_examples // config.batch_size)
    return (config.epochs_disp + config.epochs_yaw) * per_epoch


def _train(drives: list[tuple[Drive, SensorBias]], config: ModelConfig, meter: TrainingMeter | _ScopedMeter | None,
           description: str, parent: IdnnModel | None = None, device: str = "cpu",
           hold_out: bool | tuple[float, float] = True, uncertainty: bool = True, data: TrainingSet | None = None,
           planned: bool = False) -> IdnnModel:
    """Train (or fine-tune from ``parent``) both networks; ``hold_out=False``: on every window,
    ``(lo, hi)``: on every window outside that block of each drive (:meth:`TrainingSet.block_split`),
    either with no validation data (``config.keep`` must be ``"last"``); ``uncertainty=False``: fit none.
    ``data``: the drives' :func:`training_examples` when the caller has them already; ``planned``:
    the ``meter`` was told of this call's steps already."""
    import torch

    config.validate()
    if parent is not None and hold_out is True and config.validation_folds > 0:
        return _fine_tune_cross_validated(drives, config, meter, description, parent, device)
    inputs = input_record([d for d, _ in drives])  # one IMU kind and rate
    if parent is not None:
        _check_fits_parent(config, parent)
        for drive, _ in drives:
            check_inputs(parent.metadata, drive, f"the parent model {parent.directory}")
    if data is None:
        data = training_examples(drives, config.n_steps_disp, config.n_steps_yaw, inputs=config.inputs,
                                 seed=config.seed)
    if hold_out is not True:
        train = data.subset(data.block_split(*hold_out)[0]) if hold_out else data
        val = data.subset(np.zeros(len(data), dtype=bool))
    elif config.validation_tail > 0:
        train_mask, val_mask = data.time_split(config.validation_tail)
        train, val = data.subset(train_mask), data.subset(val_mask)
        if not len(train) or not len(val):
            raise InputError(f"no {'training' if not len(train) else 'validation'} windows when the last "
                             f"{config.validation_tail:.0%} of each drive is held out for validation",
                             "give longer drives or spans")
    else:
        rng = np.random.default_rng(config.seed)
        val_mask = rng.random(len(data)) < 0.1
        train, val = data.subset(~val_mask), data.subset(val_mask)
    # Feedback input and output share one scaling, and so do gyro input and yaw-rate output
    # (same units), which the residual skip terms need. A fine-tuned model keeps its parent's.
    rate_scale = MinMax.fit(np.concatenate([train.gyro_radps.ravel(), train.yaw_rate_radps]))
    norm = parent.norm if parent is not None else Normalisation(
        accel=MinMax.fit(train.accel_mps2),
        disp=MinMax.fit(np.concatenate([train.disp_m, train.prev_disp_m])),
        gyro=rate_scale,
        yaw=rate_scale,
    )

    disp_net = build_net(config.arch, config.n_steps_disp, config.hidden, config.dropout, True,
                         norm.skip_terms(True) if config.residual else None)
    yaw_net = build_net(config.arch, config.n_steps_yaw, config.hidden, config.dropout, False,
                        norm.skip_terms(False) if config.residual else None)
    if parent is not None:
        disp_net.load_state_dict(parent.disp_net.state_dict())
        yaw_net.load_state_dict(parent.yaw_net.state_dict())
    noise_sd = config.feedback_noise_m / (norm.disp.hi - norm.disp.lo)  # metres -> normalised units
    # Only the first try runs here: the retries of "all,first" (the first layer alone where validation keeps the parent
    # from every layer) are made by _fine_tune_cross_validated, so without validation_folds they are skipped, unsaid.
    layers = config.tune_layers.split(",")[0] if parent is not None else "all"
    disp_fit = FitSettings(config.lr_disp, config.epochs_disp, config.batch_size, config.seed, config.n_steps_disp,
                           noise_sd, config.lr_decay_tail, config.lr_schedule, device, config.keep, config.anchor,
                           layers)
    selection: dict[str, dict[str, Any]] = {"displacement": {}, "yaw_rate": {}}
    disp_val: Any = (displacement_inputs(norm, val), norm.disp.scale(val.disp_m)) if config.keep != "last" else None
    if disp_val is not None and config.validation_outage_s > 0 and config.validation_tail > 0 and device == "cpu":
        score = outage_validation(drives, config, config.validation_tail, config.validation_outage_s)
        if score is not None:
            disp_val = lambda: score(IdnnModel(config, norm, disp_net, yaw_net))  # noqa: E731
    if meter is not None and not planned:
        meter.plan(fit_steps(config, len(train)))
    disp_loss = fit_network(disp_net, displacement_inputs(norm, train), norm.disp.scale(train.disp_m), disp_fit, meter,
                            "displacement", disp_val, selection["displacement"])
    if callable(disp_val):
        selection["displacement"]["validation"] = (f"displacement CRSE (m, mean) of {config.validation_outage_s} s "
                                                   "outages starting every 0.1 s in the tail, the network's own "
                                                   "displacement fed back")
    yaw_fit = FitSettings(config.lr_yaw, config.epochs_yaw, config.batch_size, config.seed + 1, None, 0.0,
                          config.lr_decay_tail, config.lr_schedule, device, config.keep, config.anchor, layers)
    yaw_loss = fit_network(yaw_net, norm.gyro.scale(train.gyro_radps), norm.yaw.scale(train.yaw_rate_radps), yaw_fit,
                           meter, "orientation rate",
                           (norm.gyro.scale(val.gyro_radps), norm.yaw.scale(val.yaw_rate_radps))
                           if config.keep != "last" else None,
                           selection["yaw_rate"])

    model = IdnnModel(config, norm, disp_net, yaw_net)
    with torch.no_grad():
        val_disp = norm.disp.unscale(model._run(disp_net, displacement_inputs(norm, val))) if len(val) else np.zeros(0)
        val_yaw = model.predict_yaw_rate(val.gyro_radps) if len(val) else np.zeros(0)
    model.metadata = {
        "training": {
            "description": description,
            "drives": [{**drive_record(d), "bias_accel_mps2": b.accel_mps2, "bias_gyro_radps": b.gyro_radps}
                       for d, b in drives],
            "n_examples": len(train),
            "n_validation": len(val),
            "final_loss_normalised": {"displacement": disp_loss[-1], "yaw_rate": yaw_loss[-1]},
        },
        "validation": {
            "disp_mae_m": float(np.mean(np.abs(val_disp - val.disp_m))) if len(val) else None,
            "yaw_rate_mae_radps": float(np.mean(np.abs(val_yaw - val.yaw_rate_radps))) if len(val) else None,
            "note": "one-window predictions on " + (f"the last {config.validation_tail:.0%} of each drive (by time)"
                                                    if config.validation_tail > 0 else "a seeded 10 % hold-out")
                    + ", previous displacement from GNSS",
        },
        "trainable_parameters": {"displacement": count_parameters(disp_net), "yaw_rate": count_parameters(yaw_net)},
        "versions": _versions(),
        "hyperparameters": asdict(config),
        "input": inputs,
    }
    if parent is not None:
        model.metadata["parent"] = parent_record(parent)
    if config.keep != "last":
        model.metadata["epoch_selection"] = _selection_record(selection, parent is not None, config.validation_tail)
    if uncertainty:
        add_uncertainty(model, drives, parent)
    return model


#: Cross-validated fine-tuning (:func:`_fine_tune_cross_validated`) scores outages placed from this
#: far into each drive on, as ``evaluate`` places them after its default warm-up (GNSS time before
#: the first outage, during which the filter's calibration settles).
CROSS_VALIDATION_WARM_UP_S = 30.0


def _fine_tune_cross_validated(drives: list[tuple[Drive, SensorBias]], config: ModelConfig,
                               meter: TrainingMeter | _ScopedMeter | None, description: str, parent: IdnnModel,
                               device: str) -> IdnnModel:
    """Fine-tune ``parent`` on every window of ``drives``, keeping each network's fine-tuned weights
    only when fine-tuning beats the parent on data it did not see (``config.validation_folds``).

    With ``k = 1`` the one block left out is the last ``config.validation_tail`` of each drive (by
    time): the tail decides, as it does without ``validation_folds``, but the model kept is then
    fine-tuned on every window, the tail too. With ``k > 1`` each drive is cut by time into ``k``
    blocks (blocked cross-validation: neighbouring windows are nearly the same example, so the data
    left out must be a stretch of time, never shuffled windows). For each block in turn the parent
    is fine-tuned on every window outside that block of every drive (a window across its edges is in
    neither), with the final settings, and it and the parent are scored inside the block: the
    displacement network by the displacement CRSE of ``config.validation_outage_s`` s outages
    starting every 0.1 s from :data:`CROSS_VALIDATION_WARM_UP_S` into the drive (its own output fed
    back, as the estimator runs it), the orientation-rate network by its one-window L1 loss. Pooled
    over the blocks, the scores say whether fine-tuning on this car's data generalises to time it
    did not see; the final fit on every window is then kept for each network that did.

    ``config.tune_layers`` lists what is fine-tuned, in turn: ``"all,first"`` fine-tunes every layer,
    and a network whose fine-tuning that did not beat the parent is tried again with its first layer
    alone trained (the rest the parent's), decided the same way (each try from the same seed); a
    network no try beats keeps the parent's weights (said in one line and in the metadata's
    ``epoch_selection``, with the layers each network kept).

    First of all, the share of the INS DR's displacement the model takes (``ins_blend``) is chosen
    on the parent (:func:`choose_ins_blend`, recorded as ``epoch_selection["ins_blend"]``); the
    parent and every fine-tuned network are then scored, and the model kept, with that blend."""
    import dataclasses
    import logging

    import torch

    blend, blend_record = choose_ins_blend(drives, config, parent)
    config = dataclasses.replace(config, ins_blend=blend)
    parent = dataclasses.replace(parent, config=dataclasses.replace(parent.config, ins_blend=blend))
    if blend != blend_record["parent"]:
        logging.getLogger("ionav_viz").info("fine-tuning: the displacement takes %.0f %% of the INS DR's (%s)",
                                            100 * blend, blend_record["validation"])
    k = config.validation_folds
    where = (f"each of {k} blocks of each drive (by time) left out in turn"
             if k > 1 else f"the last {config.validation_tail:.0%} of each drive (by time) left out")
    what = (f"{where}: the displacement CRSE (m, mean) of {config.validation_outage_s} s "
            f"outages in it starting every 0.1 s from {CROSS_VALIDATION_WARM_UP_S:g} s into the drive, the network's "
            "own displacement fed back, and the orientation rate's one-window L1 loss (normalised), of the parent and "
            "of the parent fine-tuned outside the block")
    selection: dict[str, Any] = {"validation": what, "folds": [], "ins_blend": blend_record}
    nets = {"displacement": ("disp_net", parent.disp_net), "yaw_rate": ("yaw_net", parent.yaw_net)}
    undecided = list(nets)
    tried: dict[str, list[dict[str, Any]]] = {name: [] for name in nets}
    model: IdnnModel | None = None
    stages = config.tune_layers.split(",")
    # the same windows and validation outages for every try (each try's are the same draws of the same seed)
    data = training_examples(drives, config.n_steps_disp, config.n_steps_yaw, inputs=config.inputs, seed=config.seed)
    cases: dict[tuple[float, float], list[tuple]] = {}
    for layers in stages:
        torch.manual_seed(config.seed)  # each try as if it were the only one
        stage = dataclasses.replace(config, tune_layers=layers)
        stage_meter = meter if meter is None or len(stages) == 1 else meter.within(f" ({layers} layers)")
        final, folds, scores, n_validation = _validated_fine_tune(drives, stage, stage_meter, description, parent,
                                                                  device, where, data, cases)
        selection["folds"] += [{**f, "layers": layers} if len(stages) > 1 else f for f in folds]
        if model is None:
            model = final
        for name in list(undecided):
            tried[name].append({"layers": layers, "validation_loss_fine_tuned": scores[name]["fine-tuned"]})
            selection[name] = {"validation_loss_parent": scores[name]["parent"],
                               "validation_loss_fine_tuned": scores[name]["fine-tuned"],
                               "n_validation": n_validation[name], "layers": None, "kept": "parent"}
            if scores[name]["fine-tuned"] < scores[name]["parent"]:
                attr = nets[name][0]
                setattr(model, attr, getattr(final, attr))
                selection[name].update(layers=layers, kept="fine-tuned on every window" if layers == "all"
                                       else f"{layers} layer fine-tuned on every window")
                undecided.remove(name)
        if not undecided:
            break
    assert model is not None
    for name in nets:
        if len(stages) > 1:
            selection[name]["tried"] = tried[name]
    for name in undecided:
        attr, parent_net = nets[name]
        with torch.no_grad():
            getattr(model, attr).load_state_dict(parent_net.state_dict())
        losses = ", ".join(f"fine-tuned{'' if t['layers'] == 'all' else ' (' + t['layers'] + ' layer)'} "
                           f"{t['validation_loss_fine_tuned']:.4g}"
                           for t in tried[name])
        line = (f"fine-tuning did not beat the parent on time it did not see ({where}): the "
                f"{name.replace('_', '-')} network keeps the parent's weights (validation loss: parent "
                f"{selection[name]['validation_loss_parent']:.4g}, {losses})")
        selection[name]["note"] = line
        logging.getLogger("ionav_viz").warning("%s", line)
    model.config = config
    model.metadata["hyperparameters"] = asdict(config)
    model.metadata["epoch_selection"] = selection
    add_uncertainty(model, drives, parent)
    return model


def _validated_fine_tune(drives: list[tuple[Drive, SensorBias]], config: ModelConfig,
                         meter: TrainingMeter | _ScopedMeter | None, description: str, parent: IdnnModel, device: str,
                         where: str, data: TrainingSet, cases_of: dict[tuple[float, float], list[tuple]]
                         ) -> tuple[IdnnModel, list[dict[str, Any]], dict[str, dict[str, float]], dict[str, int]]:
    """One try of :func:`_fine_tune_cross_validated`: the parent fine-tuned (the layers
    ``config.tune_layers`` says) on every window, the fold records, and each network's pooled scores
    (``"parent"``, ``"fine-tuned"``) and number of validation values. ``data``: the drives'
    :func:`training_examples`; ``cases_of``: the validation outages of each block left out, kept
    across tries (filled here)."""
    import dataclasses

    k = config.validation_folds
    inner = dataclasses.replace(config, validation_folds=0, validation_tail=0.0, keep="last")
    norm = parent.norm
    pooled: dict[str, dict[str, list[np.ndarray]]] = {name: {"parent": [], "fine-tuned": []}
                                                      for name in ("displacement", "yaw_rate")}
    one_window: dict[str, list[np.ndarray]] = {"disp_m": [], "yaw_rate_radps": []}
    folds = []
    blocks = [(fold / k, (fold + 1) / k) for fold in range(k)] if k > 1 else [(1.0 - config.validation_tail, 1.0)]
    for block in blocks:
        if block not in cases_of:
            cases_of[block] = outage_cases(drives, config, config.validation_outage_s,
                                           warm_up_s=CROSS_VALIDATION_WARM_UP_S, block=block)
    used = [(fold, block) for fold, block in enumerate(blocks) if cases_of[block] or data.block_split(*block)[1].any()]
    if meter is not None:  # every fit of this try, before the first: the time left is the try's
        meter.plan(sum(fit_steps(inner, int(data.block_split(*block)[0].sum())) for _, block in used)
                   + fit_steps(inner, len(data)))
    for fold, block in used:
        cases = cases_of[block]
        ex = data.subset(data.block_split(*block)[1])
        fold_meter = None if meter is None else meter.within(f" (block {fold + 1}/{len(blocks)} left out)")
        model = _train(drives, inner, fold_meter, description, parent, device, hold_out=block, uncertainty=False,
                       data=data, planned=True)
        record: dict[str, Any] = {"left_out": [round(block[0], 4), round(block[1], 4)],
                                  "n_outages": sum(len(c[1]) for c in cases), "n_windows": len(ex)}
        yaw_radps = {who: m.predict_yaw_rate(ex.gyro_radps) for who, m in (("parent", parent), ("fine-tuned", model))}
        for who, m in (("parent", parent), ("fine-tuned", model)):
            disp_err = _outage_errors(m, cases)
            yaw_err = np.abs(norm.yaw.scale(yaw_radps[who]) - norm.yaw.scale(ex.yaw_rate_radps))
            pooled["displacement"][who].append(disp_err)
            pooled["yaw_rate"][who].append(yaw_err)
            record[who] = {"displacement": float(np.mean(disp_err)) if len(disp_err) else None,
                           "yaw_rate": float(np.mean(yaw_err)) if len(yaw_err) else None}
        one_window["disp_m"].append(np.abs(norm.disp.unscale(model._run(model.disp_net, displacement_inputs(norm, ex)))
                                           - ex.disp_m))
        one_window["yaw_rate_radps"].append(np.abs(yaw_radps["fine-tuned"] - ex.yaw_rate_radps))
        folds.append(record)
    final_meter = None if meter is None else meter.within(" (every window)")
    model = _train(drives, inner, final_meter, description, parent, device, hold_out=False, uncertainty=False,
                   data=data, planned=True)
    held = {key: np.concatenate(v) if v else np.zeros(0) for key, v in one_window.items()}
    model.metadata["validation"] = {
        "disp_mae_m": float(np.mean(held["disp_m"])) if len(held["disp_m"]) else None,
        "yaw_rate_mae_radps": float(np.mean(held["yaw_rate_radps"])) if len(held["yaw_rate_radps"]) else None,
        "note": f"one-window predictions with {where}, by the model fine-tuned on the rest, previous "
                "displacement from GNSS; the final model trained on every window",
    }
    scores, n_validation = {}, {}
    for name, by_who in pooled.items():
        errors = {who: np.concatenate(v) if v else np.zeros(0) for who, v in by_who.items()}
        scores[name] = {who: float(np.mean(e)) if len(e) else math.inf for who, e in errors.items()}
        n_validation[name] = int(len(errors["parent"]))
    return model, folds, scores, n_validation


def outage_validation(drives: list[tuple[Drive, SensorBias]], config: ModelConfig, tail: float,
                      n: int) -> Callable[[IdnnModel], float] | None:
    """A score of a model on ``n``-window outages lying (with the window before each) in the last
    ``tail`` of each drive, at ten grid phases: the mean displacement CRSE (m), run as the estimator
    runs them (its own displacement fed back, calibrated at the start, standing windows). None when
    no such outage fits."""
    cases = outage_cases(drives, config, n, block=(1.0 - tail, 1.0))
    if not cases:
        return None

    def score(model: IdnnModel) -> float:
        return float(np.mean(_outage_errors(model, cases)))

    return score


def outage_cases(drives: list[tuple[Drive, SensorBias]], config: ModelConfig, n: int, warm_up_s: float = 0.0,
                  block: tuple[float, float] = (0.0, 1.0)) -> list[tuple]:
    """The ``n``-window outages :func:`outage_validation` runs: at ten grid phases, each with the
    window before it not before ``warm_up_s`` into its drive, and all of it (that window too) in the
    ``block`` (fractions of the drive by time; the last ``tail`` of each drive: ``(1 - tail, 1)``)."""
    return outage_cases_by_block(drives, config, n, warm_up_s, [block])[0]


def outage_cases_by_block(drives: list[tuple[Drive, SensorBias]], config: ModelConfig, n: int, warm_up_s: float,
                          blocks: list[tuple[float, float]]) -> list[list[tuple]]:
    """:func:`outage_cases` of each of ``blocks``, the windows and the calibration worked out once."""
    from ..nav.protocol import EstimatorInputs
    from ..nav.windows import valid_start

    out: list[list[tuple]] = [[] for _ in blocks]
    for drive, bias in drives:
        t_first = float(drive.t_s[0])
        length = float(drive.t_s[-1]) - t_first + 1.0 / drive.rate_hz
        for phase in range(10):
            # the model runs on the truth's GNSS here
            w = make_windows(drive, offset_s=phase / 10.0).ignoring_receiver()
            ok = np.array([k for k in range(1, len(w) - n + 1)
                           if w.segment[k - 1] == w.segment[k] and valid_start(w, k, n)
                           and w.truth_ok[k - 1 : k + n].all()], dtype=int)
            cal = None
            for i, block in enumerate(blocks):
                cut = t_first + max(warm_up_s, block[0] * length)
                end = t_first + block[1] * length
                ends_in = (block[1] >= 1.0) | (w.t0_s[ok + n - 1] + WINDOW_S <= end + 1e-9)
                inside = (w.t0_s[ok - 1] >= cut - 1e-9) & ends_in
                starts = ok[inside] if len(ok) else ok
                if not len(starts):
                    continue
                inputs = EstimatorInputs(drive, w, starts, n, bias)
                if cal is None and config.inputs == "calibrated":
                    cal = calibration(drive, w, bias.accel_mps2, bias.gyro_radps)
                truth = w.gnss_disp_m[starts[:, None] + np.arange(n)[None, :]]
                out[i].append((w, starts, bias, cal, inputs.still, truth))
    return out


#: Fine-tuning's share of the INS DR's displacement in the model's (:func:`choose_ins_blend`): the
#: shares it may keep (at most 3/4: the network keeps a say), the time blocks of each drive they are
#: scored in (the last is the tail that decides between parent and fine-tuned networks,
#: :data:`FINE_TUNE_VALIDATION_TAIL`) and the outages they are scored on (s).
FINE_TUNE_INS_BLENDS = (0.0, 0.25, 0.5, 0.75)
FINE_TUNE_BLEND_BLOCKS = 5
FINE_TUNE_BLEND_OUTAGE_S = 10


def choose_ins_blend(drives: list[tuple[Drive, SensorBias]], config: ModelConfig, parent: IdnnModel,
                     blends: tuple[float, ...] = FINE_TUNE_INS_BLENDS, k: int = FINE_TUNE_BLEND_BLOCKS,
                     outage_s: int = FINE_TUNE_BLEND_OUTAGE_S) -> tuple[float, dict[str, Any]]:
    """The share of the INS DR's displacement (``ModelConfig.ins_blend``) ``parent`` is given on
    ``drives``, and the record of the choice.

    The parent's own share, each of ``blends`` and the INS DR alone (share 1) are scored on the
    drives' ``outage_s`` s outages starting every 0.1 s from :data:`CROSS_VALIDATION_WARM_UP_S`
    into each drive (the displacement CRSE, the network's own output fed back, as the estimator
    runs them), in ``k`` time blocks of each drive. The parent has never seen these drives, so
    every block is data it did not see. The parent's own share is kept unless the INS DR beats it
    on this car: over all the blocks and in the last one (the stretch nearest the outages the model
    will bridge). Then the share of least mean CRSE over all the blocks is kept, among those no
    worse than the parent's own in the last block. No outage fitting: the parent's own."""
    import dataclasses

    base = parent.config.ins_blend
    candidates = sorted({base, *blends, 1.0})
    blocks = [(i / k, (i + 1) / k) for i in range(k)]
    by_block = outage_cases_by_block(drives, config, outage_s, CROSS_VALIDATION_WARM_UP_S, blocks)
    record: dict[str, Any] = {
        "validation": (f"displacement CRSE (m, mean) of {outage_s} s outages starting every 0.1 s from "
                       f"{CROSS_VALIDATION_WARM_UP_S:g} s into each drive, in {k} time blocks of each drive, the "
                       "parent's network blended with the INS DR (1: the INS DR alone); the parent's share kept unless "
                       "the INS DR beats it over all blocks and in the last, then the share of least CRSE of those no "
                       "worse than the parent's in the last block"),
        "parent": base}
    errors: dict[float, list[np.ndarray]] = {b: [] for b in candidates}
    for cases in by_block:
        for b in candidates:
            blended = dataclasses.replace(parent, config=dataclasses.replace(parent.config, ins_blend=b))
            errors[b].append(_outage_errors(blended, cases))
    record["n_outages"] = [int(len(e)) for e in errors[base]]
    last = max((i for i, e in enumerate(errors[base]) if len(e)), default=None)
    if last is None:
        record.update(kept=base, note=f"no {outage_s} s validation outage fits: the parent's share is kept")
        return base, record
    pooled = {b: float(np.mean(np.concatenate(errors[b]))) for b in candidates}
    in_last = {b: float(np.mean(errors[b][last])) for b in candidates}
    record.update(mean_m={f"{b:g}": pooled[b] for b in candidates},
                  last_block_m={f"{b:g}": in_last[b] for b in candidates})
    choice = base
    if pooled[1.0] < pooled[base] and in_last[1.0] < in_last[base]:
        eligible = [b for b in {base, *blends} if in_last[b] <= in_last[base]]
        choice = min(eligible, key=lambda b: (pooled[b], abs(b - base)))
    record["kept"] = choice
    return choice, record


def _outage_errors(model: IdnnModel, cases: list[tuple]) -> np.ndarray:
    """Each case's outages' displacement CRSE (m), run as the estimator runs them."""
    if not cases:
        return np.zeros(0)
    n = cases[0][-1].shape[1]
    return np.concatenate([np.abs(model.predict(w, starts, n, bias, cal, still)[0] - truth).sum(axis=1)
                           for w, starts, bias, cal, still, truth in cases])


def _selection_record(selection: dict[str, dict[str, Any]], fine_tuned: bool, tail: float) -> dict[str, Any]:
    """The metadata's record of which epoch's weights each network kept (``keep``), and one
    line, logged, for each network that kept its parent's weights."""
    import logging

    where = f"the last {tail:.0%} of each drive" if tail > 0 else "a seeded 10 % of the windows"
    record: dict[str, Any] = {"validation": f"L1 loss (normalised) of one-window predictions on {where}, "
                                            "after every epoch"}
    for name, sel in selection.items():
        if not sel:
            continue
        kept_parent = fine_tuned and sel["kept_epoch"] == 0
        record[name] = {**sel, "kept": "parent" if kept_parent else f"epoch {sel['kept_epoch']} of {sel['epochs']}"}
        if kept_parent:
            trained = (sel["validation_loss_last"]
                       if sel["keep"] == "last-or-start" else sel["validation_loss_best_trained"])
            line = (f"fine-tuning did not beat the parent on validation ({where}): the {name.replace('_', '-')} "
                    "network keeps the parent's weights (validation loss: parent "
                    f"{sel['validation_loss_start']:.4g}, fine-tuned {trained:.4g})")
            record[name]["note"] = line
            logging.getLogger("ionav_viz").warning("%s", line)
    return record


#: Fewer outages than this cannot fit the uncertainty's seven parameters: the model gets none.
MIN_UNCERTAINTY_OUTAGES = 30


def add_uncertainty(model: IdnnModel, drives: list[tuple[Drive, SensorBias]],
                    parent: IdnnModel | None = None) -> IdnnModel:
    """Fit ``model``'s uncertainty on ``drives`` (:func:`fit_uncertainty`) and set it with its record in
    the metadata; drives too short for :data:`MIN_UNCERTAINTY_OUTAGES` outages leave the model
    without one (it then estimates no covariance), said in the metadata. The networks are unchanged.

    A fine-tuned model (``parent`` given) is fitted only on :data:`MIN_UNCERTAINTY_OUTAGES`
    independent outages (the overlapping ones' total time over one outage's length); on fewer it
    keeps its parent's uncertainty, said in the metadata's ``inherited``. A few minutes of one drive,
    cut into outages that overlap 19 times in 20, fit seven parameters to what amounts to three or
    four outages: too narrow on the rest of the drive. The parent's, fitted on its fleet, is the
    better prior; the estimator's check on each drive's GNSS widens it where the drive says so."""
    import logging

    outages = uncertainty_outages(drives)
    found = sum(len(starts) for *_, starts in outages)
    independent = found * UNCERTAINTY_STRIDE_WINDOWS / UNCERTAINTY_OUTAGE_WINDOWS
    if parent is not None and parent.uncertainty is not None and independent < MIN_UNCERTAINTY_OUTAGES:
        model.uncertainty = parent.uncertainty
        model.metadata.pop("uncertainty_skipped", None)
        model.metadata["uncertainty"] = {
            **{k: v for k, v in parent.metadata.get("uncertainty", {}).items() if k not in ("file", "sha256")},
            "inherited": (f"the parent's: the fine-tuning drives hold {found} overlapping outages of "
                          f"{UNCERTAINTY_OUTAGE_WINDOWS * WINDOW_S:g} s (one every "
                          f"{UNCERTAINTY_STRIDE_WINDOWS * WINDOW_S:g} s), about {independent:.1f} independent, "
                          f"fewer than {MIN_UNCERTAINTY_OUTAGES} to fit its own")}
        return model
    if found < MIN_UNCERTAINTY_OUTAGES:
        model.uncertainty = None
        model.metadata["uncertainty_skipped"] = (f"{found} overlapping outages of "
                                                 f"{UNCERTAINTY_OUTAGE_WINDOWS * WINDOW_S:g} s (one every "
                                                 f"{UNCERTAINTY_STRIDE_WINDOWS * WINDOW_S:g} s, after a "
                                                 f"{UNCERTAINTY_WARM_UP_S:g} s warm-up) in the training drives, fewer "
                                                 f"than {MIN_UNCERTAINTY_OUTAGES}: no uncertainty fitted")
        logging.getLogger("ionav_viz").warning("IDNN uncertainty not fitted: %s", model.metadata["uncertainty_skipped"])
        return model
    runs = _run_outages(model, outages, UNCERTAINTY_OUTAGE_WINDOWS)
    model.uncertainty, info = fit_uncertainty(model, drives, runs)
    model.metadata.pop("uncertainty_skipped", None)
    model.metadata["uncertainty"] = info
    return model


def parent_record(parent: IdnnModel) -> dict[str, Any]:
    """What a fine-tuned model keeps of its parent: where it was, its weights' checksums, and the
    drives it saw (so the leakage check also knows the parent's training data)."""
    from .idnn import is_shipped_model_dir

    training = parent.metadata.get("training", {})
    return {"directory": ("shipped" if parent.directory and is_shipped_model_dir(Path(parent.directory))
                          else parent.directory),
            "weights_sha256": parent.metadata.get("weights_sha256"), "description": training.get("description", ""),
            "drives": seen_drives(parent.metadata)}


def _check_fits_parent(config: ModelConfig, parent: IdnnModel) -> None:
    """A fine-tuning ``config`` keeps the parent's architecture, input steps and inputs (its weights must fit)."""
    for name in ("arch", "n_steps_disp", "n_steps_yaw", "hidden", "residual", "inputs"):
        if getattr(config, name) != getattr(parent.config, name):
            raise InputError(f"fine-tuning keeps the parent model's {name} ({getattr(parent.config, name)!r}), and "
                             f"{getattr(config, name)!r} was asked for",
                             "leave the architecture options out with --from-model", param=name)


def _versions() -> dict[str, Any]:
    from importlib.metadata import version  # not the package's __version__: nav imports nothing above it

    import numpy
    import torch

    return {"ionav_viz": version("ionav-viz"), "torch": torch.__version__, "numpy": numpy.__version__,
            "python": platform.python_version()}


#: The uncertainty's fit (:func:`fit_uncertainty`): outages of this many windows, one starting every
#: ``UNCERTAINTY_STRIDE_WINDOWS`` windows (overlapping), after the warm-up evaluations use.
UNCERTAINTY_OUTAGE_WINDOWS = 60
UNCERTAINTY_STRIDE_WINDOWS = 3
UNCERTAINTY_WARM_UP_S = 30.0


@dataclass
class OutageRuns:
    """Outages run as the estimator runs them: predicted displacement (m) and yaw rate (rad/s) per
    window (n, w), GNSS course (deg) and speed (m/s) at each start (n,), and the position error
    (estimate minus GNSS fix, east and north, m) at every boundary after the start (n, w, 2)."""

    disp_m: np.ndarray
    yaw_rate_radps: np.ndarray
    course0_deg: np.ndarray
    speed0_mps: np.ndarray
    error_en_m: np.ndarray
    _tracks: TrackCovariance | None = field(default=None, repr=False, compare=False)

    def __len__(self) -> int:
        return len(self.disp_m)

    def tracks(self) -> TrackCovariance:
        """The runs' :class:`~ionav_viz.nav.track.TrackCovariance` (worked out once)."""
        if self._tracks is None:
            self._tracks = TrackCovariance(self.course0_deg, self.disp_m, self.yaw_rate_radps)
        return self._tracks


def outage_runs(model: IdnnModel, drives: list[tuple[Drive, SensorBias]], n_windows: int = UNCERTAINTY_OUTAGE_WINDOWS,
                stride: int = UNCERTAINTY_STRIDE_WINDOWS) -> OutageRuns:
    """Run ``model`` on overlapping ``n_windows`` outages of ``drives`` exactly as
    :class:`~ionav_viz.learning.idnn.IdnnEstimator` runs them (calibration at the start, its own
    displacement fed back, standing windows), and measure the rebuilt track against the fixes."""
    return _run_outages(model, uncertainty_outages(drives, n_windows, stride), n_windows)


def uncertainty_outages(drives: list[tuple[Drive, SensorBias]], n_windows: int = UNCERTAINTY_OUTAGE_WINDOWS,
                        stride: int = UNCERTAINTY_STRIDE_WINDOWS) -> list[tuple[Drive, SensorBias, Any, np.ndarray]]:
    """Each drive's overlapping ``n_windows`` outages for the uncertainty's fit, one every ``stride``
    windows after :data:`UNCERTAINTY_WARM_UP_S`: ``(drive, bias, windows, starts)``, the drives with
    none left out. Counting them runs no model."""
    from ..nav.windows import valid_start

    found = []
    for drive, bias in drives:
        # the truth's GNSS, as training's
        windows = make_windows(drive).ignoring_receiver().after_warm_up(UNCERTAINTY_WARM_UP_S)
        starts = np.array([k for k in range(windows.first_start, len(windows) - n_windows + 1, stride)
                           if valid_start(windows, k, n_windows)], dtype=int)
        if len(starts):
            found.append((drive, bias, windows, starts))
    return found


def _run_outages(model: IdnnModel, outages: list[tuple[Drive, SensorBias, Any, np.ndarray]],
                 n_windows: int) -> OutageRuns:
    from ..core.geo import wgs84
    from ..nav.protocol import EstimatorInputs
    from ..nav.track import rebuild_track

    parts = []
    for drive, bias, windows, starts in outages:
        inputs = EstimatorInputs(drive, windows, starts, n_windows, bias)
        cal = (calibration(drive, windows, bias.accel_mps2, bias.gyro_radps)
               if model.config.inputs == "calibrated" else None)
        disp, yaw = model.predict(windows, starts, n_windows, bias, cal, inputs.still)
        track = rebuild_track(inputs.lat0_deg, inputs.lon0_deg, inputs.course0_deg, disp, yaw)
        idx = inputs.window_index
        az, _, dist = wgs84().inv(windows.lon1_deg[idx], windows.lat1_deg[idx], track.lon_deg[:, 1:],
                                  track.lat_deg[:, 1:])
        az, dist = np.deg2rad(np.asarray(az).reshape(idx.shape)), np.asarray(dist).reshape(idx.shape)
        err = np.stack([dist * np.sin(az), dist * np.cos(az)], axis=-1)
        parts.append((disp, yaw, np.asarray(inputs.course0_deg, dtype=float),
                      np.asarray(inputs.speed0_mps, dtype=float), err))
    if not parts:
        raise InputError(f"no {n_windows} s outages fit in the training drives for the IDNN's uncertainty",
                         "give longer drives")
    return OutageRuns(*(np.concatenate(p) for p in zip(*parts)))


#: The likelihood's floor on the covariance's determinant (m^4): far below the NEES's
#: (:data:`~ionav_viz.core.covariance.NEES_MIN_DET_M4`), it only keeps the logarithm finite.
NLL_MIN_DET_M4 = 1e-300


def uncertainty_nll(unc: Uncertainty, runs: OutageRuns) -> float:
    """Mean Gaussian negative log-likelihood (per boundary, constant dropped) of the runs' 2D position
    errors under ``unc``'s covariance."""
    cov = unc.position_covariance(runs.course0_deg, runs.speed0_mps, runs.disp_m, runs.yaw_rate_radps,
                                  runs.tracks())[:, 1:]
    nees = nees_en(runs.error_en_m, cov, NLL_MIN_DET_M4)
    return float(np.mean(0.5 * (nees + np.log(determinant_en(cov, NLL_MIN_DET_M4)))))


def nees(unc: Uncertainty, runs: OutageRuns) -> np.ndarray:
    """Normalised estimation error squared at every boundary after the start (n, w)."""
    cov = unc.position_covariance(runs.course0_deg, runs.speed0_mps, runs.disp_m, runs.yaw_rate_radps)[:, 1:]
    return np.einsum("nwa,nwab,nwb->nw", runs.error_en_m, np.linalg.inv(cov), runs.error_en_m)


def fit_uncertainty(model: IdnnModel, drives: list[tuple[Drive, SensorBias]],
                    runs: OutageRuns | None = None) -> tuple[Uncertainty, dict[str, Any]]:
    """Fit ``model``'s :class:`~ionav_viz.learning.idnn.Uncertainty` on ``drives`` (its networks unchanged);
    returns it and what the fit saw (for the metadata).

    The outages are run as the estimator runs them (:func:`outage_runs`), so the per-window
    variances absorb how errors compound through the fed-back displacement and the integrated
    course; the seven parameters minimise the Gaussian negative log-likelihood of the 2D position
    error at every boundary (:func:`uncertainty_nll`; L-BFGS from a fixed start, deterministic)."""
    from scipy.optimize import minimize

    runs = runs if runs is not None else outage_runs(model, drives)

    def unpack(theta: np.ndarray) -> Uncertainty:
        return Uncertainty(np.asarray(theta[0:3]), np.asarray(theta[3:6]), float(np.exp(theta[6])))

    def loss(theta: np.ndarray) -> float:
        value = uncertainty_nll(unpack(theta), runs)
        return value if np.isfinite(value) else 1e12

    # the start: about the shipped model's (a window's distance 0.2 m at first, growing; 3 mrad/s)
    start = np.array([-3.0, 2.0, 0.0, -11.0, 0.0, 0.5, np.log(0.05)])
    best = minimize(loss, start, method="L-BFGS-B", options={"maxiter": 500})
    unc = unpack(best.x)
    q = nees(unc, runs)
    info = {
        "description": "per-window displacement and yaw-rate variances, log-linear in (1, log j, predicted "
                       "speed or turn); docs/method.md, 'The IDNN's uncertainty'",
        "fitted_on": f"{len(runs)} outages of {runs.disp_m.shape[1]} s (one every "
                     f"{UNCERTAINTY_STRIDE_WINDOWS} s, after a {UNCERTAINTY_WARM_UP_S:g} s warm-up) of the training "
                     "drives, run as the estimator runs them",
        "nll": float(best.fun),
        "parameters": {"disp_coef": unc.disp_coef.tolist(), "yaw_coef": unc.yaw_coef.tolist(),
                       "fix_var_m2": unc.fix_var_m2},
        "mean_nees": {f"{k}s": float(np.mean(q[:, k - 1])) for k in (10, 30, 60) if k <= q.shape[1]},
        "coverage_95": {f"{k}s": float(np.mean(q[:, k - 1] <= CHI2_2_95)) for k in (10, 30, 60) if k <= q.shape[1]},
    }
    return unc, info


