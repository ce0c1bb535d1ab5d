"""Rebuild the real-log corpus (``tests/data/real/*.mcap``) from the original public files.

Usage::

    python tests/data/real/build_corpus.py ORIGINALS [--out DIR] [--only NAME]

``ORIGINALS`` holds each source repository's files under ``OWNER/NAME/PATH``, exactly as
``git show COMMIT:PATH`` gives them at the commits listed in :data:`SOURCES` (and in this folder's
README). Every file is checked against its git blob hash before use, so a wrong or changed file
stops the build (one line, exit code 2). Nothing is downloaded. ``--out`` defaults to this file's
folder; ``--only`` rebuilds one log; ``--whole`` writes the whole logs instead of the committed
segments (for local measurements: they are over the corpus's size limit).

Each log is written as a ROS 2 MCAP (``cdr``, zstd chunks) that ``ionav-viz`` reads:

* ``/imu/data`` ``sensor_msgs/msg/Imu`` at the IMU's native rate, one message per recorded sample,
  in the IMU's own axes (SI units; no mount, bias or axis change applied), values rounded to
  float32 (what the sensors resolve is far coarser) so that the chunks compress;
* ``/gps/fix`` ``sensor_msgs/msg/NavSatFix``, the receiver's fixes, with the receiver's reported
  accuracy as a diagonal ENU covariance where it gives one;
* ``/gps/vel`` ``geometry_msgs/msg/TwistStamped`` (frame ``gps``: ``linear.x`` east, ``linear.y``
  north, ``linear.z`` up, m/s) where the receiver gives a speed and course or a velocity;
* ``/truth/fix`` ``NavSatFix``, a separate reference trajectory, where the source has one;
* ``/wheel/odom`` ``nav_msgs/msg/Odometry`` (child frame ``base_link``), the car's own speed, where
  the source has one.

Every message's log and publish time is its header stamp (UNIX time, ns). The output is
deterministic: the same originals and the same ``mcap``/``zstandard`` versions give the same bytes
(other zstd versions: the same messages). Written to a temporary file, then renamed.
"""

from __future__ import annotations

import argparse
import datetime as dt
import functools
import hashlib
import math
import os
import struct
import sys
from pathlib import Path

import numpy as np

G_MPS2 = 9.80665
GPS_UTC_LEAP_S = 18  # GPS time minus UTC since 2017-01-01 (every source here is later)
GPS_EPOCH_UNIX_S = 315_964_800  # 1980-01-06T00:00:00Z

