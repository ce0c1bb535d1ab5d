"""Reading an MCAP log's fixed-layout messages as columns gives what reading them one by one gives.

A chunk whose messages of every chosen topic share one CDR layout is read field by field with
numpy (:func:`ionav_viz.sources.cdr.decode_many`); a chunk where one topic's layout varies (here: the
IMU's frame_id changes length) is read message by message. The same messages either way must give
the same drive bit for bit, the same warnings and the same one-line refusals. Below them, what it
rests on: ``decode_many`` reads what ``encode_many`` writes, and IMU samples binned a block at a time
sum as one by one.
"""

import logging
import math

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.errors import InputError
from ionav_viz.sources.cdr import decode_many, encode_many
from ionav_viz.sources.ros2_msgs import DEFINITIONS

from . import mcap_fixtures as fx


def _stamp(t_s):
    sec = math.floor(t_s)
    return {"sec": sec, "nanosec": round((t_s - sec) * 1e9) % 1_000_000_000}


def _covariance(i):
    """A fix's position covariance: east and north variances that differ, north negative or NaN now and
    then (the larger of the two, as Python's max takes it, gives the fix's sigma: one for every fix)."""
    east = float(i % 5)
    north = math.nan if i % 13 == 5 else float(i % 7) - 2.0
    return [east if k == 0 else north if k == 4 else 0.0 for k in range(9)]


