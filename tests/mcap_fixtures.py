"""MCAP files written directly with mcap / mcap_ros2 writers (independent of ionav-viz's converter)."""

from __future__ import annotations

import json
import math

import numpy as np

from ionav_viz.sources.ros2_msgs import DEFINITIONS

ACCEL_MPS2 = 0.5
YAW_RATE_RADPS = 0.02
COURSE_DEG = 30.0
V0_MPS = 5.0
LAT0, LON0 = 52.40, -1.52
T0_S = 1_700_000_000.0 + 0.0123  # a UNIX time with a fraction


def truth_position(t_s):
    """Straight line at COURSE_DEG, speed V0 + a t."""
    from pyproj import Geod

    dist = V0_MPS * t_s + 0.5 * ACCEL_MPS2 * t_s**2
    lon, lat, _ = Geod(ellps="WGS84").fwd(np.full_like(dist, LON0), np.full_like(dist, LAT0), np.full_like(dist, COURSE_DEG), dist)
    return lat, lon


def _stamp(t):
    sec = int(math.floor(t))
    return {"sec": sec, "nanosec": int(round((t - sec) * 1e9)) % 1_000_000_000}


def sample_times(rate_hz, duration_s, rng, jitter_s=0.002):
    t = np.arange(0, duration_s, 1.0 / rate_hz)
    return np.sort(t + rng.uniform(-jitter_s, jitter_s, len(t)))


def write_ros2(path, duration_s=30.0, imu_hz=100, gnss_hz=5, seed=0, no_fix_times=(), extra_imu_topic=False,
               latency_s=0.03, compression=None, imu_until_s=None):
    """IMU at ``imu_hz`` and NavSatFix at ``gnss_hz`` with jittered header stamps; log time = stamp + latency;
    ``imu_until_s``: the IMU stops then (the fixes go on)."""
    from mcap.writer import CompressionType
    from mcap_ros2.writer import Writer

    rng = np.random.default_rng(seed)
    with open(path, "wb") as f:
        kwargs = {} if compression is None else {"compression": CompressionType[compression]}
        w = Writer(f, **kwargs)
        imu_schema = w.register_msgdef("sensor_msgs/msg/Imu", DEFINITIONS["sensor_msgs/msg/Imu"])
        fix_schema = w.register_msgdef("sensor_msgs/msg/NavSatFix", DEFINITIONS["sensor_msgs/msg/NavSatFix"])
        events = []
        for t in sample_times(imu_hz, duration_s, rng):
            if imu_until_s is not None and t > imu_until_s:
                continue
            msg = {"header": {"stamp": _stamp(T0_S + t), "frame_id": "base_link"},
                   "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}, "orientation_covariance": [-1.0] + [0.0] * 8,
                   "angular_velocity": {"x": 0.0, "y": 0.0, "z": YAW_RATE_RADPS}, "angular_velocity_covariance": [0.0] * 9,
                   "linear_acceleration": {"x": ACCEL_MPS2, "y": 0.0, "z": 9.81}, "linear_acceleration_covariance": [0.0] * 9}
            events.append((t, "/imu", imu_schema, msg))
            if extra_imu_topic:
                events.append((t, "/imu2", imu_schema, msg))
        g_t = sample_times(gnss_hz, duration_s, rng)
        lat, lon = truth_position(g_t)
        for t, la, lo in zip(g_t, lat, lon):
            status = -1 if any(abs(t - x) < 0.5 / gnss_hz for x in no_fix_times) else 0
            msg = {"header": {"stamp": _stamp(T0_S + t), "frame_id": "gps"}, "status": {"status": status, "service": 1},
                   "latitude": float(la) + (1.0 if status < 0 else 0.0), "longitude": float(lo), "altitude": 100.0,
                   "position_covariance": [0.0] * 9, "position_covariance_type": 0}
            events.append((t, "/fix", fix_schema, msg))
        for t, topic, schema, msg in sorted(events, key=lambda e: e[0]):
            log_ns = int(round((T0_S + t + latency_s) * 1e9))
            w.write_message(topic, schema, msg, log_time=log_ns, publish_time=log_ns)
        w.finish()
    return path


