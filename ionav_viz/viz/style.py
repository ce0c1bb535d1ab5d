"""Colours and names of what recordings and screenshots draw: one home for each.

Two schemes, never mixed. The tracks (the truth and the estimators) take Okabe and Ito's
colour-blind-safe palette (:data:`OKABE_ITO`; Okabe & Ito, "Color Universal Design", 2008): the
truth its bluish green, each built-in estimator one of the others (fixed in its class), a plug-in
without a colour one of :data:`PALETTE`: yellow (no built-in's) while it is free, else one chosen
by a stable hash of its name among the colours no other estimator of the run uses, so it keeps its
colour from run to run (black is left out: unseen on the viewer's dark theme). Everything else
that is coloured by kind (measurement kinds in the filter-health view, the states of the GNSS,
outage and manoeuvre lanes, the manoeuvre dots) takes Paul Tol's "muted" scheme
(:data:`TOL_MUTED`; Tol, "Colour Schemes", SRON, 2021), and marks that name no kind (grid, scale
bars, outage starts, sensors) are grey.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from typing import Any

RGB = tuple[int, int, int]

#: Okabe and Ito's palette, by name: the tracks' colours (the truth and the estimators) and no others.
OKABE_ITO: dict[str, RGB] = {
    "orange": (230, 159, 0), "sky blue": (86, 180, 233), "green": (0, 158, 115), "yellow": (240, 228, 66),
    "blue": (0, 114, 178), "vermillion": (213, 94, 0), "pink": (204, 121, 167), "black": (0, 0, 0),
}
#: Paul Tol's "muted" scheme, by name: what is coloured by kind and is no track.
TOL_MUTED: dict[str, RGB] = {
    "rose": (204, 102, 119), "indigo": (51, 34, 136), "sand": (221, 204, 119), "dark green": (17, 119, 51),
    "cyan": (136, 204, 238), "teal": (68, 170, 153), "olive": (153, 153, 51), "wine": (136, 34, 85),
    "purple": (170, 68, 153),
}

#: Colours of what is not an estimator: the truth (Okabe-Ito's green), the rest grey or Tol's.
GNSS_COLOR: RGB = OKABE_ITO["green"]
GYRO_COLOR: RGB = (150, 150, 150)
OUTAGE_MARK_COLOR: RGB = (110, 110, 110)
EVENT_COLOR: RGB = TOL_MUTED["sand"]
#: Stretches of the GNSS track that are not trustworthy truth (drawn thin and grey).
BAD_GNSS_COLOR: RGB = (175, 175, 175)
#: Grid lines of the metric 2D views; their scale bars and tick labels: a mid grey, read on the
#: viewer's dark theme and its light one (white was lost on white).
GRID_COLOR: RGB = (55, 55, 55)
SCALE_COLOR: RGB = (120, 120, 120)
#: The state lanes' colours (Tol's muted, grey for the ordinary state): GNSS there, outages
#: (alternating, so that consecutive ones are told apart), the log's own losses, the receiver lost
#: beside a reference; the truth good or bad; each manoeuvre type, no manoeuvre.
STATE_COLORS: dict[str, RGB] = {
    "GNSS": (90, 90, 90), "outage": TOL_MUTED["indigo"], "outage alt": TOL_MUTED["purple"],
    "real outage": TOL_MUTED["wine"], "receiver": TOL_MUTED["rose"], "good": (90, 90, 90), "bad": TOL_MUTED["rose"],
    "none": (60, 60, 60),
}
EVENT_STATE_COLORS: dict[str, RGB] = {
    "hard-brake": TOL_MUTED["rose"], "quick-accel": TOL_MUTED["olive"], "roundabout": TOL_MUTED["teal"],
    "sharp-cornering": TOL_MUTED["purple"], "left-right": TOL_MUTED["indigo"], "cruise": TOL_MUTED["dark green"],
    "gnss-outage": TOL_MUTED["wine"],
}
GNSS_LABEL = "GNSS (truth)"
#: Where the truth is a reference beside the receiver: its label, and the receiver's fixes' colour.
REFERENCE_LABEL = "reference (truth)"
RECEIVER_COLOR: RGB = (130, 200, 175)
GYRO_LABEL = "gyro"

#: Colours for plug-ins that bring none: Okabe-Ito's but the truth's green and black, yellow first
#: (the one no built-in takes), then those the run's built-ins leave free.
PALETTE: tuple[RGB, ...] = tuple(OKABE_ITO[n] for n in ("yellow", "orange", "sky blue", "pink", "blue", "vermillion"))
#: The built-in estimators' colours (each class holds its own; a test keeps them equal).
BUILT_IN_COLORS: dict[str, RGB] = {"ins": OKABE_ITO["vermillion"], "idnn": OKABE_ITO["blue"], "odo": OKABE_ITO["pink"],
                                   "ekf": OKABE_ITO["sky blue"], "gins": OKABE_ITO["orange"]}


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
        first = [c for c in free if c not in BUILT_IN_COLORS.values()]  # yellow while no plug-in took it
        color = first[0] if first else free[zlib.crc32(est.name.encode()) % len(free)]
        out[est.name] = color
        taken.add(color)
    return out


_COLOR_WORDS = {
    **OKABE_ITO, "red": (230, 60, 50), "purple": (150, 60, 200), "cyan": (0, 170, 190), "brown": (120, 90, 40),
    "olive": (110, 160, 30), "grey": (100, 100, 100), "white": (240, 240, 240),
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
    np.put_along_axis(rank, order, np.arange(len(names)).reshape((-1,) + (1,) * (err.ndim - 1)) * np.ones_like(order),
                      axis=0)
    return {n: rank[i] / len(names) for i, n in enumerate(names)}
