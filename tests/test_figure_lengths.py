"""Issue 63.3: ``figures`` of a report of several outage lengths (``evaluate --outage 10s,30s --json``)
refused it ("write one drive's report"); it draws the error against outage length now."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from PIL import Image

from .conftest import one_line_error, run_cli


@pytest.fixture(scope="module")
def bundled_runs(tmp_path_factory) -> Path:
    """The bundled roundabout drive evaluated at 10 and 30 s outages."""
    folder = tmp_path_factory.mktemp("lengths")
    proc = run_cli("evaluate", "roundabout", "--estimators", "ins,odo", "--outage", "10s,30s", "--json", "-q")
    assert proc.returncode == 0, proc.stderr
    (folder / "lengths.json").write_text(proc.stdout)
    return folder


def test_figures_of_several_outage_lengths_draw_error_against_length(bundled_runs, tmp_path):
    """'figures' refused 'evaluate --outage 10s,30s --json' ("write one drive's report"); it draws
    the error against outage length now."""
    proc = run_cli("figures", str(bundled_runs / "lengths.json"), "-o", str(tmp_path / "figs"))
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == ["lengths.pdf", "lengths.png", "lengths.svg"]
    assert Image.open(tmp_path / "figs" / "lengths.png").size[0] == 1050
    svg = (tmp_path / "figs" / "lengths.svg").read_text()
    assert "error against outage length" in svg and "INS DR" in svg and "Odometry" in svg and "90th percentile" in svg
    help_text = " ".join(run_cli("figures", "--help", env={"COLUMNS": "1000"}).stdout.split())
    assert "or lengths (a report of several outage lengths)" in help_text
    broken = json.loads((bundled_runs / "lengths.json").read_text())
    del broken["by_length"]["odo"]["final_error_p90_m"]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(broken))
    one_line_error(
        run_cli("figures", str(bad), "-o", str(tmp_path / "none")), f"{bad}: by_length.odo.final_error_p90_m: missing"
    )
    assert not (tmp_path / "none").exists()
