"""Camera odometry that survives smoke: image-quality-driven cleaning, LK tracks, PnP.

Public API: :class:`CameraOdometry` (``track(frame) -> CameraOdometryResult``) and
:class:`Preprocessor` (``apply(image) -> (clean_image, ImageQuality)``).
"""

from smokyslam.frontends.camera.odometry import (
    CameraHealth,
    CameraOdometry,
    CameraOdometryResult,
    TrackingStatus,
)
from smokyslam.frontends.camera.preprocess import ImageQuality, Preprocessor

__all__ = [
    "CameraHealth",
    "CameraOdometry",
    "CameraOdometryResult",
    "ImageQuality",
    "Preprocessor",
    "TrackingStatus",
]
