"""MCAP in (ROS 2 cdr and JSON, written independently of the converter) and out (convert round trip)."""

import json

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.errors import InputError
from ionav_viz.sources.mcap_reader import read_mcap

from . import mcap_fixtures as fx
from .conftest import assert_same_sequences, expect_one_line_error, run_cli


def _check_straight_line(drive, start_offset_s=0.0, gnss_hz=5, longest_gnss_gap_s=None):
    dt = np.diff(drive.t_s)
    assert drive.rate_hz == 10.0 and np.allclose(dt, 0.1, atol=1e-6)
    # IMU averaged per 0.1 s bin: constant readings come back exactly
    np.testing.assert_allclose(drive.accel_long_mps2, fx.ACCEL_MPS2, rtol=1e-12)
    np.testing.assert_allclose(drive.yaw_rate_radps, fx.YAW_RATE_RADPS, rtol=1e-12)
    # GNSS interpolated onto the grid: the path is a parabola in time, so linear interpolation
    # between fixes 1/gnss_hz apart is off by at most a h^2 / 8
    t_abs = drive.start_time_of_day_s - (fx.T0_S % 86400) + drive.t_s - start_offset_s
    lat, lon = fx.truth_position(t_abs)
    from pyproj import Geod

    _, _, err = Geod(ellps="WGS84").inv(lon, lat, drive.lon_deg, drive.lat_deg)
    h = (longest_gnss_gap_s or 1.0 / gnss_hz) + 0.004
    assert np.max(err) < fx.ACCEL_MPS2 * h * h / 8 + 0.002
    # speed and course from the GNSS fixes: a parabola fitted to the fixes within +-1 s is exact
    # for this parabolic track, at the ends too
    v_true = fx.V0_MPS + fx.ACCEL_MPS2 * t_abs
    assert np.max(np.abs(drive.speed_mps - v_true)) < 1e-3
    assert np.max(np.abs(drive.heading_deg - fx.COURSE_DEG)) < 0.01


def test_ros2_imu_100hz_gnss_5hz_jittered(tmp_path):
    path = fx.write_ros2(tmp_path / "a.mcap")
    drive = read_mcap(path)
    assert drive.start_time_of_day_s == pytest.approx(fx.T0_S % 86400, abs=0.06)
    assert 28.5 < drive.duration_s < 30.0
    _check_straight_line(drive)


def test_log_time_instead_of_header_stamps(tmp_path):
    path = fx.write_ros2(tmp_path / "a.mcap", latency_s=0.03)
    header = read_mcap(path)
    log = read_mcap(path, iv.LogOptions(stamps="log"))
    # the recorder's log time is 30 ms late: the grid starts 30 ms later in the day
    assert log.start_time_of_day_s - header.start_time_of_day_s == pytest.approx(0.03, abs=0.003)


def test_json_location_fix_and_imu(tmp_path):
    drive = read_mcap(fx.write_json(tmp_path / "j.mcap"))
    _check_straight_line(drive, gnss_hz=2)


def test_gnss_without_fix_is_dropped(tmp_path, caplog):
    path = fx.write_ros2(tmp_path / "n.mcap", no_fix_times=(10.0, 10.2))
    with caplog.at_level("WARNING", logger="ionav_viz"):
        drive = read_mcap(path)
    assert "without a fix" in caplog.text
    # the bogus no-fix positions (1 degree off) never show up; two dropped fixes leave a 0.6 s gap
    _check_straight_line(drive, longest_gnss_gap_s=0.6)


