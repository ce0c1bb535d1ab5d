"""Hostile inputs on fleets, round 6 (issue 60, part A): outputs that replaced one another or an
input, workers left half-written files behind on a signal, pools larger than the cores, outputs
inside the installed package, and windows that moved with a nanosecond of clock offset. Each case
states what happened before.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import HANG_S, REPO, run_cli

pytestmark = pytest.mark.xdist_group("fleet")


def _simulate(path: Path, scenario: str = "roundabout", seed: int = 0, duration_s: float = 60.0) -> Path:
    from ionav_viz.sim.simulate import write_simulated_drive

    path.parent.mkdir(parents=True, exist_ok=True)
    return write_simulated_drive(path, scenario, seed=seed, duration_s=duration_s)


def _one_line_error(done, *words: str) -> str:
    assert done.returncode == 2, (done.returncode, done.stderr)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), done.stderr
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


# --- the pool: sized by the cores, one thread per library --------------------------------------------
def test_workers_beyond_the_cores_start_no_more_processes_than_cores():
    """``--workers 100000`` over 40 drives on 2 cores had started 17 processes and more when it
    was stopped: the pool followed the drives, not the cores."""
    from ionav_viz.api.engine import Engine, default_workers, run_each
    from tests.fleet_helpers import worker_pid

    engine = Engine(workers=100000)
    assert engine.pool_size(40) == min(default_workers(), 40)
    pids = {pid for _, pid in run_each(worker_pid, [str(i) for i in range(40)], engine)}
    assert 1 <= len(pids) <= default_workers(), pids
    assert os.getpid() not in pids  # asked for workers: they are processes of their own, even on one core
    assert Engine(workers=100000).describe() == f"{default_workers()} processes"


def test_workers_beyond_the_cores_is_said_in_one_note(tmp_path):
    from ionav_viz.api.engine import default_workers

    for i in range(3):
        _simulate(tmp_path / "drives" / f"V-n{i}.csv", seed=i, duration_s=40.0)
    done = run_cli("evaluate", str(tmp_path / "drives"), "--workers", "100000", "--estimators", "ins", "--json")
    assert done.returncode == 0, done.stderr
    notes = [line for line in done.stderr.splitlines() if line.startswith("note:")]
    assert notes == [f"note: --workers 100000: {default_workers()} worker process(es), the cores this process may use "
                     "(more would only share them)"], done.stderr
    assert json.loads(done.stdout)["timing"]["engine"] == f"{default_workers()} processes"
    quiet = run_cli("evaluate", str(tmp_path / "drives"), "--workers", "100000", "--estimators", "ins", "-q")
    assert quiet.returncode == 0 and "note:" not in quiet.stderr, quiet.stderr
    dry = run_cli("evaluate", str(tmp_path / "drives"), "--workers", "100000", "--dry-run", "-q")
    assert f"on {min(default_workers(), 3)} worker(s)" in dry.stdout, dry.stdout


def test_each_worker_runs_its_numerical_libraries_on_one_thread():
    from ionav_viz.api.engine import Engine, run_each
    from tests.fleet_helpers import thread_settings

    for _, settings in run_each(thread_settings, ["a", "b", "c"], Engine(workers=2)):
        assert settings.pop("torch", 1) == 1
        assert set(settings.values()) == {"1"}, settings


# --- a stop signal to the whole process group --------------------------------------------------------
@pytest.fixture(scope="module")
def long_drives(tmp_path_factory) -> Path:
    """Four simulated motorway drives of 10 minutes: each recording takes long enough to write that
    a signal finds the workers writing."""
    folder = tmp_path_factory.mktemp("long")
    for i in range(4):
        _simulate(folder / f"V-b{i}.csv", "motorway", seed=i, duration_s=600.0)
    return folder


def _group_alive(pgid: int) -> list[str]:
    """The processes of group ``pgid`` still running (zombies awaiting their reaper left out)."""
    alive = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            alive.append(entry)
    return alive


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_a_stop_signal_to_the_process_group_leaves_no_partial_recording(long_drives, tmp_path, signame):
    """SIGTERM to the process group during ``replay DIR --workers 2 -o recs`` (as systemd or a batch
    scheduler sends it) left ``.V-b1.rrd.*.tmp`` files of up to 14 MB: the workers had no handler
    and died where they were. Now each worker stops its drive as the command does (its temporary
    file removed), and the command exits 143 (130 for Ctrl-C's SIGINT)."""
    recs = tmp_path / "recs"
    proc = subprocess.Popen([sys.executable, "-m", "ionav_viz.cli", "replay", str(long_drives), "--workers", "2", "-o", str(recs),
                             "--estimators", "ins", "-q"], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        while proc.poll() is None and not any(size > 0 for size in _temporary_sizes(recs)):
            time.sleep(0.02)  # a recording is being written
        assert proc.poll() is None, proc.communicate()
        os.killpg(proc.pid, getattr(signal, signame))
        _, err = proc.communicate()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == {"SIGTERM": 143, "SIGINT": 130}[signame], err
    assert err.strip() in ("terminated (SIGTERM)", "interrupted"), err
    guard = time.monotonic() + HANG_S  # the workers end by themselves: polled, not timed (a hang guard only)
    while _group_alive(proc.pid) and time.monotonic() < guard:
        time.sleep(0.05)
    assert not _group_alive(proc.pid), "a process of the command's group was left running"
    left = sorted(p.name for p in recs.iterdir()) if recs.exists() else []
    assert not [name for name in left if not name.endswith(".rrd")], left
    from ionav_viz.viz.recording_info import read_recording_info

    for name in left:  # a recording there is complete (its drive finished before the signal)
        assert read_recording_info(recs / name).outages, name


def _temporary_sizes(folder: Path) -> list[int]:
    """The sizes of the temporary files in ``folder`` (none while it does not exist)."""
    sizes = []
    for path in folder.glob(".*.tmp") if folder.is_dir() else []:
        try:
            sizes.append(path.stat().st_size)
        except OSError:  # renamed into place meanwhile
            continue
    return sizes


# --- outputs inside the installed package --------------------------------------------------------------
def test_train_into_the_installed_package_refused_before_any_work(tmp_path):
    """``train DRIVE -o <package>/models/mine`` exited 0 and wrote a model inside the installed
    package: train checked its model directory with its own check (never the shipped model), not
    the one every other output goes through."""
    import shutil

    from ionav_viz.core.fileio import PACKAGE_DIR

    drive = _simulate(tmp_path / "V-t.csv", duration_s=60.0)
    target = PACKAGE_DIR / "mine-round6"
    try:
        done = run_cli("train", str(drive), "-o", str(target), "-q")
        _one_line_error(done, "-o", str(target), "installed ionav-viz package")
        assert not target.exists()
    finally:
        shutil.rmtree(target, ignore_errors=True)  # what the command wrote before the fix


def test_a_model_directory_beside_the_shipped_model_is_refused():
    """The shipped model's package (``ionav_viz.models``; the repository's ``models/`` in an editable
    install, ``<package>/models`` in a wheel) is the installed package too."""
    from ionav_viz.core.errors import InputError
    from ionav_viz.learning.idnn import check_model_dir, default_model_dir

    with pytest.raises(InputError, match="installed ionav-viz package"):
        check_model_dir(default_model_dir().parent / "mine")


# --- no output replaces another output of the run, or an input ------------------------------------------
@pytest.fixture(scope="module")
def same_names(tmp_path_factory) -> Path:
    """``a/V-x.csv`` (40 s), ``b/V-x.csv`` (50 s) and ``c/V-x-2.csv`` (60 s): two drives of one name,
    and a third whose own name is the one a numbered copy would take."""
    root = tmp_path_factory.mktemp("same-names")
    for folder, name, seconds in (("a", "V-x", 40.0), ("b", "V-x", 50.0), ("c", "V-x-2", 60.0)):
        _simulate(root / folder / f"{name}.csv", seed=int(seconds), duration_s=seconds)
    return root


@pytest.mark.parametrize("workers", ["1", "2"])
def test_two_drives_of_one_name_get_their_own_recordings(same_names, tmp_path, workers):
    """``replay a/V-x.csv b/V-x.csv c/V-x-2.csv --workers 2 -o out`` exited 0 with two recordings
    and printed ``out/V-x-2.rrd`` twice: b's numbered copy was c's own name, and whichever worker
    finished last kept the file. Names are now planned before any work, the same for every
    ``--workers``, and the renamed drive is said."""
    from ionav_viz.viz.recording_info import read_recording_info

    done = run_cli("replay", "a/V-x.csv", "b/V-x.csv", "c/V-x-2.csv", "--workers", workers, "-o", str(tmp_path / "out"),
                   "--estimators", "ins", "-q", cwd=same_names)
    assert done.returncode == 0, done.stderr
    printed = done.stdout.split()
    assert printed == [str(tmp_path / "out" / f"{name}.rrd") for name in ("V-x", "V-x-3", "V-x-2")], done.stdout
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["V-x-2.rrd", "V-x-3.rrd", "V-x.rrd"]
    assert [round(read_recording_info(Path(p)).end_s, -1) for p in printed] == [40.0, 50.0, 60.0]  # each drive its own file
    said = [line for line in done.stderr.splitlines() if line.startswith("warning:")]
    assert said == [f"warning: b/V-x.csv: recorded as {tmp_path / 'out' / 'V-x-3.rrd'}, as another output of this run has the "
                    "drive's name"], done.stderr


def test_recording_names_are_distinct_without_case_and_keep_each_drives_own_name(tmp_path):
    """The one place that names a fleet's outputs: every recording its own file (compared without
    case, as macOS and Windows compare them), a drive's own name kept by it, the rest numbered."""
    from ionav_viz.api.fleet import FleetDrive, plan_outputs

    cases = {
        ("a/V-x", "b/V-x", "c/V-x-2"): ["V-x", "V-x-3", "V-x-2"],
        ("c/V-x-2", "a/V-x", "b/V-x", "d/V-x-2"): ["V-x-2", "V-x", "V-x-3", "V-x-2-2"],
        ("a/V-X", "b/V-x", "c/v-x"): ["V-X", "V-x-2", "v-x-3"],
        ("a/r", "b/r", "c/r", "d/r-3"): ["r", "r-2", "r-4", "r-3"],
    }
    for stems, expected in cases.items():
        items = [FleetDrive(f"{stem}.csv") for stem in stems]
        planned = plan_outputs(items, folder=tmp_path / "out")
        assert [Path(r).stem for r in planned.recordings] == expected, stems
        assert planned.recordings == plan_outputs(items, folder=tmp_path / "out").recordings  # decided by the order given alone
    taken = plan_outputs([FleetDrive("a/Fleet.csv")], folder=tmp_path / "out", fleet_rrd=tmp_path / "out" / "fleet.rrd")
    assert [Path(r).name for r in taken.recordings] == ["Fleet-2.rrd"]  # the overview's name, but for case: taken too


def test_the_fleet_overview_onto_a_drives_recording_refused_before_any_work(same_names, tmp_path):
    """``replay a/V-x.csv a/V-y.csv -o out --fleet-rrd out/V-x.rrd`` replaced V-x's recording with the
    fleet overview, and still named it as V-x's."""
    done = run_cli("replay", "a/V-x.csv", "c/V-x-2.csv", "-o", str(tmp_path / "out"), "--fleet-rrd", str(tmp_path / "out" / "V-x.rrd"),
                   "--estimators", "ins", "-q", cwd=same_names)
    _one_line_error(done, "--fleet-rrd", "V-x.rrd", "a/V-x.csv")
    assert not (tmp_path / "out").exists()
    (tmp_path / "out").mkdir()
    again = run_cli("replay", "a/V-x.csv", "c/V-x-2.csv", "-o", "out", "--fleet-rrd", "out/../out/V-x-2.rrd", "--estimators", "ins", "-q",
                    cwd=tmp_path)
    assert again.returncode == 2  # the drive paths are not found from here: refused before them all the same
    _one_line_error(again, "--fleet-rrd")


def test_outputs_onto_an_input_list_refused_before_any_work(same_names, tmp_path):
    """A list of drives is an input: neither the overview nor a recording may replace it."""
    (tmp_path / "out").mkdir()
    listing = tmp_path / "out" / "V-x.rrd"
    listing.write_text(f"{same_names / 'a' / 'V-x.csv'}\n")
    done = run_cli("replay", f"@{listing}", str(same_names / "c" / "V-x-2.csv"), "-o", str(tmp_path / "out"), "-q")
    _one_line_error(done, "-o", "V-x.rrd", "input")
    overview = run_cli("evaluate", f"@{listing}", "--fleet-rrd", str(listing), "-q")
    _one_line_error(overview, "--fleet-rrd", "input")
    assert listing.read_text() == f"{same_names / 'a' / 'V-x.csv'}\n"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["V-x.rrd"]


# --- a clock offset far below the sample period moves nothing -------------------------------------------
@pytest.fixture(scope="module")
def offset_logs(tmp_path_factory) -> dict[str, Path]:
    """A simulated 2 min MEMS log (100 Hz IMU, 10 Hz GNSS, its first IMU sample on the first fix's
    stamp) and a converted IO-VNBD drive (IMU and fixes on the same stamps)."""
    import ionav_viz as iv
    from ionav_viz.sim.imu import IMU_GRADES, write_imu_log

    folder = tmp_path_factory.mktemp("offsets")
    mems = write_imu_log(folder / "mems.mcap", "roundabout", 5, 120.0, IMU_GRADES["mems"])
    converted = folder / "converted.mcap"
    iv.convert(_simulate(folder / "V-c.csv", seed=5, duration_s=90.0), converted)
    return {"mems": mems, "converted": converted}


def _sequences(log: Path, offset: str) -> list[dict]:
    from ionav_viz.sim.imu import SIM_TRUTH_TOPIC

    truth = ["--truth-topic", SIM_TRUTH_TOPIC] if log.name == "mems.mcap" else []
    done = run_cli("evaluate", str(log), *truth, "--imu-time-offset", offset, "--estimators", "ins", "--json")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)["sequences"]


@pytest.mark.parametrize("log", ["mems", "converted"])
def test_a_nanosecond_of_imu_time_offset_gives_the_results_of_none(offset_logs, log):
    """``--imu-time-offset 1e-9`` moved the INS DR's mean CRSE by 2 % (one outage by 9.8 %): the
    grid's first time was the first fix's stamp, so any positive offset put it outside the fixes'
    span, the drive lost its first sample and every window moved by a sample; and a log whose IMU
    and fixes share their stamps was binned another way as soon as any offset was given."""
    from tests.conftest import assert_same_sequences

    none = _sequences(offset_logs[log], "0")
    for tiny in ("1e-9", "-1e-9"):
        assert_same_sequences(none, _sequences(offset_logs[log], tiny), ["ins"], rel=1e-6, abs=1e-6)
    real = _sequences(offset_logs[log], "0.05")  # half a grid step: the samples do move against the fixes
    same_outages = [(a["ins"]["final_position_error_m"], b["ins"]["final_position_error_m"])
                    for a, b in zip(none, real) if a["start_s"] == b["start_s"]]
    assert same_outages and any(abs(a - b) > 1e-3 for a, b in same_outages), same_outages
