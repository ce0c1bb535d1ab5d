"""``ionav-viz simulate``: synthetic drives in the exact IO-VNBD format."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..core.errors import InputError
from . import common as c
from .app import app


@app.command()
def simulate(
    scenario: Optional[str] = typer.Argument(None,
                                             help="motorway, roundabout, quick-accel, hard-brake, sharp-cornering "
                                                  "or stationary."),
    output: Optional[Path] = typer.Option(None, "-o", "--output",
                                          help="The V-*.csv file to write (with --imu: the .mcap)."),
    seed: int = typer.Option(0, "--seed", help="Random seed; the same seed gives the same bytes."),
    duration: str = typer.Option("120s", "--duration", help="Length of the drive, e.g. 120s or 5m."),
    ideal: bool = typer.Option(False, "--ideal", help="Perfect sensors and flat roads (for checks)."),
    bundled: Optional[Path] = typer.Option(None, "--bundled",
                                           help="Regenerate every bundled sample into this directory instead."),
    fleet: Optional[str] = typer.Option(None, "--fleet",
                                        help="Draw the car's sensor and vehicle errors from a fleet: training (the "
                                             "bundled training drives') or held-out (outside every training range)."),
    gnss_loss: int = typer.Option(0, "--gnss-loss",
                                  help="Add this many tunnel-like GNSS losses (3-15 s while driving: satellites 0, the "
                                       "fix frozen or zeros)."),
    imu: Optional[str] = typer.Option(None, "--imu",
                                      help="Write a 6-axis logger MCAP instead: mems (100 Hz, 10 Hz GNSS, CAN speed), "
                                           "phone (10 Hz, 1 Hz GPS), dash (104 Hz, 10 Hz GNSS), "
                                           "roof (100 Hz, 4 Hz RTK); truth on /truth/fix."),
    quiet: bool = c.QuietOpt,  # accepted as every command accepts it: simulate writes nothing to stderr but errors
) -> None:
    """Write a synthetic drive in the exact IO-VNBD V-*.csv format (or, with --imu, a 6-axis MCAP log)."""
    from .. import api
    from .app import options_named

    if bundled is not None:
        given = [name for name, value, default in (("SCENARIO", scenario, None), ("-o", output, None),
                                                   ("--seed", seed, 0), ("--duration", duration, "120s"),
                                                   ("--ideal", ideal, False), ("--fleet", fleet, None),
                                                   ("--gnss-loss", gnss_loss, 0), ("--imu", imu, None))
                 if value != default]
        if given:  # each was ignored without a word: the bundled samples have their own scenarios, seeds and lengths
            raise InputError(f"--bundled regenerates every bundled sample as it is shipped, so {', '.join(given)} "
                             "would be ignored",
                             "leave them out, or simulate one drive without --bundled", param="bundled")
        for path in api.simulate_bundled(bundled):
            print(path)
        return
    if scenario is None:
        raise InputError("no scenario to simulate",
                         "give one, as in 'ionav-viz simulate motorway -o V-sim.csv' (or --bundled DIR for the "
                         "bundled drives)")
    if output is None:
        raise InputError("no file to write",
                         "give -o FILE.csv (an IO-VNBD CSV) or -o FILE.mcap (a 6-axis log with --imu)", param="output")
    with options_named(scenario="SCENARIO", gnss_losses="--gnss-loss", fleet="--fleet", imu="--imu", output="-o"):
        print(api.simulate(scenario, output, seed, c.duration_s(duration, "--duration"), fleet=fleet, ideal=ideal,
                           gnss_losses=gnss_loss, imu=imu))
