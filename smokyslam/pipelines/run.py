"""``smokyslam run``: one odometry source over one log, with every output a run leaves.

The table of contents: open the log behind the smoke emulator, run the source, build the maps
on the estimated poses, then write trajectories, maps, metrics and the effective config.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import ConfigError
from smokyslam.evaluation.trajectory_metrics import Alignment
from smokyslam.frontends.readers.base import LogReader
from smokyslam.frontends.readers.registry import config_for_log, open_log
from smokyslam.mapping.build import radar_map_on_poses
from smokyslam.outputs import OutputFolder
from smokyslam.pipelines.camera_only import CameraRun, camera_visual_map, run_camera_odometry
from smokyslam.pipelines.odometry import (
    OdometryRun,
    ProgressCallback,
    anchor_to_ground_truth,
    run_radar_odometry,
    write_odometry_outputs,
)
from smokyslam.pipelines.slam import SlamRun, run_fused_slam, slam_metrics, visual_map
from smokyslam.pipelines.truth_mapping import map_metrics
from smokyslam.smoke import SmokedLog
from smokyslam.types import GroundTruthMap
from smokyslam.viz.rerun_recorder import Recorder, open_recorder

logger = logging.getLogger(__name__)

Estimator = Callable[[LogReader, SmokySlamConfig, ProgressCallback | None], OdometryRun]


def _radar(
    reader: LogReader, config: SmokySlamConfig, on_progress: ProgressCallback | None = None
) -> OdometryRun:
    return run_radar_odometry(reader, config, "radar", on_progress)


def _dead_reckoning(
    reader: LogReader, config: SmokySlamConfig, on_progress: ProgressCallback | None = None
) -> OdometryRun:
    return run_radar_odometry(reader, config, "dead-reckoning", on_progress)


# source -> (estimator, streams the log must have, how its trajectory is aligned for the ATE)
SOURCES: dict[str, tuple[Estimator, tuple[str, ...], Alignment]] = {
    "radar": (_radar, ("radar",), Alignment.SE2),
    "dead-reckoning": (_dead_reckoning, ("radar",), Alignment.SE2),
    "camera": (run_camera_odometry, ("camera_image",), Alignment.SIM2),
    "fused": (run_fused_slam, ("radar",), Alignment.SE2),
}


@dataclass
class RunResult:
    """A finished run: its folder, its metrics (as in metrics.json) and the trajectory."""

    source: str
    out_dir: Path
    metrics: dict[str, Any]
    run: OdometryRun


def run_log(
    log_path: Path | str,
    source: str,
    config: SmokySlamConfig,
    out_dir: Path | str,
    on_progress: ProgressCallback | None = None,
    rerun_path: Path | str | None = None,
) -> RunResult:
    """Run ``source`` over the log at ``log_path`` and write its outputs into ``out_dir``.

    on_progress: (stamp_s, health text) as frames are processed. rerun_path: also write a
    Rerun recording (``.rrd``) of the run there.
    """
    if source not in SOURCES:
        raise ConfigError(f"unknown odometry source '{source}': choose from {', '.join(SOURCES)}")
    estimator, required, alignment = SOURCES[source]
    config = config_for_log(log_path, config)
    started = time.perf_counter()
    with OutputFolder(out_dir) as out:
        out.write_config(config)
        reader = SmokedLog(open_log(log_path, config, require=required), config.smoke)
        run = anchor_to_ground_truth(estimator(reader, config, on_progress))
        gt_map = reader.ground_truth_map()
        write_odometry_outputs(run, out.root, alignment, gt_map)
        _write_maps(out, run, reader, config, gt_map)
        _record(open_recorder(rerun_path), run, reader, gt_map, out)
        wall_s = time.perf_counter() - started
        duration_s = reader.summary().duration_s
        metrics = out.update_metrics(
            {
                "wall_s": wall_s,
                "duration_s": duration_s,
                "realtime_factor": duration_s / wall_s if wall_s > 0 else None,
            }
        )
    logger.info("%s run on %s: %.1f s of log in %.1f s", source, log_path, duration_s, wall_s)
    return RunResult(source, out.root, metrics, run)


def _record(
    recorder: Recorder,
    run: OdometryRun,
    reader: LogReader,
    gt_map: GroundTruthMap | None,
    out: OutputFolder,
) -> None:
    """The run, its maps and the ground truth into a Rerun recording (or nowhere)."""
    recorder.log_ground_truth(gt_map, run.gt_stamps_s, run.gt_poses_world_base)
    recorder.log_trajectory(
        run.source, run.stamps_s, run.poses_world_base, run.scans, reader.extrinsics()
    )
    for name, (cells, spec) in out.maps.items():
        recorder.log_map(name, cells, spec)
    recorder.close()


def _write_maps(
    out: OutputFolder,
    run: OdometryRun,
    reader: LogReader,
    config: SmokySlamConfig,
    gt_map: GroundTruthMap | None,
) -> None:
    """``maps/radar_sparse`` from the run's radar poses; scored when there is a true map."""
    if isinstance(run, CameraRun):
        _write_camera_map(out, run, reader, config, gt_map)
    if not run.scans:
        return
    grid = radar_map_on_poses(run.scans, run.poses_world_base, reader.extrinsics(), config.mapping)
    cells = grid.to_cells()
    out.write_map("radar_sparse", cells, grid.spec, gt_map, run.poses_world_base[:, :2])
    if gt_map is not None and run.has_ground_truth:
        out.update_metrics({"maps": {"radar_sparse": map_metrics(cells, grid.spec, gt_map)}})
    if isinstance(run, SlamRun):
        _write_slam_outputs(out, run, config, gt_map)


def _write_camera_map(
    out: OutputFolder,
    run: CameraRun,
    reader: LogReader,
    config: SmokySlamConfig,
    gt_map: GroundTruthMap | None,
) -> None:
    """``maps/visual`` of a camera-only run (metric through the Sim(2) alignment)."""
    grid, scale = camera_visual_map(run, reader.extrinsics().T_base_camera, config)
    out.update_metrics(
        {"odometry": {"reinitializations": run.reinitializations, "visual_map_scale": scale}}
    )
    if grid is None:
        return
    cells = grid.to_cells()
    out.write_map("visual", cells, grid.spec, gt_map)
    if gt_map is not None and run.has_ground_truth:
        out.update_metrics({"maps": {"visual": map_metrics(cells, grid.spec, gt_map)}})


def _write_slam_outputs(
    out: OutputFolder, run: SlamRun, config: SmokySlamConfig, gt_map: GroundTruthMap | None
) -> None:
    """``maps/visual`` on the fused poses (scored with a true map) and the graph's numbers."""
    out.update_metrics(slam_metrics(run))
    grid = visual_map(run, config)
    if grid is None:
        return
    cells = grid.to_cells()
    out.write_map("visual", cells, grid.spec, gt_map, run.poses_world_base[:, :2])
    if gt_map is not None and run.has_ground_truth:
        out.update_metrics({"maps": {"visual": map_metrics(cells, grid.spec, gt_map)}})
