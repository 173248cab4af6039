"""Online maps: grids that grow as the run goes, follow the pose graph, and can be read at any
moment.

- ``radar_sparse``: each backend keyframe's levelled radar scan is stitched at the keyframe's
  estimate as soon as the keyframe exists. The scans are kept; when the graph has moved a
  drawn keyframe by more than ``remap_translation_m`` / ``remap_rotation_rad`` (a loop
  closure), the grid is drawn again from the kept scans on the corrected poses. The check runs
  when the grid is read, so a burst of closures costs one redraw.
- ``visual``: camera keyframe landmarks, kept in base_link and flattened on the trajectory's
  current poses whenever the grid is read.

:meth:`OnlineMaps.maps` returns a snapshot of every grid (copies later updates leave alone);
:meth:`OnlineMaps.render` draws them afresh on the current poses moved by a rigid transform
(e.g. into the ground-truth frame). Both give, cell for cell, the maps a post-hoc build on
the same poses and keyframes gives.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from smokyslam.config import MappingConfig
from smokyslam.geometry import se2_between, se2_compose
from smokyslam.mapping.grid import OccupancyGrid
from smokyslam.mapping.radar_mapper import RadarGridMapper, get_radar_mapper
from smokyslam.mapping.visual_map import VisualKeyframes, visual_map_on_poses
from smokyslam.types import RadarScan

IDENTITY = np.zeros(3)


class PoseSource(Protocol):
    """Where the maps read the current poses: the backend."""

    def keyframe_poses(self) -> np.ndarray:
        """(K, 3) base_link estimate of every keyframe."""
        ...

    def keyframe_pose(self, index: int) -> np.ndarray:
        """(3,) base_link estimate of one keyframe."""
        ...

    def trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        """(N,) stamps and (N, 3) base_link poses of every frame so far."""
        ...


class KeyframeRadarMap:
    """The radar grid of the backend's keyframes, drawn where the graph puts them now."""

    def __init__(
        self,
        mapper: RadarGridMapper,
        pose_base_radar: np.ndarray,
        remap_translation_m: float,
        remap_rotation_rad: float,
    ) -> None:
        self._mapper = mapper
        self._pose_base_radar = np.asarray(pose_base_radar, dtype=float)
        self._remap = (remap_translation_m, remap_rotation_rad)
        self._scans: list[RadarScan] = []
        self._drawn = np.zeros((0, 3))
        self.redraws = 0

    def __len__(self) -> int:
        return len(self._scans)

    def insert(self, scan: RadarScan, pose_world_base: np.ndarray) -> None:
        """The next keyframe's levelled scan, stitched at its base pose now."""
        pose = np.asarray(pose_world_base, dtype=float)
        self._scans.append(scan)
        self._drawn = np.vstack([self._drawn, pose])
        self._mapper.insert(scan, se2_compose(pose, self._pose_base_radar))

    def grid(self, keyframe_poses: np.ndarray) -> OccupancyGrid:
        """The live grid on (K, 3) current keyframe poses (drawn again if any has moved)."""
        poses = np.asarray(keyframe_poses, dtype=float).reshape(-1, 3)[: len(self._scans)]
        moved = se2_between(self._drawn[: len(poses)], poses)
        if len(poses) and (
            np.hypot(moved[:, 0], moved[:, 1]).max() > self._remap[0]
            or np.abs(moved[:, 2]).max() > self._remap[1]
        ):
            self._mapper.restart()
            self._draw(self._mapper, poses)
            self._drawn = poses.copy()
            self.redraws += 1
        return self._mapper.grid

    def render(self, keyframe_poses: np.ndarray) -> OccupancyGrid:
        """A new grid of every kept scan on (K, 3) given keyframe poses (the live one stays)."""
        mapper = RadarGridMapper(
            self._mapper.grid.empty_like(),
            self._mapper.stitch_method,
            self._mapper.max_range_m,
            self._mapper.local_grid_size_m,
        )
        self._draw(mapper, np.asarray(keyframe_poses, dtype=float)[: len(self._scans)])
        return mapper.grid

    def _draw(self, mapper: RadarGridMapper, poses: np.ndarray) -> None:
        radar_poses = se2_compose(poses, self._pose_base_radar).reshape(-1, 3)
        for scan, pose in zip(self._scans, radar_poses, strict=False):  # one call a keyframe
            mapper.insert(scan, pose)


class OnlineMaps:
    """The run's grids. Verbs: :meth:`add_radar_keyframe` per backend keyframe,
    :meth:`add_camera_keyframe` per metric camera keyframe; :meth:`maps` at any moment."""

    def __init__(
        self,
        config: MappingConfig,
        poses: PoseSource,
        pose_base_radar: np.ndarray | None,
        T_base_camera: np.ndarray | None,
    ) -> None:
        """``pose_base_radar``: (3,) levelled radar mount, None for no radar map.
        ``T_base_camera``: (4, 4) camera mount, None for no visual map."""
        self._config = config
        self._poses = poses
        self._radar = None
        if pose_base_radar is not None:
            self._radar = KeyframeRadarMap(
                get_radar_mapper(config),
                pose_base_radar,
                config.remap_translation_m,
                config.remap_rotation_rad,
            )
        self._visual = None if T_base_camera is None else VisualKeyframes(T_base_camera)

    @property
    def radar_redraws(self) -> int:
        """How often the radar grid was drawn again after the graph moved its keyframes."""
        return self._radar.redraws if self._radar is not None else 0

    def add_radar_keyframe(self, index: int, scan: RadarScan) -> None:
        """Backend keyframe ``index`` (they come in order) with its levelled radar scan."""
        if self._radar is not None:
            self._radar.insert(scan, self._poses.keyframe_pose(index))

    def add_camera_keyframe(
        self,
        stamp_s: float,
        T_world_camera: np.ndarray,
        landmarks_world: np.ndarray,
        metres_per_unit: float,
    ) -> None:
        """A camera keyframe's landmarks (camera odometry world and units, see
        :meth:`VisualKeyframes.add`)."""
        if self._visual is not None:
            self._visual.add(stamp_s, T_world_camera, landmarks_world, metres_per_unit)

    def maps(self) -> dict[str, OccupancyGrid]:
        """A snapshot of every grid with content so far, by map name, in the map frame."""
        snapshot = {}
        if self._radar is not None and len(self._radar):
            snapshot["radar_sparse"] = self._radar.grid(self._poses.keyframe_poses()).copy()
        if self._visual is not None and len(self._visual):
            snapshot["visual"] = self._visual_grid(IDENTITY)
        return snapshot

    def render(self, T_target_map: np.ndarray) -> dict[str, OccupancyGrid]:
        """Every grid drawn afresh on the current poses moved by the rigid (3,) transform
        ``T_target_map`` [x_m, y_m, yaw_rad] (e.g. the run's alignment to ground truth)."""
        target = np.asarray(T_target_map, dtype=float)
        grids = {}
        if self._radar is not None and len(self._radar):
            poses = se2_compose(target, self._poses.keyframe_poses()).reshape(-1, 3)
            grids["radar_sparse"] = self._radar.render(poses)
        if self._visual is not None and len(self._visual):
            grids["visual"] = self._visual_grid(target)
        return grids

    def _visual_grid(self, target: np.ndarray) -> OccupancyGrid:
        stamps_s, poses = self._poses.trajectory()
        moved = se2_compose(target, poses).reshape(-1, 3)
        return visual_map_on_poses(self._visual, stamps_s, moved, self._config)
