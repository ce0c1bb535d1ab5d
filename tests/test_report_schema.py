"""The reports' JSON names its kind and layout version (``schema``), every key it writes is in
docs/report-schema.md, and the readers refuse a newer version in one line while reading old reports."""

from __future__ import annotations

import json
import re

import pytest

import ionav_viz as iv
from ionav_viz.analysis.report import lengths_to_json, reports_to_json
from tests.conftest import REPO, run_cli

DOC = REPO / "docs" / "report-schema.md"


def documented_keys(kind: str) -> set[str]:
    """The top-level keys docs/report-schema.md lists for ``kind``: the backticked names in the
    first column of the table under the kind's heading (for ``lengths``, ``scenarios`` and
    ``by_event``: the names in their row of the shared table)."""
    text = DOC.read_text()
    if kind in ("lengths", "scenarios", "by_event"):
        row = re.findall(rf"^\| `{kind}` \| (.*)$", text, re.M)[-1]  # the first table says who writes it
        return {"schema", *re.findall(r"`([a-z_0-9]+)`", row)}
    section = re.search(rf"^## `{re.escape(kind)}`.*?$(.*?)(?=^## |\Z)", text, re.M | re.S).group(1)
    keys = set()
    for line in section.splitlines():
        if line.startswith("| `"):
            keys |= set(re.findall(r"`([a-z_0-9]+)`", line.split("|")[1]))
    return keys


@pytest.fixture(scope="module")
def report():
    return iv.evaluate(["roundabout"], 10.0)


def test_a_drive_report_names_its_kind_first_and_documents_every_key(report):
    doc = report.to_dict()
    assert next(iter(doc)) == "schema" and doc["schema"] == "ionav-viz/report/1"
    assert set(doc) - documented_keys("report") == set()


def test_several_reports_and_a_fleet_name_their_kinds_and_document_every_key(report):
    lengths = json.loads(lengths_to_json(iv.evaluate(["roundabout"], [10, 30])))
    by_event = json.loads(reports_to_json(iv.evaluate(["roundabout"], 10.0, by_event=True), key="by_event"))
    fleet = iv.evaluate(["roundabout", "hard-brake"], 10.0, engine=iv.Engine(1)).to_dict()
    for kind, doc in (("lengths", lengths), ("by_event", by_event), ("fleet", fleet)):
        assert doc["schema"] == f"ionav-viz/{kind}/1"
        assert set(doc) - documented_keys(kind) == set(), kind
    assert lengths["lengths"]["10"]["schema"] == "ionav-viz/report/1"  # each part is a report


def test_a_comparison_names_its_kind_and_documents_every_key(tmp_path, report):
    a = tmp_path / "a.json"
    a.write_text(report.to_json())
    doc = json.loads(run_cli("compare", str(a), str(a), "--json").stdout)
    assert doc["schema"] == "ionav-viz/comparison/1"
    assert set(doc) - documented_keys("comparison") == set()


@pytest.mark.parametrize("command", ["figures", "compare"])
def test_a_newer_version_is_refused_in_one_line_and_an_old_report_read(tmp_path, report, command):
    doc = report.to_dict()
    old = {k: v for k, v in doc.items() if k != "schema"}  # as reports were written before the schema key
    (tmp_path / "new.json").write_text(json.dumps({**doc, "schema": "ionav-viz/report/2"}, default=float))
    (tmp_path / "old.json").write_text(json.dumps(old, default=float).replace("NaN", "null"))
    (tmp_path / "a.json").write_text(report.to_json())
    out = ["-o", str(tmp_path / "figs")] if command == "figures" else [str(tmp_path / "a.json")]
    newer = run_cli(command, str(tmp_path / "new.json"), *out)
    assert newer.returncode == 2 and newer.stderr.count("\n") == 1
    assert "new.json: written by a newer ionav-viz (ionav-viz/report/2; this one reads version 1)" in newer.stderr
    older = run_cli(command, str(tmp_path / "old.json"), *out)
    assert older.returncode == 0, older.stderr


