"""``--odometry camera``: monocular camera odometry alone, honest about its scale.

Camera-only odometry is up to scale: ``trajectory.tum`` is in the odometry's own units and its
ATE is taken after a Sim(2) alignment. The visual map needs metres, so when the log has ground
truth its landmarks are placed on the Sim(2)-aligned trajectory (the scale the alignment
found); without ground truth the map is drawn in odometry units (written in run.log).
The camera body is taken as base_link up to its mounting yaw; the few centimetres of lever
arm cannot be expressed in an unknown scale.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import TopicError
from smokyslam.evaluation.trajectory_metrics import associate, umeyama_2d
from smokyslam.frontends.camera.odometry import CameraOdometry, CameraOdometryResult
from smokyslam.frontends.camera.pose import planar_from_camera
from smokyslam.frontends.readers.base import LogReader
from smokyslam.geometry import se2_compose
from smokyslam.mapping.grid import OccupancyGrid
from smokyslam.pipelines.odometry import OdometryRun, ProgressCallback
from smokyslam.pipelines.visual_map import VisualKeyframes, visual_map_on_poses
from smokyslam.types import CameraFrame, GroundTruthPose

logger = logging.getLogger(__name__)


@dataclass
class CameraRun(OdometryRun):
    """An OdometryRun of the camera, with the keyframe results the visual map is made of."""

    keyframes: list[CameraOdometryResult] = field(default_factory=list)
    reinitializations: int = 0


def run_camera_odometry(
    reader: LogReader, config: SmokySlamConfig, on_progress: ProgressCallback | None = None
) -> CameraRun:
    """Track every camera frame of ``reader``; one pose per frame, lost frames flagged."""
    intrinsics = reader.camera_intrinsics()
    if intrinsics is None:
        raise TopicError(f"{reader.path}: the log has no camera_info, needed for the camera")
    odometry = CameraOdometry(intrinsics, config.camera_odometry)
    yaw_mount = planar_from_camera(reader.extrinsics().T_base_camera)[2]
    stamps, poses, lost, keyframes = [], [], [], []
    gt_stamps, gt_poses = [], []
    busy_s, reinitializations = 0.0, 0
    for frame in reader.frames():
        if isinstance(frame, CameraFrame):
            started = time.perf_counter()
            result = odometry.track(frame)
            busy_s += time.perf_counter() - started
            stamps.append(result.stamp_s)
            poses.append(se2_compose(result.pose_world_camera, np.array([0.0, 0.0, -yaw_mount])))
            lost.append(result.lost)
            reinitializations = result.reinitializations
            if result.is_keyframe and len(result.landmarks_world):
                keyframes.append(result)
            if on_progress is not None:
                on_progress(
                    result.stamp_s, f"camera {result.status.value}, {result.health.tracked} tracks"
                )
        elif isinstance(frame, GroundTruthPose):
            gt_stamps.append(frame.stamp_s)
            gt_poses.append(frame.pose_world_base)
    order = np.argsort(gt_stamps, kind="stable")
    run = CameraRun(
        source="camera",
        stamps_s=np.asarray(stamps, dtype=float),
        poses_world_base=np.asarray(poses, dtype=float).reshape(-1, 3),
        lost=np.asarray(lost, dtype=bool),
        gt_stamps_s=np.asarray(gt_stamps, dtype=float)[order],
        gt_poses_world_base=np.asarray(gt_poses, dtype=float).reshape(-1, 3)[order],
        frames_per_s=len(stamps) / busy_s if busy_s > 0 else float("nan"),
        keyframes=keyframes,
        reinitializations=reinitializations,
    )
    logger.info(
        "camera odometry: %d frames at %.0f frames/s, %d lost, %d restarts",
        len(stamps),
        run.frames_per_s,
        int(run.lost.sum()),
        reinitializations,
    )
    return run


def camera_visual_map(run: CameraRun, T_base_camera: np.ndarray, config: SmokySlamConfig):
    """The flattened visual grid of a camera run, metric when the run has ground truth.

    Returns ``(grid, scale)``; ``grid`` is None when there are no landmarks.
    """
    if not run.keyframes:
        return None, 1.0
    stamps, poses, scale = run.stamps_s, run.poses_world_base, 1.0
    tracked = ~run.lost
    if run.has_ground_truth and tracked.sum() >= 2:
        inside, gt_at = associate(stamps[tracked], run.gt_stamps_s, run.gt_poses_world_base)
        similarity = umeyama_2d(poses[tracked][inside, :2], gt_at[:, :2], with_scale=True)
        scale = similarity.scale
        poses = similarity.apply(poses)
    else:
        logger.warning("camera-only visual map is in odometry units (no ground truth for scale)")
    visual = VisualKeyframes(T_base_camera=T_base_camera)
    for result in run.keyframes:
        visual.add(result, scale)
    grid: OccupancyGrid = visual_map_on_poses(visual, stamps, poses, config.mapping)
    return grid, scale
