"""Reading MCAP logs (ROS 2 ``cdr`` or JSON messages) into a :class:`~ionav_viz.drive.Drive`.

Channels are found by schema name (``--imu-topic`` / ``--gnss-topic`` / ``--speed-topic`` choose
when there are several or none match):

* IMU: ``sensor_msgs/msg/Imu`` (cdr) or a JSON message with the same field names. REP 103 body
  frame: x forward, y left, z up. ``linear_acceleration.x`` is the longitudinal specific force
  (m/s^2) and ``angular_velocity.z`` the yaw rate, counter-clockwise positive (rad/s): both are
  already the drive model's conventions.
* GNSS (ground truth): ``sensor_msgs/msg/NavSatFix`` (fixes with ``status.status < 0``, no fix,
  are dropped) or JSON ``foxglove.LocationFix`` (``timestamp``, ``latitude``, ``longitude``,
  ``altitude``). A known ``position_covariance`` (type > 0) gives the fix's horizontal standard
  deviation, ``gnss_sigma_m`` (the larger of east and north), which the GNSS quality checks use.
* Speed and course (optional): ``geometry_msgs/msg/TwistStamped`` in a world frame is GNSS
  velocity as GNSS drivers publish it (nmea_navsat_driver's ``/vel``: ``linear.x`` east,
  ``linear.y`` north, m/s), giving speed and course; a TwistStamped whose ``frame_id`` is a body
  frame (``base_link``, ``base_footprint``, ``body``, ``vehicle``) and ``nav_msgs/msg/Odometry``
  (twist in the child body frame) give the speed ``linear.x`` only. Without them, speed and
  course come from the GNSS fixes by a local parabola fitted over at least 2 s of track
  (:func:`fit_fixes`), never by dividing by the time between two fixes, and the positions are
  that fit's (smoothed: a 1-second window's displacement would otherwise carry the fixes' white
  noise twice); the course is held below 2 m/s (1 m/s for a receiver's own course).
* Values: every value is checked against the physical limits of :mod:`.plausibility` (an
  impossible one is an error naming the topic and stamp). Fixes with ``status.status < 0`` or a
  non-finite position (how drivers say "no fix") are dropped with one warning; of fixes sharing a
  stamp (published twice, or stamped to whole seconds) the first is kept, with one warning.

Time stamps: the message **header stamp** (the sensor's acquisition time) by default, the MCAP
log time (when the recorder received it, with transport latency and jitter) with
``stamps='log'``; a zero header stamp falls back to the log time. The time of day of the drive
is the UTC time of day of the first stamp. Stamps more than an hour away from the rest of their
topic (a boot-time stamp among UNIX stamps, a clock not yet synchronised) are dropped with one
warning, so they cannot stretch the drive.

Rates: sensors at different rates (IMU at 50-400 Hz, GNSS at 1-20 Hz) are resampled onto one
10 Hz grid: IMU samples are averaged per bin of 0.1 s centred on each grid time, GNSS positions
(and speeds) linearly interpolated. Grid times without IMU samples are left out (a gap, which
the windows bridge when short and split at when long); grid times with IMU samples inside a GNSS
gap (longer than 1 s and than 1.5 of the receiver's usual interval between fixes: a tunnel) are
kept with ``gnss_fix`` 0, so the GNSS quality marks them no-fix: never scored, but the inertial
data through the gap is there for ``replay --on gnss-outage``. A log whose IMU and GNSS stamps are the same (as ``ionav-viz convert`` writes
them) is kept at its own stamps, so converting a CSV and reading it back changes nothing.

Memory: messages are streamed; IMU samples are folded into per-bin sums as they arrive, so memory
grows with the output columns (and the GNSS fixes), not with the file.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from ..core.grid import GRID_RATE_HZ, hold_course_when_slow
from ..core.units import wrap_360
from .imu_frame import AXES, YAW_REVERSED, check_imu_frame, parse_imu_axes
from .plausibility import first_implausible, implausible

log = logging.getLogger("ionav_viz")

IMU_SCHEMAS = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
GNSS_SCHEMAS = ("sensor_msgs/msg/NavSatFix", "sensor_msgs/NavSatFix", "foxglove.LocationFix", "foxglove_msgs/msg/LocationFix")
SPEED_SCHEMAS = ("geometry_msgs/msg/TwistStamped", "geometry_msgs/TwistStamped", "nav_msgs/msg/Odometry", "nav_msgs/Odometry")
BODY_FRAMES = ("base_link", "base_footprint", "body", "vehicle")
ENCODINGS = ("cdr", "json")
RATE_HZ = GRID_RATE_HZ
MAX_GNSS_GAP_S = 1.0


@dataclass
class ChannelInfo:
    """One channel of an MCAP file, with what ionav-viz would use it for."""

    topic: str
    schema: str
    encoding: str
    count: int
    role: str = ""


@dataclass
class Selection:
    imu: ChannelInfo
    gnss: ChannelInfo
    speed: ChannelInfo | None
    channels: list[ChannelInfo] = field(default_factory=list)


def _open_reader(stream):
    from mcap.reader import make_reader

    return make_reader(stream, validate_crcs=True)


def _bad(path: Path, exc: BaseException) -> InputError:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    name = type(exc).__name__
    if "crc" in text.lower() or "CRC" in name:
        what = f"CRC mismatch, the file is corrupted ({text})"
    elif name in ("EndOfFile", "InvalidMagic") or "magic" in text.lower() or "end of file" in text.lower():
        what = f"truncated or not an MCAP file ({name}: {text})"
    else:
        what = f"damaged MCAP file ({name}: {text})"
    return InputError(f"{path}: {what}", "re-record or repair it (e.g. 'mcap recover')")


MAGIC = b"\x89MCAP0\r\n"


def _check_framing(path: Path) -> str:
    """``"complete"`` (magic at both ends) or ``"unterminated"`` (no footer, but the file ends at a
    record boundary: a recorder that stopped without closing the file; readable by streaming).
    Empty, foreign files and files cut off inside a record are refused with that reason."""
    size = path.stat().st_size
    if size == 0:
        raise InputError(f"{path}: empty file", "not an MCAP recording")
    with open(path, "rb") as f:
        head = f.read(len(MAGIC))
        f.seek(max(0, size - len(MAGIC)))
        tail = f.read(len(MAGIC))
    if head != MAGIC:
        raise InputError(f"{path}: not an MCAP file (no MCAP magic at the start)", "ionav-viz reads .mcap logs and IO-VNBD .csv files")
    if tail == MAGIC and size >= 2 * len(MAGIC):
        return "complete"
    end = _last_record_end(path, size)
    if end == size and end > len(MAGIC):
        return "unterminated"
    raise InputError(f"{path}: truncated MCAP file (cut off inside a record, at byte {end} of {size})",
                     "repair it with 'mcap recover', then replay the result")


def _last_record_end(path: Path, size: int) -> int:
    """Where the last complete top-level record ends (records: 1-byte opcode, uint64 length, payload)."""
    pos = len(MAGIC)
    with open(path, "rb") as f:
        while pos + 9 <= size:
            f.seek(pos)
            header = f.read(9)
            nxt = pos + 9 + int.from_bytes(header[1:9], "little")
            if nxt > size:
                break
            pos = nxt
    return pos


def list_channels(path: Path) -> list[ChannelInfo]:
    """Every channel with its schema, encoding and message count: from the summary, or, when the
    file has no footer, no summary or no statistics, by reading it through once (one warning)."""
    path = Path(path)
    framing = _check_framing(path)
    summary = None
    if framing == "complete":
        try:
            with open(path, "rb") as f:
                summary = _open_reader(f).get_summary()
        except InputError:
            raise
        except Exception as exc:
            raise _bad(path, exc) from None
    if summary is not None and summary.statistics is not None:
        counts = summary.statistics.channel_message_counts
        out = []
        for cid, ch in sorted(summary.channels.items()):
            schema = summary.schemas.get(ch.schema_id)
            out.append(ChannelInfo(ch.topic, schema.name if schema else "", ch.message_encoding, int(counts.get(cid, 0))))
        return out
    why = {"unterminated": "no footer (the recorder stopped without closing the file)"}.get(
        framing, "no summary section" if summary is None else "no message statistics")
    log.warning("%s: %s; reading it by streaming (slower)", path, why)
    return _scan_channels(path, framing)


def _scan_channels(path: Path, framing: str) -> list[ChannelInfo]:
    """Channels and message counts by streaming through every record (CRCs checked)."""
    from mcap.exceptions import EndOfFile
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    schemas: dict[int, str] = {}
    channels: dict[int, Any] = {}
    counts: dict[int, int] = {}
    try:
        with open(path, "rb") as f:
            try:
                for record in StreamReader(f, skip_magic=False, validate_crcs=True).records:
                    if isinstance(record, Message):
                        counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
                    elif isinstance(record, Channel):
                        channels[record.id] = record
                    elif isinstance(record, Schema):
                        schemas[record.id] = record.name
            except EndOfFile:
                if framing != "unterminated":
                    raise
    except InputError:
        raise
    except Exception as exc:
        raise _bad(path, exc) from None
    return [ChannelInfo(ch.topic, schemas.get(ch.schema_id, ""), ch.message_encoding, counts.get(cid, 0))
            for cid, ch in sorted(channels.items())]


def _pick(channels: list[ChannelInfo], schemas: tuple[str, ...], topic: str | None, what: str, option: str,
          path: Path, required: bool) -> ChannelInfo | None:
    if topic is not None:
        found = [c for c in channels if c.topic == topic]
        if not found:
            raise InputError(f"{path}: no topic {topic!r}", f"topics: {', '.join(c.topic for c in channels) or 'none'}")
        return found[0]
    found = [c for c in channels if c.schema in schemas]
    if len(found) > 1:
        raise InputError(f"{path}: several {what} topics ({', '.join(c.topic for c in found)})", f"choose one with {option}")
    if not found:
        if not required:
            return None
        listing = ", ".join(f"{c.topic} [{c.schema}]" for c in channels) or "none"
        raise InputError(f"{path}: no {what} channel ({schemas[0]}); channels: {listing}", f"choose one with {option}")
    return found[0]


def select_channels(path: Path, imu_topic: str | None = None, gnss_topic: str | None = None,
                    speed_topic: str | None = None) -> Selection:
    """The IMU, GNSS and (optional) speed channels to read, by schema or by the given topics."""
    channels = list_channels(path)
    if not channels:
        raise InputError(f"{path}: no channels (an empty recording)", "record IMU and GNSS topics")
    imu = _pick(channels, IMU_SCHEMAS, imu_topic, "IMU", "--imu-topic", path, True)
    gnss = _pick(channels, GNSS_SCHEMAS, gnss_topic, "GNSS", "--gnss-topic", path, True)
    speed = _pick(channels, SPEED_SCHEMAS, speed_topic, "speed", "--speed-topic", path, False)
    for role, ch in (("IMU", imu), ("GNSS", gnss), ("speed", speed)):
        if ch is None:
            continue
        ch.role = role
        if ch.encoding not in ENCODINGS:
            raise InputError(f"{path}: {role} topic {ch.topic} has message encoding {ch.encoding!r}", "ionav-viz reads cdr (ROS 2) and json messages")
        if ch.count == 0:
            raise InputError(f"{path}: {role} topic {ch.topic} has no messages", "record some, or choose another topic")
    return Selection(imu, gnss, speed, channels)


def _get(obj: Any, *names: str) -> Any:
    for name in names:
        obj = obj[name] if isinstance(obj, dict) else getattr(obj, name)
    return obj


def _stamp_s(stamp: Any) -> float:
    sec = _get(stamp, "sec")
    try:
        nsec = _get(stamp, "nanosec")
    except (KeyError, AttributeError):
        nsec = _get(stamp, "nsec")
    return float(sec) + float(nsec) * 1e-9


def _messages(path: Path, sel: Selection) -> Iterator[tuple[str, float, Any]]:
    """(role, log time s, decoded message) for the selected topics, streamed."""
    from mcap_ros2.decoder import DecoderFactory

    roles = {c.topic: c.role for c in (sel.imu, sel.gnss, sel.speed) if c is not None}
    factory = DecoderFactory()
    decoders: dict[int, Any] = {}
    with open(path, "rb") as f:
        for schema, channel, message in _iter_messages(path, f, list(roles)):
            if channel.message_encoding == "json":
                try:
                    decoded = json.loads(message.data)
                except (json.JSONDecodeError, UnicodeDecodeError) as exc:
                    raise InputError(f"{path}: topic {channel.topic}: message at log time {message.log_time} is not valid JSON ({exc})") from None
            else:
                if channel.id not in decoders:
                    decoder = factory.decoder_for(channel.message_encoding, schema)
                    if decoder is None:
                        raise InputError(f"{path}: topic {channel.topic}: cannot decode {channel.message_encoding} with schema encoding {schema.encoding if schema else None!r}")
                    decoders[channel.id] = decoder
                decoded = decoders[channel.id](message.data)
            yield roles[channel.topic], message.log_time * 1e-9, decoded


def _iter_messages(path: Path, f: Any, topics: list[str]) -> Iterator[tuple[Any, Any, Any]]:
    """The file's messages on ``topics``: indexed when it can be, else streamed (a file without a
    footer ends at its last complete record)."""
    from mcap.exceptions import EndOfFile
    from mcap.reader import NonSeekingReader

    if _check_framing(path) == "complete":
        yield from _open_reader(f).iter_messages(topics=topics, log_time_order=False)
        return
    try:
        yield from NonSeekingReader(f, validate_crcs=True).iter_messages(topics=topics, log_time_order=False)
    except EndOfFile:
        return


class _BinSums:
    """Per-bin sums of IMU samples on a grid of ``dt`` (bins centred on grid times), streamed.

    Sums are kept sparse (occupied bins only), so a stray stamp far from the others (a boot-time
    stamp among UNIX stamps) costs one entry, not an array spanning the distance. Samples arrive
    as the log has them, ``(t, accel x, y, z, gyro x, y, z)``; ``prepare`` turns each buffered
    block into body-frame samples (checking their values) with numpy, not per message.
    """

    def __init__(self, dt: float, keep_samples: bool, prepare: Callable[[np.ndarray], np.ndarray]) -> None:
        self.dt = dt
        self.prepare = prepare
        self.origin: float | None = None
        self.parts: list[tuple[np.ndarray, np.ndarray]] = []  # (bins, [value sums..., count])
        self.buffer: list[tuple[float, ...]] = []
        # A log that may be single-rate (as many IMU as GNSS messages) also keeps its samples:
        # then they are as many as the output rows.
        self.samples: list[np.ndarray] | None = [] if keep_samples else None

    def add(self, sample: tuple[float, ...]) -> None:
        self.buffer.append(sample)
        if len(self.buffer) >= 65536:
            self.flush()

    def flush(self) -> None:
        if not self.buffer:
            return
        data = self.prepare(np.asarray(self.buffer))
        self.buffer.clear()
        if self.samples is not None:
            self.samples.append(data)
        if self.origin is None:
            self.origin = float(data[0, 0])
        bins = np.rint((data[:, 0] - self.origin) / self.dt).astype(np.int64)
        self.parts.append(_sum_by_bin(bins, np.column_stack([data[:, 1:], np.ones(len(data))])))
        if len(self.parts) > 64:
            self.parts = [_sum_by_bin(np.concatenate([b for b, _ in self.parts]), np.concatenate([v for _, v in self.parts]))]

    def means(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Grid times (s) of non-empty bins, the mean values per bin (n, 6), samples per bin."""
        self.flush()
        if not self.parts:
            return np.zeros(0), np.zeros((0, 6)), np.zeros(0)
        bins, sums = _sum_by_bin(np.concatenate([b for b, _ in self.parts]), np.concatenate([v for _, v in self.parts]))
        return self.origin + bins * self.dt, sums[:, :-1] / sums[:, -1:], sums[:, -1]

    def kept_samples(self) -> np.ndarray | None:
        """The body-frame samples in time order, when they were kept (else None)."""
        self.flush()
        if not self.samples:
            return None
        data = np.concatenate(self.samples)
        return data[np.argsort(data[:, 0], kind="stable")]


