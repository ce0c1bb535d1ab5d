"""Experiment files (issue 61, point 3): ``ionav-viz run FILE``, ``--config FILE`` on any command,
``--print-config``, and the configuration embedded in JSON reports and recordings."""

from __future__ import annotations

import json

import pytest

from .conftest import one_line_error, run_cli

FAST = ["--estimators", "ins", "--outage", "10s", "-q"]


def write(tmp_path, text: str, name: str = "exp.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_run_gives_what_the_same_flags_give(tmp_path):
    exp = write(tmp_path, 'command = "evaluate"\ndrives = ["roundabout"]\noutage = "10s"\nestimators = ["ins", "odo"]\n'
                          'warm_up = "20s"\njson = true\nquiet = true\n')
    by_file = run_cli("run", str(exp))
    by_flags = run_cli("evaluate", "roundabout", "--outage", "10s", "--estimators", "ins,odo", "--warm-up", "20s", "--json", "-q")
    assert by_file.returncode == 0 == by_flags.returncode, by_file.stderr
    a, b = json.loads(by_file.stdout), json.loads(by_flags.stdout)
    assert a["config"] == b["config"] == {"command": "evaluate", "drives": ["roundabout"], "outage": "10s", "json": True,
                                          "estimators": "ins,odo", "warm-up": "20s"}  # not -q: how it runs, not what
    assert a["summary"] == b["summary"] and [e["name"] for e in a["estimators"]] == ["ins", "odo"]


def test_command_line_wins_over_the_file_and_replaces_its_drives(tmp_path):
    exp = write(tmp_path, 'command = "evaluate"\ndrives = ["roundabout"]\noutage = "10s"\nestimators = "ins"\n')
    done = run_cli("run", str(exp), "motorway", "--outage", "5s", "--print-config")
    assert done.returncode == 0, done.stderr
    assert 'drives = ["motorway"]' in done.stdout and 'outage = "5s"' in done.stdout and 'estimators = "ins"' in done.stdout
    again = run_cli("evaluate", "--config", str(exp), "--print-config")  # --config on the command itself
    assert 'drives = ["roundabout"]' in again.stdout and 'outage = "10s"' in again.stdout


def test_print_config_round_trips(tmp_path):
    printed = run_cli("replay", "roundabout", *FAST, "-o", str(tmp_path / "r.rrd"), "--print-config")
    assert printed.returncode == 0 and not (tmp_path / "r.rrd").exists()  # printed, not run
    exp = write(tmp_path, printed.stdout)
    again = run_cli("run", str(exp), "--print-config")
    assert again.stdout == printed.stdout
    done = run_cli("run", str(exp))
    assert done.returncode == 0, done.stderr
    from ionav_viz.viz.figures import read_report

    assert read_report(tmp_path / "r.rrd")["config"]["command"] == "replay"  # the recording carries it


@pytest.mark.parametrize(("text", "words"), [
    ('command = "evaluate"\ndrives = ["roundabout"]\noutgae = "10s"\n', ["exp.toml line 3", "--outgae", "did you mean outage"]),
    ('command = "evaluate"\ndrives = ["roundabout"]\njson = "yes"\n', ["exp.toml line 3", "--json is a flag"]),
    ('command = "evaluate"\ndrives = ["roundabout"]\n[options]\noutage = "10s"\n', ["exp.toml line 3", "[options] is a table"]),
    ('command = "evaluate"\ndrives = ["roundabout"\n', ["exp.toml", "not valid TOML"]),
    ('drives = ["roundabout"]\n', ["exp.toml", "no command"]),
    ('command = "evaluat"\n', ["unknown command 'evaluat'"]),
    ('command = "evaluate"\ndrives = ["roundabout"]\noutage = "ten"\n', ["exp.toml line 3", "--outage"]),
    ('command = "evaluate"\ndrives = ["roundabout"]\nworkers = "x"\n', ["exp.toml line 3", "--workers"]),
])
def test_bad_files_are_one_line_naming_the_line(tmp_path, text, words):
    one_line_error(run_cli("run", str(write(tmp_path, text))), *words)


def test_bad_paths_and_uses(tmp_path):
    one_line_error(run_cli("run", str(tmp_path / "missing.toml")), "missing.toml", "cannot read")
    one_line_error(run_cli("run", str(tmp_path)), "is a folder")
    one_line_error(run_cli("evaluate", "roundabout", "--config"), "--config needs a file")
    exp = write(tmp_path, 'command = "replay"\n')
    one_line_error(run_cli("evaluate", "roundabout", "--config", str(exp)), "for 'replay', not 'evaluate'")


def test_a_fleet_report_is_the_same_whatever_the_workers(tmp_path):
    import ionav_viz as iv

    for seed in (1, 2):
        iv.simulate("roundabout", tmp_path / f"V-w{seed}.csv", seed=seed, duration_s=90.0)
    one = run_cli("evaluate", str(tmp_path), "--workers", "1", "--estimators", "ins", "--json", "-q")
    two = run_cli("evaluate", str(tmp_path), "--workers", "2", "--estimators", "ins", "--json", "-q")
    a, b = json.loads(one.stdout), json.loads(two.stdout)
    for report in (a, b):
        report.pop("timing")
    assert a == b and a["config"] == {"command": "evaluate", "drives": [str(tmp_path)], "json": True, "estimators": "ins"}
    printed = run_cli("evaluate", str(tmp_path), "--workers", "2", "--print-config")
    assert "workers = 2" in printed.stdout  # printed, so that the file reruns it the same way
