"""The fleet report's breakdowns (issue 42, point 3): by manoeuvre type, by time into the outage,
and each estimator's consistency pooled over the fleet, from hand-made per-drive tables whose
expected numbers are worked out here by hand; and the manoeuvre label of an outage."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from ionav_viz.analysis.events import Event, outage_manoeuvres
from ionav_viz.analysis.fleet import DriveTable, FleetReport
from ionav_viz.analysis.rows import GnssTruth
from ionav_viz.core.json_out import dumps_json


def _table(name: str, ins: list[float], odo: list[float], manoeuvre: list[str], outage_s: float = 30.0,
           at10: dict[str, list[float]] | None = None, cons: dict[str, list[float]] | None = None) -> DriveTable:
    n = len(ins)
    metrics = {est: {"final_position_error_m": np.asarray(v, dtype=float)} for est, v in (("ins", ins), ("odo", odo))}
    for per in metrics.values():  # the other metrics: not looked at here
        per |= {m: np.zeros(n) for m in ("crse_m", "cae_m", "aeps_m", "yaw_crse_radps", "yaw_cae_radps", "yaw_aeps_radps", "final_error_pct")}
    return DriveTable(spec=f"{name}.csv", name=name, source=f"{name}.csv", duration_s=600.0, distance_m=1000.0, outage_s=outage_s,
                      estimators=[{"name": "ins", "label": "INS DR"}, {"name": "odo", "label": "Odometry"}],
                      start_s=30.0 + outage_s * np.arange(n), gnss_distance_m=np.full(n, 300.0), metrics=metrics,
                      bias={}, gnss_truth=GnssTruth(n, 0, {}, 0, 0), manoeuvre=manoeuvre,
                      error_at_s={e: {"10": np.asarray(v, dtype=float)} for e, v in (at10 or {}).items()},
                      consistency={"odo": {k: np.asarray(v, dtype=float) for k, v in cons.items()}} if cons else {})


@pytest.fixture
def report() -> FleetReport:
    a = _table("A", [10.0, 20.0, 30.0], [5.0, 5.0, 15.0], ["cruise", "roundabout", "cruise"],
               at10={"ins": [1.0, 2.0, 3.0], "odo": [1.0, 1.0, 1.0]},
               cons={"nees_mean": [2.0, 4.0, 0.0], "final_nees": [1.0, 7.0, 0.5], "sq_error_m2_10": [1.0, 4.0, 9.0],
                     "trace_m2_10": [2.0, 2.0, 2.0], "sq_error_m2_30": [16.0, 16.0, 16.0], "trace_m2_30": [4.0, 4.0, 4.0]})
    b = _table("B", [40.0, 60.0], [10.0, 30.0], ["none", "cruise"], at10={"ins": [4.0, 5.0], "odo": [2.0, 2.0]},
               cons={"nees_mean": [6.0, 2.0], "final_nees": [2.0, 9.0], "sq_error_m2_10": [1.0, 1.0],
                     "trace_m2_10": [2.0, 2.0], "sq_error_m2_30": [16.0, 16.0], "trace_m2_30": [4.0, 4.0]})
    return FleetReport([a, b], outage_s=30.0)


def test_by_manoeuvre_means_and_improvement_per_type(report):
    got = report.by_manoeuvre()
    assert list(got) == ["roundabout", "cruise", "none"]  # the manoeuvre types' order, then none
    # cruise: A's 1st and 3rd, B's 2nd: INS (10 + 30 + 60) / 3 = 33.33, odometry (5 + 15 + 30) / 3 = 16.67: 50 % better
    assert got["cruise"]["outages"] == 3
    assert got["cruise"]["mean_error_m"]["ins"] == pytest.approx(100 / 3)
    assert got["cruise"]["mean_error_m"]["odo"] == pytest.approx(50 / 3)
    assert got["cruise"]["improvement_pct"]["odo"] == pytest.approx(50.0)
    assert got["roundabout"]["outages"] == 1 and got["roundabout"]["improvement_pct"]["odo"] == pytest.approx(75.0)  # 20 -> 5
    assert got["none"]["mean_error_m"] == pytest.approx({"ins": 40.0, "odo": 10.0})


def test_by_length_is_the_error_that_far_into_the_outages(report):
    got = report.by_length()
    assert list(got) == ["10", "30"]  # 10 s into 30 s outages, and their end
    assert got["10"]["outages"] == 5
    assert got["10"]["mean_error_m"]["ins"] == pytest.approx(3.0)  # (1 + 2 + 3 + 4 + 5) / 5
    assert got["10"]["mean_error_m"]["odo"] == pytest.approx(7 / 5)
    assert got["10"]["improvement_pct"]["odo"] == pytest.approx(100 * (3 - 1.4) / 3)
    assert got["30"]["mean_error_m"]["ins"] == pytest.approx(32.0)  # the final errors: 160 / 5
    assert got["30"]["improvement_pct"]["odo"] == pytest.approx(100 * (32 - 13) / 32)


def test_consistency_is_pooled_over_the_fleets_outages(report):
    got = report.consistency()
    assert list(got) == ["odo"]  # the INS DR gave no covariance
    c = got["odo"]
    assert c["anees"] == pytest.approx((2 + 4 + 0 + 6 + 2) / 5 / 2)  # per degree of freedom: NEES / 2
    assert c["n_outages"] == 5 and c["n_samples"] == 5 * 30
    assert c["coverage_95"] == pytest.approx(60.0)  # 7 and 9 lie outside the 95 % ellipse (5.99)
    assert c["error_over_sigma"]["10"] == pytest.approx(np.sqrt((1 + 4 + 9 + 1 + 1) / 5 / 2))
    assert c["error_over_sigma"]["30"] == pytest.approx(2.0)
    assert c["verdict"] == "overconfident"  # 1.4, above the band of 150 samples


def test_the_breakdowns_in_text_markdown_and_json(report):
    text = report.to_text(width=120)
    assert "By manoeuvre" in text and "By time into the outage" in text and "Odometry uncertainty: ANEES 1.40" in text
    row = next(ln for ln in text.splitlines() if ln.startswith("cruise"))
    assert row.split() == ["cruise", "3", "33.33", "16.67", "50.0"]
    md = report.to_markdown()
    assert "## By manoeuvre" in md and "| roundabout | 1 | 20.00 | 5.00 | 75.0 |" in md and "| 10 s | 5 | 3.00 | 1.40 | 53.3 |" in md
    out = json.loads(report.to_json())
    assert out["by_manoeuvre"]["cruise"]["outages"] == 3 and out["by_length"]["30"]["mean_error_m"]["ins"] == 32.0
    assert out["consistency"]["odo"]["coverage_95"] == 60.0
    assert [s["manoeuvre"] for s in out["sequences"]] == ["cruise", "roundabout", "cruise", "none", "cruise"]


def test_an_outage_is_labelled_by_the_manoeuvre_that_fills_most_of_it():
    events = [Event("cruise", 0.0, 14.0), Event("hard-brake", 14.0, 17.0), Event("roundabout", 40.0, 48.0),
              Event("sharp-cornering", 44.0, 52.0), Event("gnss-outage", 60.0, 80.0)]
    # 0-10: cruise only; 10-20: cruise 4 s, hard brake 3 s; 20-30: nothing; 40-50: roundabout 8 s, corner 6 s;
    # 42-52: 6 s and 8 s; 60-70: a real GNSS loss, not a manoeuvre
    assert outage_manoeuvres(events, np.array([0.0, 10.0, 20.0, 40.0, 42.0, 60.0]), 10.0) == [
        "cruise", "cruise", "none", "roundabout", "sharp-cornering", "none"]
    # a tie: the type first in MANOEUVRE_TYPES (hard-brake before roundabout)
    assert outage_manoeuvres([Event("roundabout", 0.0, 5.0), Event("hard-brake", 5.0, 10.0)], np.array([0.0]), 10.0) == ["hard-brake"]


def test_figures_of_a_fleet_box_per_estimator_and_pooled_cdf(report, tmp_path):
    """'figures' of a fleet's JSON: the per-drive box plot (each drive's mean final error) and the
    pooled CDF of every outage's final error, one column wide (3.5 in at 300 dpi)."""
    from PIL import Image

    from ionav_viz.viz.figures import figure, read_report
    from tests.conftest import run_cli

    src = tmp_path / "fleet.json"
    src.write_text(report.to_json())
    proc = run_cli("figures", str(src), "-o", str(tmp_path / "figs"))
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == sorted(f"fleet-{f}.{x}" for f in ("box", "cdf") for x in ("pdf", "png", "svg"))
    assert Image.open(tmp_path / "figs" / "fleet-cdf.png").size[0] == 1050
    rep = read_report(src)
    cdf = figure(rep, "fleet-cdf").axes[0]
    steps = {line.get_label().split(" (")[0]: line.get_xdata()[1:-1] for line in cdf.get_lines()}  # after 0, before the run to the edge
    np.testing.assert_allclose(steps["INS DR"], [10, 20, 30, 40, 60])  # every outage of both drives, sorted
    np.testing.assert_allclose(steps["Odometry"], [5, 5, 10, 15, 30])
    assert "INS DR (p50 30.0 m, 2 drives)" in [line.get_label() for line in cdf.get_lines()]
    box = figure(rep, "fleet-box").axes[0]
    # the drives' means: INS 20 and 50, odometry 8.33 and 20; a box's median line is the median of its drives
    medians = [line.get_ydata()[0] for line in box.get_lines() if len(line.get_xdata()) == 2 and line.get_linewidth() == 1.6]
    assert medians == pytest.approx([35.0, (25 / 3 + 20) / 2])
    points = [c.get_offsets()[:, 1] for c in box.collections if len(c.get_offsets())]
    np.testing.assert_allclose(points[0], [20.0, 50.0])
    for value in ("far", None):  # a string; a missing error (not null: absent)
        bad = json.loads(report.to_json())
        if value is None:
            del bad["sequences"][1]["ins"]["final_position_error_m"]
        else:
            bad["sequences"][1]["ins"]["final_position_error_m"] = value
        src.write_text(json.dumps(bad))
        proc = run_cli("figures", str(src), "-o", str(tmp_path / "figs2"))
        assert proc.returncode == 2 and "sequences[1].ins.final_position_error_m" in proc.stderr and not (tmp_path / "figs2").exists()
        assert len(proc.stderr.strip().splitlines()) == 1


