"""Commands over logs, maps and configs: simulate, info, map, evaluate, dump-config."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from smokyslam.cli.options import (
    CameraNoiseOption,
    ConfigOption,
    HazeOption,
    OverwriteOption,
    RadarLossOption,
    SmokeOption,
    effective_config,
    smoke_overrides,
)
from smokyslam.config import config_to_yaml
from smokyslam.errors import ConfigError
from smokyslam.outputs import writable_file


def dump_config(config: ConfigOption = None) -> None:
    """Print the effective configuration as YAML."""
    typer.echo(config_to_yaml(effective_config(config)), nl=False)


def simulate(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Log to write: .mcap (ROS2) or .bag (ROS1).")
    ],
    world: Annotated[
        str, typer.Option(help="office, warehouse, corridor, or a map_server floor-plan YAML.")
    ] = "office",
    duration: Annotated[float, typer.Option(min=1.0, help="Seconds of walking.")] = 60.0,
    seed: Annotated[int, typer.Option(help="Seed for the world, the walk and the sensors.")] = 0,
    walk_seed: Annotated[
        int | None,
        typer.Option(help="Seed for the walk and the sensors only (default: --seed)."),
    ] = None,
    sensors: Annotated[
        str,
        typer.Option(help="Sensors to record, e.g. radar,imu (no camera: many times faster)."),
    ] = "radar,camera,imu",
    overwrite: Annotated[bool, typer.Option(help="Replace an existing log.")] = False,
    config: ConfigOption = None,
) -> None:
    """Simulate a walk through a building and record radar, camera, IMU and ground truth."""
    from smokyslam.sim.simulate import parse_sensors
    from smokyslam.sim.simulate import simulate as run_simulation

    if out.suffix not in (".mcap", ".bag"):
        raise ConfigError(f"--out must end in .mcap or .bag, got '{out.name}'")
    chosen = parse_sensors(sensors)
    writable_file(out, "--out")
    cfg = effective_config(config)
    from smokyslam.progress import progress_bar

    with progress_bar(f"simulating {world}", duration) as update:
        result = run_simulation(
            world,
            duration,
            seed,
            out,
            cfg,
            overwrite=overwrite,
            on_progress=update,
            sensors=chosen,
            walk_seed=walk_seed,
        )
    typer.echo(
        f"wrote {result.log_path}: {result.duration_s:.0f} s of {result.world.name}, "
        f"path {result.trajectory.path_length_m:.1f} m, {result.radar_frames} radar frames "
        f"({result.radar_points_per_frame:.0f} points each), {result.camera_frames} images, "
        f"in {result.wall_s:.1f} s ({result.realtime_factor:.1f}x real time)"
    )


def info(
    log: Annotated[Path, typer.Argument(help="A .bag, .mcap, .db3 or CARMEN .log(.gz).")],
    smoke: SmokeOption = None,
    radar_loss: RadarLossOption = None,
    camera_noise: CameraNoiseOption = None,
    haze: HazeOption = None,
    config: ConfigOption = None,
) -> None:
    """Print each topic of a log: type, message count, rate, and the log's duration."""
    cfg = effective_config(config, smoke_overrides(smoke, radar_loss, camera_noise, haze))
    from smokyslam.frontends.readers.registry import open_log
    from smokyslam.loginfo import format_summary

    typer.echo(format_summary(open_log(log, cfg).summary()))
    level = cfg.smoke
    if level.radar_loss or level.camera_noise or level.haze:
        typer.echo(
            f"smoke at replay: {level.radar_loss:g}:{level.camera_noise:g}:{level.haze:g} "
            "(radar loss : camera noise : haze)"
        )


