"""Estimators as plug-ins: one protocol, the inputs every estimator gets, and how they are found.

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

Use it with ``ionav-viz evaluate DRIVE --estimator mymodule:ConstantSpeed`` (a class or a
no-argument factory), or register it in a package's metadata under the entry-point group
``ionav_viz.estimators`` (``const = "mymodule:ConstantSpeed"``) and select it by name with
``--estimators ins,const``.

Optional members: ``color`` (RGB), ``applies(drive) -> bool`` (default: applies to every
drive), ``describe() -> dict`` (shown in reports and recordings).

Rule for fair comparison: GNSS inside an outage is the truth being scored. An estimator may
read ``inputs.windows`` (the whole drive's windows) only *before* each outage's start window.
"""

from __future__ import annotations

import importlib
import inspect
import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..core.drive import Drive
from ..core.errors import InputError
from .bias import SensorBias
from .track import Track, rebuild_track
from .windows import Windows

log = logging.getLogger("ionav_viz")

#: The entry-point group that installed packages register estimators under.
ENTRY_POINT_GROUP = "ionav_viz.estimators"
#: The built-in estimators, in report order. ``ins`` is the paper's baseline (improvements are
#: reported against it).
BUILTIN = ("ins", "idnn", "odo", "ekf")
BASELINE = "ins"
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
    """The estimator protocol (see the module docstring for an example)."""

    name: str
    label: str

    def estimate(self, inputs: EstimatorInputs) -> Estimate: ...


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


# --- finding estimators -------------------------------------------------------------------


def builtin(name: str, model: Any = None) -> Estimator:
    """A built-in estimator by name; ``model`` (an IDNN model or its directory) is for ``idnn``."""
    if name == "ins":
        from .ins import InsEstimator

        return InsEstimator()
    if name == "idnn":
        from .idnn import IdnnEstimator

        return IdnnEstimator(model)
    if name == "odo":
        from .odometry import OdometryEstimator

        return OdometryEstimator()
    if name == "ekf":
        from .ekf import EkfEstimator

        return EkfEstimator()
    raise EstimatorError(f"unknown built-in estimator {name!r}", f"choose from {', '.join(BUILTIN)}")


def entry_points() -> dict[str, Any]:
    """Estimators registered by installed packages under :data:`ENTRY_POINT_GROUP`, by name."""
    from importlib.metadata import entry_points as eps

    return {ep.name: ep for ep in eps(group=ENTRY_POINT_GROUP)}


def load_plugin(spec: str) -> Estimator:
    """``MODULE:NAME`` or ``PATH.py:NAME`` -> an estimator: NAME is a class or a no-argument factory.

    A module is looked up as Python imports it, and then in the current directory (a console
    script does not put it on ``sys.path``, ``python -m`` does); a path to a ``.py`` file is
    loaded from that file, its folder added to ``sys.path`` so that it can import its neighbours.
    """
    module_spec, _, attr = spec.rpartition(":")  # rpartition: a Windows path has a drive colon
    if not module_spec or not attr:
        raise EstimatorError(f"estimator {spec!r}: expected MODULE:NAME or FILE.py:NAME",
                             "e.g. 'mymodule:ConstantSpeed' or './myest.py:ConstantSpeed'", param="estimators")
    try:
        module = _import_file(module_spec) if _is_path(module_spec) else _import_module(module_spec)
    except EstimatorError:
        raise
    except Exception as exc:
        raise EstimatorError(
            f"estimator {spec!r}: cannot import {module_spec} ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})",
            "give a module importable from the current directory or installed, or a path like ./myest.py",
        ) from exc
    factory = module
    for part in attr.split("."):
        factory = getattr(factory, part, None)
        if factory is None:
            raise EstimatorError(f"estimator {spec!r}: {module_spec} has no {attr}", "name a class or a no-argument factory")
    return _instantiate(factory, spec)


def _is_path(module_spec: str) -> bool:
    return module_spec.endswith(".py") or "/" in module_spec or "\\" in module_spec


def _import_module(name: str) -> Any:
    """Import ``name`` as Python would, falling back to the current directory (appended to
    ``sys.path``, so a local file never shadows an installed package)."""
    import os
    import sys

    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        here = os.getcwd()
        top = name.split(".")[0]
        if exc.name != top or here in sys.path or "" in sys.path:
            raise
        sys.path.append(here)
        return importlib.import_module(name)


