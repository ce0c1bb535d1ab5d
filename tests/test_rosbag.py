"""ROS 1 bags and ROS 2 bag folders, written with rosbags' own writers, read through every entry point."""

import json
import shutil
import sqlite3

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.errors import InputError

from . import bag_fixtures as bf
from .conftest import assert_same_sequences, expect_one_line_error, run_cli

ESTIMATORS = ["ins", "idnn", "odo", "ekf"]


@pytest.fixture(scope="module")
def drive():
    return iv.load_drive("hard-brake")


@pytest.fixture(scope="module")
def reference(drive):
    """Metrics of the CSV drive reduced to what a bag carries: IMU, fixes, GNSS velocity and the CAN
    speed on /wheel/odom (odometry and the filter's speed updates run from it, as from the CSV)."""
    return json.loads(iv.evaluate(bf.carried(drive, speed_can_mps=drive.columns["speed_can_mps"]), estimators=ESTIMATORS).to_json())


def _same_metrics(reference, report):
    got = json.loads(report.to_json())
    assert len(got["sequences"]) > 50
    # same stamps as the CSV, so no resampling: equal up to float rounding
    assert_same_sequences(reference["sequences"], got["sequences"], ESTIMATORS, rel=1e-6)


BAGS = [
    ("ros1", {"compression": None, "broken_extra_topic": True, "image_every": 10}),
    ("ros1", {"compression": "bz2"}),
    ("ros1", {"compression": "lz4"}),
    ("ros2", {"storage": "sqlite3"}),
    ("ros2", {"storage": "sqlite3", "compression": "message"}),
    ("ros2", {"storage": "mcap", "compression": "file", "image_every": 10}),
    ("ros2", {"storage": "mcap", "compression": "message"}),
]


@pytest.mark.parametrize(("kind", "options"), BAGS, ids=[f"{k}-{'-'.join(str(v) for v in o.values())}" for k, o in BAGS])
def test_round_trip_gives_the_csv_metrics(tmp_path, drive, reference, kind, options):
    if kind == "ros1":
        path = bf.write_ros1(drive, tmp_path / "drive.bag", **options)
    else:
        path = bf.write_ros2(drive, tmp_path / "drive", **options)
    _same_metrics(reference, iv.evaluate(path, estimators=ESTIMATORS))
    if kind == "ros2":  # the folder's metadata.yaml names the same bag
        read = iv.load_drive(path / "metadata.yaml")
        assert read.name == "drive" and len(read) == len(drive)
    assert not list(tmp_path.glob("**/*.tmp*")) and sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_topics_are_chosen_by_type_or_by_option(tmp_path, drive):
    path = bf.write_ros1(drive, tmp_path / "a.bag", broken_extra_topic=True, image_every=50)
    proc = run_cli("info", str(path))
    assert proc.returncode == 0, proc.stderr
    rows = {line.split()[0]: line.split() for line in proc.stdout.splitlines()[1:]}
    assert rows["/imu/data"][1:] == ["5990", "ros1", "sensor_msgs/msg/Imu", "IMU"]
    assert rows["/gps/fix"][-1] == "GNSS" and rows["/gps/vel"][4:] == ["GNSS", "velocity"]
    assert rows["/camera/image"][1:] == ["120", "ros1", "sensor_msgs/msg/Image", "-"]
    assert rows["/vendor/status"][-1] == "-"  # its definition cannot be parsed, and it is never decoded
    # --gnss-velocity-topic picks the topic; a missing one is named with the topics there are
    proc = run_cli("evaluate", str(path), "--no-idnn", "--gnss-velocity-topic", "/nope")
    assert proc.returncode == 2 and "no topic '/nope'" in proc.stderr and "/gps/vel" in proc.stderr, proc.stderr


def test_header_or_receive_stamps(tmp_path, drive):
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    # the recorder received every message 40 ms after its header stamp
    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "late"
    with Writer(path, version=9) as w:
        conns = {}
        for topic, msgtype, ns, msg in bf._messages(store, drive, bf._stamps_ns(drive), ros1=False):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=store)
            w.write(conns[topic], ns + 40_000_000, store.serialize_cdr(msg, msgtype))
    header = iv.load_drive(path)
    received = iv.load_drive(path, iv.ReadOptions(log=iv.LogOptions(stamps="log")))
    with pytest.deprecated_call():  # the earlier keyword, for one release
        assert iv.load_drive(path, mcap=iv.LogOptions(stamps="log")).start_time_of_day_s == received.start_time_of_day_s
    assert received.start_time_of_day_s - header.start_time_of_day_s == pytest.approx(0.04, abs=1e-6)
    assert header.start_time_of_day_s == pytest.approx(bf.T0_S % 86400, abs=1e-9)


