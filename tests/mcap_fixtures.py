"""MCAP files written directly with mcap's writer (independent of ionav-viz's converter; the CDR from encode_many)."""

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


def _stamps(t_s):
    """``_stamp`` of every time at once: (sec, nanosec) arrays."""
    t_s = np.asarray(t_s, dtype=float)
    sec = np.floor(t_s)
    return sec.astype(np.int64), np.round((t_s - sec) * 1e9).astype(np.int64) % 1_000_000_000


def _header(t_s, frame):
    sec, nanosec = _stamps(t_s)
    return [("i4", sec), ("u4", nanosec), ("string", frame)]


def _imu_fields(t_s, frame, gyro, accel, gyro_cov=np.zeros(9), accel_cov=np.zeros(9)):
    """sensor_msgs/msg/Imu of every sample: ``gyro``, ``accel`` (3, n), orientation unknown."""
    return [*_header(t_s, frame), ("f8", [[0.0, 0.0, 0.0, 1.0]]), ("f8", [[-1.0] + [0.0] * 8]),
            ("f8", np.asarray(gyro, dtype=float).T), ("f8", np.asarray(gyro_cov, dtype=float)[None]),
            ("f8", np.asarray(accel, dtype=float).T), ("f8", np.asarray(accel_cov, dtype=float)[None])]


def _fix_fields(t_s, frame, lat, lon, status=0, altitude_m=100.0, cov=np.zeros(9), cov_type=0):
    """sensor_msgs/msg/NavSatFix of every fix."""
    return [*_header(t_s, frame), ("i1", status), ("u2", 1), ("f8", lat), ("f8", lon), ("f8", altitude_m),
            ("f8", np.asarray(cov, dtype=float)[None]), ("u1", cov_type)]


def _odometry_fields(t_s, frame, child, position, pose_cov, speed_x):
    """nav_msgs/msg/Odometry of every sample: ``position`` (n, 3), identity orientation, forward speed only."""
    n = len(t_s)
    return [*_header(t_s, frame), ("string", child), ("f8", position), ("f8", [[0.0, 0.0, 0.0, 1.0]]),
            ("f8", np.asarray(pose_cov, dtype=float)[None]),
            ("f8", np.c_[speed_x, np.zeros((n, 5))]), ("f8", np.zeros((1, 36)))]


def _write_messages(path, streams, t0_s, log_offset_s, compression=None):
    """Write ``streams`` [(topic, schema name, t_s after t0_s, fields of encode_many)] as a ROS 2 MCAP with
    mcap's own writer, every message in time order (ties in the order given, as ``sorted`` keeps them),
    log and publish time ``t0_s + t_s + log_offset_s``. The CDR comes from ``encode_many``, which test_mcap checks
    byte for byte against mcap_ros2's encoder on these message types."""
    from mcap.writer import CompressionType, Writer

    from ionav_viz.sources.cdr import encode_many

    topics, t_all, rows, payloads = [], [], [], []
    for k, (topic, schema, t_s, fields) in enumerate(streams):
        t_s = np.asarray(t_s, dtype=float)
        topics.append((topic, schema))
        t_all.append(t_s)
        rows.append(np.c_[np.full(len(t_s), k), np.arange(len(t_s))])
        payloads.append(encode_many(fields, len(t_s)) if len(t_s) else None)
    t_all, rows = np.concatenate(t_all), np.concatenate(rows)
    order = np.argsort(t_all, kind="stable")
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType[compression] if compression else CompressionType.ZSTD)
        w.start(profile="ros2", library="ionav-viz tests")
        schemas, channels = {}, {}
        for _topic, schema in topics:
            if schema not in schemas:
                schemas[schema] = w.register_schema(schema, "ros2msg", DEFINITIONS[schema].encode())
        for i in order:
            k, j = rows[i]
            if k not in channels:
                channels[k] = w.register_channel(topics[k][0], "cdr", schemas[topics[k][1]])
            ns = int(round((t0_s + t_all[i] + log_offset_s) * 1e9))
            w.add_message(channels[k], log_time=ns, data=payloads[k][j].tobytes(), publish_time=ns)
        w.finish()
    return path


def sample_times(rate_hz, duration_s, rng, jitter_s=0.002):
    t = np.arange(0, duration_s, 1.0 / rate_hz)
    return np.sort(t + rng.uniform(-jitter_s, jitter_s, len(t)))


