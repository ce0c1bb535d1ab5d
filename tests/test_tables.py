"""Text tables fit the terminal (COLUMNS) without losing a number; JSON and Markdown never change."""

from __future__ import annotations

import re

import pytest

from ionav_viz.analysis.document import aligned

from .conftest import run_cli

# the module's generated fixtures are built once, on one worker (pytest-xdist's --dist loadgroup)
pytestmark = pytest.mark.xdist_group("tables")

NUMBER = re.compile(r"-?\d+(?:\.\d+)?")


def numbers(text: str) -> list[str]:
    return sorted(NUMBER.findall(text))


def widest(text: str) -> int:
    return max(len(line) for line in text.splitlines())


@pytest.fixture(scope="module")
def full_tables():
    """The tables at a width they all fit (COLUMNS=1000): one line per row."""
    evaluate = run_cli("evaluate", "roundabout", "--every", "60s", "-q", env={"COLUMNS": "1000"})
    overview = run_cli("evaluate", "--scenario", "all", "--overview", "-q", env={"COLUMNS": "1000"})
    assert evaluate.returncode == 0 and overview.returncode == 0, evaluate.stderr + overview.stderr
    assert widest(overview.stdout) > 300 and widest(evaluate.stdout) > 150  # otherwise nothing below is tested
    return evaluate.stdout, overview.stdout


@pytest.mark.parametrize("columns", [100, 120])
def test_evaluate_fits_the_width_and_keeps_every_number(full_tables, columns):
    proc = run_cli("evaluate", "roundabout", "--every", "60s", "-q", env={"COLUMNS": str(columns)})
    assert proc.returncode == 0, proc.stderr
    assert widest(proc.stdout) <= columns
    assert numbers(proc.stdout) == numbers(full_tables[0])


def test_overview_is_readable_at_120_columns(full_tables):
    """Transposed: one column per scenario and the total, one row per metric and estimator."""
    proc = run_cli("evaluate", "--scenario", "all", "--overview", "-q", env={"COLUMNS": "120"})
    assert proc.returncode == 0, proc.stderr
    assert widest(proc.stdout) <= 120
    header = proc.stdout.splitlines()[0].split()
    assert header == ["Metric", "Estimator", "motorway", "roundabout", "quick-accel", "hard-brake", "sharp-cornering", "total"]
    assert numbers(proc.stdout) == numbers(full_tables[1])
    ins = next(line for line in proc.stdout.splitlines() if line.startswith("Disp. CRSE"))
    full_total = next(line for line in full_tables[1].splitlines() if line.startswith("total"))
    assert ins.split()[-1] == full_total.split()[2]  # the total's INS DR mean CRSE, the first value of the total row


@pytest.mark.parametrize("args", [["evaluate", "roundabout", "--every", "60s", "--json"],
                                  ["evaluate", "roundabout", "--every", "60s", "--markdown"],
                                  ["evaluate", "--scenario", "motorway", "--overview", "--markdown", "-q"]])
def test_json_and_markdown_ignore_the_width(args):
    wide, narrow = run_cli(*args), run_cli(*args, env={"COLUMNS": "60"})
    assert wide.returncode == 0 and wide.stdout == narrow.stdout, narrow.stderr


def test_aligned_wraps_headers_then_splits_columns_into_blocks():
    header = ["Key", "a long header one", "another long header", "third"]
    rows = [["alpha", "1.00", "2.00", "3.00"], ["beta", "4.00", "", "6.00"]]
    full = aligned(header, rows, 1)
    assert full[0] == "Key    a long header one  another long header  third" and len(full) == 4  # 52 wide: no limit
    wrapped = aligned(header, rows, 1, width=40)
    assert max(map(len, wrapped)) <= 40 and wrapped[-2].startswith("alpha") and "-----" in wrapped[-3]
    assert sorted(" ".join(wrapped[:-3]).split()) == sorted(" ".join(header).split())  # every header word kept
    # width 22: key column 5 + 2 leaves 15 for values; wrapped headers make the value columns
    # 6 ("a long/header/one"), 7 ("another/long/header") and 5 wide: 6 + 2 + 7 = 15, so two blocks.
    blocks = aligned(header, rows, 1, width=22)
    assert max(map(len, blocks)) <= 22 and blocks.count("") == 1
    assert blocks[blocks.index("") + 1].split() == ["Key", "third"]
    assert sum(line.startswith("alpha") for line in blocks) == 2 and sum(line.startswith("beta") for line in blocks) == 2
    assert [line.split() for line in blocks if line.startswith("beta")] == [["beta", "4.00"], ["beta", "6.00"]]
    alone = aligned(["Key", "x", "y"], [["a", "1.00", "2.00"], ["b", "3.00", ""]], 1, width=9)  # one value column per block
    assert [line.split() for line in alone if line.startswith("b")] == [["b", "3.00"]]  # row b has no y: left out of its block
    assert numbers("\n".join(blocks)) == numbers("\n".join(full))


