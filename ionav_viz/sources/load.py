"""Loading a drive from whatever the user names: one entry point over all readers."""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..core.drive import Drive, measured_imu
from ..core.durations import Span, parse_span
from ..core.errors import InputError
from ..core.gnss_lag import speed_lag_of
from ..core.gnss_quality import GnssFault, GnssLimits, ReceiverQuality, assess_gnss, count_by_fault
from ..core.grid import stamp_tolerance_s
from ..core.timing import stage
from .log_options import LogOptions
from .resolve import data_root, resolve_drive, warn_if_not_published

log = logging.getLogger("ionav_viz")


@dataclass(frozen=True)
class ReadOptions:
    """How drives are found and read, the same for every command and API function.

    Attributes:
        data_root: where run names are looked up (default ``$IONAV_DATA``, else the per-user data
            directory ``fetch`` fills).
        yaw_sign: sign of the yaw rate (the CSV column, a log's gyro z): ``"auto"`` (the source's
            convention, checked against the GNSS course), ``"cw"`` or ``"ccw"``.
        log: topics, stamps and IMU axes of message logs (MCAP, ROS bags).
        gnss_limits: thresholds of the GNSS quality checks that mark untrustworthy fixes.
        span: only this stretch of each drive, on the drive's own time (``"0s:330s"``, ``"330s:"``,
            a ``(start_s, end_s)`` pair or a :class:`~ionav_viz.core.durations.Span`; default the
            whole drive): the samples outside it are dropped as the drive is read, so outages,
            training windows, biases and filters see nothing else; times keep the drive's clock.
    """

    data_root: str | Path | None = None
    yaw_sign: str = "auto"
    log: LogOptions = field(default_factory=LogOptions)
    gnss_limits: GnssLimits = field(default_factory=GnssLimits)
    span: Span | str | tuple | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "span", parse_span(self.span))  # checked, and one type, before any work
        if self.yaw_sign not in ("auto", "cw", "ccw"):
            raise InputError(f"yaw sign {self.yaw_sign!r} is not auto, cw or ccw", "choose auto, cw or ccw",
                             param="yaw_sign")
        # the log options' text (stamps, axes, mount, clock offset, samples, origin) was checked, and
        # parsed, when the LogOptions was made (sources/log_options.py)

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
        drives = sorted({p.suffix.lower() for p in path.iterdir() if p.suffix.lower() in (".csv", ".mcap", ".bag") and
                         p.is_file()})
        if drives:  # a folder of drives: each is one drive
            globs = " ".join(f"{path}/*{suffix}" for suffix in drives)
            raise InputError(f"{path}: a folder of drives, not one drive (a ROS 2 bag folder or a KITTI raw drive)",
                             f"give the drives themselves: {globs}")
        raise InputError(f"{path}: neither a ROS 2 bag folder (no metadata.yaml) nor a KITTI raw drive (no oxts/)",
                         _SUPPORTED)
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


#: The options of message logs alone (command-line name, LogOptions field): their topics, and how
#: their IMU is read (axes, mount, clock, sample kind). ``stamps`` has a default: it counts when it is
#: not that (:func:`_log_only_options_given`).
_LOG_ONLY_OPTIONS = (("--imu-topic", "imu_topic"), ("--gnss-topic", "gnss_topic"),
                     ("--gnss-velocity-topic", "gnss_velocity_topic"), ("--vehicle-speed-topic", "vehicle_speed_topic"),
                     ("--truth-topic", "truth_topic"), ("--truth-origin", "truth_origin"), ("--imu-axes", "imu_axes"),
                     ("--imu-mount", "imu_mount"), ("--imu-time-offset", "imu_time_offset"),
                     ("--imu-samples", "imu_samples"))


def _log_only_options_given(opts: LogOptions) -> list[str]:
    """The message-log options ``opts`` sets, by their command-line names."""
    named = [o for o, v in _LOG_ONLY_OPTIONS if getattr(opts, v) is not None]
    return named + (["--stamps"] if opts.stamps != LogOptions.stamps else [])