def _sum_by_bin(bins: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted unique bins and the column sums of ``values`` per bin."""
    unique, inverse = np.unique(bins, return_inverse=True)
    sums = np.zeros((len(unique), values.shape[1]))
    np.add.at(sums, inverse, values)
    return unique, sums


#: Stamps separated from the bulk of a topic's stamps by more than this (s) are strays (a clock
#: not yet synchronised, a boot-time stamp) and are dropped; a recording paused for less is kept.
MAX_STAMP_JUMP_S = 3600.0


def _main_span(t: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Mask of the stamps in the largest group of ``t`` without a jump over MAX_STAMP_JUMP_S.

    ``t`` must be sorted; ``weights`` count samples per stamp (default one each).
    """
    if len(t) == 0:
        return np.zeros(0, dtype=bool)
    group = np.concatenate([[0], np.cumsum(np.diff(t) > MAX_STAMP_JUMP_S)])
    size = np.bincount(group, weights=weights)
    return group == int(np.argmax(size))


def _drop_strays(path: Path, what: str, t: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Mask of ``t`` (sorted) to keep, warning once about stray stamps."""
    keep = _main_span(t, weights)
    if not keep.all():
        n = int((weights[~keep] if weights is not None else (~keep)).sum())
        log.warning("%s: dropped %d %s sample(s) stamped more than %g s away from the rest of the log "
                    "(e.g. %.3f s against %.3f-%.3f s): a clock not yet synchronised?",
                    path, n, what, MAX_STAMP_JUMP_S, float(t[~keep][0]), float(t[keep][0]), float(t[keep][-1]))
    return keep


def _first_per_stamp(path: Path, fixes: np.ndarray) -> np.ndarray:
    """Fixes in time order, keeping the first (as recorded) of fixes sharing one stamp."""
    order = np.argsort(fixes[:, 0], kind="stable")
    fixes = fixes[order]
    first = np.concatenate([[True], np.diff(fixes[:, 0]) > 0])
    if not first.all():
        same_place = (np.diff(fixes[:, 1]) == 0) & (np.diff(fixes[:, 2]) == 0)
        repeats = int((~first[1:] & same_place).sum())
        log.warning("%s: %d GNSS fix(es) share a time stamp with an earlier one (%d of them the same position); "
                    "kept the first of each stamp (a receiver publishing twice, or stamping whole seconds?)",
                    path, int((~first).sum()), repeats)
    return fixes[first]


def read_mcap(path: str | Path, *, imu_topic: str | None = None, gnss_topic: str | None = None,
              speed_topic: str | None = None, stamps: str = "header", name: str | None = None,
              imu_axes: str | None = None, yaw_sign: str = "auto") -> Drive:
    """Read an MCAP log into a drive on a 10 Hz grid (see the module docstring).

    ``imu_axes`` maps the log's IMU axes to the body frame (``"x=-y,y=x,z=z"``, see
    :mod:`.imu_frame`); ``yaw_sign`` ``"cw"`` says the yaw axis turns clockwise positive, ``"ccw"``
    (REP 103) that it does not, ``"auto"`` assumes REP 103 and checks it against the GNSS course.
    """
    path = Path(path)
    if stamps not in ("header", "log"):
        raise InputError(f"stamps {stamps!r}: choose header or log", param="stamps")
    if yaw_sign not in ("auto", "cw", "ccw"):
        raise InputError(f"yaw sign {yaw_sign!r} is not auto, cw or ccw", param="yaw_sign")
    mapping = parse_imu_axes(imu_axes) if imu_axes else np.eye(3)
    sel = select_channels(path, imu_topic, gnss_topic, speed_topic)
    gnss: list[tuple[float, float, float, float, float]] = []  # t, lat, lon, altitude, sigma (nan: unknown)
    speed: list[tuple[float, float, float]] = []  # t, speed m/s, course deg (nan if unknown)
    dropped_no_fix = 0

    def when(msg: Any, log_t: float, *stamp_path: str) -> float:
        if stamps == "log":
            return log_t
        try:
            t = _stamp_s(_get(msg, *stamp_path))
        except (KeyError, AttributeError, TypeError):
            return log_t
        return t if t > 0 and math.isfinite(t) else log_t

    def check(topic: str, t: float, field_name: str, column: str, value: float) -> None:
        reason = implausible(column, value)
        if reason:
            raise InputError(f"{path}: topic {topic}, message stamped {t:.3f} s: {field_name} {reason}",
                             "no car sensor produces that value: fix the log or choose another topic")

    def to_body(data: np.ndarray) -> np.ndarray:
        """A block of IMU samples as the log has them -> checked, in the body frame."""
        if (bad := _first_implausible_imu(data)) is not None:
            i, k = bad
            check(sel.imu.topic, float(data[i, 0]), _IMU_FIELDS[k - 1], _IMU_COLUMNS[k - 1], float(data[i, k]))
        return _imu_to_body(data, mapping)

    imu = _BinSums(1.0 / RATE_HZ, keep_samples=sel.imu.count == sel.gnss.count, prepare=to_body)

    try:
        for role, log_t, msg in _messages(path, sel):
            try:
                if role == "IMU":
                    t = when(msg, log_t, "header", "stamp")
                    lin, ang = _get(msg, "linear_acceleration"), _get(msg, "angular_velocity")
                    imu.add((t, *(float(_get(lin, a)) for a in AXES), *(float(_get(ang, a)) for a in AXES)))
                elif role == "GNSS":
                    if sel.gnss.schema.startswith("foxglove"):
                        t = when(msg, log_t, "timestamp")
                    else:
                        t = when(msg, log_t, "header", "stamp")
                        if int(_get(msg, "status", "status")) < 0:
                            dropped_no_fix += 1
                            continue
                    lat, lon = float(_get(msg, "latitude")), float(_get(msg, "longitude"))
                    if not (math.isfinite(lat) and math.isfinite(lon)):
                        dropped_no_fix += 1  # drivers publish NaN positions when they have no fix
                        continue
                    check(sel.gnss.topic, t, "latitude", "lat_deg", lat)
                    check(sel.gnss.topic, t, "longitude", "lon_deg", lon)
                    alt = msg.get("altitude", 0.0) if isinstance(msg, dict) else getattr(msg, "altitude", 0.0)
                    gnss.append((t, lat, lon, float(alt if alt is not None else math.nan), _horizontal_sigma_m(msg)))
                else:
                    sample = _speed_sample(msg, log_t, when, sel.speed.schema)
                    check(sel.speed.topic, sample[0], "speed", "speed_mps", sample[1])
                    speed.append(sample)
            except (KeyError, AttributeError, TypeError, ValueError) as exc:
                topic = {"IMU": sel.imu, "GNSS": sel.gnss}.get(role, sel.speed).topic
                raise InputError(f"{path}: topic {topic}: message lacks a field ({type(exc).__name__}: {exc})",
                                 f"expected the {role} field names of {({'IMU': IMU_SCHEMAS, 'GNSS': GNSS_SCHEMAS}.get(role, SPEED_SCHEMAS))[0]}") from None
    except InputError:
        raise
    except Exception as exc:
        raise _bad(path, exc) from None

    if len(gnss) < 2:
        without = f" ({dropped_no_fix} message(s) without a fix)" if dropped_no_fix else ""
        raise InputError(f"{path}: fewer than 2 GNSS fixes on {sel.gnss.topic}{without}", "the drive needs GNSS ground truth")
    if dropped_no_fix:
        log.warning("%s: dropped %d GNSS message(s) without a fix", path, dropped_no_fix)
    fixes = _first_per_stamp(path, np.asarray(gnss))
    fixes = fixes[_drop_strays(path, "GNSS", fixes[:, 0])]
    speeds = None
    if speed:
        speeds = np.asarray(speed)
        speeds = speeds[np.argsort(speeds[:, 0], kind="stable")]
        speeds = speeds[_drop_strays(path, "speed", speeds[:, 0])]
    return _to_drive(path, name or path.stem, imu, fixes, speeds, mapping, yaw_sign)


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


def _speed_sample(msg: Any, log_t: float, when, schema: str) -> tuple[float, float, float]:
    if "Odometry" in schema:
        t = when(msg, log_t, "header", "stamp")
        return t, abs(float(_get(msg, "twist", "twist", "linear", "x"))), math.nan
    t = when(msg, log_t, "header", "stamp")
    lin = _get(msg, "twist", "linear")
    vx, vy = float(_get(lin, "x")), float(_get(lin, "y"))
    frame = str(_get(msg, "header", "frame_id")).strip("/").lower()
    if frame in BODY_FRAMES:
        return t, abs(vx), math.nan
    return t, math.hypot(vx, vy), math.degrees(math.atan2(vx, vy)) % 360.0  # east, north -> course


#: The IMU sample columns after the stamp, as the log names them and the limits that apply to them
#: (every accelerometer axis has the longitudinal one's, every gyro axis the yaw rate's).
_IMU_FIELDS = tuple(f"linear_acceleration.{a}" for a in AXES) + tuple(f"angular_velocity.{a}" for a in AXES)
_IMU_COLUMNS = ("accel_long_mps2",) * 3 + ("yaw_rate_radps",) * 3


def _first_implausible_imu(data: np.ndarray) -> tuple[int, int] | None:
    """(row, column) of the first implausible value in a block of IMU samples (columns 1-6), in
    the order a message is checked (accelerometer then gyro, x then y then z), or None."""
    order = (1, 4, 2, 5, 3, 6)
    firsts = [(i, n, k) for n, k in enumerate(order) if (i := first_implausible(_IMU_COLUMNS[k - 1], data[:, k])) is not None]
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


def _to_drive(path: Path, name: str, imu: _BinSums, gnss: np.ndarray, speed: np.ndarray | None,
              mapping: np.ndarray, yaw_sign: str) -> Drive:
    g_t, g_lat, g_lon, g_alt, g_sigma = gnss.T
    samples = imu.kept_samples()
    if samples is not None and len(samples) == len(g_t) and np.array_equal(samples[:, 0], g_t):
        t, body = samples[:, 0], samples[:, 1:]  # IMU and GNSS share their stamps: keep them
        lat, lon, alt, sigma = g_lat, g_lon, g_alt, g_sigma
        has_fix = np.ones(len(t), dtype=bool)
    else:
        t, body, count = imu.means()
        keep = _drop_strays(path, "IMU", t, count) & (t >= g_t[0]) & (t <= g_t[-1])
        t, body = t[keep], body[keep]
        has_fix = _covered(t, g_t)  # the IMU goes on through a GNSS gap: no-fix samples, not a gap
        lat, lon, alt, sigma = (np.interp(t, g_t, x) for x in (g_lat, g_lon, g_alt, g_sigma))
    if len(t) < 2:
        raise InputError(f"{path}: IMU and GNSS do not overlap in time", "check the topics and the choice of stamps (header or log)", param="stamps")

    v = course = None
    if speed is not None and len(speed) >= 2:
        s_t, s_v, s_course = speed.T
        v = np.interp(t, s_t, s_v)
        has_course = np.isfinite(s_course)
        if has_course.any():
            unwrapped = np.rad2deg(np.unwrap(np.deg2rad(s_course[has_course])))
            course = wrap_360(np.interp(t, s_t[has_course], unwrapped))
    if v is None or course is None:
        # no velocity from the receiver: the fixes' local fit gives it, and smoothed positions
        # (the per-window displacement of raw fixes would carry their white noise twice)
        fit = fit_fixes(t, g_t, g_lat, g_lon)
        v = fit.speed_mps if v is None else v
        course = hold_course_when_slow(fit.course_deg, fit.speed_mps, FIX_COURSE_MIN_SPEED_MPS) if course is None else course
        lat, lon = fit.lat_deg, fit.lon_deg
    accel, yaw = body[:, 0], body[:, 5] * (-1.0 if yaw_sign == "cw" else 1.0)
    if _imu_frame_reversed(path, t, body, v, course, mapping, check_yaw_sign=yaw_sign == "auto"):
        yaw = -yaw
    columns = {"t_s": t - float(t[0]), "lat_deg": lat, "lon_deg": lon, "speed_mps": v, "heading_deg": course,
               "accel_long_mps2": accel, "yaw_rate_radps": yaw}
    if first_implausible("height_m", alt) is None:
        columns["height_m"] = alt
    if len(sigma) and np.isfinite(sigma).all():  # the receiver's own accuracy, when every fix has one
        columns["gnss_sigma_m"] = sigma
    if not has_fix.all():
        columns["gnss_fix"] = has_fix.astype(float)
    start = float(t[0])
    return Drive(name=name, source=str(path), rate_hz=round(1.0 / float(np.median(np.diff(t))), 1),
                 start_time_of_day_s=start % 86400.0, columns=columns)


def _imu_frame_reversed(path: Path, t: np.ndarray, body: np.ndarray, speed_mps: np.ndarray, course_deg: np.ndarray,
                        mapping: np.ndarray, check_yaw_sign: bool) -> bool:
    """Check the IMU's frame (:func:`.imu_frame.check_imu_frame`), warn once, and say whether the
    yaw rate must be flipped (only when ``check_yaw_sign``)."""
    found = check_imu_frame(t, body[:, :3], body[:, 3:], speed_mps, course_deg, mapping)
    problems = [p for p in found.problems if check_yaw_sign or not p.startswith(YAW_REVERSED)]
    if problems:
        fix = f"; map the axes with --imu-axes {found.suggestion}" if found.suggestion else ""
        force = "; force the sign with --yaw-sign cw|ccw" if found.yaw_reversed and check_yaw_sign else ""
        log.warning("%s: the IMU is not in the body frame ionav-viz expects (REP 103: x forward, z up): %s%s%s",
                    path, "; ".join(problems), fix, force)
    return found.yaw_reversed and check_yaw_sign


#: Below this speed (m/s) a course from fixes is noise (the fixes' scatter, not the car's motion,
#: sets its direction), so the last course at speed is held; a receiver's Doppler course is good
#: down to MIN_COURSE_SPEED_MPS.
FIX_COURSE_MIN_SPEED_MPS = 2.0

#: Shortest half-width (s) of the local fit that gives speed and course from fixes: the fix noise is
#: averaged over at least 2 s of track, never divided by the time between two fixes.
MIN_HALF_BASELINE_S = 1.0
_WGS84_A_M, _WGS84_E2 = 6_378_137.0, 6.694379990141317e-3


def fit_fixes(t: np.ndarray, g_t: np.ndarray, g_lat: np.ndarray, g_lon: np.ndarray) -> FixFit:
    """Position, speed (m/s) and course (deg from north, clockwise) at times ``t`` from GNSS fixes alone.

    A parabola in time fitted by least squares to the fixes within ``t - h .. t + h`` (``h`` the
    larger of MIN_HALF_BASELINE_S and 1.5 median fix intervals), evaluated and differentiated at
    ``t``: exact for a constant acceleration whatever the spacing of the fixes, unbiased for a
    constant turn rate, and the noise of the fixes averaged over every fix in the window, whatever
    the rate (1-20 Hz), jitter or duplicates. Degrees become metres with the WGS84 radii of
    curvature at the window's first fix. ``g_t`` must be strictly increasing.

    At a standstill the parabola's speed is the magnitude of the fix noise's slope (a Rayleigh
    variable, ~0.2 m/s for 0.15 m of noise at 10 Hz), which would hide the stillness the bias
    estimate needs. So below ~1.5 m/s the speed blends towards the smaller of it and a straight
    line fitted over SLOW_BASELINE_FACTOR times the baseline (well under 0.1 m/s when still); the
    smaller, because the long line lags when the car stops, and blended, so the speed stays
    continuous (its derivative is the events' acceleration).
    """
    gap = float(np.median(np.diff(g_t))) if len(g_t) > 1 else 0.0
    h = max(MIN_HALF_BASELINE_S, 1.5 * gap)
    lat, lon, ve, vn = _local_fit(t, g_t, g_lat, g_lon, h, degree=2)
    speed = np.hypot(ve, vn)
    _, _, slow_ve, slow_vn = _local_fit(t, g_t, g_lat, g_lon, SLOW_BASELINE_FACTOR * h, degree=1)
    still = np.minimum(speed, np.hypot(slow_ve, slow_vn))
    w = np.clip((speed - SLOW_BLEND_MPS[0]) / (SLOW_BLEND_MPS[1] - SLOW_BLEND_MPS[0]), 0.0, 1.0)
    return FixFit(lat, lon, w * speed + (1.0 - w) * still, wrap_360(np.degrees(np.arctan2(ve, vn))))


@dataclass(frozen=True)
class FixFit:
    """What :func:`fit_fixes` gives per grid time: smoothed position (deg), speed (m/s), course (deg)."""

    lat_deg: np.ndarray
    lon_deg: np.ndarray
    speed_mps: np.ndarray
    course_deg: np.ndarray


#: How much longer the straight-line fit is where the car is slow, and the speeds (m/s) between
#: which the fixes' speed blends from it to the parabola's (see fit_fixes).
SLOW_BASELINE_FACTOR = 2.5
SLOW_BLEND_MPS = (0.5, 1.5)


def _local_fit(t: np.ndarray, g_t: np.ndarray, g_lat: np.ndarray, g_lon: np.ndarray, h: float,
               degree: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Latitude, longitude (deg) and east, north velocity (m/s) at ``t`` from a polynomial of
    ``degree`` (1 or 2) in time fitted to the fixes within ``t +- h``."""
    lat, lon, ve, vn = (np.zeros(len(t)) for _ in range(4))
    need = degree + 1
    max_fixes = int(np.max(np.searchsorted(g_t, g_t + 2 * h, side="right") - np.arange(len(g_t)))) + need
    block = max(1, 2_000_000 // max_fixes)  # bounds the (grid x fixes) arrays
    for a in range(0, len(t), block):
        tb = t[a : a + block]
        at = np.searchsorted(g_t, tb)
        # the fixes within h, and at least the ones either side of t (across a wider gap: the chord)
        lo = np.minimum(np.searchsorted(g_t, tb - h, side="left"), np.clip(at - 1, 0, None))
        hi = np.maximum(np.searchsorted(g_t, tb + h, side="right"), np.minimum(at + 1, len(g_t)))
        lo = np.maximum(np.minimum(lo, hi - need), 0)  # enough fixes for the polynomial, at the ends too
        hi = np.minimum(np.maximum(hi, lo + need), len(g_t))
        idx = lo[:, None] + np.arange(max_fixes)[None, :]
        use = idx < hi[:, None]
        idx = np.minimum(idx, len(g_t) - 1)
        dt = np.where(use, g_t[idx] - tb[:, None], 0.0)
        terms = [use * 1.0, dt, 0.5 * dt * dt][:need]  # value, rate, acceleration at t
        design = np.stack(terms, axis=-1)
        normal = design.transpose(0, 2, 1) @ design
        normal[:, -1, -1] += 1e-9  # fewer fixes than terms (two fixes): the chord
        for position, rate, values in ((lat, vn, g_lat), (lon, ve, g_lon)):
            y = np.where(use, values[idx] - values[lo][:, None], 0.0)
            coef = np.linalg.solve(normal, (design.transpose(0, 2, 1) @ y[:, :, None]))
            position[a : a + block] = values[lo] + coef[:, 0, 0]
            rate[a : a + block] = coef[:, 1, 0]  # deg/s
        sin2 = np.sin(np.radians(g_lat[lo])) ** 2
        vn[a : a + block] *= np.radians(_WGS84_A_M * (1 - _WGS84_E2) / (1 - _WGS84_E2 * sin2) ** 1.5)
        ve[a : a + block] *= np.radians(_WGS84_A_M / np.sqrt(1 - _WGS84_E2 * sin2)) * np.cos(np.radians(g_lat[lo]))
    return lat, lon, ve, vn


def _covered(t: np.ndarray, g_t: np.ndarray) -> np.ndarray:
    """Grid times inside the GNSS record and not inside a GNSS gap: a gap is longer than
    MAX_GNSS_GAP_S and than 1.5 of the receiver's usual intervals (a jittered 1 Hz receiver's
    1.004 s between fixes is its rate, not a gap)."""
    inside = (t >= g_t[0]) & (t <= g_t[-1])
    k = np.clip(np.searchsorted(g_t, t), 1, len(g_t) - 1)
    gap = g_t[k] - g_t[k - 1]
    usual = float(np.median(np.diff(g_t))) if len(g_t) > 1 else 0.0
    return inside & (gap <= max(MAX_GNSS_GAP_S, 1.5 * usual))
