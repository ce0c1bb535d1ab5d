"""Issue 46.2: publication figures a journal takes as they come: their widths whatever the number of
drives, titles and legends inside the figure and off the axes, drives apart, the worst outage's
start, end, direction of travel and north, bands told apart without colour. Drawn from small
synthetic reports (no replay): fast and deterministic."""

import numpy as np
import pytest
from PIL import Image

from ionav_viz.viz.figures import COLUMN_IN, FIGURES, PAGE_IN, figure, write_figures

ESTIMATORS = [("ins", "INS DR", [230, 60, 50]), ("odo", "Odometry", [150, 60, 200]), ("ekf", "GNSS-aided INS", [0, 170, 190])]


def _report(drives: list[tuple[str, int]], outage_s: float = 10.0) -> dict:
    """A report of ``drives`` (name, outages), as ``evaluate --json`` writes it, with the fields
    the figures draw; the car drives south-east in the worst outage."""
    rng = np.random.default_rng(7)
    sequences = []
    for drive, n in drives:
        for k in range(n):
            sequences.append({"drive": drive, "start_s": 20.0 * k,
                              **{name: {"final_position_error_m": float(rng.uniform(0.5, 30.0 / (1 + j)))} for j, (name, _l, _c) in enumerate(ESTIMATORS)}})
    t = np.arange(int(outage_s) + 1, dtype=float)
    drift = {name: {"t_s": t.tolist(), "mean_m": (0.1 * t**2 / (1 + j)).tolist(), "p10_m": (0.05 * t**2 / (1 + j)).tolist(),
                    "p90_m": (0.2 * t**2 / (1 + j)).tolist()} for j, (name, _l, _c) in enumerate(ESTIMATORS)}
    east, north = np.linspace(0.0, 80.0, 11), np.linspace(0.0, -60.0, 11)  # south-east
    worst = {"drive": drives[0][0], "number": 3, "start_s": 40.0, "truth": {"east_m": east.tolist(), "north_m": north.tolist()},
             **{name: {"east_m": (east * (1 + 0.1 * j)).tolist(), "north_m": (north * (1 - 0.1 * j)).tolist()} for j, (name, _l, _c) in enumerate(ESTIMATORS)}}
    return {
        "drive": "+".join(d for d, _n in drives), "n_sequences": len(sequences), "outage_s": outage_s, "sequences": sequences,
        "estimators": [{"name": n, "label": lab, "color": c} for n, lab, c in ESTIMATORS], "drift": drift,
        "final_error_percentiles": {name: {"p50": 5.0} for name, _l, _c in ESTIMATORS}, "worst_tracks": worst,
    }


ONE = _report([("V-sim-roundabout", 12)])
TWO = _report([("V-sim-roundabout", 59), ("V-sim-sharp-cornering", 59)])
MANY = _report([(f"a-rather-long-drive-name-{k}", 8) for k in range(6)])


@pytest.mark.parametrize("rep", [ONE, TWO, MANY], ids=["one drive", "two drives", "six drives"])
def test_saved_widths_are_one_column_or_the_page_whatever_the_drives(rep, tmp_path):
    """3.5 in (7.16 in for outages-wide) at 300 dpi in every PNG, however many drives and however
    long their names (with two drives outages.png was 6 in, drift.png 4.3 in)."""
    write_figures(rep, tmp_path, ("svg", "png"))  # the PDFs' width is the same figure's
    for name in FIGURES:
        png = Image.open(tmp_path / f"{name}.png")
        want_in = PAGE_IN if name == "outages-wide" else COLUMN_IN
        assert png.size[0] == round(want_in * 300), (name, png.size)
        assert [round(d) for d in png.info["dpi"]] == [300, 300], name
        assert f'width="{want_in * 72:g}pt"' in (tmp_path / f"{name}.svg").read_text()[:2000], name


def _inside(inner, outer, tol=1.0) -> bool:
    return inner.x0 >= outer.x0 - tol and inner.x1 <= outer.x1 + tol and inner.y0 >= outer.y0 - tol and inner.y1 <= outer.y1 + tol


