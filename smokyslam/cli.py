"""The ``smokyslam`` command line: glue over library functions that return results.

Heavy modules are imported inside each command, after its arguments are validated. Known
errors (SmokySlamError) become one line on stderr and exit code 1, never a traceback.
"""

from __future__ import annotations

import json
import logging
import sys
from pathlib import Path
from typing import Annotated

import typer

from smokyslam import __version__
from smokyslam.config import SmokySlamConfig, config_to_yaml, load_config
from smokyslam.errors import ConfigError, SmokySlamError

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
CalibrationOption = Annotated[
    Path | None,
    typer.Option(
        "--calibration",
        help="Radar calibration YAML (l_b_r_*, q_b_r_*), e.g. the TI demo bag's *.calib.yaml; "
        "replaces the log's /tf_static mounting.",
    ),
]


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


def effective_config(
    config_path: Path | None,
    radar_loss: float | None = None,
    camera_noise: float | None = None,
    haze: float | None = None,
    calibration: Path | None = None,
) -> SmokySlamConfig:
    """Defaults <- YAML file <- smoke and calibration options given on the command line."""
    smoke = {
        key: value
        for key, value in (
            ("radar_loss", radar_loss),
            ("camera_noise", camera_noise),
            ("haze", haze),
        )
        if value is not None
    }
    overrides: dict = {"smoke": smoke} if smoke else {}
    if calibration is not None:
        overrides["rig"] = {"calibration": str(calibration.resolve())}
    return load_config(config_path, overrides or None)


@app.command("dump-config")
def dump_config(config: ConfigOption = None) -> None:
    """Print the effective configuration as YAML."""
    typer.echo(config_to_yaml(effective_config(config)), nl=False)


@app.command()
def simulate(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Log to write: .mcap (ROS2) or .bag (ROS1).")
    ],
    world: Annotated[
        str, typer.Option(help="office, warehouse, corridor, or a map_server floor-plan YAML.")
    ] = "office",
    duration: Annotated[float, typer.Option(min=1.0, help="Seconds of walking.")] = 60.0,
    seed: Annotated[int, typer.Option(help="Seed for the world, the walk and the sensors.")] = 0,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing log.")] = False,
    config: ConfigOption = None,
) -> None:
    """Simulate a walk through a building and record radar, camera, IMU and ground truth."""
    if out.suffix not in (".mcap", ".bag"):
        raise ConfigError(f"--out must end in .mcap or .bag, got '{out.name}'")
    cfg = effective_config(config)
    from smokyslam.progress import progress_bar
    from smokyslam.sim.simulate import simulate as run_simulation

    with progress_bar(f"simulating {world}", duration) as update:
        result = run_simulation(
            world, duration, seed, out, cfg, overwrite=overwrite, on_progress=update
        )
    typer.echo(
        f"wrote {result.log_path}: {result.duration_s:.0f} s of {result.world.name}, "
        f"path {result.trajectory.path_length_m:.1f} m, {result.radar_frames} radar frames "
        f"({result.radar_points_per_frame:.0f} points each), {result.camera_frames} images, "
        f"in {result.wall_s:.1f} s ({result.realtime_factor:.1f}x real time)"
    )


@app.command()
def info(
    log: Annotated[Path, typer.Argument(help="A .bag, .mcap, .db3 or CARMEN .log(.gz).")],
    config: ConfigOption = None,
) -> None:
    """Print each topic of a log: type, message count, rate, and the log's duration."""
    from smokyslam.frontends.readers.registry import open_log
    from smokyslam.loginfo import format_summary

    typer.echo(format_summary(open_log(log, effective_config(config)).summary()))


@app.command("compare")
def compare_command(
    log: Annotated[Path, typer.Argument(help="A log with ground truth (e.g. a simulation).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    sources: Annotated[
        str, typer.Option(help="Comma-separated sources: camera, radar, dead-reckoning, fused.")
    ] = "camera,radar,dead-reckoning,fused",
    smoke: Annotated[
        str, typer.Option(help="Comma-separated radar_loss:camera_noise levels, each in [0, 1].")
    ] = "0:0,0.1:0.2,0.2:0.4",
    haze: Annotated[
        str | None,
        typer.Option(help="Comma-separated haze densities B (1/m): each smoke level runs again."),
    ] = None,
    jobs: Annotated[
        int | None,
        typer.Option("--jobs", "-j", min=1, help="Parallel runs (default: 2, or 1 on one core)."),
    ] = None,
    calibration: CalibrationOption = None,
    config: ConfigOption = None,
) -> None:
    """Run odometry sources at several smoke levels: run folders, a table and plots."""
    cfg = effective_config(config, calibration=calibration)
    from smokyslam.pipelines.compare import compare, parse_smoke_levels, parse_sources
    from smokyslam.progress import progress_bar

    source_list, levels = parse_sources(sources), parse_smoke_levels(smoke, haze)
    total = len(source_list) * len(levels)
    with progress_bar(f"comparing {total} runs", total, unit="items") as update:
        result = compare(log, source_list, levels, cfg, out, jobs, on_progress=update)
    typer.echo(result.markdown_path.read_text(), nl=False)
    typer.echo(f"wrote {result.out_dir}/ ({total} runs in {result.wall_s:.1f} s)")
    if result.failed:
        typer.echo(f"error: {len(result.failed)} of {total} runs failed", err=True)
        raise typer.Exit(1)


@app.command("map")
def map_command(
    log: Annotated[Path, typer.Argument(help="A log with radar and ground-truth poses.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    poses: Annotated[
        str, typer.Option(help="Pose source for stitching (only 'ground-truth' here).")
    ] = "ground-truth",
    radar_loss: RadarLossOption = None,
    camera_noise: CameraNoiseOption = None,
    haze: HazeOption = None,
    config: ConfigOption = None,
) -> None:
    """Build the sparse radar map on ground-truth poses and score it against the true map."""
    if poses != "ground-truth":
        raise ConfigError(f"--poses must be 'ground-truth', got '{poses}' (use 'run' for SLAM)")
    cfg = effective_config(config, radar_loss, camera_noise, haze)
    from smokyslam.pipelines.truth_mapping import run_truth_mapping

    result = run_truth_mapping(log, cfg, out)
    for name, scores in result.metrics.get("maps", {}).items():
        typer.echo(f"{name}: " + ", ".join(f"{k} {v:.3f}" for k, v in scores.items()))
    typer.echo(f"wrote {result.out_dir}/ in {result.wall_s:.1f} s")


@app.command()
def evaluate(
    map_yaml: Annotated[Path, typer.Argument(help="A map_server map YAML to score.")],
    truth: Annotated[Path, typer.Option(help="Ground truth: a log with a map, or a map YAML.")],
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="JSON file for the metrics.")
    ] = None,
    config: ConfigOption = None,
) -> None:
    """Score a saved map against ground truth (error index, occupied precision/recall/F1/IoU)."""
    from smokyslam.pipelines.evaluate_map import evaluate_map_file

    metrics = evaluate_map_file(map_yaml, truth, effective_config(config))
    for key, value in metrics.items():
        typer.echo(f"{key:20s} {value:.4f}")
    target = out or map_yaml.with_name(map_yaml.stem + "_metrics.json")
    target.write_text(json.dumps(metrics, indent=2) + "\n")
    typer.echo(f"wrote {target}")


