"""Hostile inputs, round 4, on what ionav-viz writes: figures of a report, JSON output with
plug-ins' values, and converted MCAP logs (issue 45, points 3 and 4).

Each test fails without its fix. Bad input is exit code 2, one line on stderr starting with
``error:`` that names the file or field, no traceback, and nothing written.
"""

from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.errors import InputError
from ionav_viz.core.fileio import current_umask, staging_folder
from ionav_viz.core.json_out import dumps_json, plain_json

from .conftest import HANG_S, run_cli

PLUGINS = Path(__file__).resolve().parent / "plugins"


def _one_line_error(proc, *fragments: str) -> None:
    lines = proc.stderr.splitlines()
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in proc.stderr, proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


# ---------------------------------------------------------------------------------------------
# convert: the lateral acceleration, and axes that read one value over the whole log


@pytest.fixture(scope="session")
def two_channel(tmp_path_factory) -> Path:
    """A short simulated motorway drive as the IO-VNBD logger writes it: longitudinal and lateral
    acceleration and yaw rate, no full IMU."""
    from ionav_viz.sim.simulate import write_simulated_drive

    return write_simulated_drive(tmp_path_factory.mktemp("convert") / "V-short-motorway.csv", "motorway", seed=5, duration_s=150)


@pytest.fixture(scope="session")
def converted(two_channel, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("converted") / "short.mcap"
    iv.convert(two_channel, out)
    return out


def _ins_crse(report) -> list[float]:
    return [s["ins"]["crse_m"] for s in json.loads(report.to_json())["sequences"]]


def test_convert_writes_the_lateral_acceleration(two_channel, converted, caplog):
    """sensor_msgs/Imu carries it: linear_acceleration.y, left positive (it was dropped, 'not
    carried by the MCAP log', and written as 0)."""
    from ionav_viz.sources.mcap_reader import read_mcap

    csv = iv.load_drive(two_channel)
    back = read_mcap(converted)
    np.testing.assert_allclose(back.columns["accel_y_mps2"], csv.columns["accel_lat_mps2"], atol=1e-9)
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        iv.convert(two_channel, converted.parent / "again.mcap")
    assert "accel_lat_mps2" not in caplog.text


def test_a_lateral_acceleration_read_right_positive_is_written_left_positive(two_channel, tmp_path, caplog):
    csv = iv.load_drive(two_channel)
    csv.columns["accel_lat_mps2"] = -csv.columns["accel_lat_mps2"]  # a source whose lateral is right positive
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        iv.convert(csv, tmp_path / "right.mcap")
    assert "the lateral acceleration reads right positive" in caplog.text
    from ionav_viz.sources.mcap_reader import read_mcap

    np.testing.assert_allclose(read_mcap(tmp_path / "right.mcap").columns["accel_y_mps2"], -csv.columns["accel_lat_mps2"], atol=1e-9)


def test_a_drive_whose_imu_is_not_finite_is_not_converted(two_channel, tmp_path):
    """A drive built in Python with NaN in its lateral acceleration was written, and the log did
    not read back ('linear_acceleration.y not a finite number')."""
    csv = iv.load_drive(two_channel)
    csv.columns["accel_lat_mps2"][50] = np.nan
    with pytest.raises(iv.InputError, match=r"linear_acceleration\.y at 5\.00 s is not a finite number \(nan\)"):
        iv.convert(csv, tmp_path / "nan.mcap")
    assert list(tmp_path.iterdir()) == []


def test_convert_then_evaluate_gives_the_drives_metrics(two_channel, converted):
    """Gravity and the gyro's x and y of a converted two-channel drive are placeholders (one value
    throughout): no mount is estimated from them (a wrong one was applied by default: 8.00 -> 7.93 m
    INS CRSE on the bundled motorway), no --imu-axes is suggested, and gins is left out."""
    direct = iv.evaluate(two_channel)
    via_log = iv.evaluate(converted)
    got = json.loads(via_log.to_json())
    assert [e["name"] for e in got["estimators"]] == [e["name"] for e in json.loads(direct.to_json())["estimators"]]
    assert "gins" not in [e["name"] for e in got["estimators"]]
    assert got["warnings"] == [], got["warnings"]
    np.testing.assert_allclose(_ins_crse(via_log), _ins_crse(direct), rtol=1e-6)


def test_a_log_whose_lateral_axis_reads_zero_gets_no_mount(two_channel, tmp_path, caplog):
    """The log the converter wrote before (lateral 0 throughout): the lateral is no measurement, so
    no yaw mount is estimated from it and the metrics are the drive's."""
    csv = iv.load_drive(two_channel)
    del csv.columns["accel_lat_mps2"]
    zero = tmp_path / "zero-lateral.mcap"
    iv.convert(csv, zero)
    with caplog.at_level(logging.INFO, logger="ionav_viz"):
        via_log = iv.evaluate(zero, estimators=["ins"])
    assert not any("applied the IMU mount" in w or "--imu-axes" in w for w in via_log.warnings), via_log.warnings
    assert "accel y, accel z, gyro x, gyro y read one value over the whole log (not measured)" in caplog.text
    np.testing.assert_allclose(_ins_crse(via_log), _ins_crse(iv.evaluate(two_channel, estimators=["ins"])), rtol=1e-6)


def test_gins_asked_for_on_a_two_channel_log_is_left_out_with_its_reason(converted):
    proc = run_cli("evaluate", str(converted), "--estimators", "ins,gins", "--json")
    assert proc.returncode == 0, proc.stderr
    assert [e["name"] for e in json.loads(proc.stdout)["estimators"]] == ["ins"]
    assert "GNSS/INS 3D left out" in proc.stderr and "all six IMU axes, measured" in proc.stderr, proc.stderr


def test_a_mount_given_for_a_log_with_unmeasured_axes_is_one_line(converted):
    proc = run_cli("evaluate", str(converted), "--imu-mount", "roll=1,pitch=2,yaw=3", "--no-idnn")
    _one_line_error(proc, str(converted), "accel z, gyro x, gyro y read one value over the whole log (not measured)", "--imu-mount")


def test_bundled_motorway_converted_and_evaluated_keeps_its_ins_crse(tmp_path):
    """The issue's case by hand: convert motorway, then evaluate the log (mean INS CRSE 8.00 m both)."""
    out = tmp_path / "m.mcap"
    iv.convert("motorway", out)
    a, b = iv.evaluate("motorway", estimators=["ins"]), iv.evaluate(out, estimators=["ins"])
    assert a.summary["ins"]["crse_m"]["mean"] == pytest.approx(b.summary["ins"]["crse_m"]["mean"], rel=1e-6)


# ---------------------------------------------------------------------------------------------
# JSON output: plug-ins' and reports' values become plain JSON at one boundary


class _Described:
    """A plug-in (ConstantSpeed's estimate) whose describe() holds what numpy and Python give."""

    name = "described"
    label = "Described"

    def __init__(self, info):
        self.info = info

    def estimate(self, inputs):
        disp = np.repeat(inputs.speed0_mps[:, None], inputs.n_windows, axis=1) * 1.0
        return iv.Estimate(disp_m=disp, yaw_rate_radps=np.zeros_like(disp))

    def describe(self):
        return self.info


HOSTILE_INFO = {"gains": np.array([[1.0, np.nan], [np.inf, -np.inf]]), "n": np.int64(3), "f32": np.float32(0.5),
                "ok": np.bool_(True), "weights": Path("/models/w.safetensors"), "shape": (2, 3), "nan": float("nan"),
                "set": {3, 1, 2}, 7: "int key", "empty": np.zeros((0, 2))}
PLAIN_INFO = {"gains": [[1.0, None], [None, None]], "n": 3, "f32": 0.5, "ok": True, "weights": "/models/w.safetensors",
              "shape": [2, 3], "nan": None, "set": [1, 2, 3], "7": "int key", "empty": []}


def test_plain_json_converts_what_numpy_and_plugins_give():
    assert plain_json(HOSTILE_INFO) == PLAIN_INFO
    text = dumps_json({"x": np.float64("nan"), "y": [np.float32("inf")]})
    assert json.loads(text) == {"x": None, "y": [None]} and "NaN" not in text and "Infinity" not in text


def test_a_plugin_describing_numpy_values_gets_plain_json(tmp_path):
    """--json crashed with 'Object of type ndarray is not JSON serializable' (a traceback)."""
    report = iv.evaluate(["roundabout"], 10.0, iv.Every(60.0), run=iv.RunOptions(plugins=[_Described(HOSTILE_INFO)], without=["idnn"]))
    got = json.loads(report.to_json())
    assert got["estimators"][-1]["info"] == PLAIN_INFO
    assert "Described" in report.to_text()


def test_cli_json_with_a_numpy_plugin_is_valid_json(tmp_path):
    (tmp_path / "npest.py").write_text(
        "import numpy as np\n"
        "from ionav_viz import Estimate\n\n"
        "class NumpyInfo:\n"
        "    name, label = 'npinfo', 'Numpy info'\n\n"
        "    def estimate(self, inputs):\n"
        "        disp = np.repeat(inputs.speed0_mps[:, None], inputs.n_windows, axis=1) * 1.0\n"
        "        return Estimate(disp_m=disp, yaw_rate_radps=np.zeros_like(disp))\n\n"
        "    def describe(self):\n"
        "        return {'gains': np.array([1.0, np.nan, np.inf]), 'k': np.float64(2.5), 'mode': ('a', 'b')}\n")
    proc = run_cli("evaluate", "roundabout", "--estimator", "./npest.py:NumpyInfo", "--every", "60s", "--no-idnn", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "NaN" not in proc.stdout and "Infinity" not in proc.stdout
    info = json.loads(proc.stdout)["estimators"][-1]["info"]
    assert info == {"gains": [1.0, None, None], "k": 2.5, "mode": ["a", "b"]}


@pytest.mark.parametrize(("info", "fragment"), [("cycle", "holds itself"), ("deep", "is nested more than 16 levels")])
def test_a_plugin_describing_a_cycle_or_a_deep_value_is_one_line(info, fragment):
    value: dict = {}
    if info == "cycle":
        value["self"] = value
    else:
        inner = value
        for _ in range(100):
            inner["x"] = {}
            inner = inner["x"]
    with pytest.raises(iv.InputError, match=rf"estimator 'described': describe\(\) returned a value that {fragment}"):
        iv.evaluate(["roundabout"], 10.0, iv.Every(60.0), run=iv.RunOptions(plugins=[_Described(value)], without=["idnn"])).to_json()


def test_the_recording_carries_the_plugins_plain_report(tmp_path):
    """The report stored in a recording passes the same boundary: figures read it back."""
    from ionav_viz.viz.recording_info import report_json

    result = iv.replay("roundabout", output=tmp_path / "r.rrd", run=iv.RunOptions(plugins=[_Described(HOSTILE_INFO)], without=["idnn"]))
    stored = json.loads(report_json(result.path))
    assert next(e for e in stored["estimators"] if e["name"] == "described")["info"] == PLAIN_INFO
    assert {p.name for p in iv.figures(result.path, tmp_path / "figs")} == FIGURE_FILES


def test_exports_and_nan_metrics_are_plain_json(tmp_path):
    """An undefined metric (final_error_pct below 10 m driven) is null in --json and the GeoJSON is
    valid strict JSON."""
    report = iv.evaluate(["stationary"], 10.0, iv.Every(30.0), estimators=["ins"], export=tmp_path / "x")
    text = report.to_json()
    assert "NaN" not in text and any(s["ins"]["final_error_pct"] is None for s in json.loads(text)["sequences"])
    geo = (tmp_path / "x" / "tracks.geojson").read_text()
    json.loads(geo, parse_constant=lambda token: pytest.fail(f"{token} in tracks.geojson"))


def test_stationary_drive_has_undefined_metrics():
    """The case above relies on the stationary drive having undefined percentages."""
    report = iv.evaluate(["stationary"], 10.0, iv.Every(30.0), estimators=["ins"])
    assert any(math.isnan(v) for v in report.metric("ins", "final_error_pct"))


def test_an_outage_plan_with_numpy_values_is_plain_json():
    from ionav_viz.experiment.plan_file import PlanFile

    plan = PlanFile(source="x.mcap", source_sha256="0" * 64, drive="x", outage_s=np.float64(10.0), placement="every 30 s",
                    placement_options={"every_s": np.float64(30.0), "seed": np.int64(3), "at": np.array([1.0, np.nan])},
                    start_stamps_s=(np.float64(100.0),), start_s=(np.float64(0.0),), clock="UNIX seconds")
    body = json.loads(plan.to_json())
    assert body["placement_options"] == {"every_s": 30.0, "seed": 3, "at": [1.0, None]} and body["outages"][0]["end_s"] == 10.0


# ---------------------------------------------------------------------------------------------
# figures: hostile reports, outputs that are files, signals and full disks while drawing

FIGURE_FILES = {f"{f}.{x}" for f in ("drift", "cdf", "outages", "outages-wide", "worst", "calibration") for x in ("svg", "pdf", "png")}


@pytest.fixture(scope="session")
def report(tmp_path_factory) -> Path:
    """One drive's evaluate --json (INS DR and odometry, outages every 60 s)."""
    path = tmp_path_factory.mktemp("report") / "report.json"
    path.write_text(iv.evaluate("roundabout", 10.0, iv.Every(60.0), estimators=["ins", "odo"]).to_json())
    return path


def _variant(report: Path, folder: Path, change) -> Path:
    rep = json.loads(report.read_text())
    change(rep)
    out = folder / "variant.json"
    out.write_text(json.dumps(rep))
    return out


def _nulls(rep: dict) -> None:
    rep["drift"]["ins"]["mean_m"][3] = None
    rep["drift"]["odo"] = {k: [None] * len(v) if k != "t_s" else v for k, v in rep["drift"]["odo"].items()}
    rep["sequences"][0]["ins"]["final_position_error_m"] = None
    rep["final_error_percentiles"]["ins"]["p50"] = None
    rep["worst_tracks"]["odo"]["east_m"][2] = None


def test_a_report_with_null_drift_is_drawn_and_what_is_left_out_is_said(report, tmp_path, caplog):
    """Was a TypeError traceback. Values the report leaves undefined are not drawn, each figure
    says what it left out, and an estimator with nothing defined is left out of that figure."""
    bad = _variant(report, tmp_path, _nulls)
    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        written = iv.figures(bad, tmp_path / "figs")
    assert {p.name for p in written} == FIGURE_FILES == {p.name for p in (tmp_path / "figs").iterdir()}
    said = [r.getMessage() for r in caplog.records]
    assert any(m.startswith("figures: drift:") and "Odometry has no defined point, left out" in m and "INS DR: 1 of" in m for m in said), said
    assert any(m.startswith("figures: cdf:") and "INS DR: 1 of" in m for m in said), said
    assert any(m.startswith("figures: worst:") and "Odometry: 1 of" in m for m in said), said
    assert "Odometry" not in (tmp_path / "figs" / "drift.svg").read_text()
    assert "INS DR (p50 n/a)" in (tmp_path / "figs" / "cdf.svg").read_text()


def _deep(rep: dict) -> None:
    inner = rep["estimators"][0]
    for _ in range(80):
        inner["info"] = {}
        inner = inner["info"]


HOSTILE_REPORTS = {
    "not JSON": (lambda path: path.write_bytes(b"%PDF-1.4\n\xe2\xe3"), "not UTF-8 text"),
    "truncated": (lambda path: path.write_text('{"drive": "x", "drift": {'), "not valid JSON"),
    "Infinity": (lambda path: path.write_text('{"drive": "x", "outage_s": Infinity}'), "Infinity is not a number JSON allows"),
    "overflow": (lambda path: path.write_text('{"drive": "x", "outage_s": 1e999}'), "1e999 overflows to infinity"),
    "nested brackets": (lambda path: path.write_text("[" * 100_000 + "]" * 100_000), "nested 100000 levels deep"),
    "huge": (lambda path: os.truncate(path.write_bytes(b"") or path, 100 << 20), "104857600 bytes is too large for a report"),
    "an array": (lambda path: path.write_text("[1, 2]"), "a JSON array, not a report"),
    "several reports": (lambda path: path.write_text('{"scenarios": {}}'), "holds one report per scenario"),
}
HOSTILE_FIELDS = {
    "drift not numbers": (lambda rep: rep["drift"]["ins"]["mean_m"].__setitem__(2, "x"), "drift.ins.mean_m[2]: 'x' is not a number"),
    "drift lengths differ": (lambda rep: rep["drift"]["odo"]["p90_m"].pop(), "drift.odo: t_s, mean_m, p10_m and p90_m differ in length"),
    "no drift for one": (lambda rep: rep["drift"].pop("odo"), "drift.odo: missing"),
    "a huge value": (lambda rep: rep["worst_tracks"]["ins"]["east_m"].__setitem__(1, 1e300), "worst_tracks.ins.east_m[1]: 1e+300 is beyond any drive"),
    "negative length": (lambda rep: rep.__setitem__("outage_s", -10), "outage_s: -10 is not an outage length"),
    "estimators a string": (lambda rep: rep.__setitem__("estimators", "ins"), "estimators: is not a list of estimators"),
    "a bad colour": (lambda rep: rep["estimators"][0].__setitem__("color", [300, 0, 0]), "estimators[0].color: [300, 0, 0] is not an RGB triple"),
    "an outage without one": (lambda rep: rep["sequences"][1].pop("odo"), "sequences[1].odo: missing"),
    "a boolean final error": (lambda rep: rep["sequences"][0]["ins"].__setitem__("final_position_error_m", True),
                              "sequences[0].ins.final_position_error_m: True is not a number"),
    "no outages": (lambda rep: rep.__setitem__("n_sequences", 0), "n_sequences: 0 is not a count of outages"),
    "deeply nested info": (_deep, "levels deep; a report nests at most 64"),
}


@pytest.mark.parametrize("case", list(HOSTILE_REPORTS) + list(HOSTILE_FIELDS))
def test_hostile_reports_are_one_line_and_write_nothing(report, tmp_path, case):
    if case in HOSTILE_REPORTS:
        write, fragment = HOSTILE_REPORTS[case]
        bad = tmp_path / "bad.json"
        write(bad)
    else:
        change, fragment = HOSTILE_FIELDS[case]
        bad = _variant(report, tmp_path, change)
    out = tmp_path / "figs"
    proc = run_cli("figures", str(bad), "-o", str(out))
    _one_line_error(proc, str(bad), fragment, "ionav-viz evaluate")
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [bad.name]


def test_figures_onto_an_existing_file_is_one_line(report, tmp_path):
    """Was a FileExistsError traceback."""
    target = tmp_path / "paper.pdf"
    target.write_bytes(b"my paper")
    _one_line_error(run_cli("figures", str(report), "-o", str(target)), str(target), "not a folder")
    assert target.read_bytes() == b"my paper"
    _one_line_error(run_cli("figures", str(report), "-o", str(target / "figs")), "not a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paper.pdf"]


def test_figures_leave_the_callers_matplotlib_alone(report, tmp_path):
    """viz.figures called matplotlib.use('Agg'): a caller's backend was switched for good."""
    import matplotlib

    before, font = matplotlib.get_backend(), matplotlib.rcParams["font.size"]
    matplotlib.use("pdf")
    try:
        iv.figures(report, tmp_path / "figs", formats=("png",))
        assert matplotlib.get_backend() == "pdf" and matplotlib.rcParams["font.size"] == font
    finally:
        matplotlib.use(before)


def test_a_full_disk_while_drawing_leaves_the_folder_as_it_was(report, tmp_path, monkeypatch):
    """No room for the fifth file: one line naming the folder; the earlier figures, the user's
    other files and no temporary folder are what is left."""
    from matplotlib.figure import Figure

    from ionav_viz.core.errors import ToolFailure

    out = tmp_path / "figs"
    out.mkdir()
    before = {name: f"old {name}".encode() for name in FIGURE_FILES} | {"notes.txt": b"mine"}
    for name, data in before.items():
        (out / name).write_bytes(data)
    real, calls = Figure.savefig, []

    def failing(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 5:
            raise OSError(28, "No space left on device")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", failing)
    with pytest.raises(ToolFailure, match=r"figs/cdf\.pdf: write failed \(No space left on device\); is the disk full\?"):
        iv.figures(report, out)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figs"]
    monkeypatch.setattr(Figure, "savefig", real)
    again = {p.name for p in iv.figures(report, out, formats=("pdf",))}
    assert again == {name for name in FIGURE_FILES if name.endswith(".pdf")}
    assert (out / "notes.txt").read_bytes() == b"mine" and (out / "drift.pdf").read_bytes().startswith(b"%PDF")
    assert (out / "drift.png").read_bytes() == b"old drift.png"  # a format not asked for is left as it was


@pytest.mark.parametrize("existing", [False, True])
def test_sigterm_while_drawing_leaves_the_folder_as_it_was(report, tmp_path, existing):
    """A real SIGTERM once the first figure is written: exit 143, and the output folder as it was
    (absent, or with its old figures and other files); no temporary folder left beside it."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "figs"
    before = {name: b"old" for name in FIGURE_FILES} | {"notes.txt": b"mine"} if existing else None
    if existing:
        out.mkdir()
        for name, data in before.items():
            (out / name).write_bytes(data)
    proc = subprocess.Popen([sys.executable, "-m", "ionav_viz.cli", "figures", str(report), "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while proc.poll() is None:  # until the first figure is drawn (or the command ends)
        if any(p.read_bytes() != b"old" for p in tmp_path.rglob("drift.png")):  # in the temporary folder (or, before, in figs)
            break
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 143, (proc.returncode, err)
    if existing:
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    else:
        assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == (["figs"] if existing else []), list(tmp_path.iterdir())


def test_a_staging_folder_is_hidden_beside_its_output_and_gone_however_the_block_ends(tmp_path):
    with staging_folder(tmp_path / "out") as stage:
        assert stage.parent == tmp_path and stage.name.startswith(".out.")
        assert stage.stat().st_mode & 0o777 == 0o777 & ~current_umask()  # an output's permissions, not mkdtemp's 0700
        (stage / "half-written").write_text("x")
    with pytest.raises(KeyboardInterrupt), staging_folder(tmp_path / "out") as stage:
        (stage / "half-written").write_text("x")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_a_staging_folder_that_cannot_be_made_raises_what_the_caller_says(tmp_path, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("tempfile.mkdtemp", full)
    with pytest.raises(InputError, match="No space left"), staging_folder(tmp_path / "out", refused=lambda exc: InputError(exc.strerror, "free some")):
        pass
    with pytest.raises(OSError, match="No space left"), staging_folder(tmp_path / "out"):
        pass


def test_long_lists_of_objects_are_written_a_row_each():
    """Reports are indented, but a list of more than 20 objects (the outages) is one object to a
    line, written by the C encoder (the pure-Python indenting one took 4.6 s for a 240 h fleet), and
    the text parses to what the compact form does."""
    import json

    from ionav_viz.core.json_out import dumps_json

    value = {"sequences": [{"drive": "V", "start_s": float(i), "ins": {"crse_m": 0.5 * i}} for i in range(25)],
             "few": [{"a": 1}, {"b": [1, 2]}], "curve": [0.5, 1.5, float("nan")]}
    text = dumps_json(value)
    lines = text.splitlines()
    rows = [ln for ln in lines if ln.startswith('    {"drive": "V"')]
    assert len(rows) == 25 and rows[3] == '    {"drive": "V", "start_s": 3.0, "ins": {"crse_m": 1.5}},'
    assert '  "curve": [0.5, 1.5, null]' in lines and '      "a": 1' in lines  # a short list of objects stays indented
    assert json.loads(text) == json.loads(dumps_json(value, indent=None))


@pytest.mark.parametrize("command", [
    ["simulate", "roundabout", "-o", "{pkg}/data/samples/V-sim-new.csv"],
    ["replay", "roundabout", "--estimators", "ins", "-o", "{pkg}/data/new.rrd"],
    ["evaluate", "roundabout", "--estimators", "ins", "--export", "{pkg}/data/exported"],
])
def test_the_installed_package_is_never_written_to(command, tmp_path):
    """docs/robustness.md: the installed package is read-only package data. 'simulate -o' onto a
    bundled drive's path replaced the shipped drive with exit code 0 (a tour found it)."""
    pkg = Path(iv.__file__).resolve().parent
    args = [a.format(pkg=pkg) for a in command]
    target = Path(args[-1])
    try:
        proc = run_cli(*args, cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert "is inside the installed ionav-viz package" in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr
        assert not target.exists()
    finally:  # never leave a written file in the package, even when the check fails
        if target.is_file():
            target.unlink()
        elif target.is_dir():
            import shutil

            shutil.rmtree(target)


def test_simulate_bundled_alone_may_write_into_the_package(monkeypatch):
    """The refusal of outputs inside the package stopped 'simulate --bundled ionav_viz/data/samples',
    the one way the bundled samples are regenerated, blaming an -o never given (a review found it):
    its writes pass package_ok; every other output check refuses the same path."""
    from ionav_viz.api import simulation
    from ionav_viz.core.fileio import PACKAGE_DIR, check_output_file

    target = PACKAGE_DIR / "data" / "samples" / "V-sim-roundabout.csv"
    assert check_output_file(target, package_ok=True) == target
    with pytest.raises(InputError, match="inside the installed ionav-viz package"):
        check_output_file(target)
    seen = []  # what each sample's write would be given (nothing is written here)
    monkeypatch.setattr(simulation, "write_simulated_drive", lambda path, *a, **k: seen.append(k.get("package_ok")) or Path(path))
    simulation.simulate_bundled(PACKAGE_DIR / "data" / "samples")
    assert seen and all(seen)


@pytest.mark.parametrize(("key", "holds"), [("scenarios", "one report per scenario (evaluate --scenario)"),
                                            ("by_event", "one report per manoeuvre type (evaluate --by-event)")])
def test_several_reports_are_refused_saying_what_figures_takes(tmp_path, key, holds):
    # issue 63: the hint said "write one drive's report", though one report of several drives is drawn
    bad = tmp_path / "several.json"
    bad.write_text(json.dumps({key: {}, "worst": []}))
    proc = run_cli("figures", str(bad), "-o", str(tmp_path / "figs"))
    _one_line_error(proc, str(bad), holds, "one drive or several, one outage length")
    assert "one drive's" not in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [bad.name]
