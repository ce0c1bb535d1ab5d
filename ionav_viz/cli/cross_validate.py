"""``ionav-viz cross-validate``: K models, each tested on drives or time blocks it never saw."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Optional

import typer

from . import common as c
from .app import app

if TYPE_CHECKING:
    from ..api.options import ReadOptions


@app.command("cross-validate")
@c.with_source_options
def cross_validate(
    drives: list[str] = typer.Argument(...,
                                       help="Drives of one vehicle: K or more (folds by drive), or one long drive "
                                            "(folds by time blocks)."),
    folds: int = typer.Option(5, "--folds", help="Number of folds (models trained)."),
    outage: str = c.OutageOpt,
    from_model: Optional[str] = typer.Option(None, "--from-model",
                                             help="Fine-tune this model in every fold (a model directory, or "
                                                  "'shipped') instead of training from random weights.",
                                             show_default=False),
    epochs_disp: Optional[int] = c.EpochsDispOpt,
    epochs_yaw: Optional[int] = c.EpochsYawOpt,
    seed: int = c.TrainSeedOpt,
    output: Optional[Path] = typer.Option(None, "-o", "--output",
                                          help="An existing folder to write each fold's model into (fold-1, "
                                               "fold-2, ...).", show_default=False),
    bias_from: Optional[str] = c.BiasFromOpt,
    as_json: bool = typer.Option(False, "--json", help="Print the folds and their spread as JSON."),
    quiet: bool = c.QuietOpt,
    # ReadOptions: --span, --data-root, --yaw-sign, log topics and stamps, --gnss-limit (c.with_source_options)
    read: ReadOptions | None = None,
) -> None:
    """Train K models, each tested on drives (or time blocks of one drive) it never saw; per-fold metrics and spread."""
    from .. import api
    from ..api.cross_validate import cross_validate as run_folds
    from ..api.training import training_device
    from ..learning.idnn import ModelConfig

    outage_s = c.duration_s(outage, "--outage")
    if from_model is not None:
        config = api.fine_tune_settings(from_model, epochs_disp, epochs_yaw, seed)
    else:
        config = ModelConfig(epochs_disp=epochs_disp or ModelConfig.epochs_disp, epochs_yaw=epochs_yaw or
                             ModelConfig.epochs_yaw, seed=seed)
    device = training_device()
    with c.progress(quiet) as bar:
        advance, said = c.progress_callback(bar, "cross-validating"), []

        def step(text: str, done: int, total: int) -> None:
            if not said and not quiet:  # once the folds are checked (said before their error, it was a second line)
                said.append(f"training on {_device_text(device)}")
                if bar is not None:
                    bar.console.print(said[0], markup=False, highlight=False)
                else:
                    print(said[0], file=sys.stderr)
            advance(text, done, total)

        result = run_folds(drives, folds, outage_s, config=api.TrainingOptions(config, from_model, device),
                           output=output, progress=step, read=read, run=api.RunOptions(bias_from=bias_from))
    print(result.to_json() if as_json else result.to_text())


def _device_text(device: str) -> str:
    if device == "cpu":
        return "the CPU (torch sees no GPU)"
    import torch

    return f"the GPU ({device}: {torch.cuda.get_device_name(0)})"