@app.command()
def run(
    log: Annotated[Path, typer.Argument(help="A .bag, .mcap, .db3 or CARMEN .log(.gz) log.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    odometry: Annotated[
        str, typer.Option(help="Odometry source: fused, radar, camera or dead-reckoning.")
    ] = "fused",
    radar_loss: RadarLossOption = None,
    camera_noise: CameraNoiseOption = None,
    haze: HazeOption = None,
    rerun: Annotated[
        Path | None, typer.Option("--rerun", help="Also write a Rerun recording (.rrd) here.")
    ] = None,
    calibration: CalibrationOption = None,
    config: ConfigOption = None,
) -> None:
    """Run SLAM/odometry on a log: trajectory (TUM, KITTI), maps, metrics and config."""
    cfg = effective_config(config, radar_loss, camera_noise, haze, calibration)
    from smokyslam.frontends.readers.registry import open_log
    from smokyslam.pipelines.run import run_log
    from smokyslam.progress import progress_bar

    duration_s = open_log(log, cfg).summary().duration_s
    with progress_bar(f"{odometry} on {log.name}", duration_s) as update:
        result = run_log(
            log, odometry, cfg, out, on_progress=lambda t, s: update(t, status=s), rerun_path=rerun
        )
    typer.echo(_summary_line(result.metrics))
    typer.echo(f"wrote {result.out_dir}/")


def _summary_line(metrics: dict) -> str:
    parts = []
    trajectory = metrics.get("trajectory")
    if trajectory:
        parts.append(
            f"ATE {trajectory['ate_rmse_m']:.3f} m ({trajectory['ate_alignment']}, "
            f"{trajectory['drift_pct']:.2f}% of {trajectory['path_length_m']:.1f} m), "
            f"lost {trajectory['lost_frames']}/{trajectory['frames']} frames"
        )
    for name, scores in metrics.get("maps", {}).items():
        parts.append(f"{name} error index {scores['error_index']:.3f}")
    if metrics.get("realtime_factor"):
        parts.append(f"{metrics['realtime_factor']:.1f}x real time")
    return "; ".join(parts)


@app.command()
def demo(
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")] = Path("demo_output"),
    duration: Annotated[float, typer.Option(min=10.0, help="Seconds of walking.")] = 60.0,
    config: ConfigOption = None,
) -> None:
    """Simulate a smoky office, run SLAM on it, and write every output under --out."""
    from smokyslam.pipelines.demo import run_demo
    from smokyslam.progress import console

    result = run_demo(out, effective_config(config), duration, on_step=console.log)
    sim = result.simulation
    typer.echo(
        f"log:            {sim.log_path} ({sim.duration_s:.0f} s, {sim.wall_s:.1f} s to make)"
    )
    typer.echo(f"map on truth:   {result.mapping_dir}/maps/radar_sparse_vs_truth.png")
    for run_result in result.runs:
        typer.echo(f"{run_result.source + ':':15s} {run_result.out_dir}/")
        typer.echo(f"{'':15s} {_summary_line(run_result.metrics)}")
    typer.echo(f"everything is under {out}/")


@app.command()
def bench(
    out: Annotated[Path, typer.Option("--out", "-o", help="JSON file for the numbers.")] = Path(
        "bench.json"
    ),
    config: ConfigOption = None,
) -> None:
    """Measure speed and memory (ray casting, simulation, rendering, mapping) into JSON."""
    import tempfile

    from smokyslam.benchmarks.suite import run_benchmarks
    from smokyslam.progress import console

    with tempfile.TemporaryDirectory(prefix="smokyslam-bench-") as workdir:
        results = run_benchmarks(
            Path(workdir), effective_config(config), on_step=lambda s: console.log(s)
        )
    out.write_text(json.dumps(results, indent=2) + "\n")
    for key, value in results.items():
        typer.echo(f"{key:32s} {value:12.2f}")
    typer.echo(f"wrote {out}")


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
