"""The public Python API: load drives, evaluate estimators on GNSS outages, replay to ``.rrd``, render screenshots.

Every function here is what one CLI command does, without the shell: arguments are Python values
(seconds as floats, paths, placement objects, estimator names or objects), results are
dataclasses, and problems are :class:`~ionav_viz.core.errors.InputError` (bad input) or
:class:`~ionav_viz.core.errors.ToolFailure` (the environment: disk, renderer, network).

    import ionav_viz as iv

    drive = iv.load_drive("roundabout")                  # a bundled scenario, a path or a run name
    report = iv.evaluate([drive], outage_s=10.0)          # the paper's consecutive outages
    print(report.to_text())
    result = iv.replay(drive, placement=iv.Every(30.0), output="roundabout.rrd")
    iv.screenshot([result.path], "shots/", iv.Shots(times=["worst"], views=["local"]))
    reports = iv.evaluate(iv.Experiment([drive], outage_s=[10, 30]))  # {10.0: Report, 30.0: Report}

:class:`Experiment` (``experiment.py``) is one run's set-up; :func:`evaluate` and :func:`replay`
(``run.py``) take it, or its fields as arguments, and its fields choose the variant (several
outage lengths, by manoeuvre, a fleet on an :class:`Engine`, a scenario). The previous release's
names of the variants are in ``deprecated.py``, for one release.
"""


from ..viz.live import WebServing
from .compare import compare
from .cross_validate import CrossValidation, cross_validate
from .datasets import DatasetSource, RunSelection, fetch, list_runs
from .deprecated import (
    evaluate_by_event,
    evaluate_fleet,
    evaluate_lengths,
    replay_fleet,
    replay_lengths,
    replay_scenario,
)
from .engine import Engine
from .evaluate import ScenarioDrives, scenario_drives
from .events import DetectorQuality, detector_quality, find_events
from .experiment import Experiment, FleetOptions
from .figures import figures
from .fleet import run_fleet, write_fleet_recording
from .options import RunOptions
from .outage_log import OutageLogResult, outage_log
from .replay import RECORDINGS_DIR, Outage, ReplayResult, serve_web
from .run import evaluate, replay
from .screenshots import Shots, screenshot
from .simulation import Converted, convert, simulate, simulate_bundled
from .training import TrainingDrives, TrainingOptions, fine_tune_settings, train, training_drives

__all__ = [
    "RECORDINGS_DIR",
    "Converted",
    "CrossValidation",
    "DatasetSource",
    "DetectorQuality",
    "Engine",
    "Experiment",
    "FleetOptions",
    "Outage",
    "OutageLogResult",
    "ReplayResult",
    "RunOptions",
    "RunSelection",
    "ScenarioDrives",
    "Shots",
    "TrainingDrives",
    "TrainingOptions",
    "WebServing",
    "compare",
    "convert",
    "cross_validate",
    "detector_quality",
    "evaluate",
    "evaluate_by_event",
    "evaluate_fleet",
    "evaluate_lengths",
    "fetch",
    "figures",
    "find_events",
    "fine_tune_settings",
    "list_runs",
    "outage_log",
    "replay",
    "replay_fleet",
    "replay_lengths",
    "replay_scenario",
    "run_fleet",
    "scenario_drives",
    "screenshot",
    "serve_web",
    "simulate",
    "simulate_bundled",
    "train",
    "training_drives",
    "write_fleet_recording",
]
