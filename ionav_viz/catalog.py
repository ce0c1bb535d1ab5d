"""What the paper uses from IO-VNBD, and the dataset's LFS manifest (path, sha256, size).

Run names are compared by :func:`run_key`: case-insensitive, without the ``V-`` prefix or the
``.csv`` suffix, and without zero padding (folder ``Vta01a`` holds ``V-Vta1a.csv``).
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

SCENARIOS = ("motorway", "roundabout", "quick-accel", "hard-brake", "sharp-cornering")

#: Training runs of the paper's Table 1.
PAPER_TRAIN_RUNS = (
    "V-Vta1a", "V-Vta2", "V-Vta8", "V-Vta10", "V-Vta16", "V-Vta17", "V-Vta20", "V-Vta21",
    "V-Vta22", "V-Vta27", "V-Vta28", "V-Vta29", "V-Vta30", "V-Vtb1", "V-Vtb2", "V-Vtb3",
    "V-Vtb5", "V-Vw4", "V-Vw5", "V-Vw14b", "V-Vw14c", "V-Vfa01", "V-Vfa02", "V-Vfb01a",
    "V-Vfb01b", "V-Vfb02b",
)  # fmt: skip

#: Test runs of the paper's Tables 6 and 7, per scenario.
PAPER_TEST_RUNS = {
    "motorway": ("V-Vw12",),
    "roundabout": ("V-Vta11", "V-Vfb02d"),
    "quick-accel": ("V-Vfb02e", "V-Vta12"),
    "hard-brake": ("V-Vw16b", "V-Vw17", "V-Vta9"),
    "sharp-cornering": ("V-Vw6", "V-Vw7", "V-Vw8"),
}

#: The long stationary recording the authors' scripts use for sensor biases.
BIAS_RUN = "V-Vw1"

DATASET_URL = "https://github.com/onyekpeu/IO-VNBD"


def run_key(name: str) -> str:
    """``'V-Vta01a'``, ``'vta1a'``, ``'v-vta1a.csv'`` -> ``'vta1a'``."""
    key = name.strip().lower()
    if key.endswith(".csv"):
        key = key[:-4]
    if key.startswith("v-"):
        key = key[2:]
    return re.sub(r"(?<=[a-z])0+(?=\d)", "", key)


def paper_role(name: str) -> str | None:
    """What the paper uses a run for, e.g. "the paper's sharp-cornering test run (Table 7)"."""
    key = run_key(name)
    for scenario, runs in PAPER_TEST_RUNS.items():
        if key in {run_key(r) for r in runs}:
            table = 6 if scenario == "motorway" else 7
            return f"the paper's {scenario} test run (Table {table})"
    if key in {run_key(r) for r in PAPER_TRAIN_RUNS}:
        return "one of the paper's training runs (Table 1)"
    if key == run_key(BIAS_RUN):
        return "the stationary recording used for sensor biases"
    return None


@dataclass(frozen=True)
class ManifestEntry:
    """One LFS object of the dataset repository."""

    path: str
    sha256: str
    size_bytes: int


@lru_cache(maxsize=1)
def manifest() -> tuple[ManifestEntry, ...]:
    """All entries of the packaged LFS manifest."""
    text = resources.files("ionav_viz").joinpath("data/iovnbd-manifest.tsv").read_text(encoding="utf-8")
    rows = csv.DictReader(text.splitlines(), delimiter="\t")
    return tuple(ManifestEntry(r["path"], r["sha256"], int(r["size_bytes"])) for r in rows)


@lru_cache(maxsize=1)
def vehicle_runs() -> dict[str, list[ManifestEntry]]:
    """Vehicle ``V-*.csv`` files of the manifest, by :func:`run_key`."""
    runs: dict[str, list[ManifestEntry]] = {}
    for entry in manifest():
        name = entry.path.rsplit("/", 1)[-1]
        if name.lower().startswith("v-") and name.lower().endswith(".csv"):
            runs.setdefault(run_key(name), []).append(entry)
    return runs
