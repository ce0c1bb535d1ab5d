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


def parse_manifest(text: str, source: str = "manifest") -> tuple[ManifestEntry, ...]:
    """Entries of a manifest TSV (``path``, ``sha256``, ``size_bytes``)."""
    from ..core.errors import InputError

    rows = csv.DictReader(text.splitlines(), delimiter="\t")
    if rows.fieldnames is None or not {"path", "sha256", "size_bytes"} <= set(rows.fieldnames):
        raise InputError(f"{source}: not a manifest (expected the columns path, sha256, size_bytes)")
    out = []
    for line, r in enumerate(rows, start=2):
        try:
            size = int(r["size_bytes"])
        except (TypeError, ValueError):
            raise InputError(f"{source}: line {line}: size_bytes {r['size_bytes']!r} is not a whole number") from None
        if not re.fullmatch(r"[0-9a-f]{64}", (r["sha256"] or "").lower()):
            raise InputError(f"{source}: line {line}: sha256 {r['sha256']!r} is not 64 hex digits")
        out.append(ManifestEntry(r["path"], r["sha256"].lower(), size))
    return tuple(out)


@lru_cache(maxsize=1)
def manifest() -> tuple[ManifestEntry, ...]:
    """All entries of the packaged LFS manifest."""
    text = resources.files("ionav_viz").joinpath("data/iovnbd-manifest.tsv").read_text(encoding="utf-8")
    return parse_manifest(text, "packaged manifest")


@dataclass(frozen=True)
class RunFiles:
    """A run of the dataset and its files: vehicle (``V-``) and phone (``S-``), both trees."""

    key: str
    name: str
    group: str
    driver: str
    vehicle: ManifestEntry | None  # unsynchronised (complete) copy
    vehicle_sync: ManifestEntry | None
    phone: ManifestEntry | None
    phone_sync: ManifestEntry | None


def _tree_rank(path: str) -> tuple[int, int]:
    low = path.lower()
    return (0 if low.startswith("unsynchronised") else 1, 0 if "/categorised" in low else 1)


def runs(entries: tuple[ManifestEntry, ...] | None = None) -> dict[str, RunFiles]:
    """Every run with a vehicle file in the manifest, by :func:`run_key`, in name order."""
    entries = manifest() if entries is None else entries
    found: dict[str, dict[str, list[ManifestEntry]]] = {}
    for entry in entries:
        base = entry.path.rsplit("/", 1)[-1]
        low = base.lower()
        if not low.endswith(".csv") or low[:2] not in ("v-", "s-"):
            continue
        kind = "V" if low.startswith("v-") else "S"
        sync = "sync" if not entry.path.lower().startswith("unsynchronised") else "unsync"
        found.setdefault(run_key(base[2:]), {}).setdefault(kind + sync, []).append(entry)
    out = {}
    for key, files in found.items():
        def best(k: str, files: dict = files) -> ManifestEntry | None:
            return min(files.get(k, []), key=lambda e: _tree_rank(e.path), default=None)

        vehicle, vehicle_sync = best("Vunsync"), best("Vsync")
        main = vehicle or vehicle_sync
        if main is None:
            continue
        group, driver = "", ""
        for part in main.path.split("/"):
            m = re.fullmatch(r"(\w+) \(Driver (\w+)\)", part)
            if m:
                group, driver = m.groups()
        name = "V-" + main.path.rsplit("/", 1)[-1][2:-4]
        out[key] = RunFiles(key, name, group, driver, vehicle, vehicle_sync, best("Sunsync"), best("Ssync"))
    return dict(sorted(out.items(), key=lambda kv: kv[1].name.lower()))


@lru_cache(maxsize=1)
def vehicle_runs() -> dict[str, list[ManifestEntry]]:
    """Vehicle ``V-*.csv`` files of the manifest, by :func:`run_key`."""
    runs: dict[str, list[ManifestEntry]] = {}
    for entry in manifest():
        name = entry.path.rsplit("/", 1)[-1]
        if name.lower().startswith("v-") and name.lower().endswith(".csv"):
            runs.setdefault(run_key(name), []).append(entry)
    return runs
