"""Visual point flattening: the 3-point threshold, the height band, free space, big clouds."""

from __future__ import annotations

import numpy as np

from smokyslam.config import MappingConfig
from smokyslam.mapping.flatten import flatten_points, occupied_cells_from_points
from smokyslam.mapping.grid import OccupancyGrid, get_occupancy_grid


def _cell_value(grid: OccupancyGrid, xy_m) -> int:
    ix, iy = grid.spec.cells_of(np.array([xy_m], dtype=float))[0]
    return int(grid.to_cells()[iy, ix])


def test_threshold_is_exact_at_two_versus_three_points():
    points = np.array(
        [
            [1.01, 1.01, 1.0],  # cell (10, 10): three points
            [1.05, 1.02, 0.5],
            [1.09, 1.08, 1.9],
            [2.01, 1.01, 1.0],  # cell (20, 10): two points
            [2.05, 1.05, 1.0],
            [3.01, 1.01, 1.0],  # cell (30, 10): two in the band, one below, one above
            [3.02, 1.02, 1.0],
            [3.03, 1.03, 0.1],
            [3.04, 1.04, 2.1],
        ]
    )
    cells, counts = occupied_cells_from_points(points, 0.1, 0.2, 2.0, 3)
    assert cells.tolist() == [[10, 10]] and counts.tolist() == [3]
    cells, counts = occupied_cells_from_points(points, 0.1, 0.2, 2.0, 2)
    assert sorted(cells.tolist()) == [[10, 10], [20, 10], [30, 10]]
    cells, _ = occupied_cells_from_points(points, 0.1, 0.0, 2.5, 4)
    assert cells.tolist() == [[30, 10]]  # the widened band lets all four count


def test_flatten_marks_obstacles_and_free_space_from_the_camera():
    rng = np.random.default_rng(0)
    wall_y = rng.uniform(-1.0, 1.0, 3000)  # a wall at x = 3 m seen from (0, 0)
    points = np.column_stack([np.full(3000, 3.02), wall_y, rng.uniform(0.3, 1.8, 3000)])
    grid = get_occupancy_grid(MappingConfig())
    occupied = flatten_points(grid, points, np.array([0.0, 0.0]))
    assert set(occupied[:, 0].tolist()) == {30}
    assert len(occupied) == 20  # y from -1 to 1 m in 0.1 m cells
    assert _cell_value(grid, [3.05, 0.05]) == 100
    assert _cell_value(grid, [1.5, 0.0]) == 0  # decisive: free after one flattening
    assert _cell_value(grid, [2.95, 0.95]) == 0
    assert _cell_value(grid, [3.5, 0.0]) == -1  # behind the wall
    assert _cell_value(grid, [1.0, 2.0]) == -1  # outside the view


def test_per_point_cameras_cast_from_where_each_point_was_seen():
    wall = np.column_stack([np.full(40, 2.02), np.repeat(np.linspace(-0.95, 0.95, 20), 2)])
    points = np.column_stack([np.tile(wall, (2, 1)), np.full(80, 1.0)])
    cameras = np.concatenate([np.tile([0.0, -3.0], (40, 1)), np.tile([0.0, 3.0], (40, 1))])
    grid = get_occupancy_grid(MappingConfig())
    occupied = flatten_points(grid, points, cameras, min_points_per_cell=3)
    assert len(occupied) == 20  # two points per camera, four per cell in all
    assert _cell_value(grid, [0.5, -2.0]) == 0  # on a ray from the first camera
    assert _cell_value(grid, [0.5, 2.0]) == 0  # on a ray from the second camera
    assert _cell_value(grid, [1.0, 0.0]) == -1  # between the two fans: never seen


def test_a_million_points_flatten():
    rng = np.random.default_rng(1)
    n = 1_000_000
    along = rng.uniform(0.0, 40.0, n)  # the four walls of a 10 m x 10 m room
    side = (along // 10).astype(int)
    s = along % 10
    x = np.select([side == 0, side == 1, side == 2], [s, 10.0, 10.0 - s], 0.0)
    y = np.select([side == 0, side == 1, side == 2], [0.0, s, 10.0], 10.0 - s)
    points = np.column_stack([x + 0.05, y + 0.05, rng.uniform(0.0, 2.5, n)])
    grid = get_occupancy_grid(MappingConfig())
    occupied = flatten_points(grid, points, np.array([5.0, 5.0]))
    assert 390 <= len(occupied) <= 404
    cells = grid.to_cells()
    assert (cells == 100).sum() == len(occupied)
    assert (cells == 0).sum() > 0.9 * 99 * 99