def _write_mixed(path, varying_frames, bad=None, seed=5):
    """60 s of a 100 Hz IMU, 5 Hz fixes and velocity, 20 Hz odometry, with what real logs hold:
    IMU messages marking a field 'not provided' (one or both), stamped out of order, with a zero or
    a negative header stamp; fixes without a fix, with NaN positions, sharing a stamp, with odd
    covariances; a velocity stamped late; odometry reversing; a reference in a local frame. ``varying_frames``: the IMU's frame_id
    changes length from one message to the next (so its chunks are read message by message). ``bad``: one implausible value
    on that topic ("imu", "gnss", "odom")."""
    from mcap_ros2.writer import Writer

    rng = np.random.default_rng(seed)
    events = []
    for i, t in enumerate(np.arange(0.0, 60.0, 0.01)):
        stamp_s = t - 0.015 if i % 7 == 5 else t
        stamp = _stamp(fx.T0_S + stamp_s)
        if i % 211 == 7:
            stamp = {"sec": 0, "nanosec": 0}
        elif i % 333 == 10:
            stamp = {"sec": -5, "nanosec": 7}
        accel = rng.normal(0.0, 0.3, 3) + [0.2, 0.0, 9.8]
        if bad == "imu" and i == 4000:
            accel[2] = 1e6
        events.append((t, "/imu", "sensor_msgs/msg/Imu", {
            "header": {"stamp": stamp, "frame_id": "imu" if varying_frames and i % 2 else "imu_link"},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}, "orientation_covariance": [-1.0] + [0.0] * 8,
            "angular_velocity": dict(zip("xyz", map(float, rng.normal(0.0, 0.01, 3)))),
            "angular_velocity_covariance": [-1.0] + [0.0] * 8 if i % 401 == 9 or i == 2411 else [0.0] * 9,
            "linear_acceleration": dict(zip("xyz", map(float, accel))),
            "linear_acceleration_covariance": [-1.0] + [0.0] * 8 if i % 301 == 3 else [0.01] * 9}))
    fix_t = np.arange(0.0, 60.0, 0.2)
    lat, lon = fx.truth_position(fix_t)
    for i, (t, la, lo) in enumerate(zip(fix_t, lat, lon)):
        status = -1 if i % 37 == 4 else 0
        la = math.nan if i % 41 == 6 else 95.0 if bad == "gnss" and i == 200 else float(la)
        header = {"stamp": _stamp(fx.T0_S + (fix_t[i - 1] if i % 53 == 8 else t)), "frame_id": "gps"}
        events.append((t, "/fix", "sensor_msgs/msg/NavSatFix", {
            "header": header, "status": {"status": status, "service": 1}, "latitude": la, "longitude": float(lo),
            "altitude": 100.0 + t, "position_covariance": _covariance(i), "position_covariance_type": 2}))
        events.append((t, "/vel", "geometry_msgs/msg/TwistStamped", {
            "header": {"stamp": _stamp(fx.T0_S + t - (0.3 if i % 29 == 2 else 0.0)), "frame_id": "gps"},
            "twist": {"linear": {"x": 3.0 + math.sin(t), "y": 4.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}}))
    for i, (t, la, lo) in enumerate(zip(fix_t, lat, lon)):  # a reference in a local frame, 5 Hz
        east, north = (lo - fx.LON0) * 68_000.0, (la - fx.LAT0) * 111_000.0
        events.append((t, "/truth/odom", "nav_msgs/msg/Odometry", {
            "header": {"stamp": _stamp(fx.T0_S + t - (0.3 if i % 31 == 3 else 0.0)), "frame_id": "/Map"},
            "child_frame_id": "base_link",
            "pose": {"pose": {"position": {"x": float(east), "y": float(north), "z": 0.0},
                              "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}, "covariance": [0.0] * 36},
            "twist": {"twist": {"linear": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
                      "covariance": [0.0] * 36}}))
    for t in np.arange(0.0, 60.0, 0.05):
        speed_mps = (-5.0 if t > 30 else 5.0) * (1000.0 if bad == "odom" and abs(t - 40.0) < 0.01 else 1.0)
        events.append((t, "/odom", "nav_msgs/msg/Odometry", {
            "header": {"stamp": _stamp(fx.T0_S + t), "frame_id": "odom"}, "child_frame_id": "base_link",
            "pose": {"pose": {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
                              "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}, "covariance": [0.0] * 36},
            "twist": {"twist": {"linear": {"x": speed_mps, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
                      "covariance": [0.0] * 36}}))
    with open(path, "wb") as f:
        writer = Writer(f, chunk_size=16384)  # many chunks: what carries from one to the next is read too
        schemas = {name: writer.register_msgdef(name, DEFINITIONS[name]) for name in DEFINITIONS}
        for t, topic, schema, msg in sorted(events, key=lambda e: e[0]):
            log_ns = round((fx.T0_S + t + 0.02) * 1e9)
            writer.write_message(topic, schemas[schema], msg, log_time=log_ns, publish_time=log_ns)
        writer.finish()
    return path


def _read(path, caplog, **options):
    """(the drive or the refusal's text, the warnings), with the file's name taken out."""
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        try:
            got = iv.load_drive(path, iv.ReadOptions(log=iv.LogOptions(vehicle_speed_topic="/odom", **options)))
        except InputError as exc:
            got = str(exc).replace(str(path), "LOG")
    warnings = [r.getMessage().replace(str(path), "LOG") for r in caplog.records if not r.getMessage().startswith("read ")]
    return got, warnings


@pytest.fixture(scope="module")
def mixed_logs(tmp_path_factory):
    """(the mixed log whose chunks are read as columns, the same log read message by message), written
    once for every reading option below."""
    root = tmp_path_factory.mktemp("mixed")
    return _write_mixed(root / "columns.mcap", False), _write_mixed(root / "messages.mcap", True)


@pytest.mark.parametrize("options", [{}, {"stamps": "log"}, {"truth_topic": "/truth/odom", "truth_origin": "auto"}])
def test_columns_read_as_one_by_one(caplog, mixed_logs, options):
    stamps = options.get("stamps", "header")
    by_columns, by_columns_warnings = _read(mixed_logs[0], caplog, **options)
    one_by_one, one_by_one_warnings = _read(mixed_logs[1], caplog, **options)
    assert by_columns_warnings == one_by_one_warnings
    assert any("'not provided'" in w for w in one_by_one_warnings), one_by_one_warnings
    assert any("without a fix" in w for w in one_by_one_warnings), one_by_one_warnings
    if stamps == "header":
        assert any("/imu: " in w and "stamped earlier" in w for w in one_by_one_warnings), one_by_one_warnings
    assert by_columns.columns.keys() == one_by_one.columns.keys()
    assert "gnss_sigma_m" in one_by_one.columns
    for name, values in one_by_one.columns.items():
        assert np.array_equal(by_columns.columns[name], values, equal_nan=True), name
    assert (by_columns.start_stamp_s, by_columns.imu) == (one_by_one.start_stamp_s, one_by_one.imu)


@pytest.mark.parametrize("bad", ["imu", "gnss", "odom"])
def test_columns_refuse_as_one_by_one(tmp_path, caplog, bad):
    by_columns, _ = _read(_write_mixed(tmp_path / "columns.mcap", False, bad), caplog)
    one_by_one, _ = _read(_write_mixed(tmp_path / "messages.mcap", True, bad), caplog)
    assert isinstance(one_by_one, str) and "outside" in one_by_one, one_by_one
    assert by_columns == one_by_one


def _layout_fields(rng, n):
    """Fields of every kind in an order that needs padding before most of them."""
    return [("u1", rng.integers(0, 255, n)), ("f8", rng.normal(size=n)), ("string", "imu_link"),
            ("i2", rng.integers(-30000, 30000, n)), ("f4", rng.normal(size=(n, 3)).astype(np.float32)),
            ("i1", -3), ("u8", rng.integers(0, 2**63, n, dtype=np.uint64)), ("string", "a"),
            ("u2", rng.integers(0, 65535, n)), ("f8", rng.normal(size=(n, 9))), ("i4", rng.integers(-2**31, 2**31 - 1, n)),
            ("u4", rng.integers(0, 2**32 - 1, n)), ("i8", rng.integers(-2**62, 2**62, n)), ("string", "")]


def test_decode_many_inverts_encode_many():
    rng = np.random.default_rng(7)
    n = 50
    fields = _layout_fields(rng, n)
    data = encode_many(fields, n)
    got = decode_many([(kind, np.shape(v)[1] if np.ndim(v) == 2 else 0) for kind, v in fields], data)
    assert got is not None
    for (kind, values), back in zip(fields, got):
        if kind == "string":
            assert back == values
        else:
            assert np.array_equal(np.broadcast_to(np.asarray(values, dtype=kind), back.shape), back), kind


def test_decode_many_refuses_what_is_not_one_layout():
    rng = np.random.default_rng(8)
    fields = [("f8", rng.normal(size=4)), ("string", "gps"), ("f8", rng.normal(size=4))]
    spec = [("f8", 0), ("string", 0), ("f8", 0)]
    data = encode_many(fields, 4)
    assert decode_many(spec, data) is not None
    assert decode_many(spec, np.pad(data, ((0, 0), (0, 3)))) is not None  # padding rosbags allows
    assert decode_many(spec, np.pad(data, ((0, 0), (0, 4)))) is None  # a longer message
    other = data.copy()
    other[2, 16] = ord("x")  # another frame of the same length
    assert decode_many(spec, other) is None
    big_endian = data.copy()
    big_endian[:, 1] = 0
    assert decode_many(spec, big_endian) is None
    assert decode_many(spec, data[:, :-1]) is None  # too short
    assert decode_many(spec, data[:0]) is None


def test_imu_bins_take_many_samples_as_one_by_one():
    """Samples added a block at a time reach ``prepare`` in the same blocks and sum to the same bins,
    bit for bit, as added one by one (over several of its blocks)."""
    from ionav_viz.sources.resample import IMU_BLOCK_SAMPLES, ImuBins

    rng = np.random.default_rng(9)
    n = 2 * IMU_BLOCK_SAMPLES + 12345
    samples = np.column_stack([np.sort(rng.uniform(0.0, n / 100.0, n)), rng.normal(size=(n, 6))])
    seen = {"one": [], "many": []}

    def bins(key):
        return ImuBins(0.1, keep_samples=True, prepare=lambda block: seen[key].append(len(block)) or block * 1.0)

    one, many = bins("one"), bins("many")
    for row in samples.tolist():
        one.add(tuple(row))
    start = 0
    while start < n:
        size = int(rng.integers(1, 20000))
        if rng.random() < 0.3:  # one by one between blocks
            many.add(tuple(samples[start].tolist()))
            size = 1
        else:
            many.add_many(samples[start : start + size])
        start += size
    for got, expected in zip(many.means(), one.means()):
        assert np.array_equal(got, expected)
    assert np.array_equal(many.kept_samples(), one.kept_samples())
    assert seen["many"] == seen["one"] == [IMU_BLOCK_SAMPLES, IMU_BLOCK_SAMPLES, 12345]


def test_a_type_defined_otherwise_under_the_same_name_is_read_by_its_own_definition(tmp_path):
    """Parsed definitions are kept per process: a log whose sensor_msgs/msg/Imu carries one more
    field (a vendor's build) is read by its own definition, after a log with the standard one."""
    from mcap_ros2.writer import Writer

    standard = iv.load_drive(fx.write_ros2(tmp_path / "standard.mcap", duration_s=10.0))
    definition = DEFINITIONS["sensor_msgs/msg/Imu"].replace(
        "float64[9] linear_acceleration_covariance", "float64[9] linear_acceleration_covariance\nfloat32 temperature", 1)
    assert "temperature" in definition
    path = tmp_path / "vendor.mcap"
    with open(path, "wb") as f:
        writer = Writer(f)
        imu = writer.register_msgdef("sensor_msgs/msg/Imu", definition)
        fix = writer.register_msgdef("sensor_msgs/msg/NavSatFix", DEFINITIONS["sensor_msgs/msg/NavSatFix"])
        for i, t in enumerate(np.arange(0.0, 10.0, 0.01)):
            stamp, log_ns = _stamp(fx.T0_S + t), round((fx.T0_S + t) * 1e9)
            writer.write_message("/imu", imu, {
                "header": {"stamp": stamp, "frame_id": "imu"}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                "orientation_covariance": [-1.0] + [0.0] * 8, "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.02},
                "angular_velocity_covariance": [0.0] * 9, "linear_acceleration": {"x": 0.5, "y": 0.0, "z": 9.81},
                "linear_acceleration_covariance": [0.0] * 9, "temperature": 40.0}, log_time=log_ns, publish_time=log_ns)
            if i % 20 == 0:
                lat, lon = fx.truth_position(np.array([t]))
                writer.write_message("/fix", fix, {
                    "header": {"stamp": stamp, "frame_id": "gps"}, "status": {"status": 0, "service": 1},
                    "latitude": float(lat[0]), "longitude": float(lon[0]), "altitude": 100.0,
                    "position_covariance": [0.0] * 9, "position_covariance_type": 0}, log_time=log_ns, publish_time=log_ns)
        writer.finish()
    vendor = iv.load_drive(path)
    assert np.array_equal(vendor.accel_long_mps2, np.full(len(vendor), 0.5))
    assert np.array_equal(standard.accel_long_mps2, np.full(len(standard), fx.ACCEL_MPS2))


def test_a_damaged_chunk_after_the_first_is_one_line(tmp_path):
    """A log with a velocity topic and a corrupted chunk past its first: reading a TwistStamped's
    first frame used to read every chunk and let the mcap package's CRC error out as a traceback
    (exit 1); now the chunk is met when it is read, and refused in one line."""
    from mcap.reader import make_reader

    from ionav_viz.sim.imu import SIM_TRUTH_TOPIC, write_imu_log

    from .conftest import run_cli

    path = tmp_path / "damaged.mcap"
    write_imu_log(path, "roundabout", 1, 60.0, "mems")
    with open(path, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    assert len(chunks) > 2
    data = bytearray(path.read_bytes())
    data[chunks[2].chunk_start_offset + chunks[2].chunk_length // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    proc = run_cli("evaluate", str(path), "--truth-topic", SIM_TRUTH_TOPIC, "--no-idnn")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.startswith(f"error: {path}: ") and ("corrupted" in proc.stderr or "damaged" in proc.stderr)
