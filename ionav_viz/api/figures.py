"""``figures``: publication figures of a run's report (:mod:`ionav_viz.viz.figures`)."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ..core.errors import InputError
from ..core.fileio import check_output_folder, check_regular_input, refuse_output_onto_input
from ..core.timing import stage

if TYPE_CHECKING:
    from ..analysis.report import Report
    from .replay import ReplayResult


def figures(result: ReplayResult | Report | str | os.PathLike[str], output: str | Path,
            formats: Sequence[str] = ("svg", "pdf", "png")) -> list[Path]:
    """Draw the drift curve, the final-error CDF, the per-outage errors (one column and page-wide)
    and the worst outage's tracks of ``result`` (a recording written by :func:`replay`, or ``evaluate --json`` output;
    a fleet's ``evaluate --workers N --json``: its per-drive box plot and pooled CDF instead; several
    outage lengths, ``evaluate --outage 10s,30s --json``: the error against outage length instead)
    into the folder ``output`` in each of ``formats`` (``svg``, ``pdf``, ``png``; PDF embeds its fonts, the slowest
    to write); ``result`` may also be what :func:`replay`
    returned (its recording is read) or a :class:`~ionav_viz.analysis.report.Report` from
    :func:`evaluate`. Returns the files written.

    The report is checked field by field first (one :class:`InputError` naming the file and the
    field); values it leaves undefined (null) are not drawn, each figure warning what it left out.
    The figures appear in ``output`` only when all are complete (drawn in a temporary folder beside
    it, or inside it when it exists); other files there are kept."""
    from ..analysis.report import Report
    from ..viz.figures import FIGURES, FLEET_FIGURES, FORMATS, LENGTH_FIGURES, check_report, read_report, write_figures
    from .replay import ReplayResult

    if isinstance(result, ReplayResult):  # iv.figures(iv.replay(...), folder) was a TypeError naming no argument
        result = result.path
    formats = _checked_formats(formats, FORMATS)
    check_output_folder(Path(output))  # before any work: -o naming a file is refused
    if isinstance(result, Report):
        rep = json.loads(result.to_json())  # exactly what 'evaluate --json' writes
        check_report(rep, Path("report"))
        with stage("figures of the report"):
            return write_figures(rep, output, formats)
    if not isinstance(result, (str, os.PathLike)):
        raise InputError(f"result of type {type(result).__name__}: not a recording, a report or its file",
                         "give what replay or evaluate returned, a .rrd, or the output of 'evaluate --json'",
                         param="result")
    refuse_output_onto_input(output, [result])  # before reading: -o inside the input's folder, or the input itself
    # the files it replaces (others there are kept)
    for name in (f"{f}.{fmt}" for f in (*FIGURES, *FLEET_FIGURES, *LENGTH_FIGURES) for fmt in formats):
        refuse_output_onto_input(Path(output) / name, [result])
    check_regular_input(result, "result", hint="give a .rrd written by replay or the output of 'evaluate --json'",
                        missing_ok=True)
    rep = read_report(result)
    with stage(f"figures of {Path(result).name}"):
        return write_figures(rep, output, formats)


def _checked_formats(formats: Sequence[str], known: Sequence[str]) -> tuple[str, ...]:
    """``formats`` as lower-case names in :data:`~ionav_viz.viz.figures.FORMATS`' order, each once; an
    unknown or no format is an :class:`InputError`."""
    if isinstance(formats, str):
        formats = (formats,)
    chosen = {str(f).strip().lower().lstrip(".") for f in formats}
    if unknown := sorted(chosen - set(known)):
        raise InputError(f"format {unknown[0]!r} is unknown", f"choose from {', '.join(known)}", param="formats")
    if not chosen:
        raise InputError("no format given", f"choose one or more of {', '.join(known)}", param="formats")
    return tuple(f for f in known if f in chosen)
