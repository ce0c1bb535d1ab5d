"""The recording's entity paths: one module builds and parses them, the docs list exactly them."""

from __future__ import annotations

import re
from itertools import product
from pathlib import Path

import pytest

from ionav_viz.viz import entities as ent

from .conftest import run_cli
from .test_replay import read_rrd

# the module's generated fixtures are built once, on one worker (pytest-xdist's --dist loadgroup)
pytestmark = pytest.mark.xdist_group("entities")

DOC = Path(__file__).resolve().parent.parent / "docs" / "recording.md"


def expand(pattern: str) -> list[str]:
    """``errors/{crse_m,cae_m}/<est>`` -> the paths it stands for (braces expanded)."""
    parts = re.split(r"\{([^}]*)\}", pattern)
    choices = [[p] if i % 2 == 0 else p.split(",") for i, p in enumerate(parts)]
    return ["".join(c) for c in product(*choices)]


def documented() -> set[str]:
    """Every path in the first column of docs/recording.md's entity table."""
    paths = set()
    for line in DOC.read_text(encoding="utf-8").splitlines():
        if line.startswith("| `"):
            first = line.split("|")[1]
            for code in re.findall(r"`([^`]+)`", first):
                paths.update(expand(code))
    return paths


def test_the_docs_list_exactly_the_paths_the_module_builds():
    assert documented() == set(ent.PATTERNS), (documented() ^ set(ent.PATTERNS))


def test_expand_reads_the_tables_brace_lists():
    assert expand("errors/{crse_m,cae_m}/<est>") == ["errors/crse_m/<est>", "errors/cae_m/<est>"]
    assert expand("summary") == ["summary"]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """Every entity path of two real recordings: synthetic outages on the roundabout (with a
    plug-in), and the tunnel drive's own GNSS losses."""
    folder = tmp_path_factory.mktemp("rrd")
    paths = set()
    for args in (["roundabout", "--every", "60s"], ["V-sim-motorway-tunnels", "--on", "gnss-outage,cruise"]):
        out = folder / f"{args[0]}.rrd"
        proc = run_cli("replay", *args, "-o", str(out), "-q")
        assert proc.returncode == 0, proc.stderr
        rows, static = read_rrd(out)
        paths |= {p.strip("/") for p in [*rows, *static] if not p.startswith("/__")}
    return paths


def test_every_written_path_is_one_the_module_builds(written):
    assert len(written) > 60
    assert sorted(p for p in written if ent.pattern_of(p) is None) == []
    used = {ent.pattern_of(p) for p in written}
    # drawn only where fixes are bad but usable, where a filter's gate left a fix out, and beside a reference (--truth-topic)
    assert set(ent.PATTERNS) - used <= {ent.truth_bad(ent.MAP), ent.truth_bad(ent.LOCAL), f"{ent.HEALTH}/<est>/gated/<kind>",
                                        ent.receiver(ent.MAP), ent.receiver(ent.LOCAL)}, set(ent.PATTERNS) - used


def test_labels_and_paths_parse_back():
    assert ent.parse_outage_state(ent.outage_state(12, 110.0, 120.0)) == 12
    assert ent.parse_outage_state(ent.real_outage_state(3, 41.2, 52.9)) is None
    assert ent.is_outage_state(ent.real_outage_state(3, 41.2, 52.9)) and not ent.is_outage_state(ent.GNSS_AVAILABLE_STATE)
    assert ent.parse_error_series("/" + ent.error_series("position_error_m", "my-est")) == ("position_error_m", "my-est")
    assert ent.parse_error_series(ent.real_outage_errors("ins")) is None  # a real loss's errors are not an outage series
    assert ent.is_outage_frame("/" + ent.live_track(ent.LOCAL, "idnn")) and not ent.is_outage_frame(ent.all_tracks(ent.LOCAL, "idnn"))
    assert ent.pattern_of(ent.live_track(ent.INSPECT, "const")) == "inspect/<est>"
    assert ent.pattern_of(ent.INSPECT_GRID) == ent.INSPECT_GRID  # a literal path before a pattern it also fits


def test_the_receivers_fixes_beside_a_reference_are_a_known_documented_path():
    """Tour 51: a log read with --truth-topic draws the receiver's own fixes at map/gnss_receiver and
    local/gnss_receiver; neither was in PATTERNS (pattern_of gave None) nor in the docs' table."""
    for view in (ent.MAP, ent.LOCAL):
        assert ent.pattern_of("/" + ent.receiver(view)) == ent.receiver(view)
        assert ent.receiver(view) in documented()
