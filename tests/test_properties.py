"""Property-based tests (hypothesis, derandomised so runs are repeatable)."""

from __future__ import annotations

import contextlib
import functools
import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ionav_viz.analysis.metrics import aeps, cae, crse, sequence_metrics
from ionav_viz.core.errors import InputError
from ionav_viz.nav.protocol import Solution
from ionav_viz.nav.track import Track
from ionav_viz.sources.iovnbd import HEADER, HEADER_LINE, read_iovnbd

SETTINGS = settings(max_examples=120, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

cell = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32).map(lambda x: f"{x:.6g}"),
    st.integers(-10**6, 10**6).map(str),
    st.sampled_from(["", " ", "nan", "inf", "-", "1e400", "abc", "0x10", "1,5", '"3"', "°", "\t"]),
)


def plausible_row(i: int, draw) -> list[str]:
    """A row of the real format with values near a real drive, so some inputs pass."""
    t = 36000.0 + 0.1 * i + draw(st.floats(-0.02, 0.02))
    cells = ["9", f"{t:.3f}", f"{52.4 + 1e-5 * i:.8f}", f"{-1.5 + 1e-5 * i:.8f}", f"{draw(st.floats(0, 120)):.2f}",
             f"{draw(st.floats(-10, 400)):.2f}"] + ["1.0"] * 23
    return cells


@st.composite
def csv_texts(draw) -> bytes:
    kind = draw(st.sampled_from(["plausible", "mutated", "garbage", "header-variants"]))
    if kind == "garbage":
        return draw(st.binary(max_size=2000))
    n = draw(st.integers(0, 40))
    rows = [plausible_row(i, draw) for i in range(n)]
    if kind == "mutated" and rows:
        for _ in range(draw(st.integers(1, 6))):
            r = draw(st.integers(0, len(rows) - 1))
            c = draw(st.integers(0, 28))
            rows[r][c] = draw(cell)
        if draw(st.booleans()):
            r = draw(st.integers(0, len(rows) - 1))
            rows[r] = rows[r][: draw(st.integers(0, 29))] + draw(st.lists(cell, max_size=3))
    header = HEADER_LINE
    if kind == "header-variants":
        names = list(HEADER)
        if draw(st.booleans()):
            names = draw(st.permutations(names))
        if draw(st.booleans()):
            del names[draw(st.integers(0, len(names) - 1))]
            rows = [r[: len(names)] for r in rows]
        header = ",".join([names[0]] + [" " + h for h in names[1:]])
    end = draw(st.sampled_from(["\r\n", "\n"]))
    text = end.join([header] + [",".join(r) for r in rows]) + draw(st.sampled_from([end, ""]))
    data = text.encode(draw(st.sampled_from(["utf-8", "cp1252", "utf-16"])), errors="replace")
    if draw(st.booleans()) and data:
        data = data[: draw(st.integers(0, len(data)))]
    return data


@SETTINGS
@given(data=csv_texts())
def test_reader_returns_a_valid_drive_or_its_own_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("h") / "V-h.csv"
    path.write_bytes(data)
    try:
        drive = read_iovnbd(path)
    except InputError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    from hypothesis import event

    event("a valid drive")
    t = drive.t_s
    assert len(drive) >= 2 and t[0] == 0.0 and np.all(np.diff(t) > 0)
    for key in ("lat_deg", "lon_deg", "speed_mps", "heading_deg", "accel_long_mps2", "yaw_rate_radps"):
        assert np.all(np.isfinite(drive.columns[key])), key
    assert np.all(np.abs(drive.lat_deg) <= 90) and np.all(np.abs(drive.lon_deg) <= 180)
    assert np.all((drive.heading_deg >= 0) & (drive.heading_deg < 360))
    # and what the reader accepts, the navigation code takes
    from ionav_viz.analysis.evaluate import evaluate_drive

    with contextlib.suppress(InputError):
        evaluate_drive(drive, 1, ["ins"])


errors = st.lists(st.floats(-1e4, 1e4), min_size=1, max_size=30).map(np.array)


@SETTINGS
@given(err=errors)
def test_metric_invariants(err):
    assert crse(err) >= abs(cae(err)) - 1e-9
    assert math.isclose(aeps(err), crse(err) / len(err), rel_tol=1e-12, abs_tol=1e-12)
    assert crse(np.zeros_like(err)) == 0 and cae(np.zeros_like(err)) == 0


