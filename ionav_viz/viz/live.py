"""Live viewing by Rerun's conventions: stream a replay to a running viewer, or serve it to a browser.

``send_recording``: the written ``.rrd`` file streamed to a viewer's gRPC endpoint (default Rerun's
local ``rerun+http://127.0.0.1:9876/proxy``, where a plain ``rerun`` listens) by a child process
that is dropped when the viewer stops taking data, so a stuck viewer never hangs us.
``serve_web``: the written ``.rrd`` served to browsers by a ``rerun --serve-web`` process of our own
(a gRPC server holding it and Rerun's web viewer pointing at it), bound to the loopback address
unless the user opens it to a network (``--bind``); stopped with the command.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote, urlparse

from ..core.errors import InputError, ToolFailure

#: Where a viewer started with a plain ``rerun`` listens.
DEFAULT_GRPC_PORT = 9876
DEFAULT_WEB_PORT = 9090
DEFAULT_CONNECT_URL = f"rerun+http://127.0.0.1:{DEFAULT_GRPC_PORT}/proxy"


def _endpoint(url: str) -> tuple[str, int]:
    """(host, port) of a ``rerun+http://host:port/proxy`` URL; a bad URL is the user's input."""
    parsed = urlparse(url)
    if parsed.scheme not in ("rerun+http", "rerun+https", "rerun", "http", "https") or not parsed.hostname:
        raise InputError(f"{url}: not a Rerun viewer address", f"use e.g. {DEFAULT_CONNECT_URL}", param="connect")
    try:
        port = parsed.port or DEFAULT_GRPC_PORT
    except ValueError:
        raise InputError(f"{url}: the port is not a number", f"use e.g. {DEFAULT_CONNECT_URL}",
                         param="connect") from None
    return parsed.hostname, port


#: A gRPC server's first words: the HTTP/2 client preface and an empty SETTINGS frame. A Rerun
#: viewer (or server) answers with its own SETTINGS frame; a socket that swallows data or an
#: HTTP/1 server does not.
_H2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes(3) + b"\x04" + bytes(5)
_SETTINGS = 4


def check_viewer(url: str, timeout_s: float = 2.0) -> None:
    """Fail with one line unless a gRPC server answers at the viewer address within ``timeout_s``:
    nothing listening, or something that accepts connections but never answers as a Rerun viewer
    does (the SDK's own sink would retry or block in the background and lose the data)."""
    import ssl

    host, port = _endpoint(url)
    try:
        raw = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as exc:
        raise ToolFailure(f"--connect {url}: no Rerun viewer is listening there ({exc.strerror or exc}); start one "
                          "with 'rerun' (or 'ionav-viz replay ... --serve-web' to view in a browser)") from None
    try:
        with raw:
            sock = raw
            if url.startswith(("rerun+https", "https")):
                context = ssl.create_default_context()
                context.set_alpn_protocols(["h2"])
                sock = context.wrap_socket(raw, server_hostname=host)
            sock.settimeout(timeout_s)
            sock.sendall(_H2_PREFACE)
            head = _read_exactly(sock, 9)
    except OSError:  # reset, TLS refused: not a viewer either
        head = b""
    if len(head) < 9 or head[3] != _SETTINGS:
        raise ToolFailure(f"--connect {url}: something accepts connections there but does not answer as a Rerun viewer "
                          f"(no gRPC reply within {timeout_s:g} s); check the address, or start a viewer with 'rerun'")


def _read_exactly(sock, n: int) -> bytes:
    """Up to ``n`` bytes; fewer when the peer closes or stays silent past the socket's timeout."""
    data = b""
    try:
        while len(data) < n:
            got = sock.recv(n - len(data))
            if not got:
                break
            data += got
    except TimeoutError:
        pass
    return data


def send_recording(path: Path, url: str = DEFAULT_CONNECT_URL, timeout_s: float = 60.0) -> None:
    """Stream the written recording ``path`` to the viewer at ``url`` (its recording id and layout
    as in the file) and wait until it is sent.

    The sending runs in a child process: a viewer that stops reading mid-stream can block the
    SDK's flush and its shutdown hook for ever, and only a process can be stopped for sure. After
    ``timeout_s`` the stream is dropped (the child killed) with one line; the file stays.
    """
    import sys

    check_viewer(url)
    code = ("import sys; from ionav_viz.viz.live import stream_file; "
            "stream_file(sys.argv[1], sys.argv[2], float(sys.argv[3]))")
    with subprocess.Popen([sys.executable, "-c", code, url, str(path), str(timeout_s)], stdin=subprocess.DEVNULL,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) as proc:
        try:
            _, err = proc.communicate(timeout=timeout_s + 5.0)
        except subprocess.TimeoutExpired:
            _stop(proc)
            raise ToolFailure(f"--connect {url}: the viewer did not take the recording within {timeout_s:g} s; "
                              f"the stream was dropped (the recording is saved in {path.name})") from None
        finally:
            if proc.poll() is None:  # interrupted (Ctrl-C): the stream goes with us
                _stop(proc)
    if proc.returncode != 0:
        last = next((line for line in reversed(err.decode(errors="replace").splitlines()) if line.strip()), "")
        raise ToolFailure(f"--connect {url}: streaming failed ({last.strip()[:200] or f'exit {proc.returncode}'}); "
                          f"the recording is saved in {path.name}")


