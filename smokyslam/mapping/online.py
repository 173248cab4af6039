"""Online maps: grids that grow as the run goes, follow the pose graph, and can be read at any
moment.

- ``radar_sparse``: each backend keyframe's levelled radar scan is stitched at the keyframe's
  estimate as soon as the keyframe exists. The scans are kept; when the graph has moved a
  drawn keyframe by more than ``remap_translation_m`` / ``remap_rotation_rad`` (a loop
  closure), the grid is drawn again from the kept scans on the corrected poses. The check runs
  when the grid is read, so a burst of closures costs one redraw.
- ``visual``: camera keyframe landmarks, kept in base_link and flattened on the trajectory's
  current poses whenever the grid is read.
- ``radar_dense``: the radar grid up-sampled (``upsample/online.py``): refreshed in the
  background during the run (:meth:`OnlineMaps.maps` gives the latest), made afresh from the
  rendered radar grid by :meth:`OnlineMaps.render`.
- ``fused``: the radar map (dense, else sparse) and the visual map fused by the trust index
  measured at the camera keyframes (``fusion/``), whenever both exist and the maps are read.

:meth:`OnlineMaps.maps` returns a snapshot of every grid (copies later updates leave alone);
:meth:`OnlineMaps.render` draws them afresh on the current poses moved by a rigid transform
(e.g. into the ground-truth frame). Both give, cell for cell, the maps a post-hoc build on
the same poses and keyframes gives.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from typing import TYPE_CHECKING, Protocol

import numpy as np

from smokyslam.config import MappingConfig
from smokyslam.errors import UpsamplerError
from smokyslam.fusion.trust import trust_grid
from smokyslam.geometry import GridSpec, se2_between, se2_compose
from smokyslam.mapping.grid import OccupancyGrid
from smokyslam.mapping.radar_mapper import RadarGridMapper, get_radar_mapper
from smokyslam.mapping.visual_map import VisualKeyframes, visual_map_on_poses
from smokyslam.types import RadarScan

if TYPE_CHECKING:
    from smokyslam.fusion.fuse import FusedMap
    from smokyslam.fusion.fuser import MapFuser
    from smokyslam.upsample.infer import DenseMap
    from smokyslam.upsample.online import DenseRefresher

logger = logging.getLogger(__name__)

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
        dense: DenseRefresher | None = None,
        fuser: MapFuser | None = None,
    ) -> None:
        """``pose_base_radar``: (3,) levelled radar mount, None for no radar map.
        ``T_base_camera``: (4, 4) camera mount, None for no visual map. ``dense``: the
        up-sampler of the radar map (``radar_dense``), None for none. ``fuser``: measures the
        visual map's trust and fuses it with the radar map (``fused``), None for none."""
        self._config = config
        self._poses = poses
        self.dense = dense if pose_base_radar is not None else None
        self.fuser = fuser if T_base_camera is not None else None
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
            if self.dense is not None and self.dense.due(scan.stamp_s):
                grid = self._radar.grid(self._poses.keyframe_poses())
                self.dense.refresh(scan.stamp_s, grid.to_cells(), grid.spec)

    def add_camera_keyframe(
        self,
        stamp_s: float,
        T_world_camera: np.ndarray,
        landmarks_world: np.ndarray,
        metres_per_unit: float,
        camera_trust: float,
    ) -> None:
        """A camera keyframe's landmarks (camera odometry world and units) and the camera's
        trust in it (see :meth:`VisualKeyframes.add`)."""
        if self._visual is not None:
            self._visual.add(
                stamp_s, T_world_camera, landmarks_world, metres_per_unit, camera_trust
            )

    def maps(self) -> dict[str, OccupancyGrid | DenseMap | FusedMap]:
        """A snapshot of every grid with content so far, by map name, in the map frame."""
        snapshot = {}
        if self._radar is not None and len(self._radar):
            snapshot["radar_sparse"] = self._radar.grid(self._poses.keyframe_poses()).copy()
            if self.dense is not None and self.dense.latest is not None:
                snapshot["radar_dense"] = self.dense.latest
        if self._visual is not None and len(self._visual):
            snapshot["visual"] = self._visual_grid(IDENTITY)
        self._add_fused(snapshot, IDENTITY)
        return snapshot

    def render(self, T_target_map: np.ndarray) -> dict[str, OccupancyGrid | DenseMap | FusedMap]:
        """Every grid drawn afresh on the current poses moved by the rigid (3,) transform
        ``T_target_map`` [x_m, y_m, yaw_rad] (e.g. the run's alignment to ground truth)."""
        return dict(self.render_each(T_target_map))

    def render_each(
        self, T_target_map: np.ndarray
    ) -> Iterator[tuple[str, OccupancyGrid | DenseMap | FusedMap]]:
        """As :meth:`render`, one ``(name, grid)`` at a time as each is drawn. The dense map
        is up-sampled in the background meanwhile: a caller writes the maps before it (the
        sparse and the visual map) while it is made."""
        target = np.asarray(T_target_map, dtype=float)
        grids: dict[str, OccupancyGrid | DenseMap | FusedMap] = {}
        dense = None
        if self._radar is not None and len(self._radar):
            poses = se2_compose(target, self._poses.keyframe_poses()).reshape(-1, 3)
            grids["radar_sparse"] = sparse = self._radar.render(poses)
            if self.dense is not None:
                dense = self.dense.final(sparse.to_cells(), sparse.spec)
            yield "radar_sparse", sparse
        if self._visual is not None and len(self._visual):
            grids["visual"] = self._visual_grid(target)
            yield "visual", grids["visual"]
        if dense is not None:
            try:
                grids["radar_dense"] = dense.result()
            except UpsamplerError:  # the up-sampler could not be loaded (its ``failure``)
                logger.info("no dense map: the up-sampler could not be loaded")
            else:
                yield "radar_dense", grids["radar_dense"]
        self._add_fused(grids, target)
        if "fused" in grids:
            yield "fused", grids["fused"]

    def visual_trust(self, target: np.ndarray, spec: GridSpec) -> tuple[np.ndarray, float]:
        """``(t grid over spec, the run's t)``: the trust index measured at the camera
        keyframes, per cell they saw (the run's mean elsewhere), with the maps moved by the
        rigid ``target``."""
        t_keyframes = self.fuser.trust.radar_trust(np.asarray(self._visual.camera_trust))
        t_run = float(t_keyframes.mean()) if len(t_keyframes) else 1.0
        if not self.fuser.per_region:
            return np.full(spec.shape, t_run), t_run
        stamps_s, poses = self._poses.trajectory()
        moved = se2_compose(target, poses).reshape(-1, 3)
        points, _, keyframe = self._visual.world_points(stamps_s, moved)
        return trust_grid(spec, t_keyframes, points[:, :2], keyframe, t_run), t_run

    def _add_fused(self, grids: dict, target: np.ndarray) -> None:
        """``grids["fused"]`` from the radar map and the visual map in ``grids``."""
        if self.fuser is None or "visual" not in grids:
            return
        radar = grids.get(self.fuser.radar_map, grids.get("radar_sparse"))
        if radar is None:
            return
        visual = grids["visual"]
        trust, t_run = self.visual_trust(target, visual.spec)
        grids["fused"] = self.fuser.fuse(
            radar.to_cells(), radar.spec, visual.to_cells(), visual.spec, trust, t_run
        )

    def _visual_grid(self, target: np.ndarray) -> OccupancyGrid:
        stamps_s, poses = self._poses.trajectory()
        moved = se2_compose(target, poses).reshape(-1, 3)
        return visual_map_on_poses(self._visual, stamps_s, moved, self._config)
