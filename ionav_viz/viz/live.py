"""Live viewing by Rerun's conventions: stream a replay to a running viewer, or serve it to a browser.

``connect``: the same recording as the ``.rrd`` file, logged to a viewer's gRPC endpoint
(default Rerun's local ``rerun+http://127.0.0.1:9876/proxy``, where a plain ``rerun`` listens).
``serve_web``: a gRPC server in this process holding the recording, and Rerun's web viewer
served over HTTP pointing at it; both live until the process is stopped.
"""

from __future__ import annotations

import socket
from dataclasses import dataclass
from typing import TYPE_CHECKING
from urllib.parse import quote, urlparse

from ..core.errors import InputError, ToolFailure

if TYPE_CHECKING:  # the CLI reads the defaults here without loading the logging layer
    from ..analysis.evaluate import DriveResult

#: Where a viewer started with a plain ``rerun`` listens.
DEFAULT_GRPC_PORT = 9876
DEFAULT_WEB_PORT = 9090
DEFAULT_CONNECT_URL = f"rerun+http://127.0.0.1:{DEFAULT_GRPC_PORT}/proxy"


def _endpoint(url: str) -> tuple[str, int]:
    """(host, port) of a ``rerun+http://host:port/proxy`` URL; a bad URL is the user's input."""
    parsed = urlparse(url)
    if parsed.scheme not in ("rerun+http", "rerun+https", "rerun", "http", "https") or not parsed.hostname:
        raise InputError(f"--connect {url}: not a Rerun viewer address", f"use e.g. {DEFAULT_CONNECT_URL}", param="connect")
    try:
        port = parsed.port or DEFAULT_GRPC_PORT
    except ValueError:
        raise InputError(f"--connect {url}: the port is not a number", f"use e.g. {DEFAULT_CONNECT_URL}", param="connect") from None
    return parsed.hostname, port


def check_listening(url: str, timeout_s: float = 2.0) -> None:
    """Fail with one line unless something accepts connections at the viewer address (the SDK's
    own sink would retry silently in the background and lose the data)."""
    host, port = _endpoint(url)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            return
    except OSError as exc:
        raise ToolFailure(f"--connect {url}: no Rerun viewer is listening there ({exc.strerror or exc}); start one with 'rerun' "
                          "(or 'ionav-viz replay ... --serve-web' to view in a browser)") from None


def connect(result: DriveResult, summary_md: str, url: str = DEFAULT_CONNECT_URL, events: list | None = None,
            timeout_s: float = 30.0) -> None:
    """Stream the recording of ``result`` to the viewer at ``url`` and wait until it is sent."""
    import rerun as rr

    from .recording import APP_ID, log_result, recording_id

    check_listening(url)
    rec = rr.RecordingStream(APP_ID, recording_id=recording_id(result))
    rec.connect_grpc(url)
    log_result(rec, result, summary_md, events=events)
    rec.flush(timeout_sec=timeout_s)
    rec.disconnect()


@dataclass
class WebServer:
    """A served recording: the browser address, the gRPC address, and the stream holding it."""

    web_url: str
    grpc_url: str
    stream: object


def serve_web(result: DriveResult, summary_md: str, events: list | None = None, grpc_port: int = DEFAULT_GRPC_PORT,
              web_port: int = DEFAULT_WEB_PORT) -> WebServer:
    """Serve the recording of ``result`` from this process: a gRPC server on ``grpc_port`` and
    Rerun's web viewer on ``web_port`` (both on all interfaces, as ``rerun --serve-web``). The
    servers run until the process ends; the caller waits (``ionav-viz replay --serve-web`` until Ctrl-C)."""
    import rerun as rr

    from .recording import APP_ID, log_result, recording_id

    for port, option in ((grpc_port, "--grpc-port"), (web_port, "--web-port")):
        _check_free(port, option)
    rec = rr.RecordingStream(APP_ID, recording_id=recording_id(result))
    grpc_url = rec.serve_grpc(grpc_port=grpc_port)
    log_result(rec, result, summary_md, events=events)
    rr.serve_web_viewer(web_port=web_port, open_browser=False, connect_to=grpc_url)
    return WebServer(f"http://127.0.0.1:{web_port}/?url={quote(grpc_url, safe=':/')}", grpc_url, rec)


def _check_free(port: int, option: str) -> None:
    if not 1 <= port <= 65535:
        raise InputError(f"{option} {port}: not a TCP port", "choose a port between 1024 and 65535", param=option)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("0.0.0.0", port))
        except OSError:
            raise ToolFailure(f"{option} {port}: the port is in use (another viewer or server?); choose another with {option}") from None
