"""Shared helpers: run the CLI as a user would, and write small drives."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
#: The variables that size the numerical libraries' thread pools (OpenMP: torch's intra-op threads).
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def pytest_configure(config) -> None:
    """Each pytest-xdist worker is one core's worth of tests (``-n 2`` on 2 cores): its torch, and
    every process it starts, runs one thread, as the fleet's worker processes do. Two workers whose
    torch ran a thread per core each (four threads on two cores) spent most of their CPU waiting on
    each other in every small network's step. A variable the user set is kept; ``-n 0`` is untouched.

    Ctrl-C is Python's again where the suite was started with SIGINT ignored (a shell's background
    job without job control, ``nohup``): every process the tests start inherits an ignored SIGINT,
    so a test stopping ``replay --serve-web`` with Ctrl-C, as a user does, waited on it for
    :data:`HANG_S`."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        if config.pluginmanager.hasplugin("xdist") and config.getoption("numprocesses", None):
            compile_kernels_once()
        return
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    if "torch" in sys.modules:  # imported before this hook: its pool is already sized
        sys.modules["torch"].set_num_threads(int(os.environ["OMP_NUM_THREADS"]))


#: Every numba kernel the suite runs, compiled into numba's cache (the package's ``__pycache__``), in
#: two processes, one a core: the strapdown filter (gins), the longest (about 15 s); the planar filter
#: (ekf, the IDNN's calibration), the mechanisation alone and the simulator's first-order lag.
_DRIVE = """
import json
import numpy as np
import ionav_viz as iv
entry = json.load(open("tests/data/real/corpus.json"))["logs"]["roof_mems_rtk"]
options = iv.ReadOptions(log=iv.LogOptions(imu_mount="auto", **entry.get("log", {})), span="0s:40s")
drive = iv.load_drive("tests/data/real/" + entry["file"], options)
"""
KERNELS = (_DRIVE + """
iv.evaluate([drive], 10, estimators=["gins"])
""", _DRIVE + """
from ionav_viz.nav.strapdown import N_NOMINAL, QW, propagate
from ionav_viz.sim.imu import _first_order
iv.evaluate([drive], 10, estimators=["ekf"])
_first_order(np.zeros((3, 1)), np.full(3, 0.5))
still = np.zeros(N_NOMINAL)
still[QW] = 1.0
propagate(np.arange(3.0), np.zeros((3, 3)), np.zeros((3, 3)), still, 50.0)
""")


def compile_kernels_once() -> None:
    """Before the workers start: on a fresh checkout each worker, and each command a test starts
    before the cache is written, compiled the same kernels at once (about 20 s of a core each; a
    cold suite 5:25 against 4:38 warm). A failure here is left to the tests that use the kernels."""
    runs = [subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL) for code in KERNELS]
    for run in runs:
        try:
            run.wait(timeout=HANG_S)
        except subprocess.TimeoutExpired:
            run.kill()
            run.wait()


#: Modules of one test that runs for half a minute (a browser loading the web viewer): queued first.
LONG_FIRST = ("tests/test_web_browser.py::",)


def pytest_collection_modifyitems(items) -> None:
    """The tests of :data:`LONG_FIRST` first. pytest-xdist's ``loadgroup`` queues the groups of most
    tests first, then the single tests in their collection order: a half-minute test collected near
    the end ran alone on one worker while the other had finished."""
    items.sort(key=lambda item: not item.nodeid.startswith(LONG_FIRST))


#: A guard against a hang, never a limit on a slow run: a run that takes this long is stuck (a loaded
#: machine makes a test slower, never 30 times slower). Tests time nothing else.
HANG_S = 1800.0


def run_cli(*args: str, env: dict | None = None, cwd: Path | None = None, timeout: float | None = None) -> subprocess.CompletedProcess:
    """Run ``ionav-viz ARGS`` as a user would and return the completed process (text).

    In this process by default: ``ionav_viz.cli.main`` with its own argv, environment, working
    directory, standard streams (no standard input) and a fresh set of Python's default warning
    filters, exactly as the console script calls it, without paying the interpreter's start and
    the imports of torch and Rerun on every call. ``IONAV_TEST_SUBPROCESS=1`` runs every call in a
    fresh interpreter instead; a test whose point is the process itself (signals, start-up time,
    what is imported) uses :func:`run_cli_process`. ``timeout`` (s): a guard against a hang only
    (:data:`HANG_S`), for a test about one; none by default."""
    if os.environ.get("IONAV_TEST_SUBPROCESS") == "1":
        return run_cli_process(*args, env=env, cwd=cwd, timeout=timeout)
    return _run_cli_here(list(args), env, cwd, timeout)


def run_cli_process(*args: str, env: dict | None = None, cwd: Path | None = None, timeout: float | None = None) -> subprocess.CompletedProcess:
    """Run ``ionav-viz ARGS`` in a fresh interpreter; returns the completed process (text)."""
    return subprocess.run(
        [sys.executable, "-m", "ionav_viz.cli", *args],
        capture_output=True,
        text=True,
        env=_cli_env(env),
        cwd=cwd or REPO,
        timeout=timeout,
    )


