"""Issue 63.3: two or more runs of the same outages side by side (``ionav-viz compare``, ``iv.compare``).

The golden numbers of the small hand-written reports are worked by hand in the comments (Student
t quantiles from the printed tables); the runs of a bundled drive are checked against numpy on the
files' own outages."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from .conftest import one_line_error, run_cli

pytestmark = pytest.mark.xdist_group("compare")

METRICS = (
    "crse_m",
    "cae_m",
    "aeps_m",
    "yaw_crse_radps",
    "yaw_cae_radps",
    "yaw_aeps_radps",
    "final_position_error_m",
    "final_error_pct",
)
EST = {"ins": ("INS DR", [230, 60, 50]), "odo": ("Odometry", [150, 60, 200]), "ekf": ("GNSS-aided INS", [0, 170, 190])}


def _report(
    values: dict[str, dict[str, list]],
    drive: str = "V-sim-roundabout",
    starts: list[float] | None = None,
    outage_s: float = 10.0,
    distances: list[float] | None = None,
) -> dict:
    """A report as ``evaluate --json`` writes it, with the fields compare reads: per estimator the
    given metrics (the others 0)."""
    n = len(next(iter(next(iter(values.values())).values())))
    starts = starts or [30.0 + 10.0 * k for k in range(n)]
    distances = distances or [100.0 + k for k in range(n)]
    sequences = [
        {
            "drive": drive,
            "start_s": starts[k],
            "gnss_distance_m": distances[k],
            **{e: {m: per.get(m, [0.0] * n)[k] for m in METRICS} for e, per in values.items()},
        }
        for k in range(n)
    ]
    return {
        "drive": drive,
        "outage_s": outage_s,
        "n_sequences": n,
        "sequences": sequences,
        "estimators": [{"name": e, "label": EST[e][0], "color": EST[e][1]} for e in values],
    }


# Hand-worked: the INS DR's CRSE goes from A = 2, 4, 6, 8, 10 to B = 3, 6, 9, 12, 15 (d = 1, 2, 3, 4, 5).
# mean(d) = 3; sd(d) = sqrt(((-2)^2 + 1 + 0 + 1 + 2^2) / 4) = sqrt(2.5) = 1.5811388; se = sd / sqrt(5) = 0.70710678;
# t(0.975, 4) = 2.7764451 (tables); half = 2.7764451 * 0.70710678 = 1.9632432: [1.0367568, 4.9632432].
# B's statistics: mean 9, median 9, std sqrt((36 + 9 + 0 + 9 + 36) / 5) = sqrt(18) = 4.2426407, min 3, max 15,
# rmse sqrt((9 + 36 + 81 + 144 + 225) / 5) = sqrt(99) = 9.9498744, sse 495. Change 3 of A's mean 6: +50 %.
# The CAE is the same in both (unchanged); the final error % is undefined (null) on outage 2 in both: 4 pairs,
# d = 0.5, -0.5, 1.5, 2.5: mean 1.0, sd sqrt((0.25 + 2.25 + 0.25 + 2.25) / 3) = 1.2909944, se 0.6454972,
# t(0.975, 3) = 3.1824463, half 2.0542603: [-1.0542603, 3.0542603], no clear change.
A = _report(
    {
        "ins": {
            "crse_m": [2.0, 4.0, 6.0, 8.0, 10.0],
            "cae_m": [-1.0, 1.0, -1.0, 1.0, -1.0],
            "final_error_pct": [1.0, None, 2.0, 3.0, 4.0],
        }
    }
)
B = _report(
    {
        "ins": {
            "crse_m": [3.0, 6.0, 9.0, 12.0, 15.0],
            "cae_m": [-1.0, 1.0, -1.0, 1.0, -1.0],
            "final_error_pct": [1.5, None, 1.5, 4.5, 6.5],
        },
        "ekf": {"crse_m": [1.0] * 5},
    }
)


def _write(folder: Path, name: str, rep: dict) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(rep))
    return path


def test_the_change_and_its_interval_are_the_hand_worked_ones(tmp_path):
    a, b = _write(tmp_path, "a.json", A), _write(tmp_path, "b.json", B)
    proc = run_cli("compare", str(a), str(b), "--json")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["baseline"] == "a" and [r["label"] for r in out["runs"]] == ["a", "b"] and out["n_outages"] == 5
    assert out["interval"] == {"method": "paired Student t over the outages", "level": 0.95}
    ch = out["changes"]["ins"]["crse_m"]["b"]
    assert ch["n"] == 5 and ch["change"] == pytest.approx(3.0) and ch["change_pct"] == pytest.approx(50.0)
    assert ch["ci95"] == pytest.approx([1.0367568, 4.9632432], abs=1e-6)
    assert (ch["lower"], ch["higher"], ch["verdict"]) == (0, 5, "higher")
    stats = out["stats"]["ins"]["crse_m"]["b"]
    assert stats == pytest.approx(
        {
            "n": 5,
            "mean": 9.0,
            "median": 9.0,
            "std": 4.2426407,
            "min": 3.0,
            "max": 15.0,
            "rmse": 9.9498744,
            "sse": 495.0,
        },
        abs=1e-6,
    )
    cae = out["changes"]["ins"]["cae_m"]["b"]
    assert (
        cae["verdict"] == "unchanged" and cae["ci95"] == [0.0, 0.0] and cae["change_pct"] is None
    )  # signed: no percent
    pct = out["changes"]["ins"]["final_error_pct"]["b"]
    assert pct["n"] == 4 and pct["change"] == pytest.approx(1.0)
    assert pct["ci95"] == pytest.approx([-1.0542603, 3.0542603], abs=1e-6) and pct["verdict"] == "no clear change"
    # the outages that changed most in the first shown metric (CRSE): the 5th (d = 5), then the 4th, ...
    top = out["most_changed"]["ins"]["b"]
    assert [(o["number"], o["start_s"], o["outage_s"], o["baseline"], o["run"], o["change"]) for o in top[:2]] == [
        (5, 70.0, 10.0, 10.0, 15.0, 5.0),
        (4, 60.0, 10.0, 8.0, 12.0, 4.0),
    ]
    # the GNSS-aided INS ran in b only: its statistics, no change
    assert "ekf" not in out["changes"] and out["stats"]["ekf"]["crse_m"]["b"]["mean"] == 1.0
    assert [e["runs"] for e in out["estimators"]] == [["a", "b"], ["b"]]


def test_the_terminal_table_holds_evo_res_statistics_and_the_change(tmp_path):
    a, b = _write(tmp_path, "a.json", A), _write(tmp_path, "b.json", B)
    proc = run_cli("compare", str(a), str(b), "--label", "before,after")
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    for column in ("n", "mean", "median", "std", "min", "max", "rmse", "sse"):  # evo_res's table, and the count
        assert f" {column} " in text or f" {column}\n" in text, column
    assert "before mean" in text and "[+1.04, +4.96]" in text and "+50.0 %" in text and "higher" in text
    assert "Not compared (in one run only, or not in before): GNSS-aided INS (after)" in text
    assert "paired Student t" in text
    md = run_cli("compare", str(a), str(b), "--markdown", "--metric", "final_error_pct")
    assert md.returncode == 0 and "| INS DR | b | 4 |" in md.stdout and "[-1.1, +3.1]" in md.stdout, md.stdout


def test_a_narrow_terminal_gets_every_table(tmp_path):
    """At 40 columns the runs' table (keys only: nothing to split into blocks) is printed as it is
    and the others are split; it printed a traceback."""
    a, b = _write(tmp_path, "a.json", A), _write(tmp_path, "b.json", B)
    proc = run_cli("compare", str(a), str(b), "--label", "before,after", env={"COLUMNS": "40"})
    assert proc.returncode == 0 and not proc.stderr, proc.stderr
    assert str(a) in proc.stdout and "[+1.04, +4.96]" in proc.stdout


def test_runs_of_other_outages_are_refused_naming_both_files_and_the_first_that_differs(tmp_path):
    a = _write(tmp_path, "a.json", A)
    moved = _write(
        tmp_path, "moved.json", _report({"ins": {"crse_m": [1.0] * 5}}, starts=[30.0, 40.0, 55.0, 60.0, 70.0])
    )
    line = one_line_error(
        run_cli("compare", str(a), str(moved)),
        str(a),
        str(moved),
        "outage 3 of a, V-sim-roundabout at 50 s (10 s), "
        "is not in moved (its outage 3: V-sim-roundabout at 55 s (10 s))",
        "hint:",
    )
    assert "--warm-up" in line
    other = _write(tmp_path, "other.json", _report({"ins": {"crse_m": [1.0] * 5}}, drive="V-sim-motorway"))
    one_line_error(
        run_cli("compare", str(a), str(other)), "outage 1 of a, V-sim-roundabout at 30 s (10 s), is not in other"
    )
    more = _write(tmp_path, "more.json", _report({"ins": {"crse_m": [1.0] * 6}}))
    one_line_error(
        run_cli("compare", str(a), str(more)),
        "(5 and 6)",
        "outage 6 of more, V-sim-roundabout at 80 s (10 s), is not in a",
    )
    longer = _write(tmp_path, "longer.json", _report({"ins": {"crse_m": [1.0] * 5}}, outage_s=30.0))
    one_line_error(run_cli("compare", str(a), str(longer)), "V-sim-roundabout at 30 s (10 s), is not in longer")
    # the same outages over other data (another drive of that name): the truth's distance differs
    elsewhere = _write(
        tmp_path,
        "elsewhere.json",
        _report({"ins": {"crse_m": [1.0] * 5}}, distances=[100.0, 101.0, 150.0, 103.0, 104.0]),
    )
    one_line_error(
        run_cli("compare", str(a), str(elsewhere)),
        "outage 3, V-sim-roundabout at 50 s (10 s), covers 102.000 m of truth in a "
        "and 150.000 m in elsewhere: not the same drive data",
    )


def test_outages_in_another_order_are_paired_by_drive_start_and_length(tmp_path):
    """A run of the drives given in another order pairs outage by outage with the baseline's."""
    a = _report({"ins": {"crse_m": [1.0, 2.0]}}, drive="x")
    b = _report({"ins": {"crse_m": [3.0, 4.0]}}, drive="y")
    ab = {**a, "sequences": a["sequences"] + b["sequences"]}
    ba = {
        **a,
        "sequences": [
            {**s, "ins": {**s["ins"], "crse_m": s["ins"]["crse_m"] + 1}} for s in b["sequences"] + a["sequences"]
        ],
    }
    out = json.loads(
        run_cli("compare", str(_write(tmp_path, "ab.json", ab)), str(_write(tmp_path, "ba.json", ba)), "--json").stdout
    )
    ch = out["changes"]["ins"]["crse_m"]["ba"]
    assert ch["change"] == 1.0 and ch["verdict"] == "higher" and ch["ci95"] == [1.0, 1.0]


