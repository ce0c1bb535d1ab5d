"""Hostile inputs, round 4, on what ionav-viz writes: figures of a report, JSON output with
plug-ins' values, and converted MCAP logs (issue 45, points 3 and 4).

Each test fails without its fix. Bad input is exit code 2, one line on stderr starting with
``error:`` that names the file or field, no traceback, and nothing written.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv

from .conftest import run_cli

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
