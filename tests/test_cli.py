import json

import pytest

from .conftest import run_cli


def test_help_lists_commands_without_heavy_imports():
    proc = run_cli("--help")
    assert proc.returncode == 0
    assert "evaluate" in proc.stdout and "simulate" in proc.stdout
    # no heavy import at start-up: numpy/torch/rerun stay out of the help path
    proc = run_cli("--help", env={"PYTHONPROFILEIMPORTTIME": "1"})
    assert "torch" not in proc.stderr and "rerun" not in proc.stderr and "numpy" not in proc.stderr and "matplotlib" not in proc.stderr


def test_evaluate_json_schema():
    proc = run_cli("evaluate", "roundabout", "--outage", "10s", "--json", "--no-idnn")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert rep["drive"] == "V-sim-roundabout" and rep["outage_s"] == 10
    seq = rep["sequences"][0]
    assert {"start_s", "gnss_distance_m", "ins"} <= set(seq)
    assert set(seq["ins"]) == {"crse_m", "cae_m", "aeps_m", "yaw_crse_radps", "yaw_cae_radps", "yaw_aeps_radps", "final_position_error_m", "final_error_pct"}
    assert set(rep["summary"]["ins"]["crse_m"]) == {"max", "min", "mean", "std"}
    # the final error as a percentage of the outage's GNSS distance, undefined below 10 m driven
    pcts = []
    for s in rep["sequences"]:
        if s["gnss_distance_m"] >= 10.0:
            assert s["ins"]["final_error_pct"] == pytest.approx(100 * s["ins"]["final_position_error_m"] / s["gnss_distance_m"])
            pcts.append(s["ins"]["final_error_pct"])
        else:
            assert s["ins"]["final_error_pct"] is None
    assert rep["summary"]["ins"]["final_error_pct"]["mean"] == pytest.approx(sum(pcts) / len(pcts))
    # 600 s drive, outages after the 30 s warm-up: (600 - 30) // 10 = 57 sequences
    assert rep["n_sequences"] == len(rep["sequences"]) == 57
    starts = [s["start_s"] for s in rep["sequences"]]
    assert all(abs((b - a) - 10.0) < 1e-6 for a, b in zip(starts, starts[1:]))


def test_bad_outage_and_unknown_drive_are_usage_errors():
    proc = run_cli("evaluate", "roundabout", "--outage", "ten")
    assert proc.returncode == 2 and "not a duration" in proc.stderr
    proc = run_cli("evaluate", "roundabot", "--no-idnn")
    assert proc.returncode == 2 and "did you mean roundabout" in proc.stderr
    proc = run_cli("evaluate", "roundabout", "--outage", "1500ms", "--no-idnn")
    assert proc.returncode == 2 and "whole number of seconds" in proc.stderr


def test_version():
    proc = run_cli("--version")
    assert proc.returncode == 0 and proc.stdout.startswith("ionav-viz 0.")


@pytest.mark.parametrize("args, option", [(["--steps", "30"], "--steps"), (["--steps-yaw", "0"], "--steps-yaw"),
                                          (["--lr-decay-tail", "1.5"], "--lr-decay-tail"),
                                          (["--feedback-noise", "-1"], "--feedback-noise")])
def test_train_refuses_bad_hyperparameters_before_any_work(tmp_path, args, option):
    out = tmp_path / "m"
    proc = run_cli("train", "-o", str(out), "-q", *args)
    assert proc.returncode == 2 and option in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize("steps", ["-1", "0", "21"])
def test_architectures_takes_the_time_steps_a_model_may_have(steps):
    """'architectures --steps -1' was a ValueError traceback (exit 1), and --steps 0 or 1000 printed
    a table of networks no model may have (train takes 1-20); refused now as train refuses them."""
    proc = run_cli("architectures", "--steps", steps)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    assert proc.stderr == f"error: --steps: {steps} time steps (n_steps_disp) out of range (hint: use 1 to 20 time steps (2 s at 10 Hz))\n"
    table = run_cli("architectures", "--steps", "20")
    assert table.returncode == 0 and table.stdout.splitlines()[1].split() == ["8", "257", "105", "242", "706", "938"]


