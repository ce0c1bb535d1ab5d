"""Issue 31.2 and 31.4: drift curves and final-error percentiles in the report, and the exports
(outages.csv, evo's TUM tracks, GeoJSON and GPX) read back with the tools they are for."""

from __future__ import annotations

import csv
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import ionav_viz as iv

from .conftest import run_cli


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    report = iv.evaluate("roundabout", placement=iv.Every(60.0), estimators=["ins", "odo", "ekf"], export=folder)
    return report, json.loads(report.to_json()), folder


def test_evo_reads_the_tum_tracks_and_their_end_points_are_the_final_errors(exported):
    """The end-point distance between an estimate's and the truth's TUM track, as evo reads them,
    is the report's final position error within 1 cm."""
    from evo.tools import file_interface

    _, got, folder = exported
    tum = folder / "tum" / "V-sim-roundabout"
    checked = 0
    for i, seq in enumerate(got["sequences"], start=1):
        truth = file_interface.read_tum_trajectory_file(str(tum / f"outage-{i:03d}-truth.tum"))
        assert truth.num_poses == 11 and abs(truth.timestamps[-1] - truth.timestamps[0] - 10.0) < 1e-6
        for est in ("ins", "odo", "ekf"):
            track = file_interface.read_tum_trajectory_file(str(tum / f"outage-{i:03d}-{est}.tum"))
            np.testing.assert_allclose(track.timestamps, truth.timestamps)
            end = float(np.linalg.norm(track.positions_xyz[-1] - truth.positions_xyz[-1]))
            assert abs(end - seq[est]["final_position_error_m"]) < 0.01, (i, est, end, seq[est]["final_position_error_m"])
            checked += 1
    assert checked >= 27


