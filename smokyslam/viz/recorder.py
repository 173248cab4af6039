"""What a run records for the viewer: the recorder stage's verbs and the records it is given.

The recorder is a stage of the run loop. Before the first frame it gets the
:class:`RecordingSetup` (the rig, the camera, the log's clock and, for display only, the
ground truth); then every primary frame (:class:`FrameRecord`), every tracked camera frame,
and, when it says one is due, a :class:`RunSnapshot` of the graph and the maps; at the end,
the run's alignment to the truth and its final path. :class:`NullRecorder` stands in when no
recording is asked for, so the loop never branches on "if visualize". Only ``viz/`` calls
``rr.*``; this module imports nothing of rerun.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from smokyslam.backends.slam import SlamStatus
from smokyslam.config import RecordingConfig
from smokyslam.frontends.camera.result import CameraOdometryResult
from smokyslam.geometry import GridSpec
from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    GroundTruthMap,
    GroundTruthTrajectory,
    RadarScan,
)


@dataclass(frozen=True)
class RecordingSetup:
    """Logged once, before the first frame. ``log_time_s``: stamps from the log start to the
    log's own clock (the recording's ``sensor_time``). ``truth``, ``gt_map``: shown, and the
    error so far, never given to an estimator."""

    source: str
    extrinsics: Extrinsics
    intrinsics: CameraIntrinsics | None
    log_time_s: Callable[[np.ndarray], np.ndarray]
    truth: GroundTruthTrajectory | None = None
    gt_map: GroundTruthMap | None = None


@dataclass(frozen=True)
class FrameRecord:
    """One primary frame as the loop processed it: ``index`` (0, 1, ...), ``pose_map_base``
    (3,) the backend's current estimate, ``scan`` the levelled radar scan (None: camera-only),
    ``status`` the run's health then."""

    index: int
    stamp_s: float
    pose_map_base: np.ndarray
    scan: RadarScan | None
    status: SlamStatus


@dataclass(frozen=True)
class RunSnapshot:
    """The graph and the maps at one moment: ``poses_map_base`` (N, 3) every primary frame,
    ``keyframe_poses`` (K, 3), ``loop_edges`` (L, 2) keyframe index pairs, and ``maps`` name ->
    (trinary cells, spec) in the map frame (empty when maps are not due)."""

    stamp_s: float
    poses_map_base: np.ndarray
    keyframe_poses: np.ndarray
    loop_edges: np.ndarray
    maps: dict[str, tuple[np.ndarray, GridSpec]] = field(default_factory=dict)


@dataclass(frozen=True)
class Due:
    """What a snapshot at this frame should hold: the path (and keyframes), the maps."""

    path: bool = False
    maps: bool = False

    def __bool__(self) -> bool:
        return self.path or self.maps


class Recorder(Protocol):
    """The recorder stage: one verb per thing the loop has."""

    keeps_camera_views: bool
    """Whether camera results should carry their images (the camera stage keeps them)."""

    def start(self, setup: RecordingSetup) -> None:
        """Static content, once, before the first frame."""

    def log_frame(self, record: FrameRecord) -> None:
        """One primary frame, as the run processes it."""

    def log_camera(self, result: CameraOdometryResult, trust_index: float) -> None:
        """One tracked camera frame: its images and features (when kept), its measured smoke
        and health, and the trust index t it gives the radar."""

    def due(self, stamp_s: float) -> Due:
        """Whether a snapshot is wanted at this frame (the null recorder never wants one)."""

    def log_snapshot(self, snapshot: RunSnapshot) -> None:
        """The graph's path, keyframes, loop closures and (when due) the growing maps."""

    def log_result(
        self, pose_world_map: np.ndarray, stamps_s: np.ndarray, poses_map_base: np.ndarray
    ) -> None:
        """The end: where the map frame lies in the world, (3,) x, y, yaw, and the final
        path."""

    def close(self) -> None: ...


class NullRecorder:
    """Records nothing."""

    keeps_camera_views = False

    def start(self, setup: RecordingSetup) -> None:
        pass

    def log_frame(self, record: FrameRecord) -> None:
        pass

    def log_camera(self, result: CameraOdometryResult, trust_index: float) -> None:
        pass

    def due(self, stamp_s: float) -> Due:
        return Due()

    def log_snapshot(self, snapshot: RunSnapshot) -> None:
        pass

    def log_result(self, pose_world_map, stamps_s, poses_map_base) -> None:
        pass

    def close(self) -> None:
        pass


def open_recorder(
    path: Path | str | None, config: RecordingConfig, spawn: bool = False
) -> Recorder:
    """A Rerun recorder writing ``path`` and/or streaming to a spawned viewer (``spawn``), or
    a :class:`NullRecorder` when neither is asked for."""
    if path is None and not spawn:
        return NullRecorder()
    from smokyslam.viz.rerun_recorder import RerunRecorder

    return RerunRecorder(path, config, spawn=spawn)
