"""Starting worker processes: the ``forkserver`` the local pool's workers are forked from.

Light on purpose (the standard library only): the command line starts the forkserver from here
before it imports the rest of the package, so that the forkserver's imports (numpy, numba and
the estimators: about 2 s) run on another core while the command starts, instead of after it.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

#: The variables that size the numerical libraries' thread pools, read when each library loads.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")

#: What the forkserver imports once, before it forks the workers: each worker then starts with
#: them loaded instead of importing them again (the IDNN runs in numpy: torch is not needed to evaluate).
PRELOAD = ("numpy", "pandas", "safetensors.numpy", "numba", "ionav_viz.api.fleet", "ionav_viz.learning.idnn",
           "ionav_viz.nav.planar_filter")


@contextlib.contextmanager
def one_thread_environment() -> Iterator[None]:
    """While worker processes (or the forkserver) are started: :data:`THREAD_VARIABLES` at 1 where
    unset, so that they load numpy's BLAS and the others with one thread (set later, in the
    worker, they come after numpy's import and do nothing); this process's own setting is restored
    after (its libraries read them when they loaded)."""
    unset = [name for name in THREAD_VARIABLES if name not in os.environ]
    os.environ.update(dict.fromkeys(unset, "1"))
    try:
        yield
    finally:
        for name in unset:
            os.environ.pop(name, None)


def worker_context():
    """A ``forkserver`` where there is one (Linux, macOS), else ``spawn``: never a plain ``fork``
    of this process, which may run threads (torch, numba, the progress bar), and a fork after
    threads can deadlock. The forkserver is a fresh single-threaded process that imports
    :data:`PRELOAD` once; the workers are forked from it. Starting it returns at once (the imports
    run in the forkserver); a second call reuses it. It exits with this process."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    from multiprocessing import forkserver

    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(PRELOAD))
    with one_thread_environment():
        forkserver.ensure_running()  # started now, with one thread per library (a no-op when it runs)
    return context
