"""Camera pose from landmarks: PnP with RANSAC, a planar refinement, and its covariance.

Poses are ``T_world_camera`` (4, 4) in optical axes (z forward, x right, y down), or planar
``[x, y, yaw]`` of the camera body (x forward, y left, z up). The odometry world is the first
camera's body frame with its origin at the camera, so a level camera carried over a floor
keeps z = 0 and moves in (x, y, yaw).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from smokyslam.frontends.camera.landmarks import project
from smokyslam.geometry import R_BODY_OPTICAL, se2_from_matrix, se3_from_se2, se3_inverse

HUBER_PX = 1.0
"""Residuals beyond this get Huber weights in the planar refinement."""

MIN_SIGMA_PX = 0.25
"""Floor on the pixel noise behind the covariance: LK tracks are not better than this."""


def camera_from_planar(pose: np.ndarray) -> np.ndarray:
    """``T_world_camera`` (4, 4, optical axes) of a level camera body at ``[x, y, yaw]``, z = 0."""
    T = se3_from_se2(pose)
    T[:3, :3] = T[:3, :3] @ R_BODY_OPTICAL
    return T


def planar_from_camera(T_world_camera: np.ndarray) -> np.ndarray:
    """``[x, y, yaw]`` of the camera body (x forward) of an optical ``T_world_camera``."""
    T = np.array(T_world_camera, dtype=float)
    T[:3, :3] = T[:3, :3] @ R_BODY_OPTICAL.T
    return se2_from_matrix(T)


def body_to_world(poses: np.ndarray, points_optical: np.ndarray) -> np.ndarray:
    """(N, 3) world points of (N, 3) optical-frame points seen from (N, 3) planar poses."""
    p = points_optical @ R_BODY_OPTICAL.T  # optical -> body axes
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    return np.column_stack(
        [poses[:, 0] + c * p[:, 0] - s * p[:, 1], poses[:, 1] + s * p[:, 0] + c * p[:, 1], p[:, 2]]
    )


def project_planar(
    poses: np.ndarray, points_world: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project (N, 3) world points from planar poses ((3,) or (N, 3)): (N, 2) px, (N,) depth."""
    uv, z, _, _ = project_planar_jacobians(poses, points_world, K, jacobians=False)
    return uv, z


