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
    verify: bool = typer.Option(False, "--verify",
                                help="Check the sha256 of present files not verified before (slow for big files)."),
    all_runs: bool = typer.Option(False, "--all",
                                  help="List every IO-VNBD run, the missing ones too (default: those here, and a count "
                                       "of the rest)."),
    data_root_opt: Optional[Path] = typer.Option(None, "--data-root",
                                                 help="Data root (default: $IONAV_DATA, else the per-user "
                                                      "data directory).", show_default=False),
    manifest_opt: Optional[Path] = c.ManifestOpt,
) -> None:
    """List the bundled drives, then the IO-VNBD runs: group, driver, paper role, size, and whether present locally."""
    from ..api.datasets import DatasetSource, bundled_drives, fetch_root, list_runs
    from ..core.json_out import dumps_json

    root = fetch_root(data_root_opt)
    rows = list_runs(root, DatasetSource(manifest=manifest_opt), verify)
    bundled = bundled_drives()
    if as_json:
        print(dumps_json({"bundled": bundled, "data_root": root, "runs": rows}))
        return
    _print_bundled(bundled)
    shown = rows if all_runs else [r for r in rows if r["status"] != "missing"]
    missing = [r for r in rows if r["status"] == "missing"]
    print(f"\nIO-VNBD runs (the real dataset) under the data root {root}: {len(rows) - len(missing)} of "
          f"{len(rows)} here")
    if shown:
        width = max(len(r["name"]) for r in shown)
        print(f"{'run'.ljust(width)}  group  driver  {'size':>9}  {'local':<8}  role in the paper")
        for r in shown:
            print(f"{r['name'].ljust(width)}  {r['group']:<5}  {r['driver']:<6}  {r['size_bytes'] / 1e6:>7.2f}MB  "
                  f"{r['status']:<8}  {r['role']}")
    said = [text for status, text in _STATUS_TEXT if status in {r["status"] for r in shown}]
    if said:
        print("\nlocal: " + "; ".join(said))
    if missing and not all_runs:
        print(f"{len(missing)} missing ({sum(r['size_bytes'] for r in missing) / 1e6:.0f} MB), each listed by "
              "'ionav-viz list --all'; get one with 'ionav-viz fetch NAME',\nthe paper's test runs with 'ionav-viz "
              "fetch --paper-test'")


def _print_bundled(bundled: list[dict]) -> None:
    """The bundled drives, one line each (the training drives counted in one line)."""
    listed = [b for b in bundled if b["role"] != "train"]
    width = max(len(b["name"]) for b in listed)
    stands = max(len(", ".join(b["stands_in_for"])) for b in listed)
    print("Bundled drives: give the name wherever a drive goes ('ionav-viz replay roundabout')")
    print(f"{'name'.ljust(width)}  {'stands in for'.ljust(stands)}  what")
    for b in listed:
        print(f"{b['name'].ljust(width)}  {', '.join(b['stands_in_for']).ljust(stands)}  {b['what']}")
    train = [b for b in bundled if b["role"] == "train"]
    if train:
        print(f"and {len(train)} simulated training drives (V-sim-SCENARIO-train-N), what 'ionav-viz train' trains "
              "on by default")


#: What each local status of ``list`` means, in the order said under the table.
_STATUS_TEXT = (("verified", "verified = size and sha256 match the dataset's manifest"),
                ("present", "present = the size matches, the sha256 not checked yet (--verify)"),
                ("mismatch",
                 "mismatch = the size or sha256 differs from the manifest's: an edited copy, another version "
                 "or a damaged download ('ionav-viz fetch NAME' gets the published one)"),
                ("missing", "missing = no V-*.csv of the run under the data root ('ionav-viz fetch NAME')"))


@app.command()
def fetch(
    names: Optional[list[str]] = typer.Argument(None, help="Run names, e.g. V-Vw8 Vta11."),
    scenario: Optional[str] = typer.Option(None, "--scenario", help="The paper's test runs of a scenario, or all."),
    paper_test: bool = typer.Option(False, "--paper-test", help="All the paper's test runs (Tables 6-7)."),
    paper_train: bool = typer.Option(False, "--paper-train", help="All the paper's training runs (Table 1)."),
    synchronised: bool = typer.Option(False, "--synchronised",
                                      help="The synchronised copy instead of the complete (unsynchronised) run."),
    phone: bool = typer.Option(False, "--phone", help="Also the phone's S- file of each run."),
    data_root_opt: Optional[Path] = typer.Option(None, "--data-root",
                                                 help="Where to put the files (default: $IONAV_DATA, else the per-user "
                                                      "data directory).", show_default=False),
    base_url_opt: Optional[str] = typer.Option(None, "--base-url",
                                               help="Repository root URL to download from (default: $IONAV_BASE_URL, "
                                                    "else the dataset's Git LFS media URL)."),
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
