"""The Python API, in-process: the same results as the commands, placements as values, clear errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz import InputError

from .conftest import run_cli
from .test_replay import read_rrd

N_WIN = 10


def test_evaluate_to_json_is_exactly_what_the_command_prints():
    proc = run_cli("evaluate", "roundabout", "motorway", "--json")
    assert proc.returncode == 0, proc.stderr
    from ionav_viz.core import run_config

    with run_config.running({"command": "evaluate", "drives": ["roundabout", "motorway"], "json": True}):  # what the command carries
        report = iv.evaluate(["roundabout", "motorway"], outage_s=10.0)
    assert report.to_json() + "\n" == proc.stdout
    assert report.n_outages == 2 * 57 and report.estimators == ["ins", "idnn", "odo", "ekf"]
    # text and Markdown renderings come from the same report
    assert report.to_text().startswith("V-sim-roundabout+V-sim-motorway, 10 s GNSS outages")
    assert "| **CRSE** | max |" in report.to_markdown()


def test_report_fields_agree_with_each_other():
    report = iv.evaluate("hard-brake", 10.0, estimators=["ins"])
    crse = report.metric("ins", "crse_m")
    assert crse.shape == (report.n_outages,)
    assert report.summary["ins"]["crse_m"]["mean"] == pytest.approx(crse.mean())
    assert report.summary["ins"]["crse_m"]["std"] == pytest.approx(crse.std())  # population std, as the paper
    assert report.improvement_pct == {}  # nothing to compare with the INS
    assert report.improvement_ci95_pct == {}


def test_each_improvement_carries_a_95_percent_interval_in_the_json_and_the_text():
    report = iv.evaluate("hard-brake", 10.0, estimators=["ins", "odo"])
    (lo, hi), point = report.improvement_ci95_pct["odo"]["final_position_error_m"], report.improvement_pct["odo"]["final_position_error_m"]
    assert lo < point < hi
    assert report.to_dict()["improvement_ci95_pct"]["odo"]["crse_m"] == report.improvement_ci95_pct["odo"]["crse_m"]
    assert f"final position error {point:.1f} % (95 % interval {lo:.1f} to {hi:.1f} %)" in report.to_text()
    again = iv.evaluate("hard-brake", 10.0, estimators=["ins", "odo"])
    assert again.improvement_ci95_pct == report.improvement_ci95_pct  # seeded: the same on every run


@pytest.mark.parametrize(
    ("placement", "n_outages"),
    [(iv.At((12.0, 40.0)), 2), (iv.Every(150.0), 4), (iv.Random(3, seed=7), 3), (iv.Tile(), 57)],
)
def test_replay_with_placements(tmp_path, placement, n_outages):
    result = iv.replay("hard-brake", 10.0, placement, estimators=["ins"], output=tmp_path / "x.rrd")
    assert result.path == tmp_path / "x.rrd" and result.path.is_file()
    assert len(result.outages) == n_outages == result.report.n_outages
    assert all(o.end_s - o.start_s == 10.0 for o in result.outages)
    assert all(b.start_s >= a.end_s for a, b in zip(result.outages, result.outages[1:]))  # no overlap
    rows, _ = read_rrd(result.path)
    values = [v[0] for _, v in rows["/errors/crse_m/ins"]]
    assert sum(np.isfinite(values)) == n_outages * N_WIN
    # a NaN after every outage that GNSS follows, so the plot does not bridge the gap
    gaps = sum(b.start_s > a.end_s for a, b in zip(result.outages, result.outages[1:]))
    assert sum(np.isnan(values)) == gaps
    assert "/errors/crse_m/idnn" not in rows


def test_at_times_are_where_asked(tmp_path):
    result = iv.replay("hard-brake", 5.0, iv.At((12.0, 40.0)), estimators=["ins"], output=tmp_path / "x.rrd")
    assert [o.start_s for o in result.outages] == pytest.approx([12.0, 40.0], abs=0.05)
    rows, _ = read_rrd(result.path)
    t = np.array([t for t, v in rows["/errors/crse_m/ins"] if np.isfinite(v[0])])
    np.testing.assert_allclose(t, np.concatenate([12 + np.arange(1, 6), 40 + np.arange(1, 6)]), atol=0.05)


def test_evaluate_by_event_builds_reports_per_manoeuvre():
    by = iv.evaluate(["hard-brake", "sharp-cornering"], 10.0, by_event=["hard-brake", "sharp-cornering", "left-right"])
    assert set(by) == {"hard-brake", "sharp-cornering", "left-right"}
    assert {s["drive"] for s in by["hard-brake"].to_dict()["sequences"]} == {"V-sim-hard-brake"}
    assert by["left-right"].estimators == ["ins", "idnn", "odo", "ekf"]
    assert by["hard-brake"].to_text().startswith("hard-brake: V-sim-hard-brake, 10 s GNSS outages")


@pytest.mark.parametrize(
    ("call", "param", "fragment"),
    [
        (lambda out: iv.replay("hard-brake", 10.0, iv.At((5000.0,)), estimators=["ins"], output=out), "placement", "start time 5000 s"),
        (lambda out: iv.replay("hard-brake", 10.0, iv.At((12.0, 15.0)), estimators=["ins"], output=out), "placement", "overlaps"),
        (lambda out: iv.replay("hard-brake", 10.0, iv.Every(5.0), estimators=["ins"], output=out), "placement", "shorter than the outage"),
        (lambda out: iv.replay("hard-brake", 600.0, estimators=["ins"], output=out), "outage_s", "too short"),
        (lambda out: iv.replay("hard-brake", 2.5, estimators=["ins"], output=out), "outage_s", "whole number of seconds"),
    ],
)
def test_library_errors_make_sense_outside_a_shell(tmp_path, call, param, fragment):
    with pytest.raises(InputError) as info:
        call(tmp_path / "x.rrd")
    assert info.value.param == param and fragment in str(info.value)
    assert "--" not in str(info.value)  # no command-line option in a library message
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_load_drive_accepts_names_paths_and_drives(tmp_path):
    from ionav_viz.dataset.samples import samples_dir

    by_name = iv.load_drive("roundabout")
    by_path = iv.load_drive(samples_dir() / "V-sim-roundabout.csv")
    assert by_name.name == by_path.name == "V-sim-roundabout" and len(by_name) == len(by_path)
    assert iv.load_drive(by_name) is by_name
    with pytest.raises(InputError, match="unknown drive"):
        iv.load_drive("no-such-drive")


def test_the_package_exports_a_typed_api():
    import inspect

    for name in ("load_drive", "evaluate", "replay", "screenshot"):
        sig = inspect.signature(getattr(iv, name))
        assert sig.return_annotation != inspect.Signature.empty, name
    assert {"Estimate", "EstimatorInputs", "Report", "ReplayResult", "Tile", "Every", "At", "Random", "AroundEvents"} <= set(dir(iv))


def test_the_training_settings_are_exported_for_train_and_cross_validate():
    # iv.train(config=...) and iv.cross_validate(config=...) take a ModelConfig: it is part of the API
    assert "ModelConfig" in iv.__all__ and "ModelConfig" in dir(iv)
    config = iv.ModelConfig(epochs_disp=2, epochs_yaw=2, seed=1)
    config.validate()
    assert isinstance(iv.fine_tune_settings("shipped"), iv.ModelConfig)


def test_help_does_not_import_the_heavy_libraries():
    import subprocess
    import sys

    code = "import sys, ionav_viz; import ionav_viz.cli; print(sorted(m for m in ('numpy','torch','rerun','pyproj') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert json.loads(out.replace("'", '"')) == []


@pytest.mark.parametrize("call", [lambda: iv.evaluate("roundabout", outage_s="10"), lambda: iv.Random(1.5), lambda: iv.Random(2, seed=-1),
                                  lambda: iv.Every("30")])
def test_arguments_of_the_wrong_type_are_input_errors_naming_the_argument(call):
    """Round 3: a string outage length was a numpy TypeError naming no argument; Random(1.5) gave 46 outages."""
    with pytest.raises(iv.InputError) as info:
        call()
    assert info.value.param in ("outage_s", "placement")


@pytest.mark.parametrize(
    ("call", "param", "said"),
    [
        # "'float' object is not iterable", a numpy UFuncTypeError, and a report of no outage at all
        (lambda: iv.At(12.0), "placement", "outage start times 12.0: not a sequence of seconds"),
        (lambda: iv.At(("12",)), "placement", "outage start time '12' is not a number of seconds"),
        (lambda: iv.evaluate("roundabout", 10.0, iv.At(()), estimators=["ins"]), "placement", "outage start times (): not a sequence"),
        # "unknown event type(s) h, a, r, d, -, b, r, a, k, e", and "no GNSS outage of 2 s or more in this drive"
        (lambda: iv.AroundEvents("hard-brake"), "placement", "event types 'hard-brake': not a sequence of names"),
        (lambda: iv.evaluate("hard-brake", 10.0, iv.AroundEvents(()), estimators=["ins"]), "placement", "event types (): not a sequence"),
        # "unknown estimator 'i'"
        (lambda: iv.evaluate("roundabout", 10.0, estimators="ins"), "estimators", "estimators='ins' is not a sequence of estimators"),
    ],
)
def test_a_lone_value_where_a_sequence_goes_is_refused_saying_so(call, param, said):
    with pytest.raises(iv.InputError) as info:
        call()
    assert info.value.param == param and said in str(info.value), str(info.value)


def test_sequences_of_any_kind_still_place_outages():
    at = iv.At(np.array([12.0, 40.0]))
    assert at.times_s == (12.0, 40.0) and iv.AroundEvents(["hard-brake"]).types == ("hard-brake",)
    assert len(iv.evaluate("roundabout", 10.0, at, estimators=["ins"]).metric("ins", "crse_m")) == 2


def test_a_metric_the_report_does_not_hold_names_the_choices():
    """report.metric("idnn", "crse_m") on a report without the IDNN was a bare KeyError: 'idnn' (a
    typo in the metric, KeyError: 'crse'); now an InputError naming what the report holds."""
    report = iv.evaluate("roundabout", 10.0, estimators=["ins", "odo"])
    with pytest.raises(iv.InputError, match=r"no estimator 'idnn' in this report \(hint: choose from ins, odo\)") as info:
        report.metric("idnn", "crse_m")
    assert info.value.param == "estimator"
    with pytest.raises(iv.InputError, match=r"unknown metric 'crse' \(hint: choose from crse_m, cae_m, ") as info:
        report.metric("ins", "crse")
    assert info.value.param == "metric" and len(report.metric("odo", "crse_m")) == len(report.metric("ins", "final_error_pct"))


@pytest.mark.parametrize(("call", "param"), [
    (lambda tmp: iv.convert("roundabout", tmp / "x.mcap", read="x"), "read"),
    (lambda tmp: iv.outage_log("roundabout", tmp / "cut.csv", read="x"), "read"),
    (lambda tmp: iv.evaluate("roundabout", 10.0, run="x"), "run"),
    (lambda tmp: iv.evaluate(["roundabout", "motorway"], 10.0, read="x", engine=iv.Engine(1)), "read"),
    (lambda tmp: iv.cross_validate(["roundabout", "motorway"], 2, output=tmp, run="x"), "run"),
    (lambda tmp: iv.screenshot([tmp / "r.rrd"], tmp / "shots", shots="x"), "shots"),
    (lambda tmp: iv.find_events("roundabout", thresholds=iv.EventThresholds(hard_brake_g=-1)), "thresholds"),
    (lambda tmp: iv.load_drive("roundabout", iv.ReadOptions(gnss_limits=iv.GnssLimits(max_sigma_m=0.0))), "gnss_limits"),
])
def test_options_of_the_wrong_kind_or_out_of_range_are_input_errors_naming_them(call, param, tmp_path):
    """iv.convert(read="x") and evaluate(run="x") were AttributeErrors naming no argument, and
    EventThresholds(hard_brake_g=-1) was taken (only --threshold checked the ranges): a tour found them."""
    (tmp_path / "r.rrd").write_bytes(b"")
    with pytest.raises(iv.InputError) as info:
        call(tmp_path)
    assert info.value.param == param, (info.value.param, str(info.value))
    assert not (tmp_path / "x.mcap").exists() and not (tmp_path / "cut.csv").exists()


def test_the_worst_outage_example_prints_display_names():
    # issue 63: examples/worst_outage_screenshots.py printed the internal names ("ins 27.0 m, idnn 15.8 m")
    import importlib.util
    from pathlib import Path

    path = Path(__file__).parent.parent / "examples" / "worst_outage_screenshots.py"
    spec = importlib.util.spec_from_file_location("worst_outage_screenshots", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    report = iv.evaluate("hard-brake", 10.0, estimators=["ins", "odo"])
    worst = report.worst_outages(1)[0]
    line = example.worst_line("hard-brake", report, Path("shots/hard-brake-worst.png"))
    assert line == (f"hard-brake: outage {worst['number']} ({worst['start_s']:.0f}-{worst['end_s']:.0f} s), final error "
                    f"INS DR {worst['final_error_m']['ins']:.1f} m, Odometry {worst['final_error_m']['odo']:.1f} m "
                    "-> shots/hard-brake-worst.png")
