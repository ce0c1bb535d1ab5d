"""The tool's own error for bad input; the CLI turns it into one line and exit code 2."""

from __future__ import annotations


class InputError(Exception):
    """Bad user input: a file, row, column, option or model that cannot be used.

    ``str(err)`` is one line naming what is wrong; ``hint`` says how to fix it. ``param`` names
    the API argument the problem is about (``"outage_s"``, ``"placement"``, ``"model"``...), so
    the command line can name its option instead.
    """

    def __init__(self, message: str, hint: str | None = None, param: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint
        self.param = param
        self.option: str | None = None  # the command-line option that set ``param``, when a command says

    def __str__(self) -> str:
        return f"{self.message} (hint: {self.hint})" if self.hint else self.message


class ToolFailure(RuntimeError):
    """Something outside the user's input failed (network, renderer): one line, exit code 1."""
