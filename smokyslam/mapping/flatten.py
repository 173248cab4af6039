"""Visual point flattening: a 3D point cloud becomes a 2D occupancy grid (the paper's Sec. IV).

Points within a height band (above the floor, below the ceiling) are dropped to the floor
plane and counted per cell; a cell with at least ``min_points_per_cell`` points is an obstacle
(the paper's threshold of 3, which also ignores stray triangulations). Free space is ray-cast
from the cameras that saw the points to the obstacle cells. Everything is one pass of sorting
and ray casting, so a million points take about a second.
"""

from __future__ import annotations

import numpy as np

from smokyslam.mapping.grid import OccupancyGrid


def _cell_keys(cells_ixy: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Integer keys of (N, 2) cells (same cell, same key), with the ``(low, width)`` to decode."""
    low = cells_ixy.min(axis=0)
    width = int(cells_ixy[:, 0].max() - low[0]) + 1
    local = cells_ixy - low
    return local[:, 1] * width + local[:, 0], low, width


def _cells_of_keys(keys: np.ndarray, low: np.ndarray, width: int) -> np.ndarray:
    return np.stack([keys % width, keys // width], axis=1) + low


def _in_band(points_xyz_m: np.ndarray, min_height_m: float, max_height_m: float) -> np.ndarray:
    z = points_xyz_m[:, 2]
    return (z >= min_height_m) & (z <= max_height_m) & np.all(np.isfinite(points_xyz_m), axis=1)


def occupied_cells_from_points(
    points_xyz_m: np.ndarray,
    resolution_m: float,
    min_height_m: float = 0.2,
    max_height_m: float = 2.0,
    min_points_per_cell: int = 3,
) -> tuple[np.ndarray, np.ndarray]:
    """Obstacle cells of a world-frame point cloud.

    points_xyz_m: (N, 3) world points, metres (z up). Points with ``min_height_m <= z <=
    max_height_m`` count. Returns ``(cells_ixy (K, 2) int64, counts (K,) int64)``: the world
    cells (aligned with the world origin, side ``resolution_m``) holding at least
    ``min_points_per_cell`` points, and their point counts.
    """
    points = np.asarray(points_xyz_m, dtype=float).reshape(-1, 3)
    points = points[_in_band(points, min_height_m, max_height_m)]
    if len(points) == 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    keys, low, width = _cell_keys(np.floor(points[:, :2] / resolution_m).astype(np.int64))
    unique_keys, counts = np.unique(keys, return_counts=True)
    kept = counts >= min_points_per_cell
    return _cells_of_keys(unique_keys[kept], low, width), counts[kept]


def flatten_points(
    grid: OccupancyGrid,
    points_xyz_m: np.ndarray,
    camera_xy_m: np.ndarray,
    min_height_m: float = 0.2,
    max_height_m: float = 2.0,
    min_points_per_cell: int = 3,
    weight: float = np.inf,
) -> np.ndarray:
    """Flatten a point cloud into ``grid`` as one observation; returns the obstacle cells.

    points_xyz_m: (N, 3) world points. camera_xy_m: (2,) one camera position for all points,
    or (N, 2) the position of the camera that saw each point (world, metres; a third column
    is ignored). Free space: rays from each distinct camera cell to each obstacle cell its
    points fell in. ``weight`` as in :meth:`OccupancyGrid.update`; the default makes the
    flattened cloud decisive (a finished point cloud is one certain observation).
    Returns (K, 2) int64 obstacle world cells ``[ix, iy]``.
    """
    points = np.asarray(points_xyz_m, dtype=float).reshape(-1, 3)
    cameras = np.asarray(camera_xy_m, dtype=float)
    band = _in_band(points, min_height_m, max_height_m)
    occupied, _ = occupied_cells_from_points(
        points[band], grid.resolution_m, min_height_m, max_height_m, min_points_per_cell
    )
    if len(occupied) == 0:
        return occupied
    if cameras.ndim == 1:
        grid.insert_rays(grid.cells_of(cameras[:2])[0], occupied, weight=weight)
        return occupied

    # One ray per distinct (camera cell, obstacle cell) pair among the points that count.
    point_cells = np.floor(points[band, :2] / grid.resolution_m).astype(np.int64)
    camera_cells = grid.cells_of(cameras.reshape(len(points), -1)[band, :2])
    keys, low, width = _cell_keys(np.concatenate([point_cells, camera_cells, occupied]))
    n = len(point_cells)
    point_keys, camera_keys, occupied_keys = keys[:n], keys[n : 2 * n], keys[2 * n :]
    counted = np.isin(point_keys, occupied_keys)
    n_keys = int(keys.max()) + 1
    pairs = np.unique(camera_keys[counted] * n_keys + point_keys[counted])
    origins = _cells_of_keys(pairs // n_keys, low, width)
    ends = _cells_of_keys(pairs % n_keys, low, width)
    grid.insert_rays(origins, ends, weight=weight)
    return occupied
