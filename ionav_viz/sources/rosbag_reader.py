"""ROS 1 bags and ROS 2 bags: their format under the shared message-log reader, with ``rosbags``.

``rosbags`` (pure Python, no ROS install) reads:

* ROS 1 ``.bag`` files (format 2.0), uncompressed or with bz2/lz4 chunks;
* ROS 2 bag folders (``metadata.yaml`` plus SQLite ``.db3`` or ``.mcap`` storage files), named by
  the folder or by its ``metadata.yaml``, with zstd file or message compression (file-compressed
  storage is decompressed to a temporary file that is removed when reading ends), and a single
  ``.db3`` file without its folder.

What is read from which topic, stamps, rates and memory: :mod:`.message_log`. Here: listing the
topics (type, serialization, message count from the bag's index or metadata) and streaming the
selected topics' messages, deserialised with the message definitions the bag carries (ROS 1
always; ROS 2 from Iron on, and MCAP storage) or, for a bag without them, with the standard
ROS 2 Humble / ROS 1 Noetic definitions. Only the selected topics are deserialised, each with a
type store built from its own definition, so a broken definition on a topic that is not used
(a camera driver's custom message) does not stop the read. Messages of other topics are never
decoded: an SQLite bag does not even read them; a ROS 1 bag decompresses the chunks that hold
selected messages one at a time (memory: one chunk).

A ROS 2 bag's messages go to the reader in blocks of :data:`BAG_BLOCK_MESSAGES`, in the bag's order; a
topic whose messages in a block share one fixed CDR layout is read as columns (:mod:`.cdr`), by the same
rules as one by one.

Log time (``--stamps log``) is the bag's receive time stamp.
"""

from __future__ import annotations

import contextlib
import re
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import InputError
from .cdr import CdrType, fields_of
from .inflate import check_declared, inflate
from .message_log import Block, ChannelInfo, Columns, StreamBlock

#: A ROS 2 bag's messages are handed to the reader this many at a time (about an MCAP chunk's worth).
BAG_BLOCK_MESSAGES = 4096

ROS1_MAGIC = b"#ROSBAG V2.0\n"
ROS1_SUFFIXES = (".bag", ".active")  # ``x.bag.active``: a recording that did not finish
ROS2_STORAGE_SUFFIXES = (".db3", ".mcap")


def is_ros1_bag(path: Path) -> bool:
    return path.suffix.lower() in ROS1_SUFFIXES


