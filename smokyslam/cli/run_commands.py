"""Commands that run estimators: run, compare, demo, bench."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from smokyslam.cli.options import (
    CalibrationOption,
    CameraCfgOption,
    CameraNoiseOption,
    CameraOption,
    ConfigOption,
    DurationOption,
    HazeOption,
    LiveOption,
    OverwriteOption,
    RadarCfgOption,
    RadarCliOption,
    RadarDataOption,
    RadarLossOption,
    RerunOption,
    RerunSpawnOption,
    SmokeOption,
    check_live,
    check_rerun,
    echo_recording,
    effective_config,
    smoke_overrides,
    summary_line,
)
from smokyslam.errors import ConfigError


def run(
    log: Annotated[
        Path | None,
        typer.Argument(help="A .bag, .mcap, .db3 or CARMEN .log/.clf(.gz) log (none with --live)."),
    ] = None,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Output folder.")] = None,
    odometry: Annotated[
        str, typer.Option(help="Odometry source: fused, radar, camera or dead-reckoning.")
    ] = "fused",
    smoke: SmokeOption = None,
    radar_loss: RadarLossOption = None,
    camera_noise: CameraNoiseOption = None,
    haze: HazeOption = None,
    rerun: RerunOption = None,
    rerun_spawn: RerunSpawnOption = False,
    calibration: CalibrationOption = None,
    live: LiveOption = False,
    radar_cli: RadarCliOption = None,
    radar_data: RadarDataOption = None,
    radar_cfg: RadarCfgOption = None,
    duration: DurationOption = None,
    camera: CameraOption = None,
    camera_cfg: CameraCfgOption = None,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Run SLAM/odometry on a log, or live on a TI radar: trajectory (TUM, KITTI), maps,
    metrics and config."""
    cfg = effective_config(
        config, smoke_overrides(smoke, radar_loss, camera_noise, haze), calibration
    )
    if out is None:
        raise ConfigError("--out is required")
    check_live(live, log, radar_cli, radar_data, radar_cfg)
    check_rerun(rerun, rerun_spawn)
    from smokyslam.pipelines.sources import get_source
    from smokyslam.progress import progress_bar

    get_source(odometry)
    if live:
        from smokyslam.pipelines.live import run_live

        with progress_bar(f"{odometry} live", duration or 0.0) as update:
            result = run_live(
                radar_cli,
                radar_data,
                radar_cfg,
                odometry,
                cfg,
                out,
                duration,
                on_progress=lambda t, s: update(t, status=s),
                rerun_path=rerun,
                rerun_spawn=rerun_spawn,
                overwrite=overwrite,
                camera=camera,
                camera_cfg=camera_cfg,
            )
    else:
        from smokyslam.frontends.readers.registry import open_log
        from smokyslam.pipelines.run import run_log

        duration_s = open_log(log, cfg).summary().duration_s
        with progress_bar(f"{odometry} on {log.name}", duration_s) as update:
            result = run_log(
                log,
                odometry,
                cfg,
                out,
                on_progress=lambda t, s: update(t, status=s),
                rerun_path=rerun,
                overwrite=overwrite,
                rerun_spawn=rerun_spawn,
            )
    typer.echo(summary_line(result.metrics))
    typer.echo(f"wrote {result.out_dir}/")
    echo_recording(rerun)


