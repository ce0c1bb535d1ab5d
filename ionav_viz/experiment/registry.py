"""Finding estimators: the built-ins by name, plug-ins by entry point or ``MODULE:NAME`` /
``FILE.py:NAME``, and the default set.

Use a plug-in with ``ionav-viz evaluate DRIVE --estimator mymodule:ConstantSpeed`` (a class or a
no-argument factory; ``./myest.py:ConstantSpeed`` loads a file), or register it in a package's
metadata under the entry-point group ``ionav_viz.estimators`` (``const = "mymodule:ConstantSpeed"``)
and select it by name with ``--estimators ins,const``. The contract an estimator follows is
:mod:`ionav_viz.nav.protocol`.
"""

from __future__ import annotations

import importlib
import inspect
import re
from collections.abc import Sequence
from typing import Any

from ..core.fileio import check_regular_input
from ..nav.protocol import Estimator, EstimatorError, available, validate

#: The entry-point group that installed packages register estimators under.
ENTRY_POINT_GROUP = "ionav_viz.estimators"
#: The built-in estimators, in report order. ``ins`` is the paper's baseline (improvements are
#: reported against it).
BUILTIN = ("ins", "idnn", "odo", "ekf", "gins")
BASELINE = "ins"


def builtin(name: str, model: Any = None) -> Estimator:
    """A built-in estimator by name; ``model`` (an IDNN model or its directory) is for ``idnn``."""
    if name == "ins":
        from ..nav.ins import InsEstimator

        return InsEstimator()
    if name == "idnn":
        from ..learning.idnn import IdnnEstimator

        return IdnnEstimator(model)
    if name == "odo":
        from ..nav.odometry import OdometryEstimator

        return OdometryEstimator()
    if name == "ekf":
        from ..nav.ekf import EkfEstimator

        return EkfEstimator()
    if name == "gins":
        from ..nav.gins import GinsEstimator

        return GinsEstimator()
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
            f"estimator {spec!r}: cannot import {module_spec} ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0] if str(exc) else ''})",
            "give a module importable from the current directory or installed, or a path like ./myest.py",
        ) from exc
    factory = module
    for part in attr.split("."):
        factory = getattr(factory, part, None)
        if factory is None:
            raise EstimatorError(f"estimator {spec!r}: {module_spec} has no {attr}",
                                 "name a class or a no-argument factory")
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
        raise EstimatorError(f"estimator file {path_text!r} is not a .py file",
                             "give a Python file, e.g. ./myest.py:ConstantSpeed", param="estimators")
    check_regular_input(path, "estimators", hint="give a Python file, e.g. ./myest.py:ConstantSpeed", missing_ok=True)
    if not path.is_file():
        raise EstimatorError(f"estimator file {path_text}: no such file",
                             "check the path (relative to the current directory)", param="estimators")
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
            f"estimator {origin!r}: creating it failed ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0] if str(exc) else ''})",
            "NAME must be a class or a factory that takes no arguments",
        ) from exc
    return validate(obj, origin)


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
        raise EstimatorError(f"cannot leave out {', '.join(map(repr, unknown))}: not a built-in estimator",
                             f"built-ins: {', '.join(BUILTIN)}")
    defaults = [n for n in BUILTIN if n not in without]
    chosen: list[Estimator] = []
    for item in list(defaults if names is None else names):
        est = _one(item, model, explicit)
        if est is not None:
            chosen.append(est)
    for item in plugins:
        try:
            chosen.append(_one(item, model, True))
        except EstimatorError as exc:
            exc.param = "plugins"  # the command line's --estimator
            raise
    # a plug-in named 'ins' without the INS DR became the baseline every improvement is measured against
    for est in chosen:
        if est.name in BUILTIN and not isinstance(est, type(builtin(est.name))):
            raise EstimatorError(f"estimator {est.name!r} ({type(est).__name__}): that is a built-in estimator's name",
                                 "give the plug-in a name of its own (its name attribute)")
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


def _one(item: str | Estimator, model: Any, explicit: bool) -> Estimator | None:
    """One estimator from a name, spec or object (None: a default built-in not available here); a
    chosen plug-in must be available."""
    est = _named(item, model, explicit)
    plugin = est is not None and not (isinstance(item, str) and item.strip() in BUILTIN)
    if plugin and not available(est):
        raise EstimatorError(f"estimator {est.name!r} is not available here (its available() says so)",
                             "leave it out, or fix what it needs")
    return est


def _named(item: str | Estimator, model: Any, explicit: bool) -> Estimator | None:
    """One estimator from a name, spec or object (None: a default built-in not available here)."""
    if not isinstance(item, str):  # an object, a class or a factory
        return _instantiate(item, getattr(item, "__name__", type(item).__name__))
    key = item.strip()
    if ":" in key:
        return load_plugin(key)
    elif key in BUILTIN:
        est = builtin(key, model)
        return est if explicit or available(est) else None
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
        return _instantiate(factory, found[key].value)
