"""``figures``: publication figures of a run's report (:mod:`ionav_viz.viz.figures`)."""

from __future__ import annotations

from pathlib import Path

from ..core.fileio import check_regular_input, refuse_output_onto_input
from ..core.timing import stage


def figures(result: str | Path, output: str | Path) -> list[Path]:
    """Draw the drift curve, the final-error CDF, the per-outage errors and the worst outage's
    tracks of ``result`` (a recording written by :func:`replay`, or ``evaluate --json`` output)
    into the folder ``output`` as SVG, PDF and PNG. Returns the files written."""
    from ..viz.figures import read_report, write_figures

    refuse_output_onto_input(output, [result], output_is_folder=True)  # before reading: the folder is replaced
    check_regular_input(result, "result", hint="give a .rrd written by replay or the output of 'evaluate --json'", missing_ok=True)
    rep = read_report(result)
    with stage(f"figures of {Path(result).name}"):
        return write_figures(rep, output)
