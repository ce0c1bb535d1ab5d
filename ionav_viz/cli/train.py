"""``ionav-viz train`` and ``architectures``: the IDNN's two networks and their sizes."""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import typer

from . import common as c
from .app import app

if TYPE_CHECKING:
    from ..api.options import ReadOptions


def training_command(argv: list[str]) -> str:
    """The command that trained a model, without the options that only say where and how loudly
    (so the same training gives the same metadata wherever it is written)."""
    words, skip = ["ionav-viz"], False
    for arg in argv:
        if skip:
            skip = False
            continue
        if arg in ("-o", "--output"):
            skip = True
            continue
        if arg.startswith("--output=") or arg in ("--force", "-q", "--quiet", "--debug", "-v", "--verbose"):
            continue
        words.append(arg)
    return " ".join(words)


#: Without a terminal, a line of training progress at most this often (s).
PLAIN_PROGRESS_EVERY_S = 5.0


def progress_line(status: Any) -> str:
    """One line of training progress: the fit, its epoch, its loss, time elapsed and left."""
    val = f", validation {status.validation_loss:.4g}" if status.validation_loss is not None else ""
    return (f"training: {status.label}, epoch {status.epoch}/{status.epochs}, loss {status.loss:.4g}{val}; "
            f"{status.elapsed_s:.0f} s elapsed, about {status.left_s:.0f} s left")


@contextlib.contextmanager
def training_progress(quiet: bool, stream: Any = None) -> Iterator[Optional[Callable[[Any], None]]]:
    """An ``on_epoch`` callback for :func:`ionav_viz.train`: on a terminal a bar of the whole
    training (optimiser steps done of those planned) with the fit, its epoch and loss, time elapsed
    and left; otherwise a plain line (:func:`progress_line`) at most every
    :data:`PLAIN_PROGRESS_EVERY_S` seconds; None when ``quiet``."""
    stream = stream or sys.stderr
    if quiet:
        yield None
        return
    if not stream.isatty():
        last = [time.monotonic()]

        def plain(status: Any) -> None:
            now = time.monotonic()
            if now - last[0] >= PLAIN_PROGRESS_EVERY_S:
                last[0] = now
                print(progress_line(status), file=stream, flush=True)

        yield plain
        return
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    columns = (BarColumn(bar_width=16), TextColumn("{task.description}"), TextColumn("epoch {task.fields[epoch]}"),
               TextColumn("loss {task.fields[loss]}"), TimeElapsedColumn(), TextColumn("{task.fields[left]}"))
    with Progress(*columns, console=Console(file=stream), transient=True) as bar:
        # the description: the fit being trained
        task = bar.add_task("training", total=None, epoch="", loss="", left="")

        def update(status: Any) -> None:
            bar.update(task, description=status.label, completed=status.steps_done, total=status.steps_planned,
                       epoch=f"{status.epoch}/{status.epochs}", loss=f"{status.loss:.4g}",
                       left=f"about {status.left_s:.0f} s left")

        yield update


