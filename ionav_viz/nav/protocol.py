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
:mod:`ionav_viz.experiment.registry`.

Rule for fair comparison: GNSS inside an outage is the truth being scored. An estimator may
read ``inputs.windows`` (the whole drive's windows) only *before* each outage's start window.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, fields, replace
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..core.covariance import covariance_faults
from ..core.drive import Drive
from ..core.errors import InputError
from ..core.grid import WINDOW_S
from ..core.json_out import plain_json
from ..sources.plausibility import LIMITS
from .bias import SensorBias
from .stillness import still_on_grid
from .track import Track, rebuild_track
from .windows import Windows

_NAME = re.compile(r"^[a-z][a-z0-9_-]{0,31}$")


class EstimatorError(InputError):
    """An estimator plug-in that cannot be loaded or returned unusable output."""


#: The kind a filter logs a safeguard's act under in its :class:`FilterHealth` (gins: re-initialised
#: from GNSS instead of gating the fixes out): its "innovation" is how far off the filter was, not
#: a measurement's, so it counts as acts, never in a mean NIS.
REINITIALISED = "re-initialised from GNSS"
SAFEGUARD_KINDS = frozenset({REINITIALISED})


@dataclass(frozen=True)
class FilterHealth:
    """What a filter's measurement updates saw over the drive (its pass with GNSS): per row (a
    window boundary, at ``t_s``, s since the drive's first sample) and measurement slot (``slots``,
    each of a ``kinds`` entry, e.g. ``"gnss_east"`` of ``"GNSS position"``), the innovation
    (measured minus predicted, in the measurement's unit), its variance ``S`` (the unit squared)
    and ``status`` (0 none, 1 used, 2 left out by the filter's gate): see
    :mod:`ionav_viz.nav.kalman`. A consistent filter's normalised innovations squared
    (``innovation**2 / variance``) average 1."""

    t_s: np.ndarray
    slots: tuple[str, ...]
    kinds: tuple[str, ...]
    innovation: np.ndarray
    variance: np.ndarray
    status: np.ndarray

    def nis(self) -> np.ndarray:
        """The normalised innovation squared per row and slot (NaN where nothing was measured)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            out = self.innovation**2 / self.variance
        return np.where(self.status > 0, out, np.nan)


@dataclass(frozen=True)
class Estimate:
    """One estimator's output for every outage of a drive.

    Attributes:
        disp_m: distance travelled in each 1-second window (m), shape ``(n_outages, n_windows)``.
        yaw_rate_radps: mean yaw rate over each window (rad/s, counter-clockwise positive),
            same shape.
        lat_deg, lon_deg: optional, the estimator's own positions at the window boundaries (WGS84
            degrees), shape ``(n_outages, n_windows + 1)``, the first at the outage's start: then
            the final position error and the drawn track use them, not the track rebuilt from
            ``disp_m`` and ``yaw_rate_radps`` (an estimator that tracks positions itself, or an
            external trajectory).
        health: optional, what the filter's updates saw over the drive (:class:`FilterHealth`),
            for the reports' and the recording's filter health.
        pos_cov_m2: optional, how sure the estimator is of its position: the east/north covariance
            (m^2) at each window boundary, shape ``(n_outages, n_windows + 1, 2, 2)`` (the first at
            the outage's start fix); checked finite, symmetric and positive semi-definite.
    """

    disp_m: np.ndarray
    yaw_rate_radps: np.ndarray
    lat_deg: np.ndarray | None = None
    lon_deg: np.ndarray | None = None
    health: FilterHealth | None = None
    pos_cov_m2: np.ndarray | None = None


@dataclass
class Solution:
    """An :class:`Estimate` with the track the library rebuilt from it (what metrics score)."""

    disp_m: np.ndarray
    yaw_rate_radps: np.ndarray
    track: Track
    health: FilterHealth | None = None
    pos_cov_m2: np.ndarray | None = None


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
    specific force, forward positive) and ``gyro_radps`` (yaw rate, counter-clockwise positive);
    and ``still``, the same shape: where the IMU shows the car standing
    (:func:`ionav_viz.nav.stillness.still_on_grid`), for zero-velocity updates; ``still_grid``, the
    same for every window of the drive ``(n_windows_of_drive, samples)`` (for work over the GNSS
    before the outages, e.g. :mod:`ionav_viz.nav.history_check`'s pseudo-outages).
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
    still: np.ndarray = field(init=False, repr=False)
    still_grid: np.ndarray = field(init=False, repr=False)

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
        self.still_grid = still_on_grid(self.drive, w)
        self.still = self.still_grid[idx]
        # every estimator sees the same data: none can change what the others (or the metrics) see
        self.drive = replace(self.drive, columns={k: _read_only(v) for k, v in self.drive.columns.items()},
                             gnss_fault=None if self.drive.gnss_fault is None else _read_only(self.drive.gnss_fault))
        self.windows = replace(self.windows, **{f.name: _read_only(getattr(self.windows, f.name))
                                                for f in fields(self.windows)
                                                if isinstance(getattr(self.windows, f.name), np.ndarray)})
        for name in ("starts", "t0_s", "speed0_mps", "course0_deg", "lat0_deg", "lon0_deg", "prev_gnss_disp_m",
                     "accel_mps2", "gyro_radps", "still", "still_grid"):
            setattr(self, name, _read_only(getattr(self, name)))

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


def _read_only(values: np.ndarray) -> np.ndarray:
    """A view of ``values`` that cannot be written through."""
    view = values.view()
    view.flags.writeable = False
    return view


@runtime_checkable
class Estimator(Protocol):
    """The estimator protocol: a ``name`` (a short lower-case identifier: JSON key and entity path
    segment), a ``label`` (legends, table headers) and :meth:`estimate`.

    Optional members, read with :func:`applies`, :func:`describe`, :func:`available` and
    :func:`color_of` (an estimator without them gets the defaults):

    * ``color``: RGB triple of 0-255 integers (default: a palette colour chosen by name);
    * ``applies(drive) -> bool``: whether it can run on a drive (default: every drive), and
      ``requires``, a short text of what a drive must have (said when it is left out);
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


def _member(estimator: Estimator, member: str, default: Any, *args: Any) -> Any:
    """Call an optional member of a plug-in; one it has that raises is the plug-in's error."""
    fn = getattr(estimator, member, None)
    if not callable(fn):
        return default
    try:
        return fn(*args)
    except InputError:
        raise
    except Exception as exc:
        raise EstimatorError(f"estimator {getattr(estimator, 'name', '?')!r}: {member}() failed: {type(exc).__name__}: "
                             f"{str(exc).splitlines()[0] if str(exc) else ''}".rstrip(": "),
                             "fix the plug-in (run with --debug for the traceback)") from exc


def applies(estimator: Estimator, drive: Drive) -> bool:
    """Whether ``estimator`` runs on ``drive`` (its optional ``applies``; default yes)."""
    return bool(_member(estimator, "applies", True, drive))


#: How deep a plug-in's description may nest (arrays and objects): "names to short values".
DESCRIBE_MAX_DEPTH = 16


def describe(estimator: Estimator) -> dict[str, Any]:
    """The estimator's own description (its optional ``describe()``), for reports: a mapping of
    names to short values, as JSON's plain types (:func:`~ionav_viz.core.json_out.plain_json`:
    numpy values, paths and tuples converted, NaN and infinities None)."""
    info = _member(estimator, "describe", {})
    if not isinstance(info, dict):
        raise EstimatorError(f"estimator {estimator.name!r}: describe() returned {type(info).__name__}, not a dict",
                             "return a dict of names to short values, e.g. {'model': 'v2'}")
    try:
        return plain_json(info, max_depth=DESCRIBE_MAX_DEPTH)
    except ValueError as exc:
        raise EstimatorError(f"estimator {estimator.name!r}: describe() returned a value that {exc}",
                             "return a dict of names to short values, e.g. {'model': 'v2'}") from None


def available(estimator: Estimator) -> bool:
    """Whether ``estimator`` can run here at all (its optional ``available()``; default yes)."""
    return bool(_member(estimator, "available", True))


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
            f"estimator {name!r} failed: {type(exc).__name__}: "
            f"{str(exc).splitlines()[0] if str(exc) else ''}".rstrip(": "),
            "fix the plug-in (run with --debug for the traceback)",
        ) from exc
    disp, yaw = _checked(name, est, inputs.n_outages, inputs.n_windows)
    own = _own_positions(name, est, inputs.n_outages, inputs.n_windows)
    if own is None:
        track = rebuild_track(inputs.lat0_deg, inputs.lon0_deg, inputs.course0_deg, disp, yaw)
    else:  # its own positions; the course at the boundaries as its yaw rates turn it
        course = np.asarray(inputs.course0_deg, dtype=float)[:, None] - np.concatenate(
            [np.zeros((inputs.n_outages, 1)), np.cumsum(np.rad2deg(yaw) * WINDOW_S, axis=1)], axis=1)
        track = Track(own[0], own[1], np.mod(course, 360.0))
    return Solution(disp, yaw, track, _checked_health(name, getattr(est, "health", None)),
                    _checked_covariance(name, getattr(est, "pos_cov_m2", None), inputs.n_outages, inputs.n_windows))


