"""The ``ionav-viz`` command line: parses options and wires sources, navigation and outputs.

Heavy libraries (numpy, torch, pyproj, rerun) are imported inside the commands so that
``ionav-viz --help`` answers at once. Every known input problem is an
:class:`~ionav_viz.errors.InputError`, printed by :func:`main` as one line with exit code 2
(a traceback only with ``--debug``); Ctrl-C exits with 130.
"""

from __future__ import annotations

import json
import logging
import math
import re
import sys
from pathlib import Path
from typing import Any, Optional

import typer

from .errors import InputError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Replay drives, inject GNSS outages, and compare INS dead reckoning with the IDNN in Rerun.",
)
log = logging.getLogger("ionav_viz")

SCENARIO_CHOICES = ("motorway", "roundabout", "quick-accel", "hard-brake", "sharp-cornering")
_DURATION = re.compile(r"^\s*(?:(\d+(?:\.\d+)?)h)?\s*(?:(\d+(?:\.\d+)?)m(?!s))?\s*(?:(\d+(?:\.\d+)?)s)?\s*(?:(\d+(?:\.\d+)?)ms)?\s*$")


def parse_duration_s(text: str, option: str = "duration") -> float:
    """``'10s'``, ``'500ms'``, ``'1m'``, ``'1m30s'``, ``'2h'`` or a plain number of seconds -> seconds."""
    value = str(text).strip().lower()
    try:
        seconds = float(value)
    except ValueError:
        match = _DURATION.match(value)
        if not value or not match or not any(match.groups()):
            raise typer.BadParameter(f"{text!r} is not a duration; use e.g. 10s, 500ms, 1m", param_hint=option) from None
        h, m, s, ms = (float(g) if g else 0.0 for g in match.groups())
        seconds = h * 3600 + m * 60 + s + ms / 1000
    if not math.isfinite(seconds) or seconds <= 0:
        raise typer.BadParameter(f"{text!r} must be a positive duration", param_hint=option)
    return seconds


class _StderrHandler(logging.Handler):
    def emit(self, record: logging.LogRecord) -> None:
        prefix = "warning: " if record.levelno >= logging.WARNING else ""
        print(prefix + record.getMessage(), file=sys.stderr)


def _setup_logging(verbose: bool = False) -> None:
    log.handlers[:] = [_StderrHandler()]
    log.setLevel(logging.INFO if verbose else logging.WARNING)
    log.propagate = False


@app.callback()
def _root(
    debug: bool = typer.Option(False, "--debug", help="Show full tracebacks on errors."),
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Say more about what is read and assumed."),
) -> None:
    _setup_logging(verbose)


DataRoot = typer.Option(None, "--data-root", help="IO-VNBD checkout to find run names in (default: $IONAV_DATA).", show_default=False)
YawSign = typer.Option("auto", "--yaw-sign", help="Sign of the CSV yaw-rate column: auto (checked against the GNSS heading), cw or ccw positive.")


def _json_safe(obj: Any) -> Any:
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    return obj


@app.command()
def simulate(
    scenario: Optional[str] = typer.Argument(None, help="motorway, roundabout, quick-accel, hard-brake, sharp-cornering or stationary."),
    output: Optional[Path] = typer.Option(None, "-o", "--output", help="The V-*.csv file to write."),
    seed: int = typer.Option(0, "--seed", help="Random seed; the same seed gives the same bytes."),
    duration: str = typer.Option("120s", "--duration", help="Length of the drive, e.g. 120s or 5m."),
    ideal: bool = typer.Option(False, "--ideal", help="Perfect sensors and flat roads (for checks)."),
    bundled: Optional[Path] = typer.Option(None, "--bundled", help="Regenerate every bundled sample into this directory instead."),
) -> None:
    """Write a synthetic drive in the exact IO-VNBD V-*.csv format."""
    from .samples import SAMPLES
    from .simulate import SCENARIOS, SensorModel, write_simulated_drive

    if bundled is not None:
        bundled.mkdir(parents=True, exist_ok=True)
        for sample in SAMPLES:
            write_simulated_drive(bundled / sample.file, sample.scenario, sample.seed, sample.duration_s)
            print(bundled / sample.file)
        return
    if scenario is None or output is None:
        raise typer.BadParameter("give a SCENARIO and -o FILE.csv (or --bundled DIR)")
    if scenario not in SCENARIOS:
        raise typer.BadParameter(f"unknown scenario {scenario!r}; choose one of {', '.join(SCENARIOS)}", param_hint="SCENARIO")
    seconds = parse_duration_s(duration, "--duration")
    path = write_simulated_drive(output, scenario, seed, seconds, SensorModel.ideal() if ideal else None)
    print(path)


