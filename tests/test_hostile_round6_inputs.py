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
import os
import socket
import threading
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv

from .conftest import one_line_error as _one_line_error
from .conftest import run_cli, run_cli_process
from .test_hostile_files import fifo_unblocked


@pytest.fixture(scope="module")
def drives(tmp_path_factory) -> Path:
    """A folder of two simulated 60 s roundabout drives, ``V-a.csv`` and ``V-b.csv``."""
    from ionav_viz.sim.simulate import write_simulated_drive

    folder = tmp_path_factory.mktemp("drives6")
    for name, seed in (("V-a", 1), ("V-b", 2)):
        write_simulated_drive(folder / f"{name}.csv", "roundabout", seed=seed, duration_s=60)
    return folder


def _dry_run(*args: str, cwd: Path) -> list[str]:
    done = run_cli("evaluate", *args, "--dry-run", "--json", cwd=cwd)
    assert done.returncode == 0, done.stderr
    return [d["drive"] for d in json.loads(done.stdout)["drives"]]


# --- 1. every way of naming drives is bounded ---------------------------------------------------
def test_a_list_file_that_is_a_pipe_or_a_device_is_refused(tmp_path):
    """``@fifo.txt`` blocked forever on the open; ``@/dev/zero`` read 2.7 GB, then a MemoryError
    (``/dev/null`` here, which was read as an empty list: "no drive to evaluate")."""
    with fifo_unblocked(tmp_path / "fifo.txt"):
        _one_line_error(run_cli("evaluate", "@fifo.txt", "--dry-run", cwd=tmp_path), "@fifo.txt", "named pipe")
    _one_line_error(run_cli("evaluate", "@/dev/null", "--dry-run", cwd=tmp_path), "@/dev/null", "character device")


def test_a_list_file_over_the_limit_says_the_limit(tmp_path):
    """A list is read with a size limit, said when exceeded (a sparse file: nothing is read)."""
    from ionav_viz.api.fleet import MAX_LIST_BYTES

    with open(tmp_path / "huge.txt", "wb") as f:
        f.truncate(MAX_LIST_BYTES + 1)
    done = run_cli("evaluate", "@huge.txt", "--dry-run", cwd=tmp_path)
    _one_line_error(done, "@huge.txt", f"at most {MAX_LIST_BYTES}")


def test_a_list_that_includes_itself_is_read_once(tmp_path, drives):
    """A list naming itself (or another list twice) was read again at every level, until "nested
    more than 4 deep" (three such lines: 3^5 reads; a thousand: a hang); each list is read once now."""
    (tmp_path / "self.txt").write_text(f"@self.txt\n@self.txt\n{drives / 'V-a.csv'}\n@self.txt\n")
    assert _dry_run("@self.txt", cwd=tmp_path) == [str(drives / "V-a.csv")]


def test_a_recursive_glob_does_not_follow_a_link_loop(tmp_path, drives):
    """``'logs/**/*.csv'`` over ``logs/a -> .`` followed the link 40 levels deep (and two such links
    made it endless): '**' does not enter links to folders, as bash's globstar."""
    logs = tmp_path / "logs"
    (logs / "sub").mkdir(parents=True)
    os.link(drives / "V-a.csv", logs / "V-a.csv")
    os.link(drives / "V-b.csv", logs / "sub" / "V-b.csv")
    (logs / "a").symlink_to(".")
    (logs / "sub" / "up").symlink_to("..")
    assert _dry_run("logs/**/*.csv", cwd=tmp_path) == ["logs/V-a.csv", "logs/sub/V-b.csv"]
    assert _dry_run("logs", cwd=tmp_path) == ["logs/V-a.csv"]  # a folder: its own drives, not those below


def test_a_hard_link_and_its_file_are_one_drive(tmp_path, drives):
    """Drives are compared by the file they reach: a hard link was a second drive."""
    os.link(drives / "V-a.csv", tmp_path / "same.csv")
    (tmp_path / "soft.csv").symlink_to(drives / "V-a.csv")
    assert _dry_run(str(drives / "V-a.csv"), "same.csv", "soft.csv", str(drives / "V-b.csv"), cwd=tmp_path) == [
        str(drives / "V-a.csv"), str(drives / "V-b.csv")]


