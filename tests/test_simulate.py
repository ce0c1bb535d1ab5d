
import numpy as np
import pytest

from ionav_viz.dataset.samples import SAMPLES, samples_dir
from ionav_viz.sim.simulate import write_simulated_drive
from ionav_viz.sources.iovnbd import HEADER_LINE, read_iovnbd

from .conftest import run_cli


def test_regenerating_a_bundled_sample_gives_the_same_bytes(tmp_path):
    sample = next(s for s in SAMPLES if s.scenario == "hard-brake" and s.role == "test")
    out = tmp_path / sample.file
    proc = run_cli("simulate", sample.scenario, "-o", str(out), "--seed", str(sample.seed), "--duration", f"{sample.duration_s:g}s")
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes() == (samples_dir() / sample.file).read_bytes()


def test_same_seed_same_bytes_other_seed_other_bytes(tmp_path):
    a = write_simulated_drive(tmp_path / "a.csv", "roundabout", seed=7, duration_s=30).read_bytes()
    b = write_simulated_drive(tmp_path / "b.csv", "roundabout", seed=7, duration_s=30).read_bytes()
    c = write_simulated_drive(tmp_path / "c.csv", "roundabout", seed=8, duration_s=30).read_bytes()
    assert a == b and a != c


def test_format_is_the_real_one(tmp_path):
    raw = write_simulated_drive(tmp_path / "V-x.csv", "sharp-cornering", seed=1, duration_s=20).read_bytes()
    lines = raw.split(b"\r\n")
    assert lines[0].decode() == HEADER_LINE
    assert all(len(row.split(b",")) == 29 for row in lines[1:-1]) and lines[-1] == b""
    d = read_iovnbd(tmp_path / "V-x.csv")
    dt = np.diff(d.t_s)
    assert 9.5 < d.rate_hz < 10.5 and dt.min() > 0.09 and dt.max() < 0.31


@pytest.mark.parametrize(
    "scenario, check",
    [
        ("motorway", lambda d: 80 / 3.6 <= np.percentile(d.speed_mps, 90) <= 100 / 3.6),
        ("hard-brake", lambda d: d.accel_long_mps2.min() <= -0.45 * 9.80665),
        ("roundabout", lambda d: np.degrees(np.abs(d.yaw_rate_radps)).max() > 15),
        ("sharp-cornering", lambda d: np.degrees(np.abs(d.yaw_rate_radps)).max() > 20 and d.speed_mps.max() < 47 / 3.6),
        ("stationary", lambda d: d.speed_mps.max() < 0.5),
    ],
)
def test_scenarios_have_their_defining_motion(scenario, check):
    sample = next(s for s in SAMPLES if s.scenario == scenario)
    assert check(read_iovnbd(samples_dir() / sample.file))


def _losses_in(path) -> int:
    """Stretches of rows with no GNS satellite in a written CSV (the logger's own mark of a loss)."""
    import csv

    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    none = np.array([float(r[0]) == 0 for r in rows[1:]])
    return int(np.sum(none[1:] & ~none[:-1]) + none[0])


@pytest.mark.parametrize(("duration", "asked", "room"), [("20s", 5, 0), ("2m", 3, 4)])
def test_fewer_gnss_losses_than_asked_is_said_with_the_room(tmp_path, duration, asked, room):
    """--gnss-loss 5 on a 20 s drive wrote none, silently (and 3 on 2 minutes, 2). One warning line
    says how many were written and how many the drive has room for: each loss 3-15 s, 20 s from the
    ends and from each other, so (D - 20 s) / (3 s + 20 s) at most: 0 in 20 s, 4 in 120 s."""
    out = tmp_path / "V-lossy.csv"
    proc = run_cli("simulate", "motorway", "--duration", duration, "--gnss-loss", str(asked), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    written = _losses_in(out)
    assert written < asked and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith(f"warning: motorway drive of {120 if duration == '2m' else 20} s: wrote {written} of the {asked} GNSS losses")
    assert f"room for at most {room}," in proc.stderr and "--duration" in proc.stderr
    proc = run_cli("simulate", "motorway", "--duration", "10m", "--gnss-loss", "3", "-o", str(tmp_path / "V-fits.csv"))
    assert proc.returncode == 0 and proc.stderr == "" and _losses_in(tmp_path / "V-fits.csv") == 3


def test_the_api_warns_too(tmp_path, caplog):
    import logging

    import ionav_viz as iv

    with caplog.at_level(logging.WARNING, logger="ionav_viz"):
        iv.simulate("motorway", tmp_path / "V-short.csv", duration_s=20.0, gnss_losses=5)
    assert [r.getMessage().split(" (")[0] for r in caplog.records] == ["motorway drive of 20 s: wrote 0 of the 5 GNSS losses asked for"]


@pytest.mark.parametrize(("name", "hint"), [("x.mcap", "--imu mems|phone|dash"), ("x.txt", "V-drive.csv"), ("x", "V-drive.csv")])
def test_a_drive_is_written_only_as_a_csv(tmp_path, name, hint):
    """simulate without --imu wrote its IO-VNBD CSV text under any name: -o x.mcap gave a '.mcap'
    no reader takes ("no MCAP magic"), -o x.txt one replay refuses by its type. Refused now, nothing written."""
    proc = run_cli("simulate", "roundabout", "--duration", "20s", "-o", str(tmp_path / name))
    assert proc.returncode == 2 and "a simulated drive is an IO-VNBD CSV file (.csv)" in proc.stderr and hint in proc.stderr, proc.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("duration", "rows"), [("500ms", 6), ("2s", 21)])
def test_a_drive_under_3_s_is_written(tmp_path, duration, rows):
    """'simulate roundabout --duration 2s' stopped with a ValueError traceback and exit code 1 (the
    standing flag's 3 s window was longer than the drive); now the short CSV is written and reads."""
    out = tmp_path / "V-short.csv"
    proc = run_cli("simulate", "roundabout", "--duration", duration, "-o", str(out))
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert len(read_iovnbd(out).t_s) == rows


@pytest.mark.parametrize("losses", [1.5, "2", True, -1])
def test_gnss_losses_are_a_whole_number(tmp_path, losses):
    """iv.simulate(..., gnss_losses=1.5) wrote one loss and warned 'wrote 1 of the 1 GNSS losses
    asked for'; "2" was a TypeError. Refused now, naming the argument, nothing written."""
    import ionav_viz as iv

    with pytest.raises(iv.InputError, match=r"GNSS losses: give a whole number, 0 or more") as info:
        iv.simulate("motorway", tmp_path / "V-x.csv", duration_s=60.0, gnss_losses=losses)
    assert info.value.param == "gnss_losses" and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("args", "named"), [(["roundabout", "-o", "x.csv"], "SCENARIO, -o"), (["--seed", "5", "--duration", "10s"], "--seed, --duration")])
def test_bundled_refuses_the_options_it_would_ignore(tmp_path, args, named):
    """'simulate --bundled DIR --seed 5 --duration 10s' (or with a scenario and -o) wrote the 47
    bundled samples with their own seeds and lengths, ignoring the options without a word."""
    proc = run_cli("simulate", "--bundled", "bund", *args, cwd=tmp_path)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    assert proc.stderr == f"error: --bundled regenerates every bundled sample as it is shipped, so {named} would be ignored (hint: leave them out, or simulate one drive without --bundled)\n"
    assert list(tmp_path.iterdir()) == []