@pytest.mark.parametrize("name", FIGURES)
@pytest.mark.parametrize("rep", [ONE, TWO, MANY], ids=["one drive", "two drives", "six drives"])
def test_title_and_legend_inside_the_figure_and_the_legend_off_the_axes(rep, name):
    """The title wraps rather than running off the figure; the legend sits below the axes, not on
    the data; each estimator is in the legend by its label."""
    fig = figure(rep, name)
    renderer = fig.canvas.get_renderer()
    whole = fig.bbox
    title = fig._suptitle
    assert title is not None and _inside(title.get_window_extent(renderer), whole), (name, title.get_text())
    [legend] = fig.legends
    box = legend.get_window_extent(renderer)
    assert _inside(box, whole), name
    [ax] = fig.axes
    assert box.y1 <= ax.get_window_extent(renderer).y0 + 1, "the legend overlaps the axes"
    texts = [t.get_text() for t in legend.get_texts()]
    for _n, label, _c in ESTIMATORS:
        assert any(t.startswith(label) for t in texts), (name, label, texts)


def test_drives_are_separated_and_named_in_the_per_outage_plot():
    fig = figure(TWO, "outages")
    [ax] = fig.axes
    separators = [line for line in ax.get_lines() if len(line.get_xdata()) == 2 and np.allclose(line.get_xdata(), [59.5, 59.5])]
    assert len(separators) == 1  # between outage 59 (the first drive's last) and 60
    names = [t.get_text() for t in ax.texts]
    assert names == ["V-sim-roundabout", "V-sim-sharp-cornering"]
    # six drives' names do not fit above their outages: numbered there, named in the axis label
    fig = figure(MANY, "outages")
    [ax] = fig.axes
    assert [t.get_text() for t in ax.texts] == [f"D{k}" for k in range(1, 7)]
    assert "D1 a-rather-long-drive-name-0" in ax.get_xlabel().replace("\n", " ")
    assert not [t for t in figure(ONE, "outages").axes[0].texts]  # one drive: nothing to separate


def test_worst_outage_marks_start_end_direction_and_north_apart_from_the_track():
    fig = figure(ONE, "worst")
    [ax] = fig.axes
    renderer = fig.canvas.get_renderer()
    by_label = {line.get_label(): line for line in ax.get_lines()}
    start, end = by_label["start (last GNSS fix)"], by_label["end (truth)"]
    assert (start.get_xdata()[0], start.get_ydata()[0]) == (0.0, 0.0)
    assert (end.get_xdata()[0], end.get_ydata()[0]) == (80.0, -60.0)
    arrows = [a for a in ax.texts if getattr(a, "arrow_patch", None) is not None and a.get_text() == ""]
    assert len(arrows) == 2
    for a in arrows:  # each points the way the car drove (south-east), not north
        (x0, y0), (x1, y1) = a.xyann, a.xy
        assert x1 > x0 and y1 < y0
    [north] = [a for a in ax.texts if a.get_text() == "N"]
    assert north.xycoords == "axes fraction" and north.xy[1] > north.xyann[1]  # pointing up the page
    truth = by_label["GNSS (truth)"]
    truth_px = ax.transData.transform(np.column_stack([truth.get_xdata(), truth.get_ydata()]))
    box = north.get_window_extent(renderer).union([north.get_window_extent(renderer), north.arrow_patch.get_window_extent(renderer)])
    assert not any(box.contains(x, y) for x, y in truth_px), "the north arrow lies on the track"


def test_an_estimate_ending_on_the_truths_end_is_seen():
    """Issue 63: the truth's end was a filled square drawn over the estimates' end dots, so an
    estimate ending within a few metres of it (roundabout's GNSS-aided INS 1.0 m, odometry 1.3 m)
    had no end to see. The square is hollow now and the ends are drawn above it: the INS DR of this
    report ends exactly on the truth's end, and its colour shows there."""
    fig = figure(ONE, "worst")
    [ax] = fig.axes
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)
    x, y = ax.transData.transform((80.0, -60.0))  # the truth's end, where the INS DR ends too
    row, col = int(round(rgb.shape[0] - y)), int(round(x))
    box = rgb[row - 4 : row + 5, col - 4 : col + 5]
    ins = np.array(ESTIMATORS[0][2])
    assert int((np.abs(box - ins).max(axis=-1) <= 40).sum()) >= 6, box.tolist()


