"""Whole columns of line strips for ``send_columns``, built as Arrow arrays in one go.

Rerun's own converters turn a list of strips into Arrow one strip at a time, in Python: for the
~100,000 growing outage tracks of a 3.5 h drive that was 90 % of the time spent writing the
recording. Here every strip of a column is one slice of a single flat array of points, and the
Arrow list array is built from that array and the strips' offsets without a Python loop (Rerun
takes an Arrow array of its component's type as it is).
"""

from __future__ import annotations

import numpy as np


def ragged(strips: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``strips`` (each ``(n_i, 2)``) as one ``(sum n_i, 2)`` array of points and the ``len+1``
    offsets where each strip starts."""
    lengths = np.fromiter((len(s) for s in strips), dtype=np.int64, count=len(strips))
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    points = np.concatenate(strips) if strips else np.zeros((0, 2))
    return points.reshape(-1, 2), offsets


def stacked(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One strip per outage of ``points`` (``(outages, n+1, 2)``), as :func:`ragged` returns them."""
    n_out, n_pts = points.shape[:2]
    return points.reshape(-1, 2), np.arange(n_out + 1) * n_pts


def growing(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per outage of ``points`` (``(outages, n+1, 2)``), the strips ``points[s, :k+1]`` for
    ``k = 0..n``: the start point alone, then one more point at each window's end. As
    :func:`ragged` returns them: flat points and offsets."""
    n_out, n_pts = points.shape[:2]
    take = np.concatenate([np.arange(k + 1) for k in range(n_pts)])  # the points of one outage's strips in order
    lengths = np.tile(np.arange(1, n_pts + 1), n_out)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    return points[:, take].reshape(-1, 2), offsets


def line_strips_2d(points: np.ndarray, offsets: np.ndarray):
    """The ``LineStrip2D`` column of strips ``points[offsets[i]:offsets[i+1]]`` (float32 metres)."""
    import rerun as rr

    return _list_of_pairs(points, offsets, np.float32, rr.components.LineStrip2DBatch._ARROW_DATATYPE)


def geo_line_strings(points: np.ndarray, offsets: np.ndarray):
    """The ``GeoLineString`` column of strips ``points[offsets[i]:offsets[i+1]]`` of (lat, lon) degrees (float64)."""
    import rerun as rr

    return _list_of_pairs(points, offsets, np.float64, rr.components.GeoLineStringBatch._ARROW_DATATYPE)


def _list_of_pairs(points: np.ndarray, offsets: np.ndarray, dtype, arrow_type):
    import pyarrow as pa

    flat = pa.array(np.ascontiguousarray(points, dtype=dtype).ravel())
    pairs = pa.FixedSizeListArray.from_arrays(flat, type=arrow_type.value_type)
    return pa.ListArray.from_arrays(pa.array(np.asarray(offsets, dtype=np.int32)), pairs, type=arrow_type)


def with_breaks(t_s: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-outage series (seq, win) flattened, with a NaN half a second after every outage that the
    next one does not follow at once, so plots break the line instead of bridging the GNSS stretch."""
    t, v = t_s.ravel(), np.asarray(values, dtype=np.float64).ravel()
    if t_s.shape[0] < 2:
        return t, v
    gaps = np.flatnonzero(t_s[1:, 0] - t_s[:-1, -1] > 1.0 + 1e-6)  # outage i is followed by GNSS
    at = (gaps + 1) * t_s.shape[1]
    return np.insert(t, at, t_s[gaps, -1] + 0.5), np.insert(v, at, np.nan)
