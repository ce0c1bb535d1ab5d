"""The fleet's overview recording (``evaluate --fleet-rrd FILE``): one ``.rrd`` that opens on a
table of the fleet's drives (each drive a row: its outages, each estimator's mean final error, its
worst outage and the command that renders it, and its recording when it was replayed; a second tab
holds the whole fleet report, Markdown) above two bar charts side by side, each drive a group of
bars (one per estimator, in its colour) numbered as the table's rows, all on one y scale: the mean
final error of each drive, and its worst outage's final error. Everything is static: the
recording has no timeline.

Rerun has no box-plot archetype: the per-drive spread is in ``figures`` of the fleet (a box plot
per estimator and the pooled CDF, :mod:`ionav_viz.viz.figures`)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..analysis.fleet import DriveTable, FleetReport
from ..analysis.metrics import summarise
from .recording import APP_ID, streamed_to
from .recording_info import FLEET_ID_PREFIX, rrd_reader
from .style import estimator_colors
from .viewer import HeadlessViewer

#: Entity paths of the fleet recording.
FLEET_TABLE = "fleet/drives"
FLEET_REPORT = "fleet/report"
MEAN_BARS = "fleet/mean_final_error_m"
WORST_BARS = "fleet/worst_final_error_m"
#: Seconds the headless viewer waits before the overview's screenshot (its start-up notices fade).
SCREENSHOT_SETTLE_S = 6.0
#: Each drive's bar, centred on its number.
BAR_WIDTH = 0.8


def through_real_losses(report: FleetReport) -> bool:
    """Whether the fleet ran through its logs' own GNSS losses alone (``--on gnss-outage``): then
    the overview's rows and bars are of those, not of synthetic outages (it has none)."""
    return report.n_outages == 0 and report.n_real_outages > 0


def final_errors_m(report: FleetReport, table: DriveTable, estimator: str) -> np.ndarray:
    """The drive's final position errors (m) of ``estimator``: over its synthetic outages, or over
    its own GNSS losses in a fleet through them alone (:func:`through_real_losses`)."""
    if through_real_losses(report):
        return np.array([b.final_error_m[estimator] for b in table.real_outages if estimator in b.final_error_m],
                        dtype=float)
    return table.metrics[estimator]["final_position_error_m"] if estimator in table.metrics else np.zeros(0)


def worst_outage(report: FleetReport, table: DriveTable) -> dict[str, Any] | None:
    """The drive's outage with the largest final error of the report's :attr:`~FleetReport.worst_of`
    (the INS DR if it ran): ``number`` (from 1, the replay's "outage N"), ``name`` (how the
    replay names it: "outage 3 (20-30 s)", or in a fleet through the logs' own losses "real GNSS
    outage 2 (118-133 s)"), ``final_error_m``; None when it has none."""
    est = report.worst_of
    err = final_errors_m(report, table, est) if est is not None else np.zeros(0)
    if not np.isfinite(err).any():
        return None
    i = int(np.nanargmax(err))
    if through_real_losses(report):
        b = table.real_outages[i]
        return {"number": b.number, "name": f"real GNSS outage {b.number} ({b.gap_start_s:.0f}-{b.gap_end_s:.0f} s)",
                "final_error_m": float(err[i])}
    t0 = float(table.start_s[i])
    return {"number": i + 1, "name": f"outage {i + 1} ({t0:.0f}-{t0 + table.outage_s:.0f} s)",
            "final_error_m": float(err[i])}


def open_command(report: FleetReport, table: DriveTable, worst: dict[str, Any]) -> str:
    """The command that shows the drive's worst outage (``worst``, :func:`worst_outage`):
    :meth:`FleetReport.open_command` of its number."""
    return report.open_command(table, worst["number"])


def key_line(report: FleetReport, colors: dict[str, tuple[int, int, int]]) -> str:
    """Which colour is which estimator's bars, in words."""
    from .style import color_word

    return "Bars: " + ", ".join(f"{report.labels[e]} {color_word(colors[e])}" for e in report.estimators) + "."


def drives_markdown(report: FleetReport, colors: dict[str, tuple[int, int, int]] | None = None) -> str:
    """The overview's table: one row per drive, numbered as the bars; then the command that
    shows each drive's worst outage (:func:`open_command`) and its recording."""
    from ..analysis.fleet import _f

    ests, labels = report.estimators, report.labels
    by = labels[report.worst_of] if report.worst_of else ""
    real = through_real_losses(report)
    header = (["#", "drive", "losses" if real else "outages"] + [f"{labels[e]} m" for e in ests]
              + [f"worst {'loss' if real else 'outage'} ({by} m)"])
    title = (f"{report.n_real_outages} of the logs' own GNSS losses, bridged" if real
             else f"{report.n_outages} outages of {report.outage_s:g} s")
    what = "loss" if real else "outage"
    lines = [f"# Fleet: {len(report.drives)} drive(s), {title}",
             "",
             f"Mean final position error per drive (the bars are numbered as the rows), and each drive's worst {what}."
             + (f" {key_line(report, colors)}" if colors else ""), "",
             "| " + " | ".join(header) + " |",
             "|" + "|".join("---" if j == 1 or j == len(header) - 1 else "---:" for j in range(len(header))) + "|"]
    replays = []
    for k, t in enumerate(report.drives, 1):
        worst = worst_outage(report, t)
        count = len(t.real_outages) if real else t.n_outages
        cells = [str(k), t.name, str(count)] + [_f(summarise(final_errors_m(report, t, e))["mean"]) for e in ests]
        cells.append("-" if worst is None else f"{worst['name']}: {worst['final_error_m']:.1f}")
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        where = f"; its recording `{t.recording}`" if t.recording else ""
        if worst is None:
            replays.append(f"{k}. {t.name}: `{report.command(t.spec)}`{where}")
        else:
            replays.append(f"{k}. {t.name}, {worst['name']}: `{open_command(report, t, worst)}`{where}")
    lines += ["", f"## See a drive's worst {what}", "",
              f"Each command renders the {what} it names, framed (in the viewer, `rerun <drive>.rrd`: the inspector "
              "shows it from its start on).",
              "", *replays]
    if report.failures or report.skipped:
        lines += ["", "## Not evaluated", "", *(f"- {f.spec}: {f.reason}" for f in [*report.failures, *report.skipped])]
    return "\n".join(lines) + "\n"