# --- 2. cross-validate --folds ------------------------------------------------------------------
def test_cross_validate_folds_beyond_the_drive_are_refused_before_any_allocation(tmp_path):
    """``--folds 99999999999999999999`` on one drive built the blocks' edges first (2.3 GB, then a
    MemoryError); the count is checked against what the drive holds first, in one line (the device
    line came before it, a second line)."""
    from ionav_viz.sim.simulate import write_simulated_drive

    drive = write_simulated_drive(tmp_path / "V-long.csv", "roundabout", seed=3, duration_s=200)
    done = run_cli("cross-validate", str(drive), "--folds", "1000", cwd=tmp_path)
    line = _one_line_error(done, "--folds", "at most 5 folds")
    assert "1000 time blocks" in line
    (tmp_path / "out").mkdir()
    done = run_cli("cross-validate", str(drive), "--folds", "99999999999999999999", "-o", "out", cwd=tmp_path)
    _one_line_error(done, "--folds")
    assert list((tmp_path / "out").iterdir()) == []


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
            _fleet([str(drives / "V-a.csv")], estimators=["ins"], cluster=address)
        assert err.value.param == "cluster"


# --- 4. the fleet API's arguments ---------------------------------------------------------------
def _fleet(drives, estimators=None, placement=None, progress=None, workers=1, cluster=None, runs=(), replay_options=""):
    """A fleet through the API: ``iv.evaluate`` on an engine, its arguments as the fleet took them."""
    return iv.evaluate(drives, None, placement, estimators, progress=progress, runs=runs,
                       engine=iv.Engine(workers, cluster), fleet=iv.FleetOptions(replay_options=replay_options))


@pytest.mark.parametrize(("kwargs", "param"), [
    ({"cluster": 5}, "cluster"), ({"cluster": ["local"]}, "cluster"), ({"cluster": "tcp://[::1"}, "cluster"),
    ({"drives": None}, "drives"), ({"drives": 5}, "drives"), ({"drives": ["x", 5]}, "drives"), ({"runs": 5}, "runs"),
    ({"placement": 5}, "placement"), ({"estimators": 5}, "estimators"), ({"progress": 5}, "progress"),
    ({"replay_options": 5}, "replay_options"),
])
def test_the_fleet_api_names_a_bad_argument(drives, kwargs, param):
    """Each was a TypeError (or an AttributeError) naming no argument; now an InputError naming it."""
    call = {"drives": [str(drives / "V-a.csv")], "estimators": ["ins"], "workers": 1, **kwargs}
    with pytest.raises(iv.InputError) as err:
        _fleet(**call)
    assert err.value.param == param, err.value


def test_one_path_given_to_the_fleet_api_is_one_drive_or_folder(drives, tmp_path):
    """``evaluate_fleet("/path/fleet")`` iterated the string's characters into 17 failed "drives"."""
    report = _fleet(str(drives), estimators=["ins"], workers=1)
    assert [Path(t.spec).name for t in report.drives] == ["V-a.csv", "V-b.csv"] and not report.failures
    from ionav_viz.api.fleet import plan_fleet

    assert [Path(d.spec).name for d in plan_fleet(drives / "V-b.csv").drives] == ["V-b.csv"]
    for call, param in ((lambda: iv.replay(str(drives), output=5, engine=iv.Engine(1)), "output"),
                        (lambda: iv.replay(None, engine=iv.Engine(1)), "drives"),
                        (lambda: iv.write_fleet_recording({"drives": []}, tmp_path / "f.rrd"), "report")):
        with pytest.raises(iv.InputError) as err:
            call()
        assert err.value.param == param
    assert list(tmp_path.iterdir()) == []


