"""Writing a drive's log with its GNSS removed inside outages (``ionav-viz outage-log``), for an
estimator outside ionav-viz to run on.

Every outage is ``(start, end]`` on the source's own clock (:meth:`~ionav_viz.core.drive.Drive.stamp_s`):
the fix at its start stays (the estimators' start state), every GNSS message after it up to and
including its end goes. A logger stamps its fixes a few milliseconds off the grid an outage starts on
(IO-VNBD's 60653.341 for the grid's 60653.34), so a fix within :data:`STAMP_TOL_S` after the start is
the start fix, and one within it after the end is the end's: removed is ``(start + tol, end + tol]``.
Formats, by the output's name:

* ``.mcap`` from an MCAP source: every message of every topic copied byte for byte, in the
  file's order, except the GNSS fixes and GNSS velocity (the topics the reader uses) stamped inside an
  outage (the header stamp, or the log time with ``stamps="log"``, as the reader decides).
* ``.mcap`` from any other source: the drive as ``ionav-viz convert`` writes it
  (:mod:`.mcap_writer`, stamps on the source's clock), without ``/gps/fix`` and ``/gps/vel``
  messages inside an outage. Where the drive has a reference truth, the receiver's fixes are written.
* ``.bag`` (ROS 1) from a ROS 1 bag, or a folder (a name without a suffix, that does not exist
  yet: a ROS 2 bag) from a ROS 2 bag: every message copied as it is, connections and definitions
  too, except the GNSS fixes and velocities inside an outage (stamped as the reader decides); a
  ROS 2 bag is written as SQLite storage, uncompressed. From any other source: the drive's topics
  as for ``.mcap`` from a drive, as standard ROS messages.
* ``.csv`` from an IO-VNBD ``V-*.csv``: every line as it was, except rows whose time of day lies
  inside an outage: the logger's no-fix convention, 0 satellites and the last fix before the
  outage repeated in the GNSS columns (latitude to vertical velocity).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from ..core.fileio import atomic_path, atomic_write_bytes, check_output_file, staging_folder

log = logging.getLogger("ionav_viz")


@dataclass(frozen=True)
class OutageLog:
    """What :func:`write_outage_log` wrote: the file, its format, how many GNSS messages (or CSV rows)
    it left out, from which topics (or columns)."""

    path: Path
    format: str
    removed: int
    removed_topics: tuple[str, ...]


#: A fix stamped within this (s) after an outage's start (end) is the fix at its start (end): a
#: logger's stamps jitter by milliseconds around the 10 Hz grid; a receiver's fixes are 50 ms or more apart.
STAMP_TOL_S = 0.01


def inside(stamps_s: np.ndarray, outages: Sequence[tuple[float, float]]) -> np.ndarray:
    """Which stamps lie inside an outage: ``(start + STAMP_TOL_S, end + STAMP_TOL_S]`` (s on the
    same clock). The fix at the start stays whether it is stamped a millisecond before or after it
    (with ``1e-6`` here, the first of ``outage-log roundabout --every 30s`` lost its 60653.341 fix)."""
    stamps_s = np.asarray(stamps_s, dtype=float)
    hit = np.zeros(len(stamps_s), dtype=bool)
    for a, b in outages:
        hit |= (stamps_s > a + STAMP_TOL_S) & (stamps_s <= b + STAMP_TOL_S)
    return hit


def write_outage_log(drive: Drive, source: Path, kind: str, outages: Sequence[tuple[float, float]], out: Path,
                     gnss_topics: Sequence[str] = (), stamps: str = "header",
                     vehicle_speed: tuple[np.ndarray, tuple[str, ...]] | None = None) -> OutageLog:
    """Write ``drive`` (read from ``source``, of reader ``kind``) with its GNSS removed inside
    ``outages`` (``(start, end]`` stamps, s) to ``out`` (atomically; format by its suffix).
    ``gnss_topics``: for a message-log source, the topics the reader took GNSS from;
    ``vehicle_speed``: for a log written from the drive, its vehicle speed (m/s per sample) and the
    columns it stands for (as ``convert`` writes it)."""
    suffix = out.suffix.lower()
    if suffix == "" and not out.is_file():  # a ROS 2 bag folder
        if kind == "ros2":
            return _bag_copy(source, outages, out, tuple(gnss_topics), stamps)
        return _bag_from_drive(drive, outages, out, vehicle_speed, ros1=False)
    check_output_file(out)
    if suffix == ".bag":
        if kind == "ros1":
            return _bag_copy(source, outages, out, tuple(gnss_topics), stamps)
        return _bag_from_drive(drive, outages, out, vehicle_speed, ros1=True)
    if suffix == ".csv":
        if kind != "iovnbd":
            raise InputError(f"{out}: a CSV outage log is an IO-VNBD file, and {source} is not one",
                             "write .mcap instead", param="output")
        return _iovnbd(source, outages, out)
    if suffix != ".mcap":
        raise InputError(f"{out}: unsupported outage-log format {suffix}",
                         "write .mcap (any source), .bag (a ROS 1 bag), a folder (a ROS 2 bag) or .csv (an "
                         "IO-VNBD source)", param="output")
    if kind == "mcap":
        return _mcap_copy(source, outages, out, tuple(gnss_topics), stamps)
    return _mcap_from_drive(drive, outages, out, vehicle_speed)


def _mcap_from_drive(drive: Drive, outages: Sequence[tuple[float, float]], out: Path,
                     vehicle_speed: tuple[np.ndarray, tuple[str, ...]] | None) -> OutageLog:
    from .mcap_writer import TOPICS, write_mcap

    received = drive.as_received()
    speed_mps, columns = vehicle_speed if vehicle_speed is not None else (None, ())
    lost = inside(received.stamp_s(received.t_s), outages)
    write_mcap(received, out, speed_mps, columns, omit_gnss=lost)
    return OutageLog(out, "mcap", int(lost.sum()) * 2, (TOPICS["fix"], TOPICS["vel"]))


def _mcap_copy(source: Path, outages: Sequence[tuple[float, float]], out: Path, gnss_topics: tuple[str, ...],
               stamps: str) -> OutageLog:
    from mcap.writer import Writer
    from mcap_ros2.decoder import DecoderFactory

    from .mcap_reader import iter_messages
    from .message_log import decode_json, get_field, stamp_ns

    factory = DecoderFactory()
    decoders: dict[int, Any] = {}
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    removed = 0

    def stamp_s(schema: Any, channel: Any, message: Any) -> float:
        if stamps == "log":
            return message.log_time * 1e-9
        if channel.message_encoding == "json":
            msg = decode_json(source, channel.topic, message.data, message.log_time)
        else:
            if channel.id not in decoders:
                decoders[channel.id] = factory.decoder_for(channel.message_encoding, schema)
            msg = decoders[channel.id](message.data)
        try:
            ns = stamp_ns(get_field(msg, "timestamp") if schema is not None and
                          schema.name.startswith("foxglove") else get_field(msg, "header", "stamp"))
        except (KeyError, AttributeError, TypeError, ValueError):
            ns = 0
        return (ns if ns > 0 else message.log_time) * 1e-9

    with atomic_path(out, suffix=".tmp.mcap") as tmp, open(tmp, "wb") as stream, open(source, "rb") as f:
        writer = Writer(stream)
        writer.start(profile="ros2", library="ionav-viz outage-log")
        for schema, channel, message in iter_messages(source, f, None):
            if channel.topic in gnss_topics and inside(np.array([stamp_s(schema, channel, message)]), outages)[0]:
                removed += 1
                continue
            if schema is not None and schema.id not in schema_ids:
                schema_ids[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channel_ids:
                channel_ids[channel.id] = writer.register_channel(channel.topic, channel.message_encoding,
                                                                  schema_ids.get(channel.schema_id, 0),
                                                                  dict(channel.metadata))
            writer.add_message(channel_ids[channel.id], message.log_time, message.data, message.publish_time,
                               message.sequence)
        writer.finish()
    return OutageLog(out, "mcap", removed, gnss_topics)


def _staging(out: Path) -> AbstractContextManager[Path]:
    """A new hidden folder beside ``out`` to write into, removed afterwards (:func:`.staging_folder`)."""
    if not out.parent.is_dir():
        raise InputError(f"{out}: no folder {out.parent}", "create it first", param="output")
    return staging_folder(out)


def _bag_from_drive(drive: Drive, outages: Sequence[tuple[float, float]], out: Path,
                    vehicle_speed: tuple[np.ndarray, tuple[str, ...]] | None, ros1: bool) -> OutageLog:
    """The drive's topics as ``convert`` writes them (:mod:`.mcap_writer`), as a ROS 1 bag or a ROS 2
    bag folder: the MCAP's CDR messages, standard ROS types, re-serialised for ROS 1."""
    import os

    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    if not ros1 and out.exists():
        raise InputError(f"{out}: exists; a ROS 2 outage log is a new folder", "remove it or choose another name",
                         param="output")
    with _staging(out) as stage:
        written = _mcap_from_drive(drive, outages, stage / "drive.mcap", vehicle_speed)
        if ros1:
            from rosbags.rosbag1 import Writer

            writer = Writer(stage / out.name)
        else:
            from rosbags.rosbag2 import Writer

            writer = Writer(stage / out.name, version=9)
        store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        cdr = get_typestore(Stores.ROS2_HUMBLE)
        connections: dict[int, Any] = {}
        with writer, open(stage / "drive.mcap", "rb") as f:
            for schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
                if channel.id not in connections:
                    connections[channel.id] = writer.add_connection(channel.topic, schema.name, typestore=store)
                data = cdr.cdr_to_ros1(message.data, schema.name) if ros1 else message.data
                writer.write(connections[channel.id], message.log_time, data)
        if ros1:
            os.replace(stage / out.name, out)
        else:
            (stage / out.name).rename(out)
    return OutageLog(out, "ros1" if ros1 else "ros2", written.removed, written.removed_topics)


