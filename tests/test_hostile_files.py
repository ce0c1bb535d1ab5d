"""Issue 45: hostile files on the commands that read and write them (outage-log, plans, external
trajectories, exports, figures, convert, train, screenshots).

Bad input -> exit code 2, one line on stderr starting ``error:`` that names the file, row or
field with a hint, no traceback, and nothing written. Each case states the input and why it
failed before.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import pytest

import ionav_viz as iv

from .conftest import run_cli


# --- shared inputs ------------------------------------------------------------------------------
@pytest.fixture(scope="session")
def short_csv(tmp_path_factory) -> Path:
    """A 70 s simulated roundabout drive (IO-VNBD CSV, stamps jittered by a millisecond as a logger's)."""
    from ionav_viz.sim.simulate import write_simulated_drive

    return write_simulated_drive(tmp_path_factory.mktemp("drives") / "V-short.csv", "roundabout", seed=4, duration_s=70)


@pytest.fixture(scope="session")
def outaged(tmp_path_factory, short_csv) -> tuple[Path, Path]:
    """The short drive's outaged MCAP and its plan: two 10 s outages, at 20 s and 40 s."""
    folder = tmp_path_factory.mktemp("outaged")
    done = iv.outage_log(short_csv, folder / "cut.mcap", 10.0, iv.At((20.0, 40.0)))
    return done.path, done.plan_path


def snapshot(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (links as links) and its checksum: to show nothing was written."""
    out = {}
    for p in sorted(folder.rglob("*")):
        rel = str(p.relative_to(folder))
        if p.is_symlink():
            out[rel] = "-> " + os.readlink(p)
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[rel] = "dir" if p.is_dir() else "special"
    return out


def assert_refused(proc, *fragments: str) -> str:
    """Exit code 2, exactly one line on stderr starting ``error:`` with a hint and ``fragments``."""
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in proc.stderr, proc.stderr
    assert "(hint: " in lines[0], lines[0]
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


# --- 1. the source of a command is never its output ---------------------------------------------
def test_no_command_writes_over_its_input(tmp_path, short_csv):
    """``outage-log rb.mcap -o rb.mcap`` replaced the user's source log and exited 0. Now every
    command that reads and writes files refuses an output that is an input: the same path, a
    symbolic link to it, another hard link of it (same st_dev/st_ino), an input inside a folder the
    command replaces whole, an output inside an input folder; before any work, nothing written."""
    src = tmp_path / "V-src.csv"
    shutil.copyfile(short_csv, src)
    os.link(src, tmp_path / "hard.csv")
    os.link(src, tmp_path / "hard.rrd")
    os.link(src, tmp_path / "cut.outages.json")  # the plan outage-log would write beside cut.mcap
    (tmp_path / "link.csv").symlink_to(src)
    (tmp_path / "link.mcap").symlink_to(src)
    exported = tmp_path / "exp"
    (exported / "tum" / "x").mkdir(parents=True)
    shutil.copyfile(short_csv, exported / "outages.csv")  # a drive named as an export file
    shutil.copyfile(short_csv, exported / "tum" / "x" / "V-in.csv")  # a drive in the folder export replaces
    (tmp_path / "model").mkdir()
    shutil.copyfile(short_csv, tmp_path / "model" / "V-train.csv")
    (tmp_path / "figs").mkdir()
    (tmp_path / "figs" / "report.json").write_text("{}")
    (tmp_path / "a.rrd").write_bytes(b"not a recording")
    os.link(tmp_path / "a.rrd", tmp_path / "shot.png")
    before = snapshot(tmp_path)
    cases = [
        (("outage-log", "V-src.csv", "-o", "V-src.csv"), "V-src.csv: is the input V-src.csv"),
        (("outage-log", "V-src.csv", "-o", "hard.csv"), "hard.csv: is another name (a hard link) of the input V-src.csv"),
        (("outage-log", "V-src.csv", "-o", "link.csv"), "link.csv: is a link to the input V-src.csv"),
        (("outage-log", "link.csv", "-o", "V-src.csv"), "is the input link.csv (a link to it)"),
        (("outage-log", "V-src.csv", "-o", "cut.mcap"), "cut.outages.json: is another name (a hard link) of the input"),
        (("convert", "V-src.csv", "-o", "link.mcap"), "link.mcap: is a link to the input V-src.csv"),
        (("replay", "V-src.csv", "--no-idnn", "-o", "hard.rrd"), "hard.rrd: is another name (a hard link)"),
        (("replay", "exp/outages.csv", "--no-idnn", "-o", "r.rrd", "--export", "exp"), "--export: exp/outages.csv: is the input"),
        (("evaluate", "exp/tum/x/V-in.csv", "--no-idnn", "--export", "exp"), "exp/tum: holds the input exp/tum/x/V-in.csv"),
        (("replay", "V-src.csv", "--no-idnn", "-o", "r.rrd", "--screenshot", "hard.csv"), "--screenshot: hard.csv: exists and is not a folder"),
        (("train", "model/V-train.csv", "-o", "model", "--force"), "model: holds the input model/V-train.csv"),
        (("figures", "figs/report.json", "-o", "figs"), "figs: holds the input figs/report.json"),
        (("figures", "figs/report.json", "-o", "figs/report.json"), "figs/report.json: is the input"),
        (("screenshot", "a.rrd", "-o", "shot.png"), "shot.png: is another name (a hard link) of the input a.rrd"),
    ]
    for args, fragment in cases:
        assert_refused(run_cli(*args, cwd=tmp_path), fragment)
        assert snapshot(tmp_path) == before, args  # nothing written, nothing replaced
