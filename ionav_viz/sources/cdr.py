"""ROS 2's CDR serialisation (little endian, ``CDR_LE``) of many fixed-layout messages at once, both ways.

A message whose fields are numbers, fixed-size arrays of numbers and strings that are the same in
every message (a ``frame_id``) has the same bytes layout in every message, so all of them are
written as one ``(messages, bytes)`` array, column by column. Alignment follows the CDR rule:
a value of ``k`` bytes starts at a multiple of ``k`` counted from the end of the 4-byte
encapsulation header; a string is its ``uint32`` length (with the terminating NUL), its bytes
and the NUL. Nothing pads the end, as ``rclpy`` and ``mcap_ros2`` write it (a reader allows up to
3 bytes of padding, as rosbags does).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

#: The numeric kinds a field may be (numpy's little-endian type codes).
CDR_KINDS = ("i1", "u1", "i2", "u2", "i4", "u4", "i8", "u8", "f4", "f8")
#: The encapsulation header of little-endian plain CDR.
CDR_HEADER = b"\x00\x01\x00\x00"


def encode_many(fields: Sequence[tuple[str, object]], n: int) -> np.ndarray:
    """``n`` messages, each the CDR of ``fields`` in their order, as an ``(n, bytes)`` uint8 array.

    A field is ``(kind, values)``: ``kind`` one of :data:`CDR_KINDS` with ``values`` a scalar (the same
    in every message), an ``(n,)`` array (one value per message), an ``(n, k)`` array (a ``k``-element
    array field) or a ``(1, k)`` one (the same array in every message); or ``("string", text)``, the
    same text in every message."""
    placed: list[tuple[int, np.ndarray]] = []  # (offset after the header, (n, k) values)
    end = 0
    for kind, values in fields:
        if kind == "string":
            text = str(values).encode() + b"\0"
            end += -end % 4
            constant = np.frombuffer(np.uint32(len(text)).astype("<u4").tobytes() + text, np.uint8)
            placed.append((end, np.broadcast_to(constant, (n, constant.size))))
            end += 4 + len(text)
            continue
        if kind not in CDR_KINDS:
            raise ValueError(f"unknown CDR kind {kind!r}")
        array = np.asarray(values, dtype="<" + kind)
        width = array.shape[1] if array.ndim == 2 else 1
        end += -end % array.itemsize
        placed.append((end, np.broadcast_to(array.reshape(-1, width), (n, width))))
        end += array.itemsize * width
    out = np.zeros((n, len(CDR_HEADER) + end), np.uint8)
    out[:, : len(CDR_HEADER)] = np.frombuffer(CDR_HEADER, np.uint8)
    for offset, values in placed:
        start = len(CDR_HEADER) + offset
        out[:, start : start + values.itemsize * values.shape[1]].view(values.dtype)[:] = values
    return out


def decode_many(fields: Sequence[tuple[str, int]], data: np.ndarray) -> list | None:
    """The values of ``n`` messages of one layout, read from their CDR bytes ``data`` (an ``(n, bytes)``
    uint8 array): the inverse of :func:`encode_many`.

    A field is ``(kind, count)``: ``kind`` one of :data:`CDR_KINDS` gives an ``(n,)`` array when
    ``count`` is 0 (a single value) and an ``(n, count)`` one otherwise (a fixed-size array field);
    ``"string"`` gives its text, which must be the same in every message. None when the messages do
    not all have that layout (or there are none): another encapsulation than little-endian plain CDR, a string whose
    length or bytes differ between messages, one not NUL-terminated or not UTF-8, or a message size
    that is not the layout's (plus at most 3 bytes of padding)."""
    header = np.frombuffer(CDR_HEADER, np.uint8)
    if not len(data) or data.shape[1] < len(CDR_HEADER) or (data[:, : len(CDR_HEADER)] != header).any():
        return None
    body = data[:, len(CDR_HEADER):]
    out: list = []
    end = 0
    for kind, count in fields:
        if kind == "string":
            end += -end % 4
            if end + 4 > body.shape[1]:
                return None
            length = int(body[0, end : end + 4].copy().view("<u4")[0])
            stop = end + 4 + length
            text = body[0, end + 4 : stop]
            if length < 1 or stop > body.shape[1] or text[-1] != 0 or (body[:, end:stop] != body[0, end:stop]).any():
                return None
            try:
                out.append(text[:-1].tobytes().decode())
            except UnicodeDecodeError:
                return None
            end = stop
            continue
        if kind not in CDR_KINDS:
            raise ValueError(f"unknown CDR kind {kind!r}")
        dtype = np.dtype("<" + kind)
        end += -end % dtype.itemsize
        stop = end + dtype.itemsize * max(count, 1)
        if stop > body.shape[1]:
            return None
        values = np.ascontiguousarray(body[:, end:stop]).view(dtype)
        out.append(values[:, 0] if count == 0 else values)
        end = stop
    if not end <= body.shape[1] <= end + 3:
        return None
    return out


def fields_of(cdr_type: CdrType, rows: np.ndarray) -> dict[str, Any] | None:
    """The messages ``rows`` (an ``(n, bytes)`` uint8 array of CDR messages of ``cdr_type``, every one
    the same size) as ``{field path: values}`` (:func:`decode_many`), or None where they cannot be read
    so: no fixed layout, bytes another layout's, or a first message rosbags refuses (then the caller reads
    them one by one, which says why)."""
    layout = cdr_type.layout()
    if layout is None or not len(rows):
        return None
    try:
        cdr_type.decode(rows[0].tobytes())
    except Exception:
        return None
    values = decode_many([(kind, count) for _, kind, count in layout], rows)
    return None if values is None else {name: v for (name, _, _), v in zip(layout, values)}


@dataclasses.dataclass
class CdrType:
    """A ``ros2msg`` message type as rosbags reads it."""

    store: Any
    msgtype: str
    _layout: list | None = None

    def decode(self, data: bytes) -> Any:
        return self.store.deserialize_cdr(data, self.msgtype)

    def layout(self) -> list[tuple[str, str, int]] | None:
        """The message's fields in CDR order as ``(path, kind, count)`` (:func:`decode_many`'s
        kinds and counts, strings included), or None when one has no fixed place (a sequence, an
        array of messages, a type :data:`CDR_KINDS` does not hold)."""
        if self._layout is None:
            self._layout = _flatten(self.store, self.msgtype, "") or []
        return self._layout or None


#: rosbags' base types that :func:`decode_many` reads, as its kinds.
_KINDS = {"int8": "i1", "uint8": "u1", "int16": "i2", "uint16": "u2", "int32": "i4", "uint32": "u4", "int64": "i8",
          "uint64": "u8", "float32": "f4", "float64": "f8", "string": "string"}


def _flatten(store: Any, msgtype: str, prefix: str) -> list[tuple[str, str, int]] | None:
    from rosbags.typesys.base import Nodetype

    out: list[tuple[str, str, int]] = []
    for name, (node, detail) in store.fielddefs[msgtype][1]:
        path = prefix + name
        if node == Nodetype.NAME:
            inner = _flatten(store, detail, path + ".")
            if inner is None:
                return None
            out += inner
        elif node == Nodetype.BASE and detail[0] in _KINDS and (detail[0] != "string" or not detail[1]):
            out.append((path, _KINDS[detail[0]], 0))
        elif (node == Nodetype.ARRAY and detail[0][0] == Nodetype.BASE and detail[0][1][0] in _KINDS
              and detail[0][1][0] != "string"):
            out.append((path, _KINDS[detail[0][1][0]], detail[1]))
        else:
            return None
    return out
