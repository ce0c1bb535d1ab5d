"""Writing a drive as a ROS 2 MCAP log (``ionav-viz convert``), readable by Foxglove and ``ros2 bag``.

Topics (``cdr`` encoding, standard schemas from :mod:`ionav_viz.ros2_msgs`):

* ``/imu/data`` ``sensor_msgs/msg/Imu``, frame ``base_link`` (REP 103: x forward, z up):
  ``linear_acceleration.x`` = longitudinal specific force (m/s^2), ``angular_velocity.z`` = yaw
  rate, counter-clockwise positive (rad/s); orientation unknown (``orientation_covariance[0] = -1``,
  REP 145). The other axes are the drive's full IMU (``accel_y_mps2``, ...) when it has one, else
  ``linear_acceleration.y`` its lateral acceleration (``accel_lat_mps2``, left positive: a drive
  whose lateral clearly reads right positive against speed x yaw rate is turned over, with a
  warning) and the rest those of a level IMU: ``linear_acceleration.z`` gravity's +9.80665 m/s^2,
  the others 0. Such a placeholder reads one value over the whole log, and the reader takes an
  axis that does as not measured (:mod:`.resample`): no mount is estimated from it.
* ``/gps/fix`` ``sensor_msgs/msg/NavSatFix``, frame ``gps``: latitude, longitude, altitude (m).
* ``/gps/vel`` ``geometry_msgs/msg/TwistStamped``, frame ``gps``: GNSS velocity as
  nmea_navsat_driver publishes it, ``linear.x`` east and ``linear.y`` north (m/s), from the GNSS
  speed and course.
* ``/wheel/odom`` ``nav_msgs/msg/Odometry``, frame ``odom``, child frame ``base_link``, when the
  drive has a vehicle speed (the caller gives it in m/s): ``twist.twist.linear.x`` (m/s); the pose
  is unknown (covariance -1 on the diagonal, as robot_localization reads "do not use").

Also carried: ``height_m`` as the fix's altitude, ``gnss_sigma_m`` as a diagonal
``position_covariance`` (type 2, sigma^2 on east, north and up), and samples without a fix
(``gnss_fix`` 0) as fixes with ``status.status = -1`` (no fix), which the reader drops. Other
columns are not carried; :func:`write_mcap` names them.

Every message of a sample carries the same header stamp, also used as log and publish time: the
source's own stamp (:meth:`~ionav_viz.core.drive.Drive.stamp_s`: UNIX time for message logs and
KITTI; for IO-VNBD, which carries no date, the UTC time of day on 1970-01-01).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.drive import IMU_COLUMNS, RECEIVER_COLUMNS, Drive
from ..core.errors import InputError
from ..core.fileio import atomic_path, check_output_file
from ..core.units import G_MPS2
from .cdr import encode_many
from .ros2_msgs import DEFINITIONS

log = logging.getLogger("ionav_viz")

#: Where a drive with a reference trajectory (:data:`~ionav_viz.core.drive.RECEIVER_COLUMNS`) has it
#: written: the receiver's fixes go on ``/gps/fix``, the reference on this NavSatFix topic
#: (read back with ``--truth-topic /truth/fix``).
TRUTH_TOPIC = "/truth/fix"
TOPICS = {"imu": "/imu/data", "fix": "/gps/fix", "vel": "/gps/vel", "odom": "/wheel/odom", "truth": TRUTH_TOPIC}
SCHEMAS = {"imu": "sensor_msgs/msg/Imu", "fix": "sensor_msgs/msg/NavSatFix", "vel": "geometry_msgs/msg/TwistStamped",
           "odom": "nav_msgs/msg/Odometry", "truth": "sensor_msgs/msg/NavSatFix"}
#: The drive's columns a log written here carries (``speed_can_mps`` and the wheel speeds: as the
#: vehicle speed the caller gives).
CARRIED = ("t_s", "lat_deg", "lon_deg", "speed_mps", "heading_deg", "accel_long_mps2", "yaw_rate_radps", "height_m",
           "gnss_sigma_m", "gnss_fix", "gnss_speed_fitted", "accel_lat_mps2", *IMU_COLUMNS, *RECEIVER_COLUMNS)
#: The lateral sign check looks at samples whose centripetal acceleration (speed x yaw rate) is above
#: this (m/s^2), needs this many of them, and turns the lateral over below minus this correlation.
LATERAL_CHECK_MPS2, LATERAL_CHECK_SAMPLES, LATERAL_CHECK_CORRELATION = 0.5, 50, 0.5


@dataclass(frozen=True)
class Written:
    """What :func:`write_mcap` wrote: messages, topics, and the drive's columns it could not carry."""

    messages: int
    topics: tuple[str, ...]
    left_out: tuple[str, ...]


