"""The figure of a comparison of runs (``ionav-viz compare --figure``): per estimator, the change of
each later run's mean against the baseline with its paired 95 % interval, one panel per metric the
comparison shows, drawn as :mod:`.figures` draws (matplotlib's object interface, its type sizes
and one column's width, the estimators' colours, each later run its own marker).

Each row is one estimator and one later run: the point is the change of the mean (``run -
baseline``), the bar its interval, the dashed line no change; the change and interval are written
beside each row, so the figure reads without the table. A change without an interval (fewer than
two outages) is a point alone; an estimator without a defined change is left out of that panel,
said in one warning.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.fileio import atomic_path, check_output_file
from .figures import COLUMN_IN, FONT_PT, MARKERS, STYLE, _legend, _new_figure, _set_title, _skipped, colors_of

#: The formats the figure is written in, by the output's suffix.
FIGURE_FORMATS = ("png", "svg", "pdf")


def check_figure_output(path: str | Path) -> Path:
    """That ``path`` can be written as the comparison's figure (``.png``, ``.svg`` or ``.pdf``), before any work."""
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FIGURE_FORMATS:
        raise InputError(
            f"{path}: the figure is written as {', '.join(f'.{f}' for f in FIGURE_FORMATS)}, "
            f"not {path.suffix or 'a name without suffix'}",
            "name it e.g. compare.png",
            param="figure",
        )
    try:
        return check_output_file(path)
    except InputError as exc:
        exc.param = "figure"
        raise


def comparison_figure(cmp: dict[str, Any]) -> Any:
    """The matplotlib ``Figure`` of a comparison (:meth:`ionav_viz.analysis.compare.Comparison.to_dict`)."""
    from matplotlib import rc_context
    from matplotlib.lines import Line2D

    base = cmp["baseline"]
    later = [r["label"] for r in cmp["runs"][1:]]
    colors = colors_of(cmp)
    labels = {e["name"]: e["label"] for e in cmp["estimators"]}
    metrics = cmp["metrics"]
    with rc_context(STYLE):
        rows = [(e, run) for e, per in cmp["changes"].items() for run in per[metrics[0]]]
        height = 0.75 + len(metrics) * (0.55 + 0.2 * max(len(rows), 1))
        fig, first = _new_figure(COLUMN_IN, height)
        fig.delaxes(first)
        axes = list(fig.subplots(len(metrics), 1, squeeze=False)[:, 0])
        skipped: list[str] = []
        for ax, metric in zip(axes, metrics):
            _panel(ax, cmp, metric, rows, colors, labels, later, skipped)
        _skipped("compare", skipped)
        if len(later) > 1:
            handles = [
                (Line2D([], [], ls="none", marker=MARKERS[j % len(MARKERS)], color="0.3", ms=4), f"{run} \u2212 {base}")
                for j, run in enumerate(later)
            ]
            _legend(fig, axes[-1], COLUMN_IN, handles)
        n = cmp["n_outages"]
        _set_title(
            axes[0],
            f"Change of each estimator's mean against {base} on {n} outage{'s' * (n != 1)}, "
            "with its paired t 95 % interval",
        )
        fig.canvas.draw()
    return fig


def _panel(
    ax: Any,
    cmp: dict[str, Any],
    metric: str,
    rows: list[tuple[str, str]],
    colors: dict[str, Any],
    labels: dict[str, str],
    later: list[str],
    skipped: list[str],
) -> None:
    """One metric's rows: a point at each change, its interval as a bar, the change and interval
    written on the right."""
    import textwrap

    from matplotlib.ticker import MaxNLocator

    from ..analysis.compare import METRIC_LABELS, _decimals, _fmt, _interval

    decimals = _decimals(metric)
    ys, ticks, right = [], [], []
    y = 0.0
    last = None
    lows, highs = [0.0], [0.0]
    for e, run in rows:
        if last is not None and e != last:
            y += 0.5  # estimators apart
        last = e
        ch = cmp["changes"][e][metric][run]
        change, (lo, hi) = ch["change"], ch["ci95"]
        if change is None or not math.isfinite(change):
            skipped.append(f"{labels[e]} ({run}): no outage defines {metric} in both runs, left out")
            y += 1
            continue
        j = later.index(run)
        defined = lo is not None and hi is not None and math.isfinite(lo) and math.isfinite(hi)
        ax.errorbar(
            [change],
            [y],
            xerr=[[change - lo], [hi - change]] if defined else None,
            fmt=MARKERS[j % len(MARKERS)],
            color=colors[e],
            ms=4,
            capsize=2.5,
            elinewidth=1.1,
            mew=0.6,
            mec="black",
        )
        lows += [lo if defined else change]
        highs += [hi if defined else change]
        ys.append(y)
        ticks.append(labels[e] if len(later) == 1 else f"{labels[e]}: {run}")
        right.append(f"{_fmt(change, decimals, True)} {_interval([lo, hi], decimals) if defined else '(no interval)'}")
        y += 1
    ax.axvline(0.0, color="0.35", lw=0.8, ls=(0, (4, 2)), zorder=0)
    # at least twenty steps of the printed resolution: changes that print as +0.00 (a float's last bits apart) had
    # an axis of +-8e-5, its "1e-5" offset drawn over the axis label
    least = 20.0 * 10.0 ** -decimals
    span = max(max(highs) - min(lows), least)
    mid = 0.5 * (max(highs) + min(lows))
    lo_x, hi_x = min(min(lows), mid - 0.5 * span), max(max(highs), mid + 0.5 * span)
    ax.set_xlim(lo_x - 0.08 * span, hi_x + 0.08 * span)
    ax.ticklabel_format(axis="x", useOffset=False)
    ax.set_ylim(max(y - 0.5, 0.5), -0.5)  # the first row on top
    ax.set_yticks(ys, ticks)
    ax.tick_params(axis="y", length=0)
    twin = ax.twinx()  # the numbers on the right, as tick labels: inside the figure's layout
    twin.set_ylim(ax.get_ylim())
    twin.set_yticks(ys, right, fontsize=FONT_PT - 1.5)
    twin.tick_params(axis="y", length=0)
    for side in ("top", "right", "left", "bottom"):
        twin.spines[side].set_visible(False)
    run = later[0] if len(later) == 1 else "run"
    name = METRIC_LABELS[metric]
    ax.set_title(name[:1].upper() + name[1:], loc="left", fontsize=FONT_PT)
    ax.set_xlabel("\n".join(textwrap.wrap(f"change of the mean, {run} \u2212 {cmp['baseline']}", 50)))
    # labels of 3 decimals are wide; steps of 1, 2 or 5 (a step of 0.025 wrote "-0.050-0.025" as one)
    ax.xaxis.set_major_locator(MaxNLocator(3 if decimals > 2 else 5, steps=[1, 2, 5, 10]))
    if not ys:
        ax.text(
            0.5, 0.5, "no estimator defines this metric in two runs", transform=ax.transAxes, ha="center", va="center"
        )


def write_comparison_figure(cmp: dict[str, Any], path: str | Path) -> Path:
    """Draw :func:`comparison_figure` into ``path`` (its suffix the format; PNG at 300 dpi), written
    under a temporary name and renamed when complete. Returns ``path``."""
    from matplotlib import rc_context

    path = check_figure_output(path)
    fig = comparison_figure(cmp)
    with rc_context(STYLE), atomic_path(path, suffix=path.suffix) as tmp:
        fig.savefig(tmp, format=path.suffix.lower().lstrip("."), dpi=300)
    return path
