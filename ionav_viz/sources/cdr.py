"""ROS 2's CDR serialisation (little endian, ``CDR_LE``) of many fixed-layout messages at once.

A message whose fields are numbers, fixed-size arrays of numbers and strings that are the same in
every message (a ``frame_id``) has the same bytes layout in every message, so all of them are
written as one ``(messages, bytes)`` array, column by column. Alignment follows the CDR rule:
a value of ``k`` bytes starts at a multiple of ``k`` counted from the end of the 4-byte
encapsulation header; a string is its ``uint32`` length (with the terminating NUL), its bytes
and the NUL. Nothing pads the end, as ``rclpy`` and ``mcap_ros2`` write it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: The numeric kinds a field may be (numpy's little-endian type codes).
CDR_KINDS = ("i1", "u1", "u2", "i4", "u4", "f8")
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
