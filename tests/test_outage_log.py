"""Issue 32, part 1: the outaged log and its plan (``ionav-viz outage-log``, ``--plan``).

The outaged files are read back here with the format's own libraries (mcap, mcap_ros2, plain text),
not with ionav-viz's readers, and compared with the source message by message or line by line.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.sources.outage_writer import STAMP_TOL_S

from .conftest import HANG_S, run_cli
from .mcap_fixtures import write_realistic


def _messages(path):
    """Every message of an MCAP file: (topic, log time ns, raw bytes, header stamp s or None)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out = []
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            header = getattr(decoded, "header", None)
            stamp = header.stamp.sec + header.stamp.nanosec * 1e-9 if header is not None else None
            out.append((channel.topic, message.log_time, bytes(message.data), stamp))
    return out


def _inside(stamp, plan):
    return any(o["start_stamp_s"] + STAMP_TOL_S < stamp <= o["end_stamp_s"] + STAMP_TOL_S for o in plan["outages"])


def test_the_outaged_log_lacks_gnss_exactly_in_the_plans_outages(tmp_path):
    """From a CSV drive: an MCAP whose fixes and velocities stop inside each planned outage and
    nowhere else; the plan's outages are those evaluate places with the same options, and
    evaluate --plan scores exactly them."""
    out = tmp_path / "r.mcap"
    proc = run_cli("outage-log", "roundabout", "--every", "30s", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == [str(out), str(tmp_path / "r.outages.json")]
    plan = json.loads((tmp_path / "r.outages.json").read_text())
    assert plan["outage_s"] == 10 and plan["placement_options"] == {"type": "Every", "period_s": 30.0}
    drive = iv.load_drive("roundabout")
    msgs = _messages(out)
    fixes = [m for m in msgs if m[0] == "/gps/fix"]
    imu = [m for m in msgs if m[0] == "/imu/data"]
    assert len(imu) == len(drive)  # the IMU goes on through every outage
    stamps = drive.start_stamp_s + drive.t_s
    expected = [s for s in stamps if not _inside(s, plan)]
    assert len(fixes) == len(expected) and len(fixes) < len(drive) - 15 * 90
    np.testing.assert_allclose([m[3] for m in fixes], expected, atol=1e-6)
    assert all(not _inside(m[3], plan) for m in msgs if m[0] in ("/gps/fix", "/gps/vel"))

    every = json.loads(iv.evaluate("roundabout", placement=iv.Every(30.0), estimators=["ins", "ekf"]).to_json())
    planned = json.loads(iv.evaluate("roundabout", plan=tmp_path / "r.outages.json", estimators=["ins", "ekf"]).to_json())
    assert [s["start_s"] for s in every["sequences"]] == [o["start_s"] for o in plan["outages"]]
    assert every["sequences"] == planned["sequences"]


def test_an_mcap_source_keeps_every_other_message_byte_for_byte(tmp_path):
    """From a real-looking MCAP (IMU at 100 Hz, receiver at 5 Hz with velocity, wheel odometry, a
    reference): only the receiver's fix and velocity messages stamped inside an outage go."""
    log = write_realistic(iv.load_drive("hard-brake"), tmp_path / "car.mcap", duration_s=60.0)
    out = tmp_path / "cut.mcap"
    result = iv.outage_log(log, out, 10.0, iv.At((10.0, 30.0)), read=iv.ReadOptions(log=iv.LogOptions(gnss_topic="/gps/fix")))
    plan = json.loads(result.plan_path.read_text())
    assert plan["removed_topics"] == ["/gps/fix", "/gps/vel"] and plan["clock"].startswith("UNIX time")
    before, after = _messages(log), _messages(out)
    gone = [m for m in before if m[0] in ("/gps/fix", "/gps/vel") and _inside(m[3], plan)]
    assert len(gone) == 2 * 2 * 10 * 5 == result.removed  # 2 outages x 10 s x 5 Hz, fix and velocity
    assert sorted(after) == sorted(m for m in before if m not in gone)

    # with a reference truth, an external trajectory on the log's UNIX clock is scored (the drive
    # the estimators get kept its clock): the reference itself ends every outage on the truth
    read = iv.ReadOptions(log=iv.LogOptions(gnss_topic="/gps/fix", truth_topic="/reference/fix"))
    iv.outage_log(log, out, 10.0, iv.At((10.0, 30.0)), read=read)
    got = json.loads(iv.evaluate(log, plan=result.plan_path, estimators=["ins"], read=read,
                                 external={"ref": f"{log}:/reference/fix"}).to_json())
    # (centimetres: the drive's truth is the reference fitted on the 10 Hz grid, the external one is interpolated raw)
    assert all(s["ref"]["final_position_error_m"] < 0.2 for s in got["sequences"]) and len(got["sequences"]) == 2


def test_an_iovnbd_source_gets_the_loggers_no_fix_rows(tmp_path):
    """A CSV outage log: rows inside an outage have 0 satellites and the last fix repeated in the
    GNSS columns; every other line and every other cell is the source's, byte for byte."""
    source = iv.load_drive("roundabout").source
    out = tmp_path / "V-cut.csv"
    result = iv.outage_log(source, out, 10.0, iv.At((20.0,)))
    plan = json.loads(result.plan_path.read_text())
    (a, b), = [(o["start_stamp_s"], o["end_stamp_s"]) for o in plan["outages"]]
    src, cut = Path(source).read_bytes().split(b"\r\n"), out.read_bytes().split(b"\r\n")
    assert len(src) == len(cut) and src[0] == cut[0]
    changed = [i for i, (x, y) in enumerate(zip(src, cut)) if x != y]
    times = [float(line.split(b",")[1]) for line in src[1:-1]]
    assert [i - 1 for i in changed] == [k for k, t in enumerate(times) if a + STAMP_TOL_S < t <= b + STAMP_TOL_S] and 95 <= len(changed) <= 101  # 10 s at 10 Hz, stamps jittered
    last = src[changed[0] - 1].split(b",")
    for i in changed:
        x, y = src[i].split(b","), cut[i].split(b",")
        assert y[0] == b"0" and y[2:8] == last[2:8] and y[1] == x[1] and y[8:] == x[8:]
    drive = iv.load_drive(out)  # read back: the outage is the logger's own GNSS loss
    assert (~drive.gnss_ok).sum() == len(changed)


def test_plans_and_outage_logs_refuse_what_does_not_fit(tmp_path):
    out = tmp_path / "r.mcap"
    assert run_cli("outage-log", "roundabout", "--at", "20s", "-o", str(out)).returncode == 0
    plan = str(tmp_path / "r.outages.json")
    for args, fragment in [
        (("evaluate", "hard-brake", "--plan", plan), "the plan was made on another file"),
        (("evaluate", "roundabout", "--plan", plan, "--outage", "30s"), "the plan"),
        (("evaluate", "roundabout", "--plan", plan, "--every", "30s"), "give --plan or --every"),
        (("evaluate", "roundabout", "hard-brake", "--plan", plan), "a plan is made for one drive"),
        (("replay", "roundabout", "--plan", str(tmp_path / "none.json"), "-o", str(tmp_path / "x.rrd")), "no such plan file"),
        (("outage-log", str(out), "-o", str(tmp_path / "y.csv")), "is not one"),
        (("outage-log", "roundabout", "-o", str(tmp_path / "y.txt")), "unsupported outage-log format"),
        (("outage-log", "roundabout", "-o", str(tmp_path / "no" / "y.bag")), "y.bag"),
    ]:
        proc = run_cli(*args)
        assert proc.returncode == 2 and fragment in proc.stderr and "Traceback" not in proc.stderr, (args, proc.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.mcap", "r.outages.json"]  # nothing half-written
    (tmp_path / "bad.json").write_text(json.dumps({"format": "ionav-viz outage plan", "version": 1}))
    with pytest.raises(iv.InputError, match="field 'source'"):
        iv.evaluate("roundabout", plan=tmp_path / "bad.json")


def test_an_outage_log_of_a_drive_too_short_names_it_and_what_to_change(tmp_path):
    """outage-log of a drive with no room for an outage said "no 10 s outage fits in  " (no name,
    no length, no word of the warm-up); it now says what replay and evaluate say."""
    proc = run_cli("outage-log", "roundabout", "--span", "0s:35s", "-o", str(tmp_path / "cut.mcap"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "V-sim-roundabout" in proc.stderr and "too short for a 10 s outage after the 30 s warm-up (35.0 s in the span 0s:35s)" in proc.stderr
    assert "a shorter warm-up" in proc.stderr and list(tmp_path.iterdir()) == []


def test_an_external_estimate_across_midnight_is_scored(tmp_path):
    """An IO-VNBD drive across midnight: its plan's stamps run on past 86,400 s, while a filter on
    the outaged CSV writes the log's own time of day, 0 again after midnight. Every outage after
    midnight was "does not cover outage N" (it spans 0-86399.9 s); those poses are a day on now."""
    drive = tmp_path / "V-midnight.csv"
    iv.simulate("roundabout", tmp_path / "V-day.csv", seed=1, duration_s=120.0)
    lines = (tmp_path / "V-day.csv").read_text().splitlines()
    first = float(lines[1].split(",")[1])
    rows = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        of_day = round(86400.0 - 50.0 + float(cells[1]) - first, 3)
        cells[1] = f"{of_day - 86400.0 if of_day >= 86400.0 else of_day:.3f}"
        rows.append(",".join(cells))
    drive.write_text("\n".join(rows) + "\n")
    cut = tmp_path / "cut.csv"
    assert run_cli("outage-log", str(drive), "--every", "30s", "-o", str(cut)).returncode == 0
    stamps = [line.split(",")[1] for line in cut.read_text().splitlines()[1:]]  # the outaged log's own clock
    truth = iv.load_drive(drive)
    mine = tmp_path / "mine.csv"  # the truth 1e-5 deg (1.11 m) north
    mine.write_text("time_s,lat_deg,lon_deg\n" + "".join(f"{t},{la + 1e-5:.9f},{lo:.9f}\n" for t, la, lo in zip(stamps, truth.lat_deg, truth.lon_deg)))
    proc = run_cli("evaluate", str(drive), "--plan", str(tmp_path / "cut.outages.json"), "--external", f"mine={mine}", "--estimators", "ins", "--json")
    assert proc.returncode == 0, proc.stderr
    sequences = json.loads(proc.stdout)["sequences"]
    assert [s["start_s"] for s in sequences] == [30.0, 60.0, 90.0]  # midnight at 50 s
    # 1.11 m, give or take the CSV's stamps jittering about the 10 Hz grid the truth is on
    assert all(abs(s["mine"]["final_position_error_m"] - 1.11) < 0.15 for s in sequences), [s["mine"]["final_position_error_m"] for s in sequences]


class ConstantVelocity:
    """tests/external/constant_velocity.py as a plug-in: from the last fix at or before each
    outage's start, along its course at its speed (its own positions at the window boundaries)."""

    name, label = "cv", "Constant velocity"

    def estimate(self, inputs):
        from pyproj import Geod

        drive = inputs.drive
        stamps = drive.stamp_s(drive.t_s)
        starts = drive.stamp_s(inputs.t0_s)
        last = np.searchsorted(stamps, starts + STAMP_TOL_S) - 1  # the last fix the outaged log keeps
        t_fix, speed, course = stamps[last], drive.speed_mps[last], drive.heading_deg[last]
        when = starts[:, None] + np.arange(inputs.n_windows + 1)[None, :] - t_fix[:, None]
        lon, lat, _ = Geod(ellps="WGS84").fwd(np.broadcast_to(drive.lon_deg[last][:, None], when.shape),
                                              np.broadcast_to(drive.lat_deg[last][:, None], when.shape),
                                              np.broadcast_to(course[:, None], when.shape), speed[:, None] * when)
        from ionav_viz.nav.track import windows_of_track

        shape = (inputs.n_outages, inputs.n_windows)
        _, yaw = windows_of_track(lat, lon, inputs.course0_deg)  # the yaw rates its track implies, as for an external one
        return iv.Estimate(np.broadcast_to(speed[:, None], shape).copy(), yaw, lat_deg=lat, lon_deg=lon)


def test_an_external_filter_is_scored_exactly_as_the_same_plug_in(tmp_path):
    """Issue 32.2-3: a filter in its own process (tests/external/constant_velocity.py, no ionav-viz
    in it) runs on the outaged log and writes its trajectory; --external scores it like the same
    algorithm as a plug-in, within 1 mm, and in every view."""
    import subprocess
    import sys

    cut = tmp_path / "cut.mcap"
    assert run_cli("outage-log", "roundabout", "--every", "40s", "-o", str(cut)).returncode == 0
    plan = tmp_path / "cut.outages.json"
    script = Path(__file__).parent / "external" / "constant_velocity.py"
    subprocess.run([sys.executable, str(script), str(cut), str(tmp_path / "cv.csv")], check=True, timeout=HANG_S)

    proc = run_cli("evaluate", "roundabout", "--plan", str(plan), "--external", f"ext={tmp_path / 'cv.csv'}", "--estimators", "ins", "--json")
    assert proc.returncode == 0, proc.stderr
    external = json.loads(proc.stdout)
    plugin = json.loads(iv.evaluate("roundabout", plan=plan, estimators=["ins", ConstantVelocity()]).to_json())
    assert [e["name"] for e in external["estimators"]] == ["ins", "ext"] and external["estimators"][1]["label"] == "ext (external)"
    assert len(external["sequences"]) == len(plugin["sequences"]) >= 10
    for a, b in zip(external["sequences"], plugin["sequences"], strict=True):
        for metric in ("crse_m", "cae_m", "final_position_error_m"):
            assert abs(a["ext"][metric] - b["cv"][metric]) < 1e-3, (metric, a["start_s"], a["ext"][metric], b["cv"][metric])
        assert abs(a["ext"]["yaw_crse_radps"] - b["cv"]["yaw_crse_radps"]) < 1e-5  # the course from written positions: 0.0006 deg/s
        assert a["ins"] == b["ins"]
    assert "positions are the GNSS fixes" not in proc.stderr

    # the same trajectory in the local frame, as TUM: the same scores
    origin = iv.load_drive("roundabout")
    data = np.loadtxt(tmp_path / "cv.csv", delimiter=",", skiprows=1)
    from pyproj import Geod

    az, _, dist = Geod(ellps="WGS84").inv(np.full(len(data), origin.lon_deg[0]), np.full(len(data), origin.lat_deg[0]), data[:, 2], data[:, 1])
    east, north = dist * np.sin(np.radians(az)), dist * np.cos(np.radians(az))
    (tmp_path / "cv.tum").write_text("".join(f"{t:.9f} {x:.6f} {y:.6f} 0 0 0 0 1\n" for t, x, y in zip(data[:, 0], east, north)))
    tum = json.loads(iv.evaluate("roundabout", plan=plan, estimators=["ins"], external={"ext": tmp_path / "cv.tum"}).to_json())
    for a, b in zip(tum["sequences"], external["sequences"], strict=True):
        assert abs(a["ext"]["final_position_error_m"] - b["ext"]["final_position_error_m"]) < 1e-3

    # the trajectory recorded and drawn like a built-in
    replayed = iv.replay("roundabout", plan=plan, estimators=["ins"], external={"ext": tmp_path / "cv.csv"}, output=tmp_path / "r.rrd")
    assert "ext" in {e.name for e in replayed.result.estimators}


def test_external_estimates_that_cheat_or_fall_short_are_named(tmp_path):
    cut = tmp_path / "cut.mcap"
    assert run_cli("outage-log", "roundabout", "--at", "20s,60s", "-o", str(cut)).returncode == 0
    plan = str(tmp_path / "cut.outages.json")
    drive = iv.load_drive("roundabout")
    gnss = tmp_path / "gnss.csv"  # the GNSS itself, outages included: it saw the removed fixes
    np.savetxt(gnss, np.column_stack([drive.stamp_s(drive.t_s), drive.lat_deg, drive.lon_deg]), delimiter=",",
               header="time_s,lat_deg,lon_deg", comments="", fmt="%.9f")
    proc = run_cli("evaluate", "roundabout", "--plan", plan, "--external", f"gnss={gnss}", "--estimators", "ins")
    assert proc.returncode == 0 and "external gnss: inside 2 of 2 outage(s) its positions are the GNSS fixes" in proc.stderr, proc.stderr
    short = tmp_path / "short.csv"  # ends before the second outage
    keep = drive.t_s < 40
    np.savetxt(short, np.column_stack([drive.stamp_s(drive.t_s[keep]), drive.lat_deg[keep], drive.lon_deg[keep]]), delimiter=",",
               header="time_s,lat_deg,lon_deg", comments="", fmt="%.9f")
    for args, fragment in [
        (("--external", f"short={short}"), "does not cover outage 2"),
        (("--external", f"x={tmp_path / 'none.csv'}"), "no such trajectory file"),
        (("--external", "x"), "give NAME=TRAJECTORY"),
        (("--external", f"Bad Name={gnss}"), "is not a short lower-case identifier"),
        (("--external", f"x={cut}:/imu/data"), "is a sensor_msgs/msg/Imu"),
    ]:
        proc = run_cli("evaluate", "roundabout", "--plan", plan, "--estimators", "ins", *args)
        assert proc.returncode == 2 and fragment in proc.stderr and "Traceback" not in proc.stderr, (args, proc.stderr)
    proc = run_cli("evaluate", "roundabout", "--external", f"gnss={gnss}")
    assert proc.returncode == 2 and "that log's plan (its NAME.outages.json)" in proc.stderr, proc.stderr


def test_an_external_named_in_estimators_runs_once(tmp_path):
    """--estimators ins,mine with --external mine=... was "unknown estimator 'mine'" (exit 2): the
    external's name is one of the estimators now, run once; alone it is the only one."""
    cut = tmp_path / "cut.mcap"
    assert run_cli("outage-log", "roundabout", "--at", "20s,60s", "-o", str(cut)).returncode == 0
    plan = str(tmp_path / "cut.outages.json")
    drive = iv.load_drive("roundabout")
    mine = tmp_path / "mine.csv"
    np.savetxt(mine, np.column_stack([drive.stamp_s(drive.t_s), drive.lat_deg + 1e-5, drive.lon_deg]), delimiter=",",
               header="time_s,lat_deg,lon_deg", comments="", fmt="%.9f")
    for names, expected in [("ins,mine", ["ins", "mine"]), ("mine", ["mine"])]:
        proc = run_cli("evaluate", "roundabout", "--plan", plan, "--external", f"mine={mine}", "--estimators", names, "--json")
        assert proc.returncode == 0, proc.stderr
        assert [e["name"] for e in json.loads(proc.stdout)["estimators"]] == expected
    # an external named as a built-in: with --estimators odo it ran as 'ins', the INS DR every improvement is measured against
    proc = run_cli("evaluate", "roundabout", "--plan", plan, "--external", f"ins={mine}", "--estimators", "odo")
    assert proc.returncode == 2 and "--external ins: 'ins' is a built-in estimator's name" in proc.stderr and "improvement" not in proc.stderr


def _bag_messages(path):
    """Every message of a ROS bag read with rosbags itself: (topic, log time ns, raw bytes)."""
    from rosbags.highlevel import AnyReader

    with AnyReader([Path(path)]) as reader:
        return [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()]


@pytest.mark.parametrize("kind", ["ros1", "ros2"])
def test_a_bag_source_is_copied_to_a_bag_without_the_outages_gnss(tmp_path, kind):
    """Issue 32.1: ROS 1 and ROS 2 bags (with an image topic ionav-viz does not read) copied with
    rosbags' writers: every message as it was, the fixes and velocities inside each outage gone."""
    from .bag_fixtures import T0_S, write_ros1, write_ros2

    drive = iv.load_drive("hard-brake")
    keep = drive.t_s < 60
    short = iv.Drive("short", "", drive.rate_hz, drive.start_time_of_day_s, {k: v[keep] for k, v in drive.columns.items()})
    source = write_ros1(short, tmp_path / "car.bag", image_every=50) if kind == "ros1" else write_ros2(short, tmp_path / "car", image_every=50)
    out = tmp_path / ("cut.bag" if kind == "ros1" else "cut")
    result = iv.outage_log(source, out, 10.0, iv.At((10.0, 30.0)))
    plan = json.loads(result.plan_path.read_text())
    assert result.plan_path == tmp_path / "cut.outages.json" and plan["removed_topics"] == ["/gps/fix", "/gps/vel"]
    before, after = _bag_messages(source), _bag_messages(out)
    gone = [m for m in before if m[0] in ("/gps/fix", "/gps/vel") and _inside(m[1] * 1e-9, plan)]  # header stamp = log time here
    assert len(gone) == result.removed and 390 <= len(gone) <= 400  # 2 outages x 10 s x 10 Hz, fix and velocity (stamps jitter)
    assert {m[0] for m in before} == {m[0] for m in after}
    assert sorted(after) == sorted(m for m in before if m not in gone)
    assert abs(plan["outages"][0]["start_stamp_s"] - (int(T0_S) + 10.0)) < 1e-6
    if kind == "ros2":  # a folder is never replaced (a file is, atomically)
        proc = run_cli("outage-log", str(source), "-o", str(out))
        assert proc.returncode == 2 and "exists" in proc.stderr, proc.stderr


@pytest.mark.parametrize("name", ["cut.bag", "cut"])
def test_a_csv_drive_becomes_a_bag_of_the_kind_asked_for(tmp_path, name):
    """From an IO-VNBD drive, a ROS 1 bag (.bag) or a ROS 2 bag (a new folder): standard messages,
    read back with rosbags itself; no fix stamped inside an outage, every other one there."""
    from rosbags.highlevel import AnyReader

    out = tmp_path / name
    result = iv.outage_log("roundabout", out, 10.0, iv.Every(40.0))
    plan = json.loads(result.plan_path.read_text())
    with AnyReader([out]) as reader:
        fixes = [(reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages() if c.topic == "/gps/fix"]
        topics = {c.topic for c in reader.connections}
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in fixes]
    drive = iv.load_drive("roundabout")
    expected = [s for s in drive.start_stamp_s + drive.t_s if not _inside(s, plan)]
    assert topics == {"/imu/data", "/gps/fix", "/gps/vel", "/wheel/odom"}
    np.testing.assert_allclose(stamps, expected, atol=1e-6)
    np.testing.assert_allclose([m.latitude for m in fixes], drive.lat_deg[[not _inside(s, plan) for s in drive.start_stamp_s + drive.t_s]])


def test_the_printed_evaluate_command_runs_as_printed(tmp_path):
    """outage-log printed 'ionav-viz evaluate DRIVE --plan cut phone.outages.json ...': a plan path
    with a space unquoted, and none of the source options the log was read with (a phone log cut with
    --truth-topic then failed with 'several GNSS topics'). The command is now quoted and carries them."""
    import shlex

    out = tmp_path / "cut rb.mcap"
    proc = run_cli("outage-log", "roundabout", "--every", "60s", "--span", "0s:300s", "--gnss-limit", "max_sigma_m=13", "--yaw-sign", "cw",
                   "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    said = proc.stderr.splitlines()[-1].split(": ", 1)[1]
    argv = shlex.split(said)
    assert argv[:3] == ["ionav-viz", "evaluate", "roundabout"] and argv[-2:] == ["--external", "NAME=TRAJECTORY"]
    assert argv[argv.index("--plan") + 1] == str(tmp_path / "cut rb.outages.json")
    assert {"--span": "0s:300s", "--gnss-limit": "max_sigma_m=13", "--yaw-sign": "cw"}.items() <= dict(zip(argv[3:-2:2], argv[4:-2:2])).items()
    done = run_cli(*argv[1:-2], "--estimators", "ins", "--json")
    assert done.returncode == 0 and json.loads(done.stdout)["n_sequences"] == 5, done.stderr