def test_every_command_takes_a_bag(tmp_path):
    """Each command reads a bag (its first 150 s are enough for a replay's outage and the training's span)."""
    drive = iv.load_drive("hard-brake", iv.ReadOptions(span="0s:150s"))
    bag = bf.write_ros1(drive, tmp_path / "hb.bag", compression="lz4")
    folder = bf.write_ros2(drive, tmp_path / "hb2", storage="sqlite3")
    for args in (("replay", str(bag), "-o", str(tmp_path / "r.rrd"), "-q"),
                 ("events", str(folder / "metadata.yaml")),
                 ("convert", str(folder), "-o", str(tmp_path / "c.mcap")),
                 ("train", str(bag), "--span", "0s:120s", "-o", str(tmp_path / "m"), "--epochs-disp", "1", "--epochs-yaw", "1", "-q")):
        proc = run_cli(*args)
        assert proc.returncode == 0, (args, proc.stderr)
    assert (tmp_path / "r.rrd").stat().st_size > 100_000
    assert json.loads((tmp_path / "m" / "metadata.json").read_text())["training"]["drives"][0]["file"] == "hb.bag"
    converted = iv.load_drive(tmp_path / "c.mcap")
    np.testing.assert_allclose(converted.lat_deg, drive.lat_deg, rtol=0, atol=1e-12)


# --- bad input: one line, the file, what to do, exit 2 -------------------------------------------

@pytest.fixture(scope="module")
def small(drive):
    return bf.carried(drive, 300)


@pytest.mark.parametrize("option, topic, message, hint", [
    ("--imu-topic", "/gps/fix", "/gps/fix is a sensor_msgs/msg/NavSatFix, not IMU", "IMU topics: /imu/data"),
    ("--gnss-topic", "/imu/data", "/imu/data is a sensor_msgs/msg/Imu, not GNSS", "GNSS topics: /gps/fix"),
    ("--gnss-velocity-topic", "/imu/data", "/imu/data is a sensor_msgs/msg/Imu, not GNSS velocity", "GNSS velocity topics: /gps/vel"),
])
def test_a_topic_of_another_type_is_refused(tmp_path, small, option, topic, message, hint):
    """A named topic of a standard type of another role is refused up front, naming both and the fitting topics."""
    bag = bf.write_ros1(small, tmp_path / "d.bag")
    proc = run_cli("evaluate", str(bag), "--no-idnn", option, topic)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert f"error: {option}: " in proc.stderr and "d.bag" in proc.stderr, proc.stderr
    assert message in proc.stderr and hint in proc.stderr and "AttributeError" not in proc.stderr, proc.stderr


def test_truncated_ros1_bag(tmp_path, small):
    good = bf.write_ros1(small, tmp_path / "good.bag")
    cut = tmp_path / "cut.bag"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    expect_one_line_error(cut, "cut.bag: truncated ROS 1 bag", "rosbag reindex")


def test_unindexed_ros1_bag(tmp_path, small):
    good = bf.write_ros1(small, tmp_path / "good.bag")
    data = bytearray(good.read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    data[at : at + 8] = bytes(8)  # what 'rosbag record' leaves when it is killed
    (tmp_path / "live.bag.active").write_bytes(bytes(data))
    expect_one_line_error(tmp_path / "live.bag.active", "live.bag.active: the ROS 1 bag has no index", "rosbag reindex")


def test_not_a_bag(tmp_path):
    (tmp_path / "notes.bag").write_text("hello")
    expect_one_line_error(tmp_path / "notes.bag", "notes.bag: not a ROS 1 bag")


def test_bag_folder_without_metadata(tmp_path, small):
    folder = bf.write_ros2(small, tmp_path / "rec")
    (folder / "metadata.yaml").unlink()
    expect_one_line_error(folder, "rec: a folder without metadata.yaml is not a ROS 2 bag", "rec.db3", "ros2 bag reindex")
    # its storage file alone is still readable
    assert len(iv.load_drive(folder / "rec.db3")) == 300
    (folder / "rec.db3").unlink()
    expect_one_line_error(folder, "neither a ROS 2 bag folder (no metadata.yaml) nor a KITTI raw drive")


def test_metadata_pointing_to_missing_files(tmp_path, small):
    folder = bf.write_ros2(small, tmp_path / "rec", storage="mcap")
    (folder / "rec.mcap").rename(tmp_path / "elsewhere.mcap")
    expect_one_line_error(folder / "metadata.yaml", "metadata.yaml: lists storage files that are not in the folder (rec.mcap)", "copy the whole bag folder")


def test_unparseable_definition_of_a_used_topic(tmp_path, small):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / "bad.bag"
    with Writer(path) as w:
        conns = {}
        for topic, msgtype, ns, msg in bf._messages(store, small, bf._stamps_ns(small), ros1=True):
            if topic not in conns:
                broken = {"msgdef": bf.BROKEN_DEFINITION, "md5sum": "0" * 32} if topic == "/imu/data" else {"typestore": store}
                conns[topic] = w.add_connection(topic, msgtype, **broken)
            w.write(conns[topic], ns, store.serialize_ros1(msg, msgtype))
    expect_one_line_error(path, "topic /imu/data: the bag's definition of sensor_msgs/msg/Imu cannot be read")


def test_unknown_message_type_without_definition(tmp_path, small):
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg("float64 latitude\nfloat64 longitude\n", "acme_msgs/msg/Position"))
    folder = tmp_path / "old"
    with Writer(folder, version=9) as w:
        fix = w.add_connection("/acme/position", "acme_msgs/msg/Position", typestore=store)
        imu = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=store)
        for topic, msgtype, ns, msg in bf._messages(store, small, bf._stamps_ns(small), ros1=False):
            if topic == "/imu/data":
                w.write(imu, ns, store.serialize_cdr(msg, msgtype))
            elif topic == "/gps/fix":
                pos = store.types["acme_msgs/msg/Position"](latitude=msg.latitude, longitude=msg.longitude)
                w.write(fix, ns, store.serialize_cdr(pos, "acme_msgs/msg/Position"))
    with sqlite3.connect(folder / "old.db3") as db:  # a bag from before ROS 2 Iron: no definitions
        db.execute("DELETE FROM message_definitions")
    proc = run_cli("evaluate", str(folder), "--no-idnn", "--gnss-topic", "/acme/position")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "topic /acme/position: the bag has no definition of its message type acme_msgs/msg/Position" in proc.stderr
    assert "ROS 2 Iron" in proc.stderr


