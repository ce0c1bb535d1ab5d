"""KITTI raw drive folders (OXTS packets), written as the KITTI devkit documents them."""

import json
from pathlib import Path

import numpy as np
import pytest

import ionav_viz as iv
from ionav_viz.core.drive import Drive
from ionav_viz.sources.kitti import FIELDS

from . import bag_fixtures as bf
from .conftest import assert_same_sequences, expect_one_line_error, run_cli

ESTIMATORS = ["ins", "idnn", "ekf"]


@pytest.fixture(scope="module")
def drive():
    return iv.load_drive("hard-brake")


def test_round_trip_gives_the_csv_metrics(tmp_path, drive):
    folder = bf.write_kitti(drive, tmp_path / "2011_09_26_drive_0001_sync")
    read = iv.load_drive(folder)
    assert read.name == "2011_09_26_drive_0001_sync" and read.rate_hz == 10.0 and len(read) == len(drive)
    assert read.start_time_of_day_s == pytest.approx(bf.T0_S % 86400, abs=1e-9)
    moving = drive.speed_mps > 1.0  # the course comes from vn, ve (clockwise from north), not from KITTI's yaw
    np.testing.assert_allclose(read.heading_deg[moving], drive.heading_deg[moving], atol=1e-9)
    np.testing.assert_allclose(read.columns["gnss_sigma_m"], 0.02)
    np.testing.assert_allclose(read.columns["n_satellites"], 11)
    # OXTS's full IMU (af, al, au, wf, wl, wu: forward, left, up) is kept, gravity on z
    np.testing.assert_allclose(read.columns["accel_z_mps2"], bf.G, atol=1e-9)
    np.testing.assert_array_equal(read.columns["gyro_z_radps"], read.yaw_rate_radps)
    # the same drive with the receiver's accuracy KITTI carries: the same metrics
    reference = json.loads(iv.evaluate(bf.carried(drive, gnss_sigma_m=np.full(len(drive), 0.02)), estimators=ESTIMATORS).to_json())
    got = json.loads(iv.evaluate(folder / "oxts", estimators=ESTIMATORS).to_json())
    assert len(got["sequences"]) > 50
    assert_same_sequences(reference["sequences"], got["sequences"], ESTIMATORS, rel=1e-6)


def test_extract_at_100hz_is_averaged_onto_the_grid(tmp_path, drive):
    short = bf.carried(drive, 600)
    t = np.arange(0, short.t_s[-1], 0.01)
    ramp = 0.01 * t  # m/s^2
    wiggle = np.where(np.arange(len(t)) % 2 == 0, 1.0, -1.0)  # 50 Hz, averages out per 0.1 s
    cols = {c: np.interp(t, short.t_s, short.columns[c]) for c in bf.CARRIED}
    cols.update(t_s=t, accel_long_mps2=ramp + wiggle, yaw_rate_radps=np.full(len(t), 0.05))
    fast = Drive("fast", "x", 100.0, 0.0, cols)
    read = iv.load_drive(bf.write_kitti(fast, tmp_path / "2011_09_26_drive_0002_extract"))
    assert read.rate_hz == 10.0 and abs(len(read) - len(t) / 10) <= 1
    # a 0.1 s bin holds 9 to 11 samples (a stamp on a bin's edge goes to the even bin), so the
    # wiggle's mean is at most 1/9 of it; taking one sample per bin would be off by the whole wiggle
    assert np.max(np.abs(read.accel_long_mps2 - 0.01 * read.t_s)) < 1 / 9 + 0.01 * 0.06
    np.testing.assert_allclose(read.yaw_rate_radps, 0.05)


def test_navigation_status_is_the_truth_quality(tmp_path, drive, caplog):
    short = bf.carried(drive, 900)
    navstat = np.full(900, 4)
    navstat[400:430] = 2  # 3 s initialising: not a locked solution
    folder = bf.write_kitti(short, tmp_path / "k", navstat=navstat)
    with caplog.at_level("WARNING", logger="ionav_viz"):
        read = iv.load_drive(folder)
    assert "30 of 900 OXTS packets are not locked" in caplog.text
    assert len(read) == 900  # the inertial data goes on through the loss
    bad = ~read.gnss_ok
    assert bad[401:429].all() and not bad[:399].any() and not bad[431:].any()
    proc = run_cli("info", str(folder))
    span_s = short.t_s[-1] - short.t_s[0]
    expected = f"900 packets over {span_s:.1f} s ({899 / span_s:.1f} Hz): 30 x navstat 2, 870 x navstat 4 (locked)"
    assert proc.returncode == 0 and expected in proc.stdout, proc.stdout


def test_replay_of_a_kitti_drive(tmp_path, drive):
    folder = bf.write_kitti(bf.carried(drive, 1200), tmp_path / "2011_09_26_drive_0005_sync")
    proc = run_cli("replay", str(folder), "-o", str(tmp_path / "k.rrd"), "-q")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "k.rrd").stat().st_size > 50_000


