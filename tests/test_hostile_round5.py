"""Hostile inputs, round 5 (issue 45, points 3 and 4): what still broke after rounds 1-4, tried on
every command as a careless or malicious user would. Each case states what happened before.

Bad input -> exit code 2, one line on stderr starting ``error:`` that names the file, option or
field with a hint, no traceback, and nothing written.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from .conftest import one_line_error as _one_line_error
from .conftest import run_cli


@pytest.fixture(scope="session")
def short_csv(tmp_path_factory) -> Path:
    """A 60 s simulated roundabout drive (IO-VNBD CSV)."""
    from ionav_viz.sim.simulate import write_simulated_drive

    return write_simulated_drive(tmp_path_factory.mktemp("drives5") / "V-short.csv", "roundabout", seed=4, duration_s=60)


# --- output equal to output, or to a system file ----------------------------------------------------
def test_replay_output_and_export_the_same_path_refused_before_work(tmp_path, short_csv):
    """``replay -o X.rrd --export X.rrd`` wrote the recording, then failed making the export folder
    (exit 2 with X.rrd written)."""
    done = run_cli("replay", str(short_csv), "-q", "-o", "X.rrd", "--export", "X.rrd", "--estimators", "ins", cwd=tmp_path)
    _one_line_error(done, "--export", "X.rrd")
    assert list(tmp_path.iterdir()) == []


def test_replay_output_and_screenshot_the_same_path_refused_before_work(tmp_path, short_csv):
    """``replay -o X.rrd --screenshot X.rrd`` wrote the recording, then the screenshot step called it
    its own input ("is the input X.rrd"), exit 2 with X.rrd written."""
    done = run_cli("replay", str(short_csv), "-q", "-o", "X.rrd", "--screenshot", "X.rrd", "--estimators", "ins", cwd=tmp_path)
    _one_line_error(done, "--screenshot", "X.rrd")
    assert list(tmp_path.iterdir()) == []


def test_replay_output_inside_the_export_tum_folder_refused(tmp_path, short_csv):
    """``-o ex/tum/X.rrd --export ex``: the export replaces ``ex/tum/<drive>`` whole."""
    (tmp_path / "ex" / "tum").mkdir(parents=True)
    done = run_cli("replay", str(short_csv), "-q", "-o", "ex/tum/X.rrd", "--export", "ex", "--estimators", "ins", cwd=tmp_path)
    _one_line_error(done, "--export", "tum")
    assert list((tmp_path / "ex" / "tum").iterdir()) == []


def test_output_through_a_link_into_proc_refused(tmp_path):
    """``simulate -o /dev/stdout`` with standard output a file passed every check, and the rename
    replaced the system's ``/dev/stdout`` link with a regular file (as root). Tried here on a link
    of our own into ``/proc/self/fd`` (a regular file behind it), which was replaced the same way."""
    behind = tmp_path / "behind.txt"
    with open(behind, "w") as keep_open:
        link = tmp_path / "out.csv"
        link.symlink_to(f"/proc/self/fd/{keep_open.fileno()}")
        done = run_cli("simulate", "roundabout", "--duration", "30s", "-o", str(link))
        _one_line_error(done, "out.csv", "system file")
        assert link.is_symlink()
    assert behind.stat().st_size == 0


def test_output_a_symbolic_link_loop_refused(tmp_path):
    """``simulate -o loop`` (a link loop) replaced the link with the drive, exit 0."""
    (tmp_path / "a.csv").symlink_to("b.csv")
    (tmp_path / "b.csv").symlink_to("a.csv")
    done = run_cli("simulate", "roundabout", "--duration", "30s", "-o", "a.csv", cwd=tmp_path)
    _one_line_error(done, "a.csv", "loop")
    assert (tmp_path / "a.csv").is_symlink()


@pytest.mark.parametrize("output", [".", "..", "/"])
def test_outage_log_output_a_nameless_folder(tmp_path, short_csv, output):
    """``outage-log D -o .`` was a ValueError traceback ("PosixPath('.') has an empty name")."""
    (tmp_path / "here").mkdir()
    done = run_cli("outage-log", str(short_csv), "-q", "-o", output, cwd=tmp_path / "here")
    _one_line_error(done, "-o")
    assert list((tmp_path / "here").iterdir()) == []


# --- huge and absurd inputs ---------------------------------------------------------------------
@pytest.fixture(scope="session")
def outaged5(tmp_path_factory, short_csv) -> Path:
    """The short drive's plan: one 10 s outage at 20 s."""
    import ionav_viz as iv

    folder = tmp_path_factory.mktemp("outaged5")
    iv.outage_log(short_csv, folder / "cut.mcap", 10.0, iv.At((20.0,)))
    return folder / "cut.outages.json"


