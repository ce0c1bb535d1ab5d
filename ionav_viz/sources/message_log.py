"""Reading message logs (MCAP files, ROS 1 bags, ROS 2 bags) into a :class:`~ionav_viz.core.drive.Drive`.

This is the one layer every message-log format shares; a format only says what its channels are
and streams decoded messages (:class:`MessageLog`: :mod:`.mcap_reader`, :mod:`.rosbag_reader`).

Channels are found by message type (``--imu-topic``, ``--gnss-topic``, ``--gnss-velocity-topic``
and ``--vehicle-speed-topic`` choose when there are several or none match):

* IMU: ``sensor_msgs/msg/Imu`` (ROS 1 ``sensor_msgs/Imu``) or a JSON message with the same field
  names. REP 103 body frame: x forward, y left, z up. ``linear_acceleration.x`` is the
  longitudinal specific force (m/s^2) and ``angular_velocity.z`` the yaw rate, counter-clockwise
  positive (rad/s): both are already the drive model's conventions (``--imu-axes`` maps another
  mount, :mod:`.imu.axes` checks it). Messages marking their accelerations or rates "not
  provided" (REP 145: ``covariance[0] = -1``) are skipped.
* GNSS (ground truth): ``sensor_msgs/msg/NavSatFix`` (fixes with ``status.status < 0``, no fix,
  are dropped) or JSON ``foxglove.LocationFix`` (``timestamp``, ``latitude``, ``longitude``,
  ``altitude``). A known ``position_covariance`` (type > 0) gives the fix's horizontal standard
  deviation, ``gnss_sigma_m`` (the larger of east and north), which the GNSS quality checks use.
* GNSS velocity (optional): ``geometry_msgs/msg/TwistStamped`` in a world frame, as GNSS drivers
  publish it (nmea_navsat_driver's ``/vel``: ``linear.x`` east, ``linear.y`` north, m/s), gives
  the GNSS speed and course. Without it, speed and course come from the fixes
  (:func:`.gnss_fixes.fit_fixes`).
* Vehicle speed (optional): the vehicle's own speed, wheel or CAN odometry, as
  ``nav_msgs/msg/Odometry`` (``twist.twist.linear.x`` in the child body frame) or a
  ``TwistStamped`` whose ``frame_id`` is a body frame (``base_link``, ``base_footprint``, ``body``,
  ``vehicle``; ``linear.x``): the drive's ``speed_can_mps`` (magnitude: reversing is distance
  too), which odometry and the filter's speed updates use. Several candidates (wheel odometry
  beside robot_localization's fused ``/odometry/filtered``) use none, with a warning;
  ``--vehicle-speed-topic none`` leaves a log's vehicle speed out.
* Reference (optional, ``--truth-topic``): a trajectory to score against beside the receiver
  (post-processed GNSS/INS, RTK): a ``NavSatFix``, or an ``Odometry``/``PoseStamped``/
  ``PoseWithCovarianceStamped`` in a local world frame that ``--truth-origin`` places on the earth
  (:mod:`.reference`). It becomes the drive's positions, speed and course; the receiver's fixes
  stay the estimators' GNSS (:data:`~ionav_viz.core.drive.RECEIVER_COLUMNS`).
* Values: every value is checked against the physical limits of :mod:`.plausibility` (an
  impossible one is an error naming the topic and stamp). Fixes with ``status.status < 0`` or a
  non-finite position (how drivers say "no fix") are dropped with one warning; of fixes sharing a
  stamp (published twice, or stamped to whole seconds) the first is kept, with one warning.

Time stamps: the message **header stamp** (the sensor's acquisition time) by default, the log's
receive time (when the recorder got it, with transport latency and jitter) with
``stamps='log'``; a zero header stamp falls back to the log time. The time of day of the drive is
the UTC time of day of the first stamp.

Rates, gaps and memory: see :mod:`.resample` (one 10 Hz grid; IMU samples folded into per-bin
sums as they stream past, so memory grows with the output, not the log). Only the selected
topics are decoded. A format that reads in blocks (an MCAP chunk: :class:`Block`) hands over each
topic's messages of one fixed layout as columns, read by the same rules all at once; a block where
that is not so (a layout that varies, JSON, a value to refuse) is read message by message.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from ..core.grid import GRID_RATE_HZ
from .gnss_fixes import first_per_stamp
from .imu.axes import AXES
from .imu.character import ImuSettings
from .log_options import LogOptions
from .plausibility import first_implausible, implausible
from .reference import place_reference
from .resample import ImuBins, LogStreams, assemble_drive, drop_strays

log = logging.getLogger("ionav_viz")

IMU_SCHEMAS = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
GNSS_SCHEMAS = ("sensor_msgs/msg/NavSatFix", "sensor_msgs/NavSatFix", "foxglove.LocationFix",
                "foxglove_msgs/msg/LocationFix")
TWIST_SCHEMAS = ("geometry_msgs/msg/TwistStamped", "geometry_msgs/TwistStamped")
ODOMETRY_SCHEMAS = ("nav_msgs/msg/Odometry", "nav_msgs/Odometry")
SPEED_SCHEMAS = TWIST_SCHEMAS + ODOMETRY_SCHEMAS
POSE_SCHEMAS = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/PoseStamped",
                "geometry_msgs/msg/PoseWithCovarianceStamped", "geometry_msgs/PoseWithCovarianceStamped")
#: A reference trajectory: fixes, or poses in a local world frame placed by ``--truth-origin`` (:mod:`.reference`).
REFERENCE_SCHEMAS = GNSS_SCHEMAS[:2] + ODOMETRY_SCHEMAS + POSE_SCHEMAS
BODY_FRAMES = ("base_link", "base_footprint", "body", "vehicle")
#: ``vehicle_speed_topic`` that leaves a log's vehicle speed out (what the IMU alone achieves).
NO_TOPIC = "none"


@dataclass
class ChannelInfo:
    """One topic of a log (a channel in MCAP terms), with what ionav-viz would use it for."""

    topic: str
    schema: str  # the message type, e.g. sensor_msgs/msg/Imu
    encoding: str  # cdr, json, ros1
    count: int
    role: str = ""


@dataclass
class Selection:
    """The topics read: IMU, GNSS fixes, and optionally the receiver's velocity (GNSS speed and
    course) and the vehicle's own speed (wheel or CAN odometry)."""

    imu: ChannelInfo
    gnss: ChannelInfo
    gnss_velocity: ChannelInfo | None
    vehicle_speed: ChannelInfo | None
    channels: list[ChannelInfo] = field(default_factory=list)
    reference: ChannelInfo | None = None

    @property
    def chosen(self) -> list[ChannelInfo]:
        return [c for c in (self.imu, self.gnss, self.gnss_velocity, self.vehicle_speed, self.reference)
                if c is not None]


