"""The IO-VNBD runs: which there are and which are here (``ionav-viz list``), and verified downloads
into the data root (``ionav-viz fetch``)."""

from __future__ import annotations

import contextlib
import difflib
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.fileio import check_regular_input
from ..dataset.catalog import PAPER_TEST_RUNS, PAPER_TRAIN_RUNS, manifest, paper_role, parse_manifest, run_key, runs
from ..dataset.fetch import (
    VERIFIED_CACHE,
    VerifiedCache,
    base_url,
    configured_data_root,
    default_data_root,
    fetch_file,
    safe_target,
)


@dataclass(frozen=True)
class RunSelection:
    """Which runs to fetch: by name, a scenario's test runs (``"all"``: every scenario's), the
    paper's test or training runs; each run's vehicle file (complete, or ``synchronised``), and with
    ``phone`` its phone's ``S-`` file too."""

    names: Sequence[str] = ()
    scenario: str | None = None
    paper_test: bool = False
    paper_train: bool = False
    synchronised: bool = False
    phone: bool = False


@dataclass(frozen=True)
class DatasetSource:
    """Where runs come from: the repository root (default ``$IONAV_BASE_URL``, else the dataset's
    Git LFS media URL), how long a stalled connection may wait, and the manifest (path, sha256,
    size of every file; default the packaged one)."""

    base_url: str | None = None
    timeout_s: float = 30.0
    manifest: str | Path | None = None

    def catalog(self) -> dict[str, Any]:
        """The runs of the manifest, by key."""
        if self.manifest is None:
            return runs(manifest())
        check_regular_input(self.manifest, "manifest", hint="give a manifest TSV (path, sha256, size_bytes)",
                            missing_ok=True)
        try:
            return runs(parse_manifest(Path(self.manifest).read_text(encoding="utf-8"), str(self.manifest)))
        except OSError as exc:
            raise InputError(f"{self.manifest}: cannot read the manifest ({exc.strerror})", param="manifest") from None


def fetch_root(data_root: str | Path | None = None) -> Path:
    """Where fetch writes and list looks: ``data_root``, ``$IONAV_DATA``, else the per-user data directory.
    One that exists must be a folder (``--data-root FILE`` listed every run as missing, exit 0, and
    fetch said "cannot create it (File exists)")."""
    root = configured_data_root(data_root) or default_data_root()
    if root.exists() and not root.is_dir():
        raise InputError(f"data root {root}: is not a folder",
                         "give the folder that holds (or will hold) the IO-VNBD runs as --data-root", param="data_root")
    return root


def list_runs(data_root: str | Path | None = None, source: DatasetSource | None = None,
              verify: bool = False) -> list[dict[str, Any]]:
    """Every IO-VNBD run: name, group, driver, role in the paper, size, path and local status
    (``verify``: check the sha256 of present files not verified before)."""
    from ..sources.resolve import index_data_root

    root = fetch_root(data_root)
    cache = VerifiedCache(root)
    elsewhere: dict[str, list[Path]] | None = None
    rows = []
    for run in (source or DatasetSource()).catalog().values():
        entry = run.vehicle or run.vehicle_sync
        status, local = "missing", None
        if root.is_dir():
            target = safe_target(root, entry.path)
            if target.is_file():
                status, local = cache.status(entry, target, check=verify), target
            else:
                # a run's V-*.csv anywhere under the root, by name: what 'evaluate NAME' reads (a copy laid out
                # otherwise)
                if elsewhere is None:
                    # the files as they are now, not as an earlier call of this process saw them
                    index_data_root.cache_clear()
                    elsewhere = index_data_root(root.resolve())
                found = [p for p in elsewhere.get(run.key, []) if p.is_file()]
                if not found:
                    rows.append(_run_row(run, entry, "missing", None))
                    continue
                local = found[0]
                statuses = [cache.status(e, local, check=verify) for e in (run.vehicle, run.vehicle_sync)
                            if e is not None]
                status = next((st for st in ("verified", "present") if st in statuses), "mismatch")
        rows.append(_run_row(run, entry, status, local))
    return rows


def bundled_drives() -> list[dict[str, Any]]:
    """The drives bundled with the package, test drives first: ``name`` (what to give wherever a
    drive is expected), ``file``, ``role`` (test, losses, bias or train), ``what`` (a few words) and
    ``stands_in_for`` (the IO-VNBD runs of the paper it replaces when they are not here)."""
    from ..dataset.samples import SAMPLES, address, stand_in, what_it_is

    catalog = runs(manifest())
    order = {"test": 0, "losses": 1, "bias": 2, "train": 3}
    return [{"name": address(s), "file": s.file, "role": s.role, "what": what_it_is(s),
             "stands_in_for": [r.name for r in catalog.values() if stand_in(r.name) == s]}
            for s in sorted(SAMPLES, key=lambda s: order.get(s.role, len(order)))]


def _run_row(run: Any, entry: Any, status: str, local: Path | None) -> dict[str, Any]:
    return {"name": run.name, "group": run.group, "driver": run.driver, "role": paper_role(run.name) or "",
            "size_bytes": entry.size_bytes, "path": entry.path, "status": status,
            **({"local_path": str(local)} if local is not None else {})}


