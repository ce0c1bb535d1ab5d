"""The paper's Input Delay Neural Networks (Section 2.2, Table 5), and the comparison networks.

Two models predict once per 1-second window:

* **Displacement** (m): input = the bias-corrected longitudinal acceleration samples of the last
  ``n_steps_disp`` time steps (10 at 10 Hz by default, Table 4) and the displacement of the previous
  window; output = this window's displacement. In training the previous displacement is the
  GNSS one plus white Gaussian noise of ``feedback_noise_m`` (Figure 1); in prediction the
  model's own previous output is fed back, and the first window of an outage gets the last
  GNSS displacement before the outage (Figure 2).
* **Orientation rate** (rad/s, counter-clockwise positive): input = the bias-corrected gyro
  yaw-rate samples of the last ``n_steps_yaw`` time steps (10 by default, Table 3); output = the
  GNSS yaw rate of the window.

Inputs are bias-corrected with the same stationary biases as the INS (the paper's a_INS,
Eq. 10; ``inputs="plain"``), so a model carries over between cars with different mount tilts.
With ``inputs="calibrated"`` (beyond the paper) they are corrected instead by what the GNSS-aided
INS (:mod:`ionav_viz.nav.planar_filter`) has learnt at the outage start: the accelerometer offset (bias,
tilt and the road grade there), the gyro bias and the gyro scale error. Every feature group
and the target are min-max normalised to [0, 1] with the training statistics, stored with the
model. With ``residual`` (default, beyond the paper) each network learns a correction to a
kinematic skip term (:func:`kinematic_weights`, :meth:`Normalisation.skip_terms`). Architectures
(``arch``): ``idnn`` (the paper's: a feed-forward net on the time-delayed inputs, 2 hidden layers
of 32 units, 10 % dropout), ``mlp`` (the same net on the latest sample only), and
``rnn``/``gru``/``lstm`` (2 recurrent layers over the time steps; the feedback input joins the
last hidden state).

In prediction (beyond the paper, as the INS DR, :mod:`ionav_viz.nav.ins`): a displacement is a
distance, so the network's output is clipped at zero before it is fed back, and a window where the
IMU shows the car standing throughout (:mod:`ionav_viz.nav.stillness`) predicts no displacement and
no turn and feeds back zero. And a car without acceleration keeps its speed: what the displacement
network predicts for the window with no acceleration, beyond the fed-back displacement, is its
drift and is taken off (:meth:`IdnnModel.predict_displacement`). The paper's method allows both:
its feedback input is the previous window's displacement, zero for a standing car, and its
networks and their training are unchanged. A model may blend the INS DR's displacement into its
own (``ins_blend``, :meth:`IdnnModel.predict`): fine-tuning chooses the share on the car's own
drive (:func:`ionav_viz.learning.training.choose_ins_blend`); the shipped model has none.

Uncertainty (beyond the paper, optional: :class:`Uncertainty`): each window's displacement and
yaw-rate variance as a function of what the networks predicted and how far into the outage the
window lies, fitted after the networks by a Gaussian likelihood of the position errors of outages
run as the estimator runs them (:func:`ionav_viz.learning.training.fit_uncertainty`), and propagated
through the rebuilt track (:func:`ionav_viz.nav.track.track_covariance`) to the estimate's
``pos_cov_m2``. A model without it (every model before it) estimates no covariance.

Weights are stored as safetensors (no pickle is ever loaded) beside a ``metadata.json``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import stat
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.fileio import (
    check_regular_input,
    read_json_bounded,
    refuse_system_output,
    staging_folder,
    swap_in_directory,
    write_failure,
)
from ..core.grid import GRID_STEP_S, MIN_COURSE_SPEED_MPS, WINDOW_S
from ..nav import history_check
from ..nav.bias import SensorBias
from ..nav.planar_filter import SensorCalibration, calibration
from ..nav.protocol import Estimate, EstimatorInputs
from ..nav.track import TrackCovariance
from ..nav.windows import Windows
from .domain import Domain, outside, sigma_scale
from .provenance import check_inputs, trained_outages

log = logging.getLogger("ionav_viz")

ARCHS = ("idnn", "mlp", "rnn", "gru", "lstm")
INPUTS = ("plain", "calibrated")
LR_SCHEDULES = ("tail", "cosine")
KEEP_CHOICES = ("last", "best", "last-or-start")
TUNE_LAYERS_CHOICES = ("all", "first", "all,first")
FORMAT_VERSION = 2
MODEL_FILES = {"displacement": "displacement.safetensors", "yaw_rate": "yaw_rate.safetensors"}
#: The optional uncertainty model's file (:class:`Uncertainty`); metadata.json's ``uncertainty`` names it.
UNCERTAINTY_FILE = "uncertainty.safetensors"
#: What a model directory holds: replacing one (``overwrite``, ``--force``) deletes only these.
MODEL_DIR_FILES = frozenset({"metadata.json", *MODEL_FILES.values(), UNCERTAINTY_FILE})


@dataclass
class ModelConfig:
    """Architecture and training hyperparameters (defaults: the paper's Table 5)."""

    arch: str = "idnn"
    n_steps_disp: int = 14  # the shipped model's (Table 4's range is 1-20)
    n_steps_yaw: int = 10
    hidden: int = 32
    dropout: float = 0.1
    feedback_noise_m: float = 0.1
    residual: bool = True
    lr_disp: float = 0.004
    lr_yaw: float = 0.001
    batch_size: int = 256
    epochs_disp: int = 40
    epochs_yaw: int = 60
    lr_decay_tail: float = 0.3
    # the ekf's calibration at the outage start (the shipped model's); "plain": the paper's standstill biases
    inputs: str = "calibrated"
    seed: int = 0
    # "tail": constant, then linear to 0 over lr_decay_tail; "cosine": cosine to 0 throughout (fine-tuning)
    lr_schedule: str = "tail"
    # 0: a seeded random 10 % of the windows is the validation set; > 0: the last fraction of each drive, by time
    validation_tail: float = 0.0
    # which weights each network ends with: "last" epoch's; "best" epoch's on validation; "last-or-start": the last
    # unless the start (a parent's) is better on validation
    keep: str = "last"
    anchor: float = 0.0  # fine-tuning: loss + anchor * mean squared distance of the weights from the parent's (L2-SP)
    # > 0, with validation_tail: the displacement network is validated on outages this long in the tail, its own output
    # fed back
    validation_outage_s: int = 0
    # fine-tuning: 1: the tail decides, then refit on every window; k > 1: k time blocks left out in turn decide; 0: the
    # tail-trained fit is kept
    validation_folds: int = 0
    # fine-tuning trains "all" layers, or the "first" only; "all,first" (with validation_folds): the first only for a
    # network validation keeps from all
    tune_layers: str = "all"
    # prediction: this share of each window's displacement is the INS DR's, the rest the network's
    # (fine-tuning chooses it)
    ins_blend: float = 0.0

    def validate(self) -> None:
        """Check types and ranges; errors name the field (``param``) so the command line can name its
        option. Sizes are bounded before any network is built (a huge ``hidden`` would eat the memory)."""
        if self.arch not in ARCHS:
            raise InputError(f"unknown architecture {self.arch!r}", f"choose one of {', '.join(ARCHS)}", param="arch")
        for name, (low, high) in _INT_LIMITS.items():
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool):
                raise InputError(f"{name} = {value!r} is not a whole number", param=name)
            if not low <= value <= high:
                what = "time steps" if name.startswith("n_steps") else name
                raise InputError(f"{value} {what} ({name}) out of range",
                                 f"use {low} to {high}" + (" time steps (2 s at 10 Hz)"
                                                           if name.startswith("n_steps") else ""), param=name)
        for name, (low, high) in _FLOAT_LIMITS.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise InputError(f"{name} = {value!r} is not a finite number", param=name)
            if not low <= value <= high:
                raise InputError(f"{name} = {value:g} out of range", f"use {low:g} to {high:g}", param=name)
        if self.dropout >= 1:
            raise InputError(f"dropout {self.dropout} out of range", "use a dropout in [0, 1)", param="dropout")
        if self.inputs not in INPUTS:
            raise InputError(f"unknown inputs {self.inputs!r}", f"choose one of {', '.join(INPUTS)}", param="inputs")
        if self.lr_schedule not in LR_SCHEDULES:
            raise InputError(f"unknown learning-rate schedule {self.lr_schedule!r}",
                             f"choose one of {', '.join(LR_SCHEDULES)}", param="lr_schedule")
        if not isinstance(self.residual, bool):
            raise InputError(f"residual = {self.residual!r} is not true or false", param="residual")
        if self.tune_layers not in TUNE_LAYERS_CHOICES:
            raise InputError(f"unknown tune_layers {self.tune_layers!r}",
                             f"choose one of {', '.join(TUNE_LAYERS_CHOICES)}", param="tune_layers")
        if self.keep not in KEEP_CHOICES:
            raise InputError(f"unknown keep {self.keep!r}", f"choose one of {', '.join(KEEP_CHOICES)}", param="keep")


