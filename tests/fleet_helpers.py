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
