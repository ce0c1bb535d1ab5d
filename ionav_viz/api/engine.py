"""Where the work over many drives runs: in this process, in a pool of local processes, or on a
Dask cluster, behind one function, :func:`run_each`.

The seam is deliberately small: ``fn(item)`` maps one picklable item (a drive's name and the run's
options) to a small picklable result (a drive's per-outage table, never the drive), and
:func:`run_each` yields ``(index, result)`` as each finishes. The caller orders the results by
index, so what it builds does not depend on the back-end or on the number of workers. Another
back-end (Ray) is one more branch here; nothing in the analysis changes.

A worker process that dies (killed, out of memory) loses the items it was running and the pool:
those items are run again, once, each alone in a fresh process; an item whose process dies again
comes back as a :class:`WorkerLost`. On Dask the scheduler does the same (``allowed-failures``,
set to 1 for a ``local`` cluster) and a ``KilledWorker`` comes back as a :class:`WorkerLost`.

A local pool has at most as many processes as this process may use cores (:func:`default_workers`)
and items (:meth:`Engine.pool_size`). A worker that gets SIGTERM, SIGHUP or SIGINT (the process
group killed by a scheduler, Ctrl-C on a terminal, or the worker alone) stops its item as the
command would, so its ``finally`` blocks remove its partial outputs, then dies by that signal; when
the caller stops early (an exception, a signal, the iterator closed), the workers still running are
sent SIGTERM and so stop the same way.
"""

from __future__ import annotations

import contextlib
import os
import signal
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from ..core.errors import InputError
from ..core.processes import THREAD_VARIABLES, one_thread_environment, worker_context

#: ``--cluster local``: a Dask ``LocalCluster`` on this machine, one single-threaded worker per process.
LOCAL_CLUSTER = "local"


@dataclass(frozen=True)
class WorkerLost:
    """An item whose worker process died twice (or that Dask gave up on): why, in one line."""

    reason: str


@dataclass(frozen=True)
class Engine:
    """How work is spread: ``workers`` processes on this machine (1: in this process), or a Dask
    scheduler's address (``tcp://host:8786``) or ``"local"`` for a ``LocalCluster`` of ``workers``."""

    workers: int = 1
    cluster: str | None = None

    def __post_init__(self) -> None:
        if isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 1:
            raise InputError(f"{self.workers!r} workers: give a whole number of 1 or more", "e.g. --workers 2",
                             param="workers")
        if self.cluster is not None:
            check_cluster_address(self.cluster)

    def pool_size(self, n_items: int | None = None) -> int:
        """The processes a local pool (or a ``local`` Dask cluster) starts: ``workers``, but at most
        the cores this process may use (:func:`default_workers`; more only fight over them) and
        ``n_items``. A remote cluster's size is its own: ``workers``."""
        if self.cluster is not None and self.cluster != LOCAL_CLUSTER:
            return self.workers
        return max(1, min(self.workers, default_workers(), n_items if n_items is not None else self.workers))

    def capped_note(self) -> str | None:
        """One line saying that the pool is smaller than the ``workers`` asked for, because this
        process may use fewer cores; None when it is not."""
        size = self.pool_size()
        if self.backend == "serial" or size == self.workers:
            return None
        return (f"--workers {self.workers}: {size} worker process(es), the cores this process may use "
                "(more would only share them)")

    @property
    def backend(self) -> str:
        """``serial``, ``processes`` or ``dask``."""
        if self.cluster is not None:
            return "dask"
        return "serial" if self.workers == 1 else "processes"

    def start(self) -> Engine:
        """Start the local workers' forkserver now (a no-op for the other back-ends), so that its
        imports (torch, numba: about 2 s) run on another core while this process checks the run's
        options and loads the model, instead of after it. Returns this engine."""
        if self.backend == "processes":
            worker_context()
        return self

    def describe(self) -> str:
        """One line for reports: ``4 processes``, ``in this process``, ``Dask at tcp://...``."""
        if self.backend == "dask":
            where = f"a local cluster of {self.pool_size()} workers" if self.cluster == LOCAL_CLUSTER else self.cluster
            return f"Dask ({where})"
        return "in this process" if self.backend == "serial" else f"{self.pool_size()} processes"


