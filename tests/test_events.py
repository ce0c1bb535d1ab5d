"""Manoeuvre detectors: measured against the simulator's own record of where it put each one."""

import json

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.analysis.events import EVENT_TYPES, EventThresholds, detect_events, score
from ionav_viz.dataset.samples import SAMPLES, sample_path
from ionav_viz.sim.simulate import simulated_manoeuvres
from ionav_viz.sources.load import load_drive

from .conftest import run_cli


def _planned(file: str, kind: str) -> int:
    """How many manoeuvres of ``kind`` the simulator put into the bundled drive ``file``."""
    sample = next(s for s in SAMPLES if s.file == file)
    return sum(k == kind for k, _, _ in simulated_manoeuvres(sample.scenario, sample.seed, sample.duration_s, sample.gnss_losses))


@pytest.fixture(scope="module")
def quality():
    totals = {k: np.zeros(4, int) for k in EVENT_TYPES}
    for sample in SAMPLES:
        drive = load_drive(str(sample_path(sample)))
        truth = simulated_manoeuvres(sample.scenario, sample.seed, sample.duration_s, sample.gnss_losses)
        for kind, sc in score(truth, detect_events(drive), drive.duration_s).items():
            totals[kind] += (sc.n_truth, sc.recalled, sc.n_found, sc.precise)
    return totals


@pytest.mark.parametrize("kind", EVENT_TYPES)
def test_recall_and_precision_on_the_bundled_drives(quality, kind):
    n_truth, recalled, n_found, precise = quality[kind]
    assert n_truth >= 5, f"too few {kind} manoeuvres in the bundled drives to measure"
    assert recalled / n_truth >= 0.9, (kind, recalled, n_truth)
    assert precise / n_found >= 0.8, (kind, precise, n_found)


def test_no_hard_brake_or_roundabout_on_the_motorway():
    sample = next(s for s in SAMPLES if s.file == "V-sim-motorway.csv")
    found = detect_events(load_drive(str(sample_path(sample))))
    assert not [e for e in found if e.type in ("hard-brake", "roundabout")]
    assert [e for e in found if e.type == "cruise"]


def test_hard_brake_values_match_the_plan():
    sample = next(s for s in SAMPLES if s.file == "V-sim-hard-brake.csv")
    found = [e for e in detect_events(load_drive(str(sample_path(sample)))) if e.type == "hard-brake"]
    assert found and all(0.45 <= e.values["peak_decel_g"] <= 0.8 for e in found)


def test_thresholds_can_be_overridden():
    sample = next(s for s in SAMPLES if s.file == "V-sim-hard-brake.csv")
    drive = load_drive(str(sample_path(sample)))
    assert not [e for e in detect_events(drive, EventThresholds().with_overrides(["hard_brake_g=0.9"])) if e.type == "hard-brake"]
    proc = run_cli("events", "hard-brake", "--threshold", "nonsense=1")
    assert proc.returncode == 2 and "unknown threshold" in proc.stderr


def test_events_cli_json_and_quality():
    proc = run_cli("events", "roundabout", "--json")
    assert proc.returncode == 0, proc.stderr
    found = json.loads(proc.stdout)["V-sim-roundabout"]
    assert [e["type"] for e in found].count("roundabout") == _planned("V-sim-roundabout.csv", "roundabout")
    assert {"start_s", "end_s", "turn_deg", "radius_m"} <= set(found[0])
    q = run_cli("events", "--quality", "--json")
    assert q.returncode == 0 and json.loads(q.stdout)["detectors"]["hard-brake"]["recall"] == 1.0


def test_replay_aims_outages_at_events(tmp_path):
    import ionav_viz as iv

    from .test_replay import read_rrd

    result = iv.replay("roundabout", 10.0, iv.AroundEvents(("roundabout",)), output=tmp_path / "rb.rrd")
    rows, static = read_rrd(result.path)
    found = [e for e in detect_events(iv.load_drive("roundabout")) if e.type == "roundabout"]
    assert len(found) == _planned("V-sim-roundabout.csv", "roundabout")
    # an outage centred on a roundabout must start after the 30 s warm-up
    events = [e for e in found if (0.5 * (e.t0_s + e.t1_s) - 5.0 if e.t1_s - e.t0_s <= 9 else e.t0_s - 1.0) >= 29.5]
    starts = [t for t, v in rows["/gnss/state"] if v[0] is not None and v[0].startswith("outage")]
    assert len(starts) == len(events) == len(result.outages) >= len(found) - 1
    for start, ev in zip(starts, events):
        if ev.t1_s - ev.t0_s <= 9:  # short enough: inside the outage
            assert start <= ev.t0_s and ev.t1_s <= start + 10
        else:  # longer than the outage: it starts 1 s into the outage
            assert start == pytest.approx(ev.t0_s - 1.0, abs=0.6)
    marked = [v[0] for _, v in rows["/events/state"] if v[0] is not None and v[0].startswith("roundabout")]
    assert len(marked) == len(set(marked)) == len(found)  # every one marked, numbered among all manoeuvres of the drive
    assert "/map/events" in static and "/local/events" in static


