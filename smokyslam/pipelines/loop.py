"""The one run loop: every source, every log, the same table of contents.

Read each sensor frame once, in time order. Apply the run's smoke to it where it is used (the
radar scan here; the camera frame where the camera tracks it). Then, in the log's order:

1. the frontends the source needs (radar odometry or dead reckoning; camera odometry);
2. the backend (keyframes, factors, loop closures, one iSAM2 update per keyframe);
3. the online maps (a radar keyframe's scan; a metric camera keyframe's landmarks);
   or, in a saved map, the localizer (the radar frame's odometry step and points, and the
   camera's odometry for its motion steps);
4. the recorder (Rerun, or nothing): every frame, every tracked camera frame, and snapshots
   of the graph and the maps when it asks for them.

The sources differ only in the stages switched on (``sources.py``). The camera may track in a
worker process; :class:`InOrder` hands its results to the backend in the order one process
would have, so results do not depend on timing. Ground truth never enters: readers yield
sensor frames only, and evaluation reads the truth apart, after the loop.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from smokyslam.errors import SmokySlamError
from smokyslam.evaluation.gyro_bias import GyroTally
from smokyslam.frontends.camera.metric import CameraStep
from smokyslam.frontends.camera.result import CameraOdometryResult
from smokyslam.frontends.radar.frontend import RadarFrame
from smokyslam.pipelines.health import RunHealth
from smokyslam.pipelines.ordering import InOrder, StageClock
from smokyslam.pipelines.stages import RunEstimate, Stages
from smokyslam.pipelines.worker_process import DeferredCtrlC
from smokyslam.types import CameraFrame, Frame, ImuSample, RadarScan
from smokyslam.viz.recorder import Due, FrameRecord, RunSnapshot

logger = logging.getLogger(__name__)

FACTOR_SOURCES = ("radar", "camera", "camera_long_turn", "loop_closure", "gyro")
"""The graph's factors by source, as ``metrics.json`` counts them."""

ProgressCallback = Callable[[float, str], None]
"""Called as frames are processed: (stamp_s of the frame just processed, health text)."""

MAX_LAG = 300
"""Frames waiting for the camera worker before reading waits for it too (a few seconds of
log: reading and radar go on while the worker starts)."""


def _never() -> bool:
    return False


