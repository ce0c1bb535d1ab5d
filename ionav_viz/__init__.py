"""ionav-viz: replay drives, inject GNSS outages, compare INS dead reckoning, the IDNN and your own
estimators, and review them in Rerun.

The public API (see "Python API" in the README, and docs/ for the reference)::

    import ionav_viz as iv

    drive = iv.load_drive("roundabout")
    report = iv.evaluate([drive], outage_s=10.0, estimators=["ins", "idnn"])
    result = iv.replay(drive, placement=iv.Every(30.0), output="roundabout.rrd",
                       run=iv.RunOptions(bias_from="stationary"), read=iv.ReadOptions(yaw_sign="auto"))
    iv.screenshot([result.path], "shots/", iv.Shots(times=["worst"]))

    exp = iv.Experiment(["roundabout", "motorway"], outage_s=[10, 30], run=iv.RunOptions(estimators=["ins"]))
    reports = iv.evaluate(exp)                            # {10.0: Report, 30.0: Report}
    fleet = iv.evaluate(iv.Experiment(["logs/"], 10.0, engine=iv.Engine(workers=4)))  # a FleetReport

An :class:`Experiment` is one run's set-up (drives, outage lengths, placement, run and read
options, engine, plan, externals); ``evaluate`` and ``replay`` take one or its fields as arguments,
and its fields choose the variant: several outage lengths, ``by_event``, a fleet (``engine``), a
``scenario``.

Data flows one way through the subpackages (a test enforces it):

    core (drive model, errors, grid)  <-  dataset (catalog, samples, fetch)  <-  sources (readers)
    <-  nav (windows, kernels, INS DR, filters, estimator plug-ins)  <-  learning (the IDNN)
    <-  experiment (outage placement, the estimators' registry)  <-  analysis (metrics, events,
    reports)  <-  sim  <-  viz (recordings, screenshots)  <-  api  <-  cli

Names are imported lazily, so ``import ionav_viz`` (and ``ionav-viz --help``) stays fast.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

_EXPORTS = {
    "load_drive": "sources.load", "evaluate": "api", "find_events": "api", "detector_quality": "api", "train": "api",
    "training_drives": "api", "replay_scenario": "api", "simulate": "api", "convert": "api", "fetch": "api",
    "list_runs": "api", "RunSelection": "api", "DatasetSource": "api", "WebServing": "api",
    "evaluate_by_event": "api", "evaluate_lengths": "api", "replay_lengths": "api", "replay": "api",
    "screenshot": "api", "scenario_drives": "api", "serve_web": "api", "ReplayResult": "api", "Outage": "api",
    "RunOptions": "api", "Shots": "api", "outage_log": "api", "figures": "api", "compare": "api",
    "Comparison": "analysis.compare", "OutageLogResult": "api", "FromPlan": "experiment.plan_file",
    "Report": "analysis.report", "DriveResult": "analysis.evaluate", "evaluate_fleet": "api", "replay_fleet": "api",
    "write_fleet_recording": "api", "FleetReport": "analysis.fleet", "Drive": "core.drive",
    "InputError": "core.errors", "ToolFailure": "core.errors", "Estimate": "nav.protocol",
    "EstimatorInputs": "nav.protocol", "Estimator": "nav.protocol", "EstimatorError": "nav.protocol",
    "FilterHealth": "nav.protocol", "SensorBias": "nav.bias", "Tile": "experiment.outages",
    "Every": "experiment.outages", "At": "experiment.outages", "Random": "experiment.outages",
    "AroundEvents": "experiment.outages", "cross_validate": "api", "fine_tune_settings": "api",
    "ModelConfig": "learning.idnn", "EventThresholds": "analysis.events",
    "Event": "analysis.events", "LogOptions": "sources.load", "ReadOptions": "sources.load",
    "GnssLimits": "core.gnss_quality", "Experiment": "api", "FleetOptions": "api", "Engine": "api",
    "TrainingOptions": "api",
}  # fmt: skip
__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> Any:
    if name == "McapOptions":  # the earlier name of LogOptions, from when MCAP was the only message log
        import warnings

        warnings.warn("ionav_viz.McapOptions is deprecated: use ionav_viz.LogOptions", DeprecationWarning, stacklevel=2)
        name = "LogOptions"
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'ionav_viz' has no attribute {name!r}")
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


if TYPE_CHECKING:  # for type checkers and IDEs; at run time __getattr__ imports on first use
    from .analysis.compare import Comparison
    from .analysis.evaluate import DriveResult
    from .analysis.events import Event, EventThresholds
    from .analysis.fleet import FleetReport
    from .analysis.report import Report
    from .api import (
        DatasetSource,
        Engine,
        Experiment,
        FleetOptions,
        Outage,
        OutageLogResult,
        ReplayResult,
        RunOptions,
        RunSelection,
        Shots,
        TrainingOptions,
        WebServing,
        compare,
        convert,
        cross_validate,
        detector_quality,
        evaluate,
        evaluate_by_event,
        evaluate_fleet,
        evaluate_lengths,
        fetch,
        figures,
        find_events,
        fine_tune_settings,
        list_runs,
        outage_log,
        replay,
        replay_fleet,
        replay_lengths,
        replay_scenario,
        scenario_drives,
        screenshot,
        serve_web,
        simulate,
        train,
        training_drives,
        write_fleet_recording,
    )
    from .core.drive import Drive
    from .core.errors import InputError, ToolFailure
    from .core.gnss_quality import GnssLimits
    from .experiment.outages import AroundEvents, At, Every, Random, Tile
    from .experiment.plan_file import FromPlan
    from .learning.idnn import ModelConfig
    from .nav.bias import SensorBias
    from .nav.protocol import Estimate, Estimator, EstimatorError, EstimatorInputs, FilterHealth
    from .sources.load import LogOptions, ReadOptions, load_drive
