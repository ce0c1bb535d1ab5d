"""Live viewing: replay --connect streams to a running viewer, --serve-web serves a browser, --open
without a display points to --serve-web. The viewer here is a private headless one."""

import contextlib
import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from .conftest import HANG_S, REPO, run_cli

ARGS = ("replay", "hard-brake", "--estimators", "ins,odo", "--every", "60s", "-q")


@pytest.fixture(scope="module")
def viewer():
    from ionav_viz.viz.viewer import HeadlessViewer, RendererMissing

    try:
        with HeadlessViewer(400, 300) as v:
            yield v
    except RendererMissing as exc:
        if os.environ.get("CI"):
            raise
        pytest.skip(f"no renderer on this machine: {exc}")


def _url(viewer) -> str:
    return f"rerun+http://127.0.0.1:{viewer.proc.args[viewer.proc.args.index('--port') + 1]}/proxy"


def _wait_for_recording(viewer, recording_id: str, timeout_s: float = HANG_S):
    deadline = time.monotonic() + timeout_s  # a hang guard: the loop ends when the viewer has it
    while time.monotonic() < deadline:
        state = viewer.call("get_state")
        found = [r for r in state.recordings if r.store_id.endswith(":" + recording_id)]
        if found:
            return found[0], state
        time.sleep(0.2)
    raise AssertionError(f"the viewer never got {recording_id}: {viewer.call('get_state')}")


def test_connect_streams_to_a_running_viewer_and_saves(viewer, tmp_path):
    out = tmp_path / "hb.rrd"
    proc = run_cli(*ARGS, "-o", str(out), "--connect", _url(viewer))
    assert proc.returncode == 0, proc.stderr
    assert out.is_file()
    rec, state = _wait_for_recording(viewer, "V-sim-hard-brake-10s")
    timeline = next(t for t in rec.timelines if t.name == "time")
    assert timeline.end / 1e9 > 590  # the whole 600 s drive arrived
    assert any(v.origin == "/inspect" for v in state.views)  # with the review layout


def test_connect_without_a_viewer_and_bad_addresses(tmp_path):
    from ionav_viz.viz.viewer import free_port

    out = tmp_path / "x.rrd"
    proc = run_cli(*ARGS, "-o", str(out), "--connect", f"rerun+http://127.0.0.1:{free_port()}/proxy")
    assert proc.returncode == 1 and "no Rerun viewer is listening" in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr
    assert not out.exists()  # checked before the work
    proc = run_cli(*ARGS, "-o", str(out), "--connect", "ftp://x")
    assert proc.returncode == 2 and "not a Rerun viewer address" in proc.stderr, proc.stderr


class _Swallower:
    """A TCP server on a free port that accepts connections and reads everything, answering
    nothing, or (``settings=True``) only a gRPC server's first frame: a viewer that stops reading."""

    def __init__(self, greeting: bytes = b""):
        import socket
        import threading

        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.greeting = greeting
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        import threading

        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            threading.Thread(target=self._swallow, args=(conn,), daemon=True).start()

    def _swallow(self, conn):
        with conn, contextlib.suppress(OSError):  # the client hangs up as it likes
            conn.sendall(self.greeting)
            while conn.recv(65536):
                pass

    def close(self):
        self.sock.close()


@pytest.mark.parametrize("greeting", [b"", b"HTTP/1.1 400 Bad Request\r\n\r\n"], ids=["silent", "http"])
def test_connect_to_something_that_is_not_a_viewer_fails_before_the_work(tmp_path, greeting):
    """Round 3: a server that accepts and discards data hung the process in Rerun's shutdown hook
    (9 minutes, once ignoring SIGTERM); an HTTP server gave a traceback."""
    server = _Swallower(greeting)
    out = tmp_path / "x.rrd"
    try:
        proc = run_cli(*ARGS, "-o", str(out), "--connect", f"rerun+http://127.0.0.1:{server.port}/proxy", timeout=HANG_S)
    finally:
        server.close()
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1, proc.stderr
    assert "does not answer as a Rerun viewer" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()


def test_a_viewer_that_stops_reading_is_dropped_in_bounded_time(tmp_path):
    """The stream to a viewer that answers, then takes no data, is dropped after the timeout with one
    line; the sending process is gone and the recording stays."""
    from ionav_viz.core.errors import ToolFailure
    from ionav_viz.viz import live

    rrd = tmp_path / "hb.rrd"
    assert run_cli(*ARGS, "-o", str(rrd)).returncode == 0
    server = _Swallower(bytes(3) + b"\x04" + bytes(5))  # an HTTP/2 SETTINGS frame, then silence
    try:
        with pytest.raises(ToolFailure, match="did not take the recording within 2 s; the stream was dropped"):
            live.send_recording(rrd, f"rerun+http://127.0.0.1:{server.port}/proxy", timeout_s=2)
    finally:
        server.close()
    assert rrd.is_file()
    senders = subprocess.run(["pgrep", "-P", str(os.getpid()), "-f", "stream_file"], capture_output=True, text=True).stdout.split()
    assert senders == [], senders  # the sending child is gone (the module's viewer may still run)


