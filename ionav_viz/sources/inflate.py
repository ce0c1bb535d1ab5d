"""Decompressing a log's chunks within bounds: a chunk inflates at most to the size its header
declares, itself at most :data:`MAX_CHUNK_BYTES`, so a damaged or crafted file (a compression
bomb: kilobytes that inflate to gigabytes) is refused before it fills memory. Used by the ROS 1
bag and MCAP readers (MCAP files and ROS 2 bags' MCAP storage), whose chunk headers declare the
uncompressed size."""

from __future__ import annotations

from ..core.errors import InputError

#: The most one chunk may inflate to ('rosbag record' writes 768 KiB chunks by default, MCAP
#: writers 1-8 MiB); more is a damaged or crafted file.
MAX_CHUNK_BYTES = 256 * 2**20

_HINT = "copy the file again, or re-record it"


class InflatedPast(InputError):
    """A chunk's data inflates past the size its header declares (or, with none declared, past
    :data:`MAX_CHUNK_BYTES`)."""


def check_declared(declared: int, where: str) -> None:
    """Refuse a chunk whose header declares more than :data:`MAX_CHUNK_BYTES` uncompressed.
    ``where`` names it in the message (``"FILE: the ROS 1 chunk at byte N"``)."""
    if declared > MAX_CHUNK_BYTES:
        raise InputError(f"{where} declares {declared / 2**20:.0f} MiB of messages, more than the "
                         f"{MAX_CHUNK_BYTES // 2**20} MiB ionav-viz inflates (a damaged or crafted file)", _HINT)


def inflate(data: bytes, compression: str, declared: int | None, where: str) -> bytes:
    """``data`` decompressed (``"bz2"``, ``"lz4"`` or ``"zstd"``; concatenated streams as their
    libraries read them), stopping as soon as the output passes ``declared`` bytes (None: where
    the format declares no size, :data:`MAX_CHUNK_BYTES`)."""
    if declared is None:
        try:
            return inflate(data, compression, MAX_CHUNK_BYTES, where)
        except InflatedPast:
            raise InflatedPast(f"{where} inflates past {MAX_CHUNK_BYTES // 2**20} MiB, more than ionav-viz inflates "
                               "(a damaged or crafted file: a compression bomb)", _HINT) from None
    check_declared(declared, where)
    if compression == "zstd":
        return _inflate_zstd(data, declared, where)
    out = bytearray()
    while data:
        if compression == "lz4":  # lz4 allocates a frame's stated content size whatever max_length says
            _check_lz4_frame(data, declared - len(out), where)
        stream = _decompressor(compression)
        out += stream.decompress(data, max_length=declared + 1 - len(out))
        if len(out) > declared:
            raise InflatedPast(f"{where} inflates past the {declared} bytes its header declares (a damaged or "
                               "crafted file: a compression bomb)", _HINT)
        if not stream.eof:
            raise InputError(f"{where}: its {compression} data is cut short (a damaged file)", _HINT)
        data = stream.unused_data
    return bytes(out)


def _inflate_zstd(data: bytes, declared: int, where: str) -> bytes:
    import io

    import zstandard

    try:
        with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data), read_across_frames=True) as reader:
            out = reader.read(declared + 1)
    except zstandard.ZstdError as exc:
        raise InputError(f"{where}: its zstd data is damaged ({exc})", _HINT) from None
    if len(out) > declared:
        raise InflatedPast(f"{where} inflates past the {declared} bytes its header declares (a damaged or "
                           "crafted file: a compression bomb)", _HINT)
    return out


def _check_lz4_frame(data: bytes, room: int, where: str) -> None:
    import lz4.frame

    try:
        stated = lz4.frame.get_frame_info(data).get("content_size", 0)
    except RuntimeError:
        raise InputError(f"{where}: its lz4 data is damaged", _HINT) from None
    if stated > room:
        raise InflatedPast(f"{where} inflates past the {room} bytes its header declares (a damaged or crafted file: "
                         "a compression bomb)", _HINT)


def _decompressor(compression: str):
    if compression == "bz2":
        import bz2

        return bz2.BZ2Decompressor()
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.LZ4FrameDecompressor()
    raise ValueError(f"not a bounded compression: {compression!r}")
