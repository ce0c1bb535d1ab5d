"""``ionav-viz compare``: runs of the same drives and outages side by side."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from ..core.errors import InputError
from . import common as c
from .app import app, options_named


@app.command()
def compare(
    runs: list[Path] = typer.Argument(
        ...,
        metavar="RUN",
        show_default=False,
        help="Two or more runs of the same drives and outages, the first the baseline: files written by "
        "'evaluate --json' (one drive or several, several --outage lengths, --scenario or --by-event "
        "groups, a fleet's) or recordings written by 'replay'.",
    ),
    label: Optional[list[str]] = typer.Option(
        None,
        "--label",
        show_default=False,
        help="The runs' names in the tables, in their order (comma-separated or repeated; default: each file's stem).",
    ),
    metric: str = typer.Option(
        "crse_m,cae_m",
        "--metric",
        help="The metrics the tables and figure show, comma-separated: crse_m, cae_m, aeps_m, yaw_crse_radps, "
        "yaw_cae_radps, yaw_aeps_radps, final_position_error_m, final_error_pct; the first ranks the outages "
        "that changed most (the JSON has every one).",
    ),
    top: int = typer.Option(
        5, "--top", help="How many of the outages that changed most to list per estimator and run."
    ),
    as_json: bool = typer.Option(False, "--json", help="Print the comparison as JSON."),
    markdown: bool = typer.Option(False, "--markdown", help="Print the tables as Markdown."),
    figure: Optional[Path] = typer.Option(
        None,
        "--figure",
        show_default=False,
        help="Also draw each estimator's change with its interval into this .png, .svg or .pdf.",
    ),
    quiet: bool = c.QuietOpt,
) -> None:
    """Compare runs of the same outages: each estimator's metrics per run, the change with a paired 95 %
    interval, the outages that changed most."""
    from .. import api

    if as_json and markdown:
        raise InputError("--json and --markdown: two output formats asked for", "give one of them")
    labels = [x for given in label for x in c.split_list(given)] if label else None
    with options_named(labels="--label", metrics="--metric", top="--top", figure="--figure"):
        result = api.compare(runs, labels=labels, metrics=c.split_list(metric), top=top, figure=figure)
    if as_json:
        print(result.to_json())
    elif markdown:
        print(result.to_markdown(), end="")
    else:
        print(result.to_text(c.terminal_width()), end="")
    if figure is not None and not quiet:
        print(f"figure: {figure}", file=sys.stderr)
