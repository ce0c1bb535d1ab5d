"""``ionav-viz list`` and ``fetch``: the IO-VNBD runs, and verified downloads into the data root."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from . import common as c
from .app import app


@app.command("list")
def list_runs(
    as_json: bool = typer.Option(False, "--json", help="Print JSON for scripts."),
    verify: bool = typer.Option(False, "--verify", help="Check the sha256 of present files not verified before (slow for big files)."),
    data_root_opt: Optional[Path] = typer.Option(None, "--data-root", help="Data root (default: $IONAV_DATA, else the per-user data directory).", show_default=False),
    manifest_opt: Optional[Path] = c.ManifestOpt,
) -> None:
    """List the IO-VNBD runs: group, driver, role in the paper, size, and whether present locally."""
    from ..api.datasets import DatasetSource, fetch_root, list_runs
    from ..core.json_out import dumps_json

    root = fetch_root(data_root_opt)
    rows = list_runs(root, DatasetSource(manifest=manifest_opt), verify)
    if as_json:
        print(dumps_json({"data_root": root, "runs": rows}))
        return
    width = max(len(r["name"]) for r in rows) if rows else 4
    print(f"data root: {root}")
    print(f"{'run'.ljust(width)}  group  driver  {'size':>9}  {'local':<8}  role in the paper")
    for r in rows:
        print(f"{r['name'].ljust(width)}  {r['group']:<5}  {r['driver']:<6}  {r['size_bytes'] / 1e6:>7.2f}MB  {r['status']:<8}  {r['role']}")
    shown = {r["status"] for r in rows}
    said = [text for status, text in _STATUS_TEXT if status in shown]
    if said:
        print("\nlocal: " + "; ".join(said))


#: What each local status of ``list`` means, in the order said under the table.
_STATUS_TEXT = (("verified", "verified = size and sha256 match the dataset's manifest"),
                ("present", "present = the size matches, the sha256 not checked yet (--verify)"),
                ("mismatch", "mismatch = the size or sha256 differs from the manifest's: an edited copy, another version or a damaged "
                             "download ('ionav-viz fetch NAME' gets the published one)"),
                ("missing", "missing = no V-*.csv of the run under the data root ('ionav-viz fetch NAME')"))


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
    from ..api.datasets import DatasetSource, RunSelection, fetch
    from .app import options_named

    selection = RunSelection(tuple(names or ()), scenario, paper_test, paper_train, synchronised, phone)
    source = DatasetSource(base_url_opt, c.duration_s(timeout, "--timeout"), manifest_opt)
    with c.progress(quiet) as bar, options_named(names="NAMES", scenario="--scenario"):
        task = [] if bar is None else [bar.add_task("fetching", total=None)]

        def progress(name: str, done: int, total: int) -> None:
            if task:
                bar.update(task[0], completed=done, total=total, description=name)

        root = fetch(selection, data_root_opt, source, progress=progress,
                     report=lambda result: print(f"{result.action:>10}  {result.path}", file=sys.stderr))
    print(root)
