"""Options shared by the commands, and the effective configuration they build.

Smoke has one notation everywhere: ``--smoke R:C[:H]`` (radar loss : camera noise : haze).
``--radar-loss``, ``--camera-noise`` and ``--haze`` stay as aliases for one part each.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from smokyslam.config import SmokySlamConfig, load_config
from smokyslam.errors import ConfigError
from smokyslam.smoke import parse_smoke

ConfigOption = Annotated[
    Path | None, typer.Option("--config", "-c", help="YAML config file (see configs/).")
]
SmokeOption = Annotated[
    str | None,
    typer.Option(
        "--smoke",
        help="Smoke level R:C[:H]: radar loss and camera noise (fractions, 0-1), haze (1/m).",
    ),
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
CalibrationOption = Annotated[
    Path | None,
    typer.Option(
        "--calibration",
        help="Radar calibration YAML (l_b_r_*, q_b_r_*), e.g. the TI demo bag's *.calib.yaml; "
        "replaces the log's /tf_static mounting.",
    ),
]
RerunOption = Annotated[
    Path | None,
    typer.Option(
        "--rerun",
        help="Write a Rerun recording (.rrd) here, as the run goes; open it with "
        "`smokyslam view FILE`.",
    ),
]
RerunSpawnOption = Annotated[
    bool,
    typer.Option("--rerun-spawn", help="Stream the recording to a Rerun viewer (needs a display)."),
]
OverwriteOption = Annotated[
    bool, typer.Option("--overwrite", help="Replace the outputs of an earlier run in --out.")
]
LiveOption = Annotated[
    bool, typer.Option("--live", help="Run on a live TI radar instead of a log.")
]
RadarCliOption = Annotated[
    str | None, typer.Option("--radar-cli", help="Live: the radar's CLI port or URL.")
]
RadarDataOption = Annotated[
    str | None, typer.Option("--radar-data", help="Live: its data port or URL.")
]
RadarCfgOption = Annotated[
    Path | None, typer.Option("--radar-cfg", help="Live: the .cfg to configure it.")
]
DurationOption = Annotated[
    float | None, typer.Option(min=0.0, help="Live: seconds to run (default: until Ctrl-C).")
]
CameraOption = Annotated[
    str | None, typer.Option(help="Live: a camera (OpenCV device index, URL or video).")
]
CameraCfgOption = Annotated[
    Path | None, typer.Option("--camera-cfg", help="Live: the camera's intrinsics YAML.")
]


def check_live(
    live: bool,
    log: Path | None,
    radar_cli: str | None,
    radar_data: str | None,
    radar_cfg: Path | None,
) -> None:
    """A log, or ``--live`` with the radar's two ports and its .cfg: ConfigError otherwise."""
    if live == (log is not None):
        raise ConfigError("give a LOG, or --live with --radar-cli, --radar-data and --radar-cfg")
    if live and None in (radar_cli, radar_data, radar_cfg):
        raise ConfigError("--live needs --radar-cli, --radar-data and --radar-cfg")


def check_rerun(rerun: Path | None, spawn: bool) -> None:
    """``--rerun`` writable and ``--rerun-spawn`` possible, before any work starts."""
    if rerun is not None:
        from smokyslam.outputs import writable_file

        writable_file(rerun, "--rerun")
    if spawn:
        from smokyslam.viz.viewer import require_display

        require_display("--rerun-spawn")


def echo_recording(rerun: Path | None) -> None:
    """The closing line of a command that wrote a recording: where, and how to open it."""
    if rerun is not None:
        typer.echo(f"recording: {rerun} (open it with `smokyslam view {rerun}`)")


def smoke_overrides(
    smoke: str | None,
    radar_loss: float | None = None,
    camera_noise: float | None = None,
    haze: float | None = None,
) -> dict[str, float]:
    """The ``smoke`` config entries given on the command line (``--smoke`` or its aliases)."""
    aliases = {"radar_loss": radar_loss, "camera_noise": camera_noise, "haze": haze}
    given = {key: value for key, value in aliases.items() if value is not None}
    if smoke is None:
        return given
    if given:
        raise ConfigError("give --smoke or --radar-loss/--camera-noise/--haze, not both")
    level = parse_smoke(smoke)
    return {"radar_loss": level.radar_loss, "camera_noise": level.camera_noise, "haze": level.haze}


def effective_config(
    config_path: Path | None,
    smoke: dict[str, float] | None = None,
    calibration: Path | None = None,
) -> SmokySlamConfig:
    """Defaults <- YAML file <- smoke and calibration options given on the command line."""
    overrides: dict = {"smoke": smoke} if smoke else {}
    if calibration is not None:
        overrides["rig"] = {"calibration": str(calibration.resolve())}
    return load_config(config_path, overrides or None)


def summary_line(metrics: dict) -> str:
    """One line of a run's metrics: ATE, map error indices, realtime factor."""
    parts = []
    trajectory = metrics.get("trajectory")
    if trajectory:
        text = (
            f"ATE {trajectory['ate_rmse_m']:.3f} m ({trajectory['ate_alignment']}, "
            f"{trajectory['drift_pct']:.2f}% of {trajectory['path_length_m']:.1f} m)"
        )
        if trajectory.get("ate_sim2_rmse_m") is not None:
            text += f", sim2 {trajectory['ate_sim2_rmse_m']:.3f} m"
        parts.append(text + f", lost {trajectory['lost_frames']}/{trajectory['frames']} frames")
    for name, scores in metrics.get("maps", {}).items():
        text = f"{name} error index {scores['error_index']:.3f}"
        if "observed" in scores:
            text += f" (observed {scores['observed']['error_index']:.3f})"
        parts.append(text)
    if metrics.get("realtime_factor"):
        parts.append(f"{metrics['realtime_factor']:.1f}x real time")
    return "; ".join(parts)
