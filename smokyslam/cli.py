"""The ``smokyslam`` command line: glue over library functions that return results.

Heavy modules are imported inside each command, after its arguments are validated. Known
errors (SmokySlamError) become one line on stderr and exit code 1, never a traceback.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path
from typing import Annotated

import typer

from smokyslam import __version__
from smokyslam.config import SmokySlamConfig, config_to_yaml, load_config
from smokyslam.errors import SmokySlamError

app = typer.Typer(
    name="smokyslam",
    help="Radar-visual SLAM for smoke-filled buildings.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

ConfigOption = Annotated[
    Path | None, typer.Option("--config", "-c", help="YAML config file (see configs/).")
]
RadarLossOption = Annotated[
    float | None,
    typer.Option("--radar-loss", min=0.0, max=1.0, help="Fraction of radar returns dropped."),
]
CameraNoiseOption = Annotated[
    float | None,
    typer.Option("--camera-noise", min=0.0, max=1.0, help="Salt-and-pepper pixel fraction."),
]
HazeOption = Annotated[float | None, typer.Option("--haze", min=0.0, help="Haze density B in 1/m.")]


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
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )


def effective_config(
    config_path: Path | None,
    radar_loss: float | None = None,
    camera_noise: float | None = None,
    haze: float | None = None,
) -> SmokySlamConfig:
    """Defaults <- YAML file <- smoke options given on the command line."""
    smoke = {
        key: value
        for key, value in (
            ("radar_loss", radar_loss),
            ("camera_noise", camera_noise),
            ("haze", haze),
        )
        if value is not None
    }
    return load_config(config_path, {"smoke": smoke} if smoke else None)


@app.command("dump-config")
def dump_config(config: ConfigOption = None) -> None:
    """Print the effective configuration as YAML."""
    typer.echo(config_to_yaml(effective_config(config)), nl=False)


def main() -> None:
    """Console entry point."""
    try:
        app()
    except SmokySlamError as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(1)
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.exit(130)


if __name__ == "__main__":
    main()
