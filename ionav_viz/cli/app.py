"""The ``ionav-viz`` application: the root options, and one-line errors with exit codes.

Commands live one per module beside this one and register themselves on :data:`app`.

Heavy libraries (numpy, torch, pyproj, rerun) are imported inside the commands so that
``ionav-viz --help`` answers at once. Every known input problem is an
:class:`~ionav_viz.errors.InputError`, printed by :func:`main` as one line with exit code 2
(a traceback only with ``--debug``); Ctrl-C exits with 130.
"""

from __future__ import annotations

import contextlib
import logging
import re
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from types import MappingProxyType

import typer

from ..core.errors import InputError, ToolFailure

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Replay drives, inject GNSS outages, and compare INS dead reckoning, the IDNN and your own "
         "estimators in Rerun.",
)
log = logging.getLogger("ionav_viz")

class _StderrHandler(logging.Handler):
    def emit(self, record: logging.LogRecord) -> None:
        from ..core.errors import plain_text

        prefix = "warning: " if record.levelno >= logging.WARNING else ""
        print(prefix + one_line(plain_text(record.getMessage())), file=sys.stderr)


def _setup_logging(verbose: bool = False) -> None:
    import os

    # Rerun's native logger writes to stderr; our own one-line errors say what failed.
    if not verbose and "--debug" not in sys.argv:
        os.environ.setdefault("RUST_LOG", "off")
    log.handlers[:] = [_StderrHandler()]
    log.setLevel(logging.INFO if verbose else logging.WARNING)
    log.propagate = False


def _print_version(value: bool) -> None:
    if value:
        from .. import __version__

        print(f"ionav-viz {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    debug: bool = typer.Option(False, "--debug", help="Show full tracebacks on errors."),
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Say more about what is read and assumed."),
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                 help="Print the version and exit."),
) -> None:
    _setup_logging(verbose)



#: API argument -> the option that sets it, for error messages; a command names options whose text
#: depends on its own arguments (``--outage 7s``) with :func:`options_named`.
OPTION_OF: Mapping[str, str] = MappingProxyType({
    "data_root": "--data-root", "stamps": "--stamps", "model": "--model", "bias_from": "--bias-from",
    "thresholds": "--threshold", "gnss_limits": "--gnss-limit", "imu_axes": "--imu-axes", "times": "--time",
    "size": "--size", "views": "--view", "yaw_sign": "--yaw-sign", "estimators": "--estimators",
    "plugins": "--estimator", "arch": "--arch", "n_steps_disp": "--steps", "n_steps_yaw": "--steps-yaw",
    "feedback_noise_m": "--feedback-noise", "lr_decay_tail": "--lr-decay-tail", "output": "-o",
    "base_url": "--base-url", "duration_s": "--duration", "seed": "--seed", "inputs": "--inputs",
    "outage_s": "--outage", "placement": "--on", "outages": "--outage", "worst_of": "--worst-of",
    "gnss_velocity_topic": "--gnss-velocity-topic", "vehicle_speed_topic": "--vehicle-speed-topic",
    "imu_mount": "--imu-mount", "imu_time_offset": "--imu-time-offset", "imu_samples": "--imu-samples",
    "warm_up": "--warm-up", "truth_topic": "--truth-topic", "truth_origin": "--truth-origin", "plan": "--plan",
    "external": "--external", "export": "--export", "imu_topic": "--imu-topic", "gnss_topic": "--gnss-topic",
    "connect": "--connect", "span": "--span", "from_model": "--from-model", "folds": "--folds", "strict": "--strict",
    "device": "--device", "formats": "--format",
})


@contextmanager
def options_named(**options: str) -> Iterator[None]:
    """Errors raised in the block name these options for the API arguments they set
    (``outage_s="--outage 7s"``), instead of :data:`OPTION_OF`'s."""
    try:
        yield
    except InputError as exc:
        if exc.param in options and exc.option is None:
            exc.option = options[exc.param]
        raise


