"""``--odometry fused``: radar and camera odometry in one iSAM2 pose graph, online.

The table of contents of :func:`run_fused_slam`: read each message once, in time order; IMU
waits for the next radar scan; a scan goes through radar odometry, then the keyframer; a
keyframe becomes a pose with a radar between factor, a camera factor once the camera has seen
past it (when healthy, metric and consistent with radar), a loop closure when its submap
matches an old one, and one iSAM2 update. The trajectory (every radar frame hung from its
keyframe's final estimate) and the maps are built last, on the final poses: every loop closure
that moved the poses has moved the maps with them.

The camera tracks in a worker process (``slam.camera_process``), fed in log order; the backend
still sees the messages in log order, so results do not depend on timing. Emulated smoke is
applied where a frame is used: radar scans here, camera frames in the worker, and only the
camera frames the pipeline tracks (every ``slam.camera_stride``-th). As with any spawned
process, a script calling this at import time needs the ``if __name__ == "__main__":`` guard.

Doppler and gyro enter only through the radar odometry's step: it already solved them jointly
with scan matching, so a separate velocity factor over the same interval would count that
information twice.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import multiprocessing
import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from smokyslam.config import CameraOdometryConfig, SmokySlamConfig
from smokyslam.frontends.camera.odometry import CameraOdometry, CameraOdometryResult
from smokyslam.frontends.radar.odometry import RadarOdometry
from smokyslam.frontends.readers.base import LogReader
from smokyslam.mapping.build import level_scan
from smokyslam.pipelines.fusion import FusedSlam
from smokyslam.pipelines.odometry import OdometryRun, ProgressCallback
from smokyslam.pipelines.visual_map import VisualKeyframes, visual_map_on_poses
from smokyslam.smoke import SmokeEmulator, split_smoke
from smokyslam.types import (
    CameraFrame,
    CameraIntrinsics,
    GroundTruthPose,
    ImuSample,
    Odometry,
    RadarScan,
)

logger = logging.getLogger(__name__)


@dataclass
class SlamRun(OdometryRun):
    """A fused run: the odometry outputs plus what the graph and the visual map need.

    factor_counts: factors per source ("prior", "radar", "camera", "loop_closure").
    camera_pairs: keyframe pairs by camera outcome (used, untracked, gated, no_scale,
    inconsistent). keyframe_stamps_s (K,), keyframe_camera (K,) bool: a camera factor ends
    at this keyframe. camera_weight (N,): gate weight of the latest camera frame at each radar
    frame. visual: camera keyframe points in base_link, placed on the final poses later.
    stage_s: busy seconds per stage (radar, camera, backend).
    """

    factor_counts: dict[str, int] = field(default_factory=dict)
    camera_pairs: dict[str, int] = field(default_factory=dict)
    keyframe_stamps_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    keyframe_camera: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    camera_weight: np.ndarray = field(default_factory=lambda: np.zeros(0))
    visual: VisualKeyframes | None = None
    stage_s: dict[str, float] = field(default_factory=dict)


class _Clock:
    """Busy seconds per stage."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def add(self, stage: str, seconds: float) -> None:
        self.seconds[stage] = self.seconds.get(stage, 0.0) + seconds

    @contextlib.contextmanager
    def time(self, stage: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.add(stage, time.perf_counter() - start)


class _SmokyCamera:
    """Camera odometry behind the smoke emulator (if any): one verb, :meth:`track`."""

    def __init__(
        self,
        intrinsics: CameraIntrinsics,
        config: CameraOdometryConfig,
        smoke: SmokeEmulator | None,
    ) -> None:
        self.odometry = CameraOdometry(intrinsics, config)
        self.smoke = smoke

    def track(self, frame: CameraFrame) -> tuple[CameraOdometryResult, float]:
        """The frame's odometry result and the seconds smoke and tracking took."""
        start = time.perf_counter()
        if self.smoke is not None:
            frame = self.smoke.apply(frame)
        return self.odometry.track(frame), time.perf_counter() - start


_WORKER: dict[str, _SmokyCamera] = {}
"""The camera odometry living in a camera worker process."""


def _start_camera_worker(*camera: Any) -> None:
    _WORKER["camera"] = _SmokyCamera(*camera)


def _track_in_worker(frame: CameraFrame) -> tuple[CameraOdometryResult, float]:
    return _WORKER["camera"].track(frame)


class _TimeOrder:
    """Feeds radar odometry frames and camera results to the backend in the log's order.

    With ``worker`` the camera tracks in a process of its own (a second core: a thread gained
    little, the GIL is held through most of the tracker), while this process reads the log and
    runs radar odometry and the backend. The backend still gets every message in the order one
    process would have given it, so runs are repeatable. When ``max_lag`` messages wait for the
    camera, reading waits too.
    """

    def __init__(
        self,
        slam: FusedSlam,
        camera: tuple[CameraIntrinsics, CameraOdometryConfig, SmokeEmulator | None] | None,
        clock: _Clock,
        worker: bool,
        max_lag: int = 30,
    ) -> None:
        self._slam, self._clock, self._max_lag = slam, clock, max_lag
        self._executor: ProcessPoolExecutor | None = None
        self._inline: _SmokyCamera | None = None
        smoke = camera[2] if camera is not None else None
        self._needs_depth = smoke is not None and smoke.needs_depth
        if camera is not None and worker:
            self._executor = ProcessPoolExecutor(
                1,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_start_camera_worker,
                initargs=camera,
            )
        elif camera is not None:
            self._inline = _SmokyCamera(*camera)
        # Radar: (Odometry, RadarScan); camera: a Future or (result, seconds), in log order.
        self._queue: deque[tuple[Odometry, RadarScan] | Future | tuple[Any, float]] = deque()
        self.on_radar: Callable[[Odometry], None] | None = None

    def camera(self, frame: CameraFrame) -> None:
        if not self._needs_depth:  # monocular: depth only for haze
            frame = dataclasses.replace(frame, depth_m=None)
        if self._executor is not None:
            self._queue.append(self._executor.submit(_track_in_worker, frame))
        else:
            self._queue.append(self._inline.track(frame))
        self.feed(block=len(self._queue) > self._max_lag)

    def radar(self, odometry: list[Odometry], scans: dict[float, RadarScan]) -> None:
        self._queue.extend((o, scans[o.stamp_s]) for o in odometry)
        self.feed(block=len(self._queue) > self._max_lag)

    def feed(self, block: bool) -> None:
        """Hand over the queue up to the first camera frame still tracking (``block``: all)."""
        while self._queue:
            item = self._queue[0]
            if isinstance(item, Future):
                if not (block or item.done()):
                    return
                item = item.result()
            self._queue.popleft()
            if isinstance(item[0], Odometry):
                with self._clock.time("backend"):
                    self._slam.add_radar(*item)
                if self.on_radar is not None:
                    self.on_radar(item[0])
                continue
            result, seconds = item
            self._clock.add("camera", seconds)
            with self._clock.time("backend"):
                self._slam.add_camera(result)

    def shutdown(self) -> None:
        """Stop the camera worker (frames not handed over yet are dropped: call
        ``feed(block=True)`` first)."""
        if self._executor is not None:
            self._executor.shutdown(cancel_futures=True)


def run_fused_slam(
    reader: LogReader, config: SmokySlamConfig, on_progress: ProgressCallback | None = None
) -> SlamRun:
    """Fused SLAM over every frame of ``reader``, online (a SmokedLog's smoke is applied
    frame by frame where the frame is used).

    on_progress: called after each radar frame reaches the backend, with its stamp and a
    one-line health summary. A log without a camera runs on radar (and loop closures) alone.
    """
    reader, smoke = split_smoke(reader)
    intrinsics = reader.camera_intrinsics()
    use_camera = config.slam.camera_factors and intrinsics is not None
    camera = (intrinsics, config.camera_odometry, smoke) if use_camera else None
    radar = RadarOdometry(config.radar_odometry)
    extrinsics = reader.extrinsics()
    T_base_radar = extrinsics.T_base_radar
    slam = FusedSlam(config, extrinsics)
    clock = _Clock()
    backend = _TimeOrder(slam, camera, clock, config.slam.camera_process)
    imu: list[ImuSample] = []
    scans: dict[float, RadarScan] = {}
    outputs: list[Odometry] = []
    gt_stamps, gt_poses = [], []
    camera_frames = 0

    def radar_done(odometry: Odometry) -> None:
        outputs.append(odometry)
        if on_progress is not None:
            on_progress(odometry.stamp_s, slam.status.text())

    backend.on_radar = radar_done
    try:
        for frame in reader.frames():
            if isinstance(frame, ImuSample):
                imu.append(frame)
            elif isinstance(frame, RadarScan):
                if smoke is not None:
                    frame = smoke.apply(frame)
                scans[frame.stamp_s] = frame
                with clock.time("radar"):
                    registered = radar.register(level_scan(frame, T_base_radar)[0], imu)
                imu = []
                backend.radar(registered, scans)
            elif isinstance(frame, CameraFrame) and camera is not None:
                camera_frames += 1
                if (camera_frames - 1) % config.slam.camera_stride == 0:
                    backend.camera(frame)
            elif isinstance(frame, GroundTruthPose):
                gt_stamps.append(frame.stamp_s)
                gt_poses.append(frame.pose_world_base)
        with clock.time("radar"):
            registered = radar.flush()
        backend.radar(registered, scans)
        backend.feed(block=True)
    finally:
        backend.shutdown()
    return _slam_run(slam, outputs, scans, gt_stamps, gt_poses, clock.seconds)


def _slam_run(
    slam: FusedSlam,
    outputs: list[Odometry],
    scans: dict[float, RadarScan],
    gt_stamps: list[float],
    gt_poses: list[np.ndarray],
    stage_s: dict[str, float],
) -> SlamRun:
    order = np.argsort(gt_stamps, kind="stable")
    camera_weight = np.asarray(slam.camera_weight)
    busy_s = sum(stage_s.values())
    logger.info(
        "fused: %d radar frames, %d keyframes, factors %s, camera pairs %s",
        len(outputs),
        len(slam.keyframe_stamps_s),
        slam.factor_counts,
        slam.camera_pairs,
    )
    return SlamRun(
        source="fused",
        stamps_s=np.array([o.stamp_s for o in outputs]),
        poses_world_base=slam.poses_world_base().reshape(-1, 3),
        # Lost: radar could not match and no healthy camera was there to carry the pose.
        lost=np.array([o.health.lost for o in outputs], dtype=bool) & (camera_weight <= 0.0),
        gt_stamps_s=np.asarray(gt_stamps, dtype=float)[order],
        gt_poses_world_base=np.asarray(gt_poses, dtype=float).reshape(-1, 3)[order],
        frames_per_s=len(outputs) / busy_s if busy_s > 0 else float("nan"),
        scans=[scans[o.stamp_s] for o in outputs],
        factor_counts=slam.factor_counts,
        camera_pairs=slam.camera_pairs,
        keyframe_stamps_s=np.asarray(slam.keyframe_stamps_s),
        keyframe_camera=np.asarray(slam.keyframe_camera, dtype=bool),
        camera_weight=camera_weight,
        visual=slam.visual,
        stage_s=dict(stage_s),
    )


def slam_metrics(run: SlamRun) -> dict[str, Any]:
    """The fused run's extra ``metrics.json`` entries: factors, camera pairs, stage times."""
    return {
        "factors": {
            "radar": run.factor_counts.get("radar", 0),
            "camera": run.factor_counts.get("camera", 0),
            "loop_closure": run.factor_counts.get("loop_closure", 0),
        },
        "camera_pairs": run.camera_pairs,
        "keyframes": len(run.keyframe_stamps_s),
        "stage_s": run.stage_s,
    }


def visual_map(run: SlamRun, config: SmokySlamConfig):
    """The flattened visual grid of the run, on its final (anchored) poses; None without one."""
    if run.visual is None or len(run.visual) == 0:
        return None
    return visual_map_on_poses(run.visual, run.stamps_s, run.poses_world_base, config.mapping)