def _messages(drive: Drive, keys: list[str], t_ns: np.ndarray, imu_axes: dict[str, np.ndarray], received: Drive,
              vehicle_speed_mps: np.ndarray | None) -> dict[str, np.ndarray]:
    """Every sample's message of each topic ``keys`` names, CDR-encoded: ``{key: (samples, bytes)}``."""
    n = len(drive)
    sec, nanosec = t_ns // 1_000_000_000, t_ns % 1_000_000_000

    def header(frame: str) -> list[tuple[str, object]]:
        return [("i4", sec), ("u4", nanosec), ("string", frame)]

    heading = np.deg2rad(received.heading_deg)
    height = drive.columns.get("height_m", np.zeros(n))
    sigma = drive.columns.get("gnss_sigma_m")
    covariance = np.zeros((n, 9))
    if sigma is not None:
        covariance[:, [0, 4, 8]] = np.asarray(sigma, dtype=float)[:, None] ** 2
    no_fix = drive.columns.get("gnss_fix", np.ones(n)) == 0
    ax, ay, az, gx, gy, gz = (imu_axes[c] for c in IMU_COLUMNS)
    zeros3, zeros9, zeros36 = np.zeros((1, 3)), np.zeros((1, 9)), np.zeros((1, 36))
    identity = np.array([[0.0, 0.0, 0.0, 1.0]])  # a quaternion (x, y, z, w)
    unknown_orientation = np.r_[-1.0, np.zeros(8)][None]
    fields = {
        "imu": [*header("base_link"), ("f8", identity), ("f8", unknown_orientation),
                ("f8", np.c_[gx, gy, gz]), ("f8", zeros9), ("f8", np.c_[ax, ay, az]), ("f8", zeros9)],
        "fix": [*header("gps"), ("i1", np.where(no_fix, -1, 0)), ("u2", 1), ("f8", received.lat_deg),
                ("f8", received.lon_deg), ("f8", np.where(np.isfinite(height), height, 0.0)), ("f8", covariance),
                ("u1", 0 if sigma is None else 2)],
        "vel": [*header("gps"), ("f8", np.c_[received.speed_mps * np.sin(heading),
                                             received.speed_mps * np.cos(heading), np.zeros(n)]), ("f8", zeros3)],
    }
    if "truth" in keys:
        fields["truth"] = [*header("truth"), ("i1", 0), ("u2", 1), ("f8", drive.lat_deg), ("f8", drive.lon_deg),
                           ("f8", 0.0), ("f8", zeros9), ("u1", 0)]
    if vehicle_speed_mps is not None:
        unknown_pose = np.array([[-1.0 if i % 7 == 0 else 0.0 for i in range(36)]])
        fields["odom"] = [*header("odom"), ("string", "base_link"), ("f8", zeros3), ("f8", identity),
                          ("f8", unknown_pose),
                          ("f8", np.c_[vehicle_speed_mps, np.zeros((n, 4)), drive.yaw_rate_radps]), ("f8", zeros36)]
    return {key: encode_many(fields[key], n) for key in keys}


def lateral_left(drive: Drive, path: Path | str = "") -> np.ndarray | None:
    """The drive's lateral acceleration (``accel_lat_mps2``) left positive (REP 103's y), or None.
    Sources disagree on its sign (IO-VNBD's is reported right positive): where the car turns, it
    must follow speed x yaw rate (counter-clockwise), and one that clearly opposes it is turned
    over, with a warning."""
    lateral = drive.columns.get("accel_lat_mps2")
    if lateral is None:
        return None
    centripetal = drive.speed_mps * drive.yaw_rate_radps
    turning = np.isfinite(centripetal) & np.isfinite(lateral) & (np.abs(centripetal) > LATERAL_CHECK_MPS2)
    if turning.sum() >= LATERAL_CHECK_SAMPLES and np.std(lateral[turning]) > 0:
        corr = float(np.corrcoef(lateral[turning], centripetal[turning])[0, 1])
        if corr < -LATERAL_CHECK_CORRELATION:
            log.warning("%s: the lateral acceleration reads right positive (correlation %+.2f with speed x yaw rate): "
                        "written left positive (REP 103's y)", path or drive.name, corr)
            return -lateral
    return lateral