#: Ranges of the integer and real hyperparameters (checked by :meth:`ModelConfig.validate`).
_INT_LIMITS = {"n_steps_disp": (1, 20), "n_steps_yaw": (1, 20), "hidden": (1, 1024), "batch_size": (1, 65536),
               "epochs_disp": (1, 100_000), "epochs_yaw": (1, 100_000), "seed": (0, 2**32 - 1),
               "validation_outage_s": (0, 600), "validation_folds": (0, 100)}
_FLOAT_LIMITS = {"dropout": (0.0, 1.0), "feedback_noise_m": (0.0, 100.0), "lr_disp": (1e-9, 10.0),
                 "lr_yaw": (1e-9, 10.0), "lr_decay_tail": (0.0, 1.0), "validation_tail": (0.0, 0.9),
                 "anchor": (0.0, 1e6), "ins_blend": (0.0, 1.0)}
#: Largest weights file read (bytes): the biggest network of the allowed sizes is far smaller.
MAX_WEIGHTS_BYTES = 256 * 2**20


def kinematic_weights(n_steps: int) -> np.ndarray:
    """Weights (summing to 1) of the last ``n_steps`` acceleration samples in ``d_t - d_{t-1}``.

    With a window of 1 s, ``d_t - d_{t-1} = integral of K(tau) a(tau) dtau`` over the two windows,
    with the triangular kernel ``K = 1 - |tau|`` (tau in s, 0 at the start of window t). The
    samples at tau = 1 - (n_steps - 1 - j) * GRID_STEP_S get ``K * GRID_STEP_S`` (the trapezoid rule on
    the 10 Hz grid): 20 steps give the exact increment for piecewise-linear acceleration; fewer
    steps miss part of the previous window, so the weights are rescaled to sum to 1 and a
    constant acceleration still gives its exact increment.
    """
    tau = 1.0 - (n_steps - 1 - np.arange(n_steps)) * GRID_STEP_S
    k = np.clip(1.0 - np.abs(tau), 0.0, None)
    if k.sum() <= 0:  # a single sample at tau = 1: fall back to it alone
        k = np.ones(n_steps)
    return k / k.sum()


def build_net(arch: str, n_steps: int, hidden: int, dropout: float, feedback: bool,
              skip: tuple[float, float] | None = None):
    """A torch module mapping normalised inputs (batch, n_steps [+ 1 feedback]) -> (batch,).

    With ``skip = (gain, offset)`` the output adds a kinematic skip term, so the layers learn a
    correction to it: ``gain * sum(w * samples) + offset`` plus, for the displacement model
    (``feedback``), the fed-back previous displacement; ``w`` are the
    :func:`kinematic_weights` for the displacement model and equal weights (the mean rate) for
    the orientation-rate model; see :meth:`Normalisation.skip_terms`.
    """
    import torch
    from torch import nn

    weights = torch.from_numpy((kinematic_weights(n_steps) if feedback
                                else np.full(n_steps, 1.0 / n_steps)).astype(np.float32))

    def skip_of(x: torch.Tensor, w: torch.Tensor) -> torch.Tensor | float:
        if skip is None:
            return 0.0
        term = skip[0] * (x[:, :n_steps] @ w) + skip[1]
        return term + x[:, n_steps] if feedback else term

    class FeedForward(nn.Module):
        def __init__(self, n_in: int, latest_only: bool) -> None:
            super().__init__()
            self.latest_only = latest_only
            self.dropout = dropout
            # moves with the net (to a GPU), not a weight
            self.register_buffer("skip_weights", weights, persistent=False)
            self.body = nn.Sequential(
                nn.Linear(n_in, hidden), nn.ReLU(), nn.Dropout(dropout),
                nn.Linear(hidden, hidden), nn.ReLU(), nn.Dropout(dropout),
                nn.Linear(hidden, 1),
            )  # fmt: skip

        def skip_term(self, x: torch.Tensor) -> torch.Tensor | float:
            """The kinematic skip term of the inputs ``x`` (0 without ``skip``)."""
            return skip_of(x, self.skip_weights)

        def trunk_input(self, x: torch.Tensor) -> torch.Tensor:
            """What the layers take of the inputs ``x`` (the latest sample and the feedback for ``mlp``)."""
            return torch.cat([x[:, n_steps - 1 : n_steps], x[:, n_steps:]], dim=1) if self.latest_only else x

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return self.skip_term(x) + self.body(self.trunk_input(x)).squeeze(-1)

    class Recurrent(nn.Module):
        def __init__(self, cell: type[nn.Module]) -> None:
            super().__init__()
            self.rnn = cell(1, hidden, num_layers=2, batch_first=True, dropout=dropout)
            self.register_buffer("skip_weights", weights, persistent=False)
            self.head = nn.Sequential(nn.Dropout(dropout), nn.Linear(hidden + int(feedback), 1))

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            seq = x[:, :n_steps].unsqueeze(-1)
            out, _ = self.rnn(seq)
            last = torch.cat([out[:, -1, :], x[:, n_steps:]], dim=1)
            return skip_of(x, self.skip_weights) + self.head(last).squeeze(-1)

    n_in = n_steps + int(feedback)
    if arch == "idnn":
        return FeedForward(n_in, latest_only=False)
    if arch == "mlp":
        return FeedForward(1 + int(feedback), latest_only=True)
    cells = {"rnn": nn.RNN, "gru": nn.GRU, "lstm": nn.LSTM}
    return Recurrent(cells[arch])


#: The feed-forward architectures, run with numpy when loaded for inference (:class:`NumpyFeedForward`).
FEED_FORWARD_ARCHS = ("idnn", "mlp")


def feed_forward_shapes(arch: str, n_steps: int, hidden: int, feedback: bool) -> dict[str, tuple[int, ...]]:
    """The weight names and shapes of :func:`build_net`'s feed-forward nets (torch's ``Linear``
    layout: ``(out, in)``), without torch."""
    n_in = (1 if arch == "mlp" else n_steps) + int(feedback)
    return {"body.0.weight": (hidden, n_in), "body.0.bias": (hidden,), "body.3.weight": (hidden, hidden),
            "body.3.bias": (hidden,), "body.6.weight": (1, hidden), "body.6.bias": (1,)}


class NumpyFeedForward:
    """:func:`build_net`'s feed-forward net for inference, in numpy float32: the same layers
    (linear, ReLU, linear, ReLU, linear; dropout is off in inference) and kinematic skip term.
    Evaluating and replaying then need no torch (about 1.2 s of import a process); training
    gets torch modules (:meth:`state_dict` gives torch tensors to load into one)."""

    def __init__(self, state: dict[str, np.ndarray], n_steps: int, feedback: bool, skip: tuple[float, float] | None,
                 latest_only: bool) -> None:
        self.state = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in state.items()}
        self.n_steps, self.feedback, self.skip, self.latest_only = n_steps, feedback, skip, latest_only
        self.weights = (kinematic_weights(n_steps) if feedback else np.full(n_steps, 1.0 / n_steps)).astype(np.float32)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Outputs ``(batch,)`` for normalised inputs ``(batch, n_steps [+ 1])``, float32."""
        x = np.asarray(x, dtype=np.float32)
        n, w = self.n_steps, self.state
        skip: np.ndarray | float = 0.0
        if self.skip is not None:
            skip = np.float32(self.skip[0]) * (x[:, :n] @ self.weights) + np.float32(self.skip[1])
            if self.feedback:
                skip = skip + x[:, n]
        if self.latest_only:
            x = np.concatenate([x[:, n - 1:n], x[:, n:]], axis=1)
        h = np.maximum(x @ w["body.0.weight"].T + w["body.0.bias"], 0.0)
        h = np.maximum(h @ w["body.3.weight"].T + w["body.3.bias"], 0.0)
        return (skip + (h @ w["body.6.weight"].T + w["body.6.bias"])[:, 0]).astype(np.float32)

    def state_dict(self) -> dict[str, Any]:
        """The weights as torch tensors, as a torch module's ``state_dict`` (for training and saving)."""
        import torch

        return {k: torch.from_numpy(v.copy()) for k, v in self.state.items()}

    def eval(self) -> NumpyFeedForward:
        return self


