"""docs/results.md's "Your own vehicle" section: benchmarks/own_vehicle.py writes it between two
marker lines, and benchmarks/results_table.py keeps it when it writes the page again."""

from __future__ import annotations

import importlib.util
import sys

from tests.conftest import REPO


def _results_table():
    sys.path.insert(0, str(REPO / "benchmarks"))
    try:
        spec = importlib.util.spec_from_file_location("results_table", REPO / "benchmarks" / "results_table.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules["results_table"] = module  # its dataclasses look their module up
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(REPO / "benchmarks"))


def test_the_section_is_added_once_replaced_after_and_kept_by_the_page(tmp_path):
    rt = _results_table()
    page = tmp_path / "results.md"
    page.write_text("# Measured results\n\nthe table\n")
    rt.replace_section(page, "## Your own vehicle\n\nold table")
    rt.replace_section(page, "## Your own vehicle\n\nnew table\n")
    text = page.read_text()
    assert text.startswith("# Measured results\n\nthe table\n\n" + rt.OWN_VEHICLE_BEGIN)
    assert text.count("## Your own vehicle") == 1 and "new table" in text and "old table" not in text
    assert text.endswith(rt.OWN_VEHICLE_END + "\n")
    kept = rt.kept_section(page)
    assert kept.startswith(rt.OWN_VEHICLE_BEGIN) and "new table" in kept and kept.endswith(rt.OWN_VEHICLE_END + "\n")
    assert rt.kept_section(tmp_path / "missing.md") == ""


def test_the_committed_results_page_has_the_section_with_both_outage_lengths():
    rt = _results_table()
    kept = rt.kept_section(REPO / "docs" / "results.md")
    assert "## Your own vehicle" in kept and "results-own-vehicle.md" in kept
    rows = [line for line in kept.splitlines() if line.startswith("| ") and " s |" in line]
    assert {"10 s", "30 s"} <= {cell.strip() for row in rows for cell in row.split("|")}
