"""A fleet in one command (issue 42): many drives, each evaluated on its own, in parallel, one bad
drive reported rather than fatal; inputs as folders, globs and @lists; the engine's back-ends."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import HANG_S, REPO, run_cli

pytestmark = pytest.mark.xdist_group("fleet")

CHEAP = "ins,odo"  # estimators without torch, for the tests about plumbing rather than results


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory) -> Path:
    """Three simulated 2-minute drives and one unreadable CSV, in one folder."""
    import ionav_viz as iv

    folder = tmp_path_factory.mktemp("fleet")
    for seed, scenario in enumerate(("motorway", "roundabout", "motorway")):
        iv.simulate(scenario, folder / f"V-f{seed}.csv", seed=seed, duration_s=120.0)
    (folder / "V-bad.csv").write_text("not,an,io-vnbd\n1,2,3\n")
    return folder


def _good(fleet_dir: Path) -> list[str]:
    return [str(fleet_dir / f"V-f{i}.csv") for i in range(3)]


def _results(report) -> dict:
    out = report.to_dict()
    out.pop("timing")  # wall times: the only part that changes from run to run
    return out


def test_pooled_results_are_bit_for_bit_the_serial_run_and_one_report_over_the_drives(fleet_dir):
    """Two worker processes give exactly the serial fleet's numbers, and those are exactly what one
    report over the same drives (plain 'evaluate A B C') gives: summary, improvement, every outage."""
    import ionav_viz as iv

    drives = _good(fleet_dir)
    calls: list[tuple[str, int, int]] = []
    serial = iv.evaluate(drives, 10, engine=iv.Engine(1), progress=lambda *call: calls.append(call))
    assert [c[1:] for c in calls] == [(1, 3), (2, 3), (3, 3)]
    assert calls[-1][0].startswith(f"3/3 drives, {serial.n_outages} outages scored, slowest V-f")
    pooled = iv.evaluate([*drives, drives[0], str(fleet_dir / ".." / fleet_dir.name / "V-f1.csv")], 10, engine=iv.Engine(2))  # the same drive twice: once
    assert [t.name for t in pooled.drives] == ["V-f0", "V-f1", "V-f2"]
    assert "idnn" in serial.estimators  # torch in the workers too
    import pickle

    for table in serial.drives:  # what comes back from a worker: the per-outage table, not the drive
        assert len(pickle.dumps(table)) < Path(table.source).stat().st_size / 20
    assert _same(_results(pooled), _results(serial))  # bit for bit: the same JSON text
    one = iv.evaluate(drives, 10).to_dict()
    fleet = serial.to_dict()
    assert _same([{k: v for k, v in s.items() if k != "manoeuvre"} for s in fleet["sequences"]], one["sequences"])
    assert "roundabout" in serial.drives[1].manoeuvre and "cruise" in serial.drives[0].manoeuvre  # the simulated manoeuvres, found
    assert sum(g["outages"] for g in fleet["by_manoeuvre"].values()) == serial.n_outages
    assert set(fleet["consistency"]) == {est for est, s in one["summary"].items() if "consistency" in s} >= {"ekf", "odo"}
    for est in serial.estimators:
        # the metrics' statistics; the consistency pooled from the compact tables is the report's (but its by-second curve)
        assert _same(fleet["pooled"][est]["summary"], {k: v for k, v in one["summary"][est].items() if k != "consistency"})
        if est in fleet["consistency"]:
            assert _same(fleet["consistency"][est], {k: v for k, v in one["summary"][est]["consistency"].items() if k != "by_second"})
        if est != "ins":
            assert _same(fleet["pooled"][est]["improvement_pct"], one["improvement_pct"][est])


def _same(a, b) -> bool:
    """Equal to the last bit (as JSON text: NaN equals NaN, 0.1 + 0.2 does not equal 0.3)."""
    return json.dumps(a) == json.dumps(b)


def test_a_bad_drive_is_reported_and_the_others_kept(fleet_dir):
    """A folder of drives with one unreadable file: every other drive's results, the bad one's
    one-line reason under its name in the text and the JSON, exit code 3; --fail-fast stops with
    exit 2 and a one-line error naming the file."""
    text = run_cli("evaluate", str(fleet_dir), "--workers", "1", "--estimators", CHEAP)
    assert text.returncode == 3, text.stderr
    assert "4 drive(s), 3 evaluated, 1 failed" in text.stdout
    bad = str(fleet_dir / "V-bad.csv")
    line = next(ln for ln in text.stdout.splitlines() if ln.startswith(bad))
    assert "missing column" in line
    assert "Traceback" not in text.stderr and "exit code 3" in text.stderr
    as_json = run_cli("evaluate", str(fleet_dir), "--workers", "1", "--estimators", CHEAP, "--json")
    assert as_json.returncode == 3
    report = json.loads(as_json.stdout)
    assert [f["drive"] for f in report["failures"]] == [bad] and "missing column" in report["failures"][0]["reason"]
    assert [d["drive"] for d in report["drives"]] == ["V-f0", "V-f1", "V-f2"]
    assert report["worst_drives"][0]["command"].startswith("ionav-viz replay ")
    # the command that replays a drive reads and scores it as the fleet did: every option but the fleet's own
    read = run_cli("evaluate", str(fleet_dir), "--workers", "1", "--estimators", CHEAP, "--warm-up", "10s", "--gnss-limit", "max_sigma_m=13",
                   "--json", "-q")
    worst = json.loads(read.stdout)["worst_outages"][0]
    command, name, number = worst["command"], worst["drive"], worst["number"]
    # ... into the drive's recording, then renders the outage it names (issue 63: it replayed the whole drive)
    replay, shot = command.split(" && ")
    assert replay.startswith("ionav-viz replay ") and replay.endswith(
        f"--outage 10s --estimators {CHEAP} --warm-up 10s --gnss-limit max_sigma_m=13 -o {name}.rrd")
    assert shot == f"ionav-viz screenshot {name}.rrd --outage-number {number} -o {name}-outage{number}.png"
    assert not any(w in command.split() for w in ("--workers", "--json", "-q")), command
    fast = run_cli("evaluate", str(fleet_dir), "--workers", "1", "--estimators", CHEAP, "--fail-fast")
    assert fast.returncode == 2 and fast.stdout == ""
    assert len(fast.stderr.strip().splitlines()) == 1 and bad in fast.stderr and "hint:" in fast.stderr
    # one hint: the drive's own, then --fail-fast's (not two "(hint: ...)" in a row)
    assert fast.stderr.count("(hint: ") == 1 and "docs/formats.md); or leave out --fail-fast" in fast.stderr, fast.stderr


def test_drives_from_lists_and_globs_once_each(fleet_dir, tmp_path):
    """@list.txt (comments, blank lines, paths relative to the list, a nested list), globs and a
    folder name the same drives once; --dry-run lists them with sizes and an estimate, reading
    nothing; a missing list and a glob matching nothing are one-line errors with exit code 2."""
    listed = tmp_path / "drives.txt"
    rel = os.path.relpath(fleet_dir / "V-f0.csv", tmp_path)
    (tmp_path / "more.txt").write_text(f"{fleet_dir / 'V-f1.csv'}\n")
    listed.write_text(f"# my fleet\n{rel}\n\n{fleet_dir}/V-f0.csv  # the same drive again\n@more.txt\n")
    dry = run_cli("evaluate", f"@{listed}", str(fleet_dir / "V-f*.csv"), str(fleet_dir), "--dry-run", "--workers", "2", "--json")
    assert dry.returncode == 0, dry.stderr
    plan = json.loads(dry.stdout)
    names = [Path(d["drive"]).name for d in plan["drives"]]
    assert names == ["V-f0.csv", "V-f1.csv", "V-f2.csv", "V-bad.csv"]
    assert all(d["size_bytes"] > 0 for d in plan["drives"]) and plan["estimate_s"] > 0 and plan["workers"] == 2
    for day in ("day1", "day2"):  # a glob over folders of drives: their drives
        (tmp_path / day).mkdir()
        shutil.copy(fleet_dir / "V-f0.csv", tmp_path / day / f"V-{day}.csv")
    days = json.loads(run_cli("evaluate", str(tmp_path / "day*"), "--dry-run", "--json").stdout)
    assert [Path(d["drive"]).name for d in days["drives"]] == ["V-day1.csv", "V-day2.csv"]
    text = run_cli("evaluate", str(fleet_dir), "--dry-run")
    assert text.returncode == 0 and "4 drive(s)" in text.stdout and "MB" in text.stdout
    # a drive that is not there is said missing (it was listed with size "-", as a bundled name is)
    gone = str(tmp_path / "gone.mcap")
    dry = run_cli("evaluate", "roundabout", gone, "--dry-run")
    assert dry.returncode == 0, dry.stderr
    rows = {line.split()[0]: line.split()[1] for line in dry.stdout.splitlines()[2:4]}
    assert rows == {"roundabout": "-", gone: "missing"}, dry.stdout
    assert f"not found, the run would report it failed: {gone}: no such file or folder" in dry.stdout
    listed = json.loads(run_cli("evaluate", "roundabout", gone, "--dry-run", "--json").stdout)["drives"]
    assert ["missing" in d for d in listed] == [False, True]
    for args, fragment in (((f"@{tmp_path / 'none.txt'}",), "no such list of drives"), ((str(tmp_path / "*.mcap"),), "no file matches"),
                           ((str(fleet_dir), "--workers", "0"), "--workers")):
        bad = run_cli("evaluate", *args)
        assert bad.returncode == 2, bad.stderr
        assert len(bad.stderr.strip().splitlines()) == 1 and fragment in bad.stderr and "Traceback" not in bad.stderr


def test_a_dying_worker_is_retried_once_then_reported():
    """A worker process that dies (here: exits at once, as one the OOM killer ends) loses the pool;
    the other items are run again and kept, the one that kills its worker twice is reported."""
    from ionav_viz.api.engine import Engine, WorkerLost, run_each
    from tests.fleet_helpers import square_or_die

    items = ["a", "bb", "die", "cccc", "ddd"]
    got = dict(run_each(square_or_die, items, Engine(workers=2)))
    # it failed once in six full-suite runs under load, cause unknown: say what came back
    assert sorted(got) == list(range(5)), got
    assert [got[i] for i in (0, 1, 3, 4)] == [1, 4, 16, 9], got
    assert isinstance(got[2], WorkerLost) and "died twice" in got[2].reason, got
    from ionav_viz.core.errors import ToolFailure

    with pytest.raises(ToolFailure, match="every worker process died before returning anything"):  # workers that cannot start
        list(run_each(square_or_die, ["die", "die", "die"], Engine(workers=2)))


def test_dask_cluster_gives_the_serial_results(fleet_dir, tmp_path):
    """A real Dask scheduler and two workers on 127.0.0.1 give exactly the serial results."""
    pytest.importorskip("distributed")
    import ionav_viz as iv

    env = {**os.environ, "PYTHONPATH": str(REPO)}  # the workers import this checkout's ionav_viz
    dask = shutil.which("dask", path=str(Path(sys.executable).parent)) or "dask"
    info = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(info)],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        while not (info.exists() and info.stat().st_size) and procs[0].poll() is None:  # the scheduler has written its address
            time.sleep(0.05)
        address = json.loads(info.read_text())["address"]
        procs += [subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1"],
                                   env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
        from distributed import Client

        with Client(address, timeout=f"{HANG_S:.0f}s") as client:  # both workers up before the work (a hang guard only)
            client.wait_for_workers(2, timeout=HANG_S)
        drives = [*_good(fleet_dir), str(fleet_dir / "V-bad.csv")]
        on_cluster = iv.evaluate(drives, 10, estimators=CHEAP.split(","), engine=iv.Engine(cluster=address))
        serial = iv.evaluate(drives, 10, estimators=CHEAP.split(","), engine=iv.Engine(1))
        assert json.dumps(_results(on_cluster)) == json.dumps(_results(serial))
        assert on_cluster.timing["engine"].startswith("Dask")
        assert len(on_cluster.failures) == 1
    finally:
        for proc in reversed(procs):  # ours alone, and nothing of theirs to keep: no graceful close to wait for
            proc.kill()
        for proc in procs:
            proc.wait(timeout=HANG_S)


def test_no_dask_scheduler_is_one_error_naming_the_option(fleet_dir):
    pytest.importorskip("distributed")
    import dask

    import ionav_viz as iv
    from ionav_viz.core.errors import InputError

    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}), pytest.raises(InputError) as err:
        iv.evaluate([str(fleet_dir / "V-f0.csv")], 10, estimators=["ins"], engine=iv.Engine(cluster="tcp://127.0.0.1:9"))
    assert err.value.param == "cluster" and "no Dask scheduler answered at tcp://127.0.0.1:9" in str(err.value)


def test_replay_of_many_drives_writes_one_recording_each(fleet_dir, tmp_path):
    """'replay A B C -o FOLDER': one recording per drive (a name given twice gets its own), the
    paths on stdout in the order given, the scores those of 'evaluate', a bad drive exit code 3."""
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(fleet_dir / "V-f0.csv", other / "V-f0.csv")
    out = tmp_path / "recs"
    result = run_cli("replay", *_good(fleet_dir), str(other / "V-f0.csv"), str(fleet_dir / "V-bad.csv"), "--workers", "1", "-o", str(out),
                     "--estimators", CHEAP, "--fleet-rrd", str(out / "fleet.rrd"))
    assert result.returncode == 3, result.stderr
    assert result.stdout.splitlines() == [str(out / n) for n in ("V-f0.rrd", "V-f1.rrd", "V-f2.rrd", "V-f0-2.rrd")]
    table = _texts_and_bars(out / "fleet.rrd")[0]["/fleet/drives"]  # the overview: each drive's recording one click away
    assert all(f"its recording `{out / n}`" in table for n in ("V-f0.rrd", "V-f1.rrd", "V-f2.rrd", "V-f0-2.rrd"))
    assert all((out / n).stat().st_size > 0 for n in ("V-f0.rrd", "V-f1.rrd", "V-f2.rrd", "V-f0-2.rrd"))
    assert "V-bad.csv: missing column" in result.stderr
    assert "Fleet: 5 drive(s), 4 evaluated, 1 failed" in result.stderr
    import ionav_viz as iv

    replayed = iv.replay(_good(fleet_dir)[:2], 10, estimators=CHEAP.split(","), output=tmp_path / "api", engine=iv.Engine(1))
    evaluated = iv.evaluate(_good(fleet_dir)[:2], 10, estimators=CHEAP.split(","), engine=iv.Engine(1))
    assert _same(replayed.to_dict()["sequences"], evaluated.to_dict()["sequences"])
    assert [r["recording"] for r in replayed.drive_rows()] == [str(tmp_path / "api" / n) for n in ("V-f0.rrd", "V-f1.rrd")]
    refused = run_cli("replay", *_good(fleet_dir), "-o", str(tmp_path / "one.rrd"))
    assert refused.returncode == 2 and "-o" in refused.stderr and len(refused.stderr.strip().splitlines()) == 1


def _texts_and_bars(path: Path) -> tuple[dict[str, str], dict[str, tuple[list, list]]]:
    from rerun.chunk import RrdReader

    texts, bars = {}, {}
    for chunk in RrdReader(path).stream():
        name, batch = str(chunk.entity_path), chunk.to_record_batch()
        cols = batch.schema.names
        if "TextDocument:text" in cols:
            cell = batch.column("TextDocument:text").to_pylist()[0]
            texts[name] = cell[0] if isinstance(cell, list) else cell
        if "BarChart:values" in cols:
            bars[name] = tuple(_numbers(batch.column(f"BarChart:{c}").to_pylist()[0]) for c in ("values", "abscissa"))
    return texts, bars


def _numbers(cell) -> list:
    """A bar chart's tensor cell as read back (a tensor: its buffer) as a list of numbers."""
    while isinstance(cell, list) and len(cell) == 1 and isinstance(cell[0], (dict, list)):
        cell = cell[0]
    return list(cell["buffer"]) if isinstance(cell, dict) else list(cell)