#: Per log: its source repository, commit, and the files used with their git blob hashes.
SOURCES = {
    "roof_mems_rtk_gnss_imu_drive0708": {
        "repo": "rtklibexplorer/GNSS_IMU",
        "commit": "8235ee6c5f349db529bf43ad556a3769b346b5a1",
        "files": {
            "LICENSE": "29ae378a625e8e8d217b563f0a47d4b771517b67",
            "data/drive_0708/imu_1934.csv": "f74142a151c63d83f50797deaf40f40929bb369e",
            "data/drive_0708/imu_1934.csv.tag": "c79867904df17050fb69470b5da68aac466700c8",
            "data/drive_0708/gnss_1934_sf.pos": "dc0ca25783ebb20d5e1e9f4fac590b72be551951",
        },
    },
    "dash_comma2k19_example1": {
        "repo": "commaai/comma2k19",
        "commit": "4c7f1a6e1957745beadc1def0e7225f559b09a2a",
        "files": {
            "LICENSE": "b8fd9e299c97ad0eaf1e4b1464558fc24324b342",
            **{f"Example_1/b0c9d2329ad1606b|2018-08-02--08-34-47/40/{k}": v for k, v in {
                "processed_log/IMU/accelerometer/t": "6f66d1f776a89364afbd99f329a20151f78ade25",
                "processed_log/IMU/accelerometer/value": "efa9ca2798aa6d5438edba5e4021e4c5ab693463",
                "processed_log/IMU/gyro/t": "6f66d1f776a89364afbd99f329a20151f78ade25",
                "processed_log/IMU/gyro/value": "eda48c19a8240ed26f5cc0c285422d4d3f4c79d4",
                "processed_log/GNSS/live_gnss_ublox/t": "c07e0e8e8e7bb6c4557018ce41c58fbf71279d99",
                "processed_log/GNSS/live_gnss_ublox/value": "b203affeb7ea6aadf6c31758c54a910f2893ab9a",
                "processed_log/CAN/speed/t": "db54caa7d3f53611713bc5f8a82d2c19950d251a",
                "processed_log/CAN/speed/value": "6da9b94fbcfaaac9fe57dd53e5fe1f38d18970c4",
                "global_pose/frame_times": "4483892a2cb0e1ddca9440e045c4f9d6991cbd77",
                "global_pose/frame_gps_times": "c0b2ff88b9c9f69efa5151a4295a5d38fd93c88b",
                "global_pose/frame_positions": "020f0010ddebf4dac622e8d75e3982d678e8d999",
            }.items()},
        },
    },
    "phone_flat_meszdav_rsq_q1_00": {
        "repo": "meszdav/road-surface-quality",
        "commit": "4512ab613564d725380b8fa8f57f07c1c1aa00b7",
        "files": {
            "LICENSE": "316be2e9f11662553114277667d0c0b57421579a",
            "data/raw_data_train/rsq_q1/00/Accelerometer.csv": "99c88ddaeec44777eac37388ef43e88f233f0e4e",
            "data/raw_data_train/rsq_q1/00/Gyroscope.csv": "86de0cece38cef37ee4919752c4f8950829cb48a",
            "data/raw_data_train/rsq_q1/00/Location.csv": "43649920122ba242e1c11867bf0192b92ff6dd2c",
        },
    },
    "phone_flat_meszdav_rsq_q2_01": {
        "repo": "meszdav/road-surface-quality",
        "commit": "4512ab613564d725380b8fa8f57f07c1c1aa00b7",
        "files": {
            "LICENSE": "316be2e9f11662553114277667d0c0b57421579a",
            "data/raw_data_train/rsq_q2/01/Accelerometer.csv": "4e451e956bc3167140e1c2b329db3996d9737086",
            "data/raw_data_train/rsq_q2/01/Gyroscope.csv": "38fd2aa3a09b556bebcf1f172c8c3c23b9a49363",
            "data/raw_data_train/rsq_q2/01/Location.csv": "a85ee14f9705c3a50bcfe3ff09d23d23e6282983",
        },
    },
    "robot_husky_robot_localization_test1": {
        "repo": "cra-ros-pkg/robot_localization",
        "commit": "1cb953379378d13b3e0935ed73d0c7407bd80543",
        "files": {
            "LICENSE": "45521a4ae662aeb648b3773cf6f127111e1cdb20",
            "test/test1.bag": "565f14c8e555135ae5c7274fc6855675fb201dab",
        },
    },
}


class BuildError(Exception):
    """A missing or changed original file: said in one line."""


# ---------------------------------------------------------------------------------------------
# Reading the originals


def original(root: Path, log: str, path: str) -> Path:
    """The original file ``path`` of ``log``'s repository under ``root``, checked against its git
    blob hash."""
    src = SOURCES[log]
    file = root / src["repo"] / path
    if not file.is_file():
        raise BuildError(f"{file}: not found; put {src['repo']} @ {src['commit'][:7]}:{path} there "
                         f"(git show {src['commit']}:'{path}')")
    data = file.read_bytes()
    blob = hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()
    if blob != src["files"][path]:
        raise BuildError(f"{file}: git blob {blob[:10]}, expected {src['files'][path][:10]} "
                         f"({src['repo']} @ {src['commit'][:7]}:{path})")
    return file