def _checked_covariance(name: str, cov: Any, n_outages: int, n_windows: int) -> np.ndarray | None:
    """An estimate's position covariance, checked: shape, then finite, symmetric and positive
    semi-definite (:func:`~ionav_viz.core.covariance.covariance_faults`)."""
    if cov is None:
        return None
    hint = "give pos_cov_m2 as east/north covariances (m^2) of shape (n_outages, n_windows + 1, 2, 2), or none"
    try:
        cov = np.asarray(cov, dtype=np.float64)
    except (TypeError, ValueError):
        raise EstimatorError(f"estimator {name!r}: pos_cov_m2 is not numeric", hint) from None
    if cov.shape != (n_outages, n_windows + 1, 2, 2):
        raise EstimatorError(f"estimator {name!r}: pos_cov_m2 has shape {cov.shape}, expected ({n_outages}, "
                             f"{n_windows + 1}, 2, 2)", hint)
    for fault, mask in covariance_faults(cov).items():
        if mask.any():
            outage, boundary = (int(x) for x in np.argwhere(mask)[0])
            raise EstimatorError(f"estimator {name!r}: pos_cov_m2 is {fault} in outage {outage + 1}, "
                                 f"boundary {boundary}", hint)
    return cov


def _checked_health(name: str, health: Any) -> FilterHealth | None:
    """An estimate's filter health, checked (None when it has none)."""
    if health is None:
        return None
    hint = "give FilterHealth(t_s (rows,), slots, kinds, innovation, variance, status (rows, slots)) or none"
    if not isinstance(health, FilterHealth):
        raise EstimatorError(f"estimator {name!r}: health is {type(health).__name__}, not a FilterHealth", hint)
    rows, slots = len(health.t_s), len(health.slots)
    for field_name in ("innovation", "variance", "status"):
        if np.shape(getattr(health, field_name)) != (rows, slots):
            raise EstimatorError(f"estimator {name!r}: health.{field_name} has shape "
                                 f"{np.shape(getattr(health, field_name))}, expected ({rows}, {slots})", hint)
    if len(health.kinds) != slots:
        raise EstimatorError(f"estimator {name!r}: health has {len(health.kinds)} kinds for {slots} slots", hint)
    return health


