"""The localizer as a stage of the run loop: each radar frame's odometry step predicts, its
points weigh, and the filter's mean is the frame's pose in the saved map's frame.

The step is the radar odometry's (Doppler velocity, gyro and scan matching), moved from the
levelled radar frame to base_link with its reported covariance (``se2_conjugate``); the
points are the levelled scan's, in base_link. Smoke reaches the stage as it reaches SLAM:
the loop hands over the smoked scan.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from smokyslam.geometry import se2_conjugate
from smokyslam.localize.mcl import MonteCarloLocalizer
from smokyslam.types import Odometry


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
    """One verb per radar frame, :meth:`localize`; :attr:`track` holds every frame's pose."""

    def __init__(
        self, mcl: MonteCarloLocalizer, pose_base_radar: np.ndarray, start: LocalizeStart
    ) -> None:
        self.mcl = mcl
        self.start = start
        self._pose_base_radar = np.asarray(pose_base_radar, dtype=float)
        self.track = LocalizationTrack()
        self.first_particles: np.ndarray | None = None
        """(P, 3) the particles as the first scan left them (a global start draws them where
        that scan fits)."""

    def localize(self, odometry: Odometry, points_base_xy: np.ndarray) -> np.ndarray:
        """Predict with the frame's odometry step, weigh by its (N, 2) base_link points;
        returns the (3,) mean pose of base_link in the map."""
        first = self.first_particles is None
        if first:  # the first frame only places the particles
            self._begin()
        else:
            step, covariance = se2_conjugate(
                odometry.delta, odometry.covariance, self._pose_base_radar
            )
            self.mcl.predict(step, covariance)
        self.mcl.update(points_base_xy)
        if first:
            self.first_particles = self.mcl.particles.copy()
        mean, covariance = self.mcl.estimate()
        self.track.stamps_s.append(odometry.stamp_s)
        self.track.poses_map_base.append(mean)
        self.track.std.append(np.sqrt(np.clip(np.diag(covariance), 0.0, None)))
        self.track.particles.append(self.mcl.count)
        return mean

    @property
    def pose(self) -> np.ndarray | None:
        """The latest mean pose, None before the first frame."""
        return self.track.poses_map_base[-1] if self.track.poses_map_base else None

    def _begin(self) -> None:
        if self.start.pose_map_base is None:
            self.mcl.start_global()
        else:
            self.mcl.start_tracking(self.start.pose_map_base, self.start.sigmas)
