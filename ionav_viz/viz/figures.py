"""Publication figures of a report (``ionav-viz figures``), drawn with matplotlib (the field's
default; imported here only, so other commands do not pay for it).

From a report's JSON (``evaluate --json``, or the copy a recording carries): each figure is written
as vector (SVG and PDF) and raster (PNG, 300 dpi), sized for one column of a two-column paper
(3.5 in wide, 8 pt type), in the recording's colours and labels:

* ``drift``: position error against seconds since the outage began, the mean per estimator with
  its 10-90 % band;
* ``cdf``: the empirical distribution of the final position error;
* ``outages``: the final position error of every outage, per estimator;
* ``worst``: the worst outage's tracks and the truth, in metres about its start, with a scale bar.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..analysis.drift import error_cdf
from ..core.errors import InputError
from ..core.fileio import atomic_path
from .style import GNSS_COLOR, GNSS_LABEL, REFERENCE_LABEL, estimator_colors

#: One column of a two-column paper (inches), and the type size (pt).
COLUMN_IN, FONT_PT = 3.5, 8
FORMATS = ("svg", "pdf", "png")
FIGURES = ("drift", "cdf", "outages", "worst")


def read_report(path: str | Path) -> dict[str, Any]:
    """A report's JSON from ``evaluate --json`` output or a recording (``.rrd``); one line of error otherwise."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file", "give a recording (.rrd) or the output of 'ionav-viz evaluate --json'", param="result")
    if path.suffix.lower() == ".rrd":
        from .recording_info import report_json

        text = report_json(path)
    else:
        if path.stat().st_size > 1 << 30:
            raise InputError(f"{path}: {path.stat().st_size} bytes is too large for a report", "give 'ionav-viz evaluate --json' output", param="result")
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise InputError(f"{path}: not JSON (not UTF-8 text)", "give 'ionav-viz evaluate --json' output", param="result") from None
        except OSError as exc:
            raise InputError(f"{path}: unreadable ({exc.strerror})", "give 'ionav-viz evaluate --json' output", param="result") from None
    try:
        rep = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not JSON ({exc.msg}, line {exc.lineno})", "give 'ionav-viz evaluate --json' output", param="result") from None
    if isinstance(rep, dict) and ("scenarios" in rep or "by_event" in rep):
        raise InputError(f"{path}: holds several reports (--scenario or --by-event)", "write one drive's report with evaluate --json", param="result")
    if not isinstance(rep, dict) or not rep.get("n_sequences") or "drift" not in rep:
        raise InputError(f"{path}: not a report with outages and drift curves", "make it with this version's 'ionav-viz evaluate --json' or replay",
                         param="result")
    return rep


def colors_of(rep: dict[str, Any]) -> dict[str, tuple[float, float, float]]:
    """Each estimator's colour as the recording draws it (matplotlib's 0-1 RGB)."""
    estimators = [SimpleNamespace(name=e["name"], color=tuple(e["color"]) if e.get("color") else None) for e in rep["estimators"]]
    return {name: tuple(c / 255 for c in rgb) for name, rgb in estimator_colors(estimators).items()}  # type: ignore[misc]