def test_the_outage_table_geojson_and_gpx_hold_every_outage(exported):
    _, got, folder = exported
    with open(folder / "outages.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3 * got["n_sequences"] and set(rows[0]) >= {"crse_m", "yaw_crse_radps", "final_position_error_m", "start_stamp_s"}
    for row in rows:
        seq = got["sequences"][int(row["outage"]) - 1]
        assert float(row["final_position_error_m"]) == pytest.approx(seq[row["estimator"]]["final_position_error_m"], rel=1e-12)
        assert float(row["start_s"]) == seq["start_s"]
    geo = json.loads((folder / "tracks.geojson").read_text())
    kinds = [f["properties"]["kind"] for f in geo["features"]]
    assert kinds.count("truth") == 1 and kinds.count("estimate") == 3 * got["n_sequences"]
    lon, lat = geo["features"][0]["geometry"]["coordinates"][0][0]
    drive = iv.load_drive("roundabout")
    assert (lat, lon) == pytest.approx((drive.lat_deg[0], drive.lon_deg[0]), abs=1e-8)  # GeoJSON: longitude first
    gpx = ET.parse(folder / "tracks.gpx").getroot()
    ns = {"g": "http://www.topografix.com/GPX/1/1"}
    assert len(gpx.findall("g:trk", ns)) == 1 + 3 * got["n_sequences"]


def test_drift_curves_and_percentiles_agree_with_the_outages(exported):
    """Drift: zero at the start for estimators that start on the fix, its end the mean final
    error; the percentiles are those of the per-outage final errors (computed here with numpy)."""
    report, got, _ = exported
    for est in ("ins", "odo", "ekf"):
        d = got["drift"][est]
        finals = np.array([s[est]["final_position_error_m"] for s in got["sequences"]])
        assert d["t_s"] == [float(k) for k in range(11)] and d["mean_m"][0] == pytest.approx(0.0, abs=1e-6)
        assert d["mean_m"][-1] == pytest.approx(finals.mean(), rel=1e-9)
        errors_at_end = finals  # the band at the end: the 10th and 90th percentiles of the final errors
        assert (d["p10_m"][-1], d["p90_m"][-1]) == pytest.approx((np.percentile(errors_at_end, 10), np.percentile(errors_at_end, 90)))
        pct = got["final_error_percentiles"][est]
        assert pct == pytest.approx({"p50": np.median(finals), "p90": np.percentile(finals, 90), "p95": np.percentile(finals, 95),
                                     "max": finals.max()})
    text = report.to_text()
    assert "Position error since the outage began (m)" in text and "p95" in text


def test_export_from_the_command_line(tmp_path):
    proc = run_cli("replay", "hard-brake", "--every", "60s", "--no-idnn", "-o", str(tmp_path / "r.rrd"), "--export", str(tmp_path / "ex"), "-q")
    assert proc.returncode == 0, proc.stderr
    assert {p.name for p in (tmp_path / "ex").iterdir()} == {"outages.csv", "tracks.geojson", "tracks.gpx", "tum"}


def test_figures_from_a_recording_and_from_json(tmp_path):
    """Issue 31.3: drift, CDF, per-outage and worst-outage figures as SVG, PDF and PNG, from the
    recording replay wrote and from evaluate --json alike; labels as text in the SVG; one paper
    column wide (3.5 in at 300 dpi)."""
    from PIL import Image

    rec = tmp_path / "r.rrd"
    assert run_cli("replay", "roundabout", "--every", "60s", "--no-idnn", "-o", str(rec), "-q").returncode == 0
    proc = run_cli("figures", str(rec), "-o", str(tmp_path / "figs"))
    assert proc.returncode == 0, proc.stderr
    names = {p.name for p in (tmp_path / "figs").iterdir()}
    assert names == {f"{f}.{x}" for f in ("drift", "cdf", "outages", "outages-wide", "worst", "calibration") for x in ("svg", "pdf", "png")}
    drift_svg = (tmp_path / "figs" / "drift.svg").read_text()
    assert all(label in drift_svg for label in ("INS DR", "Odometry", "GNSS-aided INS", "position error (m)"))
    assert "20 m" in (tmp_path / "figs" / "worst.svg").read_text() or " m</text>" in (tmp_path / "figs" / "worst.svg").read_text()
    width, _ = Image.open(tmp_path / "figs" / "drift.png").size
    assert 900 <= width <= 1200
    assert (tmp_path / "figs" / "cdf.pdf").read_bytes().startswith(b"%PDF")

    js = tmp_path / "r.json"
    js.write_text(run_cli("evaluate", "roundabout", "--every", "60s", "--no-idnn", "--json").stdout)
    proc = run_cli("figures", str(js), "-o", str(tmp_path / "figs2"), "--format", "png,.SVG")  # only those two
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "figs2").iterdir()) == sorted(f"{f}.{x}" for f in ("drift", "cdf", "outages", "outages-wide", "worst", "calibration") for x in ("svg", "png"))
    for bad, fragment in [("jpg", "error: --format: format 'jpg' is unknown (hint: choose from svg, pdf, png)"), (",", "error: --format: no format given")]:
        proc = run_cli("figures", str(js), "-o", str(tmp_path / "x"), "--format", bad)
        assert proc.returncode == 2 and proc.stderr == fragment + ("\n" if bad == "jpg" else proc.stderr[len(fragment):]), proc.stderr
        assert not (tmp_path / "x").exists()
    for bad, fragment in [(tmp_path / "figs" / "cdf.pdf", "not UTF-8 text"), (tmp_path / "none.json", "no such file")]:
        proc = run_cli("figures", str(bad), "-o", str(tmp_path / "x"))
        assert proc.returncode == 2 and fragment in proc.stderr and "Traceback" not in proc.stderr, proc.stderr


def test_several_outage_lengths_in_one_call():
    """Issue 31.2: --outage 10s,30s,60s runs every length on the same drives; each length's report
    is the single-length run's, and the error against outage length summarises them."""
    proc = run_cli("evaluate", "hard-brake", "--outage", "30s,10s", "--no-idnn", "--json")
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    assert list(got["lengths"]) == ["10", "30"]
    single = json.loads(iv.evaluate("hard-brake", 30.0, estimators=["ins", "odo", "ekf"]).to_json())
    assert got["lengths"]["30"]["sequences"] == single["sequences"]
    for est in ("ins", "odo", "ekf"):
        row = got["by_length"][est]
        assert row["outage_s"] == [10.0, 30.0]
        finals = [s[est]["final_position_error_m"] for s in single["sequences"]]
        assert row["final_position_error_m"][1] == pytest.approx(np.mean(finals)) and row["n_outages"][1] == len(finals)
    text = run_cli("evaluate", "hard-brake", "--outage", "10s,30s", "--no-idnn")
    assert text.returncode == 0 and "Error against outage length" in text.stdout
    bad = run_cli("evaluate", "--scenario", "all", "--outage", "10s,30s")
    assert bad.returncode == 2 and "--scenario" in bad.stderr