def _load_model(model: Optional[Path], no_idnn: bool):
    if no_idnn:
        return None
    from .idnn import default_model_dir, load_model

    directory = model if model is not None else default_model_dir()
    if model is None and not (directory / "metadata.json").is_file():
        log.warning("no shipped IDNN model at %s; evaluating INS only (train one with 'ionav-viz train')", directory)
        return None
    return load_model(directory)


def _scenario_specs(scenario: str, root: Optional[Path]) -> dict[str, list[str]]:
    from .catalog import PAPER_TEST_RUNS
    from .samples import by_scenario

    names = SCENARIO_CHOICES if scenario == "all" else (scenario,)
    if scenario != "all" and scenario not in SCENARIO_CHOICES:
        raise typer.BadParameter(f"unknown scenario {scenario!r}; choose {', '.join(SCENARIO_CHOICES)} or all", param_hint="--scenario")
    if root is not None:
        return {s: list(PAPER_TEST_RUNS[s]) for s in names}
    return {s: [sample.file for sample in by_scenario(s)] for s in names}


@app.command()
def evaluate(
    drives: Optional[list[str]] = typer.Argument(None, help="Drives: file paths, bundled scenario names or IO-VNBD run names."),
    outage: str = typer.Option("10s", "--outage", help="Length of each GNSS outage (whole seconds)."),
    scenario: Optional[str] = typer.Option(None, "--scenario", help="Evaluate a scenario's test drives: the paper's runs with a data root, else the bundled ones; 'all' for every scenario."),
    as_json: bool = typer.Option(False, "--json", help="Print the results as JSON."),
    markdown: bool = typer.Option(False, "--markdown", help="Print the tables as Markdown."),
    model: Optional[Path] = typer.Option(None, "--model", help="IDNN model directory (default: the shipped model)."),
    no_idnn: bool = typer.Option(False, "--no-idnn", help="Evaluate the INS only."),
    bias_from: Optional[str] = typer.Option(None, "--bias-from", help="Stationary drive for sensor biases (default: the drive's own stationary stretches)."),
    data_root_opt: Optional[Path] = DataRoot,
    yaw_sign: str = YawSign,
) -> None:
    """Evaluate INS dead reckoning (and the IDNN) on consecutive GNSS outages, as the paper does."""
    from .evaluate import evaluate_drive, report, resolve_bias
    from .resolve import data_root
    from .sources import load_drive
    from .tables import render_markdown, render_text

    outage_s = parse_duration_s(outage, "--outage")
    root = data_root(data_root_opt)
    if scenario is not None and drives:
        raise typer.BadParameter("give drives or --scenario, not both")
    groups = _scenario_specs(scenario, root) if scenario else {None: list(drives or [])}
    if not any(groups.values()):
        raise typer.BadParameter("give at least one drive (or --scenario)", param_hint="DRIVES")
    idnn = _load_model(model, no_idnn)
    stationary = load_drive(bias_from, root, yaw_sign) if bias_from else None

    reports: dict[Any, dict] = {}
    for group, specs in groups.items():
        results = []
        for spec in specs:
            drive = load_drive(spec, root, yaw_sign)
            bias = resolve_bias(drive, stationary)
            res = evaluate_drive(drive, outage_s, bias=bias, model=idnn)
            if len(res.starts) == 0:
                log.warning("%s: too short for a single %g s outage; skipped", drive.name, outage_s)
                continue
            results.append(res)
        if not results:
            raise InputError(f"no {outage_s:g} s outage fits in {', '.join(specs)}", "use a shorter --outage")
        reports[group] = report(results)

    if as_json:
        out = reports[None] if None in reports else {"scenarios": reports}
        print(json.dumps(_json_safe(out), indent=2))
        return
    render = render_markdown if markdown else render_text
    print("\n".join(render(rep, group) for group, rep in reports.items()), end="")


def main() -> None:
    """Console entry point: one-line errors with exit code 2, 130 on Ctrl-C."""
    debug = "--debug" in sys.argv[1:]
    try:
        app(standalone_mode=False)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except (KeyboardInterrupt, typer.Abort):
        print("interrupted", file=sys.stderr)
        sys.exit(130)
    except InputError as exc:
        if debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    except Exception as exc:
        # typer's (click's) usage errors know how to show themselves; their exit code is 2
        if hasattr(exc, "show") and hasattr(exc, "exit_code") and not debug:
            exc.show()
            sys.exit(exc.exit_code)
        raise


if __name__ == "__main__":
    main()
