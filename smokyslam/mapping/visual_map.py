"""The visual map: camera keyframe landmarks, metric, flattened on the trajectory's poses.

At each camera keyframe the camera's inlier landmarks are moved into the camera frame (which
undoes the camera odometry's own drift), scaled to metres and kept in base_link with their
stamp. They are placed in the world with the base pose at that stamp only when the map is
drawn, so a loop closure that moved the poses moves the map with them; then they are
flattened (height band, >= N points per cell, free space from the cameras).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from smokyslam.config import MappingConfig
from smokyslam.geometry import interpolate_se2, se2_compose, se3_inverse, transform_points_2d
from smokyslam.mapping.flatten import flatten_points
from smokyslam.mapping.grid import OccupancyGrid, get_occupancy_grid
from smokyslam.mapping.visual_cleaning import clean_point_indices


@dataclass
class VisualKeyframes:
    """Camera keyframe landmarks in base_link, metres, by stamp.

    T_base_camera: (4, 4) camera mount (optical axes). stamps_s: per keyframe.
    points_base: per keyframe, (M, 3) points in base_link at that stamp (z up from the floor).
    camera_trust: per keyframe, the camera's trust in [0, 1] from its measured smoke
    (``fusion/trust.py``).
    """

    T_base_camera: np.ndarray
    stamps_s: list[float] = field(default_factory=list)
    points_base: list[np.ndarray] = field(default_factory=list)
    camera_trust: list[float] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.stamps_s)

    def add(
        self,
        stamp_s: float,
        T_world_camera: np.ndarray,
        landmarks_world: np.ndarray,
        metres_per_unit: float,
        camera_trust: float,
    ) -> None:
        """Keep one camera keyframe's landmarks: (M, 3) points in the camera odometry's world
        (its units), seen from ``T_world_camera`` (4, 4, optical axes), as metric points in
        base_link; ``metres_per_unit`` is the metric scale of the camera's current map,
        ``camera_trust`` the camera's trust in this keyframe."""
        landmarks = np.asarray(landmarks_world, dtype=float).reshape(-1, 3)
        if len(landmarks) == 0:
            return
        T_camera_world = se3_inverse(T_world_camera)
        points_camera = (landmarks @ T_camera_world[:3, :3].T + T_camera_world[:3, 3]) * (
            metres_per_unit
        )
        R, t = self.T_base_camera[:3, :3], self.T_base_camera[:3, 3]
        self.stamps_s.append(stamp_s)
        self.points_base.append(points_camera @ R.T + t)
        self.camera_trust.append(float(camera_trust))

    def world_points(
        self, stamps_s: np.ndarray, poses_world_base: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every kept point in the world, placed by the (N, 3) base poses at (N,) sorted stamps.

        Returns ``(points_xyz_m (P, 3), camera_xy_m (P, 2), keyframe (P,))``: world points,
        the world position of the camera that saw each one, and the index of its keyframe.
        """
        if not self.stamps_s or len(stamps_s) == 0:
            return np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
        poses = interpolate_se2(stamps_s, poses_world_base, np.asarray(self.stamps_s))
        camera_in_base = self.T_base_camera[:2, 3]
        points, cameras = [], []
        for pose, local in zip(poses, self.points_base, strict=True):  # per keyframe
            world = local.copy()
            world[:, :2] = transform_points_2d(pose, local[:, :2])
            points.append(world)
            camera_xy = se2_compose(pose, np.r_[camera_in_base, 0.0])[:2]
            cameras.append(np.broadcast_to(camera_xy, (len(local), 2)))
        keyframe = np.repeat(np.arange(len(self.points_base)), [len(p) for p in self.points_base])
        return np.concatenate(points), np.concatenate(cameras), keyframe


def visual_map_on_poses(
    visual: VisualKeyframes,
    stamps_s: np.ndarray,
    poses_world_base: np.ndarray,
    config: MappingConfig,
) -> OccupancyGrid:
    """The flattened visual grid of ``visual`` placed on (N, 3) base poses at (N,) stamps."""
    grid = get_occupancy_grid(config)
    points, cameras, _ = visual.world_points(stamps_s, poses_world_base)
    if config.visual_cleaning and len(points):
        kept = clean_point_indices(points, config)
        points, cameras = points[kept], cameras[kept]
    if len(points):
        flatten_points(
            grid,
            points,
            cameras,
            config.flatten_min_height_m,
            config.flatten_max_height_m,
            config.min_points_per_cell,
        )
    return grid