def test_api_names_the_bag(tmp_path, small):
    folder = bf.write_ros2(small, tmp_path / "rec")
    shutil.rmtree(folder)
    folder.mkdir()
    with pytest.raises(InputError, match="neither a ROS 2 bag folder"):
        iv.load_drive(folder)


def test_receiver_course_is_held_at_a_standstill(tmp_path, drive):
    """A GNSS velocity of (0, 0) has no direction (atan2 gives 0, north): the course at speed is held."""
    read = iv.load_drive(bf.write_ros2(drive, tmp_path / "stop"))
    assert (drive.speed_mps == 0).sum() > 20
    last_at_speed = None
    for v, course, got in zip(read.speed_mps, drive.heading_deg, read.heading_deg):
        if v >= 1.0:
            last_at_speed = course
            assert got == pytest.approx(course, abs=1e-9)
        elif last_at_speed is not None:
            assert got == pytest.approx(last_at_speed, abs=1e-9)


def test_vehicle_speed_topics_are_told_from_gnss_velocity(tmp_path, drive, reference, caplog):
    """Round 4 (real logs): wheel odometry was read as the GNSS speed (the truth), so odometry and the
    filter's speed updates never ran from a bag. Odometry and body-frame twists are vehicle speed."""
    with_can = bf.carried(drive, speed_can_mps=drive.columns["speed_can_mps"])
    twist = bf.write_ros1(with_can, tmp_path / "twist.bag", vehicle_speed_as="twist")
    rows = {line.split()[0]: " ".join(line.split()[4:]) for line in run_cli("info", str(twist)).stdout.splitlines()[1:]}
    assert rows == {"/gps/fix": "GNSS", "/gps/vel": "GNSS velocity", "/imu/data": "IMU", "/vehicle/twist": "vehicle speed"}
    _same_metrics(reference, iv.evaluate(twist, estimators=ESTIMATORS))

    # a fused odometry beside the wheels: neither is guessed, one line says how to choose
    both = bf.write_ros1(with_can, tmp_path / "both.bag", vehicle_speed_as="odometry+filtered")
    with caplog.at_level("WARNING", logger="ionav_viz"):
        drive_both = iv.load_drive(both)
    assert "speed_can_mps" not in drive_both.columns
    assert "several vehicle speed topics (/odometry/filtered, /wheel/odom); none is used" in caplog.text
    chosen = iv.load_drive(both, iv.ReadOptions(log=iv.LogOptions(vehicle_speed_topic="/wheel/odom")))
    np.testing.assert_allclose(chosen.columns["speed_can_mps"], with_can.columns["speed_can_mps"], atol=1e-9)

    # 'none' leaves it out: the IMU alone (no odometry; the filter without speed updates)
    proc = run_cli("evaluate", str(twist), "--vehicle-speed-topic", "none", "--json")
    assert proc.returncode == 0, proc.stderr
    assert [e["name"] for e in json.loads(proc.stdout)["estimators"]] == ["ins", "idnn", "ekf"]
    # a body-frame twist is not the receiver's velocity
    proc = run_cli("evaluate", str(twist), "--gnss-velocity-topic", "/vehicle/twist")
    assert proc.returncode == 2 and "is in a body frame" in proc.stderr and "give /vehicle/twist as the vehicle speed topic" in proc.stderr


