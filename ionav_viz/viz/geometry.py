"""Framing and scale references for the 2D views: padded bounds, grid lines, scale bars.

Pure functions over numpy arrays in the views' screen frame: x east (m), y = -north (m), so north
is up in Rerun's y-down 2D view (see :func:`screen_xy`).
"""

from __future__ import annotations

import numpy as np

from ..core.geo import local_en_m

Bounds = tuple[float, float, float, float]  # x_min, x_max, y_min, y_max (m)


def padded_bounds(points: np.ndarray, margin: float = 0.15, min_half_m: float = 5.0) -> Bounds:
    """Bounds of ``points`` (N, 2) (NaN ignored) grown by ``margin`` of the larger side on each side,
    and to at least ``min_half_m`` either way of the centre, so a car standing still still gets a
    readable frame."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if not len(pts):
        return (-min_half_m, min_half_m, -min_half_m, min_half_m)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    half = np.maximum(half + margin * 2 * half.max(), min_half_m)
    return (float(centre[0] - half[0]), float(centre[0] + half[0]), float(centre[1] - half[1]),
            float(centre[1] + half[1]))


def nice_step(extent_m: float, lines: int = 6) -> float:
    """The 1-2-5 step (m) that cuts ``extent_m`` into about ``lines`` parts (at least 1 m)."""
    raw = max(float(extent_m) / max(lines, 1), 1.0)
    decade = 10.0 ** np.floor(np.log10(raw))
    return float(next(m * decade for m in (1.0, 2.0, 5.0, 10.0) if m * decade >= raw))


def grid_strips(bounds: Bounds, step_m: float) -> list[np.ndarray]:
    """Grid lines every ``step_m`` covering ``bounds`` (multiples of the step, so they stay put
    when the bounds move): one 2-point strip per line."""
    x0, x1, y0, y1 = bounds
    xs = np.arange(np.floor(x0 / step_m), np.ceil(x1 / step_m) + 1) * step_m
    ys = np.arange(np.floor(y0 / step_m), np.ceil(y1 / step_m) + 1) * step_m
    lo_x, hi_x, lo_y, hi_y = xs[0], xs[-1], ys[0], ys[-1]
    return [np.array([[x, lo_y], [x, hi_y]]) for x in xs] + [np.array([[lo_x, y], [hi_x, y]]) for y in ys]


def scale_bar(bounds: Bounds, step_m: float, above: float = 0.05) -> np.ndarray:
    """A bar one ``step_m`` long ``above`` of the height above the bottom edge of ``bounds``, from its
    left corner (2 points): with bounds padded around the data (:func:`padded_bounds`), it stays off
    the tracks, its label below it."""
    x0, _x1, y0, y1 = bounds
    y = y1 - above * (y1 - y0)  # screen y grows downwards: the bottom is y1
    return np.array([[x0, y], [x0 + step_m, y]])


def scale_bar_clear_of(bounds: Bounds, step_m: float, points: np.ndarray,
                       above: float = 0.09) -> tuple[np.ndarray, Bounds]:
    """A scale bar (as :func:`scale_bar`) that neither it nor its label covers ``points``, and the
    bounds that hold it: in the bottom-left corner of ``bounds``, else the bottom-right, the
    top-left, the top-right, else in a band grown below the points (bounds tightly around a drive
    leave the corners to its track)."""
    x0, x1, y0, y1 = bounds
    height = y1 - y0
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]

    def clear(bar: np.ndarray) -> bool:  # the bar, its label below it (about as wide), and half a step either side
        (a, y), (b, _) = bar
        pad = 0.5 * step_m
        return not ((pts[:, 0] >= a - pad) & (pts[:, 0] <= b + pad) & (pts[:, 1] >= y - 0.03 * height)
                    & (pts[:, 1] <= y + above * height)).any()

    right = x1 - x0 - step_m
    for dx, y in ((0.0, y1 - above * height), (right, y1 - above * height), (0.0, y0 + 0.03 * height),
                  (right, y0 + 0.03 * height)):
        bar = np.array([[x0 + dx, y], [x0 + dx + step_m, y]])
        if clear(bar):
            return bar, bounds
    grown = (x0, x1, y0, y1 + (above + 0.04) * height)  # the bar 0.04 of the height below the lowest point
    return np.array([[x0, y1 + 0.04 * height], [x0 + step_m, y1 + 0.04 * height]]), grown


def scale_label(step_m: float) -> str:
    """``'20 m'``, ``'1 km'``."""
    return f"{step_m / 1000:g} km" if step_m >= 1000 else f"{step_m:g} m"


def map_zoom(lat_deg: np.ndarray, lon_deg: np.ndarray, view_px: float) -> float:
    """Web-map zoom level at which the track's extent fills about ``view_px`` pixels.

    Web Mercator: metres per pixel = 156543.03 * cos(lat) / 2^zoom (checked on a rendered map view).
    """
    lat0 = float(np.mean(lat_deg))
    east, north = local_en_m(lat_deg, lon_deg, lat0, float(np.mean(lon_deg)))
    extent_m = max(float(np.ptp(east)), float(np.ptp(north)), 50.0)
    zoom = np.log2(156543.03 * np.cos(np.radians(lat0)) * view_px / extent_m)
    return float(np.clip(zoom, 3.0, 19.0))


def screen_xy(east: np.ndarray, north: np.ndarray) -> np.ndarray:
    """Local frame -> Rerun 2D view coordinates (y grows downwards on screen)."""
    return np.stack([east, -north], axis=-1)