def test_labels_by_default_the_stems_then_their_folders_and_given_ones_checked(tmp_path):
    first, second = _write(tmp_path / "old", "run.json", A), _write(tmp_path / "new", "run.json", B)
    out = json.loads(run_cli("compare", str(first), str(second), "--json").stdout)
    assert [r["label"] for r in out["runs"]] == ["old/run", "new/run"]
    one_line_error(run_cli("compare", str(first), str(second), "--label", "x"), "--label", "1 label(s) for 2 runs")
    one_line_error(
        run_cli("compare", str(first), str(second), "--label", "x", "--label", "x"),
        "--label",
        "two runs are labelled 'x'",
    )
    out = json.loads(run_cli("compare", str(first), str(second), "--label", "A", "--label", "B", "--json").stdout)
    assert out["baseline"] == "A" and "B" in out["changes"]["ins"]["crse_m"]


def test_bad_runs_and_options_are_one_line(tmp_path):
    a = _write(tmp_path, "a.json", A)
    one_line_error(run_cli("compare", str(a)), "1 run given: a comparison needs two or more")
    one_line_error(run_cli("compare", str(a), str(tmp_path / "none.json")), "none.json")
    bad = _write(tmp_path, "bad.json", [1, 2])
    one_line_error(run_cli("compare", str(a), str(bad)), f"{bad}: a JSON array, not a report")
    broken = json.loads(json.dumps(B))
    broken["sequences"][1]["ins"]["crse_m"] = "x"
    one_line_error(
        run_cli("compare", str(a), str(_write(tmp_path, "broken.json", broken))),
        "sequences[1].ins.crse_m: 'x' is not a number",
    )
    one_line_error(
        run_cli("compare", str(a), str(a), "--metric", "rmse"), "--metric", "unknown metric 'rmse'", "crse_m"
    )
    one_line_error(run_cli("compare", str(a), str(a), "--top", "0"), "--top")
    one_line_error(run_cli("compare", str(a), str(a), "--json", "--markdown"), "two output formats")
    one_line_error(
        run_cli("compare", str(a), str(a), "--figure", str(tmp_path / "f.txt")), "--figure", ".png, .svg, .pdf"
    )
    one_line_error(
        run_cli("compare", str(a), str(a), "--figure", str(tmp_path / "no" / "f.png")), "--figure", "does not exist"
    )
    png = _write(tmp_path, "same.png", A)  # the figure onto an input
    one_line_error(run_cli("compare", str(png), str(a), "--figure", str(png)), "--figure")
    assert json.loads(png.read_text()) == A and sorted(p.name for p in tmp_path.iterdir()) == [
        "a.json",
        "bad.json",
        "broken.json",
        "same.png",
    ]


