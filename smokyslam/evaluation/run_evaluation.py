"""A run scored against the log's ground truth, in one frame for trajectory and maps.

Evaluation reads the ground truth on its own (estimators never see it). It computes one rigid
SE(2) alignment of the estimate onto the ground truth (2D Umeyama over every associated
position) and applies that same alignment to the trajectory and to every map before they are
scored or drawn, so a map carries exactly the error the ATE does. For camera-only runs the
trajectory is metric through the camera's height; a Sim(2) alignment is reported beside it
(``ate_sim2_rmse_m``), with the error of the height-based scale against the Sim(2) one.
Without ground truth the alignment is the identity and there are no trajectory metrics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from smokyslam.evaluation.trajectory_metrics import (
    Alignment,
    Similarity2D,
    TrajectoryMetrics,
    associate,
    evaluate_trajectory,
    umeyama_2d,
)
from smokyslam.types import GroundTruthTrajectory

IDENTITY = Similarity2D(0.0, np.zeros(2))


@dataclass
class RunEvaluation:
    """to_truth: the rigid alignment applied to trajectory and maps (identity without ground
    truth). trajectory: SE(2) metrics. sim2: Sim(2) metrics (camera-only runs)."""

    to_truth: Similarity2D
    trajectory: TrajectoryMetrics | None = None
    sim2: TrajectoryMetrics | None = None

    @property
    def pose_truth_map(self) -> np.ndarray:
        """(3,) the alignment as a planar pose ``[x_m, y_m, yaw_rad]``."""
        return np.array([*self.to_truth.translation_m, self.to_truth.yaw_rad])

    def metrics(self) -> dict[str, Any]:
        """The ``trajectory`` and ``alignment`` entries of ``metrics.json``."""
        alignment = {
            "method": Alignment.SE2.value if self.trajectory is not None else "none",
            "yaw_rad": self.to_truth.yaw_rad,
            "translation_m": [float(v) for v in self.to_truth.translation_m],
            "applied_to": ["trajectory.tum", "trajectory_kitti.txt", "maps"],
        }
        out: dict[str, Any] = {"alignment": alignment}
        if self.trajectory is not None:
            out["trajectory"] = self.trajectory.to_dict()
        if self.sim2 is not None:
            scale = self.sim2.scale
            out["trajectory"].update(
                {
                    "ate_sim2_rmse_m": self.sim2.ate_rmse_m,
                    "sim2_scale": scale,
                    "scale_error_pct": 100.0 * (1.0 / scale - 1.0) if scale > 0 else None,
                }
            )
        return out


def evaluate_estimate(
    stamps_s: np.ndarray,
    poses_world_base: np.ndarray,
    lost: np.ndarray,
    truth: GroundTruthTrajectory | None,
    with_sim2: bool,
) -> RunEvaluation:
    """Align (N, 3) estimated poses at (N,) stamps onto ``truth`` and score them.

    The alignment uses every estimated frame inside the ground truth's time span; with fewer
    than two such frames (or no ground truth) it is the identity and nothing is scored.
    """
    if truth is None or len(truth) < 2 or len(stamps_s) == 0:
        return RunEvaluation(IDENTITY)
    inside, truth_at = associate(stamps_s, truth.stamps_s, truth.poses_world_base)
    if inside.sum() < 2:
        return RunEvaluation(IDENTITY)
    to_truth = umeyama_2d(poses_world_base[inside, :2], truth_at[:, :2], with_scale=False)
    args = (stamps_s, poses_world_base, truth.stamps_s, truth.poses_world_base)
    trajectory = evaluate_trajectory(*args, Alignment.SE2, lost=lost)
    sim2 = evaluate_trajectory(*args, Alignment.SIM2, lost=lost) if with_sim2 else None
    return RunEvaluation(to_truth, trajectory, sim2)