@pytest.mark.parametrize("name", ["sparse.csv", "sparse.tum"])
def test_external_sparse_trajectory_refused_by_its_first_bytes(tmp_path, short_csv, outaged5, name):
    """A 1 GB sparse file as ``--external``: its first "line" (the whole file) was read into memory
    and quoted in the message, more than a minute; now the NUL bytes at its start refuse it."""
    sparse = tmp_path / name
    with open(sparse, "wb") as f:
        f.truncate(1 << 30)
    done = run_cli("evaluate", str(short_csv), "-q", "--plan", str(outaged5), "--external", f"m={sparse}", "--estimators", "ins")
    _one_line_error(done, "--external", name, "binary")


def test_external_header_only_csv_one_line(tmp_path, short_csv, outaged5):
    """A trajectory CSV with its header and no rows printed numpy's UserWarning ("loadtxt: input
    contained no data") and the source line on stderr before the error."""
    empty = tmp_path / "empty.csv"
    empty.write_text("time_s,lat_deg,lon_deg\n")
    done = run_cli("evaluate", str(short_csv), "-q", "--plan", str(outaged5), "--external", f"m={empty}", "--estimators", "ins")
    _one_line_error(done, "empty.csv", "fewer than 2 poses")


def test_simulate_absurd_gnss_loss_count_is_bounded(monkeypatch):
    """``simulate --gnss-loss 1000000`` drew 50 million candidate losses (a hang of minutes); the
    draws are bounded by what fits in the drive: counted here, not timed."""
    import numpy as np

    from ionav_viz.sim import simulate

    draws = []
    real_rng = np.random.default_rng

    class Counting:
        def __init__(self, *args):
            self.rng = real_rng(*args)

        def uniform(self, *args, **kwargs):
            draws.append(1)
            if len(draws) > 100_000:  # unbounded: stop here rather than draw for minutes
                raise AssertionError("more than 100,000 draws")
            return self.rng.uniform(*args, **kwargs)

        def __getattr__(self, name):
            return getattr(self.rng, name)

    monkeypatch.setattr(simulate.np.random, "default_rng", Counting)
    simulate.gnss_loss_spans("roundabout", 0, 120.0, 1)
    one = len(draws)  # the drive's own draws, and a loss's
    spans = simulate.gnss_loss_spans("roundabout", 0, 120.0, 1_000_000)
    assert 1 <= len(spans) <= 4
    assert len(draws) - one <= one + 2 * 50 * simulate.gnss_loss_room(120.0), len(draws)  # two draws a candidate, 50 a loss that fits