def stream_file(url: str, path: str, timeout_s: float) -> None:
    """The child's work: the recording in the ``.rrd`` at ``path`` and its review layout, sent to
    ``url``. Chunks are read and sent synchronously (``log_file_from_path`` would load the file in
    the background, racing the flush and the exit)."""
    import rerun as rr

    from ..core.fileio import utf8_alias
    from .blueprints import shown_views
    from .recording import review_blueprint
    from .recording_info import read_recording_info, rrd_reader

    info = read_recording_info(Path(path))
    with utf8_alias(Path(path)) as readable:
        reader = rrd_reader(readable)
        [store] = reader.recordings()
        rec = rr.RecordingStream(store.application_id, recording_id=store.recording_id)
        rec.connect_grpc(url)
        rec.send_blueprint(review_blueprint([label for label, _ in info.estimators.values()], info.lat_deg,
                                            info.lon_deg, shown=shown_views(info), end_s=info.end_s))
        rec.send_chunks(reader.stream(store=store))
    rec.flush(timeout_sec=timeout_s)
    rec.disconnect()


def _stop(proc: subprocess.Popen, grace_s: float = 2.0) -> None:
    """SIGTERM, then SIGKILL if it is still there after ``grace_s`` (Rerun's hooks may ignore the first)."""
    proc.terminate()
    try:
        proc.wait(grace_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@dataclass(frozen=True)
class WebServing:
    """Where a recording is served to browsers: the gRPC server's and the web viewer's ports and
    the address both bind to. The loopback address by default: positions of a drive are nobody
    else's business; another address opens the recording to that network. Checked on creation,
    before any work: ports 1-65535, different, free; ``bind`` an IP address."""

    grpc_port: int = DEFAULT_GRPC_PORT
    web_port: int = DEFAULT_WEB_PORT
    bind: str = "127.0.0.1"

    def __post_init__(self) -> None:
        import ipaddress

        for port, param in ((self.grpc_port, "grpc_port"), (self.web_port, "web_port")):
            if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
                raise InputError(f"port {port!r} is not a TCP port", "choose a port between 1024 and 65535",
                                 param=param)
        if self.grpc_port == self.web_port:
            raise InputError(f"the gRPC server and the web viewer cannot share port {self.web_port}",
                             "give them different ports", param="web_port")
        try:
            ipaddress.ip_address(self.bind)
        except ValueError:
            raise InputError(f"bind address {self.bind!r} is not an IP address",
                             "use e.g. 127.0.0.1 (this machine only) or 0.0.0.0", param="bind") from None
        for port, option in ((self.grpc_port, "--grpc-port"), (self.web_port, "--web-port")):
            _check_free(self.bind, port, option)

    @property
    def public(self) -> bool:
        """Whether other machines can reach the served recording."""
        import ipaddress

        return not ipaddress.ip_address(self.bind).is_loopback

    @property
    def host(self) -> str:
        """Where this machine reaches the servers."""
        return "127.0.0.1" if self.bind in ("0.0.0.0", "::") else self.bind


class WebServer:
    """A recording served to browsers by a ``rerun --serve-web`` process of our own; a context
    manager: the process is stopped on exit (Ctrl-C and SIGTERM included)."""

    def __init__(self, path: Path, serving: WebServing, timeout_s: float = 30.0) -> None:
        self.serving = serving
        host = f"[{serving.host}]" if ":" in serving.host else serving.host
        self.grpc_url = f"rerun+http://{host}:{serving.grpc_port}/proxy"
        self.web_url = f"http://{host}:{serving.web_port}/?url={quote(self.grpc_url, safe=':/')}"
        self._path, self._timeout_s = Path(path), timeout_s
        self._dir = tempfile.TemporaryDirectory(prefix="ionav-serve-")
        self._proc: subprocess.Popen | None = None

    def __enter__(self) -> WebServer:
        from .viewer import rerun_executable

        log = Path(self._dir.name) / "serve.log"
        s = self.serving
        try:
            with open(log, "ab") as out:
                self._proc = subprocess.Popen(
                    [rerun_executable(), "--serve-web", "--bind", s.bind, "--port", str(s.grpc_port),
                     "--web-viewer-port", str(s.web_port), str(self._path.resolve())],
                    stdin=subprocess.DEVNULL, stdout=out, stderr=out, start_new_session=True,
                    env={**os.environ, "RUST_LOG": os.environ.get("RUST_LOG", "warn"), "TMPDIR": self._dir.name})
            deadline = time.monotonic() + self._timeout_s
            while not all(_accepts(s.host, port) for port in (s.grpc_port, s.web_port)):
                if self._proc.poll() is not None or time.monotonic() > deadline:
                    tail = ([line for line in log.read_text(errors="replace").splitlines() if line.strip()][-1:]
                            or ["no output"])
                    raise ToolFailure(f"the Rerun web viewer did not start ({tail[0].strip()[:200]})")
                time.sleep(0.1)
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        if self._proc is not None and self._proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self._proc.pid, signal.SIGTERM)
            try:
                self._proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self._proc.pid, signal.SIGKILL)
                self._proc.wait(timeout=5)
        self._dir.cleanup()


def serve_web(path: Path, serving: WebServing | None = None) -> WebServer:
    """A :class:`WebServer` for the ``.rrd`` at ``path`` (use it with ``with``: it starts there)."""
    return WebServer(path, serving or WebServing())


def _accepts(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.5):
            return True
    except OSError:
        return False


def _check_free(bind: str, port: int, option: str) -> None:
    family = socket.AF_INET6 if ":" in bind else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        try:
            s.bind((bind, port))
        except OSError:
            raise ToolFailure(f"{option} {port}: the port is in use on {bind} (another viewer or server?); choose "
                              f"another with {option}") from None
