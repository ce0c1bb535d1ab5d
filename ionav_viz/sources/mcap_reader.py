"""MCAP logs (ROS 2 ``cdr`` or JSON messages): the MCAP format under the shared message-log reader.

What is read from which topic, stamps, rates and memory: :mod:`.message_log`. This module only
lists an MCAP file's channels (from its summary, or by streaming a file without one) and streams
the selected channels' messages: chunk by chunk when the file is complete and indexed (one chunk in
memory at a time; a topic whose messages in a chunk share one CDR layout is handed over as columns,
:func:`.cdr.decode_many`), else record by record (a recorder that stopped without a footer ends at
its last complete record). CRCs are checked; chunks inflate within bounds (:mod:`.inflate`).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import struct
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from .cdr import CdrType, fields_of
from .inflate import check_declared, inflate
from .message_log import Block, ChannelInfo, Columns, StreamBlock, decode_json, read_log

if TYPE_CHECKING:
    from .log_options import LogOptions

log = logging.getLogger("ionav_viz")

ENCODINGS = ("cdr", "json")

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
        raise InputError(f"{path}: not an MCAP file (no MCAP magic at the start)",
                         "ionav-viz reads .mcap logs and IO-VNBD .csv files")
    if tail == MAGIC and size >= 2 * len(MAGIC):
        return "complete"
    end = _last_record_end(path, size)
    if end == size and end > len(MAGIC):
        return "unterminated"
    raise InputError(f"{path}: truncated MCAP file (cut off inside a record; the last whole record ends at byte "
                     f"{end} of {size})",
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
            out.append(ChannelInfo(ch.topic, schema.name if schema else "", ch.message_encoding,
                                   int(counts.get(cid, 0))))
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


class McapLog:
    """An MCAP file as a :class:`~.message_log.MessageLog`."""

    encodings = ENCODINGS

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def channels(self) -> list[ChannelInfo]:
        return list_channels(self.path)

    def damaged(self, exc: BaseException) -> InputError:
        return _bad(self.path, exc)

    def messages(self, channels: list[ChannelInfo]) -> Iterator[tuple[str, int, Any]]:
        for block in self.blocks(channels):
            yield from block.messages()

    def blocks(self, channels: list[ChannelInfo]) -> Iterator[Block]:
        """The messages of ``channels`` chunk by chunk (:class:`~.message_log.Block`) when the file is
        complete and indexed, else all of them as one block, streamed (:func:`iter_messages`)."""
        path = self.path
        topics = [c.topic for c in channels]
        decoders = _Decoders(path)
        with open(path, "rb") as f:
            summary = _open_reader(f).get_summary() if _check_framing(path) == "complete" else None
            if summary is None or not summary.chunk_indexes:
                yield StreamBlock(decoders.message(schema, channel, message.data, message.log_time)
                              for schema, channel, message in iter_messages(path, f, topics))
                return
            with _bounded_chunks(path):
                for chunk in _indexed_chunks(path, f, summary, topics):
                    yield _Block(decoders, summary, *chunk)


class _Decoders:
    """Each channel's decoder, made at its first message: JSON, rosbags (:func:`cdr_decoder`), else mcap_ros2."""

    def __init__(self, path: Path) -> None:
        from mcap_ros2.decoder import DecoderFactory

        self.path, self.factory = path, DecoderFactory()
        self.cdr: dict[int, CdrType | None] = {}
        self.other: dict[int, Callable[[bytes], Any]] = {}

    def message(self, schema: Any, channel: Any, data: bytes, log_time_ns: int) -> tuple[str, int, Any]:
        """``(topic, log time ns, decoded message)``."""
        if channel.message_encoding == "json":
            return channel.topic, log_time_ns, decode_json(self.path, channel.topic, data, log_time_ns)
        if (found := self.cdr_type(schema, channel)) is not None:
            return channel.topic, log_time_ns, found.decode(data)
        if channel.id not in self.other:
            decoder = self.factory.decoder_for(channel.message_encoding, schema)
            if decoder is None:
                raise InputError(f"{self.path}: topic {channel.topic}: cannot decode {channel.message_encoding} "
                                 f"with schema encoding {schema.encoding if schema else None!r}")
            self.other[channel.id] = decoder
        return channel.topic, log_time_ns, self.other[channel.id](data)

    def cdr_type(self, schema: Any, channel: Any) -> CdrType | None:
        """The channel's rosbags decoder, or None where rosbags does not decode it."""
        if channel.id not in self.cdr:
            self.cdr[channel.id] = cdr_decoder(channel.message_encoding, schema)
        return self.cdr[channel.id]


def cdr_decoder(encoding: str, schema: Any) -> CdrType | None:
    """A decoder of ``cdr`` messages of a ``ros2msg`` schema built by rosbags (several times faster
    than mcap_ros2's, the same values; number arrays as numpy arrays), or None where rosbags cannot
    read the schema (mcap_ros2 decodes those)."""
    if encoding != "cdr" or schema is None or schema.encoding != "ros2msg":
        return None
    definition = bytes(schema.data)
    parse = _parsed_type if len(definition) <= CACHED_DEFINITION_BYTES else _parsed_type.__wrapped__
    return parse(schema.name, definition)


