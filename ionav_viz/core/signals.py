"""Stopping cleanly on SIGTERM and SIGHUP as on Ctrl-C.

The command line turns SIGTERM and SIGHUP into a :class:`Terminated` exception (SIGINT already is
``KeyboardInterrupt``), so every ``finally`` and cleanup runs: no temporary file or viewer process
is left, and the exit code is 128 + the signal number (143 for SIGTERM, 129 for SIGHUP).
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Callable, Iterator
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


def raise_terminated(signum: int, frame: Any) -> None:
    """A signal handler: raise :class:`Terminated`."""
    raise Terminated(signum)


def raise_on_stop_signals() -> None:
    """Make SIGTERM and SIGHUP raise :class:`Terminated` (in the main thread)."""
    for sig in STOP_SIGNALS:
        with contextlib.suppress(ValueError):  # not the main thread
            signal.signal(sig, raise_terminated)


def hold_signals() -> Callable[[], None]:
    """Hold SIGINT, SIGTERM and SIGHUP back until the returned ``release()`` is called.

    Call ``release()`` inside the ``try`` whose cleanup must run: a signal that arrived while held
    is acted on during ``release()`` (its previous handler runs, raising ``KeyboardInterrupt`` or
    :class:`Terminated`), so it raises inside that ``try``. Python runs signal handlers in the main
    thread only, so a deferring handler closes the window whichever thread the signal reached
    (blocking the signal with ``pthread_sigmask`` would not: other threads could still take it).
    Outside the main thread this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    pending: list[int] = []
    sigs = (signal.SIGINT, *STOP_SIGNALS)
    previous = {sig: signal.signal(sig, lambda signum, frame: pending.append(signum)) for sig in sigs}
    released: list[bool] = []

    def release() -> None:
        if released:
            return
        released.append(True)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if pending:
            signum, handler = pending[0], previous[pending[0]]
            if callable(handler):
                handler(signum, None)  # raises KeyboardInterrupt or Terminated
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), signum)  # the default action, as if never held

    return release


@contextlib.contextmanager
def signals_surfaced() -> Iterator[None]:
    """Keep SIGINT, SIGTERM and SIGHUP stopping a call into a library that swallows the exception
    their handler raises: pandas' C parser turns a ``KeyboardInterrupt`` raised inside its
    ``read()`` into a ``ParserError`` ("Calling read(nbytes) on source failed"), so Ctrl-C while
    a CSV was read said the file was not a readable CSV (exit code 2). While the block runs, the
    exception each such handler raises is kept; when the block ends with another ``Exception`` or
    with none, the kept one is raised again (``KeyboardInterrupt`` or :class:`Terminated`). A
    handler is never run twice. Outside the main thread this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    raised: list[BaseException] = []
    previous: dict[int, Any] = {}
    for sig in (signal.SIGINT, *STOP_SIGNALS):
        handler = signal.getsignal(sig)
        if callable(handler):  # SIG_DFL ends the process and SIG_IGN does nothing: neither is swallowed

            def keeping(signum: int, frame: Any, handler: Callable[[int, Any], Any] = handler) -> None:
                try:
                    handler(signum, frame)
                except BaseException as exc:
                    raised.append(exc)
                    raise

            previous[sig] = signal.signal(sig, keeping)
    try:
        yield
    except Exception:
        if raised:
            raise raised[0] from None
        raise
    else:
        if raised:
            raise raised[0]
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
