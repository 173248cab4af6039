"""Odometry over a whole log, and the trajectory files a run leaves behind.

``OdometryRun`` is what any source (radar, dead reckoning, camera, fused) produced;
``run_radar_odometry`` is the radar estimator loop (no files); ``write_odometry_outputs``
writes ``trajectory.tum``, ``trajectory_kitti.txt``, ``ground_truth.tum``, the ``trajectory``
part of ``metrics.json`` and ``trajectory.png`` into an output folder.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np

from smokyslam.config import SmokySlamConfig
from smokyslam.evaluation.trajectory_io import write_kitti, write_tum
from smokyslam.evaluation.trajectory_metrics import (
    Alignment,
    TrajectoryMetrics,
    evaluate_trajectory,
)
from smokyslam.frontends.radar.odometry import DeadReckoning, RadarOdometry, poses_world_base
from smokyslam.frontends.readers.base import LogReader
from smokyslam.geometry import interpolate_se2, se2_compose, se2_inverse
from smokyslam.mapping.build import level_scan
from smokyslam.outputs import OutputFolder
from smokyslam.types import GroundTruthMap, GroundTruthPose, ImuSample, Odometry, RadarScan

logger = logging.getLogger(__name__)

RadarSource = Literal["radar", "dead-reckoning"]

ProgressCallback = Callable[[float, str], None]
"""Called by estimators as they go: (stamp_s of the frame just processed, health text)."""


@dataclass
class OdometryRun:
    """What one odometry source produced over a log.

    stamps_s: (N,) per processed frame. poses_world_base: (N, 3) in the odometry's world
    frame. lost: (N,) bool, frames the source could not measure. gt_stamps_s (M,),
    gt_poses_world_base (M, 3): the log's ground truth, empty when it has none. frames_per_s:
    estimator throughput (reading and emulation excluded). scans / poses_world_radar: the radar
    frames the run used and where it put the radar, for maps (empty for camera-only runs).
    """

    source: str
    stamps_s: np.ndarray
    poses_world_base: np.ndarray
    lost: np.ndarray
    gt_stamps_s: np.ndarray
    gt_poses_world_base: np.ndarray
    frames_per_s: float
    scans: list[RadarScan] = field(default_factory=list)
    poses_world_radar: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    extra: dict[str, float] = field(default_factory=dict)

    @property
    def has_ground_truth(self) -> bool:
        return len(self.gt_stamps_s) >= 2


def run_radar_odometry(
    reader: LogReader,
    config: SmokySlamConfig,
    source: RadarSource = "radar",
    on_progress: ProgressCallback | None = None,
) -> OdometryRun:
    """Run radar odometry (``radar``: prior + scan matching) or the Doppler/gyro baseline
    (``dead-reckoning``) over every radar frame of ``reader``.

    Scans are levelled first (rotated through ``T_base_radar`` into the radar's position and
    heading with z up), so a tilted or upside-down radar turns the same way as the gyro.
    """
    estimator = (
        DeadReckoning(config.radar_odometry)
        if source == "dead-reckoning"
        else RadarOdometry(config.radar_odometry)
    )
    T_base_radar = reader.extrinsics().T_base_radar
    imu: list[ImuSample] = []
    outputs: list[Odometry] = []
    scans: dict[float, RadarScan] = {}
    gt_stamps, gt_poses = [], []
    busy_s = 0.0
    for frame in reader.frames():
        if isinstance(frame, ImuSample):
            imu.append(frame)
        elif isinstance(frame, RadarScan):
            scans[frame.stamp_s] = frame
            start = time.perf_counter()
            finished = estimator.register(level_scan(frame, T_base_radar)[0], imu)
            busy_s += time.perf_counter() - start
            outputs.extend(finished)
            imu = []
            if on_progress is not None and finished:
                health = finished[-1].health
                on_progress(frame.stamp_s, f"radar inliers {health.inliers}")
        elif isinstance(frame, GroundTruthPose):
            gt_stamps.append(frame.stamp_s)
            gt_poses.append(frame.pose_world_base)
    start = time.perf_counter()
    outputs.extend(estimator.flush())
    busy_s += time.perf_counter() - start
    poses_sensor = np.array([o.pose_world_sensor for o in outputs]).reshape(-1, 3)
    order = np.argsort(gt_stamps, kind="stable")
    run = OdometryRun(
        source=source,
        stamps_s=np.array([o.stamp_s for o in outputs]),
        poses_world_base=poses_world_base(poses_sensor, T_base_radar),
        lost=np.array([o.health.lost for o in outputs], dtype=bool),
        gt_stamps_s=np.asarray(gt_stamps, dtype=float)[order],
        gt_poses_world_base=np.asarray(gt_poses, dtype=float).reshape(-1, 3)[order],
        frames_per_s=len(outputs) / busy_s if busy_s > 0 else float("nan"),
        scans=[scans[o.stamp_s] for o in outputs],
        poses_world_radar=poses_sensor,
    )
    logger.info("%s odometry: %d frames at %.0f frames/s", source, len(outputs), run.frames_per_s)
    return run


def evaluate_run(run: OdometryRun, alignment: Alignment | str = Alignment.SE2) -> TrajectoryMetrics:
    """ATE/RPE of the run's base_link poses against its ground truth."""
    return evaluate_trajectory(
        run.stamps_s,
        run.poses_world_base,
        run.gt_stamps_s,
        run.gt_poses_world_base,
        alignment,
        lost=run.lost,
    )


