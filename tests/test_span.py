"""--span START:END: one stretch of each drive, on its own clock, for evaluate, replay, train and the API."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import run_cli


def _starts(args: list[str]) -> list[float]:
    proc = run_cli("evaluate", "roundabout", "--estimators", "ins", "--json", *args)
    assert proc.returncode == 0, proc.stderr
    return [s["start_s"] for s in json.loads(proc.stdout)["sequences"]]


def test_outages_stay_inside_the_span_at_both_edges():
    # without a warm-up, window 30-31 s only feeds the IDNN's first input: the first outage starts at 31 s
    assert _starts(["--span", "30s:95s", "--warm-up", "0s"]) == [31.0, 41.0, 51.0, 61.0, 71.0, 81.0]  # 91-101 would cross 95 s: not placed
    assert _starts(["--span", "30s:101s", "--warm-up", "0s"])[-1] == 91.0  # ends exactly on the span's end: placed
    assert min(_starts(["--span", "580s:", "--warm-up", "0s"])) >= 581.0
    # the warm-up counts from the span's start: the filters have had the span's first 30 s
    assert _starts(["--span", "30s:95s"]) == [60.0, 70.0, 80.0]


def test_span_in_the_api_is_the_same_value():
    import ionav_viz as iv
    from ionav_viz.sources.load import ReadOptions

    report = iv.evaluate("roundabout", 10, estimators=["ins"], read=ReadOptions(span="30s:95s"), run=iv.RunOptions(warm_up_s=0.0))
    assert [s["start_s"] for s in json.loads(report.to_json())["sequences"]] == _starts(["--span", "30s:95s", "--warm-up", "0s"])
    assert ReadOptions(span=(30.0, 95.0)).span == ReadOptions(span="30s:95s").span


def test_training_windows_lie_inside_the_span():
    from ionav_viz.nav.windows import make_windows
    from ionav_viz.sources.load import ReadOptions, load_drive

    drive = load_drive("roundabout", ReadOptions(span="30s:95s"))
    again = load_drive(drive, ReadOptions(span="30s:95s"))  # a span of a span is the same span
    assert drive.t_s[0] == pytest.approx(30.0) and drive.t_s[-1] == pytest.approx(95.0) and len(again) == len(drive)
    for phase in range(10):
        w = make_windows(drive, offset_s=phase / 10)
        assert w.t0_s.min() >= 30.0 - 1e-9 and w.t0_s.max() + 1.0 <= 95.0 + 1e-9


def test_replay_takes_the_span(tmp_path):
    proc = run_cli("replay", "roundabout", "--span", "30s:95s", "--warm-up", "0s", "--estimators", "ins", "-o", str(tmp_path / "r.rrd"))
    assert proc.returncode == 0, proc.stderr
    assert "81-91" in proc.stderr and "91-101" not in proc.stderr  # the worst outages, on the drive's own clock


def test_two_spans_of_a_drive_replay_into_two_default_recordings(tmp_path):
    """'replay D --span 0s:60s' then 'replay D --span 60s:' both wrote recordings/D.rrd, the second
    over the first; the default name carries the span now, as it carries the outage length."""
    import ionav_viz as iv

    drive = iv.simulate("roundabout", tmp_path / "V-d.csv", seed=2, duration_s=120.0)
    paths = []
    for span in ("0s:60s", "60s:", None):
        proc = run_cli("replay", str(drive), *(["--span", span] if span else []), "--warm-up", "0s", "--estimators", "ins", "-q", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        paths.append(proc.stdout.strip())
    assert paths == ["recordings/V-d-0s-60s.rrd", "recordings/V-d-60s-end.rrd", "recordings/V-d.rrd"]
    assert all((tmp_path / p).is_file() for p in paths)
    proc = run_cli("replay", str(drive), "--span", "0s:60s", "--outage", "10s,20s", "--warm-up", "0s", "--estimators", "ins", "-q", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["recordings/V-d-0s-60s-10s.rrd", "recordings/V-d-0s-60s-20s.rrd"]
    # a fleet names its recordings the same way (it wrote both spans to <drive>.rrd, the second over the first)
    for span in ("0s:60s", "60s:"):
        proc = run_cli("replay", str(drive), "roundabout", "--workers", "1", "--span", span, "--warm-up", "0s", "--estimators", "ins", "-q",
                       "-o", str(tmp_path / "fleet"))
        assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "fleet").iterdir()) == ["V-d-0s-60s.rrd", "V-d-60s-end.rrd", "roundabout-0s-60s.rrd",
                                                                       "roundabout-60s-end.rrd"]


@pytest.mark.parametrize(("span", "words"), [("5s:3s", "end is not after its start"), ("5x:", "'5x' is not a time"),
                                              ("30s", "is not START:END"), ("5000s:", "holds no samples")])
def test_a_bad_span_is_one_line_naming_the_option(span, words):
    proc = run_cli("evaluate", "roundabout", "--estimators", "ins", "--span", span)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: --span:") and words in proc.stderr and proc.stderr.count("\n") == 1
    assert "Traceback" not in proc.stderr


def test_span_contains_both_ends():
    from ionav_viz.core.durations import parse_span

    span = parse_span("0s:330s")
    assert span.contains(np.array([0.0, 330.0, 330.1])).tolist() == [True, True, False]
    assert str(parse_span("330s:")) == "330s:" and parse_span(":5m").end_s == 300.0


def test_a_plan_made_on_a_span_is_read_on_the_same_span(tmp_path):
    proc = run_cli("outage-log", "roundabout", "--span", "30s:95s", "-o", str(tmp_path / "o.mcap"))
    assert proc.returncode == 0, proc.stderr
    plan = str(tmp_path / "o.outages.json")
    assert _starts(["--span", "30s:95s", "--plan", plan]) == _starts(["--span", "30s:95s"])
    elsewhere = run_cli("evaluate", "roundabout", "--span", "100s:200s", "--plan", plan, "--estimators", "ins")
    assert elsewhere.returncode == 2 and "outside the drive V-sim-roundabout (99.999-199.999 s)" in elsewhere.stderr  # the samples stamped on the ends


def test_spans_that_meet_tile_the_drive_on_its_own_grid():
    """The bundled drives are stamped as IO-VNBD is, in whole milliseconds with a millisecond of jitter
    (the roundabout's 100 s sample is stamped 99.999 s): a span's end is still on that sample, and
    the windows of 0s:100s and 100s:200s are exactly those of 0s:200s (100 + 100, on the same 0.1 s
    grid: the second span's first window starts at 100 s, not 100.1 s)."""
    from ionav_viz.nav.windows import make_windows
    from ionav_viz.sources.load import ReadOptions, load_drive

    whole = load_drive("roundabout")
    assert np.any(np.abs(whole.t_s - 99.999) < 1e-9) and not np.any(np.abs(whole.t_s - 100.0) < 1e-9)
    halves = [make_windows(load_drive("roundabout", ReadOptions(span=s))) for s in ("0s:100s", "100s:200s")]
    assert [len(w) for w in halves] == [100, 100]
    both = make_windows(load_drive("roundabout", ReadOptions(span="0s:200s")))
    np.testing.assert_allclose(np.concatenate([w.t0_s for w in halves]), both.t0_s, atol=1e-9)
    np.testing.assert_allclose(both.t0_s, np.arange(200.0), atol=1e-9)
    assert _starts(["--span", "100s:200s", "--warm-up", "0s"])[0] == 101.0


def test_a_span_past_the_drives_end_is_said_with_the_span_read(tmp_path):
    """'--span 0s:1000s' on a 180 s drive was taken silently; it is said once now, with the drive's
    end and the span read, and the model records the span it was trained on."""
    import ionav_viz as iv

    drive = iv.simulate("roundabout", tmp_path / "V-r180.csv", seed=2, duration_s=180.0)
    proc = run_cli("evaluate", str(drive), "--estimators", "ins", "--span", "0s:1000s", "--json")
    assert proc.returncode == 0, proc.stderr
    said = f"{drive}: span 0s:1000s runs past the drive's end (its samples end at 180 s): 0s:180s is read"
    assert proc.stderr.count(said) == 1, proc.stderr
    assert said in json.loads(proc.stdout)["warnings"]
    assert "runs past" not in run_cli("evaluate", str(drive), "--estimators", "ins", "--span", "0s:180s", "--json").stderr
    proc = run_cli("train", str(drive), "--span", "60s:1000s", "--epochs-disp", "1", "--epochs-yaw", "1", "-o", str(tmp_path / "m"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("span 60s:1000s runs past the drive's end (its samples end at 180 s): 60s:180s is read") == 1, proc.stderr
    meta = json.loads((tmp_path / "m" / "metadata.json").read_text())
    assert meta["training"]["drives"][0]["span_s"] == pytest.approx([60.0, 180.0], abs=0.01)


def test_events_of_a_span_lie_inside_it():
    """'events roundabout --span 500s:' found a roundabout from 0.0 to 509.9 s turning 9780 degrees:
    the detectors' 10 Hz grid began at 0 s whatever the span, and the samples before it were the
    span's first, held (a constant yaw rate for 500 s). Every event now lies inside the span, and a
    roundabout turns as a roundabout does."""
    proc = run_cli("events", "roundabout", "--span", "500s:", "--json")
    assert proc.returncode == 0, proc.stderr
    found = json.loads(proc.stdout)["V-sim-roundabout"]
    assert found and all(500.0 <= e["start_s"] <= e["end_s"] <= 600.0 for e in found), found
    assert max(e["turn_deg"] for e in found if e["type"] == "roundabout") < 400.0


def test_events_of_a_span_shorter_than_the_detectors_grid_are_none():
    """A span of a drive stamped off the 10 Hz grid (IO-VNBD's stamps jitter) that held under two
    grid points stopped events with an IndexError (a review found it); it has no manoeuvre to see."""
    from ionav_viz.analysis.events import detect_events
    from ionav_viz.core.durations import Span
    from ionav_viz.sources.load import crop_to_span, load_drive

    drive = load_drive("roundabout")
    drive.columns["t_s"] = drive.columns["t_s"] + 0.05
    for end in (100.2, 100.3, 101.0):
        assert detect_events(crop_to_span(drive, Span(100.0, end))) == []


def test_a_span_prints_as_the_option_that_gives_it_back():
    """A span printed with 6 digits (3600.125s as 3600.12s, 1234567.5s as 1.23457e+06s, which
    --span refuses), so outage-log's printed next command read another span (a review found it)."""
    from ionav_viz.core.durations import Span, parse_span

    for span in (Span(0.0, 60.0), Span(3600.125, 7200.0625), Span(1234567.5, None)):
        assert parse_span(str(span)) == span
    assert str(Span(0.0, 60.0)) == "0s:60s"
