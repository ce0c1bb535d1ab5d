"""User estimators beside the built-ins: through the API, the CLI, the tables and the recording."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.experiment.registry import resolve
from ionav_viz.nav.protocol import EstimatorError

from .conftest import HANG_S, run_cli
from .test_replay import read_rrd

PLUGINS = Path(__file__).resolve().parent / "plugins"
ENV = {"PYTHONPATH": str(PLUGINS)}


@pytest.fixture(autouse=True)
def plugins_importable(monkeypatch):
    monkeypatch.syspath_prepend(str(PLUGINS))


def test_constant_speed_metrics_follow_from_its_definition():
    import toy_estimators

    report = iv.evaluate(["roundabout"], 10.0, estimators=["ins", toy_estimators.ConstantSpeed()])
    drive = iv.load_drive("roundabout")
    rep = report.to_dict()
    assert [e["name"] for e in rep["estimators"]] == ["ins", "const"]
    for seq in rep["sequences"]:
        # By hand: e = truth - estimate per window, and the estimate is v0 * 1 s in each of 10 windows,
        # so CAE = GNSS distance - 10 v0 and AEPS = CRSE / 10; the speed is the drive's at the start.
        v0 = float(np.interp(seq["start_s"], drive.t_s, drive.speed_mps))
        assert seq["const"]["cae_m"] == pytest.approx(seq["gnss_distance_m"] - 10 * v0, abs=1e-9)
        assert seq["const"]["aeps_m"] == pytest.approx(seq["const"]["crse_m"] / 10, abs=1e-12)
        assert seq["const"]["crse_m"] >= abs(seq["const"]["cae_m"]) - 1e-12
    # the INS numbers do not depend on which other estimators run
    alone = iv.evaluate(["roundabout"], 10.0, estimators=["ins"]).to_dict()
    assert alone["summary"]["ins"] == rep["summary"]["ins"]
    assert set(rep["improvement_pct"]) == {"const"}
    base, cand = rep["summary"]["ins"]["crse_m"]["mean"], rep["summary"]["const"]["crse_m"]["mean"]
    assert rep["improvement_pct"]["const"]["crse_m"] == pytest.approx(100 * (base - cand) / base)


def test_cli_json_tables_and_recording_show_the_plugin(tmp_path):
    spec = "toy_estimators:make_constant_speed"
    ev = run_cli("evaluate", "roundabout", "--json", "--estimator", spec, env=ENV)
    assert ev.returncode == 0, ev.stderr
    rep = json.loads(ev.stdout)
    assert [e["name"] for e in rep["estimators"]] == ["ins", "idnn", "odo", "ekf", "const"]
    assert {"ins", "idnn", "odo", "ekf", "const"} <= set(rep["sequences"][0]) and set(rep["improvement_pct"]) == {"idnn", "odo", "ekf", "const"}

    text = run_cli("evaluate", "roundabout", "--estimators", "ins", "--estimator", spec, env=ENV)
    assert text.returncode == 0, text.stderr
    assert "Constant speed (m)" in text.stdout and "Constant speed improvement over INS" in text.stdout
    assert "IDNN" not in text.stdout
    overview = run_cli("evaluate", "--scenario", "roundabout", "--overview", "--estimator", spec, env={**ENV, "COLUMNS": "1000"})  # one row per drive
    assert "Constant speed (m)" in overview.stdout and overview.stdout.count("Δ %") == 8  # IDNN, odometry, EKF and const, two blocks

    out = tmp_path / "r.rrd"
    proc = run_cli("replay", "roundabout", "-o", str(out), "-q", "--estimator", spec, env=ENV)
    assert proc.returncode == 0, proc.stderr
    rows, static = read_rrd(out)
    for entity in ["/map/const/live", "/local/const/live", "/signals/displacement_m/const", "/signals/yaw_rate_radps/const",
                   "/errors/crse_m/const", "/errors/position_error_m/const"]:
        assert entity in rows, entity
    assert {"/map/const/all", "/local/const/all"} <= static
    # the last CRSE of every outage in the recording is the JSON's
    crse = [v[0] for _, v in rows["/errors/crse_m/const"] if v and v[0] == v[0]]
    np.testing.assert_allclose(crse[9::10], [s["const"]["crse_m"] for s in rep["sequences"]], rtol=1e-12)


def test_a_plugin_gets_its_own_colour_and_legend():
    import toy_estimators

    from ionav_viz.experiment.registry import resolve
    from ionav_viz.viz.style import GNSS_COLOR, estimator_colors

    ests = resolve(["ins", "idnn", toy_estimators.ConstantSpeed()])
    colors = estimator_colors(ests)
    assert len(set(colors.values()) | {GNSS_COLOR}) == 4
    assert estimator_colors(ests) == colors  # fixed from run to run


@pytest.mark.parametrize(
    ("spec", "fragments"),
    [
        ("broken_import:Anything", ["broken_import:Anything", "cannot import", "no_such_module_anywhere"]),
        ("toy_estimators:Missing", ["toy_estimators:Missing", "has no Missing"]),
        ("toy_estimators:WrongShape", ["'wrong-shape'", "disp_m has shape", "expected"]),
        ("toy_estimators:NaNOutput", ["'nan-out'", "nan in outage 2, window 4"]),
        ("toy_estimators:Raises", ["'raises' failed", "ZeroDivisionError"]),
        ("not-a-spec", ["unknown estimator 'not-a-spec'", "MODULE:NAME"]),
    ],
)
def test_broken_plugins_are_one_line_errors_naming_them(spec, fragments):
    option = "--estimators" if ":" not in spec else "--estimator"
    proc = run_cli("evaluate", "roundabout", option, spec, env=ENV)
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


def test_broken_plugin_in_python_raises_the_package_error():
    import toy_estimators

    with pytest.raises(EstimatorError, match="nan-out"):
        iv.evaluate(["roundabout"], 10.0, estimators=["ins", toy_estimators.NaNOutput()])
    with pytest.raises(EstimatorError, match="ZeroDivisionError") as info:
        iv.evaluate(["roundabout"], 10.0, estimators=[toy_estimators.Raises()])
    assert isinstance(info.value.__cause__, ZeroDivisionError)  # the plug-in's traceback is kept


def test_entry_point_plugins_are_found_by_name(tmp_path, monkeypatch):
    dist = tmp_path / "toy_estimators_pkg-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: toy-estimators-pkg\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[ionav_viz.estimators]\nconst = toy_estimators:ConstantSpeed\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    chosen = resolve(["ins", "const"])
    assert [e.name for e in chosen] == ["ins", "const"] and chosen[1].label == "Constant speed"
    proc = run_cli("evaluate", "roundabout", "--estimators", "ins,const", "--json",
                   env={"PYTHONPATH": f"{tmp_path}:{PLUGINS}"})
    assert proc.returncode == 0, proc.stderr
    assert [e["name"] for e in json.loads(proc.stdout)["estimators"]] == ["ins", "const"]


def test_estimators_option_chooses_and_orders():
    proc = run_cli("evaluate", "roundabout", "--estimators", "idnn", "--json")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert [e["name"] for e in rep["estimators"]] == ["idnn"] and "improvement_pct" not in rep


def _console_script() -> Path:
    """The installed ``ionav-viz`` script: unlike ``python -m``, it does not put the current
    directory on ``sys.path``, as a user's shell runs it."""
    import sys

    script = Path(sys.executable).parent / "ionav-viz"
    if not script.is_file():
        pytest.skip("no ionav-viz console script beside this interpreter (not installed with pip)")
    return script