def write_odometry_outputs(
    run: OdometryRun,
    out_dir: Path | str,
    alignment: Alignment | str = Alignment.SE2,
    gt_map: GroundTruthMap | None = None,
) -> dict:
    """Write the run's trajectory files, metrics and plot (over ``gt_map`` when given) into
    ``out_dir``; merge the metrics into ``metrics.json`` (NaN becomes null) and return the
    run's part (``trajectory`` only with ground truth)."""
    folder = OutputFolder(out_dir)
    out = folder.root
    write_tum(out / "trajectory.tum", run.stamps_s, run.poses_world_base)
    write_kitti(out / "trajectory_kitti.txt", run.poses_world_base)
    metrics: dict = {
        "odometry": {
            "source": run.source,
            "frames_per_s": run.frames_per_s,
            "lost_frames": int(run.lost.sum()),
        }
    }
    aligned = None
    if run.has_ground_truth:
        write_tum(out / "ground_truth.tum", run.gt_stamps_s, run.gt_poses_world_base)
        result = evaluate_run(run, alignment)
        metrics["trajectory"] = result.to_dict()
        aligned = result
    folder.update_metrics(metrics)
    from smokyslam.evaluation.trajectory_plot import plot_trajectory

    plot_trajectory(out / "trajectory.png", run, aligned, alignment, gt_map)
    return metrics


def anchor_to_ground_truth(run: OdometryRun) -> OdometryRun:
    """The run moved rigidly so its first pose sits on the ground truth at that stamp.

    Estimators start at the origin of their own world frame; anchoring expresses the whole
    trajectory in the ground-truth frame (as if initialized there), so maps built on it can be
    scored against the true map. A rigid move changes neither ATE nor RPE.
    """
    if not run.has_ground_truth or len(run.stamps_s) == 0:
        return run
    gt_start = interpolate_se2(run.gt_stamps_s, run.gt_poses_world_base, run.stamps_s[0])
    T_truth_odom = se2_compose(gt_start, se2_inverse(run.poses_world_base[0]))
    moved_radar = run.poses_world_radar
    if len(moved_radar):
        moved_radar = se2_compose(T_truth_odom, moved_radar)
    return replace(
        run,
        poses_world_base=se2_compose(T_truth_odom, run.poses_world_base),
        poses_world_radar=moved_radar,
    )
