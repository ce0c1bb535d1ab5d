"""Moving windows over a signal's samples, vectorised (cumulative sums, no per-sample loop)."""

from __future__ import annotations

import numpy as np


def as_columns(x: np.ndarray) -> np.ndarray:
    """``x`` as float columns: a 1D signal becomes one column ``(n, 1)``."""
    x = np.asarray(x, dtype=float)
    return x[:, None] if x.ndim == 1 else x


def moving_mean(x: np.ndarray, n: int) -> np.ndarray:
    """Centred moving mean over ``n`` samples along the first axis (shorter windows at the ends),
    ``(len(x), columns)``."""
    x = as_columns(x)
    m = len(x)
    c = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    out = np.empty((m, x.shape[1]))
    first, last = n // 2, m - n + n // 2  # samples whose whole window lies inside: slices, no gather
    if last >= first:
        out[first:last + 1] = (c[n:] - c[:m - n + 1]) / n
    edges = np.r_[0:min(first, m), max(last + 1, 0):m]
    lo, hi = np.clip(edges - n // 2, 0, m), np.clip(edges - n // 2 + n, 0, m)
    out[edges] = (c[hi] - c[lo]) / (hi - lo)[:, None]
    return out
