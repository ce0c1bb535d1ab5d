"""The benchmark scripts that take a user's files answer bad input as the command line does
(benchmarks/_cli.py): one line naming the file (and the option, entry and field when known) with a
hint, exit code 2, no traceback unless ``--debug``, checked before any work and nothing written."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.conftest import HANG_S, REPO


def run_script(script: str, *args: str, cwd) -> subprocess.CompletedProcess:
    """``python benchmarks/SCRIPT ARGS`` as a user runs it, on this checkout's ionav_viz."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])}
    env.pop("IONAV_DATA", None)
    return subprocess.run([sys.executable, str(REPO / "benchmarks" / script), *args], capture_output=True, text=True, env=env, cwd=cwd,
                          timeout=HANG_S)


def assert_one_line_error(proc: subprocess.CompletedProcess, *named: str) -> str:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert all(n in lines[0] for n in named), (named, lines[0])
    return lines[0]


@pytest.fixture
def files(tmp_path):
    (tmp_path / "bad.json").write_text('[{"log": "a.mcap",')
    (tmp_path / "shape.json").write_text('[{"log": "a.mcap", "lengths": {"10": {"outages": 3, "gins": "7.2"}}}]')
    (tmp_path / "garbage.mcap").write_bytes(b"not an mcap at all")
    (tmp_path / "folder").mkdir()
    return tmp_path


@pytest.mark.parametrize("script, args, named", [
    ("real_imu_logs.py", ["nothere.mcap"], ["nothere.mcap", "no such file"]),
    ("imu_character.py", ["nothere.mcap"], ["nothere.mcap", "no such file"]),
    ("sim_vs_real.py", ["folder"], ["folder", "neither a ROS 2 bag folder"]),
    ("imu_character.py", ["garbage.mcap"], ["garbage.mcap", "not an MCAP file"]),
    ("results_table.py", ["--real-logs", "missing.json"], ["--real-logs: missing.json: no such file", "hint: "]),
    ("results_table.py", ["--real-logs", "bad.json"], ["--real-logs: bad.json: not valid JSON"]),
    ("results_table.py", ["--real-logs", "shape.json"], ["shape.json: entry 1 (a.mcap): lengths['10']['gins'] is '7.2', not a number"]),
    ("idnn_heldout.py", ["--write", "no-folder/page.md"], ["--write: no-folder/page.md: output directory no-folder does not exist"]),
])
def test_bad_input_is_one_line_and_exit_code_2(files, script, args, named):
    assert_one_line_error(run_script(script, *args, cwd=files), *named)


def test_a_log_that_cannot_be_read_is_not_tabled_as_one_without_outages(files):
    proc = run_script("sim_vs_real.py", "garbage.mcap", cwd=files)
    assert_one_line_error(proc, "garbage.mcap", "not an MCAP file")
    assert "garbage" not in proc.stdout  # no row of dashes for it


def test_an_output_in_a_missing_folder_is_refused_before_any_work(files):
    proc = run_script("real_imu_logs.py", "garbage.mcap", "--json", "no-folder/out.json", cwd=files)
    assert_one_line_error(proc, "--json: no-folder/out.json: output directory no-folder does not exist")
    assert proc.stdout == "" and not (files / "no-folder").exists()


def test_debug_shows_the_traceback(files):
    proc = run_script("results_table.py", "--real-logs", "missing.json", "--debug", cwd=files)
    assert proc.returncode != 0 and "Traceback" in proc.stderr and "InputError: missing.json: no such file" in proc.stderr


def test_a_bad_outage_length_is_one_line_naming_it(files):
    line = assert_one_line_error(run_script("results_table.py", "--lengths", "10,abc", cwd=files), "--lengths", "'abc'")
    assert "is not a duration" in line
    assert_one_line_error(run_script("results_table.py", "--lengths", "10.5", cwd=files), "--lengths", "10.5 s is not a whole number")
    assert {p.name for p in files.iterdir()} == {"bad.json", "shape.json", "garbage.mcap", "folder"}  # nothing written


def test_real_imu_logs_says_whether_gins_is_above_the_ins_dr_beyond_the_outages_spread(tmp_path):
    """The second table: gins minus the INS DR per length, its mean the difference of the first
    table's means (every outage scored by both), inside its own bootstrap interval."""
    import json

    from ionav_viz.sim.imu import write_imu_log

    write_imu_log(tmp_path / "phone.mcap", "roundabout", 11, 150.0, "phone")
    proc = run_script("real_imu_logs.py", "phone.mcap", "--truth-topic", "/truth/fix", "--lengths", "10", "--json", "out.json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    cell = json.loads((tmp_path / "out.json").read_text())[0]["lengths"]["10"]
    mean, lo, hi = cell["gins_minus_ins_points"]
    assert mean == pytest.approx(cell["gins"] - cell["ins"])
    assert lo <= mean <= hi
    verdict = "above" if lo > 0 else "below" if hi < 0 else "cannot tell"
    assert f"| phone.mcap | {mean:+.1f} [{lo:+.1f}, {hi:+.1f}] {verdict} |" in proc.stdout


def test_results_table_takes_what_real_imu_logs_writes(tmp_path, monkeypatch):
    """real_imu_logs.py --json writes each length's gins-minus-INS-DR gap as [mean, low, high];
    results_table.py --real-logs refused it as 'not a number', and its real rows ranked the list
    against the estimators' numbers (a TypeError)."""
    import json

    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    import results_table

    cell = {"outages": 12, "ins": 18.0, "gins": 2.0, "idnn": None, "gins_minus_ins_points": [-16.0, -21.0, -11.8]}
    (tmp_path / "r.json").write_text(json.dumps([{"log": "roof", "lengths": {"10": cell}}]))
    real = results_table.read_real_logs([tmp_path / "r.json"])
    assert "best 2.0 % (gins), ins 18.0" in results_table.real_rows(real, [10.0])