def map_command(
    log: Annotated[Path, typer.Argument(help="A log with radar and ground-truth poses.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    poses: Annotated[
        str, typer.Option(help="Pose source for stitching (only 'ground-truth' here).")
    ] = "ground-truth",
    smoke: SmokeOption = None,
    radar_loss: RadarLossOption = None,
    camera_noise: CameraNoiseOption = None,
    haze: HazeOption = None,
    upsample: Annotated[
        bool, typer.Option(help="Also up-sample it (maps/radar_dense.*, upsample.method).")
    ] = False,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Build the sparse radar map on ground-truth poses and score it against the true map."""
    if poses != "ground-truth":
        raise ConfigError(f"--poses must be 'ground-truth', got '{poses}' (use 'run' for SLAM)")
    cfg = effective_config(config, smoke_overrides(smoke, radar_loss, camera_noise, haze))
    from smokyslam.pipelines.truth_mapping import run_truth_mapping

    result = run_truth_mapping(log, cfg, out, overwrite=overwrite, upsample_map=upsample)
    for name, scores in result.metrics.get("maps", {}).items():
        typer.echo(f"{name}: " + _scores_line(scores))
        if "observed" in scores:
            typer.echo(f"{name} (observed truth): " + _scores_line(scores["observed"]))
    typer.echo(f"wrote {result.out_dir}/ in {result.wall_s:.1f} s")


def _scores_line(scores: dict) -> str:
    return ", ".join(f"{k} {v:.3f}" for k, v in scores.items() if not isinstance(v, dict))


def evaluate(
    map_yaml: Annotated[Path, typer.Argument(help="A map_server map YAML to score.")],
    truth: Annotated[
        Path,
        typer.Option(help="Ground truth: a log with a map, a map YAML, or a .ply/.pcd cloud."),
    ],
    z_band: Annotated[
        str | None,
        typer.Option(help="LO:HI metres: the height band of a cloud truth that holds walls."),
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="JSON file for the metrics.")
    ] = None,
    config: ConfigOption = None,
) -> None:
    """Score a saved map against ground truth (error index, occupied precision/recall/F1/IoU;
    against a simulated log also against the truth its lidar observed)."""
    from smokyslam.evaluation.cloud_truth import parse_z_band
    from smokyslam.pipelines.evaluate_map import evaluate_map_file

    target = writable_file(out or map_yaml.with_name(map_yaml.stem + "_metrics.json"), "--out")
    metrics = evaluate_map_file(map_yaml, truth, effective_config(config), parse_z_band(z_band))
    for key, value in metrics.items():
        if isinstance(value, dict):
            typer.echo(f"{key} truth:")
            for inner, number in value.items():
                typer.echo(f"  {inner:18s} {number:.4f}")
        else:
            typer.echo(f"{key:20s} {value:.4f}")
    target.write_text(json.dumps(metrics, indent=2) + "\n")
    typer.echo(f"wrote {target}")


def import_ti(
    capture: Annotated[
        Path, typer.Argument(help="A raw UART capture of a TI mmWave radar (e.g. a .dat).")
    ],
    radar_cfg: Annotated[
        Path, typer.Option("--radar-cfg", help="The .cfg the radar ran with (resolutions).")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Log to write: .mcap or .bag.")],
    sdk: Annotated[
        int | None,
        typer.Option(help="Force the frame format: 1 (SDK 1.x/2.x xWR14xx) or 3 (SDK 3.x)."),
    ] = None,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Convert a raw TI mmWave UART capture into a log (one radar scan per valid frame)."""
    cfg = effective_config(config)
    if sdk is not None and sdk not in (1, 3):
        raise ConfigError(f"--sdk must be 1 or 3, got {sdk}")
    writable_file(out, "--out")
    from smokyslam.pipelines.import_ti import import_ti as run_import

    result = run_import(capture, radar_cfg, out, cfg, overwrite=overwrite, sdk=sdk)
    stats = result.stats
    reasons = ", ".join(f"{k} {v}" for k, v in stats.reasons.items())
    typer.echo(
        f"wrote {result.log_path}: {result.scans} scans over {result.duration_s:.1f} s; "
        f"{stats.dropped} frames dropped{f' ({reasons})' if reasons else ''}, "
        f"{stats.bytes_skipped} bytes skipped"
    )


def record(
    radar_cli: Annotated[str, typer.Option("--radar-cli", help="The radar's CLI port or URL.")],
    radar_data: Annotated[str, typer.Option("--radar-data", help="Its data port or URL.")],
    radar_cfg: Annotated[Path, typer.Option("--radar-cfg", help="The .cfg to configure it.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Log to write: .mcap or .bag.")],
    duration: Annotated[
        float | None, typer.Option(min=0.0, help="Seconds to record (default: until Ctrl-C).")
    ] = None,
    camera: Annotated[
        str | None,
        typer.Option(help="Also a camera: an OpenCV device index, a stream URL or a video."),
    ] = None,
    camera_cfg: Annotated[
        Path | None,
        typer.Option("--camera-cfg", help="Its intrinsics (e.g. configs/cameras/webcam.yaml)."),
    ] = None,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Record a live TI mmWave radar (and a camera) into a log (host timestamps); Ctrl-C or
    a disconnect closes the log with everything recorded so far."""
    cfg = effective_config(config)
    writable_file(out, "--out")
    from smokyslam.pipelines.record import record as run_record
    from smokyslam.progress import console

    result = run_record(
        radar_cli,
        radar_data,
        radar_cfg,
        out,
        cfg,
        duration,
        on_status=lambda text: console.print(text, markup=False, highlight=False),
        overwrite=overwrite,
        camera=camera,
        camera_cfg=camera_cfg,
    )
    stats = result.stats
    typer.echo(
        f"wrote {result.log_path}: {result.scans} scans and {result.images} images over "
        f"{result.duration_s:.1f} s "
        f"(ended: {result.ended_by}); {stats.dropped} frames dropped, "
        f"{stats.bytes_skipped} bytes skipped"
    )