class RosbagLog:
    """A ROS 1 bag, a ROS 2 bag folder (or its ``metadata.yaml``) or a ROS 2 ``.db3`` file, as a
    :class:`~.message_log.MessageLog`."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.ros1 = is_ros1_bag(self.path)
        self.encodings = ("ros1",) if self.ros1 else ("cdr",)
        # what rosbags opens: the .bag, the bag folder, or a single storage file
        self._target = self.path.parent if self.path.name == "metadata.yaml" else self.path
        self._kind = "ROS 1 bag" if self.ros1 else "ROS 2 bag"

    # --- opening, with the errors a user can act on ------------------------------------------
    def _check(self) -> None:
        if not self.path.exists():
            raise InputError(f"{self.path}: no such file or folder")
        if self.ros1:
            _check_ros1_framing(self.path)
        elif (error := missing_metadata(self._target)) is not None:
            raise error

    @contextlib.contextmanager
    def _open(self) -> Iterator[Any]:
        self._check()
        if self.ros1:
            from rosbags.rosbag1 import Reader
        else:
            from rosbags.rosbag2 import Reader
        try:
            reader = Reader(self._target)
            reader.open()
            if self.ros1:
                _bound_chunks(reader, self.path)
        except InputError:
            raise
        except Exception as exc:
            raise self.damaged(exc) from None
        try:
            with _bounded_ros2_chunks(self.path):
                yield reader
        finally:
            with contextlib.suppress(Exception):
                reader.close()

    def damaged(self, exc: BaseException) -> InputError:
        text = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        if "files are missing" in text:
            missing = ", ".join(Path(m).name for m in re.findall(r"'([^']+)'", text)) or text
            return InputError(f"{self._target / 'metadata.yaml'}: lists storage files that are not in the "
                              f"folder ({missing})",
                              "copy the whole bag folder, or run 'ros2 bag reindex DIR' to describe the files "
                              "that are there")
        if "metadata" in text.lower() or "yaml" in text.lower():
            return InputError(f"{self._target / 'metadata.yaml'}: unreadable bag metadata ({text})",
                              "recreate it with 'ros2 bag reindex DIR' (ROS 2)")
        return InputError(f"{self.path}: damaged {self._kind} ({type(exc).__name__}: {text})",
                          "run 'rosbag reindex' on it (ROS 1) or 'ros2 bag reindex DIR' (ROS 2), or re-record it")

    # --- the MessageLog interface -------------------------------------------------------------
    def channels(self) -> list[ChannelInfo]:
        with self._open() as reader:
            return _topics(reader.connections, self.ros1)

    def messages(self, channels: list[ChannelInfo]) -> Iterator[tuple[str, int, Any]]:
        wanted = {c.topic for c in channels}
        with self._open() as reader:
            connections = [c for c in reader.connections if c.topic in wanted]
            decoders = {c.id: self._decoder(c) for c in connections}
            for connection, time_ns, raw in reader.messages(connections=connections):
                yield connection.topic, int(time_ns), _decoded(self.path, connection, time_ns, raw,
                                                               decoders[connection.id])

    def blocks(self, channels: list[ChannelInfo]) -> Iterator[Block]:
        """The chosen channels' messages in blocks (a :class:`~.message_log.Block` each): a ROS 2 bag's
        :data:`BAG_BLOCK_MESSAGES` at a time, in the bag's order; a ROS 1 bag's as one stream."""
        if self.ros1:
            yield StreamBlock(self.messages(channels))
            return
        wanted = {c.topic for c in channels}
        with self._open() as reader:
            connections = [c for c in reader.connections if c.topic in wanted]
            types = {c.id: CdrType(_typestore(self.path, c, False), c.msgtype) for c in connections}
            batch: list[tuple[Any, int, bytes]] = []
            for connection, time_ns, raw in reader.messages(connections=connections):
                batch.append((connection, int(time_ns), raw))
                if len(batch) == BAG_BLOCK_MESSAGES:
                    yield _BagBlock(self.path, types, batch)
                    batch = []
            if batch:
                yield _BagBlock(self.path, types, batch)

    def copy(self, out: Path, topics: set[str], drop: Any) -> int:
        """Write every message to a new bag of the same kind at ``out`` (a ROS 1 ``.bag`` file, or a
        ROS 2 bag folder that must not exist, written as SQLite), raw bytes and definitions as they
        are, except messages on ``topics`` for which ``drop(log time ns, decoded message)`` is true.
        Returns how many were dropped."""
        if self.ros1:
            from rosbags.rosbag1 import Writer
        else:
            from rosbags.rosbag2 import Writer
        dropped = 0
        with self._open() as reader:
            writer = Writer(out) if self.ros1 else Writer(out, version=9)
            writer.open()
            try:
                ids = {}
                decoders = {c.id: self._decoder(c) for c in reader.connections if c.topic in topics}
                for c in reader.connections:
                    if self.ros1:
                        ids[c.id] = writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest,
                                                          callerid=c.ext.callerid, latching=c.ext.latching)
                    else:
                        ids[c.id] = writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data or None,
                                                          rihs01=c.digest or None,
                                                          serialization_format=c.ext.serialization_format,
                                                          offered_qos_profiles=c.ext.offered_qos_profiles)
                for connection, time_ns, raw in reader.messages():
                    if connection.id in decoders and drop(int(time_ns), decoders[connection.id](raw)):
                        dropped += 1
                        continue
                    writer.write(ids[connection.id], int(time_ns), raw)
            finally:
                writer.close()
        return dropped

    def _decoder(self, connection: Any):
        """A function raw bytes -> message object for one connection, from its own definition."""
        store = _typestore(self.path, connection, self.ros1)
        if self.ros1:
            return lambda raw: store.deserialize_ros1(raw, connection.msgtype)
        return lambda raw: store.deserialize_cdr(raw, connection.msgtype)


def _decoded(path: Path, connection: Any, time_ns: int, raw: bytes, decode: Any) -> Any:
    """``decode(raw)``; a message its definition does not read is one line naming the topic and the time."""
    try:
        return decode(raw)
    except Exception as exc:
        raise InputError(f"{path}: topic {connection.topic}: a message at log time {time_ns} does "
                         f"not match its definition of {connection.msgtype} ({type(exc).__name__}: {exc})",
                         "the bag's message definition is not the one the messages were written with; "
                         "re-record, or choose another topic") from None


class _BagBlock:
    """Consecutive messages of a ROS 2 bag's chosen connections (a :class:`~.message_log.Block`):
    ``(connection, log time ns, CDR bytes)`` in the bag's order, each connection's type in ``types``."""

    def __init__(self, path: Path, types: dict[int, CdrType], batch: list[tuple[Any, int, bytes]]) -> None:
        self.path, self.types, self.batch = path, types, batch

    def first_topic(self) -> str | None:
        return self.batch[0][0].topic if self.batch else None

    def messages(self) -> Iterator[tuple[str, int, Any]]:
        for connection, time_ns, raw in self.batch:
            yield connection.topic, time_ns, _decoded(self.path, connection, time_ns, raw,
                                                      self.types[connection.id].decode)

    def columns(self, topic: str) -> Columns | None:
        mine = [m for m in self.batch if m[0].topic == topic]
        if not mine:
            return Columns(np.zeros(0, np.int64), {})
        size = len(mine[0][2])
        if (len({m[0].id for m in mine}) > 1 or any(len(m[2]) != size for m in mine)
                or not all(-(2**63) <= m[1] < 2**63 for m in mine)):
            return None
        rows = np.frombuffer(b"".join(m[2] for m in mine), np.uint8).reshape(len(mine), size)
        fields = fields_of(self.types[mine[0][0].id], rows)
        return None if fields is None else Columns(np.array([m[1] for m in mine], np.int64), fields)


def missing_metadata(folder: Path) -> InputError | None:
    """The error for a folder of ROS 2 storage files without its ``metadata.yaml`` (else None)."""
    if not folder.is_dir() or (folder / "metadata.yaml").is_file():
        return None
    storage = sorted(p.name for p in folder.iterdir() if p.name.endswith((".db3", ".mcap", ".db3.zstd", ".mcap.zstd")))
    if not storage:
        return None
    return InputError(f"{folder}: a folder without metadata.yaml is not a ROS 2 bag (it holds "
                      f"{', '.join(storage[:3])})",
                      "recreate the metadata with 'ros2 bag reindex DIR' (ROS 2), or give one of its .db3 files")


def _topics(connections: list[Any], ros1: bool) -> list[ChannelInfo]:
    """One :class:`ChannelInfo` per topic (a ROS 1 topic can have a connection per publisher)."""
    topics: dict[str, ChannelInfo] = {}
    for c in connections:
        encoding = "ros1" if ros1 else getattr(c.ext, "serialization_format", "cdr")
        info = topics.setdefault(c.topic, ChannelInfo(c.topic, c.msgtype, encoding, 0))
        info.count += int(c.msgcount)
    return sorted(topics.values(), key=lambda ch: ch.topic)


def _typestore(path: Path, connection: Any, ros1: bool) -> Any:
    """A type store holding the connection's message type: from the definition the bag carries,
    else from the standard definitions of ROS 1 Noetic / ROS 2 Humble."""
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    msgdef, msgtype = connection.msgdef, connection.msgtype
    if msgdef.format == MessageDefinitionFormat.NONE or not msgdef.data.strip():
        store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        if msgtype not in store.fielddefs:
            raise InputError(f"{path}: topic {connection.topic}: the bag has no definition of its message "
                             f"type {msgtype}, and it is not a standard ROS message",
                             "record with ROS 2 Iron or later (bags then carry definitions), or choose another topic")
        return store
    try:
        if msgdef.format == MessageDefinitionFormat.MSG:
            types = get_types_from_msg(msgdef.data, msgtype)
        else:
            sep = "=" * 80 + "\n"
            types = {}
            parts = msgdef.data.split(sep)[1:] if msgdef.data.startswith(f"{sep}IDL: ") else [f"IDL: \n{msgdef.data}"]
            for part in parts:
                types.update(get_types_from_idl(part.split("\n", 1)[1]))
        store = typestore_of(types, msgtype)
    except Exception as exc:
        text = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise InputError(f"{path}: topic {connection.topic}: the bag's definition of {msgtype} cannot be read "
                         f"({type(exc).__name__}: {text})",
                         "re-record the topic, or choose another one") from None
    return store


def typestore_of(types: dict, msgtype: str) -> Any:
    """A rosbags type store holding ``types`` (parsed message definitions), checked to define every
    field of ``msgtype``; rosbags' own error where one is missing."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.EMPTY)
    store.register(types)
    store.get_msgdef(msgtype)  # every field's type is defined
    return store


