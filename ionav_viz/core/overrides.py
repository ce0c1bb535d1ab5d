"""``NAME=VALUE`` overrides of a frozen dataclass of thresholds, each checked against its range.

Shared by the event detectors' ``--threshold`` and the GNSS quality checks' ``--gnss-limit``.
"""

from __future__ import annotations

import math
from dataclasses import fields, replace
from typing import TypeVar

from .errors import InputError

T = TypeVar("T")


def with_overrides(settings: T, pairs: list[str], ranges: dict[str, tuple[float, float]], what: str, param: str) -> T:
    """A copy of ``settings`` with ``['name=value', ...]`` applied.

    A tuple field takes ``LOW,HIGH`` (LOW <= HIGH), an int field a whole number; every value must
    lie in ``ranges[name]``. ``what`` names a setting in messages ("threshold"), ``param`` the API
    argument the CLI maps to its option.
    """
    known = [f.name for f in fields(settings)]  # type: ignore[arg-type]
    changes: dict[str, object] = {}
    for pair in pairs:
        name, _, value = pair.partition("=")
        name = name.strip().replace("-", "_")
        if name not in known:
            raise InputError(f"unknown {what} {pair!r}", f"choose from {', '.join(known)}, as NAME=VALUE", param=param)
        if not value.strip():
            raise InputError(f"{what} {pair!r}: no value", f"give it as {name}=VALUE", param=param)
        wants_pair = isinstance(getattr(settings, name), tuple)
        try:
            parsed = tuple(float(v) for v in value.split(",")) if wants_pair else float(value)
        except ValueError:
            kind = "two numbers LOW,HIGH" if wants_pair else "one number"
            raise InputError(f"{what} {pair!r}: {value!r} is not {kind}", param=param) from None
        values = parsed if isinstance(parsed, tuple) else (parsed,)
        low, high = ranges.get(name, (0.0, 1e6))
        if wants_pair and (len(values) != 2 or values[0] > values[1]):
            raise InputError(f"{what} {pair!r}: give two numbers LOW,HIGH with LOW <= HIGH", param=param)
        if not all(math.isfinite(v) and low <= v <= high for v in values):
            raise InputError(f"{what} {pair!r} is out of range", f"{name} takes values from {low:g} to {high:g}",
                             param=param)
        whole = isinstance(getattr(settings, name), int) and not wants_pair
        if whole and parsed != int(parsed):  # int() cut 4.5 satellites to 4 silently
            raise InputError(f"{what} {pair!r}: {value!r} is not a whole number",
                             f"{name} is a count, e.g. {name}={math.ceil(parsed)}", param=param)
        value_of = int(parsed) if whole else parsed
        if name in changes and changes[name] != value_of:  # the last one won silently
            raise InputError(f"{what} {name} given twice with different values ({changes[name]} and {value_of})",
                             "give each once", param=param)
        changes[name] = value_of
    return replace(settings, **changes)  # type: ignore[type-var]


def check_ranges(settings: object, ranges: dict[str, tuple[float, float]], what: str, param: str) -> None:
    """Refuse ``settings`` (a dataclass of thresholds) built with a value outside its range, as
    :func:`with_overrides` refuses one given as ``NAME=VALUE``: ``EventThresholds(hard_brake_g=-1)``
    was taken, and every hard brake found."""
    for f in fields(settings):  # type: ignore[arg-type]
        if f.name not in ranges:
            continue
        value = getattr(settings, f.name)
        values = value if isinstance(value, tuple) else (value,)
        low, high = ranges[f.name]
        ok = all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and low <= v <= high
                 for v in values)
        if isinstance(value, tuple):
            ok = ok and len(value) == 2 and value[0] <= value[1]
        if not ok:
            raise InputError(f"{what} {f.name}={value!r} is out of range",
                             f"{f.name} takes values from {low:g} to {high:g}"
                             + (" as (LOW, HIGH), LOW <= HIGH" if isinstance(value, tuple) else ""), param=param)
