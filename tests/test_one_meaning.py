"""Issue 46's small disagreements: one meaning per option name, one name per manoeuvre, a missing
file named as missing, conflicting output flags refused, --every keeping its promise of GNSS in
between."""

from __future__ import annotations

import shutil

import pytest

from .conftest import REPO, run_cli

SAMPLES = REPO / "ionav_viz" / "data" / "samples"


def one_line_error(proc, *fragments: str) -> str:
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in proc.stderr, proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


@pytest.mark.parametrize("name", ["nothere.csv", "V-Vw88.csv", "logs/car.mcap"])
def test_a_missing_file_is_named_as_missing(tmp_path, name):
    one_line_error(run_cli("replay", name, "-q", cwd=tmp_path), f"{name}: no such file")
    assert list(tmp_path.iterdir()) == []


def test_an_unknown_name_without_a_suffix_is_still_an_unknown_drive(tmp_path):
    one_line_error(run_cli("evaluate", "roundabot", cwd=tmp_path), "unknown drive 'roundabot'", "did you mean roundabout")


def test_a_folder_of_drives_suggests_the_drives_themselves(tmp_path):
    """Where one drive is read (events, outage-log); evaluate and replay take a folder of drives as a fleet (tests/test_fleet.py)."""
    folder = tmp_path / "drives"
    folder.mkdir()
    shutil.copy(SAMPLES / "V-sim-motorway.csv", folder)
    one_line_error(run_cli("events", str(folder)), "a folder of drives, not one drive", f"{folder}/*.csv")


def test_json_and_markdown_together_are_refused():
    one_line_error(run_cli("evaluate", "roundabout", "--json", "--markdown"), "--json and --markdown", "give one of them")


@pytest.mark.parametrize(("args", "fragments"), [(["simulate", "motorway"], ["error: -o: no file to write", "-o FILE.csv"]),
                                                  (["simulate"], ["no scenario to simulate", "ionav-viz simulate motorway -o"])])
def test_simulate_without_its_arguments_answers_as_every_command(args, fragments):
    one_line_error(run_cli(*args), *fragments)


@pytest.mark.parametrize("command", ["replay", "evaluate", "outage-log"])
def test_outages_every_period_of_their_own_length_are_refused_with_the_fix(tmp_path, command):
    """--every promises GNSS between outages: a period equal to the outage length gave back-to-back
    outages silently."""
    line = one_line_error(run_cli(command, "roundabout", "--every", "30s", "--outage", "30s", "-o", str(tmp_path / "x.mcap"), "-q")
                          if command == "outage-log" else
                          run_cli(command, "roundabout", "--every", "30s", "--outage", "30s", "-q",
                                  *(["-o", str(tmp_path / "x.rrd")] if command == "replay" else [])),
                          "--every 30s", "leaves no GNSS between them", "longer period")
    assert "tile the drive" in line
    assert list(tmp_path.iterdir()) == []
    assert run_cli("evaluate", "roundabout", "--every", "31s", "--outage", "30s", "-q").returncode == 0


def test_the_manoeuvre_has_the_scenarios_name_and_the_old_one_still_works():
    events = run_cli("events", "sharp-cornering", "--type", "sharp-cornering", "--json")
    assert events.returncode == 0 and '"sharp-cornering"' in events.stdout and '"sharp-corner"' not in events.stdout
    old = run_cli("events", "sharp-cornering", "--type", "sharp-corner", "--json")
    assert old.returncode == 0 and old.stdout == events.stdout
    assert old.stderr.strip() == "warning: event type sharp-corner is sharp-cornering now"
    placed = run_cli("evaluate", "sharp-cornering", "--on", "sharp-corner", "--no-idnn", "--json")
    assert placed.returncode == 0 and "sharp-cornering now" in placed.stderr, placed.stderr


def test_every_command_that_writes_takes_quiet(tmp_path):
    """-q means the same on every command that writes a file: simulate, convert and figures take it
    too (each was 'No such option: -q'); the path written stays on stdout, convert's summary goes."""
    out = tmp_path / "V-q.csv"
    proc = run_cli("simulate", "motorway", "--duration", "20s", "-o", str(out), "-q")
    assert proc.returncode == 0 and proc.stdout.strip() == str(out) and out.is_file(), proc.stderr
    proc = run_cli("convert", str(out), "-o", str(tmp_path / "q.mcap"), "-q")  # its summary goes; warnings and the path stay
    assert proc.returncode == 0 and proc.stdout.strip() == str(tmp_path / "q.mcap") and "messages on" not in proc.stderr, proc.stderr
    report = tmp_path / "r.json"
    report.write_text(run_cli("evaluate", "hard-brake", "--estimators", "ins", "--json").stdout)
    proc = run_cli("figures", str(report), "-o", str(tmp_path / "figs"), "-q")
    assert proc.returncode == 0 and "files in" not in proc.stderr and str(tmp_path / "figs" / "drift.png") in proc.stdout, proc.stderr
