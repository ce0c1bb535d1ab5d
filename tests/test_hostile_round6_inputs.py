"""Hostile inputs, round 6 (issue 60, part B): how drives are named (list files, globs, folders,
links), ``cross-validate --folds``, ``--cluster``, the fleet API's arguments, fleet figures,
``info``'s names, huge covariances, ``events --quality`` with a span, and a truncated recording.
Each case states what happened before.

Bad input -> exit code 2, one line on stderr starting ``error:`` that names the file, option or
field with a hint, no traceback, nothing written; nothing hangs, nothing grows without bound.
"""

from __future__ import annotations

import contextlib
import json
import socket
import threading
from pathlib import Path

import pytest

import ionav_viz as iv

from .conftest import run_cli, run_cli_process


@pytest.fixture(scope="module")
def drives(tmp_path_factory) -> Path:
    """A folder of two simulated 60 s roundabout drives, ``V-a.csv`` and ``V-b.csv``."""
    from ionav_viz.sim.simulate import write_simulated_drive

    folder = tmp_path_factory.mktemp("drives6")
    for name, seed in (("V-a", 1), ("V-b", 2)):
        write_simulated_drive(folder / f"{name}.csv", "roundabout", seed=seed, duration_s=60)
    return folder


def _one_line_error(done, *words: str) -> str:
    assert done.returncode == 2, (done.returncode, done.stderr)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), done.stderr
    assert "Traceback" not in done.stderr
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


def _dry_run(*args: str, cwd: Path) -> list[str]:
    done = run_cli("evaluate", *args, "--dry-run", "--json", cwd=cwd)
    assert done.returncode == 0, done.stderr
    return [d["drive"] for d in json.loads(done.stdout)["drives"]]


# --- 3. --cluster -------------------------------------------------------------------------------
@pytest.mark.parametrize("address", ["http://scheduler:8786", "ftp://x", "tcp://127.0.0.1:notaport", "tcp://[::1",
                                     "tcp://host", "tcp://host:70000", "tcp://host:1/path", "\x1b[2J:1"])
def test_a_malformed_cluster_address_is_one_line(drives, address):
    """Dask's parser raised ValueError tracebacks (exit code 1) for these; now one line naming
    --cluster with the forms it takes, before any work."""
    done = run_cli("evaluate", str(drives / "V-a.csv"), "--estimators", "ins", "--cluster", address)
    line = _one_line_error(done, "--cluster", "tcp://scheduler:8786")
    assert "\x1b" not in line


@contextlib.contextmanager
def _silent_port():
    """A local port that accepts connections and never answers (a stuck or foreign service)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    taken: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        server.settimeout(0.1)
        while not stop.is_set():
            with contextlib.suppress(OSError):
                taken.append(server.accept()[0])

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield server.getsockname()[1]
    finally:
        stop.set()
        thread.join()
        for conn in taken:
            conn.close()
        server.close()


def test_an_unresponsive_scheduler_is_one_line_within_the_connect_timeout(drives):
    """A port that accepts and never answers held the client past Dask's connect timeout (80 s and
    more: its greeting's reply has no timeout); now the greeting is bounded by
    ``distributed.comm.timeouts.connect`` (made short here) and the run stops in one line."""
    pytest.importorskip("distributed")
    with _silent_port() as port:
        short = {"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"}  # Dask's own setting, read as it starts
        address = f"tcp://127.0.0.1:{port}"
        done = run_cli_process("evaluate", str(drives / "V-a.csv"), "--estimators", "ins", "--cluster", address, env=short)
        _one_line_error(done, "--cluster", f"no Dask scheduler answered at {address}")
        import dask

        with dask.config.set({"distributed.comm.timeouts.connect": "1s"}), pytest.raises(iv.InputError) as err:
            iv.evaluate_fleet([str(drives / "V-a.csv")], estimators=["ins"], cluster=address)
        assert err.value.param == "cluster"


# --- 6. names from a file are printed escaped ---------------------------------------------------
def test_info_and_errors_escape_names_from_the_file(tmp_path):
    """``info`` printed topic and schema names raw: an ESC sequence cleared the screen, a newline
    forged an ``error:`` line. Every such character is escaped as Python's repr writes it, in
    ``info``'s table and in every error line."""
    from mcap.writer import Writer

    log = tmp_path / "evil.mcap"
    with open(log, "wb") as f:
        writer = Writer(f)
        writer.start()
        schema = writer.register_schema("sensor_msgs/Imu\x1b[2J", "jsonschema", b"{}")
        channel = writer.register_channel("/imu\nerror: forged", "json", schema)
        for i in range(3):
            writer.add_message(channel, log_time=i, publish_time=i, data=b"{}")
        writer.finish()
    done = run_cli("info", str(log))
    assert "\x1b" not in done.stdout + done.stderr
    assert "/imu\\nerror: forged" in done.stdout and "sensor_msgs/Imu\\x1b[2J" in done.stdout
    assert not any(line.startswith("error:") for line in (done.stdout + done.stderr).splitlines())
    line = _one_line_error(run_cli("replay", str(log), "-o", str(tmp_path / "r.rrd")), "evil.mcap")
    assert "\x1b" not in line and "\\x1b[2J" in line