def test_a_fleet_and_a_report_of_several_lengths_compare_like_one_drives(tmp_path):
    """A fleet's report pairs with a report of the same drives; several outage lengths are outages
    of each length (drive, start and length tell them apart)."""
    fleet = {
        "drives_evaluated": 1,
        "pooled": {},
        "outage_s": 10.0,
        "estimators": A["estimators"],
        "sequences": B["sequences"],
    }
    out = json.loads(
        run_cli(
            "compare", str(_write(tmp_path, "a.json", A)), str(_write(tmp_path, "fleet.json", fleet)), "--json"
        ).stdout
    )
    assert out["runs"][1]["kind"] == "fleet" and out["changes"]["ins"]["crse_m"]["fleet"]["change"] == pytest.approx(
        3.0
    )
    ten, thirty = A, _report({"ins": {"crse_m": [20.0, 30.0]}}, outage_s=30.0)
    before = {"lengths": {"10": ten, "30": thirty}, "by_length": {}}
    after = {"lengths": {"10": B, "30": _report({"ins": {"crse_m": [26.0, 30.0]}}, outage_s=30.0)}, "by_length": {}}
    out = json.loads(
        run_cli(
            "compare", str(_write(tmp_path, "l1.json", before)), str(_write(tmp_path, "l2.json", after)), "--json"
        ).stdout
    )
    assert out["n_outages"] == 7 and out["outage_s"] == [10.0, 30.0] and out["runs"][0]["kind"] == "lengths"
    assert out["changes"]["ins"]["crse_m"]["l2"]["change"] == pytest.approx((15 + 6) / 7)
    assert out["most_changed"]["ins"]["l2"][0] == {
        "drive": "V-sim-roundabout",
        "number": 1,
        "start_s": 30.0,
        "outage_s": 30.0,
        "baseline": 20.0,
        "run": 26.0,
        "change": 6.0,
    }
    groups = [
        _write(tmp_path, f"g{k}.json", {"scenarios": {"roundabout": rep}, "worst": []}) for k, rep in enumerate((A, B))
    ]
    out = json.loads(run_cli("compare", *map(str, groups), "--json").stdout)
    assert out["groups"] == ["roundabout"] and out["runs"][0]["kind"] == "scenarios"
    assert out["most_changed"]["ins"]["g1"][0]["group"] == "roundabout"