def test_several_outage_lengths_replayed_into_one_recording_each(tmp_path):
    """Issue 31.2: replay --outage 10s,30s writes a recording per length (each carrying its own
    report), then the error against outage length."""
    from ionav_viz.viz.recording_info import report_json

    proc = run_cli("replay", "hard-brake", "--outage", "10s,30s", "--no-idnn", "-o", str(tmp_path / "hb.rrd"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == [str(tmp_path / "hb-10s.rrd"), str(tmp_path / "hb-30s.rrd")]
    assert [json.loads(report_json(tmp_path / f"hb-{x}s.rrd"))["outage_s"] for x in (10, 30)] == [10, 30]
    assert "Error against outage length" in proc.stderr
    bad = run_cli("replay", "hard-brake", "--outage", "10s,30s", "--open")
    assert bad.returncode == 2 and "--open" in bad.stderr


def test_a_length_the_drive_has_no_room_for_is_left_out_and_said(tmp_path):
    """--outage 10s,700s on a 600 s drive: the 10 s results, and one warning for 700 s (before, the
    whole run failed, and replay had already written the 10 s recording); none fits: one error,
    nothing written."""
    proc = run_cli("evaluate", "hard-brake", "--outage", "10s,700s", "--estimators", "ins", "--json")
    assert proc.returncode == 0, proc.stderr
    assert list(json.loads(proc.stdout)["lengths"]) == ["10"]
    assert "too short for a 700 s outage" in proc.stderr and "that length is left out" in proc.stderr
    proc = run_cli("replay", "hard-brake", "--outage", "10s,700s", "--estimators", "ins", "-q", "-o", str(tmp_path / "hb.rrd"))
    assert proc.returncode == 0 and proc.stdout.split() == [str(tmp_path / "hb-10s.rrd")], proc.stderr
    proc = run_cli("replay", "hard-brake", "--outage", "700s,800s", "--estimators", "ins", "-q", "-o", str(tmp_path / "no.rrd"))
    assert proc.returncode == 2 and "too short for a 700 s outage" in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hb-10s.rrd"]


def test_an_export_folder_that_cannot_be_made_stops_before_any_work(tmp_path):
    (tmp_path / "taken").write_text("a file")
    proc = run_cli("replay", "hard-brake", "--no-idnn", "-o", str(tmp_path / "r.rrd"), "--export", str(tmp_path / "taken" / "ex"), "-q")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "--export" in proc.stderr, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]  # no recording written


def test_exports_through_the_logs_own_losses_leave_untrusted_fixes_out_and_list_the_losses(tmp_path):
    """The bundled tunnel drive's receiver writes zeros or freezes in its six losses: the truth
    track broke to (0, 0) in QGIS (21 points of 599). Now its stretches of trustworthy fixes only,
    one GPX segment each; and with --on gnss-outage real_outages.csv lists each loss per estimator
    as the report does, and the tracks hold the estimates through them (before: an empty table)."""
    import ionav_viz as iv

    folder = tmp_path / "ex"
    proc = run_cli("evaluate", "V-sim-motorway-tunnels", "--on", "gnss-outage", "--estimators", "ins,odo", "--json", "--export", str(folder))
    assert proc.returncode == 0, proc.stderr
    bridged = json.loads(proc.stdout)["gnss_outages"]["bridged"]
    drive = iv.load_drive("V-sim-motorway-tunnels")
    good = {(round(float(a), 8), round(float(b), 8)) for a, b in zip(drive.lat_deg[drive.gnss_ok], drive.lon_deg[drive.gnss_ok])}
    geo = json.loads((folder / "tracks.geojson").read_text())
    truth = next(f for f in geo["features"] if f["properties"]["kind"] == "truth")["geometry"]
    assert truth["type"] == "MultiLineString" and len(truth["coordinates"]) >= len(bridged) + 1
    assert all((lat, lon) in good for line in truth["coordinates"] for lon, lat in line)  # no (0, 0), no frozen fix
    real = [f for f in geo["features"] if f["properties"]["kind"] == "real-outage"]
    assert len(real) == 2 * len(bridged)
    with open(folder / "real_outages.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * len(bridged)
    for row in rows:
        b = bridged[int(row["outage"]) - 1]
        assert float(row["final_position_error_m"]) == pytest.approx(b["final_error_m"][row["estimator"]], abs=1e-3)
        assert float(row["gap_s"]) == pytest.approx(b["gap_s"], abs=0.006)  # the JSON rounds to 0.01 s
    gpx = ET.parse(folder / "tracks.gpx").getroot()
    ns = {"g": "http://www.topografix.com/GPX/1/1"}
    trk = gpx.findall("g:trk", ns)
    assert len(trk[0].findall("g:trkseg", ns)) == len(truth["coordinates"]) and len(trk) == 1 + 2 * len(bridged)
    points = [(float(p.get("lat")), float(p.get("lon"))) for p in trk[0].iter("{http://www.topografix.com/GPX/1/1}trkpt")]
    assert min(abs(lat) for lat, _ in points) > 1.0


def test_the_local_frame_is_about_the_first_trustworthy_fix(tmp_path):
    """A receiver without a fix yet writes (0, 0): the TUM tracks were about that point, on the
    equator, 5,800 km from the drive (x -57006 m, y 5841111 m), where the azimuthal equidistant plane
    is 15 % off scale. Their frame, and the one an external trajectory in local metres is read in, is
    about the first trustworthy fix now, which the header names; a trajectory written in that frame
    (the exported truth) is read back onto the truth."""
    import ionav_viz as iv

    drive = tmp_path / "V-late-fix.csv"
    iv.simulate("roundabout", tmp_path / "V-day.csv", seed=3, duration_s=120.0)
    lines = (tmp_path / "V-day.csv").read_text().splitlines()
    rows = [lines[0]]
    for k, line in enumerate(lines[1:]):
        cells = line.split(",")
        if k < 50:  # the first 5 s: no satellites, no fix
            cells[0], cells[2], cells[3] = "0", "0", "0"
        rows.append(",".join(cells))
    drive.write_text("\n".join(rows) + "\n")
    loaded = iv.load_drive(drive)
    first = int(np.flatnonzero(loaded.gnss_ok)[0])
    assert first >= 50 and loaded.lat_deg[0] == 0.0
    assert run_cli("outage-log", str(drive), "--every", "30s", "-o", str(tmp_path / "cut.csv")).returncode == 0
    plan = str(tmp_path / "cut.outages.json")
    proc = run_cli("evaluate", str(drive), "--plan", plan, "--estimators", "ins", "--export", str(tmp_path / "ex"), "-q")
    assert proc.returncode == 0, proc.stderr
    files = sorted((tmp_path / "ex" / "tum" / "V-late-fix").glob("outage-*-truth.tum"))
    assert files
    header = files[0].read_text().splitlines()[0]
    assert f"lat {loaded.lat_deg[first]:.8f} lon {loaded.lon_deg[first]:.8f} deg" in header, header
    poses = np.array([[float(x) for x in line.split()] for f in files for line in f.read_text().splitlines()[1:]])
    assert np.abs(poses[:, 1:3]).max() < 5000.0  # metres about the drive, not about (0, 0)
    mine = tmp_path / "mine.tum"
    _, keep = np.unique(poses[:, 0], return_index=True)
    mine.write_text("".join(" ".join(f"{v:.9f}" for v in row) + "\n" for row in poses[keep]))
    proc = run_cli("evaluate", str(drive), "--plan", plan, "--external", f"mine={mine}", "--estimators", "ins", "--json")
    assert proc.returncode == 0, proc.stderr
    errors = [s["mine"]["final_position_error_m"] for s in json.loads(proc.stdout)["sequences"]]
    assert errors and max(errors) < 0.01, errors


def test_a_span_keeps_its_drives_local_frame(tmp_path):
    """A span kept the drive's clock but took its own frame, about the span's first fix: the TUM
    exports of the whole drive and of a span laid the same outage metres apart, and an external
    estimator's trajectory in local metres, made on the whole outaged log (``outage-log --span``
    writes the whole log, GNSS cut in the span's outages alone), was read about the wrong point. The
    span's frame is the whole drive's now."""
    iv.simulate("roundabout", tmp_path / "V-day.csv", seed=3, duration_s=120.0)
    drive = str(tmp_path / "V-day.csv")
    assert run_cli("outage-log", drive, "--span", "60s:120s", "--every", "20s", "--warm-up", "0s", "-o", str(tmp_path / "cut.csv")).returncode == 0
    plan = str(tmp_path / "cut.outages.json")
    for name, extra in (("whole", []), ("span", ["--span", "60s:120s"])):
        proc = run_cli("evaluate", drive, "--plan", plan, "--estimators", "ins", "--export", str(tmp_path / name), "-q", *extra)
        assert proc.returncode == 0, proc.stderr
    whole = sorted((tmp_path / "whole" / "tum" / "V-day").glob("*-truth.tum"))
    span = sorted((tmp_path / "span" / "tum" / "V-day").glob("*-truth.tum"))
    assert len(span) >= 2 and [f.name for f in whole] == [f.name for f in span]
    for a, b in zip(whole, span):  # the same origin, the same x and y at the same stamps
        assert a.read_text() == b.read_text()
    mine = tmp_path / "mine.tum"
    poses = {line.split()[0]: line for f in whole for line in f.read_text().splitlines()[1:]}
    mine.write_text("".join(line + "\n" for line in sorted(poses.values(), key=lambda line: float(line.split()[0]))))
    proc = run_cli("evaluate", drive, "--span", "60s:120s", "--plan", plan, "--external", f"mine={mine}", "--estimators", "ins", "--json")
    assert proc.returncode == 0, proc.stderr
    errors = [s["mine"]["final_position_error_m"] for s in json.loads(proc.stdout)["sequences"]]
    assert errors and max(errors) < 0.01, errors


def test_two_drives_of_one_name_are_told_apart_in_the_report_and_the_export(tmp_path):
    """a/V-x.csv and b/V-x.csv are both drive V-x: the JSON's sequences, worst outages and drives
    named both V-x (the worst outage's tracks came from whichever was first), and --export stopped
    with 'tum/V-x: cannot write the export (File exists)' (a tour found the JSON's). Both are named
    by their files now, in the report and the export alike."""
    import shutil

    from ionav_viz.dataset.samples import samples_dir

    for folder, sample in (("a", "V-sim-roundabout.csv"), ("b", "V-sim-motorway.csv")):
        (tmp_path / folder).mkdir()
        shutil.copy(samples_dir() / sample, tmp_path / folder / "V-x.csv")
    proc = run_cli("evaluate", "a/V-x.csv", "b/V-x.csv", "--estimators", "ins", "--export", "ex", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert [d["name"] for d in rep["drives"]] == ["a/V-x.csv", "b/V-x.csv"]
    assert {s["drive"] for s in rep["sequences"]} == {"a/V-x.csv", "b/V-x.csv"}
    report = iv.evaluate([str(tmp_path / "a" / "V-x.csv"), str(tmp_path / "b" / "V-x.csv")], 10.0, estimators=["ins"])
    b_label = report.drive_labels[1]
    assert report.outage_tracks(b_label, 1)["start_s"] == report.to_dict()["sequences"][len(report.results[0].starts)]["start_s"]
    assert sorted(p.name for p in (tmp_path / "ex" / "tum").iterdir()) == ["a_V-x.csv", "b_V-x.csv"]
    with open(tmp_path / "ex" / "outages.csv") as f:
        assert {row["drive"] for row in csv.DictReader(f)} == {"a/V-x.csv", "b/V-x.csv"}


GPX_NS = "{http://www.topografix.com/GPX/1/1}"


def _gpx_times(trk) -> list:
    """The times of a GPX track's points, each checked to be ISO 8601 in UTC."""
    from datetime import datetime, timedelta

    points = list(trk.iter(f"{GPX_NS}trkpt"))
    texts = [p.find(f"{GPX_NS}time").text for p in points]  # every point has one (None: AttributeError)
    assert all(t.endswith("Z") for t in texts), texts[:3]
    times = [datetime.fromisoformat(t) for t in texts]
    assert all(t.utcoffset() == timedelta(0) for t in times)
    tags = [child.tag.removeprefix(GPX_NS) for child in trk]  # GPX 1.1's order: name, desc, then the segments
    assert tags[:1] == ["name"] and tags[1 + (tags[1:2] == ["desc"]):] == ["trkseg"] * tags.count("trkseg") > []
    assert [p.tag for p in points[0]] == [f"{GPX_NS}time"]
    return times


def test_gpx_points_carry_their_utc_times_from_the_drives_clock(exported):
    # issue 63: the GPX tracks had no <time>; an IO-VNBD clock is a time of day, without a date
    from datetime import UTC, datetime, timedelta

    _, got, folder = exported
    drive = iv.load_drive("roundabout")
    trks = ET.parse(folder / "tracks.gpx").getroot().findall(f"{GPX_NS}trk")
    epoch = datetime(1970, 1, 1, tzinfo=UTC)
    for trk in trks:
        times = _gpx_times(trk)
        assert all(b > a for a, b in zip(times, times[1:])), trk.find(f"{GPX_NS}name").text  # increasing, segments too
        assert "carries no date" in trk.find(f"{GPX_NS}desc").text
    truth = _gpx_times(trks[0])
    assert truth[0] == epoch + timedelta(seconds=round(float(drive.stamp_s(drive.t_s[drive.gnss_ok][0])), 3))
    for i, seq in enumerate(got["sequences"]):  # each outage's tracks: 1 s apart from its start, on the drive's clock
        times = _gpx_times(trks[1 + 3 * i])
        assert times[0] == epoch + timedelta(seconds=round(float(drive.stamp_s(seq["start_s"])), 3))
        assert [(b - a).total_seconds() for a, b in zip(times, times[1:])] == [1.0] * int(got["outage_s"])


def test_gpx_times_of_a_dated_log_are_its_instants(tmp_path):
    from dataclasses import replace
    from datetime import UTC, datetime

    drive = replace(iv.load_drive("roundabout"), start_stamp_s=1_700_000_000.25)  # UNIX time, as a message log's
    iv.evaluate([drive], 10.0, iv.At((100.0,)), estimators=["ins"], export=tmp_path / "ex")
    trks = ET.parse(tmp_path / "ex" / "tracks.gpx").getroot().findall(f"{GPX_NS}trk")
    assert all(trk.find(f"{GPX_NS}desc") is None for trk in trks)  # nothing to say: the times are the log's own
    assert _gpx_times(trks[1])[0] == datetime.fromtimestamp(1_700_000_100.25, UTC)
    assert _gpx_times(trks[1])[0].isoformat() == "2023-11-14T22:15:00.250000+00:00"


def test_geojson_features_carry_simplestyle_properties_in_the_recordings_colours(exported):
    # issue 63: the GeoJSON had no style: every track drew in one default colour
    from ionav_viz.viz.style import GNSS_COLOR, estimator_colors

    report, _, folder = exported
    colors = estimator_colors(report.results[0].estimators)
    for feature in json.loads((folder / "tracks.geojson").read_text())["features"]:
        p = feature["properties"]
        rgb = GNSS_COLOR if p["kind"] == "truth" else colors[p["estimator"]]
        assert p["stroke"] == p["marker-color"] == "#{:02x}{:02x}{:02x}".format(*rgb)
        assert p["stroke-width"] > 0 and 0 < p["stroke-opacity"] <= 1 and p["title"].startswith("V-sim-roundabout ")
        if p["kind"] == "estimate":
            assert p["title"] == f"V-sim-roundabout outage {p['outage']} {p['label']}, final error {p['final_position_error_m']:.1f} m"