def count_parameters(net) -> int:
    """Trainable parameters of a torch module."""
    return int(sum(p.numel() for p in net.parameters() if p.requires_grad))


@dataclass
class MinMax:
    """Min-max scaling of one feature group to [0, 1]."""

    lo: float
    hi: float

    @classmethod
    def fit(cls, x: np.ndarray) -> MinMax:
        lo, hi = float(np.min(x)), float(np.max(x))
        return cls(lo, hi if hi > lo else lo + 1.0)

    def scale(self, x: np.ndarray) -> np.ndarray:
        return (x - self.lo) / (self.hi - self.lo)

    def unscale(self, y: np.ndarray) -> np.ndarray:
        return y * (self.hi - self.lo) + self.lo


@dataclass
class Normalisation:
    """Training statistics of every feature group and target."""

    accel: MinMax
    disp: MinMax
    gyro: MinMax
    yaw: MinMax

    def to_dict(self) -> dict[str, list[float]]:
        return {k: [getattr(self, k).lo, getattr(self, k).hi] for k in ("accel", "disp", "gyro", "yaw")}

    @classmethod
    def from_dict(cls, d: dict[str, list[float]]) -> Normalisation:
        """From metadata; every span must be finite and positive (a zero span would divide by zero)."""
        out = {}
        for k in ("accel", "disp", "gyro", "yaw"):
            lo, hi = d[k]
            if any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in (lo, hi)):
                raise ValueError(f"normalisation {k}: {d[k]!r} is not two numbers")
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
                raise ValueError(f"normalisation {k}: [{lo}, {hi}] is not a finite, non-empty range")
            out[k] = MinMax(float(lo), float(hi))
        return cls(**out)

    def skip_terms(self, displacement: bool) -> tuple[float, float]:
        """(gain, offset) of the kinematic skip term in normalised units.

        Displacement: d_t = d_{t-1} + sum(w * a) * 1 s with the :func:`kinematic_weights` ``w``
        (summing to 1). Orientation rate: the mean gyro rate (gyro and yaw rate share one scaling).
        """
        if not displacement:
            return (1.0, 0.0) if self.gyro == self.yaw else (
                (self.gyro.hi - self.gyro.lo) / (self.yaw.hi - self.yaw.lo),
                (self.gyro.lo - self.yaw.lo) / (self.yaw.hi - self.yaw.lo))
        span = self.disp.hi - self.disp.lo
        return ((self.accel.hi - self.accel.lo) * WINDOW_S / span, self.accel.lo * WINDOW_S / span)


def sample_history(samples: np.ndarray, idx: np.ndarray, n_steps: int) -> np.ndarray:
    """The last ``n_steps`` samples up to the end of each window ``idx`` (any shape).

    ``samples`` is a windows array (n_windows, steps + 1); window ``k``'s own time steps are
    ``samples[k, 1:]``. More than ``steps`` time steps reach into window ``k - 1``, which must be in
    the same segment (outage starts and training windows guarantee it).
    """
    steps = samples.shape[1] - 1
    own = samples[idx, 1:]
    if n_steps <= steps:
        return own[..., steps - n_steps :]
    before = samples[np.maximum(idx - 1, 0), 1:]
    return np.concatenate([before, own], axis=-1)[..., 2 * steps - n_steps :]


#: The GNSS course's error at the outage start, as a speed error across the direction of travel
#: (m/s): sigma_course = this / speed. A VBOX-class receiver's course comes from its Doppler
#: velocity, good to about 0.05 m/s (0.3 deg at 10 m/s, 0.1 deg at 30 m/s); below
#: :data:`~ionav_viz.core.grid.MIN_COURSE_SPEED_MPS` the course is held, and its error is taken at that speed.
COURSE_SPEED_SD_MPS = 0.05