@SETTINGS
@given(n=st.integers(1, 12), pick=st.integers(0, 10**6))
def test_errors_are_zero_when_the_estimate_is_the_truth(n, pick):
    from ionav_viz.experiment.outages import every
    from ionav_viz.nav.windows import make_windows
    from ionav_viz.sources.load import load_drive

    w = make_windows(load_drive("roundabout"))
    starts = every(w, n, n)
    starts = starts[pick % len(starts) :][:3]
    idx = starts[:, None] + np.arange(n)[None, :]
    lat = np.concatenate([w.lat0_deg[idx], w.lat1_deg[idx[:, -1:]]], axis=1)
    lon = np.concatenate([w.lon0_deg[idx], w.lon1_deg[idx[:, -1:]]], axis=1)
    truth = Solution(w.gnss_disp_m[idx], w.gnss_yaw_rate_radps[idx], Track(lat, lon, np.zeros_like(lat)))
    for name, values in sequence_metrics(w, starts, n, truth).items():
        defined = ~np.isnan(values) if name == "final_error_pct" else np.ones(len(values), bool)  # NaN below 10 m driven
        np.testing.assert_allclose(values[defined], 0.0, atol=1e-9)


value = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-50, 50), st.sampled_from([0.0, -0.0, 1e-300, 1e300]))
stamp = st.one_of(st.floats(0, 40), st.floats(-1e3, 1e10), st.sampled_from([0.0, 20.0, math.nan, math.inf, -math.inf]))


@st.composite
def mcap_messages(draw):
    """Sequences of IMU and fix messages near a drive, with any values and stamps mixed in."""
    n_imu, n_fix = draw(st.integers(0, 100)), draw(st.integers(0, 30))
    # shares of fields drawn arbitrarily: values (often fatal), stamps, fix positions and status
    wild_value, wild_stamp, wild_fix = (draw(st.sampled_from(shares)) for shares in
                                        ([0.0, 0.0, 0.0, 0.002, 0.05], [0.0, 0.05, 0.3, 1.0], [0.0, 0.0, 0.02, 0.3]))

    def maybe(strategy, normal, share):
        return draw(strategy) if draw(st.floats(0, 1)) < share else normal

    imu = [(maybe(stamp, 0.1 * i, wild_stamp), maybe(value, 0.3, wild_value), maybe(value, 0.01, wild_value)) for i in range(n_imu)]
    fixes = [(maybe(stamp, 0.4 * i, wild_stamp), maybe(value, 52.4 + 1e-5 * i, wild_fix), maybe(value, -1.5 + 1e-5 * i, wild_fix),
              maybe(st.integers(-2, 2), 0, wild_fix)) for i in range(n_fix)]
    return imu, fixes


def _write_mcap(path, imu, fixes) -> None:
    import json

    from mcap.writer import Writer

    def stamp_of(t):
        if not math.isfinite(t):
            return {"sec": 0, "nanosec": 0}
        sec = math.floor(t)
        return {"sec": int(sec), "nanosec": int((t - sec) * 1e9) % 1_000_000_000}

    t0 = 1_700_000_000
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        s_imu = w.register_schema("sensor_msgs/msg/Imu", "jsonschema", b"{}")
        s_fix = w.register_schema("sensor_msgs/msg/NavSatFix", "jsonschema", b"{}")
        c_imu, c_fix = w.register_channel("/imu", "json", s_imu), w.register_channel("/fix", "json", s_fix)
        for i, (t, a, r) in enumerate(imu):
            msg = {"header": {"stamp": stamp_of(t0 + t)}, "linear_acceleration": {"x": a}, "angular_velocity": {"z": r}}
            w.add_message(c_imu, log_time=(t0 + i) * 10**9, data=json.dumps(msg).encode(), publish_time=0)
        for i, (t, lat, lon, status) in enumerate(fixes):
            msg = {"header": {"stamp": stamp_of(t0 + t)}, "status": {"status": status}, "latitude": lat, "longitude": lon, "altitude": 80.0}
            w.add_message(c_fix, log_time=(t0 + i) * 10**9, data=json.dumps(msg).encode(), publish_time=0)
        w.finish()


