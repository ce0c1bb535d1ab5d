import numpy as np
import pytest

from ionav_viz.core.errors import InputError
from ionav_viz.core.units import G_MPS2
from ionav_viz.sources.iovnbd import HEADER, HEADER_LINE, read_iovnbd

from .conftest import run_cli

# Three rows in the real format, hand-written; the last header carries a cp1252 byte.
ROWS = [
    "9,36000.00,52.40680000,-1.51970000,36.00,90.00,80.00,0.00,0.10,1.5,10.00,10.00,10.00,10.00,-2.000,36.0,0.100,0.010,0,2,2,1500,90,0,0,0,14.2,12,20",
    "9,36000.10,52.40680000,-1.51964700,36.00,90.20,80.00,0.00,0.10,1.5,10.00,10.00,10.00,10.00,-2.000,36.0,0.100,0.010,0,2,2,1500,90,0,0,0,14.2,12,20",
    "9,36000.20,52.40680000,-1.51959400,36.00,90.40,80.00,0.00,0.10,1.5,10.00,10.00,10.00,10.00,-2.000,36.0,0.100,0.010,0,2,2,1500,90,0,0,0,14.2,12,20",
]


def _write(path, header=HEADER_LINE, rows=ROWS, encoding="cp1252"):
    path.write_bytes(("\r\n".join([header] + rows) + "\r\n").encode(encoding))
    return path


def test_reads_the_exact_real_header_with_a_cp1252_byte(tmp_path):
    header = HEADER_LINE.replace("Air Temperature (degrees)", "Air Temperature (\u00b0C)")
    path = _write(tmp_path / "V-Vw8.csv", header=header)
    assert b"\xb0" in path.read_bytes()  # not valid UTF-8
    d = read_iovnbd(path)
    assert d.name == "V-Vw8" and len(d) == 3
    np.testing.assert_allclose(d.t_s, [0.0, 0.1, 0.2], atol=1e-9)
    assert d.start_time_of_day_s == pytest.approx(36000.0)
    np.testing.assert_allclose(d.speed_mps, 10.0)  # 36 km/h
    np.testing.assert_allclose(d.accel_long_mps2, 0.1 * G_MPS2)
    np.testing.assert_allclose(d.columns["speed_can_mps"], 10.0)
    # clockwise-positive -2 deg/s in the file = a 2 deg/s left turn, counter-clockwise positive
    np.testing.assert_allclose(d.yaw_rate_radps, np.radians(2.0))
    np.testing.assert_allclose(d.lon_deg[1], -1.519647)


def test_header_has_29_columns_with_leading_spaces():
    assert len(HEADER) == 29
    parts = HEADER_LINE.split(",")
    assert len(parts) == 29 and not parts[0].startswith(" ") and all(p.startswith(" ") for p in parts[1:])
    assert "Number fof gear employed 1-5" in HEADER_LINE


def _with_cells(rows, **cells_by_index):
    out = []
    for r in rows:
        cells = r.split(",")
        for index, value in cells_by_index.items():
            cells[int(index[1:])] = value
        out.append(",".join(cells))
    return out


def test_vbox_minutes_are_detected(tmp_path):
    # VBOX minutes: latitude * 60, longitude * 60 with west positive
    rows = _with_cells(ROWS, c2=f"{52.4068 * 60:.5f}", c3=f"{1.5197 * 60:.5f}")
    d = read_iovnbd(_write(tmp_path / "V-min.csv", rows=rows))
    np.testing.assert_allclose(d.lat_deg, 52.4068)
    np.testing.assert_allclose(d.lon_deg, -1.5197)


def test_yaw_sign_flipped_when_the_data_says_so(tmp_path, caplog):
    from ionav_viz.sim.simulate import write_simulated_drive

    path = write_simulated_drive(tmp_path / "V-r.csv", "roundabout", seed=5, duration_s=90)
    reference = read_iovnbd(path)
    lines = path.read_text().splitlines()
    col = HEADER.index("Yaw Rate (deg/sec)")
    flipped = [lines[0]] + [",".join(f"{-float(c):.3f}" if i == col else c for i, c in enumerate(row.split(","))) for row in lines[1:]]
    other = tmp_path / "V-ccw.csv"
    other.write_text("\r\n".join(flipped) + "\r\n")
    with caplog.at_level("WARNING", logger="ionav_viz"):
        d = read_iovnbd(other)
    assert "flipped" in caplog.text
    np.testing.assert_allclose(d.yaw_rate_radps, reference.yaw_rate_radps, atol=1e-12)
    forced = read_iovnbd(other, yaw_sign="cw")
    np.testing.assert_allclose(forced.yaw_rate_radps, -reference.yaw_rate_radps, atol=1e-12)


def test_missing_columns_are_named(tmp_path):
    header = HEADER_LINE.replace(" Yaw Rate (deg/sec),", " Yaw (deg/sec),")
    with pytest.raises(InputError, match=r"missing column.*'yaw rate'"):
        read_iovnbd(_write(tmp_path / "V-a.csv", header=header))


def test_non_numeric_cell_names_row_and_column(tmp_path):
    rows = list(ROWS)
    rows[1] = rows[1].replace(",36.00,90.20,", ",fast,90.20,")
    with pytest.raises(InputError, match=r"row 3, column 'Velocity \(km/hr\)'.*'fast'"):
        read_iovnbd(_write(tmp_path / "V-b.csv", rows=rows))


def test_time_going_backwards_names_the_row(tmp_path):
    rows = [ROWS[0], ROWS[2], ROWS[1]]
    with pytest.raises(InputError, match="row 4: time goes backwards"):
        read_iovnbd(_write(tmp_path / "V-c.csv", rows=rows))


def test_midnight_wrap_is_not_time_going_backwards(tmp_path):
    rows = [r.replace("36000.", "86399.") for r in ROWS[:2]] + [ROWS[2].replace("36000.20", "0.00")]
    d = read_iovnbd(_write(tmp_path / "V-d.csv", rows=rows))
    np.testing.assert_allclose(d.t_s, [0.0, 0.1, 1.0], atol=1e-9)  # 86399.0, 86399.1, 86400.0


def test_cli_error_is_one_line_with_exit_code_2(tmp_path):
    rows = [ROWS[0], ROWS[2], ROWS[1]]
    path = _write(tmp_path / "V-e.csv", rows=rows)
    proc = run_cli("evaluate", str(path), "--no-idnn")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "V-e.csv: row 4" in proc.stderr
    assert "Traceback" not in proc.stderr
