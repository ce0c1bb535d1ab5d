"""K-fold cross-validation of the IDNN (``ionav-viz cross-validate``): the protocol a reviewer asks for.

With K or more drives, the folds are by drive: fold ``i`` tests on drives ``i, i + K, i + 2K, ...``
(in the order given) and trains on the others. With one drive, the folds are by time: the drive
(within ``read.span``) is cut into K blocks of equal length; fold ``i`` tests on block ``i`` and
trains on the others, which touch it only at its ends. Every fold trains its own model (from random
weights, or fine-tuning ``from_model``) and scores it and the INS DR on its test outages, with the
leakage check strict: an outage in that fold's training data is an error, never a score.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict, Unpack

from ..core.drive import Drive
from ..core.durations import Span
from ..core.errors import InputError
from ..core.signals import hold_signals
from ..sources.load import ReadOptions, crop_to_span, load_drives
from .options import DriveLike, Progress, RunOptions, options_of

if TYPE_CHECKING:
    from ..learning.idnn import IdnnModel, ModelConfig
    from .training import TrainingOptions


@dataclass
class Fold:
    """One fold: what it trained and tested on (``name span``), its outages and mean displacement
    CRSE (m) per estimator, the IDNN's improvement over the INS DR (%), and the training time (s)."""

    index: int
    train: list[str]
    test: list[str]
    n_outages: int
    crse_m: dict[str, float]
    improvement_pct: float
    train_s: float


