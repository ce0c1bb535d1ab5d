"""Hostile inputs, round 4, on what ionav-viz writes: figures of a report, JSON output with
plug-ins' values, and converted MCAP logs (issue 45, points 3 and 4).

Each test fails without its fix. Bad input is exit code 2, one line on stderr starting with
``error:`` that names the file or field, no traceback, and nothing written.
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.json_out import dumps_json, plain_json

from .conftest import run_cli

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
