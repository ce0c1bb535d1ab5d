"""ROS bags written with rosbags' own writers, and KITTI raw OXTS folders, from a drive (independent
of ionav-viz's readers: what a user's recorder or the KITTI devkit would have produced)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

G = 9.81
#: The columns a log of IMU, NavSatFix (no covariance) and GNSS velocity carries.
CARRIED = ("t_s", "lat_deg", "lon_deg", "speed_mps", "heading_deg", "accel_long_mps2", "yaw_rate_radps")
#: A ROS 1 message definition nothing can parse, for a topic ionav-viz does not read.
BROKEN_DEFINITION = "this is ### not a message definition\n"
T0_S = 1_317_042_145.0  # 2011-09-26 13:02:25 UTC, a KITTI day


def _stamps_ns(drive, t0_s: float = T0_S) -> np.ndarray:
    return int(t0_s) * 1_000_000_000 + np.rint(drive.t_s * 1e9).astype(np.int64)


def _messages(store, drive, stamps_ns, ros1: bool, vehicle_speed_as: str = "odometry"):
    """(topic, msgtype, stamp ns, message) per sample: IMU, NavSatFix and world-frame GNSS velocity,
    and the vehicle speed as ``/wheel/odom`` Odometry when the drive has ``speed_can_mps``."""
    T = store.types
    header_kw = (lambda i: {"seq": i}) if ros1 else (lambda i: {})
    v3, quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    course = np.radians(drive.heading_deg)
    v_east, v_north = drive.speed_mps * np.sin(course), drive.speed_mps * np.cos(course)
    zeros9 = np.zeros(9)
    for i, ns in enumerate(stamps_ns):
        stamp = T["builtin_interfaces/msg/Time"](sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))

        def header(frame, i=i, stamp=stamp):
            return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame, **header_kw(i))

        imu = T["sensor_msgs/msg/Imu"](
            header=header("base_link"), orientation=quat(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=np.r_[-1.0, np.zeros(8)],
            angular_velocity=v3(x=0.0, y=0.0, z=float(drive.yaw_rate_radps[i])), angular_velocity_covariance=zeros9,
            linear_acceleration=v3(x=float(drive.accel_long_mps2[i]), y=0.0, z=G), linear_acceleration_covariance=zeros9)
        fix = T["sensor_msgs/msg/NavSatFix"](
            header=header("gps"), status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
            latitude=float(drive.lat_deg[i]), longitude=float(drive.lon_deg[i]), altitude=100.0,
            position_covariance=zeros9, position_covariance_type=0)
        vel = T["geometry_msgs/msg/TwistStamped"](
            header=header("gps"), twist=T["geometry_msgs/msg/Twist"](linear=v3(x=float(v_east[i]), y=float(v_north[i]), z=0.0),
                                                                     angular=v3(x=0.0, y=0.0, z=0.0)))
        yield "/imu/data", "sensor_msgs/msg/Imu", int(ns), imu
        yield "/gps/fix", "sensor_msgs/msg/NavSatFix", int(ns), fix
        yield "/gps/vel", "geometry_msgs/msg/TwistStamped", int(ns), vel
        if "speed_can_mps" in drive.columns:  # CAN speed as a car's bridge publishes it: Odometry, twist in base_link
            twist = T["geometry_msgs/msg/Twist"](linear=v3(x=float(drive.columns["speed_can_mps"][i]), y=0.0, z=0.0),
                                                 angular=v3(x=0.0, y=0.0, z=float(drive.yaw_rate_radps[i])))
            pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0), orientation=quat(x=0.0, y=0.0, z=0.0, w=1.0))
            odom = T["nav_msgs/msg/Odometry"](
                header=header("odom"), child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.diag(np.full(6, -1.0)).ravel()),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)))
            if vehicle_speed_as in ("odometry", "odometry+filtered"):
                yield "/wheel/odom", "nav_msgs/msg/Odometry", int(ns), odom
            if vehicle_speed_as == "odometry+filtered":  # robot_localization's output beside the wheels
                yield "/odometry/filtered", "nav_msgs/msg/Odometry", int(ns), odom
            if vehicle_speed_as == "twist":  # a body-frame TwistStamped, as some CAN bridges publish it
                yield "/vehicle/twist", "geometry_msgs/msg/TwistStamped", int(ns), T["geometry_msgs/msg/TwistStamped"](
                    header=header("base_link"), twist=twist)


def _image(store, ns: int, size: tuple[int, int], ros1: bool):
    T = store.types
    h, w = size
    stamp = T["builtin_interfaces/msg/Time"](sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))
    header = T["std_msgs/msg/Header"](stamp=stamp, frame_id="camera", **({"seq": 0} if ros1 else {}))
    data = np.frombuffer(np.random.default_rng(ns % 2**32).bytes(h * w * 3), dtype=np.uint8)
    return T["sensor_msgs/msg/Image"](header=header, height=h, width=w, encoding="rgb8", is_bigendian=0, step=w * 3, data=data)


def _write_drive(w, store, drive, stamps, ros1: bool, image_every: int, image_size, vehicle_speed_as: str = "odometry") -> None:
    """The drive's messages (and an image every ``image_every`` samples) through an open rosbags writer."""
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    conns = {}
    sample = -1
    for topic, msgtype, ns, msg in _messages(store, drive, stamps, ros1=ros1, vehicle_speed_as=vehicle_speed_as):
        if topic not in conns:
            conns[topic] = w.add_connection(topic, msgtype, typestore=store)
        w.write(conns[topic], ns, serialize(msg, msgtype))
        sample += topic == "/gps/vel"
        if image_every and topic == "/gps/vel" and sample % image_every == 0:
            if "/camera/image" not in conns:
                conns["/camera/image"] = w.add_connection("/camera/image", "sensor_msgs/msg/Image", typestore=store)
            w.write(conns["/camera/image"], ns, serialize(_image(store, ns, image_size, ros1), "sensor_msgs/msg/Image"))


