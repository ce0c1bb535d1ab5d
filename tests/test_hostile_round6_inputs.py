"""Hostile inputs, round 6 (issue 60, part B): how drives are named (list files, globs, folders,
links), ``cross-validate --folds``, ``--cluster``, the fleet API's arguments, fleet figures,
``info``'s names, huge covariances, ``events --quality`` with a span, and a truncated recording.
Each case states what happened before.

Bad input -> exit code 2, one line on stderr starting ``error:`` that names the file, option or
field with a hint, no traceback, nothing written; nothing hangs, nothing grows without bound.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from .conftest import run_cli


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