def test_connect_without_an_address_means_rerun_default(monkeypatch):
    from ionav_viz.cli.app import optional_values
    from ionav_viz.viz.live import DEFAULT_CONNECT_URL

    assert optional_values(["replay", "--connect", "V-Vw8"]) == ["replay", "--connect", DEFAULT_CONNECT_URL, "V-Vw8"]
    assert optional_values(["replay", "V-Vw8", "--connect"]) == ["replay", "V-Vw8", "--connect", DEFAULT_CONNECT_URL]
    assert optional_values(["replay", "--connect", "rerun+http://h:1/proxy"]) == ["replay", "--connect", "rerun+http://h:1/proxy"]
    assert DEFAULT_CONNECT_URL == "rerun+http://127.0.0.1:9876/proxy"  # where a plain 'rerun' listens


def test_serve_web_serves_the_viewer_and_the_recording(viewer, tmp_path):
    from ionav_viz.viz.viewer import free_port

    grpc_port, web_port = free_port(), free_port()
    proc = subprocess.Popen([sys.executable, "-m", "ionav_viz.cli", *ARGS, "-o", str(tmp_path / "hb.rrd"), "--serve-web",
                             "--grpc-port", str(grpc_port), "--web-port", str(web_port)],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        saved = proc.stdout.readline()  # the recording's path, as every replay prints it
        line = proc.stdout.readline()
        assert saved.strip() == str(tmp_path / "hb.rrd") and (tmp_path / "hb.rrd").is_file(), saved
        assert line.startswith("serving the recording: open http://127.0.0.1:") and f":{web_port}/" in line, line
        page = urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=HANG_S).read().decode()
        assert "<html" in page.lower()
        viewer.call("open", f"rerun+http://127.0.0.1:{grpc_port}/proxy")
        _wait_for_recording(viewer, "V-sim-hard-brake-10s")
    finally:
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=HANG_S)
    assert code == 130 and "Traceback" not in proc.stderr.read()


def test_open_without_a_display_points_to_serve_web(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = run_cli(*ARGS, "-o", str(tmp_path / "x.rrd"), "--open", env={**env, "DISPLAY": ""})
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and "--serve-web" in proc.stderr, proc.stderr


@pytest.mark.parametrize(("extra", "fragment"), [
    (["--grpc-port", "0"], "--grpc-port: port 0 is not a TCP port"),
    (["--web-port", "70000"], "--web-port: port 70000 is not a TCP port"),
    (["--grpc-port", "19999", "--web-port", "19999"], "cannot share port 19999"),
    (["--bind", "everywhere"], "--bind: bind address 'everywhere' is not an IP address"),
])
def test_serve_options_are_checked_before_any_work(tmp_path, extra, fragment):
    """Round 3: bad ports were refused only after the whole replay; the same port for both was a traceback."""
    out = tmp_path / "x.rrd"
    proc = run_cli(*ARGS, "-o", str(out), "--serve-web", *extra)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and fragment in proc.stderr, proc.stderr
    assert not out.exists()  # before the work


def _listening(port: int) -> set[str]:
    """The local addresses a TCP port listens on, from /proc/net/tcp (state 0A: LISTEN)."""
    found = set()
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        host, p = local.split(":")
        if state == "0A" and int(p, 16) == port:
            found.add(".".join(str(int(host[i : i + 2], 16)) for i in (6, 4, 2, 0)))
    return found


@pytest.mark.parametrize("bind", [None, "0.0.0.0"])
def test_serve_web_listens_on_this_machine_only_unless_told(tmp_path, bind):
    """Round 3: --serve-web listened on 0.0.0.0, exposing the drive's positions to every network."""
    from ionav_viz.viz.viewer import free_port

    if not Path("/proc/net/tcp").is_file():
        pytest.skip("needs Linux's /proc/net/tcp")
    grpc_port, web_port = free_port(), free_port()
    proc = subprocess.Popen([sys.executable, "-m", "ionav_viz.cli", *ARGS, "-o", str(tmp_path / "hb.rrd"), "--serve-web",
                             "--grpc-port", str(grpc_port), "--web-port", str(web_port), *(["--bind", bind] if bind else [])],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        proc.stdout.readline()
        assert proc.stdout.readline().startswith("serving the recording")
        expected = {"127.0.0.1"} if bind is None else {"0.0.0.0"}
        assert _listening(grpc_port) == expected and _listening(web_port) == expected
    finally:
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=HANG_S)
    err = proc.stderr.read()
    assert code == 130 and "Traceback" not in err
    assert ("reachable from every network" in err) == (bind is not None), err
    assert _listening(grpc_port) == set() and _listening(web_port) == set()  # the server process is gone
