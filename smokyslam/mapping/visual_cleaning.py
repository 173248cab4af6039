"""Cleaning the visual map's 3D points before flattening (open3d).

The paper found reflective surfaces made its flattened visual points noisy. Two open3d steps,
both optional (``mapping.visual_cleaning``): voxel down-sampling (one point per voxel, so a
surface seen from many keyframes does not outvote the rest of the map) and statistical outlier
removal (points whose mean distance to their neighbours is far above the cloud's, e.g. stray
triangulations through a doorway). Returns indices into the input, so each kept point keeps
the camera that saw it (the free-space rays need it).
"""

from __future__ import annotations

import numpy as np

from smokyslam.config import MappingConfig


def clean_point_indices(points_xyz_m: np.ndarray, config: MappingConfig) -> np.ndarray:
    """(K,) sorted indices of the (N, 3) world points kept by the configured cleaning."""
    points = np.asarray(points_xyz_m, dtype=float).reshape(-1, 3)
    keep = np.arange(len(points))
    if not config.visual_cleaning or len(points) < config.visual_outlier_neighbours + 1:
        return keep
    import open3d as o3d  # heavy; only here

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    if config.visual_voxel_m > 0.0:
        voxel = config.visual_voxel_m
        # Voxels aligned with the world origin, like the grid's cells.
        low = (np.floor(points.min(axis=0) / voxel) - 1.0) * voxel
        high = points.max(axis=0) + voxel
        cloud, _, members = cloud.voxel_down_sample_and_trace(voxel, low, high, False)
        keep = np.array([int(np.asarray(m)[0]) for m in members], dtype=np.int64)
    _, inliers = cloud.remove_statistical_outlier(
        config.visual_outlier_neighbours, config.visual_outlier_std_ratio
    )
    return np.sort(keep[np.asarray(inliers, dtype=np.int64)])
