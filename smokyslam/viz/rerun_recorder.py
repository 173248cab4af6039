"""A run as a Rerun recording (``.rrd``), for inspecting trajectories in the Rerun viewer.

Entity paths mirror the frame tree. ``world`` is the ground-truth frame (the estimate's own
frame without ground truth); ``world/map`` is the run's map frame, placed in it by the run's
alignment once the run is evaluated. ``world/map/rig`` moves with base_link as the run goes,
``world/map/rig/radar`` holds each radar frame's levelled points under the (static) levelled
mount. The final trajectory, maps and ground truth are static entities under ``world/``.
Time is ``sensor_time``, seconds from the log's start. :class:`NullRecorder` stands in when no
recording is asked for, so callers never branch on "if visualize".
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np

from smokyslam.geometry import GridSpec, se2_from_matrix, se3_from_se2
from smokyslam.mapio import OCCUPIED
from smokyslam.types import Extrinsics, GroundTruthMap, RadarScan


class Recorder(Protocol):
    """What a run logs for visualization: a stage of the run loop, then the results."""

    def log_rig(self, extrinsics: Extrinsics) -> None:
        """The sensor mounting, once, before the first frame."""

    def log_frame(
        self, stamp_s: float, pose_world_base: np.ndarray, radar_scan: RadarScan | None
    ) -> None:
        """One primary frame as the run processes it: the rig's current estimate (map frame)
        and, for radar, the levelled scan."""

    def log_alignment(self, T_world_map: np.ndarray) -> None:
        """Where the run's map frame lies in the world (ground-truth) frame, (3,)."""

    def log_ground_truth(
        self, gt_map: GroundTruthMap | None, stamps_s: np.ndarray, poses: np.ndarray
    ) -> None: ...

    def log_trajectory(self, source: str, stamps_s: np.ndarray, poses_world_base: np.ndarray):
        """The final trajectory, world frame."""

    def log_map(self, name: str, cells: np.ndarray, spec: GridSpec) -> None:
        """A final map, world frame."""

    def close(self) -> None: ...


class NullRecorder:
    """Records nothing."""

    def log_rig(self, extrinsics) -> None:
        pass

    def log_frame(self, stamp_s, pose_world_base, radar_scan) -> None:
        pass

    def log_alignment(self, T_world_map) -> None:
        pass

    def log_ground_truth(self, gt_map, stamps_s, poses) -> None:
        pass

    def log_trajectory(self, source, stamps_s, poses_world_base) -> None:
        pass

    def log_map(self, name, cells, spec) -> None:
        pass

    def close(self) -> None:
        pass


def _occupied_points(cells: np.ndarray, spec: GridSpec) -> np.ndarray:
    """(N, 3) world centres (z = 0) of the occupied cells of a trinary grid."""
    iy, ix = np.nonzero(np.asarray(cells) == OCCUPIED)
    xy = spec.centres_of(np.column_stack([ix, iy]))
    return np.column_stack([xy, np.zeros(len(xy))])


def level_mount(T_base_radar: np.ndarray) -> np.ndarray:
    """(4, 4) the levelled radar frame on base_link: the radar's position, its heading only."""
    T = se3_from_se2(se2_from_matrix(T_base_radar), float(np.asarray(T_base_radar)[2, 3]))
    return T


def _path_3d(poses: np.ndarray) -> np.ndarray:
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    return np.column_stack([poses[:, :2], np.zeros(len(poses))])


class RerunRecorder:
    """Writes a ``.rrd`` file that ``rerun FILE.rrd`` opens."""

    def __init__(self, path: Path | str, application_id: str = "smokyslam") -> None:
        import rerun as rr

        self._rr = rr
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._rec = rr.RecordingStream(application_id)
        self._rec.save(str(self.path))
        self._rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    def log_ground_truth(
        self, gt_map: GroundTruthMap | None, stamps_s: np.ndarray, poses: np.ndarray
    ) -> None:
        rr = self._rr
        if gt_map is not None:
            walls = _occupied_points(gt_map.cells, gt_map.spec)
            self._rec.log(
                "world/ground_truth/map",
                rr.Points3D(walls, radii=gt_map.spec.resolution_m / 2, colors=[200, 60, 60]),
                static=True,
            )
        if len(stamps_s):
            self._rec.log(
                "world/ground_truth/path",
                rr.LineStrips3D([_path_3d(poses)], colors=[90, 90, 90]),
                static=True,
            )

    def log_rig(self, extrinsics: Extrinsics) -> None:
        rr = self._rr
        T = level_mount(extrinsics.T_base_radar)
        self._rec.log(
            "world/map/rig/radar",
            rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]),
            static=True,
        )

    def log_frame(
        self, stamp_s: float, pose_world_base: np.ndarray, radar_scan: RadarScan | None
    ) -> None:
        rr = self._rr
        self._rec.set_time("sensor_time", duration=float(stamp_s))
        T_world_base = se3_from_se2(pose_world_base)
        self._rec.log(
            "world/map/rig",
            rr.Transform3D(translation=T_world_base[:3, 3], mat3x3=T_world_base[:3, :3]),
        )
        if radar_scan is not None:
            self._rec.log(
                "world/map/rig/radar/points",
                rr.Points3D(radar_scan.points_xyz_m, radii=0.04, colors=[250, 170, 30]),
            )

    def log_alignment(self, T_world_map: np.ndarray) -> None:
        T = se3_from_se2(T_world_map)
        self._rec.log(
            "world/map", self._rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), static=True
        )

    def log_trajectory(self, source: str, stamps_s: np.ndarray, poses_world_base: np.ndarray):
        self._rec.log(
            f"world/estimate/{source}",
            self._rr.LineStrips3D([_path_3d(poses_world_base)], colors=[40, 110, 220]),
            static=True,
        )

    def log_map(self, name: str, cells: np.ndarray, spec: GridSpec) -> None:
        rr = self._rr
        self._rec.log(
            f"world/maps/{name}",
            rr.Points3D(_occupied_points(cells, spec), radii=spec.resolution_m / 2),
            static=True,
        )

    def close(self) -> None:
        self._rec.flush()


def open_recorder(path: Path | str | None) -> Recorder:
    """A RerunRecorder writing ``path``, or a NullRecorder when ``path`` is None."""
    return NullRecorder() if path is None else RerunRecorder(path)