@pytest.fixture(scope="module")
def bundled_runs(tmp_path_factory) -> Path:
    """The bundled roundabout drive evaluated twice, the second with the biases of the bundled
    stationary drive (the INS DR's results change, odometry's displacement does not)."""
    folder = tmp_path_factory.mktemp("runs")
    for name, extra in (("own", []), ("stationary", ["--bias-from", "stationary"])):
        proc = run_cli("evaluate", "roundabout", "--estimators", "ins,odo", "--json", "-q", *extra)
        assert proc.returncode == 0, proc.stderr
        (folder / f"{name}.json").write_text(proc.stdout)
    return folder


def test_two_settings_of_a_bundled_drive_against_numpy_on_their_outages(bundled_runs, tmp_path):
    a, b = bundled_runs / "own.json", bundled_runs / "stationary.json"
    figure = tmp_path / "compare.png"
    proc = run_cli("compare", str(a), str(b), "--json", "--figure", str(figure))
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    ra, rb = json.loads(a.read_text()), json.loads(b.read_text())
    for est in ("ins", "odo"):
        for metric in ("crse_m", "cae_m", "final_position_error_m"):
            x = np.array([s[est][metric] for s in ra["sequences"]])
            y = np.array([s[est][metric] for s in rb["sequences"]])
            d = y - x
            half = 2.0032407188 * d.std(ddof=1) / math.sqrt(len(d))  # t(0.975, 56), from the tables
            ch = out["changes"][est][metric]["stationary"]
            assert ch["n"] == 57 and ch["change"] == pytest.approx(d.mean(), abs=1e-9)
            assert ch["ci95"] == pytest.approx([d.mean() - half, d.mean() + half], abs=1e-6)
            assert out["stats"][est][metric]["own"]["mean"] == pytest.approx(ra["summary"][est][metric]["mean"])
    assert out["changes"]["ins"]["crse_m"]["stationary"]["verdict"] == "higher"
    assert out["changes"]["odo"]["crse_m"]["stationary"]["verdict"] == "unchanged"
    assert out["most_changed"]["odo"]["stationary"] == []  # no outage changed: none listed
    png = Image.open(figure)
    assert png.size[0] == 1050 and [round(v) for v in png.info["dpi"]] == [300, 300]
    assert "figure: " in proc.stderr and not [p for p in tmp_path.iterdir() if p.name != "compare.png"]