def read_source(path: Path, yaw_sign: str = "auto", options: LogOptions | None = None) -> Drive:
    """Read a path into a drive with the reader its kind needs (no GNSS quality marked yet)."""
    opts = options or LogOptions()
    kind = source_kind(path)
    if kind in ("iovnbd", "kitti") and (named := _log_only_options_given(opts)):
        # an option of message logs only: ignored for this drive (a fleet may mix them), said once
        what = "IO-VNBD CSV" if kind == "iovnbd" else "KITTI raw"
        log.warning("%s %s to message logs (MCAP, ROS bags) only: ignored for %s drives", ", ".join(named),
                    "applies" if len(named) == 1 else "apply", what)
    if kind == "iovnbd":
        from .iovnbd import read_iovnbd

        return read_iovnbd(path, yaw_sign=yaw_sign)
    if kind == "kitti":
        from .kitti import read_kitti

        return read_kitti(path, yaw_sign=yaw_sign)
    from .message_log import read_log

    return read_log(open_message_log(path, kind), opts, yaw_sign=yaw_sign)


def load_drive(spec: Drive | str | Path, read: ReadOptions | None = None, *, mcap: LogOptions | None = None) -> Drive:
    """Read a drive: a path (IO-VNBD ``V-*.csv``, ``.mcap``, ROS 1 ``.bag``, a ROS 2 bag folder or
    its ``metadata.yaml``, a KITTI raw drive folder), a bundled scenario name (``"roundabout"``,
    ``"stationary"``) or an IO-VNBD run name (``"V-Vw8"``) under ``read.data_root``. A
    :class:`Drive` is returned as it is.

    Every source gets the same GNSS quality checks (``read.gnss_limits``, see
    :mod:`ionav_viz.core.gnss_quality`). ``mcap``: the earlier name of ``read.log``, deprecated.
    """
    read = with_deprecated_log(read, mcap)
    if isinstance(spec, Drive):
        return spec if read.span is None else crop_to_span(spec, read.span)
    with stage(f"read {spec}") as s:
        path = resolve_drive(str(spec), data_root(read.data_root))
        warn_if_not_published(str(spec), path)
        drive = read_source(path, read.yaw_sign, read.log)
        check_rate(drive, path)
        # on the whole drive: a span's first fixes are judged as in the whole
        mark_gnss_quality(drive, read.gnss_limits)
        mark_speed_lag(drive)  # on the whole drive too
        if read.span is not None:
            drive = crop_to_span(drive, read.span)
        s.detail = f"{drive.name}, {len(drive)} samples, {drive.duration_s:.1f} s"
    return drive


def load_drives(specs, read: ReadOptions | None = None) -> list[Drive]:
    """:func:`load_drive` of each of ``specs``, a warning they repeat (an option that applies to
    other drives' formats) printed once."""
    from ..core.warnings_log import printing_once

    with printing_once():
        return [load_drive(spec, read) for spec in specs]


def crop_to_span(drive: Drive, span: Span) -> Drive:
    """The samples of ``drive`` inside ``span`` (both ends included, a sample stamped within
    :func:`~ionav_viz.core.grid.stamp_tolerance_s` of an end on it: IO-VNBD's 100 s sample may be
    stamped 99.999 s), on the drive's own clock: the first kept sample's ``t_s`` stays what it was
    (a span of a span is the same span), and in its local frame (``Drive.frame_origin_deg``).
    Fewer than two samples inside is an :class:`InputError` naming the drive and its length."""
    keep = span.contains(drive.t_s, stamp_tolerance_s(drive.rate_hz))
    if int(keep.sum()) < 2:
        length = f"{drive.t_s[0]:g}-{drive.t_s[-1]:g} s" if len(drive) else "empty"
        raise InputError(f"{drive.source or drive.name}: span {span} holds no samples of this drive ({length})",
                         "give a span inside the drive's own time", param="span")
    end_s = float(drive.t_s[-1])
    # a span's last sample may be a step short
    if span.end_s is not None and span.end_s > end_s + max(1.0, 1.0 / drive.rate_hz):
        log.warning("%s: span %s runs past the drive's end (its samples end at %g s): %s is read",
                    drive.source or drive.name, span, end_s,
                    Span(span.start_s, end_s) if end_s > span.start_s else span)
    if keep.all():
        return drive
    return Drive(drive.name, drive.source, drive.rate_hz, drive.start_time_of_day_s,
                 {k: v[keep] for k, v in drive.columns.items()}, gnss_fault=drive.gnss_fault[keep],
                 receiver_fault=None if drive.receiver_fault is None else drive.receiver_fault[keep],
                 start_stamp_s=drive.start_stamp_s, imu=drive.imu, frame_origin_deg=drive.local_origin_deg)


