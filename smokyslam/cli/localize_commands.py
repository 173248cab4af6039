"""``smokyslam localize``: Monte Carlo localization of a log, or of a live TI radar, in a
saved map."""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Annotated, get_args

import numpy as np
import typer

from smokyslam.cli.options import (
    CalibrationOption,
    CameraCfgOption,
    CameraOption,
    ConfigOption,
    DurationOption,
    LiveOption,
    OverwriteOption,
    RadarCfgOption,
    RadarCliOption,
    RadarDataOption,
    RerunOption,
    RerunSpawnOption,
    SmokeOption,
    check_live,
    check_rerun,
    echo_recording,
    effective_config,
    smoke_overrides,
)
from smokyslam.config.localize import LocalizeConfig
from smokyslam.errors import ConfigError

DENSIFY = get_args(LocalizeConfig.model_fields["densify"].annotation)
"""The values ``--densify`` takes: the config's."""


def parse_pose(text: str, option: str) -> np.ndarray:
    """``x,y,yaw`` (metres, metres, degrees) as (3,) [x_m, y_m, yaw_rad]."""
    parts = text.split(",")
    try:
        values = [float(part) for part in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"{option} must be three numbers x,y,yaw (m, m, degrees), got '{text}'")
    return np.array([values[0], values[1], math.radians(values[2])])


def localize(
    map_yaml: Annotated[
        Path, typer.Argument(help="A map_server map (sparse, dense, fused, or a floor plan).")
    ],
    log: Annotated[
        Path | None,
        typer.Argument(help="A log with radar scans (.bag, .mcap, .db3, .log; none with --live)."),
    ] = None,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Output folder.")] = None,
    init: Annotated[
        str | None,
        typer.Option(help="Tracking from this map pose: x,y,yaw (m, m, degrees)."),
    ] = None,
    init_offset: Annotated[
        str | None,
        typer.Option(
            "--init-offset",
            help="Tracking from the true start pose moved by dx,dy,dyaw (m, m, degrees; the "
            "shift in map axes); needs ground truth; for evaluation.",
        ),
    ] = None,
    global_: Annotated[
        bool,
        typer.Option("--global", help="Global localization: no initial pose (the default)."),
    ] = False,
    densify: Annotated[
        str | None,
        typer.Option(
            help="Up-sample the map before localizing in it: auto (a map as sparse as a "
            "stitched radar map; the default), always, never.",
        ),
    ] = None,
    smoke: SmokeOption = None,
    live: LiveOption = False,
    radar_cli: RadarCliOption = None,
    radar_data: RadarDataOption = None,
    radar_cfg: RadarCfgOption = None,
    duration: DurationOption = None,
    camera: CameraOption = None,
    camera_cfg: CameraCfgOption = None,
    rerun: RerunOption = None,
    rerun_spawn: RerunSpawnOption = False,
    calibration: CalibrationOption = None,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Find the rig in a saved map along a log, or live on a TI radar: trajectory.tum (map
    frame), metrics.json (errors against ground truth, time to converge, particle counts),
    localization.png."""
    cfg = effective_config(config, smoke_overrides(smoke), calibration)
    if out is None:
        raise ConfigError("--out is required")
    check_live(live, log, radar_cli, radar_data, radar_cfg)
    if densify is not None:
        if densify not in DENSIFY:
            raise ConfigError(f"--densify must be one of {', '.join(DENSIFY)}, got '{densify}'")
        cfg.localize.densify = densify
    if sum(x is not None for x in (init, init_offset)) + global_ > 1:
        raise ConfigError("give one of --init, --init-offset and --global")
    if not map_yaml.is_file():
        raise ConfigError(f"map not found: {map_yaml}")
    check_rerun(rerun, rerun_spawn)
    from smokyslam.frontends.readers.registry import open_log
    from smokyslam.pipelines.localize import StartRequest, localize_log
    from smokyslam.progress import progress_bar

    request = StartRequest(
        init=parse_pose(init, "--init") if init is not None else None,
        init_offset=parse_pose(init_offset, "--init-offset") if init_offset else None,
    )
    if live:  # the live sensors, or the log: the rest is the same
        from smokyslam.pipelines.live import LiveSensors, localize_live

        sensors = LiveSensors(radar_cli, radar_data, radar_cfg, duration, camera, camera_cfg)
        label, duration_s = "localizing live", duration or 0.0
        localize_source = functools.partial(localize_live, map_yaml, sensors)
    else:
        label, duration_s = f"localizing {log.name}", open_log(log, cfg).summary().duration_s
        localize_source = functools.partial(localize_log, map_yaml, log)
    with progress_bar(label, duration_s) as update:
        result = localize_source(
            cfg,
            out,
            request,
            on_progress=lambda t, s: update(t, status=s),
            rerun_path=rerun,
            rerun_spawn=rerun_spawn,
            overwrite=overwrite,
        )
    typer.echo(f"wrote {result.out_dir}: {_summary(result.metrics)}")
    echo_recording(rerun)


def _summary(metrics: dict) -> str:
    loc = metrics["localization"]
    parts = [f"{loc['mode']}, {loc['frames']} frames"]
    if loc.get("converge_time_s") is not None:
        after = loc["after_convergence"]
        parts.append(
            f"converged after {loc['converge_time_s']:.1f} s, then position RMSE "
            f"{after['position_rmse_m']:.3f} m, median yaw error {after['yaw_median_deg']:.2f} deg"
        )
    elif "all" in loc:
        parts.append("not converged")
    parts.append(f"particles {loc['particles']['mean']:.0f} on average")
    if metrics.get("realtime_factor"):
        parts.append(f"{metrics['realtime_factor']:.1f}x real time")
    return "; ".join(parts)
