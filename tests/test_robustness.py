"""Hostile inputs and interruptions: every case states its input and the expected behaviour.

The CLI behaves the same everywhere: bad input or usage -> exit code 2 and one line naming the
file, row, column or option with a hint, no traceback (unless --debug); a failure outside the
input (disk full, renderer, network) -> exit code 1 and one line; Ctrl-C -> exit code 130; and
never a partial file at the output path.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ionav_viz.dataset.samples import samples_dir
from ionav_viz.sources.iovnbd import HEADER

from .conftest import HANG_S, REPO, assert_same_sequences, run_cli

SOURCE = samples_dir() / "V-sim-hard-brake.csv"
LINES = SOURCE.read_text().splitlines()
HEADER_LINE, ROWS = LINES[0], LINES[1:]
COL = {name: i for i, name in enumerate(HEADER)}


def write(path: Path, rows: list[str], header: str = HEADER_LINE, end: str = "\r\n", encoding: str = "utf-8") -> Path:
    path.write_bytes((end.join([header] + rows) + end).encode(encoding))
    return path


def with_cell(row: str, column: str, value: str) -> str:
    cells = row.split(",")
    cells[COL[column]] = value
    return ",".join(cells)


def evaluate(path: Path, *extra: str) -> subprocess.CompletedProcess:
    return run_cli("evaluate", str(path), "--no-idnn", "--json", *extra)


def assert_input_error(proc: subprocess.CompletedProcess, *fragments: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


@pytest.fixture(scope="module")
def reference():
    proc = evaluate(SOURCE)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def same_metrics(a: dict, b: dict) -> None:
    assert_same_sequences(a["sequences"], b["sequences"], ("ins",), rel=1e-9)


# ---- CSV drives --------------------------------------------------------------------------------

@pytest.mark.parametrize(
    "case, make, fragments",
    [
        ("empty file -> 'empty file'", lambda p: p.write_bytes(b"") or p, ["empty file"]),
        ("header only -> too few rows", lambda p: write(p, []), ["fewer than 2 data rows"]),
        ("missing required column -> named",
         lambda p: write(p, ROWS, HEADER_LINE.replace(" Indicated Longitudinal Acceleration (g),", " Long Accel (g),")),
         ["missing column", "'indicated longitudinal acceleration'"]),
        ("non-numeric cell -> row and column",
         lambda p: write(p, ROWS[:10] + [with_cell(ROWS[10], "Yaw Rate (deg/sec)", "n/a")] + ROWS[11:]),
         ["row 12", "'Yaw Rate (deg/sec)'", "'n/a'"]),
        ("NaN -> row and column", lambda p: write(p, [with_cell(ROWS[0], "Latitude (degrees)", "NaN")] + ROWS[1:]),
         ["row 2", "'Latitude (degrees)'", "not a finite number"]),
        ("inf -> row and column", lambda p: write(p, ROWS[:3] + [with_cell(ROWS[3], "Velocity (km/hr)", "inf")] + ROWS[4:]),
         ["row 5", "'Velocity (km/hr)'", "not a finite number"]),
        ("latitude out of range", lambda p: write(p, ROWS[:20] + [with_cell(ROWS[20], "Latitude (degrees)", "95.5")] + ROWS[21:]),
         ["row 22", "latitude 95.5 out of range"]),
        ("longitude out of range", lambda p: write(p, ROWS[:20] + [with_cell(ROWS[20], "Longitude (degrees)", "-181")] + ROWS[21:]),
         ["row 22", "longitude -181 out of range"]),
        ("time going backwards -> row", lambda p: write(p, ROWS[:50] + [ROWS[52], ROWS[51]] + ROWS[53:]),
         ["row 53", "time goes backwards"]),
        ("binary garbage", lambda p: p.write_bytes(bytes(range(256)) * 200) or p, ["binary data"]),
        ("an MCAP log named .csv -> said, with the name to give it",
         lambda p: p.write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 20) or p, ["an MCAP log, named .csv", "V-bad.mcap"]),
        ("a ROS 1 bag named .csv -> said", lambda p: p.write_bytes(b"#ROSBAG V2.0\n" + bytes(4096)) or p, ["a ROS 1 bag, named .csv"]),
        ("a row with more fields than the header", lambda p: write(p, ROWS[:5] + [ROWS[5] + ",1,2"] + ROWS[6:]),
         ["line 7 has 31 fields, the header has 29"]),
        ("a row a field short, the next a field long (right total) -> the short one named",
         lambda p: write(p, ROWS[:7] + [ROWS[7].rsplit(",", 1)[0], ROWS[8] + ",1"] + ROWS[9:]),
         ["line 9 has 28 fields, the header has 29"]),
        # physical plausibility (sources/plausibility.py), shown in the file's own unit
        ("accelerometer 1e300 g", lambda p: write(p, ROWS[:40] + [with_cell(ROWS[40], "Indicated Longitudinal Acceleration (g)", "1e300")] + ROWS[41:]),
         ["row 42", "Indicated Longitudinal Acceleration (g)", "1e+300 g outside [-16, 16]"]),
        ("negative speed over ground", lambda p: write(p, ROWS[:40] + [with_cell(ROWS[40], "Velocity (km/hr)", "-12.5")] + ROWS[41:]),
         ["row 42", "Velocity (km/hr)", "-12.5 km/hr outside [0, 360]"]),
        ("heading 1e20", lambda p: write(p, ROWS[:3] + [with_cell(ROWS[3], "Heading (degrees)", "1e20")] + ROWS[4:]),
         ["row 5", "Heading (degrees)", "1e+20 degrees outside [-360, 360]"]),
        ("yaw rate beyond any gyro", lambda p: write(p, ROWS[:3] + [with_cell(ROWS[3], "Yaw Rate (deg/sec)", "-2500")] + ROWS[4:]),
         ["row 5", "Yaw Rate (deg/sec)", "-2500 deg/sec outside [-2000, 2000]"]),
        ("an optional column is checked too", lambda p: write(p, ROWS[:3] + [with_cell(ROWS[3], "Wheel Speed Rear Left (rad/sec)", "9999")] + ROWS[4:]),
         ["row 5", "Wheel Speed Rear Left (rad/sec)", "9999 rad/sec outside [-500, 500]"]),
        ("a unit the reader does not know",
         lambda p: write(p, ROWS, HEADER_LINE.replace("Velocity (km/hr)", "Velocity (knots)")),
         ["column 'Velocity (knots)'", "unknown unit 'knots'", "km/hr"]),
    ],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_bad_csv(tmp_path, case, make, fragments):
    path = tmp_path / "V-bad.csv"
    make(path)
    assert_input_error(evaluate(path), str(path), *fragments)


def test_debug_shows_the_traceback(tmp_path):
    path = tmp_path / "V-empty.csv"
    path.write_bytes(b"")
    proc = run_cli("--debug", "evaluate", str(path), "--no-idnn")
    assert proc.returncode != 0 and "Traceback" in proc.stderr and "InputError" in proc.stderr


def test_very_large_file_is_refused_not_read(tmp_path):
    """Input: a 3 GiB file (sparse). Expected: refused at once with a message, no memory blow-up."""
    path = tmp_path / "V-huge.csv"
    with open(path, "wb") as f:
        f.truncate(3 * 2**30)
    assert_input_error(evaluate(path), "larger than the 2 GiB")  # refused by its size: read, it would take minutes and 3 GiB


@pytest.mark.parametrize(
    "case, make",
    [
        ("extra columns -> ignored", lambda p: write(p, [r + ",7" for r in ROWS], HEADER_LINE + ", Extra (x)")),
        ("reordered columns -> matched by name",
         lambda p: write(p, [",".join(reversed(r.split(","))) for r in ROWS], ",".join(reversed(HEADER_LINE.split(","))))),
        ("UTF-16 with BOM -> decoded", lambda p: write(p, ROWS, encoding="utf-16")),
        ("LF line ends -> same", lambda p: write(p, ROWS, end="\n")),
        ("speed in m/s with a header that says so -> converted by its own unit",
         lambda p: write(p, [with_cell(r, "Velocity (km/hr)", repr(float(r.split(",")[COL["Velocity (km/hr)"]]) * (1 / 3.6))) for r in ROWS],
                         HEADER_LINE.replace("Velocity (km/hr)", "Velocity (m/s)"))),
        ("accelerations in m/s^2 with a header that says so -> converted by its own unit",
         lambda p: write(p, [with_cell(r, "Indicated Longitudinal Acceleration (g)",
                                       repr(float(r.split(",")[COL["Indicated Longitudinal Acceleration (g)"]]) * 9.80665)) for r in ROWS],
                         HEADER_LINE.replace("Indicated Longitudinal Acceleration (g)", "Indicated Longitudinal Acceleration (m/s^2)"))),
    ],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_csv_variants_give_the_same_metrics(tmp_path, reference, case, make):
    path = tmp_path / "V-ok.csv"
    make(path)
    proc = evaluate(path)
    assert proc.returncode == 0, proc.stderr
    same_metrics(reference, json.loads(proc.stdout))


def test_duplicated_timestamps_are_dropped_with_a_warning(tmp_path, reference):
    path = write(tmp_path / "V-dup.csv", ROWS[:30] + [ROWS[29]] + ROWS[30:])
    proc = evaluate(path)
    assert proc.returncode == 0 and "dropped 1 row(s) repeating the previous time stamp (first at row 32)" in proc.stderr
    same_metrics(reference, json.loads(proc.stdout))


def test_file_cut_mid_line_drops_the_last_row(tmp_path):
    path = tmp_path / "V-cut.csv"
    text = (HEADER_LINE + "\r\n" + "\r\n".join(ROWS)).encode()
    path.write_bytes(text[:-40])
    proc = evaluate(path)
    assert proc.returncode == 0 and "ends mid-line; dropped its last row" in proc.stderr


def test_30_s_dropout_splits_the_drive(tmp_path):
    """Input: 30 s of rows missing. Expected: no outage spans the gap; evaluation still runs; the
    gap is said (where, how long, and that nothing spans it), which it was not, even with -v."""
    t0 = float(ROWS[0].split(",")[1])
    times = np.array([float(r.split(",")[1]) - t0 for r in ROWS])
    kept = [r for r, t in zip(ROWS, times) if not 40.0 <= t < 70.0]
    path = write(tmp_path / "V-gap.csv", kept)
    proc = evaluate(path)
    assert proc.returncode == 0, proc.stderr
    said = f"{path}: no rows for 30.2 s from 39.8 s (row 400) to 70.0 s (row 401); no window or outage spans the gap"
    assert proc.stderr.count(said) == 1, proc.stderr
    assert any(w.startswith(said) for w in json.loads(proc.stdout)["warnings"])
    for seq in json.loads(proc.stdout)["sequences"]:
        assert seq["start_s"] + 10 <= 40.0 + 1e-6 or seq["start_s"] >= 70.0 - 1e-6


@pytest.mark.parametrize("rate_hz", [5, 20])
def test_5_and_20_hz_logs(tmp_path, reference, rate_hz):
    """Input: the drive at 5 Hz (every other row) or 20 Hz (midpoints added). Expected: read at that
    rate, resampled to the 10 Hz windows, metrics close to the 10 Hz original."""
    if rate_hz == 5:
        rows = ROWS[::2]
    else:
        rows = []
        for a, b in zip(ROWS[:-1], ROWS[1:]):
            va, vb = np.array(a.split(","), float), np.array(b.split(","), float)
            mid = 0.5 * (va + vb)
            rows += [a, ",".join(f"{x:.8f}" for x in mid)]
        rows.append(ROWS[-1])
    proc = evaluate(write(tmp_path / f"V-{rate_hz}hz.csv", rows))
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert abs(rep["summary"]["ins"]["crse_m"]["mean"] - reference["summary"]["ins"]["crse_m"]["mean"]) < 2.0


# ---- outage settings -----------------------------------------------------------------------------

@pytest.mark.parametrize(
    "args, fragments",
    [
        (["--outage", "10m"], ["--outage 10m", "too short", "shorter outages"]),
        # the outage fits the drive, not after the warm-up: the warm-up is named, not the outage
        (["--warm-up", "3600s"], ["--warm-up", "too short for a 10 s outage after the 3600 s warm-up", "(hint: use a shorter warm-up)"]),
        (["--span", "0s:35s"], ["--warm-up", "after the 30 s warm-up (35.0 s in the span 0s:35s)", "or a longer span"]),
        # shorter outages alone would not do either: the warm-up is longer than the span
        (["--span", "0s:5s"], ["--outage 10s", "after the 30 s warm-up (5.0 s in the span 0s:5s)",
                               "use shorter outages and a shorter warm-up, or a longer span"]),
        # no outage fits a 1 s stretch at all: shorter outages cannot help
        (["--span", "0s:1s", "--warm-up", "0s", "--outage", "1s"], ["--outage 1s", "too short for a 1 s outage (1.0 s in the span 0s:1s)",
                                                                   "use a longer drive (the shortest outage, 1 s, needs 2 s of it), or a longer span"]),
        (["--outage", "0"], ["--outage", "positive"]),
        (["--outage=-10s"], ["--outage", "not a duration"]),
        (["--outage", "2.5s"], ["whole number of seconds"]),
        (["--at", "20s,25s"], ["--at 20s,25s", "start time 25 s", "overlaps"]),
        (["--every", "5s"], ["shorter than the outage"]),
        (["--random", "50"], ["--random 50", "only"]),
        # an empty --on was "no GNSS outage of 2 s or more in this drive"
        (["--on", ""], ["--on", "name event types like hard-brake,roundabout"]),
    ],
)
def test_bad_outage_settings(tmp_path, args, fragments):
    out = tmp_path / "x.rrd"
    proc = run_cli("replay", "hard-brake", "--no-idnn", "-q", "-o", str(out), *args)
    assert_input_error(proc, *fragments)
    assert not list(tmp_path.iterdir())


def test_outage_starting_while_standing_still(tmp_path):
    """Input: an outage at 2 s, while the car still waits (GNSS course undefined). Expected: the
    course is the one held from the first moving fix; both estimators run; errors stay small."""
    out = tmp_path / "still.rrd"
    proc = run_cli("replay", "hard-brake", "--at", "2s", "--outage", "3s", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    ev = run_cli("evaluate", "hard-brake", "--outage", "3s", "--json")
    from ionav_viz.analysis.evaluate import evaluate_drive
    from ionav_viz.experiment.outages import OutagePlan
    from ionav_viz.sources.load import load_drive

    drive = load_drive("hard-brake")
    res = evaluate_drive(drive, 3, ["ins"], plan=OutagePlan(np.array([2]), ""))
    assert np.isfinite(res.metrics["ins"]["crse_m"]).all()
    assert res.metrics["ins"]["final_position_error_m"][0] < 1.0  # standing still: stays put
    assert ev.returncode == 0


# ---- models --------------------------------------------------------------------------------------

@pytest.fixture()
def model_copy(tmp_path):
    import shutil

    from ionav_viz.learning.idnn import default_model_dir

    target = tmp_path / "model"
    shutil.copytree(default_model_dir(), target)
    return target


def test_model_missing(tmp_path):
    assert_input_error(run_cli("evaluate", "hard-brake", "--model", str(tmp_path / "none")), "metadata.json missing")


def test_model_truncated(model_copy):
    weights = model_copy / "yaw_rate.safetensors"
    weights.write_bytes(weights.read_bytes()[:300])
    assert_input_error(run_cli("evaluate", "hard-brake", "--model", str(model_copy)), "yaw_rate.safetensors", "not a safetensors")


@pytest.mark.parametrize("change", [{"n_steps_disp": 10}, {"n_steps_yaw": 12}, {"hidden": 16}, {"arch": "gru"}])
def test_model_with_wrong_architecture_or_feature_count(model_copy, change):
    meta = json.loads((model_copy / "metadata.json").read_text())
    meta["config"].update(change)
    (model_copy / "metadata.json").write_text(json.dumps(meta))
    assert_input_error(run_cli("evaluate", "hard-brake", "--model", str(model_copy)), "do not fit")


def test_model_pickle_payload_does_not_execute(model_copy, tmp_path):
    marker = tmp_path / "executed"
    payload = f"cos\nsystem\n(S'touch {marker}'\ntR.".encode()  # a classic pickle that runs a shell command
    (model_copy / "displacement.safetensors").write_bytes(payload)
    assert_input_error(run_cli("evaluate", "hard-brake", "--model", str(model_copy)), "never loaded")
    assert not marker.exists()


# ---- outputs ---------------------------------------------------------------------------------------

def test_output_directory_missing_or_a_file(tmp_path):
    assert_input_error(run_cli("replay", "hard-brake", "-q", "--no-idnn", "-o", str(tmp_path / "no" / "x.rrd")), "does not exist")
    (tmp_path / "file").write_text("x")
    assert_input_error(run_cli("replay", "hard-brake", "-q", "--no-idnn", "-o", str(tmp_path / "file" / "x.rrd")), f"{tmp_path / 'file'} is a file, not a folder")


def test_existing_output_is_replaced_only_by_a_complete_file(tmp_path):
    """Decision (README): an existing output is replaced, atomically: a failed run leaves it intact."""
    out = tmp_path / "x.rrd"
    out.write_bytes(b"previous")
    bad = write(tmp_path / "V-bad.csv", [ROWS[1], ROWS[0]] + ROWS[2:])
    assert_input_error(run_cli("replay", str(bad), "-q", "--no-idnn", "-o", str(out)), "time goes backwards")
    assert out.read_bytes() == b"previous"
    proc = run_cli("replay", "hard-brake", "-q", "--no-idnn", "-o", str(out))
    assert proc.returncode == 0 and out.read_bytes()[:4] != b"prev"


def _limited_file_size(limit_bytes: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return apply


@pytest.mark.parametrize("command", [["replay", "hard-brake", "--no-idnn", "-q"], ["convert", "hard-brake"], ["simulate", "motorway"]])
def test_disk_full(tmp_path, command):
    """Input: writes fail part-way (file size limit, as on a full disk). Expected: exit 1 or 2 with
    one line, the old output intact, no temporary file left."""
    suffix = {"replay": ".rrd", "convert": ".mcap", "simulate": ".csv"}[command[0]]
    out = tmp_path / f"out{suffix}"
    out.write_bytes(b"previous")
    proc = subprocess.run([sys.executable, "-m", "ionav_viz.cli", *command, "-o", str(out)], cwd=REPO, capture_output=True,
                          text=True, preexec_fn=_limited_file_size(20_000), timeout=HANG_S)
    assert proc.returncode in (1, 2), proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert out.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]


@pytest.mark.parametrize("stage", ["static layers", "ins"])
def test_ctrl_c_in_the_middle_of_a_replay(tmp_path, stage):
    """Input: SIGINT while the recording is being built and written. Expected: exit 130,
    'interrupted', no output and no temporary file.

    Deterministic: the child sends itself a real SIGINT from the recording writer's progress
    callback at a given stage (the signal goes through Python's handler and the CLI's main, as a
    Ctrl-C does), instead of racing a timer against the write."""
    out = tmp_path / "r.rrd"
    child = textwrap.dedent(f"""
        import os, signal, sys
        import ionav_viz.viz.recording as recording
        real = recording.write_recording
        def interrupted_write(result, summary, path, progress=None, **kw):
            def step(label):
                if progress:
                    progress(label)
                if label == {stage!r}:
                    os.kill(os.getpid(), signal.SIGINT)
            return real(result, summary, path, progress=step, **kw)
        recording.write_recording = interrupted_write
        sys.argv = ["ionav-viz", "replay", "hard-brake", "-o", {str(out)!r}, "-q", "--no-idnn"]
        from ionav_viz.cli import main
        main()
    """)
    proc = subprocess.run([sys.executable, "-c", child], cwd=REPO, capture_output=True, text=True, timeout=HANG_S)
    assert proc.returncode == 130, proc.stderr
    assert "interrupted" in proc.stderr and "Traceback" not in proc.stderr
    assert list(tmp_path.iterdir()) == []


# ---- round 2: signals ----------------------------------------------------------------------

def _interrupted_child(argv: list[str], signum: int, private_tmp: Path | None = None) -> subprocess.CompletedProcess:
    """Run ``ionav-viz ARGV`` with a real signal sent to itself right as the output's temporary
    file is created (the moment a race once left it behind). Deterministic: no timer involved."""
    child = textwrap.dedent(f"""
        import os, sys, tempfile
        import ionav_viz.core.fileio as fileio
        real = tempfile.mkstemp
        def mkstemp_then_signal(*args, **kwargs):
            made = real(*args, **kwargs)
            os.kill(os.getpid(), {int(signum)})  # held back until the cleanup is armed
            return made
        fileio.tempfile = type(sys)("tempfile_probe")
        fileio.tempfile.mkstemp = mkstemp_then_signal
        sys.argv = ["ionav-viz", *{argv!r}]
        from ionav_viz.cli import main
        main()
    """)
    env = None if private_tmp is None else {**__import__("os").environ, "TMPDIR": str(private_tmp)}
    return subprocess.run([sys.executable, "-c", child], cwd=REPO, capture_output=True, text=True, timeout=HANG_S, env=env)


@pytest.mark.parametrize(
    ("command", "signame", "code", "word"),
    [
        (["replay", "hard-brake", "--no-idnn", "-q"], "SIGTERM", 143, "terminated (SIGTERM)"),
        (["replay", "hard-brake", "--no-idnn", "-q"], "SIGHUP", 129, "terminated (SIGHUP)"),
        (["replay", "hard-brake", "--no-idnn", "-q"], "SIGINT", 130, "interrupted"),
        (["convert", "hard-brake"], "SIGTERM", 143, "terminated (SIGTERM)"),
        (["simulate", "motorway", "--duration", "30s"], "SIGHUP", 129, "terminated (SIGHUP)"),
    ],
)
def test_stop_signals_clean_up_and_exit_128_plus_the_signal(tmp_path, command, signame, code, word):
    """Input: SIGTERM, SIGHUP or SIGINT while the output is being written. Expected: exit 130/143/129,
    one line, no output and no temporary file."""
    import signal

    suffix = {"replay": ".rrd", "convert": ".mcap", "simulate": ".csv"}[command[0]]
    proc = _interrupted_child([*command, "-o", str(tmp_path / f"out{suffix}")], getattr(signal, signame))
    assert proc.returncode == code, proc.stderr
    assert proc.stderr.strip() == word and "Traceback" not in proc.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("read", [1, 2])
def test_ctrl_c_while_a_csv_is_read_stops_the_read(monkeypatch, read):
    """Input: Ctrl-C while pandas reads a CSV drive (its header, read 1, or its columns, read 2).
    'convert long.csv -o x.mcap' stopped by Ctrl-C about a second in said 'long.csv: not a
    readable CSV (Error tokenizing data. C error: Calling read(nbytes) on source failed...)' with
    exit code 2: pandas' C parser turns the KeyboardInterrupt raised inside its read() into a
    ParserError. Expected: the KeyboardInterrupt itself (the command line's 'interrupted', 130).

    Deterministic: the real parser reads a file object that sends a real SIGINT to the process
    from its first read()."""
    import io
    import os
    import signal

    import pandas.io.common

    import ionav_viz as iv

    opened, probes = [], []

    class SignalOnRead(io.TextIOWrapper):
        def read(self, size=-1):
            os.kill(os.getpid(), signal.SIGINT)
            return super().read(size)

    def open_probe(file, mode="r", **kwargs):  # as pandas opens a path it reads as text
        opened.append(file)
        if len(opened) != read:
            return open(file, mode, **kwargs)
        probes.append(SignalOnRead(open(file, "rb"), encoding=kwargs["encoding"], errors=kwargs["errors"], newline=kwargs["newline"]))  # noqa: SIM115 (pandas closes it, or the finally below)
        return probes[-1]

    monkeypatch.setattr(pandas.io.common, "open", open_probe, raising=False)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            iv.load_drive(SOURCE)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the reader's own handler is gone
    finally:
        signal.signal(signal.SIGINT, previous)
        for probe in probes:
            probe.close()  # pandas leaves the file it was reading open when interrupted
    assert len(opened) == read


def test_sighup_during_screenshot_stops_the_viewer(tmp_path):
    """Input: SIGHUP while the headless viewer renders. Expected: exit 129, no viewer left, no scratch folder."""

    from .test_screenshot import _viewers_under

    rec = tmp_path / "r.rrd"
    assert run_cli("replay", "hard-brake", "--no-idnn", "--every", "100s", "-q", "-o", str(rec)).returncode == 0
    private_tmp = tmp_path / "tmp"
    private_tmp.mkdir()
    child = textwrap.dedent(f"""
        import os, sys, signal
        import ionav_viz.viz.screenshot as shots
        real_open = shots.HeadlessViewer.open
        def open_then_hangup(self, *args, **kwargs):
            real_open(self, *args, **kwargs)
            os.kill(os.getpid(), signal.SIGHUP)
        shots.HeadlessViewer.open = open_then_hangup
        sys.argv = ["ionav-viz", "screenshot", {str(rec)!r}, "-o", {str(tmp_path / "x.png")!r}, "--size", "400x300"]
        from ionav_viz.cli import main
        main()
    """)
    proc = subprocess.run([sys.executable, "-c", child], cwd=REPO, capture_output=True, text=True, timeout=HANG_S,
                          env={**__import__("os").environ, "TMPDIR": str(private_tmp)})
    if proc.returncode == 1 and "mesa" in proc.stderr and not __import__("os").environ.get("CI"):
        pytest.skip("no renderer on this machine")
    assert proc.returncode == 129, proc.stderr
    assert _viewers_under(private_tmp) == set() and list(private_tmp.iterdir()) == []
    assert not (tmp_path / "x.png").exists()


# ---- round 2: output paths -----------------------------------------------------------------

@pytest.mark.parametrize(
    ("command", "suffix"),
    [(["replay", "hard-brake", "--no-idnn", "-q"], ".rrd"), (["convert", "hard-brake"], ".mcap"), (["simulate", "motorway"], ".csv")],
)
@pytest.mark.parametrize("kind", ["directory", "fifo", "device"])
def test_output_that_is_not_a_regular_file_is_never_replaced(tmp_path, command, suffix, kind):
    """Input: -o naming an existing directory, FIFO or device node. Expected: exit 2 before any
    work, one line naming it, the node untouched."""
    import os
    import stat

    target = tmp_path / f"target{suffix}"
    if kind == "directory":
        target.mkdir()
    elif kind == "fifo":
        os.mkfifo(target)
    else:
        if os.geteuid() != 0:
            pytest.skip("creating a device node needs root")
        os.mknod(target, 0o600 | stat.S_IFCHR, os.makedev(1, 3))  # a private node with /dev/null's numbers
    mode = target.lstat().st_mode
    proc = run_cli(*command, "-o", str(target))
    assert_input_error(proc, str(target), "is a directory" if kind == "directory" else "not a regular file")
    assert target.lstat().st_mode == mode and sorted(p.name for p in tmp_path.iterdir()) == [target.name]


def test_train_output_that_is_a_file_is_refused_before_training(tmp_path):
    target = tmp_path / "model"
    target.write_text("not a model")
    assert_input_error(run_cli("train", "-o", str(target), "--force"), "not a directory")
    assert target.read_text() == "not a model"


def test_unwritable_output_directory_is_one_line(tmp_path, monkeypatch):
    """Input: an output directory the user cannot write (simulated: root may write anywhere)."""
    import os

    from ionav_viz import InputError
    from ionav_viz.core.fileio import check_output_file

    monkeypatch.setattr(os, "access", lambda *args, **kwargs: False)
    with pytest.raises(InputError, match="permission denied"):
        check_output_file(tmp_path / "x.rrd")


def test_names_from_inside_a_recording_never_leave_the_output_directory(tmp_path):
    """Input: a crafted .rrd whose recording name is '../../evil/x'. Expected: PNG names stay inside -o."""
    import rerun as rr

    from ionav_viz.viz.recording_info import read_recording_info
    from ionav_viz.viz.screenshot import output_paths

    crafted = tmp_path / "crafted.rrd"
    rec = rr.RecordingStream("ionav-viz", recording_id="crafted")
    rec.save(str(crafted))
    rec.send_recording_name("../../evil/x")
    rec.send_columns("gnss/state", indexes=[rr.TimeColumn("time", duration=[0.0, 5.0])],
                     columns=rr.StateChange.columns(state=["GNSS", "outage 1 (5-15 s)"]))
    rec.flush()
    rec.disconnect()
    info = read_recording_info(crafted)
    assert info.drive == "../../evil/x"
    out = tmp_path / "shots"
    for path in output_paths(out, info.drive, [("local", "end"), ("map", "worst")], single_file_ok=False):
        assert path.parent == out and ".." not in path.name and "/" not in path.name


# ---- round 2: models ---------------------------------------------------------------------

@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ({"config": {"hidden": "32"}}, "hidden = '32' is not a whole number"),
        ({"config": {"n_steps_disp": True}}, "n_steps_disp = True is not a whole number"),
        ({"config": {"hidden": 60000}}, "out of range"),
        ({"config": {"dropout": float("nan")}}, "dropout = nan is not a finite number"),
        ({"normalisation": {"accel": [0.5, 0.5]}}, "not a finite, non-empty range"),
        ({"normalisation": {"gyro": [float("nan"), 1.0]}}, "not a finite, non-empty range"),
    ],
)
def test_model_metadata_with_wrong_types_or_ranges(model_copy, change, fragment):
    meta = json.loads((model_copy / "metadata.json").read_text())
    for key, values in change.items():
        meta[key].update(values)
    (model_copy / "metadata.json").write_text(json.dumps(meta))
    assert_input_error(run_cli("evaluate", "hard-brake", "--model", str(model_copy)), "metadata.json", fragment)


@pytest.mark.parametrize("kind", ["nan", "int8", "fifo", "dev-zero"])
def test_model_weights_that_cannot_be_right(model_copy, kind):
    """NaN weights, int8 weights, a FIFO or /dev/zero as the weights file: refused at once."""
    import os

    import torch
    from safetensors.torch import load, save

    path = model_copy / "yaw_rate.safetensors"
    if kind in ("nan", "int8"):
        state = load(path.read_bytes())
        name = next(iter(state))
        state[name] = state[name].clone()
        if kind == "nan":
            state[name].view(-1)[0] = float("nan")
        else:
            state[name] = state[name].to(torch.int8)
        path.write_bytes(save(state))
        fragment = "NaN or infinite" if kind == "nan" else "is int8, expected float32"
    elif kind == "fifo":
        path.unlink()
        os.mkfifo(path)
        fragment = "not a regular file"
    else:
        path.unlink()
        path.symlink_to("/dev/zero")
        fragment = "not a regular file"
    assert_input_error(run_cli("evaluate", "hard-brake", "--model", str(model_copy), timeout=HANG_S), "yaw_rate.safetensors", fragment)


def test_training_options_that_would_make_a_nan_model(tmp_path):
    assert_input_error(run_cli("train", "-o", str(tmp_path / "m"), "--feedback-noise", "inf"), "--feedback-noise", "not a finite number")
    assert not (tmp_path / "m").exists()


# ---- round 2: sizes, options and messages ---------------------------------------------------

@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["events", "hard-brake", "--threshold", "yaw_smooth_s=1e8"], ["yaw_smooth_s", "out of range", "0.1 to 10"]),
        (["events", "hard-brake", "--threshold", "hard_brake_g=1,2"], ["hard_brake_g=1,2", "not one number"]),
        (["events", "hard-brake", "--threshold", "roundabout_radius_m=5"], ["roundabout_radius_m=5", "LOW,HIGH"]),
        (["events", "hard-brake", "--threshold", "hard_brake_g=inf"], ["out of range"]),
        (["simulate", "motorway", "-o", "{tmp}/V-x.csv", "--duration", "90h"], ["90 h", "12 h"]),
        (["simulate", "motorway", "-o", "{tmp}/V-x.csv", "--seed", "-1"], ["seed", ">= 0"]),
        (["replay", "hard-brake", "--no-idnn", "-o", "{tmp}/x.rrd", "--random", "3", "--seed", "-1"], ["--random 3", "seed -1 is negative"]),
        (["replay", "hard-brake", "--no-idnn", "-o", "{tmp}/x.rrd", "--every", "10.5s"], ["--every 10.5s", "outage period 10.5 s"]),
        (["replay", "hard-brake", "--no-idnn", "-o", "{tmp}/x.rrd", "--at", ","], ["--at", "start times like 12s,40s"]),
        (["fetch", "V-Vw8", "--base-url", "http://[bad", "--data-root", "{tmp}/root"], ["--base-url", "not a valid URL"]),
        (["fetch", "V-Vw8", "--base-url", "ftp://host/x", "--data-root", "{tmp}/root"], ["--base-url", "not an http(s) URL"]),
    ],
)
def test_options_are_checked_before_any_work(tmp_path, args, fragments):
    proc = run_cli(*[a.replace("{tmp}", str(tmp_path)) for a in args])
    assert_input_error(proc, *fragments)
    assert list(tmp_path.iterdir()) == []  # nothing written, no data root created


def test_a_1_hz_log_is_refused_with_the_real_reason(tmp_path):
    path = write(tmp_path / "V-1hz.csv", ROWS[::10])
    assert_input_error(evaluate(path), "V-1hz.csv", "1 Hz", "at least 2 Hz")


# ---- MCAP logs: impossible values, repeated and stray stamps ---------------------------------

def _mcap(tmp_path: Path, name: str, tamper=None) -> Path:
    from .mcap_fixtures import write_json

    return write_json(tmp_path / f"{name}.mcap", duration_s=40.0, imu_hz=50, gnss_hz=5, tamper=tamper)


def _set(kind: str, index: int, field: str, value: float):
    def tamper(k, i, msg):
        if k == kind and i == index:
            msg = json.loads(json.dumps(msg))
            target = msg
            *path, last = field.split(".")
            for part in path:
                target = target[part]
            target[last] = value
        return [msg]
    return tamper


def _set_many(kind: str, indices, field: str, value):
    each = [_set(kind, i, field, value) for i in indices]

    def tamper(k, i, msg):
        for one in each:
            [msg] = one(k, i, msg)
        return [msg]
    return tamper


def test_an_imu_topic_without_rates_is_refused(tmp_path):
    """Round 3: an IMU topic with only an orientation (REP 145 marks accelerations and rates 'not
    provided' with covariance[0] = -1) was scored on zeros (CRSE 6.60 m vs 0.13 m), no warning."""
    not_provided = [-1.0] + [0.0] * 8

    def orientation_only(k, i, msg):
        if k == "imu":
            msg = {**msg, "angular_velocity_covariance": not_provided, "linear_acceleration_covariance": not_provided}
        return [msg]
    path = _mcap(tmp_path, "orientation-only", orientation_only)
    proc = run_cli("evaluate", str(path), "--no-idnn")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "topic /imu marks its linear acceleration" in proc.stderr and "'not provided' (REP 145" in proc.stderr
    assert "--imu-topic" in proc.stderr


@pytest.mark.parametrize(
    "case, tamper, fragments",
    [
        ("latitude 200 deg", _set("fix", 10, "latitude", 200.0), ["topic /location", "latitude 200 deg outside [-90, 90]"]),
        ("longitude -1e9 deg", _set("fix", 3, "longitude", -1e9), ["topic /location", "longitude -1e+09 deg outside [-180, 180]"]),
        ("NaN acceleration", _set("imu", 100, "linear_acceleration.x", float("nan")), ["topic /imu", "linear_acceleration.x not a finite number"]),
        ("infinite yaw rate", _set("imu", 7, "angular_velocity.z", float("inf")), ["topic /imu", "angular_velocity.z not a finite number"]),
        ("acceleration of 1e300", _set("imu", 7, "linear_acceleration.x", 1e300), ["linear_acceleration.x 1e+300 m/s^2 outside"]),
        ("every fix NaN -> no truth", lambda k, i, m: [{**m, "latitude": float("nan")}] if k == "fix" else [m],
         ["fewer than 2 GNSS fixes"]),
    ],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_bad_mcap_values(tmp_path, case, tamper, fragments):
    path = _mcap(tmp_path, "bad", tamper)
    assert_input_error(evaluate(path), str(path), *fragments)


@pytest.fixture(scope="module")
def mcap_reference(tmp_path_factory):
    proc = evaluate(_mcap(tmp_path_factory.mktemp("ref"), "ref"), "--outage", "5s")
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _whole_second(k, i, msg):
    if k == "fix":
        msg = json.loads(json.dumps(msg))
        msg["timestamp"]["nsec"] = 0
    return [msg]


def _received_out_of_order(k, i, msg, held=[]):  # noqa: B006 - the held message, between two calls
    """IMU messages 100 and 101 received in swapped order (two publishers, a transport)."""
    if k == "imu" and i == 100:
        held.append(msg)
        return []
    if k == "imu" and i == 101:
        return [msg, held.pop()]
    return [msg]


def _boot_stamp(k, i, msg):
    if k == "imu" and i == 300:
        msg = json.loads(json.dumps(msg))
        msg["header"]["stamp"] = {"sec": 125, "nsec": 0}  # seconds since boot, among UNIX stamps
    return [msg]


@pytest.mark.parametrize(
    "case, tamper, warning, exact",
    [
        ("every fix published twice -> the first of each kept, same metrics",
         lambda k, i, m: [m, m] if k == "fix" else [m], "share a time stamp", True),
        ("NaN and infinite fixes (drivers' 'no fix') -> dropped like status -1",
         lambda k, i, m: [{**m, "latitude": float("nan")} if k == "fix" and i in (20, 21) else
                          {**m, "longitude": float("inf")} if k == "fix" and i == 40 else m],
         "dropped 3 GNSS message(s) without a fix", False),
        ("one IMU message stamped from boot time -> dropped, memory bounded, same metrics",
         _boot_stamp, "dropped 1 IMU sample(s) stamped more than 3600 s away", True),
        ("fixes stamped to whole seconds -> one fix per second, no division by 1e-9",
         _whole_second, "share a time stamp", False),
        ("IMU messages received out of stamp order -> used in stamp order, same metrics (round 3: the documented rule)",
         _received_out_of_order, "topic /imu: 1 message(s) stamped earlier than the one received before them", True),
        ("a few IMU messages marking their rates 'not provided' (REP 145) -> skipped, not read as zeros",
         _set_many("imu", range(200, 205), "angular_velocity_covariance", [-1.0] + [0.0] * 8),
         "skipped the messages marking their angular velocity (5 message(s)) 'not provided'", False),
    ],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_mcap_repeated_missing_or_stray_stamps(tmp_path, mcap_reference, case, tamper, warning, exact):
    path = _mcap(tmp_path, "odd", tamper)
    proc = subprocess.run([sys.executable, "-m", "ionav_viz.cli", "evaluate", str(path), "--no-idnn", "--json", "--outage", "5s"],
                          cwd=REPO, capture_output=True, text=True, timeout=HANG_S,
                          preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30)))
    assert proc.returncode == 0, proc.stderr
    assert warning in proc.stderr
    got = json.loads(proc.stdout)
    if exact:
        same_metrics(mcap_reference, got)
    else:
        # the straight-line drive's truth hardly changes: each outage's CRSE within 0.5 m
        for ref, seq in zip(mcap_reference["sequences"], got["sequences"], strict=True):
            assert abs(seq["ins"]["crse_m"] - ref["ins"]["crse_m"]) < 0.5, (ref, seq)


def test_fixes_at_zero_zero_are_never_scored(tmp_path, reference):
    """Input: three rows at (0, 0) in a drive in England (a 5,800 km jump in 0.1 s). Expected: exit 0,
    one warning naming them, the windows around them excluded, every metric the size of the others."""
    rows = [with_cell(with_cell(r, "Latitude (degrees)", "0"), "Longitude (degrees)", "0") if 500 <= i < 503 else r
            for i, r in enumerate(ROWS)]
    proc = evaluate(write(tmp_path / "V-zero.csv", rows))
    assert proc.returncode == 0, proc.stderr
    assert "0.3 of" in proc.stderr and "near-zero 0.3 s" in proc.stderr  # 3 samples of 10 Hz
    got = json.loads(proc.stdout)
    assert got["gnss_truth"]["excluded_by_reason"] == {"near-zero": 2}  # 50.0-50.2 s: the windows either side of 50 s
    # the size of the others: the exclusions shift the later outages by a window or two, so one may
    # come out a little worse than the reference's worst, never by the 5,800 km of the jump
    worst = max(seq["ins"]["crse_m"] for seq in reference["sequences"])
    assert all(seq["ins"]["crse_m"] <= 1.5 * worst for seq in got["sequences"])


# ---- round 3: bounded readers ---------------------------------------------------------------

def _peak_memory_run(path: Path) -> tuple[subprocess.CompletedProcess, str, int]:
    """``ionav-viz evaluate PATH`` in a child: (process, its stderr without the last line, peak RSS in MiB)."""
    # VmHWM, not ru_maxrss: Linux carries the latter over from the forking test process
    child = ("import sys\n"
             "from ionav_viz.cli import main\n"
             f"sys.argv = ['ionav-viz', 'evaluate', {str(path)!r}, '--no-idnn']\n"
             "try:\n    main()\nfinally:\n"
             "    status = open('/proc/self/status').read().split('VmHWM:')[1]\n"
             "    print(int(status.split()[0]), file=sys.stderr)\n")
    proc = subprocess.run([sys.executable, "-c", child], cwd=REPO, capture_output=True, text=True, timeout=HANG_S)
    *lines, peak_kib = proc.stderr.splitlines()
    return proc, "\n".join(lines), int(peak_kib) // 1024


BOMB_MIB = 768


def _first_call_bombs(real, compression: str):
    """A compressor whose first chunk carries BOMB_MIB MiB of zeros after its data, in a few KiB:
    bz2 as extra streams (bz2.decompress reads them all), lz4 inside the one frame."""
    import bz2

    calls = []

    def compress(data, *args, **kwargs):
        calls.append(1)
        if len(calls) > 1:
            return real(data, *args, **kwargs)
        if compression == "bz2":
            return real(data, *args, **kwargs) + bz2.compress(b"\0" * 2**20) * BOMB_MIB
        return real(data + b"\0" * (BOMB_MIB << 20), *args, **kwargs)
    return compress


@pytest.mark.parametrize("compression", ["bz2", "lz4"])
def test_a_ros1_compression_bomb_is_refused_before_it_fills_memory(tmp_path, monkeypatch, compression):
    """Round 3: a 113 KB ROS 1 bag whose bz2 chunks inflate to 6 GB climbed to the address-space cap
    before a MemoryError. Here the first chunk inflates to 768 MiB more than its header declares:
    refused with one line naming the chunk, peak memory far below the bomb."""
    import rosbags.rosbag1.writer as writer

    import ionav_viz as iv

    from . import bag_fixtures as bf

    name = f"{compression}_compress"
    monkeypatch.setattr(writer, name, _first_call_bombs(getattr(writer, name), compression))
    bag = bf.write_ros1(iv.load_drive("hard-brake"), tmp_path / "bomb.bag", compression=compression)
    assert bag.stat().st_size < 10 * 2**20
    proc, message, peak_mib = _peak_memory_run(bag)
    assert proc.returncode == 2 and message.count("\n") == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert f"{bag}: the ROS 1 chunk at byte" in message and "compression bomb" in message, message
    assert peak_mib < 600, f"peak memory {peak_mib} MiB"


@pytest.mark.parametrize("compression", ["LZ4", "ZSTD"])
def test_an_mcap_compression_bomb_is_refused_before_it_fills_memory(tmp_path, monkeypatch, compression):
    """The same for MCAP chunks: lz4 inflated without a bound in the mcap package; a chunk declaring
    more than 256 MiB (zstd would allocate it) is refused from its header."""
    import lz4.frame
    import mcap.writer

    from .mcap_fixtures import write_ros2

    if compression == "LZ4":
        monkeypatch.setattr(lz4.frame, "compress", _first_call_bombs(lz4.frame.compress, "lz4"))
    else:
        real_chunk = mcap.writer.Chunk

        def declaring_a_gigabyte(*args, **kwargs):
            return real_chunk(*args, **{**kwargs, "uncompressed_size": 2**30})
        monkeypatch.setattr(mcap.writer, "Chunk", declaring_a_gigabyte)
    path = write_ros2(tmp_path / "bomb.mcap", duration_s=20.0, compression=compression)
    proc, message, peak_mib = _peak_memory_run(path)
    assert proc.returncode == 2 and message.count("\n") == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert f"{path}: the MCAP chunk of messages from log time" in message, message
    assert ("compression bomb" if compression == "LZ4" else "declares 1024 MiB") in message, message
    assert peak_mib < 600, f"peak memory {peak_mib} MiB"


def test_a_ros2_bag_compression_bomb_is_refused_before_it_fills_memory(tmp_path, monkeypatch):
    """The same for a ROS 2 bag's MCAP storage (chunk-compressed with zstd by 'ros2 bag record
    --compression-mode file' in MCAP): rosbags inflated its chunks without a bound."""
    from rosbags.rosbag2 import storage_mcap

    import ionav_viz as iv

    from . import bag_fixtures as bf

    calls = []
    real_init = storage_mcap.McapWriter.__init__
    bomb = __import__("zstandard").ZstdCompressor().compress(b"\0" * (BOMB_MIB << 20))

    def bombing(self, *args, **kwargs):
        real_init(self, *args, **kwargs)
        real = self.compressor

        def compress(data):
            calls.append(1)
            return real(data) + (bomb if len(calls) == 1 else b"")
        self.compressor = compress
    monkeypatch.setattr(storage_mcap.McapWriter, "__init__", bombing)
    folder = bf.write_ros2(iv.load_drive("hard-brake"), tmp_path / "bomb", storage="mcap", compression="storage")
    assert calls, "the writer never compressed a chunk"
    proc, message, peak_mib = _peak_memory_run(folder)
    assert proc.returncode == 2 and message.count("\n") == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert "an MCAP chunk of the ROS 2 bag" in message and "compression bomb" in message, message
    assert peak_mib < 600, f"peak memory {peak_mib} MiB"


# ---- round 3: output limits and names ---------------------------------------------------------

def _file_size_limit(kib: int):
    return lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (kib * 1024, kib * 1024))


@pytest.mark.parametrize("command", [
    ["evaluate", "hard-brake", "--no-idnn", "--json"],
    ["train", "hard-brake", "--span", "0s:200s", "--epochs-disp", "1", "--epochs-yaw", "1", "-q"],  # its uncertainty fitted, a 13 kB model
])
def test_a_file_size_limit_is_one_line(tmp_path, command):
    """Round 3: with 'ulimit -f' low, 'evaluate --json > out.json' and 'train' ended in an
    'OSError: File too large' traceback."""
    out = tmp_path / "out.json"
    # numba writes its compiled kernels into the package's __pycache__ on first use: warm it without
    # the limit (in this process: the files it writes are the same), so that the limited run's only
    # large writes are the command's own output
    warm = run_cli(*command, *(["-o", str(tmp_path.parent / f"{tmp_path.name}-warm")] if command[0] == "train" else []))
    assert warm.returncode == 0, warm.stderr
    if command[0] == "train":
        command = [*command, "-o", str(tmp_path / "model")]
    with open(out, "wb") as stdout:
        proc = subprocess.run([sys.executable, "-m", "ionav_viz.cli", *command], cwd=REPO, stdout=stdout, stderr=subprocess.PIPE,
                              text=True, timeout=HANG_S, preexec_fn=_file_size_limit(4))
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "write failed (File too large); a file size limit was reached" in proc.stderr
    named = "standard output" if command[0] == "evaluate" else str(tmp_path / "model")
    assert proc.stderr.startswith(f"error: {named}: "), proc.stderr
    if command[0] == "train":
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]  # no model, no temporary folder