def test_fleet_box_whiskers_are_the_drives_10th_and_90th_percentiles(tmp_path):
    """The caption says 'whiskers 10-90 %': they end at the 10th and 90th percentiles of the drives'
    means, not at the farthest drive inside them (matplotlib's whis=(10, 90), which with five drives
    put them on the box's edges)."""
    from ionav_viz.viz.figures import figure, read_report

    ins = [10.0, 20.0, 30.0, 40.0, 100.0]  # one outage per drive: its final error is the drive's mean
    tables = [_table(name, [e], [e / 10], ["cruise"], at10={"ins": [e / 3], "odo": [e / 30]}) for name, e in zip("ABCDE", ins, strict=True)]
    src = tmp_path / "fleet.json"
    src.write_text(FleetReport(tables, outage_s=30.0).to_json())
    box = figure(read_report(src), "fleet-box").axes[0]
    assert "whiskers 10-90 %" in box.figure.get_suptitle().replace("\n", " ")
    # linear interpolation between the sorted means: p10 at rank 0.4 (10 + 0.4 x 10 = 14 m), p90 at
    # rank 3.6 (40 + 0.6 x 60 = 76 m); the box is the quartiles, 20 and 40 m
    whiskers = {k: sorted(tuple(line.get_ydata()) for line in box.get_lines()
                          if list(line.get_xdata()) == [k, k]) for k in (1, 2)}
    assert whiskers[1] == [pytest.approx((20.0, 14.0)), pytest.approx((40.0, 76.0))]
    assert whiskers[2] == [pytest.approx((2.0, 1.4)), pytest.approx((4.0, 7.6))]
    np.testing.assert_allclose([w[1] for w in whiskers[1]], np.percentile(ins, [10, 90]))


