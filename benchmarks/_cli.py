"""What the benchmark scripts that take a user's files share with the ``ionav-viz`` command line
(ionav_viz/cli/app.py): bad input is one line naming the file and a hint, exit code 2, and no
traceback unless ``--debug``; inputs and outputs are checked with the library's own checks before
any work, so that a typo costs no measurement and leaves nothing half-written. Not a script::

    from _cli import add_debug, check_logs, output_file, run

    def main() -> None:
        parser = add_debug(argparse.ArgumentParser(...))
        args = parser.parse_args()
        check_logs(args.logs)
        output_file(args.json, "--json", inputs=args.logs)
        ...

    if __name__ == "__main__":
        run(main)
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ionav_viz.core.errors import InputError, ToolFailure


def add_debug(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``parser`` with ``--debug`` (read by :func:`run`), as ``ionav-viz --debug``."""
    parser.add_argument("--debug", action="store_true", help="show an error's full traceback instead of its one line")
    return parser


def run(main: Callable[[], Any]) -> None:
    """Run a script's ``main`` as ``ionav-viz`` runs a command: an :class:`InputError` is one line
    on standard error (``error: OPTION: FILE: what is wrong (hint: ...)``) and exit code 2; a
    :class:`ToolFailure` or a write that found no room one line and exit code 1; with ``--debug``
    on the command line, the traceback instead."""
    debug = "--debug" in sys.argv[1:]
    try:
        main()
    except KeyboardInterrupt:  # as ionav-viz: one word, exit code 130 (what was being written is a temporary file)
        if debug:
            raise
        print("interrupted", file=sys.stderr)
        sys.exit(130)
    except (InputError, ToolFailure, OSError) as exc:
        from ionav_viz.cli.app import failure_exit_code

        # {}: the script's options are named by named(), not by the CLI's map
        if debug or (code := failure_exit_code(exc, {})) is None:
            raise
        sys.exit(code)


def lengths_s(text: str, option: str = "--lengths") -> list[float]:
    """Outage lengths as the scripts take them, comma-separated: ``10,30,60`` or ``10s,1m`` (whole
    seconds, each a duration the command line takes); a bad one is an :class:`InputError` naming it."""
    from ionav_viz.core.durations import parse_duration_s

    with named(option):
        out = [parse_duration_s(x, "outage length") for x in str(text).split(",")]
        for x in out:
            if x != round(x):
                raise InputError(f"outage length {x:g} s is not a whole number of seconds", "give lengths like 10,30,60")
    return out


@contextmanager
def named(option: str | None) -> Iterator[None]:
    """An :class:`InputError` raised in the block names the script's ``option`` (``--json``),
    unless it names one already."""
    try:
        yield
    except InputError as exc:
        if option and exc.option is None:
            exc.option = option
        raise


def check_logs(specs: Iterable[str | Path], option: str | None = None) -> list[Path]:
    """The files or folders the logs ``specs`` name (paths; bundled scenario and IO-VNBD run names
    resolve as ``ionav-viz evaluate`` resolves them), each one a reader of ionav-viz takes: not
    missing, not a folder of drives or another folder, not of a type none reads, not a pipe or a
    device. The contents are read later, by the reader, which names a damaged log itself."""
    from ionav_viz.sources.load import source_kind
    from ionav_viz.sources.resolve import data_root, resolve_drive

    out = []
    with named(option):
        root = data_root(None)
        for spec in specs:
            path = resolve_drive(str(spec), root)
            source_kind(path)
            out.append(path)
    return out


#: The paths whose log was read whole once (:func:`raise_if_unreadable`).
_READABLE: set[str] = set()


def raise_if_unreadable(specs: Iterable[str | Path], read: Any = None) -> None:
    """Where a script takes an evaluation's :class:`InputError` for "no outage of that length fits"
    (and tables a dash), raise the reader's own error instead when one of the logs ``specs`` cannot
    be read at all (damaged, truncated, no usable topics): reads each log once (``read``: its
    :class:`ionav_viz.ReadOptions`), only on that path, so a measurement that works costs nothing more."""
    import ionav_viz as iv

    for spec in specs:
        if str(spec) not in _READABLE:
            iv.load_drive(str(spec), read)
            _READABLE.add(str(spec))


def read_json(path: str | Path, option: str | None, *, what: str, hint: str) -> Any:
    """The JSON in the file ``path`` (the library's bounded, strict reader; NaN allowed, as Python's
    ``json.dumps`` writes it): missing, a folder, not JSON are errors naming ``path`` and ``option``."""
    from ionav_viz.core.fileio import read_json_bounded

    with named(option):
        return read_json_bounded(path, param=option or "input", what=what, hint=hint, allow_nan=True)


def output_file(path: str | Path | None, option: str, *, inputs: Iterable[str | Path] = ()) -> Path | None:
    """Check before any work that the file ``path`` can be written (its folder exists and is
    writable, it is not a folder, a device or a system file) and is none of ``inputs``. None: no output asked for."""
    from ionav_viz.core.fileio import check_output_file, refuse_output_onto_input

    if path is None:
        return None
    with named(option):
        check_output_file(Path(path))
        refuse_output_onto_input(path, list(inputs), param=option)
    return Path(path)


def existing_folder(path: str | Path | None, option: str) -> Path | None:
    """Check that ``path`` is an existing folder a script may write in (None: not asked for)."""
    from ionav_viz.core.fileio import check_output_folder

    if path is None:
        return None
    with named(option):
        check_output_folder(Path(path), param=option)
        if not Path(path).is_dir():
            raise InputError(f"{path}: no such folder", "create it first, or choose an existing folder", param=option)
    return Path(path)


def output_folder(path: str | Path | None, option: str) -> Path | None:
    """Check that ``path`` is a folder, or can be made, where a script may write (None: not asked for)."""
    from ionav_viz.core.fileio import check_output_folder

    if path is None:
        return None
    with named(option):
        check_output_folder(Path(path), param=option)
    return Path(path)


def check_model(path: str | Path | None, option: str = "--model") -> None:
    """Load the IDNN model directory ``path`` (None: the shipped one, not checked) before any
    work, as the estimators will: a missing or damaged model is the library's error, named ``option``."""
    from ionav_viz.learning.idnn import load_model

    if path is not None:
        with named(option):
            load_model(path)
