"""A run as a Rerun recording (``.rrd``), for inspecting trajectories in the Rerun viewer.

Entity paths mirror the frame tree: ``world/rig`` moves with base_link, ``world/rig/radar``
holds each radar frame's points in the radar frame under the (static) mounting transform;
maps and ground truth are static entities under ``world/``. Time is ``sensor_time``, seconds
from the log's start. :class:`NullRecorder` stands in when no recording is asked for, so
callers never branch on "if visualize".
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np

from smokyslam.geometry import GridSpec, se3_from_se2
from smokyslam.mapio import OCCUPIED
from smokyslam.types import Extrinsics, GroundTruthMap, RadarScan


class Recorder(Protocol):
    """What a run logs for visualization."""

    def log_ground_truth(
        self, gt_map: GroundTruthMap | None, stamps_s: np.ndarray, poses: np.ndarray
    ) -> None: ...

    def log_trajectory(
        self,
        source: str,
        stamps_s: np.ndarray,
        poses_world_base: np.ndarray,
        scans: list[RadarScan],
        extrinsics: Extrinsics,
    ) -> None: ...

    def log_map(self, name: str, cells: np.ndarray, spec: GridSpec) -> None: ...

    def close(self) -> None: ...


class NullRecorder:
    """Records nothing."""

    def log_ground_truth(self, gt_map, stamps_s, poses) -> None:
        pass

    def log_trajectory(self, source, stamps_s, poses_world_base, scans, extrinsics) -> None:
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

    def log_trajectory(
        self,
        source: str,
        stamps_s: np.ndarray,
        poses_world_base: np.ndarray,
        scans: list[RadarScan],
        extrinsics: Extrinsics,
    ) -> None:
        rr = self._rr
        self._rec.log(
            f"world/estimate/{source}",
            rr.LineStrips3D([_path_3d(poses_world_base)], colors=[40, 110, 220]),
            static=True,
        )
        T = extrinsics.T_base_radar
        self._rec.log(
            "world/rig/radar", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), static=True
        )
        for index, (stamp_s, pose) in enumerate(zip(stamps_s, poses_world_base, strict=True)):
            self._rec.set_time("sensor_time", duration=float(stamp_s))
            T_world_base = se3_from_se2(pose)
            self._rec.log(
                "world/rig",
                rr.Transform3D(translation=T_world_base[:3, 3], mat3x3=T_world_base[:3, :3]),
            )
            if index < len(scans):
                scan = scans[index]
                self._rec.log(
                    "world/rig/radar/points",
                    rr.Points3D(scan.points_xyz_m, radii=0.04, colors=[250, 170, 30]),
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
