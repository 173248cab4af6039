"""The run's health over time, gathered by the loop for the plots (``health.png``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from smokyslam.backends.slam import SlamStatus
from smokyslam.frontends.camera.result import CameraOdometryResult


@dataclass
class RunHealth:
    """Per primary frame: ``stamps_s``, ``inliers`` (the odometry's), ``lost``,
    ``loop_closures`` (so far). Per tracked camera frame: ``camera_stamps_s``,
    ``camera_tracked`` (features followed; 0 when lost), ``impulse_fraction`` and
    ``rms_contrast`` (measured smoke), ``trust_index`` (the t it gives the radar)."""

    stamps_s: list[float] = field(default_factory=list)
    inliers: list[int] = field(default_factory=list)
    lost: list[bool] = field(default_factory=list)
    loop_closures: list[int] = field(default_factory=list)
    camera_stamps_s: list[float] = field(default_factory=list)
    camera_tracked: list[int] = field(default_factory=list)
    impulse_fraction: list[float] = field(default_factory=list)
    rms_contrast: list[float] = field(default_factory=list)
    trust_index: list[float] = field(default_factory=list)

    def add_frame(self, stamp_s: float, status: SlamStatus) -> None:
        self.stamps_s.append(stamp_s)
        self.inliers.append(status.inliers)
        self.lost.append(status.lost)
        self.loop_closures.append(status.loop_closures)

    def add_camera(self, result: CameraOdometryResult, trust_index: float) -> None:
        self.camera_stamps_s.append(result.stamp_s)
        self.camera_tracked.append(0 if result.lost else result.health.tracked)
        self.impulse_fraction.append(result.quality.impulse_fraction)
        self.rms_contrast.append(result.quality.rms_contrast)
        self.trust_index.append(trust_index)

    def array(self, name: str) -> np.ndarray:
        """One series as an array."""
        return np.asarray(getattr(self, name), dtype=float)
