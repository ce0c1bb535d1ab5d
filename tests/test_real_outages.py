"""Real GNSS outages in a log (issue 16, part 6): listed as events, bridged by every estimator from
the last good fix and scored at the first good fix after, from the simulator and from MCAP gaps."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.analysis.events import detect_events
from ionav_viz.sim.simulate import gnss_loss_spans, write_simulated_drive
from ionav_viz.viz import entities as ent

from .conftest import run_cli
from .mcap_fixtures import write_fix_only
from .test_replay import read_rrd

LOSSES = 3


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """The same simulated drive without and with tunnel-like losses (the losses draw from their own
    random stream, so the sensors and the fixes outside the losses are the same)."""
    folder = tmp_path_factory.mktemp("losses")
    clean = write_simulated_drive(folder / "V-clean.csv", "motorway", 7, 240.0)
    lossy = write_simulated_drive(folder / "V-lossy.csv", "motorway", 7, 240.0, gnss_losses=LOSSES)
    return clean, lossy, gnss_loss_spans("motorway", 7, 240.0, LOSSES)


def test_losses_are_listed_with_their_length(pair):
    _, lossy, spans = pair
    assert len(spans) == LOSSES
    found = [e for e in detect_events(iv.load_drive(str(lossy))) if e.type == "gnss-outage"]
    assert len(found) == LOSSES
    for e, (t0, t1, _) in zip(found, spans):
        # from the last good fix (the sample before the loss; the file's 1 ms rounding of the time
        # may put a sample on the boundary) to the first good one (at its end)
        assert t0 - 0.11 <= e.t0_s <= t0 + 0.001 and t1 - 0.001 <= e.t1_s <= t1 + 0.11
        assert t1 - t0 - 0.01 <= e.values["length_s"] <= t1 - t0 + 0.21
    proc = run_cli("events", str(lossy), "--type", "gnss-outage", "--json")
    assert proc.returncode == 0, proc.stderr
    events = json.loads(proc.stdout)[lossy.stem]
    assert [e["type"] for e in events] == ["gnss-outage"] * LOSSES and all("length_s" in e for e in events)


def test_bridged_errors_equal_synthetic_outages_on_the_clean_drive(pair):
    """The final error of a bridged loss is scored against the first good fix: the clean copy of the
    drive has that very fix, so a synthetic outage there (same start, same length) must give the
    same final position error for every estimator. Estimators that learn from the drive before the
    outage (the filter, and the IDNN's calibration from it, odometry's scale) have seen the earlier
    losses only on the lossy drive, so they must agree on the first loss; the INS always."""
    clean, lossy, _ = pair
    report = iv.evaluate([str(lossy)], 10.0, iv.AroundEvents(("gnss-outage",)))
    bridged = report.to_dict()["gnss_outages"]["bridged"]
    assert len(bridged) == LOSSES and report.to_dict()["gnss_outages"]["not_bridged"] == 0
    for i, b in enumerate(bridged):
        ref = iv.evaluate([str(clean)], float(b["outage_s"]), iv.At((b["outage_start_s"],))).to_dict()
        for est in ("ins", "idnn", "odo", "ekf") if i == 0 else ("ins",):
            assert b["final_error_m"][est] == pytest.approx(ref["sequences"][0][est]["final_position_error_m"], abs=1e-3), (b, est)


def test_replay_on_gnss_outage_reports_and_records_them(tmp_path):
    out = tmp_path / "tunnels.rrd"
    proc = run_cli("replay", "V-sim-motorway-tunnels", "--on", "gnss-outage", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "the log's own GNSS outages" in proc.stderr and "Mean final position error over 6 real GNSS outage(s)" in proc.stderr
    rows, static = read_rrd(out)
    assert len(rows["/errors/position_error_m/real_outages/ins"]) == 6 and len(rows["/errors/position_error_m/real_outages/idnn"]) == 6
    assert {"/map/ins/real_outages", "/local/idnn/real_outages", "/local/gnss_outages/end_fix"} <= static
    lane = [(t, v) for t, v in rows["/gnss/state"] if v[0] is not None]  # empty states end the lane and pad the ruler
    states = [s for _, s in lane]
    assert sum("real GNSS outage" in str(s) for s in states) == 6
    # GNSS available: 0 in every window whose state is an outage, the log's own losses too (row per window, and the last end)
    state_t = np.array([t for t, _ in lane])
    state = [str(v[0]) for _, v in lane]
    available = rows["/gnss/available"][:-1]
    in_force = [state[i] for i in np.searchsorted(state_t, [t for t, _ in available], side="right") - 1]
    assert [v[0] == 0.0 for _, v in available] == [ent.is_outage_state(s) for s in in_force]
    # tour 51: no 95 % ellipse is drawn through a real loss, and the key named them even so
    assert not any(p.endswith("/ellipse") for p in [*rows, *static])
    # issue 63: the signals' plots showed only the GNSS around each loss; each estimator's displacement and yaw rate
    # are there through it, a value per second of the loss (its windows) between two breaks: the motorway's ~25 m/s
    spans = [(t, float(str(v[0]).split("(")[1].split("-")[0]), float(str(v[0]).split("-")[1].split(" ")[0]))
             for t, v in lane if "real GNSS outage" in str(v[0])]
    for name in ("ins", "odo", "idnn"):
        disp = rows[f"/signals/displacement_m/{name}"]
        values = np.array([v[0] for _, v in disp], dtype=float)
        assert np.isnan(values[0]) and np.isnan(values[-1]) and len(rows[f"/signals/yaw_rate_radps/{name}"]) == len(disp)
        finite = values[np.isfinite(values)]
        assert len(finite) == len(values) - 2 * len(spans) and len(finite) >= sum(b - a for _, a, b in spans)
    odo = np.array([v[0] for _, v in rows["/signals/displacement_m/odo"]], dtype=float)
    assert 20.0 < np.nanmedian(odo) < 32.0
    from rerun.chunk import RrdReader

    key = " ".join(str(v) for c in RrdReader(out).stream() if str(c.entity_path).strip("/") == ent.KEY
                   for n in c.to_record_batch().schema.names if n.endswith(":text") for v in c.to_record_batch().column(n).to_pylist())
    assert "GNSS-aided INS sky blue" in key and "ellipse" not in key, key


def test_no_loss_to_bridge_is_one_line():
    proc = run_cli("replay", "roundabout", "--on", "gnss-outage")
    assert proc.returncode == 2 and "no GNSS outage of 2 s or more" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize("command", ["evaluate", "replay"])
def test_several_lengths_through_the_logs_own_losses_alone_are_refused(tmp_path, command):
    """Each real loss has its own length: --outage 10s,30s gave empty (nan) tables and twin recordings."""
    out = tmp_path / "r.rrd"
    args = ("-o", str(out)) if command == "replay" else ()
    proc = run_cli(command, "V-sim-motorway-tunnels", "--on", "gnss-outage", "--outage", "10s,30s", "--no-idnn", *args)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "--outage 10s,30s: several outage lengths, but the log's own GNSS outages" in proc.stderr, proc.stderr
    assert "hint:" in proc.stderr and "nan" not in proc.stdout
    assert not list(tmp_path.iterdir())


def test_mcap_gap_keeps_the_imu_and_is_bridged(tmp_path, caplog):
    csv = iv.load_drive("V-sim-motorway")
    path = write_fix_only(csv, tmp_path / "tunnel.mcap", 10, white_m=0.0, duplicate_share=0.0, no_fix_spans=[(200.0, 208.0)])
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        drive = iv.load_drive(str(path))
    assert np.all(np.diff(drive.t_s) < 0.25), "the IMU samples in the gap are kept (the CSV misses a sample now and then)"
    lost = (drive.t_s + drive.start_time_of_day_s - csv.start_time_of_day_s > 200.05) & (drive.t_s + drive.start_time_of_day_s - csv.start_time_of_day_s < 207.95)
    assert np.all(drive.gnss_fault[lost] != 0) and lost.sum() >= 78
    gaps = [e for e in detect_events(drive) if e.type == "gnss-outage"]
    # the fixes stop for 8 s; the 10 Hz grid sample next to each edge may fall inside the gap
    assert len(gaps) == 1 and gaps[0].values["length_s"] == pytest.approx(8.0, abs=0.35)
    report = iv.evaluate([drive], 10.0, iv.AroundEvents(("gnss-outage",))).to_dict()
    (b,) = report["gnss_outages"]["bridged"]
    assert b["outage_s"] in (9, 10) and all(np.isfinite(v) for v in b["final_error_m"].values())


def test_evaluate_on_gnss_outage_json():
    proc = run_cli("evaluate", "V-sim-motorway-tunnels", "--on", "gnss-outage", "--json")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert rep["n_sequences"] == 0 and len(rep["gnss_outages"]["bridged"]) == 6 and rep["gnss_outages"]["not_bridged"] == 0
    assert set(rep["gnss_outages"]["final_error_m"]) == {"ins", "idnn", "odo", "ekf"}


def test_the_summary_of_a_replay_through_real_losses_only_says_what_they_gave():
    """A run through the log's own losses alone has no synthetic outage: its summary (the recording's
    summary and overview tabs) shows the real ones' mean final errors and the worst, not a table of
    NaN for outages that were never run."""
    from ionav_viz.analysis.report import overview_markdown, run_summary_markdown

    rep = iv.evaluate(["V-sim-motorway-tunnels"], 10.0, iv.AroundEvents(("gnss-outage",)), estimators=["ins", "idnn"])
    result = rep.results[0]
    bridged = rep.to_dict()["gnss_outages"]["bridged"]
    ins_mean = np.mean([b["final_error_m"]["ins"] for b in bridged])
    worst = max(bridged, key=lambda b: b["final_error_m"]["ins"])
    for text in (overview_markdown(result, rep), run_summary_markdown(result, rep, "the log's own losses")):
        assert "nan" not in text.lower(), text
        assert f"**Real GNSS outages**: {len(bridged)} (" in text and f"mean m: INS DR {ins_mean:.1f}, IDNN" in text, text
        assert f"#{worst['number']} ({worst['gap_start_s']:.0f}-{worst['gap_end_s']:.0f} s, m): INS DR {worst['final_error_m']['ins']:.1f}" in text


def test_the_distance_driven_leaves_out_fixes_without_a_fix(pair, tmp_path):
    """A receiver that writes zeros while it has no fix put (0, 0) into the drive: the fleet table
    counted the way to the equator and back (23,458 km for a 5-minute drive). The distance runs over
    the trustworthy fixes only, straight across each loss: within 1 % of the clean drive's GNSS
    speed integrated over time (an independent measure; the losses are on a motorway)."""
    clean, lossy, _ = pair
    drive = iv.load_drive(str(clean))
    integrated = float(np.sum(0.5 * (drive.speed_mps[1:] + drive.speed_mps[:-1]) * np.diff(drive.t_s)))
    assert iv.load_drive(str(lossy)).distance_m == pytest.approx(integrated, rel=0.01)
    assert drive.distance_m == pytest.approx(integrated, rel=0.01)
    proc = run_cli("evaluate", str(lossy), str(clean), "--estimators", "ins", "--fleet-rrd", str(tmp_path / "fleet.rrd"), "--json")
    assert proc.returncode == 0, proc.stderr
    drives = {d["drive"]: d for d in json.loads(proc.stdout)["drives"]}
    assert drives["V-lossy"]["distance_m"] == pytest.approx(integrated, rel=0.01)


def test_a_loss_whose_next_fix_lies_out_of_reach_is_not_bridged(pair):
    """A phone's first fix after a loss can land a kilometre off (meszdav q3_02: 1017 m after 11.9 s,
    85 m/s): scored against it every estimator 'erred' by that kilometre. A loss whose fixes either
    side lie further apart than the car could drive in it (from the faster of its speeds there,
    accelerating at 3 m/s^2 throughout, 30 m for the fixes' errors) is not bridged; the others are."""
    from dataclasses import replace

    from ionav_viz.experiment.outages import OUT_OF_REACH, bridging, unbridged
    from ionav_viz.nav.windows import make_windows

    _, lossy, _ = pair
    drive = iv.load_drive(str(lossy))
    windows = make_windows(drive)
    gaps = [(e.t0_s, e.t1_s) for e in detect_events(drive) if e.type == "gnss-outage"]
    placed = bridging(windows, gaps)
    assert len(placed) == LOSSES
    _, k, n = placed[0]
    seconds = float(windows.t0_s[k + n] - windows.t0_s[k])
    reach_m = (max(windows.speed0_mps[k], windows.speed0_mps[k + n]) + 1.5 * seconds) * seconds + 30.0
    for moved_m, kept in ((reach_m - 40.0, LOSSES), (reach_m + 200.0, LOSSES - 1)):
        # the first good fix after the first loss put due north of the one before it, moved_m away
        # (a degree of latitude is 111.2 km)
        lat, lon = windows.lat0_deg.copy(), windows.lon0_deg.copy()
        lat[k + n], lon[k + n] = lat[k] + moved_m / 111_195.0, lon[k]
        moved = replace(windows, lat0_deg=lat, lon0_deg=lon)
        assert len(bridging(moved, gaps)) == kept, (moved_m, reach_m)
        assert unbridged(moved, gaps) == ({} if kept == LOSSES else {OUT_OF_REACH: 1})


def test_the_report_says_why_a_loss_was_not_bridged(pair):
    """A loss the drive (here: its span) ends right after cannot be bridged (its first good fix is
    there, but no window from it to score at): the report counts it and says why, in the JSON and
    the text."""
    from ionav_viz.experiment.outages import DRIVE_END

    _, lossy, spans = pair
    _, t1, _ = spans[-1]
    report = iv.evaluate([str(lossy)], 10.0, iv.AroundEvents(("gnss-outage",)), read=iv.ReadOptions(span=f"0s:{t1 + 0.5:.1f}s"))
    g = report.to_dict()["gnss_outages"]
    assert len(g["bridged"]) == LOSSES - 1 and g["not_bridged"] == 1 and g["not_bridged_by_reason"] == {DRIVE_END: 1}
    assert f"; 1 outage(s) not bridged (1 with {DRIVE_END})" in report.to_text()