def test_worst_outages_in_json_text_and_replay(tmp_path):
    """``worst``: the three outages with the largest INS DR final error, found here from the JSON's
    own sequences; the text table and replay's output list the same three."""
    proc = run_cli("evaluate", "sharp-cornering", "hard-brake", "--json", "--estimators", "ins,odo")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    per_drive: dict = {}
    for s in rep["sequences"]:
        per_drive.setdefault(s["drive"], []).append(s)
    ranked = sorted(((s["ins"]["final_position_error_m"], s["drive"], i + 1, s) for d, seqs in per_drive.items()
                     for i, s in enumerate(seqs)), key=lambda r: -r[0])[:3]
    assert rep["worst_of"] == "ins"
    assert [(w["drive"], w["number"]) for w in rep["worst"]] == [(d, n) for _, d, n, _ in ranked]
    for w, (_, _, _, s) in zip(rep["worst"], ranked):
        assert w["start_s"] == s["start_s"] and w["end_s"] == s["start_s"] + 10
        assert w["final_error_m"] == {e: s[e]["final_position_error_m"] for e in ("ins", "odo")}
    text = run_cli("replay", "sharp-cornering", "--estimators", "ins,odo", "-o", str(tmp_path / "s.rrd")).stderr
    lines = text[text.index("Worst outages by INS DR final position error"):].splitlines()[3:6]
    sharp = [r for r in ranked if r[1] == "V-sim-sharp-cornering"] or ranked
    assert lines[0].split()[0] == f"#{sharp[0][2]}" and f"{sharp[0][0]:.2f}" in lines[0]
    assert len(lines) == 3 and all(line.startswith("#") for line in lines)


def test_overview_has_a_row_per_drive_and_a_total():
    """The total row is over every outage: its mean is the outage-weighted mean of the drives' rows."""
    proc = run_cli("evaluate", "sharp-cornering", "hard-brake", "--overview", "--estimators", "ins,odo", "--markdown")
    assert proc.returncode == 0, proc.stderr
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in proc.stdout.splitlines()[2:]]
    assert [r[0] for r in rows] == ["V-sim-sharp-cornering", "V-sim-hard-brake", "total"]
    n = [int(r[1]) for r in rows]
    crse = [float(r[2]) for r in rows]
    assert n[2] == n[0] + n[1]
    assert crse[2] == pytest.approx((n[0] * crse[0] + n[1] * crse[1]) / n[2], abs=0.01)


PLACEMENT_AND_QUIET = {"--every", "--at", "--random", "--seed", "--on", "-q", "--quiet"}


@pytest.mark.parametrize("command", ["replay", "evaluate", "screenshot"])
def test_every_command_that_places_outages_takes_the_same_options(command):
    import typer.main

    from ionav_viz.cli import app

    group = typer.main.get_command(app)
    cmd = group.get_command(group.context_class(group, info_name="ionav-viz"), command)
    options = {opt for param in cmd.params for opt in getattr(param, "opts", [])}
    assert options >= PLACEMENT_AND_QUIET, PLACEMENT_AND_QUIET - options


def test_evaluate_places_outages_as_replay_does(tmp_path):
    """The same placement gives the same outages in evaluate and replay (and the API)."""
    import ionav_viz as iv

    for args, placement in ((["--every", "60s"], iv.Every(60.0)), (["--at", "30s,200s"], iv.At((30.0, 200.0))),
                            (["--random", "4", "--seed", "3"], iv.Random(4, 3)), (["--on", "roundabout"], iv.AroundEvents(("roundabout",)))):
        proc = run_cli("evaluate", "roundabout", *args, "--json", "--estimators", "ins")
        assert proc.returncode == 0, proc.stderr
        starts = [s["start_s"] for s in json.loads(proc.stdout)["sequences"]]
        expected = [o.start_s for o in iv.replay("roundabout", 10.0, placement, ["ins"], tmp_path / "r.rrd").outages]
        assert starts == expected and len(starts) >= 2, (args, starts, expected)
    assert [s["start_s"] for s in json.loads(run_cli("evaluate", "roundabout", "--at", "30s,200s", "--json").stdout)["sequences"]] == [30.0, 200.0]


