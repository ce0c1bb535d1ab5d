"""Runs of a boolean mask: the stretches of samples where a condition holds."""

from __future__ import annotations

import numpy as np


def true_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end indices ``[start, end)`` of every run of True in ``mask``, in order."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]]))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


def run_ranges(mask: np.ndarray) -> list[tuple[int, int]]:
    """:func:`true_runs` as a list of ``(start, end)`` Python ints."""
    starts, ends = true_runs(mask)
    return [(int(a), int(b)) for a, b in zip(starts, ends)]


def keep_runs(mask: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``mask`` with only its runs of True for which ``keep`` (one bool per run, in the order of
    :func:`true_runs`) is True."""
    mask = np.asarray(mask, dtype=bool)
    keep = np.asarray(keep, dtype=bool)
    if not mask.any():
        return mask.copy()
    run = np.cumsum(np.diff(np.concatenate([[False], mask]).astype(np.int8)) == 1) - 1  # each sample's run (where True)
    return mask & keep[np.maximum(run, 0)]
