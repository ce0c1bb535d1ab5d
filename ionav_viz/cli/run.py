"""``ionav-viz run FILE``: an experiment file's command with its options (:mod:`.config`)."""

from __future__ import annotations

from pathlib import Path

import typer

from .app import app


@app.command(context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
def run(
    ctx: typer.Context,
    file: Path = typer.Argument(..., help="An experiment file (.toml): command = \"...\", its drives and options. "
                                "Options after FILE override the file's."),
) -> None:
    """Run an experiment file: the command it names with its options ('ionav-viz COMMAND --print-config' writes one).

    Every command also takes --config FILE (the file's options, the command line's win) and
    --print-config (print the effective configuration and exit). See 'Experiment files' in the README.
    """
    import typer.main

    from ..core import run_config
    from . import config

    group = typer.main.get_command(app)
    # reached when main() did not read it first (the API's app())
    words = config.expand(["run", str(file), *ctx.args], group)
    with run_config.running(config.effective_config(words, group, carried=True)):
        app(args=words, standalone_mode=False)
