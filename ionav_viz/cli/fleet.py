"""``ionav-viz evaluate`` of a fleet (``--workers``, ``--cluster``, ``--fail-fast``, ``--dry-run``,
or drives given as a folder of drives, a glob or ``@list.txt``): each drive on its own, in parallel,
one bad drive reported rather than fatal. Not a command: :mod:`.evaluate` hands over to it."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import typer

from . import common as c
from .app import options_named

if TYPE_CHECKING:
    from ..api.options import ReadOptions, RunOptions


def is_fleet_run(drives: Optional[list[str]], workers: Optional[int], cluster: Optional[str], fail_fast: bool,
                 dry_run: bool, runs: Optional[list[str]] = None) -> bool:
    """Whether ``evaluate`` runs as a fleet: a fleet option (``--runs`` among them), or drives given
    as a list file, a glob or a folder of drives (which one-drive evaluation refuses)."""
    if workers is not None or cluster is not None or fail_fast or dry_run or runs:
        return True
    from ..api.fleet import _is_folder_of_drives

    for spec in drives or []:
        path = Path(spec).expanduser()
        if (spec.startswith("@") or (not path.exists() and any(ch in spec for ch in "*?["))
                or (path.is_dir() and _is_folder_of_drives(path))):
            return True
    return False


def evaluate_fleet(drives: Optional[list[str]], outage: Optional[str], placement: c.PlacementArgs, run: RunOptions,
                   read: ReadOptions, *, workers: Optional[int], cluster: Optional[str], fail_fast: bool, dry_run: bool,
                   as_json: bool, markdown: bool, quiet: bool, refused: dict[str, Any],
                   fleet_rrd: Optional[Path] = None, runs: Optional[list[str]] = None) -> None:
    """Evaluate the drives as a fleet and print its report (and with ``fleet_rrd`` write its
    overview recording there); exit 3 when some drives failed
    (:data:`ionav_viz.api.fleet.EXIT_SOME_FAILED`), 2 when none could be evaluated."""
    from .. import api
    from ..api import fleet
    from ..core.json_out import dumps_json

    for option, given in refused.items():
        if given:
            raise typer.BadParameter(f"a fleet run (--workers, --cluster, many drives) does not take {option} yet",
                                     param_hint=option)
    drives = list(drives or [])
    if not drives and not runs:
        raise typer.BadParameter("give at least one drive (or --runs)", param_hint="DRIVES")
    outage_s = c.duration_s(outage, "--outage") if outage is not None else None
    with options_named(workers="--workers", cluster="--cluster", outage_s=f"--outage {outage or '10s'}",
                       placement=placement.option, runs="--runs", fleet_rrd="--fleet-rrd"):
        _note_pool(workers, cluster, quiet)
        if dry_run:
            plan = fleet.plan_fleet(drives, workers, runs or (), root=read.data_root, fleet_rrd=fleet_rrd)
            print(dumps_json(plan.to_dict()) if as_json else plan.to_text(), end="\n" if as_json else "")
            return
        with c.progress(quiet) as bar:
            report = api.evaluate(_experiment(drives, outage_s, placement, run, read, workers, cluster, runs),
                                  progress=c.progress_callback(bar, "evaluating"),
                                  fleet=api.FleetOptions(fail_fast, fleet_rrd, _replay_options(outage, placement, run,
                                                                                                read)))
    if as_json:
        print(report.to_json())
    else:
        print(report.to_markdown() if markdown else report.to_text(c.terminal_width()), end="")
    _said_fleet_rrd(report, fleet_rrd, quiet)
    _exit_for(report, quiet)


def _experiment(drives: list[str], outage_s: Optional[float], placement: c.PlacementArgs, run: RunOptions,
                read: ReadOptions, workers: Optional[int], cluster: Optional[str], runs: Optional[list[str]]) -> Any:
    """The fleet's :class:`~ionav_viz.api.experiment.Experiment`: on ``workers`` processes (default
    every core) or the Dask ``cluster``."""
    from .. import api
    from ..api.engine import default_workers

    engine = api.Engine(workers if workers is not None else default_workers(), cluster)
    return api.Experiment(drives, outage_s, placement.placement, run=run, read=read, engine=engine, runs=runs or ())


def _note_pool(workers: Optional[int], cluster: Optional[str], quiet: bool) -> None:
    """``note: ...`` on stderr when ``--workers`` asks for more processes than this process may use
    cores: the pool is capped there (:meth:`ionav_viz.api.engine.Engine.pool_size`)."""
    if workers is None or quiet:
        return
    from ..api.engine import Engine

    note = Engine(workers, cluster).capped_note()
    if note is not None:
        print(f"note: {note}", file=sys.stderr)


def _said_fleet_rrd(report: Any, fleet_rrd: Optional[Path], quiet: bool) -> None:
    """Where the overview recording went (written by the run when some drive was done)."""
    if fleet_rrd is not None and report.drives and not quiet:
        print(f"fleet overview: {fleet_rrd} (ionav-viz screenshot {fleet_rrd} -o fleet.png; rerun {fleet_rrd})",
              file=sys.stderr)


#: Options of a fleet run that say where its report goes, how loudly, or how the fleet runs: not
#: part of how one drive is read, estimated and scored, so not in the command that replays it.
_NOT_REPLAYED = frozenset(("--workers", "--cluster", "--fail-fast", "--dry-run", "--fleet-rrd", "--json", "--markdown",
                           "--overview", "--quiet", "-q", "--debug", "--export", "--by-event", "--runs", "-o",
                           "--output", "--open", "--connect", "--screenshot", "--force"))


def _replay_options(outage: Optional[str], placement: c.PlacementArgs, run: RunOptions,
                    read: ReadOptions | None = None) -> str:
    """The options that replay one drive of the fleet the same way: every option the command was
    given (how drives are read, the estimators, the placement, the warm-up, ...) but the fleet's own
    and where its output goes; from the command line as typed, else from what was parsed."""
    import shlex

    import typer.main

    from .app import app

    words = sys.argv[1:]
    commands = getattr(typer.main.get_command(app), "commands", {})
    command = next((w for w in words if w in ("evaluate", "replay") and w in commands), None)
    if command is not None:
        takes_value = {opt: not (getattr(p, "is_flag", False) or getattr(p, "count", False))
                       for p in commands[command].params
                       if p.param_type_name == "option" for opt in (*p.opts, *p.secondary_opts)}
        kept, i, rest = [], 0, words[words.index(command) + 1:]
        while i < len(rest):
            word = rest[i]
            name = word.split("=", 1)[0]
            value_follows = name in takes_value and takes_value[name] and "=" not in word
            if name.startswith("-") and name in takes_value:
                if name not in _NOT_REPLAYED:
                    kept += [word, rest[i + 1]] if value_follows and i + 1 < len(rest) else [word]
                i += 2 if value_follows else 1
                continue
            i += 1  # a drive: the command names its own
        if not any(w.split("=", 1)[0] == "--outage" for w in kept):
            kept = ["--outage", outage or "10s", *kept]
        return " ".join(shlex.quote(w) for w in kept)
    parts = [f"--outage {outage or '10s'}"]
    if placement.option != "--outage":
        option, _, value = placement.option.partition(" ")
        parts.append(f"{option} {shlex.quote(value)}")
    if run is not None and run.estimators is not None:
        parts.append("--estimators " + shlex.quote(",".join(str(e) for e in run.estimators)))
    if run is not None and run.without:
        parts.append("--no-idnn")
    if read is not None and getattr(read, "data_root", None) is not None:  # IO-VNBD run names are read there
        parts.append("--data-root " + shlex.quote(str(read.data_root)))
    return " ".join(parts)


def replay_fleet(drives: list[str], output: Optional[Path], outage: Optional[str], placement: c.PlacementArgs,
                 run: RunOptions, read: ReadOptions, *, workers: Optional[int], cluster: Optional[str], fail_fast: bool,
                 quiet: bool, refused: dict[str, Any], fleet_rrd: Optional[Path] = None,
                 runs: Optional[list[str]] = None) -> None:
    """Replay many drives, one recording each into the folder ``-o`` (default ``recordings``):
    the recordings' paths on stdout, the fleet report on stderr; exit codes as for evaluate."""
    from .. import api

    for option, given in refused.items():
        if given:
            raise typer.BadParameter(f"replaying many drives does not take {option} yet", param_hint=option)
    if output is not None and output.suffix.lower() == ".rrd":
        raise typer.BadParameter(f"{output}: many drives are replayed into a folder, one recording each",
                                 param_hint="-o")
    outage_s = c.duration_s(outage, "--outage") if outage is not None else None
    with options_named(workers="--workers", cluster="--cluster", output="-o", outage_s=f"--outage {outage or '10s'}",
                       placement=placement.option, runs="--runs", fleet_rrd="--fleet-rrd"):
        _note_pool(workers, cluster, quiet)
        with c.progress(quiet) as bar:
            report = api.replay(_experiment(drives, outage_s, placement, run, read, workers, cluster, runs),
                                output=output if output is not None else Path("recordings"),
                                progress=c.progress_callback(bar, "replaying"),
                                fleet=api.FleetOptions(fail_fast, fleet_rrd, _replay_options(outage, placement, run,
                                                                                              read)))
    if not quiet:
        print(report.to_text(c.terminal_width(sys.stderr)), end="", file=sys.stderr)
    for table in report.drives:
        print(table.recording)
    _said_fleet_rrd(report, fleet_rrd, quiet)
    _exit_for(report, quiet)


def _exit_for(report: Any, quiet: bool) -> None:
    """Exit 2 when no drive could be done (one line naming the first), 3 when some failed."""
    from ..api import fleet
    from ..core.errors import InputError

    if not report.drives:
        first = (report.failures or report.skipped)[0]
        raise InputError(f"no drive could be evaluated: {len(report.failures) + len(report.skipped)} failed or skipped "
                         f"(first: {first.spec}: {first.reason})", "see the report for each drive's reason")
    if report.failures:
        if not quiet:
            print(f"{len(report.failures)} of {len(report.drives) + len(report.failures) + len(report.skipped)} "
                  f"drives failed (exit code {fleet.EXIT_SOME_FAILED}); their reasons are in the report",
                  file=sys.stderr)
        raise typer.Exit(fleet.EXIT_SOME_FAILED)
