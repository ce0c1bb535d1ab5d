"""A private headless Rerun viewer process, driven through ``rerun.experimental.ViewerClient``.

Started in headless mode (``rerun --headless --window-size WxH``) on a free local port, it opens
recordings, shows them with a given blueprint at a given time and saves screenshots, and is always
shut down afterwards, also on Ctrl-C, SIGTERM and SIGHUP. Its own output (including the failed
OpenStreetMap tile downloads of an offline map view) goes to a log file, never to the user's
terminal. On a machine without a GPU, Mesa's lavapipe Vulkan driver (Debian package
``mesa-vulkan-drivers``) renders on the CPU; without any renderer the viewer cannot start and
:class:`RendererMissing` says so.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..core.errors import ToolFailure
from ..core.fileio import atomic_path, utf8_alias
from ..core.signals import STOP_SIGNALS, raise_terminated


class RendererMissing(ToolFailure):
    """The headless viewer could not start or render (no GPU and no software renderer)."""


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def rerun_executable() -> str:
    """The ``rerun`` executable that came with rerun-sdk (beside this interpreter, else on PATH)."""
    beside = Path(sys.executable).parent / "rerun"
    if beside.is_file():
        return str(beside)
    found = shutil.which("rerun")
    if found is None:
        raise RendererMissing("the 'rerun' viewer executable is not installed (it comes with rerun-sdk)")
    return found


def _state_probe() -> Callable[[str], None]:
    """A function that asks the viewer at a URL for its state, and raises until it answers. Through
    Rerun's native module, which imports at once: the ``rerun`` package takes about a second to
    import, in which a starting viewer answers; ViewerClient's own call where that module differs."""
    try:
        from rerun_bindings import ViewerClientInternal
    except ImportError:
        ViewerClientInternal = None
    if ViewerClientInternal is None or not hasattr(ViewerClientInternal, "viewer_control"):
        from rerun.experimental import ViewerClient

        return lambda url: ViewerClient.connect(url).get_state()
    request = json.dumps({"get_state": {}})

    def probe(url: str) -> None:
        if "get_state" not in json.loads(ViewerClientInternal(url).viewer_control(request)):
            raise RuntimeError("the viewer sent no state")

    return probe


