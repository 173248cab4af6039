"""Radar-only odometry over a whole log, and the files a run leaves behind.

``run_radar_odometry`` is the estimator loop (no files); ``write_odometry_outputs`` writes
``trajectory.tum``, ``trajectory_kitti.txt``, ``ground_truth.tum``, ``metrics.json`` and
``trajectory.png`` into an output folder.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field
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
from smokyslam.types import GroundTruthMap, GroundTruthPose, ImuSample, Odometry, RadarScan

logger = logging.getLogger(__name__)

RadarSource = Literal["radar", "dead-reckoning"]


@dataclass
class OdometryRun:
    """What one odometry source produced over a log.

    stamps_s: (N,) per processed radar frame. poses_world_sensor / poses_world_base: (N, 3)
    in the odometry's world frame. gt_stamps_s (M,), gt_poses_world_base (M, 3): the log's
    ground truth, empty when it has none. frames_per_s: estimator throughput (reading and
    emulation excluded).
    """

    source: str
    stamps_s: np.ndarray
    poses_world_sensor: np.ndarray
    poses_world_base: np.ndarray
    odometry: list[Odometry]
    gt_stamps_s: np.ndarray
    gt_poses_world_base: np.ndarray
    frames_per_s: float
    extra: dict[str, float] = field(default_factory=dict)

    @property
    def lost(self) -> np.ndarray:
        """(N,) bool: frames the source could not measure."""
        return np.array([o.health.lost for o in self.odometry], dtype=bool)

    @property
    def has_ground_truth(self) -> bool:
        return len(self.gt_stamps_s) >= 2


def run_radar_odometry(
    reader: LogReader, config: SmokySlamConfig, source: RadarSource = "radar"
) -> OdometryRun:
    """Run radar odometry (``radar``: prior + scan matching) or the Doppler/gyro baseline
    (``dead-reckoning``) over every radar frame of ``reader``."""
    estimator = (
        DeadReckoning(config.radar_odometry)
        if source == "dead-reckoning"
        else RadarOdometry(config.radar_odometry)
    )
    imu: list[ImuSample] = []
    outputs: list[Odometry] = []
    gt_stamps, gt_poses = [], []
    busy_s = 0.0
    for frame in reader.frames():
        if isinstance(frame, ImuSample):
            imu.append(frame)
        elif isinstance(frame, RadarScan):
            start = time.perf_counter()
            outputs.extend(estimator.register(frame, imu))
            busy_s += time.perf_counter() - start
            imu = []
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
        poses_world_sensor=poses_sensor,
        poses_world_base=poses_world_base(poses_sensor, reader.extrinsics().T_base_radar),
        odometry=outputs,
        gt_stamps_s=np.asarray(gt_stamps, dtype=float)[order],
        gt_poses_world_base=np.asarray(gt_poses, dtype=float).reshape(-1, 3)[order],
        frames_per_s=len(outputs) / busy_s if busy_s > 0 else float("nan"),
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
    ``out_dir``; return the metrics dictionary (``trajectory`` only with ground truth)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
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
    metrics = _json_safe(metrics)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, allow_nan=False) + "\n")
    from smokyslam.evaluation.trajectory_plot import plot_trajectory

    plot_trajectory(out / "trajectory.png", run, aligned, alignment, gt_map)
    return metrics


def _json_safe(value: object) -> object:
    """NaN and infinities become null, so metrics.json stays strict JSON."""
    if isinstance(value, dict):
        return {key: _json_safe(item) for key, item in value.items()}
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value
