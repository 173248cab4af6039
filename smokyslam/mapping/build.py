"""Offline map building from a log's frames: radar scans placed at ground-truth poses.

Poses and scans arrive interleaved and a scan may come before the pose that follows it, so
scans wait in a queue until a later pose has arrived, and are then placed at the pose linearly
interpolated at their stamp (:func:`smokyslam.geometry.interpolate_se2`). At the end of the
stream, and for scans before the first pose, the nearest pose is used if it is within
``max_pose_gap_s``; other scans are dropped (and counted in the log).
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Iterable

import numpy as np

from smokyslam.config import MappingConfig
from smokyslam.geometry import (
    interpolate_se2,
    se2_compose,
    se2_from_matrix,
    se2_inverse,
    transform_points_2d,
)
from smokyslam.mapping.grid import OccupancyGrid
from smokyslam.mapping.radar_mapper import RadarGridMapper, get_radar_mapper
from smokyslam.types import Extrinsics, Frame, GroundTruthPose, RadarScan

logger = logging.getLogger(__name__)


def level_scan(scan: RadarScan, T_base_radar: np.ndarray) -> tuple[RadarScan, np.ndarray]:
    """Express a scan in the radar's levelled frame (radar position and heading, z up).

    Returns the levelled scan and ``pose_base_radar`` [x_m, y_m, yaw_rad]. A tilted or rolled
    radar's points are rotated fully into base_link first, so only the planar part is lost.
    """
    T = np.asarray(T_base_radar, dtype=float)
    pose_base_radar = se2_from_matrix(T)
    points_base = scan.points_xyz_m @ T[:3, :3].T + T[:3, 3]
    levelled = points_base - [0.0, 0.0, T[2, 3]]
    levelled[:, :2] = transform_points_2d(se2_inverse(pose_base_radar), points_base[:, :2])
    out = RadarScan(scan.stamp_s, levelled, scan.intensity, scan.doppler_mps, scan.frame_id)
    return out, pose_base_radar


class _PoseHistory:
    """Time-ordered ground-truth poses, trimmed to what pending scans can still need."""

    def __init__(self) -> None:
        self.stamps_s: deque[float] = deque()
        self.poses: deque[np.ndarray] = deque()

    def add(self, stamp_s: float, pose: np.ndarray) -> None:
        if self.stamps_s and stamp_s <= self.stamps_s[-1]:
            return  # out of order or repeated: interpolation needs increasing stamps
        self.stamps_s.append(stamp_s)
        self.poses.append(np.asarray(pose, dtype=float))

    def pose_at(self, stamp_s: float, max_gap_s: float) -> np.ndarray | None:
        if not self.stamps_s:
            return None
        if not self.stamps_s[0] - max_gap_s <= stamp_s <= self.stamps_s[-1] + max_gap_s:
            return None
        pose = interpolate_se2(np.array(self.stamps_s), np.array(self.poses), stamp_s)
        while len(self.stamps_s) > 1 and self.stamps_s[1] <= stamp_s:
            self.stamps_s.popleft()
            self.poses.popleft()
        return pose


def build_radar_map(
    frames: Iterable[Frame],
    extrinsics: Extrinsics,
    config: MappingConfig,
    mapper: RadarGridMapper | None = None,
) -> OccupancyGrid:
    """The radar grid of a log: every radar scan stitched at its ground-truth pose.

    frames: a reader's ``frames()`` in time order (only RadarScan and GroundTruthPose used).
    extrinsics: ``T_base_radar`` places the radar on base_link. mapper: a mapper to feed (for
    callers that want its keyframes); by default one is made from ``config``.
    """
    mapper = mapper if mapper is not None else get_radar_mapper(config)
    history = _PoseHistory()
    pending: deque[RadarScan] = deque()
    dropped = 0

    def place(scan: RadarScan) -> None:
        nonlocal dropped
        pose_world_base = history.pose_at(scan.stamp_s, config.max_pose_gap_s)
        if pose_world_base is None:
            dropped += 1
            return
        levelled, pose_base_radar = level_scan(scan, extrinsics.T_base_radar)
        mapper.insert(levelled, se2_compose(pose_world_base, pose_base_radar))

    for frame in frames:
        if isinstance(frame, GroundTruthPose):
            history.add(frame.stamp_s, frame.pose_world_base)
            while pending and pending[0].stamp_s <= history.stamps_s[-1]:
                place(pending.popleft())
        elif isinstance(frame, RadarScan):
            if history.stamps_s and frame.stamp_s <= history.stamps_s[-1]:
                place(frame)
            else:
                pending.append(frame)
    while pending:
        place(pending.popleft())
    if dropped:
        logger.warning(
            "%d radar scans had no ground-truth pose within %.2f s and were dropped",
            dropped,
            config.max_pose_gap_s,
        )
    logger.info("radar map: %d keyframes", len(mapper.keyframe_scans))
    return mapper.grid


def radar_map_on_poses(
    scans: Iterable[RadarScan],
    poses_world_base: np.ndarray,
    extrinsics: Extrinsics,
    config: MappingConfig,
) -> OccupancyGrid:
    """The radar grid of scans placed at estimated base_link poses (N, 3), one per scan."""
    mapper = get_radar_mapper(config)
    for scan, pose_world_base in zip(scans, np.asarray(poses_world_base), strict=True):
        levelled, pose_base_radar = level_scan(scan, extrinsics.T_base_radar)
        mapper.insert(levelled, se2_compose(pose_world_base, pose_base_radar))
    return mapper.grid
