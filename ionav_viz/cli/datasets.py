"""``ionav-viz list`` and ``fetch``: the IO-VNBD runs, and verified downloads into the data root."""

from __future__ import annotations

import contextlib
import json
import os
import sys
from pathlib import Path
from typing import Optional

import typer

from ..core.errors import InputError
from . import common as c
from .app import app


def _fetch_root(option: Optional[Path]) -> Path:
    """Where fetch writes and list looks: --data-root, $IONAV_DATA, else the per-user data directory."""
    from ..dataset.fetch import configured_data_root, default_data_root

    return configured_data_root(option) or default_data_root()


def _manifest(option: Optional[Path]):
    from ..dataset.catalog import manifest, parse_manifest

    if option is None:
        return manifest()
    try:
        return parse_manifest(option.read_text(encoding="utf-8"), str(option))
    except OSError as exc:
        raise InputError(f"{option}: cannot read the manifest ({exc.strerror})") from None




@app.command("list")
def list_runs(
    as_json: bool = typer.Option(False, "--json", help="Print JSON for scripts."),
    verify: bool = typer.Option(False, "--verify", help="Check the sha256 of present files not verified before (slow for big files)."),
    data_root_opt: Optional[Path] = typer.Option(None, "--data-root", help="Data root (default: $IONAV_DATA, else the per-user data directory).", show_default=False),
    manifest_opt: Optional[Path] = c.ManifestOpt,
) -> None:
    """List the IO-VNBD runs: group, driver, role in the paper, size, and whether present locally."""
    from ..dataset.catalog import paper_role, runs
    from ..dataset.fetch import VerifiedCache, safe_target

    root = _fetch_root(data_root_opt)
    cache = VerifiedCache(root)
    rows = []
    for run in runs(_manifest(manifest_opt)).values():
        entry = run.vehicle or run.vehicle_sync
        status = cache.status(entry, safe_target(root, entry.path), check=verify) if root.is_dir() else "missing"
        rows.append({
            "name": run.name, "group": run.group, "driver": run.driver, "role": paper_role(run.name) or "",
            "size_bytes": entry.size_bytes, "path": entry.path, "status": status,
        })
    if as_json:
        print(json.dumps({"data_root": str(root), "runs": rows}, indent=2))
        return
    width = max(len(r["name"]) for r in rows) if rows else 4
    print(f"data root: {root}")
    print(f"{'run'.ljust(width)}  group  driver  {'size':>9}  {'local':<8}  role in the paper")
    for r in rows:
        print(f"{r['name'].ljust(width)}  {r['group']:<5}  {r['driver']:<6}  {r['size_bytes'] / 1e6:>7.2f}MB  {r['status']:<8}  {r['role']}")


@app.command()
def fetch(
    names: Optional[list[str]] = typer.Argument(None, help="Run names, e.g. V-Vw8 Vta11."),
    scenario: Optional[str] = typer.Option(None, "--scenario", help="The paper's test runs of a scenario, or all."),
    paper_test: bool = typer.Option(False, "--paper-test", help="All the paper's test runs (Tables 6-7)."),
    paper_train: bool = typer.Option(False, "--paper-train", help="All the paper's training runs (Table 1)."),
    synchronised: bool = typer.Option(False, "--synchronised", help="The synchronised copy instead of the complete (unsynchronised) run."),
    phone: bool = typer.Option(False, "--phone", help="Also the phone's S- file of each run."),
    data_root_opt: Optional[Path] = typer.Option(None, "--data-root", help="Where to put the files (default: $IONAV_DATA, else the per-user data directory).", show_default=False),
    base_url_opt: Optional[str] = typer.Option(None, "--base-url", help="Repository root URL to download from (default: $IONAV_BASE_URL, else the dataset's Git LFS media URL)."),
    timeout: str = typer.Option("30s", "--timeout", help="Give up on a connection that stalls this long."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar."),
    manifest_opt: Optional[Path] = c.ManifestOpt,
) -> None:
    """Download IO-VNBD runs by name into the data root, resuming and verifying size and sha256."""
    from ..dataset.catalog import PAPER_TEST_RUNS, PAPER_TRAIN_RUNS, run_key, runs
    from ..dataset.fetch import base_url

    catalog = runs(_manifest(manifest_opt))
    wanted = list(names or [])
    if scenario is not None:
        if scenario != "all" and scenario not in PAPER_TEST_RUNS:
            raise typer.BadParameter(f"unknown scenario {scenario!r}; choose {', '.join(PAPER_TEST_RUNS)} or all", param_hint="--scenario")
        wanted += [r for s, rs in PAPER_TEST_RUNS.items() if scenario in ("all", s) for r in rs]
    if paper_test:
        wanted += [r for rs in PAPER_TEST_RUNS.values() for r in rs]
    if paper_train:
        wanted += list(PAPER_TRAIN_RUNS)
    if not wanted:
        raise typer.BadParameter("name runs to fetch, or use --scenario, --paper-test or --paper-train", param_hint="NAMES")
    entries = []
    for name in dict.fromkeys(wanted):
        run = catalog.get(run_key(name))
        if run is None:
            import difflib

            close = difflib.get_close_matches(name, [r.name for r in catalog.values()], n=3)
            raise InputError(f"unknown IO-VNBD run {name!r}", f"did you mean {', '.join(close)}?" if close else "see 'ionav-viz list'")
        files = [run.vehicle_sync if synchronised else run.vehicle or run.vehicle_sync]
        if phone:
            files.append((run.phone_sync if synchronised else run.phone) or run.phone_sync or run.phone)
        for entry in files:
            if entry is None:
                raise InputError(f"{run.name}: the manifest has no {'synchronised ' if synchronised else ''}{'phone ' if phone else ''}file for it")
            entries.append(entry)
    root = _fetch_root(data_root_opt)
    url = base_url(base_url_opt)
    timeout_s = c.duration_s(timeout, "--timeout")
    created = [p for p in [root, *root.parents] if not p.exists()]
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"data root {root}: cannot create it ({exc.strerror})", "choose a writable --data-root") from None
    if not os.access(root, os.W_OK | os.X_OK):
        raise InputError(f"data root {root}: cannot write in it (permission denied)", "choose a writable --data-root")
    try:
        _fetch_all(entries, root, url, timeout_s, quiet)
    except BaseException:
        _remove_if_empty(created)  # a failed first download leaves no empty data root behind
        raise
    print(root)


def _remove_if_empty(created: list[Path]) -> None:
    """Remove the folders this run created (innermost first) if nothing but empty folders is in them."""
    from ..dataset.fetch import VERIFIED_CACHE

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


def _fetch_all(entries, root: Path, url: str, timeout_s: float, quiet: bool) -> None:
    from ..dataset.fetch import VerifiedCache, fetch_file

    cache = VerifiedCache(root)
    with c.progress(quiet) as bar:
        task = bar.add_task("fetching", total=sum(e.size_bytes for e in entries)) if bar else None
        finished = 0
        for entry in entries:
            def progress(e, done: int, before: int = finished) -> None:
                if bar is not None:
                    bar.update(task, completed=before + done, description=e.path.rsplit("/", 1)[-1])

            result = fetch_file(entry, root, url, timeout_s=timeout_s, cache=cache, progress=progress)
            finished += entry.size_bytes
            print(f"{result.action:>10}  {result.path}", file=sys.stderr)