@settings(SETTINGS, max_examples=250)
@given(messages=mcap_messages())
def test_mcap_reader_returns_a_valid_drive_or_its_own_error(tmp_path_factory, messages):
    from ionav_viz.sources.mcap_reader import read_mcap

    path = tmp_path_factory.mktemp("m") / "h.mcap"
    _write_mcap(path, *messages)
    from hypothesis import event

    try:
        drive = read_mcap(path)
    except InputError as exc:
        assert str(exc) and "\n" not in str(exc)
        event(str(exc).split(": ", 1)[1].split(" stamped")[0][:30])
        return
    event("a valid drive")
    t = drive.t_s
    assert len(drive) >= 2 and t[0] == 0.0 and np.all(np.diff(t) > 0)
    for key, column in drive.columns.items():
        assert np.all(np.isfinite(column)), key
    assert np.all(np.abs(drive.lat_deg) <= 90) and np.all(np.abs(drive.lon_deg) <= 180)
    assert np.all((drive.heading_deg >= 0) & (drive.heading_deg < 360)) and np.all(drive.speed_mps >= 0)
    assert drive.duration_s < 3600 + 40  # stray stamps never stretch the drive


def test_headings_wrap_into_0_360_even_for_tiny_negative_angles():
    """Found by the MCAP property test: np.mod(-1e-15, 360) is 360.0, outside [0, 360)."""
    from ionav_viz.core.units import wrap_360

    assert np.mod(-1e-15, 360.0) == 360.0
    assert list(wrap_360(np.array([-1e-15, 0.0, 359.5, 360.0, -90.0, 725.0]))) == [0.0, 0.0, 359.5, 0.0, 270.0, 5.0]


# --- KITTI OXTS folders (round 3) ------------------------------------------------------------------

oxts_text = st.one_of(
    value.map(repr),
    st.sampled_from(["", "nan", "inf", "-inf", "1e400", "abc", "0x10", "1,5", "4.", "--1", "\x00", "°"]),
)
stamp_line = st.one_of(
    st.sampled_from(["", "yesterday", "2011-09-26", "2011-13-40 25:61:61.000000000", "2262-06-01 00:00:00.000000000",
                     "1969-12-31 23:59:59.000000000", "9999-01-01 00:00:00.0", "2011-09-26 13:02:25.1234567891234"]),
    st.datetimes(min_value=__import__("datetime").datetime(1960, 1, 1), max_value=__import__("datetime").datetime(2300, 1, 1))
    .map(lambda d: d.strftime("%Y-%m-%d %H:%M:%S.%f") + "000"),
)


@st.composite
def oxts_folders(draw):
    """(stamp lines, packet texts) near a real KITTI drive, with fields, stamps and files mutated."""
    from ionav_viz.sources.kitti import FIELDS

    n = draw(st.integers(0, 40))
    base = [52.4, -1.5, 116.0, 0.0, 0.0, 0.3, 9.0, 3.0, 9.5, 0.0, 0.0, 0.2, 0.0, 9.81, 0.2, 0.0, 9.81,
            0.0, 0.0, 0.01, 0.0, 0.0, 0.01, 0.02, 0.01, 4, 11, 6, 6, 6]
    assert len(base) == len(FIELDS)
    packets = [[repr(float(v)) if k < 25 else str(int(v)) for k, v in enumerate(base)] for _ in range(n)]
    for i in range(n):
        packets[i][0], packets[i][1] = repr(52.4 + 1e-5 * i), repr(-1.5 + 1e-5 * i)
    stamps = [f"2011-09-26 13:02:{25 + i // 10:02d}.{(i % 10) * 100_000_000:09d}" for i in range(n)]
    kind = draw(st.sampled_from(["plausible", "fields", "stamps", "files"]))
    if kind == "fields" and n:
        for _ in range(draw(st.integers(1, 5))):
            packets[draw(st.integers(0, n - 1))][draw(st.integers(0, len(FIELDS) - 1))] = draw(oxts_text)
    if kind == "stamps" and n:
        for _ in range(draw(st.integers(1, 4))):
            i = draw(st.integers(0, n - 1))
            stamps[i] = draw(st.one_of(stamp_line, st.just(stamps[max(i - 1, 0)]), st.just(stamps[min(i + 1, n - 1)])))
    if kind == "files" and n:
        i = draw(st.integers(0, n - 1))
        change = draw(st.sampled_from(["ragged", "extra stamp", "missing stamp", "empty packet"]))
        if change == "ragged":
            packets[i] = packets[i][: draw(st.integers(0, len(FIELDS) - 1))] + draw(st.lists(oxts_text, max_size=3))
        elif change == "extra stamp":
            stamps.append(stamps[-1])
        elif change == "missing stamp":
            del stamps[i]
        else:
            packets[i] = []
    return stamps, packets


