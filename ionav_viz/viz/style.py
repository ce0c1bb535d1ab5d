"""Colours and names of what recordings and screenshots draw: one home for each.

Estimators carry their own ``label`` and optional ``color`` (the built-ins' are fixed in their
classes); a plug-in without a colour gets one from :data:`PALETTE`, chosen by a stable hash of
its name among the colours no other estimator of the run uses, so it keeps its colour from run to run.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from typing import Any

RGB = tuple[int, int, int]

#: Colours of what is not an estimator.
GNSS_COLOR: RGB = (0, 170, 80)
GYRO_COLOR: RGB = (150, 150, 150)
OUTAGE_MARK_COLOR: RGB = (90, 90, 90)
EVENT_COLOR: RGB = (250, 200, 40)
#: Stretches of the GNSS track that are not trustworthy truth (drawn thin and grey).
BAD_GNSS_COLOR: RGB = (175, 175, 175)
#: Grid lines and scale bars of the metric 2D views.
GRID_COLOR: RGB = (55, 55, 55)
SCALE_COLOR: RGB = (220, 220, 220)
GNSS_LABEL = "GNSS (truth)"
#: Where the truth is a reference beside the receiver: its label, and the receiver's fixes' colour.
REFERENCE_LABEL = "reference (truth)"
RECEIVER_COLOR: RGB = (120, 200, 150)
GYRO_LABEL = "gyro"

#: Colours for plug-ins that bring none (distinct from the GNSS green and the built-ins' red and blue).
PALETTE: tuple[RGB, ...] = (
    (230, 140, 20), (150, 60, 200), (0, 170, 190), (210, 60, 150), (120, 90, 40), (110, 160, 30), (60, 60, 60),
)


def estimator_colors(estimators: Sequence[Any]) -> dict[str, RGB]:
    """A distinct colour per estimator name: its own ``color``, else a palette colour."""
    out: dict[str, RGB] = {}
    for est in estimators:
        if getattr(est, "color", None) is not None:
            out[est.name] = tuple(int(c) for c in est.color)  # type: ignore[assignment]
    taken = set(out.values()) | {GNSS_COLOR}
    for est in estimators:
        if est.name in out:
            continue
        free = [c for c in PALETTE if c not in taken] or list(PALETTE)
        color = free[zlib.crc32(est.name.encode()) % len(free)]
        out[est.name] = color
        taken.add(color)
    return out


_COLOR_WORDS = {
    "red": (230, 60, 50), "blue": (40, 110, 240), "green": (0, 170, 80), "orange": (230, 140, 20), "purple": (150, 60, 200),
    "cyan": (0, 170, 190), "pink": (210, 60, 150), "brown": (120, 90, 40), "olive": (110, 160, 30), "grey": (100, 100, 100),
    "yellow": (240, 220, 40), "black": (20, 20, 20), "white": (240, 240, 240),
}


def color_word(rgb: tuple[int, int, int]) -> str:
    """The nearest plain colour name, for titles that say which line is which."""
    return min(_COLOR_WORDS, key=lambda w: sum((a - b) ** 2 for a, b in zip(_COLOR_WORDS[w], rgb)))


def faded(color: tuple[int, int, int], keep: float = 0.45) -> tuple[int, int, int]:
    """``color`` mixed into the viewer's dark background: the faint overview layers."""
    return tuple(int(round(keep * c + (1 - keep) * 18)) for c in color)  # type: ignore[return-value]


def stacking(errors_m: dict[str, Any]) -> dict[str, Any]:
    """Where each estimator's marks go in a stack of draw orders, per outage: ``errors_m`` maps each
    estimator to its final errors (one per outage, or one value); the result maps it to offsets in
    ``[0, 1)`` of the same shape, the largest error lowest (0, drawn first, underneath) and the
    smallest highest, so a close estimate is drawn over a far one and never hidden by it (a far
    one still shows where it leaves the others). An undefined error counts as the largest."""
    import numpy as np

    names = list(errors_m)
    if not names:
        return {}
    err = np.stack([np.nan_to_num(np.asarray(errors_m[n], dtype=float), nan=np.inf) for n in names])  # (est, ...)
    order = np.argsort(-err, axis=0, kind="stable")  # worst first
    rank = np.empty_like(order)
    np.put_along_axis(rank, order, np.arange(len(names)).reshape((-1,) + (1,) * (err.ndim - 1)) * np.ones_like(order), axis=0)
    return {n: rank[i] / len(names) for i, n in enumerate(names)}
