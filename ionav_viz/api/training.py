"""Training the IDNN (``ionav-viz train``): the training drives and the model directory."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict, Unpack

from ..core.errors import InputError
from ..core.fileio import refuse_output_onto_input
from ..nav.bias import resolve_bias
from ..sources.load import ReadOptions, load_drives
from ..sources.resolve import data_root as _data_root
from .options import DriveLike, Progress, input_paths, load_stationary

if TYPE_CHECKING:
    from ..learning.idnn import IdnnModel, ModelConfig

#: The devices training takes (``"auto"``: a GPU when torch sees one, else the CPU).
DEVICES = ("auto", "cpu", "cuda")


@dataclass(frozen=True)
class TrainingOptions:
    """What :func:`train` and :func:`~ionav_viz.api.cross_validate.cross_validate` train, and where.

    Attributes:
        config: the training settings (a ``ModelConfig``); default the shipped model's settings,
            or with ``from_model`` :func:`fine_tune_settings` of it.
        from_model: fine-tune this model (a model directory, ``"shipped"`` or an ``IdnnModel``)
            instead of starting from random weights: its weights, input normalisation and
            architecture are the start, and the model's metadata records it as the parent.
        device: where torch trains (``"cpu"``, ``"cuda"``; None or ``"auto"``: a GPU when torch
            sees one, :func:`training_device`; deterministic for a seed on the CPU).
    """

    config: ModelConfig | None = None
    from_model: str | Path | IdnnModel | None = None
    device: str | None = None

    def __post_init__(self) -> None:
        if self.device is not None and self.device not in DEVICES:
            raise InputError(f"unknown device {self.device!r}", f"choose one of {', '.join(DEVICES)}", param="device")


def training_of(config: ModelConfig | TrainingOptions | None, moved: Mapping[str, Any]) -> TrainingOptions:
    """The :class:`TrainingOptions` of a call: ``config`` itself, or a ``ModelConfig`` (or None)
    with the deprecated ``from_model=`` and ``device=`` keywords (each warns)."""
    from_model, device = moved.get("from_model"), moved.get("device")
    if isinstance(config, TrainingOptions):
        given = [name for name, value in (("from_model", from_model), ("device", device)) if value is not None]
        if given:
            raise InputError(f"{given[0]}= given beside TrainingOptions", "give it in the TrainingOptions",
                             param=given[0])
        return config
    for name, value in (("from_model", from_model), ("device", device)):
        if value is not None:
            warnings.warn(f"{name}= is deprecated: pass TrainingOptions(config, {name}=...)", DeprecationWarning,
                          stacklevel=3)
    return TrainingOptions(config, from_model, device)


class TrainKeywords(TypedDict, total=False):
    """:func:`train`'s keyword arguments beside the model directory, drives, settings and callbacks:
    ``bias_from``, a stationary drive for the sensor biases (default each drive's own);
    ``command``, how it was trained, kept in the metadata; ``from_model`` and ``device``
    (deprecated: :class:`TrainingOptions`)."""

    bias_from: DriveLike | None
    command: str
    from_model: str | Path | IdnnModel | None
    device: str | None


class TrainingDrives(list):
    """Training drives (a ``list``), with ``description``: what they are, kept in the model's metadata."""

    description: str = "user-given drives"


def training_drives(paper: bool = False, data_root: str | Path | None = None) -> TrainingDrives:
    """The bundled synthetic training drives, or with ``paper`` the paper's IO-VNBD training runs
    (Table 1) under the data root."""
    from ..dataset.catalog import PAPER_TRAIN_RUNS
    from ..dataset.samples import SAMPLES, sample_path

    if paper:
        if _data_root(data_root) is None:
            raise InputError("training on the paper's runs needs the IO-VNBD data",
                             "give the data root, or set IONAV_DATA", param="data_root")
        drives = TrainingDrives(PAPER_TRAIN_RUNS)
        drives.description = "the paper's IO-VNBD training runs (Table 1)"
        return drives
    drives = TrainingDrives(str(sample_path(s)) for s in SAMPLES if s.role == "train")
    drives.description = ("the bundled synthetic training drives (ionav_viz/data/samples/V-sim-*-train-*.csv), "
                          "not real data")
    return drives


def train(
    output: str | Path,
    drives: Sequence[DriveLike] | None = None,
    config: ModelConfig | TrainingOptions | None = None,
    *,
    read: ReadOptions | None = None,
    force: bool = False,
    progress: Progress | None = None,
    on_epoch: Any = None,
    **keywords: Unpack[TrainKeywords],
) -> Any:
    """Train the IDNN's two networks and write them with their metadata to ``output`` (a model
    directory; an existing one is replaced only with ``force``, atomically).

    ``drives``: default the bundled synthetic training drives (:func:`training_drives`, which
    also gives the paper's runs);
    ``config``: a :class:`TrainingOptions` (the settings, the model fine-tuned from, the device),
    or only the settings, an ``ionav_viz.ModelConfig`` (default the shipped model's settings);
    ``read.span`` (``--span``) chooses the part of each drive to train on, recorded per drive with
    the file's sha256; ``progress(label, epoch, epochs)`` and ``on_epoch(status)``
    (an ``ionav_viz.learning.training.EpochStatus``: the fit, its epoch, training and validation loss,
    optimiser steps done and planned, time elapsed and left) are called after every epoch;
    ``keywords``: ``bias_from`` and ``command`` (:class:`TrainKeywords`).
    Returns the trained ``IdnnModel``.
    """
    from ..learning.idnn import ModelConfig, check_model_dir, save_model
    from ..learning.training import train_models

    unknown = sorted(set(keywords) - set(TrainKeywords.__annotations__))
    if unknown:
        raise TypeError(f"train() got an unexpected keyword argument {unknown[0]!r}")
    training = training_of(config, keywords)
    bias_from, command = keywords.get("bias_from"), keywords.get("command", "ionav_viz.train")
    read = read if read is not None else ReadOptions()
    device = training_device(training.device)
    parent = parent_model(training.from_model) if training.from_model is not None else None
    config = (training.config if training.config is not None
              else (ModelConfig() if parent is None else fine_tune_settings(parent)))
    config.validate()
    specs = training_drives() if drives is None else drives
    description = getattr(specs, "description", TrainingDrives.description)
    # the model folder is replaced whole: no training drive may lie in it (said before its other files)
    refuse_output_onto_input(Path(output), input_paths([*specs, *([bias_from] if bias_from is not None else [])], read),
                             output_is_folder=True)
    out = check_model_dir(Path(output), overwrite=force)  # before any work
    stationary = load_stationary(bias_from, read)
    loaded = [(d, resolve_bias(d, stationary)) for d in load_drives(specs, read)]
    model = train_models(loaded, config, progress=progress, description=description, parent=parent, device=device,
                         on_epoch=on_epoch)
    model.metadata["training"]["command"] = command
    save_model(model, out, overwrite=force)
    return model


def fit_uncertainty(model: Any, output: str | Path, drives: Sequence[DriveLike] | None = None, *,
                    bias_from: DriveLike | None = None, read: ReadOptions | None = None, force: bool = False,
                    command: str = "ionav_viz.fit_uncertainty") -> Any:
    """Give a trained model (a model directory, ``"shipped"`` or an ``IdnnModel``) an uncertainty
    (or a new one) without changing its networks, and write it to ``output`` (a model directory, as
    :func:`train` writes it; its weight files are the model's, byte for byte).

    ``drives``: the drives to fit it on (default the bundled synthetic training drives, which the
    shipped model was trained on); see :func:`ionav_viz.learning.training.fit_uncertainty`. Returns the
    model with its uncertainty."""
    from ..learning.idnn import check_model_dir, save_model
    from ..learning.training import add_uncertainty

    read = read if read is not None else ReadOptions()
    model = parent_model(model)
    specs = training_drives() if drives is None else drives
    refuse_output_onto_input(Path(output), input_paths([*specs, *([bias_from] if bias_from is not None else [])], read),
                             output_is_folder=True)
    out = check_model_dir(Path(output), overwrite=force)
    stationary = load_stationary(bias_from, read)
    loaded = [(d, resolve_bias(d, stationary)) for d in load_drives(specs, read)]
    add_uncertainty(model, loaded)
    if model.uncertainty is not None:
        model.metadata["uncertainty"]["command"] = command
    save_model(model, out, overwrite=force)
    return model


def parent_model(from_model: Any) -> Any:
    """The model to fine-tune: an ``IdnnModel``, a model directory, or ``"shipped"``."""
    from ..learning.idnn import IdnnModel, default_model_dir, load_model

    if isinstance(from_model, IdnnModel):
        return from_model
    if isinstance(from_model, str) and from_model == "shipped":
        return load_model(default_model_dir())
    if not isinstance(from_model, (str, Path)):
        raise InputError(f"from_model={from_model!r} is not a model", "give a model directory or 'shipped'",
                         param="from_model")
    try:
        return load_model(from_model)
    except InputError as exc:
        exc.param = "from_model"
        raise


def fine_tune_settings(parent: Any, epochs_disp: int | None = None, epochs_yaw: int | None = None,
                       seed: int | None = None) -> Any:
    """The ``ModelConfig`` for fine-tuning ``parent`` (a model, its directory or ``"shipped"``): its
    architecture, lower learning rates with a cosine decay, fewer epochs
    (:func:`ionav_viz.learning.training.fine_tune_config` says why)."""
    from ..learning.training import fine_tune_config

    return fine_tune_config(parent_model(parent).config, epochs_disp, epochs_yaw, seed)


def training_device(device: str | None = None) -> str:
    """Where training runs: ``device`` (``"cpu"`` or ``"cuda"``), or with None or ``"auto"``
    ``"cuda"`` when torch sees a GPU, else ``"cpu"``. ``"cuda"`` without a GPU torch can use, or
    another name, is an ``InputError``."""
    if device is not None and device not in DEVICES:
        raise InputError(f"unknown device {device!r}", f"choose one of {', '.join(DEVICES)}", param="device")
    if device == "cpu":
        return device
    import torch

    if device == "cuda" and not torch.cuda.is_available():
        raise InputError("device 'cuda': torch sees no GPU here", "train on the CPU (device 'cpu' or 'auto')",
                         param="device")
    return "cuda" if torch.cuda.is_available() else "cpu"