#: The schemes of a Dask scheduler's address that reach another process (``distributed.comm``'s backends).
CLUSTER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
#: What ``--cluster`` takes, for its errors.
CLUSTER_FORMS = ("give local, HOST:PORT or SCHEME://HOST:PORT (SCHEME tcp, tls, ws, wss or ucx), "
                 "e.g. tcp://scheduler:8786")


def check_cluster_address(address: object) -> str:
    """``address`` if it is ``local`` or a Dask scheduler's address, ``[SCHEME://]HOST:PORT``
    (:data:`CLUSTER_SCHEMES`, ``tcp`` when none; an IPv6 host in brackets, ``[::1]:8786``; a port
    1-65535); else an :class:`InputError` for ``cluster`` (Dask's own parser raised a ValueError
    traceback, or a TypeError for a number)."""
    from urllib.parse import urlsplit

    from ..core.errors import printable

    if not isinstance(address, str):
        raise InputError(f"cluster={address!r} is not an address", CLUSTER_FORMS, param="cluster")
    shown = printable(address)
    if not address.strip():
        raise InputError("an empty cluster address", CLUSTER_FORMS, param="cluster")
    if address == LOCAL_CLUSTER:
        return address
    scheme, sep, _ = address.partition("://")
    if sep and scheme.lower() not in CLUSTER_SCHEMES:
        raise InputError(f"{shown}: a Dask scheduler's address does not start with {printable(scheme)}://",
                         CLUSTER_FORMS, param="cluster")
    try:
        parts = urlsplit(address if sep else f"tcp://{address}")
        port = parts.port
    except ValueError as exc:  # an unclosed IPv6 bracket, a port that is not a number or beyond 65535
        raise InputError(f"{shown}: not a scheduler's address ({exc})", CLUSTER_FORMS, param="cluster") from None
    if not parts.hostname or parts.username is not None or parts.path or parts.query or parts.fragment:
        raise InputError(f"{shown}: not a scheduler's address (HOST:PORT, nothing else)", CLUSTER_FORMS,
                         param="cluster")
    if port is None or not 0 < port < 65536:
        raise InputError(f"{shown}: no port (1-65535)", CLUSTER_FORMS, param="cluster")
    return address


def default_workers() -> int:
    """Every core this process may use (``os.process_cpu_count`` where there is one, Python 3.13;
    else ``os.sched_getaffinity``, else every core)."""
    counted = getattr(os, "process_cpu_count", None)
    if counted is not None:
        return max(counted() or 1, 1)
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # macOS, Windows
        return max(os.cpu_count() or 1, 1)


def run_each(fn: Callable[[Any], Any], items: Sequence[Any], engine: Engine) -> Iterator[tuple[int, Any]]:
    """``(index, fn(items[index]))`` for every item, in the order they finish (a
    :class:`WorkerLost` instead of a result where the worker died twice). ``fn`` must be a
    module-level function and items and results picklable for every back-end but ``serial``.
    Closing the iterator early (``--fail-fast``) cancels what has not started and stops what runs."""
    if not items:
        return iter(())
    if engine.backend == "serial":
        return ((i, fn(item)) for i, item in enumerate(items))
    if engine.backend == "processes":
        return _processes(fn, items, engine.pool_size(len(items)))
    return _dask(fn, items, engine)


def _worker_start() -> None:
    """In each worker process, before any work: one thread per library (the pool is the
    parallelism; N workers x N threads would only fight over the cores), and the stop signals'
    handler (:func:`_worker_signal`; in a local pool's workers, whose main thread runs the items)."""
    import sys
    import threading

    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    if "torch" in sys.modules:  # imported before the fork (the forkserver's preload): set, not only asked for
        sys.modules["torch"].set_num_threads(1)
    if threading.current_thread() is threading.main_thread():  # not in a Dask worker's thread: Dask handles its own
        from ..core.signals import STOP_SIGNALS

        for sig in (signal.SIGINT, *STOP_SIGNALS):
            signal.signal(sig, _worker_signal)