class RunLoop:
    """Runs :class:`Stages` over a stream of frames: one verb, :meth:`run`."""

    def __init__(
        self,
        stages: Stages,
        on_progress: ProgressCallback | None = None,
        should_stop: Callable[[], bool] | None = None,
    ) -> None:
        """``should_stop()``, asked before each frame: True ends the run as Ctrl-C does (a
        batch's runs on Dask workers, where no Ctrl-C arrives, are stopped so)."""
        self.stages = stages
        self._on_progress = on_progress
        self._should_stop = should_stop or _never
        self._order = InOrder()
        self._clock = StageClock()
        self._camera_restarts = 0
        self._health = RunHealth()
        self._gyro = GyroTally()

    def run(self, frames: Iterable[Frame]) -> RunEstimate:
        """Every frame through the stages, then the estimate (the camera worker is stopped
        on the way out, whatever happens). Ctrl-C stops reading: the estimate then holds what
        was processed so far, with ``interrupted`` set. A stage that fails (a
        :class:`SmokySlamError`) stops it too: the estimate holds what came before, with
        ``failure`` set."""
        interrupted, failure = False, None
        stamp_s = 0.0
        # A Ctrl-C is acted on between frames: the frame in hand goes through every stage (the
        # graph, the maps and the health agree), and no wait on a worker is cut short.
        with DeferredCtrlC() as ctrl_c:
            try:
                try:
                    for frame in frames:
                        if ctrl_c.take() or self._should_stop():
                            raise KeyboardInterrupt  # a requested stop is a Ctrl-C
                        stamp_s = frame.stamp_s
                        self._read(frame)
                        self._hand_over(keep=MAX_LAG)
                    self._finish()
                    if ctrl_c.take():
                        raise KeyboardInterrupt
                    if stamps := self._health.stamps_s:  # the final graph and maps
                        self._snapshot(stamps[-1], self.stages.recorder.due(float("inf")))
                except KeyboardInterrupt:
                    interrupted = True
                    logger.info("interrupted: keeping what was processed so far")
                    self._hand_over(keep=len(self._order) + 1)  # what is done, not waiting
                    self._flush_localizer()
                except SmokySlamError as exc:  # nothing more goes through the broken stage
                    failure = f"run stopped at {stamp_s:.1f} s of log: {exc}"
                    logger.error("%s; keeping what was processed before", failure)
            finally:
                if self.stages.camera is not None:
                    self.stages.camera.shutdown()
                interrupted |= ctrl_c.take()  # one while stopping: the estimate is kept
        estimate = self._estimate()
        estimate.interrupted, estimate.failure = interrupted, failure
        return estimate

    # ------------------------------------------------------------------ reading

    def _read(self, frame: Frame) -> None:
        radar, camera = self.stages.radar, self.stages.camera
        if isinstance(frame, ImuSample) and radar is not None:
            radar.add_imu(frame)
            self._gyro.add(frame)
            self.stages.backend.add_imu(frame)
        elif isinstance(frame, RadarScan) and radar is not None:
            with self._clock.time("radar"):
                self._order.extend(radar.register(self.stages.smoke.apply(frame)))
        elif isinstance(frame, CameraFrame) and camera is not None and camera.wants(frame):
            self._order.extend([camera.track(frame)])  # smoked where it is tracked

    def _finish(self) -> None:
        if self.stages.radar is not None:
            with self._clock.time("radar"):
                self._order.extend(self.stages.radar.flush())
        self._hand_over(keep=0)
        self._flush_localizer()
        if self.stages.camera_steps is not None:
            for step in self.stages.camera_steps.flush():
                self._camera_step(step)

    # ------------------------------------------------------------------ handing over

    def _hand_over(self, keep: int) -> None:
        for item in self._order.ready(keep):
            if isinstance(item, RadarFrame):
                self._radar_frame(item)
            else:
                result, seconds = item
                self._clock.add("camera", seconds)
                self._camera_result(result)

    def _radar_frame(self, frame: RadarFrame) -> None:
        stages = self.stages
        points_base_xy = stages.radar.points_base_xy(frame)
        with self._clock.time("backend"):
            keyframe = stages.backend.add_odometry(frame.odometry, points_base_xy)
        with self._clock.time("maps"):
            if keyframe is not None:
                stages.maps.add_radar_keyframe(keyframe.index, frame.scan)
        if stages.localizer is not None:
            with self._clock.time("localizer"):
                stages.localizer.localize(frame.odometry, points_base_xy)
        self._processed(frame.odometry.stamp_s, frame.scan)

    def _flush_localizer(self) -> None:
        """Radar frames still waiting for the camera go through the localizer."""
        if self.stages.localizer is not None:
            with self._clock.time("localizer"):
                self.stages.localizer.flush()

    def _camera_result(self, result: CameraOdometryResult) -> None:
        stages = self.stages
        self._camera_restarts = result.reinitializations
        trust_index = float(self._trust_index(result))
        self._health.add_camera(result, trust_index)
        with self._clock.time("recorder"):
            stages.recorder.log_camera(result, trust_index)
        if stages.camera_steps is not None:  # the camera carries the trajectory
            for step in stages.camera_steps.add(result):
                self._camera_step(step)
            return
        with self._clock.time("backend"):
            weight = stages.backend.add_camera(result)
        if stages.localizer is not None:  # the camera joins its motion steps
            with self._clock.time("localizer"):
                stages.localizer.add_camera(result)
        scale_m = stages.backend.camera_scale_m
        if weight > 0.0 and scale_m is not None:
            self._visual_keyframe(result, scale_m)

    def _camera_step(self, step: CameraStep) -> None:
        with self._clock.time("backend"):
            self.stages.backend.add_odometry(step.odometry, np.zeros((0, 2)))
        self._visual_keyframe(step.result, self.stages.camera_steps.metres_per_unit)
        self._processed(step.odometry.stamp_s, None)

    def _visual_keyframe(self, result: CameraOdometryResult, metres_per_unit: float) -> None:
        if not (self.stages.visual_map and result.is_keyframe and len(result.landmarks_world)):
            return
        with self._clock.time("maps"):
            self.stages.maps.add_camera_keyframe(
                result.stamp_s,
                result.T_world_camera,
                result.landmarks_world,
                metres_per_unit,
                float(self._camera_trust(result)),
            )

    def _camera_trust(self, result: CameraOdometryResult) -> float:
        quality = result.quality
        return self.stages.trust.camera_trust(
            quality.impulse_fraction, quality.rms_contrast, not result.lost
        )

    def _trust_index(self, result: CameraOdometryResult) -> float:
        """The trust index t this camera frame would give the radar (the paper's eq. 3)."""
        return self.stages.trust.radar_trust(self._camera_trust(result))

    def _processed(self, stamp_s: float, scan: RadarScan | None) -> None:
        backend, recorder = self.stages.backend, self.stages.recorder
        with self._clock.time("recorder"):
            index = len(self._health.stamps_s)
            localizer = self.stages.localizer
            pose = backend.latest_pose() if localizer is None else localizer.pose
            record = FrameRecord(index, stamp_s, pose, scan, backend.status)
            recorder.log_frame(record)
            self._snapshot(stamp_s, recorder.due(stamp_s))
        self._health.add_frame(stamp_s, backend.status)
        if self._on_progress is not None:
            self._on_progress(stamp_s, backend.status.text())

    def _snapshot(self, stamp_s: float, due: Due) -> None:
        """The graph (and, when due, the maps) to the recorder, when it asks for them."""
        if not due:
            return
        backend = self.stages.backend
        maps = {}
        if due.maps:
            maps = {
                name: (grid.to_cells(), grid.spec) for name, grid in self.stages.maps.maps().items()
            }
        localizer = self.stages.localizer
        path = backend.poses_world_base() if localizer is None else localizer.track.arrays()[1]
        self.stages.recorder.log_snapshot(
            RunSnapshot(
                stamp_s,
                path,
                backend.keyframe_poses(),
                np.asarray(backend.loop_edges, dtype=int).reshape(-1, 2),
                maps,
            )
        )

    # ------------------------------------------------------------------ result

    def _estimate(self) -> RunEstimate:
        backend = self.stages.backend
        stamps_s, poses = backend.trajectory()
        busy_s = sum(self._clock.seconds.values())
        # A stage that failed part-way through a frame leaves it out of the trajectory.
        camera_weight = np.asarray(backend.camera_weight, dtype=float)[: len(stamps_s)]
        # Lost: the primary odometry could not measure and no healthy camera carried the pose.
        frame_lost = np.asarray(backend.frame_lost, dtype=bool)[: len(stamps_s)]
        lost = frame_lost & (camera_weight <= 0.0)
        factors = backend.factor_counts
        graph = {
            "factors": {k: factors.get(k, 0) for k in FACTOR_SOURCES},
            "camera_pairs": backend.camera_pairs,
            "loop_searches": backend.loop_searches,
            "keyframes": len(backend.keyframe_stamps_s),
            "map_redraws": self.stages.maps.radar_redraws,
            "stage_s": dict(self._clock.seconds),
        }
        extra: dict[str, Any] = {}
        if self.stages.radar is not None and self.stages.radar.thinned:
            extra["thinned_scans"] = self.stages.radar.thinned
            logger.warning(
                "%d dense radar scans thinned to radar_odometry.max_points points",
                self.stages.radar.thinned,
            )
        if self.stages.radar is not None and self.stages.radar.gyro_bias_radps is not None:
            extra["gyro_bias_degps"] = float(np.degrees(self.stages.radar.gyro_bias_radps))
        if backend.gyro_bias_radps is not None:
            extra["graph_gyro_bias_degps"] = float(np.degrees(backend.gyro_bias_radps))
        if self.stages.camera is not None:
            extra["reinitializations"] = self._camera_restarts
        if self.stages.camera_steps is not None:
            extra["metres_per_unit"] = self.stages.camera_steps.metres_per_unit
            extra["metric_scale"] = self.stages.camera_steps.metric
        logger.info(
            "%d frames, %d keyframes, factors %s, camera pairs %s",
            len(stamps_s),
            graph["keyframes"],
            graph["factors"],
            graph["camera_pairs"],
        )
        return RunEstimate(
            stamps_s=stamps_s,
            poses_world_base=poses,
            lost=lost,
            camera_weight=camera_weight,
            keyframe_stamps_s=np.asarray(backend.keyframe_stamps_s, dtype=float),
            keyframe_camera=np.asarray(backend.keyframe_camera, dtype=bool),
            frames_per_s=len(stamps_s) / busy_s if busy_s > 0 else float("nan"),
            maps=self.stages.maps,
            graph=graph,
            extra=extra,
            health=self._health,
            localization=self.stages.localizer.track if self.stages.localizer else None,
            step_pairs=backend.step_pairs,
            gyro=self._gyro if self._gyro.samples else None,
        )
