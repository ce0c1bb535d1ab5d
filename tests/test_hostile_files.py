"""Issue 45: hostile files on the commands that read and write them (outage-log, plans, external
trajectories, exports, figures, convert, train, screenshots).

Bad input -> exit code 2, one line on stderr starting ``error:`` that names the file, row or
field with a hint, no traceback, and nothing written. Each case states the input and why it
failed before.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import threading
from pathlib import Path

import numpy as np
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
    (tmp_path / "figs" / "drift.svg").write_text("{}")
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
        (("figures", "figs/drift.svg", "-o", "figs"), "figs/drift.svg: is the input figs/drift.svg"),  # a figure it replaces
        (("figures", "figs/report.json", "-o", "figs/report.json"), "-o: figs/report.json: "),  # the input, or not a folder
        (("screenshot", "a.rrd", "-o", "shot.png"), "shot.png: is another name (a hard link) of the input a.rrd"),
    ]
    for args, fragment in cases:
        assert_refused(run_cli(*args, cwd=tmp_path), fragment)
        assert snapshot(tmp_path) == before, args  # nothing written, nothing replaced


# --- 2. special files are refused before they are opened -----------------------------------------
@contextlib.contextmanager
def fifo_unblocked(path: Path):
    """A named pipe at ``path``; if a reader opens it (the defect: it blocked forever), a writer
    opens and closes it at once, so the reader sees an empty file and the test fails instead of hanging."""
    os.mkfifo(path)
    stop = threading.Event()

    def unblock() -> None:
        while not stop.wait(0.05):
            try:
                fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
            except OSError:  # no reader (ENXIO): nothing is blocked
                continue
            os.close(fd)

    thread = threading.Thread(target=unblock, daemon=True)
    thread.start()
    try:
        yield path
    finally:
        stop.set()
        thread.join()


def test_special_files_are_refused_before_opening(tmp_path, short_csv, outaged):
    """Every input path a user gives (drive, plan, external trajectory, model, plug-in file,
    recording, manifest, figures' report) that is a named pipe or a device is one line naming it,
    before it is opened: an external trajectory that was a named pipe hung forever, a manifest too; a drive,
    model or plug-in file was 'no such file'."""
    _, plan = outaged
    (tmp_path / "model").mkdir()
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: 9\n")
    pipes = {name: tmp_path / name for name in ("pipe.csv", "pipe.json", "pipe.py", "pipe.rrd", "pipe.tsv", "model/metadata.json", "bag/bag_0.db3")}
    with contextlib.ExitStack() as stack:
        for p in pipes.values():
            stack.enter_context(fifo_unblocked(p))
        before = snapshot(tmp_path)
        cases = [
            (("evaluate", "pipe.csv", "--no-idnn"), "pipe.csv: is a named pipe (FIFO), not a regular file"),
            (("evaluate", "/dev/zero", "--no-idnn"), "/dev/zero: is a character device"),
            (("evaluate", str(short_csv), "--no-idnn", "--plan", "pipe.json"), "pipe.json: is a named pipe (FIFO)"),
            (("evaluate", str(short_csv), "--no-idnn", "--plan", str(plan), "--external", "x=pipe.csv"), "pipe.csv: is a named pipe (FIFO)"),
            (("evaluate", str(short_csv), "--no-idnn", "--plan", str(plan), "--external", "x=/dev/zero:/fix"), "/dev/zero: is a character device"),
            (("evaluate", str(short_csv), "--model", "model"), "model/metadata.json: is a named pipe (FIFO)"),
            (("evaluate", str(short_csv), "--estimator", "pipe.py:Mine"), "pipe.py: is a named pipe (FIFO)"),
            (("screenshot", "pipe.rrd", "-o", "out.png"), "pipe.rrd: is a named pipe (FIFO)"),
            (("list", "--manifest", "pipe.tsv"), "pipe.tsv: is a named pipe (FIFO)"),
            (("figures", "pipe.json", "-o", "figs"), "pipe.json: is a named pipe (FIFO)"),
            (("evaluate", "bag", "--no-idnn"), "bag/bag_0.db3: is a named pipe (FIFO)"),  # a file the reader opens in a folder
        ]
        for args, fragment in cases:
            assert_refused(run_cli(*args, cwd=tmp_path), fragment)
        assert snapshot(tmp_path) == before


# --- 3. JSON readers bound depth and size; 4. plans are checked outage by outage ----------------
def plan_with(folder: Path, plan: Path, name: str, change) -> Path:
    """``plan`` as JSON, changed by ``change(body)`` (in place), written to ``folder/name``."""
    body = json.loads(plan.read_text())
    change(body)
    out = folder / name
    out.write_text(json.dumps(body))
    return out


def test_plan_files_are_bounded_strict_json(tmp_path, short_csv):
    """A plan of nested brackets was a RecursionError traceback; one over the size limit, one with
    NaN, a number that overflows to infinity or a key given twice were read as given (JSON keeps the
    last of two keys). Each is now one line naming the file."""
    from ionav_viz.core.fileio import read_json_bounded
    from ionav_viz.experiment.plan_file import PLAN_MAX_BYTES

    (tmp_path / "deep.json").write_text("[" * 200_000 + "]" * 200_000)
    with open(tmp_path / "huge.json", "wb") as f:  # sparse: its size alone refuses it
        f.truncate(PLAN_MAX_BYTES + 1)
    (tmp_path / "nan.json").write_text('{"format": "ionav-viz outage plan", "version": 1, "outage_s": NaN}')
    (tmp_path / "inf.json").write_text('{"format": "ionav-viz outage plan", "version": 1, "outage_s": 1e999}')
    (tmp_path / "twice.json").write_text('{"format": "ionav-viz outage plan", "format": "x"}')
    (tmp_path / "binary.json").write_bytes(b"\xff\xfe{")
    before = snapshot(tmp_path)
    for name, fragment in [("deep.json", "deep.json: nested 200000 levels deep; an outage plan nests at most 16"),
                           ("huge.json", f"huge.json: {PLAN_MAX_BYTES + 1} bytes is too large for an outage plan"),
                           ("nan.json", "nan.json: not usable JSON (NaN is not a number JSON allows)"),
                           ("inf.json", "inf.json: not usable JSON (1e999 overflows to infinity)"),
                           ("twice.json", "twice.json: not usable JSON (key 'format' appears twice in one object)"),
                           ("binary.json", "binary.json: not UTF-8 text")]:
        line = assert_refused(run_cli("replay", str(short_csv), "--no-idnn", "--plan", name, "-o", "r.rrd", cwd=tmp_path), fragment)
        assert line.startswith("error: --plan: "), line
    assert snapshot(tmp_path) == before
    # the reader itself, as the figures command and the model loader use it
    (tmp_path / "ok.json").write_text('{"a": "[[[[[[[[", "b": [1, [2, {"c": 3.5}]]}')
    assert read_json_bounded(tmp_path / "ok.json", param="x", max_depth=4) == {"a": "[[[[[[[[", "b": [1, [2, {"c": 3.5}]]}
    with pytest.raises(iv.InputError, match="nested 4 levels deep"):
        read_json_bounded(tmp_path / "ok.json", param="x", max_depth=3)
    with pytest.raises(iv.InputError, match="too large"):
        read_json_bounded(tmp_path / "ok.json", param="x", max_bytes=10)
    # a model's metadata, written by json.dumps, may hold NaN (its fields are checked one by one)
    assert np.isnan(read_json_bounded(tmp_path / "nan.json", param="model", allow_nan=True)["outage_s"])


def test_model_metadata_nested_deep_is_one_line(tmp_path, short_csv):
    """A model whose metadata.json is nested brackets was a RecursionError traceback."""
    (tmp_path / "model").mkdir()
    (tmp_path / "model" / "metadata.json").write_text("[" * 100_000)
    assert_refused(run_cli("evaluate", str(short_csv), "--model", "model", cwd=tmp_path), "metadata.json: nested 100000 levels deep")


def test_hostile_plans_name_the_outage_and_the_field(tmp_path, short_csv, outaged):
    """A plan whose outage ends before it starts was accepted, as were negative times, a repeated
    or overlapping outage, stamps that disagree with the drive times, and outages outside the
    drive (those were 'does not fit this drive's windows', with no word of units). Each is one line
    naming the outage and the field."""
    _, plan = outaged
    first = json.loads(plan.read_text())["outages"][0]

    def outage(i: int, **values):
        return lambda body: body["outages"][i].update(values)

    def ms(body):  # a plan written in milliseconds by hand
        body["outages"] = [{k: v * 1000 if "stamp" in k else v for k, v in o.items()} for o in body["outages"][:1]]
        body["outages"][0]["end_stamp_s"] = body["outages"][0]["start_stamp_s"] + 10

    cases = [
        ("ends-early.json", outage(0, end_stamp_s=first["start_stamp_s"] - 5),
         "outage 1: field 'end_stamp_s' (36940.405 s) is not after its start_stamp_s (36945.405 s)"),
        ("end-s.json", outage(1, end_s=45.0), "outage 2: field 'end_s' (45.0 s) is 5 s after its start_s"),
        ("negative.json", outage(0, start_s=-20.0, end_s=-10.0), "outage 1: field 'start_s' is negative (-20.0 s)"),
        ("nan.json", outage(1, start_s=None), "outage 2: field 'start_s' is None, not a finite number of seconds"),
        ("twice.json", lambda b: b["outages"].append(dict(b["outages"][1])), "outage 3: field 'start_s' (40.0 s) repeats outage 2"),
        ("overlap.json", lambda b: b["outages"].append({"start_stamp_s": first["start_stamp_s"] + 25, "start_s": 45.0}),
         "outage 3: field 'start_s' (45.0 s) is inside outage 2 (40.0-50.0 s)"),
        ("order.json", lambda b: b["outages"].reverse(), "outage 2: field 'start_s' (20.0 s) is before outage 1's"),
        ("clock.json", outage(1, start_stamp_s=first["start_stamp_s"] + 3600, end_stamp_s=first["start_stamp_s"] + 3610),
         "outage 2: field 'start_stamp_s' (40545.405 s) and start_s (40.0 s) disagree with outage 1's"),
        ("none.json", lambda b: b.update(outages=[]), "field 'outages' holds no outage"),
        ("version.json", lambda b: b.update(version=True), "field 'version' is True"),
        ("half.json", lambda b: b.update(outage_s=10.5), "field 'outage_s' (10.5) is not a whole number of seconds"),
        ("outside.json", lambda b: b.update(outages=[{k: v + 3600 for k, v in first.items()}]),
         "outage 1: field 'start_stamp_s' (40545.405 s) puts it at 3620.000-3630.000 s, outside the drive V-short (0-"),
        ("ms.json", ms, "its stamps look like milliseconds"),
    ]
    for name, change, fragment in cases:
        bad = plan_with(tmp_path, plan, name, change)
        line = assert_refused(run_cli("evaluate", str(short_csv), "--no-idnn", "--plan", str(bad), cwd=tmp_path), fragment, str(bad))
        assert line.startswith("error: --plan: "), line
    assert not list(tmp_path.glob("*.rrd"))


# --- 5. external trajectories ----------------------------------------------------------------------
def trajectory_csv(path: Path, stamps, lat, lon) -> Path:
    np.savetxt(path, np.column_stack([stamps, lat, lon]), delimiter=",", header="time_s,lat_deg,lon_deg", comments="", fmt="%.9f")
    return path


def test_external_poses_sharing_a_stamp(tmp_path, short_csv, outaged):
    """The same stamp twice with positions 1 km apart was accepted silently (the first kept). Now a
    conflicting duplicate is refused naming both poses; an identical one is kept once, with a warning."""
    _, plan = outaged
    drive = iv.load_drive(short_csv)
    stamps, lat, lon = drive.stamp_s(drive.t_s), drive.lat_deg.copy(), drive.lon_deg.copy()
    k = 100
    conflict = trajectory_csv(tmp_path / "conflict.csv", np.insert(stamps, k + 1, stamps[k]), np.insert(lat, k + 1, lat[k] + 1000 / 111_195),
                              np.insert(lon, k + 1, lon[k]))
    line = assert_refused(run_cli("evaluate", str(short_csv), "--no-idnn", "--plan", str(plan), "--external", f"x={conflict}", cwd=tmp_path),
                          f"conflict.csv: poses {k + 1} and {k + 2} share the stamp {float(stamps[k])!r} s and lie 1000 m apart")
    assert line.startswith("error: --external: ") and "np." not in line, line
    same = trajectory_csv(tmp_path / "same.csv", np.insert(stamps, k + 1, stamps[k]), np.insert(lat, k + 1, lat[k]), np.insert(lon, k + 1, lon[k]))
    proc = run_cli("evaluate", str(short_csv), "--no-idnn", "--plan", str(plan), "--external", f"x={same}", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "warning: " + str(same) + ": 1 pose(s) repeat the stamp and position of another; each is kept once" in proc.stderr
    assert len(json.loads(proc.stdout)["sequences"]) == 2


def test_external_stamped_in_milliseconds_says_so(tmp_path, short_csv, outaged):
    """A trajectory stamped in milliseconds was 'does not cover outage 1' with no word of units."""
    _, plan = outaged
    drive = iv.load_drive(short_csv)
    ms = trajectory_csv(tmp_path / "ms.csv", drive.stamp_s(drive.t_s) * 1000, drive.lat_deg, drive.lon_deg)
    relative = trajectory_csv(tmp_path / "rel.csv", drive.t_s, drive.lat_deg, drive.lon_deg)
    for path, fragment in [(ms, "its stamps look like milliseconds"), (relative, "its stamps look like seconds since the drive's start")]:
        assert_refused(run_cli("evaluate", str(short_csv), "--no-idnn", "--plan", str(plan), "--external", f"x={path}", cwd=tmp_path),
                       "does not cover outage 1", fragment)


def test_external_written_only_inside_the_gaps_starts_from_the_start_fix(tmp_path, short_csv, outaged):
    """An estimator that writes poses only inside the outages, the first one output step (0.1 s)
    after the start, was refused as 'does not cover outage 1'. It now starts from the plan's start
    fix: here poses 5 m north of the truth score a final error of 5 m, in both outages."""
    _, plan = outaged
    drive = iv.load_drive(short_csv)
    starts = [o["start_stamp_s"] for o in json.loads(plan.read_text())["outages"]]
    t = np.concatenate([s + np.arange(1, 101) / 10 for s in starts])
    stamps = drive.stamp_s(drive.t_s)
    inside = trajectory_csv(tmp_path / "gaps.csv", t, np.interp(t, stamps, drive.lat_deg) + 5 / 111_250, np.interp(t, stamps, drive.lon_deg))
    proc = run_cli("evaluate", str(short_csv), "--estimators", "ins", "--plan", str(plan), "--external", f"gaps={inside}", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    sequences = json.loads(proc.stdout)["sequences"]
    assert len(sequences) == 2
    for s in sequences:
        assert s["gaps"]["final_position_error_m"] == pytest.approx(5.0, abs=0.1), s["gaps"]


def test_a_json_message_nested_deep_is_one_line(tmp_path, monkeypatch):
    """A JSON-encoded MCAP message of brackets nested 100,000 deep was a RecursionError traceback."""
    from . import mcap_fixtures

    real_dumps = json.dumps
    monkeypatch.setattr(mcap_fixtures.json, "dumps", lambda obj, **kw: "[" * 100_000 + "]" * 100_000 if obj == "deep" else real_dumps(obj, **kw))
    log = mcap_fixtures.write_json(tmp_path / "deep.mcap", tamper=lambda kind, i, msg: ["deep"] if kind == "imu" and i == 5 else [msg])
    monkeypatch.undo()
    assert_refused(run_cli("evaluate", str(log), "--no-idnn", cwd=tmp_path), "deep.mcap: topic /imu: message at log time", "nests too deep")


# --- 6. outage-log -q; 7. the fix at an outage's start stays ------------------------------------
def test_outage_log_takes_quiet(tmp_path, short_csv):
    """Every command that places outages takes -q; outage-log did not ('No such option: -q')."""
    proc = run_cli("outage-log", str(short_csv), "--at", "20s", "-q", "-o", "cut.mcap", cwd=tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert proc.stdout.split() == ["cut.mcap", "cut.outages.json"]


def _fix_stamps(path: Path) -> np.ndarray:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for _, _, _, m in reader.iter_decoded_messages(topics=["/gps/fix"])])


def test_the_fix_at_each_outages_start_stays(tmp_path):
    """The plan says the fix at an outage's start stays in the outaged log. IO-VNBD stamps jitter
    by a millisecond around the 10 Hz grid the outages start on: the first outage of
    ``outage-log roundabout --every 30s`` starts at 60653.34 and its fix is stamped 60653.341, which
    went (the second's, 60683.339, stayed). Both stay now; the next fix after each start is gone."""
    drive = iv.load_drive("roundabout")
    proc = run_cli("outage-log", "roundabout", "--every", "30s", "--warm-up", "0s", "-q", "-o", "x.mcap", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    plan = json.loads((tmp_path / "x.outages.json").read_text())
    fixes = _fix_stamps(tmp_path / "x.mcap")
    source = np.asarray(drive.stamp_s(drive.t_s))
    for o in plan["outages"][:2]:
        start = o["start_stamp_s"]
        at_start = source[np.argmin(np.abs(source - start))]  # the source's fix at the start: 60653.341, then 60683.339
        assert abs(at_start - start) < 0.002
        assert np.min(np.abs(fixes - at_start)) < 1e-6, (start, at_start)  # kept
        assert not np.any((fixes > at_start + 1e-6) & (fixes <= o["end_stamp_s"] - 0.05)), start  # the rest of the outage is gone
    assert abs(source[np.argmin(np.abs(source - plan["outages"][0]["start_stamp_s"]))] - 60653.341) < 1e-6  # the case the issue names


# --- 8. messages show numbers, not numpy reprs -----------------------------------------------------
def test_messages_show_plain_numbers(tmp_path, short_csv, outaged):
    """A trajectory with a NaN position said 'stamp np.float64(60648.34)'. Every InputError,
    ToolFailure and logged warning now shows numpy scalars as plain numbers."""
    import logging

    from ionav_viz.core.errors import plain
    from ionav_viz.core.warnings_log import collecting_warnings

    _, plan = outaged
    drive = iv.load_drive(short_csv)
    lat = drive.lat_deg.copy()
    lat[7] = np.nan
    nan = trajectory_csv(tmp_path / "nan.csv", drive.stamp_s(drive.t_s), lat, drive.lon_deg)
    stamp = float(drive.stamp_s(drive.t_s[7]))
    line = assert_refused(run_cli("evaluate", str(short_csv), "--no-idnn", "--plan", str(plan), "--external", f"x={nan}", cwd=tmp_path),
                          f"pose 8 (stamp {stamp!r}): not finite")
    assert "np." not in line
    x = np.float64(60648.34)
    assert str(iv.InputError(f"stamp {x!r} of {(x, np.int64(3))}", f"try {np.float32(0.5)!r}")) == "stamp 60648.34 of (60648.34, 3) (hint: try 0.5)"
    assert str(iv.ToolFailure(f"at {x!r}")) == "at 60648.34"
    assert plain((x, [np.int64(2)], np.array([1.5]))) == (60648.34, [2], [1.5])
    with collecting_warnings() as warned:
        logging.getLogger("ionav_viz").warning("stamps %s", (x, np.float64(1.25)))
    assert warned == ["stamps (60648.34, 1.25)"]


def test_external_positions_in_other_units_say_so(tmp_path_factory, short_csv, outaged):
    """Positions in radians, latitude and longitude swapped, or local metres in kilometres were
    scored as they were (errors of thousands of km, no word of why). A pose more than 1 km from the
    start fix at an outage's start is refused, naming the likely unit."""
    from ionav_viz.core.geo import local_en_m
    from ionav_viz.sim.simulate import write_simulated_drive

    tmp_path = tmp_path_factory.mktemp("units")
    _, plan = outaged
    drive = iv.load_drive(short_csv)
    stamps = drive.stamp_s(drive.t_s)
    for path, fragment in [(trajectory_csv(tmp_path / "rad.csv", stamps, np.radians(drive.lat_deg), np.radians(drive.lon_deg)), "look like radians"),
                           (trajectory_csv(tmp_path / "swap.csv", stamps, drive.lon_deg, drive.lat_deg), "look like longitude first")]:
        assert_refused(run_cli("evaluate", str(short_csv), "--no-idnn", "--plan", str(plan), "--external", f"x={path}", cwd=tmp_path),
                       "at outage 1's start its pose lies", fragment)
    # kilometres show only where the outage starts over 1 km from the first fix: a motorway, 90 s in
    motorway = write_simulated_drive(tmp_path / "V-motorway.csv", "motorway", seed=2, duration_s=120)
    cut = iv.outage_log(motorway, tmp_path / "m.mcap", 10.0, iv.At((90.0,)))
    drive = iv.load_drive(motorway)
    east, north = local_en_m(drive.lat_deg, drive.lon_deg, float(drive.lat_deg[0]), float(drive.lon_deg[0]))
    km = tmp_path / "km.tum"
    km.write_text("".join(f"{t:.6f} {x / 1000:.9f} {y / 1000:.9f} 0 0 0 0 1\n" for t, x, y in zip(drive.stamp_s(drive.t_s), east, north)))
    assert_refused(run_cli("evaluate", str(motorway), "--no-idnn", "--plan", str(cut.plan_path), "--external", f"x={km}", cwd=tmp_path),
                   "at outage 1's start its pose lies", "look like kilometres")


def test_outage_log_keeps_the_previous_log_when_its_plan_fails(tmp_path, short_csv, monkeypatch):
    """The log is written before its plan; when the plan failed (a full disk, a signal), the new
    log was removed and the previous file at OUT was already gone. Now it comes back."""
    import errno
    import importlib

    from ionav_viz.core.fileio import atomic_path as real_atomic_path

    module = importlib.import_module("ionav_viz.api.outage_log")

    out = tmp_path / "cut.mcap"
    out.write_bytes(b"the previous outaged log")
    (tmp_path / "cut.outages.json").write_text("the previous plan")

    def failing(target, *args, **kwargs):
        if str(target).endswith(".outages.json"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_atomic_path(target, *args, **kwargs)

    monkeypatch.setattr(module, "atomic_path", failing)
    with pytest.raises(OSError):
        iv.outage_log(short_csv, out, 10.0, iv.At((20.0,)))
    assert out.read_bytes() == b"the previous outaged log"
    assert (tmp_path / "cut.outages.json").read_text() == "the previous plan"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.mcap", "cut.outages.json"]  # nothing aside left


def test_no_output_inside_an_input_folder(tmp_path):
    """A ROS 2 bag is a folder: an outaged log, a conversion or an export written into it would
    change the source (its checksum, and what a reader finds there)."""
    from .bag_fixtures import write_ros2

    drive = iv.load_drive("hard-brake")
    keep = drive.t_s < 30
    short = iv.Drive("short", "", drive.rate_hz, drive.start_time_of_day_s, {k: v[keep] for k, v in drive.columns.items()})
    bag = write_ros2(short, tmp_path / "bag")
    before = snapshot(tmp_path)
    for args, fragment in [(("outage-log", "bag", "--at", "5s", "-o", "bag/cut.mcap"), "-o: bag/cut.mcap: is inside the input folder bag"),
                           (("convert", "bag", "-o", "bag/x.mcap"), "bag/x.mcap: is inside the input folder bag"),
                           (("evaluate", "bag", "--no-idnn", "--export", "bag"), "--export: bag: is the input bag")]:
        assert_refused(run_cli(*args, cwd=tmp_path), fragment)
    assert snapshot(tmp_path) == before and bag.is_dir()
