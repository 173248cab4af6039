"""kiss-icp on batches of radar frames stitched by the motion prior.

Sparse radar frames are too thin for kiss-icp one at a time, so ``kiss_batch_frames``
consecutive frames are placed by the Doppler/gyro prior into the last frame's coordinates and
registered as one cloud; each frame enters kiss-icp's map exactly once. The prior goes in as
kiss-icp's initial guess (``last_delta``); kiss-icp does not weigh it against the scan, it
replaces it. Poses are snapped to SE(2) (z = 0) after every registration: a few centimetres of
z jitter otherwise grows into metres of z and tens of degrees of tilt.

kiss-icp reports no covariance; it is computed here from point-to-point residuals against
kiss-icp's map at the final pose.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from smokyslam.config import RadarOdometryConfig
from smokyslam.frontends.radar.motion_prior import MotionPrior
from smokyslam.frontends.radar.scan_matcher import MatchResult
from smokyslam.geometry import (
    se2_between,
    se2_compose,
    se2_from_matrix,
    se2_inverse,
    se3_from_se2,
    transform_points_2d,
)

KISS_RANGE_MARGIN_M = 5.0
"""A batch cloud reaches further than one frame: kiss-icp's range is the radar's plus this."""


def _make_kiss(config: RadarOdometryConfig):
    from kiss_icp.config import KISSConfig
    from kiss_icp.config.config import (
        AdaptiveThresholdConfig,
        DataConfig,
        MappingConfig,
        RegistrationConfig,
    )
    from kiss_icp.kiss_icp import KissICP

    kiss_config = KISSConfig(
        data=DataConfig(
            max_range=config.map_radius_m + KISS_RANGE_MARGIN_M, min_range=0.0, deskew=False
        ),
        mapping=MappingConfig(voxel_size=config.kiss_voxel_size_m, max_points_per_voxel=20),
        # The default initial threshold (2 m) lets a sparse first match slide far away.
        adaptive_threshold=AdaptiveThresholdConfig(
            initial_threshold=config.kiss_initial_threshold_m, min_motion_th=0.1
        ),
        registration=RegistrationConfig(max_num_threads=1),
    )
    return KissICP(kiss_config)


def point_to_point_covariance(
    points_world_xy: np.ndarray, map_xy: np.ndarray, pose: np.ndarray, gate_m: float
) -> tuple[np.ndarray, int, float]:
    """(3, 3) world-pose covariance from the nearest-neighbour residuals of (N, 2) registered
    points against (M, 2) map points within ``gate_m``; with the inlier count and RMS (m)."""
    if len(map_xy) == 0 or len(points_world_xy) == 0:
        return np.diag([1.0, 1.0, 0.1]), 0, float("nan")
    distance, _ = cKDTree(map_xy).query(points_world_xy, distance_upper_bound=gate_m)
    inlier = np.isfinite(distance)
    count = int(inlier.sum())
    if count < 3:
        return np.diag([1.0, 1.0, 0.1]), count, float("nan")
    rms = float(np.sqrt(np.mean(distance[inlier] ** 2)))
    arm = points_world_xy[inlier] - pose[:2]
    # Residual Jacobian of a point: d/dx = I, d/dyaw = perpendicular of its lever arm.
    H = np.zeros((3, 3))
    H[:2, :2] = np.eye(2) * count
    H[:2, 2] = H[2, :2] = np.array([-arm[:, 1].sum(), arm[:, 0].sum()])
    H[2, 2] = np.sum(arm**2)
    sigma2 = max(rms**2, 1e-4)
    return np.linalg.inv(H / sigma2 + np.eye(3) * 1e-9), count, rms


class KissBatchMatcher:
    """Registers prior-stitched batches of frames with kiss-icp."""

    def __init__(self, config: RadarOdometryConfig) -> None:
        self._config = config
        self._kiss = _make_kiss(config)
        self._last_keyframe: np.ndarray | None = None

    def register_batch(
        self, frames_xy: list[np.ndarray], anchor_pose: np.ndarray, priors: list[MotionPrior]
    ) -> list[MatchResult]:
        """Register B frames (sensor-frame (N_b, 2) points) as one cloud; the batch moves
        rigidly, so only its last frame (the keyframe) carries kiss-icp's correction."""
        predicted = [anchor_pose]
        for prior in priors:
            predicted.append(se2_compose(predicted[-1], prior.delta))
        predicted = np.array(predicted[1:])
        last = predicted[-1]
        in_last = [
            transform_points_2d(se2_between(last, pose), points)
            for pose, points in zip(predicted, frames_xy, strict=True)
        ]
        cloud = np.concatenate(in_last)
        cloud_xyz = np.column_stack([cloud, np.zeros(len(cloud))])
        map_before = self._kiss.local_map.point_cloud()[:, :2]
        previous_keyframe = anchor_pose if self._last_keyframe is None else self._last_keyframe
        self._kiss.last_pose = se3_from_se2(previous_keyframe)
        self._kiss.last_delta = se3_from_se2(se2_between(previous_keyframe, last))
        self._kiss.register_frame(cloud_xyz, np.zeros(0))
        registered = se2_from_matrix(self._kiss.last_pose)
        # Keep kiss-icp planar: z = 0, no roll or pitch.
        self._kiss.last_pose = se3_from_se2(registered)
        self._last_keyframe = registered
        correction = se2_compose(registered, se2_inverse(last))
        poses = se2_compose(correction, predicted)
        return self._results(frames_xy, anchor_pose, poses, priors, map_before, in_last[-1])

    def _results(
        self,
        frames_xy: list[np.ndarray],
        anchor_pose: np.ndarray,
        poses: np.ndarray,
        priors: list[MotionPrior],
        map_before: np.ndarray,
        last_points: np.ndarray,
    ) -> list[MatchResult]:
        gate = 3.0 * self._config.kiss_voxel_size_m
        world_last = transform_points_2d(poses[-1], frames_xy[-1])
        pose_cov, inliers, rms = point_to_point_covariance(world_last, map_before, poses[-1], gate)
        previous = np.vstack([anchor_pose[None, :], poses[:-1]])
        results = []
        for b, prior in enumerate(priors):
            delta = se2_between(previous[b], poses[b])
            covariance = prior.covariance
            if b == len(priors) - 1:
                A = np.eye(3)
                c, s = np.cos(previous[b][2]), np.sin(previous[b][2])
                A[:2, :2] = np.array([[c, s], [-s, c]])
                covariance = A @ pose_cov @ A.T
            matched = len(map_before) == 0 or inliers >= self._config.min_matches
            results.append(MatchResult(poses[b], delta, covariance, inliers, rms, matched))
        return results