def test_evaluate_by_event_text():
    text = run_cli("evaluate", "hard-brake", "--by-event", "--on", "hard-brake")
    assert text.returncode == 0 and text.stdout.startswith("hard-brake: V-sim-hard-brake, 10 s GNSS outages")


def _turning_drive(yaw_profile: list[tuple[float, float]], speed_mps: float = 8.0) -> iv.Drive:
    """A 10 Hz drive at constant speed whose gyro follows ``yaw_profile`` ((seconds, rad/s), ...),
    with a GNSS track and course integrated from it (north-up, course clockwise from north)."""
    yaw = np.concatenate([np.full(int(round(dur * 10)), rate) for dur, rate in yaw_profile])
    t = np.arange(len(yaw)) / 10.0
    course = np.radians(90.0) - np.cumsum(yaw) / 10.0  # clockwise from north: a left turn lowers it
    north = np.cumsum(speed_mps * np.cos(course)) / 10.0
    east = np.cumsum(speed_mps * np.sin(course)) / 10.0
    columns = {"t_s": t, "lat_deg": 52.0 + north / 111_320.0, "lon_deg": -1.5 + east / (111_320.0 * np.cos(np.radians(52.0))),
               "speed_mps": np.full(len(t), speed_mps), "heading_deg": np.degrees(course) % 360.0,
               "accel_long_mps2": np.zeros(len(t)), "yaw_rate_radps": yaw}
    return iv.Drive("V-turns", "generated", 10.0, 0.0, columns)


def test_overlapping_detections_of_one_type_are_listed_once():
    """A left turn through 172 deg straight into a right turn through 344 deg (radius 16 m, as a
    roundabout with a long exit flare): each turning segment is a roundabout whose span takes in
    the other as its flare, so the detectors find the same stretch twice; events lists it once,
    spanning both, with the values of the longer one."""
    from ionav_viz.analysis.events import detect_events

    drive = _turning_drive([(10.0, 0.0), (6.0, 0.5), (12.0, -0.5), (10.0, 0.0)])
    found = [e for e in detect_events(drive) if e.type == "roundabout"]
    assert len(found) == 1, found
    (event,) = found
    assert 9.0 <= event.t0_s <= 10.5 and 27.0 <= event.t1_s <= 28.5  # the two turns: 10-16 s and 16-28 s
    assert event.values["turn_deg"] == pytest.approx(344.0, abs=15.0)  # the longer turn: 12 s at 0.5 rad/s = 344 deg
    assert event.values["radius_m"] == pytest.approx(16.0, rel=0.1)  # 8 m/s / 0.5 rad/s
    assert type(event.t0_s) is float and all(type(v) is float for v in event.values.values())
    assert "np.float64" not in repr(event)


def test_a_lone_type_string_is_refused_saying_so():
    """iv.find_events("roundabout", types="roundabout") said "unknown event type(s) r, o, u, n, d,
    a, b, o, u, t": the string was taken letter by letter."""
    import ionav_viz as iv

    with pytest.raises(iv.InputError, match=r"types='roundabout' is not a sequence of event types \(hint: give a list, e.g. types=\['roundabout'\]\)"):
        iv.find_events("roundabout", types="roundabout")
    assert {e.type for e in iv.find_events("roundabout", types=["roundabout"])["V-sim-roundabout"]} == {"roundabout"}


