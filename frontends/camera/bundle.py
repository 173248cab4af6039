"""Sliding-window bundle adjustment of planar keyframe poses and landmark inverse depths.

Why: a pose fitted to landmarks whose depths are noisy underestimates the translation
(errors in the variables), the landmarks triangulated next inherit the shrunken scale, and
over a few hundred keyframes the scale decays geometrically. Estimating poses and depths
jointly from the pixel observations alone removes that bias.

Model: each landmark lies on the ray of its first observation in the window (its anchor),
at inverse depth ``rho`` along the anchor camera's optical axis; every other observation
contributes a 2-pixel residual. Poses are planar ``[x, y, yaw]`` of a level camera body.
Landmarks have one parameter each, so the normal equations are reduced to the poses with a
diagonal Schur complement; the gauge (and so the scale) is held by the fixed poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.frontends.camera.pose import (
    body_to_world,
    project_planar,
    project_planar_jacobians,
)

HUBER_PX = 1.0
"""Residuals beyond this get Huber weights."""


@dataclass
class WindowProblem:
    """The window's unknowns and observations (F keyframes, L landmarks, O observations).

    poses: (F, 3) planar keyframe poses; fixed: (F,) bool, True for gauge-holding poses.
    anchor: (L,) keyframe index of each landmark's anchor; anchor_ray: (L, 3) normalized
        camera ray [x/z, y/z, 1] of its anchor observation; inverse_depth: (L,) 1/z there.
    obs_landmark, obs_keyframe: (O,) indices; obs_uv_px: (O, 2) observed pixels
        (observations in a landmark's own anchor keyframe are not listed).
    """

    poses: np.ndarray
    fixed: np.ndarray
    anchor: np.ndarray
    anchor_ray: np.ndarray
    inverse_depth: np.ndarray
    obs_landmark: np.ndarray
    obs_keyframe: np.ndarray
    obs_uv_px: np.ndarray


def _residuals_and_jacobians(
    anchor_pose: np.ndarray, obs_pose: np.ndarray, ray: np.ndarray, rho: np.ndarray, uv, K
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(O, 2) residuals and their Jacobians: (O, 2, 3) in the anchor pose, (O, 2, 3) in the
    observing pose, (O, 2) in the inverse depth. Poses (O, 3), rays (O, 3), depths (O,)."""
    points = body_to_world(anchor_pose, ray / rho[:, None])
    projected, _, J_obs, J_point = project_planar_jacobians(obs_pose, points, K)
    offset = points[:, :2] - anchor_pose[:, :2]
    dP_dyaw = np.column_stack([-offset[:, 1], offset[:, 0], np.zeros(len(rho))])
    J_anchor = np.concatenate([J_point[:, :, :2], (J_point @ dP_dyaw[:, :, None])], axis=2)
    dP_drho = -(points - np.column_stack([anchor_pose[:, :2], np.zeros(len(rho))])) / rho[:, None]
    J_rho = (J_point @ dP_drho[:, :, None])[:, :, 0]
    return projected - uv, J_anchor, J_obs, J_rho


def _huber_cost(residuals: np.ndarray) -> float:
    norm = np.linalg.norm(residuals, axis=1)
    return float(
        np.sum(np.where(norm <= HUBER_PX, 0.5 * norm**2, HUBER_PX * (norm - 0.5 * HUBER_PX)))
    )


def adjust(problem: WindowProblem, K: np.ndarray, iterations: int = 5) -> np.ndarray:
    """Levenberg-Marquardt on the window, in place on ``poses`` and ``inverse_depth``.

    A step is taken only if it lowers the Huber cost and keeps every inverse depth positive.
    Returns the (O,) final reprojection error norms in pixels.
    """
    pb = problem
    free = np.flatnonzero(~pb.fixed)
    n_pose = 3 * len(free)
    column_of = np.full(len(pb.poses), -1)
    column_of[free] = 3 * np.arange(len(free))
    lm, kf = pb.obs_landmark, pb.obs_keyframe
    akf = pb.anchor[lm]
    ray = pb.anchor_ray[lm]
    n_lm = len(pb.inverse_depth)

    def residuals(poses: np.ndarray, inverse_depth: np.ndarray) -> np.ndarray:
        points = body_to_world(poses[akf], ray / inverse_depth[lm][:, None])
        return project_planar(poses[kf], points, K)[0] - pb.obs_uv_px

    r = residuals(pb.poses, pb.inverse_depth)
    cost = _huber_cost(r)
    damping = 1e-4
    for _ in range(iterations):
        r, J_anchor, J_obs, J_rho = _residuals_and_jacobians(
            pb.poses[akf], pb.poses[kf], ray, pb.inverse_depth[lm], pb.obs_uv_px, K
        )
        J_pose = np.zeros((len(r), 2, max(n_pose, 1)))
        for which, J in ((akf, J_anchor), (kf, J_obs)):
            col = column_of[which]
            rows = np.flatnonzero(col >= 0)
            for k in range(3):
                J_pose[rows, :, col[rows] + k] += J[rows, :, k]
        norm = np.linalg.norm(r, axis=1)
        w = np.where(norm <= HUBER_PX, 1.0, HUBER_PX / np.maximum(norm, 1e-12))
        Jw = J_pose * w[:, None, None]
        rows_pose, rows_weighted = J_pose.reshape(-1, J_pose.shape[2]), Jw.reshape(-1, Jw.shape[2])
        H_pp = (rows_weighted.T @ rows_pose)[:n_pose, :n_pose]
        g_p = (rows_weighted.T @ r.reshape(-1))[:n_pose]
        H_pl_obs = np.einsum("oaj,oa->oj", Jw, J_rho)[:, :n_pose]
        H_pl = np.stack(
            [np.bincount(lm, H_pl_obs[:, j], minlength=n_lm) for j in range(n_pose)], axis=1
        ).reshape(n_lm, n_pose)
        H_ll = np.bincount(lm, w * np.sum(J_rho**2, axis=1), minlength=n_lm) + 1e-12
        g_l = np.bincount(lm, w * np.sum(J_rho * r, axis=1), minlength=n_lm)
        for _ in range(4):
            D_ll = H_ll * (1.0 + damping)
            S = H_pp + damping * np.diag(np.diag(H_pp)) - H_pl.T @ (H_pl / D_ll[:, None])
            b = g_p - H_pl.T @ (g_l / D_ll)
            d_pose = np.linalg.solve(S + 1e-12 * np.eye(n_pose), -b) if n_pose else np.zeros(0)
            d_rho = -(g_l + H_pl @ d_pose) / D_ll
            poses = pb.poses.copy()
            poses[free] += d_pose.reshape(-1, 3)
            inverse_depth = pb.inverse_depth + d_rho
            if np.all(inverse_depth > 0):
                r_new = residuals(poses, inverse_depth)
                cost_new = _huber_cost(r_new)
                if cost_new < cost:
                    pb.poses[:], pb.inverse_depth[:] = poses, inverse_depth
                    r, cost = r_new, cost_new
                    damping = max(damping / 10.0, 1e-7)
                    break
            damping *= 10.0
        else:
            break
        if np.abs(d_pose).max(initial=0.0) < 1e-7:
            break
    return np.linalg.norm(r, axis=1)