class MessageLog(Protocol):
    """What a log format gives the shared reader."""

    path: Path
    #: Message encodings the format can decode (a selected topic in another one is an error).
    encodings: tuple[str, ...]

    def channels(self) -> list[ChannelInfo]:
        """Every topic with its type, encoding and message count."""
        ...

    def messages(self, channels: list[ChannelInfo]) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log time ns since 1970, decoded message)`` for the given channels, streamed; decoding
        errors are :class:`InputError` naming the file and topic."""
        ...

    def damaged(self, exc: BaseException) -> InputError:
        """The one-line error for a failure of the format's library while reading."""
        ...


@dataclass(frozen=True)
class Columns:
    """The messages of one topic in a :class:`Block`, field by field."""

    log_ns: np.ndarray  # int64, each message's log time (ns since 1970)
    # field path ("header.stamp.sec") -> (n,) values, (n, k) for an array field, a string's text (the same in each)
    fields: dict[str, Any]


class Block(Protocol):
    """Consecutive messages of the chosen channels, in the order the log holds them (an MCAP chunk's)."""

    def first_topic(self) -> str | None:
        """The topic of the block's first message (None: the block has none)."""
        ...

    def columns(self, topic: str) -> Columns | None:
        """Every message of ``topic`` in the block as columns (none: zero rows), or None where they
        cannot be read so (a layout that varies, JSON, a schema only mcap_ros2 decodes)."""
        ...

    def messages(self) -> Iterator[tuple[str, int, Any]]:
        """The block's messages one by one, as :meth:`MessageLog.messages` gives them."""
        ...


@dataclass
class StreamBlock:
    """A format's messages as one block read one by one (a format without blocks, or a log read by streaming)."""

    stream: Iterator[tuple[str, int, Any]]

    def first_topic(self) -> str | None:
        return None

    def columns(self, topic: str) -> Columns | None:
        return None

    def messages(self) -> Iterator[tuple[str, int, Any]]:
        return self.stream


def _blocks(source: MessageLog, channels: list[ChannelInfo]) -> Iterator[Block]:
    """The chosen channels' messages in blocks: the format's own (``source.blocks``), else one stream."""
    blocks = getattr(source, "blocks", None)
    return blocks(channels) if blocks is not None else iter([StreamBlock(source.messages(channels))])


def _pick(channels: list[ChannelInfo], schemas: tuple[str, ...], topic: str | None, what: str, param: str,
          path: Path, required: bool) -> ChannelInfo | None:
    """The channel named ``topic``, else the one of ``schemas`` (``param``: the argument that names it)."""
    if topic is not None:
        found = [c for c in channels if c.topic == topic]
        if not found:
            raise InputError(f"{path}: no topic {topic!r}", f"topics: {', '.join(c.topic for c in channels) or 'none'}",
                             param=param)
        return found[0]
    found = [c for c in channels if c.schema in schemas]
    option = "--" + param.replace("_", "-")
    if len(found) > 1:
        hint = f"choose one with {option}"
        if param == "gnss_topic":  # one of them is often the reference
            hint = "name the receiver's with --gnss-topic, or the reference (truth) with --truth-topic"
        raise InputError(f"{path}: several {what} topics ({', '.join(c.topic for c in found)})", hint, param=param)
    if not found:
        if not required:
            return None
        listing = ", ".join(f"{c.topic} [{c.schema}]" for c in channels) or "none"
        raise InputError(f"{path}: no {what} topic ({schemas[0]}); topics: {listing}", f"choose one with {option}",
                         param=param)
    return found[0]


#: ROS packages whose message types ionav-viz knows: a topic of one of them named for a role whose
#: type it is not (``--imu-topic /gps/fix``) is a mistake; a vendor's own type is read by field names.
_STANDARD_PACKAGES = ("sensor_msgs", "geometry_msgs", "nav_msgs", "std_msgs", "foxglove", "foxglove_msgs", "tf2_msgs")


def _check_named(channel: ChannelInfo | None, channels: list[ChannelInfo], schemas: tuple[str, ...], what: str,
                 param: str, path: Path) -> None:
    """Refuse a topic named for ``what`` whose standard message type is another one."""
    if channel is None or channel.schema in schemas:
        return
    if channel.schema.split("/")[0].split(".")[0] not in _STANDARD_PACKAGES:
        return
    fitting = [c.topic for c in channels if c.schema in schemas]
    hint = f"{what} topics: {', '.join(fitting)}" if fitting else f"the log has no {what} topic ({schemas[0]})"
    raise InputError(f"{path}: {channel.topic} is a {channel.schema}, not {what} ({schemas[0]})", hint, param=param)


