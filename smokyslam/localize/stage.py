"""The localizer as a stage of the run loop: each radar frame's odometry step predicts, its
points weigh, and the filter's mean is the frame's pose in the saved map's frame.

The step is the radar odometry's (Doppler velocity, gyro and scan matching), moved from the
levelled radar frame to base_link with its reported covariance (``se2_conjugate``); the
points are the levelled scan's, in base_link. Smoke reaches the stage as it reaches SLAM:
the loop hands over the smoked scan.

With a camera, its odometry joins the step while it is healthy. The camera's motion between
two radar frames is made metric, checked against the radar's and weighed by the camera's
health as the SLAM backend's camera factors are (``backends/camera_factors.py``: tracking
gate, consistency check, covariance inflated as image quality falls; the scale is the one
SLAM's keyframe pairs keep, ``SharedScale``), then fused with the radar step by their
covariances (``se2_fuse``). The camera's frame after a radar frame is needed for that, so a
radar frame waits for it, at most ``CAMERA_WAIT_S`` of radar time (the first frame, which
only places the particles, never waits); a lost or absent camera leaves the radar step
alone. So with a camera the newest filtered pose (:attr:`Localizer.pose`, what the
recording shows) may be a frame behind.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from smokyslam.backends.camera_factors import CameraFactorMaker
from smokyslam.frontends.camera.result import CameraOdometryResult
from smokyslam.geometry import se2_conjugate, se2_fuse
from smokyslam.localize.mcl import MonteCarloLocalizer
from smokyslam.types import Odometry

CAMERA_WAIT_S = 0.5
"""How long (radar time) a radar frame waits for the camera frame after it; later, the
camera is taken as lost for that frame and the radar step moves the particles alone."""


@dataclass(frozen=True)
class LocalizeStart:
    """How the filter starts: ``pose_map_base`` (3,) with (3,) ``sigmas`` (m, m, rad) for
    tracking; no pose for global localization (particles over the map's free space)."""

    pose_map_base: np.ndarray | None = None
    sigmas: np.ndarray | None = None

    @property
    def mode(self) -> str:
        return "global" if self.pose_map_base is None else "tracking"


@dataclass
class LocalizationTrack:
    """Per radar frame: stamps_s (N,), poses_map_base (N, 3) (the particles' mean),
    std (N, 3) (their spread: m, m, rad) and particles (N,) (the count after resampling)."""

    stamps_s: list[float] = field(default_factory=list)
    poses_map_base: list[np.ndarray] = field(default_factory=list)
    std: list[np.ndarray] = field(default_factory=list)
    particles: list[int] = field(default_factory=list)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(stamps_s, poses_map_base, std, particles) as arrays."""
        return (
            np.asarray(self.stamps_s, dtype=float),
            np.asarray(self.poses_map_base, dtype=float).reshape(-1, 3),
            np.asarray(self.std, dtype=float).reshape(-1, 3),
            np.asarray(self.particles, dtype=int),
        )


class Localizer:
    """Verbs: :meth:`localize` per radar frame, :meth:`add_camera` per camera result,
    :meth:`flush` at the end; :attr:`track` holds every frame's pose."""

    def __init__(
        self,
        mcl: MonteCarloLocalizer,
        pose_base_radar: np.ndarray,
        start: LocalizeStart,
        camera: CameraFactorMaker | None = None,
    ) -> None:
        """``camera``: the camera's metric steps (None: radar odometry alone)."""
        self.mcl = mcl
        self.start = start
        self.camera = camera
        self._pose_base_radar = np.asarray(pose_base_radar, dtype=float)
        self._waiting: deque[tuple[Odometry, np.ndarray]] = deque()
        self.track = LocalizationTrack()
        self.first_particles: np.ndarray | None = None
        """(P, 3) the particles as the first scan left them (a global start draws them where
        that scan fits)."""

    def localize(self, odometry: Odometry, points_base_xy: np.ndarray) -> None:
        """Take one radar frame: its odometry step and (N, 2) base_link points. It is
        filtered at once without a camera, else once the camera has passed it."""
        self._waiting.append((odometry, np.asarray(points_base_xy, dtype=float)))
        self._filter_ready()

    def add_camera(self, result: CameraOdometryResult) -> None:
        """Take one camera odometry result (for the motion steps); frames waiting for it
        are filtered."""
        if self.camera is not None:
            self.camera.add(result)
            self._filter_ready()

    def flush(self) -> None:
        """Filter every frame still waiting for the camera (the log has ended)."""
        while self._waiting:
            self._filter(*self._waiting.popleft())

    @property
    def pose(self) -> np.ndarray | None:
        """The latest mean pose, None before the first frame."""
        return self.track.poses_map_base[-1] if self.track.poses_map_base else None

    def _filter_ready(self) -> None:
        while self._waiting:
            stamp_s = self._waiting[0][0].stamp_s
            needs_camera = self.camera is not None and self.first_particles is not None
            camera_passed = not needs_camera or self.camera.latest_stamp_s >= stamp_s
            if not (camera_passed or self._waiting[-1][0].stamp_s - stamp_s > CAMERA_WAIT_S):
                return
            self._filter(*self._waiting.popleft())

    def _filter(self, odometry: Odometry, points_base_xy: np.ndarray) -> None:
        """Predict with the frame's step, weigh by its points; record the mean pose."""
        if self.first_particles is None:  # the first frame only places the particles
            self._begin()
        else:
            self.mcl.predict(*self._step(odometry))
        self.mcl.update(points_base_xy)
        if self.first_particles is None:
            self.first_particles = self.mcl.particles.copy()
        mean, covariance = self.mcl.estimate()
        self.track.stamps_s.append(odometry.stamp_s)
        self.track.poses_map_base.append(mean)
        self.track.std.append(np.sqrt(np.clip(np.diag(covariance), 0.0, None)))
        self.track.particles.append(self.mcl.count)

    def _step(self, odometry: Odometry) -> tuple[np.ndarray, np.ndarray]:
        """The frame's base_link step and covariance: the radar's, fused with the camera's
        where the camera has a consistent metric step for it."""
        step, covariance = se2_conjugate(odometry.delta, odometry.covariance, self._pose_base_radar)
        if self.camera is None:
            return step, covariance
        if self.camera.latest_stamp_s < odometry.stamp_s:  # waited for it in vain
            self.camera.outcomes["untracked"] += 1
            return step, covariance
        previous_s = self.track.stamps_s[-1]  # the frame filtered before this one
        factor = self.camera.factor(previous_s, odometry.stamp_s, step, covariance)
        if factor is None:
            return step, covariance
        return se2_fuse(step, covariance, factor.delta, factor.covariance)

    def _begin(self) -> None:
        if self.start.pose_map_base is None:
            self.mcl.start_global()
        else:
            self.mcl.start_tracking(self.start.pose_map_base, self.start.sigmas)