def test_markdown_says_every_line_the_text_report_says():
    """--markdown dropped the placement, the uncertainty and the filter-health lines; every prose
    line of the text report is now a paragraph of the Markdown."""
    args = ["evaluate", "roundabout", "--every", "60s", "--estimators", "ins,ekf"]
    text, md = run_cli(*args, env={"COLUMNS": "1000"}).stdout, run_cli(*args, "--markdown").stdout  # prose lines unfolded
    prose = [ln for ln in text.splitlines() if ln.startswith(("Outages:", "GNSS-aided INS uncertainty:", "GNSS-aided INS health:", "GNSS truth:"))]
    assert len(prose) == 4
    paragraphs = md.split("\n\n")
    for line in prose:
        assert line in paragraphs, line


@pytest.mark.parametrize("form", ["text", "markdown"])
def test_an_undefined_value_is_a_dash_not_nan(form):
    """On the stationary drive (under 10 m driven per outage, so the final error as a % of the
    distance is undefined, null in the JSON) the tables printed 'nan' in four rows; they print '-'
    as the fleet's tables do."""
    proc = run_cli("evaluate", "stationary", "--estimators", "ins", *(["--markdown"] if form == "markdown" else []), env={"COLUMNS": "200"})
    assert proc.returncode == 0, proc.stderr
    assert "nan" not in proc.stdout.lower(), proc.stdout
    row = next(line for line in proc.stdout.splitlines() if "Final error, % of distance" in line)
    assert row.replace("|", " ").split()[-1] == "-", row


def test_a_value_that_rounds_to_zero_has_no_sign():
    """The stationary drive's mean orientation-rate CAE printed '-0.000' (a mean of -0.0001 rad/s)."""
    proc = run_cli("evaluate", "stationary", "--estimators", "ins", env={"COLUMNS": "200"})
    assert proc.returncode == 0, proc.stderr
    assert not re.search(r"(?<![\d.])-0\.0+(?![\d])", proc.stdout), proc.stdout
    assert re.search(r"^ +μ +\d+\.\d\d +0\.000$", proc.stdout, re.M), proc.stdout  # the CAE's mean, as it is printed now


def test_an_improvement_that_rounds_to_zero_has_no_sign():
    """An improvement of -0.04 % printed '-0.0 %' beside its interval's '0.0' (a review found it)."""
    from ionav_viz.analysis.rows import Improvement
    from ionav_viz.analysis.tables import improvement_lines

    [line] = improvement_lines({"ins": "INS DR", "odo": "Odometry"}, {"odo": Improvement(-0.04, 0.0, -0.04)},
                               {"odo": Improvement([-0.1, 0.1], [0.0, 0.0], [-0.04, 0.03])})
    assert "-0.0" not in line and "displacement CRSE 0.0 %" in line and "final position error 0.0 % (95 % interval 0.0 to 0.0 %)" in line, line


def test_piped_text_fits_a_default_width_unless_columns_says_otherwise():
    # issue 63: piped without COLUMNS, tables and prose ran to their full width (430 characters for an overview)
    from ionav_viz.cli.common import PIPED_WIDTH

    args = ("evaluate", "hard-brake", "--estimators", "ins,odo,ekf", "--every", "60s", "-q")
    piped = run_cli(*args)
    assert piped.returncode == 0, piped.stderr
    assert PIPED_WIDTH == 120 and max(map(len, piped.stdout.splitlines())) <= PIPED_WIDTH
    wide = run_cli(*args, env={"COLUMNS": "400"})
    assert max(map(len, wide.stdout.splitlines())) > PIPED_WIDTH  # COLUMNS still says how wide
    assert "GNSS-aided INS improvement over INS DR (mean)" in wide.stdout
    narrow = run_cli(*args, env={"COLUMNS": "80"})
    assert max(map(len, narrow.stdout.splitlines())) <= 80