@SETTINGS
@given(folder=oxts_folders())
def test_kitti_reader_returns_a_valid_drive_or_its_own_error(tmp_path_factory, folder):
    from hypothesis import event

    from ionav_viz.sources.kitti import read_kitti

    stamps, packets = folder
    root = tmp_path_factory.mktemp("k") / "2011_09_26_drive_0001_sync"
    (root / "oxts" / "data").mkdir(parents=True)
    (root / "oxts" / "timestamps.txt").write_text("\n".join(stamps) + "\n", errors="surrogateescape")
    for i, packet in enumerate(packets):
        (root / "oxts" / "data" / f"{i:010d}.txt").write_text(" ".join(packet) + "\n")
    try:
        drive = read_kitti(root)
    except InputError as exc:
        assert str(exc) and "\n" not in str(exc)
        event(str(exc).split(": ", 1)[1][:25])
        return
    event("a valid drive")
    t = drive.t_s
    assert len(drive) >= 2 and t[0] == 0.0 and np.all(np.diff(t) > 0)
    for key, column in drive.columns.items():
        assert np.all(np.isfinite(column)), key
    assert np.all(np.abs(drive.lat_deg) <= 90) and np.all(np.abs(drive.lon_deg) <= 180)
    assert np.all((drive.heading_deg >= 0) & (drive.heading_deg < 360)) and np.all(drive.speed_mps >= 0)


# --- plug-in outputs (round 3) ---------------------------------------------------------------------

output_cell = st.one_of(st.floats(-60, 60), st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e200, -1e200, 1e-300]))


@st.composite
def plugin_outputs(draw):
    """What a plug-in's estimate() may return for (n_outages, n_windows) = (3, 10): arrays of any
    values, shapes and types, and objects that are not an Estimate at all."""
    kind = draw(st.sampled_from(["floats", "floats", "shape", "complex", "ints", "objects", "lists", "not an estimate"]))
    if kind == "not an estimate":
        return draw(st.sampled_from([None, 3.0, "x", (1, 2), {"disp_m": 1}]))
    shape = (3, 10) if kind != "shape" else draw(st.sampled_from([(3, 9), (10, 3), (30,), (), (3, 10, 1), (0, 10)]))
    size = int(np.prod(shape))
    arrays = []
    for _ in range(2):
        cells = draw(st.lists(output_cell, min_size=size, max_size=size)) if draw(st.booleans()) else [1.0] * size
        values = np.array(cells, dtype=np.float64).reshape(shape)
        if kind == "complex":
            values = values + 1j * draw(st.floats(-1, 1))
        elif kind == "ints":
            values = np.rint(np.nan_to_num(np.clip(values, -100, 100))).astype(np.int64)
        elif kind == "objects":
            values = values.astype(object)
            values.flat[0] = draw(st.sampled_from(["a", None, [1, 2], 1.0]))
        elif kind == "lists":
            values = values.tolist()
        arrays.append(values)
    return arrays


@settings(SETTINGS, max_examples=80)
@given(output=plugin_outputs())
def test_plugin_outputs_are_accepted_only_when_real_finite_and_physical(output):
    """Whatever a plug-in returns, the run either scores real, finite, physical numbers or stops
    with one line naming the estimator (and the outage and window, for a value out of bounds)."""
    from ionav_viz.nav.protocol import ESTIMATE_LIMITS, Estimate, EstimatorError, solve

    class Returns:
        name, label, needs = "returns", "Returns", ()

        def estimate(self, inputs):
            return Estimate(*output) if isinstance(output, list) else output

    inputs = _plugin_inputs()
    try:
        solution = solve(Returns(), inputs)
    except EstimatorError as exc:
        assert str(exc).startswith("estimator 'returns'") and "\n" not in str(exc), str(exc)
        if "beyond what a car does" in str(exc):
            assert " in outage " in str(exc) and ", window " in str(exc)
        return
    for name in ("disp_m", "yaw_rate_radps"):
        values = getattr(solution, name)
        assert values.dtype == np.float64 and values.shape == (3, 10), name
        assert np.all(np.isfinite(values)) and np.all(np.abs(values) <= ESTIMATE_LIMITS[name]), name


@functools.cache
def _plugin_inputs():
    """Three outages of ten windows of a bundled drive."""
    import ionav_viz as iv
    from ionav_viz.nav.bias import SensorBias
    from ionav_viz.nav.protocol import EstimatorInputs
    from ionav_viz.nav.windows import make_windows

    drive = iv.load_drive("hard-brake")
    return EstimatorInputs(drive, make_windows(drive), np.array([5, 40, 80]), 10, SensorBias.none())
