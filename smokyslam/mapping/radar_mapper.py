"""Radar occupancy mapping: one frame's local grid, and the global grid stitched from keyframes.

Two ways to put a keyframe into the global grid (``MappingConfig.stitch_method``):

- ``raycast`` (default): the scan's rays are cast straight in the world frame.
- ``paper``: the frame's local grid (the paper's Fig. 6, radar at its centre) is rotated about
  its centre by the heading, cell by cell to the nearest cell (the paper's eq. 1), and pasted
  at the radar's cell. Rotating a raster forward leaves holes and shifts cells by up to half
  a cell, which is why it is not the default.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from smokyslam.config import MappingConfig
from smokyslam.geometry import GridSpec, transform_points_2d
from smokyslam.mapping.grid import OccupancyGrid, get_occupancy_grid
from smokyslam.mapping.raycast import raycast
from smokyslam.types import RadarScan

logger = logging.getLogger(__name__)


def scan_rays(scan: RadarScan, max_range_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Planar ray ends of a scan, radar frame: ``(points_xy_m (N, 2), max_range (N,) bool)``.

    Non-finite points are dropped; returns beyond ``max_range_m`` are pulled back onto it and
    flagged, so they clear space without marking an obstacle.
    """
    points = np.asarray(scan.points_xyz_m, dtype=float).reshape(-1, 3)[:, :2]
    points = points[np.all(np.isfinite(points), axis=1)]
    range_m = np.hypot(points[:, 0], points[:, 1])
    beyond = range_m > max_range_m
    points[beyond] *= (max_range_m / range_m[beyond])[:, None]
    return points, beyond


@dataclass
class LocalGrid:
    """One radar frame's grid in the radar frame (the paper's Fig. 6).

    evidence: (S, S) int8 indexed ``[iy, ix]``, S odd: +1 hit, -1 passed, 0 unobserved. The
    radar sits at the centre of cell ``[S // 2, S // 2]``; x forward, y left.
    """

    evidence: np.ndarray
    resolution_m: float

    @property
    def centre(self) -> int:
        """Index (on both axes) of the radar's cell."""
        return self.evidence.shape[0] // 2

    @property
    def spec(self) -> GridSpec:
        """Grid geometry in the radar frame."""
        corner = -(self.centre + 0.5) * self.resolution_m
        return GridSpec((corner, corner), self.resolution_m, self.evidence.shape)

    def to_cells(self) -> np.ndarray:
        """(S, S) int8 trinary cells: 100 hit, 0 passed, -1 unobserved."""
        return np.select([self.evidence > 0, self.evidence < 0], [100, 0], -1).astype(np.int8)


def radar_local_grid(
    scan: RadarScan, resolution_m: float, size_m: float, max_range_m: float
) -> LocalGrid:
    """Ray-cast one scan into a square grid of side ``size_m`` centred on the radar."""
    centre = max(1, round(size_m / (2.0 * resolution_m)))
    points, beyond = scan_rays(scan, min(max_range_m, centre * resolution_m))
    ends = np.rint(points / resolution_m).astype(np.int64) + centre
    free, hits = raycast(np.array([centre, centre]), ends, beyond)
    evidence = np.zeros((2 * centre + 1, 2 * centre + 1), dtype=np.int8)
    evidence[free[:, 1], free[:, 0]] = -1
    evidence[hits[:, 1], hits[:, 0]] = 1
    return LocalGrid(evidence, resolution_m)


class RadarGridMapper:
    """Global radar grid stitched from keyframe scans; one verb: :meth:`insert`.

    Which frames are keyframes is not decided here: the pose graph's keyframe gate decides
    (``backends/keyframes.py``), for online maps and for maps built after a run alike.
    """

    def __init__(
        self,
        grid: OccupancyGrid,
        stitch_method: str,
        max_range_m: float,
        local_grid_size_m: float,
    ) -> None:
        if stitch_method not in ("raycast", "paper"):
            raise ValueError(f"unknown stitch method {stitch_method!r}")
        self.grid = grid
        self.stitch_method = stitch_method
        self.max_range_m = max_range_m
        self.local_grid_size_m = local_grid_size_m

    def insert(self, scan: RadarScan, pose_world_radar: np.ndarray) -> bool:
        """Stitch ``scan`` (points in the levelled radar frame) at ``pose_world_radar``
        [x_m, y_m, yaw_rad]; returns whether it had points to stitch."""
        if len(scan) == 0:
            return False
        pose = np.asarray(pose_world_radar, dtype=float)
        if self.stitch_method == "paper":
            self._stitch_rotated_local_grid(scan, pose)
        else:
            points, beyond = scan_rays(scan, self.max_range_m)
            ends = self.grid.cells_of(transform_points_2d(pose, points))
            self.grid.insert_rays(self.grid.cells_of(pose[:2])[0], ends, beyond)
        return True

    def restart(self) -> None:
        """Start again from an empty grid (same settings), e.g. to re-render on new poses."""
        self.grid = self.grid.empty_like()

    def _stitch_rotated_local_grid(self, scan: RadarScan, pose: np.ndarray) -> None:
        local = radar_local_grid(
            scan, self.grid.resolution_m, self.local_grid_size_m, self.max_range_m
        )
        iy, ix = np.nonzero(local.evidence)
        offsets = np.stack([ix - local.centre, iy - local.centre], axis=1).astype(float)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        rotated = np.rint(offsets @ np.array([[c, s], [-s, c]])).astype(np.int64)  # eq. 1
        cells = rotated + self.grid.cells_of(pose[:2])[0]
        hit = local.evidence[iy, ix] > 0
        self.grid.update(cells[~hit], cells[hit])


def get_radar_mapper(config: MappingConfig) -> RadarGridMapper:
    """A radar mapper with an empty grid, both set up from the mapping config."""
    return RadarGridMapper(
        get_occupancy_grid(config),
        stitch_method=config.stitch_method,
        max_range_m=config.max_range_m,
        local_grid_size_m=config.local_grid_size_m,
    )