#: Message definitions up to this size (bytes; a standard one is a few KiB) are parsed once per process.
CACHED_DEFINITION_BYTES = 65536


@functools.lru_cache(maxsize=64)
def _parsed_type(name: str, definition: bytes) -> CdrType | None:
    """:func:`cdr_decoder`'s type (parsing a definition takes tens of ms)."""
    try:
        from rosbags.typesys import get_types_from_msg
        from rosbags.typesys.msg import normalize_msgtype

        from .rosbag_reader import typestore_of

        msgtype = normalize_msgtype(name)
        store = typestore_of(get_types_from_msg(definition.decode(), msgtype), msgtype)
    except Exception:  # a definition (or a rosbags release) rosbags does not parse with: left to mcap_ros2
        return None
    return CdrType(store, msgtype)


class _Block:
    """One chunk's messages of the chosen channels (a :class:`~.message_log.Block`): ``channel_ids``,
    ``log_ns`` (uint64) and each message's bytes ``data[starts[i]:starts[i] + sizes[i]]``."""

    def __init__(self, decoders: _Decoders, summary: Any, channel_ids: np.ndarray, log_ns: np.ndarray,
                 starts: np.ndarray, sizes: np.ndarray, data: bytes) -> None:
        self.decoders, self.summary = decoders, summary
        self.channel_ids, self.log_ns, self.starts, self.sizes, self.data = channel_ids, log_ns, starts, sizes, data

    def _schema(self, channel: Any) -> Any:
        return None if channel.schema_id == 0 else self.summary.schemas[channel.schema_id]

    def first_topic(self) -> str | None:
        return self.summary.channels[int(self.channel_ids[0])].topic if len(self.channel_ids) else None

    def messages(self) -> Iterator[tuple[str, int, Any]]:
        for cid, log_ns, start, size in zip(self.channel_ids.tolist(), self.log_ns.tolist(), self.starts.tolist(),
                                            self.sizes.tolist()):
            channel = self.summary.channels[cid]
            yield self.decoders.message(self._schema(channel), channel, self.data[start : start + size], log_ns)

    def columns(self, topic: str) -> Columns | None:
        ids = [cid for cid in np.unique(self.channel_ids).tolist() if self.summary.channels[cid].topic == topic]
        if not ids:
            return Columns(np.zeros(0, np.int64), {})
        if len(ids) > 1:
            return None
        channel = self.summary.channels[ids[0]]
        mine = self.channel_ids == ids[0]
        sizes, log_ns = self.sizes[mine], self.log_ns[mine]
        found = self.decoders.cdr_type(self._schema(channel), channel) if channel.message_encoding == "cdr" else None
        if found is None or found.layout() is None or (sizes != sizes[0]).any() or log_ns.max() >= 2**63:
            return None
        starts = self.starts[mine]
        fields = fields_of(found, np.frombuffer(self.data, np.uint8)[starts[:, None] + np.arange(sizes[0])])
        return None if fields is None else Columns(log_ns.astype(np.int64), fields)


def _indexed_chunks(path: Path, f: Any, summary: Any, topics: list[str]) -> Iterator[tuple]:
    """Each chunk holding messages of ``topics`` (by the summary's chunk indexes, in their order):
    the arguments of :class:`_Block`. Records are read with struct; a chunk whose records are not
    laid out plainly (one that overruns the chunk, a short message record, a schema or channel
    record that reads otherwise, a message on a channel the summary does not list) is read by the
    mcap package's own parser, which refuses it as it did."""
    import mcap.stream_reader as stream_reader
    from mcap.data_stream import ReadDataStream
    from mcap.records import Chunk, Message

    wanted = {cid for cid, channel in summary.channels.items() if channel.topic in topics}
    known = set(summary.channels)
    for index in summary.chunk_indexes:
        if not wanted.intersection(index.message_index_offsets):
            continue
        f.seek(index.chunk_start_offset + 1 + 8)
        chunk = Chunk.read(ReadDataStream(f))
        data = _inflated(path, chunk, validate_crc=True)
        found = _scan_chunk(data, wanted, known)
        if found is None:
            records = [r for r in stream_reader.breakup_chunk(chunk, validate_crc=True) if isinstance(r, Message)
                       and summary.channels[r.channel_id].topic in topics]  # an unknown channel: mcap's KeyError
            sizes = np.array([len(r.data) for r in records], np.int64)
            found = ([(r.channel_id, r.log_time, start, size) for r, start, size in
                      zip(records, np.cumsum(sizes) - sizes, sizes)], b"".join(r.data for r in records))
        rows, data = found
        table = np.array([r[0] for r in rows], np.int64), np.array([r[1] for r in rows], np.uint64)
        yield (*table, np.array([r[2] for r in rows], np.int64), np.array([r[3] for r in rows], np.int64), data)