def select_channels(source: MessageLog, imu_topic: str | None = None, gnss_topic: str | None = None,
                    gnss_velocity_topic: str | None = None, vehicle_speed_topic: str | None = None,
                    channels: list[ChannelInfo] | None = None, truth_topic: str | None = None) -> Selection:
    """The topics to read, by message type or by the given topics (see the module docstring).

    A ``TwistStamped`` topic is GNSS velocity when its first message's frame is a world frame, and
    vehicle speed when it is a body frame (:data:`BODY_FRAMES`); an ``Odometry`` is vehicle speed.
    Several vehicle-speed topics (wheel odometry beside a fused ``/odometry/filtered``) use none,
    with a warning, unless one is named; ``vehicle_speed_topic="none"`` leaves it out, and
    ``gnss_velocity_topic="none"`` the receiver's velocity (speed and course then come from the fixes).
    """
    path = source.path
    channels = source.channels() if channels is None else channels
    if not channels:
        raise InputError(f"{path}: no topics (an empty recording)", "record IMU and GNSS topics")
    for c in channels:
        c.role = ""
    imu = _pick(channels, IMU_SCHEMAS, imu_topic, "IMU", "imu_topic", path, True)
    if imu_topic is not None:
        _check_named(imu, channels, IMU_SCHEMAS, "IMU", "imu_topic", path)
    reference = (_pick(channels, GNSS_SCHEMAS, truth_topic, "reference", "truth_topic", path, False)
                 if truth_topic else None)
    if reference is not None and reference.schema not in REFERENCE_SCHEMAS:
        raise InputError(f"{path}: the reference {reference.topic} is a {reference.schema}",
                         "give a NavSatFix, or an Odometry or PoseStamped in a local world frame (with its origin)",
                         param="truth_topic")
    gnss = _pick([c for c in channels if c is not reference], GNSS_SCHEMAS, gnss_topic, "GNSS", "gnss_topic", path,
                 True)
    if gnss_topic is not None:
        _check_named(gnss, channels, GNSS_SCHEMAS, "GNSS", "gnss_topic", path)
    if reference is not None and gnss is reference:
        raise InputError(f"{path}: {gnss.topic} cannot be both the receiver and the reference",
                         "name the receiver's own topic", param="truth_topic")
    named = {t for t in (gnss_velocity_topic, vehicle_speed_topic, truth_topic) if t not in (None, NO_TOPIC)}
    body_twists = {c.topic for c in channels if c.schema in TWIST_SCHEMAS and c.count and _in_body_frame(source, c)}
    world_twists = [c for c in channels if c.schema in TWIST_SCHEMAS and c.topic not in body_twists and
                    c.topic not in named]
    if gnss_velocity_topic == NO_TOPIC:  # speed and course from the fixes (a receiver's velocity not to be trusted)
        velocity = None
    elif gnss_velocity_topic is not None:
        velocity = _pick(channels, TWIST_SCHEMAS, gnss_velocity_topic, "GNSS velocity", "gnss_velocity_topic", path,
                         False)
        _check_named(velocity, channels, TWIST_SCHEMAS, "GNSS velocity", "gnss_velocity_topic", path)
        if velocity is not None and velocity.topic in body_twists:
            raise InputError(f"{path}: {velocity.topic} is in a body frame: the vehicle's speed, not the "
                             "receiver's velocity",
                             f"give {velocity.topic} as the vehicle speed topic instead", param="gnss_velocity_topic")
    else:
        velocity = _pick(world_twists, TWIST_SCHEMAS, None, "GNSS velocity", "gnss_velocity_topic", path, False)
    if vehicle_speed_topic == NO_TOPIC:
        vehicle = None
    elif vehicle_speed_topic is not None:
        vehicle = _pick(channels, SPEED_SCHEMAS, vehicle_speed_topic, "vehicle speed", "vehicle_speed_topic", path,
                        False)
        if vehicle is not None and vehicle.schema not in SPEED_SCHEMAS:
            raise InputError(f"{path}: {vehicle.topic} is a {vehicle.schema}, not a vehicle speed",
                             "give a nav_msgs/Odometry or a TwistStamped in a body frame", param="vehicle_speed_topic")
    else:
        found = [c for c in channels if (c.schema in ODOMETRY_SCHEMAS or c.topic in body_twists) and c.count and
                 c.topic not in named]
        vehicle = found[0] if len(found) == 1 else None
        if len(found) > 1:
            log.warning("%s: several vehicle speed topics (%s); none is used: choose one with --vehicle-speed-topic",
                        path, ", ".join(c.topic for c in found))
    for role, ch in (("IMU", imu), ("GNSS", gnss), ("GNSS velocity", velocity), ("vehicle speed", vehicle),
                     ("reference (truth)", reference)):
        if ch is None:
            continue
        ch.role = role
        if ch.encoding not in source.encodings:
            raise InputError(f"{path}: {role} topic {ch.topic} has message encoding {ch.encoding!r}",
                             f"ionav-viz reads {' and '.join(source.encodings)} messages from this format")
        if ch.count == 0:
            raise InputError(f"{path}: {role} topic {ch.topic} has no messages", "record some, or choose another topic")
    return Selection(imu, gnss, velocity, vehicle, channels, reference)


def _in_body_frame(source: MessageLog, channel: ChannelInfo) -> bool:
    """Whether a TwistStamped topic's first message is in a body frame (:data:`BODY_FRAMES`)."""
    messages = source.messages([channel])
    try:
        _, _, msg = next(messages)
        return _frame_id(msg) in BODY_FRAMES
    except (StopIteration, KeyError, AttributeError, TypeError):
        return False
    finally:
        messages.close()


def _frame_id(msg: Any) -> str:
    return str(get_field(msg, "header", "frame_id")).strip("/").lower()