def test_quiet_evaluate_prints_only_the_tables():
    proc = run_cli("evaluate", "--scenario", "motorway", "-q", "--every", "100s", "--estimators", "ins")
    assert proc.returncode == 0 and proc.stderr == "" and proc.stdout.startswith("motorway: V-sim-motorway"), proc.stderr
    loud = run_cli("evaluate", "--scenario", "motorway", "--every", "100s", "--estimators", "ins")
    assert loud.stderr.startswith("drives: motorway: the bundled synthetic test drives")


def test_screenshot_scenario_takes_the_placement(tmp_path):
    out = tmp_path / "shot.png"
    proc = run_cli("screenshot", "--scenario", "motorway", "--at", "100s", "--estimators", "ins", "--view", "local", "-o", str(out), "-q",
                   "--size", "640x360")
    assert proc.returncode == 0 and proc.stdout == "" and proc.stderr == "", proc.stderr
    assert out.stat().st_size > 10_000
    wrong = run_cli("screenshot", str(out), "--every", "30s", "-o", str(tmp_path / "x.png"))
    assert wrong.returncode == 2 and "--scenario" in wrong.stderr, wrong.stderr


def test_several_outage_lengths_warn_once_of_the_same_drive(tmp_path):
    """--outage 10s,30s evaluates (or replays) the drive once per length: 'no stationary stretch'
    was printed twice. Printed once; each length's report still carries it in its warnings."""
    proc = run_cli("evaluate", "motorway", "--span", "30s:150s", "--outage", "10s,30s", "--estimators", "ins", "--json")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("no stationary stretch of 3 s") == 1 and proc.stderr.count("\n") == 1, proc.stderr
    lengths = json.loads(proc.stdout)["lengths"]
    assert list(lengths) == ["10", "30"]
    assert all(any("no stationary stretch of 3 s" in w for w in rep["warnings"]) for rep in lengths.values())
    proc = run_cli("replay", "motorway", "--span", "30s:150s", "--outage", "10s,30s", "--estimators", "ins", "-q", "-o", str(tmp_path / "m.rrd"))
    assert proc.returncode == 0 and proc.stderr.count("no stationary stretch of 3 s") == 1, proc.stderr


def test_several_outage_lengths_with_an_option_they_do_not_go_with_say_so():
    """'several outage lengths are evaluated on drives given by name, without --plan' read as if
    a file path were wrong; it names the lengths and what to do now."""
    proc = run_cli("evaluate", "roundabout", "--outage", "10s,30s", "--plan", "p.json")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "10s,30s: several outage lengths do not go with --plan: give one length with it, or leave --plan out" in proc.stderr


def test_several_outage_lengths_export_a_folder_each_as_replay_does(tmp_path):
    """evaluate --outage 10s,30s --export was refused while replay with the same options wrote
    EXPORT/10s and EXPORT/30s; evaluate writes them too, each the export of that length alone."""
    args = ("evaluate", "roundabout", "--span", "0s:120s", "--estimators", "ins", "-q")
    proc = run_cli(*args, "--outage", "10s,30s", "--export", str(tmp_path / "both"))
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "both").iterdir()) == ["10s", "30s"]
    for length in ("10s", "30s"):
        alone = run_cli(*args, "--outage", length, "--export", str(tmp_path / length))
        assert alone.returncode == 0, alone.stderr
        assert (tmp_path / "both" / length / "outages.csv").read_text() == (tmp_path / length / "outages.csv").read_text()
