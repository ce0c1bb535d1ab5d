"""The one Kalman update both filters use, and the record of what each update saw.

Both filters (:mod:`ionav_viz.nav.strapdown` behind ``gins``, :mod:`ionav_viz.nav.planar_filter`
behind ``ekf`` and the IDNN's calibration) fold their measurements in one scalar at a time (their
noise is uncorrelated between components), through :func:`scalar_update`:

    S = H P H^T + r        K = P H^T / S        x <- x + K nu        (nu: the innovation)
    P <- (I - K H) P (I - K H)^T + K r K^T      (Joseph form)

The Joseph form keeps ``P`` symmetric and positive semi-definite in floating point where the short
form ``P - K S K^T`` can lose it after many updates of a well-known state (KF-GINS,
``gi_engine.cpp`` ``EKFUpdate``, and pyins use it). In exact arithmetic the two are equal: the
results differ in the last digits.

A measurement whose normalised innovation squared ``NIS = nu^2 / S`` exceeds the caller's gate
is not used. Every update's innovation, its variance ``S`` and the decision can be kept in a
:class:`UpdateLog` (per boundary and measurement slot): the filter's health, which the reports and
the recording show and the safeguards read.

``H`` is given by its nonzeros: ``cols`` (state indices) and ``h`` (values), ``nnz`` of them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..core import jit

jit.watch(__name__)  # say a first run's compilation (core/jit.py)

#: The 95 % point of a chi-square of two degrees of freedom (``-2 ln 0.05``): a 2D error whose NEES
#: is below it lies inside the 95 % ellipse of its covariance.
CHI2_2_95 = -2.0 * math.log(0.05)

#: ``UpdateLog.status``: no such measurement at this boundary
NOT_MEASURED = 0
#: the measurement was used
USED = 1
#: the measurement was there and left out by its gate (too far from the prediction)
GATED = 2


class UpdateLog(NamedTuple):
    """What each measurement update saw, per boundary (rows) and measurement slot (columns): the
    innovation (measured minus predicted, in the measurement's unit), its variance ``S`` (the
    unit squared) and :data:`USED`/:data:`GATED`/:data:`NOT_MEASURED`. Rows: 0 to keep nothing."""

    innovation: np.ndarray
    variance: np.ndarray
    status: np.ndarray


def update_log(rows: int, slots: int) -> UpdateLog:
    """An empty record of ``rows`` boundaries by ``slots`` measurements (NaN where none)."""
    return UpdateLog(np.full((rows, slots), np.nan), np.full((rows, slots), np.nan),
                     np.zeros((rows, slots), dtype=np.int8))


@njit(cache=True)
def unit_row(H, col):  # pragma: no cover - compiled
    """Write into the scratch row ``H = (cols, h)`` a measurement of state ``col`` itself."""
    H[0][0] = col
    H[1][0] = 1.0


@njit(cache=True)
def _times_h(A, cols, h, nnz):  # pragma: no cover - compiled
    """``A H^T`` for the sparse row ``H`` (``nnz`` values ``h`` at ``cols``)."""
    out = np.zeros(A.shape[0])
    for i in range(A.shape[0]):
        acc = 0.0
        for k in range(nnz):
            acc += A[i, cols[k]] * h[k]
        out[i] = acc
    return out


@njit(cache=True)
def scalar_update(P, x, cols, h, nnz, innovation, r, gate):  # pragma: no cover - compiled
    """Fold one scalar measurement into the state ``x`` (or the error state) and covariance ``P``
    in place (see the module docstring); ``innovation``: measured minus predicted. Returns its
    variance ``S`` and whether it was used (not when ``S`` is not positive, or when
    ``innovation^2 / S > gate``)."""
    n = P.shape[0]
    PH = _times_h(P, cols, h, nnz)
    S = r
    for k in range(nnz):
        S += h[k] * PH[cols[k]]
    if not S > 0.0:
        return S, False
    if innovation * innovation > gate * S:
        return S, False
    K = PH / S
    for i in range(n):
        x[i] += K[i] * innovation
    # (I - K H) P: P is symmetric, so H P is PH^T
    for i in range(n):
        for j in range(n):
            P[i, j] -= K[i] * PH[j]
    # ... times (I - K H)^T, plus K r K^T
    APh = _times_h(P, cols, h, nnz)
    for i in range(n):
        for j in range(n):
            P[i, j] += (r * K[i] - APh[i]) * K[j]
    for i in range(n):
        for j in range(i):
            P[i, j] = P[j, i] = 0.5 * (P[i, j] + P[j, i])
    return S, True


@njit(cache=True)
def record(log, row, slot, innovation, variance, used):  # pragma: no cover - compiled
    """Keep one update in ``log`` (nothing when it keeps no rows)."""
    if log.status.shape[0] == 0:
        return
    log.innovation[row, slot] = innovation
    log.variance[row, slot] = variance
    log.status[row, slot] = 1 if used else 2


def update(P: np.ndarray, x: np.ndarray, H: np.ndarray, innovation: float, r: float,
           gate: float = np.inf) -> tuple[float, bool]:
    """:func:`scalar_update` with a dense row ``H`` (for tests and Python callers)."""
    H = np.asarray(H, dtype=float)
    cols = np.flatnonzero(H).astype(np.int64)
    return scalar_update(P, x, cols, np.ascontiguousarray(H[cols]), len(cols), float(innovation), float(r), float(gate))