def test_the_fleet_overview_recording_has_a_row_and_a_bar_per_drive(fleet_dir, tmp_path):
    """--fleet-rrd: the table names every drive with its worst outage and the command that replays
    it, the failed drive with its reason; per estimator one bar per drive, the drive's mean final
    error (the mean of its outages' final errors in the JSON report), numbered as the table's rows."""
    import numpy as np

    out = tmp_path / "fleet.rrd"
    proc = run_cli("evaluate", str(fleet_dir), "--estimators", CHEAP, "--workers", "1", "--json", "--fleet-rrd", str(out), "-q")
    assert proc.returncode == 3, proc.stderr  # the bad drive
    report = json.loads(proc.stdout)
    texts, bars = _texts_and_bars(out)
    table = texts["/fleet/drives"]
    for k, name in enumerate(["V-f0", "V-f1", "V-f2"], 1):
        errors = {est: [s[est]["final_position_error_m"] for s in report["sequences"] if s["drive"] == name] for est in ("ins", "odo")}
        worst = int(np.argmax(errors["ins"])) + 1
        assert f"| {k} | {name} | {len(errors['ins'])} | " in table
        assert (f"{k}. {name}, outage {worst} (" in table and f"`ionav-viz replay {fleet_dir / name}.csv --outage 10s --estimators ins,odo "
                f"-o {name}.rrd && ionav-viz screenshot {name}.rrd --outage-number {worst} -o {name}-outage{worst}.png`" in table)
        for j, est in enumerate(("ins", "odo")):
            values, abscissa = bars[f"/fleet/mean_final_error_m/{est}"]
            assert values[k - 1] == pytest.approx(np.mean(errors[est]))
            assert bars[f"/fleet/worst_final_error_m/{est}"][0][k - 1] == pytest.approx(max(errors[est]))
            # one chart per metric, every estimator's bar side by side in a group centred on the row's number
            assert abscissa[k - 1] == pytest.approx(k - 0.4 + 0.4 * j)
    assert "V-bad.csv:" in table and texts["/fleet/report"].startswith("# Fleet: 4 drive(s)")
    assert not list(tmp_path.glob(".fleet.rrd.*"))  # written atomically: no temporary left
    proc = run_cli("evaluate", str(fleet_dir / "V-f0.csv"), "--estimators", CHEAP, "--fleet-rrd", str(tmp_path / "f.txt"))
    assert proc.returncode == 2 and "--fleet-rrd" in proc.stderr and ".rrd" in proc.stderr
    proc = run_cli("screenshot", str(out), "-o", str(tmp_path / "fleet.png"), "--size", "800x450")
    if proc.returncode == 1 and "mesa-vulkan-drivers" in proc.stderr and not os.environ.get("CI"):
        pytest.skip(f"no renderer on this machine: {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stderr
    from PIL import Image

    assert Image.open(tmp_path / "fleet.png").size == (800, 450)
    assert "do not apply" not in proc.stderr
    proc = run_cli("screenshot", str(out), "-o", str(tmp_path / "again.png"), "--size", "800x450", "--view", "local", "--time", "worst")
    assert proc.returncode == 0 and "a fleet overview is one image of its own layout" in proc.stderr, proc.stderr  # not silently ignored


def test_the_command_the_fleet_overview_lists_shows_the_outage_it_names(fleet_dir, tmp_path):
    """Issue 63: the overview listed 'ionav-viz replay DRIVE --outage 10s' beside "outage 10", and
    nothing opened outage 10. Each listed command, run as given, makes the drive's recording and
    renders that outage framed: the recording's outage of that number has the final error the
    table gives, and the image is written."""
    import re
    import shlex

    from ionav_viz.viz.recording_info import read_recording_info

    out = tmp_path / "fleet.rrd"
    drive = str(fleet_dir / "V-f1.csv")
    proc = run_cli("evaluate", drive, "--estimators", "ins,odo", "--workers", "1", "--fleet-rrd", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    table = _texts_and_bars(out)[0]["/fleet/drives"]
    row = re.search(r"^1\. V-f1, outage (\d+) \([^)]*\): `([^`]*)`", table, re.M)
    assert row, table
    number, command = int(row.group(1)), row.group(2)
    named_error = float(re.search(r"\| outage \d+ \([^)]*\): ([0-9.]+) \|", table).group(1))
    for step in command.split(" && "):
        argv = shlex.split(step)
        assert argv[0] == "ionav-viz"
        done = run_cli(*argv[1:], cwd=tmp_path)
        if done.returncode == 1 and "mesa-vulkan-drivers" in done.stderr and not os.environ.get("CI"):
            pytest.skip(f"no renderer on this machine: {done.stderr.strip()}")
        assert done.returncode == 0, (step, done.stderr)
    outage = read_recording_info(tmp_path / "V-f1.rrd").outage(number)
    assert outage.number == number and outage.final_error_m["ins"] == pytest.approx(named_error, abs=0.05)
    assert (tmp_path / f"V-f1-outage{number}.png").stat().st_size > 0


def _manifest_runs(folder: str) -> dict[str, int]:
    """Independently of the catalog: the vehicle files the packaged manifest lists in one
    ``<Group> (Driver X)`` folder, by file name, with the unsynchronised copy's size."""
    rows = (REPO / "ionav_viz" / "data" / "iovnbd-manifest.tsv").read_text().splitlines()[1:]
    out: dict[str, int] = {}
    for path, _, size in (r.split("\t") for r in rows):
        name = path.rsplit("/", 1)[-1]
        if f"/{folder}/" in path and name.startswith("V-") and name.endswith(".csv") and path.startswith("Unsynchronised"):
            out[name[:-4]] = int(size)
    return out


def test_iovnbd_run_selections_as_drives(fleet_dir, tmp_path):
    """--runs GROUP|DRIVER|all: the dataset's runs of that group or driver, by name, once each
    (a run also named as a drive too), with the manifest's sizes in a dry run; each read under the
    data root, a run not there a failure with the fetch hint; an unknown selection one line."""
    expected = _manifest_runs("Y (Driver D)")
    assert sorted(expected) == ["V-Y1", "V-Y2"]
    dry = run_cli("evaluate", "V-Y1", "--runs", "driver D", "--runs", "y", "--dry-run", "--json")
    assert dry.returncode == 0, dry.stderr
    assert {d["drive"]: d["size_bytes"] for d in json.loads(dry.stdout)["drives"]} == {"V-Y1": None, "V-Y2": expected["V-Y2"]}
    every = json.loads(run_cli("evaluate", "--runs", "all", "--dry-run", "--json").stdout)["drives"]
    assert {"V-Y1", "V-Y2", "V-M", "V-Vw12", "V-Vfb02d"} <= {d["drive"] for d in every} and len(every) == len({d["drive"] for d in every})
    root = tmp_path / "iovnbd" / "Y (Driver D)" / "Y1"
    root.mkdir(parents=True)
    shutil.copy(fleet_dir / "V-f0.csv", root / "V-Y1.csv")
    proc = run_cli("evaluate", "--runs", "D", "--data-root", str(tmp_path / "iovnbd"), "--estimators", CHEAP, "--workers", "1", "--json", "-q")
    assert proc.returncode == 3, proc.stderr  # V-Y2 is not under the data root
    report = json.loads(proc.stdout)
    assert [d["drive"] for d in report["drives"]] == ["V-Y1"] and f"--data-root {tmp_path / 'iovnbd'}" in report["worst_drives"][0]["command"]
    assert [f["drive"] for f in report["failures"]] == ["V-Y2"] and "ionav-viz fetch V-Y2" in report["failures"][0]["reason"]
    bad = run_cli("evaluate", "--runs", "Q")
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "--runs Q" in bad.stderr and "Vta" in bad.stderr


def test_the_error_into_an_outage_is_the_final_error_of_a_shorter_one(fleet_dir):
    """by_length: 10 s into the 30 s outages, each estimator's error is the final error of the 10 s
    outage from the same start (evaluated on its own), so the breakdown stands for the length."""
    import numpy as np

    import ionav_viz as iv

    drives = _good(fleet_dir)
    long, short = (iv.evaluate(drives, n, estimators=["ins", "odo", "ekf"], engine=iv.Engine(1)) for n in (30, 10))
    compared = 0
    for t30, t10 in zip(long.drives, short.drives):
        for est in ("ins", "odo", "ekf"):
            for i, start in enumerate(t30.start_s):
                same = np.flatnonzero(np.isclose(t10.start_s, start))
                if len(same):
                    assert t30.error_at_s[est]["10"][i] == pytest.approx(t10.metrics[est]["final_position_error_m"][same[0]], abs=1e-9)
                    compared += 1
    assert compared >= 9
    assert long.by_length()["30"]["mean_error_m"] == {e: long.pooled()[e]["summary"]["final_position_error_m"]["mean"] for e in long.estimators}


def test_a_fleet_through_the_logs_own_losses_reports_them(tmp_path):
    """``--on gnss-outage`` over a fleet: each drive's own GNSS losses, bridged, pooled and per drive
    (before, the fleet report said "0 outages" and nothing of them). Pooled means and counts
    against each drive evaluated on its own through its losses."""
    import numpy as np

    import ionav_viz as iv

    drives = [str(iv.simulate(sc, tmp_path / f"V-loss{i}.csv", seed=10 + i, duration_s=240.0, gnss_losses=3)) for i, sc in
              enumerate(("motorway", "roundabout"))]
    single = []
    for d in drives:
        proc = run_cli("evaluate", d, "--on", "gnss-outage", "--estimators", CHEAP, "--json")
        assert proc.returncode == 0, proc.stderr
        single.append(json.loads(proc.stdout)["gnss_outages"]["bridged"])
    clean = str(iv.simulate("motorway", tmp_path / "V-clean.csv", seed=12, duration_s=120.0))  # no loss: nothing to bridge, not a failure
    proc = run_cli("evaluate", *drives, clean, "--on", "gnss-outage", "--estimators", CHEAP, "--workers", "2", "--json")
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    assert got["drives_failed"] == 0 and [s["drive"] for s in got["skipped"]] == [clean], got["skipped"]
    real = got["real_outages"]
    every = [b for drive in single for b in drive]
    assert real["n"] == len(every) >= 4
    for est in ("ins", "odo"):
        errors = [b["final_error_m"][est] for b in every]
        assert real["pooled"][est]["losses"] == len(every)
        assert real["pooled"][est]["mean_final_error_m"] == pytest.approx(np.mean(errors), abs=1e-3)
        assert real["pooled"][est]["worst"]["final_error_m"] == pytest.approx(max(errors), abs=1e-3)
    assert [d["losses"] for d in real["drives"]] == [len(s) for s in single]
    out = tmp_path / "fleet.rrd"
    text = run_cli("evaluate", *drives, "--on", "gnss-outage", "--estimators", CHEAP, "--workers", "2", "--fleet-rrd", str(out)).stdout
    assert f"; {len(every)} of the logs' own GNSS losses bridged over" in text and "Through the logs' own GNSS losses" in text
    assert "Pooled over the fleet" not in text  # no synthetic outage: no table of dashes
    # the overview recording: a row and a bar per drive of its losses (it had only dashes and empty bars)
    texts, bars = _texts_and_bars(out)
    for k, losses in enumerate(single, 1):
        errors = {est: [b["final_error_m"][est] for b in losses] for est in ("ins", "odo")}
        worst = losses[int(np.argmax(errors["ins"]))]["number"]
        assert f"{k}. V-loss{k - 1}, real GNSS outage {worst} (" in texts["/fleet/drives"]
        assert f" -o V-loss{k - 1}.rrd && ionav-viz screenshot V-loss{k - 1}.rrd --outage-number {worst} -o " in texts["/fleet/drives"]
        assert f"| {k} | V-loss{k - 1} | {len(losses)} | " in texts["/fleet/drives"]
        for est in ("ins", "odo"):
            assert bars[f"/fleet/mean_final_error_m/{est}"][0][k - 1] == pytest.approx(np.mean(errors[est]), abs=1e-3)
            assert bars[f"/fleet/worst_final_error_m/{est}"][0][k - 1] == pytest.approx(max(errors[est]), abs=1e-3)


def test_a_replay_fleet_where_every_drive_fails_leaves_no_folder_behind(tmp_path):
    """Every drive unreadable: the run fails (exit 2) and the output folders it made for the
    recordings are gone again (they were left empty)."""
    bad = tmp_path / "logs"
    bad.mkdir()
    (bad / "V-a.csv").write_text("not,a,drive\n1,2,3\n")
    proc = run_cli("replay", str(bad), "--workers", "1", "--estimators", CHEAP, "-o", str(tmp_path / "recs" / "fleet"))
    assert proc.returncode == 2, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logs"]


@pytest.mark.parametrize("command", ["evaluate", "replay"])
def test_a_bad_bias_from_stops_the_fleet_before_any_drive(fleet_dir, tmp_path, command):
    """'evaluate a.csv b.csv --workers 2 --bias-from bad.csv' failed every drive on the same
    --bias-from, in a fleet report; it is one line and exit 2 now, before any work."""
    out = ["-o", str(tmp_path / "recs")] if command == "replay" else []
    for bias, words in ((fleet_dir / "V-bad.csv", "missing column"), (tmp_path / "V-none.csv", "no such file")):
        proc = run_cli(command, *_good(fleet_dir)[:2], "--workers", "2", "--estimators", CHEAP, "--bias-from", str(bias), *out)
        lines = [line for line in proc.stderr.splitlines() if line.strip()]
        assert proc.returncode == 2 and len(lines) == 1, proc.stderr
        assert lines[0].startswith(f"error: --bias-from: {bias}: ") and words in lines[0], lines[0]
        assert not (tmp_path / "recs").exists()


def test_fail_fast_says_a_drives_hint_of_several_lines_once(tmp_path):
    """A plug-in's hint of two lines was collapsed in the drive's reason but not in its hint, so
    --fail-fast's line carried it twice (a review found it)."""
    plugin = f"{REPO / 'tests' / 'plugins' / 'toy_estimators.py'}:HintRaises"
    proc = run_cli("evaluate", "roundabout", "motorway", "--workers", "1", "--estimators", "ins", "--estimator", plugin,
                   "--fail-fast", "--warm-up", "0s", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("(hint: ") == 1 and proc.stderr.count("run my-calibrate first") == 1, proc.stderr
