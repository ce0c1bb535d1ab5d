"""The synthetic drives bundled with the package (``ionav_viz/data/samples/``) and how they were generated.

Each is a ``V-*.csv`` written by :func:`ionav_viz.api.simulation.simulate` (``iv.simulate``); regenerating one with the
same scenario, seed and duration gives the same bytes (``ionav-viz simulate --bundled DIR``
regenerates them all). The test drive of each scenario is addressable by the scenario name
wherever a drive is expected (``ionav-viz evaluate roundabout``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from .catalog import BIAS_RUN, PAPER_TEST_RUNS, SCENARIOS, run_key


@dataclass(frozen=True)
class Sample:
    """A bundled synthetic drive: file name, scenario, seed, duration (s), role and how many
    tunnel-like GNSS losses it has (see :func:`ionav_viz.sim.simulate.gnss_loss_spans`)."""

    file: str
    scenario: str
    seed: int
    duration_s: float
    role: str  # "test", "train", "bias" or "losses" (real GNSS losses, for replay --on gnss-outage)
    gnss_losses: int = 0
    fleet: str = ""  # "": the simulator's default car; else a fleet of ionav_viz.sim.simulate.FLEETS


TRAIN_DRIVES_PER_SCENARIO = 8

# Test drives: 10 minutes each, so a scenario is compared over 59 outages of 10 s (a 2-minute
# drive gives only 11, too few to tell a 10 % difference from chance). Training drives: eight
# short drives per scenario, each from another car of the training fleet (its own offset, gyro
# bias, scale and latency, noise, road grade and wheel radius), so the networks learn what cars
# have in common rather than one car's quirks.
SAMPLES = tuple(
    [Sample(f"V-sim-{s}.csv", s, 100 + i, 600.0, "test") for i, s in enumerate(SCENARIOS)]
    + [Sample(f"V-sim-{s}-train-{k + 1}.csv", s, 200 + 10 * i + k, 150.0, "train", fleet="training")
       for i, s in enumerate(SCENARIOS) for k in range(TRAIN_DRIVES_PER_SCENARIO)]
    + [Sample("V-sim-stationary.csv", "stationary", 300, 180.0, "bias")]
    + [Sample("V-sim-motorway-tunnels.csv", "motorway", 400, 600.0, "losses", gnss_losses=6)]
)  # fmt: skip


def samples_dir() -> Path:
    """Where the bundled samples are: ``$IONAV_SAMPLES``, else the package data (``ionav_viz/data/samples``)."""
    env = os.environ.get("IONAV_SAMPLES")
    return Path(env) if env else package_data("samples")


def package_data(*parts: str) -> Path:
    """A file or folder of the package's own data (read-only), as a path.

    Installed packages keep their data as plain files (wheels are unpacked), so the resource is
    a real directory; nothing is ever written there.
    """
    return Path(str(resources.files("ionav_viz").joinpath("data", *parts)))


def address(sample: Sample) -> str:
    """The name a bundled drive is given by wherever a drive is expected: its scenario for a test
    drive (``roundabout``), ``stationary``, else its file's stem (``V-sim-motorway-tunnels``)."""
    if sample.role == "test":
        return sample.scenario
    return "stationary" if sample.role == "bias" else Path(sample.file).stem


def what_it_is(sample: Sample) -> str:
    """What a bundled drive is, in a few words: ``simulated 10-min roundabout test drive``."""
    minutes = f"{sample.duration_s / 60:g}-min"
    if sample.role == "test":
        return f"simulated {minutes} {sample.scenario} test drive"
    if sample.role == "bias":
        return f"simulated {minutes} standstill, for the sensor biases"
    if sample.role == "losses":
        return f"simulated {minutes} {sample.scenario} drive, {sample.gnss_losses} tunnels (--on gnss-outage)"
    return f"simulated {minutes} {sample.scenario} training drive"


def stand_in(run: str) -> Sample | None:
    """The bundled drive that stands in for an IO-VNBD run the paper uses: the scenario's test drive
    for one of its test runs (``V-Vw8`` -> ``sharp-cornering``), the standstill for the bias run;
    None for any other run."""
    key = run_key(run)
    for scenario, runs in PAPER_TEST_RUNS.items():
        if key in {run_key(r) for r in runs}:
            return next((s for s in by_scenario(scenario)), None)
    if key == run_key(BIAS_RUN):
        return next((s for s in SAMPLES if s.role == "bias"), None)
    return None


def by_scenario(scenario: str, role: str = "test") -> list[Sample]:
    return [s for s in SAMPLES if s.scenario == scenario and s.role == role]


def sample_path(sample: Sample) -> Path:
    return samples_dir() / sample.file