@app.command()
@c.with_source_options
def train(
    drives: Optional[list[str]] = typer.Argument(None,
                                                 help="Training drives (default: the bundled synthetic "
                                                      "training drives)."),
    output: Path = typer.Option(..., "-o", "--output",
                                help="Model directory to write (weights + metadata.json); it must not exist yet, "
                                     "unless --force."),
    force: bool = typer.Option(False, "--force",
                               help="Replace an existing model directory (atomically: the old one stays if "
                                    "training fails)."),
    paper_train: bool = typer.Option(False, "--paper-train",
                                     help="Train on the paper's Table 1 runs under the data root."),
    arch: str = typer.Option("idnn", "--arch", help="idnn (the paper's), mlp, rnn, gru or lstm (Section 3.3)."),
    steps: int = typer.Option(14, "--steps",
                              help="Time steps (10 Hz samples) of acceleration per displacement input (Table 4; "
                                   "10 = 1 s, 20 = 2 s; 14 as the shipped model)."),
    steps_yaw: int = typer.Option(10, "--steps-yaw",
                                  help="Time steps of gyro yaw rate per orientation-rate input (Table 3)."),
    epochs_disp: Optional[int] = c.EpochsDispOpt,
    epochs_yaw: Optional[int] = c.EpochsYawOpt,
    from_model: Optional[str] = typer.Option(None, "--from-model",
                                              help="Fine-tune this model (a model directory, or 'shipped'): its "
                                                   "weights and normalisation are the start; learning rates / 2, "
                                                   "cosine decay (README, 'Your own vehicle').", show_default=False),
    feedback_noise: float = typer.Option(0.1, "--feedback-noise",
                                         help="Std (m) of the white noise on the fed-back GNSS displacement "
                                              "in training."),
    residual: bool = typer.Option(True, "--residual/--no-residual",
                                  help="Kinematic skip terms (docs/method.md, 'The IDNN'); --no-residual is the "
                                       "paper's plain net."),
    lr_decay_tail: float = typer.Option(0.3, "--lr-decay-tail",
                                        help="Fraction of the training over which the learning rate falls linearly to "
                                             "0 at the end (0 = constant, as in the paper)."),
    inputs: str = typer.Option("calibrated", "--inputs",
                               help="calibrated (shipped): samples corrected by the GNSS-aided INS at the outage "
                                    "start; plain: by the standstill biases (the paper)."),
    seed: int = c.TrainSeedOpt,
    quiet: bool = typer.Option(False, "--quiet", "-q",
                               help="No progress (a bar on a terminal, else a line every few seconds)."),
    device: str = typer.Option("auto", "--device", help="auto: a GPU when torch sees one, else the CPU; cpu; cuda. "
                                                        "Deterministic for a seed on the CPU."),
    bias_from: Optional[str] = c.BiasFromOpt,
    # ReadOptions: --data-root, --yaw-sign, log topics and stamps, --gnss-limit (c.with_source_options)
    read: ReadOptions | None = None,
) -> None:
    """Train the displacement and orientation-rate networks and write them with their metadata."""
    from .. import api
    from ..learning.idnn import ModelConfig

    if paper_train and drives:  # the drives were dropped silently for the paper's runs
        raise typer.BadParameter(f"--paper-train trains on the paper's runs, and {len(drives)} drive(s) were given "
                                 "too: give one or the other",
                                 param_hint="--paper-train")
    if from_model is not None:
        defaults = ModelConfig()
        given = [option for option, value, default in (("--arch", arch, defaults.arch),
                                                       ("--steps", steps, defaults.n_steps_disp),
                                                       ("--steps-yaw", steps_yaw, defaults.n_steps_yaw),
                                                       ("--inputs", inputs, defaults.inputs),
                                                       ("--no-residual", residual, defaults.residual),
                                                       ("--lr-decay-tail", lr_decay_tail, defaults.lr_decay_tail),
                                                       ("--feedback-noise", feedback_noise, defaults.feedback_noise_m))
                 if value != default]
        if given:
            raise typer.BadParameter(f"{given[0]} with --from-model: a fine-tuned model keeps its parent's "
                                     "architecture and schedule", param_hint=given[0])
        config = api.fine_tune_settings(from_model, epochs_disp, epochs_yaw, seed)
    else:
        config = ModelConfig(arch=arch, n_steps_disp=steps, n_steps_yaw=steps_yaw,
                             epochs_disp=epochs_disp or ModelConfig.epochs_disp,
                             epochs_yaw=epochs_yaw or ModelConfig.epochs_yaw, feedback_noise_m=feedback_noise,
                             residual=residual, lr_decay_tail=lr_decay_tail, inputs=inputs, seed=seed)
    specs = (api.training_drives(paper=True, data_root=read.data_root)
             if paper_train else (list(drives) if drives else None))
    with training_progress(quiet) as on_epoch:
        model = api.train(output, specs, api.TrainingOptions(config, from_model, device), read=read, force=force,
                          on_epoch=on_epoch, bias_from=bias_from, command=training_command(sys.argv[1:]))
    val = model.metadata["validation"]
    params = model.metadata["trainable_parameters"]
    from ..core.grid import WINDOW_S
    from ..learning.training import EXAMPLE_STEP_S

    print(f"trained {arch} on {len(model.metadata['training']['drives'])} drive(s), "
          f"{model.metadata['training']['n_examples']} training examples ({WINDOW_S:g} s windows every "
          f"{EXAMPLE_STEP_S:g} s); trainable parameters: displacement {params['displacement']}, orientation rate "
          f"{params['yaw_rate']}", file=sys.stderr)
    if "parent" in model.metadata:
        print(f"fine-tuned from {model.metadata['parent']['directory']}", file=sys.stderr)
        blend = model.metadata.get("epoch_selection", {}).get("ins_blend")
        if blend is not None and blend["kept"] != blend["parent"]:
            means, kept, before = blend["mean_m"], blend["kept"], blend["parent"]
            print(f"displacement: {100 * kept:.0f} % the INS DR's, {100 * (1 - kept):.0f} % the network's "
                  "(displacement CRSE of the "
                  f"drive's own outages: the INS DR {means['1']:.2f} m, the parent {means[f'{before:g}']:.2f} m, "
                  f"the blend {means[f'{kept:g}']:.2f} m)", file=sys.stderr)
    print(f"validation MAE: displacement {val['disp_mae_m']:.3f} m, orientation rate "
          f"{val['yaw_rate_mae_radps']:.4f} rad/s", file=sys.stderr)
    if (unc := model.metadata.get("uncertainty")) is not None and "inherited" in unc:
        print(f"uncertainty: {unc['inherited']}", file=sys.stderr)
    elif unc is not None:
        inside = ", ".join(f"{100 * v:.0f} % at {k}" for k, v in unc["coverage_95"].items())
        print(f"uncertainty: the 95 % ellipse holds the training outages' position errors {inside}", file=sys.stderr)
    else:
        print(f"uncertainty: {model.metadata.get('uncertainty_skipped', 'not fitted')}", file=sys.stderr)
    print(output)


@app.command()
def architectures(
    steps: int = typer.Option(10, "--steps", help="Time steps (10 Hz samples) per input, 1-20."),
) -> None:
    """Trainable parameters of each network per hidden width, laid out like the paper's Table 2."""
    from ..learning.idnn import ARCHS, ModelConfig, build_net, count_parameters

    ModelConfig(n_steps_disp=steps).validate()  # the time steps a model may have (1-20), as train checks them
    widths = (8, 16, 32, 64, 128, 192, 256, 320)
    print("hidden units  " + "  ".join(f"{a.upper():>8}" for a in ARCHS)
          + "   (displacement model, with feedback input)")
    for width in widths:
        counts = [count_parameters(build_net(a, steps, width, 0.1, True)) for a in ARCHS]
        print(f"{width:>12}  " + "  ".join(f"{c:>8,}" for c in counts))