def ecef_to_geodetic(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """WGS84 latitude, longitude (deg) and ellipsoidal height (m) of ECEF points (N x 3, m)
    (Bowring's start, five fixed-point iterations: below a millimetre near the earth's surface)."""
    a, f = 6_378_137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1 - e2))
    for _ in range(5):
        n = a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - n
        lat = np.arctan2(z, p * (1 - e2 * n / (n + h)))
    n = a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
    h = p / np.cos(lat) - n
    return np.degrees(lat), np.degrees(np.arctan2(y, x)), h


# ---------------------------------------------------------------------------------------------
# Messages


def _header(t_ns: int, frame: str) -> dict:
    return {"stamp": {"sec": t_ns // 1_000_000_000, "nanosec": t_ns % 1_000_000_000}, "frame_id": frame}


def _f32(values) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=np.float32)]


def imu_msg(t_ns: int, accel_mps2, gyro_radps) -> dict:
    ax, ay, az = _f32(accel_mps2)
    gx, gy, gz = _f32(gyro_radps)
    return {"header": _header(t_ns, "imu_link"),
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}, "orientation_covariance": [-1.0] + [0.0] * 8,
            "angular_velocity": {"x": gx, "y": gy, "z": gz}, "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": {"x": ax, "y": ay, "z": az}, "linear_acceleration_covariance": [0.0] * 9}


def fix_msg(t_ns: int, lat_deg: float, lon_deg: float, alt_m: float, sigma_enu_m=None, status: int = 0,
            frame: str = "gps") -> dict:
    """A NavSatFix; ``sigma_enu_m`` (east, north, up standard deviations) gives a diagonal
    covariance (type 2), None an unknown one (type 0)."""
    cov = [0.0] * 9
    kind = 0
    if sigma_enu_m is not None:
        e, n, u = (float(s) for s in sigma_enu_m)
        cov[0], cov[4], cov[8], kind = e * e, n * n, u * u, 2
    return {"header": _header(t_ns, frame), "status": {"status": status, "service": 1},
            "latitude": float(lat_deg), "longitude": float(lon_deg), "altitude": float(alt_m),
            "position_covariance": cov, "position_covariance_type": kind}


