"""``ionav-viz figures``: publication figures of a recording or an ``evaluate --json`` report."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from . import common as c
from .app import app


@app.command()
def figures(
    result: Path = typer.Argument(..., metavar="RESULT",
                                  help="A recording (.rrd) written by replay, or the output of 'evaluate --json' (a "
                                       "fleet's too, or several --outage lengths: their error against length)."),
    output: Path = typer.Option(..., "-o", "--output",
                                help="The folder to write drift, cdf, outages, outages-wide, worst and calibration "
                                     "(a fleet's: fleet-box and fleet-cdf), or lengths (a report of several "
                                     "outage lengths) into (made when missing)."),
    formats: str = typer.Option("svg,pdf,png", "--format", metavar="LIST",
                                help="The formats to write, comma-separated: svg, pdf, png (PDF, its fonts embedded, "
                                     "is the slowest to write)."),
    quiet: bool = c.QuietOpt,
) -> None:
    """Draw a run's publication figures: drift, error CDF, per-outage errors, worst outage, uncertainty calibration."""
    from .. import api

    written = api.figures(result, output, c.split_list(formats))
    if not quiet:
        print(f"{len(written)} files in {output}", file=sys.stderr)
    for path in written:
        print(path)