def test_a_comparison_is_not_taken_for_a_report(tmp_path, report):
    (tmp_path / "a.json").write_text(report.to_json())
    comparison = tmp_path / "c.json"
    comparison.write_text(run_cli("compare", str(tmp_path / "a.json"), str(tmp_path / "a.json"), "--json").stdout)
    for args in (("figures", str(comparison), "-o", str(tmp_path / "f")), ("compare", str(comparison), str(tmp_path / "a.json"))):
        proc = run_cli(*args)
        assert proc.returncode == 2 and "a comparison" in proc.stderr and proc.stderr.count("\n") == 1


def test_a_reports_typed_rows_are_its_json_and_its_tables(report):
    """The tables and the JSON are built from the same typed rows: each row is the JSON's entry,
    and its numbers are the Markdown table's cells."""
    from dataclasses import asdict

    from ionav_viz.analysis.metrics import METRICS
    from ionav_viz.core.json_out import dumps_json

    doc, markdown = report.to_dict(), report.to_markdown()
    assert [asdict(w) for w in report.worst_rows()] == doc["worst"] and doc["worst"]
    for w in report.worst_rows():
        assert f"| #{w.number} | {w.start_s:.0f}-{w.end_s:.0f} | " in markdown
        assert all(f" {x:.2f} " in markdown for x in w.final_error_m.values())
    assert [r.name for r in report.estimator_rows] == report.estimators
    for row in report.estimator_rows:
        spreads = {m: asdict(getattr(row, m)) for m in METRICS}
        assert dumps_json(spreads) == dumps_json({m: doc["summary"][row.name][m] for m in METRICS})
        assert f" {row.final_position_error_m.mean:.2f} " in markdown
    for d in report.drift_rows:
        assert doc["drift"][d.name] == {"t_s": d.t_s, "mean_m": d.mean_m, "p10_m": d.p10_m, "p90_m": d.p90_m}
        assert doc["final_error_percentiles"][d.name] == {"p50": d.final_p50_m, "p90": d.final_p90_m,
                                                          "p95": d.final_p95_m, "max": d.final_max_m}
        assert f"| {d.label} | " in markdown and f" {d.final_max_m:.1f} |" in markdown


def test_a_reports_lines_are_its_typed_values_and_those_its_json(report):
    """The lines under the tables (improvements, GNSS truth, drives, uncertainty) and the JSON are
    built from the same typed values: each is the JSON's entry, and its numbers are the lines'."""
    from dataclasses import asdict

    doc, text, markdown = report.to_dict(), report.to_text(), report.to_markdown()
    assert report.improvement_pct == doc["improvement_pct"]
    assert report.improvement_ci95_pct == doc["improvement_ci95_pct"]
    # a caller's own json.dumps takes them as the plain dicts they were
    assert json.loads(json.dumps(report.improvement_pct)) == json.loads(report.to_json())["improvement_pct"]
    assert list(report.improvement_pct) == ["idnn", "odo", "ekf"]  # every estimator but the INS DR
    for est, imp in report.improvement_pct.items():
        assert imp["crse_m"] == imp.crse_pct and imp.to_dict() == doc["improvement_pct"][est]
        lo, hi = report.improvement_ci95_pct[est].final_position_error_pct
        line = (f"{report.labels[est]} improvement over INS DR (mean): displacement CRSE {imp.crse_pct:.1f} %, "
                f"orientation-rate CRSE {imp.yaw_crse_pct:.1f} %, final position error "
                f"{imp.final_position_error_pct:.1f} % (95 % interval {lo:.1f} to {hi:.1f} %)")
        assert line in text and line in markdown
    truth = report.gnss_truth
    assert asdict(truth) == doc["gnss_truth"] and f"GNSS truth: all {truth.windows} windows trustworthy" in text
    [drive] = report.drive_entries
    assert drive.to_dict() == doc["drives"][0] and asdict(drive.gnss_truth) == doc["drives"][0]["gnss_truth"]
    assert [doc["drives"][0][k] for k in ("name", "source", "placement")] == [drive.name, drive.source, drive.placement]
    assert drive.imu is None and "imu" not in doc["drives"][0] and f"Outages: {drive.placement}\n" in text
    assert {k: v for k, v in asdict(report.distance_m).items() if k != "std"} == doc["distance_m"]
    assert report.filter_health == doc["filter_health"] and set(report.filter_health) == {"ekf"}
    assert f"{report.labels['ekf']} health: " in text
    assert report.consistency and all(doc["summary"][e]["consistency"] == c for e, c in report.consistency.items())