def _check_ros1_framing(path: Path) -> None:
    """Refuse a file that is not a ROS 1 bag, an unindexed bag or a truncated one, saying what to do."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        magic = f.read(len(ROS1_MAGIC))
        if magic != ROS1_MAGIC:
            if magic.startswith(b"#ROSBAG V"):
                raise InputError(f"{path}: ROS bag version {magic[9:].strip().decode(errors='replace')} is "
                                 "not supported",
                                 "ionav-viz reads ROS 1 bags of format 2.0 (ROS 1 Groovy and later)")
            raise InputError(f"{path}: not a ROS 1 bag (no '#ROSBAG V2.0' magic at the start)",
                             "ionav-viz reads .bag files written by 'rosbag record'")
        index_pos = _bag_header_index_pos(f)
    if index_pos is None:
        raise InputError(f"{path}: truncated ROS 1 bag (its header is incomplete, {size} bytes)",
                         "copy the file again whole")
    if index_pos == 0:
        raise InputError(f"{path}: the ROS 1 bag has no index (a recording that did not finish)",
                         "run 'rosbag reindex' on it (ROS 1), then read it again")
    if index_pos >= size:
        raise InputError(f"{path}: truncated ROS 1 bag (its index should start at byte {index_pos}, the file has "
                         f"{size} bytes)",
                         "copy the file again whole, or recover the messages before the cut with 'rosbag "
                         "reindex' (ROS 1)")


def _bag_header_index_pos(f: Any) -> int | None:
    """The ``index_pos`` field of a ROS 1 bag's header record (the stream is just past the magic)."""
    raw = f.read(4)
    if len(raw) < 4:
        return None
    (length,) = struct.unpack("<I", raw)
    header = f.read(length)
    if len(header) < length:
        return None
    pos = 0
    while pos + 4 <= length:
        (n,) = struct.unpack_from("<I", header, pos)
        name, _, value = header[pos + 4 : pos + 4 + n].partition(b"=")
        if name == b"index_pos" and len(value) == 8:
            return struct.unpack("<Q", value)[0]
        pos += 4 + n
    return None