def test_the_earlier_speed_topic_is_the_gnss_velocity_topic():
    with pytest.deprecated_call():
        options = iv.LogOptions(speed_topic="/gps/vel")
    assert options.gnss_velocity_topic == "/gps/vel" and options.speed_topic is None


def _write_messy_ros2(drive, path, varying_frames, bad_imu=False):
    """``drive`` as a ROS 2 bag holding what real bags hold: IMU messages marking a field 'not provided',
    one stamped a second early, fixes without a fix or with NaN positions and with covariances, velocity
    messages with a zero stamp. ``varying_frames``: the IMU's frame_id changes length from one message to
    the next (so no block of it is one CDR layout: read one by one). ``bad_imu``: one implausible value."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    time_type = store.types["builtin_interfaces/msg/Time"]
    seen: dict[str, int] = {}
    with Writer(path, version=9) as w:
        connections = {}
        for topic, msgtype, ns, msg in bf._messages(store, drive, bf._stamps_ns(drive), ros1=False):
            i = seen[topic] = seen.get(topic, -1) + 1
            if topic == "/imu/data":
                msg.header.frame_id = ("imu" if i % 2 else "base_link") if varying_frames else "base_link"
                if i % 397 == 5:
                    msg.linear_acceleration_covariance = np.r_[-1.0, np.zeros(8)]
                if i == 300:
                    msg.header.stamp = time_type(sec=msg.header.stamp.sec - 1, nanosec=msg.header.stamp.nanosec)
                if bad_imu and i == 1200:
                    msg.linear_acceleration.x = 1e6
            elif topic == "/gps/fix":
                msg.status.status = -1 if i % 211 == 7 else 0
                msg.latitude = float("nan") if i % 307 == 3 else msg.latitude
                msg.position_covariance_type = 2
                msg.position_covariance = np.array([4.0 + i % 3, 0, 0, 0, float("nan") if i % 5 == 0 else 5.0, 0, 0, 0, 1.0])
            elif topic == "/gps/vel" and i % 401 == 11:
                msg.header.stamp = time_type(sec=0, nanosec=0)
            if topic not in connections:
                connections[topic] = w.add_connection(topic, msgtype, typestore=store)
            w.write(connections[topic], ns, store.serialize_cdr(msg, msgtype))
    return path


@pytest.fixture(scope="module")
def messy_bags(tmp_path_factory):
    """The roundabout as a messy ROS 2 bag (:func:`_write_messy_ros2`), by (IMU frame names varying,
    one implausible IMU value); written once, read by each stamps case."""
    drive = iv.load_drive("roundabout")
    root = tmp_path_factory.mktemp("messy")
    return {(varying, bad): _write_messy_ros2(drive, root / f"bag-{varying}-{bad}", varying, bad)
            for varying in (False, True) for bad in (False, True)}


@pytest.mark.parametrize("stamps", ["header", "log"])
def test_a_ros2_bag_reads_the_same_as_columns_and_one_by_one(caplog, messy_bags, stamps):
    """A ROS 2 bag's fixed-layout messages are read as columns, a block at a time: the same drive bit
    for bit, the same warnings and the same refusal as its messages read one by one."""
    import logging

    got = {}
    for varying in (False, True):
        for bad in (False, True):
            path = messy_bags[varying, bad]
            caplog.clear()
            with caplog.at_level(logging.WARNING, logger="ionav_viz"):
                try:
                    read = iv.load_drive(path, iv.ReadOptions(log=iv.LogOptions(stamps=stamps)))
                except InputError as exc:
                    read = str(exc).replace(str(path), "BAG")
            got[varying, bad] = read, [r.getMessage().replace(str(path), "BAG") for r in caplog.records]
    (columns, warned), (one_by_one, warned_one_by_one) = got[False, False], got[True, False]
    assert warned == warned_one_by_one and any("'not provided'" in w for w in warned), warned
    assert any("without a fix" in w for w in warned), warned
    assert stamps == "log" or any("/imu/data: 1 message(s) stamped earlier" in w for w in warned), warned
    assert columns.columns.keys() == one_by_one.columns.keys() and "gnss_sigma_m" in columns.columns
    for name, values in one_by_one.columns.items():
        assert np.array_equal(columns.columns[name], values, equal_nan=True), name
    assert (columns.start_stamp_s, columns.imu) == (one_by_one.start_stamp_s, one_by_one.imu)
    assert got[False, True][0] == got[True, True][0] and "linear_acceleration.x 1e+06" in got[True, True][0]
