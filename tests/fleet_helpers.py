"""Module-level functions the fleet tests hand to worker processes (a spawned worker imports them
by name, so they cannot live in a test module with fixtures)."""

from __future__ import annotations

import os


def square_or_die(item: str) -> int | str:
    """``"die"``: the worker process exits at once, as one killed by the OOM killer would;
    anything else: its length squared, with the worker's process id."""
    if item == "die":
        os._exit(9)
    return len(item) ** 2


def worker_pid(item: str) -> int:
    """The process id of the worker that ran ``item``."""
    return os.getpid()


def thread_settings(item: str) -> dict:
    """What sizes the numerical libraries' thread pools in the worker that ran ``item``: the
    variables they read, and torch's own setting when torch is loaded there."""
    import sys

    settings = {name: os.environ.get(name) for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")}
    if "torch" in sys.modules:
        settings["torch"] = sys.modules["torch"].get_num_threads()
    return settings