def test_the_pooled_improvement_carries_an_interval_with_the_drives_resampled(report):
    # A: INS 60 m over its outages, odometry 25; B: 100 and 40. Pooled 1 - 65/160 = 59.4 %; drawing
    # two drives: AA 1 - 50/120 = 58.3 %, AB 59.4 %, BB 1 - 80/200 = 60.0 %: 58.3 to 60.0 with the
    # drives resampled, and with two drives at least the outages' interval
    from ionav_viz.analysis.evaluate import improvement_ci95_pct

    pooled = report.pooled()["odo"]
    assert pooled["improvement_pct"]["final_position_error_m"] == pytest.approx(100.0 * (1 - 65 / 160))
    lo_o, hi_o = improvement_ci95_pct(np.array([10.0, 20.0, 30.0, 40.0, 60.0]), np.array([5.0, 5.0, 15.0, 10.0, 30.0]))
    expected = [min(100.0 * (1 - 50 / 120), lo_o), max(60.0, hi_o)]
    assert pooled["improvement_ci95_pct"]["final_position_error_m"] == pytest.approx(expected)
    row = next(ln for ln in report.to_text(width=160).splitlines() if ln.startswith("Odometry "))
    assert row.split()[-4:] == ["59.4", f"{expected[0]:.1f}", "to", f"{expected[1]:.1f}"]
    assert json.loads(report.to_json())["pooled"]["odo"]["improvement_ci95_pct"]["final_position_error_m"] == pytest.approx(expected, abs=1e-6)