# --- 5. figures of an inconsistent fleet report -------------------------------------------------
@pytest.fixture(scope="module")
def fleet_json(drives) -> dict:
    done = run_cli("evaluate", str(drives / "V-a.csv"), str(drives / "V-b.csv"), "--workers", "1",
                   "--estimators", "ins", "--json", "-q")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_figures_refuse_a_fleet_report_whose_pooled_entry_is_a_number(tmp_path, fleet_json):
    """A pooled entry that is a number was an AttributeError in the CDF's legend."""
    (tmp_path / "r.json").write_text(json.dumps({**fleet_json, "pooled": {**fleet_json["pooled"], "ins": 5}}))
    _one_line_error(run_cli("figures", "r.json", "-o", "figs", cwd=tmp_path), "r.json", "pooled.ins")
    assert not (tmp_path / "figs").exists()


def test_figures_refuse_a_fleet_report_whose_outages_name_drives_it_does_not_list(tmp_path, fleet_json):
    """Outages of a drive the report does not list were drawn as a drive of the box plot."""
    (tmp_path / "r.json").write_text(json.dumps({**fleet_json, "drives": fleet_json["drives"][:1]}))
    done = run_cli("figures", "r.json", "-o", "figs", cwd=tmp_path)
    _one_line_error(done, "r.json", "'V-b' is not among the report's drives")
    assert not (tmp_path / "figs").exists()


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


# --- 7. a covariance beyond any position --------------------------------------------------------
def test_a_huge_covariance_is_refused_without_numpy_warnings(tmp_path):
    """Covariance columns of 1e300 m^2 printed numpy's overflow warnings with their source lines and
    were scored; refused at the reader now, naming the pose."""
    assert run_cli("outage-log", "roundabout", "--at", "20s,60s", "-o", str(tmp_path / "cut.mcap")).returncode == 0
    drive = iv.load_drive("roundabout")
    stamps = np.asarray(drive.stamp_s(drive.t_s))
    n = len(stamps)
    huge = np.full(n, 1e300)
    np.savetxt(tmp_path / "huge.csv", np.column_stack([stamps, drive.lat_deg, drive.lon_deg, huge, np.zeros(n), huge]),
               delimiter=",", header="time_s,lat_deg,lon_deg,cov_ee_m2,cov_en_m2,cov_nn_m2", comments="", fmt="%.9g")
    done = run_cli("evaluate", "roundabout", "--plan", str(tmp_path / "cut.outages.json"), "--estimators", "ins",
                   "--external", "x=huge.csv", cwd=tmp_path)
    _one_line_error(done, "--external", "huge.csv: pose 1", "beyond any position")
    assert "RuntimeWarning" not in done.stderr


# --- 9. events --quality with a span ------------------------------------------------------------
@pytest.mark.parametrize("option", [("--span", "0s:5s"), ("--yaw-sign", "cw")])
def test_events_quality_refuses_reading_options_it_would_ignore(option):
    """``events --quality --span 0s:5s`` measured the detectors on the whole bundled drives,
    ignoring the span silently: --quality reads them whole and as they are, so it refuses them."""
    _one_line_error(run_cli("events", "--quality", *option), option[0], "bundled synthetic drives whole")


# --- 10. a truncated recording ------------------------------------------------------------------
def test_screenshot_of_a_truncated_recording_is_our_one_line_only(tmp_path, drives):
    """Rerun's own "no footer/manifest" RerunWarning and its source line came above our error (a
    fresh process: in this one, pytest records the warnings instead of letting them reach stderr)."""
    done = run_cli("replay", str(drives / "V-a.csv"), "--estimators", "ins", "-q", "-o", str(tmp_path / "r.rrd"))
    assert done.returncode == 0, done.stderr
    whole = (tmp_path / "r.rrd").read_bytes()
    (tmp_path / "cut.rrd").write_bytes(whole[: len(whole) // 4])
    done = run_cli_process("screenshot", "cut.rrd", "-o", "s.png", cwd=tmp_path)
    _one_line_error(done, "cut.rrd", "not a readable Rerun recording")
    assert not (tmp_path / "s.png").exists()