def bar_abscissa(numbers: np.ndarray, j: int, n_estimators: int) -> np.ndarray:
    """Where estimator ``j`` of ``n_estimators`` puts its bars' left edges: side by side in a group
    of :data:`BAR_WIDTH` centred on each drive's number (one chart, one y scale for all)."""
    width = BAR_WIDTH / n_estimators
    return numbers - BAR_WIDTH / 2 + j * width


def fleet_blueprint(report: FleetReport) -> Any:
    """The overview's layout: above, tabs of the drives' table (with the commands that show each
    drive's worst outage) and the whole report; below, side by side, one bar chart of each drive's
    mean final error and one of its worst outage's, every estimator's bars grouped by drive on
    one y scale (an estimator's bars are comparable with another's)."""
    import rerun.blueprint as rrb

    what = "loss" if through_real_losses(report) else "outage"
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Tabs(rrb.TextDocumentView(origin=FLEET_TABLE, name="Drives"),
                     rrb.TextDocumentView(origin=FLEET_REPORT, name="Fleet report")),
            rrb.Horizontal(
                rrb.BarChartView(origin=MEAN_BARS, name="Mean final error per drive (m)",
                                 plot_legend=rrb.PlotLegend(visible=False)),
                rrb.BarChartView(origin=WORST_BARS, name=f"Worst {what}'s final error per drive (m)",
                                 plot_legend=rrb.PlotLegend(visible=False)),
            ),
            row_shares=[4, 5]),
        collapse_panels=True)


def write_fleet_recording(report: FleetReport, path: Path, target: Path | None = None) -> dict[str, int]:
    """Log the fleet's overview to the ``.rrd`` file ``path`` (the caller makes the write atomic:
    ``path`` is then a temporary file, ``target`` the name for messages). Returns rows per entity."""
    import rerun as rr

    own = report.colors
    colors = estimator_colors([SimpleNamespace(name=e, color=own.get(e)) for e in report.estimators])
    what = "their own GNSS losses" if through_real_losses(report) else f"{report.outage_s:g} s outages"
    rec = rr.RecordingStream(APP_ID, recording_id=f"{FLEET_ID_PREFIX}{len(report.drives)} drives, {what}")
    rows: dict[str, int] = {}
    with streamed_to(rec, path, target):
        rec.send_blueprint(fleet_blueprint(report))
        rec.log(FLEET_TABLE, rr.TextDocument(drives_markdown(report, colors), media_type=rr.MediaType.MARKDOWN),
                static=True)
        rec.log(FLEET_REPORT, rr.TextDocument(report.to_markdown(), media_type=rr.MediaType.MARKDOWN), static=True)
        rows |= {FLEET_TABLE: 1, FLEET_REPORT: 1}
        numbers = np.arange(1, len(report.drives) + 1, dtype=np.float64)
        n_est = len(report.estimators)
        for j, e in enumerate(report.estimators):
            errors = [final_errors_m(report, t, e) for t in report.drives]
            means = np.array([summarise(err)["mean"] for err in errors])
            worst = np.array([np.nanmax(err) if np.isfinite(err).any() else np.nan for err in errors])
            for root, values in ((MEAN_BARS, means), (WORST_BARS, worst)):
                rec.log(f"{root}/{e}", rr.BarChart(np.nan_to_num(values, nan=0.0), color=colors[e],
                                                   abscissa=bar_abscissa(numbers, j, n_est),
                                                   widths=np.full(len(numbers), BAR_WIDTH / n_est, dtype=np.float32)),
                        static=True)
                rows[f"{root}/{e}"] = 1
    return rows


def screenshot_fleet(recording: Path, out: Path, size: tuple[int, int], timeout_s: float = 120.0,
                     viewer: HeadlessViewer | None = None) -> Path:
    """A PNG of the fleet overview ``recording`` in its own layout, by the private headless viewer
    (``viewer``: a started one of ``size``, else one is started and shut down here)."""
    import contextlib
    import time

    from ..core.fileio import utf8_alias
    from .blueprints import without_panels
    from .screenshot import draw_key

    with utf8_alias(Path(recording)) as readable:
        ids = [str(r.recording_id) for r in rrd_reader(readable).recordings()]
    title = next((i for i in ids if i.startswith(FLEET_ID_PREFIX)), FLEET_ID_PREFIX)
    with HeadlessViewer(*size, timeout_s=timeout_s) if viewer is None else contextlib.nullcontext(viewer) as viewer:
        viewer.open(Path(recording))
        time.sleep(SCREENSHOT_SETTLE_S)
        # the band above the views (the viewer's title bar) says what the image is, as a replay's key does
        viewer.show(without_panels(viewer.base_blueprint), None, Path(out),
                    finish=lambda png: draw_key(png, [], title[0].upper() + title[1:]))
    return Path(out)