def _bag_copy(source: Path, outages: Sequence[tuple[float, float]], out: Path, gnss_topics: tuple[str, ...],
              stamps: str) -> OutageLog:
    import os

    from .message_log import get_field, stamp_ns
    from .rosbag_reader import RosbagLog

    log_ = RosbagLog(source)
    if not log_.ros1 and out.exists():
        raise InputError(f"{out}: exists; a ROS 2 outage log is a new folder", "remove it or choose another name",
                         param="output")

    def inside_outage(log_ns: int, msg: Any) -> bool:
        ns = log_ns
        if stamps != "log":
            try:
                ns = stamp_ns(get_field(msg, "header", "stamp")) or log_ns
            except (KeyError, AttributeError, TypeError, ValueError):
                ns = log_ns
        return bool(inside(np.array([ns * 1e-9]), outages)[0])

    with _staging(out) as stage:
        staged = stage / out.name
        removed = log_.copy(staged, set(gnss_topics), inside_outage)
        if log_.ros1:
            os.replace(staged, out)
        else:
            staged.rename(out)
    return OutageLog(out, "ros1" if log_.ros1 else "ros2", removed, gnss_topics)


#: IO-VNBD columns the logger fills from its fix (latitude ... vertical velocity), and the satellites.
_CSV_SATELLITES, _CSV_TIME, _CSV_GNSS = 0, 1, (2, 3, 4, 5, 6, 7)


def _iovnbd(source: Path, outages: Sequence[tuple[float, float]], out: Path) -> OutageLog:
    raw = source.read_bytes()
    lines = raw.splitlines(keepends=True)
    removed, last_fix = 0, None
    for i, line in enumerate(lines[1:], start=1):
        body = line.rstrip(b"\r\n")
        cells = body.split(b",")
        try:
            t = float(cells[_CSV_TIME])
        except (IndexError, ValueError):
            continue  # a line the reader skips or refuses: left as it is
        if not inside(np.array([t]), outages)[0]:
            last_fix = cells
            continue
        if last_fix is None:
            continue
        cells = list(cells)
        cells[_CSV_SATELLITES] = b"0"
        for k in _CSV_GNSS:
            cells[k] = last_fix[k]
        lines[i] = b",".join(cells) + line[len(body):]
        removed += 1
    atomic_write_bytes(out, b"".join(lines))
    return OutageLog(out, "iovnbd", removed, ("GNSS columns (satellites 0, the last fix repeated)",))