@dataclass
class Uncertainty:
    """How sure the IDNN is of each window, and so of its position through an outage.

    A window's displacement variance (m^2) and yaw-rate variance ((rad/s)^2) are log-linear in
    :meth:`features`: the window's place in the outage (``log j``, j = 1, 2, ...: errors compound,
    the displacement network being fed its own output), the predicted displacement and the
    predicted turn. They are the variances of independent per-window errors that
    :func:`~ionav_viz.nav.track.track_covariance` propagates, fitted (with ``fix_var_m2``, the GNSS
    fixes' own error at the start and the end, which the scoring truth also has) by the Gaussian
    likelihood of the 2D position error at every window boundary of outages run as the estimator
    runs them (:func:`ionav_viz.learning.training.fit_uncertainty`): the compounding is in the fit.
    The course at the start has the GNSS course's error (:data:`COURSE_SPEED_SD_MPS`).
    """

    disp_coef: np.ndarray  # (3,) over features(...)[0]
    yaw_coef: np.ndarray  # (3,) over features(...)[1]
    fix_var_m2: float

    @staticmethod
    def features(disp_m: np.ndarray, yaw_rate_radps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The displacement and yaw-rate variances' features, each (..., n_windows, 3)."""
        disp_m, yaw = np.asarray(disp_m, dtype=float), np.asarray(yaw_rate_radps, dtype=float)
        log_j = np.broadcast_to(np.log(np.arange(1, disp_m.shape[-1] + 1, dtype=float)), disp_m.shape)
        one = np.ones_like(disp_m)
        speed = np.log1p(np.maximum(disp_m, 0.0) / WINDOW_S)  # log(1 + m/s)
        return np.stack([one, log_j, speed], axis=-1), np.stack([one, log_j, 10.0 * np.abs(yaw)], axis=-1)

    def variances(self, disp_m: np.ndarray, yaw_rate_radps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per window: displacement variance (m^2) and yaw-rate variance ((rad/s)^2)."""
        fd, fy = self.features(disp_m, yaw_rate_radps)
        return np.exp(np.clip(fd @ self.disp_coef, -30, 30)), np.exp(np.clip(fy @ self.yaw_coef, -30, 30))

    def position_covariance(self, course0_deg: np.ndarray, speed0_mps: np.ndarray, disp_m: np.ndarray,
                            yaw_rate_radps: np.ndarray, tracks: TrackCovariance | None = None) -> np.ndarray:
        """East/north covariance (m^2) at every window boundary, (n_outages, n_windows + 1, 2, 2);
        ``tracks``: these outages' :class:`~ionav_viz.nav.track.TrackCovariance`, when the caller has it."""
        var_d, var_w = self.variances(disp_m, yaw_rate_radps)
        var_course = (COURSE_SPEED_SD_MPS / np.maximum(np.asarray(speed0_mps, dtype=float), MIN_COURSE_SPEED_MPS)) ** 2
        tracks = tracks if tracks is not None else TrackCovariance(course0_deg, disp_m, yaw_rate_radps)
        cov = tracks(var_d, var_w, var_course)
        cov[:, 1:] += self.fix_var_m2 * np.eye(2)
        return cov

    def to_tensors(self) -> dict[str, np.ndarray]:
        return {"disp_coef": np.asarray(self.disp_coef, dtype=np.float64),
                "yaw_coef": np.asarray(self.yaw_coef, dtype=np.float64),
                "fix_var_m2": np.asarray([self.fix_var_m2], dtype=np.float64)}

    @classmethod
    def from_tensors(cls, tensors: dict[str, np.ndarray]) -> Uncertainty:
        """From its safetensors; shapes and finiteness checked (a ValueError names the tensor)."""
        for name, size in (("disp_coef", 3), ("yaw_coef", 3), ("fix_var_m2", 1)):
            t = tensors.get(name)
            if t is None or t.shape != (size,) or not np.isfinite(t).all():
                raise ValueError(f"{name}: expected {size} finite number(s), got {None if t is None else t.shape}")
        if tensors["fix_var_m2"][0] < 0:
            raise ValueError("fix_var_m2 is negative")
        return cls(tensors["disp_coef"].astype(np.float64), tensors["yaw_coef"].astype(np.float64),
                   float(tensors["fix_var_m2"][0]))


@dataclass
class IdnnModel:
    """A trained displacement model and orientation-rate model with their normalisation."""

    config: ModelConfig
    norm: Normalisation
    disp_net: Any
    yaw_net: Any
    metadata: dict[str, Any] = field(default_factory=dict)
    directory: str = ""
    #: optional: the per-window uncertainty (:class:`Uncertainty`); without it no covariance
    uncertainty: Uncertainty | None = None

    @property
    def domain(self) -> Domain | None:
        """What its training inputs were (:class:`~ionav_viz.learning.domain.Domain`, the metadata's
        ``domain``), None for a model without the record (older ones)."""
        record = self.metadata.get("domain")
        return Domain.from_dict(record) if record is not None else None

    def _run(self, net, x: np.ndarray) -> np.ndarray:
        if isinstance(net, NumpyFeedForward):
            return net(x.astype(np.float32)).astype(np.float64)
        import torch

        with torch.no_grad():
            return net(torch.from_numpy(x.astype(np.float32))).numpy().astype(np.float64)

    def predict_yaw_rate(self, gyro_radps: np.ndarray) -> np.ndarray:
        """Orientation rate (rad/s) from bias-corrected gyro histories (..., n_steps), in one call."""
        shape = gyro_radps.shape[:-1]
        x = self.norm.gyro.scale(gyro_radps.reshape(-1, self.config.n_steps_yaw))
        return self.norm.yaw.unscale(self._run(self.yaw_net, x)).reshape(shape)

    def predict_displacement(self, accel_mps2: np.ndarray, first_prev_disp_m: np.ndarray,
                             still: np.ndarray | None = None) -> np.ndarray:
        """Displacement (m) of every window of every sequence, feeding back the model's own output.

        ``accel_mps2``: (n_seq, n_windows, n_steps_disp) bias-corrected; ``first_prev_disp_m``: (n_seq,)
        GNSS displacement of the second before each outage; ``still``: (n_seq, n_windows), windows
        where the car stands throughout. All sequences step together. A displacement is a distance:
        it is never below zero, and a still window's is zero; what is fed back is that.

        Without acceleration a car keeps its speed: the network's output for the window with its
        acceleration set to zero, less the fed-back displacement, is its drift at that speed and is
        taken off (the shipped model's is +0.09 m a window at 25 m/s; fed back over a 30 s outage
        it had added tens of metres on motorways).
        """
        n_seq, n_win, n_steps = accel_mps2.shape
        acc = self.norm.accel.scale(accel_mps2)
        level = np.broadcast_to(self.norm.accel.scale(np.zeros(n_steps)), (n_seq, n_steps))  # no acceleration
        prev_m = np.asarray(first_prev_disp_m, dtype=np.float64)
        out = np.empty((n_seq, n_win))
        for w in range(n_win):  # each window feeds the next
            prev = self.norm.disp.scale(prev_m)[:, None]
            # the window as measured, and the same window without acceleration, in one batch
            y = self.norm.disp.unscale(self._run(self.disp_net, np.concatenate(
                [np.concatenate([acc[:, w, :], prev], axis=1), np.concatenate([level, prev], axis=1)])))
            disp = np.maximum(y[:n_seq] - (y[n_seq:] - prev_m), 0.0)
            if still is not None:
                disp = np.where(still[:, w], 0.0, disp)
            out[:, w] = disp
            prev_m = disp
        return out

    def predict(self, windows: Windows, starts: np.ndarray, n_windows: int, bias: SensorBias,
                calibration: SensorCalibration | None = None,
                still: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Displacement (m) and yaw rate (rad/s) per window for outages of ``n_windows`` starting at
        ``starts`` (batched): two arrays of shape (n_outages, n_windows).

        Inputs are corrected with the standstill ``bias`` (``inputs="plain"``, the paper's) or with
        the filter's ``calibration`` at each outage start (``inputs="calibrated"``, required then).
        ``still`` (n_outages, n_windows, steps + 1): where the IMU shows the car standing; a window
        standing throughout has no displacement and no turn (see :meth:`predict_displacement`).

        With ``config.ins_blend`` = b > 0, each window's displacement is (1 - b) x the network's + b x
        the INS DR's (:func:`~ionav_viz.nav.ins.dead_reckon` on the same samples, ``bias`` and
        ``still``, from the GNSS speed at each start): b = 1 is the INS DR's displacement exactly.
        The yaw rate is the network's."""
        starts = np.asarray(starts, dtype=int)
        idx = starts[:, None] + np.arange(n_windows)[None, :]
        if len(starts) == 0:
            return np.zeros((0, n_windows)), np.zeros((0, n_windows))
        accel = sample_history(windows.accel_mps2, idx, self.config.n_steps_disp)
        gyro = sample_history(windows.gyro_radps, idx, self.config.n_steps_yaw)
        if self.config.inputs == "calibrated":
            if calibration is None:
                raise ValueError("this model takes calibrated inputs: pass the filter's calibration "
                                 "(ionav_viz.nav.planar_filter.calibration)")
            # the road driven since the start, as the speed there would take it (the grade part fades)
            at_start = calibration.at(np.broadcast_to(starts[:, None], idx.shape))
            driven = windows.speed0_mps[starts][:, None] * WINDOW_S * np.arange(n_windows)[None, :]
            accel, gyro = at_start.accel(accel, driven), at_start.gyro(gyro)
        else:
            accel, gyro = accel - bias.accel_mps2, gyro - bias.gyro_radps
        standing = None if still is None else np.asarray(still).all(axis=-1)
        yaw = self.predict_yaw_rate(gyro)
        if standing is not None:
            yaw = np.where(standing, 0.0, yaw)
        disp = self.predict_displacement(accel, windows.gnss_disp_m[starts - 1], standing)
        if self.config.ins_blend > 0:
            from ..nav.ins import dead_reckon

            ins_m, _ = dead_reckon(windows.accel_mps2[idx], windows.gyro_radps[idx], windows.speed0_mps[starts], bias,
                                   windows.rate_hz, still)
            disp = (1.0 - self.config.ins_blend) * disp + self.config.ins_blend * ins_m
        return disp, yaw

    def describe(self) -> dict[str, Any]:
        """What the recording and reports say about the model (``ins_blend``: only a model that takes
        a share of the INS DR's displacement)."""
        return {
            "directory": self.directory,
            "arch": self.config.arch,
            "n_steps_disp": self.config.n_steps_disp,
            "n_steps_yaw": self.config.n_steps_yaw,
            "inputs": self.config.inputs,
            "trained_on": self.metadata.get("training", {}).get("drives", []),
            "training_data": self.metadata.get("training", {}).get("description", ""),
        } | ({"ins_blend": self.config.ins_blend} if self.config.ins_blend > 0 else {})


#: The shares of the INS DR's displacement the IDNN's history arbiter chooses from per outage
#: (:meth:`IdnnEstimator._arbitrate`): the first, none, is the model as trained.
ARBITER_INS_SHARES = (0.0, 0.5, 1.0)
#: The prior of the arbiter: the INS DR's displacement alone errs this many times as much as the
#: network's, on pseudo-outages, until the drive's own past says otherwise (how it was chosen:
#: docs/real-imu-logs.md, "The IDNN's history arbiter").
ARBITER_PRIOR_INS_RATIO = 2.0
#: The prior ratio of the gyro's heading error to the network's yaw rate's, on pseudo-outages
#: (:meth:`IdnnEstimator._arbitrate`): none, the drive's own past decides (why: docs/real-imu-logs.md,
#: "The IDNN's history arbiter").
ARBITER_GYRO_PRIOR_RATIO = 1.0


def _outages(k: int) -> str:
    return f"{k} outage" + ("" if k == 1 else "s")


def arbiter_prior_ratio(share: float) -> float:
    """The prior ratio of a blend's displacement CRSE to the network's: linear in the INS DR's ``share``."""
    return 1.0 + (ARBITER_PRIOR_INS_RATIO - 1.0) * share


@dataclass(frozen=True)
class _PseudoRuns:
    """The network's and the INS DR's estimates on pseudo-outages of ``n_windows`` windows over the
    GNSS before the last outage (:func:`~ionav_viz.nav.history_check.pseudo_starts_before`), and how
    each candidate of the history arbiter erred there: ``disp_err`` ``(c, k)``, the displacement
    CRSE (m) of each of :data:`ARBITER_INS_SHARES`; ``heading_err`` ``(2, k)``, the heading's error
    summed over the window boundaries (rad s), of the network's yaw rate and the gyro's."""

    starts: np.ndarray
    n_windows: int
    net_m: np.ndarray
    net_yaw_radps: np.ndarray
    ins_m: np.ndarray
    ins_yaw_radps: np.ndarray
    disp_err: np.ndarray
    heading_err: np.ndarray

    def choose(self, at: np.ndarray) -> tuple[np.ndarray, ...]:
        """For outages starting at windows ``at``, from the pseudo-outages that ended by then
        (:func:`~ionav_viz.nav.history_check.past_choice`; each share's record shrunk toward
        :func:`arbiter_prior_ratio`, the gyro's toward :data:`ARBITER_GYRO_PRIOR_RATIO`): the share's
        index, each share's summed error, the count behind, whether the gyro's yaw rate, and the two yaw
        candidates' summed error."""
        ends = self.starts + self.n_windows
        choice, sums, count = history_check.past_choice(
            ends, self.disp_err, at, np.array([arbiter_prior_ratio(b) for b in ARBITER_INS_SHARES]))
        yaw_choice, yaw_sums, _ = history_check.past_choice(ends, self.heading_err, at,
                                                            np.array([1.0, ARBITER_GYRO_PRIOR_RATIO]))
        return choice, sums, count, yaw_choice == 1, yaw_sums

    def as_chosen(self, picked: tuple[np.ndarray, ...] | None) -> _Judged:
        """These pseudo-outages with ``picked`` (:func:`_choices` at :attr:`starts`) applied: the
        estimate an outage starting at each would have got (the network's where nothing was picked)."""
        if picked is None:
            return _Judged(self.starts, self.net_m, self.net_yaw_radps)
        choice, _, gyro, _, _ = picked
        share = np.asarray(ARBITER_INS_SHARES)[choice][:, None]
        return _Judged(self.starts, (1.0 - share) * self.net_m + share * self.ins_m,
                       np.where(gyro[:, None], self.ins_yaw_radps, self.net_yaw_radps))


@dataclass(frozen=True)
class _Judged:
    """Pseudo-outages (first windows ``starts``) estimated as the IDNN's outages are, with its history
    arbiter's choices: displacement (m) and yaw rate (rad/s, CCW +) per window ``(k, n)``."""

    starts: np.ndarray
    disp_m: np.ndarray
    yaw_radps: np.ndarray


class _Network:
    """The model's network run on outages or pseudo-outages of a drive, its inputs calibrated by the
    filter (``cal``) with or without the road grade part of the accelerometer's offset, per start as
    the pseudo-outages of :data:`history_check.SHORT_WINDOWS` windows before it say
    (:func:`~ionav_viz.nav.history_check.past_choice` under :data:`GRADE_PRIOR_RATIO`; the grade, as
    the model was trained, until :data:`history_check.ENOUGH` of them lie behind). The filter's grade
    follows the receiver's speed: worth its noise with a good receiver, not with a phone's
    (docs/real-imu-logs.md, "The held-out phone drive"). ``choose_grade`` False: always the grade."""

    def __init__(self, model: IdnnModel, inputs: EstimatorInputs, cal: SensorCalibration | None,
                 choose_grade: bool) -> None:
        self.model, self.inputs, self.cal = model, inputs, cal
        self.flat_cal = None
        self.ends = self.err = None
        if cal is None or not choose_grade:
            return
        w, n = inputs.windows, history_check.SHORT_WINDOWS
        pseudo = history_check.pseudo_starts_before(w, n, np.asarray(inputs.starts, dtype=int))
        if not len(pseudo):
            return
        self.flat_cal = replace(cal, accel_grade_mps2=np.zeros_like(cal.accel_grade_mps2))
        idx = pseudo[:, None] + np.arange(n)[None, :]
        truth = w.gnss_disp_m[idx]
        still = inputs.still_grid[idx]
        self.err = np.stack([np.abs(model.predict(w, pseudo, n, inputs.bias, c, still)[0] - truth).sum(axis=1)
                             for c in (cal, self.flat_cal)])
        self.ends = pseudo + n

    def flat_at(self, starts: np.ndarray) -> np.ndarray:
        """Whether the outages starting at windows ``starts`` leave the grade out."""
        return self._choice(starts)[0] == 1

    def _choice(self, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per start, 1 where the grade is left out; the two candidates' summed ``log(1 + CRSE)`` behind
        it, and how many pseudo-outages those are. Judged on the logs: which is better pseudo-outage
        by pseudo-outage, not one pseudo-outage's large error (a roof log's 41 m against 14 m, over a
        grade the RTK-fed filter had right everywhere else)."""
        if self.ends is None:
            return np.zeros(len(starts), dtype=int), np.zeros((2, len(starts))), np.zeros(len(starts), dtype=int)
        choice, sums, count = history_check.past_choice(self.ends, np.log1p(self.err), starts,
                                                        np.array([1.0, GRADE_PRIOR_RATIO]))
        return np.where(count >= history_check.ENOUGH, choice, 0), sums, count

    def describe(self, starts: np.ndarray) -> str:
        """What was chosen for the outages at ``starts``, for the arbiter's note ("" where nothing)."""
        choice, sums, count = self._choice(starts)
        flat = choice == 1
        if not flat.any():
            return ""
        lower = 1.0 - math.exp(float(np.sum(sums[1][flat] - sums[0][flat]) / np.sum(count[flat])))
        return (f"the inputs without the filter's road grade on {_outages(int(flat.sum()))} (their past "
                f"{history_check.SHORT_WINDOWS} s pseudo-outages' 1 m + displacement CRSE {100.0 * lower:.1f} % "
                "lower without it, geometric mean)")

    def __call__(self, starts: np.ndarray, n: int, still: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Displacement (m) and yaw rate (rad/s) per window ``(m, n)`` of outages at ``starts``."""
        w, bias = self.inputs.windows, self.inputs.bias
        disp, yaw = self.model.predict(w, starts, n, bias, self.cal, still)
        flat = self.flat_at(starts)
        if flat.any():
            disp = disp.copy()
            disp[flat] = self.model.predict(w, starts[flat], n, bias, self.flat_cal,
                                            None if still is None else still[flat])[0]
        return disp, yaw


#: The prior of the grade's choice (:class:`_Network`): the error without the grade over the error
#: with it, on the pseudo-outages, until the drive's own past says otherwise.
GRADE_PRIOR_RATIO = 1.0


def _pseudo_runs(network: _Network, inputs: EstimatorInputs, n: int) -> _PseudoRuns | None:
    """The history arbiter's record (:class:`_PseudoRuns`) on pseudo-outages of ``n`` windows; None
    where none fits before the last outage."""
    from ..nav.ins import dead_reckon

    w = inputs.windows
    pseudo = history_check.pseudo_starts_before(w, n, np.asarray(inputs.starts, dtype=int))
    if not len(pseudo):
        return None
    idx = pseudo[:, None] + np.arange(n)[None, :]
    still = inputs.still_grid[idx]
    net, net_yaw = network(pseudo, n, still)
    ins, ins_yaw = dead_reckon(w.accel_mps2[idx], w.gyro_radps[idx], w.speed0_mps[pseudo], inputs.bias, w.rate_hz,
                               still)
    truth, truth_yaw = w.gnss_disp_m[idx], w.gnss_yaw_rate_radps[idx]
    err = np.stack([np.abs((1.0 - b) * net + b * ins - truth).sum(axis=1) for b in ARBITER_INS_SHARES])
    # the heading's error at each boundary (rad s), not the rate's: a rate erring one way turns the
    # track away, the same error back and forth does not
    heading_err = np.stack([np.abs(np.cumsum(y - truth_yaw, axis=1)).sum(axis=1) for y in (net_yaw, ins_yaw)])
    return _PseudoRuns(pseudo, n, net, net_yaw, ins, ins_yaw, err, heading_err)


def _choices(runs: _PseudoRuns | None, short: _PseudoRuns | None,
             at: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """The history arbiter's choices for outages starting at windows ``at``: on ``runs`` (pseudo-outages
    of the outages' length), or on ``short`` (of :data:`history_check.SHORT_WINDOWS`) for an outage with
    fewer than :data:`history_check.ENOUGH` of its own length behind it or none at all. Returns the
    share's index, each share's summed error ``(c, m)``, whether the gyro's yaw rate, the two yaw
    candidates' summed error ``(2, m)`` and whether the short ones decided; None when neither exists."""
    shorter = np.zeros(len(at), dtype=bool)
    if runs is None and short is None:
        return None
    if runs is None:
        choice, sums, _, gyro, yaw_sums = short.choose(at)
        return choice, sums, gyro, yaw_sums, ~shorter
    choice, sums, count, gyro, yaw_sums = runs.choose(at)
    if short is not None:
        shorter = count < history_check.ENOUGH
        s_choice, s_sums, _, s_gyro, s_yaw_sums = short.choose(at)
        choice, sums = np.where(shorter, s_choice, choice), np.where(shorter, s_sums, sums)
        gyro, yaw_sums = np.where(shorter, s_gyro, gyro), np.where(shorter, s_yaw_sums, yaw_sums)
    return choice, sums, gyro, yaw_sums, shorter


class IdnnEstimator:
    """The paper's IDNN as an estimator: a trained model, or the shipped one (loaded when first used).

    ``model``: an :class:`IdnnModel`, a model directory, or None for the shipped model. Without a
    shipped model the estimator is not :meth:`available` (the default estimator set then skips it).
    """

    name = "idnn"
    label = "IDNN"
    color = (0, 114, 178)  # Okabe-Ito blue

    def __init__(self, model: IdnnModel | str | Path | None = None, strict: bool = False,
                 arbiter: bool = True) -> None:
        self._model = model if isinstance(model, IdnnModel) else None
        #: per outage, take a share of the INS DR's displacement where the drive's past says so (:meth:`_arbitrate`)
        self.arbiter = bool(arbiter)
        self._directory = Path(model) if isinstance(model, (str, Path)) else None
        #: refuse (instead of warn) when an outage lies in data the model was trained on
        self.strict = strict
        #: per drive name, how its inputs lay outside the model's domain (for reports)
        self._domain_notes: dict[str, dict[str, Any]] = {}

    def available(self) -> bool:
        """A model was given, or the shipped one exists."""
        if self._model is not None or self._directory is not None:
            return True
        if (default_model_dir() / "metadata.json").is_file():
            return True
        log.warning("no shipped IDNN model at %s; evaluating without the IDNN (train one with 'ionav-viz train')",
                    default_model_dir())
        return False

    @property
    def model(self) -> IdnnModel:
        if self._model is None:
            self._model = load_model(self._directory or default_model_dir())
        return self._model

    def estimate(self, inputs: EstimatorInputs) -> Estimate:
        model, cal = self.model, None
        label = f"the IDNN model {model.directory or '(in memory)'}"
        check_inputs(model.metadata, inputs.drive, label)
        self._check_leakage(model, inputs, label)
        if model.config.inputs == "calibrated":
            cal = calibration(inputs.drive, inputs.windows, inputs.bias.accel_mps2, inputs.bias.gyro_radps)
        network = _Network(model, inputs, cal, choose_grade=self.arbiter)
        disp, yaw = network(np.asarray(inputs.starts, dtype=int), inputs.n_windows, inputs.still)
        self._arbiter_note = ""
        judged = None
        if self.arbiter:
            disp, yaw, judged = self._arbitrate(network, inputs, disp, yaw)
        cov = None
        self._scale_note = ""
        widen = self._check_domain(model, inputs, label, disp)
        if model.uncertainty is not None:
            cov = model.uncertainty.position_covariance(inputs.course0_deg, inputs.speed0_mps, disp, yaw)
            cov = cov * (widen(inputs.accel_mps2, inputs.gyro_radps, disp) ** 2
                         * self._history_scale(network, inputs, widen, judged))[:, None, None, None]
        return Estimate(disp, yaw, pos_cov_m2=cov)

    def _arbitrate(self, network: _Network, inputs: EstimatorInputs, disp_m: np.ndarray,
                   yaw_radps: np.ndarray) -> tuple[np.ndarray, np.ndarray, _Judged | None]:
        """Per outage, the model's displacement (m, ``(m, n)``) with a share of the INS DR's on the same
        samples (:data:`ARBITER_INS_SHARES`), and its yaw rate (rad/s) or the INS DR's (the gyro's),
        where the drive's own past says so (:func:`_choices`), and the pseudo-outages of the outage's
        length each with the choice the arbiter would have made for an outage starting there (for
        :meth:`_history_scale`: the covariance is judged on what the outages get; None where none fits)."""
        from ..nav.ins import dead_reckon

        n, starts = int(inputs.n_windows), np.asarray(inputs.starts, dtype=int)
        runs = _pseudo_runs(network, inputs, n)
        short = (_pseudo_runs(network, inputs, history_check.SHORT_WINDOWS)
                 if n > history_check.SHORT_WINDOWS else None)
        picked = _choices(runs, short, starts)
        if picked is None:
            self._arbiter_note = (f"the network's displacement and yaw rate on all {len(starts)} outages (no "
                                  "pseudo-outage over the GNSS before them to compare with)")
            return disp_m, yaw_radps, None
        choice, sums, gyro, yaw_sums, shorter = picked
        share = np.asarray(ARBITER_INS_SHARES)[choice]
        parts = [f"the network's displacement on {_outages(int(np.sum(choice == 0)))}"]
        if grade := network.describe(starts):
            parts.append(grade)
        for c, b in enumerate(ARBITER_INS_SHARES[1:], start=1):
            on = choice == c
            if on.any():
                lower = 1.0 - np.sum(sums[c][on]) / max(float(np.sum(sums[0][on])), 1e-9)
                parts.append(f"{100 * b:.0f} % of the INS DR's on {_outages(int(on.sum()))} (their past "
                             f"pseudo-outages' displacement CRSE {100.0 * lower:.0f} % lower with it)")
        if gyro.any():
            lower = 1.0 - np.sum(yaw_sums[1][gyro]) / max(float(np.sum(yaw_sums[0][gyro])), 1e-9)
            parts.append(f"the gyro's yaw rate on {_outages(int(gyro.sum()))} (their past pseudo-outages' heading "
                         f"error {100.0 * lower:.0f} % lower with it)")
        self._arbiter_note = (", ".join(parts) + f"; chosen per outage from the {n} s pseudo-outages over the GNSS "
                              "before it" + (f"; {_outages(int(shorter.sum()))} with fewer than {history_check.ENOUGH} "
                                             f"behind them judged on the {history_check.SHORT_WINDOWS} s ones"
                                             if shorter.any() and n > history_check.SHORT_WINDOWS else ""))
        judged = runs.as_chosen(_choices(runs, short, runs.starts)) if runs is not None else None
        if not share.any() and not gyro.any():
            return disp_m, yaw_radps, judged
        ins_m, ins_yaw = dead_reckon(inputs.accel_mps2, inputs.gyro_radps, inputs.speed0_mps, inputs.bias,
                                     inputs.rate_hz, inputs.still)
        return ((1.0 - share)[:, None] * disp_m + share[:, None] * ins_m, np.where(gyro[:, None], ins_yaw, yaw_radps),
                judged)

    def _check_domain(self, model: IdnnModel, inputs: EstimatorInputs, label: str, disp_m: np.ndarray):
        """Warn when the drive's inputs lie outside what ``model`` was trained on
        (:func:`~ionav_viz.learning.domain.outside`), naming what, and return the factor on each outage's
        position sigma, ``widen(accel, gyro, disp)`` (:func:`~ionav_viz.learning.domain.sigma_scale`: 1
        for a model without a domain record, or inside it)."""
        domain = model.domain
        drive, bias = inputs.drive, inputs.bias
        if domain is None:
            return lambda accel, gyro, disp: np.ones(len(disp))
        found = outside(domain, drive, bias)

        def widen(accel: np.ndarray, gyro: np.ndarray, disp: np.ndarray) -> np.ndarray:
            return sigma_scale(domain, found, np.asarray(accel) - bias.accel_mps2, np.asarray(gyro) - bias.gyro_radps,
                               np.asarray(disp) / WINDOW_S)

        self._domain_notes.pop(drive.name, None)
        if any(o.widens for o in found):  # a sensor only quieter than any trained on is no reason to doubt the model
            scale = widen(inputs.accel_mps2, inputs.gyro_radps, disp_m) if len(disp_m) else np.ones(1)
            what = "; ".join(o.text for o in found)
            note = {"outside": [o.text for o in found], "sigma_scale_median": float(np.median(scale)),
                    "sigma_scale_max": float(np.max(scale))}
            self._domain_notes[drive.name] = note
            widened = (f"its uncertainty widened (sigma x{note['sigma_scale_median']:.2f} median, "
                       f"x{note['sigma_scale_max']:.2f} at most)"
                       if model.uncertainty is not None else "it has no uncertainty to widen")
            which = ("the shipped model"
                     if model.directory and is_shipped_model_dir(Path(model.directory))
                     else f"the model {model.directory or '(in memory)'}")
            log.warning("%s: IDNN: inputs outside what %s was trained on: %s; %s", drive.name, which, what, widened)
        return widen

    def _history_scale(self, network: _Network, inputs: EstimatorInputs, widen,
                       judged: _Judged | None = None) -> np.ndarray:
        """Per outage, how much to widen the learned covariance (``widen``-ed out of the model's
        domain): the model's NEES on pseudo-outages over the GNSS before it (:mod:`ionav_viz.nav.history_check`),
        each run as the outages are (``judged``: the arbiter's choice on each; None: the network's own)."""
        w, n = inputs.windows, inputs.n_windows

        def run(starts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            idx = starts[:, None] + np.arange(n)[None, :]
            if judged is not None and np.array_equal(judged.starts, starts):
                disp, yaw = judged.disp_m, judged.yaw_radps
            else:
                disp, yaw = network(starts, n, inputs.still_grid[idx])
            cov = network.model.uncertainty.position_covariance(w.heading0_deg[starts], w.speed0_mps[starts], disp, yaw)
            return disp, yaw, cov * (widen(w.accel_mps2[idx], w.gyro_radps[idx], disp) ** 2)[:, None, None, None]

        scale, self._scale_note = history_check.covariance_scale(w, n, inputs.starts, run)
        return scale

    def describe(self) -> dict[str, Any]:
        note, arbiter = getattr(self, "_scale_note", ""), getattr(self, "_arbiter_note", "")
        return self.model.describe() | ({"uncertainty_scale": note} if note else {}) | (
            {"arbiter": arbiter} if arbiter else {}) | (
            {"domain": dict(self._domain_notes)} if self._domain_notes else {})

    def _check_leakage(self, model: IdnnModel, inputs: EstimatorInputs, label: str) -> None:
        """Warn (refuse when ``strict``) when outages lie in data ``model`` was trained on, naming them."""
        starts = np.asarray(inputs.starts, dtype=int)
        if len(starts) == 0:
            return
        t0 = inputs.windows.t0_s[starts]
        inside = np.flatnonzero(outages_in_training(model, inputs.drive, inputs.windows, starts,
                                                    inputs.n_windows)).tolist()
        if not inside:
            return
        listed = (", ".join(f"{t0[i]:g}-{t0[i] + inputs.n_windows * WINDOW_S:g} s" for i in inside[:20])
                  + (" ..." if len(inside) > 20 else ""))
        text = (f"{inputs.drive.name}: {len(inside)} of {len(starts)} outages lie in data {label} was trained on "
                f"(same file by sha256, overlapping time): {listed}")
        if self.strict:
            raise InputError(text,
                             "evaluate on drives or spans the model never saw (--span), or leave out --strict to "
                             "score them anyway", param="strict")
        log.warning("%s; their IDNN scores flatter the model", text)


def outages_in_training(model: IdnnModel, drive: Any, windows: Windows, starts: np.ndarray,
                        n_windows: int) -> np.ndarray:
    """Per outage (``starts``: first window indices), whether it lies in data ``model`` (or its
    parent) was trained on: the same file by sha256 and overlapping time, the window before the
    outage included (it feeds the first input; :func:`ionav_viz.learning.provenance.trained_outages`)."""
    starts = np.asarray(starts, dtype=int)
    hit = np.zeros(len(starts), dtype=bool)
    if len(starts):
        t0 = windows.t0_s[starts]
        hit[trained_outages(model.metadata, drive, np.column_stack([t0 - WINDOW_S, t0 + n_windows * WINDOW_S]))] = True
    return hit


def default_model_dir() -> Path:
    """The shipped model (read-only): ``models/idnn`` of the repository, installed as the package
    data of ``ionav_viz.models``."""
    from importlib import resources

    return Path(str(resources.files("ionav_viz.models").joinpath("idnn")))


def is_shipped_model_dir(directory: Path) -> bool:
    """Whether ``directory`` is (or lies inside) the package's shipped model."""
    shipped = default_model_dir().resolve()
    target = Path(directory).expanduser().resolve()
    return target == shipped or shipped in target.parents


def check_model_dir(directory: Path, overwrite: bool = False) -> Path:
    """Check, before any training, that a model can be written as ``directory``: never the shipped
    model nor anywhere else in the installed package or a system folder
    (:func:`~ionav_viz.core.fileio.refuse_system_output`), an existing directory only with
    ``overwrite``, and its parent must exist."""
    directory = Path(directory)
    if is_shipped_model_dir(directory):
        raise InputError(f"{directory}: this is the shipped IDNN model, which is never overwritten",
                         "write the new model somewhere else, then choose it as the model", param="output")
    refuse_system_output(directory)
    if directory.exists() and not directory.is_dir():
        raise InputError(f"{directory}: exists and is not a directory", "choose a model directory name", param="output")
    if directory.exists() and not overwrite:
        raise InputError(f"{directory}: exists already",
                         "choose another directory, or allow replacing it (overwrite=True, --force)", param="output")
    if directory.is_dir():  # replaced whole: --force on a folder of other files deleted them with it
        foreign = sorted(p.name for p in directory.iterdir() if p.name not in MODEL_DIR_FILES)
        if foreign:
            more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
            raise InputError(f"{directory}: holds {foreign[0]!r}{more}, not a model's file; replacing the model "
                             "would delete them",
                             "choose another directory, or move them out first", param="output")
    parent = directory.parent if str(directory.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{directory}: {parent} does not exist", "create it first", param="output")
    return directory


def save_model(model: IdnnModel, directory: Path, *, overwrite: bool = False) -> None:
    """Write weights (safetensors) and ``metadata.json`` (with each weight file's sha256) as one
    directory, atomically: they are written into a temporary directory beside ``directory`` that is
    renamed when complete, so a failed or interrupted save leaves the previous model intact.

    An existing ``directory`` is replaced only with ``overwrite``; the shipped model never.
    """
    import hashlib

    from safetensors.torch import save

    directory = check_model_dir(directory, overwrite)
    parent = directory.parent if str(directory.parent) else Path(".")

    def refused(exc: OSError) -> InputError:
        return InputError(f"{directory}: cannot write in {parent} ({exc.strerror})", "choose a writable directory",
                          param="output")

    with staging_folder(directory, parent, refused=refused) as tmp:
        try:
            checksums = {}
            for key, net in (("displacement", model.disp_net), ("yaw_rate", model.yaw_net)):
                data = save({k: v.detach().contiguous() for k, v in net.state_dict().items()})
                (tmp / MODEL_FILES[key]).write_bytes(data)
                checksums[MODEL_FILES[key]] = hashlib.sha256(data).hexdigest()
            meta = dict(model.metadata)
            meta.pop("uncertainty", None)
            if model.uncertainty is not None:
                from safetensors.numpy import save as save_arrays

                data = save_arrays(model.uncertainty.to_tensors())
                (tmp / UNCERTAINTY_FILE).write_bytes(data)
                meta["uncertainty"] = {**model.metadata.get("uncertainty", {}), "file": UNCERTAINTY_FILE,
                                       "sha256": hashlib.sha256(data).hexdigest()}
            meta.update(format_version=FORMAT_VERSION, config=written_config(model.config),
                        normalisation=model.norm.to_dict(), weights_sha256=checksums)
            (tmp / "metadata.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
            swap_in_directory(tmp, directory)
        except OSError as exc:
            if (failure := write_failure(directory, exc)) is not None:
                raise failure from None
            raise



#: Config fields later versions added: written only when not at their default, so that a model
#: trained without them stays readable by the versions before them (which refuse unknown fields).
LATER_CONFIG_FIELDS = ("validation_tail", "keep", "anchor", "validation_outage_s", "validation_folds", "tune_layers",
                       "ins_blend")


def written_config(config: ModelConfig) -> dict[str, Any]:
    """The config as metadata.json holds it (see :data:`LATER_CONFIG_FIELDS`)."""
    default = ModelConfig()
    return {k: v for k, v in asdict(config).items() if k not in LATER_CONFIG_FIELDS or v != getattr(default, k)}


def load_model(directory: str | Path) -> IdnnModel:
    """Load a model directory; a missing, corrupted or mismatched model is an :class:`InputError`."""
    from safetensors import SafetensorError
    from safetensors.numpy import load as load_arrays

    directory = Path(directory)
    meta_path = directory / "metadata.json"
    check_regular_input(directory, "model", hint="give a model directory written by 'ionav-viz train'", folder_ok=True,
                        missing_ok=True)
    # its metadata.json, a weights file: was "DIR/metadata.json/metadata.json: cannot read it (Not a directory)"
    if directory.is_file():
        raise InputError(f"{directory}: a file; a model is the directory holding metadata.json and the weights",
                         f"give its directory ({directory.parent})", param="model")
    check_regular_input(meta_path, "model", hint="retrain or restore the model", missing_ok=True)
    if not meta_path.is_file():
        folds = (sorted(p.name for p in directory.glob("fold-*") if (p / "metadata.json").is_file())
                 if directory.is_dir() else [])
        hint = (f"it holds cross-validate's fold models ({', '.join(folds[:3])}{' ...' if len(folds) > 3 else ''}): "
                "give one of them" if folds
                else "train one with 'ionav-viz train -o DIR' and give that directory")
        raise InputError(f"{directory}: no IDNN model here (metadata.json missing)", hint, param="model")
    # bounded in size (16 MiB) and depth: nested brackets were a RecursionError traceback
    meta = read_json_bounded(meta_path, param="model", max_bytes=16 * 2**20, hint="retrain or restore the model",
                             what="a model's metadata",
                             # json.dumps wrote them (a NaN validation score); the fields are checked below
                             allow_nan=True)
    try:
        if meta.get("format_version") != FORMAT_VERSION:
            raise InputError(f"{meta_path}: model format {meta.get('format_version')!r}, expected {FORMAT_VERSION}",
                             "retrain with this version of ionav-viz")
        config = ModelConfig(**{"inputs": "plain", **meta["config"]})  # models from before the option took plain inputs
        norm = Normalisation.from_dict(meta["normalisation"])
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{meta_path}: not valid JSON ({exc})",
                         "the model directory is damaged; retrain or restore it") from None
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise InputError(f"{meta_path}: incomplete or invalid metadata ({type(exc).__name__}: {exc})",
                         "retrain or restore the model") from None
    try:
        config.validate()
    except InputError as exc:
        raise InputError(f"{meta_path}: {exc.message}",
                         "the metadata is damaged; retrain or restore the model") from None
    digests = meta.get("weights_sha256")
    if not isinstance(digests, dict):
        raise InputError(f"{meta_path}: no weights_sha256 (checksums of the weight files)",
                         "retrain it with this version of ionav-viz")
    nets = {}
    for key, filename in MODEL_FILES.items():
        path = directory / filename
        is_disp = key == "displacement"
        skip = norm.skip_terms(is_disp) if config.residual else None
        steps = config.n_steps_disp if is_disp else config.n_steps_yaw
        numpy_net = config.arch in FEED_FORWARD_ARCHS  # inference without torch (NumpyFeedForward)
        if numpy_net:
            net = None
            expected = {k: (v, "float32")
                        for k, v in feed_forward_shapes(config.arch, steps, config.hidden, is_disp).items()}
        else:
            net = build_net(config.arch, steps, config.hidden, config.dropout, is_disp, skip)
            expected = {k: (tuple(v.shape), str(v.dtype).removeprefix("torch.")) for k, v in net.state_dict().items()}
        try:
            info = path.stat()
            if not stat.S_ISREG(info.st_mode):
                raise InputError(f"{path}: not a regular file", "the weights must be a safetensors file")
            if info.st_size > MAX_WEIGHTS_BYTES:
                raise InputError(f"{path}: {info.st_size / 2**20:.0f} MiB, far more than any IDNN's weights",
                                 "retrain or restore the model")
            raw = path.read_bytes()
            state = load_arrays(raw)  # numpy arrays; safetensors holds no code (pickles are never loaded)
        except OSError as exc:
            raise InputError(f"{path}: cannot read model weights ({exc.strerror})",
                             "retrain or restore the model") from None
        except InputError:
            raise
        except (SafetensorError, ValueError, Exception) as exc:  # safetensors rejects anything else, pickles included
            raise InputError(f"{path}: not a safetensors weights file "
                             f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})",
                             "weights must be safetensors; pickled files are never loaded") from None
        bad = [k for k in expected if k not in state or tuple(state[k].shape) != tuple(expected[k][0])]
        extra = [k for k in state if k not in expected]
        if bad or extra:
            first = (bad or extra)[0]
            got = tuple(state[first].shape) if first in state else "missing"
            want = tuple(expected[first][0]) if first in expected else "unexpected"
            raise InputError(
                f"{path}: weights do not fit the {config.arch} architecture of metadata.json "
                f"({first}: {got} vs {want})",
                "the weights and metadata come from different models; retrain",
            )
        for name, array in state.items():
            if str(array.dtype) != expected[name][1]:
                raise InputError(f"{path}: {name} is {array.dtype}, expected {expected[name][1]}",
                                 "retrain or restore the model")
            if not bool(np.isfinite(array).all()):
                raise InputError(f"{path}: {name} holds NaN or infinite weights", "retrain or restore the model")
        if digests.get(filename) != hashlib.sha256(raw).hexdigest():
            raise InputError(
                f"{path}: sha256 differs from the one metadata.json records",
                "the weights and metadata come from different models (or a file was changed); retrain or restore it",
            )
        if numpy_net:
            net = NumpyFeedForward(state, steps, is_disp, skip, latest_only=config.arch == "mlp")
        else:
            import torch

            net.load_state_dict({k: torch.from_numpy(v.copy()) for k, v in state.items()})
            net.eval()
        nets[key] = net
    if meta.get("domain") is not None:
        try:
            Domain.from_dict(meta["domain"])
        except ValueError as exc:
            raise InputError(f"{meta_path}: {exc}", "the metadata is damaged; retrain or restore the model",
                             param="model") from None
    return IdnnModel(config, norm, nets["displacement"], nets["yaw_rate"], meta, str(directory),
                     _load_uncertainty(directory, meta))


def _load_uncertainty(directory: Path, meta: dict[str, Any]) -> Uncertainty | None:
    """The model's optional :class:`Uncertainty` (None when its metadata has none: older models)."""
    from safetensors import SafetensorError
    from safetensors.numpy import load as load_arrays

    info = meta.get("uncertainty")
    if info is None:
        return None
    path = directory / UNCERTAINTY_FILE
    hint = "retrain or restore the model"
    if not isinstance(info, dict) or info.get("file") != UNCERTAINTY_FILE or not isinstance(info.get("sha256"), str):
        raise InputError(f"{directory / 'metadata.json'}: the uncertainty entry does not name {UNCERTAINTY_FILE} "
                         "with its sha256", hint)
    try:
        size = path.stat()
        if not stat.S_ISREG(size.st_mode) or size.st_size > 2**20:
            raise InputError(f"{path}: not a small regular file", hint)
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read the model's uncertainty ({exc.strerror})", hint) from None
    if hashlib.sha256(raw).hexdigest() != info["sha256"]:
        raise InputError(f"{path}: sha256 differs from the one metadata.json records", hint)
    try:
        return Uncertainty.from_tensors(load_arrays(raw))
    except (SafetensorError, ValueError, Exception) as exc:  # safetensors only: never a pickle
        raise InputError(f"{path}: not a valid uncertainty file "
                         f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})", hint) from None
