"""Durations as people type them: ``'10s'``, ``'500ms'``, ``'1m30s'``, ``'2h'`` or plain seconds."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from .errors import InputError


class NotADuration(InputError):
    """The text is not a duration at all (``'ten'``), as against one that is not positive (``'0s'``)."""


_DURATION = re.compile(r"^\s*(?:(\d+(?:\.\d+)?)h)?\s*(?:(\d+(?:\.\d+)?)m(?!s))?"
                       r"\s*(?:(\d+(?:\.\d+)?)s)?\s*(?:(\d+(?:\.\d+)?)ms)?\s*$")


def parse_duration_s(text: str | float, what: str = "duration", allow_zero: bool = False) -> float:
    """``'10s'``, ``'500ms'``, ``'1m'``, ``'1m30s'``, ``'2h'`` or a plain number of seconds -> seconds
    (> 0; >= 0 with ``allow_zero``)."""
    value = str(text).strip().lower()
    try:
        seconds = float(value)
    except ValueError:
        match = _DURATION.match(value)
        if not value or not match or not any(match.groups()):
            raise NotADuration(f"{what} {text!r} is not a duration", "use e.g. 10s, 500ms, 1m") from None
        h, m, s, ms = (float(g) if g else 0.0 for g in match.groups())
        seconds = h * 3600 + m * 60 + s + ms / 1000
    if not math.isfinite(seconds) or seconds < 0 or (seconds == 0 and not allow_zero):
        raise InputError(f"{what} {text!r} must be a positive duration")
    return seconds


@dataclass(frozen=True)
class Span:
    """A stretch of a drive on the drive's own time (s since its first sample): ``start_s`` to
    ``end_s`` (None: to the end), both included. ``str(span)`` is how it is typed (``0s:330s``)."""

    start_s: float = 0.0
    end_s: float | None = None

    def __post_init__(self) -> None:
        for name, value in (("start", self.start_s), ("end", self.end_s)):
            if value is None and name == "end":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise InputError(f"span {name} {value!r} is not a time of at least 0 s", SPAN_HINT, param="span")
        if self.end_s is not None and self.end_s <= self.start_s:
            raise InputError(f"span {self}: its end is not after its start", SPAN_HINT, param="span")

    def __str__(self) -> str:
        # 12 digits: what --span takes back (':g' kept 6: 3600.125s printed as 3600.12s, 1234567s as 1.23457e+06s)
        return f"{self.start_s:.12g}s:" + ("" if self.end_s is None else f"{self.end_s:.12g}s")

    def contains(self, t_s: np.ndarray, tolerance_s: float = 1e-6) -> np.ndarray:
        """Which times lie in the span (both ends included, to ``tolerance_s``: a sample stamped a
        millisecond off an end is on it with :func:`ionav_viz.core.grid.stamp_tolerance_s`)."""
        t_s = np.asarray(t_s, dtype=np.float64)
        inside = t_s >= self.start_s - tolerance_s
        return inside if self.end_s is None else inside & (t_s <= self.end_s + tolerance_s)


SPAN_HINT = "give START:END on the drive's own time, e.g. 0s:330s, 330s: or :5m"


def parse_span(value: str | Span | tuple | None) -> Span | None:
    """``'0s:330s'``, ``'330s:'``, ``':5m'``, a ``(start_s, end_s)`` pair or a :class:`Span` -> a
    :class:`Span` (None stays None); anything else is an :class:`InputError` naming ``span``."""
    if value is None or isinstance(value, Span):
        return value
    if isinstance(value, (tuple, list)) and len(value) == 2:
        start, end = value
        return Span(0.0 if start is None else start, end)
    if not isinstance(value, str) or value.count(":") != 1:
        raise InputError(f"span {value!r} is not START:END", SPAN_HINT, param="span")
    start_text, end_text = (part.strip() for part in value.split(":"))

    def seconds(text: str) -> float:
        if text.strip().lower() in ("0", "0s", "0.0", "0ms"):
            return 0.0
        try:
            return parse_duration_s(text, "span")
        except InputError:
            raise InputError(f"span {value!r}: {text!r} is not a time", SPAN_HINT, param="span") from None

    return Span(seconds(start_text) if start_text else 0.0, seconds(end_text) if end_text else None)