def _run_script(*args: str, cwd: Path):
    import os
    import subprocess

    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "IONAV_DATA")}
    return subprocess.run([str(_console_script()), *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=HANG_S)


@pytest.mark.parametrize("spec", ["myest:ConstantSpeed", "./myest.py:ConstantSpeed", "sub/myest.py:ConstantSpeed"])
def test_a_plugin_in_the_current_directory_or_a_file_loads_without_pythonpath(tmp_path, spec):
    """A module in the current directory, or a .py file by path (relative or absolute), loads as
    the user expects; a file's neighbours are importable from it."""
    folder = tmp_path / "sub" if spec.startswith("sub/") else tmp_path
    folder.mkdir(exist_ok=True)
    (folder / "myest_helpers.py").write_text("SPEED_FACTOR = 1.0\n")
    (folder / "myest.py").write_text((PLUGINS / "toy_estimators.py").read_text() + "\nfrom myest_helpers import SPEED_FACTOR  # a neighbour\n")
    proc = _run_script("evaluate", "roundabout", "--estimator", spec, "--every", "60s", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "left out" not in proc.stderr, proc.stderr  # odo applies here; nothing the user did not ask for is reported
    names = [e["name"] for e in json.loads(proc.stdout)["estimators"]]
    assert names[-1] == "const" and "ins" in names, names
    if spec.startswith("sub/"):  # and by its absolute path from elsewhere (one process more: once)
        absolute = _run_script("evaluate", "roundabout", "--estimator", f"{folder / 'myest.py'}:ConstantSpeed", "--every", "60s", "-q",
                               cwd=PLUGINS)
        assert absolute.returncode == 0 and "Constant speed" in absolute.stdout, absolute.stderr


def test_adding_a_plugin_warns_only_of_estimators_the_user_named(tmp_path):
    """The stationary drive has no usable vehicle speed, so odometry does not apply: a default
    built-in left out is not a warning (with a plug-in or --no-idnn), a named one is."""
    (tmp_path / "myest.py").write_text((PLUGINS / "toy_estimators.py").read_text())
    for extra in (["--estimator", "myest:ConstantSpeed"], ["--no-idnn", "--estimator", "./myest.py:ConstantSpeed"]):
        proc = _run_script("evaluate", "stationary", *extra, "--every", "30s", "-q", cwd=tmp_path)
        assert proc.returncode == 0 and proc.stderr == "", (extra, proc.stderr)
    # without a plug-in to import, the process is not the point
    proc = run_cli("evaluate", "stationary", "--no-idnn", "--every", "30s", "-q", cwd=tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    named = run_cli("evaluate", "stationary", "--estimators", "ins,odo", "--every", "30s", "-q", cwd=tmp_path)
    assert named.returncode == 0 and named.stderr.strip() == ("warning: Odometry left out: it does not apply to V-sim-stationary "
                                                              "(it needs a vehicle speed: wheel speeds, CAN speed or wheel odometry)")


@pytest.mark.parametrize(("spec", "fragment"), [("./missing.py:X", "no such file"), ("./notes.txt:X", "is not a .py file"),
                                                ("missing_module:X", "cannot import missing_module")])
def test_a_plugin_path_that_cannot_load_is_one_line(tmp_path, spec, fragment):
    (tmp_path / "notes.txt").write_text("not python")
    proc = _run_script("evaluate", "roundabout", "--estimator", spec, cwd=tmp_path)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and fragment in lines[0] and lines[0].startswith("error: --estimator:"), proc.stderr


def test_python_api_takes_plugins_and_leaves_defaults_out():
    import toy_estimators

    report = iv.evaluate(["roundabout"], 10.0, iv.Every(60.0), run=iv.RunOptions(plugins=[toy_estimators.ConstantSpeed()], without=["idnn"]))
    assert [e["name"] for e in report.to_dict()["estimators"]] == ["ins", "odo", "ekf", "const"]  # run order
    with pytest.raises(EstimatorError, match="not a built-in"):
        iv.evaluate(["roundabout"], run=iv.RunOptions(without=["const"]))


@pytest.mark.parametrize(
    ("spec", "fragments"),
    [
        ("toy_estimators:WritesInputs", ["'writes' failed", "ValueError", "read-only"]),
        ("toy_estimators:ComplexOutput", ["'complex'", "disp_m is complex"]),
        ("toy_estimators:HugeOutput", ["'huge'", "disp_m is 1e+200 in outage 3, window 6", "beyond what a car does in 1 s"]),
        ("toy_estimators:AppliesRaises", ["'applies-raises'", "applies() failed", "KeyError"]),
        ("toy_estimators:AvailableRaises", ["'available-raises'", "available() failed", "no licence"]),
        ("toy_estimators:DescribesAList", ["'describes-list'", "describe() returned list, not a dict"]),
    ],
)
def test_hostile_plugins_are_one_line_errors(spec, fragments):
    """Round 3: a plug-in that writes into its inputs, returns complex or impossible numbers, or
    whose optional members raise or return the wrong type: one line naming it, exit 2."""
    proc = run_cli("evaluate", "roundabout", "--every", "60s", "--estimator", spec, env=ENV)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and "Traceback" not in proc.stderr and "Warning" not in proc.stderr, proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


def test_a_plugin_cannot_change_what_the_others_see():
    """The INS DR's metrics are the same whether a plug-in that writes into the drive runs before it
    or not (it fails; with writable inputs it changed the INS's first outage from 1.84 m to 15.45 m)."""
    import toy_estimators

    drive = iv.load_drive("roundabout")
    before = drive.lat_deg.copy()
    with pytest.raises(EstimatorError, match="read-only"):
        iv.evaluate([drive], 10.0, iv.Every(60.0), [toy_estimators.WritesInputs(), "ins"])
    np.testing.assert_array_equal(drive.lat_deg, before)


def test_a_plugin_named_as_a_built_in_is_refused():
    """A plug-in named 'ins', run without the INS DR, was taken as the INS DR: 'Odometry
    improvement over INS DR' was measured against the plug-in. A built-in's name is refused."""

    class Fake:
        name, label = "ins", "Fake"

        def estimate(self, inputs):
            disp = np.repeat(inputs.speed0_mps[:, None], inputs.n_windows, axis=1)
            return iv.Estimate(disp_m=disp, yaw_rate_radps=np.zeros_like(disp))

    with pytest.raises(EstimatorError, match=r"estimator 'ins' \(Fake\): that is a built-in estimator's name"):
        resolve(["odo"], plugins=[Fake()])
    with pytest.raises(EstimatorError, match="built-in estimator's name"):
        iv.evaluate("roundabout", estimators=["odo", Fake()])
    assert [e.name for e in resolve(["ins", "odo"])] == ["ins", "odo"]  # the built-ins themselves