def write_json(path, duration_s=30.0, imu_hz=50, gnss_hz=2, seed=1, tamper=None, **writer_options):
    """JSON-encoded MCAP: foxglove.LocationFix and an IMU message with sensor_msgs/Imu field names.
    ``writer_options`` go to mcap's Writer (e.g. ``use_statistics=False``); ``tamper(kind, i, msg)``
    (kind "imu" or "fix", i the message's index) returns the messages to write instead of ``msg``."""
    from mcap.writer import Writer

    rng = np.random.default_rng(seed)
    with open(path, "wb") as f:
        w = Writer(f, **writer_options)
        w.start()
        s_fix = w.register_schema("foxglove.LocationFix", "jsonschema", json.dumps({"type": "object"}).encode())
        s_imu = w.register_schema("sensor_msgs/Imu", "jsonschema", json.dumps({"type": "object"}).encode())
        c_fix = w.register_channel("/location", "json", s_fix)
        c_imu = w.register_channel("/imu", "json", s_imu)
        events = []
        for t in sample_times(imu_hz, duration_s, rng):
            st = _stamp(T0_S + t)
            msg = {"header": {"stamp": {"sec": st["sec"], "nsec": st["nanosec"]}, "frame_id": "base_link"},
                   "angular_velocity": {"x": 0, "y": 0, "z": YAW_RATE_RADPS}, "linear_acceleration": {"x": ACCEL_MPS2, "y": 0, "z": 9.81}}
            events.append((t, c_imu, msg))
        g_t = sample_times(gnss_hz, duration_s, rng)
        lat, lon = truth_position(g_t)
        for t, la, lo in zip(g_t, lat, lon):
            st = _stamp(T0_S + t)
            events.append((t, c_fix, {"timestamp": {"sec": st["sec"], "nsec": st["nanosec"]}, "frame_id": "gps",
                                      "latitude": float(la), "longitude": float(lo), "altitude": 100.0}))
        counters = {c_imu: 0, c_fix: 0}
        for t, ch, msg in sorted(events, key=lambda e: e[0]):
            ns = int(round((T0_S + t) * 1e9))
            out = [msg]
            if tamper is not None:
                out = tamper("imu" if ch == c_imu else "fix", counters[ch], msg)
                counters[ch] += 1
            for m in out:
                w.add_message(ch, log_time=ns, data=json.dumps(m).encode(), publish_time=ns)
        w.finish()
    return path


def write_fix_only(drive, path, gnss_hz, seed=0, white_m=0.15, duplicate_share=0.02, jitter_s=0.004, sensor_from_body=None,
                   no_fix_spans=(), imu_noise=False):
    """``drive`` (a simulated one, the logger's CSV) as a ROS 2 MCAP the way many real bags are:
    ``sensor_msgs/Imu`` at the drive's samples and ``NavSatFix`` at ``gnss_hz`` with no velocity
    topic. The fixes are the CSV's positions at jittered (``jitter_s``) stamps plus what a
    consumer receiver adds on top of a VBOX-class track: white noise of ``white_m`` per axis, the
    1e-7 deg rounding of its NMEA output and the odd fix published twice (``duplicate_share``).
    The IMU carries gravity (+9.81 m/s^2 up) and the centripetal acceleration (speed x yaw rate,
    to the left in a left turn); ``sensor_from_body`` (3x3) rotates both vectors into a mount
    other than REP 103's; no fix is published within ``no_fix_spans`` ((start s, end s), a tunnel).
    ``imu_noise``: white noise on every axis (0.05 m/s^2, 0.002 rad/s; drawn in the body frame, so
    every mount carries the same), as a real IMU has: without it gravity and the gyro's x and y
    read one value throughout, which the reader takes as axes not measured (no mount estimated).
    Written with mcap_ros2 directly, not with ionav-viz's converter."""
    from mcap_ros2.writer import Writer

    rng = np.random.default_rng(seed)
    rot = np.eye(3) if sensor_from_body is None else np.asarray(sensor_from_body, dtype=float)
    t0 = T0_S - T0_S % 86400 + drive.start_time_of_day_s
    g_t = np.arange(0.0, drive.t_s[-1], 1.0 / gnss_hz)
    g_t = np.clip(np.sort(g_t + rng.uniform(-jitter_s, jitter_s, len(g_t))), 0.0, drive.t_s[-1])
    for a, b in no_fix_spans:
        g_t = g_t[(g_t < a) | (g_t >= b)]
    m_per_deg = 6_371_008.8 * math.pi / 180.0
    lat = np.round(np.interp(g_t, drive.t_s, drive.lat_deg) + rng.normal(0, white_m, len(g_t)) / m_per_deg, 7)
    lon = np.interp(g_t, drive.t_s, drive.lon_deg)
    lon = np.round(lon + rng.normal(0, white_m, len(g_t)) / (m_per_deg * np.cos(np.radians(lat))), 7)
    accel = np.stack([drive.accel_long_mps2, drive.speed_mps * drive.yaw_rate_radps, np.full(len(drive), 9.81)])
    gyro = np.stack([np.zeros(len(drive)), np.zeros(len(drive)), drive.yaw_rate_radps])
    if imu_noise:
        noise = np.random.default_rng(seed + 7919)
        accel, gyro = accel + noise.normal(0.0, 0.05, accel.shape), gyro + noise.normal(0.0, 0.002, gyro.shape)
    accel, gyro = rot @ accel, rot @ gyro
    with open(path, "wb") as f:
        w = Writer(f)
        imu_schema = w.register_msgdef("sensor_msgs/msg/Imu", DEFINITIONS["sensor_msgs/msg/Imu"])
        fix_schema = w.register_msgdef("sensor_msgs/msg/NavSatFix", DEFINITIONS["sensor_msgs/msg/NavSatFix"])
        events = []
        for i, t in enumerate(drive.t_s):
            events.append((t, "/imu/data", imu_schema, {
                "header": {"stamp": _stamp(t0 + t), "frame_id": "imu_link"},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}, "orientation_covariance": [-1.0] + [0.0] * 8,
                "angular_velocity": dict(zip("xyz", map(float, gyro[:, i]))), "angular_velocity_covariance": [0.0] * 9,
                "linear_acceleration": dict(zip("xyz", map(float, accel[:, i]))), "linear_acceleration_covariance": [0.0] * 9}))
        for t, la, lo in zip(g_t, lat, lon):
            msg = {"header": {"stamp": _stamp(t0 + t), "frame_id": "gps"}, "status": {"status": 0, "service": 1},
                   "latitude": float(la), "longitude": float(lo), "altitude": 100.0,
                   "position_covariance": [0.0] * 9, "position_covariance_type": 0}
            events.append((t, "/fix", fix_schema, msg))
            if rng.uniform() < duplicate_share:
                events.append((t + 0.001, "/fix", fix_schema, msg))
        for t, topic, schema, msg in sorted(events, key=lambda e: e[0]):
            ns = int(round((t0 + t + 0.02) * 1e9))
            w.write_message(topic, schema, msg, log_time=ns, publish_time=ns)
        w.finish()
    return path


