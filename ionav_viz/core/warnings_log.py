"""Collecting the warnings a run prints, so that they reach the review: the JSON report's
``warnings`` and the recording's summary carry what stderr said (an IMU frame, a GNSS quality
problem, an estimator left out, dropped stamps), for whoever opens them later."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator

from .errors import plain_text

#: The logger every module of ionav-viz writes to.
LOGGER = "ionav_viz"


class _Collector(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        with contextlib.suppress(Exception):  # a message that cannot be formatted is not worth failing a run for
            message = " ".join(plain_text(record.getMessage()).split())
            if message not in self.messages:
                self.messages.append(message)


@contextlib.contextmanager
def collecting_warnings() -> Iterator[list[str]]:
    """Within the block, every warning logged by ionav-viz is also appended (once, on one line) to
    the yielded list; what is printed is unchanged."""
    collector = _Collector()
    logger = logging.getLogger(LOGGER)
    logger.addHandler(collector)
    try:
        yield collector.messages
    finally:
        logger.removeHandler(collector)


class _Once(logging.Filter):
    def __init__(self) -> None:
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        try:
            message = record.getMessage()
        except Exception:  # left to the handler to report
            return True
        if message in self.seen:
            return False
        self.seen.add(message)
        return True


@contextlib.contextmanager
def printing_once() -> Iterator[None]:
    """Within the block, a message the ionav-viz logger's handlers (the command line's stderr) have
    already printed is not printed again: a drive evaluated once per outage length warns once, in
    order. Handlers added inside the block (:func:`collecting_warnings`: each report's own
    warnings) still get every message."""
    handlers = [(handler, _Once()) for handler in logging.getLogger(LOGGER).handlers]  # one each: a filter shared
    for handler, once in handlers:  # would keep a message from every handler after the first (a report's collector)
        handler.addFilter(once)
    try:
        yield
    finally:
        for handler, once in handlers:
            handler.removeFilter(once)