def test_the_report_names_each_estimator_by_its_display_name(report):
    # issue 63: the fleet report said "INS" (headers, worst outages) where every other output says "INS DR"
    for out in (report.to_text(width=120), report.to_markdown()):
        assert "INS DR" in out and not re.search(r"\bINS\b(?! DR)", out), out
    assert "Manoeuvre   outages  INS DR  Odometry  Odometry %" in report.to_text(width=120)


def test_the_typed_rows_are_the_json_and_the_tables(report):
    """The pooled and breakdown tables and the JSON are built from the same typed rows."""
    doc, markdown = report.to_dict(), report.to_markdown()
    pooled = report.pooled_rows()
    assert [p.spreads.name for p in pooled] == ["ins", "odo"]
    # as JSON: NaN (the CRSE's improvement over an INS DR without CRSE here) is null on both sides
    assert dumps_json({p.spreads.name: p.to_dict() for p in pooled}) == dumps_json(doc["pooled"])
    odo = pooled[1]
    assert odo.spreads.final_position_error_m.mean == pytest.approx(13.0)  # (5 + 5 + 15 + 10 + 30) / 5
    assert odo.improvement_pct["final_position_error_m"] == pytest.approx(100 * (1 - 13 / 32))  # INS DR: 160 / 5
    assert f"| Odometry | 2 | 5 | {odo.spreads.final_position_error_m.mean:.2f} | {odo.final_p90_m:.2f} |" in markdown
    for rows, key in ((report.manoeuvre_rows(), "by_manoeuvre"), (report.length_rows(), "by_length")):
        assert dumps_json({r.key: r.to_dict() for r in rows}) == dumps_json(doc[key])
        for r in rows:
            assert f" {r.outages} | {r.mean_error_m['ins']:.2f} | {r.mean_error_m['odo']:.2f} |" in markdown


