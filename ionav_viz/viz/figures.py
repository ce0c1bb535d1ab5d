"""Publication figures of a report (``ionav-viz figures``), drawn with matplotlib (the field's
default; imported here only, so other commands do not pay for it).

From a report's JSON (``evaluate --json``, or the copy a recording carries): each figure is written
as vector (SVG and PDF) and raster (PNG, 300 dpi), exactly one column of a two-column paper wide
(3.5 in, 8 pt type; ``outages-wide`` the page, 7.16 in) whatever the number of drives, titles
wrapped and legends below the axes, in the recording's colours and labels, each estimator with its
own line style, hatch and marker too (readable in greyscale):

* ``drift``: position error against seconds since the outage began, the mean per estimator with
  its hatched and outlined 10-90 % band;
* ``cdf``: the empirical distribution of the final position error;
* ``outages`` and ``outages-wide``: the final position error of every outage, per estimator, the
  drives separated and named;
* ``worst``: the worst outage's tracks and the truth, in metres about its start: start and end
  marked, arrows along the truth for the direction of travel, a north arrow apart from the tracks,
  a scale bar.

A fleet's report (``evaluate --workers N --json``, :class:`ionav_viz.analysis.fleet.FleetReport`)
gets its own two figures instead (:data:`FLEET_FIGURES`), one column wide:

* ``fleet-box``: per estimator, a box plot of the drives' mean final position errors (each drive
  one point, drawn over its box): how much the drives differ;
* ``fleet-cdf``: the empirical distribution of the final position error over every outage of the
  fleet, per estimator (over the drives it ran on).

The report is read as bounded, strict JSON and checked field by field before anything is drawn
(:func:`read_report`: one line naming the file and the field otherwise). A value a report leaves
undefined (``null``: the JSON writes NaN so) is not drawn: a gap in a curve or track, an outage
left out of the CDF and the per-outage errors, ``p50 n/a`` in a legend, and an estimator with no
defined value in a figure is left out of it; each is said in one warning line per figure.

The figures are drawn into a temporary folder (beside a new output folder, inside an existing one)
and moved in when all are complete, with stop signals held (:func:`write_figures`): a run stopped
while drawing leaves the folder as it was. Other files in the folder are kept. Matplotlib is used through its object
interface (``Figure`` and the Agg canvas), never ``pyplot``: the caller's backend and figures are
untouched.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
from collections.abc import Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..analysis.drift import error_cdf
from ..analysis.schema import schema_of
from ..core.errors import InputError
from ..core.fileio import (
    check_output_folder,
    check_regular_input,
    parse_json_bounded,
    read_json_bounded,
    staging_folder,
    write_failure,
)
from ..core.json_out import is_finite_number
from ..core.signals import hold_signals
from .style import GNSS_COLOR, GNSS_LABEL, REFERENCE_LABEL, estimator_colors, stacking

log = logging.getLogger("ionav_viz")

#: One column of a two-column paper and its full width (inches), and the type size (pt).
COLUMN_IN, PAGE_IN, FONT_PT = 3.5, 7.16, 8
FORMATS = ("svg", "pdf", "png")
#: Each figure's file name, how it is drawn and its width: one column each; the per-outage errors
#: also across the page (``outages-wide``: room for every outage of a long drive or several drives).
FIGURES = ("drift", "cdf", "outages", "outages-wide", "worst", "calibration")
#: matplotlib settings of every figure: the type sizes, no top and right spines, text kept as text
#: in SVG and PDF, the figure saved at its own size.
STYLE = {"font.size": FONT_PT, "axes.titlesize": FONT_PT, "axes.labelsize": FONT_PT, "legend.fontsize": FONT_PT - 1,
         "xtick.labelsize": FONT_PT - 1, "ytick.labelsize": FONT_PT - 1, "axes.spines.top": False,
         "axes.spines.right": False, "svg.fonttype": "none", "pdf.fonttype": 42, "savefig.bbox": "standard",
         "hatch.linewidth": 0.5}
#: The figures of a fleet's report.
FLEET_FIGURES = ("fleet-box", "fleet-cdf")
#: The figure of a report of several outage lengths (``evaluate --outage 10s,30s --json``).
LENGTH_FIGURES = ("lengths",)
_WIDTHS = {"fleet-box": COLUMN_IN, "fleet-cdf": COLUMN_IN, "drift": COLUMN_IN, "cdf": COLUMN_IN, "outages": COLUMN_IN,
           "outages-wide": PAGE_IN, "worst": COLUMN_IN, "calibration": COLUMN_IN, "lengths": COLUMN_IN}


#: What a report's reader says to give instead of a bad one.
REPORT_HINT = ("give the output of 'ionav-viz evaluate --json' (one outage length; a fleet's too), or a recording "
               "written by 'ionav-viz replay'")
#: The JSON of several reports, which figures does not draw: its key, and what it holds.
SEVERAL_REPORTS = {"scenarios": "one report per scenario (evaluate --scenario)",
                   "by_event": "one report per manoeuvre type (evaluate --by-event)",
                   "lengths": "one report per outage length (evaluate --outage 10s,30s)"}
#: Numbers a report may hold (metres, seconds): beyond this none comes from a drive (the earth's
#: circumference is 4e7 m, twelve hours 4.3e4 s), and the axes and scale bar could not be drawn.
MAX_REPORT_VALUE = 1e9


def read_report(path: str | Path) -> dict[str, Any]:
    """A report's JSON from ``evaluate --json`` output or a recording (``.rrd``), read as bounded,
    strict JSON (:func:`~ionav_viz.core.fileio.read_json_bounded`) and checked field by field
    (:func:`check_report`); one line of error naming the file and the field otherwise."""
    path = Path(path)
    if path.suffix.lower() == ".rrd":
        from .recording_info import report_json

        check_regular_input(path, "result", hint=REPORT_HINT)
        rep = parse_json_bounded(report_json(path), path, param="result", hint=REPORT_HINT, what="a report")
    else:
        rep = read_json_bounded(path, param="result", hint=REPORT_HINT, what="a report")
    check_report(rep, path)
    return rep


def check_report(rep: Any, path: Path) -> None:
    """That ``rep`` holds every field the figures draw, of the right type: the estimators (a name,
    a label, an optional RGB colour), their drift curves, every outage's final error, the final
    error percentiles and the worst outage's tracks. Numbers are finite (the strict reader) and
    within :data:`MAX_REPORT_VALUE`; ``null`` is allowed where the report leaves a value undefined."""

    def fail(field: str, why: str) -> None:
        raise InputError(f"{path}: {field}: {why}", REPORT_HINT, param="result")

    if schema_of(rep, path, "result", REPORT_HINT) == "comparison":
        raise InputError(f"{path}: a comparison of runs (compare --json), not a report", "draw it with "
                         "'ionav-viz compare A.json B.json --figure OUT.png'", param="result")
    if is_fleet_report(rep):
        check_fleet_report(rep, path)
        return
    if is_lengths_report(rep):
        check_lengths_report(rep, path)
        return
    several = [what for key, what in SEVERAL_REPORTS.items() if isinstance(rep, dict) and key in rep]
    if several:
        raise InputError(f"{path}: holds {several[0]}, and figures draws one report",
                         "give 'ionav-viz evaluate DRIVE... --json' (one drive or several, one outage length or "
                         "several; --on TYPE for one manoeuvre type), a fleet's, or a recording written by "
                         "'ionav-viz replay'",
                         param="result")
    if not isinstance(rep, dict):
        raise InputError(f"{path}: a JSON {_kind(rep)}, not a report (an object)", REPORT_HINT, param="result")
    if isinstance(rep.get("folds"), list) and "by" in rep and "drive" not in rep:
        raise InputError(f"{path}: a cross-validation report (cross-validate --json: each fold's CRSE), with "
                         "no outages or drift curves to draw",
                         "figures takes one drive's 'ionav-viz evaluate DRIVE --json' (e.g. with "
                         "--model on a fold's model from cross-validate -o), a fleet's, or a recording from "
                         "'ionav-viz replay'",
                         param="result")
    if not rep.get("sequences") and isinstance(rep.get("gnss_outages"), dict):
        bridged = rep["gnss_outages"].get("bridged")
        _refuse_real_losses_only(path, len(bridged) if isinstance(bridged, list) else None, "drive")
    for key in ("drive", "n_sequences", "outage_s", "estimators", "sequences", "drift", "final_error_percentiles",
                "worst_tracks"):
        if key not in rep:
            fail(key, "missing (not a report with outages and drift curves, or one made by an earlier ionav-viz)")
    _need_text(rep["drive"], "drive", fail)
    if not _is_int(rep["n_sequences"]) or rep["n_sequences"] < 1:
        fail("n_sequences", f"{rep['n_sequences']!r} is not a count of outages (1 or more)")
    outage = rep["outage_s"]
    if not is_finite_number(outage) or not 0 < outage <= MAX_REPORT_VALUE:
        fail("outage_s", f"{outage!r} is not an outage length in seconds")
    ests = rep["estimators"]
    if not isinstance(ests, list) or not ests:
        fail("estimators", "is not a list of estimators")
    names: list[str] = []
    for i, e in enumerate(ests):
        where = f"estimators[{i}]"
        if not isinstance(e, dict):
            fail(where, f"is a JSON {_kind(e)}, not an object")
        for key in ("name", "label"):
            _need_text(e.get(key), f"{where}.{key}", fail)
        if e["name"] in names:
            fail(f"{where}.name", f"{e['name']!r} is listed twice")
        names.append(e["name"])
        color = e.get("color")
        if color is not None and not (isinstance(color, list) and len(color) == 3 and
                                      all(_is_int(c) and 0 <= c <= 255 for c in color)):
            fail(f"{where}.color", f"{color!r} is not an RGB triple of 0-255 integers")
    for name in names:
        curve = _need_object(_need_object(rep["drift"], "drift", fail).get(name), f"drift.{name}", fail)
        lengths = {key: len(_need_numbers(curve.get(key), f"drift.{name}.{key}", fail))
                   for key in ("t_s", "mean_m", "p10_m", "p90_m")}
        if len(set(lengths.values())) != 1:
            fail(f"drift.{name}",
                 f"t_s, mean_m, p10_m and p90_m differ in length ({', '.join(f'{k} {n}' for k, n in lengths.items())})")
        p50 = _need_object(_need_object(rep["final_error_percentiles"], "final_error_percentiles", fail).get(name),
                           f"final_error_percentiles.{name}", fail).get("p50")
        _need_number(p50, f"final_error_percentiles.{name}.p50", fail)
    sequences = rep["sequences"]
    if not isinstance(sequences, list) or not sequences:
        fail("sequences", "is not a list of outages")
    for i, seq in enumerate(sequences):
        for name in names:
            metrics = _need_object(_need_object(seq, f"sequences[{i}]", fail).get(name), f"sequences[{i}].{name}", fail)
            if "final_position_error_m" not in metrics:
                fail(f"sequences[{i}].{name}.final_position_error_m", "missing")
            _need_number(metrics["final_position_error_m"], f"sequences[{i}].{name}.final_position_error_m", fail)
    tracks = _need_object(rep["worst_tracks"], "worst_tracks", fail)
    _need_text(tracks.get("drive"), "worst_tracks.drive", fail)
    if not _is_int(tracks.get("number")):
        fail("worst_tracks.number", f"{tracks.get('number')!r} is not an outage number")
    if not is_finite_number(tracks.get("start_s")) or abs(tracks["start_s"]) > MAX_REPORT_VALUE:
        fail("worst_tracks.start_s", f"{tracks.get('start_s')!r} is not a time in seconds")
    for name in ("truth", *names):
        track = _need_object(tracks.get(name), f"worst_tracks.{name}", fail)
        east = _need_numbers(track.get("east_m"), f"worst_tracks.{name}.east_m", fail)
        north = _need_numbers(track.get("north_m"), f"worst_tracks.{name}.north_m", fail)
        if len(east) != len(north):
            fail(f"worst_tracks.{name}", f"east_m has {len(east)} points, north_m {len(north)}")
    if rep.get("truth") is not None:
        _need_text(rep["truth"], "truth", fail)


def is_fleet_report(rep: Any) -> bool:
    """Whether ``rep`` is a fleet's report (``evaluate --workers N --json``)."""
    return isinstance(rep, dict) and "drives_evaluated" in rep and "pooled" in rep