# --- full disks and signals mid-write --------------------------------------------------------------
def test_export_failing_part_way_leaves_the_folder_as_it_was(tmp_path, short_csv, monkeypatch):
    """``evaluate --export ex`` under ``ulimit -f`` (or a full disk) failing at a later file left
    ``outages.csv`` and the TUM tracks without ``tracks.gpx``, and a new export folder made but
    empty when the first file failed; now the export is staged and moved in whole."""
    import errno

    from ionav_viz.analysis import exports

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(exports, "_gpx", full)
    done = run_cli("evaluate", str(short_csv), "-q", "--export", "new/ex", "--estimators", "ins", cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    assert "tracks.gpx" in done.stderr and "Traceback" not in done.stderr
    assert list(tmp_path.iterdir()) == []  # neither ex nor the new/ made for it

    old = tmp_path / "old"
    old.mkdir()
    (old / "outages.csv").write_text("previous\n")
    (old / "mine.txt").write_text("the user's\n")
    done = run_cli("evaluate", str(short_csv), "-q", "--export", "old", "--estimators", "ins", cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    assert sorted(p.name for p in old.iterdir()) == ["mine.txt", "outages.csv"]
    assert (old / "outages.csv").read_text() == "previous\n"


# --- wrong units ------------------------------------------------------------------------------------
@pytest.fixture(scope="session")
def motorway_rows(tmp_path_factory) -> tuple[str, list[list[str]]]:
    """A 90 s simulated roundabout drive's header line and rows (cells as written): it turns through every heading."""
    from ionav_viz.sim.simulate import write_simulated_drive

    path = write_simulated_drive(tmp_path_factory.mktemp("units5") / "V-rb.csv", "roundabout", seed=1, duration_s=90)
    header, *rows = path.read_text().splitlines()
    return header, [row.split(",") for row in rows]


def _with_column(tmp_path: Path, motorway_rows, change) -> Path:
    header, rows = motorway_rows
    labels = [h.strip() for h in header.split(",")]
    out = tmp_path / "V-units.csv"
    lines = [header]
    for row in rows:
        row = list(row)
        for label, fn in change.items():
            k = labels.index(label)
            row[k] = repr(fn(float(row[k])))
        lines.append(",".join(row))
    out.write_text("\n".join(lines) + "\n")
    return out


@pytest.mark.parametrize("change, words", [
    ({"Velocity (km/hr)": lambda v: v / 3.6}, ["Velocity (km/hr)", "m/s where the header says km/h"]),
    ({"Latitude (degrees)": lambda v: v * 3.141592653589793 / 180, "Longitude (degrees)": lambda v: v * 3.141592653589793 / 180},
     ["the speed the positions give", "radians"]),
    ({"Heading (degrees)": lambda v: v * 3.141592653589793 / 180}, ["Heading (degrees)", "radians"]),
    ({"Time Since Start of Day (seconds)": lambda v: v * 1000}, ["milliseconds"]),
], ids=["speed-in-mps", "positions-in-radians", "heading-in-radians", "time-in-ms"])
def test_csv_columns_in_the_wrong_unit_are_named(tmp_path, motorway_rows, change, words):
    """A speed written in m/s under the 'Velocity (km/hr)' header, latitude and longitude in
    radians, or the heading in radians: every value within its limits, so the drive was scored
    silently (exit 0, INS errors of a drive 3.6 or 57 times slower or turning wrong); now the
    columns are checked against the speed and course the positions give."""
    path = _with_column(tmp_path, motorway_rows, change)
    done = run_cli("evaluate", str(path), "-q", "--estimators", "ins")
    _one_line_error(done, "V-units.csv", "unit", *words)


def test_csv_in_the_right_units_still_reads(tmp_path, motorway_rows):
    path = _with_column(tmp_path, motorway_rows, {})
    done = run_cli("evaluate", str(path), "-q", "--estimators", "ins")
    assert done.returncode == 0, done.stderr


# --- duplicated and conflicting -----------------------------------------------------------------
def test_csv_column_named_twice_refused(tmp_path, short_csv):
    """A header naming 'Latitude (degrees)' twice (the second in place of the steering angle) was
    read silently (pandas renamed the second 'Latitude (degrees).1'; the first was used)."""
    header, *rows = short_csv.read_text().splitlines()
    names = header.split(",")
    names[9] = names[2]
    path = tmp_path / "V-twice.csv"
    path.write_text("\n".join([",".join(names), *rows]) + "\n")
    done = run_cli("evaluate", str(path), "-q", "--estimators", "ins")
    _one_line_error(done, "V-twice.csv", "Latitude (degrees)", "twice", "columns 3 and 10")


@pytest.mark.parametrize("command", [
    ["evaluate", "{drive}", "-q", "--estimators", "ins", "--gnss-limit", "max_sigma_m=1", "--gnss-limit", "max_sigma_m=20"],
    ["events", "{drive}", "--threshold", "hard_brake_g=0.4", "--threshold", "hard-brake-g=0.5"],
])
def test_an_override_given_twice_with_different_values_refused(short_csv, command):
    """``--gnss-limit max_sigma_m=1 --gnss-limit max_sigma_m=20`` (or ``--threshold``): the last
    one won silently; the same value twice is still fine."""
    done = run_cli(*[c.format(drive=short_csv) for c in command])
    _one_line_error(done, "given twice", "different values")


# --- NaN, infinities and absurd values in files -------------------------------------------------------
def test_plan_integer_beyond_float_range_refused(tmp_path, short_csv, outaged5):
    """An integer of 401 digits as a plan's stamp (under Python's 4300-digit limit, so JSON read
    it) was an OverflowError traceback when the plan turned it into seconds; ``1e400`` was refused
    as infinity, so is the integer now."""
    import json

    plan = json.loads(outaged5.read_text())
    plan["outages"][0]["start_stamp_s"] = 10**400
    path = tmp_path / "big.outages.json"
    path.write_text(json.dumps(plan))
    done = run_cli("evaluate", str(short_csv), "-q", "--plan", str(path), "--estimators", "ins")
    _one_line_error(done, "--plan", "big.outages.json", "overflows")


# --- special files -----------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["dangling", "loop"])
@pytest.mark.parametrize("command", ["replay", "info"])
def test_a_dangling_link_or_loop_as_the_drive_is_named(tmp_path, kind, command):
    """A dangling link as the drive was "unknown drive 'x.csv'" (taken for a run name) with a hint
    at bundled scenarios, a link loop the same; ``info`` said "no such file or folder"."""
    if kind == "dangling":
        (tmp_path / "x.csv").symlink_to("gone.csv")
    else:
        (tmp_path / "x.csv").symlink_to("y.csv")
        (tmp_path / "y.csv").symlink_to("x.csv")
    done = run_cli(command, "x.csv", cwd=tmp_path)
    _one_line_error(done, "x.csv", "gone.csv" if kind == "dangling" else "loop")


@pytest.mark.parametrize(
    "command",
    [["evaluate", "gone.mcap"], ["replay", "logs/gone.bag"], ["convert", "gone.db3", "-o", "x.mcap"], ["info", "gone.mcap"], ["info", "roundabout"]],
)
def test_a_missing_log_is_named_with_a_hint(tmp_path, command):
    """A log that is not there was 'gone.mcap: no such file or folder' and nothing more (a missing
    CSV had 'check the path'); ``info roundabout`` the same, without saying that info takes a log,
    not a drive's name."""
    line = _one_line_error(run_cli(*command, cwd=tmp_path), ": no such file or folder (hint: check the path (relative to the current directory)")
    assert command[0] != "info" or "info takes a log's file or folder, not a drive's name" in line
    assert list(tmp_path.iterdir()) == []


def test_info_on_a_named_pipe_names_it(tmp_path):
    """``info pipe.mcap`` said "empty file" (it did not hang, but named the wrong problem)."""
    os.mkfifo(tmp_path / "pipe.mcap")
    done = run_cli("info", "pipe.mcap", cwd=tmp_path)
    _one_line_error(done, "pipe.mcap", "named pipe")


@pytest.mark.parametrize("command", [["list"], ["fetch", "V-Vw8", "--base-url", "http://127.0.0.1:9/"]])
def test_a_data_root_that_is_a_file_refused(tmp_path, command):
    """``list --data-root FILE`` listed every run as missing (exit 0); ``fetch`` said "cannot create
    it (File exists)"."""
    (tmp_path / "root.csv").write_text("x\n")
    done = run_cli(*command, "--data-root", "root.csv", cwd=tmp_path)
    _one_line_error(done, "root.csv", "not a folder")
    assert (tmp_path / "root.csv").read_text() == "x\n"
