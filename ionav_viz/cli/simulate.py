"""``ionav-viz simulate``: synthetic drives in the exact IO-VNBD format."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from . import common as c
from .app import app


@app.command()
def simulate(
    scenario: Optional[str] = typer.Argument(None, help="motorway, roundabout, quick-accel, hard-brake, sharp-cornering or stationary."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="The V-*.csv file to write."),
    seed: int = typer.Option(0, "--seed", help="Random seed; the same seed gives the same bytes."),
    duration: str = typer.Option("120s", "--duration", help="Length of the drive, e.g. 120s or 5m."),
    ideal: bool = typer.Option(False, "--ideal", help="Perfect sensors and flat roads (for checks)."),
    bundled: Optional[Path] = typer.Option(None, "--bundled", help="Regenerate every bundled sample into this directory instead."),
    fleet: Optional[str] = typer.Option(None, "--fleet", help="Draw the car's sensor and vehicle errors from a fleet: training (the bundled training drives') or held-out (outside every training range)."),
    gnss_loss: int = typer.Option(0, "--gnss-loss", help="Add this many tunnel-like GNSS losses (3-15 s while driving: satellites 0, the fix frozen or zeros)."),
) -> None:
    """Write a synthetic drive in the exact IO-VNBD V-*.csv format."""
    from ..dataset.samples import SAMPLES
    from ..sim.simulate import FLEETS, SIMULATED_SCENARIOS, SensorModel, fleet_sensors, write_simulated_drive

    if bundled is not None:
        bundled.mkdir(parents=True, exist_ok=True)
        for sample in SAMPLES:
            write_simulated_drive(bundled / sample.file, sample.scenario, sample.seed, sample.duration_s,
                                  fleet_sensors(sample.fleet, sample.seed) if sample.fleet else None, gnss_losses=sample.gnss_losses)
            print(bundled / sample.file)
        return
    if scenario is None or output is None:
        raise typer.BadParameter("give a SCENARIO and -o FILE.csv (or --bundled DIR)")
    if scenario not in SIMULATED_SCENARIOS:
        raise typer.BadParameter(f"unknown scenario {scenario!r}; choose one of {', '.join(SIMULATED_SCENARIOS)}", param_hint="SCENARIO")
    seconds = c.duration_s(duration, "--duration")
    if gnss_loss < 0:
        raise typer.BadParameter(f"{gnss_loss}: give 0 or more losses", param_hint="--gnss-loss")
    if fleet is not None and fleet not in FLEETS:
        raise typer.BadParameter(f"unknown fleet {fleet!r}; choose one of {', '.join(FLEETS)}", param_hint="--fleet")
    if fleet is not None and ideal:
        raise typer.BadParameter("--ideal and --fleet exclude each other", param_hint="--fleet")
    sensors = SensorModel.ideal() if ideal else fleet_sensors(fleet, seed) if fleet else None
    path = write_simulated_drive(output, scenario, seed, seconds, sensors, gnss_losses=gnss_loss)
    print(path)