def check_fleet_report(rep: dict[str, Any], path: Path) -> None:
    """That a fleet's report holds what its figures draw: the estimators (name, label, optional
    colour), the evaluated drives' names, each estimator's pooled median (an object per estimator,
    its ``p50`` a number or null), and every outage's drive (one of the drives listed) and final
    errors (a number or null; an estimator may be missing on a drive it did not run on). The one
    check of a fleet report's structure: the figures read it without checking again."""

    def fail(field: str, why: str) -> None:
        raise InputError(f"{path}: {field}: {why}", REPORT_HINT, param="result")

    real = rep.get("real_outages")
    if not rep.get("sequences") and isinstance(real, dict) and _is_int(real.get("n")) and real["n"] > 0:
        _refuse_real_losses_only(path, real["n"], "drives")
    outage = rep.get("outage_s")
    if not is_finite_number(outage) or not 0 < outage <= MAX_REPORT_VALUE:
        fail("outage_s", f"{outage!r} is not an outage length in seconds")
    ests = rep.get("estimators")
    if not isinstance(ests, list) or not ests:
        fail("estimators", "is not a list of estimators (no drive was evaluated?)")
    names = []
    for i, e in enumerate(ests):
        if not isinstance(e, dict):
            fail(f"estimators[{i}]", f"is a JSON {_kind(e)}, not an object")
        for key in ("name", "label"):
            _need_text(e.get(key), f"estimators[{i}].{key}", fail)
        color = e.get("color")
        if color is not None and not (isinstance(color, list) and len(color) == 3 and
                                      all(_is_int(c) and 0 <= c <= 255 for c in color)):
            fail(f"estimators[{i}].color", f"{color!r} is not an RGB triple of 0-255 integers")
        names.append(e["name"])
    drives = rep.get("drives")
    if not isinstance(drives, list) or not drives:
        fail("drives", "is not a list of evaluated drives")
    listed = {_need_text(_need_object(d, f"drives[{i}]", fail).get("drive"), f"drives[{i}].drive", fail)
              for i, d in enumerate(drives)}
    pooled = _need_object(rep.get("pooled"), "pooled", fail)
    for name, entry in pooled.items():  # the CDF's legend gives each estimator's pooled median
        percentiles = _need_object(entry, f"pooled.{name}", fail).get("final_error_percentiles")
        if percentiles is not None:
            _need_number(_need_object(percentiles, f"pooled.{name}.final_error_percentiles", fail).get("p50"),
                         f"pooled.{name}.final_error_percentiles.p50", fail)
    sequences = rep.get("sequences")
    if not isinstance(sequences, list) or not sequences:
        fail("sequences", "is not a list of outages")
    for i, seq in enumerate(sequences):
        drive = _need_text(_need_object(seq, f"sequences[{i}]", fail).get("drive"), f"sequences[{i}].drive", fail)
        if drive not in listed:  # the box plot would draw a drive the report does not have: the report is not one run's
            fail(f"sequences[{i}].drive", f"{drive!r} is not among the report's drives (outages and drives disagree)")
        for name in names:
            if name in seq:
                metrics = _need_object(seq[name], f"sequences[{i}].{name}", fail)
                if "final_position_error_m" not in metrics:
                    fail(f"sequences[{i}].{name}.final_position_error_m", "missing")
                _need_number(metrics["final_position_error_m"], f"sequences[{i}].{name}.final_position_error_m", fail)