#: Root options that work anywhere on the command line (moved before the command name).
_ANYWHERE = ("--debug", "--verbose", "-v")


def root_options_first(argv: list[str]) -> list[str]:
    """``ionav-viz replay X --debug`` -> ``ionav-viz --debug replay X`` (arguments after ``--`` stay)."""
    end = argv.index("--") if "--" in argv else len(argv)
    moved = [a for a in argv[:end] if a in _ANYWHERE]
    return moved + [a for a in argv[:end] if a not in _ANYWHERE] + argv[end:]


def optional_values(argv: list[str]) -> list[str]:
    """``--connect`` without an address (the next word is not a URL) -> ``--connect <default>``,
    as ``rerun --connect [URL]`` takes it."""
    from ..viz.live import DEFAULT_CONNECT_URL

    out = []
    for i, arg in enumerate(argv):
        out.append(arg)
        if arg == "--connect" and (i + 1 == len(argv) or "://" not in argv[i + 1]):
            out.append(DEFAULT_CONNECT_URL)
    return out


def one_line(text: str) -> str:
    """Errors are one line: line breaks (e.g. from a server's reply quoted in a message) become
    spaces, and what else a terminal would act on (ESC, a topic name's control characters quoted
    from a file) is escaped (:func:`~ionav_viz.core.errors.printable`): no message clears the
    screen or forges a line of its own."""
    from ..core.errors import printable

    return printable(" ".join(text.split()) if "\n" in text or "\r" in text else text)


def input_error_line(exc: InputError, options: Mapping[str, str] = OPTION_OF) -> str:
    """The one line an :class:`InputError` is printed as (exit code 2): ``error: OPTION: message
    (hint: ...)``, the option the error's ``option`` names, else the one ``options`` maps its
    ``param`` to (a script with options of its own gives its own map, or none)."""
    from .config import origin_of

    option = exc.option or options.get(exc.param or "")
    text = f"{option}: {exc}" if option and not exc.message.startswith(option) else str(exc)
    origin = origin_of(option)
    return f"error: {one_line(f'{origin}: {text}' if origin else text)}"


def failure_exit_code(exc: BaseException, options: Mapping[str, str] = OPTION_OF) -> int | None:
    """Print the one line of an error the command line reports without a traceback and return its
    exit code: an :class:`InputError` 2 (:func:`input_error_line`, ``options`` naming the options),
    a :class:`ToolFailure` or a write that found no room 1; None for any other error (re-raise it).
    The benchmark scripts share it (benchmarks/_cli.py)."""
    if isinstance(exc, InputError):
        print(input_error_line(exc, options), file=sys.stderr)
        return 2
    if isinstance(exc, ToolFailure):
        print(f"error: {one_line(str(exc))}", file=sys.stderr)
        return 1
    if isinstance(exc, OSError):
        from ..core.fileio import write_failure

        failure = write_failure(exc.filename or "standard output", exc)
        if failure is None:
            return None
        _silence_stdout()  # what is still buffered would fail again at exit, with a second message
        print(f"error: {one_line(str(failure))}", file=sys.stderr)
        return 1
    return None


def _silence_stdout() -> None:
    """Point standard output at /dev/null (Python's advice for a closed pipe: exit quietly)."""
    import os

    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


#: Suffixes of the files a folder of drives holds (a guess made before the options are parsed).
_DRIVE_SUFFIXES = (".csv", ".mcap", ".bag")


