"""The simulated building: a 2.5D occupancy world shared by every sensor model."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN, with_implicit_walls


@dataclass
class World:
    """A building as a grid of solid columns.

    occupied: (rows_y, cols_x) bool, True where a wall/furniture column stands (wall_height_m tall).
        Sensors treat every occupied cell as solid; floor-plan unknown cells are occupied too.
    known: (rows_y, cols_x) bool, False where the ground truth is unknown (outside the building,
        or unknown in a floor plan). Ground-truth map cells are 100 / 0 / -1 from these two masks.
    spec: grid geometry (origin, resolution, shape); arrays are indexed [iy, ix].
    start_pose: [x_m, y_m, yaw_rad] where walking paths begin.
    """

    name: str
    occupied: np.ndarray
    known: np.ndarray
    spec: GridSpec
    wall_height_m: float = 2.5
    start_pose: np.ndarray | None = None

    def ground_truth_cells(self) -> np.ndarray:
        """(rows_y, cols_x) int8: 100 occupied, 0 free, -1 unknown.

        Every solid cell that borders free space is occupied, known or not: a robot-built
        floor plan often draws no wall at all (the wall is where free meets unknown), yet the
        sensors hit that edge as they hit a drawn wall.
        """
        cells = np.where(self.occupied, OCCUPIED, FREE).astype(np.int8)
        cells[~self.known] = UNKNOWN  # solid there (``occupied``), so its edge is a wall
        return with_implicit_walls(cells)

    def is_free(self, points_xy: np.ndarray) -> np.ndarray:
        """(N,) bool: points lying in a free, in-bounds cell."""
        cells = self.spec.cells_of(points_xy)
        ok = self.spec.inside(cells)
        free = np.zeros(len(cells), dtype=bool)
        free[ok] = ~self.occupied[cells[ok, 1], cells[ok, 0]]
        return free


def box_world(width_m: float = 8.0, depth_m: float = 6.0, resolution_m: float = 0.1) -> World:
    """A single empty rectangular room with one-cell walls: the smallest world, for tests."""
    cols = round(width_m / resolution_m) + 2
    rows = round(depth_m / resolution_m) + 2
    occupied = np.zeros((rows, cols), dtype=bool)
    occupied[[0, -1], :] = True
    occupied[:, [0, -1]] = True
    spec = GridSpec(
        origin_xy_m=(-resolution_m, -resolution_m), resolution_m=resolution_m, shape=(rows, cols)
    )
    start = np.array([width_m / 2.0, depth_m / 2.0, 0.0])
    return World("box", occupied, np.ones_like(occupied), spec, start_pose=start)