def test_the_api_gives_what_the_command_prints(bundled_runs):
    import ionav_viz as iv

    a, b = bundled_runs / "own.json", bundled_runs / "stationary.json"
    cmp = iv.compare([a, b])
    assert (
        isinstance(cmp, iv.Comparison) and cmp.to_json() + "\n" == run_cli("compare", str(a), str(b), "--json").stdout
    )
    report = iv.evaluate(["roundabout"], 10.0, estimators=["ins", "odo"])  # what evaluate returns: the same as its JSON
    from_objects = iv.compare([report, json.loads(b.read_text())], labels=["own", "stationary"]).to_dict()
    assert from_objects["changes"] == cmp.to_dict()["changes"]
    replayed = iv.replay("roundabout", 10.0, estimators=["ins", "odo"], output=bundled_runs / "own.rrd")
    from_recording = iv.compare(
        [replayed.path, a]
    ).to_dict()  # the report the recording carries: the same outages and numbers
    assert from_recording["runs"][0] == {"label": "own.rrd", "file": str(replayed.path), "kind": "report"}
    assert {ch["crse_m"]["own.json"]["verdict"] for ch in from_recording["changes"].values()} == {"unchanged"}
    with pytest.raises(iv.InputError, match="a run of type int") as info:
        iv.compare([a, 42])
    assert info.value.param == "runs"


def test_the_figure_of_unchanged_runs_has_a_readable_axis(tmp_path):
    """Two runs whose changes print as +0.00 (a float's last bits apart) drew an axis of +-8e-5 with
    its '1e-5' offset over the axis label ('B - A1e-5'): the axis now spans at least twenty steps of the
    printed resolution, with no offset."""
    import matplotlib

    matplotlib.use("Agg")
    import ionav_viz as iv
    from ionav_viz.viz.compare_figure import comparison_figure

    b = json.loads(json.dumps(A))
    for seq in b["sequences"]:
        for est in seq.values():
            if isinstance(est, dict) and isinstance(est.get("crse_m"), float):
                est["crse_m"] *= 1 + 1e-13
    cmp = iv.compare([_write(tmp_path, "a.json", A), _write(tmp_path, "b.json", b)]).to_json()
    fig = comparison_figure(cmp if isinstance(cmp, dict) else json.loads(cmp))
    fig.canvas.draw()
    for ax in fig.axes:
        lo, hi = ax.get_xlim()
        assert hi - lo >= 0.1 and ax.xaxis.get_offset_text().get_text() == "", (lo, hi)
