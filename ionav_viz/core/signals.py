"""Stopping cleanly on SIGTERM and SIGHUP as on Ctrl-C.

The command line turns SIGTERM and SIGHUP into a :class:`Terminated` exception (SIGINT already is
``KeyboardInterrupt``), so every ``finally`` and cleanup runs: no temporary file or viewer process
is left, and the exit code is 128 + the signal number (143 for SIGTERM, 129 for SIGHUP).
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator
from typing import Any

#: The signals that stop a command; SIGINT is Python's KeyboardInterrupt.
STOP_SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s is not None)


class Terminated(BaseException):
    """The process was asked to stop (SIGTERM or SIGHUP); ``signum`` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated(signum)


def raise_on_stop_signals() -> None:
    """Make SIGTERM and SIGHUP raise :class:`Terminated` (in the main thread)."""
    for sig in STOP_SIGNALS:
        with contextlib.suppress(ValueError):  # not the main thread
            signal.signal(sig, _raise_terminated)


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP back for the duration of the block (e.g. while a temporary
    file is created and its cleanup armed); they are delivered when the block ends."""
    sigs = {signal.SIGINT, *STOP_SIGNALS}
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    except (AttributeError, ValueError, OSError):  # no pthread_sigmask here
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
