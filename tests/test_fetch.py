"""fetch and list against a local HTTP server serving fixture files with a test manifest."""

import contextlib
import hashlib
import json
import threading
import time
import urllib.parse
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

from ionav_viz.dataset.samples import samples_dir

from .conftest import run_cli

UNSYNC = "Unsynchronised V and S Dataset/Categorised IOVNB (V) Dataset/V Dataset/Vw (Driver E)"
FILES = {
    f"{UNSYNC}/Vw08/V-Vw8.csv": (samples_dir() / "V-sim-sharp-cornering.csv").read_bytes(),
    f"{UNSYNC}/Vw12/V-Vw12.csv": (samples_dir() / "V-sim-motorway.csv").read_bytes()[:50_000],
    "Synchronised V abd S datasets/Categorised IOVNB Dataset/Vw (Driver E)/Vw08/V-Vw8.csv": b"sync copy\n" * 100,
    "Unsynchronised V and S Dataset/Uncategorised IOVNB (V and S) Dataset/S-Dataset/S-Vw8.csv": b"phone\n" * 100,
    f"{UNSYNC}/Vw17/V-Vw17.csv": b"x" * 3000,  # served with other bytes: checksum mismatch
    f"{UNSYNC}/Vw6/V-Vw6.csv": b"y" * 3000,  # 404
    f"{UNSYNC}/Vw7/V-Vw7.csv": b"z" * 3000,  # 500
    f"{UNSYNC}/Vw16b/V-Vw16b.csv": b"s" * 3000,  # stalls
    f"{UNSYNC}/Vta (9)/V-Vta9.csv": b"t" * 3000,  # spaces and parentheses are normal
}


