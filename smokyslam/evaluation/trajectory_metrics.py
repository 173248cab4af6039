"""Trajectory accuracy: ATE after a planar SE(2) or Sim(2) alignment, and RPE per metre.

Definitions (all on planar poses ``[x_m, y_m, yaw_rad]``):
- Association: ground truth is interpolated at the estimate's stamps; estimate frames outside
  the ground truth's time span are left out.
- ATE RMSE: RMS position error after the least-squares 2D alignment of the estimate onto the
  ground truth (:func:`umeyama_2d`; rotation + translation, plus scale for ``sim2``). A 3D
  Umeyama on planar data can return a reflection (z is degenerate), hence this 2D version.
- RPE translation RMSE: for every frame i, the first frame j at least 1 m of ground-truth
  travel later; the translation norm of ``(gt_i^-1 gt_j)^-1 (est_i^-1 est_j)``, RMS over i.
- drift_pct: ``100 * ATE RMSE / ground-truth path length``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from enum import StrEnum

import numpy as np

from smokyslam.errors import EstimationError
from smokyslam.geometry import interpolate_se2, rotation_2d, se2_between, wrap_angle


class Alignment(StrEnum):
    """How the estimate is aligned to the ground truth before the ATE."""

    SE2 = "se2"
    SIM2 = "sim2"


@dataclass(frozen=True)
class Similarity2D:
    """``p_target = scale * R(yaw_rad) @ p_source + translation_m``."""

    yaw_rad: float
    translation_m: np.ndarray
    scale: float = 1.0

    def apply(self, poses: np.ndarray) -> np.ndarray:
        """(N, 3) poses mapped into the target frame (positions scaled, yaws rotated)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        xy = self.scale * poses[:, :2] @ rotation_2d(self.yaw_rad).T + self.translation_m
        return np.column_stack([xy, wrap_angle(poses[:, 2] + self.yaw_rad)])


def umeyama_2d(source_xy: np.ndarray, target_xy: np.ndarray, with_scale: bool) -> Similarity2D:
    """Least-squares rotation (never a reflection), translation and optional scale taking
    (N, 2) ``source_xy`` onto (N, 2) ``target_xy`` (Umeyama 1991, in the plane)."""
    source = np.asarray(source_xy, dtype=float)
    target = np.asarray(target_xy, dtype=float)
    if len(source) < 2 or source.shape != target.shape:
        raise EstimationError("trajectory alignment needs two or more associated positions")
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    ds, dt = source - mu_s, target - mu_t
    # For 2D rotations the optimum has a closed form: the angle of sum(conj(s) * t).
    cross = np.sum(ds[:, 0] * dt[:, 1] - ds[:, 1] * dt[:, 0])
    dot = np.sum(ds[:, 0] * dt[:, 0] + ds[:, 1] * dt[:, 1])
    yaw = float(np.arctan2(cross, dot))
    variance = float(np.sum(ds**2))
    scale = float(np.hypot(cross, dot) / variance) if with_scale and variance > 0 else 1.0
    translation = mu_t - scale * rotation_2d(yaw) @ mu_s
    return Similarity2D(yaw, translation, scale)


def path_length_m(poses: np.ndarray) -> float:
    """Sum of the (N, 3) poses' position steps, metres."""
    steps = np.diff(np.asarray(poses, dtype=float)[:, :2], axis=0)
    return float(np.linalg.norm(steps, axis=1).sum())


def rpe_translation_rmse(
    poses_est: np.ndarray, poses_gt: np.ndarray, delta_m: float = 1.0
) -> float:
    """RMS translation of the relative pose error over ``delta_m`` of ground-truth travel
    ((N, 3) associated poses); NaN when the path is shorter than ``delta_m``."""
    travelled = np.concatenate(
        [[0.0], np.cumsum(np.linalg.norm(np.diff(poses_gt[:, :2], axis=0), axis=1))]
    )
    j = np.searchsorted(travelled, travelled + delta_m)
    i = np.flatnonzero(j < len(travelled))
    if i.size == 0:
        return float("nan")
    j = j[i]
    error = se2_between(
        se2_between(poses_gt[i], poses_gt[j]), se2_between(poses_est[i], poses_est[j])
    )
    return float(np.sqrt(np.mean(np.sum(error[:, :2] ** 2, axis=1))))


@dataclass
class TrajectoryMetrics:
    """What ``metrics.json`` holds under ``trajectory``."""

    ate_rmse_m: float
    ate_alignment: str
    rpe_trans_rmse_m: float
    path_length_m: float
    drift_pct: float
    frames: int
    lost_frames: int
    scale: float = 1.0

    def to_dict(self) -> dict[str, float | int | str]:
        return asdict(self)


def associate(
    stamps_s: np.ndarray, gt_stamps_s: np.ndarray, gt_poses: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Mask (N,) of estimate stamps inside the ground truth's span, and the (M, 3) ground
    truth interpolated at those stamps (``gt_stamps_s`` sorted)."""
    stamps = np.asarray(stamps_s, dtype=float)
    gt_stamps = np.asarray(gt_stamps_s, dtype=float)
    inside = (stamps >= gt_stamps[0] - 1e-9) & (stamps <= gt_stamps[-1] + 1e-9)
    return inside, interpolate_se2(gt_stamps, gt_poses, stamps[inside]).reshape(-1, 3)


def evaluate_trajectory(
    stamps_s: np.ndarray,
    poses_est: np.ndarray,
    gt_stamps_s: np.ndarray,
    gt_poses: np.ndarray,
    alignment: Alignment | str = Alignment.SE2,
    lost: np.ndarray | None = None,
) -> TrajectoryMetrics:
    """Score (N, 3) estimated poses at (N,) stamps against (M, 3) ground truth at (M,) stamps.

    ``lost``: (N,) bool per estimated frame, counted into ``lost_frames``.
    """
    alignment = Alignment(alignment)
    inside, gt = associate(stamps_s, gt_stamps_s, gt_poses)
    est = np.asarray(poses_est, dtype=float)[inside]
    similarity = umeyama_2d(est[:, :2], gt[:, :2], with_scale=alignment is Alignment.SIM2)
    aligned = similarity.apply(est)
    ate = float(np.sqrt(np.mean(np.sum((aligned[:, :2] - gt[:, :2]) ** 2, axis=1))))
    length = path_length_m(gt)
    return TrajectoryMetrics(
        ate_rmse_m=ate,
        ate_alignment=alignment.value,
        rpe_trans_rmse_m=rpe_translation_rmse(aligned, gt),
        path_length_m=length,
        drift_pct=100.0 * ate / length if length > 0 else float("nan"),
        frames=len(np.asarray(stamps_s)),
        lost_frames=int(np.count_nonzero(lost)) if lost is not None else 0,
        scale=similarity.scale,
    )
