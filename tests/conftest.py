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
    full_env.pop("IONAV_DATA", None) if env is None or "IONAV_DATA" not in env else None
    return subprocess.run(
        [sys.executable, "-m", "ionav_viz.cli", *args],
        capture_output=True,
        text=True,
        env=full_env,
        cwd=cwd or REPO,
        timeout=timeout,
    )


@pytest.fixture(scope="session")
def ideal_drive_csv(tmp_path_factory) -> Path:
    """A noise-free synthetic motorway drive (perfect sensors, flat road)."""
    from ionav_viz.sim.simulate import SensorModel, write_simulated_drive

    path = tmp_path_factory.mktemp("drives") / "V-ideal.csv"
    return write_simulated_drive(path, "motorway", seed=3, duration_s=120, sensors=SensorModel.ideal())
