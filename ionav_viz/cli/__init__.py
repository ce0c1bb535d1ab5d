"""The ``ionav-viz`` command line: one module per command, the shared options in :mod:`.common`.

The commands only parse options, call :mod:`ionav_viz.api` (or the library below it) and print.
Importing this package registers every command on :data:`app`, in the order ``--help`` lists them.
"""

from importlib import import_module

from .app import app, main

for _command in ("simulate", "evaluate", "train", "replay", "screenshot", "figures", "compare", "convert", "outage_log",
                 "datasets", "events", "cross_validate", "run"):
    import_module(f".{_command}", __name__)

__all__ = ["app", "main"]
