"""MCAP logs (ROS 2 ``cdr`` or JSON messages): the MCAP format under the shared message-log reader.

What is read from which topic, stamps, rates and memory: :mod:`.message_log`. This module only
lists an MCAP file's channels (from its summary, or by streaming a file without one) and streams
the selected channels' decoded messages: indexed when the file is complete, else record by record
(a recorder that stopped without a footer ends at its last complete record). CRCs are checked.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..core.drive import Drive
from ..core.errors import InputError
from .inflate import check_declared, inflate
from .message_log import ChannelInfo, decode_json, read_log

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
        from mcap_ros2.decoder import DecoderFactory

        path = self.path
        factory = DecoderFactory()
        decoders: dict[int, Any] = {}
        with open(path, "rb") as f:
            for schema, channel, message in iter_messages(path, f, [c.topic for c in channels]):
                if channel.message_encoding == "json":
                    decoded = decode_json(path, channel.topic, message.data, message.log_time)
                else:
                    if channel.id not in decoders:
                        decoder = cdr_decoder(channel.message_encoding, schema) or factory.decoder_for(
                            channel.message_encoding, schema)
                        if decoder is None:
                            raise InputError(f"{path}: topic {channel.topic}: cannot decode {channel.message_encoding} "
                                             f"with schema encoding {schema.encoding if schema else None!r}")
                        decoders[channel.id] = decoder
                    decoded = decoders[channel.id](message.data)
                yield channel.topic, message.log_time, decoded


def cdr_decoder(encoding: str, schema: Any) -> Callable[[bytes], Any] | None:
    """A decoder of ``cdr`` messages of a ``ros2msg`` schema built by rosbags (several times faster
    than mcap_ros2's, the same values; number arrays as numpy arrays), or None where rosbags cannot
    read the schema (mcap_ros2 decodes those)."""
    if encoding != "cdr" or schema is None or schema.encoding != "ros2msg":
        return None
    try:
        from rosbags.typesys import get_types_from_msg
        from rosbags.typesys.msg import normalize_msgtype

        from .rosbag_reader import typestore_of

        msgtype = normalize_msgtype(schema.name)
        store = typestore_of(get_types_from_msg(schema.data.decode(), msgtype), msgtype)
    except Exception:  # a definition (or a rosbags release) rosbags does not parse with: left to mcap_ros2
        return None
    return lambda data: store.deserialize_cdr(data, msgtype)


def iter_messages(path: Path, f: Any, topics: list[str]) -> Iterator[tuple[Any, Any, Any]]:
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


@contextlib.contextmanager
def _bounded_chunks(path: Path) -> Iterator[None]:
    """While reading, every chunk inflates within bounds (:mod:`.inflate`).

    Both of the ``mcap`` package's readers decompress each chunk through
    ``mcap.stream_reader.get_chunk_data_stream``, which bounds zstd by the chunk's declared size
    but inflates lz4 without limit; it has no hook, so for the time of a read that function checks
    the declared size first and inflates lz4 here.
    """
    import mcap.stream_reader as stream_reader

    real = stream_reader.get_chunk_data_stream

    def bounded(chunk: Any, validate_crc: bool = False):
        where = f"{path}: the MCAP chunk of messages from log time {chunk.message_start_time} ns"
        check_declared(chunk.uncompressed_size, where)
        if chunk.compression == "lz4":
            chunk = dataclasses.replace(chunk, compression="",
                                        data=inflate(chunk.data, "lz4", chunk.uncompressed_size, where))
        return real(chunk, validate_crc)

    stream_reader.get_chunk_data_stream = bounded
    try:
        yield
    finally:
        stream_reader.get_chunk_data_stream = real


def read_mcap(path: str | Path, options: LogOptions | None = None, *, name: str | None = None,
              yaw_sign: str = "auto") -> Drive:
    """Read an MCAP log into a drive on a 10 Hz grid (see :mod:`.message_log`), its topics, stamps
    and IMU frame as ``options`` say (default :class:`~.log_options.LogOptions`: each found)."""
    from .log_options import LogOptions

    return read_log(McapLog(path), options if options is not None else LogOptions(), name=name, yaw_sign=yaw_sign)