def write_ros2(path, duration_s=30.0, imu_hz=100, gnss_hz=5, seed=0, no_fix_times=(), extra_imu_topic=False,
               latency_s=0.03, compression=None, imu_until_s=None):
    """IMU at ``imu_hz`` and NavSatFix at ``gnss_hz`` with jittered header stamps; log time = stamp + latency;
    ``imu_until_s``: the IMU stops then (the fixes go on)."""
    rng = np.random.default_rng(seed)
    t = sample_times(imu_hz, duration_s, rng)
    if imu_until_s is not None:
        t = t[t <= imu_until_s]
    imu = _imu_fields(T0_S + t, "base_link", np.c_[np.zeros((len(t), 2)), np.full(len(t), YAW_RATE_RADPS)].T,
                      np.c_[np.full(len(t), ACCEL_MPS2), np.zeros(len(t)), np.full(len(t), 9.81)].T)
    g_t = sample_times(gnss_hz, duration_s, rng)
    lat, lon = truth_position(g_t)
    no_fix = np.array([any(abs(t - x) < 0.5 / gnss_hz for x in no_fix_times) for t in g_t], dtype=bool)
    streams = [("/imu", "sensor_msgs/msg/Imu", t, imu)]
    if extra_imu_topic:
        streams.append(("/imu2", "sensor_msgs/msg/Imu", t, imu))
    streams.append(("/fix", "sensor_msgs/msg/NavSatFix", g_t,
                    _fix_fields(T0_S + g_t, "gps", lat + np.where(no_fix, 1.0, 0.0), lon, status=np.where(no_fix, -1, 0))))
    return _write_messages(path, streams, T0_S, latency_s, compression)


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
    Written with mcap's writer, not with ionav-viz's converter."""
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
    twice = rng.uniform(size=len(g_t)) < duplicate_share  # the odd fix published again 1 ms later
    fix = np.repeat(np.arange(len(g_t)), np.where(twice, 2, 1))
    again = np.r_[False, fix[1:] == fix[:-1]]
    t = np.asarray(drive.t_s, dtype=float)
    return _write_messages(path, [
        ("/imu/data", "sensor_msgs/msg/Imu", t, _imu_fields(t0 + t, "imu_link", gyro, accel)),
        ("/fix", "sensor_msgs/msg/NavSatFix", g_t[fix] + np.where(again, 0.001, 0.0),
         _fix_fields(t0 + g_t[fix], "gps", lat[fix], lon[fix])),
    ], t0, 0.02)


def _turn(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """Rz(yaw) @ Ry(pitch) @ Rx(roll): the IMU's axes in the body frame (written out here, not
    taken from ionav-viz)."""
    r, p, y = np.radians([roll_deg, pitch_deg, yaw_deg])
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def write_realistic(drive, path, mount_deg=(2.0, -3.0, 4.0), imu_hz=100, gnss_hz=5, odom_hz=50, seed=0,
                    gnss_sigma_m=1.0, lever_arm_m=(0.5, -0.3, 0.4), duration_s=None, reference_frame=None,
                    velocity_gap_s=None):
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
    ``velocity_gap_s`` ``(t0, t1)``: no velocity message in that span of drive time, the fixes going
    on (a phone's location service losing its course). Written with mcap's writer, not with
    ionav-viz's converter."""
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
    n_g = len(g_t)
    vel = np.ones(n_g, dtype=bool) if velocity_gap_s is None else (g_t < velocity_gap_s[0]) | (g_t > velocity_gap_s[1])
    keep = drive.t_s < end
    t_ref = np.asarray(drive.t_s[keep], dtype=float)
    streams = [
        ("/imu/data_raw", "sensor_msgs/msg/Imu", t_imu,
         _imu_fields(t0 + t_imu, "imu_link", gyro, accel, [4e-6 if k % 4 == 0 else 0.0 for k in range(9)],
                     [2.5e-3 if k % 4 == 0 else 0.0 for k in range(9)])),
        ("/gps/fix", "sensor_msgs/msg/NavSatFix", g_t, _fix_fields(t0 + g_t, "gps", lat, lon, cov=cov, cov_type=2)),
        ("/gps/vel", "geometry_msgs/msg/TwistStamped", g_t[vel],
         [*_header(t0 + g_t[vel], "gps"),
          ("f8", np.c_[g_speed * np.sin(course), g_speed * np.cos(course), np.zeros(n_g)][vel]),
          ("f8", np.zeros((1, 3)))]),
        ("/wheel/odom", "nav_msgs/msg/Odometry", o_t,
         _odometry_fields(t0 + o_t, "odom", "base_link", np.zeros((1, 3)),
                          [-1.0 if k % 7 == 0 else 0.0 for k in range(36)], o_speed)),
        ("/reference/fix", "sensor_msgs/msg/NavSatFix", t_ref,
         _fix_fields(t0 + t_ref, "gps", drive.lat_deg[keep], drive.lon_deg[keep], status=2,
                     cov=[1e-4 if k % 4 == 0 else 0.0 for k in range(9)], cov_type=2)),
    ]
    if reference_frame is not None:
        from pyproj import Geod

        lat0, lon0, yaw0 = reference_frame
        az, _, dist = Geod(ellps="WGS84").inv(np.full(keep.sum(), lon0), np.full(keep.sum(), lat0), drive.lon_deg[keep], drive.lat_deg[keep])
        east, north = dist * np.sin(np.radians(az)), dist * np.cos(np.radians(az))
        c, s_ = math.cos(math.radians(yaw0)), math.sin(math.radians(yaw0))
        position = np.c_[c * east + s_ * north, -s_ * east + c * north, np.full(len(t_ref), 3.0)]
        streams.append(("/reference/odom", "nav_msgs/msg/Odometry", t_ref,
                        _odometry_fields(t0 + t_ref, "map", "base_link", position, np.zeros(36), np.zeros(len(t_ref)))))
    return _write_messages(path, streams, t0, 0.01)
