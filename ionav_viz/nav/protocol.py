"""The estimator contract: what an estimator gets, what it returns, and how its output is checked.

An estimator bridges GNSS outages. Given the outages of one drive (:class:`EstimatorInputs`) it
returns, for every outage and every 1-second window of it, the distance travelled (m) and the
mean yaw rate (rad/s, counter-clockwise positive) as an :class:`Estimate`. The library then
rebuilds the 2D track from the GNSS fix and course at each outage start (:func:`solve`) and
scores every estimator the same way (:mod:`ionav_viz.analysis.metrics`).

Writing one::

    import numpy as np
    from ionav_viz import Estimate, EstimatorInputs

    class ConstantSpeed:
        name = "const"                 # JSON key and entity path segment
        label = "Constant speed"       # legends and table headers
        color = (200, 120, 0)          # optional, RGB 0-255

        def estimate(self, inputs: EstimatorInputs) -> Estimate:
            disp = np.repeat(inputs.speed0_mps[:, None], inputs.n_windows, axis=1) * 1.0  # m per 1 s window
            return Estimate(disp_m=disp, yaw_rate_radps=np.zeros_like(disp))

How estimators are found by name, loaded as plug-ins and chosen by default is
:mod:`ionav_viz.nav.registry`.

Rule for fair comparison: GNSS inside an outage is the truth being scored. An estimator may
read ``inputs.windows`` (the whole drive's windows) only *before* each outage's start window.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from .bias import SensorBias
from .track import Track, rebuild_track
from .windows import Windows

_NAME = re.compile(r"^[a-z][a-z0-9_-]{0,31}$")


class EstimatorError(InputError):
    """An estimator plug-in that cannot be loaded or returned unusable output."""


@dataclass(frozen=True)
class Estimate:
    """One estimator's output for every outage of a drive.

    Attributes:
        disp_m: distance travelled in each 1-second window (m), shape ``(n_outages, n_windows)``.
        yaw_rate_radps: mean yaw rate over each window (rad/s, counter-clockwise positive),
            same shape.
    """

    disp_m: np.ndarray
    yaw_rate_radps: np.ndarray


@dataclass
class Solution:
    """An :class:`Estimate` with the track the library rebuilt from it (what metrics score)."""

    disp_m: np.ndarray
    yaw_rate_radps: np.ndarray
    track: Track


@dataclass
class EstimatorInputs:
    """What an estimator gets: the outages of one drive, with the GNSS state at each start.

    Attributes:
        drive: the whole drive (samples at their native rate).
        windows: the drive's 1-second windows (GNSS truth included: use only windows before
            each outage's start).
        starts: index into ``windows`` of the first window of each outage, shape ``(n_outages,)``.
        n_windows: windows (seconds) per outage.
        bias: sensor biases (accelerometer m/s², gyro rad/s) estimated while standing still.

    Per outage (shape ``(n_outages,)``), the GNSS state at its start: ``t0_s`` (s since the drive's
    first sample), ``speed0_mps``, ``course0_deg`` (clockwise from north), ``lat0_deg``,
    ``lon0_deg``, and ``prev_gnss_disp_m`` (GNSS distance travelled in the second before).

    Inertial samples on the 10 Hz grid, as measured (not bias-corrected), shape
    ``(n_outages, n_windows, samples)`` with ``samples = 11``: the window's grid points including
    both ends (a window's last sample is the next window's first): ``accel_mps2`` (longitudinal
    specific force, forward positive) and ``gyro_radps`` (yaw rate, counter-clockwise positive).
    """

    drive: Drive
    windows: Windows
    starts: np.ndarray
    n_windows: int
    bias: SensorBias
    t0_s: np.ndarray = field(init=False, repr=False)
    speed0_mps: np.ndarray = field(init=False, repr=False)
    course0_deg: np.ndarray = field(init=False, repr=False)
    lat0_deg: np.ndarray = field(init=False, repr=False)
    lon0_deg: np.ndarray = field(init=False, repr=False)
    prev_gnss_disp_m: np.ndarray = field(init=False, repr=False)
    accel_mps2: np.ndarray = field(init=False, repr=False)
    gyro_radps: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.starts = np.asarray(self.starts, dtype=int)
        w, k = self.windows, self.starts
        idx = self.window_index
        self.t0_s = w.t0_s[k]
        self.speed0_mps = w.speed0_mps[k]
        self.course0_deg = w.heading0_deg[k]
        self.lat0_deg = w.lat0_deg[k]
        self.lon0_deg = w.lon0_deg[k]
        self.prev_gnss_disp_m = w.gnss_disp_m[k - 1] if len(k) else np.zeros(0)
        self.accel_mps2 = w.accel_mps2[idx]
        self.gyro_radps = w.gyro_radps[idx]

    @property
    def n_outages(self) -> int:
        return len(self.starts)

    @property
    def window_index(self) -> np.ndarray:
        """Index into ``windows`` of every window of every outage, shape ``(n_outages, n_windows)``."""
        return self.starts[:, None] + np.arange(self.n_windows)[None, :]

    @property
    def rate_hz(self) -> float:
        """Rate of the inertial samples (Hz)."""
        return self.windows.rate_hz


@runtime_checkable
class Estimator(Protocol):
    """The estimator protocol: a ``name`` (a short lower-case identifier: JSON key and entity path
    segment), a ``label`` (legends, table headers) and :meth:`estimate`.

    Optional members, read with :func:`applies`, :func:`describe`, :func:`available` and
    :func:`color_of` (an estimator without them gets the defaults):

    * ``color``: RGB triple of 0-255 integers (default: a palette colour chosen by name);
    * ``applies(drive) -> bool``: whether it can run on a drive (default: every drive);
    * ``describe() -> dict``: what it is and what it used, shown in reports (default: nothing);
    * ``available() -> bool``: whether it can run at all here, e.g. the IDNN needs a model
      (default: yes); one that is not is left out of the default set.
    """

    name: str
    label: str

    def estimate(self, inputs: EstimatorInputs) -> Estimate: ...


class OptionalMembers(Protocol):
    """The optional members of :class:`Estimator`, for type checkers (see its docstring)."""

    color: tuple[int, int, int]

    def applies(self, drive: Drive) -> bool: ...

    def describe(self) -> dict[str, Any]: ...

    def available(self) -> bool: ...


def short_label(label: str) -> str:
    """``'INS DR'`` -> ``'INS'``: titles and legends that list estimators name them briefly."""
    return label.removesuffix(" DR")


def applies(estimator: Estimator, drive: Drive) -> bool:
    """Whether ``estimator`` runs on ``drive`` (its optional ``applies``; default yes)."""
    check = getattr(estimator, "applies", None)
    return bool(check(drive)) if callable(check) else True


def describe(estimator: Estimator) -> dict[str, Any]:
    """The estimator's own description (its optional ``describe()``), for reports."""
    fn = getattr(estimator, "describe", None)
    return dict(fn()) if callable(fn) else {}


