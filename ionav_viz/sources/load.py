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
class McapOptions:
    """How to read MCAP logs: topics (None: found by schema) and which time stamps to use."""

    imu_topic: str | None = None
    gnss_topic: str | None = None
    speed_topic: str | None = None
    stamps: str = "header"
    imu_axes: str | None = None  # e.g. "x=-y,y=x,z=z": body x is the log's -y (see sources.imu_frame)


def load_drive(spec: str, root: Path | None = None, yaw_sign: str = "auto", mcap: McapOptions | None = None,
               gnss_limits: GnssLimits | None = None) -> Drive:
    """Resolve ``spec`` (path, bundled scenario or run name) and read it into a :class:`Drive`.

    ``.csv`` files are IO-VNBD vehicle files; ``.mcap`` files are ROS 2 or JSON MCAP logs
    (``mcap`` options apply). ``yaw_sign`` applies to both (``auto``: the source's convention,
    checked against the GNSS course). Every source then gets the same GNSS quality checks
    (``gnss_limits``, see :mod:`ionav_viz.core.gnss_quality`).
    """
    path = resolve_drive(spec, root)
    suffix = path.suffix.lower()
    opts = mcap or McapOptions()
    if suffix == ".csv":
        from .iovnbd import read_iovnbd

        if opts.imu_axes:
            raise InputError(f"{path}: an IO-VNBD file has one accelerometer and one gyro axis; --imu-axes applies to MCAP logs",
                             "leave --imu-axes out (--yaw-sign still chooses the yaw-rate sign)", param="imu_axes")
        drive = read_iovnbd(path, yaw_sign=yaw_sign)
    elif suffix == ".mcap":
        from .mcap_reader import read_mcap

        drive = read_mcap(path, imu_topic=opts.imu_topic, gnss_topic=opts.gnss_topic, speed_topic=opts.speed_topic, stamps=opts.stamps,
                          imu_axes=opts.imu_axes, yaw_sign=yaw_sign)
    else:
        raise InputError(f"{path}: unsupported file type {suffix or '(none)'}", "ionav-viz reads IO-VNBD V-*.csv files and MCAP (.mcap) logs")
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