@dataclass
class CrossValidation:
    """The folds of :func:`cross_validate` and the spread of their test metrics."""

    folds: list[Fold]
    by: str  # "drive" or "time"
    outage_s: float
    device: str
    training: str  # "from random weights" or "fine-tuning <parent>"
    warnings: list[str] = field(default_factory=list)

    def spread(self, values: Sequence[float]) -> dict[str, float]:
        n = len(values)
        mean = sum(values) / n
        sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1)) if n > 1 else 0.0
        return {"mean": mean, "sd": sd, "min": min(values), "max": max(values)}

    def summary(self) -> dict[str, Any]:
        """Per estimator the spread of the folds' CRSEs (``ins_crse_m``: mean, sd, min, max);
        ``idnn_improvement_pct``: the IDNN's improvement over the INS DR of those mean CRSEs (%, as
        the mean row shows it); ``idnn_improvement_pct_by_fold``: the spread of the folds' own
        improvements (%; their mean is not the improvement of the means)."""
        names = list(self.folds[0].crse_m)
        out: dict[str, Any] = {f"{name}_crse_m": self.spread([f.crse_m[name] for f in self.folds]) for name in names}
        ins, idnn = out["ins_crse_m"]["mean"], out["idnn_crse_m"]["mean"]
        out["idnn_improvement_pct"] = 100.0 * (ins - idnn) / ins
        out["idnn_improvement_pct_by_fold"] = self.spread([f.improvement_pct for f in self.folds])
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``cross-validate --json`` object (docs/report-schema.md)."""
        from ..analysis.schema import tagged

        return tagged("cross-validation", {"by": self.by, "folds": [vars(f) for f in self.folds],
                                           "outage_s": self.outage_s, "device": self.device, "training": self.training,
                                           "summary": self.summary(), "warnings": list(self.warnings)})

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    def to_text(self) -> str:
        rows = [f"{len(self.folds)}-fold cross-validation by {self.by}, {self.outage_s:g} s outages, {self.training}, "
                f"trained on {self.device}",
                f"{'fold':>4}  {'outages':>7}  {'INS DR CRSE (m)':>15}  {'IDNN CRSE (m)':>13}  {'IDNN vs INS DR':>14}  "
                f"{'training':>8}  test"]
        for f in self.folds:
            rows.append(f"{f.index + 1:>4}  {f.n_outages:>7}  {f.crse_m['ins']:>15.2f}  {f.crse_m['idnn']:>13.2f}  "
                        f"{f.improvement_pct:>+13.1f}%  {f.train_s:>7.1f}s  {', '.join(f.test)}")
        s = self.summary()
        ins, idnn, gain = s["ins_crse_m"], s["idnn_crse_m"], s["idnn_improvement_pct_by_fold"]
        rows.append(f"{'mean':>4}  {sum(f.n_outages for f in self.folds):>7}  {ins['mean']:>15.2f}  "
                    f"{idnn['mean']:>13.2f}  {s['idnn_improvement_pct']:>+13.1f}%")
        rows.append(f"spread over folds: IDNN CRSE sd {idnn['sd']:.2f} m (min {idnn['min']:.2f}, max "
                    f"{idnn['max']:.2f}); IDNN vs INS DR sd {gain['sd']:.1f} points (min {gain['min']:+.1f} %, max "
                    f"{gain['max']:+.1f} %)")
        return "\n".join(rows)


class CrossValidateKeywords(TypedDict, total=False):
    """:func:`cross_validate`'s keyword arguments beside the settings, output and progress: ``read``,
    how drives are read (``read.span`` limits every drive first); ``run``, its ``bias_from`` and
    warm-up are used; ``from_model`` and ``device`` (deprecated:
    :class:`~ionav_viz.api.training.TrainingOptions`)."""

    read: ReadOptions | None
    run: RunOptions | None
    from_model: str | Path | IdnnModel | None
    device: str | None


def cross_validate(
    drives: Sequence[DriveLike],
    folds: int = 5,
    outage_s: float = 10.0,
    *,
    config: ModelConfig | TrainingOptions | None = None,
    output: str | Path | None = None,
    progress: Progress | None = None,
    **keywords: Unpack[CrossValidateKeywords],
) -> CrossValidation:
    """Train ``folds`` models, each tested on data it never saw (module docstring), and report each
    fold's test metrics and their spread.

    ``config``: a :class:`~ionav_viz.api.training.TrainingOptions` (the settings, default the
    shipped model's, or with ``from_model`` :func:`~ionav_viz.api.training.fine_tune_settings`; the
    model fine-tuned from; where torch trains, default ``"cuda"`` when torch sees a GPU, else the
    CPU), or only the settings (a ``ModelConfig``); ``output``: a folder to write each fold's model
    into (``fold-1`` ...); ``keywords``: ``read`` and ``run`` (:class:`CrossValidateKeywords`).
    """
    import time

    from ..core.warnings_log import printing_once
    from ..learning.idnn import ModelConfig, check_model_dir, save_model
    from ..learning.training import train_models
    from .options import windows_of
    from .run import evaluate
    from .training import parent_model, training_device, training_of

    unknown = sorted(set(keywords) - set(CrossValidateKeywords.__annotations__))
    if unknown:
        raise TypeError(f"cross_validate() got an unexpected keyword argument {unknown[0]!r}")
    training = training_of(config, keywords)
    config, from_model, device = training.config, training.from_model, training.device
    run, read = keywords.get("run"), keywords.get("read")

    if isinstance(folds, bool) or not isinstance(folds, int) or folds < 2:
        raise InputError(f"{folds!r} folds: need at least 2", "give --folds 2 or more (5 is usual)", param="folds")
    windows_of(outage_s)
    items = [drives] if isinstance(drives, (Drive, str, Path)) else list(drives)
    if not items:
        raise InputError("no drive to cross-validate",
                         "give one long drive (folds by time) or at least as many drives as folds")
    if 1 < len(items) < folds:
        raise InputError(f"{len(items)} drives for {folds} folds by drive",
                         f"give at least {folds} drives, or one drive (folds by time blocks)", param="folds")
    run, read = options_of(run, None, read, None)  # checked: run="x" was an AttributeError
    parent = parent_model(from_model) if from_model is not None else None
    config = config if config is not None else (ModelConfig() if parent is None else _fine_tune(parent))
    config.validate()
    out_dir = Path(output) if output is not None else None
    if out_dir is not None:
        if not out_dir.is_dir():
            what = "is not a directory" if out_dir.exists() else "does not exist"
            raise InputError(f"{out_dir}: {what}",
                             "give an existing folder for the folds' models (fold-1, fold-2, ...)", param="output")
        numbers = (re.fullmatch(r"fold-([1-9][0-9]*)", p.name) for p in out_dir.iterdir())
        taken = sorted(n for m in numbers if m and (n := int(m.group(1))) <= folds)
        if taken:  # every fold's directory before any training, not fold-1 alone (listed: --folds may be huge)
            raise InputError(f"{out_dir / f'fold-{taken[0]}'}: exists already",
                             "give an empty folder, or remove the earlier folds' models from it", param="output")
        check_model_dir(out_dir / "fold-1", overwrite=False)  # the same checks for every fold's directory beside it
    loaded = load_drives(items, read)
    by = "time" if len(loaded) == 1 else "drive"
    need_s = float(run.warm_up_s) + float(outage_s)  # every fold's test drive needs the warm-up and an outage
    short = [d for d in loaded if d.duration_s < need_s - 1e-6] if by == "drive" else []
    if short:
        raise InputError(f"{short[0].source or short[0].name}: {short[0].duration_s:.0f} s is too short to test on: a "
                         f"fold tests its outages after the {float(run.warm_up_s):g} s warm-up ({need_s:g} s with "
                         f"{float(outage_s):g} s outages)",
                         "leave it out, give longer drives or shorter outages (--outage)", param="drives")
    splits = _time_blocks(loaded[0], folds, need_s) if by == "time" else [
        ([d for j, d in enumerate(loaded) if j % folds != i], [d for j, d in enumerate(loaded) if j % folds == i])
        for i in range(folds)]
    device = training_device(device)  # after the folds are checked: said before an error, it was a second line
    bias_of = run.bias_of(read)
    results = []
    warned: list[str] = []
    written: list[Path] = []  # the folds' models this run wrote: removed when it fails or is stopped
    with printing_once():  # a warning each fold repeats (the drive's biases, the uncertainty not fitted) is said once
        try:
            for i, (train_set, test_set) in enumerate(splits):
                def step(label: str, done: int, total: int, i: int = i) -> None:
                    if progress:
                        progress(f"fold {i + 1}/{folds}: training {label}", done, total)

                started = time.perf_counter()
                model = train_models([(d, bias_of(d)) for d in train_set], config, step,
                                     f"cross-validation fold {i + 1} of {folds} (by {by})", parent=parent,
                                     device=device)
                train_s = time.perf_counter() - started
                if out_dir is not None:
                    model.metadata["training"]["command"] = "ionav_viz.cross_validate"
                    written.append(out_dir / f"fold-{i + 1}")  # before: a signal as save_model returns leaves it listed
                    save_model(model, out_dir / f"fold-{i + 1}")
                if progress:
                    progress(f"fold {i + 1}/{folds}: testing", 0, 1)
                try:
                    report = evaluate(test_set, outage_s, estimators=["ins", "idnn"],
                                      run=replace(run, estimators=None, plugins=(), without=(), model=model,
                                                  strict=True), read=replace(read, span=None))
                except InputError as exc:
                    if exc.param != "strict":
                        raise
                    raise _leak(exc, i, parent, model) from None
                data = json.loads(report.to_json())
                warned += [w for w in data.get("warnings", []) if w not in warned]
                crse = {name: data["summary"][name]["crse_m"]["mean"] for name in ("ins", "idnn")}
                results.append(Fold(i, [_label(d) for d in train_set], [_label(d) for d in test_set],
                                    int(data["n_sequences"]), crse, 100.0 * (crse["ins"] - crse["idnn"]) / crse["ins"],
                                    train_s))
                if progress:
                    progress(f"fold {i + 1}/{folds}: done", 1, 1)
        except BaseException:
            release = hold_signals()
            try:
                for folder in written:
                    shutil.rmtree(folder, ignore_errors=True)
            finally:
                release()
            raise
    training = "from random weights" if parent is None else f"fine-tuning {model.metadata['parent']['directory']}"
    return CrossValidation(results, by, float(outage_s), device, training, warned)


def _leak(exc: InputError, i: int, parent: Any, model: Any) -> InputError:
    """The leakage check's refusal of fold ``i``'s test outages (always strict here) said for
    cross-validate: which fold, the model fine-tuned from which parent, and what to change (the
    message blamed a --strict the command does not have, and a model "(in memory)")."""
    if parent is not None:
        name = model.metadata.get("parent", {}).get("directory", "the parent model")
        name = "the shipped model" if name == "shipped" else name
        text = exc.message.replace("the IDNN model (in memory)",
                                   f"fold {i + 1}'s model (fine-tuned from {name}) or its parent")
        return InputError(f"fold {i + 1}: {text}",
                          f"cross-validate on drives {name} was not trained on, or from random weights (leave out "
                          "--from-model)", param="from_model")
    text = exc.message.replace("the IDNN model (in memory)", f"fold {i + 1}'s model")
    return InputError(f"fold {i + 1}: {text}", "give each drive once: the same file twice puts it in training and test",
                      param="drives")


def _fine_tune(parent: Any) -> Any:
    from ..learning.training import fine_tune_config

    return fine_tune_config(parent.config)


def _label(drive: Drive) -> str:
    return f"{drive.name} {drive.t_s[0]:.0f}-{drive.t_s[-1]:.0f}s"


def _time_blocks(drive: Drive, folds: int, need_s: float = 30.0) -> list[tuple[list[Drive], list[Drive]]]:
    """K contiguous blocks of equal length of one drive: per fold (the other blocks, [block i]).
    Each must last ``need_s`` (the warm-up and one outage, 30 s at least), or no outage is tested in it."""
    t0, t1 = float(drive.t_s[0]), float(drive.t_s[-1])
    need_s = max(30.0, need_s)
    blocks = []
    if folds <= (t1 - t0) / need_s + 1e-6:  # checked before the blocks are made: --folds 10**20 was a MemoryError
        edges = [t0 + (t1 - t0) * k / folds for k in range(folds + 1)]
        with contextlib.suppress(InputError):
            blocks = [crop_to_span(drive, Span(edges[k], edges[k + 1])) for k in range(folds)]
    if len(blocks) < folds or min(b.duration_s for b in blocks) < need_s - 1e-6:
        fit = int((t1 - t0) / need_s + 1e-6)
        raise InputError(f"{drive.source or drive.name}: {t1 - t0:.0f} s is too short for {folds} time blocks of "
                         f"{need_s:g} s or more (each tests an outage after the warm-up)",
                         f"give at most {fit} folds, shorter outages or a longer drive" if fit >= 2
                         else "give shorter outages or a longer drive",
                         param="folds")
    return [([b for j, b in enumerate(blocks) if j != i], [blocks[i]]) for i in range(folds)]


__all__ = ["CrossValidation", "Fold", "cross_validate"]