class Server:
    def __init__(self):
        self.requests = []
        self.dropped = set()
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):
                pass

            def do_GET(self):
                path = urllib.parse.unquote(self.path.lstrip("/"))
                outer.requests.append((path, self.headers.get("Range")))
                data = FILES.get(path)
                name = path.rsplit("/", 1)[-1]
                if data is None or name == "V-Vw6.csv":
                    self.send_error(404)
                    return
                if name == "V-Vw7.csv":
                    self.send_error(500)
                    return
                if name == "V-Vw16b.csv":
                    time.sleep(3)
                if name == "V-Vw17.csv":
                    data = b"q" * len(data)
                start = 0
                rng = self.headers.get("Range")
                if rng:
                    start = int(rng.split("=")[1].split("-")[0])
                    self.send_response(206)
                    self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{len(data)}")
                else:
                    self.send_response(200)
                body = data[start:]
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                if name == "V-Vw8.csv" and path.startswith("Unsync") and path not in outer.dropped:
                    outer.dropped.add(path)  # drop the connection half-way, once
                    self.wfile.write(body[: len(body) // 2])
                    self.wfile.flush()
                    self.connection.shutdown(2)
                    return
                with contextlib.suppress(BrokenPipeError, ConnectionResetError):  # the client gave up (the stall test)
                    self.wfile.write(body)

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def close(self):
        self.httpd.shutdown()


@pytest.fixture()
def server():
    s = Server()
    yield s
    s.close()


@pytest.fixture()
def manifest(tmp_path):
    lines = ["path\tsha256\tsize_bytes"] + [f"{p}\t{hashlib.sha256(d).hexdigest()}\t{len(d)}" for p, d in FILES.items()]
    path = tmp_path / "manifest.tsv"
    path.write_text("\n".join(lines) + "\n")
    return path


def fetch(server, manifest, root, *args):
    return run_cli("fetch", *args, "--data-root", str(root), "--base-url", server.url, "--manifest", str(manifest),
                   "--timeout", "1s", "-q")


def test_fetch_resumes_after_a_dropped_connection_and_replay_finds_it(server, manifest, tmp_path):
    root = tmp_path / "data"
    proc = fetch(server, manifest, root, "V-Vw8")
    assert proc.returncode == 0, proc.stderr
    target = root / f"{UNSYNC}/Vw08/V-Vw8.csv"
    assert target.read_bytes() == FILES[f"{UNSYNC}/Vw08/V-Vw8.csv"]
    ranges = [r for p, r in server.requests if p.endswith("Vw08/V-Vw8.csv")]
    assert ranges[0] is None and ranges[1] == f"bytes={len(FILES[f'{UNSYNC}/Vw08/V-Vw8.csv']) // 2}-"
    assert "resumed" in proc.stderr
    # a verified file is skipped
    again = fetch(server, manifest, root, "V-Vw8")
    assert again.returncode == 0 and "skipped" in again.stderr
    # run names now resolve under the data root, with no other flag
    ev = run_cli("evaluate", "V-Vw8", "--no-idnn", "--json", env={"IONAV_DATA": str(root)})
    assert ev.returncode == 0, ev.stderr
    assert json.loads(ev.stdout)["drive"] == "V-Vw8"
    listing = run_cli("list", "--json", "--data-root", str(root), "--manifest", str(manifest))
    status = {r["name"]: r["status"] for r in json.loads(listing.stdout)["runs"]}
    assert status["V-Vw8"] == "verified" and status["V-Vw12"] == "missing"
    assert {r["name"]: r["role"] for r in json.loads(listing.stdout)["runs"]}["V-Vw8"].startswith("the paper's sharp-cornering")


def test_synchronised_and_phone_copies(server, manifest, tmp_path):
    root = tmp_path / "data"
    proc = fetch(server, manifest, root, "Vw8", "--synchronised")
    assert proc.returncode == 0, proc.stderr
    assert (root / "Synchronised V abd S datasets/Categorised IOVNB Dataset/Vw (Driver E)/Vw08/V-Vw8.csv").is_file()
    proc = fetch(server, manifest, root, "Vw12", "--phone")
    assert proc.returncode != 0 and "no phone file" in proc.stderr  # Vw12 has no S- file in this manifest


def test_names_with_spaces_and_parentheses(server, manifest, tmp_path):
    root = tmp_path / "data"
    proc = fetch(server, manifest, root, "V-Vta9")
    assert proc.returncode == 0, proc.stderr
    assert (root / f"{UNSYNC}/Vta (9)/V-Vta9.csv").read_bytes() == b"t" * 3000


@pytest.mark.parametrize(
    "name, message",
    [("V-Vw17", "does not match the manifest"), ("V-Vw6", "HTTP 404"), ("V-Vw7", "HTTP 500"), ("V-Vw16b", "timed out")],
)
def test_failures_are_one_line_and_leave_nothing(server, manifest, tmp_path, name, message):
    root = tmp_path / "data"
    proc = fetch(server, manifest, root, name)
    assert proc.returncode == 1, proc.stderr
    assert message in proc.stderr and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert not root.exists()  # a failed first download leaves no (empty) data root behind


def test_crafted_paths_never_leave_the_data_root(server, tmp_path):
    evil = tmp_path / "evil.tsv"
    data = b"pwned"
    sha = hashlib.sha256(data).hexdigest()
    root = tmp_path / "data"
    for crafted in ["../../outside/V-Vw8.csv", "/tmp/V-Vw8.csv", "Unsynchronised V and S Dataset/../../V-Vw8.csv"]:
        evil.write_text(f"path\tsha256\tsize_bytes\n{crafted}\t{sha}\t{len(data)}\n")
        proc = run_cli("fetch", "V-Vw8", "--data-root", str(root), "--base-url", server.url, "--manifest", str(evil), "-q")
        assert proc.returncode == 2 and "unsafe" in proc.stderr, (crafted, proc.stderr)
    assert not (tmp_path / "outside").exists() and not list(tmp_path.glob("V-Vw8.csv"))


def test_symlink_inside_the_data_root_is_refused(server, manifest, tmp_path):
    root = tmp_path / "data"
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (root / "Unsynchronised V and S Dataset").parent.mkdir(parents=True)
    (root / "Unsynchronised V and S Dataset").symlink_to(outside, target_is_directory=True)
    proc = fetch(server, manifest, root, "V-Vw8")
    assert proc.returncode == 2 and "symlink" in proc.stderr
    assert not list(outside.rglob("*"))


class RawServer:
    """A TCP server that answers every request with the same raw bytes, then closes."""

    def __init__(self, response: bytes) -> None:
        import socket

        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        self.response = response
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            with conn, contextlib.suppress(OSError):
                conn.recv(65536)
                conn.sendall(self.response)

    def close(self) -> None:
        self.sock.close()


@pytest.mark.parametrize(
    ("response", "why"),
    [
        (b"HTTP/1.1 2OO OK\r\n\r\n", "malformed status line"),
        (b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n400\r\nabc", "truncated chunked body"),
        (b"HTTP/1.1 200 OK\r\n" + b"".join(b"X-H%d: v\r\n" % i for i in range(200)) + b"\r\n", "over 100 headers"),
        (b"HTTP/1.1 200 OK\r\nX-Long: " + b"a" * 100_000 + b"\r\n\r\n", "an over-long header line"),
    ],
)
def test_a_broken_server_is_one_line_and_leaves_nothing(manifest, tmp_path, response, why):
    """Input: a server answering with a malformed HTTP response. Expected: exit 1, one line, and at most
    a resumable ``.part`` of what arrived (never a file under the run's name, never an empty folder)."""
    raw = RawServer(response)
    try:
        root = tmp_path / "data"
        proc = run_cli("fetch", "V-Vw8", "--data-root", str(root), "--base-url", raw.url, "--manifest", str(manifest), "--timeout", "2s", "-q")
    finally:
        raw.close()
    assert proc.returncode == 1, (why, proc.stderr)
    assert proc.stderr.count("\n") == 1 and "download failed" in proc.stderr and "Traceback" not in proc.stderr, (why, proc.stderr)
    left = list(root.rglob("*")) if root.exists() else []
    assert all(p.is_dir() or p.name.endswith(".csv.part") for p in left), left
    assert all(any(p.iterdir()) for p in left if p.is_dir())


def test_no_network_names_the_host_and_what_to_do(manifest, tmp_path):
    """Input: nothing listening at the base URL (as offline). Expected: exit 1, one line naming the
    file and the host, with a hint; nothing left behind."""
    import socket

    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    root = tmp_path / "data"
    proc = run_cli("fetch", "V-Vw8", "--data-root", str(root), "--base-url", f"http://127.0.0.1:{port}/repo", "--manifest", str(manifest),
                   "--timeout", "2s", "-q")
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "V-Vw8.csv: download failed after 3 attempts from 127.0.0.1" in proc.stderr, proc.stderr
    assert "(hint: check the network connection, or give a mirror with --base-url" in proc.stderr, proc.stderr
    assert not root.exists() or not any(p.is_file() for p in root.rglob("*"))