@dataclass
class LogDescription:
    """What a log holds and what ionav-viz would read from it (``ionav-viz info``)."""

    channels: list[ChannelInfo]
    problem: str | None  # why the log cannot be read as is (no IMU topic, ...), else None

    @property
    def used(self) -> dict[str, str]:
        """topic -> role (IMU, GNSS, GNSS velocity, vehicle speed) of the topics that would be read."""
        return {c.topic: c.role for c in self.channels if c.role}


def describe_log(source: MessageLog, imu_topic: str | None = None, gnss_topic: str | None = None,
                 gnss_velocity_topic: str | None = None, vehicle_speed_topic: str | None = None,
                 truth_topic: str | None = None) -> LogDescription:
    """Every topic of the log, with the roles the reader would give them (or why it cannot)."""
    channels = source.channels()
    try:
        select_channels(source, imu_topic, gnss_topic, gnss_velocity_topic, vehicle_speed_topic, channels=channels,
                        truth_topic=truth_topic)
        problem = None
    except InputError as exc:
        for c in channels:
            c.role = ""
        problem = str(exc)
    return LogDescription(channels, problem)


def get_field(obj: Any, *names: str) -> Any:
    """``obj.a.b`` (or ``obj["a"]["b"]`` for a JSON message) for ``names`` ``("a", "b")``."""
    for name in names:
        obj = obj[name] if isinstance(obj, dict) else getattr(obj, name)
    return obj


def _not_provided(msg: Any) -> str | None:
    """The IMU field a ``sensor_msgs/Imu`` message marks "not provided" (REP 145: the first element
    of its covariance is -1), linear acceleration before angular velocity; None if all are there."""
    for name in ("linear_acceleration", "angular_velocity"):
        try:
            cov = get_field(msg, f"{name}_covariance")
            if len(cov) and float(cov[0]) == -1.0:
                return name.replace("_", " ")
        except (KeyError, AttributeError, TypeError, ValueError, IndexError):
            continue
    return None


def stamp_ns(stamp: Any) -> int:
    """A ROS time stamp (ROS 2 ``sec``/``nanosec``, ROS 1 ``sec``/``nsec``) as nanoseconds since 1970."""
    sec = get_field(stamp, "sec")
    try:
        nsec = get_field(stamp, "nanosec")
    except (KeyError, AttributeError):
        nsec = get_field(stamp, "nsec")
    return int(sec) * 1_000_000_000 + int(nsec)


def decode_json(path: Path, topic: str, data: bytes, log_time_ns: int) -> Any:
    """A JSON message, or an error naming the topic and log time."""
    try:
        return json.loads(data)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: topic {topic}: message at log time {log_time_ns} is not valid "
                         f"JSON ({exc})") from None
    except RecursionError:  # brackets nested thousands deep (a message is bounded in size by its chunk)
        raise InputError(f"{path}: topic {topic}: message at log time {log_time_ns} nests too deep to be a "
                         "sensor message",
                         "the log is damaged or crafted; record it again") from None
    except ValueError as exc:  # an integer of over 4300 digits
        raise InputError(f"{path}: topic {topic}: message at log time {log_time_ns} is not usable JSON "
                         f"({str(exc)[:80]})") from None