#: Whether this worker process is running an item (:func:`_in_worker`), and whether a stop signal
#: has stopped it already (its cleanup runs).
_running_item = False
_stopping = False


def _worker_signal(signum: int, frame: Any) -> None:
    """A worker's handler of SIGINT, SIGTERM and SIGHUP: while it runs an item, the item stops
    as the command stops (``KeyboardInterrupt``, :class:`~ionav_viz.core.signals.Terminated`), so
    that its ``finally`` blocks remove what it had begun to write; idle, it dies by the signal. A
    signal after the first (Ctrl-C to the group, then the parent's SIGTERM) is let go: raised
    inside the first one's cleanup, it would cut it short and leave the temporary file."""
    global _stopping
    if not _running_item:
        _die_by(signum)
    if _stopping:
        return
    _stopping = True
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    from ..core.signals import Terminated

    raise Terminated(signum)


def _die_by(signum: int) -> None:
    """End this process by ``signum``'s default action, as if it had no handler: its parent sees a
    worker killed by that signal."""
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, [signum])  # delivered by now, unless it was blocked
    os._exit(128 + signum)  # not reached


def _in_worker(fn: Callable[[Any], Any], item: Any) -> Any:
    """``fn(item)`` in a worker process; a stop signal that came meanwhile (the item has cleaned
    up) ends the process by that signal rather than the item alone: the pool's other items do
    not start in a process that was told to stop."""
    from ..core.signals import Terminated

    global _running_item
    _running_item = True
    try:
        return fn(item)
    except KeyboardInterrupt:
        _die_by(signal.SIGINT)
    except Terminated as exc:
        _die_by(exc.signum)
    finally:
        _running_item = False


