"""Two-view start of a monocular map: essential matrix with RANSAC, then triangulation.

The relative pose of two views is known only up to scale; the caller picks the baseline
length (1 unit for the first map, a speed-based guess after a loss).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from smokyslam.config import CameraOdometryConfig
from smokyslam.frontends.camera.landmarks import triangulate
from smokyslam.frontends.camera.pose import camera_from_planar, planar_from_camera
from smokyslam.geometry import se3_inverse


@dataclass
class TwoViewStart:
    """A successful two-view start.

    T_world_camera: (4, 4) pose of the second view (optical axes).
    points_world: (N, 3) triangulated points, NaN where a pair gave none.
    inliers: (N,) bool, pairs consistent with the essential matrix.
    parallax_deg: median ray angle of the triangulated points.
    """

    T_world_camera: np.ndarray
    points_world: np.ndarray
    inliers: np.ndarray
    parallax_deg: float


def start_two_view(
    T_world_reference: np.ndarray,
    uv_reference_px: np.ndarray,
    uv_px: np.ndarray,
    K: np.ndarray,
    baseline: float,
    config: CameraOdometryConfig,
) -> TwoViewStart | None:
    """Try to start a map from (N, 2) pixel pairs between a reference view and this view.

    Returns None while the views are not yet far enough apart (median ray angle below
    ``init_parallax_deg``) or too few pairs agree (``min_inliers``).
    """
    n = len(uv_px)
    flow_px = np.median(np.linalg.norm(uv_px - uv_reference_px, axis=1)) if n else 0.0
    if n < config.min_inliers or flow_px < K[0, 0] * np.tan(np.radians(config.init_parallax_deg)):
        return None
    E, mask = cv2.findEssentialMat(
        uv_reference_px,
        uv_px,
        K,
        method=cv2.RANSAC,
        prob=0.999,
        threshold=config.essential_threshold_px,
    )
    if E is None or E.shape != (3, 3):
        return None
    good, R, t, mask = cv2.recoverPose(E, uv_reference_px, uv_px, K, mask=mask)
    if good < config.min_inliers:
        return None
    T_current_reference = np.eye(4)
    T_current_reference[:3, :3] = R
    T_current_reference[:3, 3] = t.ravel() * baseline
    T_world_camera = T_world_reference @ se3_inverse(T_current_reference)
    if config.planar_motion:
        T_world_camera = camera_from_planar(planar_from_camera(T_world_camera))
    inliers = mask.ravel() > 0
    points, angles, ok = triangulate(
        T_world_reference, T_world_camera, uv_reference_px, uv_px, K, config.pnp_threshold_px
    )
    in_front = inliers & np.isfinite(angles)
    # Gate on the median over every inlier, not only the accepted points: an angle threshold
    # per point keeps the points that noise made look closer, which biases the scale.
    parallax = float(np.median(angles[in_front])) if in_front.any() else 0.0
    ok &= inliers
    if ok.sum() < config.min_inliers or parallax < config.init_parallax_deg:
        return None
    points[~ok] = np.nan
    return TwoViewStart(T_world_camera, points, inliers, parallax)
