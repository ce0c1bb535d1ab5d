"""Replay writes a reviewable .rrd: read back with Rerun's own reader and checked against evaluate."""

import json
from collections import defaultdict

import numpy as np
import pytest

from .conftest import run_cli

# the module's generated fixtures are built once, on one worker (pytest-xdist's --dist loadgroup)
pytestmark = pytest.mark.xdist_group("replay")

N_WIN = 10


def read_rrd(path):
    """entity path -> list of (time_s, main component of the row), via rerun.chunk.RrdReader."""
    from rerun.chunk import RrdReader

    reader = RrdReader(path)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1
    rows = defaultdict(list)
    static = set()
    for chunk in reader.stream():
        entity = str(chunk.entity_path)
        if chunk.is_static:
            static.add(entity)
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if "time" not in names:
            continue
        times = batch.column("time").cast("int64").to_numpy() / 1e9
        cols = {n.split(":")[-1]: batch.column(n).to_pylist() for n in names if ":" in n}
        # the row's main component: scalars, strips, positions or state
        key = next(k for k in ("scalars", "strips", "line_strings", "positions", "state") if k in cols)
        rows[entity].extend(zip(times, cols[key]))
    return {k: sorted(v, key=lambda r: r[0]) for k, v in rows.items()}, static


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    out = tmp_path_factory.mktemp("rrd") / "roundabout.rrd"
    proc = run_cli("replay", "roundabout", "--outage", "10s", "-o", str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    ev = run_cli("evaluate", "roundabout", "--outage", "10s", "--json")
    assert ev.returncode == 0, ev.stderr
    return out, json.loads(ev.stdout)


def test_recording_has_the_documented_entities(replayed):
    path, _ = replayed
    rows, static = read_rrd(path)
    for entity in [
        "/map/gnss/position", "/local/gnss/position", "/gnss/available", "/gnss/state",
        "/signals/accel_long_mps2", "/signals/speed_mps",
        "/signals/yaw_rate_radps/gyro", "/signals/yaw_rate_radps/gnss", "/signals/displacement_m/gnss",
    ] + [f"/{g}/{e}/live" for g in ("map", "local") for e in ("ins", "idnn")] + [
        f"/signals/{s}/{e}" for s in ("yaw_rate_radps", "displacement_m") for e in ("ins", "idnn")
    ] + [f"/errors/{m}/{e}" for m in ("crse_m", "cae_m", "yaw_crse_radps", "position_error_m") for e in ("ins", "idnn")]:
        assert entity in rows, entity
    for entity in ["/map/gnss", "/local/gnss", "/summary", "/local/outages"] + [f"/{g}/{e}/all" for g in ("map", "local") for e in ("ins", "idnn")]:
        assert entity in static, entity


def test_row_counts_per_outage(replayed):
    path, rep = replayed
    rows, _ = read_rrd(path)
    n_seq = rep["n_sequences"]
    assert n_seq == 57  # (600 s - 30 s warm-up) // 10 s
    for entity in ("/errors/crse_m/ins", "/errors/crse_m/idnn", "/signals/displacement_m/idnn"):
        assert len(rows[entity]) == n_seq * N_WIN, entity
    for entity in ("/map/idnn/live", "/local/ins/live", "/inspect/ins", "/inspect/idnn"):
        assert len(rows[entity]) == n_seq * (N_WIN + 1), entity
    # the track of outage k is its start alone just after the start (clearing the previous one), then grows to 11 points
    lengths = [len(v[0]) for _, v in rows["/local/ins/live"]]  # one strip per row
    assert lengths == list(range(1, N_WIN + 2)) * n_seq
    for entity in ("/inspect/gnss", "/inspect/grid", "/inspect/scale", "/local/gnss/outage", "/map/gnss/outage"):
        assert len(rows[entity]) == n_seq, entity
    # GNSS available: 0 during outages
    available = np.array([v[0] for _, v in rows["/gnss/available"]])[:-1]  # per window; the last value is repeated at the drive's end
    assert int((available == 0).sum()) == n_seq * N_WIN
    states = [v[0] for _, v in rows["/gnss/state"]]
    assert states[-2:] == [None, None]  # empty states: the lane's end at the drive's, and the ruler's (blueprints.ruler_end_s)
    # between two spans, an empty state 1 ms before the next (layers.with_merge_breaks: Rerun folds touching narrow spans)
    assert states[1:-2:2] == [None] * (len(states[:-2]) // 2)
    states = states[:-2:2]
    # GNSS through the warm-up, then outage 1 .. outage 57 back to back to the drive's end (600 s)
    assert states[0] == "GNSS" and states[1] == "outage 1 (30-40 s)" and states[-1] == "outage 57 (590-600 s)" and len(states) == n_seq + 1


def test_outage_inspector_shows_each_outage_from_its_start_fix(replayed):
    """The inspector's truth is the GNSS track of the outage (read from the logged per-sample
    positions) less the fix at its start; each estimate's end is its final error away from the
    truth's end (evaluate's number, computed from lat/lon); the grid covers everything drawn and the
    scale bar's label is the grid's step."""
    path, rep = replayed
    rows, _ = read_rrd(path)
    pos_t = np.array([t for t, _ in rows["/local/gnss/position"]])
    pos = np.array([v[0] for _, v in rows["/local/gnss/position"]])
    truth_rows = rows["/inspect/gnss"]
    for k, seq in enumerate(rep["sequences"]):
        t0 = seq["start_s"]
        t_row, strip = truth_rows[k]
        assert t0 < t_row < t0 + 0.01  # just after the start: the previous outage stays shown at t0
        inside = (pos_t > t0 + 1e-6) & (pos_t < t0 + N_WIN - 1e-6)
        start_local = np.array(rows["/local/ins/live"][k * (N_WIN + 1)][1][0][0])  # the fix every estimate starts from
        truth = np.array(strip[0])
        assert np.allclose(truth[0], 0.0)
        np.testing.assert_allclose(truth[1:-1], pos[inside] - start_local, atol=1e-3)
        assert np.hypot(*(truth[-1] - truth[-2])) < 2.0  # the end on the windows' grid, a sample's travel from the last fix
        drawn = [np.array(strip[0])]
        for est in ("ins", "idnn"):
            final_strip = np.array(rows[f"/inspect/{est}"][k * (N_WIN + 1) + N_WIN][1][0])
            assert len(final_strip) == N_WIN + 1 and np.allclose(final_strip[0], 0.0, atol=1e-6)
            error = np.hypot(*(final_strip[-1] - np.array(strip[0])[-1]))
            assert error == pytest.approx(seq[est]["final_position_error_m"], abs=0.05 + 0.02 * seq[est]["final_position_error_m"])
            drawn.append(final_strip)
        pts = np.concatenate(drawn)
        grid = np.concatenate([np.array(line) for line in rows["/inspect/grid"][k][1]])
        assert (pts.min(axis=0) >= grid.min(axis=0)).all() and (pts.max(axis=0) <= grid.max(axis=0)).all()
        xs = np.unique(np.round([line[0][0] for line in rows["/inspect/grid"][k][1] if line[0][0] == line[1][0]], 6))
        bar = np.array(rows["/inspect/scale"][k][1][0])
        assert np.diff(xs) == pytest.approx(np.full(len(xs) - 1, bar[1, 0] - bar[0, 0]))


def test_recorded_errors_equal_evaluate_json(replayed):
    path, rep = replayed
    rows, _ = read_rrd(path)
    for est in ("ins", "idnn"):
        for entity, key in (("crse_m", "crse_m"), ("cae_m", "cae_m"), ("yaw_crse_radps", "yaw_crse_radps"), ("position_error_m", "final_position_error_m")):
            values = np.array([v[0] for _, v in rows[f"/errors/{entity}/{est}"]]).reshape(-1, N_WIN)
            expected = [s[est][key] for s in rep["sequences"]]
            np.testing.assert_allclose(values[:, -1], expected, rtol=1e-9, atol=1e-9, err_msg=f"{est} {key}")
        # the outage's last error sample sits at its end time
        times = np.array([t for t, _ in rows[f"/errors/crse_m/{est}"]]).reshape(-1, N_WIN)
        np.testing.assert_allclose(times[:, -1], [s["start_s"] + N_WIN for s in rep["sequences"]], atol=1e-6)


def test_paper_run_without_data_root_explains(tmp_path):
    proc = run_cli("replay", "V-Vw8", "--outage", "10s", "-o", str(tmp_path / "x.rrd"))
    assert proc.returncode == 2
    assert "sharp-cornering test run" in proc.stderr and "--data-root" in proc.stderr
    assert "Traceback" not in proc.stderr and not list(tmp_path.iterdir())


def test_bad_placements_are_clear(tmp_path):
    # The placement logic is tested through the API (test_api.py); here: the CLI names its options.
    out = str(tmp_path / "x.rrd")
    cases = [
        (["--at", "12s,15s"], ["--at 12s,15s", "overlaps"]),
        (["--at", "12s", "--every", "30s"], ["choose one outage placement"]),
    ]
    for extra, fragments in cases:
        proc = run_cli("replay", "hard-brake", "--no-idnn", "-q", "-o", out, *extra)
        assert proc.returncode == 2 and all(f in proc.stderr for f in fragments), (extra, proc.stderr)
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_the_recording_draws_the_drift_curve_of_its_report(tmp_path):
    """Issue 31.2: the drift view's mean lines are the report's drift curve (plot units: seconds
    across 160, the axis top in metres down 100), and the current outage's curve ends at its final
    error."""
    import json

    from rerun.chunk import RrdReader

    import ionav_viz as iv

    replayed = iv.replay("hard-brake", placement=iv.Every(60.0), estimators=["ins", "odo"], output=tmp_path / "r.rrd")
    drift = json.loads(replayed.report.to_json())["drift"]
    strips = {}
    for chunk in RrdReader(replayed.path).stream():
        path = str(chunk.entity_path).strip("/")
        if path.startswith("drift/") and path.endswith("/mean"):
            batch = chunk.to_record_batch()
            column = next(n for n in batch.schema.names if n.endswith(":strips"))
            strips[path.split("/")[1]] = np.asarray(batch.column(column).to_pylist()[0][0])
    assert set(strips) == {"ins", "odo"}
    for est, points in strips.items():
        x, y = points[:, 0], -points[:, 1]
        assert np.allclose(x, np.arange(len(x)) / (len(x) - 1) * 160.0)
        mean = np.asarray(drift[est]["mean_m"])
        scale = y[-1] / mean[-1]  # metres per plot unit: one for both estimators
        assert np.allclose(y, mean * scale, atol=1e-3) and 100.0 / scale >= max(drift[e]["p90_m"][-1] for e in drift)


def test_the_whole_drives_scale_bar_lies_clear_of_the_track(tmp_path):
    """Tour 51: the local view's grid hugs the drive and its scale bar sat in the bottom-left corner
    whatever lay there: on the roundabout's 60-200 s the bar and its label covered a roundabout (90
    fixes under them). It now goes to a corner the track leaves free, inside the grid."""
    out = tmp_path / "span.rrd"
    proc = run_cli("replay", "roundabout", "--span", "60s:200s", "--every", "30s", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    from rerun.chunk import RrdReader

    strips = {str(c.entity_path): c.to_record_batch().column("LineStrips2D:strips").to_pylist()[0] for c in RrdReader(out).stream()
              if str(c.entity_path) in ("/local/gnss", "/local/grid", "/local/grid/scale")}
    truth = np.concatenate([np.array(s) for s in strips["/local/gnss"]])
    grid = np.concatenate([np.array(s) for s in strips["/local/grid"]])
    (x0, y), (x1, _) = np.array(strips["/local/grid/scale"][0])
    height = np.ptp(grid[:, 1])
    # the bar, its label below it, half a step either side
    under = ((truth[:, 0] >= x0 - (x1 - x0) / 2) & (truth[:, 0] <= x1 + (x1 - x0) / 2)
             & (truth[:, 1] >= y - 0.03 * height) & (truth[:, 1] <= y + 0.09 * height))
    assert int(under.sum()) == 0
    assert grid[:, 0].min() <= x0 < x1 <= grid[:, 0].max() and grid[:, 1].min() <= y <= grid[:, 1].max()


def test_the_inspector_shows_where_the_truth_was_when_each_estimate_was_where_it_is(tmp_path):
    """Tour 51: the inspector drew the outage's whole truth from its start and each estimate growing,
    with a dot at each estimate's current position but none on the truth: scrubbing inside an outage
    showed no drift so far. inspect/gnss/position is the truth at the same instants; at every
    window's end the distance between the two dots is the recorded position error."""
    out = tmp_path / "r.rrd"
    proc = run_cli("replay", "roundabout", "--every", "60s", "--estimators", "ins,odo", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    rows, _ = read_rrd(out)
    for est in ("ins", "odo"):
        truth, estimate = rows["/inspect/gnss/position"], rows[f"/inspect/{est}/position"]
        assert [t for t, _ in truth] == [t for t, _ in estimate] and len(truth) > 20
        error = {round(t, 3): v[0] for t, v in rows[f"/errors/position_error_m/{est}"] if np.isfinite(v[0])}
        gaps = [(np.hypot(*np.subtract(a[0], b[0])), error[round(t, 3)]) for (t, a), (_, b) in zip(truth, estimate) if round(t, 3) in error]
        assert len(gaps) >= 0.9 * len(truth)
        np.testing.assert_allclose(*np.array(gaps).T, atol=1e-3)
