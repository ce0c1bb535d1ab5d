"""The first run's compilation of the filters is said once, to whoever asked (core/jit.py); a kernel
loaded from numba's cache, or one of a module nobody watches, says nothing."""

from __future__ import annotations

import numba

from ionav_viz.core import jit


def _kernel(module: str):
    def double(x):
        return 2 * x

    double.__module__ = module
    return numba.njit(double)  # no cache: every new argument type compiles


def test_a_watched_modules_first_compilation_is_said_once():
    said: list[str] = []
    double = _kernel(__name__)
    jit.watch(__name__)
    jit.on_first_compile(lambda: said.append("compiling"))
    try:
        assert double(1) == 2 and double(1.5) == 3.0  # two compilations, one notice
    finally:
        jit.on_first_compile(None)
    assert said == ["compiling"]


def test_an_unwatched_module_or_no_one_asking_says_nothing():
    said: list[str] = []
    jit.on_first_compile(lambda: said.append("compiling"))
    try:
        assert _kernel("somebody.elses")(2) == 4
    finally:
        jit.on_first_compile(None)
    jit.watch(__name__)
    assert _kernel(__name__)(3) == 6  # compiled, but no one asked
    assert said == []