def runs_selected(selections: Sequence[str], source: DatasetSource | None = None) -> list[tuple[str, int]]:
    """The IO-VNBD runs each of ``selections`` names (``evaluate --runs``), each once, in name
    order, with its vehicle file's size in bytes (the file ``list`` shows): ``all``; a group of
    the dataset's categorised tree (``Vta``, ``Vw``...: the folder ``<Group> (Driver X)``), or a
    driver (``E``, ``driver E``), case-insensitive; a selection may list several, comma-separated.
    An unknown one is an :class:`InputError` listing the groups and drivers."""
    catalog = (source or DatasetSource()).catalog()
    groups = sorted({r.group for r in catalog.values() if r.group}, key=str.lower)
    drivers = sorted({r.driver for r in catalog.values() if r.driver})
    chosen: dict[str, tuple[str, int]] = {}
    for selection in selections:
        for word in (w.strip() for w in str(selection).split(",")):
            if not word:
                continue
            low = word.lower()
            driver = low.removeprefix("driver").strip() if low.startswith("driver") else None
            if low == "all":
                hits = list(catalog.values())
            elif driver is None and low in {g.lower() for g in groups}:
                hits = [r for r in catalog.values() if r.group.lower() == low]
            elif (driver or low) in {d.lower() for d in drivers}:
                hits = [r for r in catalog.values() if r.driver.lower() == (driver or low)]
            else:
                raise InputError(f"--runs {word}: no such IO-VNBD group or driver",
                                 f"give all, a group ({', '.join(groups)}) or a driver ({', '.join(drivers)}); see "
                                 "'ionav-viz list'",
                                 param="runs")
            for run in hits:
                entry = run.vehicle or run.vehicle_sync
                chosen.setdefault(run.key, (run.name, entry.size_bytes))
    return sorted(chosen.values(), key=lambda r: r[0].lower())


def selected_files(selection: RunSelection, source: DatasetSource | None = None) -> list[Any]:
    """The manifest entries a selection names (checked: known runs, files the manifest has)."""
    catalog = (source or DatasetSource()).catalog()
    wanted = list(selection.names)
    if selection.scenario is not None:
        if selection.scenario != "all" and selection.scenario not in PAPER_TEST_RUNS:
            raise InputError(f"unknown scenario {selection.scenario!r}", f"choose {', '.join(PAPER_TEST_RUNS)} or all",
                             param="scenario")
        wanted += [r for s, rs in PAPER_TEST_RUNS.items() if selection.scenario in ("all", s) for r in rs]
    if selection.paper_test:
        wanted += [r for rs in PAPER_TEST_RUNS.values() for r in rs]
    if selection.paper_train:
        wanted += list(PAPER_TRAIN_RUNS)
    if not wanted:
        raise InputError("no run to fetch",
                         "name runs, or choose a scenario, the paper's test runs or its training runs", param="names")
    entries = []
    for name in dict.fromkeys(wanted):
        run = catalog.get(run_key(name))
        if run is None:
            close = difflib.get_close_matches(name, [r.name for r in catalog.values()], n=3)
            raise InputError(f"unknown IO-VNBD run {name!r}",
                             f"did you mean {', '.join(close)}?" if close else "see 'ionav-viz list'")
        files = [run.vehicle_sync if selection.synchronised else run.vehicle or run.vehicle_sync]
        if selection.phone:
            files.append((run.phone_sync if selection.synchronised else run.phone) or run.phone_sync or run.phone)
        for entry in files:
            if entry is None:
                raise InputError(f"{run.name}: the manifest has no {'synchronised ' if selection.synchronised else ''}"
                                 f"{'phone ' if selection.phone else ''}file for it")
            entries.append(entry)
    return entries


def fetch(selection: RunSelection, data_root: str | Path | None = None, source: DatasetSource | None = None, *,
          progress: Callable[[str, int, int], None] | None = None, report: Callable[[Any], None] | None = None) -> Path:
    """Download the selected runs into the data root, resuming and verifying size and sha256;
    returns the data root. ``progress(file name, bytes done, bytes in all)``; ``report(result)``
    after each file (its ``action``: downloaded, resumed, skipped; its ``path``). A failed first
    download leaves no empty data root behind."""
    source = source or DatasetSource()
    entries = selected_files(selection, source)
    root = fetch_root(data_root)
    url = base_url(source.base_url)
    created = [p for p in [root, *root.parents] if not p.exists()]
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"data root {root}: cannot create it ({exc.strerror})", "choose a writable data root",
                         param="data_root") from None
    if not os.access(root, os.W_OK | os.X_OK):
        raise InputError(f"data root {root}: cannot write in it (permission denied)", "choose a writable data root",
                         param="data_root")
    cache = VerifiedCache(root)
    total = sum(e.size_bytes for e in entries)
    try:
        finished = 0
        for entry in entries:
            def advance(e, done: int, before: int = finished) -> None:
                if progress:
                    progress(e.path.rsplit("/", 1)[-1], before + done, total)

            result = fetch_file(entry, root, url, timeout_s=source.timeout_s, cache=cache, progress=advance)
            finished += entry.size_bytes
            if report:
                report(result)
    except BaseException:
        _remove_if_empty(created)
        raise
    return root


def _remove_if_empty(created: list[Path]) -> None:
    """Remove the folders this run created (innermost first) if nothing but empty folders is in them."""

    for folder in created:
        if not folder.is_dir():
            continue
        for path in sorted(folder.rglob("*"), key=lambda p: len(p.parts), reverse=True):
            if path.is_dir():
                with contextlib.suppress(OSError):
                    path.rmdir()
        cache = folder / VERIFIED_CACHE
        if cache.is_file() and [p.name for p in folder.iterdir()] == [VERIFIED_CACHE]:
            cache.unlink()
        try:
            folder.rmdir()
        except OSError:
            return  # something was downloaded: keep it