def write_mcap(drive: Drive, path: Path, vehicle_speed_mps: np.ndarray | None = None,
               vehicle_speed_from: tuple[str, ...] = (), omit_gnss: np.ndarray | None = None) -> Written:
    """Write ``drive`` to ``path`` (atomically), with ``vehicle_speed_mps`` (per sample, or None)
    on ``/wheel/odom``; ``vehicle_speed_from``: the columns it stands for (carried through it).
    ``omit_gnss``: per sample, True where no ``/gps/fix`` and ``/gps/vel`` message is written (an outage).
    A drive with a reference trajectory has its receiver written on ``/gps/fix`` and ``/gps/vel``
    and the reference on :data:`TRUTH_TOPIC` (at every sample)."""
    from mcap.writer import CompressionType, Writer

    check_output_file(Path(path))
    n = len(drive)
    t_ns = np.rint(np.asarray(drive.stamp_s(drive.t_s)) * 1e9).astype(np.int64)
    if n and not (t_ns.min() // 1_000_000_000 >= -(2**31) and t_ns.max() // 1_000_000_000 < 2**31):
        raise InputError(f"{drive.name}: its time stamps ({float(drive.stamp_s(drive.t_s[0])):.0f} s to "
                         f"{float(drive.stamp_s(drive.t_s[-1])):.0f} s since 1970) do not fit ROS 2's int32 seconds "
                         "(1901-12-13 to 2038-01-19)", "a log of these dates cannot be written as ROS 2 messages",
                         param="drive")
    omit = np.zeros(n, dtype=bool) if omit_gnss is None else np.asarray(omit_gnss, dtype=bool)
    received = drive.as_received()  # the receiver's fixes, speed and course (the drive itself without a reference)
    # the full IMU when the drive has it, else a level IMU: gravity on z, nothing on the other axes
    imu_axes = {c: drive.columns.get(c, np.full(n, G_MPS2 if c == "accel_z_mps2" else 0.0)) for c in IMU_COLUMNS}
    imu_axes["accel_x_mps2"], imu_axes["gyro_z_radps"] = drive.accel_long_mps2, drive.yaw_rate_radps
    if "accel_y_mps2" not in drive.columns and (lateral := lateral_left(drive, path)) is not None:
        imu_axes["accel_y_mps2"] = lateral
    for axis, column in enumerate(IMU_COLUMNS):
        values = imu_axes[column]
        if not np.isfinite(values).all():  # the reader refuses it: the log would not read back
            k = int(np.flatnonzero(~np.isfinite(values))[0])
            field = f"{'linear_acceleration' if axis < 3 else 'angular_velocity'}.{'xyz'[axis % 3]}"
            raise InputError(f"{drive.name}: {field} at {float(drive.t_s[k]):.2f} s is not a finite number "
                             f"({float(values[k])})",
                             "fix the drive's IMU columns: a log with it would not read back", param="drive")
    # a speed fitted to the fixes is no receiver's velocity: written as one it would read back as measured
    keys = (["imu", "fix"] + ([] if drive.velocity_fitted else ["vel"])
            + (["odom"] if vehicle_speed_mps is not None else []) + (["truth"] if drive.has_reference else []))
    rows = _messages(drive, keys, t_ns, imu_axes, received, vehicle_speed_mps)
    count = 0
    with atomic_path(Path(path), suffix=".tmp.mcap") as tmp, open(tmp, "wb") as stream:
        writer = Writer(stream, chunk_size=1024 * 1024, compression=CompressionType.ZSTD, enable_crcs=True)
        writer.start(profile="ros2", library="ionav-viz")
        channels = {}
        for key in keys:
            schema = writer.register_schema(SCHEMAS[key], "ros2msg", DEFINITIONS[SCHEMAS[key]].encode())
            channels[key] = writer.register_channel(TOPICS[key], "cdr", schema)
        for i in range(n):  # one message per sample and topic, in time order
            stamp = int(t_ns[i])
            for key in keys:
                if omit[i] and key in ("fix", "vel"):
                    continue
                writer.add_message(channels[key], log_time=stamp, data=rows[key][i].tobytes(), publish_time=stamp)
                count += 1
        writer.finish()
    left_out = tuple(c for c in drive.columns if c not in CARRIED and c not in vehicle_speed_from)
    return Written(count, tuple(TOPICS[k] for k in keys), left_out)