def project_planar_jacobians(
    poses: np.ndarray, points_world: np.ndarray, K: np.ndarray, jacobians: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Projection of (N, 3) world points from planar poses ((3,) or (N, 3)) and its Jacobians.

    Returns (N, 2) pixels, (N,) optical depths, the (N, 2, 3) Jacobian with respect to the
    pose [x, y, yaw] and the (N, 2, 3) Jacobian with respect to the point (None, None when
    ``jacobians`` is False).
    """
    poses = np.asarray(poses, dtype=float)
    x, y, yaw = (poses[..., k] for k in range(3))
    c, s = np.cos(yaw), np.sin(yaw)
    dx, dy = points_world[:, 0] - x, points_world[:, 1] - y
    body = np.column_stack([c * dx + s * dy, -s * dx + c * dy, points_world[:, 2]])
    p = body @ R_BODY_OPTICAL  # body -> optical axes
    z = p[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_z = 1.0 / z
        uv = p[:, :2] * inv_z[:, None] * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    if not jacobians:
        return uv, z, None, None
    D = np.zeros((len(z), 2, 3))  # d pixel / d optical point
    D[:, 0, 0] = K[0, 0] * inv_z
    D[:, 0, 2] = -K[0, 0] * p[:, 0] * inv_z**2
    D[:, 1, 1] = K[1, 1] * inv_z
    D[:, 1, 2] = -K[1, 1] * p[:, 1] * inv_z**2
    M = D @ R_BODY_OPTICAL.T  # d pixel / d body point
    c, s = np.broadcast_to(c, z.shape)[:, None], np.broadcast_to(s, z.shape)[:, None]
    J_point = np.stack([M[:, :, 0] * c - M[:, :, 1] * s, M[:, :, 0] * s + M[:, :, 1] * c], -1)
    J_point = np.concatenate([J_point, M[:, :, 2:]], axis=2)
    J_yaw = M[:, :, 0] * body[:, 1:2] - M[:, :, 1] * body[:, 0:1]
    J_pose = np.concatenate([-J_point[:, :, :2], J_yaw[:, :, None]], axis=2)
    return uv, z, J_pose, J_point


def planar_jacobian(
    pose: np.ndarray, points_world: np.ndarray, uv_px: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) residuals of a planar pose and their (N, 2, 3) Jacobian in [x, y, yaw]."""
    uv, _, J, _ = project_planar_jacobians(pose, points_world, K)
    return uv - uv_px, J


@dataclass
class PoseEstimate:
    """A camera pose fitted to landmarks.

    T_world_camera: (4, 4) optical axes. inliers: (N,) bool over the landmarks given.
    residual_rms_px: RMS reprojection error of the inliers.
    covariance: (3, 3) of the body pose [x, y, yaw] given the landmarks (odometry units, rad).
    """

    T_world_camera: np.ndarray
    inliers: np.ndarray
    residual_rms_px: float
    covariance: np.ndarray


def refine_planar(
    pose: np.ndarray, points_world: np.ndarray, uv_px: np.ndarray, K: np.ndarray, iterations=4
) -> np.ndarray:
    """Gauss-Newton with Huber weights on the planar pose [x, y, yaw] of a level camera."""
    pose = np.asarray(pose, dtype=float).copy()
    for _ in range(iterations):
        r, J = planar_jacobian(pose, points_world, uv_px, K)
        norm = np.linalg.norm(r, axis=1)
        w = np.where(norm <= HUBER_PX, 1.0, HUBER_PX / np.maximum(norm, 1e-12))
        H = np.einsum("naj,n,nak->jk", J, w, J)
        step = -np.linalg.solve(H + 1e-9 * np.eye(3), np.einsum("naj,n,na->j", J, w, r))
        pose += step
        if np.abs(step).max() < 1e-5:
            break
    return pose


def planar_covariance(
    pose: np.ndarray, points_world: np.ndarray, K: np.ndarray, residual_rms_px: float
) -> np.ndarray:
    """(3, 3) covariance of [x, y, yaw] from the reprojection Jacobian at ``pose``.

    sigma^2 (J^T J)^-1 with sigma the residual RMS (floored at ``MIN_SIGMA_PX``): it shrinks
    with more and better-spread landmarks and grows with worse tracks.
    """
    uv, _ = project_planar(pose, points_world, K)
    _, J = planar_jacobian(pose, points_world, uv, K)
    sigma = max(residual_rms_px, MIN_SIGMA_PX)
    return sigma**2 * np.linalg.pinv(np.einsum("naj,nak->jk", J, J))


def solve_pnp(
    points_world: np.ndarray,
    uv_px: np.ndarray,
    K: np.ndarray,
    T_guess: np.ndarray,
    threshold_px: float,
    planar: bool,
) -> PoseEstimate | None:
    """Fit a camera pose to (N, 3) world landmarks seen at (N, 2) pixels, or None if it fails.

    RANSAC (P3P on minimal sets) picks the inliers; the pose is then refined on them, as a
    planar [x, y, yaw] pose of a level camera when ``planar`` is set, else in 6 DoF.
    """
    if len(points_world) < 6:
        return None
    T_cw = se3_inverse(T_guess)
    rvec0, _ = cv2.Rodrigues(T_cw[:3, :3])
    ok, rvec, tvec, idx = cv2.solvePnPRansac(
        points_world,
        uv_px,
        K,
        None,
        rvec=rvec0.copy(),
        tvec=T_cw[:3, 3].reshape(3, 1).copy(),
        useExtrinsicGuess=False,
        iterationsCount=100,
        reprojectionError=threshold_px,
        confidence=0.999,
        flags=cv2.SOLVEPNP_P3P,
    )
    if not ok or idx is None or len(idx) < 6:
        return None
    inl = np.zeros(len(points_world), dtype=bool)
    inl[idx.ravel()] = True
    if planar:
        R_cw, _ = cv2.Rodrigues(rvec)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R_cw, tvec.ravel()
        pose = refine_planar(planar_from_camera(se3_inverse(T)), points_world[inl], uv_px[inl], K)
        uv, z = project_planar(pose, points_world, K)
        T_world_camera = camera_from_planar(pose)
    else:
        rvec, tvec = cv2.solvePnPRefineLM(points_world[inl], uv_px[inl], K, None, rvec, tvec)
        R_cw, _ = cv2.Rodrigues(rvec)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R_cw, tvec.ravel()
        T_world_camera = se3_inverse(T)
        uv, z = project(T_world_camera, points_world, K)
    error = np.linalg.norm(uv - uv_px, axis=1)
    inl = (z > 0) & (error <= threshold_px)
    if inl.sum() < 6:
        return None
    rms = float(np.sqrt(np.mean(error[inl] ** 2)))
    covariance = planar_covariance(planar_from_camera(T_world_camera), points_world[inl], K, rms)
    return PoseEstimate(T_world_camera, inl, rms, covariance)