def _cli_env(env: dict | None) -> dict:
    full_env = {**os.environ, **(env or {})}
    for inherited in ("IONAV_DATA", "COLUMNS"):  # the developer's data root and terminal width are not the test's
        if inherited not in (env or {}):
            full_env.pop(inherited, None)
    return full_env


def _run_cli_here(args: list[str], env: dict | None, cwd: Path | None, timeout: float | None) -> subprocess.CompletedProcess:
    import io
    import logging
    import signal
    import traceback
    import warnings

    from ionav_viz.cli import main

    saved_env, saved_cwd, saved_argv = dict(os.environ), os.getcwd(), sys.argv
    saved_streams = sys.stdin, sys.stdout, sys.stderr
    saved_signals = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGALRM)}
    logger = logging.getLogger("ionav_viz")  # main() points it at stderr; library tests read it with caplog
    saved_logger = logger.handlers[:], logger.level, logger.propagate
    out, err = io.StringIO(), io.StringIO()
    code = 0
    try:
        run_env = _cli_env(env)  # before the clear: a subprocess inherits this process's environment
        os.environ.clear()
        os.environ.update(run_env)
        os.chdir(cwd or REPO)
        sys.argv = ["ionav-viz", *args]
        sys.stdin, sys.stdout, sys.stderr = io.StringIO(""), out, err

        def expired(signum, frame):  # as subprocess.run(timeout=) raises: a hang fails the test, not the suite
            raise subprocess.TimeoutExpired(["ionav-viz", *args], timeout, out.getvalue(), err.getvalue())

        if timeout is not None:  # a hang guard (HANG_S) where a hang is what the test is about
            signal.signal(signal.SIGALRM, expired)
            signal.setitimer(signal.ITIMER_REAL, timeout)
        with warnings.catch_warnings():
            # a fresh interpreter's filters, printed to stderr as there (pytest records them instead)
            warnings.resetwarnings()
            for category in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
                warnings.simplefilter("ignore", category)
            warnings.showwarning = warnings._showwarning_orig  # type: ignore[attr-defined]
            try:
                main()
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            except subprocess.TimeoutExpired:
                raise
            except BaseException:  # what the interpreter would print before exiting with 1
                traceback.print_exc(file=err)
                code = 1
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        sys.stdin, sys.stdout, sys.stderr = saved_streams
        sys.argv = saved_argv
        os.chdir(saved_cwd)
        os.environ.clear()
        os.environ.update(saved_env)
        for signum, handler in saved_signals.items():
            signal.signal(signum, handler)
        logger.handlers[:], logger.level, logger.propagate = saved_logger
    return subprocess.CompletedProcess(["ionav-viz", *args], code, out.getvalue(), err.getvalue())


def assert_same_sequences(reference: list[dict], got: list[dict], estimators, rel: float, abs: float = 1e-9) -> None:
    """Two reports' ``sequences`` (``to_json``) agree: the same outages, and every metric of each
    estimator within ``rel``/``abs``. A metric that is undefined (``None``, e.g. ``final_error_pct``
    below 10 m driven) must be undefined in both."""
    assert len(got) == len(reference) > 0
    for a, b in zip(reference, got):
        assert b["start_s"] == pytest.approx(a["start_s"], abs=1e-9)
        for est in estimators:
            assert b[est].keys() == a[est].keys(), est
            for key, value in a[est].items():
                if value is None:
                    assert b[est][key] is None, (est, key, b[est][key])
                else:
                    assert b[est][key] == pytest.approx(value, rel=rel, abs=abs), (est, key)


def one_line_error(done: subprocess.CompletedProcess, *words: str) -> str:
    """Bad input as the CLI promises it: exit code 2, one line on stderr starting ``error:`` that
    holds each of ``words``, no traceback. Returns the line."""
    assert done.returncode == 2, (done.returncode, done.stderr)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), done.stderr
    assert "Traceback" not in done.stderr
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


def expect_one_line_error(path: Path, *messages: str) -> None:
    """``ionav-viz evaluate PATH`` fails on bad input: exit 2, one line, no traceback, naming ``messages``."""
    proc = run_cli("evaluate", str(path), "--no-idnn")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    for message in messages:
        assert message in proc.stderr, proc.stderr


@pytest.fixture(scope="session")
def ideal_drive_csv(tmp_path_factory) -> Path:
    """A noise-free synthetic motorway drive (perfect sensors, flat road)."""
    from ionav_viz.sim.simulate import SensorModel, write_simulated_drive

    path = tmp_path_factory.mktemp("drives") / "V-ideal.csv"
    return write_simulated_drive(path, "motorway", seed=3, duration_s=120, sensors=SensorModel.ideal())
