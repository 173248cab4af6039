"""Small hand-made worlds, a robot-style floor plan and exact geometry helpers for sim tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN, save_map
from smokyslam.sim.world import World, box_world


def pillar_world() -> World:
    """8 x 6 m room (inner faces x = 0, 8 and y = 0, 6) with a 1 x 1 m pillar at (6, 3)."""
    world = box_world(8.0, 6.0)
    cells = world.spec.cells_of(np.array([[5.55, 2.55], [6.45, 3.45]]))
    world.occupied[cells[0, 1] : cells[1, 1] + 1, cells[0, 0] : cells[1, 0] + 1] = True
    return world


def l_world() -> World:
    """L-shaped corridor: free where x in [0, 12], y in [0, 2.5] or x in [0, 2.5], y in [0, 10]."""
    res = 0.1
    spec = GridSpec(origin_xy_m=(-0.5, -0.5), resolution_m=res, shape=(110, 130))
    centres = spec.centres_of(
        np.stack(np.meshgrid(np.arange(130), np.arange(110)), axis=-1).reshape(-1, 2)
    ).reshape(110, 130, 2)
    x, y = centres[..., 0], centres[..., 1]
    inside = (x > 0) & (y > 0)
    free = inside & (((x < 12) & (y < 2.5)) | ((x < 2.5) & (y < 10)))
    occupied = ~free
    return World("l", occupied, np.ones_like(occupied), spec, start_pose=np.array([1.2, 1.2, 0]))


def symmetric_hall() -> World:
    """16 x 2 m hall (x in [0, 16], y in [0, 2]) that looks the same turned 180 degrees about
    (8, 1): alcoves at x 3-4 (top) and 12-13 (bottom), 6-6.6 (bottom) and 9.4-10 (top). One
    0.4 m pillar at (15.4, 1.4), with no twin near x = 0.6, breaks the symmetry."""
    spec = GridSpec(origin_xy_m=(-0.5, -0.5), resolution_m=0.1, shape=(40, 180))
    centres = spec.centres_of(
        np.stack(np.meshgrid(np.arange(180), np.arange(40)), axis=-1).reshape(-1, 2)
    ).reshape(40, 180, 2)
    x, y = centres[..., 0], centres[..., 1]
    free = (x > 0) & (x < 16) & (y > 0) & (y < 2)
    for (x0, x1), top in (((3.0, 4.0), True), ((6.0, 6.6), False)):
        for (a, b), up in (((x0, x1), top), ((16.0 - x1, 16.0 - x0), not top)):
            free |= (x > a) & (x < b) & ((y >= 2) & (y < 2.8) if up else (y > -0.8) & (y <= 0))
    free &= ~((x > 15.2) & (x < 15.6) & (y > 1.2) & (y < 1.6))
    occupied = ~free
    return World("hall", occupied, np.ones_like(occupied), spec, start_pose=np.array([4, 1, 0]))


def distance_to_occupied(world: World, points_xy: np.ndarray) -> np.ndarray:
    """(N,) exact distance, metres, from each point to the nearest occupied square (0 inside)."""
    cells = np.argwhere(world.occupied)[:, ::-1]
    centres = world.spec.centres_of(cells)
    half = 0.5 * world.spec.resolution_m
    gap = np.maximum(np.abs(points_xy[:, None, :] - centres[None, :, :]) - half, 0.0)
    return np.sqrt((gap**2).sum(axis=-1)).min(axis=1)


def free_poses(world: World, n: int, rng: np.random.Generator, clearance_m: float = 0.5):
    """(n, 3) random poses at least ``clearance_m`` away from every occupied cell."""
    x0, x1, y0, y1 = world.spec.extent_m
    poses = []
    while len(poses) < n:
        p = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
        if distance_to_occupied(world, p[None])[0] > clearance_m:
            poses.append([p[0], p[1], rng.uniform(-np.pi, np.pi)])
    return np.array(poses)


def write_robot_floorplan(
    yaml_path: Path, seed: int = 0, resolution_m: float = 0.05, walls: bool = True
) -> Path:
    """A 12 x 8 m flat as a robot maps it: 1-pixel walls with 15 % missed pixels, speckle,
    unknown outside the walls and an unexplored blob. An interior wall at x = 6 m has a 1 m door
    at y in (2, 3) m. Map origin (-1, -1): the flat spans x in (0, 12), y in (0, 8) m. Without
    ``walls`` nothing is drawn on the outline: free space simply ends at unknown, as in many
    robot-built maps (the interior wall is then a strip of unknown).
    """
    rng = np.random.default_rng(seed)
    rows, cols = round(10.0 / resolution_m), round(14.0 / resolution_m)
    y, x = (np.mgrid[0:rows, 0:cols] + 0.5) * resolution_m - 1.0
    inside = (x > 0.0) & (x < 12.0) & (y > 0.0) & (y < 8.0)
    cells = np.full((rows, cols), UNKNOWN, dtype=np.int8)
    cells[inside] = FREE
    edge = resolution_m
    wall = inside & ((x < edge) | (x > 12.0 - edge) | (y < edge) | (y > 8.0 - edge))
    wall |= inside & (np.abs(x - 6.0) < 0.5 * edge) & ~((y > 2.0) & (y < 3.0))
    if walls:
        cells[wall & (rng.random(wall.shape) > 0.15)] = OCCUPIED
    else:
        cells[wall] = UNKNOWN
    cells[inside & (rng.random(wall.shape) < 0.002)] = OCCUPIED
    cells[(x - 9.0) ** 2 + (y - 6.5) ** 2 < 0.3] = UNKNOWN
    return save_map(yaml_path, cells, GridSpec((-1.0, -1.0), resolution_m, cells.shape))