def test_an_imu_that_stops_early_is_said(tmp_path):
    """An IMU that stops 20 s into 60 s of fixes cut the drive to 20 s with no word ('too short
    (20.0 s)' was all evaluate said); the cut is said now, with both lengths."""
    path = fx.write_ros2(tmp_path / "cut.mcap", duration_s=60.0, imu_until_s=20.0)
    proc = run_cli("evaluate", str(path), "--estimators", "ins")
    assert proc.returncode == 2, proc.stderr
    said = f"{path}: the IMU covers only 19.9 of the 59.8 s of GNSS fixes (it stops 39.8 s before the last fix)"
    assert said in proc.stderr and "too short" in proc.stderr, proc.stderr
    proc = run_cli("evaluate", str(fx.write_ros2(tmp_path / "whole.mcap", duration_s=60.0)), "--estimators", "ins", "--json")
    assert proc.returncode == 0 and "the IMU covers only" not in proc.stderr, proc.stderr


def test_several_imu_topics_need_a_choice(tmp_path):
    path = fx.write_ros2(tmp_path / "two.mcap", extra_imu_topic=True)
    with pytest.raises(InputError, match=r"several IMU topics") as raised:
        read_mcap(path)
    assert raised.value.param == "imu_topic"  # the command line names it --imu-topic
    _check_straight_line(read_mcap(path, iv.LogOptions(imu_topic="/imu2")))
    proc = run_cli("info", str(path))
    assert proc.returncode == 0 and "/imu2" in proc.stdout and "several IMU topics" in proc.stderr