def available(estimator: Estimator) -> bool:
    """Whether ``estimator`` can run here at all (its optional ``available()``; default yes)."""
    check = getattr(estimator, "available", None)
    return bool(check()) if callable(check) else True


def color_of(estimator: Estimator) -> tuple[int, int, int] | None:
    """The estimator's own colour (its optional ``color``), or None."""
    color = getattr(estimator, "color", None)
    return None if color is None else tuple(color)  # type: ignore[return-value]


def solve(estimator: Estimator, inputs: EstimatorInputs) -> Solution:
    """Run ``estimator`` on ``inputs``, check its output, and rebuild the track from it."""
    name = estimator.name
    try:
        est = estimator.estimate(inputs)
    except InputError:
        raise
    except Exception as exc:
        raise EstimatorError(
            f"estimator {name!r} failed: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}".rstrip(": "),
            "fix the plug-in (run with --debug for the traceback)",
        ) from exc
    disp, yaw = _checked(name, est, inputs.n_outages, inputs.n_windows)
    track = rebuild_track(inputs.lat0_deg, inputs.lon0_deg, inputs.course0_deg, disp, yaw)
    return Solution(disp, yaw, track)


def _checked(name: str, est: Any, n_outages: int, n_windows: int) -> tuple[np.ndarray, np.ndarray]:
    hint = "estimate() must return Estimate(disp_m=..., yaw_rate_radps=...) with finite arrays of shape (n_outages, n_windows)"
    if not hasattr(est, "disp_m") or not hasattr(est, "yaw_rate_radps"):
        raise EstimatorError(f"estimator {name!r} returned {type(est).__name__}, not an Estimate", hint)
    out = []
    for field_name in ("disp_m", "yaw_rate_radps"):
        try:
            values = np.asarray(getattr(est, field_name), dtype=np.float64)
        except (TypeError, ValueError):
            raise EstimatorError(f"estimator {name!r}: {field_name} is not numeric", hint) from None
        if values.shape != (n_outages, n_windows):
            raise EstimatorError(
                f"estimator {name!r}: {field_name} has shape {values.shape}, expected ({n_outages}, {n_windows})", hint
            )
        bad = ~np.isfinite(values)
        if bad.any():
            i, j = (int(x) for x in np.argwhere(bad)[0])
            raise EstimatorError(
                f"estimator {name!r}: {field_name} is {values[i, j]} in outage {i + 1}, window {j + 1} "
                f"({int(bad.sum())} non-finite value(s))",
                hint,
            )
        out.append(values)
    return out[0], out[1]


def validate(obj: Any, origin: str = "") -> Estimator:
    """Check that ``obj`` follows the protocol; returns it."""
    where = f" ({origin})" if origin else ""
    name = getattr(obj, "name", None)
    if not isinstance(name, str) or not _NAME.match(name):
        raise EstimatorError(
            f"estimator{where}: name {name!r} is not a short lower-case identifier",
            "give it a name like 'const' or 'my-filter' (letters, digits, '-' and '_', up to 32)",
        )
    if not isinstance(getattr(obj, "label", None), str) or not callable(getattr(obj, "estimate", None)):
        raise EstimatorError(f"estimator {name!r}{where}: needs a 'label' string and an estimate(inputs) method",
                             "see 'Your own estimator' in the README")
    color = getattr(obj, "color", None)
    if color is not None and (len(tuple(color)) != 3 or not all(isinstance(c, int) and 0 <= c <= 255 for c in color)):
        raise EstimatorError(f"estimator {name!r}{where}: color {color!r} is not an RGB triple of 0-255 integers")
    return obj
