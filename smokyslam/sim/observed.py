"""The observed ground truth: what a 360° 2D lidar records while walking the true path.

The paper scored its maps against the map a virtual lidar robot recorded while roaming the
building (its Fig. 13), and milliMap scores against lidar maps of the same walk: a map cannot
know rooms the walk never saw, so scoring against the whole building mostly measures
coverage. Along the true path (a scan every ``spacing_m`` or ``turn_rad``) an ideal lidar
(``beams`` over 360°, ``max_range_m``, no noise) casts exact rays: every cell a beam crosses
and the cell it hits are observed, and take the full truth's value there.
"""

from __future__ import annotations

import numpy as np

from smokyslam.config import LidarConfig
from smokyslam.geometry import se2_between
from smokyslam.sim.raycast2d import RayCaster, directions_from_angles
from smokyslam.sim.world import World

SCANS_PER_BATCH = 8
"""Scans whose rays are traced in one call (bounded memory, few calls)."""

SAMPLES_PER_CELL_INV = 0.25
"""Free-space samples along a beam, as a fraction of a cell."""


def lidar_poses(poses_world_base: np.ndarray, spacing_m: float, turn_rad: float) -> np.ndarray:
    """The (K, 3) poses of (N, 3) sampled path poses where the lidar takes a scan: the first,
    then each one ``spacing_m`` away from or turned ``turn_rad`` from the last scan."""
    kept = [np.asarray(poses_world_base[0], dtype=float)]
    for pose in poses_world_base[1:]:  # sequential by nature: one test per sample
        step = se2_between(kept[-1], pose)
        if np.hypot(step[0], step[1]) >= spacing_m or abs(step[2]) >= turn_rad:
            kept.append(np.asarray(pose, dtype=float))
    return np.array(kept)


def observed_truth_cells(world: World, poses_world_lidar: np.ndarray, config: LidarConfig):
    """(rows, cols) int8 over ``world.spec``: the full truth (100 / 0) where the lidar scans
    from (K, 3) poses observed a cell, -1 elsewhere."""
    spec = world.spec
    caster = RayCaster(world)
    angles = np.arange(config.beams) * (2.0 * np.pi / config.beams)
    seen = np.zeros(spec.shape, dtype=bool)
    poses = np.asarray(poses_world_lidar, dtype=float).reshape(-1, 3)
    for start in range(0, len(poses), SCANS_PER_BATCH):
        batch = poses[start : start + SCANS_PER_BATCH]
        origins = np.repeat(batch[:, :2], config.beams, axis=0)
        directions = directions_from_angles((batch[:, 2:3] + angles).ravel())
        hits = caster.cast(origins, directions, config.max_range_m)
        lengths_m = np.where(hits.hit, hits.distance_m, config.max_range_m)
        for cells in (
            _cells_along(origins, directions, lengths_m, spec.resolution_m),
            hits.cells_ixy[hits.hit],
        ):
            cells = spec.cells_of(cells) if cells.dtype.kind == "f" else cells
            cells = cells[spec.inside(cells)]
            seen[cells[:, 1], cells[:, 0]] = True
    return np.where(seen, world.ground_truth_cells(), -1).astype(np.int8)


def _cells_along(
    origins_xy_m: np.ndarray, directions_xy: np.ndarray, lengths_m: np.ndarray, resolution_m
) -> np.ndarray:
    """(M, 2) world points every quarter cell along each ray, short of its end: the free
    space a beam crossed (denser than one line per cell, so no cell it grazes is skipped)."""
    step_m = SAMPLES_PER_CELL_INV * resolution_m
    counts = np.maximum(np.ceil(lengths_m / step_m).astype(np.int64) - 1, 0)
    ray = np.repeat(np.arange(len(counts)), counts)
    first = np.cumsum(counts) - counts
    along_m = (np.arange(counts.sum()) - np.repeat(first, counts)) * step_m
    return origins_xy_m[ray] + along_m[:, None] * directions_xy[ray]
