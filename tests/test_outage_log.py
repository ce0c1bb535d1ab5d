"""Issue 32, part 1: the outaged log and its plan (``ionav-viz outage-log``, ``--plan``).

The outaged files are read back here with the format's own libraries (mcap, mcap_ros2, plain text),
not with ionav-viz's readers, and compared with the source message by message or line by line.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import ionav_viz as iv

from .conftest import run_cli
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
    return any(o["start_stamp_s"] + 1e-6 < stamp <= o["end_stamp_s"] + 1e-6 for o in plan["outages"])


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


def test_an_iovnbd_source_gets_the_loggers_no_fix_rows(tmp_path):
    """A CSV outage log: rows inside an outage have 0 satellites and the last fix repeated in the
    GNSS columns; every other line and every other cell is the source's, byte for byte."""
    source = iv.load_drive("roundabout").source
    out = tmp_path / "V-cut.csv"
    result = iv.outage_log(source, out, 10.0, iv.At((20.0,)))
    plan = json.loads(result.plan_path.read_text())
    (a, b), = [(o["start_stamp_s"], o["end_stamp_s"]) for o in plan["outages"]]
    src, cut = open(source, "rb").read().split(b"\r\n"), out.read_bytes().split(b"\r\n")
    assert len(src) == len(cut) and src[0] == cut[0]
    changed = [i for i, (x, y) in enumerate(zip(src, cut)) if x != y]
    times = [float(line.split(b",")[1]) for line in src[1:-1]]
    assert [i - 1 for i in changed] == [k for k, t in enumerate(times) if a + 1e-6 < t <= b + 1e-6] and 95 <= len(changed) <= 101  # 10 s at 10 Hz, stamps jittered
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
        (("outage-log", "roundabout", "-o", str(tmp_path / "y.bag")), "unsupported outage-log format"),
    ]:
        proc = run_cli(*args)
        assert proc.returncode == 2 and fragment in proc.stderr and "Traceback" not in proc.stderr, (args, proc.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.mcap", "r.outages.json"]  # nothing half-written
    (tmp_path / "bad.json").write_text(json.dumps({"format": "ionav-viz outage plan", "version": 1}))
    with pytest.raises(iv.InputError, match="field 'source'"):
        iv.evaluate("roundabout", plan=tmp_path / "bad.json")