def read_log(source: MessageLog, options: LogOptions | None = None, *, name: str | None = None,
             yaw_sign: str = "auto") -> Drive:
    """Read a message log into a drive on a 10 Hz grid (see the module docstring).

    ``options`` (:class:`~.load.LogOptions`; default: every topic found by message type, header
    stamps) chooses the topics and stamps; its ``imu_axes`` maps the log's IMU axes to the body
    frame (``"x=-y,y=x,z=z"``, see :mod:`.imu.axes`); its ``imu_mount`` (``"auto"``,
    ``"roll=..,pitch=..,yaw=.."`` or ``"quat=w,x,y,z"``, see :mod:`.imu.mount`) turns them further,
    after the axes; its ``truth_topic`` names a reference trajectory, the drive's truth (NavSatFix,
    or Odometry/PoseStamped in a local frame placed by ``truth_origin``: ``"auto"`` or
    ``"LAT,LON[,YAW]"``, see :mod:`.reference`). ``yaw_sign`` ``"cw"`` says the yaw axis turns
    clockwise positive, ``"ccw"`` (REP 103) that it does not, ``"auto"`` assumes REP 103 and checks
    it against the GNSS course.
    """
    opts = options if options is not None else LogOptions()
    path = source.path
    if yaw_sign not in ("auto", "cw", "ccw"):
        raise InputError(f"yaw sign {yaw_sign!r} is not auto, cw or ccw", param="yaw_sign")
    mapping, mount, origin = opts.parsed.axes, opts.parsed.mount, opts.parsed.origin
    sel = select_channels(source, opts.imu_topic, opts.gnss_topic, opts.gnss_velocity_topic, opts.vehicle_speed_topic,
                          truth_topic=opts.truth_topic)
    if sel.reference is not None and sel.reference.schema not in GNSS_SCHEMAS and origin is None:
        place_reference(np.zeros((0, 3)), None, np.zeros((0, 3)),
                        f"{path}: reference {sel.reference.topic} ({sel.reference.schema})")
    got = _Messages(path, sel, opts.stamps, mapping)
    got.read(source)
    got.warn_skipped()
    if len(got.gnss) < 2:
        without = f" ({got.dropped_no_fix} message(s) without a fix)" if got.dropped_no_fix else ""
        raise InputError(f"{path}: fewer than 2 GNSS fixes on {sel.gnss.topic}{without}",
                         "the drive needs GNSS ground truth")
    if got.dropped_no_fix:
        log.warning("%s: dropped %d GNSS message(s) without a fix", path, got.dropped_no_fix)
    origin_s = float(got.origin_ns // 1_000_000_000)
    fixes = first_per_stamp(path, np.asarray(got.gnss))
    fixes = fixes[drop_strays(path, "GNSS", fixes[:, 0], origin_s=origin_s)]
    speeds, vehicle_speeds = (_in_stamp_order(path, what, samples, origin_s)
                              for what, samples in (("GNSS velocity", got.speed), ("vehicle speed", got.vehicle)))
    truth = _truth(got, origin, fixes, origin_s)
    streams = LogStreams(got.imu, fixes, speeds, origin_s=origin_s, vehicle_speed=vehicle_speeds, reference=truth)
    settings = ImuSettings(mapping, yaw_sign, mount, opts.parsed.time_offset_s, opts.parsed.samples)
    return assemble_drive(path, name or _default_name(path), streams, settings)


class _Messages:
    """A log's messages read into samples per role (stamps in seconds after the first stamp's whole
    second: float64 seconds since 1970 would round them to 0.24 us, and a drive's samples would no
    longer fall on its grid), each value checked for plausibility as it is read."""

    def __init__(self, path: Path, sel: Selection, stamps: str, mapping: np.ndarray) -> None:
        self.path, self.sel, self.stamps, self.mapping = path, sel, stamps, mapping
        self.gnss: list[tuple[float, float, float, float, float]] = []  # t, lat, lon, altitude, sigma (nan: unknown)
        self.speed: list[tuple[float, float, float]] = []  # GNSS velocity: t, speed m/s, course deg
        self.vehicle: list[tuple[float, float]] = []  # vehicle speed: t, m/s
        # the reference trajectory: t, lat, lon (or x, y m in a local frame)
        self.reference: list[tuple[float, float, float]] = []
        self.reference_frame: list[str] = []  # a local reference's frame_id
        self.dropped_no_fix = 0
        self.not_provided: dict[str, int] = {}  # IMU messages marking a field "not provided" (REP 145), per field
        self.last_t: dict[str, float] = {}  # per role, the previous message's stamp
        self.backwards: dict[str, list] = {}  # per role: [count, first stamp, the stamp before it]
        self.origin_ns: int | None = None
        self.imu = ImuBins(1.0 / GRID_RATE_HZ, keep_samples=sel.imu.count == sel.gnss.count, prepare=self._to_body)

    def read(self, source: MessageLog) -> None:
        """Every message of the chosen channels, each by its role's reader."""
        sel = self.sel
        roles = {c.topic: c.role for c in sel.chosen}
        local_reference = sel.reference is not None and sel.reference.schema not in GNSS_SCHEMAS
        readers = {"IMU": self._imu, "GNSS": self._gnss, "GNSS velocity": self._gnss_velocity,
                   "reference (truth)": self._local_reference if local_reference else self._reference_fix}
        try:
            for block in _blocks(source, sel.chosen):
                if self._read_columns(block, roles):
                    continue
                for topic, log_ns, msg in block.messages():
                    role = roles[topic]
                    try:
                        readers.get(role, self._vehicle_speed)(topic, log_ns, msg)
                    except (KeyError, AttributeError, TypeError, ValueError) as exc:
                        raise InputError(f"{self.path}: topic {topic}: message lacks a field "
                                         f"({type(exc).__name__}: {exc})",
                                         f"expected the {role} field names of "
                                         f"{({'IMU': IMU_SCHEMAS, 'GNSS': GNSS_SCHEMAS}.get(role, SPEED_SCHEMAS))[0]}"
                                         ) from None
        except InputError:
            raise
        except Exception as exc:
            raise source.damaged(exc) from None

    def _read_columns(self, block: Block, roles: dict[str, str]) -> bool:
        """Read a block's messages topic by topic as columns, with the same result as reading them
        one by one; False (nothing read) where a topic's messages are not columns, lack a field,
        or hold a value that is refused (then the messages are read one by one, which refuses it)."""
        columns = {}
        for topic in roles:
            if (found := block.columns(topic)) is None:
                return False
            columns[topic] = found
        first = block.first_topic()
        if first is None:
            return True
        readers = {"IMU": self._imu_columns, "GNSS": self._gnss_columns, "GNSS velocity": self._velocity_columns,
                   "reference (truth)": self._reference_columns, "vehicle speed": self._vehicle_columns}
        origin_ns = self.origin_ns
        try:
            if origin_ns is None:
                first_ns = int(self._stamps_ns(columns[first])[0])
                origin_ns = first_ns - first_ns % 1_000_000_000
            commits = [readers[role](topic, columns[topic], origin_ns) for topic, role in roles.items()
                       if len(columns[topic].log_ns)]
        except (KeyError, IndexError, TypeError, ValueError):  # another type's fields or shapes: read one by one
            return False
        if any(commit is None for commit in commits):
            return False
        self.origin_ns = origin_ns
        for commit in commits:
            commit()
        return True

    def _stamps_ns(self, c: Columns) -> np.ndarray:
        """Each message's stamp (ns since 1970) as :meth:`_when` takes it: the header stamp, the log
        time where that is zero (or with ``stamps='log'``)."""
        if self.stamps == "log":
            return c.log_ns
        ns = c.fields["header.stamp.sec"].astype(np.int64) * 1_000_000_000 + c.fields["header.stamp.nanosec"]
        return np.where(ns > 0, ns, c.log_ns)

    def _seconds_many(self, c: Columns, origin_ns: int) -> np.ndarray:
        return (self._stamps_ns(c) - origin_ns).astype(float) * 1e-9

    def _plausible(self, *checks: tuple[str, np.ndarray]) -> bool:
        return all(first_implausible(column, values) is None for column, values in checks)

    def _in_order_many(self, role: str, t: np.ndarray) -> None:
        """:meth:`_in_order` of each stamp ``t`` in turn."""
        if not len(t):
            return
        before = np.concatenate([[self.last_t.get(role, -math.inf)], t[:-1]])
        backwards = t < before
        if backwards.any():
            i = int(np.argmax(backwards))
            seen = self.backwards.setdefault(role, [0, float(t[i]), float(before[i])])
            seen[0] += int(backwards.sum())
        self.last_t[role] = float(t[-1])

    def _imu_columns(self, topic: str, c: Columns, origin_ns: int):
        """:meth:`_imu` of every message in ``c``: a function that adds them."""
        t = self._seconds_many(c, origin_ns)
        linear = c.fields["linear_acceleration_covariance"][:, 0] == -1.0
        angular = ~linear & (c.fields["angular_velocity_covariance"][:, 0] == -1.0)
        keep = ~(linear | angular)
        samples = np.column_stack([t, *(c.fields[f"linear_acceleration.{a}"] for a in AXES),
                                   *(c.fields[f"angular_velocity.{a}"] for a in AXES)]).astype(float)[keep]

        def commit() -> None:
            for name, skipped in (("linear acceleration", linear), ("angular velocity", angular)):
                if skipped.any():
                    self.not_provided[name] = self.not_provided.get(name, 0) + int(skipped.sum())
            self._in_order_many("IMU", samples[:, 0])
            self.imu.add_many(samples)
        return commit

    def _gnss_columns(self, topic: str, c: Columns, origin_ns: int):
        """:meth:`_gnss` of every message in ``c`` (a NavSatFix): a function that adds them, or
        None when one of them would be refused."""
        if self.sel.gnss.schema not in GNSS_SCHEMAS[:2]:
            return None
        t = self._seconds_many(c, origin_ns)
        lat, lon = c.fields["latitude"].astype(float), c.fields["longitude"].astype(float)
        keep = (c.fields["status.status"] >= 0) & np.isfinite(lat) & np.isfinite(lon)
        if not self._plausible(("lat_deg", lat[keep]), ("lon_deg", lon[keep])):
            return None
        covariance = c.fields["position_covariance"].astype(float)
        variance = np.where(covariance[:, 4] > covariance[:, 0], covariance[:, 4], covariance[:, 0])
        known = (c.fields["position_covariance_type"] != 0) & np.isfinite(variance) & (variance >= 0)
        sigma = np.where(known, np.sqrt(np.where(known, variance, 0.0)), math.nan)
        rows = np.column_stack([t, lat, lon, c.fields["altitude"].astype(float), sigma])[keep]

        def commit() -> None:
            self.dropped_no_fix += int((~keep).sum())
            self._in_order_many("GNSS", rows[:, 0])
            self.gnss.extend(map(tuple, rows.tolist()))
        return commit

    def _reference_columns(self, topic: str, c: Columns, origin_ns: int):
        """:meth:`_reference_fix` (or :meth:`_local_reference`) of every message in ``c``: a function
        that adds them, or None when one would be refused."""
        schema = self.sel.reference.schema
        t = self._seconds_many(c, origin_ns)
        if schema not in GNSS_SCHEMAS:
            pose = "pose" if schema in POSE_SCHEMAS[:2] else "pose.pose"
            x, y = (c.fields[f"{pose}.position.{a}"].astype(float) for a in "xy")
            frame = str(c.fields["header.frame_id"]).strip("/").lower()

            def commit_local() -> None:
                if not self.reference_frame:
                    self.reference_frame.append(frame)
                self._in_order_many("reference (truth)", t)
                self.reference.extend(zip(t.tolist(), x.tolist(), y.tolist()))
            return commit_local
        if schema not in GNSS_SCHEMAS[:2]:
            return None
        lat, lon = c.fields["latitude"].astype(float), c.fields["longitude"].astype(float)
        keep = (c.fields["status.status"] >= 0) & np.isfinite(lat) & np.isfinite(lon)
        if not self._plausible(("lat_deg", lat[keep]), ("lon_deg", lon[keep])):
            return None
        rows = np.column_stack([t, lat, lon])[keep]

        def commit() -> None:
            self._in_order_many("reference (truth)", rows[:, 0])
            self.reference.extend(map(tuple, rows.tolist()))
        return commit

    def _velocity_columns(self, topic: str, c: Columns, origin_ns: int):
        """:meth:`_gnss_velocity` of every message in ``c`` (a TwistStamped): a function that adds
        them, or None when one would be refused."""
        if self.sel.gnss_velocity.schema not in TWIST_SCHEMAS:
            return None
        t = self._seconds_many(c, origin_ns).tolist()
        east, north = (c.fields[f"twist.linear.{a}"].astype(float).tolist() for a in "xy")
        # math's functions, as one message at a time: numpy's may round the last bit otherwise
        rows = [(ti, math.hypot(e, n), math.degrees(math.atan2(e, n)) % 360.0) for ti, e, n in zip(t, east, north)]
        if not self._plausible(("speed_mps", np.array([r[1] for r in rows]))):
            return None

        def commit() -> None:
            self._in_order_many("GNSS velocity", np.array(t))
            self.speed.extend(rows)
        return commit

    def _vehicle_columns(self, topic: str, c: Columns, origin_ns: int):
        """:meth:`_vehicle_speed` of every message in ``c``: a function that adds them, or None when
        one would be refused."""
        schema = self.sel.vehicle_speed.schema
        if schema not in SPEED_SCHEMAS:
            return None
        t = self._seconds_many(c, origin_ns)
        v = np.abs(c.fields["twist.twist.linear.x" if schema in ODOMETRY_SCHEMAS else "twist.linear.x"].astype(float))
        if not self._plausible(("speed_can_mps", v)):
            return None

        def commit() -> None:
            self._in_order_many("vehicle speed", t)
            self.vehicle.extend(zip(t.tolist(), v.tolist()))
        return commit

    def warn_skipped(self) -> None:
        """Say which IMU messages were skipped ('not provided') and which came out of stamp order;
        refuse an IMU topic whose every message was skipped."""
        if self.not_provided:
            fields = " and ".join(f"{name} ({n} message(s))" for name, n in sorted(self.not_provided.items()))
            if "IMU" not in self.last_t:
                raise InputError(f"{self.path}: topic {self.sel.imu.topic} marks its {fields} 'not provided' (REP 145: "
                                 "covariance[0] = -1)",
                                 "ionav-viz needs accelerations and turn rates: choose the IMU's raw topic (e.g. "
                                 "/imu/data_raw)", param="imu_topic")
            log.warning("%s: topic %s: skipped the messages marking their %s 'not provided' (REP 145: "
                        "covariance[0] = -1)",
                        self.path, self.sel.imu.topic, fields)
        topic_of = {c.role: c.topic for c in self.sel.chosen}
        # in the selection's order (IMU, GNSS, ...), not the order found: the same read one by one or as columns
        for role in sorted(self.backwards, key=list(topic_of).index):
            n, first, before = self.backwards[role]
            log.warning("%s: topic %s: %d message(s) stamped earlier than the one received before them (first %.3f s "
                        "after %.3f s); used in stamp order", self.path, topic_of[role], n, self.absolute_s(first),
                        self.absolute_s(before))

    def _in_order(self, role: str, t: float) -> None:
        """Count messages stamped before the one received before them (used in stamp order)."""
        if t < self.last_t.get(role, -math.inf):
            seen = self.backwards.setdefault(role, [0, t, self.last_t[role]])
            seen[0] += 1
        self.last_t[role] = t

    def _seconds(self, ns: int) -> float:
        if self.origin_ns is None:
            self.origin_ns = ns - ns % 1_000_000_000
        return (ns - self.origin_ns) * 1e-9

    def _when(self, msg: Any, log_ns: int, *stamp_path: str) -> float:
        if self.stamps == "log":
            return self._seconds(log_ns)
        try:
            ns = stamp_ns(get_field(msg, *stamp_path))
        except (KeyError, AttributeError, TypeError, ValueError, OverflowError):
            return self._seconds(log_ns)
        return self._seconds(ns) if ns > 0 else self._seconds(log_ns)

    def absolute_s(self, t: float) -> float:
        """A stamp as seconds since 1970."""
        return t + (self.origin_ns // 1_000_000_000 if self.origin_ns is not None else 0)

    def _check(self, topic: str, t: float, field_name: str, column: str, value: float) -> None:
        reason = implausible(column, value)
        if reason:
            raise InputError(f"{self.path}: topic {topic}, message stamped {self.absolute_s(t):.3f} s: "
                             f"{field_name} {reason}",
                             "no car sensor produces that value: fix the log or choose another topic")

    def _to_body(self, data: np.ndarray) -> np.ndarray:
        """A block of IMU samples as the log has them -> checked, in the body frame."""
        if (bad := _first_implausible_imu(data)) is not None:
            i, k = bad
            self._check(self.sel.imu.topic, float(data[i, 0]), _IMU_FIELDS[k - 1], _IMU_COLUMNS[k - 1],
                        float(data[i, k]))
        return _imu_to_body(data, self.mapping)

    def _imu(self, topic: str, log_ns: int, msg: Any) -> None:
        t = self._when(msg, log_ns, "header", "stamp")
        if missing := _not_provided(msg):
            self.not_provided[missing] = self.not_provided.get(missing, 0) + 1
            return
        self._in_order("IMU", t)
        lin, ang = get_field(msg, "linear_acceleration"), get_field(msg, "angular_velocity")
        self.imu.add((t, *(float(get_field(lin, a)) for a in AXES), *(float(get_field(ang, a)) for a in AXES)))

    def _gnss(self, topic: str, log_ns: int, msg: Any) -> None:
        if self.sel.gnss.schema.startswith("foxglove"):
            t = self._when(msg, log_ns, "timestamp")
        else:
            t = self._when(msg, log_ns, "header", "stamp")
            if int(get_field(msg, "status", "status")) < 0:
                self.dropped_no_fix += 1
                return
        lat, lon = float(get_field(msg, "latitude")), float(get_field(msg, "longitude"))
        if not (math.isfinite(lat) and math.isfinite(lon)):
            self.dropped_no_fix += 1  # drivers publish NaN positions when they have no fix
            return
        self._check(self.sel.gnss.topic, t, "latitude", "lat_deg", lat)
        self._check(self.sel.gnss.topic, t, "longitude", "lon_deg", lon)
        alt = msg.get("altitude", 0.0) if isinstance(msg, dict) else getattr(msg, "altitude", 0.0)
        self._in_order("GNSS", t)
        self.gnss.append((t, lat, lon, float(alt if alt is not None else math.nan), _horizontal_sigma_m(msg)))

    def _local_reference(self, topic: str, log_ns: int, msg: Any) -> None:
        t = self._when(msg, log_ns, "header", "stamp")
        pose = (get_field(msg, "pose", "pose")
                if self.sel.reference.schema not in POSE_SCHEMAS[:2] else get_field(msg, "pose"))
        position = get_field(pose, "position")
        if not self.reference_frame:
            self.reference_frame.append(_frame_id(msg))
        self._in_order("reference (truth)", t)
        self.reference.append((t, float(get_field(position, "x")), float(get_field(position, "y"))))

    def _reference_fix(self, topic: str, log_ns: int, msg: Any) -> None:
        t = self._when(msg, log_ns, "header", "stamp")
        lat, lon = float(get_field(msg, "latitude")), float(get_field(msg, "longitude"))
        if int(get_field(msg, "status", "status")) < 0 or not (math.isfinite(lat) and math.isfinite(lon)):
            return
        self._check(topic, t, "latitude", "lat_deg", lat)
        self._check(topic, t, "longitude", "lon_deg", lon)
        self._in_order("reference (truth)", t)
        self.reference.append((t, lat, lon))

    def _gnss_velocity(self, topic: str, log_ns: int, msg: Any) -> None:
        t = self._when(msg, log_ns, "header", "stamp")
        lin = get_field(msg, "twist", "linear")
        v_east, v_north = float(get_field(lin, "x")), float(get_field(lin, "y"))  # as nmea_navsat_driver publishes it
        sample = (t, math.hypot(v_east, v_north), math.degrees(math.atan2(v_east, v_north)) % 360.0)
        self._check(topic, t, "speed", "speed_mps", sample[1])
        self._in_order("GNSS velocity", t)
        self.speed.append(sample)

    def _vehicle_speed(self, topic: str, log_ns: int, msg: Any) -> None:
        t = self._when(msg, log_ns, "header", "stamp")
        twist = (get_field(msg, "twist", "twist")
                 if self.sel.vehicle_speed.schema in ODOMETRY_SCHEMAS else get_field(msg, "twist"))
        v = abs(float(get_field(twist, "linear", "x")))  # body-frame forward speed; reversing counts as distance
        self._check(topic, t, "linear.x", "speed_can_mps", v)
        self._in_order("vehicle speed", t)
        self.vehicle.append((t, v))


def _truth(got: _Messages, origin: Any, fixes: np.ndarray, origin_s: float) -> np.ndarray | None:
    """The reference trajectory read, in stamp order and on the earth (a local one placed by
    ``origin``), or None without a reference topic."""
    path, sel = got.path, got.sel
    if sel.reference is not None:
        truth = _in_stamp_order(path, "reference", got.reference, origin_s)
        if truth is None or len(truth) < 2:
            raise InputError(f"{path}: fewer than 2 positions on the reference {sel.reference.topic}",
                             "choose another reference topic", param="truth_topic")
        truth = truth[np.concatenate([[True], np.diff(truth[:, 0]) > 0])]
        if sel.reference.schema not in GNSS_SCHEMAS:
            where = f"{path}: reference {sel.reference.topic} (frame {got.reference_frame[0] or 'unnamed'!r})"
            truth, how = place_reference(truth, origin, fixes, where)
            log.warning("%s: %s", where, how)
        elif origin is not None:  # was silently ignored
            log.warning("%s: the truth origin is ignored: the reference %s is %s, in latitude and longitude already",
                        path, sel.reference.topic, sel.reference.schema)
        return truth
    if origin is not None:
        raise InputError(f"{path}: a truth origin places a reference in a local frame, and no truth topic is given",
                         "name the reference topic, or leave the origin out", param="truth_origin")
    return None


def _in_stamp_order(path: Path, what: str, samples: list, origin_s: float) -> np.ndarray | None:
    """Samples ``(t, ...)`` sorted by stamp without strays, or None when there are none."""
    if not samples:
        return None
    data = np.asarray(samples, dtype=float)
    data = data[np.argsort(data[:, 0], kind="stable")]
    return data[drop_strays(path, what, data[:, 0], origin_s=origin_s)]


def _default_name(path: Path) -> str:
    """A drive's name from its log: the file's stem, or the bag folder's name for its metadata.yaml."""
    return path.parent.name if path.name == "metadata.yaml" else path.stem


def _horizontal_sigma_m(msg: Any) -> float:
    """Horizontal standard deviation (m) from a fix's ``position_covariance`` (ENU, m^2), the
    larger of east and north; NaN when the type says unknown (0) or the field is missing."""
    get = msg.get if isinstance(msg, dict) else (lambda name, default=None: getattr(msg, name, default))
    kind, cov = get("position_covariance_type", 0), get("position_covariance", None)
    try:
        if not kind or cov is None or len(cov) < 5:
            return math.nan
        var = max(float(cov[0]), float(cov[4]))
    except (TypeError, ValueError):
        return math.nan
    return math.sqrt(var) if math.isfinite(var) and var >= 0 else math.nan


#: The IMU sample columns after the stamp, as the log names them and the limits that apply to them
#: (every accelerometer axis has the longitudinal one's, every gyro axis the yaw rate's).
_IMU_FIELDS = tuple(f"linear_acceleration.{a}" for a in AXES) + tuple(f"angular_velocity.{a}" for a in AXES)
_IMU_COLUMNS = ("accel_long_mps2",) * 3 + ("yaw_rate_radps",) * 3


def _first_implausible_imu(data: np.ndarray) -> tuple[int, int] | None:
    """(row, column) of the first implausible value in a block of IMU samples (columns 1-6), in
    the order a message is checked (accelerometer then gyro, x then y then z), or None."""
    order = (1, 4, 2, 5, 3, 6)
    firsts = [(i, n, k) for n, k in enumerate(order)
              if (i := first_implausible(_IMU_COLUMNS[k - 1], data[:, k])) is not None]
    if not firsts:
        return None
    row, _, column = min(firsts)
    return row, column


def _imu_to_body(data: np.ndarray, mapping: np.ndarray) -> np.ndarray:
    """``(t, accel xyz, gyro xyz)`` in the log's axes -> the body frame (``body = mapping @ log``)."""
    out = data.copy()
    out[:, 1:4] = data[:, 1:4] @ mapping.T
    out[:, 4:7] = data[:, 4:7] @ mapping.T
    return out
