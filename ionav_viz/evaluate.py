"""Run the estimators on the same outage sequences of a drive and collect the paper's metrics.

:func:`evaluate_drive` is the one pure entry point used by ``evaluate`` and ``replay``: it cuts
the drive into windows, places the outages, runs INS dead reckoning (and the IDNN when a
model is given) and returns a :class:`DriveResult`. :func:`report` turns results into the JSON
object that ``ionav-viz evaluate --json`` prints.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .drive import Drive
from .ins import Estimate, SensorBias, dead_reckon, estimate_bias
from .metrics import METRICS, sequence_metrics, summarise, truth_for
from .outages import outage_windows, tile
from .windows import Windows, make_windows

if TYPE_CHECKING:
    from .idnn import IdnnModel

log = logging.getLogger("ionav_viz")


@dataclass
class DriveResult:
    """Everything computed for one drive: windows, outages, estimates and metrics per estimator."""

    drive: Drive
    windows: Windows
    outage_s: float
    starts: np.ndarray
    bias: SensorBias
    estimates: dict[str, Estimate]
    metrics: dict[str, dict[str, np.ndarray]]
    model_info: dict[str, Any] = field(default_factory=dict)

    @property
    def n_windows(self) -> int:
        return outage_windows(self.outage_s)

    @property
    def gnss_distance_m(self) -> np.ndarray:
        disp, _ = truth_for(self.windows, self.starts, self.n_windows)
        return disp.sum(axis=1)


def resolve_bias(drive: Drive, stationary: Drive | None = None) -> SensorBias:
    """Biases from ``stationary`` if given, else from the drive's own stationary stretches, else none."""
    if stationary is not None:
        bias = estimate_bias(stationary)
        if bias is None:
            from .errors import InputError

            raise InputError(
                f"{stationary.source}: stands still for less than 3 s",
                "--bias-from needs a stationary recording (e.g. the bundled 'stationary' drive)",
            )
        return bias
    bias = estimate_bias(drive)
    if bias is None:
        log.warning(
            "%s: no stationary stretch of 3 s to estimate sensor biases; INS runs uncorrected "
            "(pass --bias-from STATIONARY_DRIVE)",
            drive.name,
        )
        return SensorBias.none()
    return bias


def evaluate_drive(
    drive: Drive,
    outage_s: float,
    *,
    bias: SensorBias | None = None,
    model: "IdnnModel | None" = None,
    starts: np.ndarray | None = None,
    windows: Windows | None = None,
) -> DriveResult:
    """INS (and IDNN) on the outages ``starts`` (default: the paper's tiling) of ``drive``."""
    n = outage_windows(outage_s)
    windows = windows if windows is not None else make_windows(drive)
    starts = tile(windows, n) if starts is None else np.asarray(starts, dtype=int)
    bias = bias if bias is not None else resolve_bias(drive)
    estimates = {"ins": dead_reckon(windows, starts, n, bias)}
    model_info: dict[str, Any] = {}
    if model is not None:
        estimates["idnn"] = model.predict(windows, starts, n, bias)
        model_info = model.describe()
    metrics = {name: sequence_metrics(windows, starts, n, est) for name, est in estimates.items()}
    return DriveResult(drive, windows, float(outage_s), starts, bias, estimates, metrics, model_info)


def report(results: list[DriveResult]) -> dict[str, Any]:
    """The ``evaluate --json`` object: per-sequence metrics and summaries per estimator.

    Keys: ``drive`` (names joined with '+'), ``drives``, ``outage_s``, ``sequences`` (each:
    ``drive``, ``start_s``, ``gnss_distance_m`` and per estimator the :data:`METRICS`),
    ``summary`` (per estimator and metric: ``max``, ``min``, ``mean``, ``std``),
    ``distance_m`` (max/min/mean of the sequences' GNSS distance), ``n_sequences``,
    ``improvement_pct`` (IDNN over INS on mean CRSE, when both ran), ``bias`` and ``model``.
    """
    if not results:
        raise ValueError("no results")
    estimators = list(results[0].estimates)
    sequences = []
    for res in results:
        dist = res.gnss_distance_m
        for i, k in enumerate(res.starts):
            entry: dict[str, Any] = {
                "drive": res.drive.name,
                "start_s": round(float(res.windows.t0_s[k]), 3),
                "gnss_distance_m": float(dist[i]),
            }
            for est in estimators:
                entry[est] = {m: float(res.metrics[est][m][i]) for m in METRICS}
            sequences.append(entry)
    summary = {
        est: {m: summarise(np.concatenate([r.metrics[est][m] for r in results])) for m in METRICS}
        for est in estimators
    }
    distances = np.concatenate([r.gnss_distance_m for r in results])
    out: dict[str, Any] = {
        "drive": "+".join(r.drive.name for r in results),
        "drives": [{"name": r.drive.name, "source": r.drive.source} for r in results],
        "outage_s": results[0].outage_s,
        "n_sequences": len(sequences),
        "sequences": sequences,
        "summary": summary,
        "distance_m": {k: v for k, v in summarise(distances).items() if k != "std"},
        "bias": [
            {"drive": r.drive.name, "accel_mps2": r.bias.accel_mps2, "gyro_radps": r.bias.gyro_radps, "source": r.bias.source}
            for r in results
        ],
    }
    if "idnn" in summary:
        out["improvement_pct"] = {
            m: improvement_pct(summary["ins"][m]["mean"], summary["idnn"][m]["mean"])
            for m in ("crse_m", "yaw_crse_radps", "final_position_error_m")
        }
        out["model"] = results[0].model_info
    return out


def improvement_pct(baseline: float, candidate: float) -> float:
    """How much lower ``candidate`` is than ``baseline``, in percent of the baseline."""
    if not np.isfinite(baseline) or baseline == 0:
        return float("nan")
    return 100.0 * (baseline - candidate) / baseline
