"""The configuration of the command that is running, as its experiment file says it
(``ionav-viz COMMAND --print-config``): every JSON report and recording written while it runs
carries it under ``config``, so that any result can be rerun exactly (``ionav-viz run FILE``).

Set by the command line (:func:`running`); a script that calls the API directly has none, and its
reports carry no ``config``. A fleet's workers get it with their job (they are other processes).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from contextvars import ContextVar
from typing import Any

_CURRENT: ContextVar[dict[str, Any] | None] = ContextVar("ionav_viz_run_config", default=None)


def current() -> dict[str, Any] | None:
    """The running command's configuration (``command``, its arguments and options, as an experiment
    file holds them), or None outside a command."""
    value = _CURRENT.get()
    return dict(value) if value is not None else None


@contextlib.contextmanager
def running(config: Mapping[str, Any] | None) -> Iterator[None]:
    """While the block runs, :func:`current` is ``config``."""
    token = _CURRENT.set(dict(config) if config is not None else None)
    try:
        yield
    finally:
        _CURRENT.reset(token)