def test_output_names_that_are_not_utf8(tmp_path):
    """Round 3: '-o $'out\\377.rrd'' (a valid Linux name) failed with 'does not read back ... is the
    disk full?': Rerun's reader takes only UTF-8 paths."""
    import os

    def run(*args):  # the path on stdout is not UTF-8 either
        return subprocess.run([sys.executable, "-m", "ionav_viz.cli", *args], cwd=REPO, capture_output=True, text=True,
                              errors="surrogateescape", timeout=HANG_S)

    folder = os.fsencode(tmp_path)
    rrd = os.fsdecode(folder + b"/out\xff.rrd")
    proc = run("replay", "hard-brake", "--no-idnn", "--every", "100s", "-q", "-o", rrd)
    assert proc.returncode == 0, proc.stderr
    assert os.listdir(folder) == [b"out\xff.rrd"]
    png = os.fsdecode(folder + b"/shot\xff.png")
    proc = run("screenshot", rrd, "-o", png, "--size", "400x300")
    if proc.returncode == 1 and "mesa-vulkan-drivers" in proc.stderr and not os.environ.get("CI"):
        pytest.skip("no renderer on this machine")
    assert proc.returncode == 0, proc.stderr
    assert sorted(os.listdir(folder)) == [b"out\xff.rrd", b"shot\xff.png"]  # no alias or temporary file left
    assert Path(png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_ros2_message_compression_bomb_is_refused_before_it_fills_memory(tmp_path, monkeypatch):
    """A ROS 2 bag recorded with '--compression-mode message': rosbags inflated each message
    without a bound; one message here inflates to 768 MiB."""
    import types

    import rosbags.rosbag2.writer as writer

    import ionav_viz as iv

    from . import bag_fixtures as bf

    real = writer.zstd
    bomb = real.compress(b"\0" * (BOMB_MIB << 20))
    calls = []

    def compress(data, *args, **kwargs):
        calls.append(1)
        return bomb if len(calls) == 50 else real.compress(data, *args, **kwargs)
    monkeypatch.setattr(writer, "zstd", types.SimpleNamespace(compress=compress, open=real.open))
    folder = bf.write_ros2(iv.load_drive("hard-brake"), tmp_path / "bomb", storage="sqlite3", compression="message")
    proc, message, peak_mib = _peak_memory_run(folder)
    assert proc.returncode == 2 and message.count("\n") == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert "a compressed message of the ROS 2 bag inflates past 256 MiB" in message and "compression bomb" in message, message
    assert peak_mib < 600, f"peak memory {peak_mib} MiB"


@pytest.mark.parametrize("command", [["evaluate", "roundabout", "--estimators", "ins"], ["train", "roundabout", "--span", "0s:40s", "-o", "MODEL"]])
def test_a_bad_bias_drive_is_named_as_bias_from(tmp_path, command):
    """A --bias-from file that cannot be read was said as if it were the drive ('error: x.csv: row
    ..., column ...'), with many drives not saying which option named it; it is --bias-from's now."""
    bad = tmp_path / "V-still.csv"
    lines = (samples_dir() / "V-sim-stationary.csv").read_text().splitlines()
    cells = lines[5].split(",")
    cells[1] = "soon"
    bad.write_text("\n".join([*lines[:5], ",".join(cells), *lines[6:]]) + "\n")
    args = [str(tmp_path / "m") if a == "MODEL" else a for a in command]
    assert_input_error(run_cli(*args, "--bias-from", str(bad), "-q"), "error: --bias-from: ", "V-still.csv: row 6")
    assert_input_error(run_cli(*args, "--bias-from", str(tmp_path / "none.csv"), "-q"), "error: --bias-from: ", "none.csv: no such file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["V-still.csv"]


def test_force_never_replaces_a_folder_of_other_files(tmp_path):
    """train -o FOLDER --force replaced FOLDER whole: a folder of the user's own files (a thesis, a
    subfolder) was deleted without a word. Only a folder of a model's files is replaced now."""
    folder = tmp_path / "results"
    (folder / "figs").mkdir(parents=True)
    (folder / "thesis.tex").write_text("precious")
    proc = run_cli("train", "roundabout", "--span", "0s:40s", "--epochs-disp", "1", "--epochs-yaw", "1", "-q", "-o", str(folder), "--force")
    assert_input_error(proc, "error: -o: ", "results: holds 'figs' and 1 more, not a model's file")
    assert (folder / "thesis.tex").read_text() == "precious" and (folder / "figs").is_dir()
    (folder / "thesis.tex").unlink()
    (folder / "figs").rmdir()
    proc = run_cli("train", "roundabout", "--span", "0s:40s", "--epochs-disp", "1", "--epochs-yaw", "1", "-q", "-o", str(folder), "--force")
    assert proc.returncode == 0 and (folder / "metadata.json").is_file(), proc.stderr  # an empty folder, then a model: replaced
    proc = run_cli("train", "roundabout", "--span", "0s:40s", "--epochs-disp", "1", "--epochs-yaw", "1", "-q", "-o", str(folder), "--force")
    assert proc.returncode == 0, proc.stderr