def test_bands_and_lines_are_told_apart_without_colour():
    """Each drift band is hatched in its own pattern and outlined in its estimator's colour; each
    estimator's line has its own style (drift, CDF and worst outage) and marker (per outage)."""
    fig = figure(TWO, "drift")
    [ax] = fig.axes
    bands = ax.collections
    assert len(bands) == len(ESTIMATORS)
    assert len({b.get_hatch() for b in bands}) == len(ESTIMATORS) and all(b.get_hatch() for b in bands)
    for band, (_n, _l, rgb) in zip(bands, ESTIMATORS):
        assert np.allclose(band.get_edgecolor()[0][:3], np.array(rgb) / 255)
    for name in ("drift", "cdf"):
        styles = [str(line.get_linestyle()) for line in figure(TWO, name).axes[0].get_lines()]
        assert len(set(styles)) == len(ESTIMATORS), (name, styles)
    markers = [line.get_marker() for line in figure(TWO, "outages").axes[0].get_lines() if line.get_linestyle() == "None"]
    assert len(set(markers)) == len(ESTIMATORS)
    # greyscale: the bands' hatch lines are dark enough to show on white
    for band in bands:
        grey = float(np.dot(band.get_edgecolor()[0][:3], [0.299, 0.587, 0.114]))
        assert grey < 0.75


def test_every_cdf_curve_reaches_all_outages_clear_of_the_frame():
    """A dashed curve's last step up to 1 ended at the largest error, on the axes' top edge, and
    could fall in a dash gap: it read as stopping at 0.98 (a tour found it). Every curve now runs on
    at 1 to the right edge, and 1 lies below the top of the axes."""
    ax = figure(ONE, "cdf").axes[0]
    lines = ax.get_lines()
    assert len(lines) == len(ESTIMATORS)
    right = ax.get_xlim()[1]
    finals = [max(seq[name]["final_position_error_m"] for seq in ONE["sequences"]) for name, _l, _c in ESTIMATORS]
    for line, largest in zip(lines, finals):
        x, y = line.get_xdata(), line.get_ydata()
        assert y[-1] == 1.0 and y[-2] == 1.0 and x[-2] == pytest.approx(largest) and x[-1] == right > largest
    assert ax.get_ylim()[1] > 1.0


def test_a_run_through_the_logs_own_losses_alone_is_refused_saying_so(tmp_path):
    """A replay or evaluate through the log's own GNSS losses alone (--on gnss-outage) has no
    synthetic outage to draw: one line saying so, with the option that makes them (it said 'drift:
    missing (... or one made by an earlier ionav-viz)'). The bundled tunnels drive loses GNSS 6 times."""
    from tests.conftest import run_cli

    rec, report = tmp_path / "tunnels.rrd", tmp_path / "tunnels.json"
    proc = run_cli("replay", "V-sim-motorway-tunnels", "--on", "gnss-outage", "--estimators", "ins", "-o", str(rec), "--quiet")
    assert proc.returncode == 0, proc.stderr
    proc = run_cli("evaluate", "V-sim-motorway-tunnels", "--on", "gnss-outage", "--estimators", "ins", "--json")
    assert proc.returncode == 0, proc.stderr
    report.write_text(proc.stdout)
    for given in (rec, report):
        proc = run_cli("figures", str(given), "-o", str(tmp_path / "figs"))
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
        assert proc.stderr.startswith(f"error: {given}: this run has no synthetic outages, only the log's own GNSS losses, 6 bridged")
        assert "--outage 10s, without --on gnss-outage" in proc.stderr and "earlier ionav-viz" not in proc.stderr
        assert not (tmp_path / "figs").exists()