def _stop_workers(pool: Any) -> None:
    """SIGTERM to the pool's worker processes still alive: each stops its item, removing what it
    had begun to write (:func:`_worker_signal`), and dies. ``ProcessPoolExecutor`` has no public
    list of its processes; its ``_processes`` is read defensively."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        with contextlib.suppress(OSError, ValueError, AttributeError):  # gone already, or closed
            if process.is_alive():
                process.terminate()


def _processes(fn: Callable[[Any], Any], items: Sequence[Any], workers: int) -> Iterator[tuple[int, Any]]:
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    lost: list[int] = []
    pool = ProcessPoolExecutor(workers, mp_context=worker_context(), initializer=_worker_start)
    complete = False
    try:
        futures = {}
        with one_thread_environment():  # spawn's workers start here, at the first submits
            for i, item in enumerate(items):
                try:
                    futures[pool.submit(_in_worker, fn, item)] = i
                except BrokenProcessPool:  # a worker died already, while the items were being handed out
                    lost += range(i, len(items))
                    break
        for fut in as_completed(futures):
            try:
                value = fut.result()
            except BrokenProcessPool:  # a worker died: every item not finished is lost with the pool
                lost.append(futures[fut])
                continue
            yield futures[fut], value
        complete = True
    finally:
        if not complete:  # stopped early (an exception, a signal, the caller closed the iterator): so do the workers
            _stop_workers(pool)
        pool.shutdown(wait=True, cancel_futures=True)
    yield from _retry_alone(fn, items, sorted(lost), workers, none_done=len(lost) == len(items))


def _retry_alone(fn: Callable[[Any], Any], items: Sequence[Any], lost: list[int], workers: int,
                 none_done: bool) -> Iterator[tuple[int, Any]]:
    """Each lost item once more, alone in a fresh process (``workers`` at a time), so that the
    item that kills its worker is told from those that only shared its pool. When no item had
    come back at all and the whole first batch dies again, the workers cannot start here (a
    ``spawn`` re-imports the main module: a script without ``if __name__ == "__main__":``, or
    standard input): a :class:`ToolFailure`."""
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    from ..core.errors import ToolFailure

    for first in range(0, len(lost), workers):
        batch = lost[first : first + workers]
        pools = [ProcessPoolExecutor(1, mp_context=worker_context(), initializer=_worker_start) for _ in batch]
        died = []
        complete = False
        try:
            with one_thread_environment():
                futures = {pool.submit(_in_worker, fn, items[i]): i for pool, i in zip(pools, batch)}
            for fut in as_completed(futures):
                try:
                    value = fut.result()
                except BrokenProcessPool:
                    died.append(futures[fut])
                    continue
                none_done = False
                yield futures[fut], value
            complete = True
        finally:
            for pool in pools:
                if not complete:
                    _stop_workers(pool)
                pool.shutdown(wait=True, cancel_futures=True)
        if none_done and len(died) == len(batch):
            raise ToolFailure("every worker process died before returning anything: they cannot start here (a script "
                              "that starts them needs its work under 'if __name__ == \"__main__\":', and standard "
                              "input cannot be re-imported), or every drive exhausts the memory; try --workers 1")
        for i in sorted(died):
            yield i, WorkerLost("its worker process died twice (killed, or out of memory); retried once")
        none_done = False


def _greet_scheduler(address: str, timeout_s: float) -> None:
    """Connect to the scheduler at ``address`` and exchange Dask's greeting, all within
    ``timeout_s``, then hang up: Dask's own ``Client`` bounds the connection by its timeout but
    waits for the greeting's reply without one, so a port that accepts and never answers held it
    for as long as the peer kept the connection open. A TimeoutError when nothing answers in time."""
    import asyncio

    from distributed.comm import connect
    from distributed.security import Security

    async def greet() -> None:
        comm = await connect(address, timeout=timeout_s, **Security().get_connection_args("client"))
        await comm.close()

    try:
        asyncio.run(asyncio.wait_for(greet(), timeout_s))
    except (OSError, TimeoutError, ValueError):
        raise
    except Exception as exc:  # something else answered: a frame of absurd length (MemoryError), a hang-up mid-frame
        raise OSError(f"what answered is not a Dask scheduler ({type(exc).__name__})") from None


def _dask(fn: Callable[[Any], Any], items: Sequence[Any], engine: Engine) -> Iterator[tuple[int, Any]]:
    try:
        import dask
        from dask.utils import parse_timedelta
        from distributed import Client, LocalCluster, as_completed
        from distributed.scheduler import KilledWorker
    except ImportError:
        raise InputError("--cluster needs Dask, which is not installed", 'pip install "ionav-viz[cluster]"',
                         param="cluster") from None

    cluster = None
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):  # a dying item is retried once (local cluster)
        if engine.cluster == LOCAL_CLUSTER:
            with one_thread_environment():  # its worker processes start here
                cluster = LocalCluster(n_workers=engine.pool_size(len(items)), threads_per_worker=1, processes=True,
                                       dashboard_address=None)
            address = cluster
        else:
            address = engine.cluster
        timeout_s = parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), "s")
        try:
            if cluster is None:
                _greet_scheduler(engine.cluster, timeout_s)
            client = Client(address, timeout=timeout_s)
        except (OSError, TimeoutError, ValueError) as exc:
            if cluster is not None:
                cluster.close()
            why = " ".join(str(exc).split())
            why = f" ({why})" if why else f" within {timeout_s:g} s (Dask's distributed.comm.timeouts.connect)"
            raise InputError(f"no Dask scheduler answered at {engine.cluster}{why}",
                             "start one ('dask scheduler', then 'dask worker ADDRESS'), or use --cluster local",
                             param="cluster") from None
    try:
        client.run(_worker_start)
        futures = client.map(fn, list(items), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for fut in as_completed(futures):
            try:
                value = fut.result()
            except KilledWorker as exc:
                value = WorkerLost(f"Dask gave up on it: its worker died ({' '.join(str(exc).split())[:200]})")
            fut.release()  # the result is ours now; the cluster forgets it
            yield index[fut.key], value
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
