"""East/north position covariances: built from their entries, checked, and the NEES of errors under them.

A covariance here is an array ``(..., 2, 2)`` of 2 x 2 matrices, east then north, in m^2 (an
estimate's :attr:`~ionav_viz.nav.protocol.Estimate.pos_cov_m2`, an external trajectory's
:attr:`~ionav_viz.sources.trajectory.Trajectory.cov_en_m2`). Both are checked by
:func:`covariance_faults`, so a trajectory file and a plug-in's estimate are held to one rule.
"""

from __future__ import annotations

import numpy as np

#: What the checks forgive as rounding, relative to a matrix's largest entry ``s`` (m^2): an entry
#: off by up to ``COVARIANCE_RTOL * s`` (m^2), the determinant by up to ``COVARIANCE_RTOL * s^2``
#: (m^4). Relative, so a matrix is accepted or refused whatever its size: a rank-one covariance
#: computed in float64 passes at 10 km as at 1 mm, and one whose correlation exceeds 1 fails at both.
COVARIANCE_RTOL = 1e-9
#: The smallest ``s`` the tolerance is taken relative to (m^2): an all-zero matrix is accepted.
COVARIANCE_SCALE_FLOOR_M2 = 1e-12
#: The largest entry a position covariance may have (m^2): a sigma of 10^8 m, over twice the
#: earth's circumference, says nothing a smaller one does not, and products of larger entries (the
#: determinant, the NEES) overflow float64: 1e300 printed numpy's overflow warnings.
COVARIANCE_MAX_M2 = 1e16


def covariance_en(ee: np.ndarray, en: np.ndarray, nn: np.ndarray) -> np.ndarray:
    """East/north covariance matrices ``(n, 2, 2)`` from their three distinct entries (m^2)."""
    return np.stack([np.stack([ee, en], axis=-1), np.stack([en, nn], axis=-1)], axis=-2).astype(float)


def covariance_faults(cov_m2: np.ndarray) -> dict[str, np.ndarray]:
    """What is wrong with each matrix of ``cov_m2`` ``(..., 2, 2)`` (m^2), as boolean masks of shape
    ``(...)`` in the order a check reports them: ``"not finite"``, ``"beyond any position (an entry
    over 1e+16 m^2)"`` (:data:`COVARIANCE_MAX_M2`), ``"not symmetric"`` and ``"not positive
    semi-definite"``, each up to :data:`COVARIANCE_RTOL` (a matrix is in the first of its faults'
    masks only; nothing overflows)."""
    finite = np.isfinite(cov_m2).all(axis=(-1, -2))
    huge = finite & ~(np.abs(np.where(finite[..., None, None], cov_m2, 0.0)) <= COVARIANCE_MAX_M2).all(axis=(-1, -2))
    cov = np.where((finite & ~huge)[..., None, None], cov_m2, 0.0)
    scale = np.maximum(np.abs(cov).max(axis=(-1, -2)), COVARIANCE_SCALE_FLOOR_M2)
    tol = COVARIANCE_RTOL * scale
    a, b, c = cov[..., 0, 0], cov[..., 1, 1], cov[..., 0, 1]
    return {"not finite": ~finite,
            f"beyond any position (an entry over {COVARIANCE_MAX_M2:g} m^2)": huge,
            "not symmetric": np.abs(c - cov[..., 1, 0]) > tol,
            "not positive semi-definite": (a < -tol) | (b < -tol) | (a * b - c * c < -tol * scale)}


#: The smallest determinant (m^4) the NEES divides by: a covariance thinner than about 1 mm along
#: either axis counts as that thin.
NEES_MIN_DET_M4 = 1e-12


def determinant_en(cov_m2: np.ndarray, min_det_m4: float = NEES_MIN_DET_M4) -> np.ndarray:
    """The determinant (m^4) of each matrix of ``cov_m2`` ``(..., 2, 2)`` (m^2), at least ``min_det_m4``."""
    a, b, c = cov_m2[..., 0, 0], cov_m2[..., 1, 1], cov_m2[..., 0, 1]
    return np.maximum(a * b - c * c, min_det_m4)


def nees_en(error_en_m: np.ndarray, cov_m2: np.ndarray, min_det_m4: float = NEES_MIN_DET_M4) -> np.ndarray:
    """The normalised estimation error squared ``e^T P^-1 e`` (2 degrees of freedom; 2 on average
    when ``P`` is honest) of east/north errors ``error_en_m`` ``(..., 2)`` (m) under their
    covariances ``cov_m2`` ``(..., 2, 2)`` (m^2), with the 2 x 2 inverse written out and the
    determinant at least ``min_det_m4`` (m^4; :func:`determinant_en`)."""
    a, b, c = cov_m2[..., 0, 0], cov_m2[..., 1, 1], cov_m2[..., 0, 1]
    east, north = error_en_m[..., 0], error_en_m[..., 1]
    return (b * east * east - 2 * c * east * north + a * north * north) / determinant_en(cov_m2, min_det_m4)


def growth_en(cov_m2: np.ndarray) -> np.ndarray:
    """What each outage's east/north covariance ``(m, n + 1, 2, 2)`` (m^2) grew by since its start
    (boundary 0), its negative part left out (a filter's constraints can narrow it along one axis):
    positive semi-definite, so the start's covariance plus any multiple of it is one too."""
    values, vectors = np.linalg.eigh(cov_m2 - cov_m2[:, :1])
    return (vectors * np.maximum(values, 0.0)[..., None, :]) @ np.swapaxes(vectors, -1, -2)


def scale_growth(cov_m2: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Each outage's covariance with what it grew by through the outage scaled by ``scale`` ``(m,)``
    (:func:`growth_en`); the start's own covariance as it was."""
    return cov_m2[:, :1] + np.asarray(scale, dtype=float)[:, None, None, None] * growth_en(cov_m2)