_RECORD = struct.Struct("<BQ")
_MESSAGE = struct.Struct("<HIQQ")


def _scan_chunk(data: bytes, wanted: set[int], known: set[int]) -> tuple[list, bytes] | None:
    """``([(channel id, log time, start, size)...], data)`` of a chunk's messages on ``wanted``
    channels, or None when a record is not laid out plainly or a message's channel is not among
    the ``known`` ones (see :func:`_indexed_chunks`)."""
    from io import BytesIO

    from mcap.data_stream import ReadDataStream
    from mcap.records import Channel, Schema

    rows = []
    pos, end = 0, len(data)
    while pos < end:
        if pos + _RECORD.size > end:
            return None
        opcode, length = _RECORD.unpack_from(data, pos)
        body, pos = pos + _RECORD.size, pos + _RECORD.size + length
        if pos > end:
            return None
        if opcode == _OPCODE_MESSAGE:
            if length < _MESSAGE.size:
                return None
            channel_id, _, log_time, _ = _MESSAGE.unpack_from(data, body)
            if channel_id not in known:
                return None
            if channel_id in wanted:
                rows.append((channel_id, log_time, body + _MESSAGE.size, length - _MESSAGE.size))
        elif opcode in (_OPCODE_SCHEMA, _OPCODE_CHANNEL):
            stream = ReadDataStream(BytesIO(data[body:pos]))
            try:
                (Schema if opcode == _OPCODE_SCHEMA else Channel).read(stream)
            except Exception:
                return None
            if stream.count != length:
                return None
    return rows, data


_OPCODE_SCHEMA, _OPCODE_CHANNEL, _OPCODE_MESSAGE = 0x03, 0x04, 0x05


@contextlib.contextmanager
def _bounded_chunks(path: Path) -> Iterator[None]:
    """While reading, every chunk inflates within bounds (:mod:`.inflate`).

    Both of the ``mcap`` package's readers decompress each chunk through
    ``mcap.stream_reader.get_chunk_data_stream``, which bounds zstd by the chunk's declared size
    but inflates lz4 without limit; it has no hook, so for the time of a read that function is
    :func:`_inflated`, as for the chunks read here.
    """
    from io import BytesIO

    import mcap.stream_reader as stream_reader
    from mcap.data_stream import ReadDataStream

    real = stream_reader.get_chunk_data_stream

    def bounded(chunk: Any, validate_crc: bool = False):
        data = _inflated(path, chunk, validate_crc)
        return ReadDataStream(BytesIO(data)), len(data)

    stream_reader.get_chunk_data_stream = bounded
    try:
        yield
    finally:
        stream_reader.get_chunk_data_stream = real


def iter_messages(path: Path, f: Any, topics: list[str] | None) -> Iterator[tuple[Any, Any, Any]]:
    """The file's messages on ``topics``: indexed when it can be, else streamed (a file without a
    footer ends at its last complete record); chunks inflate within bounds."""
    from mcap.exceptions import EndOfFile
    from mcap.reader import NonSeekingReader

    with _bounded_chunks(path):
        if _check_framing(path) == "complete":
            yield from _open_reader(f).iter_messages(topics=topics, log_time_order=False)
            return
        try:
            yield from NonSeekingReader(f, validate_crcs=True).iter_messages(topics=topics, log_time_order=False)
        except EndOfFile:
            return


def _inflated(path: Path, chunk: Any, validate_crc: bool) -> bytes:
    """A chunk's records, inflated within bounds (:mod:`.inflate`) and, with ``validate_crc``,
    checked against the chunk's CRC as the mcap package checks it (its error)."""
    import zlib

    from mcap.stream_reader import CRCValidationError

    where = f"{path}: the MCAP chunk of messages from log time {chunk.message_start_time} ns"
    check_declared(chunk.uncompressed_size, where)
    if chunk.compression == "lz4":
        data = inflate(chunk.data, "lz4", chunk.uncompressed_size, where)
    elif chunk.compression == "zstd":
        import zstandard

        data = zstandard.decompress(chunk.data, chunk.uncompressed_size)
    else:  # none, or a compression the mcap package does not know: its records as they are
        data = chunk.data
    if validate_crc and chunk.uncompressed_crc != 0 and zlib.crc32(data) != chunk.uncompressed_crc:
        raise CRCValidationError(expected=chunk.uncompressed_crc, actual=zlib.crc32(data), record=chunk)
    return data


def read_mcap(path: str | Path, options: LogOptions | None = None, *, name: str | None = None,
              yaw_sign: str = "auto") -> Drive:
    """Read an MCAP log into a drive on a 10 Hz grid (see :mod:`.message_log`), its topics, stamps
    and IMU frame as ``options`` say (default :class:`~.log_options.LogOptions`: each found)."""
    from .log_options import LogOptions

    return read_log(McapLog(path), options if options is not None else LogOptions(), name=name, yaw_sign=yaw_sign)