def test_two_drives_of_one_name_are_both_listed(tmp_path):
    """'events a/V-x.csv b/V-x.csv' listed one 'V-x' (the second drive's events under the shared
    name, the first's gone without a word), and 'evaluate ... --overview' one row for both; each is
    now keyed by its file when names collide (one file given twice stays one entry, by name)."""
    for folder, scenario in (("a", "roundabout"), ("b", "hard-brake")):
        (tmp_path / folder).mkdir()
        assert run_cli("simulate", scenario, "--duration", "60s", "--seed", "1", "-o", str(tmp_path / folder / "V-x.csv")).returncode == 0
    proc = run_cli("events", "a/V-x.csv", "b/V-x.csv", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    found = json.loads(proc.stdout)
    assert list(found) == ["a/V-x.csv", "b/V-x.csv"] and found["a/V-x.csv"] != found["b/V-x.csv"]
    overview = run_cli("evaluate", "a/V-x.csv", "b/V-x.csv", "--overview", "--estimators", "ins", "--warm-up", "0s", cwd=tmp_path,
                       env={"COLUMNS": "1000"})  # wide enough for one row per drive
    assert overview.returncode == 0, overview.stderr
    assert [line.split()[0] for line in overview.stdout.splitlines()[1:]] == ["a/V-x.csv", "b/V-x.csv", "total"], overview.stdout
    assert list(json.loads(run_cli("events", "roundabout", "roundabout", "--json").stdout)) == ["V-sim-roundabout"]


def test_counts_are_whole_numbers_in_the_json_and_the_text(tmp_path):
    """A left-right series' 'turns' and a GNSS loss's 'bad_samples' are counts: they were
    'turns 2.00' and 'bad_samples 115.00' in the text, 2.0 and 115.0 in the JSON."""
    lossy = tmp_path / "V-lossy.csv"
    assert run_cli("simulate", "motorway", "--duration", "90s", "--gnss-loss", "1", "-o", str(lossy)).returncode == 0
    for drive, kind, count in ((str(lossy), "gnss-outage", "bad_samples"), ("sharp-cornering", "left-right", "turns")):
        found = json.loads(run_cli("events", drive, "--type", kind, "--json").stdout)
        values = [e[count] for evs in found.values() for e in evs]
        assert values and all(type(v) is int and v > 0 for v in values), found
        text = run_cli("events", drive, "--type", kind).stdout
        assert f"{count} {values[0]}," in text or text.rstrip().endswith(f"{count} {values[0]}"), text


def test_the_help_names_every_event_type():
    """'events --help' (and the command list) said it finds '... quick acceleration changes and
    cruising', not the log's GNSS losses it lists too, and --type named no type to choose from."""
    from ionav_viz.analysis.events import EVENT_TYPES

    text = " ".join(run_cli("events", "--help", env={"COLUMNS": "1000"}).stdout.split())
    assert "cruising and the log's GNSS losses" in text
    assert "comma-separated: " + ", ".join(EVENT_TYPES) + "." in text
    assert "cruising and the log's GNSS losses" in " ".join(run_cli("--help", env={"COLUMNS": "1000"}).stdout.split())


def test_quality_is_aligned_and_refuses_drives_it_would_not_read():
    """'events --quality roundabout' printed the bundled drives' quality and read no roundabout (exit
    0); and the sharp-cornering row stood two columns right of the others."""
    proc = run_cli("events", "--quality", "roundabout")
    assert proc.returncode == 2 and proc.stdout == "" and "--quality measures the detectors on the bundled synthetic drives, not on roundabout" in proc.stderr
    lines = run_cli("events", "--quality").stdout.splitlines()
    ends = {len(line) for line in lines[1:]}
    assert len(ends) == 1 and all(line.index(" %") == lines[1].index(" %") for line in lines[1:]), lines


def test_an_events_times_and_length_agree_in_the_json():
    """start_s and end_s were rounded to 0.01 s and length_s to 0.001 s: a GNSS loss ending at the
    sample stamped 65.899 s read end 65.9, length 9.799 (a tour found it). The JSON's times are the
    drive's own sample stamps, to the millisecond they are written with."""
    import ionav_viz as iv

    drive = iv.load_drive("V-sim-motorway-tunnels")
    events = iv.find_events(drive, ["gnss-outage"])[drive.name]
    assert events
    for e in events:
        d = e.to_dict()
        for key in ("start_s", "end_s"):
            assert np.min(np.abs(drive.t_s - d[key])) < 1e-6, (key, d)
        assert d["end_s"] - d["start_s"] == pytest.approx(d["length_s"], abs=1e-6)


def test_by_event_says_a_type_without_events_in_every_format():
    # issue 63: --on hard-brake,quick-accel on the hard-brake drive printed hard-brake's tables and
    # nothing of quick-accel, as if it had not been asked for
    args = ("evaluate", "hard-brake", "--by-event", "--on", "hard-brake,quick-accel", "--estimators", "ins")
    text = run_cli(*args)
    assert text.returncode == 0, text.stderr
    assert text.stdout.startswith("hard-brake: V-sim-hard-brake, 10 s GNSS outages")
    assert text.stdout.splitlines()[-1] == "quick-accel: 0 events"
    markdown = run_cli(*args, "--markdown")
    assert markdown.stdout.splitlines()[-1] == "**quick-accel: 0 events**"
    overview = run_cli(*args, "--overview")
    assert overview.stdout.splitlines()[-1] == "quick-accel: 0 events"
    out = json.loads(run_cli(*args, "--json").stdout)
    assert list(out["by_event"]) == ["hard-brake"] and out["events"] == {"hard-brake": 20, "quick-accel": 0}
    by = iv.evaluate(["hard-brake"], 10.0, estimators=["ins"], by_event=["hard-brake", "quick-accel"])
    assert list(by) == ["hard-brake"] and by.events == {"hard-brake": 20, "quick-accel": 0}
    assert by.without_outage_lines() == ["quick-accel: 0 events"]


def test_by_event_with_export_is_refused_in_one_line(tmp_path):
    """``evaluate --by-event --export DIR`` exited 0 and wrote nothing into DIR, without a word."""
    proc = run_cli("evaluate", "hard-brake", "--by-event", "--on", "hard-brake", "--export", str(tmp_path / "out"))
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1 and "--export" in proc.stderr
    assert list(tmp_path.iterdir()) == []
