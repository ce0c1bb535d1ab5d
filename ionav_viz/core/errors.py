"""The tool's own error for bad input; the CLI turns it into one line and exit code 2."""

from __future__ import annotations

import re
from typing import Any

#: numpy's repr of a scalar (``np.float64(60648.34)``, ``np.int64(3)``, ``np.True_``), as printed in
#: an f-string's ``{x!r}`` or inside a tuple or list.
_NUMPY_REPR = re.compile(r"\bnp\.(?:float|int|uint|complex|bool|str|bytes)_?\d*\((.*?)\)|\bnp\.(True|False)_")


def plain(value: Any) -> Any:
    """``value`` as a message should show it: numpy scalars as Python numbers, arrays as lists,
    recursively in tuples, lists and dicts (``f"{plain(x)!r}"`` prints ``60648.34``, never
    ``np.float64(60648.34)``)."""
    if hasattr(value, "tolist") and type(value).__module__ == "numpy":
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return type(value)(plain(v) for v in value)
    if isinstance(value, dict):
        return {plain(k): plain(v) for k, v in value.items()}
    return value


def plain_text(text: str) -> str:
    """``text`` with numpy's scalar reprs as plain numbers (``stamp np.float64(60648.34)`` ->
    ``stamp 60648.34``): the one place every message passes (errors here, warnings in their handlers)."""
    return (_NUMPY_REPR.sub(lambda m: m.group(1) if m.group(1) is not None else m.group(2), text)
            if "np." in text else text)


def printable(text: str) -> str:
    """``text`` safe to print on a terminal: every character that is not printable (control
    characters such as ESC, which starts a terminal's commands, line breaks, tabs, Unicode format
    and separator characters such as a right-to-left override) escaped as Python's ``repr`` writes
    it (``\\x1b``, ``\\n``, ``\\u202e``), for text that comes from a file's content or a user's
    argument: it can neither clear the screen nor forge a line of its own."""
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in text)


class InputError(Exception):
    """Bad user input: a file, row, column, option or model that cannot be used.

    ``str(err)`` is one line naming what is wrong; ``hint`` says how to fix it. ``param`` names
    the API argument the problem is about (``"outage_s"``, ``"placement"``, ``"model"``...), so
    the command line can name its option instead.
    """

    def __init__(self, message: str, hint: str | None = None, param: str | None = None) -> None:
        message, hint = plain_text(message), None if hint is None else plain_text(hint)
        super().__init__(message)
        self.message = message
        self.hint = hint
        self.param = param
        self.option: str | None = None  # the command-line option that set ``param``, when a command says

    def __str__(self) -> str:
        return f"{self.message} (hint: {self.hint})" if self.hint else self.message


class ToolFailure(RuntimeError):
    """Something outside the user's input failed (network, renderer): one line, exit code 1."""

    def __init__(self, message: str = "", *args: Any) -> None:
        super().__init__(plain_text(str(message)), *args)
