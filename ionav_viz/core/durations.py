"""Durations as people type them: ``'10s'``, ``'500ms'``, ``'1m30s'``, ``'2h'`` or plain seconds."""

from __future__ import annotations

import math
import re

from .errors import InputError


class NotADuration(InputError):
    """The text is not a duration at all (``'ten'``), as against one that is not positive (``'0s'``)."""


_DURATION = re.compile(r"^\s*(?:(\d+(?:\.\d+)?)h)?\s*(?:(\d+(?:\.\d+)?)m(?!s))?\s*(?:(\d+(?:\.\d+)?)s)?\s*(?:(\d+(?:\.\d+)?)ms)?\s*$")


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
