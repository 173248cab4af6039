"""Camera odometry that survives smoke: image-quality-driven cleaning, LK tracks, PnP.

Public API: :class:`CameraOdometry` (``track(frame) -> CameraOdometryResult``) and
:class:`Preprocessor` (``apply(image) -> (clean_image, ImageQuality)``).
"""

from smokyslam.frontends.camera.odometry import CameraOdometry
from smokyslam.frontends.camera.preprocess import ImageQuality, Preprocessor
from smokyslam.frontends.camera.result import CameraHealth, CameraOdometryResult, TrackingStatus

__all__ = [
    "CameraHealth",
    "CameraOdometry",
    "CameraOdometryResult",
    "ImageQuality",
    "Preprocessor",
    "TrackingStatus",
]
