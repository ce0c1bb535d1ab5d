"""The command line starts the workers' forkserver before its own imports when a run will likely
use local worker processes (``ionav_viz.cli.app.runs_worker_processes``): a guess from the words
alone, which must never start one for a run that cannot use it."""

from __future__ import annotations

import pytest

from ionav_viz.cli.app import runs_worker_processes


@pytest.fixture
def fleet_folder(tmp_path):
    folder = tmp_path / "fleet"
    folder.mkdir()
    for name in ("V-a.csv", "V-b.mcap"):
        (folder / name).write_text("")
    return folder


@pytest.fixture
def one_drive_folder(tmp_path):
    folder = tmp_path / "bag"
    folder.mkdir()
    (folder / "metadata.yaml").write_text("")
    (folder / "bag_0.db3").write_text("")
    return folder


def test_workers_of_two_or_more_start_it(fleet_folder):
    assert runs_worker_processes(["evaluate", "x.csv", "y.csv", "--workers", "2"])
    assert runs_worker_processes(["replay", str(fleet_folder), "--workers=3", "-o", "out"])
    assert runs_worker_processes(["-v", "evaluate", str(fleet_folder)])  # a folder of drives: every core


@pytest.mark.parametrize("extra", [["--workers", "1"], ["--workers=1"], ["--workers"], ["--workers", "two"], ["--cluster", "local"],
                                   ["--dry-run"], ["--help"]])
def test_runs_in_this_process_or_elsewhere_do_not(fleet_folder, extra):
    assert not runs_worker_processes(["evaluate", str(fleet_folder), *extra])


def test_other_commands_and_single_drives_do_not(fleet_folder, one_drive_folder):
    assert not runs_worker_processes(["screenshot", str(fleet_folder)])
    assert not runs_worker_processes(["evaluate", "roundabout"])
    assert not runs_worker_processes(["replay", str(one_drive_folder)])  # a ROS 2 bag's folder is one drive
    assert not runs_worker_processes([])