# --- bad folders: one line naming the file, exit 2 -------------------------------------------

@pytest.fixture()
def small(tmp_path, drive):
    return bf.write_kitti(bf.carried(drive, 200), tmp_path / "2011_09_26_drive_0009_sync")


def test_missing_timestamps(small):
    (small / "oxts" / "timestamps.txt").unlink()
    expect_one_line_error(small, "oxts/timestamps.txt: missing", "extract the drive's zip again")


def test_missing_packet_file(small):
    (small / "oxts" / "data" / "0000000007.txt").unlink()
    expect_one_line_error(small, "oxts/data/0000000007.txt: missing")


def test_ragged_packet(small):
    f = small / "oxts" / "data" / "0000000042.txt"
    f.write_text(" ".join(f.read_text().split()[:29]) + "\n")
    expect_one_line_error(small, "0000000042.txt: 29 values, an OXTS packet has 30")


def test_more_stamps_than_packets(small):
    stamps = small / "oxts" / "timestamps.txt"
    stamps.write_text(stamps.read_text() + "2011-09-26 13:05:00.000000000\n")
    expect_one_line_error(small, "201 stamps in timestamps.txt but 200 packet files in data/")


def test_garbled_values_and_stamps(small):
    f = small / "oxts" / "data" / "0000000003.txt"
    f.write_text(f.read_text().replace(" ", " x", 1))
    expect_one_line_error(small, "0000000003.txt: not all values are numbers")
    f.write_text("49.0 8.4 " + " ".join(["0"] * 12) + " 250.0 " + " ".join(["0"] * 15) + "\n")  # af 250 m/s^2
    expect_one_line_error(small, "0000000003.txt: af 250 m/s^2 outside")
    (small / "oxts" / "timestamps.txt").write_text("yesterday\n")
    expect_one_line_error(small, "timestamps.txt: line 1 is not a stamp")


def _set_field(packet: Path, field: str, value: str) -> None:
    values = packet.read_text().split()
    values[FIELDS.index(field)] = value
    packet.write_text(" ".join(values) + "\n")


@pytest.mark.parametrize(("field", "value", "message"), [
    ("vn", "1e9", "0000000005.txt: vn 1e+09 m/s outside [-100, 100]"),  # round 3: a mean CRSE of 909,090,894 m, exit 0
    ("ve", "nan", "0000000005.txt: ve not a finite number"),  # round 3: blamed on the INS ("disp_m is nan in outage 4")
    ("pos_accuracy", "inf", "0000000005.txt: pos_accuracy not a finite number"),
])
def test_every_field_used_is_checked(small, field, value, message):
    _set_field(small / "oxts" / "data" / "0000000005.txt", field, value)
    expect_one_line_error(small, message, "the packet is damaged")


def test_a_folder_named_like_a_packet(small):
    """Round 3: an IsADirectoryError traceback."""
    packet = small / "oxts" / "data" / "0000000011.txt"
    packet.unlink()
    packet.mkdir()
    expect_one_line_error(small, "0000000011.txt: not a packet file", "extract the drive's zip again")


def test_stamps_going_backwards_are_refused_like_csv_rows(small):
    """Round 3: out-of-order stamps were silently sorted (CRSE 5.87 m vs 0.26 m) where the CSV
    reader refuses time going backwards: packets are numbered in the order they were sampled."""
    stamps = small / "oxts" / "timestamps.txt"
    lines = stamps.read_text().splitlines()
    lines[40], lines[41] = lines[41], lines[40]
    stamps.write_text("\n".join(lines) + "\n")
    expect_one_line_error(small, "timestamps.txt: line 42: time goes backwards", "packets 0000000040 and 0000000041")


def test_stamps_beyond_numpys_clock_are_named(small):
    """Round 3: a stamp in 2262 (past datetime64[ns]) printed a nonsense time in a warning."""
    stamps = small / "oxts" / "timestamps.txt"
    lines = stamps.read_text().splitlines()
    lines[7] = "2262-06-01 00:00:00.000000000"
    stamps.write_text("\n".join(lines) + "\n")
    expect_one_line_error(small, "timestamps.txt: line 8: the stamp '2262-06-01 00:00:00.000000000' is not in the years 1970-2199")


@pytest.mark.parametrize("name", ["timestamps.txt", "data/0000000003.txt"])
def test_sparse_giant_files_are_refused_before_reading(small, name):
    """Round 3: a sparse 3 GiB packet or timestamps file was read whole (MemoryError traceback)."""
    f = small / "oxts" / name
    with open(f, "r+b") as handle:
        handle.truncate(3 * 2**30)  # sparse: no disk used
    expect_one_line_error(small, f"{name}: 3221225472 bytes is far more than", "extract the drive's zip again")
