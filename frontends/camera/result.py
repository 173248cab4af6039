"""What camera odometry reports per frame: status, pose, health, landmarks and scale."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from smokyslam.frontends.camera.preprocess import ImageQuality

LOST_VARIANCE = 1e6
"""Variance (units^2, rad^2) reported on every axis of a frame without a pose estimate."""


class TrackingStatus(Enum):
    """``tracking``: pose from PnP. ``initializing``: waiting for the first two-view start.
    ``lost``: tracking failed; the pose is extrapolated until a new map starts."""

    TRACKING = "tracking"
    INITIALIZING = "initializing"
    LOST = "lost"


@dataclass(frozen=True)
class CameraHealth:
    """How well one frame was tracked.

    tracked: points followed into this frame. landmarks: of them, with a landmark.
    inliers: PnP inliers; inlier_ratio = inliers / landmarks.
    parallax_deg: median ray angle of the inlier landmarks since the reference keyframe.
    residual_rms_px: RMS reprojection error of the inliers.
    """

    tracked: int = 0
    landmarks: int = 0
    inliers: int = 0
    inlier_ratio: float = 0.0
    parallax_deg: float = 0.0
    residual_rms_px: float = float("nan")


@dataclass(frozen=True)
class CameraView:
    """What one tracked frame looked like, for a recording: ``raw`` (H, W) uint8 the image as
    tracked (smoke included), ``clean`` (H, W) uint8 after preprocessing, ``features_px``
    (N, 2) the tracked points (u, v) and ``has_landmark`` (N,) bool those with a landmark."""

    raw: np.ndarray
    clean: np.ndarray
    features_px: np.ndarray
    has_landmark: np.ndarray


@dataclass
class CameraOdometryResult:
    """The odometry's output for one frame (lengths in odometry units: up to scale).

    pose_world_camera: (3,) [x, y, yaw_rad] of the camera body (x forward, y left) in the
        odometry world: the first camera's body frame.
    T_world_camera: (4, 4) the same pose in optical axes (z forward, x right, y down).
    keyframe_id: the keyframe ``relative_pose`` is measured from.
    relative_pose: (3,) [x, y, yaw_rad] of this frame in the body frame of that keyframe
        (as adjusted by this frame's bundle adjustment, if any).
    covariance: (3, 3) of ``relative_pose`` given the landmarks, from the reprojection
        Jacobian and residuals; ``LOST_VARIANCE`` on the diagonal when lost.
    is_keyframe: this frame became keyframe ``keyframe_id + 1``.
    reinitialized: a new map (and a new scale) started at this frame.
    reinitializations: maps started after the first, so far.
    landmarks_world: (M, 3) world points of this frame's inlier landmarks.
    metres_per_unit: metres per odometry unit from the camera's known height above the
        floor (the first map's floor depth below the camera), None until the floor is found
        or when the height is not known.
    view: the frame's images and features, when the camera stage keeps them for a recording.
    """

    stamp_s: float
    status: TrackingStatus
    pose_world_camera: np.ndarray
    T_world_camera: np.ndarray
    keyframe_id: int
    relative_pose: np.ndarray
    covariance: np.ndarray
    health: CameraHealth
    quality: ImageQuality
    is_keyframe: bool
    reinitialized: bool
    reinitializations: int
    landmarks_world: np.ndarray
    metres_per_unit: float | None = None
    view: CameraView | None = None

    @property
    def lost(self) -> bool:
        """True when the pose is not measured from the image (initializing or lost)."""
        return self.status is not TrackingStatus.TRACKING
