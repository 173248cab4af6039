"""The observed ground truth: what an ideal 360-degree lidar records along the true walk."""

from __future__ import annotations

import dataclasses

import numpy as np

from smokyslam.config import LidarConfig
from smokyslam.sim.observed import lidar_poses, observed_truth_cells
from smokyslam.sim.world import box_world

LIDAR = LidarConfig()


def test_the_observed_truth_of_a_box_is_its_visible_walls():
    world = box_world(8.0, 6.0)
    observed = observed_truth_cells(world, world.start_pose[None], LIDAR)
    walls = world.occupied.copy()
    walls[[0, 0, -1, -1], [0, -1, 0, -1]] = False  # corners touch the room only diagonally
    assert np.array_equal(observed == 100, walls)
    assert np.array_equal(observed == 0, ~world.occupied)
    assert np.array_equal(observed == -1, world.occupied & ~walls)


def test_a_partition_hides_what_lies_behind_it_until_the_walk_passes():
    world = box_world(8.0, 6.0)
    occupied = world.occupied.copy()
    occupied[1:50, 50] = True  # a partition at x = 4.9 m, open at the top (y > 4.9 m)
    world = dataclasses.replace(world, occupied=occupied)
    left = np.array([[2.0, 1.0, 0.0]])
    observed = observed_truth_cells(world, left, LIDAR)
    # Behind the partition, low down, is a shadow the lidar never saw ...
    assert (observed[2:20, 60:80] == -1).all()
    # ... its near face is seen, its far face is not.
    assert (observed[5:40, 50] == 100).all()
    assert (observed[5:40, 51] == -1).all()
    # Walking round the partition sees the whole room.
    walk = np.array([[2.0, 1.0, 0.0], [4.5, 5.5, 0.0], [7.0, 1.0, 0.0]])
    whole = observed_truth_cells(world, walk, LIDAR)
    assert (whole[1:-1, 1:-1] != -1).sum() == (observed.shape[0] - 2) * (observed.shape[1] - 2)
    assert np.array_equal(whole[1:-1, 1:-1] == 100, occupied[1:-1, 1:-1])


def test_range_limits_what_is_seen():
    world = box_world(30.0, 4.0)
    near = LIDAR.model_copy(update={"max_range_m": 5.0})
    observed = observed_truth_cells(world, np.array([[2.0, 2.0, 0.0]]), near)
    seen_x = world.spec.origin_xy_m[0] + (np.nonzero((observed != -1).any(axis=0))[0] + 0.5) * 0.1
    assert seen_x.max() < 7.1 and seen_x.max() > 6.5


def test_scans_are_taken_every_half_metre_or_turn():
    path = np.column_stack([np.linspace(0, 10, 1001), np.zeros(1001), np.zeros(1001)])
    poses = lidar_poses(path, 0.5, 0.4)
    assert len(poses) == 21 and np.allclose(np.diff(poses[:, 0]), 0.5)
    spin = np.column_stack([np.zeros(100), np.zeros(100), np.linspace(0, 3.0, 100)])
    assert len(lidar_poses(spin, 0.5, 0.4)) == 8
