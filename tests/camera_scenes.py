"""Rendered camera scenes with known truth, shared by the camera tests."""

import numpy as np

from smokyslam.sim.world import World, box_world

RATE_HZ = 15.0
SPEED_MPS = 0.5


def pillar_room() -> World:
    """8 x 6 m room with three 0.4 m pillars, so the camera sees depth differences."""
    world = box_world(8.0, 6.0)
    for x, y in ((4.0, 3.0), (2.0, 4.5), (6.0, 1.5)):
        ix, iy = world.spec.cells_of(np.array([[x, y]]))[0]
        world.occupied[iy - 2 : iy + 2, ix - 2 : ix + 2] = True
    return world


def ellipse_walk(n_frames: int) -> np.ndarray:
    """(n, 3) camera poses walking an ellipse round the middle pillar, facing along the path.

    0.5 m/s at 15 Hz: the walk turns continuously, about 14-25 deg/s.
    """
    theta = np.linspace(0.0, 2.0 * np.pi, 20001) - np.pi / 2
    x, y = 4.0 + 2.3 * np.cos(theta), 3.0 + 1.6 * np.sin(theta)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    s = SPEED_MPS * np.arange(n_frames) / RATE_HZ
    heading = np.arctan2(1.6 * np.cos(theta), -2.3 * np.sin(theta))
    return np.column_stack(
        [np.interp(s, arc, x), np.interp(s, arc, y), np.interp(s, arc, np.unwrap(heading))]
    )