def write_figures(rep: dict[str, Any], folder: str | Path) -> list[Path]:
    """Every figure of :data:`FIGURES` in every format of :data:`FORMATS`, into ``folder`` (made
    when missing); each file written atomically. Returns the files."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    style = {"font.size": FONT_PT, "axes.titlesize": FONT_PT, "axes.labelsize": FONT_PT, "legend.fontsize": FONT_PT - 1,
             "xtick.labelsize": FONT_PT - 1, "ytick.labelsize": FONT_PT - 1, "axes.spines.top": False, "axes.spines.right": False,
             "svg.fonttype": "none", "pdf.fonttype": 42, "savefig.bbox": "tight", "savefig.pad_inches": 0.02}
    written = []
    with plt.rc_context(style):
        for name, draw in (("drift", _drift), ("cdf", _cdf), ("outages", _outages), ("worst", _worst)):
            fig = draw(plt, rep)
            for fmt in FORMATS:
                target = folder / f"{name}.{fmt}"
                with atomic_path(target, suffix=f".{fmt}") as tmp:
                    fig.savefig(tmp, format=fmt, dpi=300)
                written.append(target)
            plt.close(fig)
    return written


def _labels(rep: dict[str, Any]) -> dict[str, str]:
    return {e["name"]: e["label"] for e in rep["estimators"]}


def _title(rep: dict[str, Any]) -> str:
    return f"{rep['drive']}: {rep['n_sequences']} outages of {rep['outage_s']:g} s"


def _drift(plt: Any, rep: dict[str, Any]) -> Any:
    fig, ax = plt.subplots(figsize=(COLUMN_IN, 2.4))
    colors = colors_of(rep)
    for name, label in _labels(rep).items():
        d = rep["drift"][name]
        t, mean = np.asarray(d["t_s"]), np.asarray(d["mean_m"], dtype=float)
        ax.fill_between(t, np.asarray(d["p10_m"], dtype=float), np.asarray(d["p90_m"], dtype=float), color=colors[name], alpha=0.18, lw=0)
        ax.plot(t, mean, color=colors[name], lw=1.2, label=label)
    ax.set_xlabel("time since the outage began (s)")
    ax.set_ylabel("position error (m)")
    ax.set_xlim(0, float(rep["outage_s"]))
    ax.set_ylim(bottom=0)
    ax.set_title(f"{_title(rep)}; mean and 10-90 %")
    ax.legend(frameon=False, loc="upper left")
    return fig


def _finals(rep: dict[str, Any], name: str) -> np.ndarray:
    return np.array([s[name]["final_position_error_m"] if s[name]["final_position_error_m"] is not None else math.nan
                     for s in rep["sequences"]], dtype=float)


def _cdf(plt: Any, rep: dict[str, Any]) -> Any:
    fig, ax = plt.subplots(figsize=(COLUMN_IN, 2.4))
    colors = colors_of(rep)
    for name, label in _labels(rep).items():
        v, share = error_cdf(_finals(rep, name))
        if len(v):
            ax.step(np.r_[0.0, v], np.r_[0.0, share], where="post", color=colors[name], lw=1.2,
                    label=f"{label} (p50 {rep['final_error_percentiles'][name]['p50']:.1f} m)")
    ax.set_xlabel(f"final position error after {rep['outage_s']:g} s (m)")
    ax.set_ylabel("share of outages")
    ax.set_ylim(0, 1.0)
    ax.set_xlim(left=0)
    ax.set_title(_title(rep))
    ax.legend(frameon=False, loc="lower right")
    return fig


#: Above this many outages the per-outage figure draws points, not bars (bars would be hairlines).
MAX_BARS = 40


def _outages(plt: Any, rep: dict[str, Any]) -> Any:
    labels = _labels(rep)
    n = len(rep["sequences"])
    fig, ax = plt.subplots(figsize=(max(COLUMN_IN, min(7.16, 0.12 * n * len(labels))), 2.2))  # up to a full page width
    colors = colors_of(rep)
    width = 0.8 / len(labels)
    x = np.arange(1, n + 1)
    for j, (name, label) in enumerate(labels.items()):
        if n <= MAX_BARS:
            ax.bar(x - 0.4 + width * (j + 0.5), np.nan_to_num(_finals(rep, name)), width, color=colors[name], label=label, lw=0)
        else:
            ax.plot(x, _finals(rep, name), ls="none", marker=".", ms=2.5, color=colors[name], label=label)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("outage")
    ax.set_ylabel("final position error (m)")
    ax.set_xlim(0.4, n + 0.6)
    if n > 30:
        ax.set_xticks(x[:: max(1, n // 15)])
    else:
        ax.set_xticks(x)
    ax.set_title(_title(rep))
    ax.legend(frameon=False, ncols=min(4, len(labels)), loc="upper left")
    return fig


def _worst(plt: Any, rep: dict[str, Any]) -> Any:
    tracks = rep["worst_tracks"]
    fig, ax = plt.subplots(figsize=(COLUMN_IN, COLUMN_IN * 0.8))
    colors = colors_of(rep)
    truth_label = REFERENCE_LABEL if rep.get("truth") == "reference" else GNSS_LABEL
    ax.plot(tracks["truth"]["east_m"], tracks["truth"]["north_m"], color=tuple(c / 255 for c in GNSS_COLOR), lw=2.0, label=truth_label)
    for name, label in _labels(rep).items():
        t = tracks[name]
        ax.plot(t["east_m"], t["north_m"], color=colors[name], lw=1.2, marker="o", ms=1.8, label=label)
    ax.plot([0], [0], "k^", ms=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xticks([])
    ax.set_yticks([])
    for side in ("left", "bottom"):
        ax.spines[side].set_visible(False)
    _scale_bar(ax)
    ax.set_title(f"worst outage: {tracks['drive']} #{tracks['number']}, {tracks['start_s']:g}-{tracks['start_s'] + rep['outage_s']:g} s")
    ax.legend(frameon=False, loc="best")
    return fig


def _scale_bar(ax: Any) -> None:
    """A bar of a round length (1, 2 or 5 x 10^k m), about a fifth of the view, in its lower right."""
    ax.figure.canvas.draw()  # the equal-aspect limits are final only after a draw
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    target = (x1 - x0) / 5
    if target <= 0:
        return
    k = math.floor(math.log10(target))
    length = max((m * 10**k for m in (1, 2, 5) if m * 10**k <= target), default=10**k)
    right, bottom = x1 - 0.05 * (x1 - x0), y0 + 0.06 * (y1 - y0)
    ax.plot([right - length, right], [bottom, bottom], color="black", lw=1.5, solid_capstyle="butt")
    ax.text(right - length / 2, bottom + 0.02 * (y1 - y0), f"{length:g} m", ha="center", va="bottom", fontsize=FONT_PT - 1)