def test_convert_round_trip_gives_the_same_metrics(tmp_path):
    out = tmp_path / "V-sim-hard-brake.mcap"
    proc = run_cli("convert", "hard-brake", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    info = run_cli("info", str(out))
    uses = {line.split()[0]: " ".join(line.split()[4:]) for line in info.stdout.splitlines()[1:]}
    assert uses == {"/imu/data": "IMU", "/gps/fix": "GNSS", "/gps/vel": "GNSS velocity", "/wheel/odom": "vehicle speed"}, info.stdout
    a = run_cli("evaluate", "hard-brake", "--json")
    b = run_cli("evaluate", str(out), "--json")
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    ra, rb = json.loads(a.stdout), json.loads(b.stdout)
    assert len(ra["sequences"]) > 5
    # every estimator, odometry and the filter included (round trip of the vehicle speed on /wheel/odom)
    assert [e["name"] for e in rb["estimators"]] == ["ins", "idnn", "odo", "ekf"]
    # the float64 round trip leaves the filter's last digits (its Joseph-form updates carry them on): 1e-7
    assert_same_sequences(ra["sequences"], rb["sequences"], ("ins", "idnn", "odo", "ekf"), rel=1e-7, abs=1e-7)
    assert "not carried by the MCAP log: n_satellites, steering_angle_deg" in proc.stderr


def test_replay_and_train_accept_mcap(tmp_path):
    mcap = tmp_path / "r.mcap"
    assert run_cli("convert", "roundabout", "-o", str(mcap)).returncode == 0
    proc = run_cli("replay", str(mcap), "-o", str(tmp_path / "r.rrd"), "-q")
    assert proc.returncode == 0, proc.stderr
    proc = run_cli("train", str(mcap), "--span", "0s:120s", "-o", str(tmp_path / "m"), "--epochs-disp", "1", "--epochs-yaw", "1", "-q")
    assert proc.returncode == 0, proc.stderr
    assert json.loads((tmp_path / "m" / "metadata.json").read_text())["training"]["drives"][0]["file"] == "r.mcap"


@pytest.fixture()
def good(tmp_path):
    return fx.write_ros2(tmp_path / "good.mcap", duration_s=10.0, compression="NONE")


def test_truncated(tmp_path, good):
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    expect_one_line_error(bad, "truncated MCAP file")


def test_not_an_mcap_file(tmp_path):
    bad = tmp_path / "text.mcap"
    bad.write_text("hello")
    expect_one_line_error(bad, "not an MCAP file")


def test_crc_mismatch(tmp_path, good):
    data = bytearray(good.read_bytes())
    marker = bytes(np.float64(fx.ACCEL_MPS2).tobytes())
    at = data.find(marker, len(data) // 3)
    data[at + 7] ^= 0x01  # change one IMU reading inside a chunk
    bad = tmp_path / "flipped.mcap"
    bad.write_bytes(bytes(data))
    expect_one_line_error(bad, "CRC mismatch")


def test_empty_file(tmp_path):
    bad = tmp_path / "zero.mcap"
    bad.write_bytes(b"")
    expect_one_line_error(bad, "empty file")


def test_no_imu_or_no_gnss_channel(tmp_path):
    from mcap_ros2.writer import Writer

    from ionav_viz.sources.ros2_msgs import DEFINITIONS

    for schema_name, missing in (("sensor_msgs/msg/NavSatFix", "no IMU topic"), ("sensor_msgs/msg/Imu", "no GNSS topic")):
        path = tmp_path / f"{schema_name.rsplit('/', 1)[-1]}-only.mcap"
        with open(path, "wb") as f:
            w = Writer(f)
            schema = w.register_msgdef(schema_name, DEFINITIONS[schema_name])
            msg = fx._stamp(1.0)
            body = ({"header": {"stamp": msg, "frame_id": "x"}, "status": {"status": 0, "service": 1}, "latitude": 1.0,
                     "longitude": 1.0, "altitude": 0.0, "position_covariance": [0.0] * 9, "position_covariance_type": 0}
                    if "NavSat" in schema_name else
                    {"header": {"stamp": msg, "frame_id": "x"}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                     "orientation_covariance": [0.0] * 9, "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.0},
                     "angular_velocity_covariance": [0.0] * 9, "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 0.0},
                     "linear_acceleration_covariance": [0.0] * 9})
            w.write_message("/only", schema, body, log_time=1_000_000_000)
            w.finish()
        expect_one_line_error(path, missing)


def test_unknown_encoding(tmp_path):
    from mcap.writer import Writer

    path = tmp_path / "p.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        s_imu = w.register_schema("sensor_msgs/msg/Imu", "protobuf", b"")
        s_fix = w.register_schema("sensor_msgs/msg/NavSatFix", "protobuf", b"")
        c_imu = w.register_channel("/imu", "protobuf", s_imu)
        c_fix = w.register_channel("/fix", "protobuf", s_fix)
        w.add_message(c_imu, log_time=1, data=b"\x00", publish_time=1)
        w.add_message(c_fix, log_time=1, data=b"\x00", publish_time=1)
        w.finish()
    expect_one_line_error(path, "message encoding 'protobuf'")


def _same_drive(a, b):
    assert len(a) == len(b)
    for key in ("t_s", "lat_deg", "lon_deg", "speed_mps", "accel_long_mps2", "yaw_rate_radps"):
        np.testing.assert_array_equal(a.columns[key], b.columns[key], err_msg=key)


@pytest.mark.parametrize(
    ("options", "why"),
    [
        ({"use_statistics": False}, "no message statistics"),
        ({"use_statistics": False, "repeat_channels": False, "repeat_schemas": False, "use_summary_offsets": False,
          "index_types": __import__("mcap.writer", fromlist=["IndexType"]).IndexType.NONE, "use_chunking": False}, "no summary section"),
    ],
)
def test_valid_files_without_statistics_or_summary_are_read_by_streaming(tmp_path, caplog, options, why):
    """Input: a complete MCAP written without a Statistics record, or without any summary section.
    Expected: read (by streaming, one warning line saying why), the same drive as the indexed file."""
    full = read_mcap(fx.write_json(tmp_path / "full.mcap"))
    with caplog.at_level("WARNING", logger="ionav_viz"):
        lean = read_mcap(fx.write_json(tmp_path / "lean.mcap", **options))
    assert [r.getMessage() for r in caplog.records if "streaming" in r.getMessage()] == [f"{tmp_path / 'lean.mcap'}: {why}; reading it by streaming (slower)"]
    _same_drive(full, lean)


def _top_level_records(path):
    """(offset, opcode) of every top-level record of an MCAP file."""
    data = path.read_bytes()
    pos, out = 8, []
    while pos + 9 <= len(data) - 8:
        out.append((pos, data[pos]))
        pos += 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
    return out


def test_a_recording_stopped_at_a_record_boundary_is_read(tmp_path, caplog):
    """Input: a ROS 2 MCAP whose recorder stopped without writing its summary and footer (cut right
    before the DataEnd record). Expected: read by streaming, the same drive; a cut inside a record
    is still refused, saying so."""
    good = fx.write_ros2(tmp_path / "good.mcap")
    data_end = next(pos for pos, op in _top_level_records(good) if op == 0x0F)
    cut = tmp_path / "stopped.mcap"
    cut.write_bytes(good.read_bytes()[:data_end])
    with caplog.at_level("WARNING", logger="ionav_viz"):
        _same_drive(read_mcap(good), read_mcap(cut))
    assert any("no footer" in r.getMessage() for r in caplog.records)
    inside = tmp_path / "inside.mcap"
    inside.write_bytes(good.read_bytes()[: data_end - 100])
    with pytest.raises(InputError, match="cut off inside a record") as raised:
        read_mcap(inside)
    # where the file stops being whole, not "at byte <that> of <size>" as if the cut were there
    size = data_end - 100
    last_whole_end = max(pos for pos, _ in _top_level_records(good) if pos < size)  # where the cut record starts
    assert f"(cut off inside a record; the last whole record ends at byte {last_whole_end} of {size})" in str(raised.value)


def test_warnings_reach_the_json_and_the_recording(tmp_path):
    """What the loader warns about (here: why the IMU mount asked for is not applied) is in the
    report's 'warnings' and in the recording's summary, so a .rrd reviewed later carries it."""
    from rerun.chunk import RrdReader

    log = tmp_path / "hb.mcap"
    assert run_cli("convert", "hard-brake", "-o", str(log)).returncode == 0
    # a two-channel drive's log: gravity and the gyro's x and y are placeholders, no mount is estimated
    wrong = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto"))
    report = iv.evaluate(log, estimators=["ins"], read=wrong)
    assert any("the IMU's mount is not estimated" in w for w in report.warnings), report.warnings
    assert json.loads(report.to_json())["warnings"] == report.warnings
    assert json.loads(iv.evaluate(log, estimators=["ins"]).to_json())["warnings"] == []

    replayed = iv.replay(log, output=tmp_path / "r.rrd", estimators=["ins"], read=wrong)
    texts = [str(v) for chunk in RrdReader(replayed.path).stream() if str(chunk.entity_path) == "/summary"
             for column in chunk.to_record_batch().columns for v in column.to_pylist()]
    summary = next(t for t in texts if "Warnings" in t)
    assert "the IMU's mount is not estimated" in summary


def test_the_full_imu_is_kept_in_the_body_frame(tmp_path):
    """Round 4 (real logs): a 6-axis IMU's other axes were dropped at the reader. All six are kept
    in REP 103's body frame, also for a z-down (FRD) IMU, and convert writes them back."""
    from ionav_viz.core.drive import IMU_COLUMNS

    path = fx.write_ros2(tmp_path / "six.mcap", duration_s=30.0)
    drive = read_mcap(path)
    assert set(IMU_COLUMNS) <= set(drive.columns)
    np.testing.assert_allclose(drive.columns["accel_z_mps2"], 9.81, atol=1e-9)  # gravity, level IMU
    np.testing.assert_array_equal(drive.columns["accel_x_mps2"], drive.accel_long_mps2)
    np.testing.assert_array_equal(drive.columns["gyro_z_radps"], drive.yaw_rate_radps)
    np.testing.assert_allclose(drive.yaw_rate_radps, fx.YAW_RATE_RADPS, atol=1e-12)

    # the same IMU mounted z-down (x forward, y right): told with --yaw-sign cw, read into REP 103
    def frd(k, i, msg):
        if k == "imu":
            msg = json.loads(json.dumps(msg))
            msg["angular_velocity"]["z"] *= -1
            msg["linear_acceleration"]["z"] *= -1
            msg["angular_velocity"]["y"] = -0.01  # pitching nose down at 0.01 rad/s, seen z-down
        return [msg]

    turned = read_mcap(fx.write_json(tmp_path / "frd.mcap", duration_s=30.0, imu_hz=50, gnss_hz=5, tamper=frd), yaw_sign="cw")
    np.testing.assert_allclose(turned.columns["accel_z_mps2"], 9.81, atol=1e-9)
    np.testing.assert_allclose(turned.columns["gyro_y_radps"], 0.01, atol=1e-9)
    np.testing.assert_allclose(turned.yaw_rate_radps, fx.YAW_RATE_RADPS, atol=1e-12)

    out = tmp_path / "back.mcap"
    iv.convert(turned, out)
    back = read_mcap(out)
    for column in IMU_COLUMNS:
        np.testing.assert_allclose(back.columns[column], turned.columns[column], atol=1e-9, err_msg=column)


def test_topic_options_are_ignored_for_csv_drives_said_once(tmp_path):
    """A fleet of CSV drives and an MCAP log: --gnss-topic and --truth-topic choose the log's topics
    and are ignored for the CSV drives, in one warning (--truth-topic was refused for them while
    --gnss-topic was silently ignored)."""
    log = fx.write_ros2(tmp_path / "log.mcap", duration_s=40.0, extra_imu_topic=True)
    proc = run_cli("evaluate", "roundabout", "motorway", str(log), "--imu-topic", "/imu", "--gnss-topic", "/fix",
                   "--estimators", "ins", "--warm-up", "0s", "--overview")
    assert proc.returncode == 0, proc.stderr
    said = "--imu-topic, --gnss-topic apply to message logs (MCAP, ROS bags) only: ignored for IO-VNBD CSV drives"
    assert proc.stderr.count(said) == 1, proc.stderr
    assert all(name in proc.stdout for name in ("roundabout", "motorway", "log")), proc.stdout
    # the IMU's options too: --imu-mount auto reads the log's mount, the CSV drives ignore it (it refused the run)
    proc = run_cli("evaluate", "roundabout", str(log), "--imu-topic", "/imu", "--imu-mount", "auto", "--imu-time-offset", "0",
                   "--estimators", "ins", "--warm-up", "0s", "--overview")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("--imu-topic, --imu-mount, --imu-time-offset apply to message logs (MCAP, ROS bags) only: ignored for IO-VNBD CSV drives") == 1
    proc = run_cli("evaluate", "roundabout", "--truth-topic", "/reference/fix", "--estimators", "ins", "--overview")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("--truth-topic applies to message logs (MCAP, ROS bags) only: ignored for IO-VNBD CSV drives") == 1
    # --stamps has a default: the default says nothing, another value is said (it was silently ignored)
    proc = run_cli("evaluate", "roundabout", "--stamps", "log", "--estimators", "ins", "--overview")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("--stamps applies to message logs (MCAP, ROS bags) only: ignored for IO-VNBD CSV drives") == 1
    assert "--stamps" not in run_cli("evaluate", "roundabout", "--stamps", "header", "--estimators", "ins", "--overview").stderr
    proc = run_cli("evaluate", "roundabout", "--truth-topic", "/reference/fix", "--estimators", "ins", "--overview")
    assert proc.stderr.count("--truth-topic applies to message logs (MCAP, ROS bags) only: ignored for IO-VNBD CSV drives") == 1
    # and the report keeps it, as it keeps every warning stderr said
    proc = run_cli("evaluate", "roundabout", "motorway", "--truth-topic", "/reference/fix", "--estimators", "ins", "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["warnings"].count("--truth-topic applies to message logs (MCAP, ROS bags) only: ignored for IO-VNBD CSV drives") == 1


@pytest.mark.parametrize("drive", ["V-sim-motorway-tunnels", "simulated mems"])
def test_every_written_message_is_the_cdr_mcap_ros2_encodes(tmp_path, drive):
    """The writer encodes each topic's messages all at once; every message must be, byte for byte,
    what mcap_ros2's own encoder makes of it (decoded by mcap_ros2, written again by its Writer):
    IMU, fixes (no-fix status, with and without sigma), GNSS velocity, wheel odometry and truth."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from mcap_ros2.writer import Writer

    from ionav_viz.sim.imu import write_imu_log

    ours = tmp_path / "ours.mcap"
    if drive == "simulated mems":
        write_imu_log(ours, "hard-brake", 3, 30.0, "mems")
    else:
        assert run_cli("convert", drive, "-o", str(ours)).returncode == 0
    factory, decoders, written, seen = DecoderFactory(), {}, [], {}
    with open(ours, "rb") as f, open(tmp_path / "again.mcap", "wb") as out:
        writer, schemas = Writer(out), {}
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            decode = decoders.setdefault(channel.id, factory.decoder_for(channel.message_encoding, schema))
            decoded = decode(message.data)
            seen[channel.topic] = seen.get(channel.topic, -1) + 1
            if seen[channel.topic] % 20 and getattr(getattr(decoded, "status", None), "status", 0) == 0:
                continue  # every 20th message of each topic and every fix without one
            if channel.topic not in schemas:
                schemas[channel.topic] = writer.register_msgdef(schema.name, schema.data.decode())
            writer.write_message(channel.topic, schemas[channel.topic], decoded, log_time=message.log_time)
            written.append((channel.topic, message.log_time, bytes(message.data)))
        writer.finish()
    with open(tmp_path / "again.mcap", "rb") as f:
        again = [(c.topic, m.log_time, bytes(m.data)) for _, c, m in make_reader(f).iter_messages(log_time_order=False)]
    assert again == written
    topics = {topic for topic, _, _ in written}
    assert len(written) > 300 and {"/imu/data", "/gps/fix"} <= topics and ("/truth/fix" in topics) == (drive == "simulated mems")


def test_a_log_reads_the_same_whichever_library_decodes_its_messages(tmp_path, monkeypatch):
    """CDR messages are decoded by rosbags where it reads the schema, else by mcap_ros2: the
    same drive either way (every column, bit for bit)."""
    import ionav_viz.sources.mcap_reader as mcap_reader
    from ionav_viz.sim.imu import SIM_TRUTH_TOPIC, write_imu_log

    path = write_imu_log(tmp_path / "d.mcap", "sharp-cornering", 5, 30.0, "mems")
    read = iv.ReadOptions(log=iv.LogOptions(truth_topic=SIM_TRUTH_TOPIC, imu_mount="auto"))
    fast = iv.load_drive(path, read)
    monkeypatch.setattr(mcap_reader, "cdr_decoder", lambda encoding, schema: None)
    slow = iv.load_drive(path, read)
    assert sorted(fast.columns) == sorted(slow.columns)
    for column in fast.columns:
        np.testing.assert_array_equal(fast.columns[column], slow.columns[column], err_msg=column)


def test_stamps_past_ros2s_int32_seconds_are_refused_in_one_line(tmp_path):
    """ROS 2's Time holds int32 seconds: a drive stamped in 2040 cannot be written (numpy would wrap
    the seconds round silently), and nothing is left behind."""
    import dataclasses

    from ionav_viz.sources.mcap_writer import write_mcap

    drive = dataclasses.replace(iv.load_drive("hard-brake"), start_stamp_s=2_208_988_800.0)  # 2040-01-01
    out = tmp_path / "late.mcap"
    with pytest.raises(InputError, match="do not fit ROS 2's int32 seconds"):
        write_mcap(drive, out)
    assert list(tmp_path.iterdir()) == []
