"""Writing a drive as a ROS 2 MCAP log (``ionav-viz convert``), readable by Foxglove and ``ros2 bag``.

Topics (``cdr`` encoding, standard schemas from :mod:`ionav_viz.ros2_msgs`):

* ``/imu/data`` ``sensor_msgs/msg/Imu``, frame ``base_link`` (REP 103: x forward, z up):
  ``linear_acceleration.x`` = longitudinal specific force (m/s^2), ``angular_velocity.z`` = yaw
  rate, counter-clockwise positive (rad/s); orientation unknown (``orientation_covariance[0] = -1``,
  REP 145); ``linear_acceleration.z`` is gravity's +9.80665 m/s^2 (what a level IMU at rest
  reads), the other axes 0, with unknown covariance.
* ``/gps/fix`` ``sensor_msgs/msg/NavSatFix``, frame ``gps``: latitude, longitude, altitude (m).
* ``/gps/vel`` ``geometry_msgs/msg/TwistStamped``, frame ``gps``: GNSS velocity as
  nmea_navsat_driver publishes it, ``linear.x`` east and ``linear.y`` north (m/s), from the GNSS
  speed and course.

Every message of a sample carries the same header stamp, also used as log and publish time:
UTC time of day of the sample on 1970-01-01 (IO-VNBD logs carry no date).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..core.drive import Drive
from ..core.fileio import atomic_path, check_output_file
from ..core.units import G_MPS2
from .ros2_msgs import DEFINITIONS

TOPICS = {"imu": "/imu/data", "fix": "/gps/fix", "vel": "/gps/vel"}


def _header(stamp_ns: int, frame: str) -> dict:
    return {"stamp": {"sec": stamp_ns // 1_000_000_000, "nanosec": stamp_ns % 1_000_000_000}, "frame_id": frame}


def write_mcap(drive: Drive, path: Path, progress=None) -> int:
    """Write ``drive`` to ``path`` (atomically); returns the number of messages."""
    from mcap_ros2.writer import Writer

    check_output_file(Path(path))

    t_ns = np.rint((drive.start_time_of_day_s + drive.t_s) * 1e9).astype(np.int64)
    heading = np.deg2rad(drive.heading_deg)
    v_east, v_north = drive.speed_mps * np.sin(heading), drive.speed_mps * np.cos(heading)
    height = drive.columns.get("height_m", np.zeros(len(drive)))
    zeros9 = [0.0] * 9
    unknown_orientation = [-1.0] + [0.0] * 8
    count = 0
    with atomic_path(Path(path), suffix=".tmp.mcap") as tmp, open(tmp, "wb") as stream:
        writer = Writer(stream)
        schemas = {
            "imu": writer.register_msgdef("sensor_msgs/msg/Imu", DEFINITIONS["sensor_msgs/msg/Imu"]),
            "fix": writer.register_msgdef("sensor_msgs/msg/NavSatFix", DEFINITIONS["sensor_msgs/msg/NavSatFix"]),
            "vel": writer.register_msgdef("geometry_msgs/msg/TwistStamped", DEFINITIONS["geometry_msgs/msg/TwistStamped"]),
        }
        for i in range(len(drive)):  # one message per sample and topic
            stamp = int(t_ns[i])
            imu = {
                "header": _header(stamp, "base_link"),
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                "orientation_covariance": unknown_orientation,
                "angular_velocity": {"x": 0.0, "y": 0.0, "z": float(drive.yaw_rate_radps[i])},
                "angular_velocity_covariance": zeros9,
                "linear_acceleration": {"x": float(drive.accel_long_mps2[i]), "y": 0.0, "z": G_MPS2},
                "linear_acceleration_covariance": zeros9,
            }
            fix = {
                "header": _header(stamp, "gps"),
                "status": {"status": 0, "service": 1},
                "latitude": float(drive.lat_deg[i]),
                "longitude": float(drive.lon_deg[i]),
                "altitude": float(height[i]) if math.isfinite(height[i]) else 0.0,
                "position_covariance": zeros9,
                "position_covariance_type": 0,
            }
            vel = {
                "header": _header(stamp, "gps"),
                "twist": {"linear": {"x": float(v_east[i]), "y": float(v_north[i]), "z": 0.0},
                          "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
            }
            for key, msg in (("imu", imu), ("fix", fix), ("vel", vel)):
                writer.write_message(TOPICS[key], schemas[key], msg, log_time=stamp, publish_time=stamp)
                count += 1
            if progress and i % 1000 == 0:
                progress(i, len(drive))
        writer.finish()
    return count
