"""The ``smokyslam`` command line: glue over library functions that return results.

Commands live in ``log_commands.py`` (logs, maps, configs), ``map_commands.py`` (the
up-sampler), ``fusion_commands.py`` (registration, fusion), ``localize_commands.py``
(localization) and ``run_commands.py`` (runs, comparisons, demo, bench) as plain
functions, registered on the app here. Heavy modules are imported inside each command,
after its arguments are validated. Known errors
(SmokySlamError) become one line on stderr and exit code 1, never a traceback.
"""

from __future__ import annotations

import logging
import sys
from typing import Annotated

import typer

from smokyslam import __version__
from smokyslam.cli import (
    fusion_commands,
    localize_commands,
    log_commands,
    map_commands,
    run_commands,
)
from smokyslam.errors import RunInterruptedError, SmokySlamError, TrainingInterruptedError

app = typer.Typer(
    name="smokyslam",
    help="Radar-visual SLAM for smoke-filled buildings.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

COMMANDS = {
    "simulate": log_commands.simulate,
    "info": log_commands.info,
    "import-ti": log_commands.import_ti,
    "record": log_commands.record,
    "run": run_commands.run,
    "compare": run_commands.compare,
    "sweep": run_commands.sweep,
    "map": log_commands.map_command,
    "evaluate": log_commands.evaluate,
    "upsample": map_commands.upsample,
    "train-upsampler": map_commands.train_upsampler,
    "register": fusion_commands.register,
    "fuse": fusion_commands.fuse,
    "paper-table": fusion_commands.paper_table,
    "localize": localize_commands.localize,
    "bench": run_commands.bench,
    "demo": run_commands.demo,
    "view": run_commands.view,
    "dump-config": log_commands.dump_config,
}
for _name, _command in COMMANDS.items():
    app.command(_name)(_command)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"smokyslam {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version_callback, is_eager=True, help="Show the version."
        ),
    ] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Log debug messages.")] = False,
) -> None:
    level = logging.DEBUG if verbose else logging.WARNING
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    # Run folders log INFO to run.log; the console shows only what --verbose asks for.
    for handler in logging.getLogger().handlers:
        handler.setLevel(level)


def main() -> None:
    """Console entry point: one line for any known error, and for Ctrl-C (exit code 130)."""
    try:
        app()
    except (RunInterruptedError, TrainingInterruptedError) as exc:  # what was done is kept
        typer.echo(str(exc), err=True)
        sys.exit(130)
    except SmokySlamError as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(1)
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.exit(130)
    except SystemExit as exc:
        if exc.code == 130:  # typer turns a Ctrl-C outside a run into a silent exit 130
            typer.echo("interrupted", err=True)
        raise