def test_the_logs_own_losses_are_the_typed_value_the_json_and_the_text_are_built_from():
    from dataclasses import asdict

    from ionav_viz.core.json_out import dumps_json

    report = iv.evaluate("V-sim-motorway-tunnels", placement=iv.AroundEvents(("gnss-outage",)))
    doc, text = report.to_dict(), report.to_text()
    real = report.gnss_outages
    assert dumps_json(asdict(real)) == dumps_json(doc["gnss_outages"]) and len(real.bridged) == 6
    assert real.bridged == report.bridged_rows and real.not_bridged == doc["gnss_outages"]["not_bridged"] == 0
    means = ", ".join(f"{report.labels[e]} {s.mean:.2f} m" for e, s in real.final_error_m.items())
    assert f"Mean final position error over 6 real GNSS outage(s): {means}\n" in text
    truth = report.gnss_truth
    assert asdict(truth) == doc["gnss_truth"] and truth.excluded_windows > 0
    assert f"GNSS truth: {truth.excluded_windows} of {truth.windows} windows excluded (" in text
    info = {e["name"]: e.get("info", {}) for e in doc["estimators"]}
    assert report.arbiter_notes == {e: i["arbiter"] for e, i in info.items() if "arbiter" in i} and report.arbiter_notes
    assert all(f"{report.labels[e]} arbiter: {note}\n" in text for e, note in report.arbiter_notes.items())


def test_the_overview_rows_are_the_reports_typed_values():
    """``--overview``'s total row is the report over every drive: its means and improvements, as
    ``--json`` gives them for the same drives."""
    args = ("evaluate", "roundabout", "hard-brake", "--estimators", "ins,odo", "-q")
    doc = json.loads(run_cli(*args, "--json").stdout)
    overview = run_cli(*args, "--overview", "--markdown")
    assert overview.returncode == 0, overview.stderr
    total = next(line for line in overview.stdout.splitlines() if line.startswith("| total |"))
    s, imp = doc["summary"], doc["improvement_pct"]["odo"]
    cells = [f"{s['ins']['crse_m']['mean']:.2f}", f"{s['odo']['crse_m']['mean']:.2f}", f"{imp['crse_m']:.1f}",
             f"{s['ins']['yaw_crse_radps']['mean']:.3f}", f"{s['odo']['yaw_crse_radps']['mean']:.3f}",
             f"{imp['yaw_crse_radps']:.1f}", f"{s['ins']['final_position_error_m']['mean']:.2f}",
             f"{s['odo']['final_position_error_m']['mean']:.2f}"]
    assert total.startswith(f"| total | {doc['n_sequences']} | " + " | ".join(cells) + " | "), total


def test_the_error_against_outage_length_is_typed_rows_the_json_and_the_table_are_built_from():
    from ionav_viz.analysis.report import length_rows
    from ionav_viz.core.json_out import dumps_json

    reports = iv.evaluate(["roundabout"], [10, 30], estimators=["ins", "odo"])
    rows, doc = length_rows(reports), json.loads(lengths_to_json(reports))
    assert [r.name for r in rows] == ["ins", "odo"] and rows[0].outage_s == [10.0, 30.0]
    assert dumps_json({r.name: r.to_dict() for r in rows}) == dumps_json(doc["by_length"])
    fields = ("outage_s", "n_outages", "final_position_error_m", "final_error_pct", "crse_m", "final_error_p90_m")
    assert all(doc["by_length"][r.name][f] == getattr(r, f) for r in rows for f in fields)
    assert rows[1].crse_m[1] == reports[30].summary["odo"]["crse_m"]["mean"]
    proc = run_cli("evaluate", "roundabout", "--outage", "10s,30s", "--estimators", "ins,odo", "--markdown", "-q")
    assert proc.returncode == 0, proc.stderr
    for r in rows:
        cells = [f"{m:.2f} ({p:.1f} %)" for m, p in zip(r.final_position_error_m, r.final_error_pct)]
        assert f"| {r.label} | " + " | ".join(cells + [f"{c:.2f}" for c in r.crse_m]) + " |" in proc.stdout
    assert f"10 s: {rows[0].n_outages[0]}, 30 s: {rows[0].n_outages[1]} outages)" in proc.stdout
