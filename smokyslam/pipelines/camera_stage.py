"""The camera stage of the run loop: smoke and camera odometry, in a worker process or inline.

With ``worker`` the camera tracks in a worker process of its own (a second core: a thread
gained little, the GIL is held through most of the tracker), while the main process reads the
log and runs radar odometry and the backend. Smoke is applied where the frame is tracked, by
the run's one :class:`SmokeEmulator` (seeded per frame, so a frame's smoke is the same
wherever it is applied), and only to the frames that are tracked (every ``stride``-th): that
keeps the fused run fast under smoke. As with any such worker, a script that starts a run
at import time needs the ``if __name__ == "__main__":`` guard.
"""

from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any

import numpy as np

from smokyslam.config import CameraOdometryConfig
from smokyslam.frontends.camera.odometry import CameraOdometry
from smokyslam.frontends.camera.result import CameraOdometryResult
from smokyslam.pipelines.worker_process import start_worker_pool, start_worker_process
from smokyslam.smoke import SmokeEmulator
from smokyslam.types import CameraFrame, CameraIntrinsics

Tracked = tuple[CameraOdometryResult, float]
"""A tracked frame: its odometry result and the seconds smoke and tracking took."""


class SmokyCamera:
    """Camera odometry behind the smoke emulator: one verb, :meth:`track`."""

    def __init__(
        self,
        intrinsics: CameraIntrinsics,
        config: CameraOdometryConfig,
        camera_height_m: float | None,
        smoke: SmokeEmulator,
        keep_views: bool,
    ) -> None:
        """``keep_views``: results carry their images and features (for a recording)."""
        self.odometry = CameraOdometry(intrinsics, config, camera_height_m)
        self.smoke = smoke
        self.keep_views = keep_views

    def track(self, frame: CameraFrame) -> Tracked:
        start = time.perf_counter()
        smoked = self.smoke.apply(frame)
        result = self.odometry.track(smoked)
        if self.keep_views:
            result.view = self.odometry.view(np.asarray(smoked.image, dtype=np.uint8))
        return result, time.perf_counter() - start


_WORKER: dict[str, SmokyCamera] = {}
"""The camera odometry living in a camera worker process."""


def _start_worker(parent_pid: int, *camera: Any) -> None:
    start_worker_process(parent_pid)  # Ctrl-C is the main process's to handle; exit with it
    _WORKER["camera"] = SmokyCamera(*camera)


def _track_in_worker(frame: CameraFrame) -> Tracked:
    return _WORKER["camera"].track(frame)


class CameraStage:
    """Tracks every ``stride``-th camera frame; :meth:`track` returns a Future (worker) or the
    finished :data:`Tracked` (inline). :meth:`shutdown` stops the worker."""

    def __init__(
        self,
        intrinsics: CameraIntrinsics,
        config: CameraOdometryConfig,
        camera_height_m: float | None,
        smoke: SmokeEmulator,
        stride: int,
        worker: bool,
        keep_views: bool,
    ) -> None:
        """``keep_views``: results carry the frame's images and features (a recording)."""
        camera = (intrinsics, config, camera_height_m, smoke, keep_views)
        self._stride = stride
        self._seen = 0
        self._needs_depth = smoke.needs_depth
        self._inline: SmokyCamera | None = None
        self._executor: ProcessPoolExecutor | None = None
        if worker:
            self._executor = start_worker_pool(_start_worker, (os.getpid(), *camera))
        else:
            self._inline = SmokyCamera(*camera)

    def wants(self, frame: CameraFrame) -> bool:
        """Whether this camera frame is one the stage tracks (counts every frame it is asked)."""
        self._seen += 1
        return (self._seen - 1) % self._stride == 0

    def track(self, frame: CameraFrame) -> Future | Tracked:
        if not self._needs_depth:  # monocular: depth only for haze
            frame = dataclasses.replace(frame, depth_m=None)
        if self._executor is not None:
            return self._executor.submit(_track_in_worker, frame)
        return self._inline.track(frame)

    def shutdown(self) -> None:
        """Stop the worker; frames still tracking are dropped."""
        if self._executor is not None:
            self._executor.shutdown(cancel_futures=True)