def compare(
    log: Annotated[Path, typer.Argument(help="A log with ground truth (e.g. a simulation).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    sources: Annotated[
        str, typer.Option(help="Comma-separated sources: camera, radar, dead-reckoning, fused.")
    ] = "camera,radar,dead-reckoning,fused",
    smoke: Annotated[
        str,
        typer.Option(help="Comma-separated smoke levels R:C[:H] (radar loss, camera noise, haze)."),
    ] = "0:0,0.1:0.2,0.2:0.4",
    haze: Annotated[
        str | None,
        typer.Option(help="Comma-separated haze densities B (1/m): each smoke level runs again."),
    ] = None,
    jobs: Annotated[
        int | None,
        typer.Option("--jobs", "-j", min=1, help="Parallel runs (default: 2, or 1 on one core)."),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(help="Run on this Dask scheduler (e.g. tcp://host:8786), not a local one."),
    ] = None,
    rerun: RerunOption = None,
    rerun_spawn: RerunSpawnOption = False,
    calibration: CalibrationOption = None,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Run odometry sources at several smoke levels: run folders, a table and plots."""
    cfg = effective_config(config, calibration=calibration)
    check_rerun(rerun, rerun_spawn)
    from smokyslam.pipelines.compare import compare as run_compare
    from smokyslam.pipelines.compare import parse_smoke_levels, parse_sources
    from smokyslam.progress import progress_bar

    source_list, levels = parse_sources(sources), parse_smoke_levels(smoke, haze)
    total = len(source_list) * len(levels)
    with progress_bar(f"comparing {total} runs", total, unit="items") as update:
        result = run_compare(
            log,
            source_list,
            levels,
            cfg,
            out,
            jobs,
            on_progress=update,
            overwrite=overwrite,
            rerun_path=rerun,
            rerun_spawn=rerun_spawn,
            scheduler=scheduler,
        )
    typer.echo(result.markdown_path.read_text(), nl=False)
    typer.echo(f"wrote {result.out_dir}/ ({total} runs in {result.wall_s:.1f} s)")
    echo_recording(rerun)
    if result.failed:
        typer.echo(f"error: {len(result.failed)} of {total} runs failed", err=True)
        raise typer.Exit(1)


def demo(
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")] = Path("demo_output"),
    duration: Annotated[float, typer.Option(min=10.0, help="Seconds of walking.")] = 60.0,
    smoke: SmokeOption = None,
    radar_loss: RadarLossOption = None,
    camera_noise: CameraNoiseOption = None,
    haze: HazeOption = None,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Simulate a smoky office, run SLAM on it, and write every output under --out."""
    from smokyslam.pipelines.demo import DEMO_SMOKE, run_demo
    from smokyslam.progress import console
    from smokyslam.smoke import SmokeLevel

    values = {
        "radar_loss": DEMO_SMOKE.radar_loss,
        "camera_noise": DEMO_SMOKE.camera_noise,
        "haze": DEMO_SMOKE.haze,
    }
    values.update(smoke_overrides(smoke, radar_loss, camera_noise, haze))
    level = SmokeLevel.from_values(**values)
    result = run_demo(
        out, effective_config(config), duration, console.log, level, overwrite=overwrite
    )
    sim = result.simulation
    typer.echo(
        f"log:            {sim.log_path} ({sim.duration_s:.0f} s, {sim.wall_s:.1f} s to make)"
    )
    typer.echo(f"map on truth:   {result.mapping_dir}/maps/radar_sparse_vs_truth.png")
    for run_result in result.runs:
        typer.echo(f"{run_result.source + ':':15s} {run_result.out_dir}/")
        typer.echo(f"{'':15s} {summary_line(run_result.metrics)}")
    typer.echo(f"summary:        {result.summary} (every path: {out}/trajectories.png)")
    typer.echo(f"recording:      {result.recording} (open it: smokyslam view {result.recording})")
    typer.echo(f"everything is under {out}/")


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


def view(
    path: Annotated[
        Path, typer.Argument(help="A .rrd recording, or a folder holding one (e.g. a run).")
    ],
) -> None:
    """Open a Rerun recording in the Rerun viewer (needs a display)."""
    from smokyslam.viz.viewer import find_recording
    from smokyslam.viz.viewer import view as open_viewer

    recording = open_viewer(find_recording(path))
    typer.echo(f"closed {recording}")


def sweep(
    sweep_file: Annotated[
        Path, typer.Argument(help="A sweep YAML: worlds, smoke levels, sources, configs.")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder (shared by workers).")],
    scheduler: Annotated[
        str | None,
        typer.Option(help="Address of a running Dask scheduler (default: a local cluster)."),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(min=1, help="Workers of the local cluster (default: one per core)."),
    ] = None,
    config: ConfigOption = None,
) -> None:
    """Run many (world, smoke, source, config) combinations on Dask: sweep.csv, summary.md
    and plots in --out; finished runs are kept when a sweep is run again."""
    cfg = effective_config(config)
    from smokyslam.outputs import writable_folder
    from smokyslam.pipelines.sweep import sweep as run_sweep
    from smokyslam.progress import console, progress_bar

    writable_folder(out)
    with progress_bar(f"sweep {sweep_file.name}", 0, unit="tasks") as update:
        result = run_sweep(
            sweep_file,
            out,
            cfg,
            scheduler,
            workers,
            on_progress=update,
            on_dashboard=lambda link: console.print(f"dask dashboard: {link}", markup=False),
        )
    typer.echo((result.out_dir / "summary.md").read_text(), nl=False)
    total = len(result.rows)
    typer.echo(
        f"wrote {result.out_dir}/sweep.csv ({total} runs, {result.skipped} already finished, "
        f"{result.wall_s:.1f} s)"
    )
    if result.failed:
        typer.echo(f"error: {len(result.failed)} of {total} runs failed", err=True)
        raise typer.Exit(1)
