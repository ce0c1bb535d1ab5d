"""Shared helpers: run the CLI as a user would, and write small drives."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def run_cli(*args: str, env: dict | None = None, cwd: Path | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    """Run ``ionav-viz ARGS`` in a fresh interpreter; returns the completed process (text)."""
    full_env = {**os.environ, **(env or {})}
    for inherited in ("IONAV_DATA", "COLUMNS"):  # the developer's data root and terminal width are not the test's
        if inherited not in (env or {}):
            full_env.pop(inherited, None)
    return subprocess.run(
        [sys.executable, "-m", "ionav_viz.cli", *args],
        capture_output=True,
        text=True,
        env=full_env,
        cwd=cwd or REPO,
        timeout=timeout,
    )


def assert_same_sequences(reference: list[dict], got: list[dict], estimators, rel: float, abs: float = 1e-9) -> None:
    """Two reports' ``sequences`` (``to_json``) agree: the same outages, and every metric of each
    estimator within ``rel``/``abs``. A metric that is undefined (``None``, e.g. ``final_error_pct``
    below 10 m driven) must be undefined in both."""
    assert len(got) == len(reference) > 0
    for a, b in zip(reference, got):
        assert b["start_s"] == pytest.approx(a["start_s"], abs=1e-9)
        for est in estimators:
            assert b[est].keys() == a[est].keys(), est
            for key, value in a[est].items():
                if value is None:
                    assert b[est][key] is None, (est, key, b[est][key])
                else:
                    assert b[est][key] == pytest.approx(value, rel=rel, abs=abs), (est, key)


def expect_one_line_error(path: Path, *messages: str) -> None:
    """``ionav-viz evaluate PATH`` fails on bad input: exit 2, one line, no traceback, naming ``messages``."""
    proc = run_cli("evaluate", str(path), "--no-idnn")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    for message in messages:
        assert message in proc.stderr, proc.stderr


@pytest.fixture(scope="session")
def ideal_drive_csv(tmp_path_factory) -> Path:
    """A noise-free synthetic motorway drive (perfect sensors, flat road)."""
    from ionav_viz.sim.simulate import SensorModel, write_simulated_drive

    path = tmp_path_factory.mktemp("drives") / "V-ideal.csv"
    return write_simulated_drive(path, "motorway", seed=3, duration_s=120, sensors=SensorModel.ideal())
