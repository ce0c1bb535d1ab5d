"""The corpus of public real logs in tests/data/real stays small and redistributable: every log is
at most 2 MB, all together at most 8 MB, and each is listed in the folder's README with a licence
that allows redistribution and its licence text beside it."""

from __future__ import annotations

import re
from pathlib import Path

CORPUS = Path(__file__).parent / "data" / "real"
MAX_FILE_BYTES = 2_000_000
MAX_TOTAL_BYTES = 8_000_000
#: Licences under which a log may enter the repository (SPDX identifiers, as the README writes them).
REDISTRIBUTABLE = {"MIT", "BSD-2-Clause", "BSD-3-Clause", "Apache-2.0", "CC-BY-4.0", "CC0-1.0"}


def corpus_logs() -> list[Path]:
    return sorted(CORPUS.glob("*.mcap"))


def readme_rows() -> dict[str, list[str]]:
    """The first README table row that names each corpus file (the table of the logs), by file
    name: its cells."""
    rows = {}
    for line in (CORPUS / "README.md").read_text(encoding="utf-8").splitlines():
        if not line.startswith("|"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        for name in re.findall(r"`([^`]+\.mcap)`", line):
            rows.setdefault(name, cells)
    return rows


def test_corpus_is_small():
    logs = corpus_logs()
    assert len(logs) >= 3
    sizes = {p.name: p.stat().st_size for p in logs}
    assert {name: size for name, size in sizes.items() if size > MAX_FILE_BYTES} == {}
    assert sum(sizes.values()) <= MAX_TOTAL_BYTES


def test_every_log_is_listed_with_a_redistributable_licence():
    rows = readme_rows()
    for log in corpus_logs():
        assert log.name in rows, f"{log.name} is not in tests/data/real/README.md's table"
        licences = REDISTRIBUTABLE.intersection(rows[log.name])
        assert licences, f"{log.name}: no redistributable licence in its README row {rows[log.name]}"
        text = CORPUS / f"LICENSE-{log.stem}"
        assert text.is_file() and text.stat().st_size > 200, f"{log.name}: no licence text {text.name}"
        assert re.search(r"[0-9a-f]{40}", " ".join(rows[log.name])), f"{log.name}: no source commit in its row"
