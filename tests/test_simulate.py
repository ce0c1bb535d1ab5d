
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
