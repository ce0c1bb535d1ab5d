"""Loading a drive from whatever the user names: one entry point over all readers."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from ..core.drive import Drive
from ..core.errors import InputError
from ..core.gnss_quality import GnssLimits, assess_gnss, count_by_fault
from .resolve import resolve_drive

log = logging.getLogger("ionav_viz")


@dataclass(frozen=True)
class LogOptions:
    """How to read message logs (MCAP, ROS 1 and ROS 2 bags): topics (None: found by message
    type), which time stamps to use and the IMU's axes."""

    imu_topic: str | None = None
    gnss_topic: str | None = None
    speed_topic: str | None = None
    stamps: str = "header"
    imu_axes: str | None = None  # e.g. "x=-y,y=x,z=z": body x is the log's -y (see sources.imu_frame)


#: The earlier name of :class:`LogOptions`, from when MCAP was the only message log.
McapOptions = LogOptions

_SUPPORTED = ("ionav-viz reads IO-VNBD V-*.csv files, MCAP (.mcap) logs, ROS 1 .bag files, ROS 2 bag folders "
              "(or their metadata.yaml / .db3) and KITTI raw drive folders")


def source_kind(path: Path) -> str:
    """Which reader a path needs (``iovnbd``, ``mcap``, ``ros1``, ``ros2`` or ``kitti``), or an error
    saying what it is not."""
    from .kitti import oxts_folder
    from .rosbag_reader import is_ros1_bag, missing_metadata

    suffix = path.suffix.lower()
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return "ros2"
        if oxts_folder(path) is not None:
            return "kitti"
        if (error := missing_metadata(path)) is not None:
            raise error
        raise InputError(f"{path}: neither a ROS 2 bag folder (no metadata.yaml) nor a KITTI raw drive (no oxts/)", _SUPPORTED)
    if suffix == ".csv":
        return "iovnbd"
    if suffix == ".mcap":
        return "mcap"
    if is_ros1_bag(path):
        return "ros1"
    if path.name == "metadata.yaml" or suffix == ".db3":
        return "ros2"
    raise InputError(f"{path}: unsupported file type {suffix or '(none)'}", _SUPPORTED)


def open_message_log(path: Path, kind: str | None = None):
    """The :class:`~.message_log.MessageLog` of an MCAP file or a ROS bag, else None (``kind``:
    the path's :func:`source_kind`, when known)."""
    kind = kind or source_kind(path)
    if kind == "mcap":
        from .mcap_reader import McapLog

        return McapLog(path)
    if kind in ("ros1", "ros2"):
        from .rosbag_reader import RosbagLog

        return RosbagLog(path)
    return None


def read_source(path: Path, yaw_sign: str = "auto", options: LogOptions | None = None) -> Drive:
    """Read a path into a drive with the reader its kind needs (no GNSS quality marked yet)."""
    opts = options or LogOptions()
    kind = source_kind(path)
    if kind in ("iovnbd", "kitti") and opts.imu_axes:
        what = "an IO-VNBD file has one accelerometer and one gyro axis" if kind == "iovnbd" else "KITTI's OXTS gives its inertial data in the vehicle frame"
        raise InputError(f"{path}: {what}; --imu-axes applies to MCAP logs and ROS bags",
                         "leave --imu-axes out (--yaw-sign still chooses the yaw-rate sign)", param="imu_axes")
    if kind == "iovnbd":
        from .iovnbd import read_iovnbd

        return read_iovnbd(path, yaw_sign=yaw_sign)
    if kind == "kitti":
        from .kitti import read_kitti

        return read_kitti(path, yaw_sign=yaw_sign)
    from .message_log import read_log

    return read_log(open_message_log(path, kind), imu_topic=opts.imu_topic, gnss_topic=opts.gnss_topic, speed_topic=opts.speed_topic,
                    stamps=opts.stamps, imu_axes=opts.imu_axes, yaw_sign=yaw_sign)


def load_drive(spec: str, root: Path | None = None, yaw_sign: str = "auto", mcap: LogOptions | None = None,
               gnss_limits: GnssLimits | None = None) -> Drive:
    """Resolve ``spec`` (path, bundled scenario or run name) and read it into a :class:`Drive`.

    ``.csv`` files are IO-VNBD vehicle files; ``.mcap`` files, ROS 1 ``.bag`` files and ROS 2 bag
    folders are message logs (``mcap``: the :class:`LogOptions` that apply to all of them); a
    folder with ``oxts/`` is a KITTI raw drive. ``yaw_sign`` applies to all (``auto``: the
    source's convention, checked against the GNSS course). Every source then gets the same GNSS
    quality checks (``gnss_limits``, see :mod:`ionav_viz.core.gnss_quality`).
    """
    path = resolve_drive(spec, root)
    drive = read_source(path, yaw_sign, mcap)
    check_rate(drive, path)
    mark_gnss_quality(drive, gnss_limits or GnssLimits())
    return drive


def mark_gnss_quality(drive: Drive, limits: GnssLimits) -> None:
    """Set ``drive.gnss_fault`` from the GNSS quality checks and say once what was found."""
    cols = drive.columns
    drive.gnss_fault = assess_gnss(drive.t_s, drive.lat_deg, drive.lon_deg, drive.speed_mps, cols.get("n_satellites"),
                                   cols.get("gnss_sigma_m"), cols.get("speed_can_mps"), limits,
                                   has_fix=cols.get("gnss_fix"), accel_mps2=drive.accel_long_mps2)
    bad = ~drive.gnss_ok
    if bad.any():
        reasons = ", ".join(f"{name} {n}" for name, n in count_by_fault(drive.gnss_fault).items())
        log.warning(
            "%s: %d of %d GNSS samples are not trustworthy truth (%s); windows touching them are not scored",
            drive.source, int(bad.sum()), len(drive), reasons)


#: Slowest sample rate a drive may have (Hz): the estimators work on 1 s windows of 10 Hz samples,
#: so a slower log cannot be put on that grid without inventing most of it.
MIN_RATE_HZ = 2.0


def check_rate(drive: Drive, path: Path) -> Drive:
    """Refuse a drive sampled too slowly for the 10 Hz grid (with the real reason, not 'too short')."""
    import numpy as np

    if len(drive) > 1:
        dt = float(np.median(np.diff(drive.t_s)))
        if dt > 1.0 / MIN_RATE_HZ:
            raise InputError(f"{path}: samples are {dt:.2f} s apart ({1 / dt:.2g} Hz); ionav-viz needs at least {MIN_RATE_HZ:g} Hz",
                             "the estimators use 1 s windows of 10 Hz samples: use the log's full-rate file")
    return drive