def _import_file(path_text: str) -> Any:
    """Load a plug-in module from a ``.py`` file (registered in ``sys.modules`` under a private name)."""
    import importlib.util
    import sys
    import zlib
    from pathlib import Path

    path = Path(path_text).expanduser()
    if path.suffix != ".py":
        raise EstimatorError(f"estimator file {path_text!r} is not a .py file", "give a Python file, e.g. ./myest.py:ConstantSpeed",
                             param="estimators")
    if not path.is_file():
        raise EstimatorError(f"estimator file {path_text}: no such file", "check the path (relative to the current directory)",
                             param="estimators")
    path = path.resolve()
    stem = re.sub(r"\W", "_", path.stem)
    name = f"ionav_viz_plugin_{stem}_{zlib.crc32(str(path).encode()):08x}"  # one module per file
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise EstimatorError(f"estimator file {path_text}: cannot be loaded as a Python module", param="estimators")
    module = importlib.util.module_from_spec(spec)
    if str(path.parent) not in sys.path:
        sys.path.append(str(path.parent))
    sys.modules[name] = module  # before running it: dataclasses and pickling look the module up
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _instantiate(factory: Any, origin: str) -> Estimator:
    try:
        # a class passes the protocol check by its class attributes: instantiate classes always
        is_instance = not inspect.isclass(factory) and isinstance(factory, Estimator)
        obj = factory if is_instance or not callable(factory) else factory()
    except Exception as exc:
        raise EstimatorError(
            f"estimator {origin!r}: creating it failed ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})",
            "NAME must be a class or a factory that takes no arguments",
        ) from exc
    return validate(obj, origin)


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


def resolve(
    names: Sequence[str | Estimator] | None = None,
    *,
    plugins: Sequence[str | Estimator] = (),
    without: Sequence[str] = (),
    model: Any = None,
) -> list[Estimator]:
    """The estimators to run, in order, without duplicates.

    ``names``: built-in names, entry-point names, ``MODULE:NAME`` / ``FILE.py:NAME`` specs or
    estimator objects; None means every built-in but those in ``without`` (the IDNN only if a
    model is available: the shipped one or ``model``). ``plugins`` are added after them
    (``--estimator``).
    """
    explicit = names is not None
    unknown = [w for w in without if w not in BUILTIN]
    if unknown:
        raise EstimatorError(f"cannot leave out {', '.join(map(repr, unknown))}: not a built-in estimator", f"built-ins: {', '.join(BUILTIN)}")
    defaults = [n for n in BUILTIN if n not in without]
    chosen: list[Estimator] = []
    for item in list(defaults if names is None else names) + list(plugins):
        if not isinstance(item, str):  # an object, a class or a factory
            chosen.append(_instantiate(item, getattr(item, "__name__", type(item).__name__)))
            continue
        key = item.strip()
        if ":" in key:
            chosen.append(load_plugin(key))
        elif key in BUILTIN:
            est = builtin(key, model)
            if not explicit and not est.available():  # type: ignore[attr-defined]
                continue
            chosen.append(est)
        else:
            found = entry_points()
            if key not in found:
                known = sorted(set(BUILTIN) | set(found))
                raise EstimatorError(f"unknown estimator {key!r}", f"choose from {', '.join(known)}, or give MODULE:NAME")
            try:
                factory = found[key].load()
            except Exception as exc:
                raise EstimatorError(f"estimator {key!r}: its entry point {found[key].value} does not load "
                                     f"({type(exc).__name__}: {exc})", "reinstall the package that provides it") from exc
            chosen.append(_instantiate(factory, found[key].value))
    seen: dict[str, Estimator] = {}
    for est in chosen:
        if est.name in seen:
            if seen[est.name] is not est and type(seen[est.name]) is not type(est):
                raise EstimatorError(f"two estimators are named {est.name!r}", "rename one of them")
            continue
        seen[est.name] = est
    if not seen:
        raise EstimatorError("no estimator to run", "choose at least one, e.g. ins", param="estimators")
    return list(seen.values())