def _bound_chunks(reader: Any, path: Path) -> None:
    """Make every compressed chunk of an open ROS 1 reader inflate within bounds (:mod:`.inflate`:
    at most the size its header declares)."""
    from rosbags.rosbag1.reader import Header, RecordType

    with open(path, "rb") as f:
        for pos, chunk in list(reader.chunks.items()):
            f.seek(pos)
            header = Header.read(f, RecordType.CHUNK)
            declared, compression = header.get_uint32("size"), header.get_string("compression")
            where = f"{path}: the ROS 1 chunk at byte {pos}"
            check_declared(declared, where)
            if compression in ("bz2", "lz4"):
                reader.chunks[pos] = chunk._replace(
                    decompressor=lambda data, c=compression, n=declared, w=where: inflate(data, c, n, w))


@contextlib.contextmanager
def _bounded_ros2_chunks(path: Path) -> Iterator[None]:
    """While reading, what ``rosbags`` inflates of a ROS 2 bag stays within bounds (:mod:`.inflate`):
    the chunks of its MCAP storage (through the table ``rosbags.rosbag2.storage_mcap.DECOMPRESSORS``
    of (data, declared size)) and zstd-compressed messages (through the ``zstd`` module
    ``rosbags.rosbag2.reader`` calls), each without a bound in ``rosbags``.
    """
    import types

    from rosbags.rosbag2 import reader as bag_reader
    from rosbags.rosbag2 import storage_mcap

    table = storage_mcap.DECOMPRESSORS
    saved, real_zstd = dict(table), bag_reader.zstd
    chunk, message = f"{path}: an MCAP chunk of the ROS 2 bag", f"{path}: a compressed message of the ROS 2 bag"
    for compression in ("lz4", "zstd"):
        table[compression] = lambda data, size, c=compression: inflate(data, c, size, chunk)
    bag_reader.zstd = types.SimpleNamespace(open=real_zstd.open,
                                            decompress=lambda data: inflate(data, "zstd", None, message))
    try:
        yield
    finally:
        table.update(saved)
        bag_reader.zstd = real_zstd