def vel_msg(t_ns: int, east_mps: float, north_mps: float, up_mps: float = 0.0) -> dict:
    return {"header": _header(t_ns, "gps"),
            "twist": {"linear": {"x": float(east_mps), "y": float(north_mps), "z": float(up_mps)},
                      "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}}


def odom_msg(t_ns: int, speed_mps: float) -> dict:
    unknown = [0.0] * 36
    for i in range(6):
        unknown[i * 7] = -1.0
    return {"header": _header(t_ns, "odom"), "child_frame_id": "base_link",
            "pose": {"pose": {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
                              "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}, "covariance": unknown},
            "twist": {"twist": {"linear": {"x": float(speed_mps), "y": 0.0, "z": 0.0},
                                "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}, "covariance": [0.0] * 36}}


SCHEMAS = {"/imu/data": "sensor_msgs/msg/Imu", "/gps/fix": "sensor_msgs/msg/NavSatFix",
           "/gps/vel": "geometry_msgs/msg/TwistStamped", "/truth/fix": "sensor_msgs/msg/NavSatFix",
           "/wheel/odom": "nav_msgs/msg/Odometry"}
TOPIC_ORDER = list(SCHEMAS)


def write_mcap(path: Path, events: list[tuple[int, str, dict]]) -> int:
    """Write ``events`` ((stamp ns, topic, message)) in stamp order (ties in :data:`TOPIC_ORDER`,
    then as given) to ``path`` atomically; returns the message count."""
    from mcap.writer import CompressionType
    from mcap_ros2.writer import Writer

    from ionav_viz.sources.ros2_msgs import DEFINITIONS

    order = sorted(range(len(events)), key=lambda i: (events[i][0], TOPIC_ORDER.index(events[i][1]), i))
    tmp = path.with_name(path.name + ".part")
    try:
        with open(tmp, "wb") as f:
            w = Writer(f, chunk_size=4 * 1024 * 1024, compression=CompressionType.ZSTD)
            schemas = {}
            for topic in TOPIC_ORDER:
                if any(e[1] == topic for e in events):
                    name = SCHEMAS[topic]
                    schemas[topic] = w.register_msgdef(name, DEFINITIONS[name])
            for i in order:
                t_ns, topic, msg = events[i]
                w.write_message(topic, schemas[topic], msg, log_time=t_ns, publish_time=t_ns)
            w.finish()
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return len(events)


def _ns(t_s: float) -> int:
    return int(round(t_s * 1e9))


# ---------------------------------------------------------------------------------------------
# The logs


#: The segment kept ends this long after the IMU log's first time tag (s); it begins with the log.
ROOF_END_S = 390.0


def roof_mems_rtk(root: Path, whole: bool = False) -> list:
    """rtklibexplorer/GNSS_IMU's drive_0708: a TDK ICM-45686 IMU at 100 Hz and a u-blox X20 RTK
    receiver at 4 Hz, both on a car's roof (the repository's ``src/drive_config.py``), Colorado,
    2025-07-08: its first :data:`ROOF_END_S` seconds (of 549: the stand, the residential streets on
    a hill, the start of the parking lot).

    IMU: the CSV's columns are accelerometer x, y, z (g), gyro x, y, z (deg/s) and the IMU's
    millisecond counter. As the repository's ``src/convert_imu_file.py`` does, the counter is
    put on GPS time linearly between the logger's time tags at the file's start and end
    (``.tag``: RTKLIB's TIMETAG header, then (ms, byte offset) pairs), the first and last lines
    (possibly cut) are left out, and the logging delay its ``drive_config.py`` states (``imu_t_off
    = -0.125`` s) is applied; unlike that script no low-pass filter is applied. Repeated rows (2 %:
    the sensor read out twice) are kept as recorded. Axes as recorded (``drive_config.py``: roll
    and yaw of 180 degrees from forward-right-down, so x backward, y right, z up).

    GNSS: RTKLIB's solution file (GPS time; Q 1 fix, 2 float; sdn, sde, sdu; vn, ve, vu)."""
    log = "roof_mems_rtk_gnss_imu_drive0708"
    csv = original(root, log, "data/drive_0708/imu_1934.csv")
    tag = original(root, log, "data/drive_0708/imu_1934.csv.tag").read_bytes()
    pos = original(root, log, "data/drive_0708/gnss_1934_sf.pos")
    if tag[:7] != b"TIMETAG" or (len(tag) - 76) % 8:
        raise BuildError(f"{root / SOURCES[log]['repo']}/data/drive_0708/imu_1934.csv.tag: not an RTKLIB time tag file")
    start_gpst_s = struct.unpack("<I", tag[64:68])[0] + struct.unpack("<d", tag[68:76])[0]
    last_tick_ms = struct.unpack("<I", tag[-8:-4])[0]
    end_gpst_s = start_gpst_s + last_tick_ms / 1000.0
    rows = np.loadtxt(csv, delimiter=",", dtype=float)[1:-1]
    counter_s = (rows[:, 6] - rows[0, 6]) / 1000.0
    t_gpst_s = start_gpst_s + counter_s * (end_gpst_s - start_gpst_s) / counter_s[-1] - 0.125
    t_unix_s = t_gpst_s - GPS_UTC_LEAP_S
    end_unix_s = start_gpst_s - GPS_UTC_LEAP_S + (math.inf if whole else ROOF_END_S)
    keep = t_unix_s <= end_unix_s
    events = []
    for t, acc_g, gyro_dps in zip(t_unix_s[keep], rows[keep, 0:3], rows[keep, 3:6]):
        events.append((_ns(t), "/imu/data", imu_msg(_ns(t), acc_g * G_MPS2, np.radians(gyro_dps))))
    with open(pos, encoding="ascii") as f:
        lines = [ln.split() for ln in f if ln.strip() and not ln.startswith("%")]
    for cols in lines:
        stamp = dt.datetime.strptime(cols[0] + " " + cols[1], "%Y/%m/%d %H:%M:%S.%f").replace(tzinfo=dt.UTC)
        t_ns = _ns(stamp.timestamp() - GPS_UTC_LEAP_S)
        if t_ns / 1e9 > end_unix_s:
            break
        lat, lon, h, q = float(cols[2]), float(cols[3]), float(cols[4]), int(float(cols[5]))
        sdn, sde, sdu = float(cols[7]), float(cols[8]), float(cols[9])
        vn, ve, vu = float(cols[15]), float(cols[16]), float(cols[17])
        status = 2 if q in (1, 2) else 0  # RTK fix or float: ground-based augmentation
        events.append((t_ns, "/gps/fix", fix_msg(t_ns, lat, lon, h, (sde, sdn, sdu), status)))
        events.append((t_ns, "/gps/vel", vel_msg(t_ns, ve, vn, vu)))
    return events


def dash_comma2k19(root: Path, whole: bool = False) -> list:
    """commaai/comma2k19's Example_1 segment 40: a comma EON on the windshield of a Toyota RAV4 on
    California's 280, 2018-08-02, 60 s. Kept whole.

    IMU: ``processed_log/IMU`` accelerometer and gyro (one stamp array for both, 104 Hz) in the
    EON's forward-right-down axes as recorded. GNSS: ``live_gnss_ublox`` (10 Hz; latitude,
    longitude, speed, UTC time in ms, altitude, bearing in degrees; no accuracy). Reference:
    ``global_pose`` (20 Hz, ECEF positions of the camera from comma's post-processing; GPS time).
    Vehicle speed: ``CAN/speed``. Boot time goes to UNIX time by the u-blox's UTC stamps (their
    median offset); the reference by its own GPS stamps."""
    log = "dash_comma2k19_example1"
    seg = "Example_1/b0c9d2329ad1606b|2018-08-02--08-34-47/40/"

    def npy(path: str) -> np.ndarray:
        return np.load(original(root, log, seg + path), allow_pickle=False)

    t_imu, acc = npy("processed_log/IMU/accelerometer/t"), npy("processed_log/IMU/accelerometer/value")
    t_gyro, gyro = npy("processed_log/IMU/gyro/t"), npy("processed_log/IMU/gyro/value")
    if not np.array_equal(t_imu, t_gyro):
        raise BuildError(f"{root / SOURCES[log]['repo'] / seg}: accelerometer and gyro stamps differ")
    t_fix, fix = npy("processed_log/GNSS/live_gnss_ublox/t"), npy("processed_log/GNSS/live_gnss_ublox/value")
    boot_to_unix_s = float(np.median(fix[:, 3] / 1000.0 - t_fix))
    events = []
    for t, a, g in zip(t_imu, acc, gyro):
        t_ns = _ns(t + boot_to_unix_s)
        events.append((t_ns, "/imu/data", imu_msg(t_ns, a, g)))
    for lat, lon, speed, utc_ms, alt, bearing_deg in fix:
        t_ns = int(round(utc_ms)) * 1_000_000
        events.append((t_ns, "/gps/fix", fix_msg(t_ns, lat, lon, alt)))
        b = math.radians(bearing_deg)
        events.append((t_ns, "/gps/vel", vel_msg(t_ns, speed * math.sin(b), speed * math.cos(b))))
    gps_times = npy("global_pose/frame_gps_times")
    lat, lon, h = ecef_to_geodetic(npy("global_pose/frame_positions"))
    for (week, tow), la, lo, hh in zip(gps_times, lat, lon, h):
        t_ns = _ns(GPS_EPOCH_UNIX_S + week * 604_800 + tow - GPS_UTC_LEAP_S)
        events.append((t_ns, "/truth/fix", fix_msg(t_ns, la, lo, hh, status=2, frame="reference")))
    t_can, speed = npy("processed_log/CAN/speed/t"), npy("processed_log/CAN/speed/value")[:, 0]
    for t, v in zip(t_can, speed):
        t_ns = _ns(t + boot_to_unix_s)
        events.append((t_ns, "/wheel/odom", odom_msg(t_ns, v)))
    return events


#: phyphox gives times from the experiment's start only: put on this UTC date (the data's
#: commit date; the hour is daytime in Hungary).
MESZDAV_T0_UNIX_S = dt.datetime(2020, 9, 1, 8, 0, tzinfo=dt.UTC).timestamp()
MESZDAV_KEEP_S = 330.0


def phone_flat_meszdav(root: Path, whole: bool = False, log: str = "phone_flat_meszdav_rsq_q1_00",
                       folder: str = "data/raw_data_train/rsq_q1/00/") -> list:
    """meszdav/road-surface-quality's ``rsq_q1/00`` (or another phyphox ``folder`` of the same
    repository, as ``log``): an iPhone lying flat, phyphox app, 100 Hz accelerometer (with gravity)
    and gyro, iOS location at 1 Hz, Hungary 2020; its first :data:`MESZDAV_KEEP_S` seconds (of 632;
    ``rsq_q2/01``: of 374).

    phyphox stamps the accelerometer and the gyro apart (both 100 Hz, 0-5 ms apart): each
    accelerometer sample is paired with the gyro sample nearest in time (none resampled), the
    message at the accelerometer's stamp; pairs more than 6 ms apart are left out. Axes as
    recorded (iOS: x right, y forward along the phone, z up out of the screen). Location: the
    horizontal accuracy as east and north sigma, the vertical as up (phyphox labels its unit
    degrees; it is metres); speed and course where iOS gives them (not -1)."""
    def table(name: str) -> np.ndarray:
        return np.loadtxt(original(root, log, folder + name), delimiter=",", skiprows=1, dtype=float)

    acc, gyro, loc = table("Accelerometer.csv"), table("Gyroscope.csv"), table("Location.csv")
    keep_s = math.inf if whole else MESZDAV_KEEP_S
    acc = acc[acc[:, 0] <= keep_s]
    j = np.clip(np.searchsorted(gyro[:, 0], acc[:, 0]), 1, len(gyro) - 1)
    j -= (acc[:, 0] - gyro[j - 1, 0]) < (gyro[j, 0] - acc[:, 0])
    near = np.abs(gyro[j, 0] - acc[:, 0]) <= 0.006
    events = []
    for t, a, g in zip(acc[near, 0], acc[near, 1:4], gyro[j[near], 1:4]):
        t_ns = _ns(MESZDAV_T0_UNIX_S + t)
        events.append((t_ns, "/imu/data", imu_msg(t_ns, a, g)))
    for t, lat, lon, h, speed, course_deg, h_acc, v_acc in loc[loc[:, 0] <= keep_s]:
        t_ns = _ns(MESZDAV_T0_UNIX_S + t)
        events.append((t_ns, "/gps/fix", fix_msg(t_ns, lat, lon, h, (h_acc, h_acc, v_acc))))
        if speed >= 0 and course_deg >= 0:
            c = math.radians(course_deg)
            events.append((t_ns, "/gps/vel", vel_msg(t_ns, speed * math.sin(c), speed * math.cos(c))))
    return events


def robot_husky(root: Path, whole: bool = False) -> list:
    """cra-ros-pkg/robot_localization's ``test/test1.bag`` (its own EKF tests' bag): a Clearpath
    Husky robot outdoors, 2015-05-21, 395 s, kept whole. ``/imu/data`` (30 Hz, ``imu_link``),
    ``/fix`` (2.5 Hz, SBAS, approximated covariance) and ``/husky_velocity_controller/odom``
    (10 Hz wheel odometry) become ``/imu/data``, ``/gps/fix`` and ``/wheel/odom`` with every field
    as recorded (the IMU's vectors and orientation rounded to float32 as for every log here; the ROS 1 header's
    ``seq`` has no ROS 2 field). Stamps: the messages' header stamps."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    log = "robot_husky_robot_localization_test1"
    bag = original(root, log, "test/test1.bag")
    store = get_typestore(Stores.ROS1_NOETIC)
    topics = {"/imu/data": "/imu/data", "/fix": "/gps/fix", "/husky_velocity_controller/odom": "/wheel/odom"}
    events = []

    def stamp_ns(msg) -> int:
        return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec

    def vec(v) -> dict:
        return {"x": float(v.x), "y": float(v.y), "z": float(v.z)}

    with Reader(bag) as reader:
        for conn, _, raw in reader.messages(connections=[c for c in reader.connections if c.topic in topics]):
            msg = store.deserialize_ros1(raw, conn.msgtype)
            t_ns, topic = stamp_ns(msg), topics[conn.topic]
            if topic == "/imu/data":
                out = imu_msg(t_ns, [msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z],
                              [msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z])
                out["header"]["frame_id"] = msg.header.frame_id
                q = _f32([msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w])
                out["orientation"] = dict(zip("xyzw", q))
                for field in ("orientation_covariance", "angular_velocity_covariance", "linear_acceleration_covariance"):
                    out[field] = [float(v) for v in getattr(msg, field)]
            elif topic == "/gps/fix":
                out = {"header": _header(t_ns, msg.header.frame_id),
                       "status": {"status": int(msg.status.status), "service": int(msg.status.service)},
                       "latitude": float(msg.latitude), "longitude": float(msg.longitude), "altitude": float(msg.altitude),
                       "position_covariance": [float(v) for v in msg.position_covariance],
                       "position_covariance_type": int(msg.position_covariance_type)}
            else:
                out = {"header": _header(t_ns, msg.header.frame_id), "child_frame_id": msg.child_frame_id,
                       "pose": {"pose": {"position": vec(msg.pose.pose.position),
                                         "orientation": {"x": float(msg.pose.pose.orientation.x),
                                                         "y": float(msg.pose.pose.orientation.y),
                                                         "z": float(msg.pose.pose.orientation.z),
                                                         "w": float(msg.pose.pose.orientation.w)}},
                                "covariance": [float(v) for v in msg.pose.covariance]},
                       "twist": {"twist": {"linear": vec(msg.twist.twist.linear), "angular": vec(msg.twist.twist.angular)},
                                 "covariance": [float(v) for v in msg.twist.covariance]}}
            events.append((t_ns, topic, out))
    return events


BUILDERS = {"roof_mems_rtk_gnss_imu_drive0708": roof_mems_rtk, "dash_comma2k19_example1": dash_comma2k19,
            "phone_flat_meszdav_rsq_q1_00": phone_flat_meszdav, "robot_husky_robot_localization_test1": robot_husky,
            "phone_flat_meszdav_rsq_q2_01": functools.partial(phone_flat_meszdav, log="phone_flat_meszdav_rsq_q2_01",
                                                              folder="data/raw_data_train/rsq_q2/01/")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("originals", type=Path, help="folder holding OWNER/NAME/PATH of each source file")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent, help="where the MCAPs go")
    parser.add_argument("--only", choices=sorted(BUILDERS), help="rebuild this log only")
    parser.add_argument("--whole", action="store_true",
                        help="write the whole logs, not the committed segments (for local use: over the size limit)")
    args = parser.parse_args(argv)
    try:
        if not args.originals.is_dir():
            raise BuildError(f"{args.originals}: not a folder (give the folder holding OWNER/NAME/PATH)")
        if not args.out.is_dir():
            raise BuildError(f"--out {args.out}: not a folder")
        names = [args.only] if args.only else list(BUILDERS)
        for name in names:  # every original checked before anything is written
            for path in SOURCES[name]["files"]:
                original(args.originals, name, path)
        for name in names:
            out = args.out / f"{name}.mcap"
            count = write_mcap(out, BUILDERS[name](args.originals, whole=args.whole))
            print(f"{out}: {count} messages, {out.stat().st_size} bytes")
    except BuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