def test_the_worst_drives_and_outages_are_typed_rows_the_json_and_the_text_are_built_from(report):
    from dataclasses import asdict

    doc, markdown = report.to_dict(), report.to_markdown()
    drives, outages = report.worst_drive_rows(), report.worst_outage_rows()
    assert [asdict(w) for w in drives] == doc["worst_drives"] == report.worst_drives()
    assert [d["gnss_truth"] for d in doc["drives"]] == [asdict(t.gnss_truth) for t in report.drives]
    assert [asdict(w) for w in outages] == doc["worst_outages"] == report.worst_outages()
    assert [(w.drive, w.mean_final_error_m["ins"]) for w in drives] == [("B", 50.0), ("A", 20.0)]
    assert [(w.drive, w.number, w.start_s, w.end_s) for w in outages[:2]] == [("B", 2, 60.0, 90.0), ("B", 1, 30.0, 60.0)]
    for k, w in enumerate(drives, 1):
        assert f"{k}. {w.drive}: {w.mean_final_error_m['ins']:.2f} m; replay: `{w.command}`" in markdown
    for k, w in enumerate(outages, 1):
        assert (f"{k}. {w.drive} outage {w.number} ({w.start_s:.0f}-{w.end_s:.0f} s): "
                f"INS DR {w.final_error_m['ins']:.1f} m, Odometry {w.final_error_m['odo']:.1f} m; see it: `{w.command}`"
                in markdown)


def test_the_logs_own_losses_are_typed_rows_the_json_and_the_text_are_built_from():
    """A fleet through its drives' own GNSS losses: per estimator pooled and per drive, worked out by
    hand, as typed rows, as the JSON's ``real_outages`` and as the tables' cells."""
    from dataclasses import asdict

    from ionav_viz.analysis.rows import BridgedRow

    def loss(drive: str, number: int, gap_s: float, ins: float, odo: float) -> BridgedRow:
        return BridgedRow(drive, number, 100.0 * number, 100.0 * number + gap_s, gap_s, 100.0 * number,
                          int(gap_s), 250.0, {"ins": ins, "odo": odo})

    none = {"ins": [], "odo": []}  # no synthetic outage
    a, b = _table("A", [], [], [], at10=none), _table("B", [], [], [], at10=none)
    a.real_outages = [loss("A", 1, 10.0, 8.0, 2.0), loss("A", 2, 5.0, 4.0, 1.0)]
    b.real_outages = [loss("B", 1, 12.0, 12.0, 6.0)]
    report = FleetReport([a, b], outage_s=30.0)
    real, doc, markdown = report.real_losses(), report.to_dict(), report.to_markdown()
    assert real.to_dict() == doc["real_outages"] == report.real_outages() and doc["real_outages"]["n"] == real.n == 3
    assert [asdict(x) for x in real.losses] == doc["real_outages"]["losses"] and real.losses[2].drive == "B"
    ins, odo = real.pooled["ins"], real.pooled["odo"]
    assert (ins.drives, ins.losses, ins.mean_final_error_m, ins.worst_drive, ins.worst_number) == (2, 3, 8.0, "B", 1)
    assert doc["real_outages"]["pooled"]["ins"]["worst"] == {"drive": "B", "number": 1, "final_error_m": 12.0}
    assert odo.mean_final_error_m == pytest.approx(3.0) and odo.worst_final_error_m == 6.0
    assert [(d.drive, d.losses, d.gap_s, d.mean_final_error_m) for d in real.drives] == [
        ("A", 2, 15.0, {"ins": 6.0, "odo": 1.5}), ("B", 1, 12.0, {"ins": 12.0, "odo": 6.0})]
    assert [asdict(d) for d in real.drives] == doc["real_outages"]["drives"]
    for e, p in real.pooled.items():
        assert (f"| {report.labels[e]} | {p.drives} | {p.losses} | {p.mean_final_error_m:.2f} | {p.p90_final_error_m:.2f} "
                f"| {p.worst_final_error_m:.1f} ({p.worst_drive} #{p.worst_number}) |") in markdown
    assert "| A | 2 | 15.0 | 6.00 | 1.50 |" in markdown and "| B | 1 | 12.0 | 12.00 | 6.00 |" in markdown