def test_a_fleet_overview_recording_is_refused_naming_the_fleets_json(tmp_path):
    """'figures fleet.rrd' (evaluate --fleet-rrd) said the recording 'carries no report (made by an
    earlier ionav-viz?)': it is a fleet overview, and the figures take the fleet's --json."""
    from ionav_viz.sim.simulate import write_simulated_drive
    from tests.conftest import run_cli

    drives = [str(write_simulated_drive(tmp_path / f"V-{s}.csv", "motorway", seed=s, duration_s=60)) for s in (1, 2)]
    proc = run_cli("evaluate", *drives, "--estimators", "ins", "--fleet-rrd", str(tmp_path / "fleet.rrd"), "--json")
    assert proc.returncode == 0, proc.stderr
    (tmp_path / "fleet.json").write_text(proc.stdout)
    proc = run_cli("figures", str(tmp_path / "fleet.rrd"), "-o", str(tmp_path / "figs"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith(f"error: {tmp_path / 'fleet.rrd'}: a fleet overview (evaluate --fleet-rrd)")
    assert "'ionav-viz evaluate DRIVES --json > fleet.json', then 'figures fleet.json'" in proc.stderr
    assert "earlier ionav-viz" not in proc.stderr
    proc = run_cli("figures", str(tmp_path / "fleet.json"), "-o", str(tmp_path / "figs"))  # as the hint says
    assert proc.returncode == 0 and (tmp_path / "figs" / "fleet-box.png").exists(), proc.stderr


def test_a_cross_validation_report_is_named_for_what_it_is(tmp_path):
    """'figures cv.json' on cross-validate --json said "drive: missing (not a report with outages ...)":
    it now says the file is a cross-validation report and what figures takes."""
    from ionav_viz.api import CrossValidation
    from ionav_viz.api.cross_validate import Fold
    from tests.conftest import run_cli

    folds = [Fold(0, ["b"], ["a"], 10, {"ins": 2.0, "idnn": 1.5}, 25.0, 1.0), Fold(1, ["a"], ["b"], 12, {"ins": 3.0, "idnn": 2.0}, 33.3, 1.0)]
    given = tmp_path / "cv.json"
    given.write_text(CrossValidation(folds, "drive", 10.0, "cpu", "from random weights").to_json())
    proc = run_cli("figures", str(given), "-o", str(tmp_path / "figs"))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert f"{given}: a cross-validation report" in proc.stderr and "evaluate DRIVE --json" in proc.stderr
    assert "drive: missing" not in proc.stderr and not (tmp_path / "figs").exists()


def test_the_help_names_every_figure_written_and_what_it_reads():
    """'figures --help' said it writes 'drift, cdf, outages and worst' (not outages-wide nor
    calibration, nor a fleet's two) and reads 'evaluate --json' of one drive only (several drives and
    a fleet's report draw too)."""
    from ionav_viz.viz.figures import FLEET_FIGURES

    from .conftest import run_cli

    proc = run_cli("figures", "--help", env={"COLUMNS": "1000"})
    assert proc.returncode == 0
    text = " ".join(proc.stdout.split())
    assert all(f" {name} " in text or f" {name}," in text or f" {name})" in text for name in (*FIGURES, *FLEET_FIGURES)), text
    assert "for one drive" not in text and "a fleet's too" in text


def test_the_api_draws_what_replay_and_evaluate_return(tmp_path):
    """iv.figures(result, folder), as docs/outputs.md writes it, was a TypeError ('expected str,
    bytes or os.PathLike object, not ReplayResult') naming no argument, and so was a Report. Both draw
    now, the same pictures as the recording's file; anything else is an InputError naming result."""
    import ionav_viz as iv

    result = iv.replay("hard-brake", 10.0, iv.Every(60.0), estimators=["ins", "odo"], output=tmp_path / "hb.rrd")
    from_file = iv.figures(result, tmp_path / "replayed", formats=["png"])  # its recording, read back
    drawn = iv.figures(result.report, tmp_path / "report", formats=("PNG",))
    assert [p.name for p in drawn] == [p.name for p in from_file] == [f"{name}.png" for name in FIGURES]
    assert all(a.read_bytes() == b.read_bytes() for a, b in zip(drawn, from_file))
    with pytest.raises(iv.InputError, match="result of type int: not a recording, a report or its file") as info:
        iv.figures(42, tmp_path / "none")
    assert info.value.param == "result" and not (tmp_path / "none").exists()