def _refuse_real_losses_only(path: Path, bridged: int | None, drives: str) -> None:
    """The error for a run through the log's own GNSS losses alone (``--on gnss-outage``): nothing
    the figures draw (they draw synthetic outages: drift curves, per-outage errors, the worst one)."""
    losses = f", {bridged} bridged" if bridged is not None else ", bridged"
    raise InputError(f"{path}: this run has no synthetic outages, only the log's own GNSS losses{losses} "
                     "(--on gnss-outage); the figures draw synthetic outages",
                     f"replay or evaluate the {drives} with synthetic ones: --outage 10s, without --on gnss-outage",
                     param="result")


def _kind(value: Any) -> str:
    return {dict: "object", list: "array", str: "string", bool: "boolean",
            type(None): "null"}.get(type(value), "number")


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _need_text(value: Any, field: str, fail: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        fail(field, f"{value!r} is not a name (a non-empty string)")
    return value


def _need_object(value: Any, field: str, fail: Any) -> dict[str, Any]:
    if value is None:
        fail(field, "missing")
    if not isinstance(value, dict):
        fail(field, f"is a JSON {_kind(value)}, not an object")
    return value


def _need_numbers(values: Any, field: str, fail: Any) -> list[Any]:
    """A list of numbers within MAX_REPORT_VALUE, or null (undefined)."""
    if values is None:
        fail(field, "missing")
    if not isinstance(values, list):
        fail(field, f"is a JSON {_kind(values)}, not a list of numbers")
    for k, v in enumerate(values):
        _need_number(v, f"{field}[{k}]", fail)
    return values


def _need_number(value: Any, field: str, fail: Any) -> None:
    """A number within MAX_REPORT_VALUE, or null (undefined)."""
    if value is not None and not is_finite_number(value):
        fail(field, f"{value!r} is not a number")
    if value is not None and abs(value) > MAX_REPORT_VALUE:
        fail(field, f"{value!r} is beyond any drive (at most {MAX_REPORT_VALUE:g} m or s)")


def _floats(values: list[Any]) -> np.ndarray:
    """Checked numbers, null as NaN (not drawn)."""
    return np.array([math.nan if v is None else v for v in values], dtype=float)


def colors_of(rep: dict[str, Any]) -> dict[str, tuple[float, float, float]]:
    """Each estimator's colour as the recording draws it (matplotlib's 0-1 RGB)."""
    estimators = [SimpleNamespace(name=e["name"], color=tuple(e["color"]) if e.get("color") else None)
                  for e in rep["estimators"]]
    return {name: tuple(c / 255 for c in rgb)  # type: ignore[misc]
            for name, rgb in estimator_colors(estimators).items()}


def write_figures(rep: dict[str, Any], folder: str | Path, formats: Sequence[str] = FORMATS) -> list[Path]:
    """Every figure of :data:`FIGURES` (a fleet's report: :data:`FLEET_FIGURES`) in each of ``formats`` (some of
    :data:`FORMATS`), into ``folder`` (made when missing, with its parents). Returns the files.

    Drawn into a temporary folder, beside ``folder`` when that is new (then renamed to it), else
    inside it (``-o .`` needs no right to write in the folder above); when all are written, the
    files are moved in (replacing the figures of an earlier run, keeping everything else), with
    stop signals held. A failure or a signal while drawing leaves ``folder`` as it was and no
    temporary folder."""
    from matplotlib import rc_context

    given = check_output_folder(Path(folder))  # as messages name it
    folder = Path(os.path.abspath(given))  # '.' and '..' by name
    drawn = FLEET_FIGURES if is_fleet_report(rep) else LENGTH_FIGURES if is_lengths_report(rep) else FIGURES
    for name in (f"{f}.{fmt}" for f in drawn for fmt in formats):  # before drawing: what the moves would refuse
        _check_replaceable(folder / name, given / name)
    parent = folder if folder.is_dir() else folder.parent
    made = [] if folder.is_dir() else _make_parents(parent, given)
    try:
        # removed at the end: gone when moved in; otherwise nothing half-drawn stays
        with staging_folder(folder, parent, refused=lambda exc: _write_error(given, exc)) as scratch:
            names = []
            with rc_context(STYLE):
                for name in drawn:
                    fig = figure(rep, name)
                    for fmt in formats:
                        target = scratch / f"{name}.{fmt}"
                        try:
                            fig.savefig(target, format=fmt, dpi=300)
                        except OSError as exc:
                            raise _write_error(given / target.name, exc) from None
                        names.append(target.name)
            _move_in(scratch, folder, names, given)
    except BaseException:
        for level in reversed(made):  # folders made for the output, still empty
            with contextlib.suppress(OSError):
                level.rmdir()
        raise
    return [given / name for name in names]


def figure(rep: dict[str, Any], name: str) -> Any:
    """The matplotlib ``Figure`` of :data:`FIGURES` (or :data:`FLEET_FIGURES`) ``name`` for the checked report ``rep``,
    at its width (:data:`COLUMN_IN` or :data:`PAGE_IN`), drawn with :data:`STYLE`."""
    from matplotlib import rc_context

    draws = {"fleet-box": _fleet_box, "fleet-cdf": _fleet_cdf, "drift": _drift, "cdf": _cdf, "outages": _outages,
             "outages-wide": _outages, "worst": _worst, "calibration": _calibration, "lengths": _lengths}
    with rc_context(STYLE):
        fig = draws[name](rep, _WIDTHS[name])
        fig.canvas.draw()  # laid out with the style's sizes
    return fig


def _make_parents(parent: Path, folder: Path) -> list[Path]:
    """Make ``folder``'s missing parents (not ``folder``); returns those made, outermost first."""
    made: list[Path] = []
    for level in [*reversed(parent.parents), parent]:
        if not level.exists():
            try:
                level.mkdir()
            except OSError as exc:
                for done in reversed(made):
                    with contextlib.suppress(OSError):
                        done.rmdir()
                raise _write_error(folder, exc) from None
            made.append(level)
    return made


def _write_error(target: Path, exc: OSError) -> Exception:
    """A write that failed: no room (one line, :func:`~ionav_viz.core.fileio.write_failure`) or a
    folder that cannot be written."""
    return write_failure(target, exc) or InputError(f"{target}: cannot write it ({exc.strerror or type(exc).__name__})",
                                                    "choose a writable output folder", param="output")


def _move_in(scratch: Path, folder: Path, names: list[str], given: Path) -> None:
    """The complete figures in ``scratch`` into ``folder`` (``given``: as messages name it), with
    stop signals held: the whole folder renamed when ``folder`` is new, else each file renamed over
    its old version."""
    release = hold_signals()
    try:
        if not folder.exists():
            scratch.rename(folder)
            return
        for name in names:
            _check_replaceable(folder / name, given / name)
        for name in names:
            os.replace(scratch / name, folder / name)
    except OSError as exc:
        raise _write_error(given, exc) from None
    finally:
        release()  # a signal that came during the moves acts now, with the figures complete


def _check_replaceable(target: Path, shown: Path) -> None:
    if target.is_dir() or (target.exists() and not target.is_file()):
        raise InputError(f"{shown}: exists and is not a regular file",
                         "ionav-viz only ever replaces regular files; choose another folder", param="output")


def _new_figure(width_in: float, height_in: float) -> tuple[Any, Any]:
    """A figure on its own Agg canvas, and its axes: no pyplot, no global state. Laid out by
    matplotlib's constrained layout inside exactly ``width_in`` x ``height_in`` (saved so: no
    tight bounding box that would widen or narrow it), legends placed outside the axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    fig.get_layout_engine().set(w_pad=0.02, h_pad=0.02, wspace=0.0, hspace=0.0)
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


#: Per estimator (in the report's order), what tells it apart without colour: its line style, the
#: hatching of its band, its marker (greyscale prints and colour-blind readers).
LINE_STYLES = ("-", "--", "-.", ":", (0, (5, 1, 1, 1, 1, 1)), (0, (1, 1)))
HATCHES = ("////", "\\\\", "xxxx", "....", "++++", "oo")
MARKERS = ("o", "s", "^", "D", "v", "P")


def _styled(rep: dict[str, Any]) -> list[tuple[str, str, Any, int]]:
    """(name, label, colour, index) of each estimator: the index picks its line style, hatch and marker."""
    colors = colors_of(rep)
    return [(name, label, colors[name], i) for i, (name, label) in enumerate(_labels(rep).items())]


def _labels(rep: dict[str, Any]) -> dict[str, str]:
    return {e["name"]: e["label"] for e in rep["estimators"]}


def _title(rep: dict[str, Any]) -> str:
    return f"{rep['drive']}: {rep['n_sequences']} outages of {rep['outage_s']:g} s"


def _set_title(ax: Any, text: str) -> None:
    """``text`` as the figure's title (centred on the figure, so that it can use all its width),
    broken into lines (after a word, or after a '+' between drive names) until every line fits
    the figure's width."""
    import textwrap

    fig = ax.figure
    room_px = fig.bbox.width * 0.96
    renderer = fig.canvas.get_renderer()
    for chars in range(len(text), 9, -2):
        wrapped = "\n".join(textwrap.wrap(text.replace("+", "+ "), chars)).replace("+ ", "+")
        title = fig.suptitle(wrapped, fontsize=FONT_PT)
        if title.get_window_extent(renderer).width <= room_px:
            return


def _skipped(figure: str, what: list[str]) -> None:
    if what:
        log.warning("figures: %s: %s (undefined in the report, null)", figure, "; ".join(what))


def _legend(fig: Any, ax: Any, width_in: float, entries: list[tuple[Any, str]] | None = None) -> None:
    """The legend below the axes, outside them (nothing drawn: no legend), in as many columns as
    fit ``width_in``; ``entries``: (handle, label) pairs instead of the labelled artists."""
    from matplotlib.legend_handler import HandlerTuple

    handles, labels = (([h for h, _ in entries], [t for _, t in entries])
                       if entries is not None else ax.get_legend_handles_labels())
    if not handles:  # nothing drawn: no empty legend (matplotlib warns)
        return
    longest = max(len(t) for t in labels)
    per_column_in = (longest * (FONT_PT - 1) * 0.55 + 30) / 72  # text, its line sample and the gap
    ncols = max(1, min(len(labels), int(width_in // per_column_in)))
    fig.legend(handles, labels, loc="outside lower center", ncols=ncols, frameon=False, handlelength=2.4,
               columnspacing=1.2, handler_map={tuple: HandlerTuple(ndivide=1)})


def _defined(label: str, x: np.ndarray, y: np.ndarray, skipped: list[str]) -> np.ndarray | None:
    """Where both ``x`` and ``y`` are defined (a report's null is NaN here); None when nowhere.
    What is left out is said in ``skipped``."""
    shown = np.isfinite(x) & np.isfinite(y)
    if not shown.any():
        skipped.append(f"{label} has no defined point, left out")
        return None
    if not shown.all():
        skipped.append(f"{label}: {int((~shown).sum())} of {len(x)} points left out")
    return shown


def _drift(rep: dict[str, Any], width_in: float = COLUMN_IN) -> Any:
    fig, ax = _new_figure(width_in, 2.9)
    skipped: list[str] = []
    handles: list[tuple[Any, str]] = []
    for name, label, color, i in _styled(rep):
        d = rep["drift"][name]
        t, mean, p10, p90 = (_floats(d[k]) for k in ("t_s", "mean_m", "p10_m", "p90_m"))
        shown = _defined(label, t, mean, skipped)
        if shown is None:
            continue
        band = np.isfinite(t) & np.isfinite(p10) & np.isfinite(p90)
        # each band hatched in its own pattern and outlined in its colour: overlapping bands stay
        # apart (in greyscale too), where filled ones blended into one colour
        patch = ax.fill_between(t, p10, p90, where=band, facecolor=(*color, 0.08), edgecolor=color,
                                hatch=HATCHES[i % len(HATCHES)], lw=0.5)
        # a gap where undefined
        [line] = ax.plot(t, np.where(shown, mean, np.nan), color=color, lw=1.3, ls=LINE_STYLES[i % len(LINE_STYLES)])
        handles.append(((patch, line), label))  # the legend shows the band's hatching under the line
    _skipped("drift", skipped)
    ax.set_xlabel("time since the outage began (s)")
    ax.set_ylabel("position error (m)")
    ax.set_xlim(0, float(rep["outage_s"]))
    ax.set_ylim(bottom=0)
    _set_title(ax, f"{_title(rep)}; mean (line) and 10-90 % band (hatched)")
    _legend(fig, ax, width_in, handles)
    return fig


def _calibration(rep: dict[str, Any], width_in: float = COLUMN_IN) -> Any:
    """Each estimator's predicted sigma (rms of ``sqrt(trace P)``) against its actual rms error, at
    every second into the outages, with the ideal line: below it underconfident, above it overconfident."""
    fig, ax = _new_figure(width_in, 2.9)
    handles: list[tuple[Any, str]] = []
    top = 0.0
    for name, label, color, i in _styled(rep):
        c = rep["summary"].get(name, {}).get("consistency") if isinstance(rep.get("summary"), dict) else None
        if not isinstance(c, dict) or not isinstance(c.get("by_second"), dict):
            [none] = ax.plot([], [], color=color, lw=1.0, ls=LINE_STYLES[i % len(LINE_STYLES)])
            handles.append((none, f"{label}: gives no covariance"))
            continue
        sigma, error = _floats(c["by_second"]["rms_sigma_m"]), _floats(c["by_second"]["rms_error_m"])
        [line] = ax.plot(sigma, error, color=color, lw=1.0, ls=LINE_STYLES[i % len(LINE_STYLES)], marker="o", ms=2.5)
        handles.append((line, f"{label}: ANEES {c['anees']:.2f}, {c['coverage_95']:.0f} % in 95 %"))
        top = max(top, float(np.nanmax(np.concatenate([sigma, error]))) if len(sigma) else 0.0)
    top = top * 1.05 if top > 0 else 1.0
    [ideal] = ax.plot([0, top], [0, top], color="0.4", lw=0.8, ls="--")
    handles.append((ideal, "honest: error = sigma"))
    if all(text.endswith("gives no covariance") for _, text in handles[:-1]):
        ax.text(0.5, 0.5, "no estimator gave a position covariance", transform=ax.transAxes, ha="center", va="center")
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    ax.set_xlabel("predicted sigma, rms of sqrt(trace P) (m)")
    ax.set_ylabel("actual rms position error (m)")
    _set_title(ax, f"{_title(rep)}; uncertainty calibration, one point per second into the outages")
    _legend(fig, ax, width_in, handles)
    return fig


def _finals(rep: dict[str, Any], name: str) -> np.ndarray:
    return _floats([s[name]["final_position_error_m"] for s in rep["sequences"]])


def _cdf(rep: dict[str, Any], width_in: float = COLUMN_IN) -> Any:
    def legend(name: str, label: str) -> str:
        p50 = rep["final_error_percentiles"][name]["p50"]
        return f"{label} (p50 {p50:.1f} m)" if p50 is not None else f"{label} (p50 n/a)"

    curves = [(name, label, color, i, _finals(rep, name)) for name, label, color, i in _styled(rep)]
    return _cdf_figure(rep, "cdf", _title(rep), curves, legend, width_in)


def _cdf_figure(rep: dict[str, Any], kind: str, title: str, curves: list[tuple[str, str, Any, int, np.ndarray]],
                legend: Any, width_in: float) -> Any:
    """The distribution of final errors, a step curve per estimator: ``curves`` of (name, label,
    colour, style index, final errors (m)); ``legend(name, label)`` its legend entry; an estimator
    without a defined final error is left out, saying so (``kind`` names the figure)."""
    fig, ax = _new_figure(width_in, 2.7)
    skipped = []
    drawn = []
    for name, label, color, i, finals in curves:
        v, share = error_cdf(finals)
        if not len(v):
            skipped.append(f"{label} has no defined final error, left out")
            continue
        if len(v) < len(finals):
            skipped.append(f"{label}: {len(finals) - len(v)} of {len(finals)} outages left out")
        drawn.append((name, label, color, i, v, share))
    # every curve runs on at 1 to the right edge: a dashed curve's last step up could fall in a dash
    # gap at the axes' top, and read as stopping short of all outages (0.98)
    right = 1.05 * max((float(d[4][-1]) for d in drawn), default=1.0) or 1.0
    for name, label, color, i, v, share in drawn:
        ax.step(np.r_[0.0, v, right], np.r_[0.0, share, 1.0], where="post", color=color, lw=1.3,
                ls=LINE_STYLES[i % len(LINE_STYLES)], label=legend(name, label))
    _skipped(kind, skipped)
    ax.set_xlabel(f"final position error after {rep['outage_s']:g} s (m)")
    ax.set_ylabel("share of outages")
    ax.set_ylim(0, 1.03)  # the top step clear of the frame
    ax.set_xlim(0, right)
    _set_title(ax, title)
    _legend(fig, ax, width_in)
    return fig


#: Above this many outages per inch of axes the per-outage figure draws points, not bars (bars
#: would be hairlines).
MAX_BARS_PER_IN = 12


def _drive_runs(rep: dict[str, Any]) -> list[tuple[str, int, int]]:
    """(drive, first, last outage number) of each run of consecutive outages of one drive."""
    runs: list[tuple[str, int, int]] = []
    for k, seq in enumerate(rep["sequences"], start=1):
        drive = seq.get("drive") if isinstance(seq.get("drive"), str) else rep["drive"]
        if runs and runs[-1][0] == drive:
            runs[-1] = (drive, runs[-1][1], k)
        else:
            runs.append((drive, k, k))
    return runs


def _outages(rep: dict[str, Any], width_in: float = COLUMN_IN) -> Any:
    import textwrap

    from matplotlib.transforms import blended_transform_factory

    styled = _styled(rep)
    n = len(rep["sequences"])
    fig, ax = _new_figure(width_in, 2.8)
    bars = n * len(styled) <= MAX_BARS_PER_IN * (width_in - 0.6)
    width = 0.8 / len(styled)
    x = np.arange(1, n + 1)
    skipped = []
    for name, label, color, j in styled:
        finals = _finals(rep, name)
        shown = np.isfinite(finals)
        if not shown.any():
            skipped.append(f"{label} has no defined final error, left out")
            continue
        if not shown.all():
            missing = x[~shown]
            skipped.append(f"{label}: outage(s) "
                           f"{', '.join(str(k) for k in missing[:5])}{' ...' if len(missing) > 5 else ''} left out")
        if bars:
            ax.bar(x[shown] - 0.4 + width * (j + 0.5), finals[shown], width, color=color, label=label, lw=0.4,
                   edgecolor="black", hatch=HATCHES[j % len(HATCHES)] if len(styled) > 1 else None)
        else:
            ax.plot(x[shown], finals[shown], ls="none", marker=MARKERS[j % len(MARKERS)], ms=2.4, mew=0.4,
                    mfc="none" if j % 2 else color, color=color, label=label)
    _skipped("outages", skipped)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("outage (numbered through the drives)")
    ax.set_ylabel("final position error (m)")
    ax.set_xlim(0.4, n + 0.6)
    ticks = max(1, round(n / (4 * width_in)))  # about four labels per inch
    ax.set_xticks(x[::ticks] if ticks > 1 else x)
    runs = _drive_runs(rep)
    if len(runs) > 1:  # drives apart: a line between them, each named above its outages
        on_top = blended_transform_factory(ax.transData, ax.transAxes)
        for k, (drive, first, last) in enumerate(runs):
            if k:
                ax.axvline(first - 0.5, color="0.35", lw=0.6, ls=(0, (3, 2)))
            span_in = (last - first + 1) / n * (width_in - 0.6)
            text = drive if len(drive) * (FONT_PT - 1.5) * 0.55 / 72 <= span_in else f"D{k + 1}"
            ax.text((first + last) / 2, 1.01, text, transform=on_top, ha="center", va="bottom", fontsize=FONT_PT - 1.5,
                    clip_on=False)
        if any(len(d) * (FONT_PT - 1.5) * 0.55 / 72 > (last - first + 1) / n * (width_in - 0.6)
               for d, first, last in runs):
            names = ", ".join(f"D{k + 1} {d}" for k, (d, _a, _b) in enumerate(runs))
            ax.set_xlabel("\n".join(textwrap.wrap(f"outage; {names}", int(width_in * 14))))
    title = f"{rep['n_sequences']} outages of {rep['outage_s']:g} s" if len(runs) > 1 else _title(rep)
    _set_title(ax, f"final position error of each outage: {title}")
    _legend(fig, ax, width_in)
    return fig


def _end_gap_m(tracks: dict[str, Any], name: str) -> float:
    """How far (m) the worst outage's track of ``name`` ends from the truth's end (NaN if undefined)."""
    ends = []
    for who in (name, "truth"):
        east, north = _floats(tracks[who]["east_m"]), _floats(tracks[who]["north_m"])
        ok = np.flatnonzero(np.isfinite(east) & np.isfinite(north))
        ends.append((east[ok[-1]], north[ok[-1]]) if len(ok) else (np.nan, np.nan))
    return float(np.hypot(ends[0][0] - ends[1][0], ends[0][1] - ends[1][1]))


#: The worst outage's start and truth-end markers (the estimates' ends are drawn above them).
END_ZORDER = 5.0


def _worst(rep: dict[str, Any], width_in: float = COLUMN_IN) -> Any:
    tracks = rep["worst_tracks"]
    fig, ax = _new_figure(width_in, 3.7)
    truth_label = REFERENCE_LABEL if rep.get("truth") == "reference" else GNSS_LABEL
    truth_color = tuple(c / 255 for c in GNSS_COLOR)
    skipped = []
    lines = [("truth", truth_label, truth_color, {"lw": 2.6, "alpha": 0.8, "solid_capstyle": "round"}),
             *((name, label, color, {"lw": 1.1, "ls": LINE_STYLES[i % len(LINE_STYLES)]})
               for name, label, color, i in _styled(rep))]
    truth_xy = None
    # the worst estimate underneath, the best on top
    stack = stacking({name: _end_gap_m(tracks, name) for name, *_ in lines[1:]})
    for name, label, color, style in lines:
        east, north = _floats(tracks[name]["east_m"]), _floats(tracks[name]["north_m"])
        shown = _defined(label, east, north, skipped)
        if shown is None:
            continue
        z = 2.0 + stack.get(name, 0.0)
        ax.plot(np.where(shown, east, np.nan), np.where(shown, north, np.nan), color=color, label=label, zorder=z,
                **style)
        if name == "truth":
            truth_xy = np.column_stack([east[shown], north[shown]])
        else:
            # where this estimate ended: over the truth's end marker, which is hollow (an estimate ending on it
            # shows inside)
            last = np.flatnonzero(shown)[-1]
            ax.plot([east[last]], [north[last]], marker="o", ms=3, color=color, mec="black", mew=0.4, ls="none",
                    zorder=END_ZORDER + 1 + z)
    _skipped("worst", skipped)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xticks([])
    ax.set_yticks([])
    for side in ("left", "bottom"):
        ax.spines[side].set_visible(False)
    ax.plot([0], [0], marker="o", ms=6, mfc="white", mec="black", mew=1.0, ls="none", label="start (last GNSS fix)",
            zorder=END_ZORDER)
    if truth_xy is not None and len(truth_xy) > 1:
        ax.plot(*truth_xy[-1], marker="s", ms=5.5, mfc="none", mec="black", mew=1.0, ls="none", label="end (truth)",
                zorder=END_ZORDER)
        _direction_arrows(ax, truth_xy, truth_color)
    ax.margins(0.12)
    _north_arrow(ax)
    _scale_bar(ax)
    _set_title(ax, f"worst outage: {tracks['drive']} #{tracks['number']}, {tracks['start_s']:g}-"
              f"{tracks['start_s'] + rep['outage_s']:g} s; arrows: direction of travel")
    _legend(fig, ax, width_in)
    return fig


def _direction_arrows(ax: Any, xy: np.ndarray, color: Any) -> None:
    """Arrowheads along the truth track at a third and two thirds of its length, pointing the way
    the vehicle drove."""
    steps = np.hypot(*np.diff(xy, axis=0).T)
    along = np.r_[0.0, np.cumsum(steps)]
    if along[-1] <= 0:
        return
    for share in (1 / 3, 2 / 3):
        k = int(np.clip(np.searchsorted(along, share * along[-1]), 1, len(xy) - 1))
        ax.annotate("", xy=tuple(xy[k]), xytext=tuple(xy[k - 1]),
                    arrowprops={"arrowstyle": "-|>,head_length=0.6,head_width=0.35", "color": "black", "lw": 0.8,
                                "shrinkA": 0, "shrinkB": 0})


def _north_arrow(ax: Any) -> None:
    """A north arrow in the upper left corner of the axes, apart from the tracks (north is up: the
    axes have equal scales)."""
    ax.annotate("N", xy=(0.05, 0.97), xytext=(0.05, 0.82), xycoords="axes fraction", textcoords="axes fraction",
                ha="center", va="top", fontsize=FONT_PT - 1,
                arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 0.9})


def _scale_bar(ax: Any) -> None:
    """A bar of a round length (1, 2 or 5 x 10^k m), about a fifth of the view, in its lower right."""
    ax.figure.canvas.draw()  # the equal-aspect limits are final only after a draw
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    target = (x1 - x0) / 5
    if not math.isfinite(target) or target <= 0:
        return
    k = math.floor(math.log10(target))
    length = max((m * 10**k for m in (1, 2, 5) if m * 10**k <= target), default=10**k)
    right, bottom = x1 - 0.05 * (x1 - x0), y0 + 0.06 * (y1 - y0)
    ax.plot([right - length, right], [bottom, bottom], color="black", lw=1.5, solid_capstyle="butt")
    ax.text(right - length / 2, bottom + 0.02 * (y1 - y0), f"{length:g} m", ha="center", va="bottom",
            fontsize=FONT_PT - 1)


def _fleet_finals(rep: dict[str, Any], name: str) -> dict[str, np.ndarray]:
    """Per drive (in the report's order) the final errors of estimator ``name`` on its outages
    (drives it did not run on left out)."""
    out: dict[str, list[Any]] = {}
    for seq in rep["sequences"]:
        if name in seq:
            out.setdefault(seq["drive"], []).append(seq[name]["final_position_error_m"])
    return {d: _floats(v) for d, v in out.items()}


def _fleet_title(rep: dict[str, Any]) -> str:
    return f"Fleet of {len(rep['drives'])} drives: {len(rep['sequences'])} outages of {rep['outage_s']:g} s"


def _fleet_box(rep: dict[str, Any], width_in: float = COLUMN_IN) -> Any:
    """Per estimator a box of the drives' mean final errors (quartiles, median, whiskers at the 10th
    and 90th percentiles), each drive a point over it."""
    from matplotlib import cbook

    fig, ax = _new_figure(width_in, 2.7)
    skipped: list[str] = []
    rng = np.random.default_rng(0)  # the points' horizontal jitter: the same figure every time
    shown = []
    for name, label, color, i in _styled(rep):
        means = np.array([np.nanmean(v) if np.isfinite(v).any() else np.nan for v in _fleet_finals(rep, name).values()])
        defined = means[np.isfinite(means)]
        if not len(defined):
            skipped.append(f"{label} has no defined final error, left out")
            continue
        if len(defined) < len(means):
            skipped.append(f"{label}: {len(means) - len(defined)} of {len(means)} drives left out")
        k = len(shown) + 1
        # the whiskers at the 10th and 90th percentiles themselves: boxplot(whis=(10, 90)) draws them at
        # the farthest drive inside those, which with a few drives is the box's own edge
        stats = cbook.boxplot_stats(defined)[0]
        stats["whislo"], stats["whishi"] = np.percentile(defined, [10, 90])
        ax.bxp([stats], positions=[k], widths=0.55, showfliers=False, patch_artist=True,
                   medianprops={"color": color, "lw": 1.6}, whiskerprops={"color": color}, capprops={"color": color},
                   boxprops={"edgecolor": color, "facecolor": (*color, 0.15), "hatch": HATCHES[i % len(HATCHES)],
                             "lw": 0.8})
        ax.scatter(k + rng.uniform(-0.16, 0.16, len(defined)), defined, s=7, color=color,
                   marker=MARKERS[i % len(MARKERS)], lw=0, alpha=0.85, zorder=3)
        shown.append(label)
    _skipped("fleet-box", skipped)
    ax.set_xticks(range(1, len(shown) + 1), shown, rotation=20 if len(shown) > 3 else 0,
                  ha="right" if len(shown) > 3 else "center")
    ax.set_ylabel(f"drive's mean final error after {rep['outage_s']:g} s (m)")
    ax.set_ylim(bottom=0)
    ax.set_xlim(0.4, len(shown) + 0.6)
    _set_title(ax, _fleet_title(rep) + " (box: quartiles, whiskers 10-90 %; a point per drive)")
    return fig


def _fleet_cdf(rep: dict[str, Any], width_in: float = COLUMN_IN) -> Any:
    """The pooled distribution of the final errors of every outage, per estimator."""
    per_drive = {name: _fleet_finals(rep, name) for name, *_ in _styled(rep)}

    def legend(name: str, label: str) -> str:
        p50 = ((rep["pooled"].get(name) or {}).get("final_error_percentiles") or {}).get("p50")  # checked when read
        median = f"p50 {p50:.1f} m" if is_finite_number(p50) else "p50 n/a"
        return f"{label} ({median}, {len(per_drive[name])} drives)"

    curves = [(name, label, color, i,
               np.concatenate(list(per_drive[name].values())) if per_drive[name] else np.zeros(0))
              for name, label, color, i in _styled(rep)]
    return _cdf_figure(rep, "fleet-cdf", _fleet_title(rep), curves, legend, width_in)


def is_lengths_report(rep: Any) -> bool:
    """Whether ``rep`` is a report of several outage lengths (``evaluate --outage 10s,30s --json``)."""
    return isinstance(rep, dict) and isinstance(rep.get("lengths"), dict) and "by_length" in rep


def check_lengths_report(rep: dict[str, Any], path: Path) -> None:
    """That a report of several outage lengths holds what its figure draws: the first length's
    drive and estimators (name, label, optional colour), and per estimator ``by_length``'s outage
    lengths (positive), outage counts, mean and 90th percentile final errors and mean final error as
    a share of the distance (numbers or null), all of one length."""

    def fail(field: str, why: str) -> None:
        raise InputError(f"{path}: {field}: {why}", REPORT_HINT, param="result")

    if not rep["lengths"]:
        fail("lengths", "holds no report")
    key, first = next(iter(rep["lengths"].items()))
    first = _need_object(first, f"lengths.{key}", fail)
    _need_text(first.get("drive"), f"lengths.{key}.drive", fail)
    ests = first.get("estimators")
    if not isinstance(ests, list) or not ests:
        fail(f"lengths.{key}.estimators", "is not a list of estimators")
    by_length = _need_object(rep["by_length"], "by_length", fail)
    for i, e in enumerate(ests):
        where = f"lengths.{key}.estimators[{i}]"
        for field in ("name", "label"):
            _need_text(_need_object(e, where, fail).get(field), f"{where}.{field}", fail)
        color = e.get("color")
        rgb = isinstance(color, list) and len(color) == 3 and all(_is_int(c) and 0 <= c <= 255 for c in color)
        if color is not None and not rgb:
            fail(f"{where}.color", f"{color!r} is not an RGB triple of 0-255 integers")
        rows = _need_object(by_length.get(e["name"]), f"by_length.{e['name']}", fail)
        sizes = {}
        for field in ("outage_s", "n_outages", "final_position_error_m", "final_error_p90_m", "final_error_pct"):
            sizes[field] = len(_need_numbers(rows.get(field), f"by_length.{e['name']}.{field}", fail))
        if len(set(sizes.values())) != 1 or not sizes["outage_s"]:
            fail(f"by_length.{e['name']}", "outage_s, n_outages and the errors differ in length, or are empty ("
                 + ", ".join(f"{k} {n}" for k, n in sizes.items()) + ")")
        for k, length in enumerate(rows["outage_s"]):
            if length is None or not 0 < length <= MAX_REPORT_VALUE:
                fail(f"by_length.{e['name']}.outage_s[{k}]", f"{length!r} is not an outage length in seconds")
        for k, count in enumerate(rows["n_outages"]):
            if not _is_int(count) or count < 0:
                fail(f"by_length.{e['name']}.n_outages[{k}]", f"{count!r} is not a count of outages")


def _lengths(rep: dict[str, Any], width_in: float = COLUMN_IN) -> Any:
    """Error against outage length: per estimator the mean final position error (filled markers)
    and its 90th percentile (hollow), and below it the mean final error as a share of the distance
    driven, at each length."""
    from matplotlib.lines import Line2D

    first = next(iter(rep["lengths"].values()))
    info = {"estimators": first["estimators"]}
    styled = _styled(info)
    fig, top = _new_figure(width_in, 3.9)
    fig.delaxes(top)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[3, 2])
    skipped: list[str] = []
    handles: list[tuple[Any, str]] = []
    lengths = np.array([])
    for name, label, color, i in styled:
        rows = rep["by_length"][name]
        x = _floats(rows["outage_s"])
        lengths = np.union1d(lengths, x)
        style = {"color": color, "ls": LINE_STYLES[i % len(LINE_STYLES)], "marker": MARKERS[i % len(MARKERS)]}
        mean, p90 = _floats(rows["final_position_error_m"]), _floats(rows["final_error_p90_m"])
        pct = _floats(rows["final_error_pct"])
        shown = _defined(label, x, mean, skipped)
        if shown is None:
            continue
        [line] = top.plot(x[shown], mean[shown], lw=1.2, ms=4, **style)
        high = np.isfinite(p90)
        top.plot(x[high], p90[high], lw=0.6, ms=4, mfc="white", alpha=0.9, **style)
        defined = np.isfinite(pct)
        bottom.plot(x[defined], pct[defined], lw=1.2, ms=4, **style)
        handles.append((line, label))
    _skipped("lengths", skipped)
    handles.append((Line2D([], [], color="0.3", marker="o", ls="none", ms=4), "mean"))
    handles.append((Line2D([], [], color="0.3", marker="o", mfc="white", ls="none", ms=4), "90th percentile"))
    top.set_ylabel("final position error (m)")
    bottom.set_ylabel("final error (% of distance)")
    bottom.set_xlabel("outage length (s)")
    for ax in (top, bottom):
        ax.set_ylim(bottom=0)
    if len(lengths):
        bottom.set_xticks(lengths, [f"{x:g}" for x in lengths])
        bottom.set_xlim(0.0, 1.06 * lengths[-1])  # from zero: how the error grows with the length
    counts = rep["by_length"][styled[0][0]]
    per = ", ".join(f"{n} of {x:g} s" for x, n in zip(counts["outage_s"], counts["n_outages"]))
    _set_title(top, f"{first['drive']}: error against outage length ({per} outages)")
    _legend(fig, bottom, width_in, handles)
    return fig
