"""JSON output: every value a JSON file or ``--json`` prints passes :func:`plain_json` once, here.

Reports, the report a recording carries, exports and outage plans hold what numpy and plug-ins
give them: numpy scalars and arrays, NaN and infinities, tuples, paths. JSON has none of those
(and Python's ``json`` writes NaN as the invalid token ``NaN``), so :func:`plain_json` turns them
into JSON's own types, and :func:`dumps_json` writes the result, refusing anything left over:

* NaN, +inf and -inf become ``null``;
* numpy scalars become numbers or booleans, arrays (any shape) nested lists, tuples and sets
  lists (sets sorted when they can be), paths strings, bytes UTF-8 text (undecodable bytes
  replaced), dates ISO 8601 text, enumerations their values, complex numbers their text;
* mapping keys become strings as ``json`` would make them (``1`` -> ``"1"``, ``None`` -> ``"null"``);
* anything else becomes its ``str()``.

A value nested deeper than :data:`MAX_DEPTH` (or the caller's limit) or holding itself is refused
with ``ValueError`` (the caller names where it came from: a plug-in's ``describe()`` is one line
naming the plug-in).
"""

from __future__ import annotations

import contextlib
import datetime
import enum
import json
import math
from collections.abc import Mapping
from pathlib import PurePath
from typing import Any

import numpy as np

#: Deeper than this a value is refused: a report is six levels deep, a plug-in's description at
#: most :data:`~ionav_viz.nav.protocol.DESCRIBE_MAX_DEPTH` inside it; readers take 64 (core.fileio).
MAX_DEPTH = 48


def is_finite_number(value: Any) -> bool:
    """A JSON number that is finite (a boolean is not a number here)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def plain_json(value: Any, max_depth: int = MAX_DEPTH) -> Any:
    """``value`` as JSON's own types: dict (string keys), list, str, int, float (finite), bool or
    None (see the module docstring). ValueError for a value nested deeper than ``max_depth``
    arrays and objects, or holding itself."""
    return _plain(value, 0, set(), max_depth)


#: A list of more objects than this is written one object to a line (see :func:`dumps_json`).
ROWS_FROM = 20


def dumps_json(value: Any, indent: int | None = 2) -> str:
    """``json.dumps`` of :func:`plain_json` of ``value``: valid JSON whatever numpy or a plug-in gave.

    Indented, objects and lists open one level a line, but a long list of objects (a report's
    outages: more than :data:`ROWS_FROM`) one object to a line, and a list of plain values on one
    line: Python's indenting encoder is pure Python (4.6 s for a 240-drive-hour fleet's 86,000
    outages, 2.8 s this way), the compact one is C, and a row per outage reads and diffs as well."""
    plain = plain_json(value)
    if indent is None:
        return json.dumps(plain, allow_nan=False)
    return _indented(plain, indent, 0, json.JSONEncoder(allow_nan=False, separators=(", ", ": ")))


def _indented(value: Any, indent: int, level: int, row: json.JSONEncoder) -> str:
    pad, end = " " * (indent * (level + 1)), " " * (indent * level)
    if isinstance(value, dict) and value:
        items = (f"{pad}{json.dumps(k)}: {_indented(v, indent, level + 1, row)}" for k, v in value.items())
        return "{\n" + ",\n".join(items) + "\n" + end + "}"
    if isinstance(value, list) and value:
        if len(value) > ROWS_FROM and all(isinstance(v, dict) for v in value):
            return "[\n" + ",\n".join(pad + row.encode(v) for v in value) + "\n" + end + "]"
        if any(isinstance(v, (dict, list)) for v in value):
            return "[\n" + ",\n".join(pad + _indented(v, indent, level + 1, row) for v in value) + "\n" + end + "]"
    return row.encode(value)


def _plain(value: Any, depth: int, path: set[int], max_depth: int = MAX_DEPTH) -> Any:
    kind = type(value)
    if kind is float:  # the common cases first, by exact type: a report is mostly floats in dicts and lists
        return value if math.isfinite(value) else None
    if value is None or kind is str or kind is int or kind is bool:
        return value
    if kind is dict or kind is list or kind is tuple:
        return _nested(value, depth, path, max_depth)
    if isinstance(value, (bool, str)):
        return value
    if isinstance(value, int):
        return int(value)  # an int subclass (IntEnum's member is an Enum: handled below) prints as a number
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.generic):
        return _plain(value.item(), depth, path, max_depth)  # numpy bool, integer, floating, complex, str, datetime
    if isinstance(value, enum.Enum):
        return _plain(value.value, depth, path, max_depth)
    if isinstance(value, complex):
        return str(value)
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).decode("utf-8", "replace")
    if isinstance(value, (datetime.date, datetime.time)):
        return value.isoformat()
    if isinstance(value, (Mapping, list, tuple, set, frozenset, np.ndarray)):
        return _nested(value, depth, path, max_depth)
    return str(value)


def _nested(value: Any, depth: int, path: set[int], max_depth: int) -> Any:
    """A mapping, sequence, set or array: its items, each plain."""
    if depth >= max_depth:
        raise ValueError(f"is nested more than {max_depth} levels deep")
    if id(value) in path:
        raise ValueError("holds itself (a cycle)")
    path.add(id(value))
    try:
        kind = type(value)
        if kind is dict:
            return {k if type(k) is str else _key(k): _plain(v, depth + 1, path, max_depth) for k, v in value.items()}
        if kind is list or kind is tuple:
            return [_plain(v, depth + 1, path, max_depth) for v in value]
        if isinstance(value, np.ndarray):
            return _plain(value.tolist(), depth, path, max_depth)  # tolist gives Python scalars, nested per axis
        if isinstance(value, Mapping):
            return {k if type(k) is str else _key(k): _plain(v, depth + 1, path, max_depth) for k, v in value.items()}
        items = list(value)
        if isinstance(value, (set, frozenset)):
            with contextlib.suppress(TypeError):  # mixed types do not sort: as iterated
                items = sorted(items)
        return [_plain(v, depth + 1, path, max_depth) for v in items]
    finally:
        path.discard(id(value))


def _key(key: Any) -> str:
    """A mapping key as ``json`` writes one (it takes str, int, float, bool and None only)."""
    if isinstance(key, str):
        return key
    plain = _plain(key, 0, set())
    if isinstance(plain, str):
        return plain
    if plain is None or isinstance(plain, (bool, int, float)):
        return json.dumps(plain)
    return str(key)