def write_ros1(drive, path: Path, compression: str | None = None, image_every: int = 0, image_size=(48, 64),
               broken_extra_topic: bool = False, vehicle_speed_as: str = "odometry") -> Path:
    """A ROS 1 bag of ``drive`` (compression None, "bz2" or "lz4"); an rgb8 image every
    ``image_every`` samples; a topic with an unparseable definition if ``broken_extra_topic``;
    the vehicle speed (when the drive has one) as ``"odometry"``, ``"odometry+filtered"`` (and a
    fused odometry beside it) or ``"twist"`` (a body-frame TwistStamped)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    stamps = _stamps_ns(drive)
    w = Writer(path)
    if compression:
        w.set_compression(Writer.CompressionFormat[compression.upper()])
    with w:
        if broken_extra_topic:
            bad = w.add_connection("/vendor/status", "vendor_msgs/msg/Status", msgdef=BROKEN_DEFINITION, md5sum="0" * 32)
            w.write(bad, int(stamps[0]), b"\x00\x01\x02")
        _write_drive(w, store, drive, stamps, True, image_every, image_size, vehicle_speed_as)
    return path


def write_ros2(drive, path: Path, storage: str = "sqlite3", compression: str | None = None, image_every: int = 0,
               image_size=(48, 64)) -> Path:
    """A ROS 2 bag folder of ``drive``: storage "sqlite3" or "mcap", compression None, "message"
    or "file" (zstd)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    stamps = _stamps_ns(drive)
    w = Writer(path, version=9, storage_plugin=StoragePlugin[storage.upper()])
    if compression:
        w.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
    with w:
        _write_drive(w, store, drive, stamps, False, image_every, image_size)
    return path


def write_kitti(drive, folder: Path, navstat=None, t0_s: float = T0_S) -> Path:
    """A KITTI raw drive folder (``oxts/timestamps.txt`` and ``oxts/data/*.txt``, the 30 OXTS
    fields) of ``drive``: a flat road, level IMU, the drive's course as ``atan2(ve, vn)``."""
    oxts = folder / "oxts"
    (oxts / "data").mkdir(parents=True)
    course = np.radians(drive.heading_deg)
    v = drive.speed_mps
    n = len(drive)
    navstat = np.full(n, 4) if navstat is None else np.asarray(navstat)
    yaw_ccw_from_east = np.arctan2(np.cos(course), np.sin(course))  # KITTI's yaw convention
    fields = np.column_stack([
        drive.lat_deg, drive.lon_deg, np.full(n, 116.0), np.zeros(n), np.zeros(n), yaw_ccw_from_east,
        v * np.cos(course), v * np.sin(course), v, np.zeros(n), np.zeros(n),  # vn ve vf vl vu
        drive.accel_long_mps2, np.zeros(n), np.full(n, G),  # ax ay az
        drive.accel_long_mps2, np.zeros(n), np.full(n, G),  # af al au
        np.zeros(n), np.zeros(n), drive.yaw_rate_radps,  # wx wy wz
        np.zeros(n), np.zeros(n), drive.yaw_rate_radps,  # wf wl wu
        np.full(n, 0.02), np.full(n, 0.01), navstat, np.full(n, 11), np.full(n, 6), np.full(n, 6), np.full(n, 6),
    ])
    for i, row in enumerate(fields):
        text = " ".join(repr(float(x)) if k < 25 else str(int(x)) for k, x in enumerate(row))
        (oxts / "data" / f"{i:010d}.txt").write_text(text + "\n")
    lines = []
    for ns in _stamps_ns(drive, t0_s):
        whole, frac = divmod(int(ns), 1_000_000_000)
        stamp = dt.datetime.fromtimestamp(whole, tz=dt.UTC).strftime("%Y-%m-%d %H:%M:%S")
        lines.append(f"{stamp}.{frac:09d}")
    (oxts / "timestamps.txt").write_text("\n".join(lines) + "\n")
    return folder


def carried(drive, n: int | None = None, **extra):
    """The first ``n`` samples of ``drive`` with only the :data:`CARRIED` columns (plus ``extra``)."""
    from ionav_viz.core.drive import Drive

    return Drive(drive.name, drive.source, drive.rate_hz, drive.start_time_of_day_s, {c: drive.columns[c][:n] for c in CARRIED} | extra)