class HeadlessViewer:
    """A private headless Rerun viewer process; use as a context manager (always shut down)."""

    #: Seconds between tries to reach a starting viewer.
    poll_s = 0.05
    #: Seconds to let the viewer draw after a change of blueprint and time, before the screenshot.
    settle_s = 0.4
    #: No screenshot before this many seconds after the viewer answered: at its start it shows two
    #: notification toasts over the top right of the window ("Listening for gRPC connections on ...",
    #: "Software rasterizer detected"), which no option or command turns off. Measured on this 2-core
    #: machine, idle and with three busy processes alike, they are gone 1.6-1.8 s after the start; a
    #: shot after 1.2 s (a CI run, 2026-11-26) carried one over the map view.
    toasts_gone_s = 2.5

    def __init__(self, width: int, height: int, timeout_s: float = 60.0, *, wait: bool = True) -> None:
        """``wait``: entering waits until the viewer answers (:class:`RendererMissing` if it cannot
        start); False: entering only starts its process, and :meth:`ready` (and every call) waits, so
        that the caller's work before its first call runs while it starts and its toasts fade."""
        self.width, self.height, self.timeout_s, self.wait = width, height, timeout_s, wait
        self._dir = tempfile.TemporaryDirectory(prefix="ionav-viewer-")
        self._aliases = contextlib.ExitStack()  # UTF-8 names of open recordings, while the viewer reads them
        self.log_path = Path(self._dir.name) / "viewer.log"
        self.proc: subprocess.Popen | None = None
        self.client: Any = None
        self._answered = 0.0  # when the viewer first answered (time.monotonic())
        self._watcher: threading.Thread | None = None  # notes when the viewer first answers
        self._stopping = threading.Event()
        self._failure: RendererMissing | None = None  # the viewer could not be started
        self._url = ""
        self._old_handlers: dict[int, Any] = {}
        self._shown = False  # whether an image has set a blueprint (the app's active one is then that image's)

    def __enter__(self) -> HeadlessViewer:
        """Start the viewer process; wait for its answer unless ``wait`` is False."""
        # SIGTERM and SIGHUP become an exception too (as Ctrl-C is), so __exit__ always runs.
        for sig in STOP_SIGNALS:
            with contextlib.suppress(ValueError):  # not the main thread
                self._old_handlers[sig] = signal.signal(sig, raise_terminated)
        try:
            self._spawn()
            if self.wait:
                self.ready()
        except BaseException:
            self.__exit__(*sys.exc_info())
            raise
        return self

    def _spawn(self) -> None:
        """Start the viewer process on a free port, and a thread that notes when it first answers.
        A viewer that cannot start is said by :meth:`ready`, after the caller's own errors."""
        try:
            executable = rerun_executable()
        except RendererMissing as exc:
            self._failure = exc
            return
        port = free_port()
        with open(self.log_path, "ab") as log:
            self.proc = subprocess.Popen(
                [executable, "--headless", "--port", str(port), "--window-size",
                 f"{self.width}x{self.height}", "--hide-welcome-screen", "--memory-limit", "25%"],
                stdin=subprocess.DEVNULL, stdout=log, stderr=log, start_new_session=True,
                # TMPDIR: the viewer's own scratch folders go into ours and are removed with it
                env={**os.environ, "RERUN_APP_ONLY": "true", "RUST_LOG": os.environ.get("RUST_LOG", "warn"),
                     "TMPDIR": self._dir.name},
            )
        self._url = f"rerun+http://127.0.0.1:{port}/proxy"
        # made here, never in the thread (Python's import locks)
        self._watcher = threading.Thread(target=self._watch, args=(_state_probe(), self.proc, self._url),
                                         name="ionav-viewer-answer", daemon=True)
        self._watcher.start()

    def _watch(self, probe: Callable[[str], None], proc: subprocess.Popen, url: str) -> None:
        """In a thread: ask the viewer for its state until it answers (then note when), it exits, the
        start-up deadline passes or the viewer is being shut down."""
        deadline = time.monotonic() + self.answer_limit_s
        while time.monotonic() < deadline and proc.poll() is None and not self._stopping.is_set():
            try:
                probe(url)
            except Exception:
                self._stopping.wait(self.poll_s)
                continue
            self._answered = time.monotonic()
            return

    @property
    def answer_limit_s(self) -> float:
        """Longest wait for a started viewer's first answer."""
        return min(30.0, self.timeout_s)

    def ready(self) -> None:
        """Wait until the viewer answers; :class:`RendererMissing` if it cannot start. At once once it has."""
        for attempt in range(3):  # another process may grab the free port first
            if attempt:
                self._spawn()
            if self._failure is not None:
                raise self._failure
            while self._watcher is not None and self._watcher.is_alive():
                self._watcher.join(0.1)  # short waits: a signal's handler runs between them
            if self.client is not None:
                return
            if self._answered:
                from rerun.experimental import ViewerClient

                self.client = ViewerClient.connect(self._url)
                return
            if self.proc is not None and self.proc.poll() is None:
                self._stop()
                raise RendererMissing(f"the headless Rerun viewer did not answer within {self.answer_limit_s:.0f} s")
            if "Address already in use" not in self._log_tail():
                self._raise_dead()
        self._raise_dead()

    def _log_tail(self) -> str:
        try:
            return self.log_path.read_text(errors="replace")[-20000:]
        except OSError:
            return ""

    def _raise_dead(self) -> None:
        text = self._log_tail()
        lines = [line for line in text.splitlines() if "panicked" in line or "adapter" in line.lower() or
                 "Error" in line]
        why = lines[0].strip() if lines else f"exit code {self.proc.returncode if self.proc else '?'}"
        raise RendererMissing(
            f"the headless Rerun viewer could not render ({why[:200]}); on a machine without a GPU install "
            "Mesa's software Vulkan driver: apt-get install mesa-vulkan-drivers"
        )

    def call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        """A ViewerClient call, once the viewer answers (:meth:`ready`); a dead viewer becomes
        :class:`RendererMissing`."""
        self.ready()
        try:
            return getattr(self.client, method)(*args, **kwargs)
        except (KeyboardInterrupt, SystemExit):
            raise
        except Exception as exc:
            if self.proc is not None and self.proc.poll() is not None:
                self._raise_dead()
            raise RendererMissing(f"the headless Rerun viewer failed during {method}: "
                                  f"{str(exc).splitlines()[0][:200]}") from None

    def open(self, path: Path) -> None:
        """Open a recording and wait until it is the active one."""
        self.call("close", "all")
        self.call("open", str(self._aliases.enter_context(utf8_alias(path.resolve()))))
        deadline = time.monotonic() + self.timeout_s
        while self.call("get_state").active_recording is None:
            if time.monotonic() > deadline:
                raise RendererMissing(f"the viewer did not load {path} within {self.timeout_s:.0f} s")
            time.sleep(0.1)
        # every image starts from the recording's own layout (shots change titles, framing, maximised view)
        self.base_blueprint = self.call("get_blueprint").blueprint
        if self._shown:
            # the viewer keeps one active blueprint per application: the next recording opened on the last
            # image's (a second drive's "all" image came out as the first's signals column); back to its own
            stale = self.base_blueprint
            self.call("run_command", "recording.reset_blueprint_to_default")
            while (own := self.call("get_blueprint").blueprint) == stale:
                if time.monotonic() > deadline:
                    raise RendererMissing(f"the viewer did not show {path}'s own layout within {self.timeout_s:.0f} s")
                time.sleep(0.05)
            self.base_blueprint = own

    def show(self, blueprint: dict[str, Any], t_s: float | None, out: Path,
             finish: Callable[[Path], None] | None = None) -> None:
        """Show the open recording with ``blueprint`` at ``t_s`` on the ``time`` timeline (None: a
        recording without one, all static) and save the image to ``out`` (atomically; ``finish``
        changes the image before it is moved in)."""
        self.call("set_blueprint", blueprint, of="recording")
        self._shown = True
        if t_s is not None:
            self.call("set_time", "time", duration=float(t_s), play_state="paused")
        # let it draw at the new time
        time.sleep(max(self.settle_s, self.toasts_gone_s - (time.monotonic() - self._answered)))
        with atomic_path(out, suffix=".tmp.png") as tmp, utf8_alias(tmp) as writable:
            self.call("save_screenshot", str(writable))
            if not tmp.is_file() or tmp.stat().st_size == 0:
                raise RendererMissing(f"the viewer wrote no screenshot for {out}")
            if finish is not None:
                finish(tmp)

    def _stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGTERM)
                self.proc.wait(timeout=5)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                try:
                    os.killpg(self.proc.pid, signal.SIGKILL)
                    self.proc.wait(timeout=5)
                except (ProcessLookupError, subprocess.TimeoutExpired):
                    pass

    def __exit__(self, *exc: Any) -> None:
        self._stopping.set()
        self._stop()
        if self._watcher is not None:
            self._watcher.join(5.0)  # it stops at its next try (the viewer is gone)
        for sig, old in self._old_handlers.items():
            signal.signal(sig, old)
        self._old_handlers = {}
        self._aliases.close()
        self._dir.cleanup()