def with_deprecated_log(read: ReadOptions | None, mcap: LogOptions | None) -> ReadOptions:
    """``read`` (default :class:`ReadOptions`), with the deprecated ``mcap=`` keyword as its ``log``."""
    if read is not None and not isinstance(read, ReadOptions):  # read="x" was an AttributeError naming no argument
        raise InputError(f"read={read!r} is not a ReadOptions", "give read=iv.ReadOptions(...), or leave it out",
                         param="read")
    read = read if read is not None else ReadOptions()
    if mcap is None:
        return read
    warnings.warn("mcap= is deprecated: pass read=ReadOptions(log=LogOptions(...))", DeprecationWarning, stacklevel=3)
    return replace(read, log=mcap)


def mark_gnss_quality(drive: Drive, limits: GnssLimits) -> None:
    """Set ``drive.gnss_fault`` from the GNSS quality checks and say once what was found."""
    cols = drive.columns
    received = drive.as_received()  # the receiver's own fixes, sigma and gaps
    said = ReceiverQuality(cols.get("n_satellites"), cols.get("gnss_sigma_m"), cols.get("gnss_fix"))
    receiver_fault = assess_gnss(drive.t_s, received.lat_deg, received.lon_deg, received.speed_mps, said,
                                 cols.get("speed_can_mps"), limits, accel_mps2=drive.accel_long_mps2)
    if drive.has_reference:  # the truth is the reference: its own continuity checks only
        # beside a reference the fixes are only the filters' input, weighted by their reported
        # sigma: a phone's 8 m fixes still aid them (they are never scored against)
        receiver_fault = receiver_fault & np.uint16(~GnssFault.POOR_ACCURACY & 0xFFFF)
        drive.receiver_fault = receiver_fault
        drive.gnss_fault = assess_gnss(drive.t_s, drive.lat_deg, drive.lon_deg, drive.speed_mps, limits=limits,
                                       accel_mps2=drive.accel_long_mps2)
        bad_input = receiver_fault != 0
        if bad_input.any():
            log.warning("%s: the receiver's GNSS is not trustworthy in %s; the filters do not use it there",
                        drive.source, _time_share(drive, receiver_fault))
    else:
        drive.gnss_fault = receiver_fault
    if not drive.gnss_ok.all():
        log.warning("%s: no trustworthy GNSS truth in %s; windows touching it are not scored", drive.source,
                    _time_share(drive, drive.gnss_fault))


def _time_share(drive: Drive, fault: np.ndarray) -> str:
    """``'88.5 of 108.0 s (no-fix 60.2 s, poor-accuracy 30.1 s)'``: how long ``fault`` marks, in
    seconds of the drive's samples (a log's fixes come at 1-10 Hz, its samples at the IMU's grid:
    counted in samples, 885 of 1080 read as ten times the 109 fixes)."""
    dt_s = 1.0 / drive.rate_hz
    reasons = ", ".join(f"{name} {n * dt_s:.1f} s" for name, n in count_by_fault(fault).items())
    return f"{np.count_nonzero(fault) * dt_s:.1f} of {len(drive) * dt_s:.1f} s ({reasons})"


def mark_speed_lag(drive: Drive) -> None:
    """Keep in ``drive.imu`` how late the receiver's speed is against the IMU
    (:mod:`ionav_viz.core.gnss_lag`), and say it where it is large enough to weigh."""
    if drive.imu is None or measured_imu(drive) is None:
        return
    lag = speed_lag_of(drive.as_received())
    drive.imu = replace(drive.imu, speed_lag_s=lag.lag_s if lag.resolved else 0.0, speed_lag_used=lag.used,
                        speed_lag_note=lag.describe())
    if lag.used:
        log.warning("%s: the receiver's speed is %.2f s behind the IMU's acceleration (correlation %.2f): a "
                    "location service's smoothing; gins weighs the receiver's velocity for it", drive.source, lag.lag_s,
                    lag.peak)


#: Slowest sample rate a drive may have (Hz): the estimators work on 1 s windows of 10 Hz samples,
#: so a slower log cannot be put on that grid without inventing most of it.
MIN_RATE_HZ = 2.0


def check_rate(drive: Drive, path: Path) -> Drive:
    """Refuse a drive sampled too slowly for the 10 Hz grid (with the real reason, not 'too short')."""
    import numpy as np

    if len(drive) > 1:
        dt = float(np.median(np.diff(drive.t_s)))
        if dt > 1.0 / MIN_RATE_HZ:
            raise InputError(f"{path}: samples are {dt:.2f} s apart ({1 / dt:.2g} Hz); ionav-viz needs at least "
                             f"{MIN_RATE_HZ:g} Hz",
                             "the estimators use 1 s windows of 10 Hz samples: use the log's full-rate file")
    return drive