def runs_worker_processes(args: list[str]) -> bool:
    """Whether ``ionav-viz ARGS`` will likely evaluate or replay drives on local worker processes:
    ``--workers N`` (N of 2 or more), or, without ``--workers``, a folder of two or more drive files
    (a fleet on every core). A guess from the words alone, before the options are parsed: a wrong
    one only starts the workers' forkserver, which does nothing and exits with this process."""
    import os

    command = next((i for i, word in enumerate(args) if not word.startswith("-")), None)
    if command is None or args[command] not in ("evaluate", "replay"):
        return False
    rest = args[command + 1:]
    if any(word in ("--help", "--dry-run", "--cluster") or word.startswith("--cluster=") for word in rest):
        return False
    for i, word in enumerate(rest):
        if word == "--workers" or word.startswith("--workers="):
            value = word.removeprefix("--workers=") if "=" in word else (rest[i + 1] if i + 1 < len(rest) else "")
            return value.isdigit() and int(value) >= 2
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    for word in rest if cores > 1 else ():
        if not word.startswith("-") and os.path.isdir(word):
            with contextlib.suppress(OSError), os.scandir(word) as entries:
                found = 0
                for entry in entries:  # stops at the second drive: a huge folder is not read through
                    found += entry.name.lower().endswith(_DRIVE_SUFFIXES)
                    if found == 2:
                        return True
    return False


def _run(args: list[str]) -> object:
    """Run the command line ``args``: experiment files read in (``run FILE``, ``--config FILE``), or
    with ``--print-config`` the effective configuration printed instead; the configuration is
    embedded in every report and recording the command writes (:mod:`ionav_viz.core.run_config`)."""
    import typer.main

    from ..core import run_config
    from . import config

    group = typer.main.get_command(app)
    config.forget()
    if any(word in (config.CONFIG_OPTION, config.PRINT_CONFIG_OPTION) or word.startswith(config.CONFIG_OPTION + "=")
           for word in args) \
            or "run" in args:
        args = config.expand(args, group)
        if config.PRINT_CONFIG_OPTION in args and "--help" not in args:
            config.print_config(args, group)
            return 0
    if runs_worker_processes(args):
        from ..core.processes import worker_context

        worker_context()  # the workers' imports run on another core while this process imports its own
    with run_config.running(config.effective_config(args, group, carried=True)):
        return app(args=args, standalone_mode=False)


def main() -> None:
    """Console entry point: one-line errors with exit code 2, 1 for the environment, 130 on Ctrl-C,
    143 on SIGTERM and 129 on SIGHUP (after cleaning up)."""
    from ..core.signals import Terminated, raise_on_stop_signals

    args = optional_values(root_options_first(sys.argv[1:]))
    debug = "--debug" in args
    raise_on_stop_signals()  # SIGTERM and SIGHUP clean up like Ctrl-C
    try:
        code = _run(args)
        # Without standalone mode, typer returns exit codes (130 for Ctrl-C) instead of exiting.
        if isinstance(code, int) and not isinstance(code, bool):
            if code == 130:
                print("interrupted", file=sys.stderr)
            sys.exit(code)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except (KeyboardInterrupt, typer.Abort):
        print("interrupted", file=sys.stderr)
        sys.exit(130)
    except Terminated as exc:
        print(f"terminated ({exc})", file=sys.stderr)
        sys.exit(exc.exit_code)
    except (InputError, ToolFailure, OSError) as exc:
        if debug or (code := failure_exit_code(exc)) is None:
            raise
        sys.exit(code)
    except Exception as exc:
        # typer's (click's) usage errors: one line too, with the command's --help as the hint
        if hasattr(exc, "format_message") and hasattr(exc, "exit_code") and not debug:
            ctx = getattr(exc, "ctx", None)
            command = (ctx.command_path.replace("python -m ionav_viz.cli", "ionav-viz")
                       if ctx is not None else "ionav-viz")
            message = one_line(exc.format_message())
            from .config import origin_of

            named = re.search(r"(--[A-Za-z0-9-]+)", message)
            origin = origin_of(named.group(1) if named else None)
            print(f"error: {origin + ': ' if origin else ''}{message} (hint: see '{command} --help')", file=sys.stderr)
            sys.exit(exc.exit_code)
        raise

