"""The numerical kernels' compilation, as a user sees it.

numba compiles a kernel the first time it runs with its argument types and keeps the result in its
cache (the package's ``__pycache__``, or the user's cache folder where that is read-only): the first
run after an install or an update compiles (the 3D filter about 15 s of a core, the planar one about
6 s), later runs load from the cache in a fraction of a second. A front end that shows progress asks
to be told once (:func:`on_first_compile`), so that a run that seems to stand still says why; a load
from the cache says nothing. The filters' modules :func:`watch` themselves at import (the
simulator's one small kernel compiles in a blink and is not watched).
"""

from __future__ import annotations

from collections.abc import Callable

_watched: set[str] = set()
_notice: list[Callable[[], None]] = []  # at most one, called at most once
_listening: list[bool] = []


def on_first_compile(notice: Callable[[], None] | None) -> None:
    """Call ``notice`` once, when numba next starts compiling a kernel of a watched module in this
    process (not when it loads one from its cache); None: tell no one."""
    _notice[:] = [notice] if notice is not None else []


def watch(module: str) -> None:
    """Count the kernels of ``module`` (its ``__name__``) for :func:`on_first_compile`; a module that
    defines kernels calls it once, at its import (it imports numba anyway)."""
    _watched.add(module)
    if _listening:
        return
    from numba.core import event

    class _Listener(event.Listener):
        def on_start(self, event) -> None:
            py_func = getattr(event.data.get("dispatcher"), "py_func", None)
            if _notice and getattr(py_func, "__module__", None) in _watched:
                _notice.pop()()

        def on_end(self, event) -> None:
            pass

    event.register("numba:compile", _Listener())
    _listening.append(True)