def _own_positions(name: str, est: Any, n_outages: int, n_windows: int) -> tuple[np.ndarray, np.ndarray] | None:
    """An estimate's own positions at the window boundaries, checked, or None when it has none."""
    lat, lon = getattr(est, "lat_deg", None), getattr(est, "lon_deg", None)
    if lat is None and lon is None:
        return None
    hint = "give lat_deg and lon_deg (WGS84 degrees) of shape (n_outages, n_windows + 1), or neither"
    try:
        lat, lon = np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64)
    except (TypeError, ValueError):
        raise EstimatorError(f"estimator {name!r}: lat_deg/lon_deg are not numeric", hint) from None
    for field_name, values, limit in (("lat_deg", lat, 90.0), ("lon_deg", lon, 180.0)):
        if values.shape != (n_outages, n_windows + 1):
            raise EstimatorError(f"estimator {name!r}: {field_name} has shape {values.shape}, expected ({n_outages}, "
                                 f"{n_windows + 1})", hint)
        bad = ~np.isfinite(values) | (np.abs(values) > limit)
        if bad.any():
            i, j = (int(x) for x in np.argwhere(bad)[0])
            raise EstimatorError(f"estimator {name!r}: {field_name} is {values[i, j]} in outage {i + 1}, boundary {j}",
                                 hint)
    return lat, lon


#: What an estimate may say of one 1 s window: no car covers more than the fastest speed the
#: readers accept (m) or turns faster than the fastest gyro (rad/s) (:mod:`ionav_viz.sources.plausibility`).
ESTIMATE_LIMITS = {"disp_m": LIMITS["speed_mps"][1] * WINDOW_S, "yaw_rate_radps": LIMITS["yaw_rate_radps"][1]}


def _checked(name: str, est: Any, n_outages: int, n_windows: int) -> tuple[np.ndarray, np.ndarray]:
    hint = ("estimate() must return Estimate(disp_m=..., yaw_rate_radps=...) with finite arrays of shape "
            "(n_outages, n_windows)")
    if not hasattr(est, "disp_m") or not hasattr(est, "yaw_rate_radps"):
        raise EstimatorError(f"estimator {name!r} returned {type(est).__name__}, not an Estimate", hint)
    out = []
    for field_name in ("disp_m", "yaw_rate_radps"):
        raw = getattr(est, field_name)
        if np.iscomplexobj(raw):
            raise EstimatorError(f"estimator {name!r}: {field_name} is complex", "return real numbers (m, rad/s)")
        try:
            values = np.asarray(raw, dtype=np.float64)
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
        limit = ESTIMATE_LIMITS[field_name]
        beyond = np.abs(values) > limit
        if beyond.any():
            i, j = (int(x) for x in np.argwhere(beyond)[0])
            raise EstimatorError(
                f"estimator {name!r}: {field_name} is {values[i, j]:.6g} in outage {i + 1}, window {j + 1}, beyond "
                f"what a car does in 1 s (|{field_name}| <= {limit:.4g})",
                "check the plug-in's units (m per 1 s window, rad/s)")
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