def _turn(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """Rz(yaw) @ Ry(pitch) @ Rx(roll): the IMU's axes in the body frame (written out here, not
    taken from ionav-viz)."""
    r, p, y = np.radians([roll_deg, pitch_deg, yaw_deg])
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def write_realistic(drive, path, mount_deg=(2.0, -3.0, 4.0), imu_hz=100, gnss_hz=5, odom_hz=50, seed=0,
                    gnss_sigma_m=1.0, lever_arm_m=(0.5, -0.3, 0.4), duration_s=None, reference_frame=None):
    """``drive`` (a simulated one) as a real car's ROS 2 MCAP looks: a 6-axis IMU at ``imu_hz`` in
    its own frame ``imu_link``, turned by ``mount_deg`` (roll, pitch, yaw of the IMU in the body
    frame) and offset by ``lever_arm_m`` from the body origin (the centripetal acceleration it adds
    there), with white noise; a receiver at ``gnss_hz`` with ``gnss_sigma_m`` of noise per axis and
    that covariance, and its velocity on ``/gps/vel``; the CAN speed as ``/wheel/odom`` Odometry at
    ``odom_hz``; and a post-processed reference on ``/reference/fix`` (the drive's own positions).
    ``duration_s``: only the drive's first seconds. ``reference_frame`` ``(lat0, lon0, yaw_deg)``:
    the reference is also on ``/reference/odom``, an Odometry in the local frame ``map`` whose
    origin is at ``lat0, lon0`` and whose x axis points ``yaw_deg`` counter-clockwise from east
    (east and north from the geodesic's distance and azimuth: the azimuthal equidistant plane).
    Written with mcap_ros2 directly."""
    from mcap_ros2.writer import Writer

    rng = np.random.default_rng(seed)
    t0 = T0_S - T0_S % 86400 + drive.start_time_of_day_s
    end = float(drive.t_s[-1]) if duration_s is None else min(float(drive.t_s[-1]), duration_s)
    m = _turn(*mount_deg)
    t_imu = np.arange(0.0, end, 1.0 / imu_hz)
    speed, yaw = (np.interp(t_imu, drive.t_s, x) for x in (drive.speed_mps, drive.yaw_rate_radps))
    body_f = np.stack([np.interp(t_imu, drive.t_s, drive.accel_long_mps2), speed * yaw, np.full(len(t_imu), 9.81)])
    body_f[0] -= yaw**2 * lever_arm_m[0]  # centripetal acceleration at the lever arm (turning about z)
    body_f[1] -= yaw**2 * lever_arm_m[1]
    body_w = np.stack([np.zeros(len(t_imu)), np.zeros(len(t_imu)), yaw])
    accel = m.T @ body_f + rng.normal(0.0, 0.05, body_f.shape)
    gyro = m.T @ body_w + rng.normal(0.0, 0.002, body_w.shape)
    g_t = np.arange(0.0, end, 1.0 / gnss_hz)
    m_per_deg = 6_371_008.8 * math.pi / 180.0
    lat = np.interp(g_t, drive.t_s, drive.lat_deg) + rng.normal(0, gnss_sigma_m, len(g_t)) / m_per_deg
    lon = np.interp(g_t, drive.t_s, drive.lon_deg) + rng.normal(0, gnss_sigma_m, len(g_t)) / (m_per_deg * np.cos(np.radians(lat)))
    course = np.radians(np.interp(g_t, drive.t_s, np.rad2deg(np.unwrap(np.radians(drive.heading_deg)))))
    g_speed = np.interp(g_t, drive.t_s, drive.speed_mps)
    o_t = np.arange(0.0, end, 1.0 / odom_hz)
    o_speed = np.interp(o_t, drive.t_s, drive.columns["speed_can_mps"])
    cov = [gnss_sigma_m**2 if k in (0, 4) else (2 * gnss_sigma_m) ** 2 if k == 8 else 0.0 for k in range(9)]
    with open(path, "wb") as f:
        w = Writer(f)
        schemas = {name: w.register_msgdef(name, DEFINITIONS[name]) for name in DEFINITIONS}
        events = []
        for i, t in enumerate(t_imu):
            events.append((t, "/imu/data_raw", "sensor_msgs/msg/Imu", {
                "header": {"stamp": _stamp(t0 + t), "frame_id": "imu_link"},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}, "orientation_covariance": [-1.0] + [0.0] * 8,
                "angular_velocity": dict(zip("xyz", map(float, gyro[:, i]))), "angular_velocity_covariance": [4e-6 if k % 4 == 0 else 0.0 for k in range(9)],
                "linear_acceleration": dict(zip("xyz", map(float, accel[:, i]))), "linear_acceleration_covariance": [2.5e-3 if k % 4 == 0 else 0.0 for k in range(9)]}))
        for t, la, lo, c, v in zip(g_t, lat, lon, course, g_speed):
            header = {"stamp": _stamp(t0 + t), "frame_id": "gps"}
            events.append((t, "/gps/fix", "sensor_msgs/msg/NavSatFix", {
                "header": header, "status": {"status": 0, "service": 1}, "latitude": float(la), "longitude": float(lo),
                "altitude": 100.0, "position_covariance": cov, "position_covariance_type": 2}))
            events.append((t, "/gps/vel", "geometry_msgs/msg/TwistStamped", {
                "header": header, "twist": {"linear": {"x": float(v * math.sin(c)), "y": float(v * math.cos(c)), "z": 0.0},
                                            "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}}))
        for t, v in zip(o_t, o_speed):
            events.append((t, "/wheel/odom", "nav_msgs/msg/Odometry", {
                "header": {"stamp": _stamp(t0 + t), "frame_id": "odom"}, "child_frame_id": "base_link",
                "pose": {"pose": {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
                         "covariance": [-1.0 if k % 7 == 0 else 0.0 for k in range(36)]},
                "twist": {"twist": {"linear": {"x": float(v), "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
                          "covariance": [0.0] * 36}}))
        for i, t in enumerate(drive.t_s[drive.t_s < end]):
            events.append((t, "/reference/fix", "sensor_msgs/msg/NavSatFix", {
                "header": {"stamp": _stamp(t0 + t), "frame_id": "gps"}, "status": {"status": 2, "service": 1},
                "latitude": float(drive.lat_deg[i]), "longitude": float(drive.lon_deg[i]), "altitude": 100.0,
                "position_covariance": [1e-4 if k % 4 == 0 else 0.0 for k in range(9)], "position_covariance_type": 2}))
        if reference_frame is not None:
            from pyproj import Geod

            lat0, lon0, yaw0 = reference_frame
            keep = drive.t_s < end
            az, _, dist = Geod(ellps="WGS84").inv(np.full(keep.sum(), lon0), np.full(keep.sum(), lat0), drive.lon_deg[keep], drive.lat_deg[keep])
            east, north = dist * np.sin(np.radians(az)), dist * np.cos(np.radians(az))
            c, s_ = math.cos(math.radians(yaw0)), math.sin(math.radians(yaw0))
            for t, x, y in zip(drive.t_s[keep], c * east + s_ * north, -s_ * east + c * north):
                events.append((t, "/reference/odom", "nav_msgs/msg/Odometry", {
                    "header": {"stamp": _stamp(t0 + t), "frame_id": "map"}, "child_frame_id": "base_link",
                    "pose": {"pose": {"position": {"x": float(x), "y": float(y), "z": 3.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
                             "covariance": [0.0] * 36},
                    "twist": {"twist": {"linear": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
                              "covariance": [0.0] * 36}}))
        for t, topic, schema, msg in sorted(events, key=lambda e: e[0]):
            ns = int(round((t0 + t + 0.01) * 1e9))
            w.write_message(topic, schemas[schema], msg, log_time=ns, publish_time=ns)
        w.finish()
    return path
