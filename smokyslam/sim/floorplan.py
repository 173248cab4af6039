"""Simulation worlds from floor plans: map_server YAML + PGM/PNG, including real robot-built maps.

Occupied cells become wall columns of ``config.wall_height_m``. Unknown cells are treated as
solid (``occupied=True``, ``known=False``): a sensor cannot see past the edge of what the map
knows. The ground truth reports them as unknown (-1), except where they border free space:
there the edge is a wall (``World.ground_truth_cells``).
"""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np
from scipy.ndimage import binary_closing

from smokyslam.config import SimulationConfig
from smokyslam.errors import WorldError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN, load_map
from smokyslam.sim.planner import start_clearance_m
from smokyslam.sim.walk_graph import clearance_map_m
from smokyslam.sim.world import World

logger = logging.getLogger(__name__)

# Robot-built maps draw walls as 1-2 pixel lines with missed hits (grazing laser angles, glass)
# leaving one-cell free gaps. A closing with a 3x3 square seals gaps of one cell (0.1 m), far
# narrower than any doorway (>= 0.7 m), so no real opening is closed.
_GAP_CLOSING = np.ones((3, 3), dtype=bool)


def resample_cells(
    cells: np.ndarray, spec: GridSpec, resolution_m: float
) -> tuple[np.ndarray, GridSpec]:
    """Trinary cells (100/0/-1) and their GridSpec at another resolution (same origin).

    Shrinking keeps a cell occupied if any occupied pixel falls in it, so thin walls survive;
    a cell is unknown if at least half of it is unknown, free otherwise.
    """
    if abs(spec.resolution_m - resolution_m) < 1e-9:
        return cells, spec
    scale = spec.resolution_m / resolution_m
    rows = max(1, round(cells.shape[0] * scale))
    cols = max(1, round(cells.shape[1] * scale))
    method = cv2.INTER_AREA if scale < 1.0 else cv2.INTER_NEAREST

    def fraction(mask: np.ndarray) -> np.ndarray:
        return cv2.resize(mask.astype(np.float32), (cols, rows), interpolation=method)

    occupied = fraction(cells == OCCUPIED) > 1e-3
    unknown = fraction(cells == UNKNOWN) >= 0.5
    out = np.full((rows, cols), FREE, dtype=np.int8)
    out[unknown] = UNKNOWN
    out[occupied] = OCCUPIED
    return out, GridSpec(spec.origin_xy_m, resolution_m, (rows, cols))


def seal_walls(solid: np.ndarray) -> np.ndarray:
    """Close one-cell gaps in walls and make them 4-connected, so rays cannot slip through.

    A diagonal step between two wall cells becomes an L (one of the two corner cells is filled):
    a ray marching cell by cell could otherwise pass between the two diagonal neighbours.
    """
    sealed = solid | binary_closing(solid, structure=_GAP_CLOSING)
    for step in (1, -1):  # main and anti diagonal
        a = sealed[:-1, :-1] if step == 1 else sealed[:-1, 1:]
        b = sealed[1:, 1:] if step == 1 else sealed[1:, :-1]
        side1 = sealed[:-1, 1:] if step == 1 else sealed[:-1, :-1]
        side2 = sealed[1:, :-1] if step == 1 else sealed[1:, 1:]
        leak = a & b & ~side1 & ~side2
        if step == 1:
            sealed[:-1, 1:] |= leak
        else:
            sealed[:-1, :-1] |= leak
    return sealed


def world_from_floorplan(yaml_path: Path | str, config: SimulationConfig) -> World:
    """A World from a map_server floor plan, resampled to ``config.resolution_m``.

    The start pose is the free cell farthest from any wall (yaw 0). Raises MapFileError for an
    unreadable plan and WorldError when no free area is large enough for a walk.
    """
    yaml_path = Path(yaml_path)
    plan = load_map(yaml_path)
    cells, spec = resample_cells(plan.cells, plan.spec, config.resolution_m)
    # One unknown cell all around, so no ray leaves the grid through free floor.
    cells = np.pad(cells, 1, constant_values=UNKNOWN)
    res = spec.resolution_m
    origin = (spec.origin_xy_m[0] - res, spec.origin_xy_m[1] - res)
    spec = GridSpec(origin, res, cells.shape)
    unknown = cells == UNKNOWN
    occupied = seal_walls((cells == OCCUPIED) | unknown)
    if not (~occupied).any():
        raise WorldError(f"floor plan {yaml_path} has no free cells")
    world = World(yaml_path.stem, occupied, ~unknown, spec, config.wall_height_m)
    clearance = clearance_map_m(world)
    needed = start_clearance_m(config.trajectory, res)
    iy, ix = np.unravel_index(int(np.argmax(clearance)), clearance.shape)
    if clearance[iy, ix] < needed:
        raise WorldError(
            f"floor plan {yaml_path}: no free area large enough to walk in (the most open spot is "
            f"{clearance[iy, ix]:.2f} m from a wall; a walk needs {needed:.2f} m to turn around)"
        )
    x_m, y_m = spec.centres_of(np.array([[ix, iy]]))[0]
    world.start_pose = np.array([x_m, y_m, 0.0])
    logger.debug("floor plan %s: %s cells, start %s", yaml_path, cells.shape, world.start_pose)
    return world
